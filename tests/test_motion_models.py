import math

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from field.angles import wrap_angle, wrap_angles
from motion_models import ConstantNoise, MotionInput, VelocityLinear
from motion_models.kernels import move_with_noise
from motion_models.reference import move_with_noise as move_with_noise_reference
from numerics.random import draw_variates
from numerics.reference import atan2_poly as atan2_poly_reference
from numerics.reference import sincos as sincos_reference
from numerics.trig import atan2_poly, sincos, wrap

finite = st.floats(-5, 5, allow_nan=False)
speeds = st.tuples(st.floats(-0.4, 0.4), st.floats(-0.2, 0.2), st.floats(-1.5, 1.5))
models = st.sampled_from(
    [VelocityLinear(), VelocityLinear(gaussian=True), ConstantNoise(), ConstantNoise(gaussian=True)]
)


def poses_strategy(n=8):
    return st.lists(st.tuples(finite, finite, st.floats(-math.pi, math.pi)), min_size=1, max_size=n).map(
        lambda rows: np.ascontiguousarray(np.array(rows, dtype=np.float64))
    )


# -- MotionInput ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("dt", [-0.01, float("nan"), float("inf"), "x"])
def test_motion_input_rejects_bad_dt(dt):
    with pytest.raises(ValueError, match="dt"):
        MotionInput(dt=dt, command=(0.1, 0.0, 0.0))


@pytest.mark.parametrize(
    "field,value",
    [
        ("command", (0.1, float("nan"), 0.0)),
        ("command", (1.0, 2.0)),
        ("odometry", (0.0, 0.0, float("inf"))),
        ("odometry", "abc"),
    ],
)
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


@given(
    poses_strategy(),
    speeds,
    models,
    st.integers(0, 2**32 - 1),
    st.floats(-math.pi, math.pi),
    st.floats(-3, 3),
    st.floats(-3, 3),
)
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
    np.testing.assert_allclose(wrap_angles(moved_then_transformed[:, 2] - transformed_then_moved[:, 2]), 0, atol=1e-9)


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


# -- drawing in the kernels ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "bit_generator", [np.random.PCG64, np.random.PCG64DXSM, np.random.MT19937, np.random.Philox, np.random.SFC64]
)
@given(st.integers(0, 2**32 - 1), st.lists(st.integers(0, 40), min_size=1, max_size=6), st.integers(0, 3))
def test_kernel_draws_are_the_generators_own(bit_generator, seed, counts, jump):
    """draw_uniforms, next_double and parallel_uniforms give what rng.random gives and leave the generator where
    rng.random leaves it (numpy's PCG64 is stepped in the kernel, the others through next_double)."""
    from numerics.random import bit_generator_handle, draw_uniforms, next_double, parallel_uniforms

    plain = np.random.Generator(bit_generator(seed))
    drawn = np.random.Generator(bit_generator(seed))
    if jump and hasattr(plain.bit_generator, "advance"):
        plain.bit_generator.advance(jump * 1000 + 7)
        drawn.bit_generator.advance(jump * 1000 + 7)
    handle = bit_generator_handle(drawn)
    for count in counts:
        out = np.empty(count)
        draw_uniforms(*handle, out, count)
        assert np.array_equal(out, plain.random(count))
        assert next_double(*handle) == plain.random()
    big = np.empty(20000)
    parallel_uniforms(*handle, big, 20000)
    assert np.array_equal(big, plain.random(20000))
    assert same_state(drawn.bit_generator.state, plain.bit_generator.state)


def same_state(a, b):
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same_state(a[k], b[k]) for k in a)
    return np.array_equal(a, b)


# highs around the edge cases of Lemire's method: one value (no draw), two, small counts of detections, and
# counts near 2³¹ where about a quarter of the 32-bit draws are rejected
integer_highs = st.one_of(
    st.integers(1, 40), st.sampled_from([2**31 - 1, 2**31, 3 * 2**29 + 1]), st.integers(2**20, 2**31)
)


