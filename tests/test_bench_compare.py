"""`robocup-mcl bench compare`: the trees it benchmarks, the order of the runs, the figures it pairs and its
verdicts. (The benchmark runs themselves are `robocup-mcl bench`'s, tested in test_bench.py; a real comparison
compiles every kernel in the exported tree, about a minute, so it is run by hand: see the README.)"""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks import compare as bc
from benchmarks.compare import CompareError, Side


def _result(step: float, b2b: float, phase: float, loop_us: float = 30.0, n: int = 100) -> dict:
    """A `robocup-mcl bench --json` result with the fields compare reads."""
    return {
        "rows": [
            {
                "n": n,
                "full_step": {"numba_ns_per_particle": step, "numpy_ns_per_particle": 10 * step},
                "full_step_back_to_back": {"numba_ns_per_particle": b2b},
                "phases": {
                    "normalize": {"numba_ns_per_particle": phase},
                    "likelihood_lines": {"error": "numba: ValueError: boom"},
                },
            }
        ],
        "models": {
            "lwpr": {"update_us": 6.0, "predict_us": 3.0},
            "ekf": {"default": {"predict_us": 4.0, "correct_us": 2.0}},
            "robot_loop": {"particles": 500, "frame_us": loop_us, "method": "..."},
        },
        "between_frames": {
            "idle_s": 0.01,
            "samples": 40,
            "rows": [{"n": n, "full_step_us": 40.0, "issue_step_us": 20.0}],
        },
        "machine": {"cpu_model": "test CPU", "python": "3.11", "numba": "0"},
    }


def test_figures_pair_every_timed_figure_with_its_unit():
    figures = bc.figures(_result(70.0, 60.0, 7.0))
    assert figures == {
        "full step, N = 100": ("ns/particle", 70.0),
        "full step, back to back, N = 100": ("ns/particle", 60.0),
        "phase normalize, N = 100": ("ns/particle", 7.0),  # the phase that failed is left out
        "LWPR update": ("µs", 6.0),
        "LWPR predict": ("µs", 3.0),
        "velocity EKF (default) predict": ("µs", 4.0),
        "velocity EKF (default) correct": ("µs", 2.0),
        "robot loop, N = 500: frame": ("µs", 30.0),
        "between frames, N = 100: full step": ("µs", 40.0),
        "between frames, N = 100: the issue's step shape": ("µs", 20.0),
    }
    assert bc.figures({"rows": [], "models": {"lwpr": None, "ekf": None, "robot_loop": None}}) == {}


@pytest.mark.parametrize(
    "base, current, expected",
    [
        ([10.0, 11.0], [8.0, 9.5], "faster"),
        ([10.0, 11.0], [11.5, 12.0], "slower"),
        ([10.0, 11.0], [9.0, 10.5], "~"),  # overlapping ranges
        ([10.0, 11.0], [11.0, 12.0], "~"),  # touching counts as overlapping
        ([10.0], [5.0], "-"),  # one round: no spread to judge by
        ([10.0, 10.2], [10.5, 10.6], "~"),  # apart, but the medians within 10 %
    ],
)
def test_verdict_needs_ranges_that_do_not_overlap(base, current, expected):
    assert bc.verdict(base, current) == expected


def test_the_threshold_sets_the_smallest_change_named():
    assert bc.verdict([10.0, 10.2], [10.5, 10.6], threshold=0.0) == "slower"
    assert bc.verdict([10.0, 10.2], [9.5, 9.6], threshold=0.05) == "faster"  # 0.944
    assert bc.verdict([10.0, 10.2], [9.5, 9.6], threshold=0.06) == "~"
    items = bc.compare(
        [_result(100.0, 60.0, 8.0)] * 2, [_result(95.0, 59.0, 8.0), _result(96.0, 59.0, 8.0)], threshold=0.02
    )
    assert next(i for i in items if i["item"] == "full step, N = 100")["verdict"] == "faster"


