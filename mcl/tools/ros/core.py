"""The node's logic without ROS: messages in (any objects with the ROS fields), the localizer's output out.

    from mcl.tools.ros.core import NodeCore
    from mcl.tools.ros.parameters import NodeSettings

    core = NodeCore(NodeSettings(field="kidsize"))
    core.goalposts(msg); core.markings(msg)          # soccer_vision_3d_msgs GoalpostArray / MarkingArray
    out = core.odometry(msg)                         # nav_msgs/Odometry -> Output (pose, covariance, map->odom)

`mcl.tools.ros.node` calls it from rclpy's callbacks; a test calls it with messages decoded from an MCAP log. It
drives the `Localizer` exactly as `robocup-mcl replay` does (`mcl.tools.replay.replay`), so a log played to the node
gives the replay's estimates:

- motion: each odometry message moves the filter by the change since the previous one, in the robot frame of
  the previous one, with the walk command in force at the previous one (the latest /cmd_vel at or before it),
  ending at the message's header stamp; the first message only sets the start;
- vision: a GoalpostArray and a MarkingArray with the same header stamp are one camera frame (converted as
  `mcl.tools.logs.mcap_io` reads them). A frame is complete once each vision topic delivered its stamp or a later one
  (a topic never heard from: once another topic delivered a later stamp). A complete frame corrects the filter right after the
  next odometry message's motion step, scored at its capture time: the replay's order ("motion first, then the
  frames that arrived by then"). The pose published for that odometry message includes it. With the messages'
  send times (DDS's source timestamps, which the node passes where rclpy gives them), "next" is by send time, so
  a frame the executor takes before an odometry message published earlier still waits for the step after it.
  Without them (rclpy of Humble has no `MessageInfo`), "next" is by the order the messages are taken, and a frame
  captured after the odometry message's stamp waits for a later step (it cannot have been sent before it);
- the ball (BallArray, the most confident ball) is side evidence (`Localizer.observe_ball`) at its capture;
- a teammate's broadcast (robocup_mcl_msgs/TeamMessage, the project's own message: no common one exists) is
  `Localizer.team_message`, its header stamp the send time on the node's clock (`team_message`);
- game events: the GameState's INITIAL (entered) is `initial_placement`, its `penalized` flag turning on and off
  is `penalized` and `penalty_return`; an event message names a `Localizer` call (`mcl.tools.ros.parameters.EVENTS`);
  an initial pose is `place` (its σ from the message's covariance when given).

A Rerun recording of the run (`NodeCore.record`, the node's `--rrd`): `mcl.tools.recording.Recorder`, made at the
first estimate (its origin is the node's, so the recording's `ros2_timestamp` timeline is the messages' header
stamps), logs each odometry message's step as `robocup-mcl replay --rrd` logs a replay's: the estimate, the entropy,
the particles every `every` steps, the detections the step used, the quality and the lost flag and their changes,
and the game events. It only reads the filter; a recording that fails is counted and stops, the node goes on.
`recording_seconds` is what the last odometry message's recording took (the node's statistics set it against the
whole callback's time).

What the node draws (no DDS here): `NodeCore.particles()` is the filter's particles, the node's PoseArray;
`field_markers(field)` is the field as `FieldMarker`s, each one visualization_msgs/Marker of the node's
MarkerArray.

Times are seconds from `origin_ns` (the first stamp seen, unless given), as the replay's are from the log's
origin. Nothing is dropped silently: `counts` holds what was not used, by reason (with the localizer's own).
"""

from __future__ import annotations

import math
import re
import time
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from field import Field, LandmarkType
from field.angles import wrap_angles
from mcl.latency import SAME_TIME
from mcl.localizer import Localizer, Quality
from mcl.tools.logs import mcap_io
from mcl.tools.replay import QUALITY_CODES, _start
from mcl.tools.ros.parameters import EVENTS, NodeSettings
from motion_models import MotionInput
from sensing.observations import Observations
from sensing.team import BallDetection, TeamMessage

GAMESTATE_INITIAL = 0


