"""`robocup-mcl bench same`: does a change leave the results bit for bit? This tree against another revision.

    robocup-mcl bench same REV [--seeds 20] [--sections battery,walk,papers,replay] [--json] [--save PATH]
    robocup-mcl bench same [--seeds 20] [--json]            # this tree's fingerprints only

Each side runs, in a fresh process that imports that side's packages, what the project promises not to move
when only its structure changes, and reduces every result to a SHA-256 fingerprint of its exact bits:

- battery: every run of the scenario battery (`robocup-mcl eval`), training and held-out seeds, each family,
  each seed: its figures without the wall-clock ones (`loop_s`);
- walk: the walk demo's estimates and entropy per step, each model, three seeds;
- papers: the paper demos' figures (`demo velocity`, `demo collision`, `demo odometry` with --json), without
  their timings (the `timing` section, compile and learning seconds) and whether the kernels were cached;
- replay: a simulated robot log replayed (`robocup-mcl replay`): estimates, entropy, quality, is_lost.

REV is a git revision of this repository or the path of another checkout (as for `bench compare`: exported
once to the cache and kept). The side's own code runs the cases through public calls that both the old and
the new layout have, so a revision from before a move compares too. Every fingerprint is printed with
"same" or "DIFFERENT"; the exit status is 1 when any differs, 0 when all are the same. The bits depend on
the processor and the numeric libraries, so both sides run here, with this interpreter.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import sys
from pathlib import Path

PROG = "robocup-mcl bench same"
SECTIONS = ("battery", "walk", "papers", "replay")
WALK_MODELS = ("constant", "velocity-linear")
WALK_SEEDS = (0, 1, 2)
PAPER_DEMOS = ("velocity", "collision", "odometry")
# Wall-clock figures, and whether numba's cache was warm: they differ between any two runs of the same code.
CLOCK_KEYS = {
    "loop_s",
    "timing",
    "compile_seconds",
    "learning_seconds",
    "elapsed_s",
    "first_step_s",
    "ms_per_step",
    "seconds_total",
    "kernels_cached",
}


# -- the fingerprints (run inside a side's tree) ---------------------------------------------------------------------
def digest(value) -> str:
    """SHA-256 of a value's exact bits: arrays by dtype, shape and bytes; anything else as canonical JSON (floats
    by repr, which round-trips every bit)."""
    import numpy as np

    hasher = hashlib.sha256()
    if isinstance(value, np.ndarray):
        hasher.update(f"{value.dtype.str}{value.shape}".encode())
        hasher.update(np.ascontiguousarray(value).tobytes())
    else:
        hasher.update(json.dumps(value, sort_keys=True, allow_nan=True, default=repr).encode())
    return hasher.hexdigest()


def without_clock(value, top: bool = True):
    """`value` without its wall-clock figures (CLOCK_KEYS at any depth; "seconds" at the top only, where it is
    the run's duration rather than a figure's time axis)."""
    if isinstance(value, dict):
        return {
            k: without_clock(v, False) for k, v in value.items() if k not in CLOCK_KEYS and not (top and k == "seconds")
        }
    if isinstance(value, list):
        return [without_clock(v, False) for v in value]
    return value


def battery_prints(seeds: int, jobs: int) -> dict[str, str]:
    from demos.battery import FAMILIES, run_battery

    results = run_battery(list(FAMILIES), ["train", "holdout"], seeds, jobs=jobs)
    prints = {}
    for split, part in results["splits"].items():
        for family, block in part["families"].items():
            for run in block["runs"]:
                prints[f"battery/{split}/{family}/{run['seed']}"] = digest(without_clock(run))
    return prints


def walk_prints() -> dict[str, str]:
    from demos.walk import run_walk

    prints = {}
    for model in WALK_MODELS:
        for seed in WALK_SEEDS:
            series = run_walk(model, 500, seed=seed, series=True)["series"]
            prints[f"walk/{model}/{seed}"] = digest([digest(series["estimates"]), digest(series["entropy"])])
    return prints


def paper_prints() -> dict[str, str]:
    import importlib

    prints = {}
    for name in PAPER_DEMOS:
        out = io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
            status = importlib.import_module(f"demos.{name}").main(["--json"])
        if status:
            raise RuntimeError(f"demo {name} exited {status}")
        prints[f"papers/{name}"] = digest(without_clock(json.loads(out.getvalue())))
    return prints


def replay_prints() -> dict[str, str]:
    from dataclasses import replace

    from demos.walk_log import to_robot_log
    from demos.walk_sim import WalkScenario, simulate
    from field import spl

    try:
        from mcl.tools.replay import replay
    except ImportError:  # a revision from before the tools moved
        from mcl.replay import replay  # type: ignore[no-redef]

    scenario = replace(WalkScenario(), duration=30.0, kidnap_time=15.0)
    prints = {}
    for seed in (0, 1):
        result = replay(to_robot_log(simulate(scenario, seed), latency=0.05), spl(), particles=500, seed=seed)
        prints[f"replay/{seed}"] = digest(
            [
                digest(result.estimates),
                digest(result.entropy),
                digest(result.quality.astype("int64")),
                digest(result.lost.astype("int64")),
            ]
        )
    return prints


def fingerprints(sections, seeds: int, jobs: int) -> dict[str, str]:
    """Every fingerprint of this process's tree, by case name."""
    prints: dict[str, str] = {}
    if "battery" in sections:
        prints.update(battery_prints(seeds, jobs))
    if "walk" in sections:
        prints.update(walk_prints())
    if "papers" in sections:
        prints.update(paper_prints())
    if "replay" in sections:
        prints.update(replay_prints())
    return prints


