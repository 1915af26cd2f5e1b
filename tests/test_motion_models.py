import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from field.angles import wrap_angles
from motion_models import ConstantNoise, MotionInput, VelocityLinear
from motion_models._kernels import draw_variates, move_with_noise, move_with_noise_reference

finite = st.floats(-5, 5, allow_nan=False)
speeds = st.tuples(st.floats(-0.4, 0.4), st.floats(-0.2, 0.2), st.floats(-1.5, 1.5))
models = st.sampled_from([VelocityLinear(), VelocityLinear(gaussian=True), ConstantNoise(),
                          ConstantNoise(gaussian=True)])


def poses_strategy(n=8):
    return st.lists(st.tuples(finite, finite, st.floats(-math.pi, math.pi)), min_size=1, max_size=n).map(
        lambda rows: np.ascontiguousarray(np.array(rows, dtype=np.float64)))


# -- MotionInput ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("dt", [-0.01, float("nan"), float("inf"), "x"])
def test_motion_input_rejects_bad_dt(dt):
    with pytest.raises(ValueError, match="dt"):
        MotionInput(dt=dt, command=(0.1, 0.0, 0.0))


@pytest.mark.parametrize("field,value", [("command", (0.1, float("nan"), 0.0)), ("command", (1.0, 2.0)),
                                         ("odometry", (0.0, 0.0, float("inf"))), ("odometry", "abc")])
def test_motion_input_rejects_bad_vectors(field, value):
    with pytest.raises(ValueError, match=field):
        MotionInput(dt=0.01, **{field: value})


def test_model_needs_command_or_odometry():
    poses = np.zeros((4, 3))
    with pytest.raises(ValueError, match="neither command nor odometry"):
        VelocityLinear().check(MotionInput(dt=0.01))
    before = poses.copy()
    with pytest.raises(ValueError):
        VelocityLinear().predict(poses, MotionInput(dt=0.01), np.random.default_rng(0))
    assert np.array_equal(poses, before)


def test_displacement_integrates_the_arc():
    # A quarter circle of radius 1: v = 1 m/s, ω = 1 rad/s for π/2 s ends at (1, 1).
    u = MotionInput(dt=math.pi / 2, command=(1.0, 0.0, 1.0))
    dx, dy, dtheta = u.displacement()
    chord = 2 * math.sin(math.pi / 4)
    assert (dx, dy) == pytest.approx((chord * math.cos(math.pi / 4), chord * math.sin(math.pi / 4)))
    assert dtheta == pytest.approx(math.pi / 2)
    assert MotionInput(dt=0.1, command=(1, 0, 0), odometry=(0.5, 0.1, 0.2)).displacement() == (0.5, 0.1, 0.2)


@pytest.mark.parametrize("model", [VelocityLinear, ConstantNoise])
def test_bad_parameters(model):
    name = "beta1" if model is VelocityLinear else "rate_x"
    with pytest.raises(ValueError, match=name):
        model(**{name: -1.0})


# -- kernels --------------------------------------------------------------------------------------------------
@given(poses_strategy(20), speeds, st.booleans(), st.integers(0, 2**32 - 1))
def test_kernel_matches_numpy_reference(poses, command, gaussian, seed):
    model = VelocityLinear(gaussian=gaussian)
    u = MotionInput(dt=0.01, command=command)
    variates = draw_variates(np.random.default_rng(seed), poses.shape[0], gaussian)
    a, b = poses.copy(), poses.copy()
    move_with_noise(a, *u.displacement(), *model.noise_bounds(u), gaussian, variates)
    move_with_noise_reference(b, *u.displacement(), *model.noise_bounds(u), gaussian, variates)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


@given(poses_strategy(), speeds, models, st.integers(0, 2**32 - 1),
       st.floats(-math.pi, math.pi), st.floats(-3, 3), st.floats(-3, 3))
