"""The goal-direction sensor model: a model that reaches the fused step through one per-particle log-likelihood
(`sensing.fused.per_particle_kernels`), compared with its numpy reference and with the filter's stages one by
one."""

import math

import numpy as np
import pytest

from field import spl
from mcl import ParticleFilter
from mcl.contracts import fast_path
from mcl.tools.testing import assert_fused_likelihood
from motion_models import MotionInput, VelocityLinear
from sensing import Observations
from sensing.goal_direction import GoalDirectionSensorModel

FIELD = spl()
TRUE_POSE = np.array([1.0, 0.5, 0.3])


class StagedGoals(GoalDirectionSensorModel):
    """The same model without `fused_likelihood`: the filter scores it through `log_likelihood`."""

    def fused_likelihood(self):
        return None


def goal_sightings(pose, rng, false_positive=False):
    """Bearings of the two goals' centres from `pose` (with noise), and a stray one now and then."""
    bearings = []
    for gx in (FIELD.half_length, -FIELD.half_length):
        bearings.append(math.atan2(-pose[1], gx - pose[0]) - pose[2] + 0.05 * rng.standard_normal())
    if false_positive:
        bearings.append(rng.uniform(-1.0, 1.0))
    count = len(bearings)
    return Observations.from_arrays(["goalpost"] * count, [4.0] * count, bearings)


def poses(n, seed=0):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-5, 5, n), rng.uniform(-3.5, 3.5, n), rng.uniform(-math.pi, math.pi, n)])


def test_the_compiled_likelihood_equals_its_numpy_reference():
    model = GoalDirectionSensorModel(FIELD)
    rng = np.random.default_rng(1)
    for k in range(5):
        frame = goal_sightings(TRUE_POSE, rng, false_positive=k % 2 == 1)
        particles = poses(1000, seed=k)
        np.testing.assert_allclose(
            model.log_likelihood(particles, frame), model.reference(particles, frame), rtol=1e-12, atol=1e-9
        )


def test_the_model_reaches_the_fused_step_through_one_function():
    model = GoalDirectionSensorModel(FIELD)
    assert fast_path(VelocityLinear(), model)["step"]
    rng = np.random.default_rng(2)
    frame = goal_sightings(TRUE_POSE, rng)
    assert assert_fused_likelihood(model, poses(700), frame)
    assert assert_fused_likelihood(model, poses(700), frame, since=(0.1, -0.05, 0.2))


def state(pf):
    estimate = pf.estimate()
    return (
        pf.poses.copy(),
        pf.log_weights.copy(),
        pf.w_slow,
        pf.w_fast,
        pf.ess,
        pf.resampled,
        pf.injected,
        pf.rng.bit_generator.state,
        estimate.pose.copy(),
        estimate.covariance.copy(),
        estimate.weight,
    )


def same(a, b):
    return all(np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y for x, y in zip(a, b))


@pytest.mark.parametrize("use_step", [True, False])
def test_the_fused_step_equals_the_stages_bit_for_bit(use_step):
    fused = ParticleFilter(FIELD, VelocityLinear(), GoalDirectionSensorModel(FIELD), n_particles=400, seed=3)
    staged = ParticleFilter(FIELD, VelocityLinear(), StagedGoals(FIELD), n_particles=400, seed=3)
    rngs = [np.random.default_rng(4), np.random.default_rng(4)]
    truth = TRUE_POSE.copy()
    for k in range(30):
        u = MotionInput(dt=0.033, command=(0.2, 0.0, 0.3 * math.cos(0.1 * k)))
        truth = truth + np.array([0.033 * 0.2, 0.0, 0.033 * 0.3 * math.cos(0.1 * k)])
        for pf, rng in zip((fused, staged), rngs):
            frame = goal_sightings(truth, rng, false_positive=k % 5 == 2) if k % 3 != 2 else None
            if use_step:
                pf.step(u, frame)
            else:
                pf.predict(u)
                pf.correct(frame, since=(0.02, 0.0, 0.01) if k % 4 == 1 else None)
        assert same(state(fused), state(staged)), k


def test_a_detection_that_is_not_a_goal_is_refused_before_anything_changes():
    pf = ParticleFilter(FIELD, VelocityLinear(), GoalDirectionSensorModel(FIELD), n_particles=100, seed=5)
    before = state(pf)
    bad = Observations.from_arrays(["goalpost", "t_crossing"], [4.0, 2.0], [0.1, 0.5])
    for call in (lambda: pf.correct(bad), lambda: pf.step(MotionInput(dt=0.01, command=(0.1, 0.0, 0.0)), bad)):
        with pytest.raises(ValueError, match="T_CROSSING"):
            call()
        assert same(before, state(pf))
