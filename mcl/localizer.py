"""One robot's localization in its control loop: motion in, detections in (with their capture time), pose,
quality and "lost" out, and the game's events as one call each.

    from field import spl
    from mcl.localizer import Localizer
    from motion_models import MotionInput

    loc = Localizer(spl(), n_particles=500, seed=0)     # velocity-linear motion, landmark sensor model
    loc.initial_placement()                              # INITIAL: on one of the own touchlines

    # every frame (100 Hz):
    loc.motion(t, MotionInput(dt=0.01, odometry=(dx, dy, dtheta)))   # t: end of the step [s]
    # whenever a camera frame arrives, however late:
    loc.observe(observations, capture_time=t_image)
    pose = loc.pose()                  # Estimate: pose [x, y, θ], covariance, weight
    loc.quality(), loc.is_lost         # Quality.SUPERB / OKAY / POOR, and a bool

Game events (what the SPL and Humanoid League rules make happen to a robot):

| call | when | belief afterwards |
|---|---|---|
| `initial_placement()` | INITIAL / entering the field | along both own touchlines, facing into the field |
| `kickoff_placement(poses)` | placed at kick-off positions | around the given poses (default: a typical line-up) |
| `manual_placement(poses)` | the referee placed it | around the given poses (default: anywhere in the own half, facing the opponent goal) |
| `anywhere_in_own_half()` | switched on or carried in, pose unknown | uniform over the own half, any heading |
| `penalty_return()` | back from a penalty | at the penalty-mark line on either own touchline, facing into the field |
| `fallen()` / `got_up()` | fall detected / standing again | corrections and motion paused; then widened by `getup_sigma` |
| `place(pose)` | pose known (a test stand, a set piece) | around that pose, its heading trusted |

After a reset over a region (the own half, both touchlines), re-localization treats the region as evidence
(`mcl.relocalization`): the point mirror of an own-half pose lies in the other half, so the filter settles on
the right one.

Latency. `observe(..., capture_time=)` scores the detections against where each particle was when the image
was taken (`mcl.latency`): the motion of the last `history` seconds is kept. An observation older than that is
refused with ValueError, and the filter is left as it was.

Quality (`QualityThresholds`), from how well the estimate explains the recent detections (`fit`: the share of
the detections of the last 1.5 s that a landmark of their type explains from the estimate, how long ago one
was last explained and how far the robot has walked since), what it should have seen (`seen_share`, for frames
passed with their camera view: the share of the landmarks the estimate puts in view that were detected), the
dominant cluster's covariance and weight, the belief's grid entropy, and the mirror odds of the last
re-localization (the mirror pose explains every detection as well; only the prior tells them apart, and the
odds must hold without the heading reference, see `mcl.relocalization`):
- SUPERB: tight (position σ, heading σ small), one cluster, low entropy, recent detections explained and the
  latest ones not contradicting it (`surprise`, a change detector that reacts within a frame or two, where the
  fit over 1.5 s lags), most of what should be in view seen, the mirror ruled out by odds of 10 or more;
- OKAY: usable for behaviour, but wider or with less support, the pose at least three times as probable as its
  mirror (never after an unseen move alone: `mcl.side.SideSettings.jump_cap`);
- POOR: anything else. `is_lost` is POOR for `lost_after` seconds (1 s) in a row.
"""

from __future__ import annotations

import enum
import math
from collections import Counter, deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import TYPE_CHECKING, Any

import numpy as np

from field import Field
from field.checks import ArgumentTypeError, real, reals
from motion_models import MotionInput
from sensing import LandmarkSensorModel
from sensing.observations import Observations
from sensing.team import BallDetection, TeamMessage
from sensing.view import CameraView

from .filter import ParticleFilter
from .latency import MotionHistory, compose, move_back
from .particles import check_sigma
from .relocalization import KIDNAP_AMBIGUITY
from .rivals import RivalPoses, RivalSettings
from .side import SideBelief, SideSettings, Team
from .summary import Entropy, Estimate

if TYPE_CHECKING:
    from motion_models.base import MotionModel

    from .contracts import SensorModel

MAX_ODOMETRY_SCALE = 10.0  # the largest odometry calibration factor a Localizer accepts


class Quality(enum.Enum):
    """How far behaviour can trust the pose (as B-Human's superb / okay / poor), and one state between: sure
    where, not sure which half (UNSURE_HALF: the pose would be SUPERB or OKAY, but its mirror image is about as
    probable; not lost: looking at the ball or asking the team decides it)."""

    SUPERB = "superb"
    OKAY = "okay"
    POOR = "poor"
    UNSURE_HALF = "unsure_half"


@dataclass(frozen=True)
class Hypothesis:
    """One mode of the belief (`Localizer.hypotheses`).

    Attributes
    ----------
    pose : numpy.ndarray
        (x [m], y [m], θ [rad]).
    covariance : numpy.ndarray
        (3, 3).
    weight : float
        Its probability, in [0, 1]; the hypotheses' weights sum to at most 1.
    kind : str
        "main" (the estimate), "mirror" (its point image: the same landmarks, the other half), "rival" (another
        place that explains the recent detections while the track is young, `mcl.rivals`) or "other" (the
        particles outside the main cluster, pooled).
    """

    pose: np.ndarray
    covariance: np.ndarray
    weight: float
    kind: str


