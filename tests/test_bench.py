"""The benchmark suite's structure: its JSON, its sections, the machine description, the targets, a missing peer.

No timing is checked here (speed is the benchmark's business, not the tests'): the runs use tiny sizes and a
tiny sampling budget.
"""

import contextlib
import io
import json
import math
import sys

import numpy as np
import pytest

from benchmarks import bench
from benchmarks import step as bench_step
from benchmarks.report import evaluate_targets, format_report
from mcl.tools.cli import main as cli_main

TINY = ["--quick", "--sizes", "40,120", "--budget", "0.002"]


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """One --quick run of every section at tiny sizes, saved to a file (and plotted when matplotlib is there)."""
    folder = tmp_path_factory.mktemp("bench")
    argv = ["bench", *TINY, "--json", "--save", str(folder / "bench.json")]
    plotting = _importable("matplotlib")
    if plotting:
        argv += ["--plot", str(folder / "bench.png")]
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        code = cli_main(argv)
    return {
        "code": code,
        "printed": json.loads(stdout.getvalue()),
        "folder": folder,
        "plotting": plotting,
        "saved": json.loads((folder / "bench.json").read_text()),
    }


def _importable(name: str) -> bool:
    try:
        __import__(name)
    except ImportError:
        return False
    return True


def test_quick_run_writes_every_section(quick_run):
    assert quick_run["code"] == 0
    result = quick_run["printed"]
    assert result == quick_run["saved"]
    for key in (
        "benchmark",
        "schema",
        "machine",
        "settings",
        "phases",
        "rows",
        "resampling",
        "threads",
        "memory",
        "numpy_without_avx512",
        "startup",
        "demo_walk",
        "models",
        "between_frames",
        "bearing_accuracy",
        "targets",
        "duration_s",
    ):
        assert key in result, key
    for key in (
        "resampling",
        "threads",
        "memory",
        "numpy_without_avx512",
        "startup",
        "demo_walk",
        "models",
        "between_frames",
        "bearing_accuracy",
    ):
        assert "error" not in result[key], (key, result[key].get("traceback"))
    assert result["settings"]["quick"] is True and result["settings"]["sizes"] == [40, 120]


def test_rows_hold_the_full_step_and_every_phase(quick_run):
    rows = quick_run["printed"]["rows"]
    assert [row["n"] for row in rows] == [40, 120]
    for row in rows:
        assert row["speedup"] > 0 and row["ns_per_particle"] > 0
        assert row["full_step"]["numpy_s"] > 0 and row["full_step_exact_bearing"]["numba_s"] > 0
        assert row["injecting_step"]["numba_s"] > 0
        # The interleaved items: one call per sample, each after calls of the others; back to back: many.
        assert row["full_step"]["numba_calls_per_sample"] == row["full_step"]["numpy_calls_per_sample"] == 1
        assert row["issue_step"]["numba_calls_per_sample"] == 1
        assert row["full_step_back_to_back"]["numba_calls_per_sample"] > 1
        assert set(row["phases"]) == set(bench_step.PHASE_NAMES)
        for phase in bench_step.PHASES:
            entry = row["phases"][phase.name]
            assert entry["numba_ns_per_particle"] > 0 and entry["numba_calls_per_sample"] == 1
            assert (entry["numpy_s"] is None) == (phase.numpy_entry is None)
            if entry["numpy_s"] is not None:
                assert entry["speedup"] == pytest.approx(entry["numpy_s"] / entry["numba_s"])


def test_machine_description(quick_run):
    machine = quick_run["printed"]["machine"]
    for key in (
        "cpu_model",
        "cpus",
        "simd_flags",
        "python",
        "numpy",
        "numba",
        "load_average",
        "load_average_end",
        "numpy_cpu_dispatch",
    ):
        assert key in machine, key
    assert machine["cpus"] >= 1 and machine["cpu_model"]
    if machine["simd_flags"] is not None:
        assert {"avx2", "avx512f"} <= set(machine["simd_flags"])
    assert {"numba_cpu_name", "numba_cpu_features"} <= set(machine)
    import numba

    assert machine["numba_svml"] is bool(numba.config.USING_SVML)
    assert machine["llvmlite_svml"] in (True, False, None)


