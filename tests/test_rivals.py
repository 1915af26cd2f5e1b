"""Rival poses (`mcl.rivals`): other places that explain the recent frames, and the quality they hold back.

The mechanics are checked with a sensor model whose every answer is set by the test (`Places`: a pose explains
a frame when it lies near one of a few places), so each lead is known exactly; the localizer's use of them with
the field's own model."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from field import spl
from field.checks import ArgumentTypeError
from mcl import reference
from mcl.localizer import Localizer, Quality, QualityThresholds
from mcl.rivals import TOLERANCE, RivalPoses, RivalSettings, beyond_tolerance, displaced, relative
from motion_models import MotionInput
from sensing import Observations
from sensing.observations import LandmarkObservation

FIELD = spl()
FRAME = Observations.coerce([LandmarkObservation("goalpost", 1.5, 0.0)])
HERE = np.array([-2.0, 1.0, 0.0])  # the estimate
THERE = np.array([-2.0, -1.5, 0.5])  # another place
NOWHERE = np.array([-3.5, 2.5, -1.0])  # a place that explains nothing


class Places:
    """A sensor model for the mechanics: a pose explains a frame (log-likelihood 0) within 0.2 m of one of
    `explaining`, else not (-5); it proposes `proposals` (the same each frame)."""

    def __init__(self, explaining, proposals):
        self.explaining = [np.asarray(p, dtype=float) for p in explaining]
        self.proposals = np.asarray(proposals, dtype=float).reshape(-1, 3)

    def log_likelihood(self, poses, observations, out=None):
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        near = np.zeros(poses.shape[0], dtype=bool)
        for p in self.explaining:
            near |= np.hypot(poses[:, 0] - p[0], poses[:, 1] - p[1]) <= 0.2
        return np.where(near, 0.0, -5.0)

    def sample_poses(self, observations, n, rng, heading=None):
        return self.proposals.copy()


def run_frames(rivals, model, frames, dt=1 / 30, estimate=HERE, start=0.0):
    for k in range(frames):
        log_odds = rivals.frame(model, FRAME, estimate, None, start + k * dt, FIELD)
    return log_odds


def test_a_place_that_explains_every_frame_as_well_is_a_rival_at_even_odds():
    rivals = RivalPoses(RivalSettings(), seed=0)
    log_odds = run_frames(rivals, Places([HERE, THERE], [THERE, NOWHERE]), 30)
    poses, leads = rivals.poses
    assert log_odds == 0.0 and leads[0] == 0.0
    assert np.hypot(*(poses[0, :2] - THERE[:2])) <= 0.2


def test_a_place_that_explains_nothing_is_dropped_and_without_rivals_the_odds_are_infinite():
    rivals = RivalPoses(RivalSettings(), seed=0)
    log_odds = run_frames(rivals, Places([HERE], [NOWHERE]), 30)
    assert log_odds == math.inf and rivals.poses[0].shape == (0, 3)


def test_a_newborn_rival_is_scored_over_the_frames_before_it_and_a_wrong_estimate_loses():
    # the estimate explains nothing; a place proposed only now explains every frame of the window: its lead is
    # the window's frames (all but the one it was drawn from) at 5 each, less the tolerance
    model = Places([THERE], [])
    rivals = RivalPoses(RivalSettings(window=1.0), seed=0)
    run_frames(rivals, model, 10)
    model.proposals = THERE.reshape(1, 3)
    log_odds = run_frames(rivals, model, 1, start=10 / 30)
    assert log_odds == pytest.approx(-(5.0 - TOLERANCE) * 10)


def test_only_a_young_track_is_checked():
    rivals = RivalPoses(RivalSettings(young=1.0), seed=0)
    model = Places([HERE, THERE], [THERE])
    assert run_frames(rivals, model, 30) == 0.0  # 1 s of frames: still young
    assert run_frames(rivals, model, 5, start=1.2) == math.inf
    rivals.new_track(2.0)  # a re-localization: young again
    assert run_frames(rivals, model, 5, start=2.0) == 0.0


def test_after_a_reset_around_known_poses_a_place_it_ruled_out_is_no_rival():
    rivals = RivalPoses(RivalSettings(), seed=0)
    rivals.new_track(0.0, forget_frames=True, near=(HERE.reshape(1, 3), 0.45))
    assert run_frames(rivals, Places([HERE, THERE], [THERE]), 30) == math.inf
    rivals.new_track(0.0, forget_frames=True, near=(np.array([HERE, THERE]), 0.45))
    assert run_frames(rivals, Places([HERE, THERE], [THERE]), 30) == 0.0


def test_the_mirror_image_and_the_estimates_own_place_are_no_rivals():
    mirror = np.array([-HERE[0], -HERE[1], HERE[2] + math.pi])
    near = HERE + np.array([0.3, 0.0, 0.0])
    rivals = RivalPoses(RivalSettings(), seed=0)
    assert run_frames(rivals, Places([HERE, mirror, near], [mirror, near]), 30) == math.inf


def test_rivals_move_with_the_odometry():
    rivals = RivalPoses(RivalSettings(), seed=0)
    model = Places([HERE, THERE], [THERE])
    run_frames(rivals, model, 3)
    rivals.moved((1.0, 0.0, 0.0))  # THERE faces 0.5 rad: it moves along that heading
    model.explaining = [HERE, displaced(THERE.reshape(1, 3), (1.0, 0.0, 0.0))[0]]
    model.proposals = np.empty((0, 3))
    assert run_frames(rivals, model, 1, start=0.2, estimate=HERE) == 0.0
    poses, _ = rivals.poses
    assert np.allclose(poses[0, :2], model.explaining[1][:2], atol=0.2)


def test_the_same_seed_gives_the_same_rivals_bit_for_bit():
    def follow(seed):
        rivals = RivalPoses(RivalSettings(), seed=seed)
        run_frames(rivals, Places([HERE, THERE], [THERE, NOWHERE]), 20)
        return rivals.poses

    (a, la), (b, lb) = follow(4), follow(4)
    assert a.tobytes() == b.tobytes() and la.tobytes() == lb.tobytes()


@given(st.lists(st.floats(-50, 50), min_size=1, max_size=20))
def test_a_difference_within_the_tolerance_is_no_evidence_and_a_larger_one_counts_beyond_it(values):
    d = np.array(values)
    out = beyond_tolerance(d)
    assert np.all(np.abs(out) <= np.abs(d)) and np.all(out * d >= 0)  # never larger, never of the other sign
    assert np.all(out[np.abs(d) <= TOLERANCE] == 0.0)
    big = np.abs(d) > TOLERANCE
    assert np.allclose(np.abs(out[big]), np.abs(d[big]) - TOLERANCE)


poses = st.tuples(st.floats(-5, 5), st.floats(-4, 4), st.floats(-math.pi, math.pi))


@given(st.lists(poses, min_size=0, max_size=8), poses)
def test_the_compiled_displacement_equals_plain_numpy_bit_for_bit(many, displacement):
    array = np.array(many, dtype=float).reshape(-1, 3)
    assert displaced(array, displacement).tobytes() == reference.displaced(array, displacement).tobytes()


@given(poses, poses)
def test_relative_then_displaced_returns_the_pose(origin, pose):
    back = displaced(np.array([origin]), relative(origin, pose))[0]
    assert np.allclose(back[:2], pose[:2], atol=1e-9)
    assert abs(math.remainder(back[2] - pose[2], 2 * math.pi)) <= 1e-9


@pytest.mark.parametrize(
    "settings",
    [
        {"window": 0.0},
        {"young": -1.0},
        {"young": math.nan},
        {"candidates": 2.5},
        {"candidates": True},
        {"keep": 0},
        {"drop_odds": 1.0},
        {"apart": 0.0},
        {"mirror_apart": math.inf},
        {"jitter": (0.1, 0.1)},
        {"jitter": (0.1, -0.1, 0.1)},
    ],
)
def test_settings_out_of_range_are_refused(settings):
    with pytest.raises(ValueError):
        RivalSettings(**settings)


def test_the_quality_refuses_rivals_that_are_not_settings():
    with pytest.raises(ArgumentTypeError, match="rivals"):
        QualityThresholds(rivals={"young": 1.0})


def walk_in_front_of_a_goalpost(loc, wrong, truth, seconds=3.0):
    """A robot that sees one goalpost straight ahead: from the reset's two candidates the frames cannot tell
    `wrong` from `truth`."""
    loc.kickoff_placement([wrong, truth])
    qualities = []
    for k in range(int(seconds * 100)):
        t = 0.01 * (k + 1)
        loc.motion(t, MotionInput(dt=0.01, odometry=(0.0, 0.0, 0.0)))
        if k % 3 == 0:
            loc.observe([LandmarkObservation("goalpost", 1.5, 0.0)], capture_time=t)
        qualities.append(loc.quality())
    return qualities


def test_two_places_the_frames_cannot_tell_apart_are_never_superb():
    posts = FIELD.landmarks_of("goalpost")
    post = posts[np.argmax(posts[:, 0] + posts[:, 1])]
    truth = np.array([post[0] - 1.5, post[1], 0.0])
    wrong = np.array([post[0] - 1.5, -post[1], 0.0])  # the same view of the goal's other post
    for seed in range(3):
        loc = Localizer(FIELD, n_particles=300, seed=seed)
        qualities = walk_in_front_of_a_goalpost(loc, wrong, truth)
        assert Quality.SUPERB not in qualities
        assert math.isfinite(loc.rival_log_odds) and loc.rival_log_odds < math.log(10.0)


def test_without_rivals_or_once_old_the_quality_is_as_without_the_check():
    posts = FIELD.landmarks_of("goalpost")
    post = posts[np.argmax(posts[:, 0] + posts[:, 1])]
    truth = np.array([post[0] - 1.5, post[1], 0.0])
    wrong = np.array([post[0] - 1.5, -post[1], 0.0])
    off = walk_in_front_of_a_goalpost(
        Localizer(FIELD, n_particles=200, seed=1, quality=QualityThresholds(rivals=None)), wrong, truth
    )
    never = walk_in_front_of_a_goalpost(
        Localizer(FIELD, n_particles=200, seed=1, quality=QualityThresholds(rivals=RivalSettings(young=0.0))),
        wrong,
        truth,
    )
    assert off == never


def test_a_young_tracks_rival_is_a_hypothesis_weighed_by_its_odds():
    posts = FIELD.landmarks_of("goalpost")
    post = posts[np.argmax(posts[:, 0] + posts[:, 1])]
    truth = np.array([post[0] - 1.5, post[1], 0.0])
    wrong = np.array([post[0] - 1.5, -post[1], 0.0])
    loc = Localizer(FIELD, n_particles=300, seed=0)
    walk_in_front_of_a_goalpost(loc, wrong, truth, seconds=1.0)
    hypotheses = loc.hypotheses()
    rivals = [h for h in hypotheses if h.kind == "rival"]
    main = next(h for h in hypotheses if h.kind == "main")
    assert rivals and sum(h.weight for h in hypotheses) <= 1.0 + 1e-12
    assert [h.weight for h in hypotheses] == sorted((h.weight for h in hypotheses), reverse=True)
    # the rival stands where the frames cannot tell from the estimate: the other post's view
    other = wrong if np.hypot(*(main.pose[:2] - truth[:2])) < 0.5 else truth
    best = max(rivals, key=lambda h: h.weight)
    assert np.hypot(*(best.pose[:2] - other[:2])) < 0.5
    poses, leads = loc.rivals.poses
    assert best.weight / main.weight == pytest.approx(
        math.exp(leads[0]) / (1.0 / (1.0 + math.exp(-loc.side_log_odds))), rel=1e-9
    )
    off = Localizer(FIELD, n_particles=300, seed=0, quality=QualityThresholds(rivals=None))
    walk_in_front_of_a_goalpost(off, wrong, truth, seconds=1.0)
    assert all(h.kind != "rival" for h in off.hypotheses())


def test_an_estimate_that_jumps_without_a_relocalization_is_a_young_track_again():
    """Once the track is old the rivals are not looked for; when the particles move to another place between
    two corrections (here: moved by hand onto the other post's identical view), the new place is checked
    against the places that explain the frames as after a re-localization, and is not SUPERB."""
    posts = FIELD.landmarks_of("goalpost")
    post = posts[np.argmax(posts[:, 0] + posts[:, 1])]
    truth = np.array([post[0] - 1.5, post[1], 0.0])
    wrong = np.array([post[0] - 1.5, -post[1], 0.0])
    loc = Localizer(FIELD, n_particles=300, seed=0, quality=QualityThresholds(rivals=RivalSettings(young=1.0)))
    loc.place(truth, sigma=(0.05, 0.05, 0.05))
    qualities, odds = [], []
    for k in range(400):
        t = 0.01 * (k + 1)
        loc.motion(t, MotionInput(dt=0.01, odometry=(0.0, 0.0, 0.0)))
        if k == 200:  # 2 s in: the track is old, and the particles jump to the other post
            assert loc.rival_log_odds == math.inf and loc.jumps == 0
            loc.filter.poses[:, 1] += wrong[1] - truth[1]
        if k % 3 == 0:
            loc.observe([LandmarkObservation("goalpost", 1.5, 0.0)], capture_time=t)
        if 200 < k <= 220:  # the first frames after the jump
            qualities.append(loc.quality())
            odds.append(loc.rival_log_odds)
    assert loc.jumps == 1
    assert np.hypot(*(loc.pose().pose[:2] - wrong[:2])) < 0.3
    assert any(math.isfinite(o) and o < math.log(10.0) for o in odds)  # the old place is a rival at once
    assert Quality.SUPERB not in qualities
