"""The camera's view and negative information: `sensing.view.CameraView`, `LandmarkSensorModel.seen` and the
localizer's quality when frames come with their view."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from field import LandmarkType, spl
from field.checks import ArgumentTypeError
from mcl.localizer import Localizer, Quality, QualityThresholds
from motion_models import MotionInput
from sensing import LandmarkSensorModel, Observations
from sensing.view import CameraView

FIELD = spl()
SENSOR = LandmarkSensorModel(FIELD)
KINDS = tuple(LandmarkType)


def detections(pose, view: CameraView, keep=1.0, noise=None, rng=None):
    """What a camera at `pose` reports: the landmarks inside `view`, each kept with probability `keep`."""
    rng = rng or np.random.default_rng(0)
    rows = []
    for kind in KINDS:
        for target in FIELD.landmarks_of(kind):
            d = target - pose[:2]
            r = math.hypot(*d)
            b = math.remainder(math.atan2(d[1], d[0]) - pose[2], 2 * math.pi)
            if (
                view.min_range <= r <= view.range_of(kind)
                and abs(math.remainder(b - view.yaw, 2 * math.pi)) <= view.half_fov
                and rng.random() < keep
            ):
                if noise is not None:
                    r += noise[0] * rng.standard_normal()
                    b += noise[1] * rng.standard_normal()
                rows.append((kind, r, b))
    return Observations.from_arrays(*zip(*rows)) if rows else Observations.empty()


# -- CameraView -----------------------------------------------------------------------------------------------
def test_a_view_wraps_its_yaw_and_insets_within_itself():
    view = CameraView(yaw=2 * math.pi + 0.25, half_fov=0.5, max_range=6.0, min_range=0.4)
    assert view.yaw == pytest.approx(0.25)
    inner = view.inset(0.8)
    assert inner.yaw == view.yaw and inner.half_fov == pytest.approx(0.4)
    assert view.min_range < inner.min_range < inner.max_range < view.max_range
    assert view.inset(1.0) == view


@pytest.mark.parametrize(
    "arguments",
    [
        dict(yaw=math.nan, half_fov=0.5, max_range=5.0),
        dict(yaw=0.0, half_fov=0.0, max_range=5.0),
        dict(yaw=0.0, half_fov=4.0, max_range=5.0),
        dict(yaw=0.0, half_fov=0.5, max_range=0.0),
        dict(yaw=0.0, half_fov=0.5, max_range=5.0, min_range=5.0),
        dict(yaw=0.0, half_fov=0.5, max_range=2e3),
        dict(yaw=1e3, half_fov=0.5, max_range=5.0),
        dict(yaw=0.0, half_fov=0.5, max_range=5.0, min_range=-1.0),
    ],
)
def test_a_bad_view_is_refused_naming_the_value(arguments):
    with pytest.raises(ValueError) as error:
        CameraView(**arguments)
    assert any(name in str(error.value) for name in arguments)


def test_a_view_of_the_wrong_type_is_refused_as_a_type_error():
    with pytest.raises(ArgumentTypeError, match="half_fov"):
        CameraView(0.0, "wide", 5.0)
    with pytest.raises(ValueError, match="share"):
        CameraView(0.0, 0.5, 5.0).inset(0.0)


# -- a farthest range per landmark type -------------------------------------------------------------------------
def test_a_range_per_type_parses_its_keys_and_fills_the_others():
    view = CameraView(0.0, 0.5, {LandmarkType.GOALPOST: 8.0, "penalty mark": 3, 3: 4.5, "T": 5.0}, 0.2)
    assert view.per_type and view.max_range == (8.0, 8.0, 5.0, 4.5, 3.0, 8.0)  # unnamed: the largest given
    assert view.range_of("post") == 8.0 and view.range_of(LandmarkType.X_CROSSING) == 4.5
    assert view.max_ranges.tolist() == list(view.max_range) and not view.max_ranges.flags.writeable
    others = CameraView(0.0, 0.5, {"goalpost": 8.0, "others": 4.0})
    assert others.max_range == (8.0, 4.0, 4.0, 4.0, 4.0, 4.0)
    assert CameraView(0.0, 0.5, others.max_range) == others  # the tuple it keeps is taken back
    assert hash(others) == hash(CameraView(0.0, 0.5, {"others": 4.0, LandmarkType.GOALPOST: 8}))
    plain = CameraView(0.0, 0.5, 6.0)
    assert not plain.per_type and plain.max_range == 6.0 and plain.range_of("X") == 6.0
    assert plain.max_ranges.tolist() == 6 * [6.0]


def test_a_view_with_ranges_per_type_insets_each_within_itself():
    view = CameraView(0.3, 0.6, {"goalpost": 8.0, "others": 4.0}, 0.4)
    inner = view.inset(0.8)
    assert inner.half_fov == pytest.approx(0.48) and inner.yaw == view.yaw
    assert inner.max_range == pytest.approx((8.0 - 0.76, *(5 * [4.0 - 0.36])))  # 10 % of each span
    assert inner.min_range == pytest.approx(0.4 + 0.36)  # 10 % of the shortest span
    assert view.inset(1.0) == view
    # with every type at one range, the per-type inset is the plain one
    same = CameraView(0.3, 0.6, {"others": 6.0}, 0.4).inset(0.7)
    plain = CameraView(0.3, 0.6, 6.0, 0.4).inset(0.7)
    assert same.max_range == 6 * (plain.max_range,) and same.min_range == plain.min_range


@pytest.mark.parametrize(
    "max_range,match",
    [
        ({}, "at least one"),
        ({"goalpost": 0.0}, r"max_range\['goalpost'\] = 0.0"),
        ({"post": 5.0, "goalpost": 6.0}, "goalpost twice"),
        ({"corner": 5.0}, "max_range key 'corner'"),
        ({9: 5.0}, "max_range key 9"),
        ({"goalpost": math.inf}, "goalpost"),
        ({"others": -1.0}, "others"),
        ((5.0, 4.0), "6 ranges"),
        ((5.0, 4.0, 4.0, 4.0, 4.0, 2e3), r"max_range\[center_mark\]"),
    ],
)
def test_bad_ranges_per_type_are_refused_naming_the_key_and_value(max_range, match):
    with pytest.raises(ValueError, match=match):
        CameraView(0.0, 0.5, max_range)


def test_ranges_per_type_of_the_wrong_type_are_type_errors_and_the_nearest_is_below_every_farthest():
    for bad in ({"goalpost": "far"}, {2.5: 4.0}, {None: 4.0}, [5.0, 4.0], "far", None):
        with pytest.raises(ArgumentTypeError, match="max_range"):
            CameraView(0.0, 0.5, bad)
    with pytest.raises(ValueError, match="min_range = 3.0"):
        CameraView(0.0, 0.5, {"goalpost": 8.0, "others": 2.5}, 3.0)


def test_a_range_per_type_decides_which_landmarks_are_expected():
    """A goalpost 6 m ahead is expected in view with {goalpost: 8, others: 4} (9 m ahead it is not); a penalty
    mark 6 m ahead is not, but is with a range of 6.5 m for penalty marks or one range of 8 m; the kernel and its
    numpy twin agree."""
    model = LandmarkSensorModel(FIELD)
    table, offsets = model.landmark_table
    post = table[offsets[LandmarkType.GOALPOST]]
    # a pose 6 m from the goalpost, looking at it, 6 m from nothing else of the field within a narrow view
    for distance, expect_post in ((6.0, True), (9.0, False)):
        pose = np.array([post[0] - distance, post[1], 0.0])
        view = CameraView(0.0, 0.05, {"goalpost": 8.0, "others": 4.0})
        assert model.seen(pose, Observations.empty(), view) == (int(expect_post), 0)
        assert model.numpy_twin().seen(pose, Observations.empty(), view) == (int(expect_post), 0)
    mark = table[offsets[LandmarkType.PENALTY_MARK]]
    pose = np.array([mark[0], mark[1] + 6.0, -math.pi / 2])  # beside the field, looking at the mark alone
    for view, expected in (
        (CameraView(0.0, 0.05, {"goalpost": 8.0, "others": 4.0}), 0),
        (CameraView(0.0, 0.05, {"goalpost": 8.0, "penalty_mark": 6.5}), 1),
        (CameraView(0.0, 0.05, 8.0), 1),
    ):
        assert model.seen(pose, Observations.empty(), view)[0] == expected
        assert model.numpy_twin().seen(pose, Observations.empty(), view)[0] == expected


ranges_per_type = st.fixed_dictionaries({}, optional={kind.name.lower(): st.floats(1.0, 9.0) for kind in KINDS}).filter(
    bool
)


# -- seen: the kernel, its twin, and what it says -----------------------------------------------------------
poses_on_field = st.tuples(st.floats(-4.5, 4.5), st.floats(-3.0, 3.0), st.floats(-math.pi, math.pi))


@settings(max_examples=60, deadline=None)
@given(
    pose=poses_on_field,
    yaw=st.floats(-1.2, 1.2),
    half_fov=st.floats(0.2, 1.6),
    seed=st.integers(0, 2**32 - 1),
    ranges=ranges_per_type,
    others=st.one_of(st.none(), st.floats(1.0, 9.0)),
    keep=st.floats(0.0, 1.0),
    rate=st.sampled_from([0.0, 0.3]),
)
def test_with_ranges_per_type_the_kernels_equal_their_numpy_twins(
    pose, yaw, half_fov, seed, ranges, others, keep, rate
):
    rng = np.random.default_rng(seed)
    model = LandmarkSensorModel(FIELD, detection_rate=rate)
    view = CameraView(yaw, half_fov, ranges if others is None else {**ranges, "others": others}, 0.3)
    observations = detections(np.array(pose), view, keep, noise=(0.1, 0.05), rng=rng).with_view(view)
    for at in (np.array(pose), np.array(pose) + rng.normal(0, 0.4, 3)):
        assert model.seen(at, observations, view, 2.5, 0.1, 0.03) == model.numpy_twin().seen(
            at, observations, view, 2.5, 0.1, 0.03
        )
    poses = np.array(pose) + rng.normal(0, 0.5, (30, 3))
    np.testing.assert_allclose(
        model.log_likelihood(poses, observations),
        model.numpy_twin().log_likelihood(poses, observations),
        rtol=1e-9,
        atol=1e-9,
    )


def test_one_range_and_the_same_range_for_every_type_score_the_same_bits():
    pose = np.array([-1.5, 0.5, 0.2])
    plain = CameraView(0.2, 0.6, 6.5, 0.3)
    every = CameraView(0.2, 0.6, {"others": 6.5}, 0.3)
    observations = detections(pose, plain, keep=0.6, rng=np.random.default_rng(2))
    poses = pose + np.random.default_rng(3).normal(0, 0.6, (200, 3))
    model = LandmarkSensorModel(FIELD, detection_rate=0.3)
    assert (
        model.log_likelihood(poses, observations.with_view(plain)).tobytes()
        == model.log_likelihood(poses, observations.with_view(every)).tobytes()
    )


@settings(max_examples=80, deadline=None)
@given(
    pose=poses_on_field,
    yaw=st.floats(-1.2, 1.2),
    half_fov=st.floats(0.2, 1.6),
    seed=st.integers(0, 2**32 - 1),
    linear=st.sampled_from([0.0, 0.05]),
    keep=st.floats(0.0, 1.0),
)
def test_seen_equals_its_numpy_twin_and_stays_within_its_bounds(pose, yaw, half_fov, seed, linear, keep):
    rng = np.random.default_rng(seed)
    model = LandmarkSensorModel(FIELD, range_noise_linear=linear)
    pose = np.array(pose)
    view = CameraView(yaw, half_fov, float(rng.uniform(3.0, 9.0)), float(rng.uniform(0.0, 0.5)))
    observations = detections(pose, view, keep, noise=(0.1, 0.05), rng=rng)
    probe = pose + rng.normal(0, 0.4, 3)
    for at in (pose, probe):
        expected, seen = model.seen(at, observations, view, 2.5, 0.1, 0.03)
        assert (expected, seen) == model.numpy_twin().seen(at, observations, view, 2.5, 0.1, 0.03)
        assert 0 <= seen <= expected <= model.landmark_table[0].shape[0]


def test_the_true_pose_sees_what_it_expects_and_a_wrong_one_does_not():
    pose = np.array([-1.5, 0.5, 0.2])
    view = CameraView(0.3, math.radians(45), 7.0, 0.3)
    observations = detections(pose, view)
    expected, seen = SENSOR.seen(pose, observations, view)
    assert expected >= 4 and seen == expected
    # the same frame scored 1.2 m and 40° away: landmarks expected in view were not reported
    expected_away, seen_away = SENSOR.seen(pose + np.array([1.2, -0.8, 0.7]), observations, view)
    assert expected_away >= 3 and seen_away / expected_away < 0.5
    # nothing reported: nothing seen
    assert SENSOR.seen(pose, Observations.empty(), view) == (expected, 0)


def test_seen_refuses_what_is_not_a_view():
    with pytest.raises(ArgumentTypeError, match="view"):
        SENSOR.seen((0.0, 0.0, 0.0), Observations.empty(), (0.0, 0.5, 5.0))


# -- the localizer ------------------------------------------------------------------------------------------------
def tracking_localizer(pose, frames=40, view=None, keep=1.0):
    loc = Localizer(FIELD, n_particles=300, seed=3)
    loc.place(pose)
    for k in range(frames):
        t = 0.04 * (k + 1)
        loc.motion(t, MotionInput(0.04, odometry=(0.0, 0.0, 0.0)))
        v = view or CameraView(0.3 * math.sin(k / 3), math.radians(35), 7.0, 0.3)
        loc.observe(detections(pose, v, keep, rng=np.random.default_rng(k)), capture_time=t, view=v)
    return loc


def test_frames_with_their_view_keep_a_right_estimate_superb():
    loc = tracking_localizer(np.array([-2.0, 1.0, 0.3]))
    assert loc.seen_share > 0.9
    assert loc.quality() is Quality.SUPERB and not loc.is_lost


def test_a_pose_that_explains_the_detections_but_misses_what_it_should_see_is_poor_then_lost():
    """Aliasing: the frames report only the landmarks a wrong pose can also explain (one crossing at a time);
    the view says the estimate should have seen more, so the quality falls to POOR and is_lost follows."""
    pose = np.array([-2.0, 1.0, 0.3])
    loc = tracking_localizer(pose)
    t = loc.time
    view = CameraView(0.0, math.radians(35), 7.0, 0.3)
    full = detections(pose, view)
    assert len(full) >= 3
    for _ in range(60):  # 2.4 s of frames that report one landmark of the view's several
        t += 0.04
        loc.motion(t, MotionInput(0.04, odometry=(0.0, 0.0, 0.0)))
        one = Observations.from_arrays(full.kinds[:1], full.ranges[:1], full.bearings[:1])
        loc.observe(one, capture_time=t, view=view)
    assert loc.fit > 0.9  # each detection still fits ...
    assert loc.seen_share < 0.4  # ... but most of what should be seen is not
    assert loc.quality() is Quality.POOR and loc.is_lost


def test_without_views_the_quality_is_what_it_was():
    """The same frames without their view: no negative information, and the seen share is NaN."""
    pose = np.array([-2.0, 1.0, 0.3])
    loc = Localizer(FIELD, n_particles=300, seed=3)
    loc.place(pose)
    view = CameraView(0.0, math.radians(35), 7.0, 0.3)
    full = detections(pose, view)
    one = Observations.from_arrays(full.kinds[:1], full.ranges[:1], full.bearings[:1])
    for k in range(60):
        t = 0.04 * (k + 1)
        loc.motion(t, MotionInput(0.04, odometry=(0.0, 0.0, 0.0)))
        loc.observe(one, capture_time=t)
    assert math.isnan(loc.seen_share)
    assert loc.quality() is not Quality.POOR


def test_a_refused_view_changes_nothing():
    loc = tracking_localizer(np.array([-2.0, 1.0, 0.3]), frames=10)
    before = (loc.filter.poses.copy(), loc.filter.weights.copy(), list(loc._frames), loc.quality())
    observations = detections(np.array([-2.0, 1.0, 0.3]), CameraView(0.0, 0.6, 7.0))
    for bad in ((0.0, 0.6, 7.0), "view", 3.0):
        with pytest.raises(ArgumentTypeError, match="view"):
            loc.observe(observations, capture_time=loc.time, view=bad)
    np.testing.assert_array_equal(before[0], loc.filter.poses)
    np.testing.assert_array_equal(before[1], loc.filter.weights)
    assert list(loc._frames) == before[2] and loc.quality() is before[3]


def test_the_seen_thresholds_are_checked():
    with pytest.raises(ValueError, match="okay_seen"):
        QualityThresholds(okay_seen=1.5)
    with pytest.raises(ValueError, match="view_inset"):
        QualityThresholds(view_inset=0.0)


# -- negative information in the likelihood ---------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(
    pose=poses_on_field,
    yaw=st.floats(-1.2, 1.2),
    seed=st.integers(0, 2**32 - 1),
    keep=st.floats(0.2, 1.0),
    rate=st.sampled_from([0.0, 0.3, 0.9]),
    mixture=st.sampled_from(["max", "sum"]),
)
def test_the_likelihood_with_a_view_equals_its_numpy_twin(pose, yaw, seed, keep, rate, mixture):
    rng = np.random.default_rng(seed)
    model = LandmarkSensorModel(FIELD, detection_rate=rate, mixture=mixture)
    view = CameraView(yaw, 0.6, 7.0, 0.3)
    observations = detections(np.array(pose), view, keep, noise=(0.1, 0.05), rng=rng).with_view(view)
    poses = np.array(pose) + rng.normal(0, 0.5, (40, 3))
    np.testing.assert_allclose(
        model.log_likelihood(poses, observations),
        model.numpy_twin().log_likelihood(poses, observations),
        rtol=1e-9,
        atol=1e-9,
    )
    missed = model.numpy_twin().missed_in_view(poses, observations)
    assert (missed <= 0).all() and np.isfinite(missed).all()
    if rate == 0.0 or len(observations) == 0:
        assert not missed.any()


def test_without_a_view_the_likelihood_is_what_it_was():
    pose = np.array([-1.0, 0.5, 0.3])
    view = CameraView(0.0, 0.6, 7.0, 0.3)
    observations = detections(pose, view)
    poses = pose + np.random.default_rng(1).normal(0, 0.5, (30, 3))
    np.testing.assert_array_equal(
        SENSOR.log_likelihood(poses, observations), SENSOR.log_likelihood(poses, observations.with_view(None))
    )
    assert not SENSOR.scores_view(observations) and SENSOR.scores_view(observations.with_view(view))
    assert not SENSOR.scores_view(Observations.empty().with_view(view))  # a blind frame says nothing


def test_a_pose_that_should_have_seen_more_is_less_likely():
    """Two poses explain the one reported crossing equally well; the one that puts more unreported landmarks in
    view scores lower by log(1 - detection_rate) per landmark."""
    pose = np.array([-2.0, 1.0, 0.3])
    view = CameraView(0.0, math.radians(35), 7.0, 0.3)
    full = detections(pose, view)
    one = Observations.from_arrays(full.kinds[:1], full.ranges[:1], full.bearings[:1]).with_view(view)
    missed = SENSOR.numpy_twin().missed_in_view(pose[None], one)[0]
    expected, seen = SENSOR.seen(pose, one, view.inset(SENSOR.view_inset), 3.0, 0.1, 0.03)
    assert expected - seen >= 2 and seen <= 1
    assert missed == pytest.approx((expected - seen) * math.log(1 - SENSOR.detection_rate), abs=1e-12)
    base = SENSOR.log_likelihood(pose[None], one.with_view(None))[0]
    assert SENSOR.log_likelihood(pose[None], one)[0] == pytest.approx(base + missed)


def test_with_view_shares_the_arrays_and_refuses_what_is_not_a_view():
    observations = detections(np.array([-2.0, 1.0, 0.3]), CameraView(0.0, 0.6, 7.0))
    view = CameraView(0.1, 0.5, 6.0)
    with_view = observations.with_view(view)
    assert with_view.view is view and with_view.kinds is observations.kinds and observations.view is None
    assert with_view.with_view(view) is with_view
    with pytest.raises(ArgumentTypeError, match="view"):
        observations.with_view((0.1, 0.5, 6.0))
    with pytest.raises(ArgumentTypeError, match="view"):
        Observations(
            observations.kinds,
            observations.ranges,
            observations.bearings,
            observations.range_sigmas,
            observations.bearing_sigmas,
            None,
            "wide",
        )
    with pytest.raises(ValueError, match="detection_rate"):
        LandmarkSensorModel(FIELD, detection_rate=1.0)


def test_the_filter_scores_a_frame_with_a_view_as_the_plain_calls_do():
    """A frame with a view goes through the model's log_likelihood: the filter's weights equal the plain
    sequence (log_likelihood, then normalize) for the same particles."""
    from mcl import ParticleFilter
    from motion_models import VelocityLinear

    pose = np.array([-2.0, 1.0, 0.3])
    view = CameraView(0.2, 0.6, 7.0, 0.3)
    observations = detections(pose, view, keep=0.6, rng=np.random.default_rng(4)).with_view(view)
    pf = ParticleFilter(
        FIELD, VelocityLinear(), SENSOR, n_particles=200, seed=5, augmented=None, resample_threshold=0.0
    )
    pf.reset_around(pose, (0.5, 0.5, 0.5))
    poses = pf.poses.copy()
    pf.correct(observations)
    expected = SENSOR.numpy_twin().log_likelihood(poses, observations)
    expected = np.exp(expected - expected.max())
    np.testing.assert_allclose(pf.weights, expected / expected.sum(), rtol=1e-9, atol=1e-15)


def test_dead_reckoning_far_without_an_explained_detection_is_no_longer_okay():
    """A blind stretch (frames without detections): standing still the estimate stays usable; after walking
    more than `okay_walked` metres on odometry alone it is POOR, and lost a second later."""
    for walk, expected in ((0.0, Quality.OKAY), (0.05, Quality.POOR)):
        loc = tracking_localizer(np.array([-2.0, 1.0, 0.0]))
        t = loc.time
        for _ in range(100):  # 4 s; 5 m when walking
            t += 0.04
            loc.motion(t, MotionInput(0.04, odometry=(walk, 0.0, 0.0)))
            loc.observe(Observations.empty(), capture_time=t)
        assert loc.quality() is expected
        assert loc.is_lost == (expected is Quality.POOR)
