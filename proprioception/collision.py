"""Collision detection by sensor-actuator comparison: the leg servos' readings against their commands.

    from proprioception.collision import CollisionDetector, learn_reference

    reference = learn_reference(commands, readings, phase, walk_commands, joint_sides)   # free walking
    reference.save("collision_reference.npz")
    detector = CollisionDetector(reference)
    for each frame:
        percept = detector.update(joint_command, joint_reading, gait_phase, walk_command)
        u = MotionInput(dt, command=walk_command, collision=percept)     # for motion_models.AdaptiveMotion

How it works (Hoffmann 2007 section 1 and 3.1, after Hoffmann & Göhring 2005). A servo lags its command by a
few frames, so each reading is compared with the command `delay` frames earlier; the delay of each joint is
estimated from free walking as the lag that minimises the mean squared deviation. The squared deviations of
the joints of one side (left legs, right legs) are summed over the last `window` frames: D(t). Free walking
leaves a deviation that depends on how fast the joints move, i.e. on the walking speed and the gait phase, so
the reference R(phase, speed) is learned from a recording of free walking: per phase bin and per walking speed,
the largest D seen there, times a `margin`. Then S_rel = D / R, and a side is in collision when S_rel > 1.
The walking speed is |v| + half_stance·|ω| (a turn moves the feet too); between the speeds the free walk
covered, R is interpolated linearly, outside them it is held at the nearest one.

The percept (`CollisionPercept`) also says how often collisions were detected in the last `recent_frames`
frames (default 60, about a gait cycle: the "collisions at high frequency" that keep the robot stopped), and
on which side(s) the latest collision was (the sides detected within `side_frames` of the latest detection,
for as long as that lies within the recent frames), which is the side of Hoffmann eq. 26
(`CollisionPercept.side`). A leg held by an obstacle is held hardest while it swings into it, so a collision is
often detected in bursts, once per step: the recent window bridges the gaps between them, and a collision on
the other side, soon after, replaces the side rather than cancelling it.

Errors: arrays of mismatched shapes, NaN readings or commands, and a reference learned from too little free
walking raise ValueError naming the problem; a rejected `update` leaves the detector as it was. A
`CollisionReference` checks itself when it is made (see its docstring for the rules, with the bounds `MAX_JOINTS`,
`MAX_DELAY`, `MAX_WINDOW` and `MIN_REFERENCE`), so any reference that exists, learned or loaded, works with the
detector; `CollisionReference.load` checks every field of a file before it builds anything, and a damaged or
foreign file raises ValueError naming the file and the field (a missing file stays FileNotFoundError).
"""

from __future__ import annotations

import math
import os
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from field.checks import show as _short_repr
from motion_models.lwpr import load_npz
from motion_models.percepts import NO_COLLISION, CollisionPercept  # noqa: F401 (re-exported: the detector's percept)

LEFT_LEG, RIGHT_LEG = 0, 1
FORMAT = "robocup-mcl collision reference"
FORMAT_VERSION = 1

MAX_JOINTS = 100
"""Most joints a `CollisionReference` covers. A humanoid's legs have 10 to 14 servos; the detector keeps a ring
buffer of (longest delay + 1) x joints commands."""
MAX_DELAY = 1000
"""Longest servo delay a `CollisionReference` holds, in frames (10 s at 100 Hz; real servos lag a few frames)."""
MAX_WINDOW = 1000
"""Longest deviation window a `CollisionReference` holds, in frames (10 s at 100 Hz; a gait cycle is about 60)."""

MIN_REFERENCE = 1e-12
"""Smallest reference value R a `CollisionReference` holds, in rad². S_rel = D / R divides by it: R = 0 would
make S_rel infinite or NaN, and a subnormal R would overflow it for any deviation. A free walk deviates far more
(servo sensors resolve about 1e-3 rad, 1e-6 rad²; learned tables are around 1e-3), so a smaller R is damage."""


def _as_2d(name: str, value, columns: int | None = None) -> np.ndarray:
    array = np.asarray(value, dtype=np.float64)
    if array.ndim != 2 or (columns is not None and array.shape[1] != columns):
        want = f"(T, {columns})" if columns is not None else "(T, J)"
        raise ValueError(f"{name} must have shape {want}, got {array.shape}")
    if not np.isfinite(array).all():
        row = int(np.argwhere(~np.isfinite(array))[0, 0])
        raise ValueError(f"{name} has a non-finite value at row {row}")
    return array