@dataclass(frozen=True)
class Output:
    """What one odometry message yields: the estimate at its stamp, and the map -> odom transform.

    Attributes
    ----------
    stamp_ns : int
        The odometry message's header stamp [ns].
    pose : numpy.ndarray
        (3,) estimate x [m], y [m], θ [rad] in the field frame.
    covariance : numpy.ndarray
        (3, 3) its covariance over (x, y, θ).
    quality : Quality
        The localizer's quality.
    lost : bool
        The localizer's "lost" flag.
    map_to_odom : tuple of float
        (x [m], y [m], θ [rad]) of the odom frame in the map frame: the estimate composed with the inverse of
        the odometry pose.
    frames_used : int
        Camera frames that corrected the filter with this step.
    """

    stamp_ns: int
    pose: np.ndarray
    covariance: np.ndarray
    quality: Quality
    lost: bool
    map_to_odom: tuple[float, float, float]
    frames_used: int


GOALPOST_DRAWN_HEIGHT = 0.8  # m: the field's dimensions have no goal height; the posts are drawn this tall
CIRCLE_SEGMENTS = 64
LINE_COLOR = (1.0, 1.0, 1.0, 1.0)
GOALPOST_COLOR = (1.0, 1.0, 0.0, 1.0)


@dataclass(frozen=True)
class FieldMarker:
    """One visualization_msgs/Marker of the field, in the field frame.

    Attributes
    ----------
    namespace : str
        "lines", "centre_circle", "goalposts" or "marks" (the penalty marks and the centre mark).
    marker_id : int
        Its id within the namespace (0, 1, ...).
    shape : str
        "line_list" (`points` in pairs: the segments), "line_strip" (`points` joined in order) or "cylinder"
        (centred on the one point of `points`).
    points : numpy.ndarray
        (K, 2) x, y [m].
    width : float
        A line's width, or a cylinder's diameter [m].
    height : float
        A cylinder's height [m] (it stands on the ground); 0 for lines.
    color : tuple of float
        r, g, b, a in [0, 1].
    """

    namespace: str
    marker_id: int
    shape: str
    points: np.ndarray
    width: float
    height: float
    color: tuple[float, float, float, float]


def field_markers(field: Field) -> list[FieldMarker]:
    """The field as markers: its straight lines (one line list of `field.segments`), the centre circle (a closed
    strip of `CIRCLE_SEGMENTS` segments), each goalpost (a cylinder of the post's diameter, drawn
    `GOALPOST_DRAWN_HEIGHT` tall) and each penalty mark and the centre mark (a flat disc twice a line's width
    across). Positions are the field's own (`Field.segments`, `center_circle`, `landmarks`)."""
    width = float(field.dims.line_width)
    markers = [
        FieldMarker(
            "lines", 0, "line_list", np.asarray(field.segments, dtype=np.float64).reshape(-1, 2), width, 0.0, LINE_COLOR
        )
    ]
    cx, cy, radius = field.center_circle
    angles = np.linspace(0.0, 2.0 * math.pi, CIRCLE_SEGMENTS + 1)
    circle = np.column_stack([cx + radius * np.cos(angles), cy + radius * np.sin(angles)])
    circle[-1] = circle[0]  # closed exactly
    markers.append(FieldMarker("centre_circle", 0, "line_strip", circle, width, 0.0, LINE_COLOR))
    for k, post in enumerate(field.landmarks_of(LandmarkType.GOALPOST)):
        markers.append(
            FieldMarker(
                "goalposts",
                k,
                "cylinder",
                np.array([post], dtype=np.float64),
                float(field.dims.goalpost_diameter),
                GOALPOST_DRAWN_HEIGHT,
                GOALPOST_COLOR,
            )
        )
    marks = np.concatenate(
        [field.landmarks_of(LandmarkType.PENALTY_MARK), field.landmarks_of(LandmarkType.CENTER_MARK)]
    )
    for k, mark in enumerate(marks):
        markers.append(
            FieldMarker("marks", k, "cylinder", np.array([mark], dtype=np.float64), 2.0 * width, 0.005, LINE_COLOR)
        )
    return markers


def stamp_ns(header: Any) -> int:
    """A header's stamp in integer nanoseconds."""
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def map_to_odom(estimate: np.ndarray, odometry: np.ndarray) -> tuple[float, float, float]:
    """The odom frame's pose in the map frame, from the robot's pose in both: map<-base composed with
    (odom<-base)⁻¹."""
    theta = float(estimate[2] - odometry[2])
    c, s = math.cos(theta), math.sin(theta)
    x = float(estimate[0] - (c * odometry[0] - s * odometry[1]))
    y = float(estimate[1] - (s * odometry[0] + c * odometry[1]))
    return x, y, math.atan2(math.sin(theta), math.cos(theta))


