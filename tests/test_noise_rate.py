"""The motion models' noise and the update rate (`noise_rate`): with "per_second" (the default) a walk spreads
the same at any update rate, with "per_step" (Hoffmann eq. 10 as written) it spreads by sqrt(Δt); at the
reference period (100 Hz) both are the same floats, bit for bit."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from field.checks import ArgumentTypeError
from motion_models import AdaptiveMotion, ConstantNoise, MotionInput, VelocityLinear
from motion_models.base import NOISE_RATES, REFERENCE_DT, noise_rate_factor
from proprioception.collision import NO_COLLISION

PARTICLES = 3000
DURATION = 10.0  # s
RATES = (30.0, 100.0, 200.0)  # Hz


def walk_spread(model, command, rate: float, seed: int) -> tuple[float, float]:
    """The standard deviations of x [m] and θ [rad] after a DURATION s walk at `command`, `rate` Hz."""
    poses = np.zeros((PARTICLES, 3))
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate
    collision = NO_COLLISION if isinstance(model, AdaptiveMotion) else None
    u = MotionInput(dt=dt, command=command, collision=collision)
    state = model.particle_state(PARTICLES) if isinstance(model, AdaptiveMotion) else None
    for _ in range(int(round(DURATION * rate))):
        if state is None:
            model.predict(poses, u, rng)
        else:
            model.predict(poses, u, rng, state)
    return float(poses[:, 0].std()), float(poses[:, 2].std())


def spreads(make, command, seed, rates=RATES):
    return np.array([walk_spread(make(), command, rate, seed + k) for k, rate in enumerate(rates)])


models = st.sampled_from(
    [
        lambda **kw: VelocityLinear(**kw),
        lambda **kw: VelocityLinear(gaussian=True, **kw),
        lambda **kw: ConstantNoise(**kw),
        lambda **kw: AdaptiveMotion(**kw),
    ]
)


@settings(max_examples=3, deadline=None)
@given(make=models, speed=st.floats(0.1, 0.4), turn=st.floats(0.0, 0.05), seed=st.integers(0, 2**32 - 4))
def test_a_walk_spreads_the_same_at_30_100_and_200_hz(make, speed, turn, seed):
    """A 10 s walk (straight, or a slow curve) at 30, 100 and 200 Hz: the spreads of x and θ within 10 % of each
    other by default; with "per_step" the 30 Hz walk spreads sqrt(100/30) ≈ 1.8 times more than the 100 Hz one
    (only these two, to keep the test fast), which the first assertion would refuse."""
    command = (speed, 0.0, turn)
    per_second = spreads(lambda: make(), command, seed)
    assert per_second.max(axis=0) / per_second.min(axis=0) == pytest.approx([1.0, 1.0], abs=0.1), per_second
    per_step = spreads(lambda: make(noise_rate="per_step"), command, seed, rates=(30.0, 100.0))
    assert per_step[0] / per_step[1] == pytest.approx([math.sqrt(100 / 30)] * 2, rel=0.1), per_step
    assert (per_step.max(axis=0) / per_step.min(axis=0) > 1.5).all()


@pytest.mark.parametrize("model", [VelocityLinear(), VelocityLinear(gaussian=True), ConstantNoise()])
@pytest.mark.parametrize(
    "u",
    [
        MotionInput(dt=0.01, command=(0.25, 0.05, 0.4)),
        MotionInput(dt=0.010000000000000009, command=(0.25, 0.05, 0.4)),
        MotionInput(dt=0.009999999999999787, odometry=(0.002, 0.0005, 0.004)),
    ],
)
def test_at_the_reference_period_the_bounds_are_eq10s_bit_for_bit(model, u):
    """At 100 Hz (also with timestamps differenced in floating point) the default bounds are the per-step
    ones, the same floats; so is AdaptiveMotion's kernel parameter array (the very memo)."""
    from dataclasses import replace

    per_step = replace(model, noise_rate="per_step")
    assert noise_rate_factor(u.dt) == 1.0
    bounds = model.noise_bounds(u)
    assert all(type(b) is float for b in bounds)
    assert np.array(bounds).tobytes() == np.array(per_step.noise_bounds(u)).tobytes()
    adaptive = AdaptiveMotion()
    assert adaptive.kernel_parameters(u.dt) is adaptive._kernel_params


@pytest.mark.parametrize("dt", [1 / 30, 0.005, 0.04, 0.5])
def test_elsewhere_the_bounds_are_scaled_by_sqrt_of_the_period_ratio(dt):
    u = MotionInput(dt=dt, command=(0.3, 0.0, 0.2))
    factor = math.sqrt(REFERENCE_DT / dt)
    assert noise_rate_factor(dt) == factor and noise_rate_factor(dt, "per_step") == 1.0
    for model in (VelocityLinear(), ConstantNoise()):
        per_step = type(model)(noise_rate="per_step")
        np.testing.assert_allclose(model.noise_bounds(u), np.array(per_step.noise_bounds(u)) * factor, rtol=1e-15)
    adaptive, plain = AdaptiveMotion(), AdaptiveMotion(noise_rate="per_step")
    scaled = adaptive.kernel_parameters(dt)
    assert not scaled.flags.writeable and adaptive.kernel_parameters(dt) is scaled  # kept per factor
    np.testing.assert_array_equal(scaled[9:13], plain.kernel_parameters(dt)[9:13] * factor)
    np.testing.assert_array_equal(np.delete(scaled, range(9, 13)), np.delete(plain.kernel_parameters(dt), range(9, 13)))


def test_a_zero_or_tiny_period_keeps_the_bounds_finite():
    """Odometry over dt = 0 (a clock glitch) is scaled as a 0.1 ms step: a factor of 10, never infinite."""
    assert noise_rate_factor(0.0) == noise_rate_factor(1e-300) == pytest.approx(10.0)
    model = VelocityLinear(*(4 * [100.0]))
    bounds = model.noise_bounds(MotionInput(dt=0.0, odometry=(50.0, 50.0, 50.0)))
    assert np.isfinite(bounds).all() and max(bounds) < 4e5
    assert ConstantNoise().noise_bounds(MotionInput(dt=0.0, command=(0.1, 0.0, 0.0))) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("make", [VelocityLinear, ConstantNoise, AdaptiveMotion])
def test_a_bad_noise_rate_is_refused_naming_it(make):
    assert make().noise_rate == "per_second" and set(NOISE_RATES) == {"per_second", "per_step"}
    with pytest.raises(ValueError, match="noise_rate = 'per_minute'"):
        make(noise_rate="per_minute")
    with pytest.raises(ArgumentTypeError, match="noise_rate"):
        make(noise_rate=1.0)


def test_a_profile_takes_the_noise_rate():
    from mcl.profile import SECTIONS, default_values

    assert SECTIONS["motion"]["noise_rate"] is str
    assert default_values()["motion.noise_rate"] == "per_second"
