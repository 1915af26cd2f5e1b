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


def _warned(call):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = call()
    messages = [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]
    assert len(messages) == 1 and "call it from there" in messages[0], messages
    return value, messages[0]


@pytest.mark.parametrize("name", ["log_likelihood", "explained", "seen", "missed_in_view", "sample_poses"])
def test_a_models_old_reference_method_is_its_numpy_twins_and_warns(name):
    from field import spl
    from sensing import LandmarkSensorModel

    model = LandmarkSensorModel(spl(), range_noise_floor=0.2)
    old, message = _warned(lambda: getattr(model, f"{name}_reference"))
    assert f"numpy_twin().{name}" in message
    assert old.__func__ is getattr(type(model.numpy_twin()), name) and old.__self__.model is model


def test_the_line_models_and_the_recordings_old_reference_names_warn_and_compute_the_same():
    import numpy as np

    from field import spl
    from mcl.tools import recording
    from sensing import LineSensorModel, Observations

    model = LineSensorModel(spl())
    poses = np.array([[0.0, 0.0, 0.0], [1.0, -2.0, 0.5]])
    observations = Observations.from_arrays([], [], [], line_points=np.array([[1.0, 0.0], [2.0, 0.5]]))
    old, _ = _warned(lambda: model.log_likelihood_reference)
    assert np.array_equal(old(poses, observations), model.numpy_twin().log_likelihood(poses, observations))
    weights = np.array([0.1, 0.7, 0.2])
    colors, message = _warned(lambda: recording.weight_colors_reference(weights))
    assert "reference=True" in message
    assert np.array_equal(colors, recording.weight_colors(weights))


def test_an_unknown_method_is_still_an_attribute_error_and_the_model_copies():
    import copy
    import pickle

    from field import spl
    from sensing import LandmarkSensorModel

    model = LandmarkSensorModel(spl())
    with pytest.raises(AttributeError, match="no_such_reference"):
        model.no_such_reference  # noqa: B018
    assert not hasattr(model, "predict")
    again = pickle.loads(pickle.dumps(model))
    assert copy.deepcopy(again).range_noise_floor == model.range_noise_floor
