import copy
import math
import pickle
import sys
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from field import spl
from field.angles import wrap_angles
from mcl import AugmentedMCL, Grid, ParticleFilter
from mcl.relocalization import RelocalizationPrior
from motion_models import AdaptiveMotion, ConstantNoise, MotionInput, VelocityLinear
from proprioception.collision import CollisionPercept
from sensing import LandmarkObservation, LandmarkSensorModel, Observations

FIELD = spl()
SENSOR = LandmarkSensorModel(FIELD)
TRUE_POSE = np.array([1.5, -1.0, 0.7])


def detections(pose=TRUE_POSE, kinds=("goalpost", "penalty_mark", "t_crossing", "x_crossing"), field=FIELD):
    rows = []
    for kind in kinds:
        for target in field.landmarks_of(kind)[:2]:
            d = target - pose[:2]
            rows.append((kind, math.hypot(*d), math.atan2(d[1], d[0]) - pose[2]))
    return Observations.from_arrays(*zip(*rows))


def make(n=300, seed=0, **kwargs):
    return ParticleFilter(FIELD, VelocityLinear(), SENSOR, n_particles=n, seed=seed, **kwargs)


def relocalization_state(relocalization):
    return repr(
        {
            name: (value.tolist() if isinstance(value, np.ndarray) else value)
            for name, value in vars(relocalization).items()
        }
    )


def state(pf):
    return (
        pf.poses.copy(),
        pf.log_weights.copy(),
        np.array(pf.weights),
        pf.w_slow,
        pf.w_fast,
        pf.rng.bit_generator.state,
        pf.ess,
        relocalization_state(pf.relocalization),
    )


def same_state(a, b):
    return all(np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y for x, y in zip(a, b))


