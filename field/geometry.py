"""Field geometry derived from `FieldDimensions`: landmarks, line segments, centre circle.

    from field import Field, LandmarkType, spl

    field = spl()
    field.landmarks_of(LandmarkType.T_CROSSING)   # (10, 2) [x, y]
    field.segments                                 # (17, 2, 2) straight lines
    field.line_points(spacing=0.05)                # points along every line

Frame: origin at the centre mark, +x toward the opponent goal, +y to the left,
headings counter-clockwise from +x in (-π, π]. All geometry is on line centre lines.
Every array a `Field` holds is float64, C-contiguous and read-only.
"""

from __future__ import annotations

import enum
import math
import numbers
import re
import types
from collections.abc import Mapping
from dataclasses import dataclass
from dataclasses import field as dataclass_field

import numpy as np
from numpy.typing import ArrayLike

from .angles import wrap_angles
from .dimensions import FieldDimensions, short_repr

MIN_LINE_SPACING = 1e-3
"""The finest spacing `Field.line_points` accepts (m): a millimetre (a few million points on the largest field)."""
MAX_NAME_LENGTH = 1000
"""Longest field name `Field` accepts, in characters. A name labels a field in messages and
files; anything longer is damage (a whole file pasted into it, say), not a name."""


class LandmarkType(enum.IntEnum):
    """Kinds of landmark a robot's vision reports; line crossings are named by shape.

    `parse` takes a member, its integer value, its name or one of the common short names in
    `LANDMARK_TYPE_ALIASES` (``L``, ``T``, ``X``, ``post``, ``penalty``, ``center``, ``centre``,
    ``centre_mark``), in any case, with hyphens or spaces for underscores (``"l-crossing"``,
    ``"penalty mark"``).
    """

    GOALPOST = 0
    L_CROSSING = 1
    T_CROSSING = 2
    X_CROSSING = 3
    PENALTY_MARK = 4
    CENTER_MARK = 5

    @classmethod
    def parse(cls, kind: LandmarkType | int | str) -> LandmarkType:
        """The member for an enum member, its integer value, or its name or an alias.

        A name or alias (`LANDMARK_TYPE_ALIASES`) is matched in any case, surrounding white
        space ignored, hyphens and spaces read as underscores: "T_CROSSING", "t-crossing",
        "T crossing" and "t" are all `T_CROSSING`.

        Parameters
        ----------
        kind : LandmarkType, int or str
            A member, its integer value, or its name or alias.

        Returns
        -------
        LandmarkType
            The member.

        Raises
        ------
        ValueError
            If `kind` names or numbers no landmark type.
        """
        if isinstance(kind, cls):
            return kind
        if isinstance(kind, str):
            key = _name_key(kind)
            member = cls.__members__.get(key)
            if member is None:
                member = LANDMARK_TYPE_ALIASES.get(key)
            if member is None:
                raise ValueError(
                    f"landmark type {kind!r} is unknown; valid names: {cls._names()}; "
                    f"aliases: {_aliases_text()} (any case, '-' or ' ' for '_')"
                )
            return member
        if isinstance(kind, (int, np.integer)) and not isinstance(kind, bool):
            try:
                return cls(int(kind))
            except ValueError:
                raise ValueError(
                    f"landmark type {kind!r} is unknown; valid values: 0..{len(cls) - 1} ({cls._names()})"
                ) from None
        raise ValueError(
            f"landmark type {kind!r} must be a LandmarkType, an int or a name ({cls._names()}; "
            f"aliases: {_aliases_text()})"
        )

    @classmethod
    def _names(cls) -> str:
        return ", ".join(member.name for member in cls)


def _name_key(text: str) -> str:
    """A type name as `LandmarkType.parse` looks it up: upper case, '_' for each run of
    hyphens and white space."""
    return re.sub(r"[\s\-]+", "_", text.strip()).upper()


LANDMARK_TYPE_ALIASES: Mapping[str, LandmarkType] = types.MappingProxyType(
    {
        "L": LandmarkType.L_CROSSING,
        "T": LandmarkType.T_CROSSING,
        "X": LandmarkType.X_CROSSING,
        "POST": LandmarkType.GOALPOST,
        "PENALTY": LandmarkType.PENALTY_MARK,
        "CENTER": LandmarkType.CENTER_MARK,
        "CENTRE": LandmarkType.CENTER_MARK,
        "CENTRE_MARK": LandmarkType.CENTER_MARK,
    }
)
"""Short names `LandmarkType.parse` accepts besides the members' names, keyed as it looks
them up (upper case, '_' for hyphens and spaces): L, T, X (the crossings), post (goalpost),
penalty (penalty mark), center, centre, centre_mark (centre mark)."""


