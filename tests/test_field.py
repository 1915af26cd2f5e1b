"""Tests for the field package: presets, derived geometry, file loading, mirroring."""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import pickle
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from field import (
    LANDMARK_TYPE_ALIASES,
    Field,
    FieldDimensions,
    LandmarkType,
    adultsize,
    kidsize,
    load_field,
    preset,
    save_field,
    spl,
    to_toml,
)

PRESETS = {"spl": spl, "kidsize": kidsize, "adultsize": adultsize}
EXPECTED_COUNTS = {
    LandmarkType.GOALPOST: 4,
    LandmarkType.L_CROSSING: 12,
    LandmarkType.T_CROSSING: 10,
    LandmarkType.X_CROSSING: 2,
    LandmarkType.PENALTY_MARK: 2,
    LandmarkType.CENTER_MARK: 1,
}
INTERSECTION_TYPES = (
    LandmarkType.L_CROSSING,
    LandmarkType.T_CROSSING,
    LandmarkType.X_CROSSING,
)


# Helpers


def as_point_set(points: np.ndarray) -> set[tuple[float, float]]:
    # Rounding absorbs the last-bit differences of sums like 4.5 - 1.65 versus -(4.5 - 1.65).
    return {(round(x, 9) + 0.0, round(y, 9) + 0.0) for x, y in points}


def distance_to_segment(point: np.ndarray, segment: np.ndarray) -> float:
    start, end = segment
    direction = end - start
    t = np.clip(np.dot(point - start, direction) / np.dot(direction, direction), 0.0, 1.0)
    return float(np.hypot(*(start + t * direction - point)))


def on_some_line(field: Field, point: np.ndarray, tolerance: float = 1e-9) -> bool:
    if min(distance_to_segment(point, segment) for segment in field.segments) <= tolerance:
        return True
    cx, cy, radius = field.center_circle
    return abs(math.hypot(point[0] - cx, point[1] - cy) - radius) <= tolerance


def angle_difference(a, b) -> np.ndarray:
    """a − b as an angle in [−π, π], independent of the wrapping under test."""
    return np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b))))


def write(tmp_path, name: str, text: str):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def full_toml(**overrides) -> str:
    """A complete field file (SPL numbers) with some dimension values replaced verbatim."""
    values = {key: repr(value) for key, value in spl().dims.to_dict().items()}
    values.update(overrides)
    body = "\n".join(f"{key} = {value}" for key, value in values.items())
    return f'name = "lab"\n\n[dimensions]\n{body}\n'


@st.composite
def valid_dimensions(draw) -> FieldDimensions:
    """Random dimensions that satisfy every rule, built from fractions of the bounds."""
    fraction = st.floats(0.05, 0.95)
    length = draw(st.floats(3.0, 30.0))
    width = draw(st.floats(2.0, 20.0))
    penalty_area_length = draw(fraction) * length / 2.0
    penalty_area_width = draw(fraction) * width
    goal_area_length = draw(fraction) * penalty_area_length
    goal_area_width = draw(fraction) * penalty_area_width
    center_circle_diameter = draw(fraction) * min(width, length - 2.0 * penalty_area_length)
    border_strip_width = draw(st.floats(0.05, 2.0))
    goalpost_diameter = draw(fraction) * min(border_strip_width, width / 4.0)
    goal_inner_width = draw(fraction) * (width - 2.0 * goalpost_diameter)
    gaps = [
        goal_area_length,
        penalty_area_length - goal_area_length,
        length / 2.0 - penalty_area_length - center_circle_diameter / 2.0,
        (penalty_area_width - goal_area_width) / 2.0,
        (width - penalty_area_width) / 2.0,
        (width - center_circle_diameter) / 2.0,
        center_circle_diameter / 2.0,
    ]
    return FieldDimensions(
        length=length,
        width=width,
        line_width=draw(fraction) * min(gaps),
        penalty_area_length=penalty_area_length,
        penalty_area_width=penalty_area_width,
        goal_area_length=goal_area_length,
        goal_area_width=goal_area_width,
        penalty_mark_distance=draw(fraction) * length / 2.0,
        center_circle_diameter=center_circle_diameter,
        goal_inner_width=goal_inner_width,
        goalpost_diameter=goalpost_diameter,
        border_strip_width=border_strip_width,
    )


