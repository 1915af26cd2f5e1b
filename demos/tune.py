"""`robocup-mcl tune`: the localizer's settings learned from a team's logs, spread over a Ray cluster.

    robocup-mcl tune LOGS... --space SPACE.toml --trials N [--holdout LOG...] [--objective auto|truth|evidence]
                     [--seeds 1] [--sampler tpe|cmaes] [--seed 0] [--study FILE] [--out PROFILE.toml]
                     [--plots DIR] [--address HOST:PORT] [--workers W] [--parallel-trials B]
                     [--field spl|FILE] [--particles 500] [--topic-odometry T ...] [--json] [--save PATH]
    robocup-mcl tune --battery K --space SPACE.toml --trials N ...   # the evaluation battery's scenarios

The command over the library `mcl.tools.tuning`. Searches the settings a space file names (`mcl.tools.tuning.space`) for the ones that localize the training logs
best, and writes them as a profile (`--out`, `mcl.profile`) that `Localizer.from_profile`, `robocup-mcl replay
--profile` and `robocup-mcl eval --profile` load. Objectives (`mcl.tools.tuning.objective`): "truth" (the battery's
figures; needs ground truth in every log) or "evidence" (the log evidence of the detections; needs none);
"auto" (the default) takes truth when every training log has it. `--battery K` tunes on the battery's
training seeds 0..K-1 of every family (`--families`, `demos.battery.BatteryCase`) and reports on its held-out seeds 1000..1000+H-1
(`--battery-holdout H`, default 10).

The study (`mcl.tools.tuning.search`): Optuna, TPE by default, kept in `--study FILE` (a journal) so that an
interrupted run resumes where it stopped; the same `--seed` gives the same study. Each trial runs every
training log × filter seed (`--seeds`) as a Ray task: on an embedded local Ray with `--workers` CPUs (default:
the machine's), or with `--address` on an existing cluster (`ray start --head` prints its address).

The report: the best settings, the defaults and the tuned profile side by side on the training and held-out
logs (`--holdout`), per held-out log, and a convergence and a parameter-importance plot (`--plots DIR`).
With truth in the logs and the evidence objective, it also gives the rank correlation of evidence and error
over the trials. `--json` prints everything as JSON, `--save PATH` writes it to a file.
"""

from __future__ import annotations

import argparse

PROG = "robocup-mcl tune"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description, positive_int
    from mcl.tools.replay import add_topic_options

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument("logs", nargs="*", metavar="LOG", help="training logs (MCAP, .npz or a CSV folder)")
    parser.add_argument("--space", required=True, metavar="TOML", help="the settings to tune and their ranges")
    parser.add_argument("--trials", type=positive_int, required=True, help="completed trials to reach")
    parser.add_argument(
        "--holdout",
        nargs="+",
        default=[],
        metavar="LOG",
        help="held-out logs: the defaults and the tuned profile are compared on them",
    )
    parser.add_argument(
        "--battery",
        type=positive_int,
        metavar="K",
        help="tune on the evaluation battery's training seeds 0..K-1 instead of logs",
    )
    parser.add_argument(
        "--battery-holdout",
        type=positive_int,
        default=10,
        metavar="H",
        help="with --battery: report on held-out seeds 1000..1000+H-1 (default 10)",
    )
    parser.add_argument("--families", default=None, help="with --battery: comma-separated families (default: all)")
    parser.add_argument("--duration", type=float, default=60.0, help="with --battery: seconds per run (default 60)")
    parser.add_argument(
        "--objective",
        default="auto",
        choices=("auto", "truth", "evidence"),
        help="what to minimize (default auto: truth when every training log has it)",
    )
    parser.add_argument("--seeds", type=positive_int, default=1, help="filter seeds per log (default 1)")
    parser.add_argument("--sampler", default="tpe", choices=("tpe", "cmaes"), help="Optuna's sampler (default tpe)")
    parser.add_argument("--seed", type=int, default=0, help="the sampler's seed (default 0)")
    parser.add_argument("--study", metavar="FILE", help="keep the study in this journal file (resumable)")
    parser.add_argument("--out", metavar="TOML", help="write the tuned profile here")
    parser.add_argument("--plots", metavar="DIR", help="write convergence.png and importance.png here")
    parser.add_argument("--address", help="an existing Ray cluster (HOST:PORT); default: a local Ray instance")
    parser.add_argument(
        "--workers", type=positive_int, default=None, help="CPUs of the local Ray instance (default: the machine's)"
    )
    parser.add_argument(
        "--parallel-trials", type=positive_int, default=1, help="trials proposed and evaluated at once (default 1)"
    )
    parser.add_argument(
        "--field",
        default="spl",
        help="the logs' field: spl, kidsize, adultsize, or a field file (.toml/.json) (default spl)",
    )
    parser.add_argument("--particles", type=positive_int, default=500, help="particles (default 500)")
    parser.add_argument("--json", action="store_true", help="the results as JSON on stdout instead of the report")
    add_save_option(parser)
    add_progress_option(parser)
    add_topic_options(parser)
    return parser