# -- construction ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(n_particles=0), "n_particles"),
        (dict(n_particles=-5), "n_particles"),
        (dict(n_particles=2.5), "n_particles"),
        (dict(resampling="best"), "resampling"),
        (dict(resample_threshold=1.5), "resample_threshold"),
    ],
)
def test_bad_construction(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ParticleFilter(FIELD, VelocityLinear(), SENSOR, **kwargs)


def test_bad_models_are_named():
    with pytest.raises(ValueError, match="sensor_model"):
        ParticleFilter(FIELD, VelocityLinear(), object())
    with pytest.raises(ValueError, match="alpha_slow"):
        AugmentedMCL(alpha_slow=0.5, alpha_fast=0.1)


# -- rejected calls leave the filter exactly as it was ----------------------------------------------------------
BAD_OBSERVATIONS = [
    [LandmarkObservation.__new__(LandmarkObservation)],  # not constructed: no fields
    "goalpost",
    [("goalpost", 1.0, 0.0)],
]


@pytest.mark.parametrize(
    "make_bad",
    [
        lambda: Observations.from_arrays(["goalpost"], [float("nan")], [0.0]),
        lambda: Observations.from_arrays(["goalpost"], [-1.0], [0.0]),
        lambda: Observations.from_arrays(["penalty_box"], [1.0], [0.0]),
        lambda: [LandmarkObservation("goalpost", float("inf"), 0.0)],
    ],
)
def test_bad_observations_raise_before_anything_changes(make_bad):
    pf = make()
    pf.correct(detections())
    before = state(pf)
    with pytest.raises(ValueError):
        pf.correct(make_bad())
    assert same_state(before, state(pf))


@pytest.mark.parametrize(
    "bad_input",
    [
        lambda: MotionInput(dt=-0.01, command=(0.1, 0, 0)),
        lambda: MotionInput(dt=float("nan"), command=(0.1, 0, 0)),
        lambda: MotionInput(dt=0.01),
        lambda: (0.01, 0.1, 0.0, 0.0),
    ],
)
def test_bad_motion_input_raises_before_anything_changes(bad_input):
    pf = make()
    before = state(pf)
    with pytest.raises(ValueError):
        u = bad_input()
        pf.predict(u)
    with pytest.raises(ValueError):
        pf.step(bad_input() if not isinstance(bad_input, type) else None, detections())
    assert same_state(before, state(pf))


def test_step_validates_observations_before_predicting():
    pf = make()
    before = state(pf)
    with pytest.raises(ValueError):
        pf.step(
            MotionInput(dt=0.01, command=(0.2, 0, 0)),
            Observations.from_arrays(["goalpost"], [-2.0], [0.0])
            if False
            else [LandmarkObservation("goalpost", 1.0, 0.0), "not an observation"],
        )
    assert same_state(before, state(pf))


@pytest.mark.parametrize(
    "name,value", [("poses", np.zeros((5000, 3))), ("poses", np.zeros((300, 3))), ("log_weights", np.zeros(300))]
)
def test_the_particle_arrays_cannot_be_rebound(name, value):
    """The kernels trust the particle arrays' shape (a larger array rebound in their place made the compiled
    step write past the others); replacing them goes through set_particles, which checks them."""
    pf = make()
    pf.step(MotionInput(dt=0.033, command=(0.1, 0.05, 0.2)), detections(TRUE_POSE))
    before = state(pf)
    with pytest.raises(AttributeError, match="set_particles"):
        setattr(pf, name, value)
    assert same_state(state(pf), before)
    assert getattr(pf, name) is getattr(pf, name) and getattr(pf, name).flags.writeable


@pytest.mark.parametrize(
    "name,value",
    [
        ("roughening", (0.1, -0.1, 0.0)),
        ("roughening", (0.1, 0.1)),
        ("roughening", (np.nan, 0.0, 0.0)),
        ("resampling", "best"),
        ("resampling", None),
        ("resample_threshold", 1.5),
        ("resample_threshold", True),
        ("resample_threshold", "0.5"),
        ("augmented", {"alpha_slow": 0.01}),
    ],
)
def test_bad_settings_between_steps_are_refused_unchanged(name, value):
    pf = make()
    u = MotionInput(dt=0.033, command=(0.1, 0.05, 0.2))
    pf.step(u, detections(TRUE_POSE))
    before, setting = state(pf), copy.deepcopy(getattr(pf, name))
    with pytest.raises(ValueError, match=name):
        setattr(pf, name, value)
    assert same_state(state(pf), before) and np.array_equal(getattr(pf, name), setting)


def test_settings_changed_between_steps_take_effect():
    u = MotionInput(dt=0.033, command=(0.1, 0.05, 0.2))
    made = make(seed=3, resample_threshold=1.0, roughening=(0.0, 0.0, 0.0), resampling="stratified", augmented=None)
    changed = make(seed=3)
    changed.roughening = [0.0, 0.0, 0.0]
    changed.resample_threshold = 1
    changed.resampling = "stratified"
    changed.augmented = None
    for pf in (made, changed):
        for _ in range(3):
            pf.step(u, detections(TRUE_POSE))
    assert same_state(state(made), state(changed)) and changed.resampled
    assert changed.resample_threshold == 1.0 and isinstance(changed.resample_threshold, float)
    with pytest.raises(ValueError):
        changed.roughening[0] = 1.0  # read-only: a new value goes through the setter's checks
    for fixed, value in (("n", 10), ("grid", Grid()), ("field", FIELD)):  # the filter's arrays are made for them
        with pytest.raises(AttributeError):
            setattr(changed, fixed, value)
    with pytest.raises(ValueError, match="grid"):
        make(grid={"position_cell": 0.2})


def test_bad_resets_are_rejected_unchanged():
    pf = make()
    before = state(pf)
    for call in (
        lambda: pf.reset_uniform("left_wing"),
        lambda: pf.reset_uniform((1, 0, 0, 1)),
        lambda: pf.reset_around((0, float("nan"), 0)),
        lambda: pf.reset_around((0, 0, 0), (1, -1, 1)),
        lambda: pf.set_particles(np.zeros((3, 3))),
        lambda: pf.set_particles(np.zeros((300, 3)), np.full(300, -np.inf)),
        lambda: pf.set_particles(np.zeros((300, 3)), np.r_[np.inf, np.zeros(299)]),
        lambda: pf.reset_uniform("field", heading="north"),
        lambda: pf.reset_uniform("field", heading=0.0, heading_sigma=float("nan")),
    ):
        with pytest.raises(ValueError):
            call()
    assert same_state(before, state(pf))


# -- invariants -------------------------------------------------------------------------------------------------
steps = st.lists(
    st.tuples(st.floats(-0.3, 0.3), st.floats(-0.1, 0.1), st.floats(-1, 1), st.booleans()), min_size=1, max_size=15
)


@given(steps, st.integers(0, 1000), st.sampled_from(["systematic", "stratified", "residual", "multinomial"]))
def test_weights_normalized_entropy_bounded_no_nan(sequence, seed, scheme):
    pf = make(n=200, seed=seed, resampling=scheme)
    pf.reset_uniform("field")
    pose = TRUE_POSE.copy()
    for vx, vy, omega, see in sequence:
        u = MotionInput(dt=0.05, command=(vx, vy, omega))
        pf.predict(u)
        if see:
            pf.correct(detections(pose))
        assert np.isfinite(pf.poses).all() and np.isfinite(pf.log_weights).all()
        assert pf.weights.sum() == pytest.approx(1.0, abs=1e-12)
        assert np.exp(pf.log_weights).sum() == pytest.approx(1.0, abs=1e-9)
        h = pf.entropy()
        bounds = pf.entropy_bounds
        assert 0.0 <= h.position <= bounds[0] + 1e-9 and 0.0 <= h.orientation <= bounds[1] + 1e-9
        e = pf.estimate()
        assert np.isfinite(e.pose).all() and np.isfinite(e.covariance).all()
        assert np.allclose(e.covariance, e.covariance.T) and np.linalg.eigvalsh(e.covariance).min() > -1e-12


def run_sequence(seed, initial=None):
    pf = make(n=400, seed=seed)
    if initial is None:
        pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
    else:
        poses, rng_state = initial
        pf.set_particles(poses)
        pf.rng.bit_generator.state = rng_state
    start = (pf.poses.copy(), copy.deepcopy(pf.rng.bit_generator.state))
    estimates, particles = [], []
    for _ in range(30):
        pf.step(MotionInput(dt=0.033, command=(0.1, 0.05, 0.2)), detections(TRUE_POSE))
        estimates.append(pf.estimate().pose.copy())
        particles.append(pf.poses.copy())
    return np.array(estimates), np.array(particles), start


def test_same_seed_same_run_bit_for_bit():
    a, pa, _ = run_sequence(3)
    b, pb, _ = run_sequence(3)
    assert np.array_equal(a, b) and np.array_equal(pa, pb)
    c, _, _ = run_sequence(4)
    assert not np.array_equal(a, c)


def _signatures() -> dict[str, int]:
    """How many compiled signatures each kernel of the filter's step has."""
    from numba.core.registry import CPUDispatcher

    from mcl.numba_cache import PACKAGES

    modules = [sys.modules[name] for name in list(sys.modules) if name.split(".")[0] in PACKAGES]
    return {
        f"{module.__name__}.{name}": len(kernel.signatures)
        for module in modules
        for name, kernel in list(vars(module).items())
        if isinstance(kernel, CPUDispatcher)
    }


@pytest.mark.parametrize("adaptive", [False, True], ids=["velocity-linear", "adaptive"])
@pytest.mark.parametrize(
    "clone", [copy.deepcopy, lambda pf: pickle.loads(pickle.dumps(pf))], ids=["deepcopy", "pickle"]
)
def test_a_copied_filter_steps_as_the_original(clone, adaptive):
    """A copy of a filter that has drawn in its kernels steps as the original does, and leaves the original's
    generator where it was (the kernels draw through the addresses of a bit generator). With the adaptive
    model, the particles' mobility states (which the compiled step resamples through a view) follow too."""
    if adaptive:
        hit = CollisionPercept(left=True, s_rel_left=2.0, rate=0.1, recent_left=True)
        u = MotionInput(dt=0.033, command=(0.1, 0.05, 0.2), collision=hit)
        pf = ParticleFilter(FIELD, AdaptiveMotion(), SENSOR, n_particles=200, seed=5, resample_threshold=1.0)
    else:
        u = MotionInput(dt=0.033, command=(0.1, 0.05, 0.2))
        pf = make(200, seed=5)
    pf.step(u, detections(TRUE_POSE))
    pf.step(u, detections(TRUE_POSE))  # (injection's kernels too)
    pf.predict(u)  # (and the prediction alone: every kernel the copy runs below has run once here)
    twin = clone(pf)
    before, compiled = state(pf), _signatures()
    for _ in range(3):
        twin.step(u, detections(TRUE_POSE))
        twin.predict(u)
    assert same_state(state(pf), before)
    # the copy's read-only arrays stayed read-only: its kernels are the original's, none compiled again
    assert _signatures() == compiled
    for _ in range(3):
        pf.step(u, detections(TRUE_POSE))
        pf.predict(u)
    assert same_state(state(twin), state(pf))
    if adaptive:
        assert len(np.unique(pf.motion_state[:, 0])) > 1  # the states differ: resampling moved them
        np.testing.assert_array_equal(twin.motion_state, pf.motion_state)


def test_mirrored_field_gives_mirrored_estimate():
    """The field is point-symmetric: the mirrored particle set under the same detections and the same draws
    evolves as the exact mirror of the original, and so does its estimate."""
    direct, particles, (start, rng_state) = run_sequence(5)
    mirrored, mirrored_particles, _ = run_sequence(5, (FIELD.mirror_poses(start), rng_state))
    for original, image in ((particles, mirrored_particles), (direct[None], mirrored[None])):
        expected = FIELD.mirror_poses(original.reshape(-1, 3))
        got = image.reshape(-1, 3)
        np.testing.assert_allclose(got[:, :2], expected[:, :2], atol=1e-6)
        assert np.abs(wrap_angles(got[:, 2] - expected[:, 2])).max() < 1e-6


def test_converges_from_uniform_with_detections():
    pf = make(n=1000, seed=1)
    pf.reset_uniform("field", heading=TRUE_POSE[2], heading_sigma=0.1)
    for _ in range(40):
        pf.step(MotionInput(dt=0.033, command=(0.0, 0.0, 0.0)), detections())
    e = pf.estimate()
    assert np.hypot(e.x - TRUE_POSE[0], e.y - TRUE_POSE[1]) < 0.15 and e.is_confident()


# -- resets -----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "region,check",
    [
        ("own_half", lambda p: (p[:, 0] <= 0).all()),
        ("opponent_half", lambda p: (p[:, 0] >= 0).all()),
        ("field", lambda p: (np.abs(p[:, 0]) <= 4.5).all() and (np.abs(p[:, 1]) <= 3.0).all()),
        ((1.0, 2.0, -0.5, 0.5), lambda p: ((p[:, 0] >= 1) & (p[:, 0] <= 2) & (np.abs(p[:, 1]) <= 0.5)).all()),
    ],
)
def test_uniform_reset_regions(region, check):
    pf = make()
    pf.reset_uniform(region)
    assert check(pf.poses) and np.allclose(pf.weights, 1 / pf.n)
    assert (pf.poses[:, 2] > -math.pi).all() and (pf.poses[:, 2] <= math.pi).all()


