"""`robocup-mcl demo walk`: the particle filter on the walk scenario, with the figures the README quotes.

    robocup-mcl demo walk [--model constant|velocity-linear] [--particles N] [--seed S | --seeds 0-9]
                          [--lines] [--rrd PATH] [--json]

The filter starts uniform over the own half (unknown heading), predicts at 100 Hz from the walk request and
corrects with each camera frame. Measured per run:
- convergence: the first time after which the position error stays below 0.3 m for a whole second;
- re-convergence: the same, counted from the kidnapping;
- tracking RMSE (position and heading): over the steps after convergence and after re-convergence;
- mirror time: the share of steps whose estimate is within 0.5 m and 0.5 rad of the mirrored true pose
  (−x, −y, θ+π) — the point-symmetric field's trap.
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
CONVERGED = 0.3     # m
HOLD = 1.0          # s the error must stay below CONVERGED


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


def run_walk(model: str = "velocity-linear", particles: int = 500, seed: int = 0, rrd: str | None = None,
             scenario: WalkScenario = WalkScenario(), sensor: LandmarkSensorModel | None = None,
             record_every: int = 5, series: bool = False, view: bool = False) -> dict:
    """Simulate the scenario with `seed`, run the filter on it, and return the figures.

    With `view`, each frame comes with its camera view (`sensing.view.CameraView`: the head's pan, the
    scenario's field of view and ranges), so the landmark model also scores what should have been seen.

    With `series`, the result also holds "series": times, truth, estimates and entropy per step (arrays).
    """
    log = simulate(scenario, seed)
    if sensor is None:
        sensor = LandmarkSensorModel(scenario.field)
        if scenario.lines:
            sensor = CombinedSensorModel((sensor, LineSensorModel(scenario.field)))
    pf = ParticleFilter(scenario.field, MODELS[model](), sensor, n_particles=particles, seed=seed)
    pf.reset_uniform("own_half")
    recorder = None
    if rrd:
        from mcl.recording import Recorder
        recorder = Recorder(rrd, scenario.field, particles_every=record_every)
    n = log.times.shape[0]
    estimates = np.empty((n, 3))
    entropy = np.empty((n, 2))
    fit = np.full(n, np.nan)     # w_fast after each correction: augmented MCL's short-term fit
    frames = {frame.step: frame for frame in log.frames}
    started = time.perf_counter()
    for k in range(n):
        pf.predict(MotionInput(dt=log.dt, command=tuple(log.commands[k])))
        frame = frames.get(k)
        if frame is not None:
            pf.correct(frame.observations.with_view(camera_view(scenario, frame)) if view else frame.observations)
            fit[k] = pf.w_fast
        estimates[k] = pf.estimate().pose
        h = pf.entropy()
        entropy[k] = (h.position, h.orientation)
        if recorder is not None:
            recorder.log_step(k, float(log.times[k]), pf, truth=log.truth[k],
                              observations=frame.observations if frame is not None else None, entropy=h)
    elapsed = time.perf_counter() - started
    if recorder is not None:
        recorder.close()
    result = summarize(log, estimates, entropy, elapsed, model, particles, seed, rrd, fit)
    if series:
        result["series"] = {"times": log.times, "truth": log.truth, "estimates": estimates, "entropy": entropy}
    return result


def summarize(log: WalkLog, estimates: np.ndarray, entropy: np.ndarray, elapsed: float, model: str,
              particles: int, seed: int, rrd: str | None, fit: np.ndarray | None = None) -> dict:
    truth, times, dt = log.truth, log.times, log.dt
    position_error = np.hypot(*(estimates[:, :2] - truth[:, :2]).T)
    heading_error = np.abs(wrap_angles(estimates[:, 2] - truth[:, 2]))
    n = times.shape[0]
    kidnap = log.kidnap_step + 1 if log.kidnap_step is not None else n
    converged = settle_time(position_error, times, 0, kidnap, dt)
    reconverged = settle_time(position_error, times, kidnap, n, dt) if kidnap < n else None
    tracking = np.zeros(n, dtype=bool)
    if converged is not None:
        tracking[int(round(converged / dt)):kidnap] = True
    if reconverged is not None:
        tracking[kidnap + int(round(reconverged / dt)):] = True
    mirror = truth.copy()
    mirror[:, :2] *= -1.0
    mirror[:, 2] = wrap_angles(truth[:, 2] + math.pi)
    on_mirror = ((np.hypot(*(estimates[:, :2] - mirror[:, :2]).T) < 0.5)
                 & (np.abs(wrap_angles(estimates[:, 2] - mirror[:, 2])) < 0.5))

    def rmse(values):
        return float(np.sqrt(np.mean(values[tracking] ** 2))) if tracking.any() else None

    return {
        "model": model, "particles": particles, "seed": seed, "lines": log.scenario.lines,
        "converged_s": converged, "reconverged_s": reconverged,
        "position_rmse_m": rmse(position_error), "heading_rmse_deg": None if rmse(heading_error) is None
        else math.degrees(rmse(heading_error)),
        "tracking_share": float(tracking.mean()), "mirror_share": float(on_mirror.mean()),
        "final_position_error_m": float(position_error[-1]),
        "mean_entropy_bits": {"position": float(entropy[:, 0].mean()), "orientation": float(entropy[:, 1].mean())},
        "filter_seconds": elapsed, "steps": n, "ms_per_step": 1e3 * elapsed / n,
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

    return {"tracking_p1": pct(tracking, 1), "tracking_p5": pct(tracking, 5), "lost_p50": pct(lost, 50),
            "lost_p95": pct(lost, 95), "tracking_frames": int(tracking.size), "lost_frames": int(lost.size)}


def parse_seeds(text: str) -> list[int]:
    """"3" → [3]; "0-9" → [0..9]; "1,4,7" → [1, 4, 7]."""
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
        pair = ordered[middle - 1:middle + 1] if len(ordered) % 2 == 0 else [ordered[middle]]
        median = None if None in pair else sum(pair) / len(pair)
        worst_run = max(runs, key=lambda r: never_last(r[key]))
        return {"median": median, "worst": worst_run[key], "worst_seed": worst_run["seed"],
                "failed_seeds": missing}

    keys = ("position_rmse_m", "heading_rmse_deg", "converged_s", "reconverged_s", "mirror_share", "ms_per_step")
    summary = {key: stat(key) for key in keys}
    if all("_fit" in r for r in runs):
        summary["fit_w_fast"] = fit_figures(runs)
    return summary


def _fmt(value, unit="", digits=3):
    return "never" if value is None else f"{value:.{digits}f}{unit}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="robocup-mcl demo walk", description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", choices=sorted(MODELS), default="velocity-linear")
    parser.add_argument("--particles", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seeds", help='several seeds: "0-9" or "0,3,5" (overrides --seed)')
    parser.add_argument("--duration", type=float, default=60.0, help="seconds of walking (default 60)")
    parser.add_argument("--lines", action="store_true",
                        help="the camera also reports points on field lines, scored by the line model")
    parser.add_argument("--view", action="store_true",
                        help="pass each frame's camera view: the landmark model also scores what should have been seen")
    parser.add_argument("--rrd", help="write a Rerun recording here (one seed only)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
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
    from mcl.cli_checks import check_output_file
    check_output_file(args.rrd, "--rrd")          # before the run, not after it
    scenario = WalkScenario(lines=args.lines)
    if args.duration != scenario.duration:
        kidnap = scenario.kidnap_time if args.duration > (scenario.kidnap_time or 0) + 5 else None
        scenario = replace(scenario, duration=args.duration, kidnap_time=kidnap)
    runs = [run_walk(args.model, args.particles, s, args.rrd, scenario, view=args.view) for s in seeds]
    summary = aggregate(runs)
    runs = [{k: v for k, v in r.items() if not k.startswith("_")} for r in runs]
    result = {"runs": runs, "summary": summary} if len(runs) > 1 else runs[0]
    if args.json:
        json.dump(result, sys.stdout, indent=2)
        print()
        return 0
    print(f"walk scenario: {scenario.duration:.0f} s on {scenario.field.name}, model {args.model}, "
          f"{args.particles} particles, kidnapping at {scenario.kidnap_time} s, "
          f"{'landmarks and lines' if scenario.lines else 'landmarks only'}"
          f"{', frames with their camera view' if args.view else ''}")
    print(f"{'seed':>4} {'pos RMSE':>9} {'head RMSE':>9} {'converge':>9} {'reconv.':>8} {'mirror':>7} {'ms/step':>8}")
    for r in runs:
        print(f"{r['seed']:>4} {_fmt(r['position_rmse_m'], ' m'):>9} {_fmt(r['heading_rmse_deg'], '°', 2):>9} "
              f"{_fmt(r['converged_s'], ' s', 2):>9} {_fmt(r['reconverged_s'], ' s', 2):>8} "
              f"{100 * r['mirror_share']:>6.1f}% {r['ms_per_step']:>8.3f}")
    if len(runs) > 1:
        s = result["summary"]
        for label, key, unit in (("position RMSE", "position_rmse_m", " m"), ("heading RMSE", "heading_rmse_deg", "°"),
                                 ("convergence", "converged_s", " s"), ("re-convergence", "reconverged_s", " s"),
                                 ("mirror share", "mirror_share", "")):
            print(f"{label:>15}: median {_fmt(s[key]['median'], unit)}, worst {_fmt(s[key]['worst'], unit)} "
                  f"(seed {s[key]['worst_seed']}), never: {s[key]['failed_seeds']}")
        fit = s["fit_w_fast"]
        if fit["tracking_p1"] is not None and fit["lost_p50"] is not None:
            print(f"  w_fast (fit), all frames of all seeds: while tracking 1st percentile {fit['tracking_p1']:.3f}, "
                  f"5th {fit['tracking_p5']:.3f} ({fit['tracking_frames']} frames); while lost median "
                  f"{fit['lost_p50']:.3f} ({fit['lost_frames']} frames)")
    if args.rrd:
        print(f"recording written to {args.rrd} (open it with: rerun {args.rrd})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
