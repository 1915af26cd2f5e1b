"""`robocup-mcl tune` (mcl.tools.tuning): the space file, the objectives, the study on a local Ray instance with two
workers (seeded, resumable), and the command's one-line errors. The two-node cluster and a worker that dies
mid-task are in tests/test_tuning_cluster.py."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("ray")
pytest.importorskip("optuna")

from demos.battery import BatteryCase  # noqa: E402
from demos.battery_sim import as_robot_log, simulate  # noqa: E402
from mcl.profile import Profile  # noqa: E402
from mcl.tools.logs import RobotLog, write_log  # noqa: E402
from mcl.tools.tuning import LogCase, SearchSpace, SpaceError, TuneSettings, combine, evaluate_case, run_study  # noqa: E402

SPACE = """
[sensor]
outlier_weight = { low = 0.002, high = 0.1, log = true }
range_noise_floor = { low = 0.02, high = 0.2, log = true }

[augmented]
fit_threshold = { low = 0.0, high = 0.4 }
"""
CASES = (BatteryCase("tracking", 0, 12.0), BatteryCase("kidnap", 0, 12.0))


def settings(trials=3, seed=0, **overrides):
    options = dict(
        cases=CASES,
        space=SearchSpace.from_toml(SPACE),
        objective="truth",
        trials=trials,
        seeds=(0,),
        seed=seed,
        particles=100,
    )
    options.update(overrides)
    return TuneSettings(**options)


@pytest.fixture(scope="module")
def local_ray():
    import ray

    from mcl.tools.tuning.search import start_ray

    info = start_ray(None, workers=2)
    yield info
    ray.shutdown()


def history(outcome):
    return [(t["number"], t["value"], tuple(sorted(t["values"].items()))) for t in outcome.trials]


# -- the space file ------------------------------------------------------------------------------------------
def test_space_reads_ranges_scales_integers_and_choices():
    space = SearchSpace.from_toml(
        SPACE
        + """
