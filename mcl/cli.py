"""The `robocup-mcl` command: demos, log replay and benchmarks.

    robocup-mcl demo walk [--model ...] [--particles N] [--seed S | --seeds 0-9] [--rrd PATH] [--json]
    robocup-mcl demo velocity [--json] ...
    robocup-mcl demo collision [--case none|single|double] [--model ...] [--vision] [--json] [--rrd PATH]
    robocup-mcl demo odometry [--surface carpet|grass|both] [--curve] [--filter] [--json]
    robocup-mcl demo latency [--latency 0.08] [--seeds 0-9] [--json]
    robocup-mcl demo penalty [--seeds 0-19] [--json]
    robocup-mcl replay LOG [--field spl|kidsize|adultsize|FILE] [--model ...] [--particles N] [--rrd PATH]
                       [--out POSES] [--list] [--json]      # a robot's log (ROS 2 MCAP, .npz, CSV folder)
    robocup-mcl bench [--sizes ...] [--json]          # the filter step, numba versus numpy
    robocup-mcl bench lwpr [--seeds N] [--json]       # LWPR on the cross benchmark
    robocup-mcl bench replay [--minutes 10] [--json]  # log replay speed in multiples of real time
    robocup-mcl bench compare REV [--rounds 3] [--json]  # this checkout against another revision, alternated
    robocup-mcl eval [--families ...] [--split train|holdout|both] [--json] [--save PATH]   # the scenario battery
"""
from __future__ import annotations

import importlib
import sys

from .numba_cache import guard_source_checkout

DEMOS = {
    "walk": ("demos.walk", "the particle filter on the 60 s walk scenario with a kidnapping"),
    "velocity": ("demos.velocity", "IMU + leg kinematics velocity estimators against the truth"),
    "collision": ("demos.collision", "Hoffmann's collision experiments: adaptive versus velocity-linear model"),
    "odometry": ("demos.odometry", "learned footstep odometry (Rouxel et al.): drift of raw vs LWPR-corrected steps"),
    "latency": ("demos.latency", "a late camera (80 ms): tracking with and without latency compensation"),
    "penalty": ("demos.penalty", "returning from a penalty on an unknown touchline: convergence, mirror share"),
}
BENCHES = {
    "step": ("mcl.bench", "one full filter step per particle count, numba versus plain numpy"),
    "lwpr": ("demos.lwpr_cross", "LWPR on the cross benchmark: accuracy, receptive fields, speed"),
    "replay": ("demos.replay_speed", "a 10-minute MCAP log replayed, in multiples of real time"),
    "compare": ("mcl.bench_compare", "this checkout's speed against another revision's, in alternated runs"),
}


def _usage() -> str:
    lines = [__doc__.strip(), "", "demos:"]
    lines += [f"  {name:<10} {text}" for name, (_, text) in DEMOS.items()]
    lines += ["benchmarks:"] + [f"  {name:<10} {text}" for name, (_, text) in BENCHES.items()]
    return "\n".join(lines)


def _dispatch(table: dict, name: str, argv: list[str], what: str) -> int:
    if name not in table:
        print(f"robocup-mcl: unknown {what} {name!r}; choose from {', '.join(table)}", file=sys.stderr)
        return 2
    module = importlib.import_module(table[name][0])
    return int(module.main(argv) or 0)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    guard_source_checkout()           # before any kernel runs (see mcl.numba_cache)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0 if argv else 2
    command, rest = argv[0], argv[1:]
    if command == "demo":
        if not rest or rest[0] in ("-h", "--help"):
            print(_usage())
            return 0 if rest else 2
        return _dispatch(DEMOS, rest[0], rest[1:], "demo")
    if command == "replay":
        from .replay import main as replay_main
        return replay_main(rest)
    if command == "eval":
        return int(importlib.import_module("demos.battery").main(rest) or 0)
    if command == "bench":
        if rest and not rest[0].startswith("-"):
            return _dispatch(BENCHES, rest[0], rest[1:], "benchmark")
        return _dispatch(BENCHES, "step", rest, "benchmark")
    print(f"robocup-mcl: unknown command {command!r}\n\n{_usage()}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
