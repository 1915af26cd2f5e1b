"""Which half: the belief that the robot is where its estimate says and not on the mirror image, from its own
prior and its teammates' view of the ball.

    from mcl.side import SideBelief, SideSettings

    side = SideBelief(field, SideSettings())
    side.log_odds(prior_log_odds, now)          # main pose against its mirror image

The field is point-symmetric, so the landmarks never tell a pose from its mirror image (−x, −y, θ+π); the mirror
hypothesis is always exactly as well supported by them as the main one. So it is kept as an explicit second
hypothesis, at the point image of the main estimate, with log odds that sum two kinds of evidence:

1. **The robot's own prior** (the re-localization's `mirror_log_odds`: continuity with the last confident
   pose, the placement region), capped at `prior_cap`: continuity holds a robot on its side, but no prior is
   certain (the kidnapping it assumes may not be the one that happened).
2. **The ball, seen by the robot and by its teammates** (`sensing.team.side_evidence`): each teammate's report
   compared once with the robot's own sighting of the ball (placed on the field through the main pose, and
   through its mirror image). Robust at every level: one report moves the odds by a bounded amount
   (`outlier_share`), one teammate's evidence is capped at `per_teammate` (a teammate can itself be mirrored
   with high stated confidence, and its errors are correlated over time), the evidence fades with `memory`
   seconds (the ball and the teammates move on), and a ball near the centre mark weighs almost nothing. A
   goalkeeper that believes it stands in the opponent half is itself on the mirror (a goalkeeper keeps to its
   own goal): its reports are taken mirrored.

The caps are chosen so that one teammate alone can decide a robot whose own prior is even, but never flip a
robot that its continuity holds (`per_teammate` < `prior_cap` + `flip`), while two agreeing teammates can
(2 · `per_teammate` > `prior_cap` + `flip`). `SideSettings` checks both.

The robot changes sides (mirrors its particles: exact, since the likelihood is symmetric) when the log odds
stay below −`flip` for `flip_hold` seconds, so that a teammate's evidence is weighed against the others'
before it acts. This module holds the numbers; `mcl.localizer.Localizer` feeds it and flips the filter.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from field import Field
from sensing.team import BallDetection, TeamMessage, ball_on_field, side_evidence, teammate_ball


@dataclass(frozen=True)
class SideSettings:
    """The weights of the side evidence (see the module docstring).

    Parameters
    ----------
    outlier_share : float, default 0.2
        Probability that a teammate's ball report has nothing to do with the ball the robot sees (a wrong
        teammate, another ball, a kick in between), within (0, 1): bounds what one report can say.
    rolling_sigma : float, default 1.0
        How fast the ball may have moved unseen [m/s], > 0: widens a report by this times its age.
    horizon : float, default 2.0
        A report is compared with the robot's sighting only when the two sightings are at most this far apart
        in time [s], > 0.
    per_teammate : float, default 4.5
        The most one teammate's evidence can move the log odds, > 0.
    prior_cap : float, default 4.6
        The most the robot's own prior can hold the log odds (log 100), > 0.
    flip : float, default 2.3
        The robot changes sides when the log odds stay below −flip (log 10) ...
    flip_hold : float, default 1.0
        ... for this many seconds, >= 0.
    memory : float, default 20.0
        Time constant [s] with which a teammate's evidence fades, > 0.
    confirm_window : float, default 0.5
        A sighting of the robot's own is used once another one within this many seconds before it lies at the
        same place [s], > 0: a false detection is rarely seen twice in the same place ...
    confirm_distance : float, default 0.5
        ... within this distance [m] plus `rolling_sigma` times the time between them (>= 0).
    gate : float, default 9.21
        A report is compared only when it lies within this squared Mahalanobis distance of the robot's
        sighting or of its mirror image (9.21: 99 % of a two-dimensional normal), > 0: far from both, one of
        the two sightings is wrong, and which of the two sides is nearer says nothing.
    future : float, default 1.0
        A message sent more than this far in the future of the robot's clock is refused [s], >= 0.
    past : float, default 10.0
        A message sent more than this long ago is refused [s], > 0.

    Raises
    ------
    ValueError
        For a value out of its range, or caps that let one teammate flip a robot its prior holds
        (per_teammate >= prior_cap + flip) or that two agreeing teammates cannot flip it
        (2 · per_teammate <= prior_cap + flip).
    """

    outlier_share: float = 0.2
    rolling_sigma: float = 1.0
    horizon: float = 2.0
    per_teammate: float = 4.5
    prior_cap: float = 4.6
    flip: float = 2.3
    flip_hold: float = 1.0
    memory: float = 20.0
    confirm_window: float = 0.5
    confirm_distance: float = 0.5
    gate: float = 9.21
    future: float = 1.0
    past: float = 10.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or value < 0:
                raise ValueError(f"{f.name} = {value!r} must be a finite number >= 0")
        for name in ("rolling_sigma", "horizon", "per_teammate", "prior_cap", "flip", "memory", "past",
                     "confirm_window", "gate"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} = {getattr(self, name)!r} must be > 0")
        if not 0 < self.outlier_share < 1:
            raise ValueError(f"outlier_share = {self.outlier_share!r} must be within (0, 1)")
        if self.per_teammate >= self.prior_cap + self.flip:
            raise ValueError(f"per_teammate = {self.per_teammate!r} must be < prior_cap + flip = "
                             f"{self.prior_cap + self.flip!r}: one teammate alone must never flip a robot its own "
                             "prior holds")
        if 2 * self.per_teammate <= self.prior_cap + self.flip:
            raise ValueError(f"per_teammate = {self.per_teammate!r} must be > (prior_cap + flip) / 2 = "
                             f"{0.5 * (self.prior_cap + self.flip)!r}: two agreeing teammates must be able to flip")


def _mahalanobis2(d: np.ndarray, covariance: np.ndarray) -> float:
    a, b, c = covariance[0, 0], covariance[0, 1], covariance[1, 1]
    return float((c * d[0] * d[0] - 2.0 * b * d[0] * d[1] + a * d[1] * d[1]) / (a * c - b * b))


@dataclass
class _Sighting:
    """The robot's own latest ball sighting, on the field through the main pose at its capture time."""

    time: float
    point: np.ndarray
    covariance: np.ndarray


