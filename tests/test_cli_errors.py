"""The command line's errors: one line on stderr naming what is wrong, a non-zero exit, never a traceback.

Every case here fails before any simulation or kernel runs (the output paths are checked right after the
arguments are parsed), so each subprocess takes about as long as the imports.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from mcl.tools.cli_checks import CommandError, check_input_file, check_output_directory, check_output_file, one_line

ROOT = Path(__file__).resolve().parent.parent
UNWRITABLE = "/proc/robocup-mcl-test.rrd"  # /proc takes no new files, not even from root


def cli(*argv, env=None, timeout=180):
    environment = {k: v for k, v in os.environ.items() if k != "ROBOCUP_MCL_DEBUG"}
    environment.update(env or {})
    return subprocess.run(
        [sys.executable, "-m", "mcl.tools.cli", *map(str, argv)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
        env=environment,
    )


def python(code, env=None):
    environment = {k: v for k, v in os.environ.items() if k != "ROBOCUP_MCL_DEBUG"}
    environment.update(env or {})
    return subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=180, env=environment
    )


def assert_one_line(done, *named, code=1, prefix="robocup-mcl: "):
    assert done.returncode == code, (done.returncode, done.stderr[-2000:])
    assert "Traceback" not in done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith(prefix), lines[0]
    for name in named:
        assert str(name) in lines[0], (name, lines[0])
    return lines[0]


@pytest.fixture
def not_a_directory(tmp_path):
    """A regular file, to be used where a directory is needed."""
    path = tmp_path / "a-file"
    path.write_text("not a directory\n")
    return path


@pytest.fixture
def garbage(tmp_path):
    path = tmp_path / "garbage.mcap"
    path.write_bytes(bytes(range(256)) * 4)
    return path


# -- output paths, checked before the run ---------------------------------------------------------------------
@pytest.mark.parametrize(
    "argv",
    [
        ("demo", "walk", "--rrd", UNWRITABLE),
        ("demo", "velocity", "--rrd", UNWRITABLE),
        ("demo", "collision", "--case", "single", "--model", "adaptive", "--rrd", UNWRITABLE),
        ("demo", "odometry", "--record", "/proc/robocup-mcl-test.npz"),
        ("bench", "--save", "/proc/robocup-mcl-test.json"),
        ("bench", "--quick", "--plot=/proc/robocup-mcl-test.png"),
        ("soak", "--save", "/proc/robocup-mcl-test.json"),
    ],
    ids=lambda argv: " ".join(argv[:2]),
)
def test_an_unwritable_output_path_fails_at_once(argv):
    line = assert_one_line(cli(*argv), argv[-1].split("=")[-1])
    assert "cannot write there" in line


def test_an_output_under_a_file_names_the_file(not_a_directory):
    target = not_a_directory / "walk.rrd"
    line = assert_one_line(cli("demo", "walk", "--rrd", target), target)
    assert f"{not_a_directory} is not a directory" in line


def test_an_output_that_is_a_directory_is_refused(tmp_path):
    line = assert_one_line(cli("demo", "walk", "--rrd", tmp_path), tmp_path)
    assert "is a directory" in line


@pytest.mark.parametrize("command", [("eval",), ("soak", "--minutes", "0.1")], ids=lambda c: c[0])
def test_save_needs_an_existing_directory(tmp_path, command):
    target = tmp_path / "no" / "such" / "dir" / "results.json"
    line = assert_one_line(cli(*command, "--save", target), target)
    assert "does not exist" in line
    assert not (tmp_path / "no").exists()


def test_odometry_checks_its_log_and_its_model_directory(tmp_path, not_a_directory):
    missing = tmp_path / "no-log.npz"
    line = assert_one_line(cli("demo", "odometry", "--train", missing, "--save", tmp_path / "models"), missing)
    assert "no such file" in line
    target = not_a_directory / "models"
    assert_one_line(cli("demo", "odometry", "--train", not_a_directory, "--save", target), target)


# -- replay: bad logs, fields, outputs --------------------------------------------------------------------------
def test_replay_of_a_missing_log():
    assert_one_line(cli("replay", "/no/such/log.mcap"), "/no/such/log.mcap", prefix="robocup-mcl replay: ")


@pytest.mark.parametrize("name", ["garbage.mcap", "garbage.npz", "empty.mcap", "folder"])
def test_replay_of_a_file_that_is_not_a_log(tmp_path, name):
    path = tmp_path / name
    if name == "folder":
        path.mkdir()
    elif name.startswith("empty"):
        path.write_bytes(b"")
    else:
        path.write_bytes(bytes(range(256)) * 4)
    assert_one_line(cli("replay", path), path, prefix="robocup-mcl replay: ")
    assert_one_line(cli("replay", path, "--list"), path, prefix="robocup-mcl replay: ")


def test_replay_with_a_missing_field_file(garbage):
    assert_one_line(cli("replay", garbage, "--field", "no_such.toml"), "no_such.toml", prefix="robocup-mcl replay: ")


def test_replay_checks_its_outputs_before_reading_the_log(tmp_path):
    log = tmp_path / "not-read-yet.mcap"  # does not exist: the outputs are checked first
    assert_one_line(cli("replay", log, "--rrd", UNWRITABLE), UNWRITABLE, prefix="robocup-mcl replay: ")
    line = assert_one_line(
        cli("replay", log, "--out", tmp_path / "poses.txt"), tmp_path / "poses.txt", prefix="robocup-mcl replay: "
    )
    assert ".mcap, .csv, .npz" in line
    assert_one_line(
        cli("replay", log, "--out", "/proc/robocup-mcl-test.csv"),
        "/proc/robocup-mcl-test.csv",
        prefix="robocup-mcl replay: ",
    )


# -- usage errors stay argparse's -------------------------------------------------------------------------------
def test_usage_errors_exit_2_without_a_traceback():
    done = cli("demo", "walk", "--particles", "-3")
    assert done.returncode == 2 and "Traceback" not in done.stderr and "--particles -3" in done.stderr
    done = cli("demo", "walk", "--seeds", "x")
    assert done.returncode == 2 and "Traceback" not in done.stderr and "--seeds 'x'" in done.stderr
    assert_one_line(cli("demo", "dance"), "dance", code=2)


# -- the last line of defence: bugs, interrupts, the debug variable ------------------------------------------
RAISE = "import sys, mcl.tools.cli as cli\ndef run(argv):\n    raise {error}\ncli._run = run\nsys.exit(cli.main([]))\n"


@pytest.mark.parametrize(
    "error, message",
    [
        ("ValueError('particles = -1 must be > 0')", "robocup-mcl: particles = -1 must be > 0"),
        ("TypeError('seed must be an integer')", "robocup-mcl: seed must be an integer"),
        (
            "FileNotFoundError(2, 'No such file or directory', '/data/game.mcap')",
            "robocup-mcl: /data/game.mcap: No such file or directory",
        ),
        ("PermissionError(13, 'Permission denied', '/data/out.rrd')", "robocup-mcl: /data/out.rrd: Permission denied"),
        ("ValueError('first line\\nsecond line')", "robocup-mcl: first line; second line"),
    ],
)
def test_user_errors_are_one_line(error, message):
    done = python(RAISE.format(error=error))
    assert done.returncode == 1 and done.stderr.splitlines() == [message]


def test_a_bug_is_one_line_with_a_hint_and_a_traceback_on_request():
    done = python(RAISE.format(error="KeyError('particles')"))
    line = assert_one_line(done, "internal error: KeyError: 'particles'", "ROBOCUP_MCL_DEBUG=1")
    assert "bug" in line
    debug = python(RAISE.format(error="KeyError('particles')"), env={"ROBOCUP_MCL_DEBUG": "1"})
    assert debug.returncode == 1 and "Traceback" in debug.stderr and "KeyError: 'particles'" in debug.stderr


def test_the_debug_variable_shows_the_traceback_of_a_user_error():
    done = cli("demo", "walk", "--rrd", UNWRITABLE, env={"ROBOCUP_MCL_DEBUG": "1"})
    assert done.returncode == 1 and "Traceback" in done.stderr and "CommandError" in done.stderr
    done = cli("demo", "walk", "--rrd", UNWRITABLE, env={"ROBOCUP_MCL_DEBUG": "0"})  # "0": off
    assert_one_line(done, UNWRITABLE)


def test_an_interrupt_exits_130_with_one_line():
    done = python(RAISE.format(error="KeyboardInterrupt()"))
    assert done.returncode == 130 and done.stderr.splitlines() == ["robocup-mcl: interrupted"]


def test_a_closed_stdout_is_not_reported():
    done = python(RAISE.format(error="BrokenPipeError(32, 'Broken pipe')"))
    assert done.returncode == 1 and done.stderr == ""


# -- the checks themselves --------------------------------------------------------------------------------------
def test_the_output_check_leaves_no_trace_and_truncates_nothing(tmp_path):
    new = tmp_path / "new.json"
    assert check_output_file(new, "--save") == new and not new.exists()
    old = tmp_path / "old.json"
    old.write_text("keep me\n")
    check_output_file(old, "--save")
    assert old.read_text() == "keep me\n"
    nested = tmp_path / "a" / "b" / "walk.rrd"
    check_output_file(nested, "--rrd")  # the writers create missing directories too
    assert nested.parent.is_dir() and not nested.exists()
    with pytest.raises(CommandError, match="does not exist"):
        check_output_file(tmp_path / "c" / "x.json", "--save", make_parents=False)
    assert check_output_file(None, "--save") is None
    models = tmp_path / "models"
    check_output_directory(models, "--save")
    assert models.is_dir() and list(models.iterdir()) == []
    with pytest.raises(CommandError, match="is a directory"):
        check_input_file(tmp_path, "--train")


def test_one_line_messages():
    assert one_line(FileNotFoundError(2, "No such file or directory", "x.mcap")) == "x.mcap: No such file or directory"
    assert one_line(OSError(28, "No space left on device")) == "No space left on device"
    assert one_line(ValueError("a\n\n  b  \n")) == "a; b"
    assert one_line(RuntimeError()) == "RuntimeError"


def test_a_module_run_with_python_dash_m_refuses_in_one_line(tmp_path):
    """`python -m mcl.tools.ros.bench` (as `make ros` and the node's docs run the ROS tools) refuses a bad value
    the way `robocup-mcl` does: one line naming the program, exit 1, no traceback."""
    done = subprocess.run(
        [sys.executable, "-m", "mcl.tools.ros.bench", str(tmp_path / "missing.mcap"), "--rate", "0"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 1 and done.stderr.splitlines() == [
        "python -m mcl.tools.ros.bench: --rate must be > 0, --repeat >= 1 and --particles > 0"
    ], done.stderr


def test_run_main_turns_a_refusal_into_one_line(capsys):
    from mcl.tools.cli_checks import CommandError, run_main

    def refuses(prog):
        raise CommandError("--save: /nowhere/x.json: No such file or directory")

    assert run_main(refuses, "prog") == 1
    assert capsys.readouterr().err == "prog: --save: /nowhere/x.json: No such file or directory\n"
    assert run_main(lambda prog: 0, "prog") == 0
