"""`robocup-mcl demo walk`: the particle filter on the walk scenario, with the figures the README quotes.

    robocup-mcl demo walk [--model constant|velocity-linear] [--particles N] [--seed S | --seeds 0-9]
                          [--lines] [--rrd PATH] [--json] [--save PATH] [--no-progress]

The filter starts uniform over the own half (unknown heading), predicts at 100 Hz from the walk request and
corrects with each camera frame. Measured per run:
- convergence: the first time after which the position error stays below 0.3 m for a whole second;
- re-convergence: the same, counted from the kidnapping;
- tracking RMSE (position and heading): over the steps after convergence and after re-convergence;
- mirror time: the share of steps whose estimate is within 0.5 m and 0.5 rad of the mirrored true pose
  (−x, −y, θ+π) — the point-symmetric field's trap.

Before the runs the filter's kernels are warmed up on a throw-away filter (`warm_up_walk`): compiled on a
machine's first run (it says so on stderr, with a progress bar over the groups of kernels), loaded from numba's
cache afterwards. ms/step is measured after the warm-up; the warm-up's time is reported apart ("compiled in
41 s"; compile_seconds in the JSON), and first_step_s is the time from the command's start to the end of the
first filter step.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace

import numpy as np

from field.angles import wrap_angles
from mcl import ParticleFilter
from motion_models import ConstantNoise, MotionInput, VelocityLinear
from sensing import CombinedSensorModel, LandmarkSensorModel, LineSensorModel
from sensing.view import CameraView

from .walk_sim import WalkLog, WalkScenario, simulate

MODELS = {"constant": ConstantNoise, "velocity-linear": VelocityLinear}
CONVERGED = 0.3  # m
HOLD = 1.0  # s the error must stay below CONVERGED


def settle_time(errors: np.ndarray, times: np.ndarray, start: int, end: int, dt: float) -> float | None:
    """Seconds from times[start] until the error first stays below CONVERGED for HOLD seconds (None: never)."""
    hold = int(round(HOLD / dt))
    below = errors[start:end] < CONVERGED
    run = 0
    for i, ok in enumerate(below):
        run = run + 1 if ok else 0
        if run >= hold:
            return float(times[start + i - hold + 1] - (times[start] - dt))
    return None


def camera_view(scenario: WalkScenario, frame) -> CameraView:
    """The frame's camera view: the head's pan, the scenario's field of view and its landmark ranges."""
    return CameraView(frame.head_angle, 0.5 * scenario.field_of_view, scenario.max_range, scenario.min_range)


def walk_filter(
    scenario: WalkScenario, model: str, particles: int, seed: int, sensor: LandmarkSensorModel | None = None
) -> ParticleFilter:
    """The demo's filter for `scenario`: the motion `model`, the landmark model (and the line model with
    `scenario.lines`) unless `sensor` is given, uniform over the own half."""
    if sensor is None:
        sensor = LandmarkSensorModel(scenario.field)
        if scenario.lines:
            sensor = CombinedSensorModel((sensor, LineSensorModel(scenario.field)))
    pf = ParticleFilter(scenario.field, MODELS[model](), sensor, n_particles=particles, seed=seed)
    pf.reset_uniform("own_half")
    return pf


WARM_UP_PARTICLES = 64
WARM_UP_SECONDS = 2.0


def warm_up_walk(scenario: WalkScenario, model: str, view: bool = False, progress: bool = False):
    """Compile (or load from numba's cache) every kernel a walk run reaches, on throw-away filters of a few
    particles, before anything is measured; returns the `mcl.numba_cache.WarmUp` (its seconds, and whether the
    kernels were cached). The filter's groups of kernels come one by one (`mcl.numba_cache.filter_stages`), then
    a 2-second walk reaches the branches a run takes later (injection, the kidnapping's recovery). The demo's
    runs are untouched: the warm-up filters have their own generators."""
    from mcl.numba_cache import filter_kernels, filter_stages, warm_up

    short = replace(scenario, duration=WARM_UP_SECONDS, kidnap_time=None)
    log = simulate(short, 0)
    pf = walk_filter(short, model, WARM_UP_PARTICLES, seed=0)
    frame = next((f for f in log.frames if len(f.observations) > 0), log.frames[0])
    observations = frame.observations.with_view(camera_view(short, frame)) if view else frame.observations
    u = MotionInput(dt=log.dt, command=tuple(log.commands[0]))
    stages = filter_stages(pf, u, observations)
    stages.append(("a short walk", lambda: run_walk(model, WARM_UP_PARTICLES, 0, None, short, view=view)))
    return warm_up(stages, filter_kernels(pf), progress=progress)


