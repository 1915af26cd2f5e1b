"""Instructions per filter step, counted by valgrind, in this checkout and in another revision.

    python -m benchmarks.instructions REV [--current REV] [--particles 500,5000] [--steps 1000] [--json]
                                      [--save PATH]

Wall-clock comparisons on a shared machine move by 10–20 % from run to run (`robocup-mcl bench compare`), so a
change of a few percent cannot be shown with them. The number of instructions a step executes can: valgrind's
callgrind counts them, and the count is the same for the same binary, inputs and environment whatever else
the machine is doing. It is not time (a cache miss costs more than an add), but code that executes the same
instructions per step runs at the same speed on the same machine.

What runs, in each tree (REV exported as `robocup-mcl bench compare` exports it; this checkout as it is on
disk), for each particle count N: a fresh process builds `ParticleFilter(spl(), VelocityLinear(),
LandmarkSensorModel(spl()), n_particles=N, seed=0)` and runs K filter steps (`step`: a walk command, and a
frame of four detections every third step), then K more. The process runs twice under callgrind, once with
K steps and once with 2K; the difference of the two totals is the instructions of K steps, free of the
start-up (interpreter, imports, loading the compiled kernels) that both runs share. Before the counted runs,
one plain run fills each tree's numba cache, so nothing is compiled under valgrind. Every run compiles for a
generic x86-64 CPU (`NUMBA_CPU_NAME=generic`): valgrind presents the program with other CPU features than the
host's, under which numba would not find the host's cached kernels; the counts are of that generic code, the
same in both trees.

The result: instructions per step for each tree and N, and their ratio (current / base).
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.compare import CompareError, Side, base_side, current_side, side_environment
from mcl.tools.cli_checks import save_json

WORKLOAD = """
import sys
from field import spl
from mcl import ParticleFilter
from motion_models import MotionInput, VelocityLinear
from sensing import Observations, LandmarkSensorModel
n, steps = int(sys.argv[1]), int(sys.argv[2])
field = spl()
pf = ParticleFilter(field, VelocityLinear(), LandmarkSensorModel(field), n_particles=n, seed=0)
u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1))
frame = Observations.from_arrays(["goalpost", "goalpost", "T", "L"], [3.1, 3.4, 2.2, 4.0], [0.3, -0.2, -0.6, 1.1])
for k in range(steps):
    pf.step(u, frame if k % 3 == 0 else None)
print(float(pf.estimate().pose[0]))
"""


# Every run: the same hash seed, and numba's code for a generic x86-64 CPU (see the module docstring).
RUN_ENVIRONMENT = {"PYTHONHASHSEED": "0", "NUMBA_CPU_NAME": "generic", "NUMBA_CPU_FEATURES": ""}


def _run(side: Side, n: int, steps: int, valgrind: bool) -> int | None:
    """Run the workload in `side`; under callgrind, the total instructions it executed."""
    command = [sys.executable, "-c", WORKLOAD, str(n), str(steps)]
    out = None
    if valgrind:
        out = Path(tempfile.mkdtemp(prefix="callgrind-")) / "callgrind.out"
        command = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", "--dump-instr=no"] + command
    done = subprocess.run(
        command, cwd=side.root, env=side_environment(side, **RUN_ENVIRONMENT), capture_output=True, text=True
    )
    if done.returncode != 0:
        raise CompareError(
            f"the workload in {side.label} failed (exit {done.returncode}):\n"
            + "\n".join(done.stderr.strip().splitlines()[-15:])
        )
    if out is None:
        return None
    try:
        match = re.search(r"^(?:summary|totals):\s+(\d+)", out.read_text(), flags=re.M)
    finally:
        shutil.rmtree(out.parent, ignore_errors=True)
    if match is None:
        raise CompareError(f"callgrind wrote no total for {side.label}")
    return int(match.group(1))


def per_step(side: Side, n: int, steps: int) -> dict:
    """Instructions per step of `side` at N = n, from the runs of `steps` and 2·`steps` steps."""
    short, long = _run(side, n, steps, True), _run(side, n, 2 * steps, True)
    return {"short_total": short, "long_total": long, "per_step": (long - short) / steps}


def measure(base: Side, current: Side, sizes: list[int], steps: int, progress=print) -> list[dict]:
    """Each N: both trees' instructions per step and the ratio current / base."""
    for side in (base, current):  # fill the numba caches: nothing compiles under valgrind
        progress(f"warming the compiled kernels of {side.label}")
        _run(side, sizes[0], 3, False)
    rows = []
    for n in sizes:
        progress(f"N = {n}: counting {base.label}")
        b = per_step(base, n, steps)
        progress(f"N = {n}: counting {current.label}")
        c = per_step(current, n, steps)
        rows.append({"particles": n, "base": b, "current": c, "ratio": c["per_step"] / b["per_step"]})
    return rows


def report(base: Side, current: Side, steps: int, rows: list[dict]) -> str:
    lines = [
        f"instructions per filter step (callgrind; {steps} and {2 * steps} steps, the difference): "
        f"base {base.label}, current {current.label}",
        f"{'N':>8} {'base':>14} {'current':>14} {'ratio':>7}",
    ]
    lines += [
        f"{r['particles']:>8} {r['base']['per_step']:>14,.0f} {r['current']['per_step']:>14,.0f} {r['ratio']:>7.3f}"
        for r in rows
    ]
    return "\n".join(lines)


def build_parser(prog: str = "python -m benchmarks.instructions") -> argparse.ArgumentParser:
    """The command's argument parser."""
    parser = argparse.ArgumentParser(
        prog=prog,
        description="Instructions per filter step under valgrind's "
        "callgrind, in this checkout and in another revision.",
    )
    parser.add_argument(
        "revision", metavar="REV", help="a git revision of this repository, or another checkout's directory"
    )
    parser.add_argument(
        "--current",
        metavar="REV",
        help="measure this revision instead of the working tree "
        "(exported the same way; a tree nobody edits while valgrind runs)",
    )
    parser.add_argument(
        "--particles", default="500,5000", metavar="N,...", help="particle counts, comma-separated (default 500,5000)"
    )
    parser.add_argument(
        "--steps",
        type=int,
        default=1000,
        metavar="K",
        help="steps of the shorter run; the longer runs 2K (default 1000: the steps must outweigh the start-up's variation)",
    )
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--save", metavar="PATH", help="also write the JSON result to PATH")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        sizes = [int(v) for v in args.particles.split(",") if v.strip()]
    except ValueError:
        raise SystemExit(f"instructions: --particles takes integers, not {args.particles!r}") from None
    if not sizes or min(sizes) < 1 or args.steps < 1:
        raise SystemExit("instructions: particle counts and --steps must be >= 1")
    if shutil.which("valgrind") is None:
        raise SystemExit("instructions: valgrind is not installed (Debian: apt-get install valgrind)")
    base = base_side(args.revision)
    current = base_side(args.current) if args.current else current_side()
    rows = measure(base, current, sizes, args.steps, progress=lambda text: print(text, file=sys.stderr))
    result = {"base": base.label, "current": current.label, "steps": args.steps, "rows": rows}
    save_json(args.save, result)
    print(json.dumps(result, indent=1) if args.json else report(base, current, args.steps, rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