def gait_speed(walk_commands: np.ndarray, half_stance: float) -> np.ndarray:
    """Walking speed of each request (vx, vy, ω): |v| + half_stance·|ω| [m/s] (how fast the feet move)."""
    walk_commands = np.atleast_2d(walk_commands)
    return np.hypot(walk_commands[:, 0], walk_commands[:, 1]) + half_stance * np.abs(walk_commands[:, 2])


def estimate_delays(commands: np.ndarray, readings: np.ndarray, max_delay: int = 10) -> np.ndarray:
    """Per joint, the delay d in frames (0..max_delay) minimising mean (reading[t] - command[t - d])²."""
    commands = _as_2d("commands", commands)
    readings = _as_2d("readings", readings, commands.shape[1])
    if readings.shape != commands.shape:
        raise ValueError(f"readings {readings.shape} and commands {commands.shape} must have the same shape")
    if commands.shape[0] <= 2 * max_delay:
        raise ValueError(
            f"need more than {2 * max_delay} frames to estimate delays up to {max_delay}, got {commands.shape[0]}"
        )
    costs = np.empty((max_delay + 1, commands.shape[1]))
    for d in range(max_delay + 1):
        # The same frames (t >= max_delay) for every candidate, so the costs compare.
        costs[d] = np.mean((readings[max_delay:] - commands[max_delay - d : commands.shape[0] - d]) ** 2, axis=0)
    return np.argmin(costs, axis=0).astype(np.int64)


def windowed_deviation(
    commands: np.ndarray, readings: np.ndarray, delays: np.ndarray, joint_sides: np.ndarray, window: int
) -> np.ndarray:
    """D(t) per side (T, 2): Σ over the last `window` frames and the side's joints of (reading - delayed
    command)². Rows before a full window (and before the longest delay) are NaN."""
    n, joints = commands.shape
    deviation = np.full((n, joints), np.nan)
    for j in range(joints):
        d = int(delays[j])
        deviation[d:, j] = (readings[d:, j] - commands[: n - d, j]) ** 2
    per_side = np.column_stack([deviation[:, joint_sides == side].sum(axis=1) for side in (LEFT_LEG, RIGHT_LEG)])
    out = np.full((n, 2), np.nan)
    if n >= window:
        windows = np.lib.stride_tricks.sliding_window_view(per_side, window, axis=0)  # (n - window + 1, 2, w)
        out[window - 1 :] = windows.sum(axis=-1)
    return out


