"""Field dimensions: the numbers a rule book gives, validated on construction.

    from field import FieldDimensions

    dims = FieldDimensions(length=9.0, width=6.0, line_width=0.05, ...)
    dims.length                     # metres

Every value is in metres. "Length" is the extent along x (goal to goal), "width" the
extent along y (touchline to touchline); for the penalty and goal areas, length is
the depth from the goal line into the field and width is the extent along the goal
line. A `FieldDimensions` that exists is geometrically possible: every check below
runs in `__post_init__`, and a violation raises a `ValueError` that names the key
and its value. It is also physically plausible: the carpet (the field and its border
strip) measures at most `MAX_FIELD_EXTENT` metres along either axis.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass

from .checks import show as short_repr

MAX_FIELD_EXTENT = 200.0
"""Largest size of the carpet along either axis, in metres: both
``length + 2 * border_strip_width`` and ``width + 2 * border_strip_width`` must be at most
this, and so must every single dimension. A full-size soccer pitch (105 m x 68 m plus a
border) fits; a larger value is a unit mistake (millimetres for metres, say) or a damaged
file, and would make grids over the field (a likelihood field, for one) too big to build."""


@dataclass(frozen=True)
class FieldDimensions:
    """Dimensions of a soccer field, in metres (see the module docstring).

    Integers are accepted and stored as floats. Requirements, each checked with a
    `ValueError` naming the offending key and value:

    - every value is a finite number greater than zero (booleans are not numbers);
    - the carpet fits into `MAX_FIELD_EXTENT` (200 m) along either axis:
      ``length + 2 * border_strip_width`` and ``width + 2 * border_strip_width`` are at
      most that, and so is every value;
    - the penalty area fits into one half: ``penalty_area_length < length / 2`` and
      ``penalty_area_width < width``;
    - the goal area fits into the penalty area (both length and width);
    - the penalty mark lies inside the half: ``penalty_mark_distance < length / 2``;
    - the centre circle fits between the touchlines and stays clear of both penalty
      areas, so the only line it crosses is the centre line;
    - the goal, posts included, is narrower than the field, and the posts are thinner
      than the border strip they stand on, so every landmark is on the carpet;
    - lines are thinner than the narrowest gap between any two of them, so no two
      lines merge into one.

    Parameters
    ----------
    length, width : float
        The field inside the outer lines' centre lines along x (goal to goal) and y
        (touchline to touchline) [m].
    line_width : float
        Width of every painted line [m].
    penalty_area_length, penalty_area_width : float
        Depth of a penalty area from its goal line and its extent along the goal line [m].
    goal_area_length, goal_area_width : float
        The same for a goal area [m].
    penalty_mark_distance : float
        Distance of a penalty mark from its goal line [m].
    center_circle_diameter : float
        Diameter of the centre circle [m].
    goal_inner_width : float
        Clear width between the goalposts [m].
    goalpost_diameter : float
        Diameter of a goalpost [m].
    border_strip_width : float
        Width of the carpet outside the outer lines [m].

    Raises
    ------
    ValueError
        If a value or a relation above fails (naming the key and its value).
    """

    length: float
    width: float
    line_width: float
    penalty_area_length: float
    penalty_area_width: float
    goal_area_length: float
    goal_area_width: float
    penalty_mark_distance: float
    center_circle_diameter: float
    goal_inner_width: float
    goalpost_diameter: float
    border_strip_width: float

    def __post_init__(self) -> None:
        for key in self.keys():
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise ValueError(f"{key} = {short_repr(value)} must be a number (metres)")
            try:
                value = float(value)
            except OverflowError:  # an int too large for a float
                raise ValueError(f"{key} = {short_repr(value)} must be finite") from None
            except (TypeError, ValueError):  # a Real type whose float() fails
                raise ValueError(f"{key} = {short_repr(value)} must be a number (metres)") from None
            if not math.isfinite(value):
                raise ValueError(f"{key} = {value!r} must be finite")
            if value <= 0.0:
                raise ValueError(f"{key} = {value!r} must be greater than 0")
            if value > MAX_FIELD_EXTENT:
                raise ValueError(f"{key} = {value!r} must be at most MAX_FIELD_EXTENT = {MAX_FIELD_EXTENT!r} (metres)")
            # Frozen dataclass: normalising ints to floats needs object.__setattr__.
            object.__setattr__(self, key, value)
        for key in ("length", "width"):
            extent = getattr(self, key) + 2.0 * self.border_strip_width
            if not extent <= MAX_FIELD_EXTENT:
                raise ValueError(
                    f"{key} + 2 * border_strip_width = {round(extent, 9)!r} (with {key} = "
                    f"{getattr(self, key)!r}, border_strip_width = {self.border_strip_width!r}) "
                    f"must be at most MAX_FIELD_EXTENT = {MAX_FIELD_EXTENT!r} (metres)"
                )
        self._check_relations()

    @classmethod
    def keys(cls) -> tuple[str, ...]:
        """Names of all dimensions, in declaration order (the file format's keys)."""
        return tuple(f.name for f in dataclasses.fields(cls))

    def to_dict(self) -> dict[str, float]:
        """Plain ``{key: value}`` dict of every dimension, in declaration order."""
        return {key: getattr(self, key) for key in self.keys()}

    def _check_relations(self) -> None:
        half_length = self.length / 2.0
        circle_radius = self.center_circle_diameter / 2.0

        _require_smaller("penalty_area_length", self.penalty_area_length, "length / 2", half_length)
        _require_smaller("penalty_area_width", self.penalty_area_width, "width", self.width)
        _require_smaller(
            "goal_area_length",
            self.goal_area_length,
            "penalty_area_length",
            self.penalty_area_length,
        )
        _require_smaller("goal_area_width", self.goal_area_width, "penalty_area_width", self.penalty_area_width)
        _require_smaller("penalty_mark_distance", self.penalty_mark_distance, "length / 2", half_length)
        _require_smaller("center_circle_diameter", self.center_circle_diameter, "width", self.width)
        # A circle reaching into a penalty area would create crossings that the
        # landmark model does not list.
        _require_smaller(
            "center_circle_diameter",
            self.center_circle_diameter,
            "length - 2 * penalty_area_length",
            self.length - 2.0 * self.penalty_area_length,
        )
        _require_smaller(
            "goal_inner_width",
            self.goal_inner_width,
            "width - 2 * goalpost_diameter",
            self.width - 2.0 * self.goalpost_diameter,
        )
        _require_smaller(
            "goalpost_diameter",
            self.goalpost_diameter,
            "border_strip_width",
            self.border_strip_width,
        )

        gaps = {
            "goal_area_length": self.goal_area_length,
            "penalty_area_length - goal_area_length": self.penalty_area_length - self.goal_area_length,
            "length / 2 - penalty_area_length - center_circle_diameter / 2": half_length
            - self.penalty_area_length
            - circle_radius,
            "(penalty_area_width - goal_area_width) / 2": (self.penalty_area_width - self.goal_area_width) / 2.0,
            "(width - penalty_area_width) / 2": (self.width - self.penalty_area_width) / 2.0,
            "(width - center_circle_diameter) / 2": (self.width - self.center_circle_diameter) / 2.0,
            "center_circle_diameter / 2": circle_radius,
        }
        narrowest = min(gaps, key=gaps.__getitem__)
        _require_smaller(
            "line_width",
            self.line_width,
            f"the narrowest gap between lines, {narrowest}",
            gaps[narrowest],
        )


def _require_smaller(key: str, value: float, bound_name: str, bound: float) -> None:
    if not value < bound:
        # Rounded for display only, so derived bounds read 0.65 rather than 0.6499999999999999.
        raise ValueError(f"{key} = {value!r} must be smaller than {bound_name} = {round(bound, 9)!r}")