def test_reset_around_and_mirrored():
    pf = make(n=2000)
    pf.reset_around((1.0, 2.0, 3.0), (0.1, 0.2, 0.05))
    assert pf.poses[:, 0].mean() == pytest.approx(1.0, abs=0.01)
    assert pf.poses[:, 1].std() == pytest.approx(0.2, rel=0.1)
    before = pf.poses.copy()
    pf.reset_mirrored()
    np.testing.assert_allclose(pf.poses[:, :2], -before[:, :2])
    np.testing.assert_allclose(wrap_angles(pf.poses[:, 2] - before[:, 2] - math.pi), 0, atol=1e-12)


# -- recovery ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Impossible:
    """A sensor model under which no particle can explain anything."""

    def check(self, observations):
        pass

    def log_likelihood(self, poses, observations, out=None):
        out = np.empty(poses.shape[0]) if out is None else out
        out[:] = -np.inf
        return out


def test_zero_likelihood_everywhere_recovers_by_injection_without_nan():
    pf = ParticleFilter(FIELD, VelocityLinear(), Impossible(), n_particles=200, seed=0)
    pf.reset_around(TRUE_POSE, (0.05, 0.05, 0.05))
    pf.correct(detections())
    assert np.isfinite(pf.poses).all() and np.isfinite(pf.log_weights).all()
    assert pf.weights.sum() == pytest.approx(1.0)
    assert pf.injected == int(round(AugmentedMCL().max_fraction_tracking * 200))  # reset_around: pose known
    assert np.isfinite(pf.estimate().pose).all()


