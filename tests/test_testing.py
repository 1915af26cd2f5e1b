"""`mcl.tools.testing`: its strategies draw what they promise, and each of its checks passes on good models and
filters and fails (AssertionError, naming the fault) on deliberately broken ones."""

import math
import types
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from field import PRESET_NAMES, Field, LandmarkType, spl
from field.angles import wrap_angles
from mcl import ParticleFilter
from mcl.tools import testing as mt
from motion_models import AdaptiveMotion, FootstepEvent, MotionInput, RawFootstepOdometry, VelocityLinear
from proprioception.collision import CollisionPercept
from sensing import LandmarkObservation, LandmarkSensorModel, Observations

FIELD = spl()
SENSOR = LandmarkSensorModel(FIELD)
STEP = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1))
FRAME = Observations.from_arrays(["goalpost", "T"], [3.0, 1.5], [0.2, -0.4])
FEW = 8  # examples for a check that is expected to fail (without shrinking the failure: faster)


def make_filter(seed=5, motion=None, n=32):
    return ParticleFilter(FIELD, VelocityLinear() if motion is None else motion, SENSOR, n_particles=n, seed=seed)


def carpet(field, margin=0.0):
    border = field.dims.border_strip_width
    return field.half_length + border - margin, field.half_width + border - margin


# -- strategies ----------------------------------------------------------------------------------------------------
@given(mt.fields())
def test_fields_are_the_presets(field):
    assert isinstance(field, Field) and field.name in PRESET_NAMES


@given(st.data())
def test_poses_lie_on_the_carpet_with_wrapped_headings(data):
    field = data.draw(mt.fields())
    margin = data.draw(st.floats(0.0, 0.5))
    pose = data.draw(mt.poses(field, margin))
    assert pose.shape == (3,) and pose.dtype == np.float64 and np.isfinite(pose).all()
    half_x, half_y = carpet(field, margin)
    assert abs(pose[0]) <= half_x and abs(pose[1]) <= half_y
    assert -math.pi < pose[2] <= math.pi


@given(st.data())
def test_pose_arrays_have_the_rows_asked_for_on_the_carpet(data):
    field = data.draw(mt.fields())
    exact = data.draw(st.booleans())
    n = data.draw(st.integers(1, 40)) if exact else (3, 9)
    poses = data.draw(mt.pose_arrays(field, n=n, margin=0.1))
    if exact:
        assert poses.shape == (n, 3)
    else:
        assert 3 <= poses.shape[0] <= 9 and poses.shape[1] == 3
    assert poses.dtype == np.float64 and poses.flags.c_contiguous and poses.flags.writeable
    mt.assert_poses_finite_and_wrapped(poses)
    assert (poses[:, 2] > -math.pi).all()
    half_x, half_y = carpet(field, 0.1)
    assert (np.abs(poses[:, 0]) <= half_x).all() and (np.abs(poses[:, 1]) <= half_y).all()


def test_the_pose_strategies_refuse_bad_arguments():
    with pytest.raises(ValueError, match="margin"):
        mt.poses(FIELD, margin=100.0)
    with pytest.raises(ValueError, match="n = "):
        mt.pose_arrays(FIELD, n=0)
    with pytest.raises(TypeError, match="field"):
        mt.pose_arrays("spl")


@settings(max_examples=20)
@given(mt.particle_sets(FIELD, n=32))
def test_particle_sets_are_what_set_particles_takes(particles):
    poses, log_weights = particles
    assert poses.shape == (32, 3) and log_weights.shape == (32,)
    assert np.isfinite(log_weights).any() and not np.isnan(log_weights).any() and not np.isposinf(log_weights).any()
    pf = make_filter()
    pf.set_particles(poses, log_weights)
    mt.assert_weights_normalized(pf)
    np.testing.assert_array_equal(pf.poses, poses)


