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

Any other key is an error. Bounds: a file holds at most `MAX_FIELD_FILE_BYTES` (1 MiB) of
UTF-8 text; the name has at most `field.geometry.MAX_NAME_LENGTH` (1000) characters; every
dimension is a finite number greater than 0 (not a boolean), and the carpet, field plus
border strip, measures at most `field.dimensions.MAX_FIELD_EXTENT` (200 m) along either
axis, besides the geometric rules `FieldDimensions` lists.

Every problem with a file raises a `ValueError` whose message names the file, and the
key and value at fault; this includes text nested too deeply for the parser (a
``RecursionError`` is reported as such a `ValueError`). A path that is not a string or
``os.PathLike`` raises `TypeError`.
"""

from __future__ import annotations

import difflib
import functools
import json
import os
import sys
from importlib import resources
from pathlib import Path

from .dimensions import FieldDimensions, short_repr
from .geometry import Field

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, as the tomli package
    import tomli as tomllib

PRESET_NAMES: tuple[str, ...] = ("spl", "kidsize", "adultsize")
"""Names accepted by `preset` (and by a file's ``preset`` key), lower case."""

MAX_FIELD_FILE_BYTES = 1 << 20
"""Largest field file `load_field` reads, in bytes (1 MiB). A field file is a few hundred
bytes; the bound is checked before the file is read, so a huge or endless file (a device,
say) is refused rather than read into memory."""

_TOP_LEVEL_KEYS = ("name", "preset", "dimensions")
_EXTENSIONS = (".toml", ".json")


def preset(name: str) -> Field:
    """The built-in field called `name` (any case): "spl", "kidsize" or "adultsize".

    Parameters
    ----------
    name : str
        A name of `PRESET_NAMES`, in any case, surrounding white space ignored.

    Returns
    -------
    Field
        The preset field (loaded once, then shared).

    Raises
    ------
    ValueError
        If `name` is not a preset's name.
    """
    if not isinstance(name, str) or name.strip().lower() not in PRESET_NAMES:
        raise ValueError(f"preset = {short_repr(name)} is unknown; valid names: {', '.join(PRESET_NAMES)}")
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
    """The field described by a ``.toml`` or ``.json`` file (format in the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The field file; its extension (``.toml`` or ``.json``, any case) selects the format.

    Returns
    -------
    Field
        The field the file describes.

    Raises
    ------
    ValueError
        If the file is missing, unreadable, too large, malformed, or describes an impossible field
        (the message starts with the path).
    TypeError
        If `path` is not a str or os.PathLike.
    """
    path = _checked_path(path)
    suffix = _checked_suffix(path)
    try:
        exists = path.is_file()
    except (OSError, ValueError) as error:  # a name too long for the file system, say
        raise ValueError(f"{path}: cannot access field file: {error}") from None
    if not exists:
        raise ValueError(f"{path}: field file does not exist")
    document = _parse(path, suffix)
    try:
        return _field_from_document(document, default_name=path.stem)
    except ValueError as error:
        raise ValueError(f"{path}: {error}") from None


def field_by_name_or_path(text: str | os.PathLike) -> Field:
    """The field a command-line option names: a preset name (any case, see `PRESET_NAMES`) or a field file
    (``.toml`` or ``.json``, see `load_field`). A name that is neither (no such preset, not a file name with a
    field file's extension) raises a one-line `ValueError` listing the presets, with the closest one, e.g.
    "unknown field 'spll' (did you mean 'spl'?); presets: spl, kidsize, adultsize, or a path to a .toml or
    .json field file"."""
    if isinstance(text, str) and text.strip().lower() in PRESET_NAMES:
        return preset(text)
    path = _checked_path(text)
    if path.suffix.lower() not in _EXTENSIONS and not path.is_file():
        close = difflib.get_close_matches(str(text).strip().lower(), PRESET_NAMES, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ValueError(
            f"unknown field {str(text)!r}{hint}; presets: {', '.join(PRESET_NAMES)}, "
            f"or a path to a {' or '.join(_EXTENSIONS)} field file"
        )
    return load_field(path)


def save_field(field: Field, path: str | os.PathLike) -> None:
    """Write `field` to a ``.toml`` or ``.json`` file that `load_field` reads back equal.

    Parameters
    ----------
    field : Field
        The field to write.
    path : str or os.PathLike
        The file; its extension (``.toml`` or ``.json``) selects the format. An existing file is replaced.

    Raises
    ------
    ValueError
        If the extension is neither.
    TypeError
        If `path` is not a str or os.PathLike.
    OSError
        If the file cannot be written.
    """
    path = _checked_path(path)
    suffix = _checked_suffix(path)
    if suffix == ".json":
        text = json.dumps(field.to_dict(), indent=2, ensure_ascii=False) + "\n"
    else:
        text = to_toml(field)
    path.write_text(text, encoding="utf-8")


def to_toml(field: Field) -> str:
    """The TOML text of a field file for `field`.

    Parameters
    ----------
    field : Field
        The field to describe.

    Returns
    -------
    str
        The file's text: its name and a ``[dimensions]`` table, newline-terminated.
    """
    lines = [f"name = {_toml_string(field.name)}", "", "[dimensions]"]
    lines += [f"{key} = {value!r}" for key, value in field.dims.to_dict().items()]
    return "\n".join(lines) + "\n"


def _checked_path(path: object) -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path = {short_repr(path)} must be a str or os.PathLike, not {type(path).__name__}")
    return Path(path)


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
        size = path.stat().st_size
        if size <= MAX_FIELD_FILE_BYTES:
            with path.open("rb") as file:
                # Read one byte past the bound: the file may have grown since stat.
                data = file.read(MAX_FIELD_FILE_BYTES + 1)
            size = len(data)
    except OSError as error:
        raise ValueError(f"{path}: cannot read field file: {error}") from None
    if size > MAX_FIELD_FILE_BYTES:
        raise ValueError(
            f"{path}: field file holds more than MAX_FIELD_FILE_BYTES = {MAX_FIELD_FILE_BYTES} "
            "bytes; a field file is a few hundred"
        )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"{path}: not UTF-8 text: {error}") from None
    kind = "TOML" if suffix == ".toml" else "JSON"
    try:
        if suffix == ".toml":
            return tomllib.loads(text)
        return json.loads(text)
    except RecursionError:
        raise ValueError(f"{path}: not valid {kind}: nested too deeply to parse") from None
    # JSONDecodeError and TOMLDecodeError are ValueErrors, and so is a number beyond
    # Python's integer digit limit.
    except ValueError as error:
        raise ValueError(f"{path}: not valid {kind}: {error}") from None


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
                f"unknown key {short_repr(key)} = {short_repr(document[key])} at the top level "
                f"(valid: {', '.join(_TOP_LEVEL_KEYS)}){hint}"
            )

    base: FieldDimensions | None = None
    preset_name = document.get("preset")
    if "preset" in document:
        if not isinstance(preset_name, str):
            raise ValueError(f"preset = {short_repr(preset_name)} must be a string")
        base = preset(preset_name).dims

    name = document.get("name", preset_name.strip().lower() if isinstance(preset_name, str) else default_name)
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"name = {short_repr(name)} must be a non-empty string")

    overrides = document.get("dimensions", {})
    if not isinstance(overrides, dict):
        raise ValueError(f"dimensions = {short_repr(overrides)} must be a table of key = value pairs")
    return Field(name, _dimensions(overrides, base))


def _dimensions(overrides: dict, base: FieldDimensions | None) -> FieldDimensions:
    keys = FieldDimensions.keys()
    for key, value in overrides.items():
        if key not in keys:
            raise ValueError(
                f"unknown key {short_repr(key)} = {short_repr(value)} in [dimensions]{_suggestion(key, keys)}"
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
