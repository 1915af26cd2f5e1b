"""The adaptive five-state motion model (Hoffmann eq. 11-26) and the filter's per-particle motion state."""

import copy
import dataclasses
import math
import pickle

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from field import spl
from mcl import ParticleFilter
from motion_models import AdaptiveMotion, MotionInput, VelocityLinear
from motion_models.adaptive import (
    CONDITIONS,
    FREE,
    HINDRANCE,
    PUSHED,
    SLIPPAGE,
    STOPPED,
    VARIATES,
    MobilityTransitions,
    adaptive_move,
)
from motion_models.reference import adaptive_move as adaptive_move_reference
from proprioception.collision import NO_COLLISION, CollisionPercept
from sensing import LandmarkSensorModel

DT = 0.01
LEFT_HIT = CollisionPercept(left=True, s_rel_left=2.0, rate=0.1, recent_left=True)
STAY = np.triu(np.ones((5, 5)))  # cumulative transition rows that keep every particle in its state

speeds = st.floats(-0.4, 0.4)
turns = st.floats(-1.5, 1.5)


def _step(model, state_index, vx, vy, omega, side, seed, n=64, odometry_noise=False):
    """Particles at the origin facing +x, all in one state, moved once; returns (poses, episode values)."""
    if not odometry_noise:
        model = dataclasses.replace(model, odometry=(0.0, 0.0, 0.0, 0.0))
    rng = np.random.default_rng(seed)
    poses = np.zeros((n, 3))
    state = np.zeros((n, 4))
    state[:, 0] = state_index
    state[:, 1:] = rng.random((n, 3))
    episode = state[:, 1:].copy()
    _, vx_, vy_, omega_, dt, _, params, redraw = model.kernel_arguments(
        MotionInput(DT, (vx, vy, omega), collision=LEFT_HIT)
    )
    adaptive_move(poses, state, STAY, vx, vy, omega, DT, side, params, False, rng.random((n, VARIATES)))
    return poses, episode


@given(speeds, speeds, turns, st.integers(0, 2**32 - 1), st.booleans())
def test_stopped_never_translates(vx, vy, omega, seed, noise):
    # eq. 23: v' = 0, with and without the odometry noise (which scales with the effective speed).
    poses, _ = _step(AdaptiveMotion(), STOPPED, vx, vy, omega, 1.0, seed, odometry_noise=noise)
    assert (poses[:, :2] == 0.0).all()


@given(speeds, speeds, st.integers(0, 2**32 - 1), st.sampled_from([1.0, -1.0, 0.0]))
def test_stopped_turns_toward_the_collision(vx, vy, seed, side):
    # eq. 25-26: ω' = |v|/w · c · β_turn · rand(0, 1), so the turn has the sign of c and a bounded size.
    model = AdaptiveMotion()
    poses, episode = _step(model, STOPPED, vx, vy, 0.0, side, seed)
    expected = math.hypot(vx, vy) / model.foot_separation * side * model.beta_turn * episode[:, 0] * DT
    np.testing.assert_allclose(poses[:, 2], expected, atol=1e-12)


@given(speeds, speeds, st.integers(0, 2**32 - 1), st.sampled_from([1.0, -1.0, 0.0, math.nan]))
def test_pivot_variant_walks_on_along_the_request_while_it_turns(vx, vy, seed, side):
    # stop_creep > 0 (the variant "adaptive-pivot"): pivoting about the held foot, the centre walks on along the
    # request at |v|·stop_creep·rand(0, 1), the same rand() as the turn; no side known (or both): no walk.
    model = AdaptiveMotion(stop_creep=0.5)
    poses, episode = _step(model, STOPPED, vx, vy, 0.0, side, seed)
    e1 = episode[:, 0]
    known = 0.0 if math.isnan(side) else abs(side)
    turn = (
        math.hypot(vx, vy) / model.foot_separation * side * model.beta_turn * e1
        if not math.isnan(side)
        else model.beta7 * (2 * e1 - 1)
    )
    half = 0.5 * turn * DT
    chord = np.where(np.abs(half) > 1e-9, np.sin(half) / np.where(half == 0, 1.0, half), 1.0)
    dx, dy = vx * 0.5 * known * e1 * DT * chord, vy * 0.5 * known * e1 * DT * chord
    np.testing.assert_allclose(poses[:, 0], np.cos(half) * dx - np.sin(half) * dy, atol=1e-12)
    np.testing.assert_allclose(poses[:, 1], np.sin(half) * dx + np.cos(half) * dy, atol=1e-12)
    np.testing.assert_allclose(poses[:, 2], turn * DT, atol=1e-12)