@given(st.data())
def test_observations_are_typed_finite_and_accepted(data):
    field = data.draw(mt.fields())
    with_sigmas = data.draw(st.booleans())
    batch = data.draw(
        mt.observations(
            field, max_detections=5, with_sigmas=with_sigmas, min_detections=1, max_line_points=4, with_view=True
        )
    )
    assert isinstance(batch, Observations) and 1 <= len(batch) <= 5 and batch.line_points.shape[0] <= 4
    present = {kind.value for kind in LandmarkType if len(field.landmarks_of(kind))}
    assert set(batch.kinds.tolist()) <= present
    half_x, half_y = carpet(field)
    assert np.isfinite(batch.ranges).all() and (batch.ranges >= 0).all()
    assert (batch.ranges <= 2 * math.hypot(half_x, half_y)).all()
    assert np.isfinite(batch.bearings).all() and (np.abs(batch.bearings) <= math.pi).all()
    for sigmas in (batch.range_sigmas, batch.bearing_sigmas):
        given_ = ~np.isnan(sigmas)
        assert with_sigmas or not given_.any()
        assert ((sigmas[given_] >= 0.005) & (sigmas[given_] <= 1.0)).all()
    LandmarkSensorModel(field).check(batch)


@given(mt.observations(FIELD))
def test_observations_without_options_have_no_noise_lines_or_view(batch):
    assert len(batch) <= 8 and batch.line_points.shape == (0, 2) and batch.view is None
    assert np.isnan(batch.range_sigmas).all() and np.isnan(batch.bearing_sigmas).all()


@given(st.data())
def test_observations_seen_from_a_pose_are_explained_by_it(data):
    field = data.draw(mt.fields())
    pose = data.draw(mt.poses(field))
    batch = data.draw(mt.observations(field, min_detections=1, max_line_points=6, seen_from=pose))
    assert LandmarkSensorModel(field).explained(pose, batch).all()
    assert (np.abs(batch.bearings) <= math.pi).all()
    c, s = math.cos(pose[2]), math.sin(pose[2])
    on_field = pose[:2] + batch.line_points @ np.array([[c, s], [-s, c]])
    lines = field.line_points(spacing=0.1)
    for point in on_field:
        assert np.hypot(*(lines - point).T).min() <= 0.03


@given(mt.edge_observations(FIELD))
def test_edge_observations_are_batches_the_constructor_accepts(batch):
    assert isinstance(batch, Observations) and len(batch) <= 6
    assert (batch.ranges <= 1000.0).all() and (np.abs(batch.bearings) <= 100.0).all()


@given(st.data())
def test_motion_inputs_are_of_their_kind_and_accepted(data):
    kind = data.draw(st.sampled_from(["command", "odometry", "footstep", "any"]))
    collision = data.draw(st.booleans())
    u = data.draw(mt.motion_inputs(kind, collision=collision))
    assert isinstance(u, MotionInput) and 0.0 <= u.dt <= 0.1
    if kind == "command":
        assert u.command is not None and u.odometry is None and u.footstep is None
    if kind == "odometry":
        assert u.odometry is not None and u.command is None and u.footstep is None
    if kind == "footstep":
        assert u.odometry is not None
        assert u.footstep is None or (isinstance(u.footstep, FootstepEvent) and u.footstep.has_online_inputs())
        RawFootstepOdometry("online").check(u)
        RawFootstepOdometry("apriori").check(u)
    assert isinstance(u.collision, CollisionPercept) if collision else u.collision is None
    VelocityLinear().check(u)
    if collision:
        AdaptiveMotion().check(u)


def test_motion_inputs_refuse_an_unknown_kind():
    with pytest.raises(ValueError, match="kind"):
        mt.motion_inputs("teleport")


@given(mt.hostile_motion_inputs())
def test_hostile_motion_inputs_are_motion_inputs(u):
    assert isinstance(u, MotionInput)


REFUSED_FILTER = make_filter()


@given(mt.hostile_values())
def test_hostile_values_are_refused_as_numbers_triples_and_poses(value):
    builds = [
        lambda: MotionInput(dt=value),
        lambda: LandmarkObservation("T", value, 0.0),
        lambda: LandmarkObservation("T", 1.0, value),
    ]
    if value is not None:  # (an optional argument's "not given")
        builds += [lambda: MotionInput(dt=0.01, command=value), lambda: MotionInput(dt=0.01, odometry=value)]
    for build in builds:
        with pytest.raises((ValueError, TypeError)):
            build()
    for method in (
        REFUSED_FILTER.reset_around,
        REFUSED_FILTER.set_particles,
        REFUSED_FILTER.diffuse,
        REFUSED_FILTER.predict,
    ):
        mt.assert_refused_leaves_state(REFUSED_FILTER, method, value)


