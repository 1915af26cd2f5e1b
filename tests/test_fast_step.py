"""The compiled step: the one-dispatch `step`/`correct`, its opt-in variants (fast, threads) and its phases.

Default settings give what the plain sequence of calls gives, bit for bit: the sequence is run here through
a sensor model that offers no compiled likelihood (so the filter scores through `log_likelihood`, weighs with
`weigh`, resamples with `_resample`), and compared after every call with the compiled path on the same seed.
"""

import math
import tracemalloc
from dataclasses import dataclass

import numba
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from benchmarks.reference import PHASES, compiled_phases, full_step, sample_injection_reference
from benchmarks.step import COLLISION
from field import spl
from mcl import AugmentedMCL, Entropy, Estimate, ParticleFilter
from mcl.augmented import Injection
from mcl.contracts import fused_kernels
from mcl.engine import Engine
from mcl.estimate import cluster_estimate, grid_entropy
from mcl.relocalization import RelocalizationPrior, SoccerRelocalization
from mcl.resampling import SCHEMES, gather_with_jitter
from mcl.step import augmented_update
from mcl.weights import log_mean_likelihood, normalize
from motion_models import AdaptiveMotion, ConstantNoise, MotionInput, VelocityLinear
from numerics.chunks import CHUNK, balanced_chunk
from numerics.random import draw_variates
from proprioception.collision import NO_COLLISION
from sensing import LandmarkSensorModel, Observations

FIELD = spl()
TRUE_POSE = np.array([1.0, 0.5, 0.3])


@dataclass(frozen=True, eq=False)
class StagedLandmarks(LandmarkSensorModel):
    """The landmark model without `fused_likelihood`: the filter scores through `log_likelihood`."""

    def fused_likelihood(self):
        return None


class PlainEngine(Engine):
    """The stages as plain calls, as the filter made them before it had compiled paths: the motion model's own
    predict, `log_mean_likelihood` and `normalize`, a resampling scheme then `gather_with_jitter` on
    `draw_variates`, `cluster_estimate` and `grid_entropy` on fresh histograms; never the fused step."""

    def motion(self, motion_model, u):
        super().motion(motion_model, u)
        return None

    def fuses(self, sensor_model, observations):
        return False

    def weigh(self, log_likelihood, count):
        p = self.particles
        native = log_mean_likelihood(p.log_weights, log_likelihood, count)
        log_evidence, ess = normalize(p.log_weights + log_likelihood, p.weights)
        return True, native, log_evidence, ess

    def reweigh(self, log_likelihood, log_evidence):
        p = self.particles
        p.log_weights[:] = p.log_weights + log_likelihood - log_evidence

    def resample(self, scheme, injected, roughening, rng):
        p = self.particles
        keep = p.n - injected.shape[0]
        ancestors = SCHEMES[scheme](p.weights, keep, rng)
        previous = p.poses.copy()
        gather_with_jitter(previous, ancestors, roughening * math.sqrt(3.0), draw_variates(rng, keep, False), p.poses)
        if p.motion_state is not None:
            p.motion_state[:keep] = p.motion_state[ancestors]
            p.motion_state[keep:] = p.motion_model.particle_state(p.n - keep)
        p.poses[keep:] = injected
        p.log_weights[:] = -math.log(p.n)
        p.weights[:] = 1.0 / p.n

    def estimate(self):
        s, p = self.summary, self.particles
        if s.estimate is None:
            g = s.grid
            mean, cov = np.empty(3), np.empty((3, 3))
            cells = (s.x_min, s.y_min, g.cluster_cell, s.cluster_nx, s.cluster_ny, g.cluster_orientation_bins)
            weight = cluster_estimate(
                p.poses,
                p.weights,
                cells,
                (g.cluster_radius, g.cluster_angle_radius, 3),
                np.empty(s.cluster_nx * s.cluster_ny * g.cluster_orientation_bins),
                s.previous,
                s.has_previous,
                mean,
                cov,
            )
            s.estimate = Estimate(mean, cov, float(weight))
            s.previous[:] = mean
            s.has_previous = True
        return s.estimate

    def entropy(self):
        s, p = self.summary, self.particles
        g = s.grid
        cells = s.entropy_nx * s.entropy_ny
        position, orientation = grid_entropy(
            p.poses,
            p.weights,
            s.x_min,
            s.y_min,
            g.position_cell,
            s.entropy_nx,
            s.entropy_ny,
            g.orientation_bins,
            np.empty(cells),
            np.empty(g.orientation_bins),
        )
        return Entropy(float(position), float(orientation))