@given(
    st.integers(0, 2**32 - 1),
    speeds,
    speeds,
    turns,
    st.sampled_from([1.0, -1.0, 0.0, math.nan]),
    st.booleans(),
    st.sampled_from(CONDITIONS),
)
def test_pivot_variant_kernel_matches_reference(seed, vx, vy, omega, side, redraw, condition):
    rng = np.random.default_rng(seed)
    _kernel_and_reference(
        rng, rng.normal(size=(50, 3)), vx, vy, omega, side, redraw, condition, AdaptiveMotion(stop_creep=0.4)
    )


@given(turns, st.integers(0, 2**32 - 1))
def test_stopped_without_a_side_turns_either_way(omega, seed):
    # eq. 24: ω' = β7 rand(-1, 1) when the percept names no side.
    model = AdaptiveMotion()
    poses, _ = _step(model, STOPPED, 0.2, 0.0, omega, math.nan, seed)
    assert (np.abs(poses[:, 2]) <= model.beta7 * DT + 1e-12).all()


@given(speeds, speeds, turns, st.integers(0, 2**32 - 1))
def test_hindrance_never_exceeds_the_request(vx, vy, omega, seed):
    # eq. 16-17: v' = v rand(β3, 1), ω' = ω rand(β4, 1).
    model = AdaptiveMotion()
    poses, _ = _step(model, HINDRANCE, vx, vy, omega, 1.0, seed)
    travelled = np.hypot(poses[:, 0], poses[:, 1])
    assert (travelled <= math.hypot(vx, vy) * DT * (1 + 1e-12) + 1e-15).all()
    assert (travelled >= model.beta3 * math.hypot(vx, vy) * DT * (1 - 1e-4) - 1e-12).all()  # chord <= 1e-4
    turned = poses[:, 2]
    assert (np.abs(turned) <= abs(omega) * DT + 1e-15).all()
    assert (np.abs(turned) >= model.beta4 * abs(omega) * DT - 1e-12).all()
    assert (np.sign(turned) * np.sign(omega) >= 0).all()


@given(speeds, speeds, turns, st.integers(0, 2**32 - 1))
def test_slippage_bounds(vx, vy, omega, seed):
    # eq. 14-15: v' = v rand(β1, 1), ω' = ω + β2 rand(-1, 1).
    model = AdaptiveMotion()
    poses, _ = _step(model, SLIPPAGE, vx, vy, omega, 1.0, seed)
    travelled = np.hypot(poses[:, 0], poses[:, 1])
    v = math.hypot(vx, vy) * DT
    assert (travelled <= v * (1 + 1e-12) + 1e-15).all() and (travelled >= model.beta1 * v * (1 - 1e-4) - 1e-12).all()
    assert (np.abs(poses[:, 2] - omega * DT) <= model.beta2 * DT + 1e-12).all()


@given(speeds, turns, st.integers(0, 2**32 - 1))
def test_pushed_displacement_is_bounded_and_all_around(vx, omega, seed):
    # eq. 18-22: displaced by up to β5 (per second here) in any direction, turned by up to β6.
    model = AdaptiveMotion()
    poses, episode = _step(model, PUSHED, 0.0, 0.0, omega, 1.0, seed, n=256)
    push = np.hypot(poses[:, 0], poses[:, 1])
    assert (push <= model.beta5 * DT * (1 + 1e-9)).all()
    # The chord of the turning step shortens it by less than 1e-4 at these turn rates.
    np.testing.assert_allclose(push, model.beta5 * episode[:, 1] * DT, rtol=1e-4, atol=1e-15)
    assert (np.abs(poses[:, 2] - omega * DT) <= model.beta6 * DT + 1e-12).all()
    directions = np.arctan2(poses[:, 1], poses[:, 0])
    assert np.histogram(directions, bins=4, range=(-math.pi, math.pi))[0].min() > 0


@given(speeds, speeds, turns, st.integers(0, 2**32 - 1))
def test_free_is_the_request_plus_bounded_odometry_noise(vx, vy, omega, seed):
    model = AdaptiveMotion()
    poses, _ = _step(model, FREE, vx, vy, omega, 1.0, seed, odometry_noise=True)
    b1, b2, b3, b4 = model.odometry
    v = math.hypot(vx, vy)
    assert (np.abs(poses[:, 2] - omega * DT) <= (b3 * v + b4 * abs(omega)) * DT + 1e-12).all()
    expected = np.array(MotionInput(DT, (vx, vy, omega)).displacement()[:2])
    assert (np.hypot(*(poses[:, :2] - expected).T) <= math.hypot(b1, b2) * v * DT * 1.01 + 1e-12).all()


