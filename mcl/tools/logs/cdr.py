"""ROS 2 CDR messages decoded by code made for their schema: mcap_ros2's messages, several times faster.

mcap-ros2-support decodes a message by walking its parsed definition field by field, and reads every number of
an array with a call of its own, which is slow for a nav_msgs/Odometry (two covariances of 36 numbers) and made
reading most of a log's replay time (`robocup-mcl bench replay` measures the replay). `DecoderFactory` here is a drop-in for `mcap_ros2.decoder.DecoderFactory`:
for each ros2msg schema it parses the definitions with mcap_ros2's own parser, then writes and compiles one
Python function per message type that reads the fields in order with `struct` at the offsets CDR's alignment
gives (a numeric array in one `unpack_from`). The messages it returns are instances of mcap_ros2's own message
classes with the same field values and types (lists, bytes for uint8/byte arrays, str), so the two compare
equal (`tests/test_mcap_io.py` checks it on every schema the reader accepts, for drawn messages).

What this does not decode it leaves to mcap_ros2, message by message: big-endian data, and definitions with a
wstring field (which mcap_ros2 cannot decode either). If mcap_ros2's internals it uses go away, the factory
returns mcap_ros2's decoders for everything.

Hostile data: every length read from the data is bounded by the bytes left before anything is made of it (a
string or byte array longer than the rest of the message raises ValueError; numeric arrays are checked by
`struct` before it allocates; a sequence of messages ends at the data's end), so a message of n bytes never
yields much more than n values. Definitions that contain themselves, directly or not, or nest deeper than
`MAX_NESTING` (which a decoder would follow until Python's recursion limit) raise ValueError when their
decoders are asked for, as ROS 2 does not define them.
"""

from __future__ import annotations

import keyword
import struct
from collections.abc import Callable
from typing import Any

from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory

try:  # the parser and the message classes mcap_ros2 decodes into
    from mcap_ros2._dynamic import TimeDefinition, _for_each_msgdef, _message_class
except ImportError:  # pragma: no cover - a mcap_ros2 without them: its own decoders throughout
    _for_each_msgdef = None  # type: ignore[assignment]  # no parser: compile_decoders checks for None

__all__ = ["DecoderFactory", "compile_decoders"]

# Primitive type -> (struct code, size); bool, byte/uint8 and strings are read by hand.
_NUMERIC = {
    "char": ("b", 1),
    "int8": ("b", 1),
    "int16": ("h", 2),
    "uint16": ("H", 2),
    "int32": ("i", 4),
    "uint32": ("I", 4),
    "int64": ("q", 8),
    "uint64": ("Q", 8),
    "float32": ("f", 4),
    "float64": ("d", 8),
}
_UINT32 = struct.Struct("<I").unpack_from
MAX_NESTING = 64  # the deepest nesting of message types accepted (ROS's own are under 10 deep)


class _Unsupported(Exception):
    """A definition this compiler leaves to mcap_ros2."""


def _align(lines: list[str], indent: str, size: int) -> None:
    """Pad the offset `o` to a multiple of `size` counted from the end of the 4-byte CDR header."""
    if size > 1:
        lines.append(f"{indent}o += (4 - o) % {size}")


def _length(lines: list[str], indent: str, fixed: int | None) -> None:
    """`n` = an array's length: fixed, or read as a uint32 before it."""
    if fixed is not None:
        lines.append(f"{indent}n = {fixed}")
    else:
        _align(lines, indent, 4)
        lines.append(f"{indent}n = U32(data, o)[0]; o += 4")


def _string(lines: list[str], indent: str, target: str) -> None:
    """A length-prefixed, NUL-terminated string into `target` (as mcap_ros2 reads it: length 0 or 1 is "")."""
    _align(lines, indent, 4)
    lines.append(f"{indent}k = U32(data, o)[0]; o += 4")
    lines.append(f"{indent}if o + k > len(data):")
    lines.append(f"{indent}    raise ValueError(f'a string of {{k}} bytes at byte {{o}} of {{len(data)}}')")
    lines.append(f"{indent}{target} = data[o:o + k - 1].decode('utf-8') if k > 1 else ''; o += k")