def test_the_header_names_a_foreign_compile_target():
    """Timed with NUMBA_CPU_NAME / NUMBA_CPU_FEATURES (a robot's instruction set on this machine), the report
    says the kernels were not compiled for this CPU; without them it says nothing of the kind."""
    machine = {"cpu_model": "x", "cpus": 1, "python": "3", "numpy": "2", "numba": "0"}
    base = {"settings": {"quick": True}, "targets": []}
    text = format_report(
        {**base, "machine": {**machine, "numba_cpu_name": "silvermont", "numba_cpu_features": "-avx,-fma"}}
    )
    assert "kernels compiled for silvermont (-avx,-fma), not this CPU" in text.splitlines()[0]
    assert "compiled for" not in format_report(
        {**base, "machine": {**machine, "numba_cpu_name": None, "numba_cpu_features": None}}
    )


def test_the_header_says_whether_numba_uses_svml():
    machine = {
        "cpu_model": "x",
        "cpus": 1,
        "python": "3",
        "numpy": "2",
        "numba": "0",
        "simd_flags": {"avx2": True, "avx512f": False},
    }
    base = {"settings": {"quick": True}, "targets": []}
    assert "(avx2 yes, avx512f no; SVML no)" in format_report({**base, "machine": {**machine, "numba_svml": False}})
    assert "; SVML yes)" in format_report({**base, "machine": {**machine, "numba_svml": True}})
    assert "SVML" not in format_report({**base, "machine": machine})  # a result saved before it was recorded


def test_resampling_section_names_ours_and_the_peers(quick_run):
    section = quick_run["printed"]["resampling"]
    assert "mcl.resampling.systematic" in section["ours"]
    for label in (
        "filterpy.monte_carlo.systematic_resample",
        "particles.resampling.systematic",
        "mcl.resampling.systematic_reference",
    ):
        assert label in section["entries"]
    for row in section["rows"]:
        assert row["best_ours_ns_per_particle"] > 0
        for label, status in section["entries"].items():
            if status["available"]:
                assert row["ns_per_particle"][label] is not None or label in row["problems"]
        assert row["problems"] == {}


def test_memory_startup_models_sections(quick_run):
    result = quick_run["printed"]
    memory = result["memory"]
    assert [row["n"] for row in memory["rows"]] == list(bench.MEMORY_SIZES)
    assert isinstance(memory["grows_with_n"], bool) and isinstance(memory["retains_memory"], bool)
    assert result["startup"]["warm_cache_s"] > 0 and result["startup"]["cold_cache_s"] is None  # --quick
    assert result["demo_walk"]["wall_s"] > 0
    models = result["models"]
    assert models["lwpr"]["inputs"] == 2 and models["lwpr"]["update_us"] > 0
    assert {"default", "paper"} == set(models["ekf"])
    loop = models["robot_loop"]
    assert loop["particles"] == 500
    for key in (
        "frame_us",
        "predict_us",
        "correct_list_us",
        "from_list_us",
        "from_arrays_us",
        "localizer_frame_us",
        "localizer_observe_us",
    ):
        assert math.isfinite(loop[key]) and loop[key] > 0, key
    threads = result["threads"]
    assert threads["available"] in (True, False)
    if not threads["available"]:
        assert "not available" in threads["note"]
    avx = result["numpy_without_avx512"]
    assert "NPY_DISABLE_CPU_FEATURES" in avx and "cpu_has_avx512" in avx


def test_between_frames_times_both_steps_at_each_small_n(quick_run):
    frames = quick_run["printed"]["between_frames"]
    assert frames["idle_s"] == 0.01 and frames["samples"] == 10  # --quick
    assert [row["n"] for row in frames["rows"]] == [40, 120]
    for row in frames["rows"]:
        for key in ("full_step_us", "issue_step_us"):
            assert math.isfinite(row[key]) and row[key] > 0, key
    for value in (frames["python_call_us"], frames["numba_call_us"], *frames["back_to_back_us"].values()):
        assert math.isfinite(value) and value > 0
    assert "between frames (one call after 10 ms asleep" in format_report(quick_run["printed"])


