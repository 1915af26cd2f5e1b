"""The README and the documentation pages: their examples run as written and do what the text says, the Quick
start has exactly its two commands, and the README stays a front door (at most 15 KB)."""

import contextlib
import io
import math
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
DOCS = ROOT / "docs"


def python_blocks(path: Path = README):
    return re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.S)


def run(path: Path, marker: str, quiet: bool = True) -> dict:
    """Run the first Python block of `path` that contains `marker`; its namespace."""
    example = next(block for block in python_blocks(path) if marker in block)
    namespace: dict = {}
    with contextlib.redirect_stdout(io.StringIO()) if quiet else contextlib.nullcontext():
        exec(compile(example, str(path), "exec"), namespace)
    return namespace


def test_integration_example_runs_and_localizes():
    example = next(block for block in python_blocks() if "ParticleFilter" in block)
    assert len(example.strip().splitlines()) <= 15
    namespace = run(README, "ParticleFilter")
    pose = namespace["est"].pose
    assert math.hypot(pose[0] + 2.0, pose[1]) < 0.05
    assert abs(math.remainder(pose[2] - math.pi, 2 * math.pi)) < 0.03
    h = namespace["h"]
    assert 0 <= h.position and 0 <= h.orientation
    assert (namespace["est"].covariance.diagonal() < 0.002).all()  # what the text says of the printed figures


def test_the_readme_integration_and_getting_started_hold_the_same_robot_loop():
    loop = next(block for block in python_blocks() if "ParticleFilter" in block)
    assert loop in python_blocks(DOCS / "integration.md") and loop in python_blocks(DOCS / "getting-started.md")


def test_getting_started_goes_from_the_clone_to_the_loop_in_order():
    """Clone, `make demo`, the recording, the loop, the printed figures: in that order, with the repository's
    address (mkdocs.yml's repo_url) in the clone command."""
    text = (DOCS / "getting-started.md").read_text()
    repo_url = re.search(r"^repo_url: (\S+)$", (ROOT / "mkdocs.yml").read_text(), flags=re.M).group(1)
    assert f"git clone {repo_url}.git" in text
    steps = [
        "## 1. Clone",
        "## 2. `make demo`",
        "## 3. Open the recording",
        "## 4. The robot's loop",
        "## 5. What each printed figure means",
    ]
    assert [text.index(step) for step in steps] == sorted(text.index(step) for step in steps)
    demo = (ROOT / "results" / "demo_walk.txt").read_text()
    header = demo.splitlines()[1].split()
    meanings = text.split("## 5.", 1)[1]
    for column in ("seed", "pos", "head", "converge", "reconv.", "mirror", "ms/step"):
        assert column in header and f"`{column}" in meanings, column


def test_readme_quick_start_has_exactly_the_two_commands():
    quick = README.read_text().split("## Quick start", 1)[1].split("##", 1)[0]
    block = re.search(r"```sh\n(.*?)```", quick, flags=re.S).group(1).strip().splitlines()
    assert block == ["make demo", "make test"]


def test_the_readme_is_a_front_door():
    assert README.stat().st_size <= 15 * 1024
    assert "../shared" not in README.read_text()
    for target in re.findall(r"\]\(([^)#\s]+)", README.read_text()):
        if not re.match(r"https?://", target):
            assert (ROOT / target).exists(), f"the README links to {target}, which is not in the repository"


def test_lwpr_example_runs_and_learns():
    namespace = run(DOCS / "papers" / "rouxel.md", "LWPR(2, 1)", quiet=False)
    assert abs(namespace["y_hat"][0] - (-0.1567)) < 0.02 and namespace["conf"][0] > 0


def test_localizer_example_runs_and_finds_the_touchline_its_frames_show():
    namespace = run(DOCS / "integration.md", "Localizer(")
    pose, truth = namespace["estimate"].pose, namespace["truth"]
    assert math.hypot(pose[0] - truth[0], pose[1] - truth[1]) < 0.15
    assert abs(math.remainder(pose[2] - truth[2], 2 * math.pi)) < 0.1
    assert namespace["loc"].quality().value == "superb" and not namespace["loc"].is_lost


def _results(name: str) -> dict:
    import json

    return json.loads((ROOT / "results" / name).read_text())


def _headline(what: str) -> str:
    """The README's headline-figures row that starts with `what`."""
    return next(line for line in README.read_text().splitlines() if line.startswith(f"| {what}"))