@pytest.mark.parametrize(
    "bit_generator", [np.random.PCG64, np.random.PCG64DXSM, np.random.MT19937, np.random.Philox, np.random.SFC64]
)
@given(st.integers(0, 2**32 - 1), st.lists(st.tuples(integer_highs, st.integers(0, 30)), min_size=1, max_size=5))
def test_kernel_integers_are_the_generators_own(bit_generator, seed, draws):
    """bounded_integers gives what rng.integers(0, high, size) gives, interleaved with uniforms, and leaves the
    generator where numpy leaves it, the unused half of a 64-bit output included."""
    from numerics.random import bit_generator_handle, bounded_integers, integers_function, next_double

    plain = np.random.Generator(bit_generator(seed))
    drawn = np.random.Generator(bit_generator(seed))
    function, state = bit_generator_handle(drawn)
    for high, size in draws:
        out = np.full(size, -1, dtype=np.int64)
        bounded_integers(integers_function(drawn), state, high, out)
        assert np.array_equal(out, plain.integers(0, high, size=size))
        assert same_state(drawn.bit_generator.state, plain.bit_generator.state)
        assert next_double(function, state) == plain.random()
    assert same_state(drawn.bit_generator.state, plain.bit_generator.state)


@pytest.mark.parametrize("bit_generator", [np.random.PCG64, np.random.MT19937])
@given(
    st.integers(0, 2**32 - 1),
    st.integers(1, 9),
    st.integers(0, 8),
    st.integers(0, 9),
    st.lists(st.integers(0, 300), min_size=1, max_size=4),
)
def test_deferred_columns_are_the_generators_own(bit_generator, seed, width, defer_from, defer_to, counts):
    """draw_rows_deferring gives rng.random((count, width)) in the columns it computes, deferred_uniform the
    deferred ones, and the generator ends where rng.random leaves it; with a shape it cannot defer (or another
    bit generator), every column is drawn."""
    from numerics.random import (
        PCG64_INLINE,
        PCG64_LANES,
        PCG64_STEPS,
        bit_generator_handle,
        deferred_uniform,
        draw_rows_deferring,
    )

    plain = np.random.Generator(bit_generator(seed))
    drawn = np.random.Generator(bit_generator(seed))
    function, state = bit_generator_handle(drawn)
    can_defer = function == PCG64_INLINE and width <= PCG64_LANES and defer_from < defer_to < width
    for count in counts:
        out = np.full((count, width), -1.0)
        bases = np.empty((count, 2), dtype=np.uint64)
        increments = np.empty((PCG64_STEPS, 2), dtype=np.uint64)
        deferred = draw_rows_deferring(function, state, out, count, defer_from, defer_to, bases, increments)
        expected = plain.random((count, width))
        assert deferred == can_defer
        if deferred:
            assert np.all(out[:, defer_from:defer_to] == -1.0)  # not computed
            for p in range(count):
                for j in range(defer_from, defer_to):
                    out[p, j] = deferred_uniform(bases, increments, p, j)
        assert np.array_equal(out, expected)
        assert same_state(drawn.bit_generator.state, plain.bit_generator.state)


def test_the_default_generator_is_stepped_in_the_kernel():
    from numerics.random import PCG64_INLINE, bit_generator_handle

    assert bit_generator_handle(np.random.default_rng(0))[0] == PCG64_INLINE
    assert bit_generator_handle(np.random.Generator(np.random.MT19937(0)))[0] != PCG64_INLINE


@given(poses_strategy(40), speeds, st.integers(0, 2**32 - 1))
def test_drawing_kernel_equals_the_kernel_on_drawn_variates(poses, command, seed):
    from motion_models.kernels import move_drawing_noise
    from numerics.random import bit_generator_handle

    model = VelocityLinear()
    u = MotionInput(dt=0.01, command=command)
    a, b = poses.copy(), poses.copy()
    plain, drawn = np.random.default_rng(seed), np.random.default_rng(seed)
    move_with_noise(a, *u.displacement(), *model.noise_bounds(u), False, draw_variates(plain, a.shape[0], False))
    move_drawing_noise(b, *u.displacement(), *model.noise_bounds(u), *bit_generator_handle(drawn))
    assert np.array_equal(a, b) and plain.bit_generator.state == drawn.bit_generator.state


@numba.njit
def _both_wraps(values, out):
    for i in range(values.shape[0]):
        out[i, 0] = wrap(values[i])
        out[i, 1] = wrap_angle(values[i])


@given(st.lists(st.floats(-50, 50), min_size=1, max_size=50))
def test_wrap_is_wrap_angle_bit_for_bit(angles):
    values = np.array(angles + [math.pi, -math.pi, 0.0, -0.0, 2 * math.pi, -3 * math.pi, 1e-300])
    out = np.empty((values.shape[0], 2))
    _both_wraps(values, out)
    assert np.array_equal(out[:, 0], out[:, 1])