def test_between_frames_sleeps_before_every_timed_call(monkeypatch):
    from benchmarks import models as bench_models

    events = []
    monkeypatch.setattr(bench_models.time, "sleep", lambda seconds: events.append(("sleep", seconds)))
    monkeypatch.setattr(bench_models, "full_step_work", lambda n: lambda: events.append(("full", n)))
    monkeypatch.setattr(bench_models, "issue_step_work", lambda n: lambda: events.append(("issue", n)))
    monkeypatch.setattr(bench_models, "_nothing", lambda: events.append(("python", 0)))
    monkeypatch.setattr(bench_models, "_first", lambda values: events.append(("numba", 0)))
    monkeypatch.setattr(bench_models, "measure", lambda work, **options: {name: {"s": 1e-7} for name in work})
    result = bench_models.time_between_frames([5000, 100, 1000, 100], samples=3, idle_s=0.5)
    assert [row["n"] for row in result["rows"]] == [100, 1000]  # N > 1 000 left out, each N once
    items = [("python", 0), ("numba", 0), ("full", 100), ("issue", 100), ("full", 1000), ("issue", 1000)]
    expected = [item for item in items for _ in range(2)]  # warm-up, untimed
    for _ in range(3):  # each timed call after a sleep
        expected += [event for item in items for event in (("sleep", 0.5), item)]
    assert events == expected
    assert result["back_to_back_us"] == pytest.approx({"python_call": 0.1, "numba_call": 0.1})


def test_targets_are_all_reported(quick_run):
    result = quick_run["printed"]
    targets = result["targets"]
    assert len(targets) >= 15
    for target in targets:
        assert target["met"] in (True, False, None)
        assert target["met"] is None or target["value"] is not None
    text = format_report(result)
    for target in targets:
        assert target["target"] in text
    assert text.count("NOT MET") == sum(t["met"] is False for t in targets)


