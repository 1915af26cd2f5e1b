"""mcl.tools.logs.cdr: the compiled CDR decoders give mcap_ros2's messages, field for field, on every schema the log
reader accepts and on a schema of every primitive and array kind; what they leave to mcap_ros2 goes there."""

import math
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st
from mcap.records import Schema
from mcap_ros2._dynamic import _for_each_msgdef, serialize_dynamic
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory

from mcl.tools.logs import schemas
from mcl.tools.logs.cdr import DecoderFactory, compile_decoders
from mcl.tools.logs.mcap_io import _DECODE_ERRORS

# Every primitive, as a scalar and as fixed, bounded and unbounded arrays; strings around the alignment;
# nested messages and arrays of them; an empty message.
EVERY_KIND = "\n".join(
    [
        "bool flag",
        "byte raw",
        "char letter",
        "int8 i8",
        "uint8 u8",
        "int16 i16",
        "uint16 u16",
        "int32 i32",
        "uint32 u32",
        "int64 i64",
        "uint64 u64",
        "float32 f32",
        "float64 f64",
        "string text",
        "string<=5 short",
        "bool[] flags",
        "byte[3] raw3",
        "uint8[] bytes",
        "char[] letters",
        "int8[2] pair",
        "int16[] i16s",
        "uint16[<=3] u16s",
        "int32[] i32s",
        "uint32[2] u32s",
        "int64[] i64s",
        "uint64[<=2] u64s",
        "float32[] f32s",
        "float64[3] f64s",
        "float64[] f64d",
        "string[] texts",
        "string[2] two_texts",
        "test_msgs/Inner inner",
        "test_msgs/Inner[] inners",
        "test_msgs/Inner[2] two_inners",
        "test_msgs/Empty empty",
        "uint8 CONSTANT=7",
        "float64 with_default 1.5",
        "=" * 80,
        "MSG: test_msgs/Inner",
        "uint8 tag",
        "float64 value",
        "string name",
        "int16[] counts",
        "=" * 80,
        "MSG: test_msgs/Empty",
        "",
    ]
)
INTEGER_RANGES = {
    "byte": (0, 255),
    "uint8": (0, 255),
    "char": (-128, 127),
    "int8": (-128, 127),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}


def _definitions(name: str, text: str) -> dict:
    found = {}
    _for_each_msgdef(name, text, lambda full, short, definition: found.update({full: definition, short: definition}))
    return found


def _scalar(type_name: str):
    if type_name == "bool":
        return st.booleans()
    if type_name in INTEGER_RANGES:
        return st.integers(*INTEGER_RANGES[type_name])
    if type_name == "float32":
        return st.floats(width=32)
    if type_name == "float64":
        return st.floats()
    return st.text(max_size=9)  # strings: every length mod 4 and 8, any code point


def _message(definition, definitions: dict):
    """A strategy of dicts that mcap_ros2 encodes as `definition`."""
    fields = {}
    for field in definition.fields:
        ftype = field.type
        if ftype.is_primitive_type():
            element = _scalar(ftype.type)
        else:
            element = st.deferred(lambda f=ftype: _message(definitions[f"{f.pkg_name}/{f.type}"], definitions))
        if not ftype.is_array:
            fields[field.name] = element
            continue
        if ftype.is_fixed_size_array():
            low = high = ftype.array_size
        else:
            low, high = 0, ftype.array_size if ftype.is_upper_bound else 4
        if ftype.type in ("byte", "uint8"):
            fields[field.name] = st.binary(min_size=low, max_size=high)
        else:
            fields[field.name] = st.lists(element, min_size=low, max_size=high)
    return st.fixed_dictionaries(fields)


def _same(a, b) -> bool:
    """Field for field equal, with the same Python types (NaN equal to NaN)."""
    kind = type(a)
    if hasattr(kind, "_type"):
        return (
            kind._type == type(b)._type
            and kind.__slots__ == type(b).__slots__
            and all(_same(getattr(a, name), getattr(b, name)) for name in kind.__slots__)
        )
    if isinstance(a, list):
        return type(b) is list and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    return kind is type(b) and a == b