@dataclass(frozen=True)
class QualityThresholds:
    """Limits for each quality level; a level needs all of its limits met.

    The fit is the share of the recent detections that the estimate explains: a detection is explained when
    a landmark of its type lies within `gate` standard deviations (the sensor model's range and bearing
    noise, widened by `range_slack` and `bearing_slack`) of where the estimate says it was seen. Recent: the
    detections captured in the last `fit_window` seconds. A belief can be tight and wrong (after a kidnap,
    until re-localization). Explaining what the camera sees is harder to fake, but the mirror pose explains it
    as well, and with few landmarks in view a wrong pose can too (see docs/relocalization.md, "Limits").

    Every limit is a finite number >= 0; the comments beside the fields say more.

    Attributes
    ----------
    superb_position, okay_position : float, default 0.15, 0.4
        At most this sqrt(var x + var y) of the dominant cluster [m].
    superb_heading, okay_heading : float, default 0.1, 0.3
        At most this heading standard deviation [rad].
    superb_weight, okay_weight : float, default 0.9, 0.6
        At least this share of the weight in the dominant cluster.
    superb_entropy, okay_entropy : float, default 7.0, 9.0
        At most this position entropy [bits] (10 cm cells: 128 cells ~ 1.3 m²).
    superb_fit, okay_fit : float, default 0.7, 0.4
        At least this share of the recent detections explained by the estimate, in [0, 1].
    superb_detections : int, default 3
        SUPERB needs at least this many explained detections.
    superb_age, okay_age : float, default 1.5, 10.0
        The last explained detection captured at most this long ago [s].
    superb_mirror_odds, okay_mirror_odds : float, default 10.0, 3.0
        The side odds that hold without any one teammate (`Localizer.held_side_log_odds`: the last
        re-localization's preference of its pose to the mirror pose, `SoccerRelocalization.mirror_log_odds`,
        plus the teammates' evidence that remains when any one of them is left out) are at least these. A pose
        that meets the other limits of SUPERB or OKAY but not these odds is UNSURE_HALF.
    superb_rival_odds, okay_rival_odds : float, default 10.0, 3.0
        While the track is young (`mcl.rivals`: after a reset, a re-localization, or a jump of the estimate), the
        estimate explains the recent frames at least this many times better than any other place that explains
        them (`Localizer.rival_log_odds`); below `okay_rival_odds` the pose is POOR, whatever else holds.
    rivals : RivalSettings or None, default RivalSettings()
        How a young track is checked against the other places that explain the same detections (`mcl.rivals`);
        None: not checked (`Localizer.rival_log_odds` stays +inf).
    fit_window : float, default 1.5
        Seconds of detections the fit is taken over (> 0).
    gate : float, default 3.0
        Standard deviations within which a detection is explained (> 0).
    range_slack : float, default 0.1
        Added to the sensor model's range σ [m].
    bearing_slack : float, default 0.03
        Added to its bearing σ [rad].
    lost_after : float, default 1.0
        Seconds of POOR in a row before `Localizer.is_lost`.
    okay_walked : float, default 2.0
        At most this distance dead-reckoned since the last explained detection [m].
    superb_surprise, okay_surprise : float, default 4.0, 5.0
        At most this `Localizer.surprise`: the evidence, in log odds, that the estimate stopped explaining
        the detections since it last did (a change detector that reacts within a frame or two, where the fit
        over `fit_window` lags: after a kidnapping the estimate is still tight and the window still full of
        explained detections).
    surprise_cap : float, default 8.0
        The surprise is held at or below this, so that once the estimate is right again a few explained
        detections make it forget a long wrong stretch (or a burst of false detections). A limit at or above it
        never binds.
    explained_rate, wrong_rate : float, default 0.9, 0.3
        The share of detections an estimate explains when it is right, and when it is wrong (a wrong pose still
        explains some: many landmarks of a type); 0 < wrong_rate < explained_rate < 1. Each unexplained
        detection adds log((1 − q) / (1 − explained_rate)) to the surprise, each explained one takes
        log(explained_rate / q) from it, q = wrong_rate; with a sensor model that says how likely a pose
        anywhere explains each detection (`LandmarkSensorModel.chance_explained`, over the carpet), q is that
        chance held within [wrong_rate, explained_rate] (`surprise_after`): a far, noisy detection of a
        common type, which a wrong pose explains as well, moves the surprise little.
    superb_seen, okay_seen : float, default 0.4, 0.3
        With views: at least this share of the landmarks the estimate expects in view detected
        (`Localizer.seen_share`), in [0, 1] ...
    view_expected : int, default 4
        ... once the recent frames expected this many.
    view_inset : float, default 0.8
        A landmark is expected inside this share of the view (`CameraView.inset`), in (0, 1].

    Raises
    ------
    ValueError
        If a limit is negative, not finite or out of its range.
    """

    superb_position: float = 0.15  # m, sqrt(var x + var y) of the dominant cluster
    superb_heading: float = 0.1  # rad
    superb_weight: float = 0.9  # share of the weight in the dominant cluster
    superb_entropy: float = 7.0  # bits of position entropy (10 cm cells: 128 cells ~ 1.3 m²)
    okay_position: float = 0.4
    okay_heading: float = 0.3
    okay_weight: float = 0.6
    okay_entropy: float = 9.0
    superb_fit: float = 0.7  # share of the recent detections the estimate explains ...
    superb_detections: int = 3  # ... of at least this many explained ...
    superb_age: float = 1.5  # s: ... the last explained one captured at most this long ago
    superb_mirror_odds: float = 10.0  # the last re-localization preferred its pose to the mirror pose by this
    # much at least (`SoccerRelocalization.mirror_log_odds`; the mirror
    # explains every detection as well, so nothing seen afterwards can)
    okay_mirror_odds: float = 3.0  # below these odds the pose is UNSURE_HALF (its mirror image too probable)
    superb_rival_odds: float = 10.0  # a young track explains the frames this much better than any other place
    okay_rival_odds: float = 3.0  # (`mcl.rivals`); below these odds the pose is POOR
    okay_fit: float = 0.4
    okay_age: float = 10.0  # s since the last explained detection, at most
    fit_window: float = 1.5  # s of detections the fit is taken over
    gate: float = 3.0  # standard deviations within which a detection is explained
    range_slack: float = 0.1  # m, added to the sensor model's range σ (the model's noise is a guess)
    bearing_slack: float = 0.03  # rad, added to its bearing σ
    lost_after: float = 1.0  # s of POOR in a row before is_lost
    okay_walked: float = 2.0  # m dead-reckoned since the last explained detection, at most
    superb_seen: float = 0.4  # with views (`observe(..., view=)`): the share of the landmarks the estimate
    okay_seen: float = 0.3  # expects in view that were detected (`seen_share`), at least this ...
    view_expected: int = 4  # ... once the recent frames expected this many
    view_inset: float = 0.8  # a landmark is expected inside this share of the view (`CameraView.inset`)
    superb_surprise: float = 4.0  # log odds that the estimate stopped explaining the detections, at most
    okay_surprise: float = 5.0
    surprise_cap: float = 8.0  # the surprise is held at or below this
    explained_rate: float = 0.9  # share of the detections a right estimate explains ...
    wrong_rate: float = 0.3  # ... and a wrong one
    rivals: RivalSettings | None = dataclass_field(default_factory=RivalSettings)  # how a young track meets its rivals

    def __post_init__(self) -> None:
        if self.rivals is not None and not isinstance(self.rivals, RivalSettings):
            raise ArgumentTypeError(f"rivals = {self.rivals!r} must be an mcl.rivals.RivalSettings or None")
        for name, value in self.__dict__.items():
            if name == "rivals":
                continue
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} = {value!r} must be a finite number >= 0")
        for name in ("superb_fit", "okay_fit", "superb_seen", "okay_seen"):
            if getattr(self, name) > 1:
                raise ValueError(f"{name} = {getattr(self, name)!r} must be within [0, 1]")
        if self.fit_window <= 0 or self.gate <= 0:
            raise ValueError(f"fit_window = {self.fit_window!r}, gate = {self.gate!r} must be > 0")
        if not 0 < self.view_inset <= 1:
            raise ValueError(f"view_inset = {self.view_inset!r} must be within (0, 1]")
        if not 0 < self.wrong_rate < self.explained_rate < 1:
            raise ValueError(
                f"wrong_rate = {self.wrong_rate!r}, explained_rate = {self.explained_rate!r}: "
                "need 0 < wrong_rate < explained_rate < 1"
            )

    @property
    def surprise_steps(self) -> tuple[float, float]:
        """What one unexplained detection adds to `Localizer.surprise`, and what one explained detection takes."""
        p, q = self.explained_rate, self.wrong_rate
        return math.log((1.0 - q) / (1.0 - p)), math.log(p / q)

    def surprise_after(self, surprise: float, explained: np.ndarray, chances: np.ndarray) -> float:
        """`next_surprise` with each detection's own wrong rate: its chance to be explained by a pose anywhere
        (`LandmarkSensorModel.chance_explained`), held within [`wrong_rate`, `explained_rate`]. A detection
        that any pose explains (far, noisy, of a type with many landmarks) then moves the surprise little
        either way; one at or above `explained_rate` not at all.

        Parameters
        ----------
        surprise : float
            Within [0, `surprise_cap`].
        explained : numpy.ndarray
            (n,) bool: which of the frame's detections the estimate explained.
        chances : numpy.ndarray
            (n,) float: each detection's chance to be explained from a random pose.

        Raises
        ------
        ValueError
            Unless the surprise lies within [0, `surprise_cap`] and the two arrays have one entry per detection,
            the chances numbers within [0, 1].
        """
        if not 0.0 <= surprise <= self.surprise_cap:
            raise ValueError(f"surprise = {surprise!r} must lie within [0, {self.surprise_cap!r}]")
        explained = np.asarray(explained, dtype=bool)
        chances = np.asarray(chances, dtype=np.float64)
        if explained.ndim != 1 or chances.shape != explained.shape:
            raise ValueError(f"explained {explained.shape} and chances {chances.shape} must be (n,) each")
        p, floor = self.explained_rate, self.wrong_rate
        step = 0.0
        # a few detections a frame: plain Python is quicker than numpy's calls on arrays this small
        for seen, chance in zip(explained.tolist(), chances.tolist()):
            if not 0.0 <= chance <= 1.0:
                raise ValueError(f"chances = {chances!r} must lie within [0, 1]")
            wrong = min(max(chance, floor), p)
            step += -math.log(p / wrong) if seen else math.log((1.0 - wrong) / (1.0 - p))
        return min(max(0.0, surprise + step), self.surprise_cap)

    def next_surprise(self, surprise: float, detections: int, explained: int) -> float:
        """The surprise after a frame of `detections` of which the estimate explained `explained`: Page's CUSUM
        of the log-likelihood ratio "the estimate stopped explaining the detections" against "it still does",
        each detection independent (`explained_rate`, `wrong_rate`), held within [0, `surprise_cap`].

        Raises
        ------
        ValueError
            Unless 0 <= explained <= detections and the surprise lies within [0, `surprise_cap`].
        """
        if not 0 <= explained <= detections:
            raise ValueError(f"explained = {explained!r} must lie within [0, detections = {detections!r}]")
        if not 0.0 <= surprise <= self.surprise_cap:
            raise ValueError(f"surprise = {surprise!r} must lie within [0, {self.surprise_cap!r}]")
        unexplained, explained_step = self.surprise_steps
        step = (detections - explained) * unexplained - explained * explained_step
        return min(max(0.0, surprise + step), self.surprise_cap)


