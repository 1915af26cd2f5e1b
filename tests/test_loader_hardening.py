"""Hostile input files: every loader answers with a ValueError naming the file and the field at fault (a wrong
argument type with a TypeError), never with RecursionError, MemoryError, NotImplementedError or an error later.

Covers `field.load_field` (and `Field` / `FieldDimensions` built directly), `LWPR.load` (and the constructor),
`CollisionReference.load` (and the dataclass itself) and `LearnedFootstepOdometry.load`. Each loader gets
concrete hostile files (deep nesting, huge sizes, wrong dtypes, damaged zip entries), deterministic byte flips
of a valid file, and a hypothesis property over corrupted fields.
"""

from __future__ import annotations

import dataclasses
import io
import json
import math
import struct
import zipfile

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from field import Field, FieldDimensions, load_field, save_field, spl
from field.dimensions import MAX_FIELD_EXTENT
from field.geometry import MAX_NAME_LENGTH
from field.io import MAX_FIELD_FILE_BYTES
from motion_models.learned_odometry import MAX_META_FILE_BYTES, META_FILE, LearnedFootstepOdometry
from motion_models.lwpr import LWPR, MAX_INITIAL_BYTES, MAX_INPUTS, MAX_OUTPUTS, load_npz
from proprioception.collision import (
    MAX_DELAY,
    MAX_JOINTS,
    MAX_WINDOW,
    MIN_REFERENCE,
    CollisionDetector,
    CollisionReference,
    detect,
)

DEEP = 100_000  # nesting levels of the deeply nested files