angles = st.floats(-50.0, 50.0, allow_nan=False)
coordinates = st.floats(-20.0, 20.0, allow_nan=False)


# Presets


@pytest.mark.parametrize("name", PRESETS)
def test_preset_landmark_counts(name):
    field = PRESETS[name]()
    assert set(field.landmarks) == set(LandmarkType)
    assert {kind: len(points) for kind, points in field.landmarks.items()} == EXPECTED_COUNTS
    assert field.segments.shape == (17, 2, 2)


@pytest.mark.parametrize("name", ["spl", "SPL", "KidSize", "adultsize "])
def test_preset_by_name_is_case_insensitive(name):
    field = preset(name)
    assert field is PRESETS[name.strip().lower()]()
    assert field.name == name.strip().lower()


def test_unknown_preset_lists_valid_names():
    with pytest.raises(ValueError, match="midsize") as error:
        preset("midsize")
    for name in PRESETS:
        assert name in str(error.value)


def test_preset_dimensions():
    assert (spl().dims.length, spl().dims.width, spl().dims.border_strip_width) == (9.0, 6.0, 0.7)
    assert kidsize().dims.goal_inner_width == 2.6
    assert (kidsize().dims.penalty_area_length, kidsize().dims.penalty_area_width) == (2.0, 5.0)
    assert (adultsize().dims.length, adultsize().dims.width) == (14.0, 9.0)
    assert (adultsize().dims.goal_area_length, adultsize().dims.goal_area_width) == (1.0, 4.0)
    assert adultsize().dims.center_circle_diameter == 3.0


def test_spl_coordinates():
    field = spl()
    assert (field.half_length, field.half_width) == (4.5, 3.0)
    np.testing.assert_allclose(field.landmarks_of("penalty_mark"), [[-3.2, 0.0], [3.2, 0.0]])
    np.testing.assert_allclose(field.landmarks_of("center_mark"), [[0.0, 0.0]])
    np.testing.assert_allclose(field.landmarks_of("x_crossing"), [[0.0, -0.75], [0.0, 0.75]])
    corners = as_point_set(field.landmarks_of(LandmarkType.L_CROSSING))
    for x in (-2.85, 2.85):
        for y in (-2.0, 2.0):
            assert (x, y) in corners  # penalty-area front corners
    for x in (-3.9, 3.9):
        for y in (-1.1, 1.1):
            assert (x, y) in corners  # goal-area front corners
    for x in (-4.5, 4.5):
        for y in (-3.0, 3.0):
            assert (x, y) in corners  # field corners
    tees = as_point_set(field.landmarks_of(LandmarkType.T_CROSSING))
    assert {(0.0, -3.0), (0.0, 3.0), (4.5, 2.0), (-4.5, -1.1)} <= tees
    np.testing.assert_allclose(
        field.landmarks_of(LandmarkType.GOALPOST),
        [[-4.525, -0.8], [-4.525, 0.8], [4.525, -0.8], [4.525, 0.8]],
    )
    assert field.center_circle == (0.0, 0.0, 0.75)


# Derived geometry


@pytest.mark.parametrize("name", PRESETS)
def test_landmarks_are_point_symmetric(name):
    for points in PRESETS[name]().landmarks.values():
        assert as_point_set(points) == as_point_set(-points)


@pytest.mark.parametrize("name", PRESETS)
def test_intersections_lie_on_lines(name):
    field = PRESETS[name]()
    for kind in INTERSECTION_TYPES:
        for point in field.landmarks_of(kind):
            assert on_some_line(field, point), (kind.name, point)


@pytest.mark.parametrize("name", PRESETS)
def test_landmarks_sorted_by_x_then_y(name):
    for points in PRESETS[name]().landmarks.values():
        order = np.lexsort((points[:, 1], points[:, 0]))
        assert np.array_equal(order, np.arange(len(points)))


def test_arrays_are_read_only_float64_contiguous():
    field = spl()
    arrays = [field.segments, *field.landmarks.values()]
    for array in arrays:
        assert array.dtype == np.float64
        assert array.flags.c_contiguous
        assert not array.flags.writeable
        with pytest.raises(ValueError):
            array[0, 0] = 1.0
    with pytest.raises(TypeError):
        field.landmarks[LandmarkType.GOALPOST] = np.zeros((0, 2))
    with pytest.raises(dataclasses.FrozenInstanceError):
        field.name = "other"