@dataclass(frozen=True)
class CollisionReference:
    """The learned free-walking deviation: what `CollisionDetector` compares with.

    delays (J,) frames per joint; joint_sides (J,) LEFT_LEG (0) or RIGHT_LEG (1) per joint; window (frames);
    speeds (S,) walking speeds the free walk covered; table (2, S, phase_bins) the reference R per side.

    Checked on construction, each violation a ValueError naming the field and its value: 1 <= J <= `MAX_JOINTS`;
    delays integers in [0, `MAX_DELAY`]; joint_sides integers 0 or 1, both sides present; window an integer in
    [1, `MAX_WINDOW`]; speeds finite, >= 0 and strictly increasing, S >= 1; table finite and at least
    `MIN_REFERENCE` (S_rel = D / R divides by it), phase_bins >= 1; half_stance a finite number > 0. Integer arrays
    are stored as int64, speeds and table as float64, window as an int and half_stance as a float.
    """

    delays: np.ndarray
    joint_sides: np.ndarray
    window: int
    speeds: np.ndarray
    table: np.ndarray
    half_stance: float

    def __post_init__(self) -> None:
        delays = _array("delays", self.delays, "iu", np.int64, 1)
        joints = delays.shape[0]
        if not 1 <= joints <= MAX_JOINTS:
            raise ValueError(f"delays covers {joints} joints; a reference needs 1 to MAX_JOINTS = {MAX_JOINTS}")
        if delays.min() < 0 or delays.max() > MAX_DELAY:
            raise ValueError(f"delays = {_short_repr(delays.tolist())} must be frames in [0, MAX_DELAY = {MAX_DELAY}]")
        sides = _array("joint_sides", self.joint_sides, "iu", np.int64, 1)
        if sides.shape != (joints,) or not np.isin(sides, (LEFT_LEG, RIGHT_LEG)).all():
            raise ValueError(
                f"joint_sides = {_short_repr(sides.tolist())} must be {joints} values of 0 (left) or "
                "1 (right), one per delay"
            )
        for side, name in ((LEFT_LEG, "left"), (RIGHT_LEG, "right")):
            if not (sides == side).any():
                raise ValueError(f"joint_sides = {_short_repr(sides.tolist())} has no {name} joint")
        window = self.window
        if (
            isinstance(window, (bool, np.bool_))
            or not isinstance(window, (int, np.integer))
            or not 1 <= window <= MAX_WINDOW
        ):
            raise ValueError(f"window = {_short_repr(window)} must be an integer in [1, MAX_WINDOW = {MAX_WINDOW}]")
        speeds = _array("speeds", self.speeds, "fiu", np.float64, 1)
        if speeds.shape[0] == 0 or not np.isfinite(speeds).all() or speeds.min() < 0 or (np.diff(speeds) <= 0).any():
            raise ValueError(
                f"speeds = {_short_repr(speeds.tolist())} must be one or more finite walking speeds "
                ">= 0, strictly increasing"
            )
        table = _array("table", self.table, "fiu", np.float64, 3)
        if table.shape[:2] != (2, speeds.shape[0]) or table.shape[2] == 0:
            raise ValueError(
                f"table has shape {table.shape}; expected (2, {speeds.shape[0]}, phase_bins) with "
                "phase_bins >= 1 (sides, speeds, phase bins)"
            )
        bad = ~(np.isfinite(table) & (table >= MIN_REFERENCE))
        if bad.any():
            side, speed, phase_bin = (int(i) for i in np.argwhere(bad)[0])
            value = float(table[side, speed, phase_bin])
            raise ValueError(
                f"table[{side}, {speed}, {phase_bin}] = {value!r} must be finite and at least "
                f"MIN_REFERENCE = {MIN_REFERENCE!r} (S_rel = D / R divides by it)"
            )
        half_stance = self.half_stance
        number = not isinstance(half_stance, (bool, np.bool_)) and isinstance(
            half_stance, (int, float, np.integer, np.floating)
        )
        try:
            half_stance = float(half_stance) if number else math.nan
        except OverflowError:  # an int too large for a float
            half_stance = math.inf
        if not (math.isfinite(half_stance) and half_stance > 0):
            raise ValueError(f"half_stance = {_short_repr(self.half_stance)} must be a finite number > 0 (metres)")
        # Frozen dataclass: the normalised values are set with object.__setattr__.
        normalised: tuple[tuple[str, object], ...] = (
            ("delays", delays),
            ("joint_sides", sides),
            ("window", int(window)),
            ("speeds", speeds),
            ("table", table),
            ("half_stance", float(half_stance)),
        )
        for name, normal in normalised:
            object.__setattr__(self, name, normal)

    @property
    def n_joints(self) -> int:
        return int(self.delays.shape[0])

    @property
    def phase_bins(self) -> int:
        return int(self.table.shape[2])

    def reference(self, phase, speed) -> np.ndarray:
        """R per side for arrays of gait phases [0, 1) and walking speeds: shape (..., 2)."""
        phase = np.asarray(phase, dtype=np.float64)
        speed = np.asarray(speed, dtype=np.float64)
        bins = np.minimum((np.mod(phase, 1.0) * self.phase_bins).astype(np.int64), self.phase_bins - 1)
        out = np.empty(np.broadcast(phase, speed).shape + (2,))
        for side in (LEFT_LEG, RIGHT_LEG):
            rows = self.table[side]  # (S, P)
            if self.speeds.shape[0] == 1:
                out[..., side] = rows[0][bins]
                continue
            position = np.interp(speed, self.speeds, np.arange(self.speeds.shape[0], dtype=np.float64))
            low = np.minimum(position.astype(np.int64), self.speeds.shape[0] - 2)
            share = position - low
            out[..., side] = (1.0 - share) * rows[low, bins] + share * rows[low + 1, bins]
        return out

    def save(self, path: str | Path) -> None:
        np.savez(
            path,
            format=np.array(FORMAT),
            version=np.array(FORMAT_VERSION),
            delays=self.delays,
            joint_sides=self.joint_sides,
            window=np.array(self.window),
            speeds=self.speeds,
            table=self.table,
            half_stance=np.array(self.half_stance),
        )

    @classmethod
    def load(cls, path: str | Path) -> CollisionReference:
        """Read a reference written by `save`. A truncated, damaged or foreign file, another format version,
        or a field of the wrong type, shape or value raise ValueError naming the file and the field (every
        field is checked before anything is built); a missing file raises FileNotFoundError, a path that is not
        a str or os.PathLike TypeError."""
        if not isinstance(path, (str, bytes, os.PathLike)):
            raise TypeError(f"path = {_short_repr(path)} must be a str or os.PathLike, not {type(path).__name__}")
        path = os.fspath(path)
        data = load_npz(path, "a collision reference")
        where = f"collision reference {path!r}"

        def need(key: str, kinds: str, ndim: int) -> np.ndarray:
            if key not in data:
                raise ValueError(f"{where} lacks the field {key!r}")
            array = data[key]
            if array.dtype.kind not in kinds or array.ndim != ndim:
                raise ValueError(
                    f"{where}: field {key!r} = {_short_repr(array)} has dtype {array.dtype} and "
                    f"{array.ndim} dimensions; expected {_KIND_NAMES[kinds]} in {ndim} dimensions"
                )
            return array

        fmt = data.get("format")
        if fmt is None or fmt.dtype.kind != "U" or fmt.shape != () or str(fmt) != FORMAT:
            raise ValueError(f"{where} is not a collision reference (format {_short_repr(fmt)})")
        version = int(need("version", "iu", 0))
        if version != FORMAT_VERSION:
            raise ValueError(
                f"{where} has format version {version}; this version of robocup-mcl reads version {FORMAT_VERSION}"
            )
        delays, joint_sides = need("delays", "iu", 1), need("joint_sides", "iu", 1)
        window, speeds = int(need("window", "iu", 0)), need("speeds", "fiu", 1)
        table, half_stance = need("table", "fiu", 3), float(need("half_stance", "fiu", 0))
        try:
            return cls(
                delays=delays,
                joint_sides=joint_sides,
                window=window,
                speeds=speeds,
                table=table,
                half_stance=half_stance,
            )
        except ValueError as error:
            raise ValueError(f"{where}: {error}") from None