@given(st.floats(0.0, 2.0), st.sampled_from(CONDITIONS))
def test_transition_rows_sum_to_one(dt, condition):
    p = MobilityTransitions().matrix(condition, dt)
    assert (p >= 0).all()
    np.testing.assert_allclose(p.sum(axis=1), 1.0, atol=1e-12)


def test_transitions_follow_the_percept():
    model, t = AdaptiveMotion(), MobilityTransitions()
    quiet, collision, frequent = (t.matrix(c, 1.0) for c in CONDITIONS)
    # No collision returns toward free; a collision leads out of free into hindrance, pushed or slippage;
    # collisions at high frequency lead into stopped and mostly keep the robot there (an episode may end while
    # the percept still says "frequent", at the fitted rates: less than one in three within a second).
    assert (np.diag(quiet)[1:] < 0.1).all() and quiet[0, 0] > 0.9
    assert collision[0, 0] < 0.1 and collision[0, [SLIPPAGE, HINDRANCE, PUSHED]].min() > 0.01
    assert 0.7 < frequent[STOPPED, STOPPED] < 1.0 and frequent[:, STOPPED].min() > 0.5
    assert (frequent[:, 0] < 0.3).all()
    assert model.condition(NO_COLLISION) == "quiet"
    assert model.condition(LEFT_HIT) == "collision"
    assert model.condition(CollisionPercept(left=True, s_rel_left=3.0, rate=0.6, recent_left=True)) == "frequent"


def test_belief_converges_to_free_without_collisions():
    model = AdaptiveMotion()
    pf = ParticleFilter(spl(), model, LandmarkSensorModel(spl()), n_particles=400, seed=1)
    pf.reset_around((0.0, 0.0, 0.0), sigma=(0.0, 0.0, 0.0))
    state = np.zeros((400, 4))
    state[:, 0] = np.arange(400) % 5
    pf.set_particles(pf.poses.copy(), motion_state=state)
    assert model.state_belief(pf.motion_state, pf.weights)[FREE] == pytest.approx(0.2)
    for _ in range(300):
        pf.predict(MotionInput(DT, (0.2, 0.0, 0.0), collision=NO_COLLISION))
    belief = model.state_belief(pf.motion_state, pf.weights)
    assert belief.sum() == pytest.approx(1.0)
    assert belief[FREE] > 0.95


def _kernel_and_reference(rng, poses, vx, vy, omega, side, redraw, condition, model=None):
    """One step of `adaptive_move` and of its numpy twin from the same particles and variates; asserts they
    agree (states exactly, poses to rounding) and returns the kernel's (poses, state)."""
    n = poses.shape[0]
    state = np.column_stack([rng.integers(0, 5, n), rng.random((n, 3))]).astype(np.float64)
    state[::3, 0] = STOPPED
    cumulative = np.cumsum(MobilityTransitions().matrix(condition, 0.5), axis=1)
    cumulative[:, -1] = 1.0
    params = (model or AdaptiveMotion()).kernel_arguments(MotionInput(DT, (vx, vy, omega), collision=LEFT_HIT))[6]
    variates = rng.random((n, VARIATES))
    a, sa, b, sb = poses.copy(), state.copy(), poses.copy(), state.copy()
    adaptive_move(a, sa, cumulative, vx, vy, omega, DT, side, params, redraw, variates)
    adaptive_move_reference(b, sb, cumulative, vx, vy, omega, DT, side, params, redraw, variates)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(sa, sb)
    assert np.isfinite(a).all()
    return a, sa


kernel_cases = given(
    st.integers(0, 2**32 - 1),
    speeds,
    speeds,
    turns,
    st.sampled_from([1.0, -1.0, 0.0, math.nan]),
    st.booleans(),
    st.sampled_from(CONDITIONS),
)


@kernel_cases
def test_kernel_matches_reference(seed, vx, vy, omega, side, redraw, condition):
    rng = np.random.default_rng(seed)
    _kernel_and_reference(rng, rng.normal(size=(50, 3)), vx, vy, omega, side, redraw, condition)


