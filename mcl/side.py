"""Which half: the belief that the robot is where its estimate says and not on the mirror image, from its own
prior and its teammates' view of the ball.

    from mcl.side import SideBelief, SideSettings

    side = SideBelief(field, SideSettings())
    side.log_odds(prior_log_odds)              # the main pose against its mirror image

The field is point-symmetric, so the landmarks never tell a pose from its mirror image (−x, −y, θ+π); the mirror
hypothesis is always exactly as well supported by them as the main one. So it is kept as an explicit second
hypothesis, at the point image of the main estimate, with log odds from two kinds of evidence:

1. **The robot's own prior** (the re-localization's `mirror_log_odds`: continuity with the last confident
   pose, the placement region), capped at `prior_cap`: continuity holds a robot on its side, but no prior is
   certain (the kidnapping it assumes may not be the one that happened).
2. **The ball, seen by the robot and by its teammates** (`sensing.team.report_log_likelihoods`): each
   teammate's report compared once with the robot's own sighting nearest to it in time (of the confirmed ones
   of the last `past` seconds), placed on the field through the main pose and through its mirror image. A
   sighting counts once it is confirmed (seen twice at the same place: false balls rarely are), and a report far
   from both places says nothing (one of the two sightings is wrong).

   **The robot's own sighting can be wrong too** (a false ball seen twice in one place, another ball), and
   every report compared with it shares that error: so the reports compared with one sighting count together,
   as the likelihood of a mixture in which the sighting is not the ball with probability `sighting_outlier`.
   Reports that fit one of its two places well add up; reports that fit neither (a teammate sees the ball at
   the centre mark, the robot a false one by the touchline) move the odds by at most log(1 / sighting_outlier)
   together, however many there are.

**A teammate can be on the mirror itself**, with high stated confidence: then its reports of the ball are
point images, and they speak against the right side. So the belief is a joint one, over the robot's side S and
a flag m_j per teammate (on the mirror or not), with the prior `teammate_mirrored` on each flag: a report of
teammate j supports S when m_j = 0 and the other side when m_j = 1. The posterior over these 2^(k+1) states
(k teammates, at most `max_teammates`) is kept exactly. What follows from it:

- one teammate alone moves the odds by at most log((1 − q) / q), q = `teammate_mirrored`, however often it
  reports: past that, "it is on the mirror" explains its reports as well as "I am";
- several teammates that agree multiply their weight, and a teammate that disagrees with the others is
  taken for mirrored;
- what the robot learns about a teammate outlives the robot's own re-localization (`moved` forgets the
  evidence about the robot's side, not about its teammates'), so a teammate that contradicted the team before
  a kidnapping is discounted after it;
- a teammate's flag may change (it is kidnapped, or recovers): `teammate_hazard` per second.

`SideSettings` checks that one teammate alone cannot flip a robot whose prior holds it (prior at its cap) and
that two agreeing teammates can.

The robot changes sides (mirrors its particles: exact, since the likelihood is symmetric) when the log odds
stay below −`flip` for `flip_hold` seconds (`flip_pending` while it waits: the localizer asks again as its clock
runs). This module holds the numbers; `mcl.localizer.Localizer` feeds it and acts on it.
"""

from __future__ import annotations

import bisect
import functools
import math
from dataclasses import dataclass, fields

import numpy as np

from field import Field
from field.checks import ArgumentTypeError, integer, real
from sensing.team import (
    MAX_PLAYER_NUMBER,
    BallDetection,
    TeamMessage,
    ball_on_field,
    mahalanobis2,
    report_log_likelihoods,
    teammate_ball,
)


