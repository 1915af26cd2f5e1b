"""Hostile robot logs: whatever a file holds, `read_log` (and `list_topics`) answer with a usable `RobotLog` or a
`ValueError` naming the file -- never another exception, a hang, or an allocation the file's bytes do not pay for.

Small valid logs of each form (ROS 2 MCAP compressed and not, NPZ stored and compressed, a folder of CSV files)
are corrupted: bit flips and cuts at deterministic offsets and at offsets hypothesis draws; then CSV folders,
NPZ arrays and MCAP messages with hostile contents written on purpose, and arguments of the wrong type.
"""

import functools
import io
import math
import struct
import tempfile
import time
import tracemalloc
import zipfile
from pathlib import Path
from unittest import mock

import lz4.frame
import numpy as np
import pytest
import zstandard
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.records import Chunk, Schema
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_ros2.writer import Writer as Ros2Writer

from mcl.tools.logs import LogError, RobotLog, VisionFrame, mcap_io, read_log, schemas
from mcl.tools.logs.cdr import MAX_NESTING, DecoderFactory, compile_decoders
from mcl.tools.logs.columnar import write_csv, write_npz
from mcl.tools.logs.mcap_io import _DECODE_ERRORS, Topics, list_topics, read_mcap, write_mcap
from mcl.tools.logs.robot_log import MAX_TIME
from sensing.observations import Observations

ORIGIN_NS = 1_700_000_000_000_000_000
SECOND = 1_000_000_000
SMALL_ALLOCATION = 32 << 20  # [bytes] the most a hostile file of a few kB may make a reader allocate


def small_log() -> RobotLog:
    """Every stream, a few rows each, on the nanosecond grid; two camera frames."""
    t = np.arange(4) * 0.1
    rng = np.random.default_rng(5)
    seen = Observations.from_arrays(
        ["goalpost", "t_crossing", "penalty_mark"],
        [1.0, 2.5, 3.0],
        [0.1, -0.2, 0.4],
        line_points=[[1.0, 2.0], [3.0, 4.0]],
    )
    return RobotLog(
        origin_ns=ORIGIN_NS,
        odometry_times=t,
        odometry=rng.uniform(-1, 1, (4, 3)),
        command_times=t,
        commands=rng.uniform(-1, 1, (4, 3)),
        imu_times=t,
        gyro=rng.uniform(-1, 1, (4, 3)),
        acceleration=rng.uniform(-1, 1, (4, 3)),
        joint_names=("HeadYaw", "HeadPitch"),
        joint_command_times=t,
        joint_commands=rng.uniform(-1, 1, (4, 2)),
        joint_reading_times=t,
        joint_readings=rng.uniform(-1, 1, (4, 2)),
        truth_times=t,
        truth=rng.uniform(-1, 1, (4, 3)),
        vision=(VisionFrame(0.0, 0.02, seen), VisionFrame(0.15, 0.17, Observations.empty())),
    )


def write_plain_mcap(log: RobotLog, path: Path) -> None:
    """`write_mcap` without compression, in small chunks: flipped bits land in the records and messages."""
    plain = functools.partial(Ros2Writer, compression=CompressionType.NONE)
    with mock.patch.object(mcap_io, "Ros2Writer", plain):
        write_mcap(log, path, chunk_size=600)


def assert_usable(log: RobotLog) -> None:
    """What every reader promises of the log it returns."""
    assert isinstance(log, RobotLog) and isinstance(log.origin_ns, int)
    for times_name, values_name, _ in log.STREAMS + (
        ("joint_command_times", "joint_commands", 0),
        ("joint_reading_times", "joint_readings", 0),
    ):
        times, values = getattr(log, times_name), getattr(log, values_name)
        assert times.dtype == np.float64 and values.dtype == np.float64
        assert np.isfinite(times).all() and np.isfinite(values).all()
        assert (np.diff(times) > 0).all() and np.abs(times).max(initial=0) <= MAX_TIME
        assert values.shape[0] == times.shape[0]
    assert math.isfinite(log.duration)
    for frame in log.vision:
        assert math.isfinite(frame.stamp) and math.isfinite(frame.received)


def outcome(read, path, label: str = ""):
    """read(path): a usable log (or topic table), else a ValueError naming the file. Anything else fails."""
    try:
        result = read(path)
    except ValueError as error:
        assert str(path) in str(error), f"{label}: the error does not name the file: {error}"
        return error
    except Exception as error:  # the failure this file is about: say which input did it
        raise AssertionError(f"{label}: {type(error).__name__} escaped: {error}") from error
    if read is list_topics:
        for row in result:
            assert isinstance(row["count"], int) and row["count"] >= 0, (label, row)
    else:
        log, report = result
        assert_usable(log)
        report.summary()
        report.to_json()
    return result


