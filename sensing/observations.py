"""Landmark observations: a landmark type seen at a range and bearing in the robot frame.

    from sensing import LandmarkObservation, Observations
    from field import LandmarkType

    obs = Observations.from_list([
        LandmarkObservation(LandmarkType.GOALPOST, range=3.2, bearing=0.15),
        LandmarkObservation("T_CROSSING", range=1.1, bearing=-0.4, range_sigma=0.08),
        LandmarkObservation("L", range=2.5, bearing=0.9),             # an alias: L_CROSSING
    ])

A landmark type is given as a `LandmarkType` member, its value, its name or a common short name, in any case
and with hyphens or spaces for underscores (`LandmarkType.parse`): "L", "T", "X" (the crossings, also
"l-crossing", "T crossing"), "post" (GOALPOST), "penalty" (PENALTY_MARK), "center", "centre", "centre_mark"
(CENTER_MARK).

`Observations` is the struct-of-arrays form the sensor kernels take. It validates everything on construction,
so a bad observation is rejected before it reaches a filter: a known landmark type; a range within
[0, `MAX_RANGE`] (1 km); a bearing within ±`MAX_BEARING` (100 rad); a noise, when given, within
[`field.checks.SMALLEST_SIGMA`, `field.checks.LARGEST_SIGMA`] (1e-6 to 1e3); line points (P, 2) within 1 km.
A value of the wrong type raises TypeError (`field.checks.ArgumentTypeError`, also a ValueError), a bad value
ValueError, each naming the argument. A noise left as NaN ("not given") is filled in by the sensor model from
its noise model.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from field import LandmarkType
from field.checks import LARGEST_ANGLE, LARGEST_COORDINATE, LARGEST_SIGMA, SMALLEST_SIGMA, ArgumentTypeError, real
from field.moved import moved_names
from numerics.frozen import keeps_arrays_frozen

from .view import CameraView

# The numpy twins moved to the package's `reference` module; their old names still work, with a warning.
__getattr__ = moved_names(__name__, {"first_invalid_reference": "sensing.reference.first_invalid"})

MAX_RANGE = LARGEST_COORDINATE
"""The largest range a detection may have (m); a farther one is refused with the frame."""
MAX_BEARING = LARGEST_ANGLE
"""The largest |bearing| a detection may have (rad)."""

# IS_KIND[v]: v is a landmark type's value (values index it from 0).
IS_KIND = np.zeros(max(kind.value for kind in LandmarkType) + 1, dtype=np.bool_)
IS_KIND[[kind.value for kind in LandmarkType]] = True
# The checks of a batch's detections, in the order they are made (`first_invalid`).
BAD_KIND, RANGE_NOT_FINITE, BEARING_NOT_FINITE, NEGATIVE_RANGE, BAD_RANGE_SIGMA, BAD_BEARING_SIGMA = range(6)
_RULES = (
    "",
    "must be finite",
    "must be finite",
    "",
    f"must be within [{SMALLEST_SIGMA:g}, {LARGEST_SIGMA:g}] (or NaN for 'not given')",
    f"must be within [{SMALLEST_SIGMA:g}, {LARGEST_SIGMA:g}] (or NaN for 'not given')",
)


def _check_view(view) -> None:
    if view is not None and not isinstance(view, CameraView):
        raise ArgumentTypeError(f"view = {view!r} must be a sensing.view.CameraView or None, not {type(view).__name__}")


def landmark_type(kind: LandmarkType | int | str) -> LandmarkType:
    """Parse a landmark type given as the enum, its value, its name or an alias such as "T" or "post"
    (`LandmarkType.parse`: any case, hyphens and spaces for underscores); ValueError naming `kind` otherwise."""
    try:
        return LandmarkType.parse(kind)
    except ValueError as error:
        raise ValueError(f"kind = {kind!r}: {error}") from None


@dataclass(frozen=True)
class LandmarkObservation:
    """One detection. range [m] >= 0; bearing [rad], counter-clockwise from the robot's +x.

    kind: a `LandmarkType`, its value, its name or an alias ("L", "T", "X", "post", "penalty", "center",
    "centre"; see the module docstring), stored as the member.

    range_sigma and bearing_sigma are this detection's noise (standard deviations); None lets the sensor
    model's noise model decide (noise growing with range, as with a camera).

    Attributes
    ----------
    kind : LandmarkType
        The landmark's type (given as a member, its value, its name or an alias).
    range : float
        Distance to the landmark [m], within [0, `MAX_RANGE`].
    bearing : float
        Direction to the landmark [rad], counter-clockwise from the robot's +x, within ±`MAX_BEARING`.
    range_sigma : float or None, optional
        Standard deviation of `range` [m]; None (the default) lets the sensor model decide.
    bearing_sigma : float or None, optional
        Standard deviation of `bearing` [rad]; None (the default) lets the sensor model decide.

    Raises
    ------
    ValueError
        If `kind` is not a landmark type or a value is out of range (naming it); TypeError
        (`field.checks.ArgumentTypeError`) for a value of the wrong type.
    """

    kind: LandmarkType
    range: float
    bearing: float
    range_sigma: float | None = None
    bearing_sigma: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "kind", landmark_type(self.kind))
        real("range", self.range, 0.0, MAX_RANGE)
        real("bearing", self.bearing, -MAX_BEARING, MAX_BEARING)
        for name in ("range_sigma", "bearing_sigma"):
            value = getattr(self, name)
            if value is not None:
                real(name, value, SMALLEST_SIGMA, LARGEST_SIGMA)


@numba.njit(cache=True)
def first_invalid(kinds, ranges, bearings, range_sigmas, bearing_sigmas, is_kind):
    """(check, i): the first of the checks BAD_KIND, RANGE_NOT_FINITE, BEARING_NOT_FINITE, NEGATIVE_RANGE (a
    range outside [0, MAX_RANGE] or a bearing outside ±MAX_BEARING), BAD_RANGE_SIGMA, BAD_BEARING_SIGMA that a
    detection fails, and the first detection failing it; (-1, -1) when all pass. A noise fails when it is given
    (not NaN) and outside [SMALLEST_SIGMA, LARGEST_SIGMA]. One pass per check, no allocation;
    `sensing.reference.first_invalid` is the same in numpy."""
    for i in range(kinds.shape[0]):
        if kinds[i] < 0 or kinds[i] >= is_kind.shape[0] or not is_kind[kinds[i]]:
            return BAD_KIND, i
    for i in range(ranges.shape[0]):
        if not math.isfinite(ranges[i]):
            return RANGE_NOT_FINITE, i
    for i in range(bearings.shape[0]):
        if not math.isfinite(bearings[i]):
            return BEARING_NOT_FINITE, i
    for i in range(ranges.shape[0]):
        if not (0.0 <= ranges[i] <= MAX_RANGE and abs(bearings[i]) <= MAX_BEARING):
            return NEGATIVE_RANGE, i
    for check, sigmas in ((BAD_RANGE_SIGMA, range_sigmas), (BAD_BEARING_SIGMA, bearing_sigmas)):
        for i in range(sigmas.shape[0]):
            if not math.isnan(sigmas[i]) and not (SMALLEST_SIGMA <= sigmas[i] <= LARGEST_SIGMA):
                return check, i
    return -1, -1


def _kind_values(kinds) -> np.ndarray:
    """The int64 type values of `kinds` (members, values or names). An array of integers is taken as it is
    when every value is a type's (`Observations` checks that again); anything else is parsed one by one, which
    names the first bad entry."""
    if isinstance(kinds, np.ndarray) and kinds.dtype.kind in "iu":
        values = kinds.astype(np.int64).reshape(-1)
        if first_invalid(values, _NO_VALUES, _NO_VALUES, _NO_VALUES, _NO_VALUES, IS_KIND)[0] < 0:
            return values
    items = np.atleast_1d(np.asarray(kinds, dtype=object))
    if not len(items):
        return np.zeros(0, np.int64)
    return np.array([landmark_type(k).value for k in items], dtype=np.int64)


def _check_kind_dtype(raw) -> None:
    """Refuse kinds that are not integers (a float or boolean array, or a sequence holding a float), which a
    cast to int64 would silently truncate to another landmark type; an empty sequence of any numeric type is
    no landmark and passes. Entries that are not numbers at all are left to the cast's own error."""
    try:
        values = np.asarray(raw)
    except (TypeError, ValueError, OverflowError):
        return
    if values.size and values.dtype.kind in "fcb":
        raise ArgumentTypeError(
            f"kinds has dtype {values.dtype}: it must hold integer landmark type values "
            f"(LandmarkType members or their values; Observations.from_arrays also takes names)"
        )


