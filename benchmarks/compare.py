"""`robocup-mcl bench compare`: this checkout's speed against another revision's, in alternated runs.

    robocup-mcl bench compare REV [--rounds 3] [--sizes 100,1000,10000,100000] [--skip SECTION,...]
                              [--threshold 0.1] [--json]

REV is a git revision of this repository (a commit, a tag, HEAD~3) or the path of another checkout. Its tree
is exported once to ~/.cache/robocup-mcl/compare/COMMIT (`git archive`; XDG_CACHE_HOME is honoured) and kept,
with the numba caches its first run compiles (about a minute), so comparing against it again starts at once.
The current side is this checkout as it is on disk, uncommitted changes included.

Each round runs `robocup-mcl bench --json` once in a fresh process in each tree, one after the other, the
order swapped every round (base first in odd rounds), so that a machine that slows down or speeds up
during the comparison weighs on both sides alike. Both sides use this interpreter and its packages. The
runs skip what does not compare code (the empty-cache compile, the peers, threads, memory, the AVX-512
switch, the accuracy; `--skip` replaces that list, "startup" and "exact" included).

It prints, for every figure both sides measured (the full step and its variants, each phase, in ns per
particle at each N; the models and the robot loop in µs): each side's values over the rounds, the ratio of
their medians (current / base: below 1 is faster), and a verdict: "faster" or "slower" only when the two
sides' ranges do not overlap and the medians differ by more than --threshold (default 10 %); else "~" ("-"
after a single round). Fresh processes running the same code differ by a few percent (where the code and
the arrays land in memory), often more than three rounds spread, so a smaller change needs more rounds and
a lower threshold to be seen, and many figures compared at once will show a few verdicts by chance. A run of
the default sizes takes one to two minutes.

--json prints the items, the two trees and every run's whole result (`robocup-mcl bench --json`'s).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mcl.numba_cache import ROOT, is_source_checkout

DEFAULT_SIZES = (100, 1_000, 10_000, 100_000)
DEFAULT_SKIP = ("startup", "exact", "peers", "threads", "memory", "avx512", "accuracy")
THRESHOLD = 0.1  # the smallest change a verdict names: processes that run the same code differ by a few
# percent (code and memory layout), more than the rounds' spread shows
SKIPPABLE = ("startup", "exact", "peers", "threads", "memory", "avx512", "models", "recording", "accuracy")
# Step variants of a row (its key, the label printed); every phase of the row follows them.
STEP_VARIANTS = (
    ("full_step", "full step"),
    ("full_step_back_to_back", "full step, back to back"),
    ("full_step_fast", "full step, fast=True"),
    ("issue_step", "issue's step shape"),
    ("issue_step_fast", "issue's step shape, fast=True"),
    ("injecting_step", "injecting step"),
    ("adaptive_step", "adaptive step"),
    ("full_step_exact_bearing", "full step, exact bearing"),
)


class CompareError(RuntimeError):
    """A side could not be prepared or run."""


@dataclass(frozen=True)
class Side:
    """One tree to benchmark: its label (a revision or "working tree") and its root directory."""

    label: str
    root: Path


# -- the trees -----------------------------------------------------------------------------------------------------
def cache_root() -> Path:
    """Where exported revisions are kept: $XDG_CACHE_HOME (or ~/.cache)/robocup-mcl/compare."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "robocup-mcl" / "compare"


def _git(repository: Path, *args: str) -> bytes:
    try:
        done = subprocess.run(["git", "-C", str(repository), *args], capture_output=True, check=False)
    except FileNotFoundError:
        raise CompareError("git is not installed: name a checkout's directory instead of a revision") from None
    if done.returncode != 0:
        message = done.stderr.decode(errors="replace").strip().splitlines()
        raise CompareError(f"git {' '.join(args)}: {message[-1] if message else f'exit {done.returncode}'}")
    return done.stdout


