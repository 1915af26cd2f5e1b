"""What teammates say and where the robot sees the ball: the evidence that tells the field's halves apart.

    from sensing.team import BallDetection, TeamMessage

    message = TeamMessage(sender=2, time=t_sent, pose=(-3.1, 0.4, 0.2), pose_covariance=None, confidence=0.9,
                          ball=(-1.0, 0.5), ball_age=0.3)
    loc.team_message(message)                            # as it arrives: late, lossy, in any order
    loc.observe_ball(BallDetection(range=2.1, bearing=-0.3), capture_time=t_image)

The field is point-symmetric: a pose and its mirror image (−x, −y, θ+π) see the same landmarks, so no
landmark tells them apart. The ball does, when somebody else sees it too. The robot's own sighting, placed on
the field through its pose, lands at b; through the mirror pose at −b. A teammate that reports the ball at p
makes the pose more probable than its mirror by the likelihood ratio of b and −b against p (`side_evidence`):
large when the ball is far from the centre mark, nothing when it lies on it.

Everything here is a plain data type or a pure function on numbers; how much a teammate is believed, and when
a robot changes sides, is `mcl.side`'s business.

Conventions: the field frame (metres, radians; +x toward the opponent goal); a detection in the robot frame
(x forward, y left); times in seconds on the receiving robot's clock (`TeamMessage.clock_offset` converts the
sender's clock to it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from field.checks import (
    LARGEST_ANGLE,
    LARGEST_COORDINATE,
    LARGEST_SIGMA,
    SMALLEST_SIGMA,
    ArgumentTypeError,
    integer,
    real,
    reals,
)
from numerics.frozen import keeps_arrays_frozen

MAX_PLAYER_NUMBER = 20
"""The largest player number a message may carry (the leagues number players from 1)."""
LARGEST_TIME = 1e9
"""The largest |time| [s] a message or detection may carry (about 30 years)."""
LARGEST_SPEED = 100.0
"""The largest ball speed [m/s] a message may report (far beyond a kick)."""
LARGEST_AGE = 3600.0
"""The oldest ball sighting [s] a message may report."""
_EYE2 = np.eye(2)
_EYE2.setflags(write=False)


def _covariance(name: str, value: Any, size: int) -> np.ndarray:
    """`value` as a symmetric positive definite (size, size) float64 matrix, variances within the library's
    sigma range; ValueError (TypeError for a non-numeric value) naming it otherwise."""
    try:
        matrix = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ArgumentTypeError(f"{name} = {value!r} must be a {size}x{size} matrix of numbers") from None
    if matrix.shape != (size, size):
        raise ValueError(f"{name} must have shape ({size}, {size}), not {matrix.shape}")
    if not np.isfinite(matrix).all():
        raise ValueError(f"{name} must be finite, got {matrix.tolist()!r}")
    if not np.allclose(matrix, matrix.T, rtol=1e-9, atol=1e-12):
        raise ValueError(f"{name} must be symmetric, got {matrix.tolist()!r}")
    matrix = 0.5 * (matrix + matrix.T)
    diagonal = np.diag(matrix)
    if (diagonal < SMALLEST_SIGMA**2).any() or (diagonal > LARGEST_SIGMA**2).any():
        raise ValueError(
            f"{name}: each variance must be within [{SMALLEST_SIGMA**2:g}, {LARGEST_SIGMA**2:g}], "
            f"got {diagonal.tolist()!r}"
        )
    try:
        np.linalg.cholesky(matrix)
    except np.linalg.LinAlgError:
        raise ValueError(f"{name} must be positive definite, got {matrix.tolist()!r}") from None
    matrix.setflags(write=False)
    return matrix


def _optional_point(name: str, value: Any, low: float, high: float) -> tuple[float, float] | None:
    if value is None:
        return None
    point = reals(name, value, 2, low, high)
    return float(point[0]), float(point[1])


@keeps_arrays_frozen
@dataclass(frozen=True, eq=False)
class TeamMessage:
    """What one teammate broadcasts, in field coordinates (its own belief: it may be wrong, even mirrored).

    Parameters
    ----------
    sender : int
        The teammate's player number, within [1, `MAX_PLAYER_NUMBER`].
    time : float
        When it was sent [s], on the sender's clock (`clock_offset` converts it to the receiver's).
    pose : sequence of 3 floats
        Its pose estimate (x [m], y [m], θ [rad]).
    pose_covariance : 3x3 array_like or None, default None
        The covariance of that pose (symmetric positive definite); None: derived from `confidence`.
    confidence : float or None, default None
        Instead of a covariance: how sure it is of its pose, within [0, 1] (None with no covariance: 0.5).
    is_goalkeeper : bool, default False
        Whether the sender is the goalkeeper (it stays near its own goal: a goalkeeper that believes it is near
        the opponent goal is itself on the mirror).
    ball : sequence of 2 floats or None, default None
        Where it believes the ball is (x [m], y [m]), at its last sighting; None: no ball.
    ball_velocity : sequence of 2 floats or None, default None
        The ball's velocity (vx, vy) [m/s] at that sighting, when the teammate estimates it.
    ball_age : float, default 0.0
        Seconds between its last sighting of the ball and `time`, within [0, `LARGEST_AGE`].
    ball_covariance : 2x2 array_like or None, default None
        The covariance of `ball` [m²]; None: derived from the pose's uncertainty and the distance to the ball.
    clock_offset : float, default 0.0
        Add to `time` to get the receiver's clock [s] (0: the team shares one clock).

    Raises
    ------
    ValueError
        For a value that is not finite or out of its range, a covariance that is not symmetric positive
        definite; TypeError (`field.checks.ArgumentTypeError`, also a ValueError) for a wrong type.

    Two messages compare equal only when they are the same object (one broadcast is one message).
    """

    sender: int
    time: float
    pose: tuple[float, float, float]
    pose_covariance: Any = None
    confidence: float | None = None
    is_goalkeeper: bool = False
    ball: tuple[float, float] | None = None
    ball_velocity: tuple[float, float] | None = None
    ball_age: float = 0.0
    ball_covariance: Any = None
    clock_offset: float = 0.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "sender", integer("sender", self.sender, 1, MAX_PLAYER_NUMBER))
        set_(self, "time", real("time", self.time, -LARGEST_TIME, LARGEST_TIME))
        set_(self, "clock_offset", real("clock_offset", self.clock_offset, -LARGEST_TIME, LARGEST_TIME))
        pose = reals("pose", self.pose, 3, -LARGEST_COORDINATE, LARGEST_COORDINATE)
        if abs(pose[2]) > LARGEST_ANGLE:
            raise ValueError(f"pose heading = {pose[2]!r} must be within ±{LARGEST_ANGLE:g} rad")
        set_(self, "pose", (float(pose[0]), float(pose[1]), math.remainder(float(pose[2]), 2 * math.pi)))
        if self.pose_covariance is not None:
            set_(self, "pose_covariance", _covariance("pose_covariance", self.pose_covariance, 3))
        if self.confidence is not None:
            set_(self, "confidence", real("confidence", self.confidence, 0.0, 1.0))
        if not isinstance(self.is_goalkeeper, (bool, np.bool_)):
            raise ArgumentTypeError(f"is_goalkeeper = {self.is_goalkeeper!r} must be True or False")
        set_(self, "is_goalkeeper", bool(self.is_goalkeeper))
        set_(self, "ball", _optional_point("ball", self.ball, -LARGEST_COORDINATE, LARGEST_COORDINATE))
        set_(self, "ball_velocity", _optional_point("ball_velocity", self.ball_velocity, -LARGEST_SPEED, LARGEST_SPEED))
        set_(self, "ball_age", real("ball_age", self.ball_age, 0.0, LARGEST_AGE))
        if self.ball_covariance is not None:
            set_(self, "ball_covariance", _covariance("ball_covariance", self.ball_covariance, 2))

    @property
    def received_time(self) -> float:
        """`time` on the receiver's clock [s]."""
        return self.time + self.clock_offset

    @property
    def sighting_time(self) -> float:
        """When the teammate last saw the ball, on the receiver's clock [s]."""
        return self.received_time - self.ball_age

    def pose_sigmas(self) -> tuple[float, float]:
        """(position σ [m], heading σ [rad]) of the sender's pose: from its covariance, else from its confidence
        (1: 0.05 m and 0.05 rad; 0: 2 m and 1 rad; linear in between)."""
        if self.pose_covariance is not None:
            cov = self.pose_covariance
            return math.sqrt(0.5 * (cov[0, 0] + cov[1, 1])), math.sqrt(cov[2, 2])
        confidence = 0.5 if self.confidence is None else self.confidence
        return 2.0 - 1.95 * confidence, 1.0 - 0.95 * confidence