_NO_VALUES = np.zeros(0)
_LANDMARK_FIELDS = ("kinds", "ranges", "bearings", "range_sigmas", "bearing_sigmas")
_NO_LINE_POINTS = np.zeros((0, 2))
_NO_LINE_POINTS.flags.writeable = False  # shared by every batch without field-line points
_EMPTY: dict[type, Observations] = {}  # `Observations.empty()` of each class


def _line_points(raw) -> np.ndarray:
    """Field-line points as a read-only (P, 2) float64 copy (None: none)."""
    if raw is None:
        return _NO_LINE_POINTS
    if isinstance(raw, (str, bytes, dict)) or np.ndim(raw) == 0 and not isinstance(raw, np.ndarray):
        raise ArgumentTypeError(f"line_points = {raw!r} must be an array of (x, y) points, not {type(raw).__name__}")
    try:
        points = np.array(raw, dtype=np.float64)  # owning its data
    except (TypeError, ValueError, OverflowError):
        raise ArgumentTypeError(f"line_points = {raw!r} must be an array of (x, y) points") from None
    if points.size == 0:
        return _NO_LINE_POINTS
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"line_points must have shape (P, 2), got {points.shape}")
    inside = np.isfinite(points).all(axis=1) & (np.abs(points) <= LARGEST_COORDINATE).all(axis=1)
    if not inside.all():
        i = int(np.argmin(inside))
        raise ValueError(
            f"line_points[{i}] = {points[i].tolist()!r} must be finite and within {LARGEST_COORDINATE:g} m"
        )
    points.flags.writeable = False
    return points