_KIND_NAMES = {"iu": "integers", "fiu": "real numbers"}


def _array(name: str, value, kinds: str, dtype, ndim: int) -> np.ndarray:
    """`value` as a `dtype` array of `ndim` dimensions, or ValueError unless its dtype kind is one of `kinds`
    (booleans are not numbers)."""
    try:
        array = np.asarray(value)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} = {_short_repr(value)} is not an array: {error}") from None
    if array.dtype.kind not in kinds:
        raise ValueError(f"{name} = {_short_repr(value)} has dtype {array.dtype}; expected {_KIND_NAMES[kinds]}")
    if array.ndim != ndim:
        raise ValueError(f"{name} has shape {array.shape}; expected {ndim} dimension{'s' if ndim > 1 else ''}")
    return array.astype(dtype, copy=False)


def learn_reference(
    commands,
    readings,
    phase,
    walk_commands,
    joint_sides,
    *,
    window: int = 10,
    phase_bins: int = 10,
    speed_grid=(0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35),
    margin: float = 1.5,
    max_delay: int = 10,
    min_samples: int = 20,
    half_stance: float = 0.05,
) -> CollisionReference:
    """Learn the reference from a recording of free walking (no collisions).

    commands, readings: (T, J) joint commands and servo readings [rad]; phase: (T,) gait phase in [0, 1);
    walk_commands: (T, 3) the walk request (vx, vy, ω) per frame; joint_sides: (J,) 0 for a left leg's joint,
    1 for a right one's. Each frame is filed under its phase bin and the nearest speed of `speed_grid`; a
    speed is kept when every phase bin holds at least `min_samples` frames there, and R is `margin` times the
    largest D of its bin. Raises ValueError when no speed is covered that well (too little free walking).
    """
    commands = _as_2d("commands", commands)
    readings = _as_2d("readings", readings, commands.shape[1])
    if readings.shape != commands.shape:
        raise ValueError(f"readings {readings.shape} and commands {commands.shape} must have the same shape")
    n, joints = commands.shape
    phase = np.asarray(phase, dtype=np.float64)
    if phase.shape != (n,) or not np.isfinite(phase).all():
        raise ValueError(f"phase must be {n} finite values, got shape {phase.shape}")
    walk_commands = _as_2d("walk_commands", walk_commands, 3)
    if walk_commands.shape[0] != n:
        raise ValueError(f"walk_commands has {walk_commands.shape[0]} rows, commands {n}")
    joint_sides = np.asarray(joint_sides, dtype=np.int64)
    if joint_sides.shape != (joints,) or not np.isin(joint_sides, (LEFT_LEG, RIGHT_LEG)).all():
        raise ValueError(f"joint_sides must be {joints} values of 0 (left) or 1 (right), got {joint_sides}")
    for side, name in ((LEFT_LEG, "left"), (RIGHT_LEG, "right")):
        if not (joint_sides == side).any():
            raise ValueError(f"joint_sides has no {name} joint")
    for name, value, low in (
        ("window", window, 1),
        ("phase_bins", phase_bins, 1),
        ("max_delay", max_delay, 0),
        ("min_samples", min_samples, 1),
    ):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise ValueError(f"{name} = {value!r} must be an integer >= {low}")
    if not (math.isfinite(margin) and margin >= 1.0):
        raise ValueError(f"margin = {margin!r} must be finite and >= 1")
    grid = np.asarray(speed_grid, dtype=np.float64)
    if grid.ndim != 1 or grid.size == 0 or not np.isfinite(grid).all() or (np.diff(grid) <= 0).any():
        raise ValueError(f"speed_grid = {speed_grid!r} must be increasing finite speeds")
    delays = estimate_delays(commands, readings, max_delay)
    deviation = windowed_deviation(commands, readings, delays, joint_sides, window)
    valid = np.isfinite(deviation[:, 0])
    speed = gait_speed(walk_commands, half_stance)
    speed_index = np.abs(speed[:, None] - grid[None, :]).argmin(axis=1)
    bins = np.minimum((np.mod(phase, 1.0) * phase_bins).astype(np.int64), phase_bins - 1)
    table = np.full((2, grid.size, phase_bins), np.nan)
    kept = []
    for s in range(grid.size):
        rows = valid & (speed_index == s)
        counts = np.bincount(bins[rows], minlength=phase_bins)
        if counts.min() < min_samples:
            continue
        kept.append(s)
        for side in (LEFT_LEG, RIGHT_LEG):
            largest = np.full(phase_bins, -np.inf)
            np.maximum.at(largest, bins[rows], deviation[rows, side])
            table[side, s] = margin * largest
    if not kept:
        raise ValueError(
            f"too little free walking to learn a reference: no walking speed of {grid.tolist()} has "
            f"{min_samples} frames in each of its {phase_bins} phase bins ({int(valid.sum())} usable "
            "frames given)"
        )
    return CollisionReference(delays, joint_sides, int(window), grid[kept], table[:, kept, :], float(half_stance))