@dataclass(frozen=True)
class SideSettings:
    """The weights of the side evidence (see the module docstring).

    Parameters
    ----------
    outlier_share : float, default 0.2
        Probability that a teammate's ball report has nothing to do with the ball the robot sees (another
        ball, a kick in between), within (0, 1): bounds what one report can say.
    rolling_sigma : float, default 1.0
        How fast the ball may have moved unseen [m/s], > 0: widens a report by this times its age.
    horizon : float, default 0.5
        A report is compared with the robot's sighting nearest to it in time only when the two sightings are at
        most this far apart [s], > 0 (until then it waits for one): a kicked ball moves metres in a second, so
        older pairs say more about the kick than about the side.
    sighting_outlier : float, default 0.2
        Probability that a confirmed sighting of the robot's own is not the ball its teammates report (a false
        detection seen twice in one place, another ball), within (0, 1): what the reports compared with one
        sighting can say together when none of them fits it.
    teammate_mirrored : float, default 0.05
        Prior probability that a teammate is itself on the mirror, within (0, 0.5).
    teammate_hazard : float, default 0.01
        Rate [1/s] at which a teammate's flag is drawn afresh from its prior (so a teammate falls onto the
        mirror at rate hazard · q and recovers at rate hazard · (1 − q)), >= 0.
    max_teammates : int, default 7
        Teammates modelled at once (2^(k+1) states); messages from further senders are ignored, within [1, 10].
    prior_cap : float, default 3.0
        The most the robot's own prior can hold the log odds (log 20), > 0 ...
    kidnap_cap : float, default 1.0
        ... and the most when the prior rests on a kidnapping law (the re-localized pose lies beyond the
        anchor's drift, `SoccerRelocalization.kidnapped`: the law of an unseen kidnapping is a guess), within
        (0, prior_cap].
    jump_cap : float, default 1.0
        ... and the most when a re-localized pose lay beyond the anchor's drift at all, however far its mirror
        image (`SoccerRelocalization.jumped`: the robot was moved unseen, and how far robots are carried is a
        guess), within [kidnap_cap, prior_cap]. The default is below log 3, the odds
        `QualityThresholds.okay_mirror_odds` asks: after an unseen move the pose is UNSURE_HALF until the
        teammates' evidence (or a placement) tells the half; a guessed law never makes it OKAY or SUPERB.
    flip : float, default 2.3
        The robot changes sides when the log odds stay below −flip (log 10) ...
    flip_hold : float, default 1.0
        ... for this many seconds, >= 0.
    confirm_window : float, default 0.5
        A sighting of the robot's own is used once another one within this many seconds before it lies at the
        same place [s], > 0: a false detection is rarely seen twice in the same place ...
    confirm_distance : float, default 0.5
        ... within this distance [m] plus `rolling_sigma` times the time between them (>= 0).
    gate : float, default 9.21
        A report is compared only when it lies within this squared Mahalanobis distance of the robot's
        sighting or of its mirror image (9.21: 99 % of a two-dimensional normal), > 0.
    future : float, default 1.0
        A message sent more than this far in the future of the robot's clock is refused [s], >= 0.
    past : float, default 10.0
        A message sent more than this long ago is refused [s], > 0.

    Raises
    ------
    ValueError
        For a value out of its range, or settings that let one teammate flip a robot its prior holds
        (log((1 − q) / q) >= prior_cap + flip) or that two agreeing teammates cannot flip it
        (2 log((1 − q) / q) <= prior_cap + flip).
    """

    outlier_share: float = 0.2
    rolling_sigma: float = 1.0
    horizon: float = 0.5
    sighting_outlier: float = 0.2
    teammate_mirrored: float = 0.05
    teammate_hazard: float = 0.01
    max_teammates: int = 7
    prior_cap: float = 3.0
    kidnap_cap: float = 1.0
    jump_cap: float = 1.0
    flip: float = 2.3
    flip_hold: float = 1.0
    confirm_window: float = 0.5
    confirm_distance: float = 0.5
    gate: float = 9.21
    future: float = 1.0
    past: float = 10.0

    def __post_init__(self) -> None:
        positive = ("rolling_sigma", "horizon", "prior_cap", "flip", "past", "confirm_window", "gate")
        for f in fields(self):
            if f.name != "max_teammates":
                real(f.name, getattr(self, f.name), 0.0, low_open=f.name in positive)
        integer("max_teammates", self.max_teammates, 1, 10)
        real("kidnap_cap", self.kidnap_cap, 0.0, self.prior_cap, low_open=True)
        real("jump_cap", self.jump_cap, self.kidnap_cap, self.prior_cap)
        real("outlier_share", self.outlier_share, 0.0, 1.0, low_open=True, high_open=True)
        real("sighting_outlier", self.sighting_outlier, 0.0, 1.0, low_open=True, high_open=True)
        real("teammate_mirrored", self.teammate_mirrored, 0.0, 0.5, low_open=True, high_open=True)
        trust = self.teammate_trust
        if trust >= self.prior_cap + self.flip:
            raise ValueError(
                f"teammate_mirrored = {self.teammate_mirrored!r}: one teammate could move the odds by "
                f"{trust:.2f} >= prior_cap + flip = {self.prior_cap + self.flip:.2f}: one teammate "
                "alone must never flip a robot its own prior holds"
            )
        if 2 * trust <= self.prior_cap + self.flip:
            raise ValueError(
                f"teammate_mirrored = {self.teammate_mirrored!r}: two agreeing teammates move the odds "
                f"by {2 * trust:.2f} <= prior_cap + flip = {self.prior_cap + self.flip:.2f}: two "
                "agreeing teammates must be able to flip"
            )

    @property
    def teammate_trust(self) -> float:
        """log((1 − q) / q): the most one teammate can move the odds, q = `teammate_mirrored`."""
        return math.log((1.0 - self.teammate_mirrored) / self.teammate_mirrored)