# -- the two sides ---------------------------------------------------------------------------------------------------
def run_side(root: Path, sections, seeds: int, jobs: int, label: str) -> dict[str, str]:
    """The fingerprints of the tree at `root`, from this file run in a fresh process that imports that tree."""
    from benchmarks.compare import Side, run_json

    command = [
        sys.executable,
        str(Path(__file__).resolve()),
        "--inside",
        "--sections",
        ",".join(sections),
        "--seeds",
        str(seeds),
        "--jobs",
        str(jobs),
    ]
    return run_json(Side(label, root), command, "cases")


def compare(base: dict[str, str], current: dict[str, str]) -> list[dict]:
    """One row per case either side ran: its two fingerprints and whether they are the same."""
    return [
        {
            "case": case,
            "base": base.get(case),
            "current": current.get(case),
            "same": base.get(case) is not None and base.get(case) == current.get(case),
        }
        for case in sorted(set(base) | set(current))
    ]


def summary_lines(rows: list[dict]) -> list[str]:
    """The report: battery runs counted per split and family, every other case on a line of its own."""
    lines, groups = [], {}
    for row in rows:
        parts = row["case"].split("/")
        if parts[0] == "battery":
            groups.setdefault("/".join(parts[:3]), []).append(row)
        else:
            lines.append(f"  {row['case']:<38} {'same' if row['same'] else 'DIFFERENT'}")
    battery = [
        f"  {group:<38} {sum(r['same'] for r in runs)}/{len(runs)} runs same"
        + (
            ""
            if all(r["same"] for r in runs)
            else "  DIFFERENT: seeds " + ", ".join(r["case"].rsplit("/", 1)[1] for r in runs if not r["same"])
        )
        for group, runs in sorted(groups.items())
    ]
    return battery + lines


def report_text(result: dict) -> str:
    """The printed report of a comparison's result (as `--json` prints and `--save` writes it)."""
    same = result["cases"] - len(result["different"])
    head = f"{result['base']} against the {result['current']}: {same}/{result['cases']} cases bit for bit the same"
    return "\n".join([head] + summary_lines(result["rows"]))


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "revision",
        nargs="?",
        help="a git revision or another checkout's directory to compare "
        "with (default: only print this tree's fingerprints)",
    )
    parser.add_argument("--seeds", type=int, default=20, help="battery seeds per family and split (default 20)")
    parser.add_argument(
        "--sections", default=",".join(SECTIONS), help=f"comma-separated, from {', '.join(SECTIONS)} (default: all)"
    )
    parser.add_argument("--jobs", type=int, default=2, help="battery worker processes per side (default 2)")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON")
    parser.add_argument("--save", metavar="PATH", help="also write the JSON result to PATH")
    parser.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bars (there are none: each side says on stderr when it starts)",
    )
    parser.add_argument(
        "--show", metavar="PATH", help="print the report of a result saved with --save, and run nothing"
    )
    parser.add_argument("--inside", action="store_true", help=argparse.SUPPRESS)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    sections = [s for s in args.sections.split(",") if s]
    if not sections or any(s not in SECTIONS for s in sections):
        parser.error(f"--sections: choose from {', '.join(SECTIONS)}")
    if args.seeds < 1 or args.jobs < 1:
        parser.error("--seeds and --jobs must be at least 1")
    if args.show:
        with open(args.show, encoding="utf-8") as saved:
            print(report_text(json.load(saved)))
        return 0
    if args.inside:  # the fresh process of one side: its fingerprints as JSON on stdout
        print(json.dumps(fingerprints(sections, args.seeds, args.jobs)))
        return 0
    from benchmarks.compare import base_side, current_side
    from mcl.tools.cli_checks import check_output_file, save_and_print

    if args.save:
        check_output_file(args.save, "--save")
    current = current_side()
    print(f"{PROG}: running the cases on {current.label}", file=sys.stderr)
    current_prints = run_side(current.root, sections, args.seeds, args.jobs, current.label)
    if args.revision is None:
        result: dict = {"sections": sections, "seeds": args.seeds, "current": current_prints}
        save_and_print(
            result,
            args.save,
            args.json,
            lambda r: print("\n".join(f"{case} {value}" for case, value in sorted(r["current"].items()))),
        )
        return 0
    base = base_side(args.revision)
    print(f"{PROG}: running the cases on {base.label}", file=sys.stderr)
    base_prints = run_side(base.root, sections, args.seeds, args.jobs, base.label)
    rows = compare(base_prints, current_prints)
    differ = [row["case"] for row in rows if not row["same"]]
    result = {
        "base": base.label,
        "current": current.label,
        "sections": sections,
        "seeds": args.seeds,
        "cases": len(rows),
        "different": differ,
        "rows": rows,
    }
    save_and_print(result, args.save, args.json, lambda r: print(report_text(r)))

    return 1 if differ else 0


if __name__ == "__main__":
    if "--inside" in sys.argv:  # run as a file inside a side's tree: that tree's packages, not this folder's
        sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
    raise SystemExit(main())