def test_nan_from_a_sensor_model_is_refused_unchanged():
    @dataclass(frozen=True)
    class Broken(Impossible):
        def log_likelihood(self, poses, observations, out=None):
            out = np.zeros(poses.shape[0]) if out is None else out
            out[:] = 0.0
            out[0] = np.nan
            return out

    pf = ParticleFilter(FIELD, VelocityLinear(), Broken(), n_particles=50, seed=0)
    before = state(pf)
    with pytest.raises(ValueError, match="NaN"):
        pf.correct(detections())
    assert same_state(before, state(pf))


def test_kidnapping_triggers_injection_and_recovery():
    pf = make(n=500, seed=2)
    pf.reset_around(TRUE_POSE, (0.05, 0.05, 0.05))
    for _ in range(60):  # a confident second of tracking
        pf.step(MotionInput(dt=0.033, command=(0, 0, 0)), detections())
    carried = TRUE_POSE + np.array([-3.0, 1.5, 0.0])
    injected = 0
    for _ in range(45):
        pf.step(MotionInput(dt=0.033, command=(0, 0, 0)), detections(carried))
        injected += pf.injected
    e = pf.estimate()
    assert injected > 0
    assert np.hypot(e.x - carried[0], e.y - carried[1]) < 0.2


def test_without_augmentation_nothing_is_injected():
    pf = make(augmented=None)
    pf.reset_around(TRUE_POSE, (0.05, 0.05, 0.05))
    pf.correct(detections(TRUE_POSE + np.array([-3.0, 1.5, 0.0])))
    assert pf.injected == 0