class PlainFilter(ParticleFilter):
    """The filter on `PlainEngine`, with injection drawn in numpy (`sample_injection_reference`)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._engine = PlainEngine(self.particles, self.summary)

    def _sample_injection(self, count, observations):
        return sample_injection_reference(self, count, observations)


def detections(pose, rng, count=10, kinds=("goalpost",), false_positives=0):
    rows = []
    for _ in range(count):
        kind = kinds[rng.integers(len(kinds))]
        target = FIELD.landmarks_of(kind)[rng.integers(len(FIELD.landmarks_of(kind)))]
        d = target - pose[:2]
        rows.append(
            (
                kind,
                math.hypot(*d) + 0.05 * rng.standard_normal(),
                math.atan2(d[1], d[0]) - pose[2] + 0.03 * rng.standard_normal(),
            )
        )
    for _ in range(false_positives):
        rows.append((kinds[0], rng.uniform(0.5, 6.0), rng.uniform(-1.0, 1.0)))
    return Observations.from_arrays(*zip(*rows))


def relocalization_state(relocalization):
    return repr(
        {
            name: (value.tolist() if isinstance(value, np.ndarray) else value)
            for name, value in vars(relocalization).items()
        }
    )


def state(pf):
    estimate = pf.estimate()
    entropy = pf.entropy()
    return (
        pf.poses.copy(),
        pf.log_weights.copy(),
        np.array(pf.weights),
        pf.w_slow,
        pf.w_fast,
        pf.ess,
        pf.resampled,
        pf.injected,
        pf.frame_fit,
        relocalization_state(pf.relocalization),
        pf.rng.bit_generator.state,
        estimate.pose.copy(),
        estimate.covariance.copy(),
        estimate.weight,
        entropy.position,
        entropy.orientation,
        None if pf.motion_state is None else pf.motion_state.copy(),
    )


def same(a, b):
    return all(
        np.array_equal(x, y, equal_nan=True)
        if isinstance(x, np.ndarray)
        else (x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y)))
        for x, y in zip(a, b)
    )


def make(n=300, seed=0, sensor=LandmarkSensorModel(FIELD), motion=VelocityLinear(), **kwargs):
    return ParticleFilter(FIELD, motion, sensor, n_particles=n, seed=seed, **kwargs)


def scenario(
    pf, steps=45, seed=1, use_step=True, kinds=("goalpost", "t_crossing"), kidnap=True, compare_every_call=None
):
    """A walk with detections most frames, a kidnapping halfway (injection), a frame with false positives."""
    rng = np.random.default_rng(seed)
    truth = TRUE_POSE.copy()
    for k in range(steps):
        command = (0.2 * math.sin(0.1 * k), 0.05, 0.3 * math.cos(0.05 * k))
        # (a stateful adaptive model also gets collisions now and then: its particles change mobility state)
        collision = (COLLISION if k % 5 == 1 else NO_COLLISION) if isinstance(pf.motion_model, AdaptiveMotion) else None
        u = MotionInput(dt=0.033, command=command, collision=collision)
        truth = truth + np.array([0.033 * command[0], 0.0, 0.033 * command[2]])
        if kidnap and k == steps // 2:
            truth = truth + np.array([-2.0, 1.0, 0.0])
        obs = detections(truth, rng, 1 + k % 10, kinds, false_positives=k % 7 == 3) if k % 3 != 2 else None
        if use_step:
            pf.step(u, obs)
        else:
            pf.predict(u)
            pf.correct(obs)
        yield k


@pytest.mark.parametrize(
    "options",
    [
        dict(),
        dict(resample_threshold=1.0, augmented=None),
        dict(augmented=None),
        dict(motion=VelocityLinear(gaussian=True)),
        dict(motion=ConstantNoise()),
        dict(resampling="stratified"),
        dict(roughening=(0.0, 0.0, 0.0)),
        dict(n=1),
        dict(n=700),
        dict(motion=AdaptiveMotion()),
        dict(motion=AdaptiveMotion(), resample_threshold=1.0, augmented=None),
        dict(bearing_model="exact"),
        dict(bearing_model="exact", motion=AdaptiveMotion(), resample_threshold=1.0),
    ],
)
@pytest.mark.parametrize("use_step", [True, False])
def test_compiled_path_equals_the_plain_sequence_bit_for_bit(options, use_step):
    options = dict(options)
    bearing_model = options.pop("bearing_model", "von_mises")
    compiled = make(sensor=LandmarkSensorModel(FIELD, bearing_model=bearing_model), **options)
    options = {"n": 300, "motion": VelocityLinear(), **options}
    plain = PlainFilter(
        FIELD,
        options.pop("motion"),
        StagedLandmarks(FIELD, bearing_model=bearing_model),
        n_particles=options.pop("n"),
        seed=0,
        **options,
    )
    for pf in (compiled, plain):
        pf.reset_uniform("own_half")
    for _ in zip(scenario(compiled, use_step=use_step), scenario(plain, use_step=use_step)):
        assert same(state(compiled), state(plain))


@pytest.mark.parametrize(
    "law",
    [
        dict(range_noise_linear=0.04, range_noise_growth=0.005),
        dict(range_noise_floor=0.08, range_noise_linear=0.02, range_noise_growth=0.0),
        dict(range_noise_linear=0.03, bearing_model="exact"),
    ],
)
@pytest.mark.parametrize("use_step", [True, False])
def test_compiled_path_with_a_linear_range_noise_law_equals_the_plain_sequence_bit_for_bit(law, use_step):
    """σ_r = floor + linear·r + growth·r² reaches the compiled step through `fused_likelihood()` (the pair
    (linear, growth)): the one-dispatch step, sensor resetting included, gives what the plain calls give."""
    compiled = make(sensor=LandmarkSensorModel(FIELD, **law))
    plain = PlainFilter(FIELD, VelocityLinear(), StagedLandmarks(FIELD, **law), n_particles=300, seed=0)
    assert fused_kernels(compiled.sensor_model).params[3] == (
        law["range_noise_linear"],
        law.get("range_noise_growth", 0.02),
    )
    for pf in (compiled, plain):
        pf.reset_uniform("own_half")
    for _ in zip(scenario(compiled, use_step=use_step), scenario(plain, use_step=use_step)):
        assert same(state(compiled), state(plain))
    default = make(sensor=LandmarkSensorModel(FIELD))
    default.reset_uniform("own_half")
    for _ in scenario(default, use_step=use_step):
        pass
    assert not np.array_equal(default.poses, compiled.poses)  # the law changed what the filter did


def test_compiled_path_covers_injection_and_global_localization():
    """The scenario above reaches the Python fallbacks of the compiled step: injection and resampling."""
    pf = make(n=400)
    pf.reset_uniform("own_half")
    injected = resampled = kept = 0
    for _ in scenario(pf, steps=60):
        injected += pf.injected > 0
        resampled += pf.resampled and pf.injected == 0
        kept += not pf.resampled
    assert injected and resampled and kept


@given(
    count=st.integers(1, 400),
    anchored=st.booleans(),
    heading=st.floats(-4.0, 4.0),
    share=st.sampled_from([0.0, 0.5, 0.9]),
    region=st.sampled_from(["field", "own_half", "opponent_half"]),
    seed=st.integers(0, 2**32 - 1),
)
def test_injection_equals_its_numpy_twin_bit_for_bit(count, anchored, heading, share, region, seed):
    """The relocalization's proposal with the compiled single-detection sampler gives the same poses as
    `sample_injection_reference` (its numpy twin), and leaves the generator at the same place; every injected
    pose is on the carpet (up to the jitter)."""
    rng = np.random.default_rng(seed)
    obs = detections(
        TRUE_POSE + np.array([rng.uniform(-3, 3), rng.uniform(-2, 2), 0.0]),
        rng,
        count=int(rng.integers(1, 8)),
        kinds=("goalpost", "t_crossing", "penalty_mark"),
    )
    prior = RelocalizationPrior(pair_share=share, uniform_share=min(0.1, 1.0 - share))
    pfs = [make(n=500, seed=seed % 1000, relocalization=SoccerRelocalization(prior)) for _ in range(2)]
    for pf in pfs:
        pf.reset_uniform(region)
        if anchored:
            pf.relocalization.reset_pose((0.5, -0.5, heading))
    compiled = pfs[0]._sample_injection(count, obs)
    plain = sample_injection_reference(pfs[1], count, obs)
    assert compiled.shape == (count, 3) and np.array_equal(compiled, plain)
    assert pfs[0].rng.bit_generator.state == pfs[1].rng.bit_generator.state
    slack = 5 * max(prior.jitter)
    x_min, x_max, y_min, y_max = pfs[0].relocalization.carpet
    assert (compiled[:, 0] >= x_min - slack).all() and (compiled[:, 0] <= x_max + slack).all()
    assert (compiled[:, 1] >= y_min - slack).all() and (compiled[:, 1] <= y_max + slack).all()
    assert (np.abs(compiled[:, 2]) <= math.pi).all()


def test_step_equals_predict_then_correct_then_estimate():
    a, b = make(seed=3), make(seed=3)
    for pf in (a, b):
        pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
    rng_a, rng_b = np.random.default_rng(0), np.random.default_rng(0)
    u = MotionInput(dt=0.033, command=(0.1, 0.05, 0.2))
    for _ in range(20):
        estimate = a.step(u, detections(TRUE_POSE, rng_a))
        b.predict(u)
        b.correct(detections(TRUE_POSE, rng_b))
        assert np.array_equal(estimate.pose, b.estimate().pose) and same(state(a), state(b))


@pytest.mark.parametrize(
    "options",
    [dict(), dict(fast=True), dict(motion=VelocityLinear(gaussian=True)), dict(motion=ConstantNoise(), augmented=None)],
)
@pytest.mark.parametrize("entropy_wanted", [False, True])
def test_a_step_without_detections_is_predict_then_estimate(options, entropy_wanted):
    """`step(u)` with no detections (None, or an empty list) is `predict(u)` then `estimate()`, bit for bit,
    with camera frames in between (they move the estimate's hysteresis anchor)."""
    stepped, plain = make(seed=5, **options), make(seed=5, **options)
    for pf in (stepped, plain):
        pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
        if entropy_wanted:
            pf.entropy()
    rng_stepped, rng_plain = np.random.default_rng(1), np.random.default_rng(1)
    for k in range(16):
        u = MotionInput(dt=0.02, command=(0.2, 0.05 * (k % 3), 0.3 * (-1) ** k))
        if k % 4 == 3:
            stepped.step(u, detections(TRUE_POSE, rng_stepped))
            plain.predict(u)
            plain.correct(detections(TRUE_POSE, rng_plain))
            plain.estimate()
            continue
        a = stepped.step(u, None if k % 2 else [])
        plain.predict(u)
        b = plain.estimate()
        assert np.array_equal(stepped.poses, plain.poses) and np.array_equal(stepped.log_weights, plain.log_weights)
        assert np.array_equal(a.pose, b.pose) and np.array_equal(a.covariance, b.covariance) and a.weight == b.weight
        assert stepped.rng.bit_generator.state == plain.rng.bit_generator.state
        assert relocalization_state(stepped.relocalization) == relocalization_state(plain.relocalization)
        # the hysteresis anchor the next estimate starts from
        assert stepped.summary.has_previous and plain.summary.has_previous
        assert np.array_equal(stepped.summary.previous, plain.summary.previous)
        if entropy_wanted:
            assert stepped.entropy() == plain.entropy()
    assert same(state(stepped), state(plain))


def test_a_step_without_detections_checks_its_input_before_anything_changes():
    pf = make(seed=2)
    pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
    before = (pf.poses.copy(), pf.rng.bit_generator.state)
    no_motion = MotionInput(dt=0.01)  # neither command nor odometry: the model cannot move
    with pytest.raises(ValueError, match="neither command nor odometry"):
        pf.step(no_motion)
    with pytest.raises(ValueError, match="must be a motion_models.MotionInput"):
        pf.step("forward")
    assert np.array_equal(pf.poses, before[0]) and pf.rng.bit_generator.state == before[1]


@pytest.mark.parametrize("options", [dict(), dict(threads=2)])
def test_the_entropy_from_the_step_is_the_entropy_computed_afresh(options):
    """Once asked for, the entropy comes out of the compiled step; it is what a fresh computation from the same
    histograms gives, it is dropped when the particles change, and asking for it changes nothing else. (Without
    injection, which the step leaves to Python, and the entropy with it.)"""
    asking, silent = make(seed=4, augmented=None, **options), make(seed=4, augmented=None, **options)
    rng_a, rng_b = np.random.default_rng(2), np.random.default_rng(2)
    u = MotionInput(dt=0.033, command=(0.1, 0.05, 0.2))
    first = asking.entropy()
    assert asking.entropy() is first  # kept until the particles change
    for _ in range(12):
        asking.step(u, detections(TRUE_POSE, rng_a))
        silent.step(u, detections(TRUE_POSE, rng_b))
        assert asking.summary.entropy is not None  # computed by the step itself
        assert silent.summary.entropy is None
        from_step = asking.entropy()
        asking.summary.entropy = None  # the same histograms, entropy computed by its own call
        assert asking.entropy() == from_step
        assert np.array_equal(asking.poses, silent.poses) and np.array_equal(asking.log_weights, silent.log_weights)
    assert silent.entropy() == asking.entropy()
    asking.predict(u)
    assert asking.summary.entropy is None  # the particles moved
    fresh = grid_entropy(
        asking.poses,
        np.array(asking.weights),
        asking.summary.x_min,
        asking.summary.y_min,
        asking.grid.position_cell,
        asking.summary.entropy_nx,
        asking.summary.entropy_ny,
        asking.grid.orientation_bins,
        np.empty(asking.summary.entropy_nx * asking.summary.entropy_ny),
        np.empty(asking.grid.orientation_bins),
    )
    entropy = asking.entropy()
    if options:  # threads: histograms summed in fixed point
        assert (entropy.position, entropy.orientation) == pytest.approx(fresh, rel=1e-12)
    else:
        assert (entropy.position, entropy.orientation) == fresh


@pytest.mark.parametrize(
    "options",
    [
        dict(),
        dict(augmented=None),
        dict(resample_threshold=1.0, augmented=None),
        dict(augmented=AugmentedMCL(fit_threshold=1e9)),  # injects every frame: sensor resetting moved forward
        dict(motion=AdaptiveMotion()),
        dict(resampling="stratified"),
        dict(n=1),
        dict(bearing_model="exact"),
    ],
)
def test_latency_compensated_correct_in_the_compiled_step_equals_the_plain_sequence(options):
    """`correct(observations, since)` scores each particle where it was at capture in the compiled step (the
    block moved back as `move_back` moves it); the filter that scores through `log_likelihood` on the poses
    `move_back` wrote gives the same state bit for bit, frames that inject and frames no particle explains
    included."""
    options = {"n": 300, "motion": VelocityLinear(), "bearing_model": "von_mises", **options}
    n, motion, bearing_model = options.pop("n"), options.pop("motion"), options.pop("bearing_model")
    compiled = ParticleFilter(
        FIELD, motion, LandmarkSensorModel(FIELD, bearing_model=bearing_model), n_particles=n, seed=2, **options
    )
    plain = ParticleFilter(
        FIELD, motion, StagedLandmarks(FIELD, bearing_model=bearing_model), n_particles=n, seed=2, **options
    )
    rng = np.random.default_rng(4)
    sinces = [(0.03, 0.01, 0.05), (0.0, 0.0, 0.0), (-0.02, 0.0, -0.3), None, (0.1, -0.05, 3.0)]
    for pf in (compiled, plain):
        pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
    u = MotionInput(dt=0.033, command=(0.2, 0.05, 0.3), collision=NO_COLLISION)
    for k in range(25):
        observations = detections(TRUE_POSE, rng, 1 + k % 6, ("goalpost", "t_crossing"))
        if k == 11:  # nothing explains these: every particle at zero
            observations = Observations.from_arrays(["goalpost"], [0.1], [math.pi])
        since = sinces[k % len(sinces)]
        for pf in (compiled, plain):
            pf.predict(u)
            pf.correct(observations, since=since)
        assert same(state(compiled), state(plain)), k


def test_latency_compensated_correct_on_threads_matches_one_thread_to_rounding():
    runs = []
    for threads in (1, 2):
        pf = make(n=20000, seed=7, threads=threads, augmented=None, resample_threshold=1.0)
        pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
        rng = np.random.default_rng(3)
        for k in range(4):
            pf.predict(MotionInput(dt=0.033, command=(0.2, 0.05, 0.3)))
            pf.correct(detections(TRUE_POSE, rng, 6), since=(0.02, 0.01, 0.1 * (k - 1)))
        runs.append(state(pf))
    one, two = runs
    np.testing.assert_allclose(two[0], one[0], rtol=0, atol=1e-9)  # the same offspring, particles to rounding
    np.testing.assert_allclose(two[12], one[12], atol=1e-9)


@pytest.mark.parametrize(
    "since",
    [
        (float("nan"), 0.0, 0.0),
        (0.0, float("inf"), 0.0),
        (0.1, 0.2),
        "abc",
        np.array([0.1, np.nan, 0.0]),
        (0.1, 0.2, 0.3, 0.4),
    ],
)
def test_a_bad_since_is_rejected_before_anything_changes(since):
    pf = make(seed=6)
    before = state(pf)
    with pytest.raises(ValueError, match="since"):
        pf.correct(detections(TRUE_POSE, np.random.default_rng(0)), since=since)
    assert same(state(pf), before)


@pytest.mark.parametrize("zero", [(0.0, 0.0, 0.0), (-0.0, 0.0, -0.0), np.zeros(3), [0, 0, 0]])
def test_a_zero_since_scores_the_particles_as_they_are(zero):
    a, b = make(seed=6), make(seed=6)
    a.correct(detections(TRUE_POSE, np.random.default_rng(0)), since=zero)
    b.correct(detections(TRUE_POSE, np.random.default_rng(0)))
    assert same(state(a), state(b))


class Unfused(ParticleFilter):
    """The filter as it was before `estimate()` and `entropy()` filled the histograms in the same dispatch: the
    histograms first (`Engine.fill`), then the estimate or the entropy, each a dispatch of its own."""

    def estimate(self):
        if self.summary.estimate is None:
            self.engine.fill()
        return super().estimate()

    def entropy(self):
        if self.summary.entropy is None:
            self.engine.fill()
        return super().entropy()


LOOP_CALLS = st.lists(
    st.sampled_from(["predict", "predict", "estimate", "entropy", "correct", "nothing"]), min_size=1, max_size=30
)


@pytest.mark.parametrize(
    "options", [dict(), dict(fast=True), dict(motion=VelocityLinear(gaussian=True)), dict(augmented=None)]
)
@given(calls=LOOP_CALLS)
def test_the_robot_loop_in_any_order_gives_what_separate_calls_give(options, calls):
    """predict, estimate, entropy and correct in any order, as a robot's loop makes them. `estimate()` fills the
    histograms, computes the estimate and (once asked for) the entropy in one dispatch; `entropy()` alone fills
    them and computes the entropy, not the estimate, whose hysteresis anchor only `estimate()` moves. Every result
    and the whole state are those of separate dispatches (bit for bit, `fast` included), and by default those of
    the plain sequence of calls."""
    options = {"motion": VelocityLinear(), **options}
    fused = make(n=200, seed=5, **options)
    unfused = Unfused(
        FIELD,
        options["motion"],
        LandmarkSensorModel(FIELD),
        n_particles=200,
        seed=5,
        **{k: v for k, v in options.items() if k != "motion"},
    )
    filters = [fused, unfused]
    if set(options) <= {"motion", "augmented"}:
        filters.append(
            PlainFilter(
                FIELD,
                options["motion"],
                StagedLandmarks(FIELD),
                n_particles=200,
                seed=5,
                **{k: v for k, v in options.items() if k != "motion"},
            )
        )
    rngs = [np.random.default_rng(9) for _ in filters]
    for pf in filters:
        pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
    u = MotionInput(dt=0.01, command=(0.2, 0.05, 0.3))
    for call in calls:
        seen = []
        for pf, rng in zip(filters, rngs):
            items = []
            if call == "predict":
                pf.predict(u)
            elif call == "estimate":
                e = pf.estimate()
                items = [e.pose.copy(), e.covariance.copy(), e.weight]
            elif call == "entropy":
                h = pf.entropy()
                items = [h.position, h.orientation]
            elif call == "correct":
                pf.correct(detections(TRUE_POSE, rng, count=4))
            seen.append(
                items
                + [pf.poses.copy(), pf.summary.previous.copy(), pf.summary.has_previous, pf.rng.bit_generator.state]
            )
        assert all(same(seen[0], other) for other in seen[1:]), call
    assert all(same(state(fused), state(pf)) for pf in filters[1:])


def test_a_missing_landmark_type_is_rejected_before_anything_changes():
    sensor = LandmarkSensorModel(FIELD)
    offsets = sensor._offsets.copy()
    offsets[2:] -= offsets[2] - offsets[1]  # a field without L crossings (the later types' rows shift)
    offsets.flags.writeable = False  # as the model holds it (a writable array would compile the kernels again)
    object.__setattr__(sensor, "_offsets", offsets)
    pf = make(sensor=sensor)
    pf.step(MotionInput(dt=0.01, command=(0.1, 0.0, 0.0)), detections(TRUE_POSE, np.random.default_rng(0)))
    before = state(pf)
    bad = Observations.from_arrays(["goalpost", "l_crossing"], [2.0, 1.0], [0.0, 0.5])
    for call in (lambda: pf.step(MotionInput(dt=0.01, command=(0.1, 0.0, 0.0)), bad), lambda: pf.correct(bad)):
        with pytest.raises(ValueError, match="L_CROSSING"):
            call()
        assert same(before, state(pf))


@given(
    st.floats(0.0, 2.0),
    st.floats(0.0, 2.0),
    st.floats(-50.0, 1.0),
    st.floats(0.001, 0.2),
    st.floats(0.2, 1.0),
    st.floats(0.05, 1.0),
    st.floats(0.0, 1.0),
)
def test_augmented_update_in_compiled_code_equals_the_python_method(
    w_slow, w_fast, log_average, alpha_slow, alpha_fast, ratio, fit
):
    a = AugmentedMCL(
        alpha_slow=alpha_slow,
        alpha_fast=max(alpha_fast, alpha_slow * 1.01),
        ratio_threshold=ratio,
        fit_threshold=fit,
    )
    injection = Injection()
    injection.w_slow, injection.w_fast = w_slow, w_fast
    compiled = augmented_update(
        w_slow, w_fast, log_average, a.alpha_slow, a.alpha_fast, a.ratio_threshold, a.fit_threshold
    )
    fraction = injection.update(a, log_average)
    assert compiled == (injection.w_slow, injection.w_fast, fraction)


# -- the opt-in variants ----------------------------------------------------------------------------------------
def test_options_are_validated():
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="threads"):
            make(threads=bad)
    with pytest.raises(ValueError, match="fast"):
        make(fast="yes")


