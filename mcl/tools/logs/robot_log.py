"""The in-memory robot log: one array per stream, times in seconds from the log's origin.

    from mcl.tools.logs import RobotLog, VisionFrame

A stream that the log does not hold has zero rows. Times are float64 seconds relative to `origin_ns` (the
first message's time in integer nanoseconds since the epoch), which keeps sub-microsecond precision over a
whole game. All poses and velocities are SI: metres, seconds, radians.

Streams (each `*_times` array is strictly increasing):
- odometry: `odometry_times` (K,), `odometry` (K, 3) the robot's odometry pose [x, y, yaw] in its odom frame
  (cumulative, as `nav_msgs/Odometry` carries it); the filter moves by the difference of consecutive poses.
- commands: `command_times` (C,), `commands` (C, 3) walk request (vx, vy, ω) [m/s, m/s, rad/s].
- IMU: `imu_times` (I,), `gyro` (I, 3) [rad/s], `acceleration` (I, 3) [m/s²].
- joints: `joint_names` (n names), `joint_command_times` (J,), `joint_commands` (J, n) [rad];
  `joint_reading_times` (R,), `joint_readings` (R, n) [rad].
- vision: `vision`, a tuple of `VisionFrame` sorted by arrival time: capture `stamp`, arrival `received`,
  and the detections as `sensing.Observations` in the robot frame.
- ground truth: `truth_times` (G,), `truth` (G, 3) field-frame pose [x, y, θ] (empty when not recorded).

The constructor refuses (`LogError`, naming the stream) values that are not finite, times out of order, and
times more than `MAX_TIME` from the origin: no clock a log comes from reaches that far (MCAP's unsigned
nanoseconds span 584 years), so such a time is corrupt, and bounded times keep every duration finite.
Arguments of the wrong type (text, complex numbers, an origin that is not an integer) raise `TypeError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from dataclasses import field as dataclass_field

import numpy as np

from sensing.observations import Observations

MAX_TIME = 1e11  # [s] the farthest a time may lie from the origin, before or after (about 3 000 years)


class LogError(ValueError):
    """A log that cannot be used as asked: names the file, topic and time where it can."""


@dataclass(frozen=True, eq=False)
class VisionFrame:
    """One camera frame's detections: captured at `stamp`, reaching the log at `received` (both [s]).

    Parameters
    ----------
    stamp : float
        Capture time [s] from the log's origin.
    received : float
        Arrival time in the log [s] from the log's origin.
    observations : Observations
        The detections, in the robot frame.
    """

    stamp: float
    received: float
    observations: Observations

    @property
    def latency(self) -> float:
        """Seconds between capture and arrival."""
        return self.received - self.stamp


def _real_array(name: str, value) -> np.ndarray:
    """`value` as a contiguous float64 array; TypeError naming `name` when it is not real numbers."""
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name} = {value!r} must be an array of numbers, not text")
    try:
        array = np.asarray(value)
    except ValueError as error:  # ragged nested sequences
        raise TypeError(f"{name} must be an array of numbers ({error})") from None
    if array.dtype.kind not in "biuf":
        raise TypeError(f"{name} has dtype {array.dtype}, expected real numbers")
    return np.ascontiguousarray(array, dtype=np.float64)


def _empty(columns: int | None = None) -> np.ndarray:
    return np.zeros((0,) if columns is None else (0, columns))


@dataclass(frozen=True, eq=False)
class RobotLog:
    """What a robot recorded (see the module docstring for the streams and their units).

    Every stream defaults to empty (zero rows); times are float64 seconds from `origin_ns`.

    Parameters
    ----------
    origin_ns : int, default 0
        The first message's time in integer nanoseconds since the epoch.
    odometry_times, odometry : numpy.ndarray
        (K,) times and (K, 3) cumulative odometry poses [x, y, yaw] in the odom frame.
    command_times, commands : numpy.ndarray
        (C,) times and (C, 3) walk requests (vx, vy, ω) [m/s, m/s, rad/s].
    imu_times, gyro, acceleration : numpy.ndarray
        (I,) times, (I, 3) angular rates [rad/s] and (I, 3) accelerations [m/s²].
    joint_names : tuple of str, default ()
        The n joints' names.
    joint_command_times, joint_commands : numpy.ndarray
        (J,) times and (J, n) joint commands [rad].
    joint_reading_times, joint_readings : numpy.ndarray
        (R,) times and (R, n) joint readings [rad].
    vision : tuple of VisionFrame, default ()
        Camera frames, sorted by arrival time.
    truth_times, truth : numpy.ndarray
        (G,) times and (G, 3) field-frame poses [x, y, θ] (empty when not recorded).

    Raises
    ------
    LogError
        For values that are not finite, times out of order or more than `MAX_TIME` from the origin (naming
        the stream).
    TypeError
        For arguments of the wrong type (text, complex numbers, an origin that is not an integer).
    """

    origin_ns: int = 0
    odometry_times: np.ndarray = dataclass_field(default_factory=_empty)
    odometry: np.ndarray = dataclass_field(default_factory=lambda: _empty(3))
    command_times: np.ndarray = dataclass_field(default_factory=_empty)
    commands: np.ndarray = dataclass_field(default_factory=lambda: _empty(3))
    imu_times: np.ndarray = dataclass_field(default_factory=_empty)
    gyro: np.ndarray = dataclass_field(default_factory=lambda: _empty(3))
    acceleration: np.ndarray = dataclass_field(default_factory=lambda: _empty(3))
    joint_names: tuple[str, ...] = ()
    joint_command_times: np.ndarray = dataclass_field(default_factory=_empty)
    joint_commands: np.ndarray = dataclass_field(default_factory=lambda: _empty(0))
    joint_reading_times: np.ndarray = dataclass_field(default_factory=_empty)
    joint_readings: np.ndarray = dataclass_field(default_factory=lambda: _empty(0))
    vision: tuple[VisionFrame, ...] = ()
    truth_times: np.ndarray = dataclass_field(default_factory=_empty)
    truth: np.ndarray = dataclass_field(default_factory=lambda: _empty(3))

    STREAMS = (
        ("odometry_times", "odometry", 3),
        ("command_times", "commands", 3),
        ("imu_times", "gyro", 3),
        ("imu_times", "acceleration", 3),
        ("truth_times", "truth", 3),
    )

    def __post_init__(self) -> None:
        if isinstance(self.origin_ns, (bool, np.bool_)) or not isinstance(self.origin_ns, (int, np.integer)):
            raise TypeError(f"origin_ns = {self.origin_ns!r} must be an integer (nanoseconds since the epoch)")
        object.__setattr__(self, "origin_ns", int(self.origin_ns))
        if isinstance(self.joint_names, (str, bytes)):
            raise TypeError(f"joint_names = {self.joint_names!r} must be a sequence of names, not one string")
        n_joints = len(self.joint_names)
        for times_name, values_name, columns in self.STREAMS + (
            ("joint_command_times", "joint_commands", n_joints),
            ("joint_reading_times", "joint_readings", n_joints),
        ):
            times = _real_array(times_name, getattr(self, times_name)).reshape(-1)
            values = _real_array(values_name, getattr(self, values_name))
            if values.size == 0:
                values = values.reshape(times.shape[0] if times.shape[0] and columns == 0 else 0, columns)
            if values.ndim != 2 or values.shape != (times.shape[0], columns):
                raise LogError(
                    f"{values_name} has shape {values.shape}, expected ({times.shape[0]}, {columns}) "
                    f"to match {times_name}"
                )
            if not (np.isfinite(times).all() and np.isfinite(values).all()):
                raise LogError(f"{times_name} / {values_name} hold a NaN or an infinity")
            if times.shape[0] and np.abs(times).max() > MAX_TIME:
                i = int(np.argmax(np.abs(times) > MAX_TIME))
                raise LogError(
                    f"{times_name}[{i}] = {float(times[i])!r} s lies more than MAX_TIME = {MAX_TIME:g} s "
                    f"from the origin"
                )
            if times.shape[0] > 1 and not (np.diff(times) > 0).all():
                i = int(np.argmax(np.diff(times) <= 0)) + 1
                raise LogError(f"{times_name}[{i}] = {times[i]:.6f} s does not follow {times[i - 1]:.6f} s")
            object.__setattr__(self, times_name, times)
            object.__setattr__(self, values_name, values)
        object.__setattr__(self, "joint_names", tuple(str(name) for name in self.joint_names))
        frames = tuple(self.vision)
        for i, frame in enumerate(frames):
            if not isinstance(frame, VisionFrame):
                raise LogError(f"vision[{i}] = {frame!r} is not a VisionFrame")
            if not isinstance(frame.observations, Observations):
                raise LogError(f"vision[{i}].observations = {frame.observations!r} is not an Observations")
            for name in ("stamp", "received"):
                value = getattr(frame, name)
                if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
                    raise TypeError(f"vision[{i}].{name} = {value!r} must be a number of seconds")
            if not (math.isfinite(frame.stamp) and math.isfinite(frame.received)):
                raise LogError(f"vision[{i}] has a non-finite time")
            if max(abs(frame.stamp), abs(frame.received)) > MAX_TIME:
                raise LogError(
                    f"vision[{i}] (stamp {float(frame.stamp)!r} s, received {float(frame.received)!r} s) "
                    f"lies more than MAX_TIME = {MAX_TIME:g} s from the origin"
                )
            if i and frame.received < frames[i - 1].received:
                raise LogError(
                    f"vision[{i}] arrives at {frame.received:.6f} s, before vision[{i - 1}] "
                    f"({frames[i - 1].received:.6f} s): frames are sorted by arrival"
                )
        object.__setattr__(self, "vision", frames)

    def _span(self) -> tuple[float, float] | None:
        starts, ends = [], []
        for times in (
            self.odometry_times,
            self.command_times,
            self.imu_times,
            self.joint_command_times,
            self.joint_reading_times,
            self.truth_times,
        ):
            if times.shape[0]:
                starts.append(times[0])
                ends.append(times[-1])
        if self.vision:
            starts.append(min(f.stamp for f in self.vision))
            ends.append(self.vision[-1].received)
        return (float(min(starts)), float(max(ends))) if starts else None

    @property
    def start_time(self) -> float:
        """The earliest time of any stream [s] (0 for an empty log)."""
        span = self._span()
        return span[0] if span else 0.0

    @property
    def end_time(self) -> float:
        """The latest time of any stream [s] (0 for an empty log)."""
        span = self._span()
        return span[1] if span else 0.0

    @property
    def duration(self) -> float:
        """Seconds from the first to the last message of any stream."""
        return self.end_time - self.start_time

    @property
    def has_truth(self) -> bool:
        """Whether the log holds ground truth poses."""
        return self.truth_times.shape[0] > 0

    def truth_at(self, times: np.ndarray) -> np.ndarray:
        """Ground truth interpolated at `times` (linear in x, y, along the shorter arc in θ); NaN outside.

        Parameters
        ----------
        times : numpy.ndarray
            Times [s] from the log's origin, any shape.

        Returns
        -------
        numpy.ndarray
            Poses [x, y, θ], shape `times.shape + (3,)`; NaN outside the truth's time span (all NaN without
            truth).
        """
        times = np.asarray(times, dtype=np.float64)
        out = np.full(times.shape + (3,), np.nan)
        if not self.has_truth:
            return out
        t = self.truth_times
        inside = (times >= t[0]) & (times <= t[-1])
        theta = np.unwrap(self.truth[:, 2])
        for column, values in enumerate((self.truth[:, 0], self.truth[:, 1], theta)):
            out[inside, column] = np.interp(times[inside], t, values)
        out[inside, 2] = np.remainder(out[inside, 2] + math.pi, 2 * math.pi) - math.pi
        return out


@dataclass
class ReadReport:
    """What a reader did with a log: messages per topic, what it dropped and why, gaps, and where it stopped.

    Nothing is skipped silently: every message not used is counted under (topic, reason) in `dropped`.

    Attributes
    ----------
    path : str
        The log's file or folder.
    messages : dict of str to int
        Messages read per topic.
    types : dict of str to str
        Each topic's message type.
    dropped : dict of (str, str) to int
        Messages not used, per (topic, reason).
    gaps : list of (str, float, float)
        Silences longer than the reader's `gap`: (topic, start [s], length [s]).
    stopped_at : float or None
        Log time [s] of the last message read from a broken log.
    stop_reason : str or None
        What broke the log; None when it was read whole.
    missing : list of str
        Default topics the log does not have.
    topics : dict of str to (str, str)
        Stream -> (topic, how it was chosen: "name", "default name" or "type"); MCAP logs only.
    """

    path: str
    messages: dict[str, int] = dataclass_field(default_factory=dict)  # topic -> messages read
    types: dict[str, str] = dataclass_field(default_factory=dict)  # topic -> message type
    dropped: dict[tuple[str, str], int] = dataclass_field(default_factory=dict)
    gaps: list[tuple[str, float, float]] = dataclass_field(default_factory=list)  # (topic, start s, length s)
    stopped_at: float | None = None  # log time [s] of the last message read from a broken log
    stop_reason: str | None = None
    missing: list[str] = dataclass_field(default_factory=list)  # default topics the log does not have
    # stream -> (topic, how it was chosen: "name", "default name" or "type"); MCAP logs only
    topics: dict[str, tuple[str, str]] = dataclass_field(default_factory=dict)

    def drop(self, topic: str, reason: str, count: int = 1) -> None:
        """Count `count` messages on `topic` as dropped for `reason`.

        Parameters
        ----------
        topic : str
            The topic (or stream) the messages came on.
        reason : str
            Why they were not used.
        count : int, default 1
            How many.
        """
        self.dropped[(topic, reason)] = self.dropped.get((topic, reason), 0) + count

    @property
    def complete(self) -> bool:
        """The whole log was read (it did not break part way)."""
        return self.stop_reason is None

    @property
    def dropped_total(self) -> int:
        """Messages dropped, over every topic and reason."""
        return sum(self.dropped.values())

    def summary(self) -> str:
        """The report as text: one line per topic read, stream chosen, drop, gap, missing topic and stop."""
        lines = [f"{self.path}: {sum(self.messages.values())} messages on {len(self.messages)} topics"]
        for topic in sorted(self.messages):
            lines.append(f"  {topic} ({self.types.get(topic, '?')}): {self.messages[topic]}")
        for stream, (topic, how) in self.topics.items():
            why = {
                "name": "by name, as given",
                "default name": "by name, the default",
                "type": f"by type: the log's only {self.types.get(topic, 'such')} topic",
            }.get(how, how)
            lines.append(f"  {stream.replace('_', ' ')} from {topic} ({why})")
        for (topic, reason), count in sorted(self.dropped.items()):
            lines.append(f"  dropped {count} on {topic}: {reason}")
        for topic, start, length in self.gaps:
            lines.append(f"  gap of {length:.2f} s on {topic} at {start:.3f} s")
        if self.missing:
            lines.append(f"  not in the log: {', '.join(self.missing)}")
        if self.stop_reason is not None:
            where = "before the first message" if self.stopped_at is None else f"at {self.stopped_at:.3f} s"
            lines.append(f"  stopped {where}: {self.stop_reason}")
        return "\n".join(lines)

    def to_json(self) -> dict:
        """The report as a dict of JSON types: the drops and gaps as lists of objects, `complete` added."""
        return {
            "path": self.path,
            "messages": dict(self.messages),
            "types": dict(self.types),
            "dropped": [{"topic": t, "reason": r, "count": c} for (t, r), c in sorted(self.dropped.items())],
            "gaps": [{"topic": t, "start_s": s, "length_s": g} for t, s, g in self.gaps],
            "complete": self.complete,
            "stopped_at_s": self.stopped_at,
            "stop_reason": self.stop_reason,
            "missing": list(self.missing),
            "topics": {stream: {"topic": topic, "by": how} for stream, (topic, how) in self.topics.items()},
        }