@dataclass(frozen=True)
class BallDetection:
    """The robot's own sighting of the ball in one camera frame, in the robot frame.

    Parameters
    ----------
    range : float
        Distance to the ball [m], within [0, 1000].
    bearing : float
        Direction to the ball [rad], within ±100 rad (x forward, y left).
    range_sigma : float or None, default None
        Its standard deviation [m]; None: 0.05 m + 10 % of the range.
    bearing_sigma : float or None, default None
        Its standard deviation [rad]; None: 0.05 rad.

    Raises
    ------
    ValueError
        For a value that is not finite or out of its range (TypeError for a wrong type).
    """

    range: float
    bearing: float
    range_sigma: float | None = None
    bearing_sigma: float | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "range", real("range", self.range, 0.0, LARGEST_COORDINATE))
        set_(self, "bearing", real("bearing", self.bearing, -LARGEST_ANGLE, LARGEST_ANGLE))
        if self.range_sigma is not None:
            set_(self, "range_sigma", real("range_sigma", self.range_sigma, SMALLEST_SIGMA, LARGEST_SIGMA))
        if self.bearing_sigma is not None:
            set_(self, "bearing_sigma", real("bearing_sigma", self.bearing_sigma, SMALLEST_SIGMA, LARGEST_SIGMA))

    def sigmas(self) -> tuple[float, float]:
        """(range σ [m], bearing σ [rad]), the defaults filled in."""
        range_sigma = 0.05 + 0.1 * self.range if self.range_sigma is None else self.range_sigma
        return range_sigma, 0.05 if self.bearing_sigma is None else self.bearing_sigma