def flipped_copies(data: bytes, budget: int = 400):
    """(offset, data with the byte at offset inverted), deterministic: `budget` offsets spread over the file, and
    in a zip file every byte of the first central-directory entry's fixed part and of the end record (the fields
    zipfile trusts: versions, flags, compression method, sizes, offsets)."""
    offsets = set(range(0, len(data), max(1, len(data) // budget)))
    start = data.find(b"PK\x01\x02")
    if start >= 0:
        offsets |= set(range(start, start + 46)) | set(range(len(data) - 22, len(data)))
    for offset in sorted(offsets):
        yield offset, data[:offset] + bytes([data[offset] ^ 0xFF]) + data[offset + 1 :]


def npz_fields(path) -> dict:
    with np.load(path) as npz:
        return {key: npz[key] for key in npz.files}


def rewrite_npz(source, target, **changes) -> None:
    """`source`'s arrays with `changes` applied (None deletes a field), saved to `target`."""
    fields = npz_fields(source)
    for key, value in changes.items():
        if value is None:
            fields.pop(key, None)
        else:
            fields[key] = value
    np.savez(target, **fields)


def patch_central_directory(data: bytes, offset: int, fmt: str, value: int) -> bytes:
    """`data` with a field of every zip central-directory entry set to `value` (offset from the entry start)."""
    out = bytearray(data)
    start = data.find(b"PK\x01\x02")
    while start >= 0:
        struct.pack_into(fmt, out, start + offset, value)
        start = data.find(b"PK\x01\x02", start + 4)
    return bytes(out)


def huge_member_npz(path, name: str = "n_in", shape=(10**12,)) -> None:
    """A zip whose one .npy member claims `shape` float64 values but holds 64 bytes."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": shape})
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr(f"{name}.npy", header.getvalue() + b"\0" * 64)


def json_values(max_leaves: int = 8):
    """Any JSON value, nested a few levels."""
    leaves = st.one_of(
        st.none(),
        st.booleans(),
        st.integers(-(10**30), 10**30),
        st.floats(allow_nan=True, allow_infinity=True),
        st.text(max_size=20),
    )
    return st.recursive(
        leaves,
        lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=12), inner, max_size=4)),
        max_leaves=max_leaves,
    )


# =============================================================================================================
# Field files
# =============================================================================================================
SPL_TOML = """name = "lab"

[dimensions]
length = 9.0
width = 6.0
line_width = 0.05
penalty_area_length = 1.65
penalty_area_width = 4.0
goal_area_length = 0.6
goal_area_width = 2.2
penalty_mark_distance = 1.3
center_circle_diameter = 1.5
goal_inner_width = 1.5
goalpost_diameter = 0.1
border_strip_width = 0.7
"""


def write(tmp_path, name: str, text: str | bytes):
    path = tmp_path / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    return path


def assert_load_error(load, path, *fragments: str) -> str:
    """`load(path)` raises ValueError whose message names the path and holds each fragment, briefly."""
    with pytest.raises(ValueError) as error:
        load(path)
    message = str(error.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    assert len(message) < 2000, "the message repeats a huge value"
    return message


def assert_field_error(path, *fragments: str) -> str:
    return assert_load_error(load_field, path, *fragments)


@pytest.mark.parametrize(
    ("name", "text"),
    [
        ("top.json", "[" * DEEP + "]" * DEEP),
        ("object.json", '{"a":' * DEEP + "1" + "}" * DEEP),
        ("value.json", '{"preset": "spl", "dimensions": {"width": ' + "[" * DEEP + "]" * DEEP + "}}"),
        ("array.toml", "a = " + "[" * DEEP + "]" * DEEP + "\n"),
        ("inline.toml", "a = " + "{b = " * DEEP + "1" + "}" * DEEP + "\n"),
    ],
)
def test_deeply_nested_field_files_are_value_errors(tmp_path, name, text):
    assert_field_error(write(tmp_path, name, text), "nested too deeply")


@pytest.mark.parametrize(
    ("header", "key"),
    [
        ("a", "'a'"),  # an unknown top-level key holding a deep table
        ("dimensions.length", "length"),  # a dimension that is a deep table
    ],
)
def test_deep_dotted_toml_tables_are_value_errors_naming_the_key(tmp_path, header, key):
    # Dotted table headers nest without recursion in the parser; the error message must not recurse either.
    # (10 000 levels, ten times Python's recursion limit: tomllib takes seconds per 100 000.)
    text = 'preset = "spl"\n[' + header + "." + ".".join(["a"] * (DEEP // 10)) + "]\nx = 1\n"
    assert_field_error(write(tmp_path, "dotted.toml", text), key)


def test_a_field_file_beyond_the_size_bound_is_refused_unread(tmp_path):
    text = SPL_TOML + "# " + "x" * MAX_FIELD_FILE_BYTES + "\n"
    assert_field_error(write(tmp_path, "big.toml", text), "MAX_FIELD_FILE_BYTES")


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_a_million_metre_field_is_refused(tmp_path, suffix):
    dims = dict(
        length=1e6,
        width=1e6,
        line_width=0.05,
        penalty_area_length=1e5,
        penalty_area_width=1e5,
        goal_area_length=1e4,
        goal_area_width=1e4,
        penalty_mark_distance=1e4,
        center_circle_diameter=1e4,
        goal_inner_width=10.0,
        goalpost_diameter=0.1,
        border_strip_width=1.0,
    )
    if suffix == ".json":
        text = json.dumps({"name": "huge", "dimensions": dims})
    else:
        text = 'name = "huge"\n[dimensions]\n' + "".join(f"{k} = {v!r}\n" for k, v in dims.items())
    assert_field_error(write(tmp_path, "huge" + suffix, text), "length", "1000000.0", "MAX_FIELD_EXTENT")


def test_the_carpet_bound_counts_the_border_strip(tmp_path):
    text = SPL_TOML.replace("length = 9.0", "length = 199.0").replace(
        "border_strip_width = 0.7", "border_strip_width = 1.0"
    )
    assert_field_error(write(tmp_path, "wide.toml", text), "length + 2 * border_strip_width", "201.0")


HUGE = "x" * 500_000


@pytest.mark.parametrize(
    ("name", "text", "fragments"),
    [
        ("string.json", '"spl"', ["top level", "str"]),
        ("number.json", "3.5", ["top level", "float"]),
        ("null.json", "null", ["top level", "NoneType"]),
        ("name_list.json", '{"name": [1, 2], "preset": "spl"}', ["name", "[1, 2]"]),
        ("name_table.toml", 'preset = "spl"\n[name]\na = 1\n', ["name", "{'a': 1}"]),
        (
            "name_huge.json",
            json.dumps({"name": HUGE, "preset": "spl"}),
            ["name", "500000 characters", "MAX_NAME_LENGTH"],
        ),
        ("name_long.toml", f'preset = "spl"\nname = "{"y" * (MAX_NAME_LENGTH + 1)}"\n', ["name", "MAX_NAME_LENGTH"]),
        ("preset_huge.json", json.dumps({"preset": HUGE}), ["preset", "xxx"]),
        ("key_huge.json", json.dumps({HUGE: 1}), ["unknown key", "xxx"]),
        ("value_huge.json", json.dumps({"preset": "spl", "dimensions": {"lenght": HUGE}}), ["lenght", "length"]),
        ("dim_string.json", json.dumps({"preset": "spl", "dimensions": {"width": HUGE}}), ["width", "number"]),
        ("dim_bool.json", '{"preset": "spl", "dimensions": {"width": true}}', ["width", "True"]),
        ("dim_nan.json", '{"preset": "spl", "dimensions": {"length": NaN}}', ["length", "nan"]),
        ("dim_inf.json", '{"preset": "spl", "dimensions": {"length": -Infinity}}', ["length", "inf"]),
        ("dim_negative.toml", 'preset = "spl"\n[dimensions]\nwidth = -6.0\n', ["width", "-6.0"]),
        ("dim_date.toml", 'preset = "spl"\n[dimensions]\nwidth = 1979-05-27\n', ["width", "1979"]),
        ("dim_digits.json", '{"preset": "spl", "dimensions": {"width": 1%s}}' % ("0" * 5000), ["not valid JSON"]),
        ("dim_digits.toml", 'preset = "spl"\n[dimensions]\nwidth = 1%s\n' % ("0" * 5000), ["not valid TOML"]),
        ("dim_bigint.json", '{"preset": "spl", "dimensions": {"width": 1%s}}' % ("0" * 4000), ["width", "finite"]),
        ("unknown.toml", 'preset = "spl"\ncolour = "green"\n', ["colour", "green"]),
        ("unknown_dim.toml", 'preset = "spl"\n[dimensions]\ncolour = 3\n', ["colour", "3"]),
        ("binary.toml", b"\xff\xfe\x00name", ["UTF-8"]),
    ],
)
def test_hostile_field_contents_are_value_errors_naming_file_and_key(tmp_path, name, text, fragments):
    assert_field_error(write(tmp_path, name, text), *fragments)


@pytest.mark.parametrize("path", [None, 3, b"lab.toml", ["lab.toml"]])
def test_a_field_path_of_the_wrong_type_is_a_type_error(path):
    with pytest.raises(TypeError, match="path"):
        load_field(path)


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("length", 1e6),
        ("width", 250.0),
        ("border_strip_width", 300.0),
        ("line_width", 1e300),
        ("length", 10**400),
        ("length", [[[[[[[[1.0]]]]]]]]),
        ("width", "w" * 1_000_000),
    ],
)
def test_absurd_dimensions_built_directly_are_value_errors_naming_the_dimension(key, value):
    values = spl().dims.to_dict()
    values[key] = value
    with pytest.raises(ValueError, match=key) as error:
        Field("lab", FieldDimensions(**values))
    assert len(str(error.value)) < 500


def test_a_deeply_nested_value_built_directly_is_a_value_error():
    nested: list = []
    for _ in range(DEEP):
        nested = [nested]
    with pytest.raises(ValueError, match="length"):
        dataclasses.replace(spl().dims, length=nested)
    with pytest.raises(ValueError, match="name"):
        Field(nested, spl().dims)
    with pytest.raises(ValueError, match="name"):
        Field("n" * (MAX_NAME_LENGTH + 1), spl().dims)


def test_the_largest_fields_are_still_accepted(tmp_path):
    pitch = dataclasses.replace(spl().dims, length=105.0, width=68.0, border_strip_width=5.0)
    field = Field("pitch", pitch)
    edge = dataclasses.replace(
        spl().dims, length=MAX_FIELD_EXTENT - 2.0, width=MAX_FIELD_EXTENT - 2.0, border_strip_width=1.0
    )
    for name, dims in (("pitch", pitch), ("edge", edge)):
        path = tmp_path / f"{name}.json"
        save_field(Field(name, dims), path)
        assert load_field(path).dims == dims
    assert field.dims.length == 105.0


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_byte_flipped_field_files_load_or_raise_value_error(tmp_path, suffix):
    path = tmp_path / f"spl{suffix}"
    save_field(spl(), path)
    for offset, data in flipped_copies(path.read_bytes()):
        path.write_bytes(data)
        try:
            field = load_field(path)
        except ValueError:
            continue
        assert isinstance(field, Field), offset


@given(text=st.one_of(st.text(max_size=200), json_values().map(json.dumps)), suffix=st.sampled_from([".toml", ".json"]))
def test_any_field_file_text_loads_or_raises_value_error(tmp_path_factory, text, suffix):
    path = tmp_path_factory.mktemp("field") / f"any{suffix}"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        assert isinstance(load_field(path), Field)
    except ValueError as error:
        assert str(path) in str(error)


@given(key=st.sampled_from(["name", "preset", "dimensions", "length", "width", "extra"]), value=json_values())
def test_any_json_value_for_a_key_loads_or_raises_value_error(tmp_path_factory, key, value):
    document = {"preset": "spl", "dimensions": {"length": 8.0}}
    if key in ("length", "width"):
        document["dimensions"][key] = value
    else:
        document[key] = value
    path = tmp_path_factory.mktemp("field") / "lab.json"
    path.write_text(json.dumps(document), encoding="utf-8")
    try:
        assert isinstance(load_field(path), Field)
    except ValueError as error:
        # A valid preset other than the default can fail on the overridden length, which the message names.
        assert str(path) in str(error) and (key in str(error) or key == "preset")


# =============================================================================================================
# LWPR model files
# =============================================================================================================
@pytest.fixture(scope="module")
def lwpr_file(tmp_path_factory):
    rng = np.random.default_rng(3)
    model = LWPR(2, 1)
    model.init_D = 20.0 * np.eye(2)
    for x in rng.uniform(-1.0, 1.0, (150, 2)):
        model.update(x, np.array([np.sin(3.0 * x[0]) * x[1]]))
    path = tmp_path_factory.mktemp("lwpr") / "model.npz"
    model.save(path)
    return path


def assert_lwpr_error(path, *fragments: str) -> str:
    return assert_load_error(LWPR.load, path, *fragments)


@pytest.mark.parametrize(
    ("field", "value", "fragments"),
    [
        ("n_in", np.array(10**5, dtype=np.int64), ["n_in", "100000"]),
        ("n_out", np.array(10**6, dtype=np.int64), ["n_out", "1000000"]),
        ("n_in", np.array(-3, dtype=np.int64), ["n_in", "-3"]),
        ("n_in", np.array("2"), ["n_in", "dtype"]),
        ("n_in", np.array([[2]], dtype=np.int64), ["n_in", "shape"]),
        ("n_in", np.array(2.0), ["n_in", "dtype"]),
        ("n_data", np.array(1e30), ["n_data", "dtype"]),
        ("n_data", np.array(2**63, dtype=np.uint64), ["n_data", str(2**63)]),
        ("n_data", np.array(-1, dtype=np.int64), ["n_data", "-1"]),
        ("format_version", np.array([1, 1]), ["format_version", "shape"]),
        ("format_version", np.array(1 + 2j), ["format_version", "dtype"]),
        ("format", np.array(7), ["format"]),
        ("format", np.array(["robocup-mcl LWPR model"] * 2), ["format"]),
        ("kernel", np.array(0), ["kernel", "dtype"]),
        ("w_gen", np.array("0.1"), ["w_gen", "dtype"]),
        ("w_gen", np.array(np.nan), ["w_gen", "non-finite"]),
        ("w_gen", np.array(7.0), ["w_gen", "7.0"]),
        ("diag_only", np.array(1.0), ["diag_only", "dtype"]),
        ("init_D", np.eye(3), ["init_D", "shape"]),
        ("init_M", np.full((2, 2), np.inf), ["init_M", "non-finite"]),
        ("norm_in", np.array(1.0), ["norm_in", "shape"]),
        ("mean_x", np.array(["a", "b"]), ["mean_x", "dtype"]),
        ("counts", np.array([[1.0, 0.0]]), ["counts", "dtype"]),
        ("counts", np.array([[10**6, 0]]), ["counts"]),
        ("rf_vec", np.zeros(3), ["rf_vec", "shape"]),
        ("rf_mat", np.zeros((1, 1, 5, 2, 2), dtype=np.complex128), ["rf_mat"]),
        ("rf_ints", np.zeros((1, 1, 2)), ["rf_ints"]),
        ("rf_scal", None, ["rf_scal"]),
    ],
)
def test_hostile_lwpr_fields_are_value_errors_naming_file_and_field(tmp_path, lwpr_file, field, value, fragments):
    path = tmp_path / "hostile.npz"
    rewrite_npz(lwpr_file, path, **{field: value})
    assert_lwpr_error(path, *fragments)


def test_a_member_claiming_a_terabyte_is_refused_before_allocation(tmp_path):
    huge_member_npz(tmp_path / "huge.npz")
    assert_lwpr_error(tmp_path / "huge.npz", "n_in.npy", "shape")


@pytest.mark.parametrize(
    ("what", "offset", "fmt", "value"),
    [
        ("compression method 1 (shrunk)", 10, "<H", 1),  # zipfile: NotImplementedError
        ("compression method 14 (lzma)", 10, "<H", 14),
        ("encryption flag", 8, "<H", 1),  # zipfile: RuntimeError (password required)
        ("uncompressed size", 24, "<I", 0xFFFFFFF0),
    ],
)
def test_damaged_zip_entries_are_value_errors(tmp_path, lwpr_file, what, offset, fmt, value):
    path = tmp_path / "damaged.npz"
    path.write_bytes(patch_central_directory(lwpr_file.read_bytes(), offset, fmt, value))
    assert_lwpr_error(path)


def test_byte_flipped_lwpr_files_load_or_raise_value_error(tmp_path, lwpr_file):
    path = tmp_path / "flipped.npz"
    x = np.array([0.2, -0.4])
    for offset, data in flipped_copies(lwpr_file.read_bytes()):
        path.write_bytes(data)
        try:
            model = LWPR.load(path)
        except ValueError:
            continue
        assert model.predict(x).shape == (1,), offset


def test_a_compressed_model_file_still_loads_bit_for_bit(tmp_path, lwpr_file):
    path = tmp_path / "compressed.npz"
    np.savez_compressed(path, **npz_fields(lwpr_file))
    grid = np.random.default_rng(1).uniform(-1.0, 1.0, (50, 2))
    a, b = LWPR.load(lwpr_file), LWPR.load(path)
    np.testing.assert_array_equal(a.predict_conf(grid)[0], b.predict_conf(grid)[0])
    np.testing.assert_array_equal(a.predict_conf(grid)[1], b.predict_conf(grid)[1])


@pytest.mark.parametrize(
    ("n_in", "n_out"),
    [(10**5, 1), (MAX_INPUTS + 1, 1), (1, MAX_OUTPUTS + 1), (MAX_INPUTS, 2), (100, MAX_OUTPUTS), (2**62, 2**62)],
)
def test_absurd_lwpr_sizes_are_value_errors_not_memory_errors(n_in, n_out):
    with pytest.raises(ValueError, match="n_in|n_out"):
        LWPR(n_in, n_out)


def test_the_size_bounds_admit_the_largest_single_output_model():
    # Checked without allocating: LWPR(MAX_INPUTS, 1) fits the budget, LWPR(MAX_INPUTS, 2) does not.
    assert LWPR._initial_bytes(MAX_INPUTS, 1) <= MAX_INITIAL_BYTES < LWPR._initial_bytes(MAX_INPUTS, 2)
    assert LWPR._initial_bytes(10, MAX_OUTPUTS) <= MAX_INITIAL_BYTES


@pytest.mark.parametrize("path", [None, 3, 2.5, ["model.npz"]])
def test_an_lwpr_path_of_the_wrong_type_is_a_type_error(path):
    with pytest.raises(TypeError, match="path"):
        LWPR.load(path)


def test_a_missing_lwpr_file_stays_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        LWPR.load(tmp_path / "absent.npz")
    with pytest.raises(FileNotFoundError):
        load_npz(str(tmp_path / "absent.npz"), "anything")


LWPR_KEYS = (
    "format",
    "format_version",
    "n_in",
    "n_out",
    "n_data",
    "kernel",
    "init_D",
    "init_M",
    "init_alpha",
    "norm_in",
    "norm_out",
    "mean_x",
    "var_x",
    "counts",
    "w_gen",
    "penalty",
    "meta",
    "rf_vec",
    "rf_mat",
    "rf_proj",
    "rf_reg",
    "rf_scal",
    "rf_ints",
)
ANY_ARRAY = hnp.arrays(
    dtype=st.sampled_from([np.int64, np.uint64, np.int8, np.float64, np.float32, np.bool_, np.complex128, "<U4"]),
    shape=hnp.array_shapes(min_dims=0, max_dims=5, min_side=0, max_side=3),
)


@given(key=st.sampled_from(LWPR_KEYS), value=ANY_ARRAY)
def test_any_array_in_any_lwpr_field_loads_or_raises_value_error(tmp_path_factory, lwpr_file, key, value):
    path = tmp_path_factory.mktemp("lwpr") / "any.npz"
    rewrite_npz(lwpr_file, path, **{key: value})
    try:
        model = LWPR.load(path)
    except ValueError as error:
        assert str(path) in str(error)
        return
    try:
        y = model.predict(np.zeros(model.n_in))
    except ValueError as error:  # a model that holds no sample yet
        assert "untrained" in str(error)
    else:
        assert y.shape == (model.n_out,)


# =============================================================================================================
# Collision references
# =============================================================================================================
def small_reference(**changes) -> CollisionReference:
    rng = np.random.default_rng(5)
    fields = dict(
        delays=np.array([2, 3, 1, 0], dtype=np.int64),
        joint_sides=np.array([0, 0, 1, 1], dtype=np.int64),
        window=5,
        speeds=np.array([0.0, 0.1, 0.2]),
        table=rng.uniform(1e-3, 1e-2, (2, 3, 4)),
        half_stance=0.05,
    )
    fields.update(changes)
    return CollisionReference(**fields)


def exercise(reference: CollisionReference) -> None:
    """Run the detector, online and offline, over a short synthetic walk: must not raise."""
    rng = np.random.default_rng(6)
    frames, joints = 40, reference.n_joints
    commands = np.sin(np.linspace(0.0, 6.0, frames))[:, None] * np.ones(joints)
    readings = commands + 0.01 * rng.standard_normal((frames, joints))
    phase = np.mod(np.arange(frames) / 30.0, 1.0)
    walk = np.tile([0.1, 0.0, 0.2], (frames, 1))
    detector = CollisionDetector(reference)
    for k in range(frames):
        detector.update(commands[k], readings[k], phase[k], walk[k])
    detect(reference, commands, readings, phase, walk)


@pytest.fixture(scope="module")
def reference_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("collision") / "reference.npz"
    small_reference().save(path)
    return path


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("window", -5),
        ("window", 0),
        ("window", MAX_WINDOW + 1),
        ("window", True),
        ("window", 2.5),
        ("window", 10**30),
        ("delays", np.array([2.0, 3.0, 1.0, 0.0])),
        ("delays", np.array([2, -1, 1, 0])),
        ("delays", np.array([2, 3, 1, MAX_DELAY + 1])),
        ("delays", np.zeros(0, dtype=np.int64)),
        ("delays", np.zeros(MAX_JOINTS + 1, dtype=np.int64)),
        ("delays", np.array([[2, 3, 1, 0]])),
        ("delays", np.array([True, False, True, True])),
        ("delays", "2310"),
        ("joint_sides", np.array([0, 0, 2, 1])),
        ("joint_sides", np.array([0, 0, 0, 0])),
        ("joint_sides", np.array([0, 1, 1])),
        ("joint_sides", np.array([0.0, 0.0, 1.0, 1.0])),
        ("speeds", np.array([0.2, 0.1, 0.0])),
        ("speeds", np.array([0.0, 0.1, 0.1])),
        ("speeds", np.array([-0.1, 0.1, 0.2])),
        ("speeds", np.array([0.0, np.nan, 0.2])),
        ("speeds", np.zeros(0)),
        ("table", np.full((2, 3, 4), np.nan)),
        ("table", np.zeros((2, 3, 4))),
        ("table", -np.ones((2, 3, 4))),
        ("table", np.full((2, 3, 4), 1e-320)),
        ("table", np.full((2, 3, 4), MIN_REFERENCE / 2)),
        ("table", np.ones((2, 3, 0))),
        ("table", np.ones((2, 2, 4))),
        ("table", np.ones((3, 3, 4))),
        ("table", np.ones((2, 3))),
        ("table", np.ones((2, 3, 4), dtype=np.complex128)),
        ("half_stance", 0.0),
        ("half_stance", -0.05),
        ("half_stance", math.nan),
        ("half_stance", math.inf),
        ("half_stance", True),
        ("half_stance", "0.05"),
        ("half_stance", 10**400),
    ],
)
def test_invalid_references_are_value_errors_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        small_reference(**{field: value})


@pytest.mark.parametrize(
    ("field", "value", "fragments"),
    [
        ("window", np.array(-5), ["window", "-5"]),
        ("window", np.array(5.0), ["window", "dtype"]),
        ("window", np.array([5, 5]), ["window", "dimensions"]),
        ("delays", np.array([2.0, 3.0, 1.0, 0.0]), ["delays", "dtype"]),
        ("delays", np.array([2, 3, 1, 2**40]), ["delays", "MAX_DELAY"]),
        ("joint_sides", np.array(["l", "l", "r", "r"]), ["joint_sides", "dtype"]),
        ("speeds", np.array([0.2, 0.1, 0.0]), ["speeds", "increasing"]),
        ("table", np.full((2, 3, 4), np.nan), ["table", "nan"]),
        ("table", np.ones((2, 3, 4), dtype=np.complex64), ["table", "dtype"]),
        ("half_stance", np.array("wide"), ["half_stance", "dtype"]),
        ("half_stance", np.array(-1.0), ["half_stance", "-1.0"]),
        ("version", np.array(2), ["version", "2"]),
        ("version", np.array("1"), ["version", "dtype"]),
        ("format", np.array("something else"), ["format", "something else"]),
        ("table", None, ["table"]),
    ],
)
def test_hostile_reference_files_are_value_errors_naming_file_and_field(
    tmp_path, reference_file, field, value, fragments
):
    path = tmp_path / "hostile.npz"
    rewrite_npz(reference_file, path, **{field: value})
    with pytest.raises(ValueError) as error:
        CollisionReference.load(path)
    message = str(error.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, (fragment, message)


@pytest.mark.parametrize(
    ("offset", "fmt", "value"), [(10, "<H", 1), (10, "<H", 99), (8, "<H", 1), (24, "<I", 0xFFFFFFF0)]
)
def test_damaged_reference_zip_entries_are_value_errors(tmp_path, reference_file, offset, fmt, value):
    path = tmp_path / "damaged.npz"
    path.write_bytes(patch_central_directory(reference_file.read_bytes(), offset, fmt, value))
    with pytest.raises(ValueError, match="damaged.npz"):
        CollisionReference.load(path)


def test_a_reference_member_claiming_a_terabyte_is_refused(tmp_path):
    huge_member_npz(tmp_path / "huge.npz", "table")
    with pytest.raises(ValueError, match="huge.npz"):
        CollisionReference.load(tmp_path / "huge.npz")


def test_byte_flipped_reference_files_load_or_raise_value_error(tmp_path, reference_file):
    path = tmp_path / "flipped.npz"
    for _, data in flipped_copies(reference_file.read_bytes()):
        path.write_bytes(data)
        try:
            reference = CollisionReference.load(path)
        except ValueError:
            continue
        exercise(reference)


def test_the_reference_bounds_themselves_are_accepted():
    exercise(
        small_reference(
            table=np.full((2, 3, 4), MIN_REFERENCE), window=MAX_WINDOW, delays=np.array([0, MAX_DELAY, 1, 2])
        )
    )
    exercise(small_reference(delays=np.zeros(MAX_JOINTS, dtype=np.int64), joint_sides=np.arange(MAX_JOINTS) % 2))


def test_a_valid_reference_round_trips_and_works(tmp_path, reference_file):
    original = small_reference()
    loaded = CollisionReference.load(reference_file)
    phases, speeds = np.linspace(0, 1, 13), np.linspace(0, 0.3, 13)
    np.testing.assert_array_equal(loaded.reference(phases, speeds), original.reference(phases, speeds))
    exercise(loaded)
    with pytest.raises(TypeError, match="path"):
        CollisionReference.load(None)
    with pytest.raises(FileNotFoundError):
        CollisionReference.load(tmp_path / "absent.npz")


REFERENCE_KEYS = ("format", "version", "delays", "joint_sides", "window", "speeds", "table", "half_stance")


@given(key=st.sampled_from(REFERENCE_KEYS), value=ANY_ARRAY)
def test_any_array_in_any_reference_field_loads_or_raises_value_error(tmp_path_factory, reference_file, key, value):
    path = tmp_path_factory.mktemp("collision") / "any.npz"
    rewrite_npz(reference_file, path, **{key: value})
    try:
        reference = CollisionReference.load(path)
    except ValueError as error:
        assert str(path) in str(error)
        return
    exercise(reference)


@given(
    delays=st.lists(st.integers(-2, 12), min_size=1, max_size=6),
    sides=st.lists(st.integers(-1, 2), min_size=1, max_size=6),
    window=st.one_of(st.integers(-3, 30), st.floats(-1.0, 30.0), st.booleans()),
    speeds=st.lists(st.one_of(st.floats(-1.0, 1.0), st.sampled_from([math.nan, math.inf])), min_size=0, max_size=4),
    bins=st.integers(0, 4),
    low=st.sampled_from([0.0, 1e-300, 1e-3]),
    half_stance=st.floats(allow_nan=True),
)
def test_any_reference_built_directly_is_refused_or_works(delays, sides, window, speeds, bins, low, half_stance):
    table = np.random.default_rng(len(delays)).uniform(low, 1e-2, (2, len(speeds), bins))
    try:
        reference = CollisionReference(np.array(delays), np.array(sides), window, np.array(speeds), table, half_stance)
    except ValueError:
        return
    exercise(reference)


# =============================================================================================================
# Learned footstep odometry directories
# =============================================================================================================
@pytest.fixture(scope="module")
def odometry_saved(tmp_path_factory):
    """A small trained holder (a-priori inputs) and the directory it was saved to."""
    rng = np.random.default_rng(8)
    models = []
    for _ in range(3):
        model = LWPR(7, 1)
        model.init_D = 0.01 * np.eye(7)
        for x in rng.uniform(-1.0, 1.0, (30, 7)):
            model.update(x, np.array([x[0] + 0.1 * x[1]]))
        models.append(model)
    holder = LearnedFootstepOdometry(tuple(models), "apriori")
    directory = tmp_path_factory.mktemp("odometry") / "model"
    holder.save(directory)
    return holder, directory


@pytest.fixture(scope="module")
def odometry_dir(odometry_saved):
    return odometry_saved[1]


@pytest.fixture
def odometry_copy(tmp_path, odometry_dir):
    directory = tmp_path / "copy"
    directory.mkdir()
    for path in odometry_dir.iterdir():
        (directory / path.name).write_bytes(path.read_bytes())
    return directory


def meta_of(directory) -> dict:
    return json.loads((directory / META_FILE).read_text())


def assert_odometry_error(directory, *fragments: str) -> str:
    return assert_load_error(LearnedFootstepOdometry.load, directory, *fragments)


@pytest.mark.parametrize(
    "text",
    [
        "[" * DEEP + "]" * DEEP,
        '{"format": ' + "[" * DEEP + "]" * DEEP + "}",
    ],
)
def test_deeply_nested_meta_files_are_value_errors(odometry_copy, text):
    (odometry_copy / META_FILE).write_text(text)
    assert_odometry_error(odometry_copy, META_FILE)


def test_a_huge_meta_file_is_refused_unread(odometry_copy):
    (odometry_copy / META_FILE).write_text(" " * (MAX_META_FILE_BYTES + 1) + "{}")
    assert_odometry_error(odometry_copy, "MAX_META_FILE_BYTES")


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("format_version", True),
        ("format_version", "1"),
        ("format", ["robocup-mcl learned footstep odometry"]),
        ("inputs", 3),
        ("inputs", ["apriori"]),
        ("inputs", "sideways"),
        ("n_inputs", True),
        ("n_inputs", 9),
        ("n_inputs", "7"),
        ("models", ["dx.npz", "dy.npz", "dtheta.npz"]),
        ("models", {"dx": "dx.npz", "dy": "dy.npz", "dtheta": "dtheta.npz", "dz": "dz.npz"}),
        ("models", {"dx": 3, "dy": "dy.npz", "dtheta": "dtheta.npz"}),
        ("models", {"dx": "../copy/dx.npz", "dy": "dy.npz", "dtheta": "dtheta.npz"}),
        ("models", {"dx": "/dev/zero", "dy": "dy.npz", "dtheta": "dtheta.npz"}),
        ("models", {"dx": "", "dy": "dy.npz", "dtheta": "dtheta.npz"}),
        ("models", {"dx": "d\u0000x.npz", "dy": "dy.npz", "dtheta": "dtheta.npz"}),
        ("fallback_sigma", "abc"),
        ("fallback_sigma", [0.1, 0.1]),
        ("fallback_sigma", [0.1, 0.1, True]),
        ("fallback_sigma", [0.1, 0.1, -0.1]),
        ("fallback_sigma", [0.1, 0.1, 10**400]),
        ("fallback_sigma", {"x": 1}),
        ("min_sigma", [0.1, 0.1, None]),
        ("noise_scale", True),
        ("noise_scale", "1"),
        ("noise_scale", 10**400),
        ("noise_scale", -1.0),
        ("residual", "yes"),
        ("residual", 1),
        ("colour", "green"),
        ("comment", "x" * 100_000),
    ],
)
def test_hostile_meta_keys_are_value_errors_naming_file_and_key(odometry_copy, key, value):
    meta = meta_of(odometry_copy)
    meta[key] = value
    (odometry_copy / META_FILE).write_text(json.dumps(meta))
    assert_odometry_error(odometry_copy, META_FILE, key)


@pytest.mark.parametrize("text", ['{"format": NaN}', "null", '"robocup"', "1e999", "\xff"])
def test_foreign_meta_files_are_value_errors(odometry_copy, text):
    (odometry_copy / META_FILE).write_bytes(text.encode("latin-1"))
    assert_odometry_error(odometry_copy, META_FILE)


def test_meta_nan_and_a_missing_key_are_value_errors(odometry_copy):
    meta = meta_of(odometry_copy)
    text = json.dumps({**meta, "noise_scale": 1.0}).replace("1.0", "NaN", 1)
    (odometry_copy / META_FILE).write_text(text)
    assert_odometry_error(odometry_copy, META_FILE, "noise_scale")
    del meta["min_sigma"]
    (odometry_copy / META_FILE).write_text(json.dumps(meta))
    assert_odometry_error(odometry_copy, META_FILE, "min_sigma")


def test_a_hostile_model_file_in_the_directory_is_a_value_error(odometry_copy):
    huge_member_npz(odometry_copy / "dy.npz")
    assert_odometry_error(odometry_copy, "dy.npz")


@pytest.mark.parametrize("directory", [None, 3, b"model"])
def test_an_odometry_directory_of_the_wrong_type_is_a_type_error(directory):
    with pytest.raises(TypeError, match="directory"):
        LearnedFootstepOdometry.load(directory)


def test_a_valid_odometry_directory_still_loads(odometry_saved):
    holder, directory = odometry_saved
    loaded = LearnedFootstepOdometry.load(directory)
    assert (loaded.inputs, loaded.fallback_sigma, loaded.residual) == (
        holder.inputs,
        holder.fallback_sigma,
        holder.residual,
    )
    X = np.random.default_rng(9).uniform(-1.0, 1.0, (5, 7))
    for got, want in zip(loaded.predict_steps(X), holder.predict_steps(X)):
        np.testing.assert_array_equal(got, want)


def test_byte_flipped_meta_files_load_or_raise_value_error(odometry_copy):
    path = odometry_copy / META_FILE
    for offset, data in flipped_copies(path.read_bytes()):
        path.write_bytes(data)
        try:
            assert isinstance(LearnedFootstepOdometry.load(odometry_copy), LearnedFootstepOdometry), offset
        except ValueError:
            pass


@given(
    key=st.sampled_from(
        [
            "format",
            "format_version",
            "inputs",
            "n_inputs",
            "models",
            "fallback_sigma",
            "noise_scale",
            "min_sigma",
            "residual",
            "other",
        ]
    ),
    value=json_values(),
)
def test_any_json_value_for_a_meta_key_loads_or_raises_value_error(tmp_path_factory, odometry_dir, key, value):
    directory = tmp_path_factory.mktemp("odometry")
    for path in odometry_dir.iterdir():
        (directory / path.name).write_bytes(path.read_bytes())
    meta = meta_of(directory)
    meta[key] = value
    (directory / META_FILE).write_text(json.dumps(meta))
    try:
        assert isinstance(LearnedFootstepOdometry.load(directory), LearnedFootstepOdometry)
    except ValueError as error:
        assert META_FILE in str(error) or str(directory) in str(error)
