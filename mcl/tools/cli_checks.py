"""Checks a command makes before its run: can it write its outputs, can it read its inputs.

A demo or a benchmark may run for minutes before it writes its recording or its results file. A path it
cannot write (a missing or read-only directory, `/proc`, a directory where a file should be) would then fail at
the very end, after the work was done. The commands call these checks right after parsing their arguments:

    from mcl.tools.cli_checks import check_output_file
    check_output_file(args.rrd, "--rrd")                              # creates missing directories
    check_output_file(args.save, "--save", make_parents=False)        # the directory must exist

Each check raises `CommandError` (a ValueError) with a one-line message naming the option and the path; the
`robocup-mcl` command prints it as `robocup-mcl: <message>` and exits 1 (see `mcl.tools.cli`).

Writability is tried, not inferred from permission bits (which say nothing for root, nor for `/proc` or a
read-only mount): the check opens the file for appending when it exists (nothing is truncated or written), or
creates it and removes it again.
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any


class CommandError(ValueError):
    """A command cannot run as asked (an output it cannot write, an input it cannot read); the message is one
    line naming the option and the path."""


def run_main(main, prog: str) -> int:
    """Run a command's `main(prog=prog)` as `python -m` does: a refusal (CommandError, ValueError, TypeError,
    OSError) is one line on stderr, `PROG: message`, and exit status 1, as under `robocup-mcl`."""
    try:
        return main(prog=prog)
    except (CommandError, ValueError, TypeError, OSError) as error:
        print(f"{prog}: {one_line(error)}", file=sys.stderr)
        return 1


def _reason(error: OSError) -> str:
    return error.strerror or str(error) or type(error).__name__


def check_output_file(path, option: str, make_parents: bool = True) -> Path | None:
    """Make sure the file `path` (given with `option`, e.g. "--rrd") can be written; returns it as a Path (None
    for None: the option was not given).

    make_parents: create missing directories (as the writers of recordings and pose files do); otherwise a
    missing directory is an error.
    """
    if path is None:
        return None
    path = Path(path)
    if str(path) == "" or path.name in ("", ".", ".."):
        raise CommandError(f"{option} {str(path)!r}: not a file name")
    if path.is_dir():
        raise CommandError(f"{option} {path}: is a directory, not a file")
    parent = path.parent
    if not parent.exists():
        if not make_parents:
            raise CommandError(f"{option} {path}: directory {parent} does not exist")
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise CommandError(f"{option} {path}: cannot create directory {parent}: {_reason(error)}") from None
    elif not parent.is_dir():
        raise CommandError(f"{option} {path}: {parent} is not a directory")
    try:
        if path.exists():
            with open(path, "ab"):  # appending writes nothing and truncates nothing
                pass
        else:
            with open(path, "xb"):
                pass
            path.unlink()
    except FileExistsError:  # created in between by someone else: it exists, fine
        pass
    except OSError as error:
        raise CommandError(f"{option} {path}: cannot write there: {_reason(error)}") from None
    return path


def check_output_directory(path, option: str) -> Path | None:
    """Make sure files can be written into the directory `path` (created if missing); returns it as a Path."""
    if path is None:
        return None
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise CommandError(f"{option} {path}: exists and is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise CommandError(f"{option} {path}: cannot create directory: {_reason(error)}") from None
    probe = path / f".robocup-mcl-write-check-{os.getpid()}"
    try:
        with open(probe, "xb"):
            pass
        probe.unlink()
    except OSError as error:
        raise CommandError(f"{option} {path}: cannot write into this directory: {_reason(error)}") from None
    return path


def check_input_file(path, option: str) -> Path | None:
    """Make sure the file `path` exists and can be opened for reading; returns it as a Path."""
    if path is None:
        return None
    path = Path(path)
    if not path.exists():
        raise CommandError(f"{option} {path}: no such file")
    if path.is_dir():
        raise CommandError(f"{option} {path}: is a directory, not a file")
    try:
        with open(path, "rb"):
            pass
    except OSError as error:
        raise CommandError(f"{option} {path}: cannot read: {_reason(error)}") from None
    return path


def one_line(error: BaseException) -> str:
    """An exception's message on one line: an OSError as "path: reason", other messages with their line breaks
    turned into "; ", an empty message as the exception's type name."""
    if isinstance(error, OSError) and error.strerror:
        names = [str(name) for name in (error.filename, error.filename2) if name is not None]
        text = f"{' -> '.join(names)}: {error.strerror}" if names else error.strerror
    else:
        text = str(error)
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return "; ".join(lines) if lines else type(error).__name__


