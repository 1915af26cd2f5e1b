"""Reading and writing field files, and the built-in presets.

    from field import load_field, preset, save_field

    field = preset("spl")                  # or spl(), kidsize(), adultsize()
    lab = load_field("my_lab.toml")        # .toml or .json
    save_field(lab, "copy.json")

A field file is a table with these top-level keys:

- ``name``: the field's name (string). Defaults to the preset's name when ``preset``
  is given, else to the file name without its extension.
- ``preset``: optional, one of `PRESET_NAMES`; its dimensions are the starting point.
- ``dimensions``: a table of `FieldDimensions` keys, in metres. Without ``preset`` every
  key is required; with ``preset`` it is optional and overrides only the keys it has.

Every problem with a file raises a `ValueError` whose message names the file, and the
key and value at fault.
"""

from __future__ import annotations

import difflib
import functools
import json
import os
import tomllib
from importlib import resources
from pathlib import Path

from .dimensions import FieldDimensions
from .geometry import Field

PRESET_NAMES: tuple[str, ...] = ("spl", "kidsize", "adultsize")
"""Names accepted by `preset` (and by a file's ``preset`` key), lower case."""

_TOP_LEVEL_KEYS = ("name", "preset", "dimensions")
_EXTENSIONS = (".toml", ".json")


def preset(name: str) -> Field:
    """The built-in field called `name` (any case): "spl", "kidsize" or "adultsize"."""
    if not isinstance(name, str) or name.strip().lower() not in PRESET_NAMES:
        raise ValueError(f"preset = {name!r} is unknown; valid names: {', '.join(PRESET_NAMES)}")
    return _load_preset(name.strip().lower())


def spl() -> Field:
    """RoboCup Standard Platform League field (rules 2020 onward), 9 m x 6 m."""
    return preset("spl")


def kidsize() -> Field:
    """RoboCup Humanoid League KidSize field, 9 m x 6 m."""
    return preset("kidsize")


def adultsize() -> Field:
    """RoboCup Humanoid League AdultSize field, 14 m x 9 m."""
    return preset("adultsize")


@functools.cache
def _load_preset(name: str) -> Field:
    # Fields are immutable, so every caller can share one instance per preset.
    with resources.as_file(resources.files(__package__) / "presets" / f"{name}.toml") as path:
        return load_field(path)


def load_field(path: str | os.PathLike) -> Field:
    """The field described by a ``.toml`` or ``.json`` file (format in the module docstring)."""
    path = Path(path)
    suffix = _checked_suffix(path)
    if not path.is_file():
        raise ValueError(f"{path}: field file does not exist")
    document = _parse(path, suffix)
    try:
        return _field_from_document(document, default_name=path.stem)
    except ValueError as error:
        raise ValueError(f"{path}: {error}") from None


def save_field(field: Field, path: str | os.PathLike) -> None:
    """Write `field` to a ``.toml`` or ``.json`` file that `load_field` reads back equal."""
    path = Path(path)
    suffix = _checked_suffix(path)
    if suffix == ".json":
        text = json.dumps(field.to_dict(), indent=2, ensure_ascii=False) + "\n"
    else:
        text = to_toml(field)
    path.write_text(text, encoding="utf-8")


def to_toml(field: Field) -> str:
    """The TOML text of a field file for `field`."""
    lines = [f"name = {_toml_string(field.name)}", "", "[dimensions]"]
    lines += [f"{key} = {value!r}" for key, value in field.dims.to_dict().items()]
    return "\n".join(lines) + "\n"


def _checked_suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in _EXTENSIONS:
        valid = ", ".join(_EXTENSIONS)
        raise ValueError(f"{path}: extension {path.suffix!r} is not supported; use one of {valid}")
    return suffix


def _toml_string(text: str) -> str:
    """`text` as a TOML basic string; TOML requires control characters to be escaped."""
    escaped = []
    for char in text:
        if char in '"\\':
            escaped.append("\\" + char)
        elif (ord(char) < 0x20 and char != "\t") or ord(char) == 0x7F:
            escaped.append(f"\\u{ord(char):04x}")
        else:
            escaped.append(char)
    return '"' + "".join(escaped) + '"'


def _parse(path: Path, suffix: str) -> object:
    try:
        data = path.read_bytes()
    except OSError as error:
        raise ValueError(f"{path}: cannot read field file: {error}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: not UTF-8 text: {error}") from None
    if suffix == ".toml":
        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as error:
            raise ValueError(f"{path}: not valid TOML: {error}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"{path}: not valid JSON: {error}") from None


def _field_from_document(document: object, default_name: str) -> Field:
    if not isinstance(document, dict):
        raise ValueError(f"the top level must be a table of keys, not {type(document).__name__}")
    for key in document:
        if key not in _TOP_LEVEL_KEYS:
            hint = _suggestion(key, _TOP_LEVEL_KEYS)
            close = difflib.get_close_matches(key, FieldDimensions.keys(), n=1)
            if not hint and close:
                # Most likely a dimension written above the [dimensions] header.
                hint = f"; {close[0]!r} belongs in the [dimensions] table"
            raise ValueError(
                f"unknown key {key!r} = {document[key]!r} at the top level "
                f"(valid: {', '.join(_TOP_LEVEL_KEYS)}){hint}"
            )

    base: FieldDimensions | None = None
    preset_name = document.get("preset")
    if preset_name is not None:
        if not isinstance(preset_name, str):
            raise ValueError(f"preset = {preset_name!r} must be a string")
        base = preset(preset_name).dims

    name = document.get("name", preset_name.strip().lower() if base is not None else default_name)
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"name = {name!r} must be a non-empty string")

    overrides = document.get("dimensions", {})
    if not isinstance(overrides, dict):
        raise ValueError(f"dimensions = {overrides!r} must be a table of key = value pairs")
    return Field(name, _dimensions(overrides, base))


def _dimensions(overrides: dict, base: FieldDimensions | None) -> FieldDimensions:
    keys = FieldDimensions.keys()
    for key, value in overrides.items():
        if key not in keys:
            raise ValueError(
                f"unknown key {key!r} = {value!r} in [dimensions]{_suggestion(key, keys)}"
            )
    values = base.to_dict() if base is not None else {}
    values.update(overrides)
    missing = [key for key in keys if key not in values]
    if missing:
        raise ValueError(f"missing key(s) in [dimensions]: {', '.join(missing)}")
    # FieldDimensions checks every value (type, finiteness, geometry) itself.
    return FieldDimensions(**values)


def _suggestion(key: str, candidates: tuple[str, ...]) -> str:
    close = difflib.get_close_matches(key, candidates, n=1)
    return f"; did you mean {close[0]!r}?" if close else ""