def _field_code(field, definitions: dict, functions: dict, lines: list[str], indent: str) -> None:
    """Code that reads one field into `value`."""
    ftype = field.type
    fixed = ftype.array_size if ftype.is_array and ftype.is_fixed_size_array() else None
    name = ftype.type
    if not ftype.is_primitive_type():
        nested = definitions.get(f"{ftype.pkg_name}/{name}")
        if nested is None:
            raise _Unsupported(f"no definition for {ftype.pkg_name}/{name}")
        function = functions[f"{ftype.pkg_name}/{name}"]
        if not ftype.is_array:
            lines.append(f"{indent}value, o = {function}(data, o)")
            return
        _length(lines, indent, fixed)
        lines.append(f"{indent}value = []")
        lines.append(f"{indent}for _ in range(n):")
        lines.append(f"{indent}    item, o = {function}(data, o)")
        lines.append(f"{indent}    value.append(item)")
        return
    if name == "wstring":
        raise _Unsupported("wstring")
    if not ftype.is_array:
        if name == "string":
            _string(lines, indent, "value")
        elif name == "bool":
            lines.append(f"{indent}value = U8(data, o)[0] != 0; o += 1")
        elif name in ("byte", "uint8"):
            lines.append(f"{indent}value = U8(data, o)[0]; o += 1")
        else:
            code, size = _NUMERIC[name]
            _align(lines, indent, size)
            lines.append(f"{indent}value = unpack_from('<{code}', data, o)[0]; o += {size}")
        return
    _length(lines, indent, fixed)
    if name == "string":
        lines.append(f"{indent}value = []")
        lines.append(f"{indent}for _ in range(n):")
        _string(lines, indent + "    ", "item")
        lines.append(f"{indent}    value.append(item)")
    elif name in ("byte", "uint8"):
        lines.append(f"{indent}if o + n > len(data):")
        lines.append(f"{indent}    raise ValueError(f'an array of {{n}} bytes at byte {{o}} of {{len(data)}}')")
        lines.append(f"{indent}value = data[o:o + n]; o += n")
    elif name == "bool":
        lines.append(f"{indent}value = [b != 0 for b in unpack_from(f'<{{n}}B', data, o)]; o += n")
    else:
        code, size = _NUMERIC[name]
        # mcap_ros2 aligns before each element it reads, so an empty array is not padded
        lines.append(f"{indent}if n:")
        _align(lines, indent + "    ", size)
        lines.append(f"{indent}    value = list(unpack_from(f'<{{n}}{code}', data, o)); o += n * {size}")
        lines.append(f"{indent}else:")
        lines.append(f"{indent}    value = []")


def _check_nesting(schema_name: str, definitions: dict) -> None:
    """ValueError when a type of `definitions` contains itself or nests deeper than MAX_NESTING."""

    def nested(definition) -> set[str]:
        return {
            f"{field.type.pkg_name}/{field.type.type}"
            for field in definition.fields
            if not field.type.is_primitive_type()
        } & definitions.keys()

    depth: dict[str, int] = {}  # type -> how many types deep its fields nest (itself counted)

    def visit(key: str, path: list[str]) -> int:
        if key in depth:
            return depth[key]
        if key in path:
            raise ValueError(
                f"{schema_name}: the message type {key} contains itself "
                f"({' -> '.join(path[path.index(key) :] + [key])})"
            )
        if len(path) < MAX_NESTING:
            depth[key] = 1 + max((visit(inner, path + [key]) for inner in nested(definitions[key])), default=0)
        if depth.get(key, MAX_NESTING + 1) > MAX_NESTING:
            raise ValueError(
                f"{schema_name}: message types nest more than MAX_NESTING = {MAX_NESTING} deep (from {key})"
            )
        return depth[key]

    for key in definitions:
        visit(key, [])


def _function_code(key: str, definition, definitions: dict, functions: dict) -> list[str]:
    lines = [f"def {functions[key]}(data, o):", f"    m = {functions[key]}_class()"]
    if not definition.fields:
        # ROS 2 gives an empty message one uint8 member (structure_needs_at_least_one_member)
        lines.append("    U8(data, o); o += 1")
    for field in definition.fields:
        _field_code(field, definitions, functions, lines, "    ")
        if field.name.isidentifier() and not keyword.iskeyword(field.name):
            lines.append(f"    m.{field.name} = value")
        else:
            lines.append(f"    setattr(m, {field.name!r}, value)")
    lines.append("    return m, o")
    return lines