TEAM_MESSAGE_FIELDS = (
    "header",
    "sender",
    "is_goalkeeper",
    "x",
    "y",
    "theta",
    "has_pose_covariance",
    "pose_covariance",
    "confidence",
    "has_ball",
    "ball_x",
    "ball_y",
    "has_ball_velocity",
    "ball_vx",
    "ball_vy",
    "ball_age",
    "has_ball_covariance",
    "ball_covariance",
    "clock_offset",
)


def _reason(error: BaseException) -> str:
    """A drop's kind for the counts: the error's text without the values it quotes (cut at its first " = " or
    ", got ", numbers left as "#"), so that messages differing only in their values count as one kind; or the
    error's type."""
    text = re.split(r" = |,? got ", str(error))[0]
    text = re.sub(r"[-+]?(?:\d+\.?\d*(?:e[-+]?\d+)?|nan|inf)\b", "#", text).strip()
    return (text or type(error).__name__)[:80]


def team_message(msg: Any, time: float, map_frame: str = "map") -> TeamMessage:
    """The `sensing.team.TeamMessage` of a robocup_mcl_msgs/TeamMessage `msg` sent at `time` [s] (its header
    stamp on the node's clock): field for field, the optional parts by their `has_*` flags, a negative
    confidence as none. ValueError for a `frame_id` other than `map_frame` (or empty) and for what
    `TeamMessage` refuses (NaN, out of range, a covariance not positive definite)."""
    frame = str(msg.header.frame_id)
    if frame not in ("", map_frame):
        raise ValueError(f"frame_id = {frame!r} is not the field frame {map_frame!r}")
    confidence = float(msg.confidence)
    if math.isnan(confidence):
        raise ValueError("confidence = nan must be a number in [0, 1] (negative: not given)")

    def matrix(values: Any, size: int) -> np.ndarray:
        return np.array([float(v) for v in values], dtype=np.float64).reshape(size, size)

    return TeamMessage(
        sender=int(msg.sender),
        time=time,
        pose=(float(msg.x), float(msg.y), float(msg.theta)),
        pose_covariance=matrix(msg.pose_covariance, 3) if msg.has_pose_covariance else None,
        confidence=None if confidence < 0 else confidence,
        is_goalkeeper=bool(msg.is_goalkeeper),
        ball=(float(msg.ball_x), float(msg.ball_y)) if msg.has_ball else None,
        ball_velocity=(float(msg.ball_vx), float(msg.ball_vy)) if msg.has_ball and msg.has_ball_velocity else None,
        ball_age=float(msg.ball_age) if msg.has_ball else 0.0,
        ball_covariance=matrix(msg.ball_covariance, 2) if msg.has_ball and msg.has_ball_covariance else None,
        clock_offset=float(msg.clock_offset),
    )