def _aliases_text() -> str:
    """The aliases grouped by member, as an error message lists them: "L (L_CROSSING), ..."."""
    groups: dict[LandmarkType, list[str]] = {}
    for alias, member in LANDMARK_TYPE_ALIASES.items():
        groups.setdefault(member, []).append(alias if len(alias) == 1 else alias.lower())
    return ", ".join(f"{', '.join(aliases)} ({member.name})" for member, aliases in groups.items())


def _require_number(name: str, value: object) -> None:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} = {value!r} must be a number (metres)")


def _frozen(array_like) -> np.ndarray:
    array = np.ascontiguousarray(array_like, dtype=np.float64)
    array.flags.writeable = False
    return array


def _sorted_points(points: list[tuple[float, float]]) -> np.ndarray:
    """(K, 2) read-only array of `points`, sorted by x, then by y (both ascending)."""
    array = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    order = np.lexsort((array[:, 1], array[:, 0]))
    return _frozen(array[order])


@dataclass(frozen=True)
class Field:
    """An immutable soccer field: a name, its dimensions and everything derived from them.

    Build one with `Field(name, dims)`, or get one from `field.preset` / `field.load_field`.
    Two fields are equal when their names and dimensions are. The name is a non-empty string
    of at most `MAX_NAME_LENGTH` characters; `dims` is a `FieldDimensions`, which has checked
    every dimension (including the `field.dimensions.MAX_FIELD_EXTENT` bound on the size).

    Parameters
    ----------
    name : str
        Non-empty name, at most `MAX_NAME_LENGTH` characters.
    dims : FieldDimensions
        The field's (already checked) dimensions.

    Attributes
    ----------
    landmarks : Mapping[LandmarkType, numpy.ndarray]
        Read-only mapping from every `LandmarkType` to a (K, 2) array of [x, y], rows sorted by x, then by y
        (both ascending). Derived in `__post_init__`, like every attribute below, all arrays read-only
        float64. Line crossings are classified as vision sees them, at the crossing of the line centre lines:

        - L: the 4 field corners, the 4 front corners of the goal areas, the 4 front corners of the penalty
          areas;
        - T: goal-area and penalty-area side lines meeting the goal lines (8), the centre line meeting the
          touchlines (2);
        - X: the centre line crossing the centre circle (2);
        - PENALTY_MARK: (±(length/2 − penalty_mark_distance), 0);
        - CENTER_MARK: (0, 0);
        - GOALPOST: post centres at x = ±(length/2 + (goalpost_diameter − line_width)/2),
          y = ±(goal_inner_width/2 + goalpost_diameter/2). That is, the field-facing side of each post is
          flush with the field-side edge of the goal line, and ``goal_inner_width`` is the clear width
          between the posts.
    segments : numpy.ndarray
        (17, 2, 2) straight lines as [[x0, y0], [x1, y1]], start point the smaller in (x, y) order. Order:
        the two touchlines (y = −w/2, then +w/2), the two goal lines (x = −l/2, then +l/2), the centre line;
        then for the own half (−x) and then the opponent half (+x): the penalty-area front line, its right
        and left side lines, the goal-area front line, its right and left side lines.
    center_circle : tuple of float
        (cx, cy, radius) of the centre circle's centre line.

    Raises
    ------
    ValueError
        If `name` is empty or too long, or `dims` is not a `FieldDimensions`.
    """

    name: str
    dims: FieldDimensions
    landmarks: Mapping[LandmarkType, np.ndarray] = dataclass_field(init=False, repr=False, compare=False)
    segments: np.ndarray = dataclass_field(init=False, repr=False, compare=False)
    center_circle: tuple[float, float, float] = dataclass_field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"name = {short_repr(self.name)} must be a non-empty string")
        if len(self.name) > MAX_NAME_LENGTH:
            raise ValueError(
                f"name = {short_repr(self.name)} has {len(self.name)} characters; "
                f"at most MAX_NAME_LENGTH = {MAX_NAME_LENGTH} are allowed"
            )
        if not isinstance(self.dims, FieldDimensions):
            raise ValueError(f"dims = {short_repr(self.dims)} must be a FieldDimensions")
        # Frozen dataclass: derived attributes are set once, here.
        object.__setattr__(self, "landmarks", types.MappingProxyType(self._derive_landmarks()))
        object.__setattr__(self, "segments", self._derive_segments())
        object.__setattr__(self, "center_circle", (0.0, 0.0, self.dims.center_circle_diameter / 2.0))

    @property
    def half_length(self) -> float:
        """Distance from the centre mark to a goal line's centre line, in metres."""
        return self.dims.length / 2.0

    @property
    def half_width(self) -> float:
        """Distance from the centre mark to a touchline's centre line, in metres."""
        return self.dims.width / 2.0

    @property
    def carpet(self) -> tuple[float, float, float, float]:
        """The carpet's bounds (x_min, x_max, y_min, y_max) [m]: the field and its border strip."""
        border = self.dims.border_strip_width
        return (
            -self.half_length - border,
            self.half_length + border,
            -self.half_width - border,
            self.half_width + border,
        )

    def landmarks_of(self, kind: LandmarkType | int | str) -> np.ndarray:
        """(K, 2) read-only positions of one landmark type.

        `kind` is a `LandmarkType`, its integer value, or its name or alias in any case
        ("goalpost", "T_CROSSING", "t", "penalty"; see `LandmarkType.parse`). Anything else
        raises `ValueError`.

        Parameters
        ----------
        kind : LandmarkType, int or str
            The landmark type, in any form `LandmarkType.parse` accepts.

        Returns
        -------
        np.ndarray
            (K, 2) read-only float64 positions [m], rows sorted by x, then y.

        Raises
        ------
        ValueError
            If `kind` is not a landmark type.
        """
        return self.landmarks[LandmarkType.parse(kind)]

    def line_points(self, spacing: float = 0.05) -> np.ndarray:
        """(P, 2) points along every segment and the centre circle, at most `spacing` apart.

        Each segment contributes both end points and evenly spaced points between them;
        the circle contributes evenly spaced points (at least 16). Points shared by
        segments (corners, crossings) appear once. Rows are sorted by x, then by y. The
        array is a fresh, writable copy.

        Parameters
        ----------
        spacing : float, optional
            The largest distance between neighbouring points [m], at least `MIN_LINE_SPACING`;
            default 0.05.

        Returns
        -------
        np.ndarray
            (P, 2) float64 points [m] on the lines' centre lines.

        Raises
        ------
        ValueError
            If `spacing` is not a finite number of at least `MIN_LINE_SPACING`.
        """
        _require_number("spacing", spacing)
        if not (math.isfinite(spacing) and spacing >= MIN_LINE_SPACING):
            raise ValueError(f"spacing = {spacing!r} must be finite and at least {MIN_LINE_SPACING:g} m")
        pieces = []
        for start, end in self.segments:
            length = float(np.hypot(*(end - start)))
            count = max(1, math.ceil(length / spacing - 1e-9))
            t = np.linspace(0.0, 1.0, count + 1)[:, None]
            pieces.append(start + t * (end - start))
        cx, cy, radius = self.center_circle
        count = max(16, math.ceil(2.0 * math.pi * radius / spacing - 1e-9))
        angles = np.linspace(0.0, 2.0 * math.pi, count, endpoint=False)
        pieces.append(np.column_stack((cx + radius * np.cos(angles), cy + radius * np.sin(angles))))
        return np.ascontiguousarray(np.unique(np.concatenate(pieces), axis=0))

    def contains(self, xy: ArrayLike, margin: float = 0.0) -> np.ndarray:
        """Whether each point lies on the carpet: the field plus its border strip, plus `margin`.

        `xy` is array-like with shape (..., 2); the result is a bool array of shape (...).
        Edges count as inside. A negative `margin` shrinks the region.

        Parameters
        ----------
        xy : array_like
            (..., 2) points (x, y) [m] in the field frame.
        margin : float, optional
            Added to the border strip on every side [m]; default 0.

        Returns
        -------
        np.ndarray
            (...) bool, True for a point on the carpet.

        Raises
        ------
        ValueError
            If `margin` is not finite or `xy` does not have shape (..., 2).
        """
        _require_number("margin", margin)
        if not math.isfinite(margin):
            raise ValueError(f"margin = {margin!r} must be finite")
        points = np.asarray(xy, dtype=np.float64)
        if points.ndim == 0 or points.shape[-1] != 2:
            raise ValueError(f"xy has shape {points.shape}; expected (..., 2)")
        reach = self.dims.border_strip_width + float(margin)
        return (np.abs(points[..., 0]) <= self.half_length + reach) & (
            np.abs(points[..., 1]) <= self.half_width + reach
        )

    @staticmethod
    def mirror_poses(poses: np.ndarray) -> np.ndarray:
        """Poses mirrored through the centre mark: (x, y, θ) -> (−x, −y, θ + π).

        The field is point-symmetric, so a mirrored pose sees the same landmarks. `poses`
        has shape (N, 3) (any (..., 3) works); returns a new float64 array of the same
        shape with θ wrapped into (−π, π] by `field.angles.wrap_angles`. Applying it
        twice gives the original poses (θ up to a multiple of 2π).

        Parameters
        ----------
        poses : np.ndarray
            (N, 3) poses (x [m], y [m], θ [rad]); anything array-like with a last axis of 3.

        Returns
        -------
        np.ndarray
            The mirrored poses, float64, same shape.

        Raises
        ------
        ValueError
            If the last axis is not of length 3.
        """
        poses = np.asarray(poses, dtype=np.float64)
        if poses.ndim == 0 or poses.shape[-1] != 3:
            raise ValueError(f"poses has shape {poses.shape}; expected (N, 3)")
        mirrored = np.empty_like(poses, order="C")
        mirrored[..., 0] = -poses[..., 0]
        mirrored[..., 1] = -poses[..., 1]
        mirrored[..., 2] = wrap_angles(poses[..., 2] + np.pi)
        return mirrored

    def to_dict(self) -> dict:
        """``{"name": ..., "dimensions": {key: value, ...}}``: the file format, as plain data."""
        return {"name": self.name, "dimensions": self.dims.to_dict()}

    def __reduce__(self):
        # Everything else is derived; the read-only landmark mapping cannot be pickled as is.
        return (Field, (self.name, self.dims))

    def __repr__(self) -> str:
        return f"Field(name={self.name!r}, length={self.dims.length!r}, width={self.dims.width!r})"

    # Derivation. Everything below works on line centre lines.

    def _derive_landmarks(self) -> dict[LandmarkType, np.ndarray]:
        d = self.dims
        hl, hw = self.half_length, self.half_width
        penalty_x = hl - d.penalty_area_length
        goal_area_x = hl - d.goal_area_length
        penalty_y = d.penalty_area_width / 2.0
        goal_area_y = d.goal_area_width / 2.0
        post_x = hl + (d.goalpost_diameter - d.line_width) / 2.0
        post_y = d.goal_inner_width / 2.0 + d.goalpost_diameter / 2.0
        radius = d.center_circle_diameter / 2.0

        def both_halves(x: float, y: float) -> list[tuple[float, float]]:
            """(±x, ±y): the four mirror images of a corner."""
            return [(sx * x, sy * y) for sx in (-1.0, 1.0) for sy in (-1.0, 1.0)]

        points = {
            LandmarkType.GOALPOST: both_halves(post_x, post_y),
            LandmarkType.L_CROSSING: both_halves(hl, hw)
            + both_halves(goal_area_x, goal_area_y)
            + both_halves(penalty_x, penalty_y),
            LandmarkType.T_CROSSING: both_halves(hl, goal_area_y)
            + both_halves(hl, penalty_y)
            + [(0.0, -hw), (0.0, hw)],
            LandmarkType.X_CROSSING: [(0.0, -radius), (0.0, radius)],
            LandmarkType.PENALTY_MARK: [
                (-(hl - d.penalty_mark_distance), 0.0),
                (hl - d.penalty_mark_distance, 0.0),
            ],
            LandmarkType.CENTER_MARK: [(0.0, 0.0)],
        }
        return {kind: _sorted_points(points[kind]) for kind in LandmarkType}

    def _derive_segments(self) -> np.ndarray:
        d = self.dims
        hl, hw = self.half_length, self.half_width
        segments = [
            ((-hl, -hw), (hl, -hw)),  # right touchline
            ((-hl, hw), (hl, hw)),  # left touchline
            ((-hl, -hw), (-hl, hw)),  # own goal line
            ((hl, -hw), (hl, hw)),  # opponent goal line
            ((0.0, -hw), (0.0, hw)),  # centre line
        ]
        for side in (-1.0, 1.0):
            for depth, half_extent in (
                (d.penalty_area_length, d.penalty_area_width / 2.0),
                (d.goal_area_length, d.goal_area_width / 2.0),
            ):
                front_x = side * (hl - depth)
                goal_x = side * hl
                low_x, high_x = sorted((front_x, goal_x))
                segments += [
                    ((front_x, -half_extent), (front_x, half_extent)),  # front line
                    ((low_x, -half_extent), (high_x, -half_extent)),  # right side line
                    ((low_x, half_extent), (high_x, half_extent)),  # left side line
                ]
        return _frozen(segments)
