"""`robocup-mcl bench`: the benchmark suite: the filter step whole and phase by phase against plain numpy, per N.

    robocup-mcl bench [--sizes 100,1000,...] [--quick] [--json] [--save PATH] [--plot PATH.png]
                      [--no-startup] [--no-exact] [--skip SECTION,...] [--budget SECONDS]
    robocup-mcl bench step ...        # the same

What it measures, all in one run so that ratios compare like with like (candidates are called in turn and
medians taken; the machine may be busy with other work). JSON keys first, the --skip name in brackets:

- rows: the full step (predict, 10 goalpost detections, normalize + ESS, systematic resampling, estimate,
  entropy) and each phase, in ns per particle at each N (default 100 ... 1 000 000), numba against the plain
  numpy twin (`benchmarks.reference`): motion models (velocity-linear, adaptive), landmark likelihood (von Mises
  and exact atan2 bearing [exact: --no-exact]), line likelihood, normalize + ESS, resampling, injection,
  estimate, entropy, recording to Rerun [recording]; `phases` says what each phase calls;
- resampling [peers]: our systematic resampler against filterpy's and particles' (`pip install -e
  '.[bench]'`; reported "not installed" without them) and its numpy twin;
- threads [threads]: two threads against one at N >= 10⁵, if the filter has a threads option;
- memory [memory]: tracemalloc's scratch memory and memory kept per step at N = 10⁴ and 10⁵, and the arrays
  the kernels allocate;
- startup, demo_walk [startup, or --no-startup]: a fresh process to its first step with an empty numba
  cache (the compile time) and with the cache found; `robocup-mcl demo walk --duration 0.1` with the cache;
- numpy_without_avx512 [avx512]: the numpy step in processes with numpy's AVX-512 code switched off
  (NPY_DISABLE_CPU_FEATURES), alternated with processes with numpy as it is;
- models [models]: LWPR update and predict (2 inputs), velocity-EKF predict and correct, and the README
  robot loop's calls at N = 500 (a frame without detections, predict alone, correct with a list of
  detections, building a batch; the Localizer's frame, its latency-compensated observe, and a frame of a young
  track with its rival places), in µs;
- between_frames [frames]: the full step and the issue's step shape at N <= 1 000, one call after each 10 ms
  sleep (a 100 Hz loop: the caches as the time between frames leaves them), in µs;
- bearing_accuracy [accuracy]: what the von Mises bearing term costs in accuracy (total-variation distance
  between its normalized weights and the exact term's);
- machine, settings, targets (each "met", "NOT MET" or "not measured" with the reason), duration_s.

--quick: N = 100, 1 000, 10 000, fewer samples, no empty-cache compile (about half a minute).
--json prints the result as JSON instead of the table; --save writes the JSON to a file; --plot draws the
scaling curves to a PNG (needs matplotlib). Progress goes to stderr.

A robot's instruction set on this machine: numba compiles for the target that NUMBA_CPU_NAME and
NUMBA_CPU_FEATURES name (with a NUMBA_CACHE_DIR of its own), and the header says so. The NAO's Atom E3845,
for one: NUMBA_CPU_NAME=silvermont NUMBA_CPU_FEATURES=+sse4.2,+popcnt,-avx,-avx2,-fma (the README's Speed
section has the whole command).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import traceback
from pathlib import Path

from .step import PHASES, bearing_accuracy, bench_setup

__all__ = ["main", "run", "bench_setup", "bearing_accuracy", "PHASES", "SIZES", "QUICK_SIZES", "SECTIONS"]

SIZES = (100, 1_000, 10_000, 100_000, 1_000_000)
QUICK_SIZES = (100, 1_000, 10_000)
MEMORY_SIZES = (10_000, 100_000)
SECTIONS = ("peers", "threads", "memory", "avx512", "startup", "models", "frames", "recording", "accuracy")
BUDGET_S = 0.4  # seconds of samples per timed item
QUICK_BUDGET_S = 0.05
SCHEMA = 2


_BAR = None  # the run's progress bar (`run` with progress=True), else None: one line per section


def _progress(text: str, done: bool = False) -> None:
    """Say which section starts (or, `done`, ends): the bar's label (and count) when a bar is on, else one line
    on stderr."""
    if _BAR is not None:
        _BAR.set_postfix_str(text, refresh=not done)
        if done:
            _BAR.update(1)
        return
    print(f"bench: {text}", file=sys.stderr, flush=True)


def _guarded(name: str, fn, *args, **kwargs) -> dict:
    """Run one section; a failure is reported in its place instead of ending the suite."""
    start = time.perf_counter()
    try:
        section = fn(*args, **kwargs)
    except Exception as error:  # the suite reports every section it can
        section = {"error": f"{type(error).__name__}: {error}", "traceback": traceback.format_exc(limit=4)}
    if isinstance(section, dict):
        section["seconds"] = time.perf_counter() - start
    _progress(f"{name} done in {time.perf_counter() - start:.1f} s", done=True)
    return section


def _models(budget_s: float) -> dict:
    from .models import time_ekf, time_lwpr, time_robot_loop

    result = {}
    for key, fn, args in (
        ("lwpr", time_lwpr, ()),
        ("ekf", time_ekf, (budget_s,)),
        ("robot_loop", time_robot_loop, (budget_s,)),
    ):
        try:
            result[key] = fn(*args)
        except Exception as error:
            result[key] = None
            result[f"{key}_error"] = f"{type(error).__name__}: {error}"
    return result


def run(
    sizes=SIZES,
    quick: bool = False,
    startup: bool = True,
    exact: bool = True,
    skip=(),
    budget_s: float | None = None,
    progress: bool = False,
) -> dict:
    """The whole suite; returns the result (see the module docstring for its sections). progress: a bar on
    stderr counting the sections, with the current one's name and the time spent (instead of a line each)."""
    global _BAR
    from mcl.tools.cli_checks import progress_bar

    _BAR = (
        progress_bar(
            enabled=True, desc="bench", unit="section", bar_format="{desc}: {n} sections done [{elapsed}] {postfix}"
        )
        if progress
        else None
    )
    try:
        return _run(sizes, quick, startup, exact, skip, budget_s)
    finally:
        if _BAR is not None:
            _BAR.close()
        _BAR = None


