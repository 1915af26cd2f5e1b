"""`robocup-mcl bench tune`: how `robocup-mcl tune` scales with Ray workers, and what Ray costs per task.

    robocup-mcl bench tune [--trials 6] [--battery 2] [--duration 30] [--particles 300] [--overhead-tasks 20]
                           [--json] [--save PATH]

One study (the battery's training seeds 0..K-1 of every family, `spaces/battery.toml`, TPE, seed 0, no journal
file) is timed on an embedded local Ray with 1 worker, then with 2 (a fresh instance each; one untimed trial
first, so that the workers have started and loaded the kernels). Both run the same trials with the same
values (the study is seeded), so the ratio of their trials per hour is the speed-up.

Ray's overhead per task: on the 1-worker instance, `--overhead-tasks` tasks are run one at a time; each
task's round trip (submit to result, in the driver) against the seconds measured inside the task. The
overhead share is (sum of round trips − sum of inside times) / sum of inside times.

The projection to a cluster: a trial is `tasks_per_trial` tasks (cases × filter seeds) of about `task_s`
seconds each; on C cores with B trials in flight (`--parallel-trials`, B = max(1, C // tasks_per_trial)), a
round of B trials takes ceil(B·tasks_per_trial / C) waves of task_s·(1 + overhead), plus what a round costs beyond its tasks
(`driver_s_per_trial`: measured on the 2-worker instance as its seconds per trial less its waves of tasks; the
sampler, the journal, gathering the results, the last wave's stragglers), so trials per hour ≈
3600·B / (waves·task_s·(1 + overhead) + driver_s). It leaves out a cluster's network.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

PROG = "robocup-mcl bench tune"
SPACE = Path(__file__).resolve().parent.parent / "spaces" / "battery.toml"
CORES = (10, 100)


def _settings(trials: int, battery: int, duration: float, particles: int):
    from demos.battery import FAMILIES, BatteryCase, split_seeds
    from mcl.tools.tuning import SearchSpace, TuneSettings

    cases = tuple(BatteryCase(f, s, duration) for s in split_seeds("train", battery) for f in FAMILIES)
    return TuneSettings(cases, SearchSpace.load(SPACE), "truth", trials, (0,), particles=particles)


def time_study(workers: int, settings) -> dict:
    """The study on a fresh local Ray with `workers` CPUs: one untimed trial, then the timed study."""
    from dataclasses import replace

    import ray

    from mcl.tools.tuning import run_study, start_ray

    start_ray(None, workers)
    try:
        run_study(replace(settings, trials=1, seed=settings.seed + 1))  # workers started, kernels loaded
        started = time.perf_counter()
        outcome = run_study(settings)
        seconds = time.perf_counter() - started
    finally:
        ray.shutdown()
    tasks = outcome.tasks.rows
    return {
        "workers": workers,
        "trials": len(outcome.trials),
        "seconds": seconds,
        "trials_per_hour": 3600.0 * len(outcome.trials) / seconds,
        "task_s_median": float(sorted(r["seconds"] for r in tasks)[len(tasks) // 2]),
        "values": [t["value"] for t in outcome.trials],
    }


def overhead(settings, tasks: int) -> dict:
    """Ray's cost per task: round trips of tasks run one at a time on a 1-worker instance."""
    import ray

    from mcl.tools.tuning import start_ray
    from mcl.tools.tuning.search import remote_task

    start_ray(None, 1)
    try:
        task = remote_task()
        case = settings.cases[0]
        ray.get(task.remote(case, {}, 0, settings.particles))  # the worker's first task, not counted
        trips, inside = [], []
        for i in range(tasks):
            case = settings.cases[i % len(settings.cases)]
            started = time.perf_counter()
            result = ray.get(task.remote(case, {}, 0, settings.particles))
            trips.append(time.perf_counter() - started)
            inside.append(result["seconds"])
    finally:
        ray.shutdown()
    share = (sum(trips) - sum(inside)) / sum(inside)
    return {
        "tasks": tasks,
        "round_trip_s": sum(trips) / tasks,
        "inside_s": sum(inside) / tasks,
        "overhead_s": (sum(trips) - sum(inside)) / tasks,
        "overhead_share": share,
    }


def driver_seconds(measured: dict, tasks_per_trial: int, overhead_share: float) -> float:
    """What a trial costs beyond its tasks on the 2-worker instance: its measured seconds per trial less its
    waves of tasks (the sampler, the journal, gathering the results, the last wave's stragglers)."""
    waves = math.ceil(tasks_per_trial / measured["workers"])
    per_trial = measured["seconds"] / measured["trials"]
    return max(0.0, per_trial - waves * measured["task_s_median"] * (1.0 + overhead_share))