@pytest.mark.parametrize(
    "kind",
    [LandmarkType.T_CROSSING, 2, np.int64(2), "T_CROSSING", "t_crossing", "T_Crossing"],
)
def test_landmarks_of_accepts_enum_int_and_name(kind):
    assert spl().landmarks_of(kind) is spl().landmarks[LandmarkType.T_CROSSING]


@pytest.mark.parametrize("kind", ["corner", 6, -1, True, 2.0, None])
def test_landmarks_of_rejects_unknown_kind(kind):
    with pytest.raises(ValueError, match=re.escape(repr(kind))):
        spl().landmarks_of(kind)


ALIASES = {
    "L": LandmarkType.L_CROSSING,
    "T": LandmarkType.T_CROSSING,
    "X": LandmarkType.X_CROSSING,
    "goalpost": LandmarkType.GOALPOST,
    "post": LandmarkType.GOALPOST,
    "penalty_mark": LandmarkType.PENALTY_MARK,
    "penalty": LandmarkType.PENALTY_MARK,
    "center_mark": LandmarkType.CENTER_MARK,
    "centre_mark": LandmarkType.CENTER_MARK,
    "center": LandmarkType.CENTER_MARK,
    "centre": LandmarkType.CENTER_MARK,
    "L-crossing": LandmarkType.L_CROSSING,
    "l_crossing": LandmarkType.L_CROSSING,
    "T crossing": LandmarkType.T_CROSSING,
    "x-Crossing": LandmarkType.X_CROSSING,
    "penalty mark": LandmarkType.PENALTY_MARK,
    "Centre-Mark": LandmarkType.CENTER_MARK,
}


@pytest.mark.parametrize("name,member", ALIASES.items())
def test_parse_takes_the_common_short_names(name, member):
    assert LandmarkType.parse(name) is member
    assert spl().landmarks_of(name) is spl().landmarks[member]


def spellings(text: str) -> st.SearchStrategy[str]:
    """`text` in any case, each underscore as '_', '-' or ' ', with white space around it."""
    parts = text.split("_")
    cased = st.tuples(*(st.tuples(*(st.sampled_from([c.lower(), c.upper()]) for c in part)) for part in parts))
    separators = st.lists(st.sampled_from(["_", "-", " "]), min_size=len(parts) - 1, max_size=len(parts) - 1)
    padding = st.sampled_from(["", " ", "\t"])

    def join(drawn):
        (chars, seps), left, right = drawn
        words = ["".join(part) for part in chars]
        return left + words[0] + "".join(sep + word for sep, word in zip(seps, words[1:])) + right

    return st.tuples(st.tuples(cased, separators), padding, padding).map(join)


NAMES = [(member.name, member) for member in LandmarkType] + list(LANDMARK_TYPE_ALIASES.items())


@given(st.sampled_from(NAMES).flatmap(lambda entry: st.tuples(spellings(entry[0]), st.just(entry[1]))))
def test_names_and_aliases_parse_in_any_spelling(drawn):
    text, member = drawn
    assert LandmarkType.parse(text) is member


def test_an_unknown_name_lists_the_names_and_the_aliases():
    with pytest.raises(ValueError) as error:
        LandmarkType.parse("corner")
    message = str(error.value)
    assert "'corner'" in message
    for member in LandmarkType:
        assert member.name in message
    for alias in (
        "L (L_CROSSING)",
        "T (T_CROSSING)",
        "X (X_CROSSING)",
        "post (GOALPOST)",
        "penalty (PENALTY_MARK)",
        "center, centre, centre_mark (CENTER_MARK)",
    ):
        assert alias in message


