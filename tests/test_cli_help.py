"""The command line speaks for itself: every subcommand's --help names the program as typed and gives every
option a help text; `robocup-mcl --version`; a wrong --field name lists the presets in one line; progress bars
stay out of --json output; the first run says that it compiles (mcl.numba_cache.warm_up) and reports the time
apart."""

from __future__ import annotations

import argparse
import importlib
import io
import json
import sys
import textwrap

import pytest

from mcl import numba_cache
from mcl.tools.cli import _harness, commands, version
from mcl.tools.cli import main as cli_main
from mcl.tools.cli_checks import description, progress_bar, progress_wanted

COMMANDS = commands()


def _words(prog: str) -> list[str]:
    return prog.split()[1:]


@pytest.mark.parametrize("prog", sorted(COMMANDS))
def test_every_option_has_help_and_the_parser_names_the_command(prog):
    parser = _harness(COMMANDS[prog]).build_parser(prog)
    assert parser.prog == prog
    assert parser.description and parser.description.rstrip().endswith("."), parser.description
    assert "python -m" not in parser.format_usage()
    silent = [
        action.option_strings or [action.dest]
        for action in parser._actions
        if not isinstance(action, argparse._HelpAction) and not (action.help or "").strip()
    ]
    assert not silent, f"{prog}: options without help text: {silent}"