@kernel_cases
def test_kernel_matches_reference_at_zero_coordinates(seed, vx, vy, omega, side, redraw, condition):
    # A stopped particle whose x and y are non-zero keeps them bit for bit (its displacement is ±0); at a zero
    # coordinate the kernel takes the general step, where the sign of that zero shows.
    rng = np.random.default_rng(seed)
    n = 60
    poses = rng.normal(size=(n, 3))
    poses[rng.random(n) < 0.3, 0] = 0.0
    poses[rng.random(n) < 0.3, 1] = -0.0
    poses[:5, :2] = 0.0
    moved, state = _kernel_and_reference(rng, poses, vx, vy, omega, side, redraw, condition)
    kept = (state[:, 0] == STOPPED) & (poses[:, :2] != 0.0).all(axis=1)
    assert moved[kept, :2].tobytes() == poses[kept, :2].tobytes()


def test_transition_rows_are_computed_once_per_condition_and_dt():
    model = AdaptiveMotion()
    u = MotionInput(DT, (0.2, 0.0, 0.0), collision=LEFT_HIT)
    first = model.kernel_arguments(u)[0]
    assert model.kernel_arguments(u)[0] is first
    expected = np.cumsum(MobilityTransitions().matrix("collision", DT), axis=1)
    expected[:, -1] = 1.0
    np.testing.assert_array_equal(first, expected)
    assert model.kernel_arguments(MotionInput(2 * DT, (0.2, 0.0, 0.0), collision=LEFT_HIT))[0] is not first
    assert not first.flags.writeable and not model.kernel_arguments(u)[6].flags.writeable
    # An equal model computes the same rows (and compares equal: the memos are not fields).
    assert AdaptiveMotion() == model and hash(AdaptiveMotion()) == hash(model)
    np.testing.assert_array_equal(AdaptiveMotion().kernel_arguments(u)[0], first)


def test_copies_and_pickles_move_the_particles_alike():
    model = AdaptiveMotion(beta1=0.3, redraw="step")
    u = MotionInput(DT, (0.2, 0.05, 0.3), collision=LEFT_HIT)
    model.predict(np.zeros((4, 3)), u, np.random.default_rng(0))  # fills the memo that copies must not share
    runs = []
    for clone in (model, pickle.loads(pickle.dumps(model)), copy.deepcopy(model), dataclasses.replace(model)):
        assert clone == model
        poses, state, rng = np.zeros((30, 3)), clone.particle_state(30), np.random.default_rng(8)
        for _ in range(20):
            clone.predict(poses, u, rng, state=state)
        runs.append(poses.tobytes() + state.tobytes())
    assert len(set(runs)) == 1


@given(st.integers(0, 2**32 - 1), st.floats(-math.pi, math.pi), st.sampled_from(CONDITIONS))
def test_commutes_with_rotating_the_world(seed, angle, condition):
    rng = np.random.default_rng(seed)
    n = 40
    poses = rng.normal(size=(n, 3))
    state = np.column_stack([rng.integers(0, 5, n), rng.random((n, 3))]).astype(np.float64)
    model = AdaptiveMotion()
    args = model.kernel_arguments(MotionInput(DT, (0.2, 0.05, 0.3), collision=LEFT_HIT))
    variates = rng.random((n, VARIATES))
    c, s = math.cos(angle), math.sin(angle)

    def rotate(p):
        out = p.copy()
        out[:, 0], out[:, 1] = c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1]
        out[:, 2] = np.angle(np.exp(1j * (p[:, 2] + angle)))
        return out

    moved, rotated = poses.copy(), rotate(poses)
    adaptive_move(moved, state.copy(), *args, variates)
    adaptive_move(rotated, state.copy(), *args, variates)
    expected = rotate(moved)
    np.testing.assert_allclose(rotated[:, :2], expected[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (rotated[:, 2] - expected[:, 2]))), 0.0, atol=1e-9)


def test_missing_percept_is_rejected_and_the_filter_untouched():
    pf = ParticleFilter(spl(), AdaptiveMotion(), LandmarkSensorModel(spl()), n_particles=50, seed=3)
    pf.predict(MotionInput(DT, (0.2, 0.0, 0.0), collision=LEFT_HIT))
    poses, state, rng_state = pf.poses.copy(), pf.motion_state.copy(), pf.rng.bit_generator.state
    for bad in (MotionInput(DT, (0.2, 0.0, 0.0)), MotionInput(DT, (0.2, 0.0, 0.0), collision="left")):
        with pytest.raises(ValueError, match="collision"):
            pf.predict(bad)
    with pytest.raises(ValueError, match="neither command nor odometry"):
        pf.predict(MotionInput(DT, collision=NO_COLLISION))
    np.testing.assert_array_equal(pf.poses, poses)
    np.testing.assert_array_equal(pf.motion_state, state)
    assert pf.rng.bit_generator.state == rng_state