def test_line_points_cover_every_line():
    field = spl()
    points = field.line_points(spacing=0.05)
    assert points.ndim == 2 and points.shape[1] == 2 and points.dtype == np.float64
    assert all(on_some_line(field, point) for point in points)
    # Every corner and crossing is sampled, and no two neighbours on a line are far apart.
    sampled = as_point_set(points)
    for kind in (LandmarkType.L_CROSSING, LandmarkType.T_CROSSING):
        assert as_point_set(field.landmarks_of(kind)) <= sampled
    # Any point on any line is within half a spacing (plus the circle's sagitta) of a sample.
    t = np.linspace(0.0, 1.0, 400)[:, None]
    dense = [start + t * (end - start) for start, end in field.segments]
    cx, cy, radius = field.center_circle
    angle = np.linspace(0.0, 2.0 * math.pi, 400)
    dense.append(np.column_stack((cx + radius * np.cos(angle), cy + radius * np.sin(angle))))
    nearest, _ = cKDTree(points).query(np.concatenate(dense))
    assert nearest.max() <= 0.05 / 2 + 1e-3
    assert len(field.line_points(spacing=0.5)) < len(points)


@pytest.mark.parametrize("spacing", [0.0, -0.1, math.nan, math.inf, "0.1", True])
def test_line_points_rejects_bad_spacing(spacing):
    with pytest.raises(ValueError, match="spacing"):
        spl().line_points(spacing)


def test_contains():
    field = spl()  # carpet reaches |x| <= 5.2, |y| <= 3.7
    points = np.array([[0.0, 0.0], [5.2, 3.7], [5.21, 0.0], [0.0, -3.71], [-5.0, -3.5]])
    assert field.contains(points).tolist() == [True, True, False, False, True]
    assert field.contains(points, margin=0.1).tolist() == [True, True, True, True, True]
    assert field.contains(points, margin=-0.8).tolist() == [True, False, False, False, False]
    assert field.contains([0.0, 0.0]).shape == ()
    assert field.contains(np.zeros((3, 4, 2))).shape == (3, 4)
    with pytest.raises(ValueError, match="shape"):
        field.contains(np.zeros((5, 3)))
    with pytest.raises(ValueError, match="margin"):
        field.contains(points, margin=math.nan)


@settings(max_examples=60, deadline=None)
@given(valid_dimensions())
def test_random_valid_dimensions_build_a_consistent_field(dims):
    field = Field("random", dims)
    for kind, points in field.landmarks.items():
        assert len(points) == EXPECTED_COUNTS[kind]
        assert field.contains(points).all(), kind.name
        assert (np.abs(points[:, 0]) <= field.half_length + dims.goalpost_diameter).all()
        assert (np.abs(points[:, 1]) <= field.half_width).all()
        assert as_point_set(points) == as_point_set(-points)
    for kind in INTERSECTION_TYPES:
        for point in field.landmarks_of(kind):
            assert on_some_line(field, point, tolerance=1e-9 * dims.length)
    # Every crossing is distinct: no two lines merge into one.
    crossings = np.concatenate([field.landmarks_of(kind) for kind in INTERSECTION_TYPES])
    assert len(as_point_set(crossings)) == len(crossings)


# Mirroring


@given(st.lists(st.tuples(coordinates, coordinates, angles), min_size=1, max_size=20))
def test_mirror_twice_is_identity(rows):
    poses = np.array(rows, dtype=np.float64)
    twice = Field.mirror_poses(Field.mirror_poses(poses))
    np.testing.assert_array_equal(twice[:, :2], poses[:, :2])
    np.testing.assert_allclose(angle_difference(twice[:, 2], poses[:, 2]), 0.0, atol=1e-9)


@given(st.lists(st.tuples(coordinates, coordinates, angles), min_size=1, max_size=20))
def test_mirror_negates_position_and_wraps_heading(rows):
    poses = np.array(rows, dtype=np.float64)
    mirrored = Field.mirror_poses(poses)
    assert mirrored.shape == poses.shape and mirrored.flags.c_contiguous
    np.testing.assert_array_equal(mirrored[:, :2], -poses[:, :2])
    assert ((mirrored[:, 2] > -math.pi) & (mirrored[:, 2] <= math.pi)).all()
    turned = angle_difference(mirrored[:, 2], poses[:, 2] + math.pi)
    np.testing.assert_allclose(turned, 0.0, atol=1e-9)


