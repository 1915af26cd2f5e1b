"""Profiles: a localizer's settings in one TOML file, as `robocup-mcl tune` writes them and a team keeps them
per venue, carpet or robot.

    from field import spl
    from mcl.localizer import Localizer
    from mcl.profile import Profile

    profile = Profile.load("venue.toml")
    loc = Localizer.from_profile(spl(), profile, seed=0)      # the same as profile.localizer(spl(), seed=0)
    profile.with_values({"sensor.outlier_weight": 0.02}).save("venue-2.toml")

or from the shell: `robocup-mcl replay game.mcap --profile venue.toml`, `robocup-mcl eval --profile venue.toml`.

A profile names only what differs from the library's defaults; everything it leaves out keeps its default.
Its sections and settings (`SECTIONS`):

| section | what it sets | settings |
|---|---|---|
| `[localizer]` | `mcl.localizer.Localizer` | `particles`, `history`, `compensate_latency` |
| `[odometry]` | `Localizer`'s `odometry_scale` | `scale_x`, `scale_y`, `scale_theta` |
| `[motion]` | the motion model | `model` ("velocity-linear" or "constant") and that model's numbers |
| `[sensor]` | `sensing.LandmarkSensorModel` | its noise, outlier floor, mixture and negative information |
| `[augmented]` | `mcl.augmented.AugmentedMCL` (injection) | its averaging rates, thresholds and caps |
| `[relocalization]` | `mcl.relocalization.RelocalizationPrior` | its scalar settings |
| `[quality]` | `mcl.localizer.QualityThresholds` | every threshold |
| `[rivals]` | `mcl.rivals.RivalSettings` (the quality's `rivals`) | its scalar settings (`young = 0`: no check) |

For example:

    # venue profile, tuned on 12 logs
    [sensor]
    range_noise_floor = 0.071
    outlier_weight = 0.0213

    [odometry]
    scale_x = 1.18

A profile is checked when it is made: an unknown section or setting, a value of the wrong type, or a value its
class refuses (a negative noise, say) raises `ProfileError` (a ValueError) with one line naming the file, the
section and the setting. Floats are written with `repr`, so a profile saved and loaded again is the same, bit
for bit.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from field import Field, spl
from motion_models import ConstantNoise, VelocityLinear
from sensing import LandmarkSensorModel

from .augmented import AugmentedMCL
from .filter import MAX_PARTICLES
from .localizer import MAX_ODOMETRY_SCALE, Localizer, QualityThresholds
from .relocalization import RelocalizationPrior, SoccerRelocalization
from .rivals import RivalSettings

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, as the tomli package
    import tomli as tomllib

if TYPE_CHECKING:
    from collections.abc import Iterable

MOTION_MODELS = {"velocity-linear": VelocityLinear, "constant": ConstantNoise}
DEFAULT_MOTION = "velocity-linear"
# The localizer's own settings: name -> (type, the Localizer keyword)
LOCALIZER_SETTINGS = {
    "particles": (int, "n_particles"),
    "history": (float, "history"),
    "compensate_latency": (bool, "compensate_latency"),
}
ODOMETRY_SETTINGS = ("scale_x", "scale_y", "scale_theta")
_CLASSES = {
    "sensor": LandmarkSensorModel,
    "augmented": AugmentedMCL,
    "relocalization": RelocalizationPrior,
    "quality": QualityThresholds,
    "rivals": RivalSettings,
}
_TYPES = {"float": float, "int": int, "bool": bool, "str": str}


class ProfileError(ValueError):
    """A profile that cannot be used: one line naming the file (when there is one), section and setting."""


def _scalar_fields(cls: type) -> dict[str, type]:
    """The dataclass `cls`'s init fields of a scalar type (float, int, bool, str), by name."""
    out = {}
    for f in dataclasses.fields(cls):
        kind = _TYPES.get(f.type if isinstance(f.type, str) else getattr(f.type, "__name__", ""))
        if f.init and kind is not None and f.name != "field":
            out[f.name] = kind
    return out


def _settings() -> dict[str, dict[str, type]]:
    sections: dict[str, dict[str, type]] = {
        "localizer": {name: kind for name, (kind, _) in LOCALIZER_SETTINGS.items()},
        "odometry": {name: float for name in ODOMETRY_SETTINGS},
        "motion": {"model": str},
    }
    for model in MOTION_MODELS.values():
        sections["motion"].update(_scalar_fields(model))
    for name, cls in _CLASSES.items():
        sections[name] = _scalar_fields(cls)
    return sections