def _cases(parser, args):
    """(training cases, held-out cases, whether every training case has truth); logs are read here, so a
    missing or unreadable log is refused before Ray starts."""
    from mcl.tools.cli_checks import check_duration
    from mcl.tools.logs import read_log
    from mcl.tools.replay import check_inputs, topics_from_args
    from mcl.tools.tuning import LogCase

    from .battery import FAMILIES, BatteryCase, parse_families, split_seeds

    if args.battery:
        if args.logs or args.holdout:
            parser.error("--battery tunes on the battery's scenarios: give no LOG and no --holdout")
        families = parse_families(parser, args.families) if args.families else list(FAMILIES)
        check_duration(parser, args.duration, 10.0)
        train = tuple(BatteryCase(f, s, args.duration) for s in split_seeds("train", args.battery) for f in families)
        held = tuple(
            BatteryCase(f, s, args.duration) for s in split_seeds("holdout", args.battery_holdout) for f in families
        )
        return train, held, True
    if not args.logs:
        parser.error("give training LOGs, or --battery K")
    from field.io import field_by_name_or_path

    field_by_name_or_path(args.field)  # an unknown preset or a bad field file: one line, before Ray starts
    truth = True
    topics = topics_from_args(args)
    for group in (args.logs, args.holdout):
        for path in group:
            try:
                log, _ = read_log(path, topics=topics)
            except OSError as error:
                raise OSError(error.errno, f"log {path}: {error.strerror or error}") from None
            check_inputs(log)
            if group is args.logs:
                truth = truth and log.has_truth
    return (
        tuple(LogCase(p, args.field, topics) for p in args.logs),
        tuple(LogCase(p, args.field, topics) for p in args.holdout),
        truth,
    )


def _warm_up(cases, field: str, progress: bool) -> None:
    """Compile (or load) the kernels once in this process, so that the workers load them from numba's cache
    instead of each compiling them."""
    from mcl.tools.tuning import LogCase

    case = cases[0]
    if not isinstance(case, LogCase):
        from .walk import warm_up_walk
        from .walk_sim import WalkScenario

        warm_up_walk(WalkScenario(), "velocity-linear", progress=progress)
        return
    from field.io import field_by_name_or_path
    from mcl.tools.logs import read_log
    from mcl.tools.replay import warm_up_replay

    warm_up_replay(
        read_log(case.path, topics=case.topics)[0], field_by_name_or_path(field), "velocity-linear", progress=progress
    )


def run(args, parser) -> dict:
    """Run the command as parsed (see the module docstring); returns the JSON-ready result."""
    import ray

    from mcl.tools.cli_checks import progress_bar, progress_wanted
    from mcl.tools.tuning import SearchSpace, TuneSettings, start_ray, tune
    from mcl.tools.tuning.search import check_address

    try:
        space = SearchSpace.load(args.space)
    except OSError as error:
        raise OSError(error.errno, f"space {args.space}: {error.strerror or error}") from None
    train, held, has_truth = _cases(parser, args)
    objective = args.objective
    if objective == "auto":
        objective = "truth" if has_truth else "evidence"
    elif objective == "truth" and not has_truth:
        parser.error("--objective truth needs ground truth in every training log (use evidence)")
    settings = TuneSettings(
        train,
        space,
        objective,
        args.trials,
        tuple(range(args.seeds)),
        args.sampler,
        args.seed,
        args.particles,
        args.parallel_trials,
    )
    if args.address:
        check_address(args.address)
    progress = progress_wanted(args)
    _warm_up(train, args.field, progress)
    started_ray = not ray.is_initialized()
    info = start_ray(args.address, args.workers)
    try:
        bar = progress_bar(enabled=progress, total=args.trials, desc="tune", unit="trial")

        def on_trial(row):
            bar.set_postfix_str(f"trial {row['number']}: {row['value']:.4f}", refresh=False)
            bar.update(1)

        result = tune(settings, held, args.study, on_trial)
        bar.close()
    finally:
        if started_ray:
            ray.shutdown()
    result["ray"] = {**info, **result["ray"]}
    result["settings"] = {
        "trials": args.trials,
        "sampler": args.sampler,
        "seed": args.seed,
        "objective": objective,
        "seeds": list(settings.seeds),
        "training_cases": len(train),
        "holdout_cases": len(held),
        "cases": [c.label for c in train],
        "holdout": [c.label for c in held],
        "space": space.to_dict(),
        "space_file": args.space,
        "study": args.study,
        "field": args.field,
        "particles": args.particles,
        "parallel_trials": args.parallel_trials,
        "battery": args.battery,
        "battery_holdout": args.battery_holdout if args.battery else None,
        "tasks_per_trial": len(train) * len(settings.seeds),
    }
    return result


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """The command line (see the module docstring); exit 2 on bad arguments, 1 on errors (one line)."""
    from mcl.profile import Profile
    from mcl.tools.cli_checks import check_output_file, save_and_print

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    import importlib.util

    if importlib.util.find_spec("ray") is None or importlib.util.find_spec("optuna") is None:
        from mcl.tools.cli_checks import CommandError

        raise CommandError("tune needs Ray and Optuna: pip install -e '.[tune]' in the clone")
    check_output_file(args.save, "--save")
    check_output_file(args.out, "--out")
    result = run(args, parser)
    if args.out:
        Profile.from_values(result["best"]["values"]).save(
            args.out,
            header=[
                f"robocup-mcl tune: best of {args.trials} trials, objective {result['settings']['objective']}",
                f"training: {', '.join(result['settings']['cases'][:6])}"
                + (", ..." if len(result["settings"]["cases"]) > 6 else ""),
                f"search space: {args.space}",
            ],
        )
        result["profile"] = args.out
    if args.plots:
        from mcl.tools.tuning.report import plot

        result["plots"] = plot(result, args.plots)
    from mcl.tools.tuning.report import format_report

    def printer(r: dict) -> None:
        print(format_report(r))
        for path in r.get("plots", []):
            print(f"plot written to {path}")
        if r.get("profile"):
            print(f"profile written to {r['profile']}")

    save_and_print(result, args.save, args.json, printer)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