class NodeCore:
    """The localizer driven by ROS messages (see the module docstring).

    Parameters
    ----------
    settings : NodeSettings
        The node's parameters.
    localizer : Localizer or None, default None
        A localizer to drive; None builds one from `settings`.
    origin_ns : int or None, default None
        What t = 0 is [ns]; None: the first stamp seen.
    """

    def __init__(
        self, settings: NodeSettings, localizer: Localizer | None = None, origin_ns: int | None = None
    ) -> None:
        self.settings = settings
        self.localizer = settings.localizer() if localizer is None else localizer
        _start(self.localizer, settings.start)
        self.origin_ns = origin_ns
        self.counts: Counter = Counter()
        self.frames_used = 0
        self._odometry: np.ndarray | None = None  # the previous odometry pose
        self._odometry_time: float | None = None
        self._commands: list[tuple[float, tuple[float, float, float]]] = []
        self._vision_streams = tuple(
            stream for stream in ("goalposts", "markings") if getattr(settings, f"{stream}_topic")
        )
        self._latest: dict[str, int] = {}  # stream -> the latest stamp it delivered
        self._pending: dict[int, dict[str, Any]] = {}  # stamp -> {stream: value}
        # complete frames waiting for a motion step: (the last part's send time or None, capture stamp, detections)
        self._ready: list[tuple[int | None, int, Observations]] = []
        self._game: Any = None
        self._record: tuple[str, int] | None = None  # (path, particles every) until the recorder is made
        self.recorder: Any = None
        self._steps = 0  # estimates given so far: the recording's step
        self.recording_seconds = 0.0  # what the last odometry message's recording took [s] (0 without one)
        # a list: (capture stamp, odometry stamp) of each camera frame the filter took, at the step it took it
        self.applied: list[tuple[int, int]] | None = None

    # -- time ----------------------------------------------------------------------------------------------
    def seconds(self, ns: int) -> float:
        """`ns` [ns] as seconds from the origin (set by the first call when not given)."""
        if self.origin_ns is None:
            self.origin_ns = int(ns)
        return (int(ns) - self.origin_ns) / 1e9

    # -- motion --------------------------------------------------------------------------------------------
    def command(self, msg: Any, received_ns: int) -> None:
        """A geometry_msgs/Twist (stamped at `received_ns`, as the replay stamps it with its log time) or
        TwistStamped."""
        try:
            value = mcap_io._command_value(msg)
            stamp = stamp_ns(msg.header) if hasattr(msg, "header") else received_ns
        except mcap_io._Drop as drop:
            self.counts[f"command: {drop}"] += 1
            return
        self._commands.append((self.seconds(stamp), (value[0], value[1], value[2])))
        # only the commands that can still be in force at the next step's start are kept
        if self._odometry_time is not None:
            while len(self._commands) > 1 and self._commands[1][0] <= self._odometry_time + SAME_TIME:
                self._commands.pop(0)

    def _command_at(self, t: float) -> tuple[float, float, float] | None:
        if not self._commands:
            return None
        current = (0.0, 0.0, 0.0)
        for at, value in self._commands:
            if at > t + SAME_TIME:
                break
            current = value
        return current

    def odometry(self, msg: Any, sent_ns: int | None = None) -> Output | None:
        """A nav_msgs/Odometry message: one motion step (none for the first), then the complete frames that
        arrived since the previous one (with `sent_ns`, the time the message was published [ns], only the frames
        published before it: a frame taken out of order waits for the next step, as in the replay; without it,
        only the frames captured at or before its stamp); the estimate afterwards, or None when the message was
        not used."""
        try:
            pose = np.array(mcap_io._odometry_value(msg), dtype=np.float64)
            stamp = stamp_ns(msg.header)
        except mcap_io._Drop as drop:
            self.counts[f"odometry: {drop}"] += 1
            return None
        self.recording_seconds = 0.0
        t = self.seconds(stamp)
        if self._odometry is None or self._odometry_time is None:
            self._odometry, self._odometry_time = pose, t
            return None
        if t <= self._odometry_time:
            self.counts[
                "odometry: time went backwards"
                if t < self._odometry_time
                else "odometry: same stamp as the previous message"
            ] += 1
            return None
        # As mcl.tools.replay.motion_events: the change in the robot frame of the previous pose.
        both = np.stack([self._odometry, pose])
        d = np.diff(both[:, :2], axis=0)
        c, s = np.cos(both[:-1, 2]), np.sin(both[:-1, 2])
        local = np.column_stack(
            [c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], wrap_angles(np.diff(both[:, 2]))]
        )
        dt = float(np.diff(np.array([self._odometry_time, t]))[0])
        command = self._command_at(self._odometry_time)
        u = MotionInput(dt=dt, odometry=tuple(local[0]), command=command)
        self._odometry, self._odometry_time = pose, t
        try:
            self.localizer.motion(t, u)
        except ValueError as error:
            self.counts[f"odometry: refused ({_reason(error)})"] += 1
            return None
        used = 0
        later = []
        step_observations = None
        for frame in self._ready:
            frame_sent, capture_ns, observations = frame
            if sent_ns is not None and frame_sent is not None:
                if frame_sent > sent_ns:  # published after this odometry message
                    later.append(frame)
                    continue
            elif capture_ns > stamp:  # no send times: captured after this odometry message's stamp
                later.append(frame)
                continue
            try:
                if self.localizer.observe(observations, capture_time=self.seconds(capture_ns)):
                    used += 1
                    step_observations = observations
                    if self.applied is not None:
                        self.applied.append((capture_ns, stamp))
            except ValueError:  # counted by the localizer ("observation older than history", ...)
                pass
        self._ready = later
        self.frames_used += used
        estimate = self.localizer.pose()
        out = Output(
            stamp,
            estimate.pose,
            estimate.covariance,
            self.localizer.quality(),
            self.localizer.is_lost,
            map_to_odom(estimate.pose, pose),
            used,
        )
        if self._record is not None or self.recorder is not None:
            started = time.perf_counter()
            self._log_step(t, out, step_observations)
            self.recording_seconds = time.perf_counter() - started
        self._steps += 1
        return out

    # -- recording -----------------------------------------------------------------------------------------
    def record(self, path: str, every: int = 5) -> None:
        """Record the run to the Rerun file `path` from the next estimate on, the particles every `every` steps
        (`mcl.tools.recording.Recorder`); `close` finishes the file. ValueError when `every` < 1."""
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise ValueError(f"every = {every!r} must be an integer >= 1")
        import mcl.tools.recording  # noqa: F401 - Rerun imports now (about a second), not in the first callback

        self._record = (str(path), every)

    def _log_step(self, t: float, out: Output, observations: Observations | None) -> None:
        try:
            if self.recorder is None and self._record is not None:
                from mcl.tools.recording import Recorder, default_blueprint

                path, every = self._record
                self._record = None
                self.recorder = Recorder(
                    path,
                    self.localizer.field,
                    particles_every=every,
                    origin_ns=self.origin_ns,
                    blueprint=default_blueprint(
                        (
                            ("/entropy", "entropy [bits]"),
                            ("/localization", "quality (2 superb, 1 okay, 0 poor, 3 unsure of the half), lost"),
                        )
                    ),
                )
                self.recorder.set_time(self._steps, t)
                self.recorder.log_event("reset", f"the node starts: {self.settings.start}")
            recorder = self.recorder
            recorder.log_step(
                self._steps, t, self.localizer.filter, observations=observations, entropy=self.localizer.entropy()
            )
            recorder.log_scalars(
                {"localization/quality": float(QUALITY_CODES[out.quality]), "localization/lost": float(out.lost)}
            )
            recorder.log_change("quality", out.quality.value, f"quality {out.quality.value}")
            recorder.log_change(
                "lost", bool(out.lost), "lost" if out.lost else "no longer lost", level="WARN" if out.lost else "INFO"
            )
        except Exception as error:  # noqa: BLE001 - the recording must never stop the node
            self.counts[f"recording: stopped ({type(error).__name__}: {error})"] += 1
            self._record = None
            self.recorder = None

    def close(self) -> None:
        """Finish the recording, when there is one (`record`)."""
        recorder, self.recorder, self._record = self.recorder, None, None
        if recorder is not None:
            recorder.close()

    # -- vision --------------------------------------------------------------------------------------------
    def goalposts(self, msg: Any, sent_ns: int | None = None) -> None:
        """A soccer_vision_3d_msgs/GoalpostArray (one camera frame's goalposts), published at `sent_ns` [ns]
        when known."""
        self._vision("goalposts", msg, sent_ns)

    def markings(self, msg: Any, sent_ns: int | None = None) -> None:
        """A soccer_vision_3d_msgs/MarkingArray (one camera frame's markings), published at `sent_ns` [ns]
        when known."""
        self._vision("markings", msg, sent_ns)

    def _vision(self, stream: str, msg: Any, sent_ns: int | None) -> None:
        try:
            stamp = stamp_ns(msg.header)
            value = mcap_io._VALUE_OF[stream](msg)
        except (mcap_io._Drop, AttributeError) as drop:
            self.counts[f"{stream}: {drop}"] += 1
            return
        for reason in value[2]:
            self.counts[f"{stream}: {reason}"] += 1
        self._latest[stream] = max(stamp, self._latest.get(stream, stamp))
        parts = self._pending.setdefault(stamp, {})
        parts[stream] = value
        if sent_ns is not None:
            parts["sent"] = max(sent_ns, parts.get("sent", sent_ns))
        newest = max(self._latest.values())
        for pending_stamp in sorted(self._pending):
            parts = self._pending[pending_stamp]
            if all(self._delivered(s, parts, pending_stamp, newest) for s in self._vision_streams):
                del self._pending[pending_stamp]
                self._frame(pending_stamp, parts)

    def _delivered(self, stream: str, parts: dict[str, Any], stamp: int, newest: int) -> bool:
        """Whether `stream` has said all it will of the frame `stamp`: its part is there, or it delivered a later
        stamp, or (a stream never heard from) another stream did."""
        if stream in parts:
            return True
        latest = self._latest.get(stream)
        return latest > stamp if latest is not None else newest > stamp

    def _frame(self, stamp: int, parts: dict[str, Any]) -> None:
        landmarks: list = []
        points: list = []
        for stream in ("goalposts", "markings"):  # a frame's order, as the log reader's
            if stream in parts:
                landmarks.extend(parts[stream][0])
                points.extend(parts[stream][1])
        try:
            observations = Observations.from_arrays(
                [int(kind) for kind, _, _ in landmarks],
                [math.hypot(x, y) for _, x, y in landmarks],
                [math.atan2(y, x) for _, x, y in landmarks],
                line_points=np.array(points, dtype=np.float64).reshape(-1, 2),
            )
        except ValueError as error:
            self.counts[f"camera frame: detections refused: {_reason(error)}"] += 1
            return
        self._ready.append((parts.get("sent"), stamp, observations))

    def balls(self, msg: Any) -> bool:
        """A soccer_vision_3d_msgs/BallArray: its most confident ball as side evidence; False when not used."""
        balls = list(getattr(msg, "balls", []))
        if not balls or self.localizer.time is None:
            return False
        best = max(balls, key=lambda ball: float(ball.confidence.confidence))
        x, y = float(best.center.x), float(best.center.y)
        try:
            used = self.localizer.observe_ball(
                BallDetection(math.hypot(x, y), math.atan2(y, x)), capture_time=self.seconds(stamp_ns(msg.header))
            )
        except ValueError as error:
            self.counts[f"ball: {type(error).__name__}"] += 1
            return False
        return used

    # -- teammates ------------------------------------------------------------------------------------------
    def team(self, msg: Any) -> bool:
        """A robocup_mcl_msgs/TeamMessage (a teammate's broadcast, `TEAM_MESSAGE_FIELDS`) to
        `Localizer.team_message`, its send time (header stamp) on the node's clock; False when not used: a
        message that does not make a `sensing.team.TeamMessage` or that the localizer refuses (its own number, a
        sender not a teammate, sent too long ago or in the future) is counted by reason and dropped."""
        try:
            message = team_message(msg, self.seconds(stamp_ns(msg.header)), self.settings.map_frame)
        except (ValueError, TypeError, AttributeError, OverflowError) as error:
            self.counts[f"team message: {_reason(error)}"] += 1
            return False
        try:
            self.localizer.team_message(message)
        except ValueError as error:
            self.counts[f"team message: refused by the localizer ({_reason(error)})"] += 1
            return False
        return True

    # -- game events ---------------------------------------------------------------------------------------
    def game_state(self, msg: Any) -> list[str]:
        """A game_controller_hl_interfaces/GameState: the events it implies (see the module docstring), applied;
        returns their names."""
        if not self.settings.game_events:
            return []
        previous, self._game = self._game, msg
        events = []
        if msg.game_state == GAMESTATE_INITIAL and (previous is None or previous.game_state != GAMESTATE_INITIAL):
            events.append("initial_placement")
        if bool(msg.penalized) and not (previous is not None and bool(previous.penalized)):
            events.append("penalized")
        if not bool(msg.penalized) and previous is not None and bool(previous.penalized):
            events.append("penalty_return")
        for name in events:
            self.event(name)
        return events

    def event(self, name: str) -> None:
        """Apply the game event `name` (one of `EVENTS`); ValueError for another name."""
        if name not in EVENTS:
            raise ValueError(f"event = {name!r} must be one of {EVENTS}")
        if name == "kickoff_placement_defending":
            self.localizer.kickoff_placement(kicking=False)
        else:
            getattr(self.localizer, name)()
        self._ready.clear()  # frames seen before a placement say nothing of the new belief
        self.counts[f"event {name}"] += 1
        if self.recorder is not None:
            self.recorder.log_event("game_event", name)

    def initial_pose(self, msg: Any) -> None:
        """A geometry_msgs/PoseWithCovarianceStamped: the pose is known (`Localizer.place`), its σ from the
        covariance's x, y and yaw variances when they are positive, else the localizer's placement σ."""
        from mcl.tools.formats import ros_to_pose

        _, pose, covariance = ros_to_pose(msg)
        variances = np.diag(covariance)
        sigma = np.sqrt(variances) if np.all(variances > 0) and np.all(np.isfinite(variances)) else None
        self.localizer.place(pose, sigma)
        self._ready.clear()
        self.counts["event place"] += 1
        if self.recorder is not None:
            self.recorder.log_event("game_event", f"place at {pose[0]:.2f} m, {pose[1]:.2f} m, {pose[2]:.2f} rad")

    def particles(self) -> np.ndarray:
        """The filter's particles now: a copy of its (N, 3) poses x [m], y [m], θ [rad] in the field frame."""
        return np.array(self.localizer.filter.poses, dtype=np.float64, copy=True)

    def all_counts(self) -> dict[str, int]:
        """What was not used, by reason: the node's counts and the localizer's."""
        return dict(self.counts + Counter(self.localizer.counts))