def test_compare_takes_the_medians_and_keeps_only_figures_of_every_run():
    base = [_result(100.0, 60.0, 8.0), _result(110.0, 61.0, 9.0), _result(105.0, 62.0, 7.0)]
    current = [_result(80.0, 60.5, 8.5), _result(90.0, 61.5, 8.0), _result(85.0, 59.0, 7.5)]
    del current[1]["models"]["robot_loop"]  # a run without it: the item is left out
    items = {item["item"]: item for item in bc.compare(base, current)}
    step = items["full step, N = 100"]
    assert step["base"] == [100.0, 110.0, 105.0] and step["current"] == [80.0, 90.0, 85.0]
    assert step["ratio"] == pytest.approx(85.0 / 105.0)
    assert step["verdict"] == "faster"
    assert items["full step, back to back, N = 100"]["verdict"] == "~"
    assert "robot loop, N = 500: frame" not in items
    assert list(items)[0] == "full step, N = 100"  # the current side's order
    text = bc.report(
        Side("base", Path("/b")), Side("working tree", Path("/c")), 3, list(items.values()), current[0]["machine"]
    )
    assert "full step, N = 100" in text and "0.81" in text and "test CPU" in text
    assert step["best_ratio"] == pytest.approx(80.0 / 100.0)  # the fastest rounds of each side
    assert text.splitlines()[-2].startswith("1 faster, 0 slower,")
    worst = max(items.values(), key=lambda item: item["best_ratio"])
    assert text.splitlines()[-1] == (
        f"best rounds: {sum(1 for i in items.values() if i['best_ratio'] > 1.05)} of "
        f"{len(items)} items more than 5 % slower; the largest ratio "
        f"{worst['best_ratio']:.2f} ({worst['item']})"
    )


def test_a_saved_comparison_is_reported_again(tmp_path, capsys):
    base = [_result(100.0, 60.0, 8.0), _result(110.0, 61.0, 9.0), _result(105.0, 62.0, 7.0)]
    current = [_result(80.0, 60.5, 8.5), _result(90.0, 61.5, 8.0), _result(85.0, 59.0, 7.5)]
    saved = tmp_path / "compare.json"
    saved.write_text(
        json.dumps(
            {
                "base": {"label": "base", "root": "/b"},
                "current": {"label": "now", "root": "/c"},
                "rounds": 3,
                "threshold": 0.1,
                "runs": {"base": base, "current": current},
            }
        )
    )
    assert bc.main(["--report", str(saved)]) == 0
    out = capsys.readouterr().out
    assert "base base, current now; 3 rounds" in out and "full step, N = 100" in out and "0.81" in out
    (tmp_path / "junk.json").write_text("{}")
    assert bc.main(["--report", str(tmp_path / "junk.json")]) == 1
    assert "is not a saved comparison" in capsys.readouterr().err


def test_runs_alternate_which_side_goes_first():
    calls = []
    base_runs, current_runs = bc.alternate(
        Side("b", Path("/b")), Side("c", Path("/c")), 3, lambda side: calls.append(side.label) or {"run": len(calls)}
    )
    assert calls == ["b", "c", "c", "b", "b", "c"]
    assert [r["run"] for r in base_runs] == [1, 4, 5] and [r["run"] for r in current_runs] == [2, 3, 6]


def test_bench_arguments():
    assert bc.bench_arguments([100, 1000], bc.DEFAULT_SKIP) == [
        "--json",
        "--sizes",
        "100,1000",
        "--no-startup",
        "--no-exact",
        "--skip",
        "peers,threads,memory,avx512,accuracy",
    ]
    assert bc.bench_arguments([10], []) == ["--json", "--sizes", "10"]


# -- the trees -----------------------------------------------------------------------------------------------------
needs_git = pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")


