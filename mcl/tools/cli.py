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
    robocup-mcl bench team [--rounds 5] [--json] [--save PATH]  # team messages and the ball in the loop
    robocup-mcl bench same [REV] [--seeds 20] [--json] [--save PATH]  # results bit for bit against REV
    robocup-mcl bench engines [--sizes ...] [--json] [--save PATH]  # the numpy reference engine's step
    robocup-mcl eval [--families ...] [--split train|holdout|both] [--json] [--save PATH]   # the scenario battery
    robocup-mcl soak [--minutes 60] [--particles 500] [--seed S] [--json] [--save PATH]  # an hour in the loop
    robocup-mcl fit adaptive|ekf|odometry [...] [--json] [--save PATH]   # a model's parameters from training logs
    robocup-mcl tune LOGS... --space SPACE.toml --trials N [--address A] [--out PROFILE.toml] [--json]
                                                      # the localizer's settings from a team's logs (Ray, Optuna)
    robocup-mcl node [--field F] [--particles N] [--ros-args ...]   # the live ROS 2 node (`make ros` installs ROS)
    robocup-mcl node bench LOG [--seconds S] [--json] [--save PATH]  # a log played to the node over DDS: latency
    robocup-mcl node play LOG [--rate R]              # a robot's MCAP log played to its topics
    robocup-mcl node messages [--check]               # generate the ROS messages that have no wheel
    robocup-mcl node figure PUBLISHED.json --out PNG  # draw what the node published in a bench run
    robocup-mcl --version                             # the installed version
    robocup-mcl COMMAND --help                        # every option of a command, each with its help

First run. The filter's kernels are compiled by numba on a machine's first run (a minute or more) and cached;
the commands warm them up before they measure anything, say so on stderr when compiling, and report the time
apart ("compiled in 41 s"; compile_seconds in --json output). Progress bars go to stderr, only when it is a
terminal, never with --json, and not with --no-progress (docs/getting-started.md).

Errors. A command that cannot run as asked prints one line on stderr, `robocup-mcl: <message>` (the replay's
own: `robocup-mcl replay: <message>`), and exits 1, never a traceback: bad values (ValueError, TypeError),
files it cannot read or write (OSError: a missing log, an unwritable output path, no permission), and the
library's own errors (`mcl.tools.logs.LogError`, `mcl.tools.cli_checks.CommandError`, `benchmarks.compare.CompareError`).
The commands check their output paths (`--rrd`, `--save`, `--out`, `--plot`, `--record`) right after parsing
their arguments, before a long run starts (`mcl.tools.cli_checks`). Usage errors (an unknown option, a malformed
value) are argparse's: the usage line and the message, exit 2. Ctrl-C prints `robocup-mcl: interrupted` and
exits 130. Any other exception is a bug in robocup-mcl: one line naming its type and message, a hint to set
the debug variable, exit 1. With `ROBOCUP_MCL_DEBUG=1` in the environment nothing is caught: every error
raises with its full traceback. (docs/reliability.md, "Command-line errors".)
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys

from mcl.numba_cache import ROOT, guard_source_checkout, is_source_checkout, serialize_cache_access
from mcl.tools.cli_checks import CommandError, one_line

DEBUG_VARIABLE = "ROBOCUP_MCL_DEBUG"
EXIT_ERROR, EXIT_USAGE, EXIT_INTERRUPTED = 1, 2, 130
NO_RERUN = (
    "Rerun recordings (--rrd, the recording benchmark) need the rerun-sdk package, 0.41, which needs "
    "Python >= 3.11: pip install 'rerun-sdk~=0.41.0'"
)

DEMOS = {
    "walk": ("demos.walk", "the particle filter on the 60 s walk scenario with a kidnapping"),
    "velocity": ("demos.velocity", "IMU + leg kinematics velocity estimators against the truth"),
    "collision": ("demos.collision", "Hoffmann's collision experiments: adaptive versus velocity-linear model"),
    "odometry": ("demos.odometry", "learned footstep odometry (Rouxel et al.): drift of raw vs LWPR-corrected steps"),
    "latency": ("demos.latency", "a late camera (80 ms): tracking with and without latency compensation"),
    "penalty": ("demos.penalty", "returning from a penalty on an unknown touchline: convergence, mirror share"),
    "venue": ("demos.venue", "logs of a new venue (odometry and detection noise 20 % off the defaults) to tune on"),
}
BENCHES = {
    "step": ("benchmarks.bench", "one full filter step per particle count, numba versus plain numpy"),
    "lwpr": ("demos.lwpr_cross", "LWPR on the cross benchmark: accuracy, receptive fields, speed"),
    "replay": ("demos.replay_speed", "a 10-minute MCAP log replayed, in multiples of real time"),
    "compare": ("benchmarks.compare", "this checkout's speed against another revision's, in alternated runs"),
    "tune": (
        "benchmarks.tune_scaling",
        "robocup-mcl tune with 1 and 2 Ray workers, Ray's cost per task, cluster projection",
    ),
    "same": ("benchmarks.same", "results bit for bit against another revision: battery, walk, paper demos, replay"),
    "team": ("benchmarks.team", "the robot's loop with and without team messages; one team message, one ball sighting"),
    "engines": ("benchmarks.engines", "the filter's step on the numpy reference engine against the compiled engine"),
}
FITS = {
    "adaptive": ("demos.fit_adaptive", "the adaptive motion model's collision terms (beta) from training logs"),
    "ekf": ("demos.fit_velocity", "the velocity EKF's noise settings from training walks"),
    "odometry": ("demos.fit_odometry", "LWPR's meta-parameters for the learned odometry from training logs"),
}