# -- the filter invariants -------------------------------------------------------------------------------------
def stub(weights, log_weights=None):
    weights = np.asarray(weights, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_weights = np.log(weights) if log_weights is None else np.asarray(log_weights, dtype=float)
    return types.SimpleNamespace(weights=weights, log_weights=log_weights, n=weights.shape[0])


def test_weights_normalized_passes_on_filters():
    pf = make_filter()
    mt.assert_weights_normalized(pf)
    for _ in range(5):
        pf.step(STEP, FRAME)
        mt.assert_weights_normalized(pf)
    mt.assert_weights_normalized(stub([0.25, 0.75, 0.0]))


@pytest.mark.parametrize(
    "broken, match",
    [
        (stub([0.25, 0.25]), "sum to 0.5"),
        (stub([0.5, math.nan, 0.5]), r"weights\[1\] = nan"),
        (stub([1.5, -0.5]), r"weights\[1\] = -0.5"),
        (stub([0.5, 0.5], [0.0, math.log(0.5)]), r"weights\[0\] = 0.5 but exp\(log_weights\[0\]\) = 1.0"),
        (stub([0.5, 0.5], [math.log(0.5), math.inf]), r"log_weights\[1\] = inf"),
        (
            types.SimpleNamespace(weights=np.full(3, 1 / 3), log_weights=np.zeros(2), n=3),
            r"log_weights must have shape",
        ),
        (types.SimpleNamespace(weights=np.full(3, 1 / 3), log_weights=np.zeros(3), n=4), r"weights must have shape"),
    ],
)
def test_weights_normalized_fails_on_broken_weights(broken, match):
    with pytest.raises(AssertionError, match=match):
        mt.assert_weights_normalized(broken)


def test_poses_finite_and_wrapped_passes_and_fails():
    pf = make_filter()
    mt.assert_poses_finite_and_wrapped(pf)
    mt.assert_poses_finite_and_wrapped(pf.poses)
    mt.assert_poses_finite_and_wrapped(np.array([[0.0, 0.0, math.pi], [0.0, 0.0, -math.pi]]))
    for bad, match in (
        (np.array([[0.0, 0.0, 0.0], [1.0, math.nan, 0.0]]), r"poses\[1\] .* not finite"),
        (np.array([[0.0, 0.0, 3.5]]), r"poses\[0\] .* heading not wrapped"),
        (np.array([[0.0, math.inf, 0.0]]), "not finite"),
        (np.zeros((4, 2)), r"shape \(N, 3\)"),
        (np.zeros(3), r"shape \(N, 3\)"),
        (np.zeros((2, 3), dtype=np.int64), "floats"),
    ):
        with pytest.raises(AssertionError, match=match):
            mt.assert_poses_finite_and_wrapped(bad)


def test_snapshots_see_every_change_and_nothing_else():
    pf = make_filter()
    pf.step(STEP, FRAME)
    before = mt.snapshot(pf)
    mt.assert_unchanged(before, mt.snapshot(pf))
    assert before == mt.snapshot(pf) and before.w_slow == pf.w_slow and before.w_fast == pf.w_fast
    assert mt.snapshot(make_filter()) == mt.snapshot(make_filter())  # NaN frame_fit equals itself
    for change, what in (
        (lambda: pf.rng.random(), "rng_state"),
        (lambda: pf.predict(STEP), "poses"),
        (lambda: pf.correct(FRAME), "poses|weights"),
        (lambda: setattr(pf, "w_slow", 0.5), "w_slow"),
        (lambda: setattr(pf, "roughening", (0.1, 0.0, 0.0)), "roughening"),
        (lambda: setattr(pf, "resampling", "residual"), "resampling"),
    ):
        before = mt.snapshot(pf)
        change()
        with pytest.raises(AssertionError, match=rf"the filter changed: .*({what})"):
            mt.assert_unchanged(before, mt.snapshot(pf))
    # A snapshot is a copy: later changes do not reach it.
    before = mt.snapshot(pf)
    poses = before.poses.copy()
    pf.diffuse((0.5, 0.5, 0.5))
    np.testing.assert_array_equal(before.poses, poses)
    assert not before.poses.flags.writeable


def test_a_snapshot_without_the_estimate_leaves_the_filter_alone():
    pf = make_filter()
    pf.predict(STEP)  # the estimate is stale: computing it would move its anchor
    first = mt.snapshot(pf, estimate=False)
    assert first.estimate is None
    assert mt.snapshot(pf, estimate=False) == first


def test_refused_leaves_state_passes_on_refused_calls():
    pf = make_filter()
    pf.step(STEP, FRAME)
    error = mt.assert_refused_leaves_state(pf, pf.step, "u")
    assert "MotionInput" in str(error)
    mt.assert_refused_leaves_state(pf, pf.correct, [LandmarkObservation("T", 1.0, 0.0), "not one"])
    mt.assert_refused_leaves_state(pf, pf.reset_around, (1e6, 0.0, 0.0))
    mt.assert_refused_leaves_state(pf, pf.diffuse, sigma="wide")


def test_refused_leaves_state_fails_on_an_accepted_call():
    pf = make_filter()
    with pytest.raises(AssertionError, match="was accepted; it should have been refused"):
        mt.assert_refused_leaves_state(pf, pf.predict, STEP)


def test_refused_leaves_state_fails_on_a_refusal_that_changed_the_filter():
    pf = make_filter()

    def sneaky(sigma):
        pf.diffuse(sigma)  # changes the particles and draws numbers, then refuses
        raise ValueError("sigma refused")

    with pytest.raises(
        AssertionError,
        match=r"was refused \(ValueError: sigma refused\) but changed the filter: "
        r"poses.*rng_state",
    ):
        mt.assert_refused_leaves_state(pf, sneaky, (0.1, 0.1, 0.1))


def test_refused_leaves_state_fails_on_other_exceptions_and_silent_refusals():
    pf = make_filter()

    def crash():
        raise RuntimeError("boom")

    def silent():
        raise ValueError()

    with pytest.raises(AssertionError, match="raised RuntimeError: boom"):
        mt.assert_refused_leaves_state(pf, crash)
    with pytest.raises(AssertionError, match="without a message"):
        mt.assert_refused_leaves_state(pf, silent)
    with pytest.raises(
        AssertionError,
        match="raised ArgumentTypeError: .*; a refused call must raise one of "
        r"\('KeyError',\)",
    ):
        mt.assert_refused_leaves_state(pf, pf.step, "u", exceptions=(KeyError,))


STEPS = [(STEP, FRAME), STEP, (MotionInput(dt=0.01, odometry=(0.01, 0.0, 0.02)), None), (STEP, FRAME)]


def test_same_seed_same_run_passes_on_seeded_filters():
    mt.assert_same_seed_same_run(make_filter, STEPS)
    mt.assert_same_seed_same_run(
        lambda: make_filter(motion=AdaptiveMotion()),
        [(MotionInput(dt=0.01, command=(0.2, 0.0, 0.1), collision=CollisionPercept()), FRAME)] * 3,
    )


@dataclass(frozen=True)
class Walk:
    """A correct little motion model: the input's displacement plus Gaussian robot-frame noise."""

    sigma: float = 0.01

    def check(self, u):
        u.displacement()

    def noise(self, rng, n):
        return self.sigma * rng.standard_normal((n, 3))

    def predict(self, poses, u, rng):
        dx, dy, dtheta = u.displacement()
        noise = self.noise(rng, poses.shape[0])
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        forward, left = dx + noise[:, 0], dy + noise[:, 1]
        poses[:, 0] += c * forward - s * left
        poses[:, 1] += s * forward + c * left
        poses[:, 2] = wrap_angles(poses[:, 2] + dtheta + noise[:, 2])


class GlobalRandom(Walk):
    """Draws its noise from a generator of its own instead of the one it is given."""

    def noise(self, rng, n):
        return self.sigma * np.random.default_rng().standard_normal((n, 3))


@dataclass(frozen=True)
class Counting(Walk):
    """Keeps a hidden count of its calls (shared by every filter it is given) and drifts with it."""

    calls: list = None

    def __post_init__(self):
        object.__setattr__(self, "calls", [])

    def noise(self, rng, n):
        self.calls.append(1)
        return super().noise(rng, n) + 1e-3 * len(self.calls)


def test_same_seed_same_run_fails_on_unseeded_filters_and_hidden_state():
    with pytest.raises(AssertionError, match=r"two filters from the same factory differ after construction: poses"):
        mt.assert_same_seed_same_run(lambda: make_filter(seed=None), STEPS)
    for model in (GlobalRandom(), Counting()):
        with pytest.raises(AssertionError, match=r"differ after step 0 .*poses"):
            mt.assert_same_seed_same_run(lambda: make_filter(motion=model), STEPS)
    pf = make_filter()
    with pytest.raises(AssertionError, match="returned the same filter twice"):
        mt.assert_same_seed_same_run(lambda: pf, STEPS)


# -- the motion model contract ---------------------------------------------------------------------------------
def test_good_motion_models_pass():
    report = mt.check_motion_model(Walk(), FIELD, strict=True, refused=[MotionInput(dt=0.01)], max_examples=15)
    assert report.examples >= 15 and report.accepted >= 15 and report.hostile_refused > 0
    report = mt.check_motion_model(
        AdaptiveMotion(),
        FIELD,
        strict=True,
        max_examples=10,
        inputs=mt.motion_inputs("command", collision=True),
        hostile=mt.hostile_motion_inputs().filter(lambda u: u.odometry is None),
    )
    assert report.accepted >= 10


@settings(max_examples=10, deadline=None)
@given(mt.pose_arrays(FIELD), mt.motion_inputs("any"), st.integers(0, 2**32))
def test_the_single_example_contract_composes_with_given(poses, u, seed):
    before = poses.copy()
    assert mt.assert_motion_contract(VelocityLinear(), poses, u, seed, strict=True)
    np.testing.assert_array_equal(poses, before)  # the check moves a copy


class NaNMotion(Walk):
    def predict(self, poses, u, rng):
        super().predict(poses, u, rng)
        poses[-1, 0] = math.nan


class Unwrapped(Walk):
    def predict(self, poses, u, rng):
        super().predict(poses, u, rng)
        poses[:, 2] += 7.0


class RuntimeCheck(Walk):
    def check(self, u):
        if u.command is None and u.odometry is None:
            raise RuntimeError("no displacement")


class LateRefusal(Walk):
    """Its check accepts everything; its predict refuses a missing displacement."""

    def check(self, u):
        pass


class PredictsWithoutChecking(Walk):
    """Its check refuses a missing displacement; its predict then stays put instead of refusing."""

    def predict(self, poses, u, rng):
        if u.command is None and u.odometry is None:
            return
        super().predict(poses, u, rng)


class MovesThenRefuses(Walk):
    def predict(self, poses, u, rng):
        poses[:, 0] += 1.0
        super().predict(poses, u, rng)


class RefusesAll(Walk):
    def check(self, u):
        raise ValueError("never")


class WrongStateRows(Walk):
    def particle_state(self, n):
        return np.zeros((n + 1, 2))


class StateGrows(Walk):
    def particle_state(self, n):
        return np.zeros((n, 2))

    def predict(self, poses, u, rng, state=None):
        super().predict(poses, u, rng)
        state[:, 0] = math.inf


@pytest.mark.parametrize(
    "model, kwargs, match",
    [
        (NaNMotion(), {}, r"NaNMotion.predict with .*poses\[\d+\] = .* not finite"),
        (Unwrapped(), {}, r"heading not wrapped"),
        (GlobalRandom(), {}, r"from the same seed gave different results: poses"),
        (Counting(), {}, r"from the same seed gave different results: poses"),
        (
            RuntimeCheck(),
            {},
            r"RuntimeCheck.check\(.*\) raised RuntimeError: no displacement; a refused input must "
            r"raise ValueError or TypeError",
        ),
        (LateRefusal(), {}, r"check accepted .* but predict raised ValueError"),
        (PredictsWithoutChecking(), dict(strict=True), r"check refused .* but predict accepted it"),
        (MovesThenRefuses(), dict(strict=True), r"predict refused .* but changed poses"),
        (RefusesAll(), {}, r"RefusesAll refused all \d+ inputs drawn"),
        (WrongStateRows(), {}, r"particle_state\(\d+\) must have \d+ rows"),
        (StateGrows(), {}, r"non-finite particle state"),
        (Walk(), dict(refused=[STEP]), r"Walk.check accepted .* which it must refuse"),
    ],
)
def test_broken_motion_models_fail(model, kwargs, match):
    with pytest.raises(AssertionError, match=match):
        mt.check_motion_model(model, FIELD, max_examples=FEW, shrink=False, **kwargs)


def test_a_lenient_predict_passes_without_strict():
    mt.check_motion_model(PredictsWithoutChecking(), FIELD, max_examples=FEW)


# -- the sensor model contract ---------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Delegating:
    """A sensor model that passes every call to `inner` (the landmark model): the base of the broken ones."""

    inner: object = SENSOR

    def check(self, observations):
        self.inner.check(observations)

    def terms(self, observations):
        return self.inner.terms(observations)

    def log_likelihood(self, poses, observations, out=None):
        return self.inner.log_likelihood(poses, observations, out=out)


class NaNOutput(Delegating):
    def log_likelihood(self, poses, observations, out=None):
        values = super().log_likelihood(poses, observations, out)
        values[0] = math.nan
        return values


class PlusInf(Delegating):
    def log_likelihood(self, poses, observations, out=None):
        return np.full(poses.shape[0], math.inf)


class MinusInf(Delegating):
    def log_likelihood(self, poses, observations, out=None):
        values = super().log_likelihood(poses, observations, out)
        values[-1] = -math.inf
        return values


class OneTooMany(Delegating):
    def log_likelihood(self, poses, observations, out=None):
        return np.zeros(poses.shape[0] + 1)


class Column(Delegating):
    def log_likelihood(self, poses, observations, out=None):
        return np.zeros((poses.shape[0], 1))


class Integers(Delegating):
    def log_likelihood(self, poses, observations, out=None):
        return np.zeros(poses.shape[0], dtype=np.int64)


class MutatesPoses(Delegating):
    def log_likelihood(self, poses, observations, out=None):
        poses[:, 2] = wrap_angles(poses[:, 2] + 0.1)  # "normalizes" the headings it was given
        return super().log_likelihood(poses, observations, out)


class Noisy(Delegating):
    def log_likelihood(self, poses, observations, out=None):
        return super().log_likelihood(poses, observations, out) + np.random.default_rng().normal(size=poses.shape[0])


class Accumulates(Delegating):
    """Adds into `out` without clearing it first."""

    def log_likelihood(self, poses, observations, out=None):
        out = np.zeros(poses.shape[0]) if out is None else out
        out += self.inner.log_likelihood(poses, observations)
        return out


class NoOut(Delegating):
    def log_likelihood(self, poses, observations):
        return self.inner.log_likelihood(poses, observations)


class NegativeTerms(Delegating):
    def terms(self, observations):
        return -1


class FloatTerms(Delegating):
    def terms(self, observations):
        return 1.5


class KeyErrorCheck(Delegating):
    def check(self, observations):
        if len(observations) > 2:
            raise KeyError("too many")


class RefusesEveryFrame(Delegating):
    def check(self, observations):
        raise ValueError("blind")


class Positive(Delegating):
    def log_likelihood(self, poses, observations, out=None):
        return np.ones(poses.shape[0])


def test_good_sensor_models_pass():
    report = mt.check_sensor_model(SENSOR, FIELD, bound=lambda z: SENSOR.terms(z) * math.log(2.0), max_examples=15)
    assert report.examples >= 15 and report.accepted >= 15
    mt.check_sensor_model(Delegating(), FIELD, max_examples=FEW)
    mt.check_sensor_model(MinusInf(), FIELD, allow_neg_inf=True, max_examples=FEW)


@pytest.mark.parametrize(
    "model, kwargs, match",
    [
        (NaNOutput(), {}, r"log_likelihood gave nan for poses\[0\]"),
        (PlusInf(), {}, r"log_likelihood gave inf .* must be finite"),
        (MinusInf(), {}, r"log_likelihood gave -inf .* must be finite\n"),
        (OneTooMany(), {}, r"returned shape \(\d+,\) for \d+ poses"),
        (Column(), {}, r"returned shape \(\d+, 1\)"),
        (Integers(), {}, r"returned dtype int64; must be floats"),
        (MutatesPoses(), {}, r"log_likelihood changed its input: poses"),
        (Noisy(), {}, r"different results for the same input"),
        (Accumulates(), {}, r"log_likelihood gave nan"),
        (NoOut(), {}, r"the filter passes `out=`"),
        (NegativeTerms(), {}, r"terms returned -1, not >= 0"),
        (FloatTerms(), {}, r"terms returned 1.5 \(float\), not an int"),
        (KeyErrorCheck(), {}, r"check raised KeyError.*must raise ValueError or TypeError"),
        (RefusesEveryFrame(), {}, r"refused all \d+ frames drawn"),
        (Positive(), dict(bound=0.0), r"log_likelihood gave 1.0 .* above the bound 0.0"),
    ],
)
def test_broken_sensor_models_fail(model, kwargs, match):
    with pytest.raises(AssertionError, match=match):
        mt.check_sensor_model(model, FIELD, max_examples=FEW, shrink=False, **kwargs)
