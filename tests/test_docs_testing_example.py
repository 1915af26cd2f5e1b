"""docs/testing.md's team test file runs as written and passes, and its tests fail when the model they check
is broken; its parametrized example runs too."""

import re
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from hypothesis import Phase, settings

DOC = Path(__file__).resolve().parent.parent / "docs" / "testing.md"


def python_blocks():
    return re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)


@pytest.fixture
def load():
    """Run a code block of the page as a module (registered while the test runs, as pytest would import it)."""
    names = []

    def run(code: str, name: str, namespace: dict | None = None) -> types.ModuleType:
        module = types.ModuleType(name)
        module.__file__ = str(DOC)
        module.__dict__.update(namespace or {})
        sys.modules[name] = module
        names.append(name)
        exec(compile(code, str(DOC), "exec"), module.__dict__)
        return module

    yield run
    for name in names:
        sys.modules.pop(name, None)


def team_file() -> str:
    return next(block for block in python_blocks() if "def make_filter" in block)


def example_tests(module) -> dict:
    return {name: value for name, value in vars(module).items() if name.startswith("test_") and callable(value)}


def test_the_team_test_file_is_complete_and_passes(load):
    code = team_file()
    assert len(code.strip().splitlines()) <= 52 and len([line for line in code.splitlines() if line.strip()]) <= 40
    module = load(code, "docs_testing_team_file")
    tests = example_tests(module)
    assert sorted(tests) == [
        "test_our_filter_stays_sane_and_reproducible",
        "test_our_odometry_keeps_the_motion_model_contract",
    ]
    for test in tests.values():
        test()


settings.register_profile(
    "docs-no-shrinking",
    parent=settings.get_profile(settings.get_current_profile_name()),
    phases=(Phase.explicit, Phase.generate),
)


@pytest.fixture
def no_shrinking():
    """Hypothesis reports the first failing example instead of shrinking it (the example's own `@settings` take
    what they leave unset from the profile loaded when they are made)."""
    previous = settings.get_current_profile_name()
    settings.load_profile("docs-no-shrinking")
    yield
    settings.load_profile(previous)


def test_the_team_tests_fail_when_the_model_forgets_to_wrap_headings(load, no_shrinking):
    module = load(team_file(), "docs_testing_broken_team_file")

    class Unwrapped(module.ScaledOdometry):
        def predict(self, poses, u, rng):
            super().predict(poses, u, rng)
            poses[:, 2] += 2 * np.pi  # headings leave (-π, π]

    module.ScaledOdometry = Unwrapped  # what make_filter and the contract test build
    for test in example_tests(module).values():
        with pytest.raises(AssertionError, match="heading not wrapped"):
            test()


def test_the_parametrized_example_runs(load):
    team = load(team_file(), "docs_testing_team_models")
    block = next(block for block in python_blocks() if "OUR_MOTION_MODELS" in block)
    module = load(block, "docs_testing_parametrized", {k: v for k, v in vars(team).items() if not k.startswith("__")})
    parametrized = {name: test for name, test in example_tests(module).items() if name not in example_tests(team)}
    assert sorted(parametrized) == ["test_motion_model_contract", "test_sensor_model_contract"]
    for model in module.OUR_MOTION_MODELS:
        module.test_motion_model_contract(model)
    for model in module.OUR_SENSOR_MODELS:
        module.test_sensor_model_contract(model)


def test_the_registration_example_runs_and_leaves_nothing_registered(load, capsys):
    from mcl.tools import testing as mt

    team = load(team_file(), "docs_testing_team_registered")
    block = next(block for block in python_blocks() if "register_motion_model" in block)
    module = load(block, "docs_testing_registration", {k: v for k, v in vars(team).items() if not k.startswith("__")})
    before = mt.registered_models()
    module.test_every_registered_model()
    printed = capsys.readouterr().out
    assert "scaled-odometry" in printed and "exact-bearings" in printed
    assert mt.registered_models() == before