def flips(data: bytes, count: int):
    """About `count` copies of `data`, each with one byte changed (three masks in turn), spread evenly."""
    step = max(1, len(data) // count)
    for i, offset in enumerate(range(0, len(data), step)):
        mask = (0x01, 0x80, 0xFF)[i % 3]
        yield f"byte {offset} ^ {mask:#04x}", data[:offset] + bytes([data[offset] ^ mask]) + data[offset + 1 :]


def cuts(data: bytes, count: int):
    step = max(1, len(data) // count)
    for offset in range(0, len(data), step):
        yield f"cut at {offset}", data[:offset]


def peak_allocation(function) -> int:
    """The most memory Python and numpy held at once while `function()` ran [bytes]."""
    tracemalloc.start()
    try:
        function()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak


# -- fixtures: the valid logs, as bytes --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("hostile")


@pytest.fixture(scope="module")
def valid_files(workdir):
    """name -> bytes of the small log in each file form (each checked to read back first)."""
    log = small_log()
    write_plain_mcap(log, workdir / "plain.mcap")
    write_mcap(log, workdir / "zstd.mcap", chunk_size=600)
    write_npz(log, workdir / "stored.npz")
    with np.load(workdir / "stored.npz") as archive:
        arrays = {key: archive[key] for key in archive.files}
    with open(workdir / "deflated.npz", "wb") as file:
        np.savez_compressed(file, **arrays)
    files = {}
    for name in ("plain.mcap", "zstd.mcap", "stored.npz", "deflated.npz"):
        back, report = read_log(workdir / name)
        assert report.complete and not report.dropped
        np.testing.assert_allclose(back.odometry_times, log.odometry_times, atol=1e-9)
        files[name] = (workdir / name).read_bytes()
    return files


# Deterministic variants: (file form, flips, cuts). The plain MCAP gets the most: its flips reach the CDR bytes.
VARIANTS = (("plain.mcap", 260, 50), ("zstd.mcap", 80, 30), ("stored.npz", 200, 40), ("deflated.npz", 80, 30))


@pytest.mark.parametrize("name, n_flips, n_cuts", VARIANTS, ids=[v[0] for v in VARIANTS])
def test_flipped_and_cut_files_read_or_raise_value_error(valid_files, workdir, name, n_flips, n_cuts):
    data = valid_files[name]
    path = workdir / f"broken{Path(name).suffix}"
    readers = (read_log, list_topics) if name.endswith(".mcap") else (read_log,)
    count = 0
    for label, broken in list(flips(data, n_flips)) + list(cuts(data, n_cuts)):
        path.write_bytes(broken)
        for read in readers:
            outcome(read, path, f"{name}, {label}, {read.__name__}")
            count += 1
    assert count >= n_flips + n_cuts


@st.composite
def damage(draw, size: int):
    """1 to 4 bytes set to drawn values, then maybe a cut."""
    edits = draw(st.lists(st.tuples(st.integers(0, size - 1), st.integers(0, 255)), min_size=1, max_size=4))
    cut = draw(st.one_of(st.none(), st.integers(0, size)))
    return edits, cut


def damaged(data: bytes, edits, cut) -> bytes:
    changed = bytearray(data)
    for offset, value in edits:
        changed[offset] = value
    return bytes(changed[:cut] if cut is not None else changed)


@pytest.mark.parametrize("name", ["plain.mcap", "stored.npz"])
@settings(max_examples=80)
@given(data=st.data())
def test_bytes_changed_where_hypothesis_chooses(valid_files, workdir, name, data):
    original = valid_files[name]
    edits, cut = data.draw(damage(len(original)))
    path = workdir / f"drawn{Path(name).suffix}"
    path.write_bytes(damaged(original, edits, cut))
    for read in (read_log, list_topics) if name.endswith(".mcap") else (read_log,):
        outcome(read, path, f"{name}, edits {edits}, cut {cut}")


# -- CSV folders with hostile contents -------------------------------------------------------------------------
ODOMETRY_HEADER = b"t_s,x_m,y_m,yaw_rad\n"
LANDMARK_HEADER = b"stamp_s,received_s,kind,range_m,bearing_rad,range_sigma_m,bearing_sigma_rad\n"
META = b"key,value\nformat_version,1\n"
# (file, content, expected): "log" must read, "error" must raise, None either (it depends on what
# `Observations` accepts as a detection).
CSV_CASES = [
    ("odometry.csv", b"", "error"),
    ("odometry.csv", b"\n\n\n", "error"),
    ("odometry.csv", b"0.0,1,2,3\n0.1,1,2,3\n", "error"),  # no header row
    ("odometry.csv", b",,,\n", "error"),
    ("odometry.csv", b"t_s,t_s,x_m,y_m,yaw_rad\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER, "log"),
    ("odometry.csv", ODOMETRY_HEADER + b"0.0,abc,2,3\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER + b"0.0,,2,3\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER + b"0.0,0x10,2,3\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER + b"nan,1,2,3\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER + b"0.0,NaN,2,3\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER + b"0.0,-inf,2,3\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER + b"infinity,1,2,3\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER + b"0.0,1e308,-1e308,3\n0.1,1e308,1e308,3\n", "log"),  # huge, but finite
    ("odometry.csv", ODOMETRY_HEADER + b"0.0,1e400,2,3\n", "error"),  # inf
    ("odometry.csv", ODOMETRY_HEADER + b"0.0,1e-400,2,3\n", "log"),  # 0.0
    ("odometry.csv", ODOMETRY_HEADER + b"1e308,1,2,3\n", "error"),  # beyond MAX_TIME
    ("odometry.csv", ODOMETRY_HEADER + b"-1e308,1,2,3\n1e308,1,2,3\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER + b"-5,1,2,3\n-4.5,1,2,3\n", "log"),  # before the origin: fine
    ("odometry.csv", ODOMETRY_HEADER + b"1,1,2,3\n0,1,2,3\n", "error"),  # decreasing
    ("odometry.csv", ODOMETRY_HEADER + b"1,1,2,3\n1,1,2,3\n", "error"),  # repeated
    ("odometry.csv", ODOMETRY_HEADER + b"0,1,2\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER + b"0,1,2,3,4\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER + b"0," + b"1" * 200_000 + b",2,3\n", "error"),  # beyond csv's field limit
    ("odometry.csv", ODOMETRY_HEADER + b",".join([b"1"] * 100_000) + b"\n", "error"),  # a very long line
    ("odometry.csv", ODOMETRY_HEADER + b"0," + b"9" * 5000 + b",2,3\n", "error"),  # 1e5000: inf
    ("odometry.csv", ODOMETRY_HEADER + b"0,\xff\xfe,2,3\n", "error"),  # not UTF-8
    ("odometry.csv", b"\xef\xbb\xbf" + ODOMETRY_HEADER + b"0,1,2,3\n", "error"),  # a byte order mark
    ("odometry.csv", ODOMETRY_HEADER + b"0,1\x00,2,3\n", "error"),
    ("odometry.csv", ODOMETRY_HEADER + b'0,"1\n2",2,3\n', "error"),
    ("odometry.csv", ODOMETRY_HEADER + b'0,"1,2,3\n', "error"),  # a quote never closed
    ("imu.csv", b"t_s\n", "error"),
    ("joint_readings.csv", b"t_s," + b",".join(b"j%d_rad" % i for i in range(3000)) + b"\n", "error"),
    ("joint_readings.csv", b"t_s,_rad\n", "error"),
    ("joint_readings.csv", b"t_s,HeadYaw_rad,HeadYaw_rad\n", "error"),
    ("meta.csv", b"", "error"),
    ("meta.csv", b"key,value\n", "error"),
    ("meta.csv", META + b"origin_ns," + b"9" * 30 + b"\n", "error"),  # beyond int64
    ("meta.csv", META + b"origin_ns,-" + b"9" * 30 + b"\n", "error"),
    ("meta.csv", META + b"origin_ns," + b"9" * 5000 + b"\n", "error"),  # beyond Python's int parsing
    ("meta.csv", META + b"origin_ns,9223372036854775807\n", "log"),
    ("meta.csv", b"key,value\nformat_version," + b"9" * 100 + b"\norigin_ns,0\n", "error"),
    ("meta.csv", META + b"origin_ns,1e18\n", "error"),
    ("meta.csv", META + b"origin_ns,nan\n", "error"),
    ("meta.csv", META + b"format_version,1\norigin_ns,0\n", "error"),
    ("meta.csv", b"key,value,extra\n", "error"),
    ("meta.csv", b"\xff\xfe\x00k\x00", "error"),
    ("vision_frames.csv", b"stamp_s,received_s\n0.0,0.02\n0.15,1e308\n", "error"),
    ("vision_frames.csv", b"stamp_s,received_s\nnan,0.02\n", "error"),
    ("vision_landmarks.csv", LANDMARK_HEADER + b"0.0,0.02,GOALPOST,1e308,0,,\n", None),
    ("vision_landmarks.csv", LANDMARK_HEADER + b"0.0,0.02,GOALPOST,1,1e300,,\n", None),
    ("vision_landmarks.csv", LANDMARK_HEADER + b"0.0,0.02," + b"9" * 5000 + b",1,0,,\n", "error"),
    ("vision_landmarks.csv", LANDMARK_HEADER + b"0.0,0.02,GOALPOST,1,0,-1,\n", "error"),
    ("vision_landmarks.csv", LANDMARK_HEADER + b"0.0,0.02,GOALPOST,1,0,1e-300,\n", None),
    ("vision_lines.csv", b"stamp_s,received_s,x_m,y_m\n0.0,0.02,1e308,0\n", None),
    ("vision_lines.csv", b"stamp_s,received_s,x_m,y_m\n0.0,0.02,inf,0\n", "error"),
]


@pytest.mark.parametrize("file, content, expected", CSV_CASES, ids=[f"{i}-{c[0]}" for i, c in enumerate(CSV_CASES)])
def test_hostile_csv_contents(tmp_path, file, content, expected):
    folder = tmp_path / "log"
    write_csv(small_log(), folder)
    (folder / file).write_bytes(content)
    result = outcome(read_log, folder, f"{file}: {content[:60]!r}")
    if expected == "error":
        assert isinstance(result, ValueError), f"{file}: {content[:60]!r} was read"
        assert isinstance(result, LogError)
    elif expected == "log":
        assert not isinstance(result, ValueError), result


# -- NPZ arrays with hostile contents ---------------------------------------------------------------------------
@functools.lru_cache(maxsize=1)
def npz_bytes() -> bytes:
    """The small log as `write_npz` writes it."""
    with tempfile.TemporaryDirectory() as folder:
        write_npz(small_log(), Path(folder) / "log.npz")
        return (Path(folder) / "log.npz").read_bytes()


def npz_arrays() -> dict[str, np.ndarray]:
    with np.load(io.BytesIO(npz_bytes())) as archive:
        return {key: archive[key] for key in archive.files}


def write_arrays(path: Path, arrays: dict) -> None:
    with open(path, "wb") as file:
        np.savez(file, **arrays)


NPZ_CASES = {
    "strings": dict(odometry=np.array([["a", "b", "c"]] * 4)),
    "bytes": dict(odometry=np.array([[b"a", b"b", b"c"]] * 4)),
    "objects": dict(odometry=np.array([[None] * 3] * 4, dtype=object)),
    "complex": dict(odometry=np.zeros((4, 3), dtype=complex)),
    "booleans": dict(odometry=np.zeros((4, 3), dtype=bool)),
    "datetimes": dict(odometry_times=np.arange(4).astype("datetime64[s]")),
    "structured": dict(odometry=np.zeros((4, 3), dtype=[("a", "<f8")])),
    "float16": dict(odometry=np.zeros((4, 3), dtype=np.float16)),
    "big-endian": dict(odometry=np.zeros((4, 3), dtype=">f8")),
    "fortran order": dict(odometry=np.asfortranarray(np.arange(12.0).reshape(4, 3))),
    "flat values": dict(odometry=np.zeros(12)),
    "3-d values": dict(odometry=np.zeros((4, 3, 1))),
    "2-d times": dict(odometry_times=np.arange(4.0).reshape(4, 1)),
    "version as an array": dict(format_version=np.array([1])),
    "version as text": dict(format_version=np.array("1")),
    "origin beyond int64": dict(origin_ns=np.uint64(2**64 - 1)),
    "origin NaN": dict(origin_ns=np.float64(np.nan)),
    "NaN time": dict(odometry_times=np.array([0.0, np.nan, 0.2, 0.3])),
    "infinite time": dict(odometry_times=np.array([0.0, np.inf, 0.2, 0.3])),
    "times beyond MAX_TIME": dict(odometry_times=np.array([0.0, 1e300, 2e300, 3e300])),
    "NaN value": dict(gyro=np.array([[0.0, np.nan, 0.0]] * 4)),
    "a stream without its times": dict(truth_times=None),
    "NaN frame stamp": dict(vision_stamps=np.array([np.nan, 0.15])),
    "huge frame time": dict(vision_received=np.array([0.02, 1e300])),
    "huge landmark count": dict(vision_landmark_counts=np.array([2**62, 2**62])),
    "landmark count beyond int64": dict(vision_landmark_counts=np.array([2**64 - 1, 4], dtype=np.uint64)),
    "negative landmark count": dict(vision_landmark_counts=np.array([-1, 4])),
    "huge range": dict(vision_ranges=np.array([1e308, 2.5, 3.0])),
    "joint names not UTF-8": dict(joint_names=np.array([b"\xff\xfe", b"a"])),
    "joint names 2-d": dict(joint_names=np.array([["a", "b"]])),
    "joint names numbers": dict(joint_names=np.array([1.5, 2.5])),
    "a key of no stream": dict(notes=np.array(["anything"])),
}


@pytest.mark.parametrize("case", list(NPZ_CASES))
def test_hostile_npz_arrays(tmp_path, case):
    arrays = npz_arrays()
    for key, value in NPZ_CASES[case].items():
        if value is None:
            del arrays[key]
        else:
            arrays[key] = value
    write_arrays(tmp_path / "log.npz", arrays)
    outcome(read_log, tmp_path / "log.npz", case)


def npy(header: str, data: bytes = b"", version: int = 1) -> bytes:
    """A .npy member with a header of our own (shape and dtype claims need not fit the data)."""
    text = header.encode("latin1")
    prefix = 10 if version == 1 else 12
    text += b" " * ((-(prefix + len(text) + 1)) % 64) + b"\n"
    length = struct.pack("<H", len(text)) if version == 1 else struct.pack("<I", len(text))
    return b"\x93NUMPY" + bytes([version, 0]) + length + text + data


def write_members(path: Path, members: dict[str, bytes], compression=zipfile.ZIP_STORED) -> None:
    """An NPZ of the small log's arrays with some members replaced by raw bytes."""
    with zipfile.ZipFile(io.BytesIO(npz_bytes())) as valid, zipfile.ZipFile(path, "w", compression) as archive:
        for info in valid.infolist():
            key = info.filename.removesuffix(".npy")
            if key not in members:
                archive.writestr(info.filename, valid.read(info))
        for key, data in members.items():
            archive.writestr(f"{key}.npy", data)


def f8(shape) -> str:
    return f"{{'descr': '<f8', 'fortran_order': False, 'shape': {shape}, }}"


ABSURD_MEMBERS = {
    "times of 2^40 rows": {"odometry_times": npy(f8("(1099511627776,)"), b"\x00" * 32)},
    "values of 2^62 x 2^62": {"odometry": npy(f8("(4611686018427387904, 4611686018427387904)"), b"\x00" * 96)},
    "a negative length": {"odometry_times": npy(f8("(-4,)"), b"\x00" * 32)},
    "a length one short of the data": {"odometry_times": npy(f8("(5,)"), b"\x00" * 32)},
    "2^40 empty strings": {"joint_names": npy("{'descr': '<U0', 'fortran_order': False, 'shape': (1099511627776,), }")},
    "2^40 objects": {"joint_names": npy("{'descr': '|O', 'fortran_order': False, 'shape': (1099511627776,), }")},
    "a header that is a list": {"odometry_times": npy("[1, 2, 3]", b"\x00" * 32)},
    "a header without shape": {"odometry_times": npy("{'descr': '<f8', 'fortran_order': False, }", b"\x00" * 32)},
    "a huge version 2 header": {"odometry_times": b"\x93NUMPY\x02\x00" + struct.pack("<I", 2**31) + b"{" * 64},
    "version 9": {"odometry_times": b"\x93NUMPY\x09\x00" + b"\x00" * 64},
    "not a .npy": {"odometry_times": b"just some bytes, no magic"},
    "joint names beyond Unicode": {
        "joint_names": npy(
            "{'descr': '<U1', 'fortran_order': False, 'shape': (2,), }", b"a\x00\x00\x00\xff\xff\xff\xff"
        )
    },
    "joint names of surrogates": {
        "joint_names": npy("{'descr': '>U1', 'fortran_order': False, 'shape': (1,), }", b"\x00\x00\xd8\x00")
    },
    "empty member": {"origin_ns": b""},
}


@pytest.mark.parametrize("case", list(ABSURD_MEMBERS))
def test_npz_headers_claiming_absurd_sizes_are_refused_before_allocating(tmp_path, case):
    path = tmp_path / "log.npz"
    write_members(path, ABSURD_MEMBERS[case])
    peak = peak_allocation(lambda: outcome(read_log, path, case))
    assert peak < SMALL_ALLOCATION, f"{case}: {peak / 1e6:.0f} MB"
    assert isinstance(outcome(read_log, path, case), LogError)


def patch_central_directory(data: bytes, field_offset: int, value: int, size: int = 4) -> bytes:
    """`data` (a zip) with one field of every central-directory entry set to `value`."""
    changed = bytearray(data)
    start = 0
    while (start := changed.find(b"PK\x01\x02", start)) >= 0:
        changed[start + field_offset : start + field_offset + size] = value.to_bytes(size, "little")
        start += 4
    return bytes(changed)


@pytest.mark.parametrize(
    "case, field_offset, value",
    [
        ("uncompressed size of 4 GB", 24, 2**32 - 1),
        ("compressed size of 4 GB", 20, 2**32 - 1),
        ("encrypted", 8, 0x0001),
        ("compressed patched data", 8, 0x0020),
        ("bzip2", 10, zipfile.ZIP_BZIP2),
        ("an unknown compression", 10, 99),
        ("a zip version from the future", 6, 0x00FF),
    ],
    ids=lambda value: value if isinstance(value, str) else "",
)
def test_npz_zip_entries_claiming_what_they_are_not(tmp_path, case, field_offset, value):
    path = tmp_path / "log.npz"
    path.write_bytes(patch_central_directory(npz_bytes(), field_offset, value, 2 if field_offset < 20 else 4))
    peak = peak_allocation(lambda: outcome(read_log, path, case))
    assert peak < SMALL_ALLOCATION, f"{case}: {peak / 1e6:.0f} MB"
    assert isinstance(outcome(read_log, path, case), LogError)


def test_compressed_npz_members_read_as_stored_ones(tmp_path):
    write_members(tmp_path / "stored.npz", {})
    write_members(tmp_path / "deflated.npz", {}, zipfile.ZIP_DEFLATED)
    stored, deflated = read_log(tmp_path / "stored.npz")[0], read_log(tmp_path / "deflated.npz")[0]
    for name in ("odometry_times", "odometry", "joint_readings", "truth"):
        np.testing.assert_array_equal(getattr(stored, name), getattr(deflated, name))
    assert stored.joint_names == deflated.joint_names == ("HeadYaw", "HeadPitch")


# -- MCAP messages with hostile contents ------------------------------------------------------------------------
def header(sec: int, nanosec: int = 0) -> dict:
    return {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": "odom"}


def odometry_message(sec: int, nanosec: int = 0, x: float = 0.0) -> dict:
    return {"header": header(sec, nanosec), "pose": {"pose": {"position": {"x": x, "y": 0.0, "z": 0.0}}}}


def write_messages(path: Path, messages, definitions: dict | None = None, metadata: dict | None = None) -> None:
    """(topic, type, message dict, log time) with mcap_ros2's writer; `definitions` replaces a type's schema
    text (a file may define a type as it likes); `metadata` is written as robocup_mcl.origin."""
    registered = {}
    with open(path, "wb") as file:
        writer = Ros2Writer(file, compression=CompressionType.NONE)
        if metadata is not None:
            writer.add_metadata(mcap_io.ORIGIN_METADATA, metadata)
        for topic, type_name, message, log_ns in messages:
            if type_name not in registered:
                text = (definitions or {}).get(type_name) or schemas.definition(type_name)
                registered[type_name] = writer.register_msgdef(type_name, text)
            writer.write_message(topic, registered[type_name], message, log_time=log_ns, publish_time=log_ns)
        writer.finish()


def write_cdr(path: Path, topic: str, type_name: str, text: str, payloads: list[bytes]) -> None:
    """Messages of raw CDR bytes (they need not fit the schema) on one topic, 1 ms apart."""
    with open(path, "wb") as file:
        writer = McapWriter(file, compression=CompressionType.NONE)
        writer.start("ros2", "test")
        schema = writer.register_schema(type_name, "ros2msg", text.encode())
        channel = writer.register_channel(topic, "cdr", schema)
        for i, payload in enumerate(payloads):
            writer.add_message(channel, ORIGIN_NS + i * 1_000_000, payload, ORIGIN_NS + i * 1_000_000)
        writer.finish()


LITTLE_ENDIAN = b"\x00\x01\x00\x00"


def joint_state_cdr(tail, frame_id_length: int = 1, order: str = "<") -> bytes:
    """A sensor_msgs/JointState in byte order `order`: its header (an empty frame_id unless its length is given),
    then `tail(order)`, from the name sequence's length on."""
    kind = b"\x00\x01\x00\x00" if order == "<" else b"\x00\x00\x00\x00"
    frame_id = b"\x00" * 4 if frame_id_length == 1 else b""
    return kind + struct.pack(f"{order}iII", 1, 0, frame_id_length) + frame_id + tail(order)


def strings(order: str, *texts: bytes) -> bytes:
    return b"".join(struct.pack(f"{order}I", len(t) + 1) + t + b"\x00" * (4 - len(t) % 4) for t in texts)


HUGE_SEQUENCES = {  # (tail, frame_id length)
    "2^31 names": (lambda e: struct.pack(f"{e}I", 2**31) + strings(e, b"abcd", b"ef", b"g"), 1),
    "2^32 - 1 names": (lambda e: struct.pack(f"{e}I", 2**32 - 1), 1),
    "2^31 positions": (lambda e: struct.pack(f"{e}II", 0, 2**31) + b"\x00" * 64, 1),
    "2^32 - 1 efforts": (lambda e: struct.pack(f"{e}IIII", 0, 0, 0, 2**32 - 1) + b"\x00" * 64, 1),
    "a frame_id of 2^31 bytes": (lambda e: b"abc" * 10, 2**31),
    "a name of 2^31 bytes": (lambda e: struct.pack(f"{e}II", 1, 2**31) + b"abc" * 10, 1),
}


@pytest.mark.parametrize("case", list(HUGE_SEQUENCES))
def test_cdr_lengths_claiming_huge_sequences_do_not_allocate(tmp_path, case):
    tail, frame_id_length = HUGE_SEQUENCES[case]
    little, big = (joint_state_cdr(tail, frame_id_length, order) for order in "<>")
    text = schemas.definition(schemas.JOINT_STATE)
    schema = Schema(id=1, name=schemas.JOINT_STATE, encoding="ros2msg", data=text.encode())
    compiled = compile_decoders(schemas.JOINT_STATE, text)[schemas.JOINT_STATE]
    factory = DecoderFactory().decoder_for("cdr", schema)
    for name, decode, data in (
        ("compiled", compiled, little),
        ("factory", factory, little),
        ("mcap_ros2, big-endian", factory, big),
    ):

        def attempt():
            with pytest.raises(_DECODE_ERRORS):
                decode(data)

        started = time.perf_counter()
        peak = peak_allocation(attempt)
        assert peak < SMALL_ALLOCATION, f"{case}, {name}: {peak / 1e6:.0f} MB"
        assert time.perf_counter() - started < 2.0, f"{case}, {name}"
    write_cdr(tmp_path / "j.mcap", "/joint_states", schemas.JOINT_STATE, text, [little, big])
    log, report = outcome(read_log, tmp_path / "j.mcap", case)
    assert log.joint_reading_times.shape == (0,)
    assert report.dropped_total == 2 and all(reason.startswith("cannot decode") for _, reason in report.dropped)


def test_a_string_longer_than_the_message_is_a_decode_error():
    """mcap_ros2 cuts such a string short and reads on; the compiled decoders refuse it."""
    text = schemas.definition(schemas.JOINT_STATE)
    decode = compile_decoders(schemas.JOINT_STATE, text)[schemas.JOINT_STATE]
    with pytest.raises(ValueError, match="a string of 100 bytes"):
        decode(joint_state_cdr(lambda e: b"abc", frame_id_length=100))
    with pytest.raises(ValueError, match="a string of 9 bytes"):
        decode(joint_state_cdr(lambda e: struct.pack("<II", 1, 9) + b"abc"))
    uint8s = compile_decoders("test_msgs/msg/Bytes", "uint8[] data\n")["test_msgs/msg/Bytes"]
    assert uint8s(LITTLE_ENDIAN + struct.pack("<I", 3) + b"abc").data == b"abc"
    with pytest.raises(ValueError, match="an array of 4 bytes"):
        uint8s(LITTLE_ENDIAN + struct.pack("<I", 4) + b"abc")


RECURSIVE = {
    "itself": "nav_msgs/Odometry next\n",
    "itself in a sequence": "int32 a\nnav_msgs/Odometry[] children\n",
    "through another type": ("test_msgs/A a\n" + schemas.SEPARATOR + "\nMSG: test_msgs/A\nnav_msgs/Odometry back\n"),
    "too deep": "\n".join(
        ["test_msgs/T0 t"]
        + [f"{schemas.SEPARATOR}\nMSG: test_msgs/T{i}\ntest_msgs/T{i + 1} t" for i in range(MAX_NESTING + 5)]
        + [f"{schemas.SEPARATOR}\nMSG: test_msgs/T{MAX_NESTING + 5}\nint32 x"]
    )
    + "\n",
}


@pytest.mark.parametrize("case", list(RECURSIVE))
def test_definitions_that_contain_themselves_are_not_followed(tmp_path, case):
    text = RECURSIVE[case]
    with pytest.raises(ValueError, match="contains itself|nest more than"):
        compile_decoders(schemas.ODOMETRY, text)
    payload = LITTLE_ENDIAN + struct.pack("<I", 1) * 400
    write_cdr(tmp_path / "r.mcap", "/motion_odometry", schemas.ODOMETRY, text, [payload, payload[:-4]])
    log, report = outcome(read_log, tmp_path / "r.mcap", case)
    assert log.odometry_times.shape == (0,)
    (((topic, reason), count),) = report.dropped.items()
    assert topic == "/motion_odometry" and count == 2 and "does not parse (ValueError)" in reason


def test_a_nesting_as_deep_as_allowed_decodes():
    text = (
        "\n".join(
            ["test_msgs/T1 t"]
            + [f"{schemas.SEPARATOR}\nMSG: test_msgs/T{i}\ntest_msgs/T{i + 1} t" for i in range(1, MAX_NESTING - 1)]
            + [f"{schemas.SEPARATOR}\nMSG: test_msgs/T{MAX_NESTING - 1}\nint32 x"]
        )
        + "\n"
    )
    decode = compile_decoders("test_msgs/msg/T0", text)["test_msgs/msg/T0"]
    message = decode(LITTLE_ENDIAN + struct.pack("<i", 7))
    for _ in range(MAX_NESTING - 1):
        message = message.t
    assert message.x == 7


def definition_with(type_name: str, old: str, new: str) -> str:
    text = schemas.definition(type_name)
    assert old in text
    return text.replace(old, new)


# (stream's type, a changed definition, a message that fits it, the reason it is dropped)
MISFIT_SCHEMAS = {
    "no header stamp": (
        schemas.ODOMETRY,
        definition_with(schemas.ODOMETRY, "builtin_interfaces/Time stamp", "int32 stamp"),
        {"header": {"stamp": 5}},
        "no field sec",
    ),
    "a header of text": (
        schemas.ODOMETRY,
        definition_with(schemas.ODOMETRY, "std_msgs/Header header\n", "string header\n"),
        {"header": "odom"},
        "no field stamp",
    ),
    "sec as a float": (
        schemas.ODOMETRY,
        definition_with(schemas.ODOMETRY, "int32 sec", "float64 sec"),
        odometry_message(1),
        "not integer sec and nanosec",
    ),
    "sec as an int64": (
        schemas.ODOMETRY,
        definition_with(schemas.ODOMETRY, "int32 sec", "int64 sec"),
        odometry_message(2**62),
        "does not fit builtin_interfaces/Time",
    ),
    "position x as text": (
        schemas.ODOMETRY,
        definition_with(schemas.ODOMETRY, "float64 x\nfloat64 y\nfloat64 z", "string x\nfloat64 y\nfloat64 z"),
        {"header": header(1), "pose": {"pose": {"position": {"x": "1.5"}}}},
        "holds str",
    ),
    "no orientation": (
        schemas.ODOMETRY,
        definition_with(schemas.ODOMETRY, "geometry_msgs/Quaternion orientation", "float64 orientation"),
        odometry_message(1),
        "no field",
    ),
    "twist without angular": (
        schemas.TWIST,
        "geometry_msgs/Vector3 linear\n"
        + schemas.SEPARATOR
        + "\nMSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n",
        {"linear": {"x": 1.0}},
        "no field angular",
    ),
    "joint names as a number": (
        schemas.JOINT_STATE,
        definition_with(schemas.JOINT_STATE, "string[] name", "float64 name"),
        {"header": header(1), "name": 1.5, "position": [1.0]},
        "not an array",
    ),
    "joint positions as text": (
        schemas.JOINT_STATE,
        definition_with(schemas.JOINT_STATE, "float64[] position", "string[] position"),
        {"header": header(1), "name": ["a"], "position": ["1"]},
        "holds str",
    ),
    "joint names as numbers": (
        schemas.JOINT_STATE,
        definition_with(schemas.JOINT_STATE, "string[] name", "int32[] name"),
        {"header": header(1), "name": [3], "position": [1.0]},
        "not text",
    ),
    "num_rays as a float": (
        schemas.MARKING_ARRAY,
        definition_with(schemas.MARKING_ARRAY, "int32 num_rays", "float64 num_rays"),
        {"header": header(1), "intersections": [{"num_rays": math.nan}]},
        "not an integer",
    ),
    "diameter as text": (
        schemas.MARKING_ARRAY,
        definition_with(schemas.MARKING_ARRAY, "float64 diameter", "string diameter"),
        {"header": header(1), "ellipses": [{"diameter": "big"}]},
        "holds str",
    ),
    "posts as one post": (
        schemas.GOALPOST_ARRAY,
        definition_with(
            schemas.GOALPOST_ARRAY, "soccer_vision_3d_msgs/Goalpost[] posts", "soccer_vision_3d_msgs/Goalpost posts"
        ),
        {"header": header(1), "posts": {}},
        "not an array",
    ),
}
STREAM_TOPIC = {
    schemas.ODOMETRY: "/motion_odometry",
    schemas.TWIST: "/cmd_vel",
    schemas.JOINT_STATE: "/joint_states",
    schemas.MARKING_ARRAY: "/markings_relative",
    schemas.GOALPOST_ARRAY: "/goal_posts_relative",
}


@pytest.mark.parametrize("case", list(MISFIT_SCHEMAS))
def test_a_message_type_defined_otherwise_is_dropped_with_the_reason(tmp_path, case):
    type_name, text, message, reason = MISFIT_SCHEMAS[case]
    topic = STREAM_TOPIC[type_name]
    write_messages(tmp_path / "m.mcap", [(topic, type_name, message, ORIGIN_NS)], {type_name: text})
    log, report = outcome(read_log, tmp_path / "m.mcap", case)
    (((dropped_topic, why), count),) = report.dropped.items()
    assert dropped_topic == topic and count == 1 and reason in why, why


def test_stamps_far_from_the_origin_that_round_to_one_time_are_one_stamp(tmp_path):
    """Sim-time stamps near -2^31 s in a file whose log times end near 2^64 ns: 1 ns apart is one float64 time."""
    last = 2**64 - 1
    write_messages(
        tmp_path / "far.mcap",
        [
            ("/motion_odometry", schemas.ODOMETRY, odometry_message(-(2**31), 0, 1.0), last - 1),
            ("/motion_odometry", schemas.ODOMETRY, odometry_message(-(2**31), 1, 2.0), last),
        ],
    )
    log, report = outcome(read_log, tmp_path / "far.mcap")
    assert log.odometry[:, 0].tolist() == [1.0] and log.origin_ns == last - 1
    assert report.dropped == {("/motion_odometry", "same stamp as the previous message"): 1}


@pytest.mark.parametrize("origin", ["9" * 30, "-" + "9" * 30, "9" * 5000, "1e18", "nan", "", str(2**64)])
def test_an_absurd_recorded_origin_is_ignored(tmp_path, origin):
    write_messages(
        tmp_path / "o.mcap",
        [("/motion_odometry", schemas.ODOMETRY, odometry_message(1), ORIGIN_NS)],
        metadata={"origin_ns": origin},
    )
    log, _ = outcome(read_log, tmp_path / "o.mcap")
    assert log.origin_ns == ORIGIN_NS and log.odometry_times.tolist() == [(SECOND - ORIGIN_NS) / 1e9]


def point(x: float, y: float) -> dict:
    return {"x": x, "y": y, "z": 0.0}


def test_absurd_detections(tmp_path):
    """A segment of a million metres is not sampled into millions of points; far detections are refused or read,
    as `Observations` decides, never an escape."""
    stamp = header(1)
    markings = {
        "header": stamp,
        "segments": [
            {"start": point(0.0, 0.0), "end": point(1e6, 0.0)},
            {"start": point(-1e300, 0.0), "end": point(1e300, 0.0)},
            {"start": point(0.0, 0.0), "end": point(0.3, 0.0)},
        ],
    }
    far = {"header": header(2), "posts": [{"bb": {"center": {"position": point(1e300, 1e300)}}}]}
    overflow = {"header": header(3), "posts": [{"bb": {"center": {"position": point(1.7e308, 1.7e308)}}}]}
    write_messages(
        tmp_path / "v.mcap",
        [
            ("/markings_relative", schemas.MARKING_ARRAY, markings, ORIGIN_NS + SECOND),
            ("/goal_posts_relative", schemas.GOALPOST_ARRAY, far, ORIGIN_NS + 2 * SECOND),
            ("/goal_posts_relative", schemas.GOALPOST_ARRAY, overflow, ORIGIN_NS + 3 * SECOND),
        ],
    )
    started = time.perf_counter()
    log, report = outcome(read_log, tmp_path / "v.mcap")
    assert time.perf_counter() - started < 5.0
    assert report.dropped[("/markings_relative", "segment longer than 30 m")] == 2
    np.testing.assert_allclose(log.vision[0].observations.line_points, [[0.0, 0.0], [0.15, 0.0], [0.3, 0.0]])
    assert len(log.vision) in (1, 2)  # the far goalpost's frame is read or refused; the overflowing one refused


def claim_content_size(frame_header: bytes, content_size: int) -> bytes:
    """An lz4 frame header (15 bytes, with a content size) claiming `content_size`, its checksum made to fit."""
    changed = bytearray(frame_header)
    changed[6:14] = content_size.to_bytes(8, "little")
    for checksum in range(256):
        changed[14] = checksum
        try:
            if lz4.frame.get_frame_info(bytes(changed))["content_size"] == content_size:
                return bytes(changed)
        except RuntimeError:
            continue
    raise AssertionError("no header checksum fits")


def zstd_round_trip(log: RobotLog) -> RobotLog:
    with tempfile.TemporaryDirectory() as folder:
        write_mcap(log, Path(folder) / "zstd.mcap")
        return read_log(Path(folder) / "zstd.mcap")[0]


def test_compressed_chunks_claiming_huge_sizes_are_not_allocated(tmp_path):
    log = small_log()
    with mock.patch.object(mcap_io, "Ros2Writer", functools.partial(Ros2Writer, compression=CompressionType.LZ4)):
        write_mcap(log, tmp_path / "lz4.mcap", chunk_size=1 << 20)
    back, report = read_log(tmp_path / "lz4.mcap")  # lz4 chunks read as the zstd ones
    assert report.complete and not report.dropped
    np.testing.assert_array_equal(back.gyro, zstd_round_trip(log).gyro)
    data = (tmp_path / "lz4.mcap").read_bytes()
    start = data.index(b"\x04\x22\x4d\x18")  # the first chunk's lz4 frame
    assert lz4.frame.get_frame_info(data[start : start + 15])["content_size"] > 0  # the writer records it
    patched = data[:start] + claim_content_size(data[start : start + 15], 1 << 33) + data[start + 15 :]
    (tmp_path / "claims.mcap").write_bytes(patched)
    peak = peak_allocation(lambda: outcome(read_log, tmp_path / "claims.mcap"))
    assert peak < SMALL_ALLOCATION, f"{peak / 1e6:.0f} MB"
    _, report = read_log(tmp_path / "claims.mcap")
    assert not report.complete
    # A zstd frame that does not record its size is decompressed as it comes, not into a buffer of the size
    # the chunk claims (up to MAX_CHUNK_BYTES, a gigabyte).
    records = zstandard.ZstdCompressor(write_content_size=False).compress(b"\x00" * 1000)
    chunk = Chunk(
        compression="zstd",
        data=records,
        message_start_time=0,
        message_end_time=0,
        uncompressed_crc=0,
        uncompressed_size=mcap_io.MAX_CHUNK_BYTES,
    )
    assert peak_allocation(lambda: mcap_io._decompressed(chunk)) < SMALL_ALLOCATION
    assert mcap_io._decompressed(chunk) == b"\x00" * 1000
    with pytest.raises(mcap_io.McapError, match="more than the 999 bytes"):
        mcap_io._decompressed(
            Chunk(
                compression="zstd",
                data=records,
                message_start_time=0,
                message_end_time=0,
                uncompressed_crc=0,
                uncompressed_size=999,
            )
        )


def test_footer_and_index_offsets_outside_the_file(valid_files, workdir):
    """list_topics seeks where the footer and the indexes point: an offset beyond the file falls back to a scan."""
    data = valid_files["zstd.mcap"]
    footer = len(data) - 8 - 29
    for offset in (2**63 - 1, 2**64 - 1, len(data) + 5):
        broken = data[: footer + 9] + offset.to_bytes(8, "little") + data[footer + 17 :]
        (workdir / "footer.mcap").write_bytes(broken)
        rows = outcome(list_topics, workdir / "footer.mcap")
        assert {row["topic"] for row in rows} >= {"/motion_odometry", "/imu/data"}


# -- arguments and the RobotLog constructor ---------------------------------------------------------------------
def test_arguments_of_the_wrong_type_or_value(valid_files, workdir, tmp_path):
    path = workdir / "zstd.mcap"
    for bad in (123, None, b"game.mcap", ["game.mcap"]):
        with pytest.raises(TypeError, match="path"):
            read_log(bad)
        with pytest.raises(TypeError, match="path"):
            list_topics(bad)
    for gap, error in (
        ("x", TypeError),
        (None, TypeError),
        (True, TypeError),
        (-1, ValueError),
        (0, ValueError),
        (math.nan, ValueError),
        (math.inf, ValueError),
    ):
        with pytest.raises(error, match="gap"):
            read_log(path, gap=gap)
        with pytest.raises(error, match="gap"):
            read_log(workdir / "stored.npz", gap=gap)  # checked whatever the form
        with pytest.raises(error, match="gap"):
            read_mcap(path, gap=gap)
    for topics in ("/odom", 5, {"odometry": "/odom"}):
        with pytest.raises(TypeError, match="topics"):
            read_log(path, topics=topics)
        with pytest.raises(TypeError, match="topics"):
            read_mcap(path, topics=topics)
    with pytest.raises(ValueError, match="Topics.odometry"):
        Topics(odometry=5)
    assert read_log(path, topics=Topics(), gap=np.float32(0.5))[0].odometry_times.shape == (4,)
    with pytest.raises(LogError, match="no such file"):
        read_log(tmp_path / "absent.mcap")
    with pytest.raises(FileNotFoundError):
        list_topics(tmp_path / "absent.mcap")
    (tmp_path / "folder.mcap").mkdir()
    with pytest.raises(LogError, match="folder.mcap is a folder"):
        list_topics(tmp_path / "folder.mcap")
    with pytest.raises(LogError, match="meta.csv is missing"):
        read_log(tmp_path / "folder.mcap")  # a folder is read as the CSV form


def test_robot_log_refuses_what_no_stream_may_hold():
    t = np.array([0.0, 0.1, 0.2])
    with pytest.raises(LogError, match=r"odometry_times / odometry hold a NaN"):
        RobotLog(odometry_times=[0.0, math.nan, 0.2], odometry=np.zeros((3, 3)))
    with pytest.raises(LogError, match=r"commands hold a NaN or an infinity"):
        RobotLog(command_times=t, commands=[[0, 0, math.inf]] * 3)
    with pytest.raises(LogError, match=r"imu_times\[2\] = 0.1.* does not follow"):
        RobotLog(imu_times=[0.0, 0.2, 0.1], gyro=np.zeros((3, 3)), acceleration=np.zeros((3, 3)))
    with pytest.raises(LogError, match=r"truth_times\[1\] = 1e\+300 s lies more than MAX_TIME"):
        RobotLog(truth_times=[0.0, 1e300], truth=np.zeros((2, 3)))
    with pytest.raises(LogError, match=r"vision\[0\] .* lies more than MAX_TIME"):
        RobotLog(vision=(VisionFrame(0.0, 1e12, Observations.empty()),))
    with pytest.raises(TypeError, match="odometry_times .* not text"):
        RobotLog(odometry_times="0.0", odometry=np.zeros((1, 3)))
    with pytest.raises(TypeError, match="odometry has dtype complex128"):
        RobotLog(odometry_times=t, odometry=np.zeros((3, 3), dtype=complex))
    with pytest.raises(TypeError, match="odometry has dtype object"):
        RobotLog(odometry_times=t, odometry=[[None] * 3] * 3)
    with pytest.raises(TypeError, match="odometry must be an array of numbers"):
        RobotLog(odometry_times=t, odometry=[[0.0], [0.0, 1.0], []])
    with pytest.raises(TypeError, match="origin_ns = 1.5 must be an integer"):
        RobotLog(origin_ns=1.5)
    with pytest.raises(TypeError, match="joint_names .* not one string"):
        RobotLog(joint_names="HeadYaw")
    with pytest.raises(TypeError, match=r"vision\[0\].stamp = '0' must be a number"):
        RobotLog(vision=(VisionFrame("0", 0.1, Observations.empty()),))
    with pytest.raises(LogError, match=r"vision\[0\].observations"):
        RobotLog(vision=(VisionFrame(0.0, 0.1, None),))
    assert RobotLog(origin_ns=np.int64(7)).origin_ns == 7 and type(RobotLog(origin_ns=np.int64(7)).origin_ns) is int
    assert RobotLog(truth_times=[-MAX_TIME, MAX_TIME], truth=np.zeros((2, 3))).duration == 2 * MAX_TIME