def test_parameters_validate():
    for bad in (
        {"beta1": 1.0},
        {"beta3": -0.1},
        {"beta5": math.nan},
        {"foot_separation": 0.0},
        {"odometry": (1.0, 1.0)},
        {"frequent_rate": 0.0},
        {"redraw": "sometimes"},
    ):
        with pytest.raises(ValueError):
            AdaptiveMotion(**bad)
    with pytest.raises(ValueError, match="not one of"):
        MobilityTransitions(quiet=(("free", "flying", 1.0),))


def test_resampling_carries_each_particles_state():
    n = 200
    pf = ParticleFilter(
        spl(),
        AdaptiveMotion(),
        LandmarkSensorModel(spl()),
        n_particles=n,
        seed=4,
        roughening=(0.0, 0.0, 0.0),
        augmented=None,
    )
    poses = np.zeros((n, 3))
    poses[:, 0] = np.linspace(-4, 4, n)
    state = np.zeros((n, 4))
    state[:, 0] = np.arange(n) % 5
    state[:, 1] = poses[:, 0]  # a tag: the particle's own x
    log_weights = -0.5 * (poses[:, 0] / 0.5) ** 2
    pf.set_particles(poses, log_weights, motion_state=state)
    pf._resample(0, None)
    after = pf.motion_state
    np.testing.assert_array_equal(after[:, 1], pf.poses[:, 0])
    np.testing.assert_array_equal(after[:, 0], state[np.searchsorted(poses[:, 0], pf.poses[:, 0]), 0])
    assert abs(pf.poses[:, 0]).max() < 2.5  # the heavy middle survived


def test_stateless_models_have_no_motion_state():
    pf = ParticleFilter(spl(), VelocityLinear(), LandmarkSensorModel(spl()), n_particles=10)
    assert pf.motion_state is None
    with pytest.raises(ValueError, match="no per-particle state"):
        pf.set_particles(pf.poses.copy(), motion_state=np.zeros((10, 4)))


def test_same_seed_same_run():
    def run():
        pf = ParticleFilter(spl(), AdaptiveMotion(), LandmarkSensorModel(spl()), n_particles=100, seed=7)
        pf.reset_around((0.0, 0.0, 0.0), sigma=(0.0, 0.0, 0.0))
        for k in range(200):
            pf.predict(MotionInput(DT, (0.2, 0.0, 0.1), collision=LEFT_HIT if 50 < k < 150 else NO_COLLISION))
        return pf.poses.copy(), pf.motion_state.copy()

    (a, sa), (b, sb) = run(), run()
    assert a.tobytes() == b.tobytes() and sa.tobytes() == sb.tobytes()


@pytest.mark.parametrize("bit_generator", [np.random.PCG64, np.random.Philox])
@given(st.integers(0, 2**32 - 1), st.integers(1, 700), st.booleans(), st.sampled_from(CONDITIONS))
def test_drawing_in_the_kernel_equals_the_drawn_variates(bit_generator, seed, n, redraw, condition):
    # `predict` draws the 7 uniforms per particle inside the kernel, a block at a time (with PCG64 the episode
    # values only for the particles that take them): the same poses and states, bit for bit, as `adaptive_move`
    # on rng.random((n, 7)), and the generator ends where that leaves it.
    from motion_models.adaptive import adaptive_move_drawing
    from numerics.random import bit_generator_handle

    setup = np.random.default_rng(seed)
    poses = np.column_stack([setup.uniform(-4, 4, n), setup.uniform(-3, 3, n), setup.uniform(-3, 3, n)])
    state = np.column_stack([setup.integers(0, 5, n), setup.random((n, 3))]).astype(np.float64)
    cumulative = np.cumsum(MobilityTransitions().matrix(condition, 0.5), axis=1)
    cumulative[:, -1] = 1.0
    arguments = AdaptiveMotion().kernel_arguments(MotionInput(DT, (0.2, 0.05, 0.4), collision=LEFT_HIT))
    args, params = arguments[1:6], arguments[6]
    a, sa, b, sb = poses.copy(), state.copy(), poses.copy(), state.copy()
    drawn, inside = (np.random.Generator(bit_generator(seed + 1)) for _ in range(2))
    adaptive_move(a, sa, cumulative, *args, params, redraw, drawn.random((n, VARIATES)))
    adaptive_move_drawing(b, sb, cumulative, *args, params, redraw, *bit_generator_handle(inside))
    assert a.tobytes() == b.tobytes() and sa.tobytes() == sb.tobytes()
    assert drawn.random() == inside.random()
