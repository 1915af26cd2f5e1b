"""End to end: the walk scenario through the filter, the recording read back, the command line."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest
import rerun.chunk as rrc

from demos.walk import aggregate, parse_seeds, run_walk
from demos.walk import main as walk_main
from demos.walk_sim import WalkScenario, simulate
from mcl.tools.cli import main as cli_main

SHORT = replace(WalkScenario(), duration=14.0, kidnap_time=7.0)


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("rrd") / "walk.rrd"
    return run_walk("velocity-linear", 500, seed=0, rrd=str(path), scenario=SHORT, series=True), path


def test_walk_tracks_converges_and_recovers(short_run):
    """A 14 s run with a kidnapping at 7 s. The README's figures (60 s, ten seeds, RMSE <= 0.10 m and 3°)
    come from `robocup-mcl demo walk --seeds 0-9`; a short run is mostly transients, hence the margin."""
    result, _ = short_run
    assert result["converged_s"] is not None and result["converged_s"] <= 5.0
    assert result["reconverged_s"] is not None and result["reconverged_s"] <= 5.0
    assert result["position_rmse_m"] <= 0.15
    assert result["heading_rmse_deg"] <= 4.0
    assert result["mirror_share"] == 0.0


def scalar_series(path, entity):
    """(step, value) pairs of a Scalars entity, read back from the .rrd file."""
    steps, values = [], []
    for chunk in rrc.RrdReader(str(path)).stream():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        steps.extend(batch.column(names.index("step")).to_pylist())
        column = next(n for n in names if n.endswith(":scalars"))
        values.extend(v[0] for v in batch.column(names.index(column)).to_pylist())
    order = np.argsort(steps)
    return np.asarray(steps)[order], np.asarray(values, dtype=np.float64)[order]


def test_recording_holds_the_entropy_the_filter_computed(short_run):
    result, path = short_run
    entropy = result["series"]["entropy"]
    for entity, column in (("/entropy/position", 0), ("/entropy/orientation", 1)):
        steps, values = scalar_series(path, entity)
        assert np.array_equal(steps, np.arange(entropy.shape[0]))
        assert np.array_equal(values, entropy[:, column])


def test_recording_has_the_scene(short_run):
    _, path = short_run
    entities = {chunk.entity_path for chunk in rrc.RrdReader(str(path)).stream()}
    for expected in (
        "/field/lines",
        "/field/center_circle",
        "/field/landmarks/goalpost",
        "/particles",
        "/robot/estimate",
        "/robot/truth",
        "/observations",
        "/error/position",
    ):
        assert expected in entities
    assert rrc.RrdReader(str(path)).blueprints(), "the file carries its blueprint"


def test_simulation_is_deterministic_and_sane():
    a, b = simulate(SHORT, 3), simulate(SHORT, 3)
    assert np.array_equal(a.truth, b.truth) and len(a.frames) == len(b.frames)
    assert len(a.frames) == pytest.approx(SHORT.duration * SHORT.camera_rate, abs=2)
    jump = np.hypot(*(a.truth[a.kidnap_step, :2] - a.truth[a.kidnap_step - 1, :2]))
    assert jump == pytest.approx(SHORT.kidnap_distance, abs=0.05)
    assert (np.abs(a.truth[:, 0]) < 4.5).all() and (np.abs(a.truth[:, 1]) < 3.0).all()


def test_walk_command_json(capsys):
    assert walk_main(["--duration", "3", "--particles", "200", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["particles"] == 200 and out["steps"] == 300 and math.isfinite(out["ms_per_step"])


def test_walk_command_several_seeds(capsys):
    assert cli_main(["demo", "walk", "--duration", "2", "--seeds", "0-1", "--particles", "100"]) == 0
    assert "median" in capsys.readouterr().out


def test_cli_rejects_unknowns(capsys):
    assert cli_main(["demo", "dance"]) == 2
    assert cli_main(["frobnicate"]) == 2
    with pytest.raises(SystemExit):
        walk_main(["--particles", "0"])


def test_bench_json(capsys):
    # the command's sizes and flags; the sections themselves are tests/test_bench.py's
    skip = "peers,threads,memory,avx512,models,frames,recording,accuracy"
    argv = ["bench", "--sizes", "50,200", "--no-startup", "--no-exact", "--budget", "0.01", "--skip", skip, "--json"]
    assert cli_main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert [row["n"] for row in out["rows"]] == [50, 200]
    assert all(row["speedup"] > 0 for row in out["rows"])


def test_seed_parsing_and_aggregate():
    assert parse_seeds("0-3") == [0, 1, 2, 3] and parse_seeds("5") == [5] and parse_seeds("1,4") == [1, 4]
    runs = [
        {
            "seed": s,
            "position_rmse_m": v,
            "heading_rmse_deg": 1.0,
            "converged_s": c,
            "reconverged_s": 1.0,
            "mirror_share": 0.0,
            "ms_per_step": 0.1,
        }
        for s, v, c in ((0, 0.05, 1.0), (1, 0.07, None), (2, 0.06, 2.0))
    ]
    summary = aggregate(runs)
    assert summary["position_rmse_m"]["median"] == 0.06 and summary["position_rmse_m"]["worst_seed"] == 1
    assert summary["converged_s"]["worst"] is None and summary["converged_s"]["failed_seeds"] == 1


def test_walk_with_lines_runs(capsys):
    assert walk_main(["--duration", "3", "--particles", "200", "--lines", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["lines"] is True


def test_bench_reports_the_accuracy_cost_of_the_fast_bearing_term():
    from benchmarks.bench import bearing_accuracy

    accuracy = bearing_accuracy(n=500)
    assert 0.0 <= accuracy["total_variation"] < 0.01
