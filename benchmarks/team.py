"""`robocup-mcl bench team`: what the team's messages and the ball cost in the robot's loop.

    robocup-mcl bench team [--rounds 5] [--particles 500] [--json] [--save PATH]

Measured in one process, alternating, so that the ratios hold on a shared machine:
- the battery's loop (`demos.battery.localize`: motion at 100 Hz, camera frames, game events, the estimate and
  quality every step) over a run of the `kidnap_even_team` family, without messages and with the teammates'
  messages and the robot's ball sightings; per step, median over the rounds, and their ratio;
- one `Localizer.team_message` call, with a confirmed sighting of the robot's own to compare it with (the
  dearest case: a report weighed against the joint belief), median and 99th percentile over many calls;
- one `Localizer.observe_ball` call, the same way.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time

import numpy as np

PROG = "robocup-mcl bench team"


def _loop_seconds_per_step(run, particles: int, team: bool) -> float:
    from demos.battery import localize

    out = localize(run, particles, team=team)
    return out["loop_s"] / run.times.shape[0]


def _calls(particles: int, count: int) -> dict:
    """Per-call seconds of team_message and observe_ball on a localizer that tracks, with a teammate."""
    from field import spl
    from mcl.localizer import Localizer
    from motion_models import MotionInput
    from sensing.team import BallDetection, TeamMessage

    loc = Localizer(spl(), n_particles=particles, seed=0)
    loc.place((-2.0, 0.0, 0.0), sigma=(0.05, 0.05, 0.05))
    t = 0.0
    for _ in range(10):
        t += 0.01
        loc.motion(t, MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
    ball = BallDetection(math.hypot(1.0, 0.8), math.atan2(0.8, 1.0))  # the ball at (-1, 0.8)
    message_times, ball_times = [], []
    for k in range(count):
        t += 0.01
        loc.motion(t, MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
        started = time.perf_counter()
        loc.observe_ball(ball, capture_time=t)
        ball_times.append(time.perf_counter() - started)
        message = TeamMessage(2 + k % 3, t, (0.5, 1.0, 0.0), confidence=0.9, ball=(-1.0, 0.8))
        started = time.perf_counter()
        loc.team_message(message)
        message_times.append(time.perf_counter() - started)
    return {"team_message": message_times, "observe_ball": ball_times}


def _summary_us(values: list[float]) -> dict:
    array = np.asarray(values) * 1e6
    return {"median_us": float(np.median(array)), "p99_us": float(np.percentile(array, 99)), "calls": len(values)}


def run(
    rounds: int = 5, particles: int = 500, duration: float = 20.0, calls: int = 2000, progress: bool = False
) -> dict:
    """The figures (see the module docstring), JSON-ready; `progress`: a bar on stderr over the rounds."""
    from demos.battery_sim import simulate
    from mcl.tools.cli_checks import progress_bar

    sim = simulate("kidnap_even_team", 0, duration)
    _loop_seconds_per_step(sim, particles, False)  # warm up (compile or load the kernels)
    _loop_seconds_per_step(sim, particles, True)
    plain, team = [], []
    bar = progress_bar(enabled=progress, total=rounds + 1, desc="bench team", unit="round")
    for _ in range(rounds):
        plain.append(_loop_seconds_per_step(sim, particles, False))
        team.append(_loop_seconds_per_step(sim, particles, True))
        bar.update(1)
    per_call = _calls(particles, calls)
    bar.update(1)
    bar.close()
    plain_us, team_us = statistics.median(plain) * 1e6, statistics.median(team) * 1e6
    return {
        "benchmark": "team",
        "particles": particles,
        "rounds": rounds,
        "duration_s": duration,
        "run": {
            "family": "kidnap_even_team",
            "seed": 0,
            "messages": len(sim.messages),
            "ball_detections": sum(d is not None for d in sim.ball_detections),
        },
        "loop_step_us": {
            "without_messages": plain_us,
            "with_team": team_us,
            "ratio": team_us / plain_us,
            "rounds_without": [v * 1e6 for v in plain],
            "rounds_with": [v * 1e6 for v in team],
        },
        "team_message": _summary_us(per_call["team_message"]),
        "observe_ball": _summary_us(per_call["observe_ball"]),
    }


def format_report(result: dict) -> str:
    loop = result["loop_step_us"]
    return "\n".join(
        [
            f"the battery's loop, {result['particles']} particles, {result['duration_s']:g} s of kidnap_even_team seed 0 "
            f"({result['run']['messages']} messages, {result['run']['ball_detections']} ball sightings), median of "
            f"{result['rounds']} alternated rounds:",
            f"  per step without messages   {loop['without_messages']:8.1f} µs",
            f"  per step with the team       {loop['with_team']:8.1f} µs   ({loop['ratio']:.2f}x)",
            f"team_message   median {result['team_message']['median_us']:6.1f} µs, p99 "
            f"{result['team_message']['p99_us']:6.1f} µs ({result['team_message']['calls']} calls)",
            f"observe_ball   median {result['observe_ball']['median_us']:6.1f} µs, p99 "
            f"{result['observe_ball']['p99_us']:6.1f} µs ({result['observe_ball']['calls']} calls)",
        ]
    )


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    from mcl.tools.cli_checks import add_progress_option, description, positive_int

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument("--rounds", type=positive_int, default=5, help="alternated rounds (default 5)")
    parser.add_argument("--particles", type=positive_int, default=500, help="particles (default 500)")
    parser.add_argument("--json", action="store_true", help="the results as JSON on stdout instead of text")
    parser.add_argument("--save", metavar="PATH", help="also write the JSON results to PATH")
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """The command line (see the module docstring)."""
    from mcl.tools.cli_checks import check_output_file, progress_wanted, save_json

    args = build_parser(prog).parse_args(argv)
    check_output_file(args.save, "--save", make_parents=False)
    result = run(args.rounds, args.particles, progress=progress_wanted(args))
    save_json(args.save, result)
    print(json.dumps(result, indent=2) if args.json else format_report(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