def test_commutes_with_rotating_and_translating_the_world(poses, command, model, seed, angle, tx, ty):
    """Moving then transforming the world equals transforming then moving (same draws)."""
    u = MotionInput(dt=0.02, command=command)

    def transform(p):
        c, s = math.cos(angle), math.sin(angle)
        out = p.copy()
        out[:, 0] = c * p[:, 0] - s * p[:, 1] + tx
        out[:, 1] = s * p[:, 0] + c * p[:, 1] + ty
        out[:, 2] = wrap_angles(p[:, 2] + angle)
        return out

    moved_then_transformed = poses.copy()
    model.predict(moved_then_transformed, u, np.random.default_rng(seed))
    moved_then_transformed = transform(moved_then_transformed)
    transformed_then_moved = transform(poses)
    model.predict(transformed_then_moved, u, np.random.default_rng(seed))
    np.testing.assert_allclose(moved_then_transformed[:, :2], transformed_then_moved[:, :2], atol=1e-9)
    np.testing.assert_allclose(wrap_angles(moved_then_transformed[:, 2] - transformed_then_moved[:, 2]), 0,
                               atol=1e-9)


@given(poses_strategy(), speeds, models, st.integers(0, 2**32 - 1))
def test_no_nan_and_headings_wrapped(poses, command, model, seed):
    model.predict(poses, MotionInput(dt=0.05, command=command), np.random.default_rng(seed))
    assert np.isfinite(poses).all()
    assert (poses[:, 2] > -math.pi).all() and (poses[:, 2] <= math.pi).all()


@given(speeds, st.integers(0, 2**32 - 1))
def test_uniform_noise_stays_within_eq10_bounds(command, seed):
    """Hoffmann eq. 10: the robot-frame error is within Δt·(β1|v|, β2|v|, β3|v| + β4|ω|)."""
    model = VelocityLinear()
    u = MotionInput(dt=0.01, command=command)
    poses = np.zeros((200, 3))
    model.predict(poses, u, np.random.default_rng(seed))
    noiseless = np.zeros((1, 3))
    move_with_noise_reference(noiseless, *u.displacement(), 0.0, 0.0, 0.0, False, np.zeros((1, 3)))
    bx, by, bt = model.noise_bounds(u)
    # At heading 0 the robot frame is the field frame.
    error = poses - noiseless
    assert (np.abs(error[:, 0]) <= bx + 1e-12).all()
    assert (np.abs(error[:, 1]) <= by + 1e-12).all()
    assert (np.abs(wrap_angles(error[:, 2])) <= bt + 1e-12).all()


def test_documented_spread_is_about_ten_percent_after_one_second():
    """The VelocityLinear defaults: at 100 Hz, one second of walking spreads ~10 % of the distance."""
    poses = np.zeros((20000, 3))
    rng = np.random.default_rng(0)
    u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.0))
    for _ in range(100):
        VelocityLinear().predict(poses, u, rng)
    relative = poses[:, 0].std() / 0.2
    assert 0.085 < relative < 0.115


def test_gaussian_option_has_the_same_variance():
    u = MotionInput(dt=0.01, command=(0.3, 0.0, 0.5))
    spreads = []
    for model in (VelocityLinear(), VelocityLinear(gaussian=True)):
        poses = np.zeros((40000, 3))
        model.predict(poses, u, np.random.default_rng(1))
        spreads.append(poses.std(axis=0))
    np.testing.assert_allclose(spreads[0], spreads[1], rtol=0.03)


def test_constant_model_diffuses_a_standing_robot_and_velocity_linear_does_not():
    u = MotionInput(dt=0.01, command=(0.0, 0.0, 0.0))
    standing_constant, standing_linear = np.zeros((100, 3)), np.zeros((100, 3))
    ConstantNoise().predict(standing_constant, u, np.random.default_rng(0))
    VelocityLinear().predict(standing_linear, u, np.random.default_rng(0))
    assert standing_constant.std(axis=0).min() > 0
    assert np.array_equal(standing_linear, np.zeros((100, 3)))


def test_odometry_input_sets_the_bounds_from_its_displacement():
    model = VelocityLinear()
    by_command = model.noise_bounds(MotionInput(dt=0.01, command=(0.2, 0.0, 0.5)))
    by_odometry = model.noise_bounds(MotionInput(dt=0.01, odometry=(0.002, 0.0, 0.005)))
    np.testing.assert_allclose(by_command, by_odometry, rtol=1e-12)


def test_predict_rejects_bad_pose_arrays():
    u = MotionInput(dt=0.01, command=(0.1, 0, 0))
    for bad in (np.zeros((3, 2)), np.zeros((3, 3), dtype=np.float32), np.zeros((3, 3))[:, ::-1]):
        with pytest.raises(ValueError, match="poses"):
            VelocityLinear().predict(bad, u, np.random.default_rng(0))