def test_mirror_examples():
    poses = np.array([[1.0, 2.0, 0.0], [1.0, -2.0, math.pi], [0.0, 0.0, -math.pi / 2], [0.0, 0.0, -math.pi]])
    mirrored = spl().mirror_poses(poses)
    np.testing.assert_allclose(
        mirrored,
        [[-1.0, -2.0, math.pi], [-1.0, 2.0, 0.0], [0.0, 0.0, math.pi / 2], [0.0, 0.0, 0.0]],
        atol=1e-15,
    )
    assert poses[0, 0] == 1.0  # input untouched
    with pytest.raises(ValueError, match="shape"):
        Field.mirror_poses(np.zeros((4, 2)))


# Files


@pytest.mark.parametrize("name", PRESETS)
@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_round_trip_through_file(tmp_path, name, suffix):
    field = PRESETS[name]()
    path = tmp_path / f"copy{suffix}"
    save_field(field, path)
    loaded = load_field(path)
    assert loaded == field
    assert loaded.to_dict() == field.to_dict()


def test_round_trip_by_hand_through_to_dict(tmp_path):
    field = kidsize()
    path = write(tmp_path, "lab.json", json.dumps(field.to_dict()))
    assert load_field(path) == field


@settings(max_examples=30, deadline=None)
@given(
    dims=valid_dimensions(),
    name=st.text(st.characters(exclude_categories=("Cs",)), min_size=1).filter(str.strip),
)
def test_random_fields_round_trip_through_toml_and_json(tmp_path_factory, dims, name):
    field = Field(name, dims)
    directory = tmp_path_factory.mktemp("round_trip")
    for suffix in (".toml", ".json"):
        path = directory / f"field{suffix}"
        save_field(field, path)
        assert load_field(path) == field


def test_preset_with_overrides(tmp_path):
    path = write(tmp_path, "lab.toml", 'preset = "SPL"\n[dimensions]\nlength = 7.5\nwidth = 5\n')
    field = load_field(path)
    assert field.name == "spl"
    assert (field.dims.length, field.dims.width) == (7.5, 5.0)
    assert isinstance(field.dims.width, float)
    assert field.dims.penalty_area_length == spl().dims.penalty_area_length
    named = load_field(write(tmp_path, "named.json", '{"name": "hall", "preset": "kidsize"}'))
    assert named == Field("hall", kidsize().dims)


def test_name_defaults_to_file_stem(tmp_path):
    text = full_toml().replace('name = "lab"\n', "")
    assert load_field(write(tmp_path, "robot_lab.toml", text)).name == "robot_lab"


def test_string_path_accepted(tmp_path):
    path = write(tmp_path, "lab.toml", full_toml())
    assert load_field(str(path)).dims == spl().dims


