"""docs/extending.md: the motion model and the sensor model written there from scratch run as written, get the
filter's fast path, and give the plain sequence of calls' particles bit for bit (with camera latency too)."""

import re
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from field import spl
from mcl import ParticleFilter
from mcl.contracts import fast_path
from mcl.latency import move_back
from motion_models import MotionInput
from sensing import Observations

DOC = Path(__file__).resolve().parent.parent / "docs" / "extending.md"


@pytest.fixture(scope="module")
def namespace():
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), re.DOTALL)
    assert len(blocks) == 3
    # A module of its own, importable by name: numba finds a cached kernel's module again when it loads it.
    module = sys.modules.setdefault("extending_example", types.ModuleType("extending_example"))
    for block in blocks:
        exec(compile(block, str(DOC), "exec"), module.__dict__)  # the third block asserts the fast path, steps
    return module.__dict__


class _Plain:
    """A model wrapped so that the filter sees only the required methods: no capability, no fast path."""

    def __init__(self, model):
        self.model = model

    def check(self, *args):
        return self.model.check(*args)

    def predict(self, poses, u, rng):
        return self.model.predict(poses, u, rng)

    def log_likelihood(self, poses, observations, out=None):
        return self.model.log_likelihood(poses, observations, out=out)


def test_the_examples_get_the_fast_path(namespace):
    motion, sensor = namespace["ProportionalNoise"](), namespace["RangeOnlyModel"](spl())
    assert fast_path(motion, sensor)["step"]
    assert not fast_path(_Plain(motion), _Plain(sensor))["step"]
    from mcl.tools.testing import assert_fused_likelihood

    poses = np.random.default_rng(2).uniform([-5, -3, -4], [5, 3, 4], (300, 3))
    frame = Observations.from_arrays(["goalpost", "T", "X"], [3.2, 2.0, 1.1], [0.0, 0.0, 0.0])
    assert assert_fused_likelihood(sensor, poses, frame) and assert_fused_likelihood(
        sensor, poses, frame, (0.1, -0.05, 0.2)
    )


@pytest.mark.parametrize("latency", [False, True])
def test_the_fast_path_equals_the_plain_calls_bit_for_bit(namespace, latency):
    field = spl()
    motion, sensor = namespace["ProportionalNoise"](), namespace["RangeOnlyModel"](field)
    fused = ParticleFilter(field, motion, sensor, n_particles=257, seed=3)
    plain = ParticleFilter(field, _Plain(motion), _Plain(sensor), n_particles=257, seed=3)
    frame = Observations.from_arrays(["goalpost", "goalpost", "T"], [3.2, 4.1, 2.0], [0.0, 0.0, 0.0])
    since = (0.05, 0.01, 0.02) if latency else None
    for pf in (fused, plain):
        pf.reset_uniform("own_half")
    for k in range(30):
        u = MotionInput(dt=0.02, command=(0.2, 0.05, 0.1))
        for pf in (fused, plain):
            if latency:
                pf.predict(u)
                pf.correct(frame, since=since)
            else:
                pf.step(u, frame if k % 3 else None)
        assert fused.poses.tobytes() == plain.poses.tobytes()
        assert fused.weights.tobytes() == plain.weights.tobytes()
        assert np.array_equal(fused.estimate().pose, plain.estimate().pose)


def test_the_range_kernel_moves_back_as_the_filter_does(namespace):
    """`numerics.trig.moved_back`, which the example's kernel uses, is `mcl.latency.move_back` bit for bit."""
    from numerics.trig import moved_back

    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.uniform(-5, 5, 200), rng.uniform(-3, 3, 200), rng.uniform(-4, 4, 200)])
    since = np.array([0.07, -0.02, 0.3])
    out = np.empty_like(poses)
    move_back(poses, since, out)
    one = np.array([moved_back.py_func(*pose, *since) for pose in poses])
    assert np.array_equal(out, one)


def test_a_refused_step_changes_nothing(namespace):
    """A motion input the example motion model cannot use (no command, no odometry) is refused by the fused
    step before anything moves; so is a frame with a NaN range (`Observations` refuses it)."""
    field = spl()
    pf = ParticleFilter(field, namespace["ProportionalNoise"](), namespace["RangeOnlyModel"](field), n_particles=64)
    frame = Observations.from_arrays(["goalpost"], [3.0], [0.0])
    pf.step(MotionInput(dt=0.02, command=(0.1, 0.0, 0.0)), frame)
    before = pf.poses.copy(), pf.weights.copy(), pf.rng.bit_generator.state
    with pytest.raises(ValueError):
        pf.step(MotionInput(dt=0.02), frame)
    with pytest.raises(ValueError):
        pf.step(MotionInput(dt=0.02, command=(0.1, 0.0, 0.0)), Observations.from_arrays(["goalpost"], [np.nan], [0.0]))
    assert np.array_equal(pf.poses, before[0]) and np.array_equal(pf.weights, before[1])
    assert pf.rng.bit_generator.state == before[2]


def test_the_examples_pass_the_registered_contract_checks(namespace):
    """Registered, the two models go through the checks the shipped ones pass, and reach the fast path."""
    from mcl.tools import testing as mt

    mt.register_motion_model("extending-proportional-noise", namespace["ProportionalNoise"])
    mt.register_sensor_model("extending-range-only", namespace["RangeOnlyModel"])
    try:
        reports = {r.model.name: r for r in mt.check_registered(max_examples=8)}
    finally:
        mt.unregister("motion", "extending-proportional-noise")
        mt.unregister("sensor", "extending-range-only")
    assert {"extending-proportional-noise", "extending-range-only"} <= set(reports)
    assert reports["extending-proportional-noise"].fast_path["motion"]
    assert reports["extending-range-only"].fast_path["likelihood"]
    assert all(r.contract.accepted > 0 for r in reports.values())