@keeps_arrays_frozen
@dataclass(frozen=True, eq=False)
class Observations:
    """One camera frame's detections as read-only arrays.

    Landmarks, arrays of equal length: kinds (int64 landmark type values), ranges, bearings, range_sigmas,
    bearing_sigmas (NaN = not given). Field lines: line_points, (P, 2) points on detected lines in the
    robot frame [m] (empty when the vision reports none). view: where the camera looked
    (`sensing.view.CameraView`), or None (not known); with it, `LandmarkSensorModel` also scores the landmarks a
    pose puts in view that the frame did not report (negative information). `with_view` attaches one.

    Attributes
    ----------
    kinds : np.ndarray
        (n,) int64 landmark type values (`LandmarkType.value`).
    ranges : np.ndarray
        (n,) float64 ranges [m].
    bearings : np.ndarray
        (n,) float64 bearings [rad], counter-clockwise from the robot's +x.
    range_sigmas : np.ndarray
        (n,) float64 range standard deviations [m]; NaN = not given.
    bearing_sigmas : np.ndarray
        (n,) float64 bearing standard deviations [rad]; NaN = not given.
    line_points : np.ndarray
        (P, 2) float64 points on detected field lines in the robot frame [m]; given as None (the default) or
        anything array-like, stored as a read-only array, (0, 2) when there are none.
    view : CameraView or None, optional
        Where the camera looked; None (the default) when not known.

    Raises
    ------
    ValueError
        If arrays differ in length, a type is unknown or a value is out of range (naming the entry); TypeError
        (`field.checks.ArgumentTypeError`) for a value of the wrong type.
    """

    kinds: np.ndarray
    ranges: np.ndarray
    bearings: np.ndarray
    range_sigmas: np.ndarray
    bearing_sigmas: np.ndarray
    # None (no line points) is replaced by a read-only (0, 2) array in __post_init__: the attribute is never None
    line_points: np.ndarray = None  # type: ignore[assignment]
    view: CameraView | None = None

    def __post_init__(self) -> None:
        _check_view(self.view)
        object.__setattr__(self, "line_points", _line_points(self.line_points))
        n = None
        for name in _LANDMARK_FIELDS:
            dtype = np.int64 if name == "kinds" else np.float64
            raw = getattr(self, name)
            if isinstance(raw, (str, bytes, dict)):
                raise ArgumentTypeError(f"{name} = {raw!r} must be an array of numbers, not {type(raw).__name__}")
            if name == "kinds":
                _check_kind_dtype(raw)
            try:
                arr = np.array(raw, dtype=dtype)  # owning its data
            except (TypeError, ValueError, OverflowError):
                raise ArgumentTypeError(f"{name} = {raw!r} must be an array of numbers") from None
            if arr.ndim > 1:
                raise ValueError(f"{name} must be one-dimensional, got shape {arr.shape}")
            if arr.ndim == 0:
                arr = arr.reshape(1).copy()
            if n is None:
                n = arr.shape[0]
            elif arr.shape[0] != n:
                raise ValueError(f"{name} has {arr.shape[0]} entries, kinds has {n}")
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        self._check_landmarks()

    @classmethod
    def _adopt(cls, kinds: np.ndarray, rows: np.ndarray, line_points=None) -> Observations:
        """A batch of arrays made for it, taken as they are instead of copied: kinds (n,) int64 and rows (4, n)
        float64 (ranges, bearings, range_sigmas, bearing_sigmas), both C-contiguous; checked as the constructor
        checks. Both become read-only."""
        kinds.flags.writeable = False
        rows.flags.writeable = False
        batch = object.__new__(cls)
        for name, arr in zip(_LANDMARK_FIELDS, (kinds, *rows)):
            object.__setattr__(batch, name, arr)
        object.__setattr__(batch, "line_points", _line_points(line_points))
        object.__setattr__(batch, "view", None)
        batch._check_landmarks()
        return batch

    def _check_landmarks(self) -> None:
        check, i = first_invalid(
            self.kinds, self.ranges, self.bearings, self.range_sigmas, self.bearing_sigmas, IS_KIND
        )
        if check == BAD_KIND:
            raise ValueError(f"kinds[{i}] = {int(self.kinds[i])} is not a landmark type")
        if check >= 0:
            name = ("ranges", "bearings", "ranges", "range_sigmas", "bearing_sigmas")[check - 1]
            rule = _RULES[check]
            if check == NEGATIVE_RANGE:
                if self.ranges[i] < 0:
                    rule = "must be >= 0"
                elif self.ranges[i] > MAX_RANGE:
                    rule = f"must be <= {MAX_RANGE:g} m"
                else:
                    name, rule = "bearings", f"must be within ±{MAX_BEARING:g} rad"
            value = getattr(self, name)[i]
            raise ValueError(f"{name}[{i}] = {value!r} {rule}")

    @classmethod
    def from_arrays(
        cls,
        kinds: Sequence | np.ndarray,
        ranges: Sequence[float] | np.ndarray,
        bearings: Sequence[float] | np.ndarray,
        range_sigmas: Sequence[float] | np.ndarray | None = None,
        bearing_sigmas: Sequence[float] | np.ndarray | None = None,
        line_points: Any = None,
    ) -> Observations:
        """A batch from equal-length sequences; kinds as LandmarkType members, their values, their names or
        aliases ("T", "post", ...; see the module docstring).

        Parameters
        ----------
        kinds : sequence or np.ndarray
            (n,) landmark types: `LandmarkType` members, values, names or aliases.
        ranges : sequence of float or np.ndarray
            (n,) ranges [m].
        bearings : sequence of float or np.ndarray
            (n,) bearings [rad], counter-clockwise from the robot's +x.
        range_sigmas, bearing_sigmas : sequence of float or np.ndarray or None, optional
            (n,) standard deviations [m] and [rad]; None (the default) or NaN entries: not given.
        line_points : array_like or None, optional
            (P, 2) points on detected field lines in the robot frame [m]; None (the default): none.

        Returns
        -------
        Observations
            The validated batch (the arrays copied).

        Raises
        ------
        ValueError
            As the constructor (an unknown type, lengths that differ, a value out of range).
        """
        kinds_arr = _kind_values(kinds)
        n = kinds_arr.shape[0]
        nan = np.full(n, np.nan)
        # the constructor converts the sequences to arrays (and refuses the rest naming the argument)
        arguments: tuple[Any, ...] = (
            kinds_arr,
            ranges,
            bearings,
            nan if range_sigmas is None else range_sigmas,
            nan if bearing_sigmas is None else bearing_sigmas,
            line_points,
        )
        return cls(*arguments)

    @classmethod
    def from_list(cls, observations: Iterable[LandmarkObservation], line_points: Any = None) -> Observations:
        """A batch from `LandmarkObservation` objects.

        Parameters
        ----------
        observations : iterable of LandmarkObservation
            The frame's detections (each already validated).
        line_points : array_like or None, optional
            (P, 2) points on detected field lines in the robot frame [m]; None (the default): none.

        Returns
        -------
        Observations
            The batch.

        Raises
        ------
        TypeError
            (`field.checks.ArgumentTypeError`) if `observations` is not iterable or holds anything else.
        """
        try:
            items = list(observations)
        except TypeError:
            raise ArgumentTypeError(
                f"observations = {observations!r} must be an Observations, a list of "
                f"LandmarkObservation or None, not {type(observations).__name__}"
            ) from None
        for i, o in enumerate(items):
            if not isinstance(o, LandmarkObservation):
                raise ArgumentTypeError(f"observations[{i}] = {o!r} is not a LandmarkObservation")
        # Two arrays built here, adopted as they are: a frame's few detections cost numpy calls, not elements.
        rows = np.array(
            [
                [o.range for o in items],
                [o.bearing for o in items],
                [math.nan if o.range_sigma is None else o.range_sigma for o in items],
                [math.nan if o.bearing_sigma is None else o.bearing_sigma for o in items],
            ],
            dtype=np.float64,
        )
        return cls._adopt(np.array([o.kind.value for o in items], dtype=np.int64), rows, line_points)

    @classmethod
    def empty(cls) -> Observations:
        """A batch without detections: one instance per class, made once (a batch cannot be changed), so that
        a frame without detections (`step(u)`, `correct(None)`) does not build one."""
        batch = _EMPTY.get(cls)
        if batch is None:
            batch = _EMPTY[cls] = cls.from_arrays([], [], [])
        return batch

    @classmethod
    def coerce(cls, observations: Observations | Iterable[LandmarkObservation] | None) -> Observations:
        """Accept a batch, a list of LandmarkObservation, or None (no observations).

        Parameters
        ----------
        observations : Observations, iterable of LandmarkObservation, or None
            A frame's detections in any accepted form.

        Returns
        -------
        Observations
            `observations` itself when it is a batch; else a batch built from it (`empty()` for None).

        Raises
        ------
        TypeError
            (`field.checks.ArgumentTypeError`) for anything else.
        """
        if observations is None:
            return cls.empty()
        if isinstance(observations, Observations):
            return observations
        return cls.from_list(observations)

    def with_view(self, view: CameraView | None) -> Observations:
        """The same detections (the read-only arrays shared, not copied) with the camera's `view` (None: without
        one). TypeError (`field.checks.ArgumentTypeError`) unless `view` is a `CameraView` or None.

        Parameters
        ----------
        view : CameraView or None
            Where the camera looked, or None to drop the view.

        Returns
        -------
        Observations
            `self` when `view` is already its view, else a new batch sharing the arrays.
        """
        _check_view(view)
        if view is self.view:
            return self
        batch = object.__new__(type(self))
        for name in (*_LANDMARK_FIELDS, "line_points"):
            object.__setattr__(batch, name, getattr(self, name))
        object.__setattr__(batch, "view", view)
        return batch

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
