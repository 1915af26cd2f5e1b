"""Landmark observations: a landmark type seen at a range and bearing in the robot frame.

    from sensing import LandmarkObservation, Observations
    from field import LandmarkType

    obs = Observations.from_list([
        LandmarkObservation(LandmarkType.GOALPOST, range=3.2, bearing=0.15),
        LandmarkObservation("T_CROSSING", range=1.1, bearing=-0.4, range_sigma=0.08),
    ])

`Observations` is the struct-of-arrays form the sensor kernels take. It validates everything on construction
(finite values, range >= 0, a known landmark type, positive noise), so a bad observation is rejected before
it reaches a filter. A noise left as NaN ("not given") is filled in by the sensor model from its noise model.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from field import LandmarkType


def landmark_type(kind: LandmarkType | int | str) -> LandmarkType:
    """Parse a landmark type given as the enum, its value or its name (case-insensitive)."""
    try:
        return LandmarkType.parse(kind)
    except ValueError as error:
        raise ValueError(f"kind = {kind!r}: {error}") from None


@dataclass(frozen=True)
class LandmarkObservation:
    """One detection. range [m] >= 0; bearing [rad], counter-clockwise from the robot's +x.

    range_sigma and bearing_sigma are this detection's noise (standard deviations); None lets the sensor
    model's noise model decide (noise growing with range, as with a camera).
    """

    kind: LandmarkType
    range: float
    bearing: float
    range_sigma: float | None = None
    bearing_sigma: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "kind", landmark_type(self.kind))
        for name in ("range", "bearing"):
            _check_number(name, getattr(self, name))
        if self.range < 0:
            raise ValueError(f"range = {self.range!r} must be >= 0")
        for name in ("range_sigma", "bearing_sigma"):
            value = getattr(self, name)
            if value is not None:
                _check_number(name, value)
                if value <= 0:
                    raise ValueError(f"{name} = {value!r} must be > 0")


def _check_number(name: str, value: object) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"{name} = {value!r} must be a number")
    if not math.isfinite(float(value)):
        raise ValueError(f"{name} = {value!r} must be finite")


@dataclass(frozen=True, eq=False)
class Observations:
    """One camera frame's detections as read-only arrays.

    Landmarks, arrays of equal length: kinds (int64 landmark type values), ranges, bearings, range_sigmas,
    bearing_sigmas (NaN = not given). Field lines: line_points, (P, 2) points on detected lines in the
    robot frame [m] (empty when the vision reports none).
    """

    kinds: np.ndarray
    ranges: np.ndarray
    bearings: np.ndarray
    range_sigmas: np.ndarray
    bearing_sigmas: np.ndarray
    line_points: np.ndarray | None = None

    def __post_init__(self) -> None:
        raw = np.zeros((0, 2)) if self.line_points is None else self.line_points
        try:
            points = np.array(raw, dtype=np.float64, copy=True).reshape(-1, 2)
        except (TypeError, ValueError):
            raise ValueError(f"line_points = {raw!r} must be an array of (x, y) points") from None
        if not np.isfinite(points).all():
            i = int(np.argmin(np.isfinite(points).all(axis=1)))
            raise ValueError(f"line_points[{i}] = {points[i].tolist()!r} must be finite")
        points.flags.writeable = False
        object.__setattr__(self, "line_points", points)
        self._check_landmarks()

    def _check_landmarks(self) -> None:
        n = None
        for name in ("kinds", "ranges", "bearings", "range_sigmas", "bearing_sigmas"):
            dtype = np.int64 if name == "kinds" else np.float64
            raw = getattr(self, name)
            try:
                arr = np.array(raw, dtype=dtype, copy=True).reshape(-1)
            except (TypeError, ValueError):
                raise ValueError(f"{name} = {raw!r} must be an array of numbers") from None
            if n is None:
                n = arr.shape[0]
            elif arr.shape[0] != n:
                raise ValueError(f"{name} has {arr.shape[0]} entries, kinds has {n}")
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        valid = np.array([t.value for t in LandmarkType])
        bad = ~np.isin(self.kinds, valid)
        if bad.any():
            raise ValueError(f"kinds[{int(np.argmax(bad))}] = {int(self.kinds[bad][0])} is not a landmark type")
        for name in ("ranges", "bearings"):
            arr = getattr(self, name)
            if not np.isfinite(arr).all():
                i = int(np.argmin(np.isfinite(arr)))
                raise ValueError(f"{name}[{i}] = {arr[i]!r} must be finite")
        if (self.ranges < 0).any():
            i = int(np.argmax(self.ranges < 0))
            raise ValueError(f"ranges[{i}] = {self.ranges[i]!r} must be >= 0")
        for name in ("range_sigmas", "bearing_sigmas"):
            arr = getattr(self, name)
            given = ~np.isnan(arr)
            if (given & ~(np.isfinite(arr) & (arr > 0))).any():
                i = int(np.argmax(given & ~(np.isfinite(arr) & (arr > 0))))
                raise ValueError(f"{name}[{i}] = {arr[i]!r} must be finite and > 0 (or NaN for 'not given')")

    @classmethod
    def from_arrays(cls, kinds: Sequence, ranges: Sequence[float], bearings: Sequence[float],
                    range_sigmas: Sequence[float] | None = None,
                    bearing_sigmas: Sequence[float] | None = None, line_points=None) -> "Observations":
        kinds_arr = np.array([landmark_type(k).value for k in np.atleast_1d(np.asarray(kinds, dtype=object))],
                             dtype=np.int64) if len(np.atleast_1d(kinds)) else np.zeros(0, np.int64)
        n = kinds_arr.shape[0]
        nan = np.full(n, np.nan)
        return cls(kinds_arr, ranges, bearings,
                   nan if range_sigmas is None else range_sigmas,
                   nan if bearing_sigmas is None else bearing_sigmas, line_points)

    @classmethod
    def from_list(cls, observations: Iterable[LandmarkObservation], line_points=None) -> "Observations":
        items = list(observations)
        for i, o in enumerate(items):
            if not isinstance(o, LandmarkObservation):
                raise ValueError(f"observations[{i}] = {o!r} is not a LandmarkObservation")
        return cls(
            np.array([o.kind.value for o in items], dtype=np.int64),
            [o.range for o in items], [o.bearing for o in items],
            [np.nan if o.range_sigma is None else o.range_sigma for o in items],
            [np.nan if o.bearing_sigma is None else o.bearing_sigma for o in items],
            line_points,
        )

    @classmethod
    def empty(cls) -> "Observations":
        return cls.from_arrays([], [], [])

    @classmethod
    def coerce(cls, observations: "Observations | Iterable[LandmarkObservation] | None") -> "Observations":
        """Accept a batch, a list of LandmarkObservation, or None (no observations)."""
        if observations is None:
            return cls.empty()
        if isinstance(observations, Observations):
            return observations
        return cls.from_list(observations)

    def __len__(self) -> int:
        """The number of landmark detections (line points are counted by `is_empty` and the line model)."""
        return int(self.kinds.shape[0])

    @property
    def is_empty(self) -> bool:
        """No landmark and no line point."""
        return self.kinds.shape[0] == 0 and self.line_points.shape[0] == 0

    def points(self) -> np.ndarray:
        """The detections as (n, 2) points in the robot frame."""
        return np.stack([self.ranges * np.cos(self.bearings), self.ranges * np.sin(self.bearings)], axis=1)