AGE_STEP = 1.0  # s: the teammates' flags are aged at most this often (the hazard is slow)


@dataclass(frozen=True)
class Team:
    """Who the robot is and whom it listens to.

    Parameters
    ----------
    player_number : int or None, default None
        The robot's own number (1..20): a team message from it is refused. None: not checked.
    teammates : iterable of int or None, default None
        The numbers of the teammates whose messages are accepted (kept as a sorted tuple); None: any number but
        the robot's own.

    Raises
    ------
    ValueError
        For a number outside 1..20, or the robot's own number among its teammates (TypeError, also a
        ValueError, for a wrong type).
    """

    player_number: int | None = None
    teammates: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        if self.player_number is not None:
            object.__setattr__(
                self, "player_number", integer("player_number", self.player_number, 1, MAX_PLAYER_NUMBER)
            )
        if self.teammates is not None:
            try:
                numbers = tuple(sorted({integer("teammates", n, 1, MAX_PLAYER_NUMBER) for n in self.teammates}))
            except TypeError:
                raise ArgumentTypeError(f"teammates = {self.teammates!r} must be player numbers") from None
            if self.player_number in numbers:
                raise ValueError(f"teammates = {numbers!r} must not hold the robot's own number {self.player_number}")
            object.__setattr__(self, "teammates", numbers)

    def accepts(self, sender: int) -> bool:
        """Whether a message from `sender` is a teammate's."""
        return sender != self.player_number and (self.teammates is None or sender in self.teammates)


