"""Soccer field geometry for localization: dimensions, landmarks, lines, presets, files.

Recommended import::

    from field import Field, LandmarkType, preset, load_field

Example::

    field = preset("spl")                                 # or spl(), kidsize(), adultsize()
    posts = field.landmarks_of(LandmarkType.GOALPOST)     # (4, 2) [x, y], metres
    marks = field.landmarks_of("penalty_mark")            # [[-3.2, 0.0], [3.2, 0.0]]
    tees = field.landmarks_of("T")                        # an alias: LANDMARK_TYPE_ALIASES
    points = field.line_points(spacing=0.05)              # for drawing or a likelihood field
    lab = load_field("my_lab.toml")                       # preset = "spl" plus overrides

Frame: origin at the centre mark, +x toward the opponent goal, +y to the left, θ
counter-clockwise in (-π, π]; SI units. Geometry lies on line centre lines.

- `FieldDimensions`: the rule-book numbers, validated on construction.
- `Field`: immutable; derives ``landmarks`` (one (K, 2) array per `LandmarkType`, sorted
  by x then y), ``segments`` (M, 2, 2), ``center_circle`` (cx, cy, r), ``line_points``,
  ``contains`` and ``mirror_poses``. Its arrays are float64, C-contiguous, read-only.
- `preset`, `spl`, `kidsize`, `adultsize`: the built-in fields, read from the TOML files
  in ``field/presets/``.
- `load_field`, `save_field`: field files in TOML or JSON, for example::

      name = "my-lab"
      preset = "spl"          # optional: start from a preset...
      [dimensions]
      length = 7.5            # ...and override some keys (all keys without a preset)
      width = 5.0

Heading wrapping (scalar for numba kernels, array form for numpy) lives in
``field.angles``: ``from field.angles import wrap_angle, wrap_angles``.

Invalid input raises `ValueError` naming the key and value (and the file, if any).
"""

from .dimensions import FieldDimensions
from .geometry import LANDMARK_TYPE_ALIASES, Field, LandmarkType
from .io import PRESET_NAMES, adultsize, kidsize, load_field, preset, save_field, spl, to_toml

__all__ = [
    "LANDMARK_TYPE_ALIASES",
    "PRESET_NAMES",
    "Field",
    "FieldDimensions",
    "LandmarkType",
    "adultsize",
    "kidsize",
    "load_field",
    "preset",
    "save_field",
    "spl",
    "to_toml",
]
