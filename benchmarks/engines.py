"""`robocup-mcl bench engines`: the filter's step on its numpy reference engine against the compiled engine.

    robocup-mcl bench engines [--sizes 100,1000,10000] [--steps 20] [--rounds 3] [--json] [--save PATH]

For each particle count N, two filters built alike but for `reference=True` (`mcl.engine.ReferenceEngine`, every
stage in numpy) step through the same frames: velocity-linear motion, eight landmarks a frame, resampling every
step (threshold 1), one thread, no injection (the detections fit). Per step, the best of `rounds` alternated
rounds, in µs and ns per particle, and the ratio reference / compiled. The two filters start from the same
particles and seed, so the run also says how far apart they ended (largest difference of a pose coordinate, of
a weight, of the estimate's pose): the engines give the same results to rounding, and speed never changes them.
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

PROG = "robocup-mcl bench engines"
TRUE_POSE = np.array([1.5, -1.0, 0.7])
KINDS = ("goalpost", "penalty_mark", "t_crossing", "x_crossing")


def _frame(field, pose):
    from sensing import Observations

    rows = []
    for kind in KINDS:
        for target in field.landmarks_of(kind)[:2]:
            d = target - pose[:2]
            rows.append((kind, math.hypot(*d), math.atan2(d[1], d[0]) - pose[2]))
    return Observations.from_arrays(*zip(*rows))


def _filters(n: int):
    from field import spl
    from mcl import ParticleFilter
    from motion_models import VelocityLinear
    from sensing import LandmarkSensorModel

    field = spl()
    made = []
    for reference in (False, True):
        pf = ParticleFilter(
            field,
            VelocityLinear(),
            LandmarkSensorModel(field),
            n_particles=n,
            seed=0,
            resample_threshold=1.0,
            augmented=None,
            reference=reference,
        )
        pf.reset_around(TRUE_POSE, (0.1, 0.1, 0.1))
        made.append(pf)
    return field, made


def _seconds_per_step(pf, frames, u) -> float:
    started = time.perf_counter()
    for frame in frames:
        pf.step(u, frame)
        pf.entropy()
    return (time.perf_counter() - started) / len(frames)


def run(sizes=(100, 1000, 10000), steps: int = 20, rounds: int = 3, progress: bool = False) -> dict:
    """The figures (see the module docstring), JSON-ready; `progress`: a bar on stderr over the sizes."""
    from mcl.tools.cli_checks import progress_bar
    from motion_models import MotionInput

    u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1))
    rows = []
    bar = progress_bar(enabled=progress, total=len(sizes), desc="bench engines", unit="size")
    for n in sizes:
        field, (compiled, reference) = _filters(int(n))
        frames = [_frame(field, TRUE_POSE) for _ in range(steps)]
        _seconds_per_step(compiled, frames[:2], u)  # warm up: compile or load the kernels
        _seconds_per_step(reference, frames[:2], u)
        best = {"compiled": math.inf, "reference": math.inf}
        for _ in range(rounds):
            best["compiled"] = min(best["compiled"], _seconds_per_step(compiled, frames, u))
            best["reference"] = min(best["reference"], _seconds_per_step(reference, frames, u))
        a, b = compiled.estimate(), reference.estimate()
        rows.append(
            {
                "particles": int(n),
                "compiled_us": best["compiled"] * 1e6,
                "reference_us": best["reference"] * 1e6,
                "compiled_ns_per_particle": best["compiled"] * 1e9 / n,
                "reference_ns_per_particle": best["reference"] * 1e9 / n,
                "ratio": best["reference"] / best["compiled"],
                "steps": (rounds + 1) * steps + 2,
                "largest_difference": {
                    "pose_coordinate": float(np.abs(compiled.poses - reference.poses).max()),
                    "weight": float(np.abs(compiled.weights - reference.weights).max()),
                    "estimate": float(np.abs(a.pose - b.pose).max()),
                },
            }
        )
        bar.update(1)
    bar.close()
    return {"benchmark": "engines", "steps": steps, "rounds": rounds, "rows": rows}


def format_report(result: dict) -> str:
    lines = [
        f"the filter's step (velocity-linear, 8 landmarks, resampling every step, one thread), best of "
        f"{result['rounds']} rounds of {result['steps']} steps:",
        "         N   compiled µs   reference µs   compiled ns/p   reference ns/p   ratio   largest difference "
        "(pose, weight, estimate)",
    ]
    for row in result["rows"]:
        d = row["largest_difference"]
        lines.append(
            f"  {row['particles']:8d}  {row['compiled_us']:12.1f}  {row['reference_us']:13.1f}  "
            f"{row['compiled_ns_per_particle']:14.1f}  {row['reference_ns_per_particle']:15.1f}  "
            f"{row['ratio']:6.1f}x   {d['pose_coordinate']:.1e}, {d['weight']:.1e}, {d['estimate']:.1e}"
        )
    return "\n".join(lines)


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    from mcl.tools.cli_checks import add_progress_option, description, positive_int

    def sizes(text: str) -> tuple[int, ...]:
        try:
            values = tuple(int(v) for v in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"--sizes {text!r}: comma-separated whole numbers") from None
        if not values or any(v < 1 or v > 1_000_000 for v in values):
            raise argparse.ArgumentTypeError(f"--sizes {text!r}: each within 1..1000000")
        return values

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument(
        "--sizes", type=sizes, default=(100, 1000, 10000), help="particle counts (default 100,1000,10000)"
    )
    parser.add_argument("--steps", type=positive_int, default=20, help="steps per round (default 20)")
    parser.add_argument("--rounds", type=positive_int, default=3, help="alternated rounds (default 3)")
    parser.add_argument("--json", action="store_true", help="the results as JSON on stdout instead of text")
    parser.add_argument("--save", metavar="PATH", help="also write the JSON results to PATH")
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """The command line (see the module docstring)."""
    from mcl.tools.cli_checks import check_output_file, progress_wanted, save_json

    args = build_parser(prog).parse_args(argv)
    check_output_file(args.save, "--save", make_parents=False)
    result = run(args.sizes, args.steps, args.rounds, progress=progress_wanted(args))
    save_json(args.save, result)
    print(json.dumps(result, indent=2) if args.json else format_report(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
