"""The soak run: one simulated hour of a robot's loop through `mcl.localizer.Localizer`, watched minute by minute.

    robocup-mcl soak [--minutes 60] [--particles 500] [--seed 0] [--json] [--save PATH]

What runs. A robot walks a smooth random path on the SPL field (`SoakScenario`, the walking simulator's
`demos.walk_sim.StreamScenario`: the same robot and camera as the walk demo's): it starts on one of its own
touchlines facing into the field (the localizer starts with `initial_placement()`), then turns toward random
waypoints and walks to them, slowing in turns. Every 10 ms (100 Hz) the loop calls `motion(t, u)` with the
walking engine's odometry (the true pose change with a per-run scale error and step-to-step noise, in the
robot frame). At 30 Hz a camera on a head panning ±45° sees the landmarks (goalposts, L/T/X crossings, penalty
and centre marks) within its 60° field of view and 0.3–6 m, with a detection probability falling with range,
range noise growing with the square of the range, bearing noise, and a few false detections of random type.
Each frame arrives 40 ms after its capture and is passed to `observe(observations, capture_time=)`. After
every step the loop reads `pose()`, `quality()` and `is_lost`, as a team's behaviour does. No kidnapping, no
falls: the run measures the localizer's health over time, not its recovery.

The scenario is generated 5 s at a time (`BLOCK_STEPS`) into buffers allocated once (the motion steps in a loop,
the camera frames vectorized), so an hour never sits in memory, and the generator's arrays stay small enough
that the allocator reuses their memory instead of keeping ever larger blocks (which would show up as RSS
growth that is not the localizer's). The measurement's buffers (a minute of step times, estimates and truth,
and the per-minute table) are allocated once as well.

What is measured, per simulated minute:
- steps and camera frames;
- step time: the wall time of one step's calls into the `Localizer` (`motion`, `observe` when a frame
  arrives, `pose`, `quality`, `is_lost`; building the inputs is not counted), median and 99th percentile [ms];
- RSS: the process's resident memory at the end of the minute (`/proc/self/statm`, after `gc.collect()`: a
  leak survives a collection, uncollected garbage is not one) [MB = 2^20 bytes], and its growth since the end
  of the first minute (the first minute loads the compiled kernels and fills the caches);
- NaN: non-finite values in the estimate (pose and covariance, checked after every step) plus, at the end of
  the minute, in the particles (`loc.filter.poses`) and their weights;
- error: the median distance between the estimate and the simulated truth over the minute's steps [m].

The verdict (exit status 0 when it holds, 1 otherwise):
- no NaN anywhere;
- memory: the RSS at the end of the run at most `MAX_GROWTH_MB` (1 MB) above the RSS at the end of the first
  minute;
- step time without upward drift: the Theil–Sen slope (the median of the slopes between every pair of
  minutes) of the per-minute median step time over minutes 2..N, as a relative change per hour (slope in ms
  per minute × 60, divided by the median of those per-minute medians), below `MAX_DRIFT_PER_HOUR` (10 %).
  The first minute is left out (loading kernels, warming caches). Theil–Sen ignores up to 29 % of outlying
  minutes (another process's burst of work), but not a lasting change of the machine's load during the run.
  The slope is estimated from `MIN_DRIFT_MINUTES` (3) minutes after the first on, but judged only from
  `JUDGED_DRIFT_MINUTES` (10) on (N >= 11): over a few minutes, the minute-to-minute noise of a shared machine
  (5 % between two minutes is common) extrapolates to tens of percent per hour. A shorter run reports the
  drift without judging it, and the verdict rests on the other two tests. As a second view, the run also gives
  the change from the median of the first third of those minutes to that of the last third.

Determinism: the same seed gives the same truth, the same detections and the same estimates bit for bit (the
run's `poses_sha256` digests every step's estimate and the final particles); only the timings differ.
"""

from __future__ import annotations

import argparse
import gc
import hashlib
import json
import math
import os
import sys
import time
from collections import deque
from dataclasses import asdict, dataclass

import numpy as np