class CollisionDetector:
    """Online detector: feed one frame at a time with `update`; `reset()` forgets the history."""

    def __init__(self, reference: CollisionReference, recent_frames: int = 60, side_frames: int = 30) -> None:
        if not isinstance(reference, CollisionReference):
            raise ValueError(f"reference = {reference!r} must be a CollisionReference (see learn_reference)")
        _check_frames(recent_frames, side_frames)
        self.reference = reference
        self.recent_frames = int(recent_frames)
        self.side_frames = int(side_frames)
        self._left_mask = reference.joint_sides == LEFT_LEG
        self._joint_index = np.arange(reference.n_joints)
        self.reset()

    def reset(self) -> None:
        longest = int(self.reference.delays.max())
        self._commands = np.zeros((longest + 1, self.reference.n_joints))  # ring buffer of past commands
        self._frames = 0
        self._deviation: deque[tuple[float, float]] = deque(maxlen=self.reference.window)  # (left, right) sums
        self._recent: deque[bool] = deque(maxlen=self.recent_frames)  # per-frame collision flags
        self._last = [-math.inf, -math.inf]  # frame of each side's last collision

    def update(self, command, reading, phase: float, walk_command) -> CollisionPercept:
        """One frame: joint commands (J,) and readings (J,) [rad], gait phase, walk request (vx, vy, ω)."""
        joints = self.reference.n_joints
        command = np.asarray(command, dtype=np.float64)
        reading = np.asarray(reading, dtype=np.float64)
        if command.shape != (joints,) or reading.shape != (joints,):
            raise ValueError(f"command {command.shape} and reading {reading.shape} must both have shape ({joints},)")
        if not (np.isfinite(command).all() and np.isfinite(reading).all()):
            raise ValueError("command and reading must be finite (a NaN servo reading?)")
        walk = np.asarray(walk_command, dtype=np.float64)
        if walk.shape != (3,) or not np.isfinite(walk).all():
            raise ValueError(f"walk_command = {walk_command!r} must be three finite numbers (vx, vy, ω)")
        if not math.isfinite(phase):
            raise ValueError(f"phase = {phase!r} must be finite")
        size = self._commands.shape[0]
        self._commands[self._frames % size] = command
        self._frames += 1
        delays = self.reference.delays
        if self._frames <= int(delays.max()):
            return self._percept(0.0, 0.0)
        delayed = self._commands[(self._frames - 1 - delays) % size, self._joint_index]
        squared = (reading - delayed) ** 2
        self._deviation.append((squared[self._left_mask].sum(), squared[~self._left_mask].sum()))
        if len(self._deviation) < self.reference.window:
            return self._percept(0.0, 0.0)
        deviation = np.sum(np.array(self._deviation), axis=0)
        reference = self.reference.reference(phase, gait_speed(walk, self.reference.half_stance)[0])
        return self._percept(float(deviation[0] / reference[0]), float(deviation[1] / reference[1]))

    def _percept(self, s_left: float, s_right: float) -> CollisionPercept:
        left, right = s_left > 1.0, s_right > 1.0
        frame = self._frames - 1
        self._recent.append(left or right)
        if left:
            self._last[0] = frame
        if right:
            self._last[1] = frame
        rate = sum(self._recent) / len(self._recent)
        latest = max(self._last)
        recent_left, recent_right = (
            frame - latest < self.recent_frames and self._last[side] >= latest - self.side_frames for side in (0, 1)
        )
        return CollisionPercept(left, right, s_left, s_right, rate, recent_left, recent_right)