def base_side(revision: str, repository: Path = ROOT, cache: Path | None = None) -> Side:
    """The base tree: `revision` as a directory if it is another checkout, else that revision of `repository`
    exported to `cache`/COMMIT (once; the export is kept with the numba caches its runs compile)."""
    as_path = Path(revision).expanduser()
    if as_path.is_dir():
        if not is_source_checkout(as_path.resolve()):
            raise CompareError(
                f"{revision!r} is a directory but not a robocup-mcl checkout (no pyproject.toml naming it)"
            )
        return Side(str(as_path), as_path.resolve())
    commit = _git(repository, "rev-parse", "--verify", "--quiet", f"{revision}^{{commit}}").decode().strip()
    tree = (cache or cache_root()) / commit
    if not (tree / "pyproject.toml").exists():
        archive = _git(repository, "archive", "--format=tar", commit)
        tree.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{commit[:12]}-", dir=tree.parent))
        try:
            with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
                # "data": plain files and folders only (Python >= 3.11.4 has the filter; before, git's own
                # archive is taken as it is)
                tar.extractall(staging, **({"filter": "data"} if hasattr(tarfile, "data_filter") else {}))
            if not is_source_checkout(staging):
                raise CompareError(f"revision {revision} ({commit[:12]}) is not a robocup-mcl tree")
            try:
                staging.rename(tree)
            except OSError:  # another comparison exported it meanwhile
                if not (tree / "pyproject.toml").exists():
                    raise
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    return Side(f"{revision} ({commit[:12]})", tree)


def current_side(root: Path = ROOT) -> Side:
    """This checkout, as it is on disk."""
    if not is_source_checkout(root):
        raise CompareError(f"{root} is an installed copy: compare runs from a source checkout")
    return Side("working tree", root)


# -- the runs ------------------------------------------------------------------------------------------------------
def bench_arguments(sizes, skip) -> list[str]:
    """The `robocup-mcl bench` arguments of each run."""
    arguments = ["--json", "--sizes", ",".join(str(n) for n in sizes)]
    if "startup" in skip:
        arguments.append("--no-startup")
    if "exact" in skip:
        arguments.append("--no-exact")
    sections = [s for s in skip if s not in ("startup", "exact")]
    if sections:
        arguments += ["--skip", ",".join(sections)]
    return arguments


def side_environment(side: Side, **extra: str) -> dict:
    """This process's environment with `side`'s root first on PYTHONPATH (a fresh process then imports that
    tree's packages), and the variables `extra`."""
    return dict(
        os.environ,
        PYTHONPATH=os.pathsep.join(
            [str(side.root)] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])
        ),
        **extra,
    )


def cli_module(root: Path) -> str:
    """The module of `robocup-mcl` in the tree at `root`: `mcl.tools.cli`, or `mcl.cli` in a revision from
    before the tools moved to `mcl.tools`."""
    return "mcl.tools.cli" if (root / "mcl" / "tools" / "cli.py").exists() else "mcl.cli"


def run_json(side: Side, command: list[str], what: str) -> dict:
    """`command` in a fresh process that imports `side`'s packages (run in its root); the JSON it printed.
    CompareError, naming `what` and quoting the end of its stderr or stdout, when it fails or prints no JSON."""
    done = subprocess.run(
        command, cwd=side.root, env=side_environment(side), capture_output=True, text=True, check=False
    )
    if done.returncode != 0:
        raise CompareError(
            f"the {what} of {side.label} failed (exit {done.returncode}):\n"
            + "\n".join(done.stderr.strip().splitlines()[-15:])
        )
    try:
        return json.loads(done.stdout)
    except json.JSONDecodeError:
        raise CompareError(f"the {what} of {side.label} printed no JSON result:\n{done.stdout[-2000:]}") from None


def run_bench(side: Side, arguments: list[str]) -> dict:
    """`robocup-mcl bench ARGUMENTS` in a fresh process that imports `side`'s packages; its JSON result."""
    return run_json(side, [sys.executable, "-m", cli_module(side.root), "bench", *arguments], "bench")


def alternate(
    base: Side,
    current: Side,
    rounds: int,
    run: Callable[[Side], dict],
    progress: Callable[[str], None] = lambda text: None,
) -> tuple[list[dict], list[dict]]:
    """`rounds` runs of each side, the order swapped every round (base first in the first); the results of
    the base's runs and of the current's, each in round order."""
    results: dict[str, list[dict]] = {"base": [], "current": []}
    for r in range(rounds):
        order = (("base", base), ("current", current))
        for key, side in order if r % 2 == 0 else order[::-1]:
            progress(f"round {r + 1}/{rounds}: {side.label}")
            results[key].append(run(side))
    return results["base"], results["current"]