def projection(tasks_per_trial: int, task_s: float, overhead_share: float, driver_s: float = 0.0) -> dict:
    """Trials per hour on clusters of `CORES` cores (the module docstring's formula, plus `driver_s` per
    round of trials)."""
    out = {}
    for cores in CORES:
        batch = max(1, cores // tasks_per_trial)
        waves = math.ceil(batch * tasks_per_trial / cores)
        hours = (waves * task_s * (1.0 + overhead_share) + driver_s) / 3600.0
        out[str(cores)] = {
            "parallel_trials": batch,
            "waves_per_round": waves,
            "trials_per_hour": batch / hours,
            "hours_for_100_trials": 100 * hours / batch,
        }
    return out


def run(
    trials: int = 6,
    battery: int = 2,
    duration: float = 30.0,
    particles: int = 300,
    overhead_tasks: int = 20,
    progress: bool = False,
) -> dict:
    """Every figure of the module docstring, JSON-ready."""
    from demos.walk import warm_up_walk
    from demos.walk_sim import WalkScenario

    warm = warm_up_walk(WalkScenario(), "velocity-linear", progress=progress)
    settings = _settings(trials, battery, duration, particles)
    one = time_study(1, settings)
    two = time_study(2, settings)
    cost = overhead(settings, overhead_tasks)
    tasks_per_trial = len(settings.cases) * len(settings.seeds)
    driver_s = driver_seconds(two, tasks_per_trial, cost["overhead_share"])
    return {
        "trials": trials,
        "battery_seeds": battery,
        "families": len(settings.cases) // battery,
        "duration_s": duration,
        "particles": particles,
        "tasks_per_trial": tasks_per_trial,
        "machine_cores": os.cpu_count(),
        "one_worker": one,
        "two_workers": two,
        "speedup": two["trials_per_hour"] / one["trials_per_hour"],
        "same_study": one["values"] == two["values"],
        "overhead": cost,
        "driver_s_per_trial": driver_s,
        "projection": projection(tasks_per_trial, two["task_s_median"], cost["overhead_share"], driver_s),
        **warm.as_dict(),
    }


def format_report(r: dict) -> str:
    """The printed table."""
    lines = [
        f"tuning study: {r['trials']} trials, {r['tasks_per_trial']} tasks per trial (battery seeds 0.."
        f"{r['battery_seeds'] - 1} × {r['families']} families, {r['duration_s']:g} s runs, {r['particles']} "
        f"particles), on a {r['machine_cores']}-core machine"
    ]
    for key in ("one_worker", "two_workers"):
        x = r[key]
        lines.append(
            f"  {x['workers']} worker(s): {x['seconds']:6.1f} s, {x['trials_per_hour']:6.0f} trials per hour "
            f"(task median {x['task_s_median']:.2f} s)"
        )
    lines.append(f"  speed-up with 2 workers: {r['speedup']:.2f}x; same trials and values: {r['same_study']}")
    o = r["overhead"]
    lines.append(
        f"Ray per task ({o['tasks']} tasks one at a time): round trip {o['round_trip_s'] * 1000:.1f} ms, "
        f"inside {o['inside_s'] * 1000:.1f} ms, overhead {o['overhead_s'] * 1000:.1f} ms = "
        f"{100 * o['overhead_share']:.1f} % of the task"
    )
    lines.append(
        f"beyond its tasks, a trial costs {r['driver_s_per_trial']:.2f} s (sampler, journal, gathering, stragglers)"
    )
    for cores, p in r["projection"].items():
        lines.append(
            f"projected on {cores} cores: {p['parallel_trials']} trial(s) in flight, "
            f"{p['trials_per_hour']:.0f} trials per hour, 100 trials in {p['hours_for_100_trials'] * 60:.1f} min"
        )
    return "\n".join(lines)


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description, positive_int

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument("--trials", type=positive_int, default=6, help="trials of the timed study (default 6)")
    parser.add_argument("--battery", type=positive_int, default=2, help="battery seeds per family (default 2)")
    parser.add_argument("--duration", type=float, default=30.0, help="seconds per run (default 30)")
    parser.add_argument("--particles", type=positive_int, default=300, help="particles (default 300)")
    parser.add_argument(
        "--overhead-tasks",
        type=positive_int,
        default=20,
        help="tasks run one at a time to measure Ray's overhead (default 20)",
    )
    parser.add_argument("--json", action="store_true", help="the results as JSON on stdout")
    add_save_option(parser)
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """The command line (see the module docstring)."""
    from mcl.tools.cli_checks import check_duration, check_output_file, progress_wanted, save_and_print

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    check_duration(parser, args.duration, 10.0)
    check_output_file(args.save, "--save")
    result = run(args.trials, args.battery, args.duration, args.particles, args.overhead_tasks, progress_wanted(args))
    save_and_print(result, args.save, args.json, lambda r: print(format_report(r)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