class SideBelief:
    """The log odds of the main pose against its mirror image (see the module docstring); one per localizer.

    Attributes
    ----------
    settings : SideSettings
    reports : int
        Teammate reports compared with a sighting of the robot's own so far.
    ignored : int
        Reports that could not be compared (no ball, too old, far from both sides' sightings).
    unconfirmed : int
        Sightings of the robot's own not used: nothing seen at the same place just before.
    """

    def __init__(self, field: Field, settings: SideSettings = SideSettings()) -> None:
        if not isinstance(settings, SideSettings):
            raise ValueError(f"settings = {settings!r} must be an mcl.side.SideSettings")
        self.settings = settings
        self._area = 4.0 * field.half_length * field.half_width
        self._evidence: dict[int, tuple[float, float]] = {}    # sender: (log odds, time it was last updated)
        self._latest: dict[int, TeamMessage] = {}             # sender: its newest message
        self._used: dict[int, float] = {}                     # sender: send time of its last message compared
        self._sighting: _Sighting | None = None
        self._recent: list[_Sighting] = []       # the robot's own sightings of the last `confirm_window` seconds
        self._below_since: float | None = None
        self.reports = 0
        self.ignored = 0
        self.unconfirmed = 0

    # -- the evidence --------------------------------------------------------------------------------------
    def team_log_odds(self, now: float) -> float:
        """The teammates' evidence at time `now`: each teammate's, faded and capped, summed."""
        s = self.settings
        total = 0.0
        for value, since in self._evidence.values():
            faded = value * math.exp(-max(now - since, 0.0) / s.memory)
            total += min(max(faded, -s.per_teammate), s.per_teammate)
        return total

    def log_odds(self, prior_log_odds: float, now: float) -> float:
        """The log odds of the main pose against its mirror image: the prior, capped at `prior_cap` (NaN counts
        as even), plus the teammates' evidence."""
        cap = self.settings.prior_cap
        prior = 0.0 if math.isnan(prior_log_odds) else min(max(prior_log_odds, -cap), cap)
        return prior + self.team_log_odds(now)

    @property
    def holds_evidence(self) -> bool:
        """Whether anything here belongs to the current main pose (teammates' evidence, the robot's own
        sightings placed through it)."""
        return bool(self._evidence or self._recent or self._sighting is not None)

    @property
    def teammates(self) -> tuple[int, ...]:
        """The senders heard from so far (sorted)."""
        return tuple(sorted(self._latest))

    def message(self, message: TeamMessage, now: float) -> None:
        """A teammate's message arrived (`now`: the robot's clock); kept if it is its newest, and compared with
        the robot's latest sighting when the two are close enough in time."""
        latest = self._latest.get(message.sender)
        if latest is not None and latest.received_time > message.received_time:
            self.ignored += 1            # an older message arriving late: its newer one was already used
            return
        self._latest[message.sender] = message
        if self._sighting is not None:
            self._compare(message.sender, now)

    def sighting(self, detection: BallDetection, pose: np.ndarray, pose_covariance: np.ndarray,
                 capture_time: float, now: float) -> None:
        """The robot saw the ball at `capture_time`, where the main estimate was `pose` (x, y, θ) with
        `pose_covariance`: compared with each teammate's newest report not yet compared."""
        s = self.settings
        point, covariance = ball_on_field(pose, pose_covariance, detection)
        new = _Sighting(capture_time, point, covariance)
        self._recent = [old for old in self._recent if 0.0 <= capture_time - old.time <= s.confirm_window]
        confirmed = any(np.hypot(*(old.point - point)) <= s.confirm_distance + s.rolling_sigma * (capture_time - old.time)
                        for old in self._recent)
        self._recent.append(new)
        if not confirmed:
            self.unconfirmed += 1
            return
        self._sighting = new
        for sender in list(self._latest):
            self._compare(sender, now)

    def _compare(self, sender: int, now: float) -> None:
        message = self._latest[sender]
        sighting = self._sighting
        assert sighting is not None
        if self._used.get(sender) == message.received_time:
            return                      # each report is evidence once: a teammate's errors persist
        s = self.settings
        report = teammate_ball(message, sighting.time, s.rolling_sigma, s.horizon)
        if report is None:
            self.ignored += 1
            self._used[sender] = message.received_time
            return
        point, covariance = report
        if message.is_goalkeeper and message.pose[0] > 0.0:
            point = -point              # a goalkeeper in the opponent half is on the mirror: so is its ball
        total = sighting.covariance + covariance
        if min(_mahalanobis2(sighting.point - point, total), _mahalanobis2(-sighting.point - point, total)) > s.gate:
            self.ignored += 1
            self._used[sender] = message.received_time
            return
        value = side_evidence(sighting.point, sighting.covariance, point, covariance, s.outlier_share, self._area)
        old, since = self._evidence.get(sender, (0.0, now))
        faded = old * math.exp(-max(now - since, 0.0) / s.memory)
        # the running sum is kept within the cap: evidence beyond it would take as long to undo
        self._evidence[sender] = (min(max(faded + value, -s.per_teammate), s.per_teammate), now)
        self._used[sender] = message.received_time
        self.reports += 1

    # -- what the localizer tells it -------------------------------------------------------------------------
    def should_flip(self, log_odds: float, now: float) -> bool:
        """Whether the robot should change sides now: the log odds below −`flip` for `flip_hold` seconds."""
        if log_odds >= -self.settings.flip:
            self._below_since = None
            return False
        if self._below_since is None:
            self._below_since = now
        return now - self._below_since >= self.settings.flip_hold

    def mirrored(self) -> None:
        """The main pose became its mirror image: the evidence changes sign."""
        self._evidence = {sender: (-value, since) for sender, (value, since) in self._evidence.items()}
        for sighting in self._recent:
            sighting.point = -sighting.point       # (the latest sighting is among them)
        if self._sighting is not None and all(self._sighting is not r for r in self._recent):
            self._sighting.point = -self._sighting.point
        self._below_since = None

    def moved(self) -> None:
        """The main pose moved somewhere new (a re-localization or a placement): evidence about where it was
        says nothing about it; the teammates' newest messages stay, to be compared with the next sighting."""
        self._evidence.clear()
        self._used.clear()
        self._sighting = None
        self._recent = []
        self._below_since = None
