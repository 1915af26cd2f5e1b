"""Where the camera looked when a frame was taken: what the frame could have seen.

    from sensing.view import CameraView

    view = CameraView(yaw=head_pan, half_fov=math.radians(30), max_range=6.0, min_range=0.3)
    view = CameraView(head_pan, math.radians(30), {"goalpost": 8.0, "others": 4.0}, 0.3)   # per landmark type
    loc.observe(observations, capture_time=t_image, view=view)

A frame's detections say what was seen. The view says what *could* have been seen: a landmark inside the
camera's horizontal field of view, between `min_range` (closer ones are below the image) and `max_range` (the
vision does not report farther ones). From the estimated pose, the landmarks inside the view should mostly be
detected; when the estimate expects many that the frame did not report, the estimate is probably wrong, even
when every detection it did get fits (perceptual aliasing: a wrong pose that explains a few detections). This
is *negative information*; `LandmarkSensorModel.seen` counts it and `mcl.localizer`'s quality uses it.

A vision detects a goalpost much farther than a penalty mark or a line crossing: `max_range` is one range for
every type, or a mapping {landmark type: range}. Its keys are what `sensing.observations.landmark_type` takes
(a `LandmarkType`, its value, its name or an alias: "goalpost", "post", "T", 4); the key "others" gives the
range of every type the mapping does not name, and without it such a type gets the largest range the mapping
gives. The view keeps the per-type form as a tuple of one range per landmark type, indexed by the type's value
(`view.max_range[LandmarkType.GOALPOST]`), and takes that tuple back; `range_of(kind)` reads either form.

All angles in the robot frame (x forward, y left), radians; ranges in metres. A team knows its head's pan
angle (the joint reading at capture time), its camera's field of view and roughly how far its vision detects
landmarks; the view is optional everywhere it is taken.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from field import LandmarkType
from field.checks import LARGEST_ANGLE, LARGEST_COORDINATE, ArgumentTypeError, real
from field.checks import show as _show
from numerics.frozen import keeps_arrays_frozen

OTHERS = "others"
"""The key of a `max_range` mapping that gives the range of every landmark type the mapping does not name."""
N_TYPES = len(LandmarkType)

MaxRange = float | Mapping[Any, float] | tuple[float, ...]


def _range(name: str, value: Any) -> float:
    return real(name, value, 0.0, LARGEST_COORDINATE, low_open=True)


def _type_key(key: Any) -> LandmarkType:
    """A mapping key as a `LandmarkType` (as `sensing.observations.landmark_type` parses it)."""
    if isinstance(key, (bool, np.bool_)) or not isinstance(key, (int, np.integer, str)):
        raise ArgumentTypeError(
            f"max_range key {_show(key)} must be a landmark type (a LandmarkType, its value or "
            f"its name) or {OTHERS!r}, not {type(key).__name__}"
        )
    try:
        return LandmarkType.parse(int(key) if isinstance(key, np.integer) else key)
    except ValueError as error:
        raise ValueError(f"max_range key {key!r}: {error}") from None


def parse_max_range(value: Any) -> float | tuple[float, ...]:
    """`CameraView.max_range` validated: a float (one range for every type), or a tuple of `N_TYPES` ranges, one
    per landmark type in the order of the types' values, from a mapping {landmark type: range} (the key "others"
    for the types it does not name; without it, the largest range given) or from such a tuple.

    Each range must be a number within (0, 1000] m; ValueError naming the key and value otherwise, and for an
    empty mapping, an unknown landmark type or one named twice (TypeError, `field.checks.ArgumentTypeError`,
    for a value or key of the wrong type).
    """
    if isinstance(value, Mapping):
        if not value:
            raise ValueError("max_range = {} must give the range of at least one landmark type")
        ranges: dict[LandmarkType, float] = {}
        keys: dict[LandmarkType, Any] = {}
        others = None
        for key, metres in value.items():
            if isinstance(key, str) and key.strip().lower() == OTHERS:
                others = _range(f"max_range[{key!r}]", metres)
                continue
            kind = _type_key(key)
            if kind in ranges:
                raise ValueError(f"max_range names {kind.name.lower()} twice: keys {keys[kind]!r} and {key!r}")
            ranges[kind] = _range(f"max_range[{key!r}]", metres)
            keys[kind] = key
        default = others if others is not None else max(ranges.values())
        return tuple(ranges.get(kind, default) for kind in sorted(LandmarkType, key=lambda t: t.value))
    if isinstance(value, tuple):
        if len(value) != N_TYPES:
            raise ValueError(
                f"max_range = {_show(value)} must hold {N_TYPES} ranges, one per landmark type "
                f"(or be a number, or a mapping {{landmark type: range}})"
            )
        return tuple(_range(f"max_range[{LandmarkType(k).name.lower()}]", metres) for k, metres in enumerate(value))
    if isinstance(value, (list, set, frozenset, str, bytes, np.ndarray)) or value is None:
        raise ArgumentTypeError(
            f"max_range = {_show(value)} must be a number [m] or a mapping {{landmark type: "
            f"range}}, not {type(value).__name__}"
        )
    return _range("max_range", value)


@keeps_arrays_frozen
@dataclass(frozen=True)
class CameraView:
    """The camera's view for one frame, in the robot frame.

    yaw:       rad, the bearing of the optical axis (the head's pan), within ±100 rad; kept wrapped to (-π, π]
    half_fov:  rad, half the horizontal field of view, within (0, π]
    max_range: m, the farthest landmark the vision reports, within (0, 1000]: one number for every landmark type,
               or a mapping {landmark type: range} (keys: a `LandmarkType`, its value, name or alias; "others" for
               the types not named, which otherwise get the largest range given), kept as a tuple of one range
               per type, indexed by the type's value (a tuple of that form is taken too)
    min_range: m, the nearest (closer ones are below the image), within [0, the smallest max_range)

    A bad value raises ValueError naming it (TypeError for a wrong type, `field.checks.ArgumentTypeError`).
    """

    yaw: float
    half_fov: float
    max_range: MaxRange
    min_range: float = 0.0

    def __post_init__(self) -> None:
        yaw = real("yaw", self.yaw, -LARGEST_ANGLE, LARGEST_ANGLE)
        object.__setattr__(self, "yaw", math.remainder(yaw, 2.0 * math.pi))
        object.__setattr__(self, "half_fov", real("half_fov", self.half_fov, 0.0, math.pi, low_open=True))
        max_range = parse_max_range(self.max_range)
        object.__setattr__(self, "max_range", max_range)
        nearest_max = min(max_range) if isinstance(max_range, tuple) else max_range
        object.__setattr__(self, "min_range", real("min_range", self.min_range, 0.0, nearest_max, high_open=True))
        ranges = np.array(max_range if isinstance(max_range, tuple) else N_TYPES * (max_range,), dtype=np.float64)
        ranges.flags.writeable = False
        object.__setattr__(self, "_max_ranges", ranges)

    @property
    def max_ranges(self) -> np.ndarray:
        """The farthest range [m] of each landmark type, indexed by the type's value (read-only (`N_TYPES`,)
        float64): `max_range` itself for every type when it is one number."""
        return self._max_ranges  # type: ignore[attr-defined]

    @property
    def per_type(self) -> bool:
        """Whether `max_range` is given per landmark type (a tuple) rather than one number."""
        return isinstance(self.max_range, tuple)

    def range_of(self, kind: LandmarkType | int | str) -> float:
        """The farthest range [m] at which the vision reports a landmark of type `kind` (a `LandmarkType`, its
        value, name or alias; ValueError naming it otherwise).

        Parameters
        ----------
        kind : LandmarkType, int or str
            The landmark type.

        Returns
        -------
        float
            Its range [m].
        """
        if isinstance(self.max_range, tuple):
            return self.max_range[LandmarkType.parse(kind).value]
        LandmarkType.parse(kind)
        return cast(float, self.max_range)

    def inset(self, share: float) -> CameraView:
        """The view shrunk to `share` (0, 1] of its half field of view and of its range span (the nearest range
        moved out and the farthest in by the same share): the part of the view where a landmark is expected
        even with a small error in the pose or in the view.

        With a range per landmark type, each type's farthest range moves in by its own share of its span, and the
        nearest range (one for every type) moves out by the share of the shortest span, so it stays below every
        type's farthest.
        """
        share = real("share", share, 0.0, 1.0, low_open=True)
        if isinstance(self.max_range, tuple):
            keep = 0.5 * (1.0 - share)
            farthest = tuple(r - keep * (r - self.min_range) for r in self.max_range)
            nearest = self.min_range + keep * (min(self.max_range) - self.min_range)
            return CameraView(self.yaw, share * self.half_fov, farthest, nearest)
        max_range = cast(float, self.max_range)
        margin = 0.5 * (1.0 - share) * (max_range - self.min_range)
        return CameraView(self.yaw, share * self.half_fov, max_range - margin, self.min_range + margin)
