"""`robocup-mcl demo penalty`: returning from a penalty on a touchline the robot cannot know.

    robocup-mcl demo penalty [--seeds 0-19] [--duration 20] [--particles 500] [--json]

The rules put a robot back from a penalty on the own touchline at the penalty mark's x, on either side. Per
seed, the side is drawn at random; the robot stands there facing into the field, then walks the walk scenario's
random waypoints with its panning camera. The filter starts with `Localizer.penalty_return()` (half the
particles at each touchline) and, as the baseline, with no knowledge (uniform over the field). Measured per
run, from the return on:
- convergence: the first time after which, for a whole second, the position error stays below 0.3 m and the
  estimate's cluster holds at least 90 % of the weight (the other touchline's hypothesis is gone);
- how the run ends (last second): on the true pose, on the other touchline's pose (x, −y, −θ), on the point
  mirror (−x, −y, θ+π), or elsewhere (within 0.5 m and 0.5 rad of each, else "elsewhere").
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace

import numpy as np

from field.angles import wrap_angles
from mcl.tools.replay import replay

from .walk import parse_seeds, settle_time
from .walk_log import to_robot_log
from .walk_sim import WalkScenario, simulate

STARTS = (("penalty_return", "penalty"), ("uniform field", "field"))
ENDINGS = ("true pose", "other touchline", "point mirror", "elsewhere")


def return_pose(scenario: WalkScenario, side: int) -> tuple[float, float, float]:
    """Where the rules put the robot back: own half, penalty mark's x, touchline `side` (+1 left, -1 right)."""
    f = scenario.field
    return (-f.half_length + f.dims.penalty_mark_distance, side * f.half_width, -side * math.pi / 2)


def ending(estimates: np.ndarray, truth: np.ndarray) -> str:
    """Which pose the last estimates sit on (see the module docstring)."""

    def near(target):
        return (np.hypot(*(estimates[:, :2] - target[:, :2]).T) < 0.5) & (
            np.abs(wrap_angles(estimates[:, 2] - target[:, 2])) < 0.5
        )

    other = truth * np.array([1.0, -1.0, -1.0])
    mirror = np.column_stack([-truth[:, 0], -truth[:, 1], wrap_angles(truth[:, 2] + math.pi)])
    for name, target in zip(ENDINGS, (truth, other, mirror)):
        if near(target).mean() > 0.5:
            return name
    return "elsewhere"


def run_seed(seed: int, particles: int, scenario: WalkScenario) -> dict:
    side = 1 if np.random.default_rng(10_000 + seed).random() < 0.5 else -1
    walk = simulate(replace(scenario, start_pose=return_pose(scenario, side)), seed)
    log = to_robot_log(walk)
    out = {"seed": seed, "side": "left" if side > 0 else "right"}
    for name, start in STARTS:
        result = replay(log, scenario.field, particles=particles, seed=seed, start=start)
        # An error above the threshold wherever the other hypothesis still holds more than 10 % of the weight.
        errors = np.where(result.weights >= 0.9, result.position_errors, np.inf)
        last = result.times >= result.times[-1] - 1.0
        out[name] = {
            "converged_s": settle_time(errors, result.times, 0, errors.shape[0], walk.dt),
            "ending": ending(result.estimates[last], result.truth[last]),
        }
    return out


def summarize(runs: list[dict]) -> dict:
    summary = {}
    for name, _ in STARTS:
        times = [r[name]["converged_s"] for r in runs]
        ordered = sorted(math.inf if t is None else t for t in times)
        summary[name] = {
            "converged_median_s": float(np.median(ordered)) if np.isfinite(np.median(ordered)) else None,
            "converged_worst_s": None if ordered[-1] == math.inf else ordered[-1],
            "never_converged": times.count(None),
            "endings": {e: sum(r[name]["ending"] == e for r in runs) for e in ENDINGS},
            "runs": len(runs),
        }
    return summary


PROG = "robocup-mcl demo penalty"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument("--seeds", default="0-19", help='seeds: "0-19", "3" or "1,4,7" (default 0-19)')
    parser.add_argument("--particles", type=int, default=500, help="particles (default 500)")
    parser.add_argument(
        "--duration", type=float, default=20.0, help="seconds of walking after the return (default 20, at least 3)"
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of the summary")
    add_save_option(parser)
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl demo penalty` (see --help); returns the exit status."""
    from mcl.tools.cli_checks import progress_bar, progress_wanted

    from .walk import warm_up_walk

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    from mcl.tools.cli_checks import check_duration, check_output_file, save_json

    check_output_file(args.save, "--save")
    if args.particles <= 0:
        parser.error(f"--particles {args.particles} must be > 0")
    check_duration(parser, args.duration, 3.0)
    try:
        seeds = parse_seeds(args.seeds)
    except ValueError:
        parser.error(f"--seeds {args.seeds!r}: give seeds as 3, 0-9 or 1,4,7")
    scenario = replace(WalkScenario(), duration=args.duration, kidnap_time=None)
    progress = progress_wanted(args)
    warm_up_walk(WalkScenario(), "velocity-linear", progress=progress)  # the first run says it compiles
    runs = [
        run_seed(seed, args.particles, scenario)
        for seed in progress_bar(seeds, enabled=progress, desc="penalty", unit="seed")
    ]
    summary = summarize(runs)
    result = {"particles": args.particles, "duration_s": args.duration, "runs": runs, "summary": summary}
    save_json(args.save, result)
    if args.json:
        json.dump(result, sys.stdout, indent=2)
        print()
        return 0
    print(
        f"penalty return on a random touchline, {len(runs)} seeds, {args.duration:.0f} s each, "
        f"{args.particles} particles"
    )
    for name, _ in STARTS:
        s = summary[name]
        median = "never" if s["converged_median_s"] is None else f"{s['converged_median_s']:.2f} s"
        worst = "never" if s["converged_worst_s"] is None else f"{s['converged_worst_s']:.2f} s"
        endings = ", ".join(f"{e} {n}" for e, n in s["endings"].items())
        print(
            f"{name:>15}: converged median {median}, worst {worst} (never: {s['never_converged']}); ends on: {endings}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