def run_walk(
    model: str = "velocity-linear",
    particles: int = 500,
    seed: int = 0,
    rrd: str | None = None,
    scenario: WalkScenario = WalkScenario(),
    sensor: LandmarkSensorModel | None = None,
    record_every: int = 5,
    series: bool = False,
    view: bool = False,
    progress: bool = False,
) -> dict:
    """Simulate the scenario with `seed`, run the filter on it, and return the figures.

    With `view`, each frame comes with its camera view (`sensing.view.CameraView`: the head's pan, the
    scenario's field of view and ranges), so the landmark model also scores what should have been seen.

    With `series`, the result also holds "series": times, truth, estimates and entropy per step (arrays).
    With `progress`, a bar over the steps on stderr (`mcl.tools.cli_checks.progress_bar`). The result's
    "first_step_at" is the `time.perf_counter()` reading when the first step was done.
    """
    from mcl.tools.cli_checks import progress_bar

    log = simulate(scenario, seed)
    pf = walk_filter(scenario, model, particles, seed, sensor)
    recorder = None
    if rrd:
        from mcl.tools.recording import Recorder

        recorder = Recorder(rrd, scenario.field, particles_every=record_every)
    n = log.times.shape[0]
    estimates = np.empty((n, 3))
    entropy = np.empty((n, 2))
    fit = np.full(n, np.nan)  # w_fast after each correction: augmented MCL's short-term fit
    frames = {frame.step: frame for frame in log.frames}
    first_step_at = None
    steps = progress_bar(range(n), enabled=progress, desc=f"seed {seed}", unit="step", mininterval=0.25)
    started = time.perf_counter()
    for k in steps:
        pf.predict(MotionInput(dt=log.dt, command=tuple(log.commands[k])))
        frame = frames.get(k)
        if frame is not None:
            pf.correct(frame.observations.with_view(camera_view(scenario, frame)) if view else frame.observations)
            fit[k] = pf.w_fast
        estimates[k] = pf.estimate().pose
        h = pf.entropy()
        entropy[k] = (h.position, h.orientation)
        if first_step_at is None:
            first_step_at = time.perf_counter()
        if recorder is not None:
            recorder.log_step(
                k,
                float(log.times[k]),
                pf,
                truth=log.truth[k],
                observations=frame.observations if frame is not None else None,
                entropy=h,
            )
            if log.kidnap_step is not None and k == log.kidnap_step + 1:
                recorder.log_event(
                    "kidnap", f"the robot was carried {scenario.kidnap_distance:g} m (heading kept)", level="WARN"
                )
    elapsed = time.perf_counter() - started
    steps.close()
    if recorder is not None:
        recorder.close()
    result = summarize(log, estimates, entropy, elapsed, model, particles, seed, rrd, fit)
    result["_first_step_at"] = first_step_at
    if series:
        result["series"] = {"times": log.times, "truth": log.truth, "estimates": estimates, "entropy": entropy}
    return result


def summarize(
    log: WalkLog,
    estimates: np.ndarray,
    entropy: np.ndarray,
    elapsed: float,
    model: str,
    particles: int,
    seed: int,
    rrd: str | None,
    fit: np.ndarray | None = None,
) -> dict:
    truth, times, dt = log.truth, log.times, log.dt
    position_error = np.hypot(*(estimates[:, :2] - truth[:, :2]).T)
    heading_error = np.abs(wrap_angles(estimates[:, 2] - truth[:, 2]))
    n = times.shape[0]
    kidnap = log.kidnap_step + 1 if log.kidnap_step is not None else n
    converged = settle_time(position_error, times, 0, kidnap, dt)
    reconverged = settle_time(position_error, times, kidnap, n, dt) if kidnap < n else None
    tracking = np.zeros(n, dtype=bool)
    if converged is not None:
        tracking[int(round(converged / dt)) : kidnap] = True
    if reconverged is not None:
        tracking[kidnap + int(round(reconverged / dt)) :] = True
    mirror = truth.copy()
    mirror[:, :2] *= -1.0
    mirror[:, 2] = wrap_angles(truth[:, 2] + math.pi)
    on_mirror = (np.hypot(*(estimates[:, :2] - mirror[:, :2]).T) < 0.5) & (
        np.abs(wrap_angles(estimates[:, 2] - mirror[:, 2])) < 0.5
    )

    def rmse(values):
        return float(np.sqrt(np.mean(values[tracking] ** 2))) if tracking.any() else None

    return {
        "model": model,
        "particles": particles,
        "seed": seed,
        "lines": log.scenario.lines,
        "converged_s": converged,
        "reconverged_s": reconverged,
        "position_rmse_m": rmse(position_error),
        "heading_rmse_deg": None if rmse(heading_error) is None else math.degrees(rmse(heading_error)),
        "tracking_share": float(tracking.mean()),
        "mirror_share": float(on_mirror.mean()),
        "final_position_error_m": float(position_error[-1]),
        "mean_entropy_bits": {"position": float(entropy[:, 0].mean()), "orientation": float(entropy[:, 1].mean())},
        "filter_seconds": elapsed,
        "steps": n,
        "ms_per_step": 1e3 * elapsed / n,
        "rrd": rrd,
        "_fit": _fit_samples(fit, position_error),
    }