# -- the figures ---------------------------------------------------------------------------------------------------
def figures(result: dict) -> dict[str, tuple[str, float]]:
    """A bench result's comparable figures: label -> (unit, value)."""
    out: dict[str, tuple[str, float]] = {}
    for row in result.get("rows", []):
        n = row["n"]
        for key, label in STEP_VARIANTS:
            entry = row.get(key)
            if isinstance(entry, dict) and "numba_ns_per_particle" in entry:
                out[f"{label}, N = {n}"] = ("ns/particle", entry["numba_ns_per_particle"])
        for name, entry in row.get("phases", {}).items():
            if isinstance(entry, dict) and "numba_ns_per_particle" in entry:
                out[f"phase {name}, N = {n}"] = ("ns/particle", entry["numba_ns_per_particle"])
    models = result.get("models")
    if isinstance(models, dict):
        lwpr, ekf, loop = models.get("lwpr"), models.get("ekf"), models.get("robot_loop")
        if isinstance(lwpr, dict):
            for key in ("update_us", "predict_us"):
                if key in lwpr:
                    out[f"LWPR {key[:-3]}"] = ("µs", lwpr[key])
        if isinstance(ekf, dict):
            for variant, entry in ekf.items():
                for key in ("predict_us", "correct_us"):
                    if isinstance(entry, dict) and key in entry:
                        out[f"velocity EKF ({variant}) {key[:-3]}"] = ("µs", entry[key])
        if isinstance(loop, dict):
            for key, value in loop.items():
                if key.endswith("_us"):
                    out[f"robot loop, N = {loop.get('particles', '?')}: {key[:-3].replace('_', ' ')}"] = ("µs", value)
    frames = result.get("between_frames")
    if isinstance(frames, dict):
        for row in frames.get("rows", []):
            for key, label in (("full_step_us", "full step"), ("issue_step_us", "the issue's step shape")):
                if key in row:
                    out[f"between frames, N = {row['n']}: {label}"] = ("µs", row[key])
        for key, label in (("python_call_us", "a Python call"), ("numba_call_us", "a compiled call")):
            if key in frames:
                out[f"between frames: {label}"] = ("µs", frames[key])
    return out


def verdict(base: list[float], current: list[float], threshold: float = THRESHOLD) -> str:
    """ "faster" / "slower" when the two ranges do not overlap and the medians differ by more than `threshold`
    (a share), else "~"; "-" with one value a side (no spread to judge by)."""
    if len(base) < 2 or len(current) < 2:
        return "-"
    ratio = statistics.median(current) / statistics.median(base)
    if max(current) < min(base) and ratio < 1.0 - threshold:
        return "faster"
    if min(current) > max(base) and ratio > 1.0 + threshold:
        return "slower"
    return "~"


def compare(base_runs: list[dict], current_runs: list[dict], threshold: float = THRESHOLD) -> list[dict]:
    """The figures both sides measured in every run, in the current side's order: each side's values, the
    ratio of the medians (current / base) and the verdict."""
    base = [figures(r) for r in base_runs]
    current = [figures(r) for r in current_runs]
    items = []
    for label, (unit, _) in current[0].items():
        if not all(label in f for f in base + current):
            continue
        b = [f[label][1] for f in base]
        c = [f[label][1] for f in current]
        items.append(
            {
                "item": label,
                "unit": unit,
                "base": b,
                "current": c,
                "ratio": statistics.median(c) / statistics.median(b) if statistics.median(b) > 0 else None,
                "best_ratio": min(c) / min(b) if min(b) > 0 else None,
                "verdict": verdict(b, c, threshold),
            }
        )
    return items


def _span(values: list[float]) -> str:
    low, high = min(values), max(values)
    digits = 1 if high < 1000 else 0
    return f"{low:.{digits}f}" if low == high else f"{low:.{digits}f}–{high:.{digits}f}"


def report(
    base: Side, current: Side, rounds: int, items: list[dict], machine: dict | None = None, threshold: float = THRESHOLD
) -> str:
    """The comparison as a table."""
    lines = [
        f"robocup-mcl bench compare: base {base.label}, current {current.label}; {rounds} round"
        f"{'s' if rounds != 1 else ''}, alternated"
        + (
            f"; {machine.get('cpu_model')}, python {machine.get('python')}, numba {machine.get('numba')}"
            if machine
            else ""
        ),
        "values over the rounds; ratio: medians, current / base (< 1: faster); best: the sides' fastest rounds, "
        "current / base (the least disturbed runs); verdict: faster or slower when "
        f"the ranges do not overlap and the ratio is beyond 1 ± {threshold:g}, else ~",
        f"{'item':<52} {'unit':<12} {'base':>15} {'current':>15} {'ratio':>7} {'best':>6}  verdict",
    ]
    for item in items:
        ratio = "-" if item["ratio"] is None else f"{item['ratio']:.2f}"
        best = "-" if item.get("best_ratio") is None else f"{item['best_ratio']:.2f}"
        lines.append(
            f"{item['item']:<52} {item['unit']:<12} {_span(item['base']):>15} "
            f"{_span(item['current']):>15} {ratio:>7} {best:>6}  {item['verdict']}"
        )
    counts = {v: sum(1 for i in items if i["verdict"] == v) for v in ("faster", "slower", "~")}
    if rounds > 1:
        lines.append(
            f"{counts['faster']} faster, {counts['slower']} slower, {counts['~']} within the spread (of {len(items)})"
        )
        best = [i for i in items if i.get("best_ratio") is not None]
        worst = max(best, key=lambda i: i["best_ratio"], default=None)
        if worst is not None:
            lines.append(
                f"best rounds: {sum(1 for i in best if i['best_ratio'] > 1.05)} of {len(best)} items more "
                f"than 5 % slower; the largest ratio {worst['best_ratio']:.2f} ({worst['item']})"
            )
    return "\n".join(lines)


