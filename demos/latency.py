"""`robocup-mcl demo latency`: tracking with a late camera, with and without latency compensation.

    robocup-mcl demo latency [--latency 0.08] [--seeds 0-9] [--particles 500] [--json]

The walk scenario (60 s, no kidnapping, the filter started at the true pose so that only tracking is
measured), and a fast walk (0.4 m/s and 1.5 rad/s instead of 0.25 and 0.8: a KidSize robot's pace), are turned
into robot logs whose camera frames arrive `--latency` seconds after capture, and each is replayed three times
per seed: the frames scored at their capture time (compensated), scored as if they were
current (not compensated), and a log without latency (the floor). Per run: the median and 95th percentile of
the position error and the median heading error over all steps; the summary gives their medians over the
seeds. Same seed, same walk and same filter random numbers in all three runs.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace

import numpy as np

from mcl.tools.replay import replay

from .walk import parse_seeds
from .walk_log import to_robot_log
from .walk_sim import WalkScenario, simulate

VARIANTS = (("compensated", True, None), ("not compensated", False, None), ("no latency", True, 0.0))
PACES = (("walk", {}), ("fast walk", {"max_speed": 0.4, "max_turn_rate": 1.5}))


def run_seed(seed: int, latency: float, particles: int, scenario: WalkScenario) -> dict:
    walk = simulate(scenario, seed)
    out = {"seed": seed}
    for name, compensate, override in VARIANTS:
        log = to_robot_log(walk, latency=latency if override is None else override)
        result = replay(
            log, scenario.field, particles=particles, seed=seed, compensate_latency=compensate, start=tuple(walk.start)
        )
        has_truth = result.has_truth  # the last step, held until the last frame arrives, has none
        position, heading = result.position_errors[has_truth], result.heading_errors[has_truth]
        out[name] = {
            "position_median_m": float(np.median(position)),
            "position_p95_m": float(np.percentile(position, 95)),
            "heading_median_deg": math.degrees(float(np.median(heading))),
        }
    return out


def summarize(runs: list[dict]) -> dict:
    return {
        name: {key: float(np.median([r[name][key] for r in runs])) for key in runs[0][name]} for name, _, _ in VARIANTS
    }


PROG = "robocup-mcl demo latency"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument("--latency", type=float, default=0.08, help="camera latency [s] (default 0.08)")
    parser.add_argument("--seeds", default="0-9", help='seeds: "0-9", "3" or "1,4,7" (default 0-9)')
    parser.add_argument("--particles", type=int, default=500, help="particles (default 500)")
    parser.add_argument("--duration", type=float, default=60.0, help="seconds of each walk (default 60)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    add_save_option(parser)
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl demo latency` (see --help); returns the exit status."""
    from mcl.tools.cli_checks import progress_bar, progress_wanted

    from .walk import warm_up_walk

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    from mcl.tools.cli_checks import check_output_file, save_json

    check_output_file(args.save, "--save")
    if not (math.isfinite(args.latency) and 0 <= args.latency <= 1.0):
        parser.error(f"--latency {args.latency} must be within [0, 1] s")
    if args.particles <= 0:
        parser.error(f"--particles {args.particles} must be > 0")
    if not (math.isfinite(args.duration) and args.duration > 0):
        parser.error(f"--duration {args.duration} must be > 0 s")
    try:
        seeds = parse_seeds(args.seeds)
    except ValueError:
        parser.error(f"--seeds {args.seeds!r}: give seeds as 3, 0-9 or 1,4,7")
    progress = progress_wanted(args)
    warm_up_walk(WalkScenario(), "velocity-linear", progress=progress)  # the first run says it compiles
    result = {"latency_s": args.latency, "particles": args.particles, "duration_s": args.duration}
    bar = progress_bar(enabled=progress, total=len(PACES) * len(seeds), desc="latency", unit="seed")
    for pace, changes in PACES:
        scenario = replace(WalkScenario(), duration=args.duration, kidnap_time=None, **changes)
        runs = []
        for seed in seeds:
            bar.set_postfix_str(f"{pace}, seed {seed}")
            runs.append(run_seed(seed, args.latency, args.particles, scenario))
            bar.update(1)
        result[pace] = {"runs": runs, "summary": summarize(runs)}
    bar.close()
    save_json(args.save, result)
    if args.json:
        json.dump(result, sys.stdout, indent=2)
        print()
        return 0
    print(
        f"walk scenario, {args.duration:.0f} s, camera latency {1e3 * args.latency:.0f} ms, "
        f"{args.particles} particles, seeds {args.seeds}; errors over every step, started at the true pose"
    )
    print(f"{'':>10} {'':>16} {'position median':>16} {'position p95':>13} {'heading median':>15}")
    for pace, _ in PACES:
        for name, _, _ in VARIANTS:
            s = result[pace]["summary"][name]
            print(
                f"{pace:>10} {name:>16} {100 * s['position_median_m']:>13.1f} cm "
                f"{100 * s['position_p95_m']:>10.1f} cm {s['heading_median_deg']:>13.2f}°"
            )
    print("(medians over the seeds of each run's figure)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