NODE_TOOLS = {
    "bench": (
        "mcl.tools.ros.bench",
        "a log played to the node over DDS in a loopback-only namespace: latency, CPU, drops",
    ),
    "play": ("mcl.tools.ros.player", "a robot's MCAP log played to its topics, in real time or faster"),
    "messages": ("mcl.tools.ros.messages", "generate the ROS 2 message packages that have no wheel (cmake)"),
    "figure": ("mcl.tools.ros.figure", "draw what the node published in a bench run (--published) as a PNG"),
}


def _usage() -> str:
    lines = [__doc__.strip(), "", "demos:"]
    lines += [f"  {name:<10} {text}" for name, (_, text) in DEMOS.items()]
    lines += ["benchmarks:"] + [f"  {name:<10} {text}" for name, (_, text) in BENCHES.items()]
    lines += ["fits:"] + [f"  {name:<10} {text}" for name, (_, text) in FITS.items()]
    lines += ["node tools:"] + [f"  {name:<10} {text}" for name, (_, text) in NODE_TOOLS.items()]
    return "\n".join(lines)


PROGRAM = "robocup-mcl"
PACKAGE = "robocup-mcl"


def version() -> str:
    """The installed distribution's version (importlib.metadata), else the `mcl` package's __version__, else
    "unknown" (a clone run without installing)."""
    from importlib import metadata

    try:
        return metadata.version(PACKAGE)
    except metadata.PackageNotFoundError:
        import mcl

        return str(getattr(mcl, "__version__", "unknown"))


def _dispatch(table: dict, name: str, argv: list[str], what: str, prog: str) -> int:
    if name not in table:
        print(f"robocup-mcl: unknown {what} {name!r}; choose from {', '.join(table)}", file=sys.stderr)
        return EXIT_USAGE
    if (what, name) in OUTPUT_OPTIONS:
        _check_outputs(argv, OUTPUT_OPTIONS[(what, name)])
    if any(a == "--rrd" or a.startswith("--rrd=") for a in argv) and not rerun_available():
        raise CommandError(NO_RERUN)  # before a run of minutes, not after it
    return _call(table[name][0], argv, prog)


def rerun_available() -> bool:
    """Whether the rerun-sdk package can be imported (it needs Python >= 3.11)."""
    return importlib.util.find_spec("rerun") is not None


def _call(module: str, argv: list[str], prog: str) -> int:
    """The harness `module`'s main(argv, prog=prog): its usage line names the command as typed."""
    return int(_harness(module).main(argv, prog=prog) or 0)


def commands() -> dict[str, str]:
    """Every subcommand's program name (as its usage line shows it) and the module whose `build_parser(prog)`
    and `main(argv, prog)` run it."""
    table = {f"{PROGRAM} demo {name}": module for name, (module, _) in DEMOS.items()}
    table.update({f"{PROGRAM} bench {name}": module for name, (module, _) in BENCHES.items()})
    table.update({f"{PROGRAM} fit {name}": module for name, (module, _) in FITS.items()})
    table.update({f"{PROGRAM} node {name}": module for name, (module, _) in NODE_TOOLS.items()})
    table.update(
        {
            f"{PROGRAM} bench": BENCHES["step"][0],
            f"{PROGRAM} eval": "demos.battery",
            f"{PROGRAM} soak": "benchmarks.soak",
            f"{PROGRAM} replay": "mcl.tools.replay",
            f"{PROGRAM} tune": "demos.tune",
            f"{PROGRAM} node": "mcl.tools.ros.node",
        }
    )
    return table


def _harness(name: str):
    """The demo or benchmark module `name`, found by name at run time: the library never imports `demos` or
    `benchmarks`; they run from a clone (`benchmarks` is not installed with the package)."""
    package = name.split(".")[0]
    if importlib.util.find_spec(package) is None and is_source_checkout() and str(ROOT) not in sys.path:
        sys.path.append(str(ROOT))  # a clone: its benchmarks/ beside the installed packages
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as error:
        if error.name != package:
            raise
        raise CommandError(
            f"{name} is not here: the {package} run from a clone of the repository "
            "(git clone, then `make demo` or `.venv/bin/robocup-mcl ...` in it)"
        ) from None


# Output options of commands whose own main does not check them before its run (the step benchmark runs for
# minutes and writes --save and --plot at the end): checked here, before dispatch.
OUTPUT_OPTIONS = {("benchmark", "step"): ("--save", "--plot"), ("benchmark", "compare"): ("--save",)}