def _git(repository: Path, *args: str) -> str:
    return subprocess.run(
        ["git", "-C", str(repository), "-c", "user.name=t", "-c", "user.email=t@t", *args],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()


@pytest.fixture
def repository(tmp_path):
    """A git repository whose first commit is a robocup-mcl tree and whose second is not."""
    root = tmp_path / "repo"
    (root / "mcl").mkdir(parents=True)
    (root / "pyproject.toml").write_text('[project]\nname = "robocup-mcl"\n')
    (root / "mcl" / "__init__.py").write_text("")
    _git(root, "init", "-q")
    _git(root, "add", ".")
    _git(root, "commit", "-q", "-m", "first")
    (root / "pyproject.toml").write_text('[project]\nname = "something-else"\n')
    _git(root, "commit", "-q", "-am", "second")
    return root


@needs_git
def test_a_revision_is_exported_once_and_kept(repository, tmp_path):
    cache = tmp_path / "cache"
    side = bc.base_side("HEAD~1", repository, cache)
    commit = _git(repository, "rev-parse", "HEAD~1")
    assert side.root == cache / commit and side.label == f"HEAD~1 ({commit[:12]})"
    assert (side.root / "mcl" / "__init__.py").exists()
    marker = side.root / "mcl" / "kept.nbi"  # what its runs compile stays
    marker.write_text("cache")
    assert bc.base_side(commit, repository, cache).root == side.root
    assert marker.exists()
    assert sorted(p.name for p in cache.iterdir()) == [commit]  # no staging directory left behind


@needs_git
def test_a_bad_revision_or_tree_is_refused(repository, tmp_path):
    cache = tmp_path / "cache"
    with pytest.raises(CompareError, match="rev-parse"):
        bc.base_side("no-such-revision", repository, cache)
    with pytest.raises(CompareError, match="not a robocup-mcl tree"):
        bc.base_side("HEAD", repository, cache)  # its pyproject names another project
    assert not cache.exists() or list(cache.iterdir()) == []
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    with pytest.raises(CompareError, match="not a robocup-mcl checkout"):
        bc.base_side(str(elsewhere), repository, cache)


def test_another_checkout_is_taken_as_it_is(repository, tmp_path):
    (repository / "pyproject.toml").write_text('[project]\nname = "robocup-mcl"\n')
    side = bc.base_side(str(repository), repository, tmp_path / "cache")
    assert side.root == repository.resolve()
    assert not (tmp_path / "cache").exists()


def test_the_current_side_must_be_a_checkout(tmp_path):
    with pytest.raises(CompareError, match="installed copy"):
        bc.current_side(tmp_path)
    assert bc.current_side().label == "working tree"


@pytest.mark.parametrize("cli", ["mcl/tools/cli.py", "mcl/cli.py"], ids=["today", "before the tools moved"])
def test_a_run_imports_its_own_tree(tmp_path, cli):
    """The fresh process imports the side's packages, not the installed ones (an editable install included),
    and runs the side's own command line wherever that tree keeps it."""
    root = tmp_path / "tree"
    (root / cli).parent.mkdir(parents=True)
    for package in {root / "mcl", (root / cli).parent}:
        (package / "__init__.py").write_text("")
    (root / cli).write_text(
        "import json, sys\n"
        "if sys.argv[1:3] == ['bench', 'fail']:\n"
        "    print('the reason it failed', file=sys.stderr)\n"
        "    raise SystemExit(3)\n"
        "print(json.dumps({'argv': sys.argv[1:], 'file': __file__}))\n"
    )
    result = bc.run_bench(Side("fake", root), ["--json", "--sizes", "100"])
    assert result["argv"] == ["bench", "--json", "--sizes", "100"]
    assert Path(result["file"]).resolve() == (root / cli).resolve()
    with pytest.raises(CompareError, match="(?s)fake failed \\(exit 3\\).*the reason it failed"):
        bc.run_bench(Side("fake", root), ["fail"])


@pytest.mark.parametrize(
    "argv",
    [
        ["HEAD", "--rounds", "0"],
        ["HEAD", "--sizes", "ten"],
        ["HEAD", "--sizes", "0"],
        ["HEAD", "--skip", "everything"],
        ["HEAD", "--threshold", "-0.1"],
        ["HEAD", "--threshold", "1"],
        [],
    ],
)
def test_bad_options_are_refused(argv):
    with pytest.raises(SystemExit) as raised:
        bc.main(argv)
    assert raised.value.code == 2


def test_the_command_line_reaches_it():
    done = subprocess.run(
        [sys.executable, "-m", "mcl.tools.cli", "bench", "compare", "--help"],
        capture_output=True,
        text=True,
        check=False,
        cwd=Path(bc.__file__).parent.parent,
    )
    assert done.returncode == 0 and "alternated" in done.stdout


def test_a_failing_side_is_reported_without_a_traceback(monkeypatch, capsys):
    def failing(side, arguments):
        raise CompareError(f"the bench of {side.label} failed (exit 1):\nboom")

    monkeypatch.setattr(bc, "base_side", lambda revision: Side("HEAD (abc)", Path("/nowhere")))
    monkeypatch.setattr(bc, "run_bench", failing)
    assert bc.main(["HEAD", "--rounds", "1"]) == 1
    assert "failed (exit 1):\nboom" in capsys.readouterr().err


def test_json_output_carries_the_items_and_every_run(monkeypatch, capsys):
    runs = iter([_result(100.0, 60.0, 8.0), _result(90.0, 60.0, 8.0)])
    monkeypatch.setattr(bc, "base_side", lambda revision: Side("HEAD (abc)", Path("/nowhere")))
    monkeypatch.setattr(bc, "run_bench", lambda side, arguments: next(runs))
    assert bc.main(["HEAD", "--rounds", "1", "--sizes", "100", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["base"]["label"] == "HEAD (abc)" and out["rounds"] == 1 and out["threshold"] == 0.1
    assert out["arguments"][:3] == ["--json", "--sizes", "100"]
    assert out["runs"]["base"][0]["rows"][0]["full_step"]["numba_ns_per_particle"] == 100.0
    step = next(i for i in out["items"] if i["item"] == "full step, N = 100")
    assert step["ratio"] == pytest.approx(0.9) and step["verdict"] == "-"
