"""`robocup-mcl bench replay`: how fast a long log replays, in multiples of real time.

    robocup-mcl bench replay [--minutes 10] [--particles 500] [--json]

Simulates the walk scenario for `--minutes` at 100 Hz (motion) and 30 Hz (camera, 80 ms latency), writes it as
a ROS 2 MCAP file, and times `robocup-mcl replay`'s work on it: reading the file, and replaying it through the
filter, once without and once with a Rerun recording (particles logged every 5th step). Real-time factor =
log seconds / wall seconds of reading plus replaying. The filter's kernels are warmed up first
(`mcl.tools.replay.warm_up_replay`), so no timing counts their compilation; the warm-up's time is reported apart.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from mcl.tools.logs import read_log, write_log
from mcl.tools.replay import replay

from .walk_log import to_robot_log
from .walk_sim import WalkScenario, simulate


def measure(minutes: float, particles: int, seed: int = 0, progress: bool = False) -> dict:
    """Write the log, warm the kernels up, and time reading and replaying it without and with a recording
    (progress: the replay's bar on stderr)."""
    from mcl.tools.replay import warm_up_replay

    scenario = replace(WalkScenario(), duration=60.0 * minutes, kidnap_time=None)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "walk.mcap"
        write_log(to_robot_log(simulate(scenario, seed), latency=0.08), path)
        size = path.stat().st_size
        out = {"minutes": minutes, "particles": particles, "mcap_bytes": size}
        out.update(warm_up_replay(read_log(path)[0], scenario.field, "velocity-linear", progress=progress).as_dict())
        for name, rrd in (("without recording", None), ("with recording", Path(folder) / "walk.rrd")):
            started = time.perf_counter()
            log, report = read_log(path)
            read_seconds = time.perf_counter() - started
            result = replay(
                log,
                scenario.field,
                particles=particles,
                seed=seed,
                rrd=None if rrd is None else str(rrd),
                progress=progress,
            )
            total = time.perf_counter() - started
            out[name] = {
                "read_s": read_seconds,
                "replay_s": result.elapsed,
                "total_s": total,
                "real_time_factor": log.duration / total,
                "steps": int(result.times.shape[0]),
                "messages": sum(report.messages.values()),
                "rrd_bytes": None if rrd is None else rrd.stat().st_size,
            }
        return out


PROG = "robocup-mcl bench replay"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument("--minutes", type=float, default=10.0, help="minutes of simulated log (default 10)")
    parser.add_argument("--particles", type=int, default=500, help="particles (default 500)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the summary")
    add_save_option(parser)
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl bench replay` (see --help); returns the exit status."""
    from mcl.tools.cli_checks import progress_wanted

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    from mcl.tools.cli_checks import check_output_file, save_json

    check_output_file(args.save, "--save")
    if not (args.minutes > 0 and args.particles > 0):
        parser.error("--minutes and --particles must be > 0")
    result = measure(args.minutes, args.particles, progress=progress_wanted(args))
    save_json(args.save, result)
    if args.json:
        json.dump(result, sys.stdout, indent=2)
        print()
        return 0
    print(
        f"replay of a {args.minutes:g}-minute log (100 Hz motion, 30 Hz camera; MCAP "
        f"{result['mcap_bytes'] / 1e6:.1f} MB), {args.particles} particles"
    )
    for name in ("without recording", "with recording"):
        r = result[name]
        print(
            f"{name:>18}: read {r['read_s']:.1f} s + replay {r['replay_s']:.1f} s = {r['total_s']:.1f} s, "
            f"{r['real_time_factor']:.1f}x real time"
        )
    print(
        f"warm-up: {'compiled' if result['kernels_cached'] is False else 'kernels ready'} in "
        f"{result['compile_seconds']:.1f} s, not counted"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