@pytest.mark.parametrize("prog", sorted(COMMANDS))
def test_help_exits_0_and_names_the_program_as_typed(prog, capsys):
    with pytest.raises(SystemExit) as done:
        cli_main([*_words(prog), "--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: {prog} "), out[:200]
    assert "--no-progress" in out or prog.endswith("compare")


def test_version_prints_the_installed_version(capsys):
    assert cli_main(["--version"]) == 0
    out = capsys.readouterr().out.strip()
    assert out == f"robocup-mcl {version()}" and version() not in ("", "unknown")


def test_a_wrong_field_name_lists_the_presets_in_one_line(tmp_path, capsys):
    log = tmp_path / "walk.npz"
    log.write_bytes(b"")
    assert cli_main(["replay", str(log), "--field", "spll"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "unknown field 'spll'" in err and "did you mean 'spl'" in err
    assert "presets: spl, kidsize, adultsize" in err and ".toml" in err


def test_a_field_is_a_preset_name_in_any_case_or_a_file(tmp_path):
    from field.io import field_by_name_or_path, save_field

    assert field_by_name_or_path("KidSize").name == field_by_name_or_path("kidsize").name
    path = tmp_path / "lab.toml"
    save_field(field_by_name_or_path("spl"), path)
    assert field_by_name_or_path(str(path)).dims == field_by_name_or_path("spl").dims
    with pytest.raises(ValueError, match="does not exist"):  # a field file's name: the file's problem
        field_by_name_or_path(str(tmp_path / "missing.toml"))


def test_descriptions_are_whole_sentences():
    assert (
        description("`robocup-mcl x`: one thing,\n    over two lines\n\nmore")
        == "robocup-mcl x: one thing, over two lines."
    )
    assert description("Done.") == "Done."


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_rule():
    terminal, pipe = _Terminal(), io.StringIO()
    assert progress_wanted(stream=terminal) and not progress_wanted(stream=pipe)
    assert progress_wanted(stream=pipe, force=True)
    assert not progress_wanted(stream=terminal, json_output=True)
    assert not progress_wanted(stream=terminal, force=True, json_output=True)
    assert not progress_wanted(stream=terminal, no_progress=True)
    assert not progress_wanted(argparse.Namespace(json=True, no_progress=False), stream=terminal)


def test_a_disabled_bar_writes_nothing(monkeypatch):
    stderr = _Terminal()
    monkeypatch.setattr(sys, "stderr", stderr)
    assert list(progress_bar(range(3), enabled=False)) == [0, 1, 2]
    assert stderr.getvalue() == ""
    assert list(progress_bar(range(3), enabled=True, desc="here")) == [0, 1, 2]
    assert "here" in stderr.getvalue()


def test_no_bar_in_json_output_even_on_a_terminal(monkeypatch, capsys):
    from demos.walk import main as walk_main

    with capsys.disabled():
        stdout, stderr = io.StringIO(), _Terminal()
        monkeypatch.setattr(sys, "stdout", stdout)
        monkeypatch.setattr(sys, "stderr", stderr)
        assert walk_main(["--duration", "2", "--particles", "50", "--json"]) == 0
        monkeypatch.undo()
    out = json.loads(stdout.getvalue())
    assert out["compile_seconds"] >= 0 and "kernels_cached" in out and out["first_step_s"] > 0
    assert "step/s" not in stderr.getvalue() and "it/s" not in stderr.getvalue() and "|" not in stderr.getvalue()


# The first run: what decides the message, and what warm_up prints.


def test_first_run_decision():
    assert numba_cache.first_run_decision(False) == (True, True)  # not cached: say so, compile
    assert numba_cache.first_run_decision(True) == (False, False)  # cached: nothing to say
    assert numba_cache.first_run_decision(None) == (False, True)  # cannot tell: no promise either way
    assert numba_cache.first_run_decision(False, quiet=True) == (False, True)


def test_kernels_cached_combines_the_kernels(monkeypatch):
    states = {"a": True, "b": False, "c": None}
    monkeypatch.setattr(numba_cache, "kernel_cached", lambda kernel: states[kernel])
    assert numba_cache.kernels_cached(["a"]) is True
    assert numba_cache.kernels_cached(["a", "b", "c"]) is False
    assert numba_cache.kernels_cached(["a", "c"]) is None
    assert numba_cache.kernels_cached([]) is None


@pytest.mark.parametrize("cached", [False, True])
def test_warm_up_announces_a_compilation_and_reports_its_time(monkeypatch, cached):
    monkeypatch.setattr(numba_cache, "kernels_cached", lambda kernels: cached)
    called, stream = [], io.StringIO()
    warm = numba_cache.warm_up(
        [("one", lambda: called.append(1)), ("two", lambda: called.append(2))],
        ["kernel"],
        progress=False,
        stream=stream,
    )
    assert called == [1, 2] and warm.seconds >= 0 and warm.as_dict()["kernels_cached"] is cached
    lines = stream.getvalue().splitlines()
    if cached:
        assert lines == [] and "loaded from the cache" in warm.summary()
    else:
        assert lines[0] == f"robocup-mcl: {numba_cache.FIRST_RUN_MESSAGE}"
        assert lines[1].startswith("robocup-mcl: compiled in ") and lines[1].endswith(" s") and len(lines) == 2


def test_warm_up_shows_the_groups_on_a_bar_while_compiling(monkeypatch):
    monkeypatch.setattr(numba_cache, "kernels_cached", lambda kernels: False)
    stream = _Terminal()
    numba_cache.warm_up([("motion model", lambda: None)], ["kernel"], progress=True, stream=stream)
    assert "compiling: " in stream.getvalue() and "motion model" in stream.getvalue()


def test_kernel_cached_reads_numba_s_cache(tmp_path, monkeypatch):
    """A real kernel in a fresh module: not cached before its first call, cached after it, and not cached once
    its source changes."""
    source = tmp_path / "fresh_kernel_module.py"
    source.write_text(
        textwrap.dedent("""
        import numba

        @numba.njit(cache=True)
        def twice(x):
            return 2 * x
    """)
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module("fresh_kernel_module")
    try:
        assert numba_cache.kernel_cached(module.twice) is False
        assert module.twice(2) == 4
        assert numba_cache.kernel_cached(module.twice) is True
        assert numba_cache.kernel_cached(len) is None  # not a numba kernel: cannot tell
    finally:
        sys.modules.pop("fresh_kernel_module", None)


def test_a_command_without_rerun_says_so_in_one_line(monkeypatch, capsys, tmp_path):
    """On a Python without rerun-sdk (3.10), a command asked for a recording fails at once with one line naming
    the package; the same command without --rrd runs."""
    import mcl.tools.cli as cli

    monkeypatch.setattr(cli, "rerun_available", lambda: False)
    assert cli_main(["demo", "walk", "--duration", "1", "--rrd", str(tmp_path / "walk.rrd")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rerun-sdk" in err[0] and err[0].startswith("robocup-mcl")
    assert not (tmp_path / "walk.rrd").exists()


def test_an_import_of_rerun_that_fails_inside_a_command_is_one_line_too(monkeypatch, capsys):
    import mcl.tools.cli as cli

    def fails(argv):
        raise ModuleNotFoundError("No module named 'rerun'", name="rerun")

    monkeypatch.setattr(cli, "_run", fails)
    assert cli_main(["demo", "walk"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"robocup-mcl: {cli.NO_RERUN}"]
