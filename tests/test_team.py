"""Team messages, the ball and the side belief: validation, the evidence's invariants, and the Localizer's calls
(team_message, observe_ball, hypotheses, penalized, capture-time gating)."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from field import spl
from mcl.localizer import Localizer, Quality
from mcl.side import SideBelief, SideSettings, Team, _Sighting
from motion_models import MotionInput
from sensing import LandmarkObservation as Seen
from sensing.team import BallDetection, TeamMessage, ball_on_field, side_evidence, teammate_ball

FIELD = spl()
AREA = 4 * FIELD.half_length * FIELD.half_width
coordinate = st.floats(-4.5, 4.5, allow_nan=False)
point = st.tuples(coordinate, st.floats(-3.0, 3.0, allow_nan=False)).map(np.array)
variance = st.floats(1e-3, 1.0)


def state(loc):
    """What a refused call must leave as it was."""
    pf = loc.filter
    return (
        pf.poses.copy(),
        pf.log_weights.copy(),
        pf.rng.bit_generator.state,
        dict(loc.counts),
        loc.side._log_joint.copy(),
        dict(loc.side._latest),
        loc.side.reports,
        loc.side.ignored,
        loc.time,
    )


def same(a, b):
    return all(np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y for x, y in zip(a, b))


def standing(pose=(-2.0, 0.0, 0.0), seconds=1.0, seed=0, **options):
    """A localizer placed at `pose` (its prior then holds the side) and stepped for `seconds` at 100 Hz."""
    loc = Localizer(FIELD, seed=seed, **options)
    loc.place(pose, sigma=(0.05, 0.05, 0.05))
    for k in range(int(round(seconds / 0.01))):
        loc.motion(0.01 * (k + 1), MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
    return loc


def sees_ball_at(loc, ball_xy, t, pose=(-2.0, 0.0, 0.0), twice=True):
    """The robot at `pose` sees the ball at `ball_xy` (field frame) at time t (and, `twice`, 0.02 s before:
    a sighting counts once it is confirmed)."""
    dx, dy = ball_xy[0] - pose[0], ball_xy[1] - pose[1]
    detection = BallDetection(math.hypot(dx, dy), math.atan2(dy, dx) - pose[2])
    if twice:
        loc.observe_ball(detection, capture_time=t - 0.02)
    return loc.observe_ball(detection, capture_time=t)


def report(sender, t, ball, confidence=0.95, **fields):
    return TeamMessage(sender, t, (0.0, 1.0, 0.0), confidence=confidence, ball=ball, **fields)


def feed(side, j, value, sighting=None):
    """Teammate j's report for the main pose by `value` (log odds), compared with `sighting` (by default a
    sighting of its own, compared with nothing else)."""
    sighting = _Sighting(0.0, np.zeros(2), np.eye(2)) if sighting is None else sighting
    side._report(j, 0.5 * value, -0.5 * value, sighting)


# -- the types ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "fields, word",
    [
        ({"sender": 0}, "sender"),
        ({"sender": 21}, "sender"),
        ({"time": math.nan}, "time"),
        ({"pose": (0.0, math.inf, 0.0)}, "pose"),
        ({"pose_covariance": np.ones((3, 3))}, "positive definite"),
        ({"pose_covariance": -np.eye(3)}, "pose_covariance"),
        ({"pose_covariance": np.eye(2)}, "shape"),
        ({"pose_covariance": [[1, 2, 0], [0, 1, 0], [0, 0, 1]]}, "symmetric"),
        ({"confidence": 1.5}, "confidence"),
        ({"ball": (math.nan, 0.0)}, "ball"),
        ({"ball_age": -1.0}, "ball_age"),
        ({"ball_velocity": (1e6, 0)}, "ball_velocity"),
        ({"is_goalkeeper": "yes"}, "is_goalkeeper"),
        ({"ball_covariance": np.zeros((2, 2))}, "ball_covariance"),
    ],
)
def test_a_bad_message_is_refused_naming_the_field(fields, word):
    base = {"sender": 2, "time": 1.0, "pose": (0.0, 0.0, 0.0)}
    with pytest.raises(ValueError, match=word):
        TeamMessage(**{**base, **fields})


@pytest.mark.parametrize(
    "fields, word",
    [
        ({"range": -1.0}, "range"),
        ({"bearing": math.nan}, "bearing"),
        ({"range_sigma": 0.0}, "range_sigma"),
        ({"range": "far"}, "range"),
    ],
)
def test_a_bad_ball_detection_is_refused(fields, word):
    with pytest.raises(ValueError, match=word):
        BallDetection(**{"range": 1.0, "bearing": 0.0, **fields})


# -- the evidence ------------------------------------------------------------------------------------------
@given(point, point, variance, variance, st.floats(0.01, 0.9))
def test_side_evidence_is_antisymmetric_bounded_and_invariant_under_the_half_turn(own, team, a, b, outlier):
    own_cov, team_cov = np.eye(2) * a, np.eye(2) * b
    value = side_evidence(own, own_cov, team, team_cov, outlier, AREA)
    assert math.isfinite(value)
    # the mirror pose sees the ball at −own: exactly the opposite evidence
    assert side_evidence(-own, own_cov, team, team_cov, outlier, AREA) == pytest.approx(-value, abs=1e-9)
    # turning the whole world by a half turn (both points through the centre mark) changes nothing
    assert side_evidence(-own, own_cov, -team, team_cov, outlier, AREA) == pytest.approx(value, abs=1e-9)
    # one report moves the odds by at most what its outlier share allows
    peak = -math.log(2 * math.pi) - 0.5 * math.log(np.linalg.det(own_cov + team_cov))
    floor = math.log(outlier / AREA)
    bound = float(np.logaddexp(math.log1p(-outlier) + peak, floor)) - floor
    assert abs(value) <= bound + 1e-9


@given(variance, variance)
def test_a_ball_on_the_centre_mark_says_nothing_about_the_side(a, b):
    assert side_evidence(np.zeros(2), np.eye(2) * a, np.array([1.0, 0.5]), np.eye(2) * b, 0.2, AREA) == pytest.approx(
        0.0, abs=1e-12
    )


def test_ball_on_field_places_the_detection_through_the_pose():
    point, covariance = ball_on_field(
        np.array([1.0, 2.0, math.pi / 2]),
        np.zeros((3, 3)),
        BallDetection(2.0, 0.0, range_sigma=0.1, bearing_sigma=0.01),
    )
    np.testing.assert_allclose(point, [1.0, 4.0], atol=1e-12)
    np.testing.assert_allclose(np.diag(covariance), [(2 * 0.01) ** 2, 0.1**2], atol=1e-12)


def test_a_teammate_ball_is_moved_on_by_its_velocity_and_widened_by_its_age():
    message = TeamMessage(
        3, 10.0, (0.0, 0.0, 0.0), confidence=1.0, ball=(1.0, 0.0), ball_velocity=(1.0, 0.0), ball_age=0.5
    )
    p_now, cov_now = teammate_ball(message, 9.5)
    p_later, cov_later = teammate_ball(message, 10.5)
    np.testing.assert_allclose(p_now, [1.0, 0.0])
    np.testing.assert_allclose(p_later, [2.0, 0.0])
    assert cov_later[0, 0] > cov_now[0, 0]
    assert teammate_ball(message, 20.0) is None  # beyond the horizon
    assert teammate_ball(TeamMessage(3, 10.0, (0.0, 0.0, 0.0)), 10.0) is None  # no ball


def test_settings_keep_one_teammate_from_flipping_a_held_robot():
    with pytest.raises(ValueError, match="one teammate"):
        SideSettings(teammate_mirrored=0.001)
    with pytest.raises(ValueError, match="two agreeing"):
        SideSettings(teammate_mirrored=0.3)
    with pytest.raises(ValueError, match="outlier_share"):
        SideSettings(outlier_share=1.0)


# -- the localizer ---------------------------------------------------------------------------------------------
def test_agreeing_reports_raise_the_odds_and_mirrored_ones_lower_them():
    ball = (-1.0, 0.8)
    agree = standing()
    agree.team_message(report(2, 0.95, ball))
    assert sees_ball_at(agree, ball, 0.99)
    disagree = standing()
    disagree.team_message(report(2, 0.95, (1.0, -0.8)))
    sees_ball_at(disagree, ball, 0.99)
    prior = standing().side_log_odds
    assert agree.side_log_odds > prior > disagree.side_log_odds
    assert agree.side.reports == disagree.side.reports == 1


def test_one_confident_teammate_never_flips_a_robot_its_prior_holds():
    loc = standing()
    before = loc.pose().pose.copy()
    t = 1.0
    for k in range(200):  # 20 s of a confident, mirrored teammate
        t = 1.0 + 0.1 * (k + 1)
        for j in range(10):
            loc.motion(t - 0.1 + 0.01 * (j + 1), MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
        loc.team_message(report(2, t - 0.05, (1.0, -0.8)))
        sees_ball_at(loc, (-1.0, 0.8), t)
    assert loc.counts["side changed by the team"] == 0
    assert np.linalg.norm(loc.pose().pose[:2] - before[:2]) < 0.3
    assert loc.side_log_odds > -loc.side.settings.flip


def test_two_agreeing_teammates_flip_it_and_the_flip_is_exact():
    loc = standing()
    before = loc.pose().pose.copy()
    particles = loc.filter.poses.copy()
    t = 1.0
    flipped_at = None
    for k in range(50):
        t = 1.0 + 0.1 * (k + 1)
        for j in range(10):
            loc.motion(t - 0.1 + 0.01 * (j + 1), MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
        loc.team_message(report(2, t - 0.05, (1.0, -0.8)))
        loc.team_message(report(4, t - 0.04, (1.05, -0.75)))
        sees_ball_at(loc, (-1.0, 0.8), t)
        if flipped_at is None and loc.counts["side changed by the team"]:
            flipped_at = t
            np.testing.assert_allclose(loc.filter.poses, FIELD.mirror_poses(particles), atol=1e-12)
    assert flipped_at is not None and flipped_at - 1.0 >= loc.side.settings.flip_hold
    assert loc.counts["side changed by the team"] == 1  # and it stays: the evidence now agrees
    np.testing.assert_allclose(loc.pose().pose[:2], -before[:2], atol=0.05)
    assert loc.side_log_odds > 0


def test_a_goalkeeper_that_believes_it_is_in_the_opponent_half_is_taken_mirrored():
    ball = (-1.0, 0.8)
    loc = standing()
    loc.team_message(TeamMessage(1, 0.95, (4.4, 0.0, math.pi), confidence=1.0, is_goalkeeper=True, ball=(1.0, -0.8)))
    sees_ball_at(loc, ball, 0.99)
    assert loc.side_log_odds > standing().side_log_odds


def test_a_sighting_seen_once_is_not_compared():
    loc = standing()
    loc.team_message(report(2, 0.95, (-1.0, 0.8)))
    sees_ball_at(loc, (-1.0, 0.8), 0.98, twice=False)  # a single, unconfirmed sighting (a false ball?)
    assert loc.side.reports == 0 and loc.side.unconfirmed == 1
    sees_ball_at(loc, (1.5, -2.0), 0.99, twice=False)  # not at the same place: still unconfirmed
    assert loc.side.reports == 0 and loc.side.unconfirmed == 2


def test_a_report_far_from_both_sides_says_nothing():
    loc = standing()
    loc.team_message(report(2, 0.95, (-1.0, -2.9), confidence=1.0))
    sees_ball_at(loc, (-1.5, 2.5), 0.99)  # neither at the report nor at its point image
    assert loc.side.reports == 0 and loc.side.ignored == 1
    assert loc.side_log_odds == standing().side_log_odds


def test_each_teammate_sighting_is_evidence_once():
    loc = standing()
    loc.team_message(report(2, 0.95, (-1.0, 0.8)))
    sees_ball_at(loc, (-1.0, 0.8), 0.98)
    assert loc.side.reports == 1
    odds = loc.side_log_odds
    sees_ball_at(loc, (-1.0, 0.8), 0.99, twice=False)  # a further sighting of the robot's own: not again
    assert loc.side.reports == 1 and loc.side_log_odds == odds
    # the teammate repeats its last sighting (sent later, its age grown by as much): the same pair, no evidence
    loc.team_message(report(2, 0.97, (-1.0, 0.8), ball_age=0.02))
    assert loc.side.reports == 1 and loc.side_log_odds == odds
    loc.team_message(report(2, 0.90, (-1.0, 0.8)))  # older than the one kept: ignored
    assert loc.side.reports == 1


@pytest.mark.parametrize(
    "message, word",
    [
        (report(7, 0.9, (0.0, 0.0)), "not a teammate"),  # not among the teammates
        (report(5, 0.9, (0.0, 0.0)), "not a teammate"),  # the robot's own number
        (report(2, 100.0, (0.0, 0.0)), "message time"),  # far in the future
        (report(2, -50.0, (0.0, 0.0)), "message time"),  # far in the past
        ((2, 0.9), "TeamMessage"),
    ],
)
def test_a_refused_message_leaves_the_localizer_untouched(message, word):
    loc = standing(team=Team(player_number=5, teammates=[1, 2, 3, 4]))
    loc.team_message(report(2, 0.8, (-1.0, 0.8)))
    before = state(loc)
    with pytest.raises(ValueError, match=word):
        loc.team_message(message)
    assert same(before, state(loc))


def test_a_refused_ball_leaves_the_localizer_untouched():
    loc = standing()
    before = state(loc)
    for call in (
        lambda: loc.observe_ball((1.0, 0.0)),
        lambda: loc.observe_ball(BallDetection(1.0, 0.0), -5.0),
        lambda: loc.observe([], ball=(1.0, 0.0)),
    ):
        with pytest.raises(ValueError):
            call()
        assert same(before, state(loc))


def test_without_teammates_the_ball_changes_nothing_bit_for_bit():
    def run(with_ball):
        loc = Localizer(FIELD, seed=4)
        loc.anywhere_in_own_half()
        for k in range(150):
            t = 0.01 * (k + 1)
            loc.motion(t, MotionInput(0.01, odometry=(0.002, 0.0, 0.001)))
            if k % 3 == 0:
                frame = [Seen("penalty_mark", 1.2, 0.0), Seen("goalpost", 2.65, 0.31), Seen("goalpost", 2.65, -0.31)]
                loc.observe(frame, capture_time=max(t - 0.02, 0.0), ball=BallDetection(1.0, 0.2) if with_ball else None)
        return loc.filter.poses.copy(), loc.filter.log_weights.copy(), loc.quality()

    plain, seen = run(False), run(True)
    np.testing.assert_array_equal(plain[0], seen[0])
    np.testing.assert_array_equal(plain[1], seen[1])
    assert plain[2] == seen[2]


def test_hypotheses_hold_the_mirror_image_weighted_by_the_side_odds():
    loc = standing()
    hypotheses = loc.hypotheses()
    assert [h.kind for h in hypotheses[:2]] == ["main", "mirror"]
    main, mirror = hypotheses[0], hypotheses[1]
    np.testing.assert_allclose(mirror.pose[:2], -main.pose[:2])
    assert sum(h.weight for h in hypotheses) <= 1.0 + 1e-12
    assert main.weight / mirror.weight == pytest.approx(math.exp(loc.side_log_odds), rel=1e-6)


def sure_of_its_pose():
    """A robot placed facing its own goal that sees the penalty mark and both goalposts for 0.9 s (until t = 1.9 s)."""
    loc = standing((-2.0, 0.0, math.pi))
    for k in range(30):
        t = 1.0 + 0.03 * (k + 1)
        for j in range(3):
            loc.motion(t - 0.03 + 0.01 * (j + 1), MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
        loc.observe(
            [Seen("penalty_mark", 1.2, 0.0), Seen("goalpost", 2.65, 0.31), Seen("goalpost", 2.65, -0.31)],
            capture_time=t,
        )
    return loc


def test_unsure_of_the_half_when_the_side_odds_are_even():
    loc = sure_of_its_pose()
    assert loc.quality() in (Quality.SUPERB, Quality.OKAY)
    # as a re-localization that could not tell the pose from its mirror image
    loc.filter.relocalization.mirror_log_odds = math.log(loc.thresholds.okay_mirror_odds) - 0.1
    loc._quality = None
    assert loc.quality() is Quality.UNSURE_HALF
    assert not loc.is_lost


# -- game events by capture time -----------------------------------------------------------------------------
def test_penalized_ignores_motion_and_frames_until_the_return():
    loc = standing()
    loc.penalized()
    poses = loc.filter.poses.copy()
    loc.motion(1.01, MotionInput(0.01, odometry=(0.5, 0.0, 0.0)))
    assert not loc.observe([Seen("penalty_mark", 1.2, 0.0)], capture_time=1.005)
    np.testing.assert_array_equal(loc.filter.poses, poses)
    assert loc.counts["motion while penalized"] == 1 and loc.counts["observation while penalized"] == 1
    assert loc.quality() is Quality.POOR and not loc.is_lost
    loc.penalty_return()
    assert not loc.is_penalized
    loc.motion(1.02, MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
    assert loc.observe([Seen("penalty_mark", 1.2, 0.0)], capture_time=1.015)


def test_a_frame_captured_while_fallen_is_not_used_when_it_arrives_after_getting_up():
    loc = standing()
    loc.fallen()  # at t = 1.0
    for k in range(50):
        loc.motion(1.0 + 0.01 * (k + 1), MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
    loc.got_up()  # at t = 1.5
    loc.motion(1.51, MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
    poses = loc.filter.poses.copy()
    assert not loc.observe([Seen("penalty_mark", 1.2, 0.0)], capture_time=1.45)  # captured while lying
    np.testing.assert_array_equal(loc.filter.poses, poses)
    assert loc.counts["observation while fallen"] == 1
    assert loc.observe([Seen("penalty_mark", 1.2, 0.0)], capture_time=1.505)  # captured standing


def test_a_teammate_that_contradicts_the_team_is_taken_for_mirrored_and_stays_so_after_a_move():
    loc = standing()
    t = 1.0
    for k in range(30):
        t = 1.0 + 0.1 * (k + 1)
        for j in range(10):
            loc.motion(t - 0.1 + 0.01 * (j + 1), MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
        loc.team_message(report(2, t - 0.05, (-1.0, 0.8)))  # two teammates agree with the robot ...
        loc.team_message(report(4, t - 0.05, (-0.95, 0.85)))
        loc.team_message(report(5, t - 0.04, (1.0, -0.8)))  # ... one reports the point image
        sees_ball_at(loc, (-1.0, 0.8), t)
    assert loc.side.teammate_mirrored(5) > 0.9
    assert loc.side.teammate_mirrored(2) < 0.1 and loc.side.teammate_mirrored(4) < 0.1
    assert loc.counts["side changed by the team"] == 0
    loc.side.moved()  # the robot re-localized somewhere new
    assert loc.side.team_log_odds() == 0.0  # nothing is known of its new side ...
    assert loc.side.teammate_mirrored(5) > 0.9  # ... but teammate 5 is still doubted


@given(st.lists(st.tuples(st.integers(1, 4), st.floats(-6.0, 6.0)), max_size=40), st.floats(-10.0, 10.0))
def test_one_teammate_never_moves_the_odds_by_more_than_its_trust(reports, prior):
    """Whatever one teammate reports, its evidence stays within ±log((1 − q) / q); with several, the odds stay
    finite and a refused teammate changes nothing."""
    side = SideBelief(FIELD)
    for sender, value in reports:
        if sender not in side._senders:
            side._add_teammate(sender)
        feed(side, side._senders.index(sender), value)
    trust = side.settings.teammate_trust
    assert abs(side.team_log_odds()) <= len(side._senders) * trust + 1e-9
    assert math.isfinite(side.log_odds(prior))
    if len(side._senders) == 1:
        assert abs(side.team_log_odds()) <= trust + 1e-9


# -- the side odds no single teammate carries ------------------------------------------------------------------
events = st.lists(
    st.one_of(
        st.tuples(st.just("report"), st.integers(1, 4), st.floats(-6.0, 6.0)),
        st.tuples(st.sampled_from(["moved", "mirrored"]), st.just(0), st.just(0.0)),
    ),
    max_size=30,
)


def replay(events, silenced=None):
    """A side belief fed `events` (a teammate's report, the robot moved or mirrored); the reports of teammate
    `silenced` count for nothing (its flag is still modelled)."""
    side = SideBelief(FIELD)
    for kind, sender, value in events:
        if kind == "report":
            if sender not in side._senders:
                side._add_teammate(sender)
            feed(side, side._senders.index(sender), 0.0 if sender == silenced else value)
        else:
            getattr(side, kind)()
    return side


@given(events)
def test_leaving_a_teammate_out_is_the_belief_that_never_heard_its_reports(events):
    """Row j + 1 of the joint is, to rounding, the belief in which teammate j's reports said nothing; the held
    odds are the least of these and the full odds."""
    side = replay(events)
    marginals = side._side_marginals()
    for j, sender in enumerate(side._senders):
        assert marginals[j + 1] == pytest.approx(replay(events, silenced=sender)._side_marginal(), abs=1e-9)
    assert side.held_team_log_odds() <= side.team_log_odds() + 1e-12
    if side._side_evidence:
        assert side.held_team_log_odds() == pytest.approx(min(marginals), abs=1e-12)


@given(st.lists(st.floats(0.0, 6.0), min_size=1, max_size=30), st.floats(-3.0, 3.0))
def test_one_teammate_alone_never_raises_the_held_odds(values, prior):
    """However often and surely one teammate speaks for the main pose, the odds the quality reads stay the
    prior's (capped); the full odds rise."""
    side = SideBelief(FIELD)
    side._add_teammate(2)
    for value in values:
        feed(side, 0, value)
    assert side.held_team_log_odds() == pytest.approx(0.0, abs=1e-9)
    assert side.held_log_odds(prior) == pytest.approx(min(max(prior, -3.0), 3.0), abs=1e-9)
    assert side.team_log_odds() >= 0.0


fit = st.floats(math.log(0.2), 0.0)  # a report that fits a place no better than anywhere on the field


def widened(side, sighting):
    """`sighting`, its reports' fits widened to the joint's teammates as `SideBelief._add_teammate` widens
    those of the sightings it keeps (tests that hand `_report` a sighting of their own)."""
    while sighting.fits is not None and sighting.fits[0].shape != side._log_joint.shape:
        sums, mixture = (np.concatenate([array, array], axis=1) for array in sighting.fits)
        sighting.fits = np.concatenate([sums, sums[:1]]), np.concatenate([mixture, mixture[:1]])
    return sighting


@given(st.lists(st.tuples(st.integers(1, 4), fit, fit), min_size=1, max_size=30), st.floats(0.01, 0.99))
def test_reports_that_fit_neither_place_of_one_sighting_say_little_together(reports, outlier):
    """Reports compared with one sighting of the robot's own that fit neither its place nor the mirror image's
    better than anywhere on the field move the side odds by at most log(1 / sighting_outlier) together, however
    many teammates send however many: the sighting itself may be no ball."""
    side = SideBelief(FIELD, SideSettings(sighting_outlier=outlier))
    sighting = _Sighting(0.0, np.array([2.0, 3.0]), np.eye(2))
    for sender, near, far in reports:
        if sender not in side._senders:
            side._add_teammate(sender)
        side._report(side._senders.index(sender), near, far, widened(side, sighting))
    assert abs(side.team_log_odds()) <= -math.log(outlier) + 1e-9


@given(st.lists(st.tuples(st.integers(1, 4), fit, st.floats(-1.6, 4.0)), min_size=1, max_size=20))
def test_a_sighting_that_is_surely_the_ball_counts_its_reports_one_by_one(reports):
    """With `sighting_outlier` near 0 the mixture is the plain sum: reports compared with one sighting move the
    odds as much as the same reports compared each with a sighting of its own."""
    together, apart = (SideBelief(FIELD, SideSettings(sighting_outlier=1e-12)) for _ in range(2))
    shared = _Sighting(0.0, np.array([2.0, 3.0]), np.eye(2))
    for sender, near, far in reports:
        for side in (together, apart):
            if sender not in side._senders:
                side._add_teammate(sender)
        together._report(together._senders.index(sender), near, far, widened(together, shared))
        apart._report(apart._senders.index(sender), near, far, _Sighting(0.0, np.array([2.0, 3.0]), np.eye(2)))
    assert together.team_log_odds() == pytest.approx(apart.team_log_odds(), abs=1e-6)
    assert together.held_team_log_odds() == pytest.approx(apart.held_team_log_odds(), abs=1e-6)


def test_a_false_ball_of_the_robots_own_does_not_let_teammates_flip_it():
    """The robot sees a false ball twice by the touchline (confirmed); two teammates report the real ball near
    the centre mark again and again, a little nearer the point image of the false one. Compared report by report
    they would flip the robot onto its mirror image; together, as what one wrong sighting can say, they do not."""
    loc = standing((1.0, 3.1, -0.2), seconds=1.0)
    loc.moved_unseen = True  # as after a kidnapping: its own prior holds the side weakly (jump_cap)
    sees_ball_at(loc, (2.1, 3.0), 1.0, pose=(1.0, 3.1, -0.2))
    for k in range(30):  # ten reports per teammate and second, for 3 s; the robot sees no ball again
        t = 1.0 + 0.1 * (k + 1)
        for j in range(10):
            loc.motion(t - 0.1 + 0.01 * (j + 1), MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
        for sender, ball in ((2, (-0.5, -0.2)), (4, (-0.3, -0.4))):
            loc.team_message(report(sender, t, ball, pose_covariance=np.diag([2.0, 2.0, 0.1])))
    assert loc.side.reports >= 8
    assert abs(loc.side.team_log_odds()) <= -math.log(loc.side.settings.sighting_outlier) + 1e-9
    assert loc.counts["side changed by the team"] == 0


def test_two_agreeing_teammates_raise_the_held_odds():
    side = SideBelief(FIELD)
    for sender in (2, 4):
        side._add_teammate(sender)
    for _ in range(5):
        feed(side, 0, 2.0)
        feed(side, 1, 2.0)
    assert side.held_team_log_odds() > 1.0
    assert side.team_log_odds() > side.held_team_log_odds()


def test_one_teammate_never_makes_the_quality_sure_of_the_half_after_an_unseen_move():
    """After a kidnapping whose side the robot's own prior cannot tell, one confident teammate lifts the side
    odds, but the quality stays UNSURE_HALF; the pose is not lost."""
    loc = sure_of_its_pose()
    loc.moved_unseen = True  # as after a kidnapping detected by its surprise: the prior is capped at jump_cap
    loc._quality = None
    assert loc.quality() is Quality.UNSURE_HALF
    t = 2.0
    for k in range(30):  # one teammate, agreeing with the robot's side, for 3 s
        t = 2.0 + 0.1 * (k + 1)
        for j in range(10):
            loc.motion(t - 0.1 + 0.01 * (j + 1), MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))
        loc.team_message(report(2, t - 0.05, (-1.0, 0.8)))
        sees_ball_at(loc, (-1.0, 0.8), t, pose=(-2.0, 0.0, math.pi))
    assert loc.side.reports > 0
    assert loc.side_log_odds > math.log(loc.thresholds.superb_mirror_odds)  # the full odds would say SUPERB
    assert loc.held_side_log_odds < math.log(loc.thresholds.okay_mirror_odds)
    assert loc.quality() is Quality.UNSURE_HALF
    assert not loc.is_lost


# -- pairing sightings, and the side change's hold -----------------------------------------------------------
def step_to(loc, t):
    """Still odometry at 100 Hz until `t`."""
    while loc.time is None or loc.time < t - 1e-9:
        loc.motion(round((loc.time or 0.0) + 0.01, 6), MotionInput(0.01, odometry=(0.0, 0.0, 0.0)))


def test_a_teammate_sighting_pairs_with_the_robots_own_sighting_nearest_in_time():
    """The robot saw the ball at 1.0 s and again at 2.0 s; a teammate's sighting of 1.0 s arrives after both:
    it is weighed against the one of 1.0 s (the ball had no time to move), not refused for the later one."""
    loc = standing()
    sees_ball_at(loc, (-1.0, 0.8), 1.0)
    step_to(loc, 2.0)
    sees_ball_at(loc, (-1.0, 0.8), 2.0)
    step_to(loc, 2.05)
    loc.team_message(report(2, 2.05, (-1.0, 0.8), ball_age=1.05))
    assert loc.side.reports == 1 and loc.side_log_odds > standing().side_log_odds


def test_a_teammate_sighting_no_own_sighting_could_pair_with_waits_for_one():
    """A report that arrives when the robot's own sightings are all more than `horizon` from it is not used up:
    the robot's next sighting, near it in time, is weighed against it."""
    loc = standing()
    sees_ball_at(loc, (-1.0, 0.8), 1.0)
    step_to(loc, 2.05)
    loc.team_message(report(2, 2.05, (-1.0, 0.8), ball_age=0.05))  # seen at 2.0 s: 1 s after the robot's
    assert loc.side.reports == 0 and loc.side.ignored == 1
    step_to(loc, 2.1)
    sees_ball_at(loc, (-1.0, 0.8), 2.1)
    assert loc.side.reports == 1


def test_a_side_change_waits_for_its_hold_without_further_reports():
    """Two agreeing teammates put the robot on the mirror, then fall silent: the side changes `flip_hold`
    seconds after the odds fell below −`flip`, as the robot's clock runs, not at the next report."""
    loc = standing()
    t = 1.0
    while loc.side_log_odds >= -loc.side.settings.flip:
        t = round(t + 0.1, 6)
        step_to(loc, t)
        loc.team_message(report(2, t - 0.05, (1.0, -0.8)))
        loc.team_message(report(4, t - 0.04, (1.05, -0.75)))
        sees_ball_at(loc, (-1.0, 0.8), t)
        assert t < 5.0
    pending_since = loc.time
    hold = loc.side.settings.flip_hold
    step_to(loc, pending_since + hold - 0.05)
    assert loc.counts["side changed by the team"] == 0
    step_to(loc, pending_since + hold + 0.05)
    assert loc.counts["side changed by the team"] == 1


def test_a_robot_placed_in_its_own_half_keeps_its_side_until_it_is_moved_unseen():
    """The rules put a placed robot in its own half: two agreeing teammates that speak for the mirror image do
    not change its side while nothing has moved it unseen; once something has, they do."""
    loc = Localizer(FIELD, seed=0)
    loc.manual_placement([(-2.0, 0.0, 0.0)])
    step_to(loc, 1.0)
    assert loc.side_placed

    def teammates_say_mirror(t0, seconds):
        t = t0
        for _ in range(int(seconds / 0.1)):
            t = round(t + 0.1, 6)
            step_to(loc, t)
            loc.team_message(report(2, t - 0.05, (1.0, -0.8)))
            loc.team_message(report(4, t - 0.04, (1.05, -0.75)))
            sees_ball_at(loc, (-1.0, 0.8), t)
        return t

    t = teammates_say_mirror(1.0, 4.0)
    assert loc.side_log_odds < -loc.side.settings.flip  # the evidence says mirror ...
    assert loc.counts["side changed by the team"] == 0  # ... and the placement holds
    loc.moved_unseen = True  # as after a kidnapping the surprise caught
    assert not loc.side_placed
    teammates_say_mirror(t, 2.0)
    assert loc.counts["side changed by the team"] == 1
