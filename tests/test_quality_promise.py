"""The quality's two fast guards: the surprise (a change detector on explained detections) and the cap on side
odds after an unseen move (`SoccerRelocalization.jumped`, `SideSettings.jump_cap`)."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from field import LandmarkType, spl
from mcl import Estimate
from mcl.localizer import Localizer, Quality, QualityThresholds
from mcl.relocalization import RelocalizationPrior, SoccerRelocalization
from mcl.side import SideBelief, SideSettings
from motion_models import MotionInput
from sensing import Observations

FIELD = spl()
DEFAULT = QualityThresholds()
frames = st.lists(st.integers(0, 12).flatmap(lambda m: st.tuples(st.just(m), st.integers(0, m))), max_size=60)


# -- the surprise ----------------------------------------------------------------------------------------------
@given(frames)
def test_the_surprise_stays_within_its_bounds_and_is_the_cusum_of_its_frames(sequence):
    unexplained, explained_step = DEFAULT.surprise_steps
    surprise = 0.0
    for m, c in sequence:
        after = DEFAULT.next_surprise(surprise, m, c)
        assert 0.0 <= after <= DEFAULT.surprise_cap and math.isfinite(after)
        expected = min(max(0.0, surprise + ((m - c) * unexplained - c * explained_step)), DEFAULT.surprise_cap)
        assert after == expected
        if c == m:  # a frame the estimate explains whole never raises it
            assert after <= surprise
        surprise = after


@given(frames, st.integers(1, 12), st.integers(0, 12))
def test_more_explained_detections_never_leave_more_surprise(sequence, m, c):
    surprise = 0.0
    for frame in sequence:
        surprise = DEFAULT.next_surprise(surprise, *frame)
    c = min(c, m - 1)
    assert DEFAULT.next_surprise(surprise, m, c + 1) <= DEFAULT.next_surprise(surprise, m, c)


def test_the_rates_and_the_frame_are_checked():
    for rates in ({"wrong_rate": 0.95}, {"explained_rate": 1.0}, {"wrong_rate": 0.0}, {"explained_rate": 0.2}):
        with pytest.raises(ValueError, match="wrong_rate"):
            QualityThresholds(**rates)
    with pytest.raises(ValueError, match="explained"):
        DEFAULT.next_surprise(0.0, 2, 3)
    with pytest.raises(ValueError, match="surprise"):
        DEFAULT.next_surprise(-1.0, 2, 1)


KINDS = tuple(LandmarkType)
PAN = [math.radians(a) for a in (-40, -20, 0, 20, 40, 20, 0, -20)]


def _frame(pose, k: int = 2, max_range: float = 5.0) -> Observations:
    """The landmarks a camera on the robot at `pose` sees, its head panned by PAN[k], exact, in the robot
    frame."""
    pan = PAN[k % len(PAN)]
    rows = []
    for kind in KINDS:
        for target in FIELD.landmarks_of(kind):
            r = math.hypot(target[0] - pose[0], target[1] - pose[1])
            b = math.remainder(math.atan2(target[1] - pose[1], target[0] - pose[0]) - pose[2], 2 * math.pi)
            if 0.3 < r < max_range and abs(math.remainder(b - pan, 2 * math.pi)) < math.radians(35):
                rows.append((kind, r, b))
    return Observations.from_arrays(*zip(*rows)) if rows else Observations.empty()


def _stand(loc: Localizer, t: float, pose, frames: int) -> float:
    for k in range(frames):
        t += 1 / 30
        loc.motion(t, MotionInput(dt=1 / 30, command=(0.0, 0.0, 0.0)))
        loc.observe(_frame(pose, k))
    return t


def test_superb_ends_within_two_frames_of_a_kidnapping_that_the_window_fit_would_hide():
    """Tracking SUPERB at a pose, then carried 2 m unseen: the detections of the new place stop fitting, and
    the quality leaves SUPERB (and OKAY) within two frames, while the 1.5 s fit still holds most of the old
    explained detections."""
    truth = np.array([-2.0, -1.0, 0.3])
    loc = Localizer(FIELD, n_particles=300, seed=3)
    loc.place(truth, sigma=(0.02, 0.02, 0.02))
    loc.filter.augmented = None  # the estimate stays where it was: what the quality says of it is the question
    t = _stand(loc, 0.0, truth, 45)  # 1.5 s at 30 Hz
    assert loc.quality() is Quality.SUPERB and loc.surprise == 0.0
    carried = truth + np.array([1.5, 1.4, 0.0])
    qualities = []
    for _ in range(2):
        t = _stand(loc, t, carried, 1)
        qualities.append(loc.quality())
    assert loc.fit > DEFAULT.superb_fit  # the window alone would still say SUPERB
    assert qualities[-1] not in (Quality.SUPERB, Quality.OKAY), qualities
    assert loc.surprise > DEFAULT.okay_surprise
    loc.place(carried)
    assert loc.surprise == 0.0


# -- side odds after an unseen move ----------------------------------------------------------------------------
def _relocalization_after_a_jump(to) -> SoccerRelocalization:
    relocalization = SoccerRelocalization()
    relocalization.bind((-5.2, 5.2, -3.7, 3.7))
    relocalization.reset_pose((-3.0, -2.0, 0.0))
    confident = Estimate(np.asarray(to, dtype=float), np.diag([1e-3, 1e-3, 1e-3]), 1.0)
    for _ in range(RelocalizationPrior().jump_corrections):
        relocalization.confirm(confident, True)
    return relocalization


def test_a_jump_is_remembered_until_the_next_reset_and_a_drift_is_not_a_jump():
    near = _relocalization_after_a_jump((-2.95, -2.0, 0.0))  # within the anchor's drift
    assert not near.jumped and near.relocalizations == 0
    # 1.5 m away, its mirror image 6 m away: not a kidnapping-law tie, but a jump
    far = _relocalization_after_a_jump((-1.8, -1.1, 0.0))
    assert far.jumped and not far.kidnapped and far.relocalizations == 1
    assert far.mirror_log_odds > math.log(3.0)  # the law's own odds would make it OKAY
    far.reset_pose((0.0, 0.0, 0.0))
    assert not far.jumped
    far = _relocalization_after_a_jump((-1.8, -1.1, 0.0))
    far.reset_region((-4.5, 0.0, -3.0, 3.0))
    assert not far.jumped


@given(st.floats(-10, 10), st.booleans(), st.booleans())
def test_the_prior_is_capped_by_what_it_rests_on(prior, kidnapped, jumped):
    settings = SideSettings()
    odds = SideBelief(FIELD, settings).log_odds(prior, kidnapped, jumped)
    cap = settings.kidnap_cap if kidnapped else settings.jump_cap if jumped else settings.prior_cap
    assert abs(odds) <= cap + 1e-12
    assert odds == pytest.approx(min(max(prior, -cap), cap))


def test_jump_cap_lies_between_the_kidnap_cap_and_the_prior_cap():
    for value in (0.5, 3.5, math.nan, math.inf):
        with pytest.raises(ValueError, match="jump_cap"):
            SideSettings(jump_cap=value)
    assert SideSettings(jump_cap=2.0).jump_cap == 2.0
    # the default keeps a guessed law below the odds OKAY asks, so an unseen move alone is UNSURE_HALF
    assert SideSettings().jump_cap < math.log(DEFAULT.okay_mirror_odds)


def test_after_an_unseen_move_without_teammates_the_pose_is_unsure_of_its_half():
    """Carried 1.4 m unseen, its mirror image four times as far from where it was: the filter finds the new
    pose, and without teammates the quality says UNSURE_HALF, not OKAY or SUPERB, however the filter's
    kidnapping law weighs the two."""
    start, carried = np.array([-3.0, -2.0, 0.4]), np.array([-2.2, -0.85, 0.4])
    loc = Localizer(FIELD, n_particles=500, seed=2)
    loc.place(start, sigma=(0.02, 0.02, 0.02))
    t = _stand(loc, 0.0, start, 60)
    assert loc.quality() is Quality.SUPERB
    t = _stand(loc, t, carried, 240)
    relocalization = loc.filter.relocalization
    assert np.hypot(*(loc.pose().pose[:2] - carried[:2])) < 0.3
    assert relocalization.jumped and not relocalization.kidnapped
    assert loc.side_log_odds <= SideSettings().jump_cap
    assert loc.quality() is Quality.UNSURE_HALF
    loc.place(carried)
    assert not relocalization.jumped and loc.quality() is not Quality.UNSURE_HALF


def test_a_pose_found_again_after_the_detections_contradicted_it_no_longer_rests_on_continuity():
    """Tracked near the centre mark, then carried 1.2 m and turned unseen: the detections contradict the
    estimate, it settles on the new pose, whose mirror image is as near to where it was, and its side odds
    are capped as after a jump (`Localizer.moved_unseen`) until the next placement."""
    start, moved = np.array([-0.6, -0.5, 0.2]), np.array([0.4, 0.15, 1.6])
    loc = Localizer(FIELD, n_particles=500, seed=4)
    loc.place(start, sigma=(0.02, 0.02, 0.02))
    t = _stand(loc, 0.0, start, 150)
    assert loc.filter.relocalization.tracking and not loc.moved_unseen
    t = _stand(loc, t, moved, 150)
    assert np.hypot(*(loc.pose().pose[:2] - moved[:2])) < 0.2
    assert loc.moved_unseen
    assert loc.side_log_odds <= SideSettings().jump_cap
    assert loc.quality() is Quality.UNSURE_HALF
    loc.place(moved)
    assert not loc.moved_unseen