def ball_on_field(
    pose: np.ndarray, pose_covariance: np.ndarray, detection: BallDetection
) -> tuple[np.ndarray, np.ndarray]:
    """Where a detection puts the ball on the field through `pose` (x, y, θ), and the covariance of that point
    from the pose's covariance (3x3) and the detection's noise (first order).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        The point (2,) [m] and its covariance (2, 2) [m²].
    """
    x, y, theta = float(pose[0]), float(pose[1]), float(pose[2])
    r, bearing = detection.range, detection.bearing
    range_sigma, bearing_sigma = detection.sigmas()
    angle = theta + bearing
    c, s = math.cos(angle), math.sin(angle)
    point = np.array([x + r * c, y + r * s])
    # d point / d (x, y, θ) and d point / d (range, bearing)
    pose_jacobian = np.array([[1.0, 0.0, -r * s], [0.0, 1.0, r * c]])
    detection_jacobian = np.array([[c, -r * s], [s, r * c]])
    covariance = (
        pose_jacobian @ np.asarray(pose_covariance, dtype=np.float64) @ pose_jacobian.T
        + detection_jacobian @ np.diag([range_sigma**2, bearing_sigma**2]) @ detection_jacobian.T
    )
    return point, covariance


def teammate_ball(
    message: TeamMessage, at_time: float, rolling_sigma: float = 1.0, horizon: float = 2.0
) -> tuple[np.ndarray, np.ndarray] | None:
    """Where `message` says the ball is at `at_time` (receiver's clock), and how uncertain that is; None when it
    reports no ball or its sighting is more than `horizon` seconds before (or after) `at_time`.

    The point is the reported ball moved on by its velocity (when given) for the time since the sighting. Its
    covariance adds: the reported ball covariance, or the sender's pose uncertainty carried to the ball (its
    position σ, and its heading σ times the distance to the ball); and the ball's unknown motion since the
    sighting, `rolling_sigma` [m/s] times the time elapsed (a kicked ball rolls several m/s).
    """
    if message.ball is None:
        return None
    elapsed = at_time - message.sighting_time
    if abs(elapsed) > horizon:
        return None
    point = np.array(message.ball, dtype=np.float64)
    if message.ball_velocity is not None and elapsed > 0:
        point = point + elapsed * np.asarray(message.ball_velocity)
    if message.ball_covariance is not None:
        covariance = np.array(message.ball_covariance, dtype=np.float64)
    else:
        position_sigma, heading_sigma = message.pose_sigmas()
        distance = math.hypot(point[0] - message.pose[0], point[1] - message.pose[1])
        variance = position_sigma**2 + (heading_sigma * distance) ** 2 + (0.05 + 0.1 * distance) ** 2
        covariance = _EYE2 * variance
    covariance = covariance + _EYE2 * (rolling_sigma * abs(elapsed)) ** 2
    return point, covariance