def _progress(text: str) -> None:
    print(f"bench compare: {text}", file=sys.stderr, flush=True)


PROG = "robocup-mcl bench compare"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import description

    parser = argparse.ArgumentParser(
        prog=prog,
        description=description(__doc__),
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split("\n\n", 2)[2],
    )
    parser.add_argument(
        "revision", nargs="?", help="a git revision of this repository, or another checkout's directory"
    )
    parser.add_argument(
        "--report",
        metavar="PATH",
        help="print the table of a comparison saved with --save (recomputing its ratios) instead of running one",
    )
    parser.add_argument("--rounds", type=int, default=3, help="runs of each side, alternated (default 3)")
    parser.add_argument(
        "--sizes",
        default=",".join(str(n) for n in DEFAULT_SIZES),
        help="particle counts, comma-separated (default %(default)s)",
    )
    parser.add_argument(
        "--skip",
        default=",".join(DEFAULT_SKIP),
        help=f"what the runs leave out, comma-separated, from {', '.join(SKIPPABLE)} "
        "(default %(default)s; an empty string skips nothing)",
    )
    parser.add_argument(
        "--threshold",
        type=float,
        default=THRESHOLD,
        help="the smallest change of the medians a verdict names, a share (default %(default)s)",
    )
    parser.add_argument("--json", action="store_true", help="print the comparison as JSON")
    parser.add_argument(
        "--save",
        metavar="PATH",
        help="also write the comparison as JSON to PATH (and the table beside it, PATH with .txt)",
    )
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl bench compare` (see --help); returns the exit status."""
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    if args.report:
        try:
            saved = json.loads(Path(args.report).read_text())
            items = compare(saved["runs"]["base"], saved["runs"]["current"], saved["threshold"])
            base, current = (Side(saved[k]["label"], Path(saved[k]["root"])) for k in ("base", "current"))
        except (OSError, ValueError, KeyError, TypeError) as error:
            print(f"robocup-mcl bench compare: {args.report} is not a saved comparison ({error})", file=sys.stderr)
            return 1
        print(
            report(
                base, current, saved["rounds"], items, saved["runs"]["current"][-1].get("machine"), saved["threshold"]
            )
        )
        return 0
    if args.revision is None:
        parser.error("give a revision to compare with (or --report PATH)")
    if args.rounds < 1:
        parser.error(f"--rounds {args.rounds} must be >= 1")
    if not 0 <= args.threshold < 1:
        parser.error(f"--threshold {args.threshold} must be within [0, 1)")
    from .bench import parse_sizes  # (imports the filter's modules: not for --help)

    sizes = parse_sizes(parser, args.sizes)
    skip = [s.strip() for s in args.skip.split(",") if s.strip()]
    unknown = sorted(set(skip) - set(SKIPPABLE))
    if unknown:
        parser.error(f"--skip {', '.join(unknown)}: choose from {', '.join(SKIPPABLE)}")
    try:
        current = current_side()
        _progress(f"the base tree: {args.revision}")
        base = base_side(args.revision)
        arguments = bench_arguments(sizes, skip)
        base_runs, current_runs = alternate(
            base, current, args.rounds, lambda side: run_bench(side, arguments), _progress
        )
    except CompareError as error:
        print(f"robocup-mcl bench compare: {error}", file=sys.stderr)
        return 1
    items = compare(base_runs, current_runs, args.threshold)
    result = {
        "base": {"label": base.label, "root": str(base.root)},
        "current": {"label": current.label, "root": str(current.root)},
        "rounds": args.rounds,
        "threshold": args.threshold,
        "arguments": arguments,
        "items": items,
        "runs": {"base": base_runs, "current": current_runs},
    }
    table = report(base, current, args.rounds, items, current_runs[-1].get("machine"), args.threshold)
    if args.save:
        path = Path(args.save)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(result, indent=2) + "\n")
        path.with_suffix(".txt").write_text(table + "\n")
    if args.json:
        json.dump(result, sys.stdout, indent=2)
        print()
    else:
        print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