@given(poses_strategy(60), speeds, st.booleans(), st.integers(0, 2**32 - 1))
def test_fast_motion_matches_to_rounding(poses, command, gaussian, seed):
    """The opt-in fast kernel: polynomial sin and cos (sincos), the same draws."""
    from motion_models.kernels import NO_WORK, move_range, move_range_fast
    from numerics.random import bit_generator_handle

    model = VelocityLinear(gaussian=gaussian)
    u = MotionInput(dt=0.02, command=command)
    variates = draw_variates(np.random.default_rng(seed), poses.shape[0], True) if gaussian else np.empty((0, 3))
    a, b = poses.copy(), poses.copy()
    args = (tuple(u.displacement()), tuple(model.noise_bounds(u)), gaussian, variates)
    generators = np.random.default_rng(seed), np.random.default_rng(seed)  # (a handle does not keep them)
    move_range(a, a, 0, a.shape[0], *args, bit_generator_handle(generators[0]), NO_WORK)
    move_range_fast(b, b, 0, b.shape[0], *args, bit_generator_handle(generators[1]), NO_WORK)
    np.testing.assert_allclose(b[:, :2], a[:, :2], rtol=0, atol=1e-12)
    assert np.abs(wrap_angles(b[:, 2] - a[:, 2])).max() < 1e-12
    assert (b[:, 2] > -math.pi).all() and (b[:, 2] <= math.pi).all()


@numba.njit
def _sincos_all(values, out):
    for i in range(values.shape[0]):
        out[i, 0], out[i, 1] = sincos(values[i])


def test_sincos_is_accurate():
    values = np.concatenate(
        [np.random.default_rng(0).uniform(-100, 100, 100000), np.arange(-8, 9) * math.pi / 4, [1e-300, -1e-300, 0.0]]
    )
    out = np.empty((values.shape[0], 2))
    _sincos_all(values, out)
    assert np.abs(out[:, 0] - np.cos(values)).max() < 2.5e-16 and np.abs(out[:, 1] - np.sin(values)).max() < 2.5e-16


@given(st.lists(st.floats(-100, 100), min_size=1, max_size=60))
def test_sincos_equals_its_numpy_twin_bit_for_bit(angles):
    """The kernels' sin and cos (no libm) are the same bits as `sincos_reference`'s elementwise numpy, so the
    numpy twins of the kernels reproduce them exactly; headings near the quadrant boundaries included."""
    values = np.array(angles + [math.pi, -math.pi, math.pi / 2, -math.pi / 2, math.pi / 4, 0.0, -0.0, 1e-300])
    out = np.empty((values.shape[0], 2))
    _sincos_all(values, out)
    cos, sin = sincos_reference(values)
    assert np.array_equal(out[:, 0], cos) and np.array_equal(out[:, 1], sin)
    assert np.array_equal(np.signbit(out[:, 1]), np.signbit(sin))


@numba.njit(error_model="numpy")
def _atan2_all(y, x, out):
    for i in range(y.shape[0]):
        out[i] = atan2_poly(y[i], x[i])


def _atan2_of(y, x):
    out = np.empty(np.shape(y))
    _atan2_all(np.asarray(y, dtype=np.float64), np.asarray(x, dtype=np.float64), out)
    return out


def test_atan2_is_within_two_units_in_the_last_place_of_libm():
    rng = np.random.default_rng(0)
    angles = rng.uniform(-math.pi, math.pi, 200_000)
    radii = np.exp(rng.uniform(-30, 30, 200_000))
    y = np.concatenate([radii * np.sin(angles), rng.uniform(-1, 1, 1000) * 1e-300, rng.uniform(-1, 1, 1000)])
    x = np.concatenate([radii * np.cos(angles), rng.uniform(-1, 1, 1000), rng.uniform(-1, 1, 1000) * 1e-300])
    out, libm = _atan2_of(y, x), np.arctan2(y, x)
    assert (np.abs(out - libm) <= 2 * np.spacing(np.abs(libm))).all()
    assert np.mean(out == libm) > 0.7


def test_atan2_at_zeros_axes_and_nan_is_atan2():
    values = [0.0, -0.0, 1.0, -1.0, 2.5, -3.0, 1e-310, -1e-310, 1e300, -1e300]
    y, x = (a.ravel() for a in np.meshgrid(values, values))
    out, libm = _atan2_of(y, x), np.arctan2(y, x)
    assert (np.abs(out - libm) <= 2 * np.spacing(np.abs(libm))).all()
    assert np.array_equal(np.signbit(out), np.signbit(libm))  # ±0 and ±π as atan2 gives them
    assert np.isnan(_atan2_of([np.nan, 1.0, np.nan, 0.0], [1.0, np.nan, np.nan, np.nan])).all()