def test_constant_model_plugs_in_unchanged():
    pf = ParticleFilter(FIELD, ConstantNoise(), SENSOR, n_particles=100, seed=0, grid=Grid(position_cell=0.2))
    pf.reset_around(TRUE_POSE, (0.1, 0.1, 0.1))
    e = pf.step(MotionInput(dt=0.01, odometry=(0.0, 0.0, 0.0)), detections())
    assert np.hypot(e.x - TRUE_POSE[0], e.y - TRUE_POSE[1]) < 0.2


def test_the_anchor_follows_odometry_and_a_confident_cluster_on_its_mirror_is_put_back():
    """The relocalization's anchor is carried by the motion inputs (dead reckoning) and follows a confident,
    well-fitting estimate. A tight cluster that settles on the mirror image of where the anchor says the robot
    is explains every detection as well, so the prior decides: the particles are mirrored back."""
    pf = make(n=500, seed=4)
    pf.reset_around(TRUE_POSE, (0.05, 0.05, 0.02))
    np.testing.assert_allclose(pf.relocalization.anchor, TRUE_POSE)
    for _ in range(10):  # turn at 1 rad/s for 0.5 s, no camera
        pf.predict(MotionInput(dt=0.05, command=(0.0, 0.0, 1.0)))
    assert pf.relocalization.anchor[2] == pytest.approx(TRUE_POSE[2] + 0.5, abs=1e-9)
    turned = TRUE_POSE + np.array([0.0, 0.0, 0.5])
    for _ in range(10):  # a consistent confident estimate becomes the anchor
        pf.step(MotionInput(dt=0.033, command=(0, 0, 0)), detections(turned))
    assert abs(math.remainder(pf.relocalization.anchor[2] - turned[2], 2 * math.pi)) < 0.05
    mirror = FIELD.mirror_poses(turned[None])[0]  # a tight cluster at the mirror pose fits just as well
    pf.set_particles(mirror + np.random.default_rng(0).normal(0, 0.02, (pf.n, 3)))
    for _ in range(RelocalizationPrior().jump_corrections + 2):
        pf.step(MotionInput(dt=0.033, command=(0, 0, 0)), detections(mirror))
    estimate = pf.estimate()
    assert estimate.is_confident()
    assert np.hypot(estimate.x - turned[0], estimate.y - turned[1]) < 0.2
    assert abs(math.remainder(estimate.theta - turned[2], 2 * math.pi)) < 0.1
    assert pf.relocalization.mirror_log_odds > math.log(RelocalizationPrior().mirror_odds)


def test_weigh_is_log_mean_likelihood_and_normalize_bit_for_bit():
    from mcl.weights import log_mean_likelihood, normalize, weigh, weigh_chunked, weigh_fast

    rng = np.random.default_rng(0)
    for trial in range(60):
        n = int(rng.integers(1, 500))
        log_weights = rng.normal(0, 3, n) if trial % 3 else np.full(n, -math.log(n))
        log_likelihood = rng.normal(-5, 4, n)
        if trial % 7 == 0:
            log_likelihood[rng.random(n) < 0.5] = -np.inf
        count = int(rng.integers(0, n + 1)) if trial % 2 else n
        weights, expected_weights = np.empty(n), np.empty(n)
        valid, native, log_total, ess = weigh(log_weights, log_likelihood, count, weights)
        expected = normalize(log_weights + log_likelihood, expected_weights)
        assert valid and (log_total, ess) == expected and np.array_equal(weights, expected_weights)
        assert native == log_mean_likelihood(log_weights, log_likelihood, count)
        one_chunk = np.empty(n)  # the chunked kernel with one chunk: weigh's bits
        assert weigh_chunked(log_weights, log_likelihood, count, one_chunk, n + trial) == (
            valid,
            native,
            log_total,
            ess,
        )
        assert np.array_equal(one_chunk, weights)
        for variant in (
            lambda w: weigh_chunked(log_weights, log_likelihood, count, w, 16),
            lambda w: weigh_fast(log_weights, log_likelihood, count, w),
        ):
            other = np.empty(n)
            result = variant(other)
            np.testing.assert_allclose(result[1:], (native, log_total, ess), rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(other, weights, rtol=1e-12, atol=1e-300)
    broken = np.zeros(5)
    broken[2] = np.nan
    assert not weigh(np.zeros(5), broken, 5, np.empty(5))[0]
    assert not weigh_chunked(np.zeros(5), broken, 5, np.empty(5), 2)[0]
    assert not weigh_fast(np.zeros(5), broken, 5, np.empty(5))[0]
