"""The soak command: a short run's table and JSON, determinism, and the verdict on synthetic figures.

The timings themselves are never asserted (they depend on the machine); the runs are fractions of a minute.
"""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from benchmarks.soak import (
    JUDGED_DRIFT_MINUTES,
    MAX_DRIFT_PER_HOUR,
    TABLE_COLUMNS,
    Drift,
    SoakScenario,
    SoakStream,
    judge,
    run_soak,
    step_time_drift,
    theil_sen_slope,
)

ROOT = Path(__file__).resolve().parent.parent
MINUTE_FIELDS = {
    "minute",
    "steps",
    "frames",
    "detections",
    "median_ms",
    "p99_ms",
    "max_ms",
    "rss_mb",
    "growth_mb",
    "nonfinite",
    "error_median_m",
    "error_p95_m",
    "heading_error_median_deg",
    "superb",
    "okay",
    "poor",
    "lost",
}


def soak(*argv, timeout=600):
    return subprocess.run(
        [sys.executable, "-m", "mcl.tools.cli", "soak", *map(str, argv)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.fixture(scope="module")
def half_minute(tmp_path_factory):
    """`robocup-mcl soak --minutes 0.5 --json --save PATH`: the printed and the saved results."""
    path = tmp_path_factory.mktemp("soak") / "soak.json"
    done = soak("--minutes", 0.5, "--seed", 0, "--json", "--save", path)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout), json.loads(path.read_text()), done


def test_json_holds_every_figure_and_no_nan(half_minute):
    printed, saved, done = half_minute
    assert printed == saved
    assert printed["settings"] == {
        "minutes": 0.5,
        "particles": 500,
        "seed": 0,
        "field": "spl",
        "motion_rate_hz": 100,
        "camera_rate_hz": 30,
        "latency_s": 0.04,
        "steps": 3000,
    }
    (row,) = printed["minutes"]  # half a minute: one (partial) row
    assert set(row) == MINUTE_FIELDS
    assert row["minute"] == 1 and row["steps"] == 3000
    assert 880 <= row["frames"] <= 900  # 30 Hz, the last frames arrive 40 ms late
    assert row["superb"] + row["okay"] + row["poor"] == 3000
    assert row["nonfinite"] == 0 and printed["nonfinite"] == 0
    assert row["growth_mb"] == 0.0 and row["rss_mb"] > 0
    assert 0 < row["median_ms"] <= row["p99_ms"] <= row["max_ms"]
    assert row["error_median_m"] < 0.2  # it tracks the simulated robot
    assert printed["drift"] is None  # too short to estimate
    assert printed["verdict"]["ok"] and printed["verdict"]["finite"] and printed["verdict"]["drift"] is None
    assert set(printed["memory"]) == {"rss_first_minute_mb", "rss_end_mb", "growth_mb", "max_growth_mb", "limit_mb"}
    assert len(printed["poses_sha256"]) == 64 and len(printed["final_estimate"]) == 3
    assert all(math.isfinite(v) for v in printed["final_estimate"])
    assert done.stderr.strip().startswith("PASS")  # stdout is pure JSON; the verdict line goes to stderr


def test_same_seed_same_poses_bit_for_bit(half_minute):
    printed, _, _ = half_minute
    again = run_soak(0.5, 500, 0)  # in this process: the same poses as the command's
    assert again["poses_sha256"] == printed["poses_sha256"]
    assert again["final_estimate"] == printed["final_estimate"]
    other = run_soak(0.5, 500, 1)
    assert other["poses_sha256"] != printed["poses_sha256"]


def test_table_has_its_columns_and_a_verdict():
    done = soak("--minutes", 0.25, "--particles", 200, "--seed", 2)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.strip().splitlines()
    header = next(line for line in lines if line.split()[:1] == ["minute"])
    at = 0
    for column in TABLE_COLUMNS:  # every column, in order
        at = header.index(column, at) + len(column)
    row = lines[lines.index(header) + 1].split()
    assert len(row) == len(TABLE_COLUMNS) and row[0] == "1" and row[1] == "1500" and row[7] == "0"
    assert lines[-1].startswith("PASS: NaN 0; memory growth")


def test_bad_options_are_refused_before_running(tmp_path):
    for bad in (["--minutes", "0"], ["--minutes", "nan"], ["--particles", "0"], ["--seed", "-1"]):
        done = soak(*bad, timeout=120)
        assert done.returncode == 2 and "Traceback" not in done.stderr
    done = soak("--minutes", 0.1, "--save", tmp_path / "missing" / "soak.json", timeout=120)
    assert done.returncode == 1
    assert done.stderr.strip().splitlines() == [
        f"robocup-mcl: --save {tmp_path / 'missing' / 'soak.json'}: directory {tmp_path / 'missing'} does not exist"
    ]


def test_the_stream_stays_on_the_field_and_repeats_itself():
    scenario = SoakScenario()
    first, second = SoakStream(scenario, 5, 500), SoakStream(scenario, 5, 500)
    for _ in range(4):
        a, b = first.next_chunk(500), second.next_chunk(500)
        assert np.array_equal(a.truth, b.truth) and np.array_equal(a.odometry, b.odometry)
        assert np.array_equal(a.kinds, b.kinds) and np.array_equal(a.ranges, b.ranges)
        assert np.all(np.abs(a.truth[:, 0]) <= scenario.field.half_length + 0.3)
        assert np.all(np.abs(a.truth[:, 1]) <= scenario.field.half_width + 0.3)
        assert a.offsets[0] == 0 and a.offsets[-1] == a.kinds.shape[0] and np.all(np.diff(a.offsets) >= 0)
        assert np.all(a.ranges >= 0) and np.all(np.abs(a.bearings) <= math.pi)
    assert first.step == 2000


# -- the drift estimator and the verdict, on synthetic figures ------------------------------------------------
def test_theil_sen_finds_the_slope_through_outliers():
    x = np.arange(30.0)
    y = 2.0 + 0.5 * x
    y[[3, 11, 20]] += 40.0  # three wild minutes
    assert theil_sen_slope(x, y) == pytest.approx(0.5)
    assert math.isnan(theil_sen_slope([1.0, 1.0], [2.0, 3.0]))


def noisy(rng, minutes, per_hour, noise=0.05, base=0.03):
    """Per-minute medians [ms]: `base`, rising by `per_hour` (relative) per hour, with relative noise."""
    t = np.arange(1, minutes + 1)
    return base * (1.0 + per_hour * t / 60.0) * (1.0 + noise * rng.standard_normal(minutes))


def test_a_flat_noisy_series_passes_and_a_drifting_one_fails():
    rng = np.random.default_rng(7)
    for _ in range(20):
        flat = noisy(rng, 60, 0.0)
        flat[0] = 5.0  # the first minute (kernels loading) is left out
        flat[[10, 30]] *= 3.0  # two minutes of another process's work
        drift = step_time_drift(flat)
        assert drift.first == 2 and drift.last == 60
        assert abs(drift.relative_per_hour) < MAX_DRIFT_PER_HOUR
        assert judge(0, 0.2, drift).ok
        rising = noisy(rng, 60, 0.3)  # +30 % per hour
        drift = step_time_drift(rising)
        assert drift.relative_per_hour > MAX_DRIFT_PER_HOUR and drift.thirds_change > 0.1
        verdict = judge(0, 0.2, drift)
        assert not verdict.ok and verdict.drift is False and verdict.text.startswith("FAIL")
    falling = noisy(rng, 60, -0.3)  # getting faster is not a drift upward
    assert judge(0, 0.0, step_time_drift(falling)).ok


def test_the_verdict_needs_no_nan_and_bounded_memory():
    flat = Drift(2, 60, 0.0, 0.03, 0.0, 0.03, 0.03, 0.0)
    assert judge(0, 1.0, flat).ok  # the limit itself is allowed
    for nonfinite, growth in ((1, 0.0), (0, 1.5)):
        verdict = judge(nonfinite, growth, flat)
        assert not verdict.ok and verdict.text.startswith("FAIL")
    assert not judge(3, 0.0, flat).finite and "NaN 3 (must be 0)" in judge(3, 0.0, flat).text
    assert not judge(0, 2.0, flat).memory


def test_a_short_run_reports_the_drift_without_judging_it():
    assert step_time_drift([1.0, 1.0, 1.0]) is None  # fewer than 3 minutes after the first
    steep = step_time_drift([0.05, 0.02, 0.03, 0.04, 0.05])
    assert steep.relative_per_hour > 1.0
    verdict = judge(0, 0.0, steep)
    assert verdict.ok and verdict.drift is None and "judged from" in verdict.text
    long_enough = step_time_drift([0.05] + [0.02 * (1 + 0.01 * m) for m in range(JUDGED_DRIFT_MINUTES)])
    assert judge(0, 0.0, long_enough).drift is False