def _check_outputs(argv: list[str], options: tuple[str, ...]) -> None:
    """`check_output_file` for each of `options` given in `argv` (exact option names, `--opt PATH` or
    `--opt=PATH`); anything else, including malformed arguments, is left to the command's own parser."""
    import argparse

    from mcl.tools.cli_checks import check_output_file

    class _Lenient(argparse.ArgumentParser):
        def error(self, message):  # the command's parser reports usage errors, not this one
            raise CommandError(message)

    parser = _Lenient(add_help=False, allow_abbrev=False)
    for option in options:
        parser.add_argument(option)
    try:
        known, _ = parser.parse_known_args(argv)
    except CommandError:
        return
    for option in options:
        check_output_file(getattr(known, option.lstrip("-").replace("-", "_")), option)


def _run(argv: list[str] | None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    guard_source_checkout()  # before any kernel runs (see mcl.numba_cache)
    serialize_cache_access()  # other processes may share numba's cache (a test session, a tuning study)
    if not argv or argv[0] in ("-h", "--help"):
        print(_usage())
        return 0 if argv else EXIT_USAGE
    if argv[0] in ("-V", "--version"):
        print(f"{PROGRAM} {version()}")
        return 0
    command, rest = argv[0], argv[1:]
    if command == "demo":
        if not rest or rest[0] in ("-h", "--help"):
            print(_usage())
            return 0 if rest else EXIT_USAGE
        return _dispatch(DEMOS, rest[0], rest[1:], "demo", f"{PROGRAM} demo {rest[0]}")
    if command == "replay":
        from mcl.tools.replay import main as replay_main

        return replay_main(rest, prog=f"{PROGRAM} replay")
    if command == "eval":
        return _call("demos.battery", rest, f"{PROGRAM} eval")
    if command == "tune":
        return _call("demos.tune", rest, f"{PROGRAM} tune")
    if command == "soak":
        return _call("benchmarks.soak", rest, f"{PROGRAM} soak")
    if command == "bench":
        if rest and not rest[0].startswith("-"):
            return _dispatch(BENCHES, rest[0], rest[1:], "benchmark", f"{PROGRAM} bench {rest[0]}")
        return _dispatch(BENCHES, "step", rest, "benchmark", f"{PROGRAM} bench")
    if command == "node":
        if rest and rest[0] in NODE_TOOLS:
            return _dispatch(NODE_TOOLS, rest[0], rest[1:], "node tool", f"{PROGRAM} node {rest[0]}")
        return _call("mcl.tools.ros.node", rest, f"{PROGRAM} node")
    if command == "fit":
        if not rest or rest[0] in ("-h", "--help"):
            print(_usage())
            return 0 if rest else EXIT_USAGE
        return _dispatch(FITS, rest[0], rest[1:], "fit", f"{PROGRAM} fit {rest[0]}")
    print(f"robocup-mcl: unknown command {command!r}\n\n{_usage()}", file=sys.stderr)
    return EXIT_USAGE


def debugging() -> bool:
    """Whether ROBOCUP_MCL_DEBUG asks for tracebacks (set, and neither empty nor "0")."""
    return os.environ.get(DEBUG_VARIABLE, "") not in ("", "0")


def _user_errors() -> tuple[type[BaseException], ...]:
    """The exceptions that mean "cannot run as asked" rather than a bug (see the module docstring)."""
    errors: list[type[BaseException]] = [ValueError, TypeError, OSError, CommandError]
    for module, name in (("mcl.tools.logs", "LogError"), ("benchmarks.compare", "CompareError")):
        loaded = sys.modules.get(module)  # raised only by a module already imported
        if loaded is not None and hasattr(loaded, name):
            errors.append(getattr(loaded, name))
    return tuple(errors)


def _say(message: str) -> None:
    try:
        print(f"robocup-mcl: {message}", file=sys.stderr, flush=True)
    except OSError:  # stderr itself is gone: nothing left to tell
        pass


def _silence_stdout() -> None:
    """After a broken pipe on stdout (`robocup-mcl ... | head`): point it at /dev/null, so the interpreter's
    final flush does not fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: list[str] | None = None) -> int:
    """The `robocup-mcl` command; returns the exit status (see the module docstring for errors)."""
    try:
        code = _run(argv)
        sys.stdout.flush()
        return code
    except KeyboardInterrupt:
        if debugging():
            raise
        _say("interrupted")
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # The reader of stdout went away (`| head`): not an error worth a message.
        if debugging():
            raise
        _silence_stdout()
        return EXIT_ERROR
    except Exception as error:  # noqa: BLE001 - the command's last line of defence, see the module docstring
        if debugging():
            raise
        if isinstance(error, ModuleNotFoundError) and (error.name or "").split(".")[0] == "rerun":
            _say(NO_RERUN)
        elif isinstance(error, _user_errors()):
            _say(one_line(error))
        else:
            _say(
                f"internal error: {type(error).__name__}: {one_line(error)} "
                f"(a bug in robocup-mcl; set {DEBUG_VARIABLE}=1 for the traceback)"
            )
        return EXIT_ERROR


if __name__ == "__main__":
    raise SystemExit(main())
