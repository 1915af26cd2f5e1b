"""How much a detection tells the quality, and what the mirror image does to it: the chance that a pose anywhere
explains a detection (`LandmarkSensorModel.chance_explained`), the surprise weighed by it
(`QualityThresholds.surprise_after`), the particles on the estimate's mirror image, and a jump there."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from field import LandmarkType, spl
from mcl.localizer import Localizer, Quality, QualityThresholds
from motion_models import MotionInput
from sensing import LandmarkObservation as Seen
from sensing import LandmarkSensorModel
from sensing.observations import Observations

FIELD = spl()
MODEL = LandmarkSensorModel(FIELD)
X0, X1, Y0, Y1 = FIELD.carpet
CARPET = (X1 - X0) * (Y1 - Y0)
FRAME = [Seen("penalty_mark", 1.2, 0.0), Seen("goalpost", 2.65, 0.31), Seen("goalpost", 2.65, -0.31)]


def one(kind: str, r: float) -> Observations:
    return Observations.coerce([Seen(kind, r, 0.1)])


# -- the chance a pose anywhere explains a detection ------------------------------------------------------------
def test_the_chance_is_the_gate_ellipses_of_the_type_over_the_area():
    r, gate, range_slack, bearing_slack = 2.0, 3.0, 0.1, 0.03
    posts = MODEL.candidates(LandmarkType.GOALPOST).shape[0]
    sigma_r = float(MODEL.range_sigma(np.array([r]))[0]) + range_slack
    sigma_b = MODEL.bearing_sigma + bearing_slack
    expected = posts * math.pi * gate**2 * sigma_r * sigma_b * r / CARPET
    got = MODEL.chance_explained(one("goalpost", r), CARPET, gate, range_slack, bearing_slack)
    assert got.shape == (1,)
    assert got[0] == pytest.approx(expected, rel=1e-12)


@given(st.floats(0.0, 12.0), st.floats(0.0, 12.0), st.sampled_from(["goalpost", "penalty_mark", "l_crossing"]))
def test_the_chance_lies_within_0_1_and_grows_with_the_range(a, b, kind):
    near, far = sorted((a, b))
    chances = MODEL.chance_explained(Observations.coerce([Seen(kind, near, 0.0), Seen(kind, far, 0.0)]), CARPET)
    assert np.all((chances >= 0.0) & (chances <= 1.0))
    assert chances[0] <= chances[1]


@pytest.mark.parametrize("area", [0.0, -1.0, math.nan, math.inf])
def test_the_chance_refuses_an_area_that_is_not_a_positive_number(area):
    with pytest.raises(ValueError, match="area"):
        MODEL.chance_explained(one("goalpost", 2.0), area)


def test_the_chance_refuses_an_area_that_is_not_a_number():
    with pytest.raises(TypeError, match="area"):
        MODEL.chance_explained(one("goalpost", 2.0), "77")  # type: ignore[arg-type]


# -- the surprise weighed by it ----------------------------------------------------------------------------------
Q = QualityThresholds()


@given(
    st.floats(0.0, Q.surprise_cap),
    st.lists(st.tuples(st.booleans(), st.floats(0.0, Q.wrong_rate)), min_size=1, max_size=12),
)
def test_detections_any_pose_rarely_explains_weigh_as_the_fixed_rates_say(surprise, detections):
    explained = np.array([e for e, _ in detections])
    chances = np.array([c for _, c in detections])
    fixed = Q.next_surprise(surprise, len(detections), int(explained.sum()))
    assert Q.surprise_after(surprise, explained, chances) == pytest.approx(fixed, abs=1e-9)


@given(
    st.floats(0.0, Q.surprise_cap), st.lists(st.booleans(), min_size=1, max_size=12), st.floats(Q.explained_rate, 1.0)
)
def test_a_detection_any_pose_explains_leaves_the_surprise_as_it_was(surprise, explained, chance):
    chances = np.full(len(explained), chance)
    assert Q.surprise_after(surprise, np.array(explained), chances) == pytest.approx(surprise, abs=1e-12)


@given(st.floats(0.0, Q.surprise_cap), st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_the_more_likely_a_wrong_pose_explains_it_the_less_a_detection_moves_the_surprise(surprise, a, b):
    low, high = sorted((a, b))
    for seen in (True, False):
        move_low = abs(Q.surprise_after(surprise, np.array([seen]), np.array([low])) - surprise)
        move_high = abs(Q.surprise_after(surprise, np.array([seen]), np.array([high])) - surprise)
        assert move_high <= move_low + 1e-12


@pytest.mark.parametrize(
    "surprise, explained, chances",
    [
        (0.0, [True], [0.1, 0.2]),  # one entry per detection each
        (0.0, [True], [1.5]),
        (0.0, [False], [math.nan]),
        (-1.0, [True], [0.1]),
        (Q.surprise_cap + 1.0, [True], [0.1]),
    ],
)
def test_the_weighed_surprise_refuses_what_does_not_fit(surprise, explained, chances):
    with pytest.raises(ValueError):
        Q.surprise_after(surprise, np.array(explained), np.array(chances))


# -- the mirror image ----------------------------------------------------------------------------------------------
def sure_of_its_pose() -> Localizer:
    """Placed facing its own goal, it sees the penalty mark and both goalposts for 0.9 s."""
    loc = Localizer(FIELD, n_particles=300, seed=3)
    loc.manual_placement([(-2.0, 0.0, math.pi)])
    loc.motion(1.0, MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
    for k in range(30):
        t = 1.0 + 0.03 * (k + 1)
        for j in range(3):
            loc.motion(t - 0.03 + 0.01 * (j + 1), MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
        loc.observe(FRAME, capture_time=t)
    return loc


def split_with_the_mirror(loc: Localizer, share: float) -> None:
    """Move `share` of the particles to their point images (-x, -y, θ + π), all weights equal."""
    poses = loc.filter.poses.copy()
    moved = np.arange(poses.shape[0]) < round(share * poses.shape[0])
    poses[moved] = FIELD.mirror_poses(poses[moved])
    loc.filter.set_particles(poses, np.full(poses.shape[0], 1.0 / poses.shape[0]))
    loc._quality = None


def test_particles_split_with_the_mirror_image_leave_the_pose_unsure_of_its_half_not_poor():
    loc = sure_of_its_pose()
    assert loc.quality() in (Quality.SUPERB, Quality.OKAY)
    split_with_the_mirror(loc, 0.45)
    assert loc.filter.estimate().weight < loc.thresholds.okay_weight  # the cluster alone would be POOR
    assert loc.quality() is Quality.UNSURE_HALF
    assert not loc.is_lost


def test_a_few_particles_on_the_mirror_image_cap_the_side_odds_the_quality_reads():
    loc = sure_of_its_pose()
    split_with_the_mirror(loc, 0.0)
    assert loc.quality() is Quality.SUPERB
    # 1 - 0.095 of the weight holds the superb limit (0.9), but 9.5:1 for the pose is less than SUPERB's 10:1
    split_with_the_mirror(loc, 0.095)
    assert loc.filter.estimate().weight >= loc.thresholds.superb_weight
    assert loc.quality() is Quality.OKAY


@pytest.mark.parametrize("where, starts", [("mirror", False), ("elsewhere", True)])
def test_a_jump_to_the_mirror_image_starts_no_new_track_for_the_rivals(monkeypatch, where, starts):
    loc = sure_of_its_pose()
    calls = []
    monkeypatch.setattr(loc.rivals, "new_track", lambda *args, **kwargs: calls.append(args))
    jumps = loc.jumps
    poses = loc.filter.poses.copy()
    if where == "mirror":
        poses = FIELD.mirror_poses(poses)
    else:
        poses[:, 1] += 1.5
    loc.filter.set_particles(poses, loc.filter.weights.copy())
    loc.motion(2.0, MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
    loc.observe([], capture_time=2.0)
    assert loc.jumps == jumps + 1
    assert bool(calls) is starts