from demos.walk_sim import StreamScenario, WalkStream
from field.angles import wrap_angles
from motion_models import MotionInput
from sensing.observations import Observations

MAX_GROWTH_MB = 1.0  # MB (2^20 bytes) of RSS growth after the first minute the verdict allows
MAX_DRIFT_PER_HOUR = 0.10  # relative upward drift of the median step time per hour the verdict allows
MIN_DRIFT_MINUTES = 3  # minutes after the first needed to estimate the drift ...
JUDGED_DRIFT_MINUTES = 10  # ... and to judge it (fewer minutes extrapolate noise to an hour)
MB = float(2**20)
BLOCK_STEPS = 500  # motion steps generated at a time (5 s: the generator's arrays stay small)
TABLE_COLUMNS = ("minute", "steps", "frames", "median ms", "p99 ms", "RSS MB", "growth MB", "NaN", "error m")


# The scenario and its stream are the walking simulator's (demos.walk_sim), under the soak's names.
SoakScenario = StreamScenario
SoakStream = WalkStream


# -- the verdict's figures ---------------------------------------------------------------------------------
def theil_sen_slope(x, y) -> float:
    """The Theil–Sen estimator: the median of the slopes (y_j - y_i) / (x_j - x_i) over all pairs i < j with
    x_i != x_j (NaN for fewer than two distinct x)."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    i, j = np.triu_indices(x.shape[0], k=1)
    dx = x[j] - x[i]
    keep = dx != 0
    if not keep.any():
        return math.nan
    return float(np.median((y[j] - y[i])[keep] / dx[keep]))


@dataclass(frozen=True)
class Drift:
    """Upward drift of the per-minute median step time over minutes `first`..`last` (1-based)."""

    first: int
    last: int
    slope_ms_per_minute: float  # Theil–Sen
    baseline_ms: float  # the median of the per-minute medians used
    relative_per_hour: float  # slope × 60 / baseline
    first_third_ms: float  # the median of the first third of those minutes' medians ...
    last_third_ms: float  # ... and of the last third
    thirds_change: float  # last_third / first_third - 1


def step_time_drift(minute_medians_ms, skip: int = 1) -> Drift | None:
    """The drift of the per-minute median step times, leaving out the first `skip` minutes; None when fewer
    than `MIN_DRIFT_MINUTES` minutes remain (see the module docstring)."""
    medians = np.asarray(minute_medians_ms, dtype=np.float64)
    y = medians[skip:]
    if y.shape[0] < MIN_DRIFT_MINUTES:
        return None
    minutes = np.arange(skip + 1, medians.shape[0] + 1, dtype=np.float64)
    slope = theil_sen_slope(minutes, y)
    baseline = float(np.median(y))
    third = max(1, y.shape[0] // 3)
    first_third, last_third = float(np.median(y[:third])), float(np.median(y[-third:]))
    return Drift(
        skip + 1,
        int(medians.shape[0]),
        slope,
        baseline,
        60.0 * slope / baseline if baseline > 0 else math.inf,
        first_third,
        last_third,
        last_third / first_third - 1.0 if first_third > 0 else math.inf,
    )


@dataclass(frozen=True)
class Verdict:
    ok: bool
    finite: bool
    memory: bool
    drift: bool | None  # None: not judged (too short a run)
    text: str


def judge(
    nonfinite: int,
    growth_mb: float,
    drift: Drift | None,
    max_growth_mb: float = MAX_GROWTH_MB,
    max_drift: float = MAX_DRIFT_PER_HOUR,
    judged_minutes: int = JUDGED_DRIFT_MINUTES,
) -> Verdict:
    """The soak verdict from the NaN count, the RSS growth after the first minute and the step-time drift (judged
    when it spans at least `judged_minutes` minutes; see the module docstring)."""
    finite = nonfinite == 0
    memory = bool(growth_mb <= max_growth_mb)
    judged = drift is not None and drift.last - drift.first + 1 >= judged_minutes
    drifting = bool(drift.relative_per_hour < max_drift) if judged else None
    ok = finite and memory and drifting is not False
    if drift is None:
        drift_text = f"step time drift not measured (needs {MIN_DRIFT_MINUTES + 1} minutes or more)"
    else:
        drift_text = (
            f"step time drift {100 * drift.relative_per_hour:+.1f} %/h over minutes "
            f"{drift.first}-{drift.last} (limit {100 * max_drift:g} %/h"
            + (")" if judged else f", judged from {judged_minutes + 1} minutes on)")
        )
    parts = [
        f"NaN {nonfinite}" + ("" if finite else " (must be 0)"),
        f"memory growth {growth_mb:+.2f} MB after the first minute (limit {max_growth_mb:g} MB)",
        drift_text,
    ]
    return Verdict(ok, finite, memory, drifting, ("PASS: " if ok else "FAIL: ") + "; ".join(parts))


# -- the run -----------------------------------------------------------------------------------------------
def rss_bytes() -> int:
    """The process's resident set size now (Linux /proc/self/statm; elsewhere the peak from getrusage)."""
    try:
        with open("/proc/self/statm") as statm:
            return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        import resource

        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return int(peak) * (1 if sys.platform == "darwin" else 1024)