MAX_FRAMES = 100_000
"""The most frames `recent_frames` and `side_frames` may span (over a quarter of an hour at 100 Hz)."""


def _check_frames(recent_frames, side_frames) -> None:
    for name, value in (("recent_frames", recent_frames), ("side_frames", side_frames)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= value <= MAX_FRAMES:
            raise ValueError(f"{name} = {value!r} must be an integer within [1, {MAX_FRAMES}]")


def detect(
    reference: CollisionReference,
    commands,
    readings,
    phase,
    walk_commands,
    recent_frames: int = 60,
    side_frames: int = 30,
) -> dict[str, np.ndarray]:
    """The detector over a whole recording at once: arrays s_rel (T, 2), collision (T, 2) bool, rate (T,),
    recent (T, 2) bool; the same as feeding `CollisionDetector.update` frame by frame (up to rounding)."""
    commands = _as_2d("commands", commands, reference.n_joints)
    readings = _as_2d("readings", readings, reference.n_joints)
    if readings.shape != commands.shape:
        raise ValueError(f"readings {readings.shape} and commands {commands.shape} must have the same shape")
    _check_frames(recent_frames, side_frames)
    n = commands.shape[0]
    phase = np.asarray(phase, dtype=np.float64)
    walk_commands = _as_2d("walk_commands", walk_commands, 3)
    if phase.shape != (n,) or walk_commands.shape[0] != n:
        raise ValueError(f"phase {phase.shape} and walk_commands {walk_commands.shape} must have {n} rows")
    if not np.isfinite(phase).all():
        raise ValueError(f"phase has a non-finite value at row {int(np.argwhere(~np.isfinite(phase))[0, 0])}")
    deviation = windowed_deviation(commands, readings, reference.delays, reference.joint_sides, reference.window)
    ref = reference.reference(phase, gait_speed(walk_commands, reference.half_stance))
    s_rel = np.where(np.isfinite(deviation), deviation / ref, 0.0)
    collision = s_rel > 1.0
    any_collision = collision.any(axis=1).astype(np.float64)
    kernel = np.ones(recent_frames)
    counts = np.convolve(any_collision, kernel)[:n]
    available = np.minimum(np.arange(1, n + 1), recent_frames)
    frames = np.arange(n, dtype=np.float64)
    last = np.column_stack(
        [np.maximum.accumulate(np.where(collision[:, side], frames, -np.inf)) for side in (LEFT_LEG, RIGHT_LEG)]
    )
    latest = last.max(axis=1)
    recent = (frames - latest < recent_frames)[:, None] & (last >= latest[:, None] - side_frames)
    return {"s_rel": s_rel, "collision": collision, "rate": counts / available, "recent": recent}