def _run(sizes, quick: bool, startup: bool, exact: bool, skip, budget_s: float | None) -> dict:
    from .report import evaluate_targets
    from .step import time_resamplers, time_size, time_threads
    from .system import load_average, machine, memory, numpy_without_avx512, time_demo_walk, time_startup

    skip = set(skip)
    if not startup:
        skip.add("startup")
    budget = budget_s if budget_s is not None else (QUICK_BUDGET_S if quick else BUDGET_S)
    started = time.perf_counter()
    result: dict = {
        "benchmark": "robocup-mcl bench",
        "schema": SCHEMA,
        "machine": machine(),
        "settings": {
            "sizes": list(sizes),
            "quick": quick,
            "budget_s": budget,
            "exact": exact,
            "skipped": sorted(skip),
            "threads": 1,
            "step": "predict (velocity-linear), 10 goalpost detections (von Mises bearing), "
            "normalize + ESS, systematic resampling every step, estimate, entropy",
        },
        "phases": [
            {"name": p.name, "description": p.description, "numba": p.numba_entry, "numpy": p.numpy_entry}
            for p in PHASES
        ],
    }
    rows = []
    for n in sizes:
        _progress(f"N = {n}: full step and phases")
        rows.append(time_size(n, budget, exact=exact, recording="recording" not in skip))
    result["rows"] = rows
    if "peers" not in skip:
        _progress("resampling against filterpy and particles")
        result["resampling"] = _guarded("resampling", time_resamplers, sizes, budget)
    if "threads" not in skip:
        result["threads"] = _guarded("threads", time_threads, sizes, budget)
    if "memory" not in skip:
        _progress(f"memory at N = {', '.join(str(n) for n in MEMORY_SIZES)}")
        result["memory"] = _guarded("memory", memory, MEMORY_SIZES)
    if "avx512" not in skip:
        _progress("numpy step with AVX-512 off")
        result["numpy_without_avx512"] = _guarded(
            "numpy without AVX-512", numpy_without_avx512, sizes, budget, rounds=1 if quick else 2
        )
    if "startup" not in skip:
        _progress("start-up" + ("" if quick else " (empty numba cache: compiles every kernel of the step)"))
        result["startup"] = _guarded("start-up", time_startup, cold=not quick, warm_runs=1 if quick else 2)
        result["demo_walk"] = _guarded("demo walk", time_demo_walk, runs=1 if quick else 2)
    if "models" not in skip:
        result["models"] = _guarded("models", _models, budget)
    if "frames" not in skip and any(n <= 1_000 for n in sizes):
        from .models import time_between_frames

        _progress("between frames: the step after 10 ms asleep")
        result["between_frames"] = _guarded("between frames", time_between_frames, sizes, samples=10 if quick else 40)
    if "accuracy" not in skip:
        result["bearing_accuracy"] = _guarded("bearing accuracy", bearing_accuracy)
    result["machine"]["load_average_end"] = load_average()
    result["targets"] = evaluate_targets(result)
    result["duration_s"] = time.perf_counter() - started
    return result