def _fit_samples(fit: np.ndarray | None, position_error: np.ndarray) -> dict:
    """w_fast after each correction, split into tracking (error < 0.2 m) and lost (error > 1 m) frames."""
    if fit is None:
        return {"tracking": np.empty(0), "lost": np.empty(0)}
    seen = ~np.isnan(fit)
    return {"tracking": fit[seen & (position_error < 0.2)], "lost": fit[seen & (position_error > 1.0)]}


def fit_figures(runs: list[dict]) -> dict:
    """Percentiles of w_fast over all frames of all runs, while tracking and while lost: the separation that
    `AugmentedMCL.fit_threshold` relies on."""
    tracking = np.concatenate([r["_fit"]["tracking"] for r in runs])
    lost = np.concatenate([r["_fit"]["lost"] for r in runs])

    def pct(values, q):
        return float(np.percentile(values, q)) if values.size else None

    return {
        "tracking_p1": pct(tracking, 1),
        "tracking_p5": pct(tracking, 5),
        "lost_p50": pct(lost, 50),
        "lost_p95": pct(lost, 95),
        "tracking_frames": int(tracking.size),
        "lost_frames": int(lost.size),
    }


def parse_seeds(text: str) -> list[int]:
    """ "3" → [3]; "0-9" → [0..9]; "1,4,7" → [1, 4, 7]."""
    seeds: list[int] = []
    for part in text.split(","):
        if "-" in part.strip()[1:]:
            lo, hi = part.split("-", 1)
            seeds.extend(range(int(lo), int(hi) + 1))
        else:
            seeds.append(int(part))
    if not seeds:
        raise ValueError(f"--seeds {text!r} names no seed")
    return seeds


def aggregate(runs: list[dict]) -> dict:
    """Medians and worst seeds of the figures over several runs (None = never converged = worst)."""

    def never_last(value):
        return math.inf if value is None else value

    def stat(key):
        values = [r[key] for r in runs]
        missing = values.count(None)
        if missing == len(values):
            return {"median": None, "worst": None, "worst_seed": None, "failed_seeds": missing}
        ordered = sorted(values, key=never_last)
        middle = len(ordered) // 2
        pair = ordered[middle - 1 : middle + 1] if len(ordered) % 2 == 0 else [ordered[middle]]
        median = None if None in pair else sum(pair) / len(pair)
        worst_run = max(runs, key=lambda r: never_last(r[key]))
        return {"median": median, "worst": worst_run[key], "worst_seed": worst_run["seed"], "failed_seeds": missing}

    keys = ("position_rmse_m", "heading_rmse_deg", "converged_s", "reconverged_s", "mirror_share", "ms_per_step")
    summary = {key: stat(key) for key in keys}
    if all("_fit" in r for r in runs):
        summary["fit_w_fast"] = fit_figures(runs)
    return summary


def _fmt(value, unit="", digits=3):
    return "never" if value is None else f"{value:.{digits}f}{unit}"