@pytest.mark.parametrize(
    ("filename", "text", "fragments"),
    [
        ("lab.toml", full_toml(length='"nine"'), ["length", "nine"]),
        ("lab.toml", full_toml(width="true"), ["width", "True"]),
        ("lab.toml", full_toml(line_width="[0.05]"), ["line_width", "0.05"]),
        ("lab.toml", full_toml(length="-9.0"), ["length", "-9.0"]),
        ("lab.toml", full_toml(line_width="0"), ["line_width", "0"]),
        ("lab.toml", full_toml(length="inf"), ["length", "inf"]),
        ("lab.toml", full_toml(length="nan"), ["length", "nan"]),
        ("lab.toml", full_toml(penalty_area_width="7.0"), ["penalty_area_width", "7.0", "width"]),
        ("lab.toml", full_toml(penalty_area_length="5.0"), ["penalty_area_length", "5.0"]),
        ("lab.toml", full_toml(goal_area_length="2.0"), ["goal_area_length", "2.0"]),
        ("lab.toml", full_toml(goal_area_width="4.5"), ["goal_area_width", "4.5"]),
        ("lab.toml", full_toml(penalty_mark_distance="4.5"), ["penalty_mark_distance", "4.5"]),
        ("lab.toml", full_toml(center_circle_diameter="6.5"), ["center_circle_diameter", "6.5"]),
        ("lab.toml", full_toml(center_circle_diameter="5.8"), ["center_circle_diameter", "5.8"]),
        ("lab.toml", full_toml(goal_inner_width="6.0"), ["goal_inner_width", "6.0"]),
        ("lab.toml", full_toml(line_width="0.7"), ["line_width", "0.7"]),
        ("lab.toml", full_toml(goalpost_diameter="0.8"), ["goalpost_diameter", "0.8"]),
        ("lab.toml", full_toml() + "lenght = 9.0\n", ["lenght", "9.0", "length"]),
        ("lab.toml", "lenght = 9.0\n" + full_toml(), ["lenght", "9.0", "length"]),
        ("lab.toml", full_toml().replace("goal_area_width = 2.2\n", ""), ["goal_area_width"]),
        ("lab.toml", 'name = "lab"\nlength = 9.0\n', ["length", "9.0", "dimensions"]),
        ("lab.toml", 'preset = "midsize"\n', ["preset", "midsize", "spl"]),
        ("lab.toml", "preset = 3\n", ["preset", "3"]),
        ("lab.toml", "name = 3\n[dimensions]\n", ["name", "3"]),
        ("lab.toml", 'preset = "spl"\ndimensions = 9\n', ["dimensions", "9"]),
        ("lab.toml", "length = = 9\n", ["not valid TOML", "line 1"]),
        ("lab.json", '{"preset": "spl", "dimensions": {"x": 9,}}', ["not valid JSON", "line 1"]),
        ("lab.json", "[1, 2]", ["top level", "list"]),
        ("lab.json", '{"preset": "spl", "dimensions": {"width": NaN}}', ["width", "nan"]),
        ("lab.json", '{"preset": "spl", "dimensions": {"width": 1e999}}', ["width", "inf"]),
        (
            "lab.json",
            '{"preset": "spl", "dimensions": {"width": 1%s}}' % ("0" * 400),
            ["width", "1000"],
        ),
        ("lab.json", '{"preset": "spl", "dimensions": {"width": null}}', ["width", "None"]),
    ],
)
def test_bad_files_raise_value_error_naming_key_and_value(tmp_path, filename, text, fragments):
    path = write(tmp_path, filename, text)
    with pytest.raises(ValueError) as error:
        load_field(path)
    message = str(error.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, (fragment, message)


def test_missing_file(tmp_path):
    path = tmp_path / "absent.toml"
    with pytest.raises(ValueError, match="does not exist") as error:
        load_field(path)
    assert str(path) in str(error.value)


@pytest.mark.parametrize("filename", ["lab.yaml", "lab", "lab.txt"])
def test_unknown_extension(tmp_path, filename):
    path = write(tmp_path, filename, full_toml())
    with pytest.raises(ValueError, match="extension") as error:
        load_field(path)
    assert str(path) in str(error.value)
    with pytest.raises(ValueError, match="extension"):
        save_field(spl(), tmp_path / filename)


def test_to_toml_escapes_names():
    text = to_toml(Field('a "quoted"\\name\x7f\n', spl().dims))
    assert 'name = "a \\"quoted\\"\\\\name\\u007f\\u000a"' in text


# FieldDimensions directly


def test_dimensions_accept_ints_and_store_floats():
    values = spl().dims.to_dict()
    values.update(length=9, width=6)
    dims = FieldDimensions(**values)
    assert isinstance(dims.length, float) and dims == spl().dims


def test_dimensions_error_message_format():
    with pytest.raises(ValueError) as error:
        dataclasses.replace(spl().dims, penalty_area_width=7.0)
    assert str(error.value) == "penalty_area_width = 7.0 must be smaller than width = 6.0"


@pytest.mark.parametrize("key", FieldDimensions.keys())
@pytest.mark.parametrize("value", [0.0, -1.0, math.inf, math.nan, False, "1.0", None])
def test_dimensions_reject_non_positive_and_non_numbers(key, value):
    with pytest.raises(ValueError, match=key):
        dataclasses.replace(spl().dims, **{key: value})


def test_field_rejects_bad_name_and_dims():
    with pytest.raises(ValueError, match="name"):
        Field("", spl().dims)
    with pytest.raises(ValueError, match="dims"):
        Field("lab", spl().dims.to_dict())


def test_field_pickles_and_copies():
    field = adultsize()
    for clone in (pickle.loads(pickle.dumps(field)), copy.deepcopy(field)):
        assert clone == field
        assert np.array_equal(clone.segments, field.segments)
        assert not clone.landmarks_of("goalpost").flags.writeable


def test_field_equality_and_hash():
    assert Field("spl", spl().dims) == spl()
    assert hash(Field("spl", spl().dims)) == hash(spl())
    assert Field("other", spl().dims) != spl()