def test_plot_is_written(quick_run):
    if not quick_run["plotting"]:
        pytest.skip("matplotlib is not installed (pip install -e '.[bench]')")
    png = (quick_run["folder"] / "bench.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_a_missing_peer_is_reported_as_not_installed(monkeypatch):
    monkeypatch.setattr(
        bench_step, "PEERS", bench_step.PEERS + (("nonexistent", "no_such_resampling_lib", "systematic"),)
    )
    monkeypatch.setitem(sys.modules, "filterpy", None)  # as if filterpy were not installed
    monkeypatch.setitem(sys.modules, "filterpy.monte_carlo", None)
    section = bench_step.time_resamplers([50], budget_s=0.001)
    for label in ("no_such_resampling_lib.systematic", "filterpy.monte_carlo.systematic_resample"):
        assert section["entries"][label] == {
            "package": section["entries"][label]["package"],
            "available": False,
            "note": "not installed",
            "version": None,
        }
        assert section["rows"][0]["ns_per_particle"][label] is None
    assert section["rows"][0]["ns_per_particle"]["mcl.resampling.systematic"] > 0
    text = format_report(
        {
            "machine": {"cpu_model": "x", "cpus": 1, "python": "3", "numpy": "2", "numba": "0"},
            "settings": {"quick": True},
            "resampling": section,
            "targets": [],
        }
    )
    assert "no_such_resampling_lib.systematic" in text and "not installed" in text


def test_targets_judge_the_figures():
    def row(n, seconds, speedup):
        phases = {"predict_adaptive": {"numba_s": 1.2}, "predict_velocity_linear": {"numba_s": 1.0}}
        return {
            "n": n,
            "ns_per_particle": 1e9 * seconds / n,
            "speedup": speedup,
            "full_step": {"numba_s": seconds},
            "phases": phases,
            "full_step_back_to_back": {"numba_s": 0.8 * seconds},
            "full_step_fast": {"numba_ns_per_particle": 0.6e9 * seconds / n},
            "issue_step": {"numba_s": 0.45 * seconds, "numba_ns_per_particle": 0.45e9 * seconds / n},
            "issue_step_fast": {"numba_ns_per_particle": 0.3e9 * seconds / n},
        }

    result = {
        "rows": [row(100, 10e-6, 25.0), row(1000, 0.2e-3, 10.0), row(10_000, 0.5e-3, 6.0)],
        "threads": {"available": False, "note": "not available: no threads option", "rows": []},
        "models": {
            "lwpr": {"update_us": 12.0, "predict_us": 2.0},
            "ekf": {"default": {"predict_us": 5.0, "correct_us": 30.0}},
        },
        "demo_walk": {"wall_s": 2.0},
    }
    verdicts = {t["id"]: t["met"] for t in evaluate_targets(result)}
    assert verdicts["full_step_ns_per_particle"] is True  # 50 ns at 10 000
    assert verdicts["full_step_ns_per_particle_aim"] is True  # 30 ns with fast=True
    assert verdicts["issue_step_ns_per_particle"] is True and verdicts["issue_step_ns_per_particle_aim"] is True
    notes = {t["id"]: t["note"] for t in evaluate_targets(result)}
    assert notes["full_step_1000"] == "back to back 0.16 ms"
    assert verdicts["full_step_1000"] is False and verdicts["full_step_100"] is True
    assert verdicts["issue_step_1000"] is True and verdicts["issue_step_100"] is True  # 0.09 ms, 4.5 µs
    assert {t["id"]: t["value"] for t in evaluate_targets(result)}["issue_step_1000"] == pytest.approx(0.09)
    without = {t["id"]: t for t in evaluate_targets({**result, "rows": result["rows"][2:]})}
    assert without["issue_step_100"]["met"] is None and "not among the sizes" in without["issue_step_100"]["note"]
    assert verdicts["speedup_10000"] is True and verdicts["speedup_100"] is True
    assert verdicts["two_threads"] is None and verdicts["resampling_1e6"] is None
    assert verdicts["steady_state_allocation"] is None and verdicts["demo_walk_cached"] is True
    assert verdicts["adaptive_vs_velocity_linear"] is True
    assert verdicts["lwpr_update"] is False and verdicts["lwpr_predict"] is True
    assert verdicts["ekf_predict"] is True and verdicts["ekf_correct"] is False


def test_measure_interleaves_and_counts_samples():
    calls = []
    timed = bench_step.measure(
        {"a": lambda: calls.append("a"), "b": lambda: calls.append("b")}, budget_s=0.0, min_samples=4, sample_s=0.0
    )
    assert {name: t["samples"] for name, t in timed.items()} == {"a": 4, "b": 4}
    assert calls[4:] == ["a", "b"] * 4  # after two warm-up calls each: A, B, A, B, ...


@pytest.mark.parametrize("argv", [["--sizes", "ten"], ["--sizes", "0"], ["--skip", "everything"], ["--budget", "0"]])
def test_bad_options_are_refused(argv):
    with pytest.raises(SystemExit):
        bench.main(argv)


def test_the_injecting_step_injects_every_step():
    """The `inject` column's filter replaces 5 % of N at every step (the cap once the heading is trusted)."""
    pf, u, observations = bench_step.injecting_setup(200)
    for _ in range(3):
        pf.step(u, observations)
        assert pf.injected == 10 and pf.resampled


def test_the_adaptive_step_resamples_in_the_compiled_step(monkeypatch):
    """The `adaptive` column's filter keeps a per-particle state and resamples every step without the Python
    fallback `_resample`."""
    from mcl.filter import ParticleFilter

    pf, u, observations = bench_step.adaptive_setup(200)
    monkeypatch.setattr(ParticleFilter, "_resample", lambda *args, **kwargs: pytest.fail("Python resampling"))
    for _ in range(3):
        pf.step(u, observations)
        assert pf.resampled and pf.motion_state.shape == (200, 4)


def test_adaptive_phase_starts_from_its_stationary_mix():
    # The collision phase is timed from the stationary mix of its transitions, so its cost does not drift
    # with the number of calls: one more transition leaves the shares of the five states where they were.
    from benchmarks.step import COLLISION, stationary_mobility
    from motion_models import AdaptiveMotion, MotionInput

    model = AdaptiveMotion()
    u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1), collision=COLLISION)
    state = stationary_mobility(model, u, 200_000, np.random.default_rng(3))
    shares = np.bincount(state[:, 0].astype(int), minlength=5) / state.shape[0]
    after = shares @ model.transitions.matrix(model.condition(COLLISION), u.dt)
    np.testing.assert_allclose(after, shares, atol=0.01)
    assert shares[0] < 0.5  # not the all-free start
    assert ((state[:, 1:] >= 0) & (state[:, 1:] < 1)).all()


def test_adaptive_ratio_takes_the_slower_scenario():
    from benchmarks.report import adaptive_ratios

    phases = {
        "predict_adaptive": {"numba_s": 1.2},
        "predict_adaptive_quiet": {"numba_s": 1.6},
        "predict_velocity_linear": {"numba_s": 1.0},
    }
    assert adaptive_ratios({"rows": [{"n": 10, "phases": phases}]}) == [(10, 1.6)]