@given(
    st.lists(
        st.one_of(st.floats(-745.1, 0.0), st.floats(-1e300, -745.2), st.sampled_from([-math.inf, -0.0])),
        min_size=1,
        max_size=40,
    )
)
def test_fast_exp_is_exp_to_rounding(values):
    """`fast_exp`, the polynomial exp of fast=True (compiled with its fast-math flags, as its callers inline
    it): relative error within 6e-16 + 3.5e-17·|x| where exp(x) is a normal number, absolute error within
    2.3e-16 everywhere (weights are exp of log-weights relative to the largest), 0 below -745.2."""
    from mcl.weights import fast_exp

    for x in values:
        got, want = fast_exp(x), math.exp(x)
        if x <= -745.2:
            assert got == 0.0
            continue
        assert abs(got - want) <= 2.3e-16
        if want >= 2.3e-308:
            assert abs(got - want) <= (6e-16 + 3.5e-17 * abs(x)) * want


@pytest.mark.parametrize("threshold", [1.0, 0.0])
def test_fast_matches_the_default_to_rounding(threshold):
    """fast=True: the same draws; after each step the particles, weights and estimate agree to about 1e-12
    (here the particles are taken from the default filter before each step, so rounding cannot accumulate)."""
    default, fast = (make(n=3000, resample_threshold=threshold, augmented=None, fast=f) for f in (False, True))
    rng = np.random.default_rng(4)
    default.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
    for _ in range(6):
        fast.set_particles(default.poses, default.log_weights)
        fast.rng.bit_generator.state = default.rng.bit_generator.state
        obs = detections(TRUE_POSE, rng)
        u = MotionInput(dt=0.033, command=(0.2, 0.0, 0.3))
        a, b = default.step(u, obs), fast.step(u, obs)
        offset = np.abs(default.poses - fast.poses)
        offset[:, 2] = np.minimum(offset[:, 2], 2 * math.pi - offset[:, 2])
        assert offset.max() < 1e-12
        np.testing.assert_allclose(fast.log_weights, default.log_weights, rtol=0, atol=1e-9)
        np.testing.assert_allclose(fast.weights, default.weights, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(b.pose, a.pose, atol=1e-12)
        np.testing.assert_allclose(b.covariance, a.covariance, atol=1e-12)
        assert b.weight == pytest.approx(a.weight, abs=1e-12) and fast.ess == pytest.approx(default.ess, rel=1e-9)
        assert fast.entropy().position == pytest.approx(default.entropy().position, abs=1e-9)


def run_threads(threads, n, numba_threads=None, steps=5, bearing_model="von_mises"):
    pf = make(
        n=n, resample_threshold=0.9, threads=threads, sensor=LandmarkSensorModel(FIELD, bearing_model=bearing_model)
    )
    pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
    if numba_threads is not None:
        pf.engine.scope.threads = numba_threads
    rng = np.random.default_rng(2)
    states = []
    for k in range(steps):
        u = MotionInput(dt=0.033, command=(0.2, 0.0, 0.3))
        if k % 2:
            pf.step(u, detections(TRUE_POSE, rng))
        else:
            pf.predict(u)
            pf.correct(detections(TRUE_POSE, rng))
        states.append(state(pf))
    return states


def test_threads_give_the_same_results_on_any_number_of_threads():
    n = 20000  # eight chunks
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread here")
    for a, b in zip(run_threads(2, n), run_threads(2, n, numba_threads=1)):
        assert same(a, b)


@pytest.mark.parametrize("bearing_model", ["von_mises", "exact"])
def test_threads_match_one_thread_to_rounding(bearing_model):
    one, two = (run_threads(threads, 20000, bearing_model=bearing_model) for threads in (1, 2))
    for a, b in zip(one, two):
        np.testing.assert_allclose(b[0], a[0], rtol=0, atol=1e-9)  # the same offspring, particles to rounding
        np.testing.assert_allclose(b[1], a[1], rtol=0, atol=1e-9)
        np.testing.assert_allclose(b[12], a[12], atol=1e-9)
        np.testing.assert_allclose(b[13], a[13], atol=1e-9)
        assert b[5] == pytest.approx(a[5], rel=1e-9)


@given(st.integers(1, 4096**2), st.sampled_from([4096, CHUNK]))
def test_chunks_split_evenly_over_1_2_4_or_8_threads(count, target):
    chunk = balanced_chunk(count, target)
    chunks = -(-count // chunk)
    if count <= target:
        assert chunk == target  # one chunk: the serial sums, bit for bit
    else:
        assert chunk <= target and chunks % 8 == 0  # prange's equal shares are equal work
        assert chunks * chunk - count < chunk  # only the last chunk is short


# -- what the benchmark calls -----------------------------------------------------------------------------------
@pytest.mark.parametrize("options", [dict(), dict(fast=True), dict(threads=2)])
def test_compiled_phases_in_order_are_the_fused_step(options):
    fused, phased = (make(n=2000, resample_threshold=1.0, augmented=None, **options) for _ in range(2))
    for pf in (fused, phased):
        pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
    u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1))
    obs = detections(TRUE_POSE, np.random.default_rng(5))
    work = compiled_phases(phased, u, obs)
    assert tuple(work) == PHASES
    for _ in range(3):
        full_step(fused, u, obs)
        for name in PHASES:
            work[name]()
        assert same(state(fused), state(phased))