def mahalanobis2(d: np.ndarray, covariance: np.ndarray) -> float:
    """The squared Mahalanobis length of a 2-vector `d` under a (2, 2) covariance."""
    a, b, c = covariance[0, 0], covariance[0, 1], covariance[1, 1]
    return float((c * d[0] * d[0] - 2.0 * b * d[0] * d[1] + a * d[1] * d[1]) / (a * c - b * b))


def _log_normal2(d: np.ndarray, covariance: np.ndarray) -> float:
    det = covariance[0, 0] * covariance[1, 1] - covariance[0, 1] * covariance[0, 1]
    return -0.5 * mahalanobis2(d, covariance) - math.log(2.0 * math.pi) - 0.5 * math.log(det)


def report_log_likelihoods(
    own_point: np.ndarray,
    own_covariance: np.ndarray,
    team_point: np.ndarray,
    team_covariance: np.ndarray,
    outlier_share: float,
    area: float,
) -> tuple[float, float]:
    """How well a teammate's report of the ball fits the robot's own sighting placed through the pose, and
    through its mirror image: (log p(report | pose), log p(report | mirror pose)), each relative to a report
    that could be anywhere on the `area` [m²] (0: no better than anywhere).

    Through the pose the robot's sighting is at `own_point`; through the mirror pose at −`own_point` (the same
    covariance). The teammate's report is normal around the ball with the two covariances added, or, with
    probability `outlier_share`, anywhere on the area (the teammate is wrong, sees another ball, or the ball was
    kicked): each value is at least log(outlier_share).
    """
    covariance = own_covariance + team_covariance
    floor = math.log(outlier_share)
    keep = math.log1p(-outlier_share) + math.log(area)
    near = _logaddexp(keep + _log_normal2(own_point - team_point, covariance), floor)
    far = _logaddexp(keep + _log_normal2(-own_point - team_point, covariance), floor)
    return near, far


def side_evidence(
    own_point: np.ndarray,
    own_covariance: np.ndarray,
    team_point: np.ndarray,
    team_covariance: np.ndarray,
    outlier_share: float,
    area: float,
) -> float:
    """log p(teammate's ball | the pose) − log p(teammate's ball | its mirror image): how much one report of
    the ball by a teammate favours the robot's pose over its mirror image (`report_log_likelihoods`, the one
    less the other): at most about log(1 / outlier_share) from a report that fits one of the two places, and
    almost nothing from a ball near the centre mark, where b and −b are close.
    """
    near, far = report_log_likelihoods(own_point, own_covariance, team_point, team_covariance, outlier_share, area)
    return near - far


def _logaddexp(a: float, b: float) -> float:
    high, low = (a, b) if a >= b else (b, a)
    return high + math.log1p(math.exp(low - high))