SECTIONS: dict[str, dict[str, type]] = _settings()
"""Every section of a profile and its settings with their types (floats also take integers)."""


def _check_value(where: str, value: Any, kind: type) -> Any:
    if kind is bool:
        if not isinstance(value, bool):
            raise ProfileError(f"{where} = {value!r} must be true or false")
        return value
    if kind is str:
        if not isinstance(value, str):
            raise ProfileError(f"{where} = {value!r} must be a string")
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ProfileError(f"{where} = {value!r} must be a number")
    if kind is int:
        if isinstance(value, float):
            if not value.is_integer():
                raise ProfileError(f"{where} = {value!r} must be an integer")
            value = int(value)
        return int(value)
    value = float(value)
    if not math.isfinite(value):
        raise ProfileError(f"{where} = {value!r} must be finite")
    return value


def read_text(path: str | os.PathLike) -> tuple[str, str]:
    """(the UTF-8 text of the file `path`, its name): what `load` methods parse (OSError if unreadable)."""
    with open(path, encoding="utf-8") as handle:
        return handle.read(), os.fspath(path)


def parse_toml(text: str, source: str, error: type[ValueError]) -> dict:
    """The TOML `text` as a dict; `error` (one line naming `source`) if it is not TOML."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as reason:
        raise error(f"{source + ': ' if source else ''}not TOML: {reason}") from None


@dataclass(frozen=True)
class Profile:
    """A localizer's settings by section (see the module docstring); checked when made.

    Parameters
    ----------
    sections : mapping of str to mapping of str to value, default {}
        {section: {setting: value}}; what is left out keeps the library's default.
    source : str, default ""
        Where it came from (a file name), for error messages.

    Raises
    ------
    ProfileError
        For an unknown section or setting, a value of the wrong type, or one the library refuses.
    """

    sections: Mapping[str, Mapping[str, Any]] = dataclasses.field(default_factory=dict)
    source: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.sections, Mapping):
            raise ProfileError(self._where(f"a profile is a table of sections, not {type(self.sections).__name__}"))
        clean: dict[str, dict[str, Any]] = {}
        for section, values in self.sections.items():
            if section not in SECTIONS:
                raise ProfileError(self._where(f"unknown section [{section}]; known: {', '.join(SECTIONS)}"))
            if not isinstance(values, Mapping):
                raise ProfileError(self._where(f"[{section}] must be a table of settings"))
            known = SECTIONS[section]
            clean[section] = {}
            for name, value in values.items():
                if name not in known:
                    raise ProfileError(self._where(f"[{section}] unknown setting {name!r}; known: {', '.join(known)}"))
                clean[section][name] = _check_value(self._where(f"[{section}] {name}"), value, known[name])
        object.__setattr__(self, "sections", {k: v for k, v in clean.items() if v})
        model = self.sections.get("motion", {}).get("model", DEFAULT_MOTION)
        if model not in MOTION_MODELS:
            raise ProfileError(self._where(f"[motion] model = {model!r} must be one of {', '.join(MOTION_MODELS)}"))
        own = _scalar_fields(MOTION_MODELS[model])
        for name in self.sections.get("motion", {}):
            if name != "model" and name not in own:
                raise ProfileError(
                    self._where(f"[motion] {name!r} is not a setting of the {model!r} model; it has {', '.join(own)}")
                )
        localizer = self.sections.get("localizer", {})
        if not 1 <= localizer.get("particles", 1) <= MAX_PARTICLES:
            raise ProfileError(
                self._where(f"[localizer] particles = {localizer['particles']!r} must lie in [1, {MAX_PARTICLES}]")
            )
        if not localizer.get("history", 1.0) > 0:
            raise ProfileError(self._where(f"[localizer] history = {localizer['history']!r} must be > 0 s"))
        for name, value in self.sections.get("odometry", {}).items():
            if not 0 < value <= MAX_ODOMETRY_SCALE:
                raise ProfileError(
                    self._where(
                        f"[odometry] {name} = {value!r} must lie in (0, {MAX_ODOMETRY_SCALE:g}] (odometry_scale)"
                    )
                )
        try:
            self.localizer_options(spl())  # every class checks its own numbers
        except ProfileError:
            raise
        except (TypeError, ValueError) as error:
            raise ProfileError(self._where(str(error))) from None

    def _where(self, message: str) -> str:
        return f"{self.source}: {message}" if self.source else message

    # -- reading and writing -------------------------------------------------------------------------------
    @classmethod
    def from_toml(cls, text: str, source: str = "") -> Profile:
        """The profile in TOML `text` (`source`: a name for error messages)."""
        return cls(parse_toml(text, source, ProfileError), source)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Profile:
        """The profile in the TOML file `path` (OSError if it cannot be read, ProfileError if it is wrong)."""
        return cls.from_toml(*read_text(path))

    @classmethod
    def from_values(cls, values: Mapping[str, Any], source: str = "") -> Profile:
        """A profile from {"section.setting": value} (the names of a tuning space)."""
        return cls({}, source).with_values(values)

    def values(self) -> dict[str, Any]:
        """{"section.setting": value} for every setting the profile names."""
        return {
            f"{section}.{name}": value
            for section, settings in self.sections.items()
            for name, value in settings.items()
        }

    def with_values(self, values: Mapping[str, Any]) -> Profile:
        """A new profile: this one with the settings in {"section.setting": value} set (checked)."""
        sections = {section: dict(settings) for section, settings in self.sections.items()}
        for key, value in values.items():
            section, dot, name = str(key).partition(".")
            if not dot or not name:
                raise ProfileError(self._where(f"{key!r} must name a setting as SECTION.SETTING"))
            sections.setdefault(section, {})[name] = value
        return Profile(sections, self.source)

    def to_toml(self, header: Iterable[str] = ()) -> str:
        """The profile as TOML, `header` lines first as comments; floats by `repr` (exact round trip)."""
        lines = [f"# {line}".rstrip() for line in header]
        for section, settings in self.sections.items():
            if lines:
                lines.append("")
            lines.append(f"[{section}]")
            for name, value in settings.items():
                if isinstance(value, bool):
                    text = "true" if value else "false"
                elif isinstance(value, str):
                    text = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
                else:
                    text = repr(value)
                lines.append(f"{name} = {text}")
        return "\n".join(lines) + "\n"

    def save(self, path: str | os.PathLike, header: Iterable[str] = ()) -> None:
        """Write `to_toml(header)` to `path`."""
        with open(path, "w", encoding="utf-8") as handle:
            handle.write(self.to_toml(header))

    # -- use ---------------------------------------------------------------------------------------------
    def localizer_options(self, field: Field) -> dict[str, Any]:
        """The keyword arguments of `Localizer(field, **options)` this profile asks for (only what it sets)."""
        s = self.sections
        options: dict[str, Any] = {}
        for name, value in s.get("localizer", {}).items():
            options[LOCALIZER_SETTINGS[name][1]] = value
        if "odometry" in s:
            options["odometry_scale"] = tuple(s["odometry"].get(name, 1.0) for name in ODOMETRY_SETTINGS)
        if "motion" in s:
            motion = dict(s["motion"])
            options["motion_model"] = MOTION_MODELS[motion.pop("model", DEFAULT_MOTION)](**motion)
        if "sensor" in s:
            options["sensor_model"] = LandmarkSensorModel(field, **s["sensor"])
        if "augmented" in s:
            options["augmented"] = AugmentedMCL(**s["augmented"])
        if "relocalization" in s:
            options["relocalization"] = SoccerRelocalization(RelocalizationPrior(**s["relocalization"]))
        if "quality" in s or "rivals" in s:
            quality = QualityThresholds(**s.get("quality", {}))
            if "rivals" in s:
                quality = dataclasses.replace(quality, rivals=RivalSettings(**s["rivals"]))
            options["quality"] = quality
        return options

    def localizer(self, field: Field, **overrides: Any) -> Localizer:
        """`Localizer(field, **options)` with this profile's options, then `overrides` (seed=, n_particles=,
        any `Localizer` keyword) on top."""
        options = self.localizer_options(field)
        options.update(overrides)
        return Localizer(field, **options)


def default_values(particles: int = 500) -> dict[str, Any]:
    """Every setting's library default, {"section.setting": value} (the motion model's: velocity-linear's and
    constant's; `localizer.particles`: `particles`, the caller's count)."""
    import inspect

    out: dict[str, Any] = {"localizer.particles": particles, "motion.model": DEFAULT_MOTION}
    signature = inspect.signature(Localizer.__init__).parameters
    for name, (_, keyword) in LOCALIZER_SETTINGS.items():
        if name != "particles":
            out[f"localizer.{name}"] = signature[keyword].default
    out.update({f"odometry.{name}": 1.0 for name in ODOMETRY_SETTINGS})
    classes = [("motion", model) for model in reversed(list(MOTION_MODELS.values()))] + list(_CLASSES.items())
    for section, cls in classes:
        for f in dataclasses.fields(cls):
            if f.name in SECTIONS[section] and f.default is not dataclasses.MISSING:
                out[f"{section}.{f.name}"] = f.default
    return out