HYPOTHESIS_SHARE = 0.05  # `Localizer.hypotheses` lists a rival or the pooled rest from this share of the weight
TWIN_RADIUS = 1.0  # m: particles this close to the estimate's mirror image form its twin ...
TWIN_HEADING = 0.8  # rad: ... and this close in heading


# m: an estimate this far from where the detections last contradicted it was re-localized (`Localizer.moved_unseen`;
# a turn alone, as after a fall or a spin, does not bring the robot nearer its mirror image)
CONTINUITY_POSITION = 0.5


def _same_place(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two poses are the same place for the side evidence (TWIN_RADIUS, TWIN_HEADING)."""
    return (
        math.hypot(a[0] - b[0], a[1] - b[1]) <= TWIN_RADIUS
        and abs(math.remainder(a[2] - b[2], 2 * math.pi)) <= TWIN_HEADING
    )


def _log(odds: float) -> float:
    return math.log(odds) if odds > 0 else -math.inf


def explained_detections(
    sensor_model: SensorModel,
    pose: Sequence[float] | np.ndarray,
    observations: Observations,
    gate: float = 3.0,
    range_slack: float = 0.0,
    bearing_slack: float = 0.0,
) -> np.ndarray | None:
    """Which detections (bool per detection) the pose (x, y, θ) explains, as the sensor model says
    (`explained(pose, observations, gate, range_slack, bearing_slack)`, a capability `LandmarkSensorModel`
    offers); None when the model cannot say.

    Parameters
    ----------
    sensor_model : SensorModel
        The sensor model; asked through its optional `explained` method.
    pose : sequence of float or numpy.ndarray
        (x [m], y [m], θ [rad]).
    observations : Observations
        One frame's detections.
    gate : float, default 3.0
        Standard deviations within which a detection counts as explained.
    range_slack : float, default 0.0
        Added to the range σ [m].
    bearing_slack : float, default 0.0
        Added to the bearing σ [rad].

    Returns
    -------
    numpy.ndarray or None
        (n,) bool, one per detection; None when the model has no `explained`.
    """
    explained = getattr(sensor_model, "explained", None)
    if not callable(explained):
        return None
    return explained(pose, observations, gate, range_slack, bearing_slack)


def touchline_poses(field: Field, x_values: float | Sequence[float] | np.ndarray) -> np.ndarray:
    """Poses on both touchlines at each x, facing into the field: (x, +w/2, -π/2) and (x, -w/2, +π/2).

    Parameters
    ----------
    field : Field
        The field (its half width).
    x_values : float, sequence of float or numpy.ndarray
        The x positions [m].

    Returns
    -------
    numpy.ndarray
        (2K, 3): the K poses on the +y touchline, then the K on the -y touchline.
    """
    xs = np.atleast_1d(np.asarray(x_values, dtype=np.float64))
    hw = field.half_width
    left = np.column_stack([xs, np.full_like(xs, hw), np.full_like(xs, -math.pi / 2)])
    right = np.column_stack([xs, np.full_like(xs, -hw), np.full_like(xs, math.pi / 2)])
    return np.concatenate([left, right])


def default_kickoff_positions(field: Field, kicking: bool) -> np.ndarray:
    """A typical line-up in the own half, facing the opponent goal (not prescribed by the rules: pass your own).

    Goalkeeper on the middle of the own goal line, two defenders at the own penalty area's front corners, one
    player at the own penalty mark's height in the middle, and one striker: just inside the centre circle
    when kicking off, outside it otherwise.

    Parameters
    ----------
    field : Field
        The field.
    kicking : bool
        Whether the team kicks off (the striker stands 0.2 m behind the centre mark, else 0.2 m outside the
        centre circle).

    Returns
    -------
    numpy.ndarray
        (5, 3) poses (x [m], y [m], θ = 0 [rad]).
    """
    d = field.dims
    hl = field.half_length
    front = -hl + d.penalty_area_length
    radius = 0.5 * d.center_circle_diameter
    striker = -0.2 if kicking else -(radius + 0.2)
    return np.array(
        [
            [-hl, 0.0, 0.0],
            [front, 0.5 * d.penalty_area_width, 0.0],
            [front, -0.5 * d.penalty_area_width, 0.0],
            [-hl + d.penalty_mark_distance, 0.0, 0.0],
            [striker, 0.0, 0.0],
        ]
    )


class Localizer:
    """A particle filter wrapped for a robot's loop: latency-aware corrections, game events, quality.

    `counts` says what was not used and why ("observation while fallen", "motion while fallen",
    "observation older than history").

    Parameters
    ----------
    field : Field
        The field, as `ParticleFilter`.
    motion_model : MotionModel or None, default None
        As `ParticleFilter`; None: `motion_models.VelocityLinear()`.
    sensor_model : SensorModel or None, default None
        As `ParticleFilter`; None: `LandmarkSensorModel(field)`.
    n_particles : int, default 500
        As `ParticleFilter`.
    seed : int or None, default 0
        As `ParticleFilter`.
    history : float, default 1.0
        Seconds of motion kept for late detections.
    compensate_latency : bool, default True
        Score detections at their capture time (True) or as if they were current.
    quality : QualityThresholds, default QualityThresholds()
        The limits of each quality level.
    getup_sigma : sequence of float, default (0.15, 0.15, 0.5)
        (x [m], y [m], θ [rad]) noise added by `got_up`.
    placement_sigma : sequence of float, default (0.15, 0.08, 0.15)
        (x [m], y [m], θ [rad]) spread around a placement pose (robots are placed by hand).
    odometry_scale : sequence of float, default (1.0, 1.0, 1.0)
        Factors (x, y, θ) applied to each motion input's odometry and walk command before the motion model: a
        calibration of the robot's odometry on this carpet (each within (0, `MAX_ODOMETRY_SCALE`]).
    side : SideSettings, default SideSettings()
        How the teammates' view of the ball weighs against the robot's own prior (`mcl.side`).
    team : Team, default Team()
        The robot's own number and its teammates' (`mcl.side.Team`): messages from others are refused.
    **filter_options
        Any further keyword of `ParticleFilter` (resampling, augmented, threads, ...).

    Raises
    ------
    ValueError
        As `ParticleFilter`, or if a standard deviation is negative or not finite, or a scale out of range.

    Attributes
    ----------
    log_evidence : float
        The sum over the frames used so far of the frame's log evidence: the filter's
        `frame_log_likelihood` plus the sensor model's `log_normalizer` (when it has one; else in the model's
        own units). The standard particle-filter estimate of log p(detections | settings), which compares
        settings on logs without ground truth (`mcl.tools.tuning`); -inf once a frame explains nothing.
    evidence_frames : int
        How many frames it sums.
    surprise : float
        The evidence (log odds) that the estimate stopped explaining the detections since it last did
        (`QualityThresholds.next_surprise`): 0 while it explains them; a frame or two of unexplained detections
        after a kidnapping raise it above `superb_surprise` and `okay_surprise`. 0 after a reset.
    moved_unseen : bool
        Whether, since the last reset, the estimate came to fit the detections again somewhere else (more than
        `CONTINUITY_POSITION` from where they last contradicted it, dead-reckoned, and its mirror image not
        more than `mcl.relocalization.KIDNAP_AMBIGUITY` times as far) after a stretch in which they contradicted
        it (the surprise above `okay_surprise`): it was re-localized, and its mirror image is as plausible a
        continuation, so its side odds are capped as after a jump (`SideSettings.jump_cap`).
    rival_log_odds : float
        How much better (log odds) the estimate explained the frames than the best rival place, while its track
        is young (`mcl.rivals`); +inf without a rival, outside that time, or with `rivals=None`.
    jumps : int
        How often a correction left the estimate more than `CONTINUITY_POSITION` from where the last one had
        (moved on by odometry) without a re-localization: each starts a young track.
    """

    def __init__(
        self,
        field: Field,
        motion_model: MotionModel | None = None,
        sensor_model: SensorModel | None = None,
        n_particles: int = 500,
        seed: int | None = 0,
        history: float = 1.0,
        compensate_latency: bool = True,
        quality: QualityThresholds = QualityThresholds(),
        getup_sigma: Sequence[float] | np.ndarray = (0.15, 0.15, 0.5),
        placement_sigma: Sequence[float] | np.ndarray = (0.15, 0.08, 0.15),
        odometry_scale: Sequence[float] | np.ndarray = (1.0, 1.0, 1.0),
        side: SideSettings = SideSettings(),
        team: Team = Team(),
        **filter_options: Any,
    ) -> None:
        scale = reals("odometry_scale", odometry_scale, 3)
        if not isinstance(side, SideSettings):
            raise ArgumentTypeError(f"side = {side!r} must be an mcl.side.SideSettings")
        if not isinstance(team, Team):
            raise ArgumentTypeError(f"team = {team!r} must be an mcl.side.Team")
        if not all(0.0 < v <= MAX_ODOMETRY_SCALE for v in scale):
            raise ValueError(
                f"odometry_scale = {tuple(scale.tolist())!r}: each factor must lie in (0, {MAX_ODOMETRY_SCALE:g}]"
            )
        if motion_model is None:
            from motion_models import VelocityLinear

            motion_model = VelocityLinear()
        if sensor_model is None:
            sensor_model = LandmarkSensorModel(field)
        self.filter = ParticleFilter(
            field, motion_model, sensor_model, n_particles=n_particles, seed=seed, **filter_options
        )
        self.field = field
        self.history = MotionHistory(history)
        self.compensate_latency = bool(compensate_latency)
        self.thresholds = quality
        self.getup_sigma = check_sigma(getup_sigma)
        self.placement_sigma = check_sigma(placement_sigma)
        self.odometry_scale: tuple[float, float, float] = (float(scale[0]), float(scale[1]), float(scale[2]))
        self._scaled = self.odometry_scale != (1.0, 1.0, 1.0)
        self.log_evidence = 0.0
        self.evidence_frames = 0
        self.time: float | None = None
        self.is_fallen = False
        self.counts: Counter = Counter()
        self._poor_since: float | None = None
        self._quality: Quality | None = None
        self._frames: deque = deque()  # (capture time, detections, explained, expected in view, seen) per frame
        self._frame_sums = [0, 0, 0, 0]  # the kept frames' detections, explained, expected in view, seen
        self._last_explained: float | None = None  # capture time of the last frame with an explained detection
        self._walked = 0.0  # m dead-reckoned since then (since the last reset, before the first one)
        self.surprise = 0.0
        # where the estimate was when the detections last contradicted it (dead-reckoned since), until they
        # fit again; and whether the estimate then fitted them somewhere else (`moved_unseen`)
        self._contradicted_at: tuple[float, float, float] | None = None
        self._track_pose: tuple[float, float, float] | None = None  # the estimate after the last correction, moved on
        self.moved_unseen = False
        self._placed_in_own_half = False  # the last reset was a placement in the own half (`side_placed`)
        self.jumps = 0
        self.is_penalized = False
        # (start, end) of the stretches the robot was fallen or penalized (end None while it lasts): a frame
        # captured inside one is not used, whenever it arrives
        self._blind: deque = deque()
        self.team = team
        self.side = SideBelief(field, side)
        self._side_sign = 1.0  # +1 while the main pose is the one the re-localization's odds were taken for
        self._side_pose: np.ndarray | None = None  # where the side evidence was last weighed
        self._relocalizations = self._relocalization_count()
        self.rivals = None if quality.rivals is None else RivalPoses(quality.rivals, seed)
        self.rival_log_odds = math.inf

    @classmethod
    def from_profile(cls, field: Field, profile: Any, **overrides: Any) -> Localizer:
        """A localizer with the settings of `profile` (an `mcl.profile.Profile`: `Profile.load("venue.toml")`),
        then `overrides` (seed=, n_particles=, any keyword of `Localizer`) on top. The same as
        `profile.localizer(field, **overrides)`.

        Raises
        ------
        ArgumentTypeError
            If `profile` is not a profile (a path is read by `Profile.load` first).
        """
        build = getattr(profile, "localizer", None)
        if not callable(build):
            raise ArgumentTypeError(
                f"profile = {profile!r} must be an mcl.profile.Profile (read a file with mcl.profile.Profile.load)"
            )
        localizer = build(field, **overrides)
        if not isinstance(localizer, cls):
            raise ArgumentTypeError(f"profile = {profile!r} did not build a {cls.__name__}")
        return localizer

    # -- the loop ----------------------------------------------------------------------------------------
    def motion(self, t: float, u: MotionInput) -> None:
        """The robot's motion during the step that ends at time `t` [s] (times never go back).

        Ignored (and counted) while the robot is fallen or penalized.

        Parameters
        ----------
        t : float
            The time the step ends [s], not before the last time given.
        u : MotionInput
            The step's motion (command or odometry over `u.dt`).

        Raises
        ------
        ValueError
            If `t` goes back or is not finite, or the motion model refuses `u`.
        """
        t = self._check_time(t)
        if not isinstance(u, MotionInput):
            raise ArgumentTypeError(f"u = {u!r} must be a motion_models.MotionInput, not {type(u).__name__}")
        if self.is_fallen or self.is_penalized:
            # A fallen robot's odometry says nothing about where it lies (got_up widens the belief instead), and
            # a penalized one is carried off the field (penalty_return places it again).
            self.counts["motion while fallen" if self.is_fallen else "motion while penalized"] += 1
            self.history.record(t, u.dt, (0.0, 0.0, 0.0))
        else:
            if self._scaled:
                u = self._scale(u)
            displacement = u.displacement() if (u.odometry is not None or u.command is not None) else (0, 0, 0)
            self.filter.predict(u)
            self.history.record(t, u.dt, displacement)
            self._walked += math.hypot(displacement[0], displacement[1])
            if self.rivals is not None:
                self.rivals.moved(displacement)
            if self._contradicted_at is not None:
                self._contradicted_at = compose(self._contradicted_at, displacement)
            if self._track_pose is not None:
                self._track_pose = compose(self._track_pose, displacement)
        self.time = t
        self._quality = None
        self._track_side()
        if self.side.flip_pending:  # the teammates' evidence holds the mirror image: its time runs without reports
            self._settle_side()
        self._update_lost()

    def observe(
        self,
        observations: Observations | Iterable | None,
        capture_time: float | None = None,
        view: CameraView | None = None,
        ball: BallDetection | None = None,
    ) -> bool:
        """Correct with one camera frame's detections, captured at `capture_time` (None: now).

        A frame captured while the robot was fallen or penalized is not used (and counted), whenever it
        arrives: the capture time decides, not the arrival.

        Parameters
        ----------
        observations : Observations, iterable of LandmarkObservation, or None
            The frame's detections (coerced by `Observations.coerce`).
        capture_time : float or None, default None
            When the frame was captured [s], on the clock of `motion`'s times; None: now.
        view : CameraView or None, default None
            Where the camera looked (`sensing.view.CameraView`: head pan, field of view, ranges), optional
            (None: the observations' own `view`, if any). With it, the correction also weighs each particle
            by the landmarks it puts in view that the frame did not report (negative information,
            `LandmarkSensorModel`'s `detection_rate`), and the quality counts them for the estimate
            (`seen_share`, `QualityThresholds`).
        ball : BallDetection or None, default None
            The ball, when the frame saw it: after the correction, as `observe_ball` with the same capture time.

        Returns
        -------
        bool
            False when the frame was not used (captured while fallen or penalized), else True.

        Raises
        ------
        ValueError
            For a frame captured before the kept motion history, detections the sensor model refuses, or a
            view that is not a `CameraView`, leaving the filter unchanged.
        """
        observations = Observations.coerce(observations)
        if view is not None:
            observations = observations.with_view(view)  # TypeError unless a CameraView
        if ball is not None and not isinstance(ball, BallDetection):
            raise ArgumentTypeError(
                f"ball = {ball!r} must be a sensing.team.BallDetection or None, not {type(ball).__name__}"
            )
        since = None
        if capture_time is not None:
            capture_time = real("capture_time", capture_time)
            if self.compensate_latency:
                try:
                    since = self.history.since(capture_time)
                except ValueError:
                    self.counts["observation older than history"] += 1
                    raise
        blind = self._blind_at(capture_time)
        if blind is not None:
            self.counts[f"observation while {blind}"] += 1
            return False
        self.filter.correct(observations, since=since)
        self._follow_relocalization()
        self._hold_side()
        if len(observations):
            normalizer = getattr(self.filter.sensor_model, "log_normalizer", None)
            self.log_evidence += self.filter.frame_log_likelihood + (normalizer(observations) if normalizer else 0.0)
            self.evidence_frames += 1
        self._record_fit(observations, since, self.time if capture_time is None else capture_time)
        if ball is not None:
            self._ball(ball, since, self._now() if capture_time is None else capture_time)
        self._quality = None
        self._update_lost()
        return True

    # -- the team and the ball -----------------------------------------------------------------------------
    def observe_ball(self, ball: BallDetection, capture_time: float | None = None) -> bool:
        """The robot saw the ball (range and bearing in the robot frame) in a frame captured at `capture_time`
        (None: now). Placed on the field through the estimate where it was at capture, and compared with the
        teammates' reports of the ball (`mcl.side`): evidence for which half the robot is in. It never moves
        the particles by itself; when the evidence turns against the estimate the robot changes sides.

        Parameters
        ----------
        ball : BallDetection
            The detection (its sigmas optional).
        capture_time : float or None, default None
            When the frame was captured [s], on the clock of `motion`'s times; None: now.

        Returns
        -------
        bool
            False when the sighting was not used (captured while fallen or penalized), else True.

        Raises
        ------
        ValueError
            For a detection that is not a `BallDetection` (TypeError, also a ValueError) or a capture time
            before the kept motion history; the localizer is left unchanged.
        """
        if not isinstance(ball, BallDetection):
            raise ArgumentTypeError(f"ball = {ball!r} must be a sensing.team.BallDetection, not {type(ball).__name__}")
        since = None
        if capture_time is not None:
            capture_time = real("capture_time", capture_time)
            since = self.history.since(capture_time) if self.compensate_latency else None
        blind = self._blind_at(capture_time)
        if blind is not None:
            self.counts[f"ball while {blind}"] += 1
            return False
        self._ball(ball, since, self._now() if capture_time is None else capture_time)
        self._quality = None
        self._update_lost()
        return True

    def team_message(self, message: TeamMessage) -> None:
        """A teammate's message, as it arrives (late, lost, in any order): its ball report is compared with the
        robot's own sightings of the ball (`mcl.side`). The robot changes sides when the teammates' evidence,
        weighed against its own prior, holds the mirror image for `SideSettings.flip_hold` seconds.

        Parameters
        ----------
        message : TeamMessage
            The message (`sensing.team.TeamMessage`: sender, send time, pose, ball, ...).

        Raises
        ------
        ValueError
            For a message that is not a `TeamMessage` (TypeError, also a ValueError), from the robot's own number
            or a sender not among its teammates (`team`), or sent more than `SideSettings.future` seconds after the
            robot's clock or more than `SideSettings.past` before it; the localizer is left unchanged.
        """
        if not isinstance(message, TeamMessage):
            raise ArgumentTypeError(
                f"message = {message!r} must be a sensing.team.TeamMessage, not {type(message).__name__}"
            )
        if not self.team.accepts(message.sender):
            known = "any but the robot's own" if self.team.teammates is None else list(self.team.teammates)
            raise ValueError(f"message sender = {message.sender} is not a teammate (teammates: {known})")
        if self.time is not None:
            s = self.side.settings
            sent = message.received_time
            if not self.time - s.past <= sent <= self.time + s.future:
                raise ValueError(
                    f"message time = {sent:.3f} s (on this robot's clock) must lie within "
                    f"[{self.time - s.past:.3f}, {self.time + s.future:.3f}] s (the robot's clock "
                    f"{self.time:.3f} s, SideSettings.past and future)"
                )
        self.counts["team message"] += 1
        if self.is_fallen or self.is_penalized:
            return
        reports = self.side.reports
        self._track_side()
        self.side.message(message, self._now())
        if self.side.reports == reports:
            return  # nothing new was weighed: the belief is as it was
        if self._side_pose is None:
            self._side_pose = self.filter.estimate().pose.copy()
        self._settle_side()
        self._quality = None
        self._update_lost()

    @property
    def side_log_odds(self) -> float:
        """The log odds of the estimate against its mirror image (−x, −y, θ+π): the last re-localization's
        prior (`SoccerRelocalization.mirror_log_odds`, capped by `SideSettings.prior_cap`, or by `kidnap_cap` once
        a re-localization since the last placement rested on a kidnapping law, by `jump_cap` once one lay beyond
        the anchor's drift at all: continuity with a pose whose side was a guess is no surer than the guess) plus
        what the
        teammates' view of the ball says (`mcl.side`: weighed jointly with whether each teammate is itself on the
        mirror)."""
        return self.side.log_odds(*self._side_prior())

    @property
    def held_side_log_odds(self) -> float:
        """`side_log_odds` with only the teammates' evidence that holds without any one of them
        (`mcl.side.SideBelief.held_team_log_odds`): the odds the quality asks for its mirror limits, so that one
        teammate alone, however sure, never makes a pose SUPERB or OKAY of its half (it may be on the mirror
        itself). Without teammates' evidence, `side_log_odds`."""
        return self.side.held_log_odds(*self._side_prior())

    @property
    def side_placed(self) -> bool:
        """Whether the half is known from the game's rules: the last reset was a placement in the own half
        (`initial_placement`, `kickoff_placement`, `manual_placement`, `penalty_return`,
        `anywhere_in_own_half`) and the robot has not been moved unseen since (no re-localization beyond the
        anchor's drift, `moved_unseen` false). The teammates' evidence does not change its side then."""
        if not self._placed_in_own_half:
            return False
        _, kidnapped, jumped = self._side_prior()  # (jumped includes moved_unseen)
        return not (kidnapped or jumped)

    def _side_prior(self) -> tuple[float, bool, bool]:
        """The re-localization's side prior (signed for the current main pose), and whether it rests on a
        kidnapping law or on an unseen move (`SideBelief.log_odds`)."""
        relocalization = self.filter.relocalization
        prior = getattr(relocalization, "mirror_log_odds", math.inf)
        kidnapped = bool(getattr(relocalization, "kidnapped", False))
        holds = getattr(relocalization, "holds", None)
        if not kidnapped and callable(holds):
            # the prior's odds are those of the anchor's pose: an estimate that has left it (a re-localization
            # not yet accepted) is no surer of its side than a kidnapping law
            kidnapped = not holds(self.filter.estimate().pose)
        jumped = self.moved_unseen or bool(getattr(relocalization, "jumped", False))
        return self._side_sign * prior, kidnapped, jumped

    def hypotheses(self) -> list[Hypothesis]:
        """The main modes of the belief, most probable first: the estimate, its mirror image (the same
        landmarks, the other half; weighed by `side_log_odds`), while the track is young the rival places that
        explain the recent detections too (`rivals`, weighed by their leads), and the particles outside the
        estimate's cluster pooled as one. A rival and the pooled rest are listed from 5 % of the weight. A
        behaviour that sees two hypotheses of similar weight can act on it: look at the ball, ask the team.

        The estimate's cluster weight is shared by the estimate, its mirror image and the rivals in proportion
        to their odds (a rival's covariance is the estimate's: the rivals are points that explain the frames).

        Returns
        -------
        list of Hypothesis
            Weights within [0, 1], summing to at most 1.
        """
        estimate = self.filter.estimate()
        odds = self.side_log_odds
        main_share = 1.0 / (1.0 + math.exp(-odds)) if odds > -700 else 0.0
        mirror_pose = self.field.mirror_poses(estimate.pose[None])[0]
        rival_poses, leads = self.rivals.poses if self.rivals is not None else (np.empty((0, 3)), np.empty(0))
        rival_odds = np.exp(np.minimum(leads, 700.0))  # each rival against the estimate
        cluster = estimate.weight / (1.0 + float(rival_odds.sum()))
        out = [
            Hypothesis(estimate.pose.copy(), estimate.covariance.copy(), cluster * main_share, "main"),
            Hypothesis(mirror_pose, estimate.covariance.copy(), cluster * (1.0 - main_share), "mirror"),
        ]
        for pose, odds_against in zip(rival_poses, rival_odds):
            if cluster * odds_against >= HYPOTHESIS_SHARE:
                out.append(Hypothesis(pose, estimate.covariance.copy(), float(cluster * odds_against), "rival"))
        rest = 1.0 - estimate.weight
        if rest >= HYPOTHESIS_SHARE:
            poses, weights = self.filter.poses, self.filter.weights
            d2 = (poses[:, 0] - estimate.pose[0]) ** 2 + (poses[:, 1] - estimate.pose[1]) ** 2
            outside = d2 > 1.0
            if outside.any() and weights[outside].sum() > 0:
                w = weights[outside] / weights[outside].sum()
                p = poses[outside]
                mean_heading = math.atan2(float(w @ np.sin(p[:, 2])), float(w @ np.cos(p[:, 2])))
                centred = np.column_stack(
                    [
                        p[:, 0] - w @ p[:, 0],
                        p[:, 1] - w @ p[:, 1],
                        np.remainder(p[:, 2] - mean_heading + math.pi, 2 * math.pi) - math.pi,
                    ]
                )
                mean = np.array([w @ p[:, 0], w @ p[:, 1], mean_heading])
                out.append(Hypothesis(mean, (centred * w[:, None]).T @ centred, float(rest), "other"))
        return sorted(out, key=lambda h: -h.weight)

    def _now(self) -> float:
        return self.time if self.time is not None else 0.0

    def _relocalization_count(self) -> int:
        return int(getattr(self.filter.relocalization, "relocalizations", 0))

    def _follow_relocalization(self) -> None:
        """After a correction: when the filter re-localized, the new pose's odds are the re-localization's own.
        Otherwise, an estimate that now lies more than `CONTINUITY_POSITION` from where the last correction left
        it (moved on by odometry) starts a new track for the rivals all the same: the particles moved to another
        place (the dominant cluster changed) without a re-localization, and a young track is checked against the
        other places that explain the frames, whatever made it."""
        count = self._relocalization_count()
        pose = self.filter.estimate().pose
        left = self._track_pose
        jumped = left is not None and math.hypot(pose[0] - left[0], pose[1] - left[1]) > CONTINUITY_POSITION
        self._track_pose = (float(pose[0]), float(pose[1]), float(pose[2]))
        if count != self._relocalizations:
            self._relocalizations = count
            self._side_sign = 1.0
            if self.rivals is not None:
                self.rivals.new_track(self._now())
        elif jumped and left is not None:
            self.jumps += 1
            # a jump to the mirror image is the side's question, not a new place: the rivals leave the mirror
            # image to the side odds, so the track they checked is the same
            to_mirror = math.hypot(pose[0] + left[0], pose[1] + left[1])
            if self.rivals is not None and to_mirror > CONTINUITY_POSITION:
                self.rivals.new_track(self._now())
        self._track_side()

    def _track_side(self) -> None:
        """The side evidence belongs to the pose it was weighed for: it follows the estimate while it moves on,
        changes sign when the estimate jumps to its mirror image (the two swapped), and is dropped when the
        estimate jumps anywhere else (a re-localization: it says nothing about the new pose). Nothing to do
        (and nothing computed) without evidence."""
        if not self.side.holds_evidence:
            self._side_pose = None
            return
        pose = self.filter.estimate().pose
        old = self._side_pose
        if old is not None and not _same_place(pose, old):
            if _same_place(pose, self.field.mirror_poses(old[None])[0]):
                self.side.mirrored()
            else:
                self.side.moved()
        self._side_pose = pose.copy()

    def _ball(self, ball: BallDetection, since, capture_time: float) -> None:
        """Compare a sighting with the teammates' reports, through the estimate where it was at capture."""
        estimate = self.filter.estimate()
        if not estimate.is_confident():
            self.counts["ball while not confident"] += 1
            return
        pose = estimate.pose
        if since is not None:
            at_capture = np.empty((1, 3))
            move_back(pose[None], np.asarray(since, dtype=np.float64), at_capture)
            pose = at_capture[0]
        self._track_side()
        reports = self.side.reports
        self.side.sighting(ball, pose, estimate.covariance, capture_time, self._now())
        self._side_pose = estimate.pose.copy()
        if self.side.reports != reports:
            self._settle_side()

    def _settle_side(self) -> None:
        """Act on the side evidence (only the teammates' evidence can: without messages nothing here touches
        the filter). When it has held the mirror image for `flip_hold` seconds, change sides (mirror the
        particles: exact, the landmarks cannot tell)."""
        if not self.side.reports:
            return
        estimate = self.filter.estimate()
        if not estimate.is_confident():
            return
        if self.side_placed:
            return  # the rules put it in the own half and nothing moved it unseen since: the evidence is wrong
        if self.side.should_flip(self.side_log_odds, self._now()):
            self.filter.reset_mirrored()
            if self._track_pose is not None:  # the same track, on the other half
                x, y, theta = self._track_pose
                self._track_pose = (-x, -y, theta + math.pi)
            self.side.mirrored()
            self._side_sign = -self._side_sign
            self._side_pose = self.field.mirror_poses(estimate.pose[None])[0]
            self.counts["side changed by the team"] += 1

    def _hold_side(self) -> None:
        """After a correction, while the side evidence holds the main pose by at least `flip`: the particles on
        its mirror image (a twin cluster a re-localization left) keep no more weight than the odds give them,
        so that the estimate does not move there by itself. Only with the teammates' evidence."""
        if not self.side.reports:
            return
        estimate = self.filter.estimate()
        if not estimate.is_confident():
            return
        odds = self.side_log_odds
        if odds >= self.side.settings.flip:
            self._weigh_twin(estimate, odds)

    def _weigh_twin(self, estimate: Estimate, odds: float) -> None:
        """Scale the weight of the particles near the estimate's mirror image down to exp(−odds) times the
        estimate's cluster weight, when they hold more."""
        near = self._twin(estimate)
        held = float(self.filter.weights[near].sum())
        allowed = estimate.weight * math.exp(-odds)
        if held > allowed > 0.0:
            factors = np.zeros(near.shape[0])
            factors[near] = math.log(allowed / held)
            self.filter.reweigh(factors)
            self.counts["mirror twin weighed down"] += 1

    def _twin(self, estimate: Estimate) -> np.ndarray:
        """Which particles (bool per particle) form the estimate's mirror twin: within `TWIN_RADIUS` of its point
        image (-x, -y) and `TWIN_HEADING` of its heading θ + π."""
        poses = self.filter.poses
        x, y, theta = (float(v) for v in estimate.pose)
        # within TWIN_HEADING of the image's heading: cos(Δ) >= cos(TWIN_HEADING)
        return ((poses[:, 0] + x) ** 2 + (poses[:, 1] + y) ** 2 <= TWIN_RADIUS**2) & (
            -(np.cos(poses[:, 2]) * math.cos(theta) + np.sin(poses[:, 2]) * math.sin(theta)) >= math.cos(TWIN_HEADING)
        )

    def _scale(self, u: MotionInput) -> MotionInput:
        """`u` with its odometry and command scaled by `odometry_scale` (a ValueError if that moves too far)."""
        sx, sy, st = self.odometry_scale
        odometry = None if u.odometry is None else (sx * u.odometry[0], sy * u.odometry[1], st * u.odometry[2])
        command = None if u.command is None else (sx * u.command[0], sy * u.command[1], st * u.command[2])
        return MotionInput(u.dt, command=command, odometry=odometry, collision=u.collision, footstep=u.footstep)

    def pose(self) -> Estimate:
        """The estimate: pose [x, y, θ] of the dominant cluster, its covariance and weight."""
        return self.filter.estimate()

    def entropy(self) -> Entropy:
        """The belief's position and orientation entropy in bits (`ParticleFilter.entropy`)."""
        return self.filter.entropy()

    # -- quality -----------------------------------------------------------------------------------------
    def quality(self) -> Quality:
        """SUPERB, OKAY or POOR (see the module docstring and `QualityThresholds`)."""
        if self._quality is None:
            self._quality = self._assess()
        return self._quality

    @property
    def fit(self) -> float:
        """The share of the detections of the last `fit_window` seconds that the estimate explained when they
        were scored (NaN when there were none)."""
        seen, explained = self._frame_sums[0], self._frame_sums[1]
        return explained / seen if seen else math.nan

    @property
    def seen_share(self) -> float:
        """Of the landmarks the estimate put inside the camera's view in the frames of the last `fit_window`
        seconds that came with a view and at least one detection, the share that a detection of their type
        explained (NaN when none was expected). A frame without any detection is left out: a blind or covered
        camera says nothing about the pose."""
        expected, seen = self._frame_sums[2], self._frame_sums[3]
        return seen / expected if expected else math.nan

    def _record_fit(self, observations: Observations, since, capture_time: float | None) -> None:
        """Score the frame against the estimate where it was at capture; keep `fit_window` seconds of frames."""
        m = len(observations)
        if m == 0:
            return
        q = self.thresholds
        pose = self.filter.estimate().pose
        if since is not None:  # where the estimate was at capture
            at_capture = np.empty((1, 3))
            move_back(pose[None], np.asarray(since, dtype=np.float64), at_capture)
            pose = at_capture[0]
        explained = explained_detections(
            self.filter.sensor_model, pose, observations, q.gate, q.range_slack, q.bearing_slack
        )
        if explained is None:  # a sensor model without landmarks: the frame's own fit
            frame_fit = self.filter.frame_fit
            count = m if frame_fit >= 0.5 else 0  # (False for NaN)
        else:
            count = int(explained.sum())
        expected = seen = 0
        counter = getattr(self.filter.sensor_model, "seen", None)
        if observations.view is not None and callable(counter):
            expected, seen = counter(
                pose, observations, observations.view.inset(q.view_inset), q.gate, q.range_slack, q.bearing_slack
            )
        now = capture_time if capture_time is not None else 0.0
        self._frames.append((now, m, count, expected, seen))
        sums = self._frame_sums
        sums[0], sums[1], sums[2], sums[3] = sums[0] + m, sums[1] + count, sums[2] + expected, sums[3] + seen
        while self._frames and self._frames[0][0] < now - q.fit_window:
            old = self._frames.popleft()
            sums[0], sums[1], sums[2], sums[3] = sums[0] - old[1], sums[1] - old[2], sums[2] - old[3], sums[3] - old[4]
        if count:
            self._last_explained = now
            self._walked = 0.0
        chance = getattr(self.filter.sensor_model, "chance_explained", None)
        if explained is not None and callable(chance):
            x0, x1, y0, y1 = self.field.carpet
            chances = chance(observations, (x1 - x0) * (y1 - y0), q.gate, q.range_slack, q.bearing_slack)
            self.surprise = q.surprise_after(self.surprise, explained, chances)
        else:
            self.surprise = q.next_surprise(self.surprise, m, count)
        self._follow_contradiction()
        if self.rivals is not None:
            self.rival_log_odds = self.rivals.frame(
                self.filter.sensor_model,
                observations,
                self.filter.estimate().pose,
                since,
                now,
                self.field,
            )

    def _follow_contradiction(self) -> None:
        """After a frame: when the surprise passes `okay_surprise`, keep where the estimate was; when it is back
        to 0, an estimate that now fits somewhere else (more than `CONTINUITY_POSITION` from there,
        dead-reckoned) was re-localized; when its mirror image lies about as near to there (within a factor
        `KIDNAP_AMBIGUITY`), its side no longer rests on continuity (`moved_unseen`). Only once the filter
        has tracked since the last reset (`SoccerRelocalization.tracking`)."""
        q = self.thresholds
        if not getattr(self.filter.relocalization, "tracking", True):
            return  # still settling after a reset: the placement's region prior speaks for the side
        if self.surprise > q.okay_surprise:
            if self._contradicted_at is None:
                x, y, theta = (float(v) for v in self.filter.estimate().pose)
                self._contradicted_at = (x, y, theta)
        elif self.surprise == 0.0 and self._contradicted_at is not None:
            pose, before = self.filter.estimate().pose, self._contradicted_at
            moved = math.hypot(pose[0] - before[0], pose[1] - before[1])
            to_mirror = math.hypot(pose[0] + before[0], pose[1] + before[1])  # from there to the pose's mirror image
            if moved > CONTINUITY_POSITION and to_mirror <= KIDNAP_AMBIGUITY * moved:
                self.moved_unseen = True
            self._contradicted_at = None

    def _assess(self) -> Quality:
        q = self.thresholds
        if self.is_fallen or self.is_penalized:
            return Quality.POOR
        estimate = self.filter.estimate()
        cov = estimate.covariance
        position_sigma = math.sqrt(max(cov[0, 0] + cov[1, 1], 0.0))
        heading_sigma = math.sqrt(max(cov[2, 2], 0.0))
        entropy = self.filter.entropy().position
        now = self.time if self.time is not None else 0.0
        age = math.inf if self._last_explained is None else now - self._last_explained
        fit = self.fit
        explained = self._frame_sums[1]
        side_log_odds = self.held_side_log_odds  # no single teammate makes a pose sure of its half
        weight = estimate.weight
        if weight < q.superb_weight or (1.0 - weight) * q.superb_mirror_odds > weight:
            # the weight on the mirror twin leaves the pose as sure of where it is, and only as sure of its half
            # as the split between the two says (computed only where the twin could change the answer)
            twin = float(self.filter.weights[self._twin(estimate)].sum())
            if twin > 0.0:
                weight += twin
                side_log_odds = min(side_log_odds, math.log(estimate.weight / twin))
        # negative information, when frames came with their view: judged once enough landmarks were expected
        expected = self._frame_sums[2]
        seen = self.seen_share if expected >= q.view_expected else 1.0
        superb = (
            position_sigma <= q.superb_position
            and heading_sigma <= q.superb_heading
            and weight >= q.superb_weight
            and entropy <= q.superb_entropy
            and fit >= q.superb_fit
            and explained >= q.superb_detections
            and age <= q.superb_age
            and seen >= q.superb_seen
            and self.surprise <= q.superb_surprise
            and self.rival_log_odds >= _log(q.superb_rival_odds)
        )
        if superb and side_log_odds >= _log(q.superb_mirror_odds):
            return Quality.SUPERB
        okay = (
            position_sigma <= q.okay_position
            and heading_sigma <= q.okay_heading
            and weight >= q.okay_weight
            and entropy <= q.okay_entropy
            and age <= q.okay_age
            and self._walked <= q.okay_walked
            and not fit < q.okay_fit
            and seen >= q.okay_seen
            and self.surprise <= q.okay_surprise
            and self.rival_log_odds >= _log(q.okay_rival_odds)
        )
        if okay and side_log_odds >= _log(q.okay_mirror_odds):
            return Quality.OKAY
        if superb or okay:
            return Quality.UNSURE_HALF  # sure where, not which half: its mirror image is about as probable
        return Quality.POOR

    @property
    def is_lost(self) -> bool:
        """POOR quality for at least `lost_after` seconds in a row while standing (a fallen or penalized robot's
        pose is POOR, but it is not lost: `got_up` widens the belief and `penalty_return` places it, and the clock
        starts then). UNSURE_HALF is not lost: the pose is known up to the field's symmetry."""
        return (
            self._poor_since is not None
            and self.time is not None
            and self.time - self._poor_since >= self.thresholds.lost_after
        )

    def _update_lost(self) -> None:
        if self.quality() is Quality.POOR and not (self.is_fallen or self.is_penalized):
            if self._poor_since is None:
                self._poor_since = self.time if self.time is not None else 0.0
        else:
            self._poor_since = None

    # -- game events -------------------------------------------------------------------------------------
    def initial_placement(self, spacing: float = 0.25) -> None:
        """INITIAL: the robot stands on one of the own touchlines (which one it cannot know), facing in.

        Parameters
        ----------
        spacing : float, default 0.25
            Distance between the candidate poses along each touchline [m], in [0.05, half length].
        """
        hl = self.field.half_length
        # Between 5 cm (at most a few hundred candidate poses) and the half's length (one).
        spacing = real("spacing", spacing, 0.05, hl)
        xs = np.arange(-hl + 0.5 * spacing, 0.0, spacing)
        self._reset(touchline_poses(self.field, xs), (0.5 * spacing, 0.08, 0.15))

    def penalized(self) -> None:
        """The robot was penalized (taken off the field): motion, frames captured from now and ball sightings
        are ignored (and counted) until `penalty_return`."""
        if not self.is_penalized:
            self.is_penalized = True
            self._blind.append([self._now(), None, "penalized"])
        self._quality = None
        self._poor_since = None

    def penalty_return(self) -> None:
        """Back from a penalty: on either own touchline at the penalty mark's x, facing into the field. Ends a
        `penalized` stretch."""
        self._end_blind("penalized")
        self.is_penalized = False
        x = -self.field.half_length + self.field.dims.penalty_mark_distance
        self._reset(touchline_poses(self.field, [x]), self.placement_sigma)

    def kickoff_placement(
        self, poses: Sequence[Sequence[float]] | np.ndarray | None = None, kicking: bool = True
    ) -> None:
        """Placed at kick-off positions: around `poses` (K, 3), or `default_kickoff_positions`.

        Parameters
        ----------
        poses : array_like or None, default None
            (K, 3) candidate poses (x [m], y [m], θ [rad]); None: `default_kickoff_positions(field, kicking)`.
        kicking : bool, default True
            Whether the team kicks off (used for the default positions).
        """
        if not isinstance(kicking, (bool, np.bool_)):
            raise ArgumentTypeError(f"kicking = {kicking!r} must be True or False, not {type(kicking).__name__}")
        if poses is None:
            poses = default_kickoff_positions(self.field, kicking)
        self._reset(poses, self.placement_sigma)

    def manual_placement(self, poses: Sequence[Sequence[float]] | np.ndarray | None = None) -> None:
        """The referee placed the robot: around `poses` (K, 3) when the team knows where, else anywhere in the
        own half facing the opponent goal.

        Parameters
        ----------
        poses : array_like or None, default None
            (K, 3) candidate poses (x [m], y [m], θ [rad]), spread by `placement_sigma`; None: uniform over the
            own half, headings around 0 with σ = 0.3 rad.
        """
        if poses is not None:
            self._reset(poses, self.placement_sigma)
            return
        self.filter.reset_uniform("own_half", heading=0.0, heading_sigma=0.3)
        self._after_reset(own_half=True)

    def anywhere_in_own_half(self) -> None:
        """The robot is somewhere in the own half, heading unknown (a robot switched on or carried in without
        a known placement): particles uniform over the own half with uniform headings."""
        self.filter.reset_uniform("own_half")
        self._after_reset(own_half=True)

    def place(self, pose: Sequence[float] | np.ndarray, sigma: Sequence[float] | np.ndarray | None = None) -> None:
        """The pose is known: particles around it, its heading trusted for injection.

        Parameters
        ----------
        pose : sequence of float or numpy.ndarray
            (x [m], y [m], θ [rad]).
        sigma : sequence of float, numpy.ndarray or None, default None
            Standard deviations (x [m], y [m], θ [rad]); None: `placement_sigma`.
        """
        sigma = self.placement_sigma if sigma is None else sigma
        self.filter.reset_around(pose, sigma)
        self._after_reset(np.asarray(pose, dtype=np.float64).reshape(1, 3), sigma)

    def fallen(self) -> None:
        """The robot fell: motion and the frames captured from now are ignored (and counted) until `got_up`."""
        if not self.is_fallen:
            self._blind.append([self._now(), None, "fallen"])
        self.is_fallen = True
        self._quality = None
        self._poor_since = None

    def got_up(self) -> None:
        """Standing again: the belief is widened by `getup_sigma` (falling and rising move and turn the robot).
        Frames captured before now, while it lay, stay unused when they arrive later."""
        if self.is_fallen:
            self.filter.diffuse(self.getup_sigma)
            self._end_blind("fallen")
        self.is_fallen = False
        self._quality = None

    def _end_blind(self, reason: str) -> None:
        for stretch in self._blind:
            if stretch[1] is None and stretch[2] == reason:
                stretch[1] = self._now()
        # stretches older than the motion history cannot hold a frame the localizer would still take
        while self._blind and self._blind[0][1] is not None and self._blind[0][1] < self._now() - self.history.keep:
            self._blind.popleft()

    def _blind_at(self, capture_time: float | None) -> str | None:
        """ "fallen" or "penalized" when a frame captured at `capture_time` (None: now) was taken while the robot
        was so, else None."""
        if capture_time is None:
            return "fallen" if self.is_fallen else "penalized" if self.is_penalized else None
        for start, end, reason in self._blind:
            if start <= capture_time and (end is None or capture_time < end):
                return reason
        return None

    def _reset(self, poses, sigma) -> None:
        self.filter.reset_candidates(poses, sigma, region="own_half")
        self._after_reset(np.asarray(poses, dtype=np.float64).reshape(-1, 3), sigma, own_half=True)

    def _after_reset(self, poses: np.ndarray | None = None, sigma=None, own_half: bool = False) -> None:
        """After any reset; `poses` (K, 3) and `sigma` (x, y, θ): a reset around these candidates (None: over a
        region), whose rivals can only lie within 3 σ of one of them; `own_half`: a placement the game's rules
        put in the own half."""
        self._placed_in_own_half = own_half
        self.side.moved()
        self._side_sign = 1.0
        self._side_pose = None
        self._relocalizations = self._relocalization_count()
        self._frames.clear()
        self._frame_sums = [0, 0, 0, 0]
        self.surprise = 0.0
        self._contradicted_at = None
        self._track_pose = None
        self.moved_unseen = False
        if self.rivals is not None:
            near = None if poses is None else (poses, 3.0 * float(max(np.asarray(sigma, dtype=np.float64)[:2])))
            self.rivals.new_track(self.time, forget_frames=True, near=near)
        self.rival_log_odds = math.inf
        self._last_explained = None
        self._walked = 0.0
        self._quality = None
        self._poor_since = None
        self.history.clear(self.time)

    def _check_time(self, t) -> float:
        t = real("t", t)
        if self.time is not None and t < self.time:
            raise ValueError(f"t = {t:.6f} s is before the previous step's {self.time:.6f} s: times never go back")
        return t