# -- memory -----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("options", [dict(), dict(fast=True)])
def test_a_steady_state_step_allocates_nothing_that_grows_with_n(options):
    """tracemalloc sees numpy's allocations; the kernels' own scratch (numba's runtime, which tracemalloc does
    not see) is a few blocks of fixed size, so the Python-visible peak must not grow with N either."""
    peaks = []
    for n in (2000, 50000):
        pf = make(n=n, resample_threshold=1.0, **options)
        pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
        u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1))
        obs = detections(TRUE_POSE, np.random.default_rng(6))
        for _ in range(2):
            pf.step(u, obs), pf.entropy()
        tracemalloc.start()
        for _ in range(3):
            pf.step(u, obs)
            pf.entropy()
            pf.predict(u)
            pf.estimate()
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    assert peaks[1] < 64 * 1024 and peaks[1] < peaks[0] + 16 * 1024


@pytest.mark.parametrize("fast", [False, True])
def test_issue_shaped_step_equals_its_numpy_twin(fast):
    # The benchmark's C-reference-shaped step (predict, likelihood, normalize + ESS, systematic resampling
    # without roughening, grid entropy) against the numpy references fed the same draws.
    from benchmarks.reference import issue_shaped_step
    from benchmarks.step import bench_setup
    from mcl.reference import grid_entropy as grid_entropy_reference
    from mcl.reference import normalize as normalize_reference
    from mcl.reference import systematic as systematic_reference
    from motion_models.reference import move_with_noise as move_with_noise_reference

    pf, u, observations = bench_setup(700, fast=fast)
    pf.step(u, observations)
    poses, log_weights = pf.poses.copy(), pf.log_weights.copy()
    rng = np.random.default_rng()
    rng.bit_generator.state = pf.rng.bit_generator.state
    ess, position, orientation = issue_shaped_step(pf, u, observations)()

    move_with_noise_reference(poses, *u.displacement(), *pf.motion_model.noise_bounds(u), False, rng.random((700, 3)))
    weights, _, expected_ess = normalize_reference(
        log_weights + pf.sensor_model.numpy_twin().log_likelihood(poses, observations)
    )
    expected = poses[systematic_reference(weights, 700, rng)]
    np.testing.assert_allclose(pf.poses, expected, rtol=0, atol=1e-12)
    assert ess == pytest.approx(expected_ess, rel=1e-12)
    g = pf.grid
    bits = grid_entropy_reference(
        expected,
        np.full(700, 1 / 700),
        pf.summary.x_min,
        pf.summary.y_min,
        g.position_cell,
        pf.summary.entropy_nx,
        pf.summary.entropy_ny,
        g.orientation_bins,
    )
    assert (position, orientation) == pytest.approx(bits, rel=1e-12)
    assert (pf.weights == 1 / 700).all() and rng.random() == pf.rng.random()