def run_soak(
    minutes: float = 60.0, particles: int = 500, seed: int = 0, scenario: SoakScenario | None = None, on_minute=None
) -> dict:
    """Run the soak (see the module docstring); returns the results as JSON-ready data. `on_minute(row)` is
    called with each minute's row as it ends."""
    from mcl.localizer import Localizer

    if not (isinstance(minutes, (int, float)) and math.isfinite(minutes) and minutes > 0):
        raise ValueError(f"minutes = {minutes!r} must be finite and > 0")
    if particles <= 0:
        raise ValueError(f"particles = {particles!r} must be > 0")
    s = SoakScenario() if scenario is None else scenario
    per_minute = int(round(60 * s.motion_rate))
    total = int(round(minutes * per_minute))
    if total < 1:
        raise ValueError(f"minutes = {minutes!r} is shorter than one motion step")
    n_minutes = -(-total // per_minute)
    started = time.perf_counter()
    stream = SoakStream(s, seed, BLOCK_STEPS)
    loc = Localizer(s.field, n_particles=particles, seed=seed)
    loc.initial_placement()
    # Buffers for the measurement, allocated once.
    step_ns = np.empty(per_minute, dtype=np.int64)
    estimates = np.empty((per_minute, 3))
    truth = np.empty((per_minute, 3))
    rows = {
        name: np.zeros(n_minutes)
        for name in (
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
        )
    }
    digest = hashlib.sha256()
    pending: deque = deque()
    quality_index = {"superb": 0, "okay": 1, "poor": 2}
    quality_counts = [0, 0, 0]
    dt = s.dt
    latency = s.latency_steps
    nonfinite_total = 0
    rss_first = 0
    for minute in range(n_minutes):
        n = min(per_minute, total - minute * per_minute)
        nonfinite = frames = detections = lost = 0
        quality_counts[:] = (0, 0, 0)
        for block_start in range(0, n, BLOCK_STEPS):
            chunk = stream.next_chunk(min(BLOCK_STEPS, n - block_start))
            truth[block_start : block_start + chunk.truth.shape[0]] = chunk.truth
            for f in range(chunk.capture_steps.shape[0]):
                a, b = chunk.offsets[f], chunk.offsets[f + 1]
                capture = int(chunk.capture_steps[f])
                pending.append(
                    (capture + latency, (capture + 1) * dt, chunk.kinds[a:b], chunk.ranges[a:b], chunk.bearings[a:b])
                )
            odometry = chunk.odometry.tolist()
            for j in range(chunk.truth.shape[0]):
                g = chunk.first_step + j
                k = block_start + j
                u = MotionInput(dt=dt, odometry=tuple(odometry[j]))
                observations = capture_time = None
                if pending and pending[0][0] <= g:
                    _, capture_time, kinds, ranges, bearings = pending.popleft()
                    observations = Observations.from_arrays(kinds, ranges, bearings)
                    frames += 1
                    detections += len(observations)
                t0 = time.perf_counter_ns()
                loc.motion((g + 1) * dt, u)
                if observations is not None:
                    loc.observe(observations, capture_time=capture_time)
                estimate = loc.pose()
                quality = loc.quality()
                is_lost = loc.is_lost
                step_ns[k] = time.perf_counter_ns() - t0
                pose = estimate.pose
                estimates[k] = pose
                if not (
                    math.isfinite(pose[0])
                    and math.isfinite(pose[1])
                    and math.isfinite(pose[2])
                    and np.isfinite(estimate.covariance).all()
                ):
                    nonfinite += 1
                quality_counts[quality_index[quality.value]] += 1
                lost += is_lost
        nonfinite += int(np.count_nonzero(~np.isfinite(loc.filter.poses)))
        nonfinite += int(np.count_nonzero(~np.isfinite(loc.filter.weights)))
        nonfinite_total += nonfinite
        digest.update(estimates[:n])  # (the buffer itself: no copy)
        times_ms = step_ns[:n] * 1e-6
        error = np.hypot(estimates[:n, 0] - truth[:n, 0], estimates[:n, 1] - truth[:n, 1])
        heading = np.abs(wrap_angles(estimates[:n, 2] - truth[:n, 2]))
        gc.collect()
        rss = rss_bytes()
        if minute == 0:
            rss_first = rss
        values = {
            "steps": n,
            "frames": frames,
            "detections": detections,
            "median_ms": float(np.median(times_ms)),
            "p99_ms": float(np.percentile(times_ms, 99)),
            "max_ms": float(times_ms.max()),
            "rss_mb": rss / MB,
            "growth_mb": (rss - rss_first) / MB,
            "nonfinite": nonfinite,
            "error_median_m": float(np.median(error)),
            "error_p95_m": float(np.percentile(error, 95)),
            "heading_error_median_deg": math.degrees(float(np.median(heading))),
            "superb": quality_counts[0],
            "okay": quality_counts[1],
            "poor": quality_counts[2],
            "lost": lost,
        }
        for name, value in values.items():
            rows[name][minute] = value
        if on_minute is not None:
            on_minute(_row(rows, minute))
    digest.update(np.ascontiguousarray(loc.filter.poses).tobytes())
    digest.update(np.ascontiguousarray(loc.filter.weights).tobytes())
    elapsed = time.perf_counter() - started
    drift = step_time_drift(rows["median_ms"])
    growth = float(rows["growth_mb"][-1])
    verdict = judge(nonfinite_total, growth, drift)
    final = loc.pose()
    return {
        "settings": {
            "minutes": minutes,
            "particles": particles,
            "seed": seed,
            "field": s.field.name,
            "motion_rate_hz": s.motion_rate,
            "camera_rate_hz": s.camera_rate,
            "latency_s": s.latency,
            "steps": total,
        },
        "minutes": [_row(rows, m) for m in range(n_minutes)],
        "nonfinite": nonfinite_total,
        "memory": {
            "rss_first_minute_mb": rss_first / MB,
            "rss_end_mb": float(rows["rss_mb"][-1]),
            "growth_mb": growth,
            "max_growth_mb": float(rows["growth_mb"].max()),
            "limit_mb": MAX_GROWTH_MB,
        },
        "drift": None
        if drift is None
        else {**asdict(drift), "limit_per_hour": MAX_DRIFT_PER_HOUR, "judged_from_minutes": JUDGED_DRIFT_MINUTES + 1},
        "verdict": {
            "ok": verdict.ok,
            "finite": verdict.finite,
            "memory": verdict.memory,
            "drift": verdict.drift,
            "text": verdict.text,
        },
        "counts": dict(loc.counts),
        "start": stream.start.tolist(),
        "final_estimate": final.pose.tolist(),
        "final_truth": truth[n - 1].tolist(),
        "poses_sha256": digest.hexdigest(),
        "elapsed_s": elapsed,
        "machine": _machine(),
    }


def _machine() -> dict:
    import platform

    import numba

    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "cpus": os.cpu_count(),
        "platform": platform.platform(),
    }