PROG = "robocup-mcl demo walk"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument(
        "--model", choices=sorted(MODELS), default="velocity-linear", help="the motion model (default velocity-linear)"
    )
    parser.add_argument("--particles", type=int, default=500, help="particles (default 500)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the simulated walk and the filter (default 0)")
    parser.add_argument("--seeds", help='several seeds: "0-9" or "0,3,5" (overrides --seed)')
    parser.add_argument("--duration", type=float, default=60.0, help="seconds of walking (default 60)")
    parser.add_argument(
        "--lines", action="store_true", help="the camera also reports points on field lines, scored by the line model"
    )
    parser.add_argument(
        "--view",
        action="store_true",
        help="pass each frame's camera view: the landmark model also scores what should have been seen",
    )
    parser.add_argument("--rrd", help="write a Rerun recording here (one seed only)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--save", metavar="PATH", help="also write the JSON results to PATH")
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl demo walk` (see --help); returns the exit status."""
    command_started = time.perf_counter()
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    if args.particles <= 0:
        parser.error(f"--particles {args.particles} must be > 0")
    if not (math.isfinite(args.duration) and args.duration > 0):
        parser.error(f"--duration {args.duration} must be > 0 s")
    try:
        seeds = parse_seeds(args.seeds) if args.seeds else [args.seed]
    except ValueError:
        parser.error(f"--seeds {args.seeds!r}: give seeds as 3, 0-9 or 1,4,7")
    if args.rrd and len(seeds) > 1:
        parser.error("--rrd records one run: give --seed, not --seeds")
    from mcl.tools.cli_checks import check_output_file, progress_wanted, save_json

    check_output_file(args.rrd, "--rrd")  # before the run, not after it
    check_output_file(args.save, "--save")
    progress = progress_wanted(args)
    scenario = WalkScenario(lines=args.lines)
    if args.duration != scenario.duration:
        kidnap = scenario.kidnap_time if args.duration > (scenario.kidnap_time or 0) + 5 else None
        scenario = replace(scenario, duration=args.duration, kidnap_time=kidnap)
    warm = warm_up_walk(scenario, args.model, args.view, progress)
    runs = [
        run_walk(args.model, args.particles, s, args.rrd, scenario, view=args.view, progress=progress) for s in seeds
    ]
    first_step_s = runs[0]["_first_step_at"] - command_started
    summary = aggregate(runs)
    runs = [{k: v for k, v in r.items() if not k.startswith("_")} for r in runs]
    result = {"runs": runs, "summary": summary} if len(runs) > 1 else runs[0]
    result.update(warm.as_dict(), first_step_s=first_step_s)
    save_json(args.save, result)
    if args.json:
        json.dump(result, sys.stdout, indent=2)
        print()
        return 0
    print(
        f"walk scenario: {scenario.duration:.0f} s on {scenario.field.name}, model {args.model}, "
        f"{args.particles} particles, kidnapping at {scenario.kidnap_time} s, "
        f"{'landmarks and lines' if scenario.lines else 'landmarks only'}"
        f"{', frames with their camera view' if args.view else ''}"
    )
    print(f"{'seed':>4} {'pos RMSE':>9} {'head RMSE':>9} {'converge':>9} {'reconv.':>8} {'mirror':>7} {'ms/step':>8}")
    for r in runs:
        print(
            f"{r['seed']:>4} {_fmt(r['position_rmse_m'], ' m'):>9} {_fmt(r['heading_rmse_deg'], '°', 2):>9} "
            f"{_fmt(r['converged_s'], ' s', 2):>9} {_fmt(r['reconverged_s'], ' s', 2):>8} "
            f"{100 * r['mirror_share']:>6.1f}% {r['ms_per_step']:>8.3f}"
        )
    if len(runs) > 1:
        s = result["summary"]
        for label, key, unit in (
            ("position RMSE", "position_rmse_m", " m"),
            ("heading RMSE", "heading_rmse_deg", "°"),
            ("convergence", "converged_s", " s"),
            ("re-convergence", "reconverged_s", " s"),
            ("mirror share", "mirror_share", ""),
        ):
            print(
                f"{label:>15}: median {_fmt(s[key]['median'], unit)}, worst {_fmt(s[key]['worst'], unit)} "
                f"(seed {s[key]['worst_seed']}), never: {s[key]['failed_seeds']}"
            )
        fit = s["fit_w_fast"]
        if fit["tracking_p1"] is not None and fit["lost_p50"] is not None:
            print(
                f"  w_fast (fit), all frames of all seeds: while tracking 1st percentile {fit['tracking_p1']:.3f}, "
                f"5th {fit['tracking_p5']:.3f} ({fit['tracking_frames']} frames); while lost median "
                f"{fit['lost_p50']:.3f} ({fit['lost_frames']} frames)"
            )
    print(f"warm-up: {warm.summary()}, not counted in ms/step; first step done {first_step_s:.1f} s after the start")
    if args.rrd:
        print(f"recording written to {args.rrd} (open it with: rerun {args.rrd})")
    if args.save:
        print(f"results written to {args.save}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