def _compile_readers(schema_name: str, schema_text: str) -> dict[str, Callable[[bytes, int], tuple[Any, int]]]:
    """read(data, offset) -> (message, offset after it) for every message type `schema_text` defines, by full
    and short name (one function per type); empty when the definitions use what this compiler leaves to
    mcap_ros2 (or when mcap_ros2's parser is not there)."""
    if _for_each_msgdef is None:
        return {}
    # by short name ("pkg/Type"), as fields name their types; the schema's own Time replaces this one
    definitions = {"builtin_interfaces/Time": TimeDefinition, "builtin_interfaces/Duration": TimeDefinition}
    names: list[tuple[str, str]] = []

    def collect(full_name, short_name, definition):
        definitions[short_name] = definition
        names.append((full_name, short_name))

    _for_each_msgdef(schema_name, schema_text, collect)
    _check_nesting(schema_name, definitions)
    functions = {key: f"_read_{i}" for i, key in enumerate(definitions)}
    classes: dict[str, type] = {}
    namespace: dict[str, Any] = {
        "unpack_from": struct.unpack_from,
        "U32": _UINT32,
        "U8": struct.Struct("<B").unpack_from,
    }
    source: list[str] = []
    try:
        for key, definition in definitions.items():
            namespace[f"{functions[key]}_class"] = _message_class(definition, classes)
            source += _function_code(key, definition, definitions, functions)
    except _Unsupported:
        return {}
    exec(compile("\n".join(source), f"<cdr decoders for {schema_name}>", "exec"), namespace)
    readers = {}
    for full_name, short_name in names:
        readers[full_name] = readers[short_name] = namespace[functions[short_name]]
    return readers


def compile_decoders(schema_name: str, schema_text: str) -> dict[str, Callable[[bytes], Any]]:
    """Decoders of little-endian CDR data for every message type `schema_text` defines, by full and short
    name, as `mcap_ros2._dynamic.generate_dynamic` names them (big-endian data raises ValueError: it is
    mcap_ros2's to read); empty when the definitions use what this compiler leaves to mcap_ros2 (or when
    mcap_ros2's parser is not there). Raises what mcap_ros2's parser raises for a definition that does not
    parse, and ValueError for one that contains itself or nests too deep (see the module docstring)."""
    decoders: dict[str, Callable[[bytes], Any]] = {}
    for name, read in _compile_readers(schema_name, schema_text).items():

        def decode(data, read=read):
            if len(data) < 4:
                raise ValueError(f"Invalid CDR data size {len(data)}, must contain at least a 4-byte header")
            if not data[1] & 1:  # CDR's second header byte: bit 0 set for little-endian
                raise ValueError("big-endian CDR data: decode it with mcap_ros2")
            return read(data, 4)[0]

        decoders[name] = decode
    return decoders


class DecoderFactory(Ros2DecoderFactory):
    """`mcap_ros2.decoder.DecoderFactory` with the compiled decoders where they apply (see the module
    docstring): the same messages, the same errors for a schema that does not parse."""

    def __init__(self) -> None:
        super().__init__()
        self._compiled: dict[int, Callable[[bytes], Any]] = {}

    def decoder_for(self, message_encoding: str, schema: Schema | None):
        general = super().decoder_for(message_encoding, schema)
        if general is None or schema is None:
            return general
        decoder = self._compiled.get(schema.id)
        if decoder is None:
            read = _compile_readers(schema.name, schema.data.decode()).get(schema.name)
            if read is None:
                decoder = general
            else:

                def decoder(data, read=read, general=general):
                    # shorter than the CDR header (mcap_ros2 raises) or big-endian (bit 0 of its second
                    # byte clear): mcap_ros2's; else the compiled reader
                    if len(data) < 4 or not data[1] & 1:
                        return general(data)
                    return read(data, 4)[0]

            self._compiled[schema.id] = decoder
        return decoder