def _row(rows: dict, minute: int) -> dict:
    integer = {"steps", "frames", "detections", "nonfinite", "superb", "okay", "poor", "lost"}
    out: dict = {"minute": minute + 1}
    for name, values in rows.items():
        out[name] = int(values[minute]) if name in integer else float(values[minute])
    return out


TABLE_WIDTHS = (6, 6, 6, 9, 7, 7, 9, 4, 7)


def table_header() -> str:
    return " ".join(f"{name:>{width}}" for name, width in zip(TABLE_COLUMNS, TABLE_WIDTHS))


def table_row(row: dict) -> str:
    return (
        f"{row['minute']:>6} {row['steps']:>6} {row['frames']:>6} {row['median_ms']:>9.3f} "
        f"{row['p99_ms']:>7.3f} {row['rss_mb']:>7.1f} {row['growth_mb']:>+9.2f} {row['nonfinite']:>4} "
        f"{row['error_median_m']:>7.3f}"
    )


PROG = "robocup-mcl soak"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument(
        "--minutes", type=float, default=60.0, help="simulated minutes (default 60; fractions allowed, e.g. 0.5)"
    )
    parser.add_argument("--particles", type=int, default=500, help="particles (default 500)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the scenario and the filter (default 0)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON instead of the table")
    parser.add_argument("--save", metavar="PATH", help="also write the JSON results to PATH")
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl soak` (see the module docstring); exit 0 when the verdict holds, 1 otherwise."""
    from mcl.tools.cli_checks import check_output_file

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    if not (math.isfinite(args.minutes) and 0 < args.minutes <= 24 * 60):
        parser.error(f"--minutes {args.minutes} must be > 0 and at most {24 * 60} (a day)")
    if args.particles <= 0:
        parser.error(f"--particles {args.particles} must be > 0")
    if args.seed < 0:
        parser.error(f"--seed {args.seed} must be >= 0")
    check_output_file(args.save, "--save", make_parents=False)  # before the run, not after it

    def show(row: dict) -> None:
        print(table_row(row), flush=True)

    scenario = SoakScenario()
    if not args.json:
        print(
            f"soak: {args.minutes:g} simulated min on {scenario.field.name}, motion at {scenario.motion_rate:g} Hz, "
            f"camera at {scenario.camera_rate:g} Hz ({1e3 * scenario.latency:.0f} ms late), {args.particles} "
            f"particles, seed {args.seed}"
        )
        print(table_header(), flush=True)
    from mcl.tools.cli_checks import progress_bar, progress_wanted

    bar = progress_bar(enabled=progress_wanted(args), total=math.ceil(args.minutes), desc="soak", unit="simulated min")

    def on_minute(row: dict) -> None:
        if not args.json:
            bar.clear()
            show(row)
        bar.update(1)

    try:
        result = run_soak(args.minutes, args.particles, args.seed, scenario, on_minute=on_minute)
    finally:
        bar.close()
    text = json.dumps(result, indent=2)
    if args.save:
        with open(args.save, "w", encoding="utf-8") as handle:
            handle.write(text + "\n")
    if args.json:
        print(text)
        print(result["verdict"]["text"], file=sys.stderr)  # stdout stays pure JSON
    else:
        drift = result["drift"]
        if drift is not None:
            print(
                f"step time: median {drift['baseline_ms']:.3f} ms over minutes {drift['first']}-{drift['last']}, "
                f"Theil-Sen slope {1e3 * drift['slope_ms_per_minute']:+.4f} µs/min "
                f"({100 * drift['relative_per_hour']:+.1f} %/h); last third vs first third "
                f"{100 * drift['thirds_change']:+.1f} %"
            )
        print(f"{result['settings']['steps']} steps in {result['elapsed_s']:.0f} s of wall time")
        if args.save:
            print(f"results written to {args.save}")
        print(result["verdict"]["text"])
    return 0 if result["verdict"]["ok"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