@given(st.lists(st.tuples(st.floats(-1e6, 1e6), st.floats(-1e6, 1e6)), min_size=1, max_size=60))
def test_atan2_equals_its_numpy_twin_bit_for_bit(points):
    """The kernels' atan2 (no libm) is the same bits as `atan2_poly_reference`'s elementwise numpy; the ranges'
    boundaries (|y/x| = 7/16, 11/16, 1), the axes and signed zeros included."""
    y = np.array([p[0] for p in points] + [7.0, 11.0, 1.0, -1.0, 0.0, -0.0, 0.0, -0.0, 3.0])
    x = np.array([p[1] for p in points] + [16.0, 16.0, 1.0, -1.0, 0.0, -0.0, -2.0, 2.0, 0.0])
    out, twin = _atan2_of(y, x), atan2_poly_reference(y, x)
    assert np.array_equal(out, twin) and np.array_equal(np.signbit(out), np.signbit(twin))


# -- bounds of a motion input (a step that would make a pose non-finite is refused) -----------------------------
def _filter(model):
    from field import spl
    from mcl import ParticleFilter
    from sensing import LandmarkSensorModel

    field = spl()
    return ParticleFilter(field, model, LandmarkSensorModel(field), n_particles=64, seed=3)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(dt=1e300, command=(1e300, 0.0, 0.0)),
        dict(dt=0.01, odometry=(0.0, 0.0, -1e300)),
        dict(dt=1e12, command=(0.0, -3e11, -5e11)),
        dict(dt=1e300, command=(0.0, 0.0, 1e300)),
        dict(dt=0.01, odometry=(1e6, 0.0, 0.0)),
    ],
)
def test_a_step_beyond_the_bounds_is_refused_naming_the_input(kwargs):
    from motion_models.base import MAX_STEP_DISTANCE, MAX_STEP_DT

    with pytest.raises(ValueError, match=r"^(odometry|dt = .* with command|dt) = ") as error:
        MotionInput(**kwargs)
    bound = (
        f"{MAX_STEP_DT:g}"
        if str(error.value).startswith("dt = ") and "command" not in str(error.value)
        else f"{MAX_STEP_DISTANCE:g} m"
    )
    assert bound in str(error.value)


def test_the_inputs_that_crashed_the_process_are_refused_in_a_child_process():
    """These finite inputs used to make poses inf or NaN, and a compiled kernel then read out of bounds
    (SIGSEGV). Run in a child process, so that a crash fails this test instead of ending the run."""
    import subprocess
    import sys

    script = """
from field import spl
from mcl import ParticleFilter
from motion_models import ConstantNoise, MotionInput, VelocityLinear
from sensing import LandmarkObservation as Seen, LandmarkSensorModel
field = spl()
refused = 0
for model, make in ((VelocityLinear(), lambda: MotionInput(dt=1e300, command=(1e300, 0, 0))),
                    (ConstantNoise(), lambda: MotionInput(dt=1e300, command=(1e300, 0, 0))),
                    (VelocityLinear(), lambda: MotionInput(dt=0.01, odometry=(0, 0, -1e300)))):
    pf = ParticleFilter(field, model, LandmarkSensorModel(field), n_particles=100, seed=0)
    pf.reset_around((-2, 0, 0))
    try:
        pf.step(make(), [Seen("penalty_mark", 1.2, 0), Seen("goalpost", 2.65, 0.31)])
    except ValueError:
        refused += 1
    pf.estimate()
print("refused", refused)
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "refused 3"


@settings(max_examples=80, deadline=None)
@given(
    dt=st.floats(0.0, 1e6),
    triple=st.tuples(*[st.floats(-1e9, 1e9)] * 3),
    odometry=st.booleans(),
    constant=st.booleans(),
)
def test_every_accepted_step_keeps_the_poses_finite_and_wrapped(dt, triple, odometry, constant):
    pf = _filter(ConstantNoise() if constant else VelocityLinear())
    pf.reset_around((-1.0, 0.5, 3.0), (0.1, 0.1, 0.1))
    try:
        u = MotionInput(dt=dt, odometry=triple) if odometry else MotionInput(dt=dt, command=triple)
    except ValueError:
        return
    pf.predict(u)
    assert np.isfinite(pf.poses).all() and (np.abs(pf.poses[:, 2]) <= math.pi).all()
    assert np.isfinite(pf.estimate().pose).all()