def parse_sizes(parser: argparse.ArgumentParser, text: str) -> list[int]:
    """--sizes: particle counts > 0, comma-separated (a parser error otherwise)."""
    try:
        sizes = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        parser.error(f"--sizes {text!r} must be comma-separated integers")
    if not sizes or min(sizes) <= 0:
        parser.error(f"--sizes {text!r} must name particle counts > 0")
    return sizes


PROG = "robocup-mcl bench"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, description

    parser = argparse.ArgumentParser(
        prog=prog,
        description=description(__doc__),
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split("\n\n", 2)[2],
    )
    parser.add_argument(
        "--sizes",
        help="particle counts, comma-separated (default 100,1000,10000,100000,1000000; with --quick 100,1000,10000)",
    )
    parser.add_argument(
        "--quick", action="store_true", help="a CI-sized run: small sizes, fewer samples, no empty-cache compile"
    )
    parser.add_argument("--json", action="store_true", help="print the result as JSON instead of the table")
    parser.add_argument("--save", metavar="PATH", help="write the result as JSON to PATH")
    parser.add_argument("--plot", metavar="PATH", help="draw the scaling curves to a PNG (needs matplotlib)")
    parser.add_argument(
        "--no-startup", action="store_true", help="skip the fresh-process timings (start-up, compile, demo walk)"
    )
    parser.add_argument("--no-exact", action="store_true", help="skip timing the exact (atan2) bearing term")
    parser.add_argument("--skip", default="", help=f"sections to leave out, comma-separated: {', '.join(SECTIONS)}")
    parser.add_argument(
        "--budget", type=float, help=f"seconds of samples per timed item (default {BUDGET_S}, --quick {QUICK_BUDGET_S})"
    )
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl bench` (see --help); returns the exit status."""
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    sizes = parse_sizes(parser, args.sizes) if args.sizes else list(QUICK_SIZES if args.quick else SIZES)
    skip = [s.strip() for s in args.skip.split(",") if s.strip()]
    unknown = sorted(set(skip) - set(SECTIONS))
    if unknown:
        parser.error(f"--skip {', '.join(unknown)}: choose from {', '.join(SECTIONS)}")
    if args.budget is not None and not args.budget > 0:
        parser.error(f"--budget {args.budget!r} must be > 0")
    if args.plot:
        from .report import matplotlib_missing

        if matplotlib_missing():
            parser.error("--plot needs matplotlib: pip install -e '.[bench]'")
    from mcl.tools.cli_checks import progress_wanted

    result = run(
        sizes,
        quick=args.quick,
        startup=not args.no_startup,
        exact=not args.no_exact,
        skip=skip,
        budget_s=args.budget,
        progress=progress_wanted(args),
    )
    for path in (args.save, args.plot):
        if path:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
    if args.save:
        with open(args.save, "w") as file:
            json.dump(result, file, indent=2)
            file.write("\n")
    if args.plot:
        from .report import plot

        plot(result, args.plot)
    if args.json:
        json.dump(result, sys.stdout, indent=2)
        print()
    else:
        from .report import format_report

        print(format_report(result))
    return 0