def test_the_readme_headline_figures_are_those_of_the_results_files():
    """Each headline figure is read from the results file its command wrote (to the digits printed): a new
    measurement that changes a figure fails here until the README says it."""
    walk = _results("walk.json")["summary"]
    row = _headline("walk scenario")
    assert f"median {walk['position_rmse_m']['median']:.3f} m" in row
    assert f"worst {walk['position_rmse_m']['worst']:.3f} m (seed {walk['position_rmse_m']['worst_seed']}" in row
    assert f"re-convergence median {walk['reconverged_s']['median']:.2f} s" in row

    families = _results("eval_holdout.json")["splits"]["holdout"]["families"]
    kidnap, tracking = families["kidnap"]["summary"], families["tracking"]["summary"]
    row = _headline("evaluation battery")
    assert f"tracking RMSE {tracking['rmse_position_m']['median']:.3f} m" in row
    assert (
        f"in {kidnap['reconverge_s']['median']:.2f} s (median), {kidnap['reconverge_s']['never']} of "
        f"{kidnap['reconverge_s']['runs']} runs never" in row
    )

    soak = _results("soak.json")
    row = _headline("an hour in the loop")
    assert soak["nonfinite"] == 0 and "no NaN" in row
    assert f"+{soak['memory']['growth_mb']:.2f} MB" in row

    fuzz = _results("fuzz_full.json")
    row = _headline("fuzzing")
    assert f"{fuzz['cases']:,} cases".replace(",", " ") in row and fuzz["crashes"] == 0 and "0 crashes" in row

    loop = _results("bench.json")["models"]["robot_loop"]
    row = _headline("robot loop")
    assert (
        f"without detections {loop['frame_us']:.1f} µs" in row and f"detections {loop['correct_list_us']:.1f} µs" in row
    )

    row = _headline("tuned on the battery")
    for name, words in (
        ("tune_battery_8.json", "fail share {:.1f} → {:.1f} %"),
        ("tune_battery.json", "({:.1f} → {:.1f} %)"),
    ):
        held = _results(name)["comparison"]["holdout"]
        assert words.format(100 * held["default"]["fail_share"], 100 * held["tuned"]["fail_share"]) in row
    held = _results("tune_battery_8.json")["comparison"]["holdout"]
    assert f"RMSE {held['default']['rmse_position_m']:.3f} → {held['tuned']['rmse_position_m']:.3f} m" in row
    assert f"never re-converge {held['default']['never']} → {held['tuned']['never']} of 90" in row

    mismatch = _results("collision_mismatch.json")["mismatch"]
    single = mismatch["containment"]["single"]
    baseline = f"velocity-linear x{mismatch['baseline_widen']['containment']:g}"
    scored = f"velocity-linear x{mismatch['baseline_widen']['log_score']:g}"
    row = _headline("Hoffmann")
    assert f"{100 * single['adaptive']['mismatch']['median']:.0f} % of steps" in row
    assert f"{100 * single['adaptive']['bins']['0.7-1.05']['median']:.0f} % in the fastest stop turns" in row
    assert mismatch["goals"]["single/adaptive"]["at_least_80_percent_everywhere"] is True and "met" in row
    assert mismatch["goals"]["single/adaptive"]["log_score_above_velocity_linear_everywhere"] is True

    def signed(value: float) -> str:
        return f"{value:.2f}".replace("-", "−")

    assert (
        f"log score {signed(single['adaptive']['mismatch']['log_score_median'])} against "
        f"{signed(single[scored]['mismatch']['log_score_median'])} for velocity-linear at its best"
    ) in row
    assert (
        f"widened ×{mismatch['baseline_widen']['containment']:g} holds the truth in "
        f"{100 * single[baseline]['mismatch']['median']:.0f} % with a cloud "
        f"{single[baseline]['mismatch']['final_spread_median_m']:.2f} m across against "
        f"{single['adaptive']['mismatch']['final_spread_median_m']:.2f} m"
    ) in row

    rows = [
        r
        for r in _results("odometry_mismatch.json")["rows"]
        if (r["surface"], r["regime"], r["robot_spread"], r["run_spread"]) == ("carpet", "fleet", 1.0, 1.0)
    ]
    row = _headline("Rouxel")
    for kind in ("apriori", "online"):
        (r,) = [r for r in rows if r["kind"] == kind]
        cut, (low, high) = r["reduction"]["lwpr"]["mean"], r["reduction"]["lwpr"]["ci95"]
        figure = f"{r['drift10_cm']['raw']:.1f} → {r['drift10_cm']['lwpr']:.1f} cm (−{100 * cut:.0f} %, "
        interval = f"−{100 * high:.0f} to −{100 * low:.0f} %)"
        assert figure + interval in row or figure + "95 % interval " + interval in row

    velocity = _results("velocity_mismatch.json")
    five = velocity["levels"]["links +-5 %"]["summary"]
    row = _headline("Wawrzyński")
    seeds = velocity["seeds"]
    assert f"walks {seeds[0]}–{seeds[-1]}" in row
    for name, text in (
        ("ekf", "for the paper's filter as written"),
        ("ekf+bias", "for the bias-state variant"),
        ("kinematics+gyro", "for kinematics+gyro"),
    ):
        assert (
            f"{five[name]['median']:.1f} %, worst {five[name]['max']:.1f} % {text}" in row
            or f"{five[name]['median']:.1f} %, {five[name]['max']:.1f} % {text}" in row
        )
    missed = len(seeds) - five["ekf"]["within_goal"]
    assert f"missed on {missed} of {len(seeds)}" in row
