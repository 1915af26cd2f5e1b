"""Run the fuzz suite: every target in a child process, its cases counted, a crash reported with its case.

    python tests/fuzz_run.py                        # the "full" profile (`make fuzz`): >= 10 000 cases
    python tests/fuzz_run.py --profile ci           # the CI profile (tests/test_fuzz.py runs it)
    python tests/fuzz_run.py --targets filter,localizer --examples 5000 --json --save results/fuzz.json

Profiles: "ci" draws a fixed set of cases (derandomized: the same on every run); "full" draws fresh random ones
(its seed is printed, `--seed` replays a run). A target's examples are the profile's total shared by its weight.

Each target runs in a child process of its own, which writes each case down before running it: if the child
dies (a crash in compiled code), the runner reports the case it was running and goes on with the next target.
Exit status 0 when every target passed.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
PROFILES = {"ci": 2400, "full": 12000}  # examples over all targets


def _child(target: str, examples: int, derandomize: bool, seed: int | None, out: str) -> int:
    sys.path.insert(0, str(HERE))
    from hypothesis import HealthCheck, Phase, settings
    from hypothesis import seed as hypothesis_seed

    from mcl.numba_cache import guard_source_checkout, serialize_cache_access

    guard_source_checkout()  # no stale compiled kernel (as tests/conftest.py)
    serialize_cache_access()  # the test session's workers may share the cache
    import fuzz_targets
    from fuzzing import COUNTS

    test = {**fuzz_targets.TARGETS, **fuzz_targets.HIDDEN}[target]
    test = settings(
        max_examples=examples,
        deadline=None,
        derandomize=derandomize,
        database=None,
        suppress_health_check=list(HealthCheck),
        print_blob=True,
        phases=[Phase.explicit, Phase.generate, Phase.shrink],
    )(test)
    if seed is not None and not derandomize:
        test = hypothesis_seed(seed)(test)
    start = time.perf_counter()
    failure = None
    try:
        test()
    except Exception as error:  # the falsifying example is in the message (hypothesis)
        failure = "".join(traceback.format_exception(error))[-8000:]
    result = {
        "target": target,
        "cases": COUNTS[(target, "cases")],
        "accepted": COUNTS[(target, "accepted")],
        "refused": COUNTS[(target, "refused")],
        "seconds": round(time.perf_counter() - start, 1),
        "failure": failure,
        "crash": None,
    }
    Path(out).write_text(json.dumps(result))
    return 0


def run_target(target: str, examples: int, derandomize: bool, seed: int | None) -> dict:
    """One target in a child process; its counts, and its failure or crash (with the case it died on)."""
    with tempfile.TemporaryDirectory() as tmp:
        out, case = os.path.join(tmp, "result.json"), os.path.join(tmp, "case.txt")
        env = dict(os.environ, ROBOCUP_MCL_FUZZ_CASE_FILE=case, PYTHONFAULTHANDLER="1")
        command = [sys.executable, __file__, "--child", target, "--examples", str(examples), "--out", out]
        if derandomize:
            command.append("--derandomize")
        if seed is not None:
            command += ["--seed", str(seed)]
        start = time.perf_counter()
        process = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
        if process.returncode == 0 and os.path.exists(out):
            return json.loads(Path(out).read_text())
        last = Path(case).read_text() if os.path.exists(case) else "(none recorded)"
        code = process.returncode
        how = f"killed by {signal.Signals(-code).name}" if code < 0 else f"exit status {code}"
        return {
            "target": target,
            "cases": None,
            "accepted": None,
            "refused": None,
            "seconds": round(time.perf_counter() - start, 1),
            "failure": None,
            "crash": f"the process died ({how}) on the case {last}\n{process.stderr[-3000:]}",
        }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", choices=sorted(PROFILES), default="full")
    parser.add_argument("--targets", help="comma-separated targets (default: all)")
    parser.add_argument("--examples", type=int, help="examples over the targets run (default: the profile's)")
    parser.add_argument("--seed", type=int, help="the random seed of a 'full' run (default: drawn and printed)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--save", help="write the results as JSON to this file")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    parser.add_argument("--derandomize", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        return _child(args.child, args.examples, args.derandomize, args.seed, args.out)

    sys.path.insert(0, str(HERE))
    from fuzz_targets import TARGETS, WEIGHTS

    targets = list(TARGETS) if not args.targets else args.targets.split(",")
    unknown = [t for t in targets if t not in TARGETS]
    if unknown:
        parser.error(f"unknown targets {unknown}; choose from {', '.join(TARGETS)}")
    derandomize = args.profile == "ci"
    seed = None if derandomize else (args.seed if args.seed is not None else int.from_bytes(os.urandom(4), "little"))
    total = args.examples or PROFILES[args.profile]
    weight = sum(WEIGHTS[t] for t in targets)
    results = []
    start = time.perf_counter()
    if not args.json:
        print(f"fuzz profile {args.profile}" + (f", seed {seed}" if seed is not None else ", derandomized"))
        print(f"{'target':<22}{'cases':>8}{'accepted':>10}{'refused':>10}{'seconds':>9}  result")
    for target in targets:
        examples = max(1, round(total * WEIGHTS[target] / weight))
        result = run_target(target, examples, derandomize, seed)
        results.append(result)
        if not args.json:
            verdict = "ok" if not (result["failure"] or result["crash"]) else "CRASH" if result["crash"] else "FAIL"
            cells = [result[k] if result[k] is not None else "-" for k in ("cases", "accepted", "refused")]
            print(f"{target:<22}{cells[0]:>8}{cells[1]:>10}{cells[2]:>10}{result['seconds']:>9}  {verdict}", flush=True)
    cases = sum(r["cases"] or 0 for r in results)
    summary = {
        "profile": args.profile,
        "seed": seed,
        "cases": cases,
        "crashes": sum(1 for r in results if r["crash"]),
        "failures": sum(1 for r in results if r["failure"]),
        "seconds": round(time.perf_counter() - start, 1),
        "targets": results,
    }
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(
            f"{'total':<22}{cases:>8}{'':>29}  {summary['seconds']} s; "
            f"{summary['crashes']} crashes, {summary['failures']} failures"
        )
        for r in results:
            for key in ("crash", "failure"):
                if r[key]:
                    print(f"\n--- {r['target']}: {key}\n{r[key]}")
    if args.save:
        Path(args.save).parent.mkdir(parents=True, exist_ok=True)
        Path(args.save).write_text(json.dumps(summary, indent=2) + "\n")
    return 0 if not (summary["crashes"] or summary["failures"]) else 1


if __name__ == "__main__":
    raise SystemExit(main())
