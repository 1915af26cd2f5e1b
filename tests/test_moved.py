"""Modules that moved keep their old names for a while: the same module objects, with a DeprecationWarning."""

import importlib
import subprocess
import sys
import warnings

import pytest

MOVED = [
    ("mcl.replay", "mcl.tools.replay"),
    ("mcl.logs", "mcl.tools.logs"),
    ("mcl.logs.mcap_io", "mcl.tools.logs.mcap_io"),
    ("mcl.testing", "mcl.tools.testing"),
    ("mcl.recording", "mcl.tools.recording"),
    ("mcl.tuning.space", "mcl.tools.tuning.space"),
    ("sensing.collision", "proprioception.collision"),
    ("sensing.velocity", "proprioception.velocity"),
    ("sensing.velocity_odometry", "proprioception.velocity_odometry"),
    ("sensing.kinematics", "proprioception.kinematics"),
]


@pytest.mark.parametrize("old, new", MOVED)
def test_an_old_name_gives_the_moved_module_and_warns(old, new):
    sys.modules.pop(old, None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        module = importlib.import_module(old)
    assert module is importlib.import_module(new)
    assert any(issubclass(w.category, DeprecationWarning) and new in str(w.message) for w in caught), caught


def test_classes_are_the_same_whichever_name_imported_them():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from mcl.logs import LogError as old_error
        from sensing.collision import CollisionDetector as old_detector
    from mcl.tools.logs import LogError
    from proprioception.collision import CollisionDetector

    assert old_error is LogError and old_detector is CollisionDetector


def test_an_unknown_name_is_still_an_import_error():
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("mcl.no_such_module")
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("mcl.logs.no_such_module")


def test_python_dash_m_runs_the_moved_module_under_its_old_name():
    done = subprocess.run([sys.executable, "-m", "mcl.cli", "--version"], capture_output=True, text=True, check=False)
    assert done.returncode == 0 and done.stdout.startswith("robocup-mcl"), done.stderr