@functools.cache
def _masks(teammates: int, j: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For a joint over the robot's side and `teammates` flags, teammate j's masks: the states in which its
    report speaks against the main pose (side bit XOR its flag), those in which it is on the mirror, and the
    index of each state with its flag swapped."""
    index = np.arange(1 << (teammates + 1))
    bit = 1 << (j + 1)
    on_mirror = (index & bit) != 0
    against = ((index & 1) != 0) != on_mirror
    for array in (index, on_mirror, against):
        array.setflags(write=False)
    return against, on_mirror, index ^ bit


@dataclass
class _Sighting:
    """One of the robot's own ball sightings, on the field through the main pose at its capture time; `fits`:
    for the reports compared with it, per row and state of the joint, their summed log-likelihoods
    (`sensing.team.report_log_likelihoods`) and what they add to the joint together, as a mixture with the
    sighting being no ball (None before the first report)."""

    time: float
    point: np.ndarray
    covariance: np.ndarray
    fits: tuple[np.ndarray, np.ndarray] | None = None


class SideBelief:
    """The joint belief over the robot's side and its teammates' (see the module docstring); one per localizer.

    State index bits: bit 0 the robot's side (0: the main pose, 1: its mirror image), bit j + 1 teammate j's
    flag (1: on the mirror). `_log_joint` holds log p(reports | state) + log p(teammates' flags); the
    robot's own prior on its side is added when the odds are read (`log_odds`). Its row 0 is the joint over
    every report, its row j + 1 the same joint without teammate j's reports (`held_team_log_odds`).

    Attributes
    ----------
    settings : SideSettings
    reports : int
        Teammate reports compared with a sighting of the robot's own so far.
    ignored : int
        Reports that could not be compared (no ball, too old, far from both sides' sightings, too many
        teammates).
    unconfirmed : int
        Sightings of the robot's own not used: nothing seen at the same place just before.
    """

    def __init__(self, field: Field, settings: SideSettings = SideSettings()) -> None:
        if not isinstance(settings, SideSettings):
            raise ValueError(f"settings = {settings!r} must be an mcl.side.SideSettings")
        self.settings = settings
        self._area = 4.0 * field.half_length * field.half_width
        # a sighting of the robot's own is no ball, or the ball its teammates report (`_report`)
        self._no_ball = math.log(settings.sighting_outlier)
        self._ball = math.log1p(-settings.sighting_outlier)
        self._senders: list[int] = []  # teammate j is bit j + 1
        self._log_joint = np.zeros((1, 2))  # over the robot's side alone, at first (row 0: every report)
        self._held: float | None = None  # held_team_log_odds, until the joint changes
        self._joint_time: float | None = None  # when the teammates' flags were last aged
        self._side_evidence = False  # whether the joint says anything of the side
        self._latest: dict[int, TeamMessage] = {}  # sender: its newest message
        self._used: dict[int, float] = {}  # sender: its sighting last compared
        # the robot's own confirmed sightings of the last `past` seconds, by capture time (and their times)
        self._confirmed: list[_Sighting] = []
        self._confirmed_times: list[float] = []
        self._recent: list[_Sighting] = []  # own sightings of the last `confirm_window` s
        self._below_since: float | None = None
        self._prior = 0.0  # the robot's own prior, as last read
        self.reports = 0
        self.ignored = 0
        self.unconfirmed = 0

    # -- reading it --------------------------------------------------------------------------------------------
    def _side_marginals(self) -> np.ndarray:
        """Per row of the joint, log p(reports | main) − log p(reports | mirror), the teammates' flags summed
        out."""
        joint = self._log_joint
        return np.logaddexp.reduce(joint[:, 0::2], axis=1) - np.logaddexp.reduce(joint[:, 1::2], axis=1)

    def _side_marginal(self) -> float:
        """log p(reports | main) − log p(reports | mirror) over every report."""
        joint = self._log_joint[0]
        return float(np.logaddexp.reduce(joint[0::2]) - np.logaddexp.reduce(joint[1::2]))

    def team_log_odds(self) -> float:
        """What the teammates' reports say of the robot's side (log odds of the main pose; 0: nothing)."""
        return self._side_marginal() if self._side_evidence else 0.0

    def held_team_log_odds(self) -> float:
        """The teammates' evidence for the main pose that holds without any one of them: the least of
        `team_log_odds` and of the same odds with each teammate's reports left out in turn (0: nothing). One
        teammate alone never raises it above 0, however sure it is; two that agree do."""
        if not self._side_evidence:
            return 0.0
        if self._held is None:
            self._held = float(self._side_marginals().min())
        return self._held

    def _capped_prior(self, prior_log_odds: float, kidnapped: bool, jumped: bool) -> float:
        s = self.settings
        cap = s.kidnap_cap if kidnapped else s.jump_cap if jumped else s.prior_cap
        return 0.0 if math.isnan(prior_log_odds) else min(max(prior_log_odds, -cap), cap)

    def log_odds(self, prior_log_odds: float, kidnapped: bool = False, jumped: bool = False) -> float:
        """The log odds of the main pose against its mirror image: the prior, capped at `prior_cap` (at
        `kidnap_cap` when it rests on a kidnapping law, `kidnapped`, at `jump_cap` when on the distance part of
        one, `jumped`; NaN counts as even), plus the teammates' evidence."""
        prior = self._capped_prior(prior_log_odds, kidnapped, jumped)
        self._prior = prior
        return prior + self.team_log_odds()

    def held_log_odds(self, prior_log_odds: float, kidnapped: bool = False, jumped: bool = False) -> float:
        """As `log_odds`, with the teammates' evidence that holds without any one of them
        (`held_team_log_odds`): what the quality asks, so that no single teammate makes a pose sure of its
        half."""
        return self._capped_prior(prior_log_odds, kidnapped, jumped) + self.held_team_log_odds()

    def teammate_mirrored(self, sender: int) -> float | None:
        """The probability that teammate `sender` is on the mirror (None: not heard from, or not modelled)."""
        if sender not in self._senders:
            return None
        bit = 1 << (self._senders.index(sender) + 1)
        full = self._log_joint[0]
        index = np.arange(full.shape[0])
        joint = full - np.logaddexp.reduce(full)
        return float(np.exp(joint[(index & bit) != 0]).sum())

    @property
    def teammates(self) -> tuple[int, ...]:
        """The senders modelled so far, in the order they were first heard from."""
        return tuple(self._senders)

    @property
    def holds_evidence(self) -> bool:
        """Whether anything here belongs to the current main pose (evidence of its side, the robot's own
        sightings placed through it)."""
        return bool(self._side_evidence or self._recent or self._confirmed)

    # -- the evidence ----------------------------------------------------------------------------------------
    def message(self, message: TeamMessage, now: float) -> None:
        """A teammate's message arrived (`now`: the robot's clock); kept if it is its newest, and compared with
        the robot's confirmed sighting nearest in time to the teammate's, when the two are close enough in time
        (`horizon`)."""
        latest = self._latest.get(message.sender)
        if latest is not None and latest.received_time > message.received_time:
            self.ignored += 1  # an older message arriving late: its newer one is kept
            return
        self._latest[message.sender] = message
        if self._confirmed:
            self._compare(message.sender, now)

    def sighting(
        self, detection: BallDetection, pose: np.ndarray, pose_covariance: np.ndarray, capture_time: float, now: float
    ) -> None:
        """The robot saw the ball at `capture_time`, where the main estimate was `pose` (x, y, θ) with
        `pose_covariance`: once confirmed, compared with each teammate's newest report not yet compared."""
        s = self.settings
        point, covariance = ball_on_field(pose, pose_covariance, detection)
        new = _Sighting(capture_time, point, covariance)
        self._recent = [old for old in self._recent if 0.0 <= capture_time - old.time <= s.confirm_window]
        confirmed = any(
            float(np.hypot(*(old.point - point))) <= s.confirm_distance + s.rolling_sigma * (capture_time - old.time)
            for old in self._recent
        )
        self._recent.append(new)
        if not confirmed:
            self.unconfirmed += 1
            return
        at = bisect.bisect_right(self._confirmed_times, capture_time)  # the end, unless frames came out of order
        self._confirmed.insert(at, new)
        self._confirmed_times.insert(at, capture_time)
        old = bisect.bisect_left(self._confirmed_times, capture_time - s.past)
        del self._confirmed[:old], self._confirmed_times[:old]
        for sender in list(self._latest):
            self._compare(sender, now)

    def _compare(self, sender: int, now: float) -> None:
        message = self._latest[sender]
        # each sighting of a teammate's is evidence once (against the first sighting of the robot's own it is
        # compared with): its error is one error, however often it is repeated (a growing age) or compared
        seen = round(message.sighting_time, 3)
        if self._used.get(sender) == seen:
            return
        # the robot's own confirmed sighting nearest in time to the teammate's (sightings of one ball, the less
        # time apart the less it can have moved)
        times = self._confirmed_times
        at = bisect.bisect_left(times, message.sighting_time)
        if at == len(times) or (at > 0 and message.sighting_time - times[at - 1] <= times[at] - message.sighting_time):
            at -= 1
        sighting = self._confirmed[at]
        s = self.settings
        report = teammate_ball(message, sighting.time, s.rolling_sigma, s.horizon)
        if report is None:
            self.ignored += 1
            return
        point, covariance = report
        if message.is_goalkeeper and message.pose[0] > 0.0:
            point = -point  # a goalkeeper in the opponent half is on the mirror: so is its ball
        total = sighting.covariance + covariance
        if min(mahalanobis2(sighting.point - point, total), mahalanobis2(-sighting.point - point, total)) > s.gate:
            self.ignored += 1
            return
        self._used[sender] = seen
        if sender not in self._senders:
            if len(self._senders) >= s.max_teammates:
                self.ignored += 1
                return
            self._add_teammate(sender)
        self._age(now)
        near, far = report_log_likelihoods(
            sighting.point, sighting.covariance, point, covariance, s.outlier_share, self._area
        )
        self._report(self._senders.index(sender), near, far, sighting)
        self.reports += 1

    def _report(self, j: int, near: float, far: float, sighting: _Sighting) -> None:
        """Teammate j's report, compared with `sighting`, fits the main pose by `near` and its mirror image by
        `far`: into every row of the joint but the one that leaves teammate j out, together with the reports
        compared with the same sighting before (see the module docstring)."""
        # the report supports the main pose when the robot's side and the teammate's flag agree (both 0 or 1)
        against = _masks(len(self._senders), j)[0]
        term = np.where(against, far, near)
        joint = self._log_joint
        if sighting.fits is None:
            sums = np.repeat(term[np.newaxis], joint.shape[0], axis=0)
            sums[j + 1] = 0.0
        else:
            sums = sighting.fits[0].copy()
            sums[: j + 1] += term
            sums[j + 2 :] += term
            # (taken out of a joint whose flags may have aged since: they change at `teammate_hazard`, about 1 %
            # a second, and a sighting's reports come within `horizon` of it)
            joint -= sighting.fits[1]
        mixture = np.logaddexp(self._no_ball, sums + self._ball)
        sighting.fits = sums, mixture
        joint += mixture
        joint -= joint.max(axis=1, keepdims=True)
        self._side_evidence = True
        self._held = None

    def _add_teammate(self, sender: int) -> None:
        """A new flag in every row, and a row without the new teammate: so far, the joint over every report."""
        q = self.settings.teammate_mirrored
        self._senders.append(sender)
        joint = self._log_joint
        joint = np.concatenate([joint + math.log1p(-q), joint + math.log(q)], axis=1)
        self._log_joint = np.concatenate([joint, joint[:1]])
        self._held = None
        for sighting in self._confirmed:  # the reports so far say nothing of the new flag
            if sighting.fits is not None:
                sums, mixture = (np.concatenate([array, array], axis=1) for array in sighting.fits)
                sighting.fits = np.concatenate([sums, sums[:1]]), np.concatenate([mixture, mixture[:1]])

    def _age(self, now: float) -> None:
        """The teammates' flags may have changed since the last report: each flag is a two-state Markov chain
        that changes at rate `teammate_hazard` towards its prior (on the mirror with probability q), so a
        teammate falls onto the mirror at rate hazard · q and recovers at rate hazard · (1 − q)."""
        if self._joint_time is not None and now - self._joint_time < AGE_STEP:
            return  # evaluated in steps of AGE_STEP: the hazard is far slower than that
        if self._joint_time is not None and now > self._joint_time and self._senders:
            s = self.settings
            share = -math.expm1(-s.teammate_hazard * (now - self._joint_time))
            if share > 0.0:
                q = s.teammate_mirrored
                fall, recover = share * q, share * (1.0 - q)
                stay_0, stay_1 = math.log1p(-fall), math.log1p(-recover)
                arrive_0, arrive_1 = math.log(recover), math.log(fall)
                for j in range(len(self._senders)):
                    _, on_mirror, swapped = _masks(len(self._senders), j)
                    stay = np.where(on_mirror, stay_1, stay_0)
                    arrive = np.where(on_mirror, arrive_1, arrive_0)
                    self._log_joint = np.logaddexp(self._log_joint + stay, self._log_joint[:, swapped] + arrive)
                self._held = None
        self._joint_time = now if self._joint_time is None else max(self._joint_time, now)

    # -- what the localizer tells it -------------------------------------------------------------------------
    @property
    def flip_pending(self) -> bool:
        """Whether the odds were below −`flip` when `should_flip` last asked: a side change waits for
        `flip_hold` seconds to pass, reports or not."""
        return self._below_since is not None

    def should_flip(self, log_odds: float, now: float) -> bool:
        """Whether the robot should change sides now: the log odds below −`flip` for `flip_hold` seconds."""
        if log_odds >= -self.settings.flip:
            self._below_since = None
            return False
        if self._below_since is None:
            self._below_since = now
        return now - self._below_since >= self.settings.flip_hold

    def mirrored(self) -> None:
        """The main pose became its mirror image: the robot's side swaps in the joint belief."""
        index = np.arange(self._log_joint.shape[1])
        self._log_joint = self._log_joint[:, index ^ 1]
        self._held = None
        for sighting in self._recent:
            sighting.point = -sighting.point
        for sighting in self._confirmed:
            if all(sighting is not r for r in self._recent):
                sighting.point = -sighting.point
            if sighting.fits is not None:
                sighting.fits = sighting.fits[0][:, index ^ 1], sighting.fits[1][:, index ^ 1]
        self._below_since = None

    def moved(self) -> None:
        """The main pose moved somewhere new (a re-localization or a placement): what the reports said of the
        robot's side is dropped, what they said of the teammates is kept (the side summed out with the prior it
        had when last read). The teammates' newest messages stay, to be compared with the next sighting."""
        if self._side_evidence:
            prior = self._prior
            main, mirror = -math.log1p(math.exp(-prior)), -math.log1p(math.exp(prior))
            teammates = np.logaddexp(self._log_joint[:, 0::2] + main, self._log_joint[:, 1::2] + mirror)
            teammates -= teammates.max(axis=1, keepdims=True)
            self._log_joint = np.repeat(teammates, 2, axis=1)
            self._held = None
        self._side_evidence = False
        self._used.clear()
        self._confirmed.clear()
        self._confirmed_times.clear()
        self._recent = []
        self._below_since = None
