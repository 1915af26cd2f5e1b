"""Latency: score an observation against the pose at its capture time, not at its arrival.

    from mcl.latency import MotionHistory

    history = MotionHistory(keep=1.0)               # seconds of motion kept
    history.record(t_end=t, dt=0.01, displacement=u.displacement())
    since = history.since(capture_time)             # the motion from capture to now, robot frame at capture
    pf.correct(observations, since=since)           # particles moved back by `since` are scored

A camera frame reaches the filter 30–150 ms after the image was taken; the robot has walked on meanwhile,
and scoring the detections against the current particles puts them where the robot is now, not where it
was when it saw them. Each motion step's displacement is kept with its time; `since(t)` composes those after
`t` (the step that contains `t` in part, linearly). Every particle is moved back along that displacement in its
own frame, scored there, and the weight applies to the particle now, as Bit-Bots do. Particles share the
displacement (not their own noise draws), which is exact for the odometry they were all moved by and off by
the motion noise of 0.15 s at most. With no motion since the capture, nothing is moved: the result is that of
an observation without latency, bit for bit.
"""

from __future__ import annotations

import math
from collections import deque
from itertools import islice

import numba
import numpy as np

from field.angles import wrap_angle
from field.checks import LARGEST_ANGLE, LARGEST_COORDINATE, real, reals
from field.moved import moved_names
from numerics.trig import moved_back, sincos

# The numpy twins moved to the package's `reference` module; their old names still work, with a warning.
__getattr__ = moved_names(__name__, {"move_back_reference": "mcl.reference.move_back"})

IDENTITY = (0.0, 0.0, 0.0)
SAME_TIME = 1e-6  # s: times closer than this are one instant (log stamps are integer nanoseconds)


def compose(first, second) -> tuple[float, float, float]:
    """The displacement `first` followed by `second` (each (dx, dy, dθ) in the frame where it starts)."""
    dx, dy, dtheta = first
    c, s = math.cos(dtheta), math.sin(dtheta)
    return (dx + c * second[0] - s * second[1], dy + s * second[0] + c * second[1], dtheta + second[2])