SCHEMAS = [(schemas.full_name(name), schemas.definition(name)) for name in schemas.FIELDS] + [
    ("test_msgs/msg/EveryKind", EVERY_KIND)
]


@pytest.mark.parametrize("name, text", SCHEMAS, ids=[name for name, _ in SCHEMAS])
@given(data=st.data())
def test_compiled_decoders_give_mcap_ros2s_messages(name, text, data):
    definitions = _definitions(name, text)
    value = data.draw(_message(definitions[name], definitions))
    encoded = serialize_dynamic(name, text)[name](value)
    schema = Schema(id=1, name=name, encoding="ros2msg", data=text.encode())
    theirs = Ros2DecoderFactory().decoder_for("cdr", schema)(encoded)
    ours = compile_decoders(name, text)[name]
    assert _same(ours(encoded), theirs)
    assert _same(DecoderFactory().decoder_for("cdr", schema)(encoded), theirs)


@given(data=st.data())
def test_cut_or_corrupt_data_raises_a_decode_error_or_decodes_as_mcap_ros2(data):
    """Bytes cut short or changed: the compiled decoder raises what the reader counts as "cannot decode",
    or gives what mcap_ros2 gives."""
    name, text = data.draw(st.sampled_from(SCHEMAS))
    definitions = _definitions(name, text)
    encoded = bytearray(serialize_dynamic(name, text)[name](data.draw(_message(definitions[name], definitions))))
    if data.draw(st.booleans()):
        encoded = encoded[: data.draw(st.integers(0, len(encoded) - 1))]
    else:
        encoded[data.draw(st.integers(4, len(encoded) - 1))] = data.draw(st.integers(0, 255))
    encoded = bytes(encoded)
    schema = Schema(id=1, name=name, encoding="ros2msg", data=text.encode())
    try:
        ours = DecoderFactory().decoder_for("cdr", schema)(encoded)
    except _DECODE_ERRORS:
        return
    assert _same(ours, Ros2DecoderFactory().decoder_for("cdr", schema)(encoded))


def test_big_endian_data_goes_to_mcap_ros2():
    name, text = schemas.full_name("geometry_msgs/Vector3"), schemas.definition("geometry_msgs/Vector3")
    big = b"\x00\x00\x00\x00" + struct.pack(">3d", 1.0, -2.5, 3.25)
    schema = Schema(id=1, name=name, encoding="ros2msg", data=text.encode())
    decoded = DecoderFactory().decoder_for("cdr", schema)(big)
    assert (decoded.x, decoded.y, decoded.z) == (1.0, -2.5, 3.25)
    with pytest.raises(ValueError, match="big-endian"):  # never read as little-endian
        compile_decoders(name, text)[name](big)


def test_what_it_leaves_to_mcap_ros2():
    assert compile_decoders("test_msgs/msg/Wide", "wstring text\n") == {}  # mcap_ros2 cannot either
    schema = Schema(id=1, name="test_msgs/msg/Wide", encoding="ros2msg", data=b"wstring text\n")
    assert DecoderFactory().decoder_for("cdr", schema) is not None
    assert DecoderFactory().decoder_for("json", schema) is None  # as mcap_ros2's factory
    with pytest.raises(ValueError, match="4-byte header"):
        compile_decoders(*SCHEMAS[0])[SCHEMAS[0][0]](b"\x00\x01")
    with pytest.raises(ValueError, match="4-byte header"):  # mcap_ros2's own error
        DecoderFactory().decoder_for(
            "cdr", Schema(id=1, name=SCHEMAS[0][0], encoding="ros2msg", data=SCHEMAS[0][1].encode())
        )(b"\x00\x01")


def test_a_schema_that_does_not_parse_raises_as_mcap_ros2s():
    schema = Schema(id=1, name="test_msgs/msg/Bad", encoding="ros2msg", data=b"no_such_type[ broken\n")
    with pytest.raises(Exception) as theirs:
        Ros2DecoderFactory().decoder_for("cdr", schema)
    with pytest.raises(type(theirs.value)):
        DecoderFactory().decoder_for("cdr", schema)