[localizer]
particles = { low = 100, high = 1000, log = true }
[sensor.mixture]
choices = ["max", "sum"]
"""
    )
    assert space.names == [
        "sensor.outlier_weight",
        "sensor.range_noise_floor",
        "sensor.mixture",
        "augmented.fit_threshold",
        "localizer.particles",
    ]  # TOML's table order
    d = space.distributions()
    assert d["sensor.outlier_weight"].log and d["localizer.particles"].low == 100
    assert d["sensor.mixture"].choices == ("max", "sum")


@pytest.mark.parametrize(
    "text, words",
    [
        ("[venue]\nx = { low = 0, high = 1 }", "unknown section [venue]"),
        ("[sensor]\nnoise = { low = 0, high = 1 }", "unknown setting 'noise'"),
        ("[sensor]\noutlier_weight = 0.1", "must be a table"),
        ("[sensor]\noutlier_weight = { low = 0.1 }", "needs low and high"),
        ("[sensor]\noutlier_weight = { low = 0.1, high = 0.01 }", "must be below"),
        ("[sensor]\noutlier_weight = { low = 0.0, high = 0.1, log = true }", "log scale needs low > 0"),
        ("[sensor]\noutlier_weight = { low = 0.01, high = 3.0 }", "refused"),
        ("[sensor]\noutlier_weight = { low = 0.01, high = 0.1, step = 2 }", "unknown key 'step'"),
        ("[sensor]\nmixture = { low = 0, high = 1 }", "choices"),
        ("[sensor]\nmixture = { choices = [] }", "non-empty list"),
        ("[localizer]\nparticles = { low = 10.5, high = 100 }", "must be an integer"),
        ("[sensor]\noutlier_weight = { low = 'a', high = 0.1 }", "finite number"),
        ("", "names no setting"),
        ("[sensor\n", "not TOML"),
    ],
)
def test_a_wrong_space_is_refused_in_one_line(text, words):
    with pytest.raises(SpaceError) as error:
        SearchSpace.from_toml(text, "space.toml")
    assert str(error.value).startswith("space.toml: ") and words in str(error.value)
    assert "\n" not in str(error.value)


# -- objectives ----------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """Two short battery runs written as logs (with truth), and the second without its truth."""
    folder = tmp_path_factory.mktemp("logs")
    paths = []
    for family, seed in (("tracking", 3), ("kidnap", 4)):
        path = folder / f"{family}-{seed}.npz"
        write_log(as_robot_log(simulate(family, seed, 15.0)), path)
        paths.append(str(path))
    log = as_robot_log(simulate("kidnap", 4, 15.0))
    blind = folder / "kidnap-4-no-truth.npz"
    write_log(RobotLog(odometry_times=log.odometry_times, odometry=log.odometry, vision=log.vision), blind)
    return paths + [str(blind)]


def test_a_log_case_gives_evidence_and_truth_figures_and_the_battery_case_agrees_on_kind(logs):
    result = evaluate_case(LogCase(logs[0]), {"sensor.outlier_weight": 0.02}, seed=0, particles=100)
    assert result["evidence_frames"] > 50 and math.isfinite(result["log_evidence"])
    assert 0.0 <= result["truth"]["fail_share"] <= 1.0 and result["truth"]["loss"] >= 0.0
    again = evaluate_case(LogCase(logs[0]), {"sensor.outlier_weight": 0.02}, seed=0, particles=100)
    assert again["log_evidence"] == result["log_evidence"]  # same seed, same result
    battery = evaluate_case(CASES[0], {}, seed=0, particles=100)
    assert battery["truth"]["reconverge_s"] is None and battery["evidence_frames"] > 0


def test_a_log_case_takes_a_field_file(logs, tmp_path):
    from field import save_field, spl

    path = tmp_path / "ours.toml"
    save_field(spl(), str(path))
    from_file = evaluate_case(LogCase(logs[0], str(path)), {}, seed=0, particles=100)
    from_preset = evaluate_case(LogCase(logs[0], "spl"), {}, seed=0, particles=100)
    assert from_file["log_evidence"] == from_preset["log_evidence"]


def test_the_evidence_objective_never_reads_the_truth(logs):
    values = {"sensor.range_noise_floor": 0.08}
    with_truth = evaluate_case(LogCase(logs[1]), values, seed=1, particles=100)
    without = evaluate_case(LogCase(logs[2]), values, seed=1, particles=100)
    assert without["truth"] is None
    assert combine("evidence", [with_truth]) == combine("evidence", [without])
    with pytest.raises(ValueError, match="needs ground truth"):
        combine("truth", [without])


def test_the_truth_loss_is_zero_for_a_perfect_run_and_counts_a_never():
    from mcl.tools.tuning import truth_figures

    times = np.arange(1, 501) * 0.01
    truth = np.zeros((500, 3))
    perfect = truth_figures(times, truth, truth, np.zeros(500, np.int8), np.zeros(500, bool), [(1.0, 1.0)])
    assert perfect["loss"] == 0.0
    off = truth.copy()
    off[200:, 0] = 2.0  # 2 m off after 2 s, never back, flagged SUPERB throughout
    lost = truth_figures(times, truth, off, np.zeros(500, np.int8), np.zeros(500, bool), [(2.5, 2.5)])
    assert lost["never"] and lost["loss"] == pytest.approx(0.6 + 0.0 + 0.25 + 0.6)


# -- the study on a local Ray instance --------------------------------------------------------------------------
@pytest.mark.ray
def test_the_same_seed_gives_the_same_study_and_it_starts_from_the_defaults(local_ray, tmp_path):
    assert local_ray["cpus"] == 2
    first = run_study(settings(), str(tmp_path / "a.journal"))
    second = run_study(settings(), str(tmp_path / "b.journal"))
    assert history(first) == history(second)
    assert first.trials[0]["start"] == "library defaults"
    assert first.trials[0]["values"] == {
        "sensor.outlier_weight": 0.01,
        "sensor.range_noise_floor": 0.05,
        "augmented.fit_threshold": 0.2,
    }
    assert first.best_value == min(t["value"] for t in first.trials)
    assert first.tasks.costs()["tasks"] == 3 * len(CASES)
    other = run_study(settings(seed=1), str(tmp_path / "c.journal"))
    assert history(other)[1:] != history(first)[1:]


@pytest.mark.ray
def test_cma_es_searches_too_and_is_seeded(local_ray):
    first = run_study(settings(trials=4, sampler="cmaes"))
    again = run_study(settings(trials=4, sampler="cmaes"))
    assert history(first) == history(again) and len({h[2] for h in history(first)}) == 4


@pytest.mark.ray
def test_parallel_trials_complete_the_count_and_are_seeded(local_ray):
    first = run_study(settings(trials=5, parallel_trials=2))
    again = run_study(settings(trials=5, parallel_trials=2))
    assert len(first.trials) == 5 and history(first) == history(again)
    assert first.tasks.costs()["tasks"] == 5 * len(CASES)


@pytest.mark.ray
def test_an_interrupted_study_resumes_where_it_stopped(local_ray, tmp_path):
    import optuna

    path = str(tmp_path / "resumed.journal")
    run_study(settings(trials=2), path)
    # a run killed mid-trial leaves a running trial behind
    study = optuna.load_study(
        study_name="robocup-mcl-tune",
        storage=optuna.storages.JournalStorage(optuna.storages.journal.JournalFileBackend(path)),
    )
    study.ask()
    resumed = run_study(settings(trials=4), path)
    straight = run_study(settings(trials=4), str(tmp_path / "straight.journal"))
    assert resumed.resumed == 2
    assert [(v, p) for _, v, p in history(resumed)] == [(v, p) for _, v, p in history(straight)]


@pytest.mark.ray
def test_a_study_file_made_for_other_settings_is_refused(local_ray, tmp_path):
    from mcl.tools.tuning import TuneError

    path = str(tmp_path / "x.journal")
    run_study(settings(trials=1), path)
    with pytest.raises(TuneError, match="other settings"):
        run_study(settings(trials=1, objective="evidence"), path)


@pytest.mark.ray
def test_refused_combinations_are_failed_trials_that_do_not_count(local_ray):
    space = SearchSpace.from_toml(
        "[augmented]\nalpha_slow = { low = 0.001, high = 0.3 }\nalpha_fast = { low = 0.05, high = 0.5 }\n"
    )
    outcome = run_study(settings(trials=6, space=space, cases=CASES[:1]))
    assert len(outcome.trials) == 6
    assert all(t["values"]["augmented.alpha_slow"] < t["values"]["augmented.alpha_fast"] for t in outcome.trials)


# -- the command -------------------------------------------------------------------------------------------------
def run_command(*args, env=None):
    return subprocess.run(
        [sys.executable, "-m", "mcl.tools.cli", "tune", *args],
        capture_output=True,
        text=True,
        env={**os.environ, **(env or {})},
        timeout=600,
    )


@pytest.mark.ray
def test_the_command_tunes_logs_writes_a_profile_that_replay_and_eval_load(logs, tmp_path):
    space = tmp_path / "space.toml"
    space.write_text(SPACE)
    profile, saved, plots = tmp_path / "venue.toml", tmp_path / "tune.json", tmp_path / "plots"
    done = run_command(
        logs[0],
        "--holdout",
        logs[1],
        "--space",
        str(space),
        "--trials",
        "3",
        "--workers",
        "2",
        "--particles",
        "100",
        "--objective",
        "evidence",
        "--out",
        str(profile),
        "--save",
        str(saved),
        "--plots",
        str(plots),
    )
    assert done.returncode == 0, done.stderr
    result = json.loads(saved.read_text())
    assert result["settings"]["objective"] == "evidence" and len(result["trials"]) == 3
    assert set(result["comparison"]) == {"training", "holdout"}
    assert (plots / "convergence.png").stat().st_size > 1000
    assert "profile written to" in done.stdout and "held-out" in done.stdout
    loaded = Profile.load(profile)
    assert loaded.values() == result["best"]["values"]
    replayed = subprocess.run(
        [
            sys.executable,
            "-m",
            "mcl.tools.cli",
            "replay",
            logs[1],
            "--profile",
            str(profile),
            "--particles",
            "100",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert replayed.returncode == 0, replayed.stderr
    evaluated = subprocess.run(
        [
            sys.executable,
            "-m",
            "mcl.tools.cli",
            "eval",
            "--families",
            "tracking",
            "--seeds",
            "1",
            "--duration",
            "10",
            "--particles",
            "100",
            "--jobs",
            "1",
            "--profile",
            str(profile),
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert evaluated.returncode == 0, evaluated.stderr
    assert json.loads(evaluated.stdout)["profile"]["values"] == result["best"]["values"]


@pytest.mark.ray
def test_the_command_tunes_on_the_battery_and_reports_held_out_seeds(tmp_path):
    space = tmp_path / "space.toml"
    space.write_text(SPACE)
    done = run_command(
        "--battery",
        "1",
        "--battery-holdout",
        "1",
        "--families",
        "tracking,fall",
        "--duration",
        "10",
        "--space",
        str(space),
        "--trials",
        "2",
        "--workers",
        "2",
        "--particles",
        "100",
        "--json",
    )
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["settings"]["objective"] == "truth"
    assert result["settings"]["cases"] == ["tracking/0", "fall/0"]
    assert result["settings"]["holdout"] == ["tracking/1000", "fall/1000"]
    assert [row["case"] for row in result["comparison"]["holdout"]["per_case"]] == ["tracking/1000", "fall/1000"]
    assert result["ray"]["cpus"] == 2 and result["ray"]["first_task_s"] is not None


@pytest.mark.ray
def test_the_command_reads_an_mcap_log_by_the_topics_given(logs, tmp_path):
    from mcl.tools.logs import read_log
    from mcl.tools.logs.mcap_io import Topics

    log, _ = read_log(logs[0])
    mcap = tmp_path / "game.mcap"
    write_log(log, mcap, topics=Topics(odometry="/team/odom"))
    space = tmp_path / "space.toml"
    space.write_text(SPACE)
    common = [str(mcap), "--space", str(space), "--trials", "1", "--workers", "1", "--particles", "50"]
    done = run_command(*common, "--topic-odometry", "/team/odom", "--json")
    assert done.returncode == 0, done.stderr
    missing = run_command(*common, "--topic-odometry", "/not/there")
    assert missing.returncode == 1 and "/not/there" in missing.stderr and len(missing.stderr.strip().splitlines()) == 1


@pytest.mark.ray
@pytest.mark.parametrize(
    "case",
    [
        "missing log",
        "bad space",
        "missing space",
        "unreachable",
        "no logs",
        "truth without truth",
        "bad profile out",
        "unknown field",
    ],
)
def test_the_command_fails_in_one_line(case, logs, tmp_path):
    space = tmp_path / "space.toml"
    space.write_text(SPACE)
    bad = tmp_path / "bad.toml"
    bad.write_text("[sensor]\noutlier_weight = { low = 0.1, high = 0.01 }\n")
    args = {
        "missing log": [str(tmp_path / "nope.mcap"), "--space", str(space)],
        "bad space": [logs[0], "--space", str(bad)],
        "missing space": [logs[0], "--space", str(tmp_path / "none.toml")],
        "unreachable": [logs[0], "--space", str(space), "--address", "127.0.0.1:1"],
        "no logs": ["--space", str(space)],
        "truth without truth": [logs[2], "--space", str(space), "--objective", "truth"],
        "bad profile out": [logs[0], "--space", str(space), "--out", str(space / "p.toml")],
        "unknown field": [logs[0], "--space", str(space), "--field", "spll"],
    }[case]
    done = run_command(*args, "--trials", "1")
    assert done.returncode in (1, 2), done.stderr
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert lines and (len(lines) == 1 or done.returncode == 2), done.stderr
    assert "Traceback" not in done.stderr and "internal error" not in done.stderr
    words = {
        "missing log": "nope.mcap",
        "bad space": "must be below",
        "missing space": "none.toml",
        "unreachable": "cannot reach the Ray cluster at 127.0.0.1:1",
        "no logs": "give training LOG",
        "truth without truth": "needs ground truth",
        "bad profile out": "--out",
        "unknown field": "spll",
    }[case]
    assert words in done.stderr


def test_a_local_start_never_joins_another_process_s_ray(monkeypatch):
    """With no address, Ray would join the newest cluster on the machine (another test worker's, another
    study's), refusing the CPU count; the embedded instance is asked for explicitly ("local")."""
    import ray

    from mcl.tools.tuning.search import start_ray

    calls = []
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", lambda **options: calls.append(options))
    monkeypatch.setattr(ray, "cluster_resources", lambda: {"CPU": 2.0})
    monkeypatch.setattr(ray, "nodes", lambda: [{"Alive": True}])
    assert start_ray(workers=2)["cpus"] == 2
    assert calls[0]["address"] == "local" and calls[0]["num_cpus"] == 2
    start_ray("127.0.0.1:6379")
    assert calls[1]["address"] == "127.0.0.1:6379" and "num_cpus" not in calls[1]


def test_a_replays_quality_codes_become_the_evaluations_level_by_level():
    """Every level of a replay, UNSURE_HALF included, is the same level in the evaluation's figures (the truth
    objective counts each level's wrong steps)."""
    from mcl.localizer import Quality
    from mcl.tools.evaluation import QUALITY_CODE
    from mcl.tools.replay import QUALITY_CODES
    from mcl.tools.tuning.objective import evaluation_codes

    levels = list(Quality) * 3
    replayed = np.array([QUALITY_CODES[level] for level in levels], dtype=np.int8)
    np.testing.assert_array_equal(evaluation_codes(replayed), [QUALITY_CODE[level] for level in levels])
    assert evaluation_codes(replayed).dtype == np.int8