@numba.njit(cache=True)
def move_back(poses: np.ndarray, displacement: np.ndarray, out: np.ndarray) -> None:
    """out = each pose moved back by `displacement` (dx, dy, dθ), given in the frame of the earlier pose."""
    dx, dy, dtheta = displacement[0], displacement[1], displacement[2]
    for i in range(poses.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = moved_back(poses[i, 0], poses[i, 1], poses[i, 2], dx, dy, dtheta)


@numba.njit(cache=True)
def move_forward(poses: np.ndarray, displacement: np.ndarray, out: np.ndarray) -> None:
    """out = each pose moved by `displacement` (dx, dy, dθ) in its own frame: the inverse of `move_back`."""
    dx, dy, dtheta = displacement[0], displacement[1], displacement[2]
    for i in range(poses.shape[0]):
        theta = poses[i, 2]
        c, s = sincos(theta)
        out[i, 0] = poses[i, 0] + (c * dx - s * dy)
        out[i, 1] = poses[i, 1] + (s * dx + c * dy)
        out[i, 2] = wrap_angle(theta + dtheta)


class MotionHistory:
    """The motion steps of the last `keep` seconds: (end time, duration, displacement) each.

    `record` takes steps in time order; `since(t)` is the displacement from time t to the end of the latest
    step. A time older than the history raises ValueError (naming both times): the correction cannot be
    placed, and the caller decides (the replay counts it as dropped).
    """

    def __init__(self, keep: float = 1.0) -> None:
        if not (isinstance(keep, (int, float)) and math.isfinite(keep) and keep > 0):
            raise ValueError(f"keep = {keep!r} must be a finite number of seconds > 0")
        self.keep = float(keep)
        self._steps: deque[tuple[float, float, tuple[float, float, float]]] = deque()
        self._start: float | None = None  # earliest time `since` can reach back to

    def clear(self, t: float | None = None) -> None:
        """Forget every step; with `t`, the history starts again at that time."""
        self._steps.clear()
        self._start = t

    @property
    def latest(self) -> float | None:
        """End time of the latest step (None before the first)."""
        return self._steps[-1][0] if self._steps else self._start

    @property
    def oldest(self) -> float | None:
        """The earliest capture time `since` accepts."""
        return self._start

    def record(self, t_end: float, dt: float, displacement) -> None:
        """A motion step of `dt` seconds ending at `t_end`, which moved the robot by `displacement` (dx, dy, dθ)
        in its frame at the step's start (at most 1 km and 100 rad)."""
        t_end = real("t_end", t_end)
        dt = real("dt", dt, 0.0)
        if not (
            type(displacement) is tuple
            and len(displacement) == 3
            and all(type(v) is float and abs(v) <= LARGEST_COORDINATE for v in displacement)
        ):
            displacement = tuple(
                float(v) for v in reals("displacement", displacement, 3, -LARGEST_COORDINATE, LARGEST_COORDINATE)
            )
        if abs(displacement[2]) > LARGEST_ANGLE:
            raise ValueError(f"displacement = {displacement!r} turns by more than {LARGEST_ANGLE:g} rad")
        latest = self.latest
        if latest is not None and t_end < latest:
            raise ValueError(f"motion step ending at {t_end:.6f} s is older than the latest ({latest:.6f} s)")
        self._steps.append((t_end, dt, displacement))
        if self._start is None:
            self._start = t_end - dt
        while self._steps and self._steps[0][0] < t_end - self.keep:
            self._start = self._steps.popleft()[0]

    def since(self, t: float) -> tuple[float, float, float]:
        """The displacement from time `t` to the latest step's end, in the robot frame at `t`.

        A step that began before `t` counts with the share of it after `t` (its displacement scaled: a step
        is short). A `t` at or after the latest step gives (0, 0, 0).
        """
        t = real("t", t)
        if self._start is not None and t < self._start - 1e-9:
            raise ValueError(
                f"an observation captured at {t:.3f} s is older than the motion history, which "
                f"reaches back to {self._start:.3f} s (keep = {self.keep} s)"
            )
        # The steps that end after t are a suffix (steps are kept in time order): found from the end, then
        # composed in time order.
        after = 0
        for t_end, _, _ in reversed(self._steps):
            if t_end <= t + SAME_TIME:
                break
            after += 1
        total = IDENTITY
        for t_end, dt, displacement in islice(self._steps, len(self._steps) - after, None):
            share = 1.0 if dt <= 0 or t_end - dt >= t else (t_end - t) / dt
            step = displacement if share == 1.0 else tuple(share * v for v in displacement)
            total = compose(total, step)
        return total


def check_since(since) -> np.ndarray | None:
    """A correction's `since` checked (`ParticleFilter.correct`): the robot's motion (dx, dy, dθ) from the
    detections' capture to now, at most `LARGEST_COORDINATE` metres and `LARGEST_ANGLE` radians; None when it
    is None or zero (captured now), else as an array.

    Raises
    ------
    ValueError
        If it is not three finite numbers, or moves or turns too far.
    """
    if since is None:
        return None
    if type(since) is tuple and len(since) == 3 and all(type(v) is float for v in since):
        # `MotionHistory.since` gives three floats: checked without numpy's calls on a tiny array
        if not (math.hypot(since[0], since[1]) <= LARGEST_COORDINATE and abs(since[2]) <= LARGEST_ANGLE):
            return check_since(list(since))  # raises, naming the rule
        return None if since == (0.0, 0.0, 0.0) else np.array(since)
    array = reals("since", since, 3)
    if math.hypot(array[0], array[1]) > LARGEST_COORDINATE or abs(array[2]) > LARGEST_ANGLE:
        raise ValueError(
            f"since = {since!r} must move at most {LARGEST_COORDINATE:g} m and turn at most {LARGEST_ANGLE:g} rad"
        )
    return None if not array.any() else array