# Progress bars. A command that runs for more than a few seconds shows a tqdm bar on stderr, by one rule: bars
# are shown when stderr is a terminal, never with --json (whose output a program reads) nor with --no-progress;
# a command may offer a way to force them on (`force`, e.g. `robocup-mcl eval --progress` into a log file).
# Bars leave nothing behind when they close, so the command's report and its JSON stay as they were.

NO_PROGRESS_HELP = "no progress bars (they go to stderr, only when it is a terminal, and never with --json)"


def add_progress_option(parser) -> None:
    """Add `--no-progress` to the argparse `parser` (see `progress_wanted`)."""
    parser.add_argument("--no-progress", action="store_true", help=NO_PROGRESS_HELP)


def positive_int(text: str) -> int:
    """An argparse type: an integer >= 1 (argparse reports anything else as a usage error)."""
    import argparse

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be at least 1")
    return value


def check_duration(parser, seconds: float, least: float) -> None:
    """`parser.error` (a usage error, exit 2) unless `--duration` `seconds` is finite and at least `least`."""
    if not (math.isfinite(seconds) and seconds >= least):
        parser.error(f"--duration {seconds} must be at least {least:g} s")


def add_save_option(parser) -> None:
    """Add `--save PATH` (also write the command's JSON results to PATH) to the argparse `parser`."""
    parser.add_argument(
        "--save",
        metavar="PATH",
        help="also write the JSON results to PATH (the figures the docs read from results files)",
    )


def save_json(path, result) -> None:
    """Write `result` as indented JSON to `path` (nothing when `path` is None): what `--save PATH` writes.

    Parameters
    ----------
    path : str or os.PathLike or None
        The file, checked before the run with `check_output_file`.
    result : object
        JSON-serializable results.
    """
    if path is None:
        return
    import json

    Path(path).write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")


def save_and_print(result: Any, save: str | os.PathLike | None, as_json: bool, printer: Callable[[Any], None]) -> None:
    """What a measuring command does with its result: `save_json(save, result)`, then print it, as indented
    JSON with `--json` (`as_json`), else with `printer(result)`.

    Parameters
    ----------
    result : object
        JSON-serializable results.
    save : str or os.PathLike or None
        The `--save` file, checked before the run with `check_output_file`; None: nothing written.
    as_json : bool
        Print `result` as JSON instead of calling `printer`.
    printer : callable
        Prints `result` for a reader.
    """
    import json

    save_json(save, result)
    if as_json:
        print(json.dumps(result, indent=2))
    else:
        printer(result)


def progress_wanted(
    args=None, *, json_output: bool | None = None, no_progress: bool | None = None, force: bool = False, stream=None
) -> bool:
    """Whether a command shows progress bars: not with --json or --no-progress (read from `args`, a parsed
    namespace, unless given), otherwise when `force` or when `stream` (default stderr) is a terminal."""
    import sys

    if json_output is None:
        json_output = bool(getattr(args, "json", False))
    if no_progress is None:
        no_progress = bool(getattr(args, "no_progress", False))
    if json_output or no_progress:
        return False
    if force:
        return True
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):  # closed or replaced by something without a terminal
        return False


def progress_bar(
    iterable=None, *, enabled: bool, total: float | None = None, desc: str | None = None, unit: str = "it", **options
):
    """A tqdm bar on stderr over `iterable` (or updated by hand up to `total`) when `enabled`; otherwise, or
    without tqdm installed, a pass-through with the same `update`, `set_postfix_str` and `close`. The bar is
    cleared when it closes (`leave=False`)."""
    import sys

    try:
        from tqdm import tqdm
    except ImportError:
        return _NoBar(iterable)
    options.setdefault("leave", False)
    options.setdefault("dynamic_ncols", True)
    return tqdm(iterable, total=total, desc=desc, unit=unit, file=sys.stderr, disable=not enabled, **options)


class _NoBar:
    """The bar when tqdm is missing: iterates and ignores the calls."""

    def __init__(self, iterable=None) -> None:
        self._iterable = iterable

    def __iter__(self):
        return iter(self._iterable if self._iterable is not None else ())

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def update(self, n: int = 1) -> None:
        """Nothing to show."""

    def set_postfix_str(self, text: str = "", refresh: bool = True) -> None:
        """Nothing to show."""

    def clear(self) -> None:
        """Nothing to clear."""

    def close(self) -> None:
        """Nothing to close."""


def description(doc: str | None) -> str:
    """A command's description for its --help, from its module docstring: the first paragraph, its lines joined
    and its backquotes dropped, ending with a full stop ("robocup-mcl demo walk: the particle filter on ...")."""
    paragraph = (doc or "").strip().split("\n\n")[0]
    text = " ".join(line.strip() for line in paragraph.splitlines()).replace("`", "").strip()
    if text and text[-1] not in ".!?":
        text = text.rstrip(":;,") + "."
    return text
