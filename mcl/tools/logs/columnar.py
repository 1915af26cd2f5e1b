"""The columnar log format, for teams without ROS: a `RobotLog` as one NPZ file or as a folder of CSV files.

    from mcl.tools.logs.columnar import read_csv, read_npz, write_csv, write_npz

    write_npz(log, "game.npz")
    log, report = read_npz("game.npz")        # report: rows per stream, and any key or file it ignored
    write_csv(log, "game_csv")                # a folder of CSV files
    log, report = read_csv("game_csv")

Both forms hold the streams of `mcl.tools.logs.robot_log.RobotLog` in SI units. Every time is float64 seconds
after `origin_ns`, the log's origin in integer nanoseconds since the epoch (it fits int64), and lies within
`MAX_TIME` (1e11 s) of it. The times of a stream increase strictly, by at most `MAX_STEP_DT` (an hour, the
longest motion step) from one to the next; vision frames are listed in the order they arrived (`received` never
decreases). A stream the robot did not record is left out or has no rows; the
writers write every stream. This is format version 1; a reader refuses another version. A file that breaks
these rules raises `LogError` (a `ValueError`) naming the file and the key, or the line and column, and for
times out of order the stream and the time; so does one whose sizes do not fit its bytes. A missing
file or folder raises `FileNotFoundError`. Keys or CSV files of no stream are ignored and listed in the
report's `dropped`.

NPZ: numpy's zip of `.npy` arrays (`np.savez` or `np.savez_compressed`; C++ can write it with cnpy). Pickled
(object) arrays are refused, so every array must be of numbers or (for `joint_names`) unicode strings. Float
arrays may be float32 or float64, integer arrays of any width. The keys of one stream come together or not at
all.

| key                            | shape, type    | unit               | meaning                                      |
|--------------------------------|----------------|--------------------|----------------------------------------------|
| `format_version`               | (), integer    |                    | 1                                            |
| `origin_ns`                    | (), integer    | ns since the epoch | the time every other time is relative to     |
| `odometry_times`, `odometry`   | (K,), (K, 3)   | s; m, m, rad       | odometry pose x, y, yaw in the odom frame    |
| `command_times`, `commands`    | (C,), (C, 3)   | s; m/s, m/s, rad/s | walk request vx, vy, ω                       |
| `imu_times`, `gyro`            | (I,), (I, 3)   | s; rad/s           | angular rate about the IMU's x, y, z         |
| `acceleration`                 | (I, 3)         | m/s²               | acceleration along the IMU's x, y, z         |
| `joint_names`                  | (n,), unicode  |                    | the joints, in the order of the columns      |
| `joint_command_times`          | (J,)           | s                  |                                              |
| `joint_commands`               | (J, n)         | rad                | commanded joint angles                       |
| `joint_reading_times`          | (R,)           | s                  |                                              |
| `joint_readings`               | (R, n)         | rad                | measured joint angles                        |
| `truth_times`, `truth`         | (G,), (G, 3)   | s; m, m, rad       | ground truth x, y, θ in the field frame      |
| `vision_stamps`                | (F,)           | s                  | capture time of each camera frame            |
| `vision_received`              | (F,)           | s                  | arrival time of each frame                   |
| `vision_landmark_counts`       | (F,), integer  |                    | landmarks per frame; the `vision_kinds` ...  |
|                                |                |                    | arrays hold frame 0's, then frame 1's, ...   |
| `vision_kinds`                 | (D,), integer  |                    | landmark type (table below)                  |
| `vision_ranges`                | (D,)           | m                  | range >= 0 in the robot frame                |
| `vision_bearings`              | (D,)           | rad                | counter-clockwise from the robot's +x        |
| `vision_range_sigmas`          | (D,)           | m                  | range noise (std), NaN when not given        |
| `vision_bearing_sigmas`        | (D,)           | rad                | bearing noise (std), NaN when not given      |
| `vision_line_point_counts`     | (F,), integer  |                    | line points per frame, frame after frame     |
| `vision_line_points`           | (P, 2)         | m                  | points on detected field lines, robot frame  |

CSV: a folder of comma-separated files, each with one header row naming its columns (with their units), then
one row per message. Columns may come in any order, but each must be there exactly once and no other.
Files are UTF-8. Numbers are written in Python's shortest round-trip form (any form `strtod` reads is
accepted); blank lines are skipped. Line numbers in errors count the header as line 1.

| file                   | columns                                                                  |
|------------------------|--------------------------------------------------------------------------|
| `meta.csv`             | `key,value`; rows `format_version,1` and `origin_ns,<integer ns>`      |
| `odometry.csv`         | `t_s,x_m,y_m,yaw_rad`                                                    |
| `commands.csv`         | `t_s,vx_m_s,vy_m_s,omega_rad_s`                                          |
| `imu.csv`              | `t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,`                            |
|                        | `acceleration_x_m_s2,acceleration_y_m_s2,acceleration_z_m_s2`            |
| `joint_commands.csv`   | `t_s,<joint>_rad,...`: one column per joint, the header names the joints |
| `joint_readings.csv`   | the same; both joint files must name the same joints in the same order   |
| `truth.csv`            | `t_s,x_m,y_m,theta_rad`                                                  |
| `vision_frames.csv`    | `stamp_s,received_s`: every camera frame, also those that saw nothing    |
| `vision_landmarks.csv` | `stamp_s,received_s,kind,range_m,bearing_rad,range_sigma_m,`             |
|                        | `bearing_sigma_rad`: one row per landmark detection                      |
| `vision_lines.csv`     | `stamp_s,received_s,x_m,y_m`: one row per line point                     |

Only `meta.csv` is required. A detection or line point belongs to the frame of `vision_frames.csv` with the same
`stamp_s` and `received_s` (write both files with the same number formatting); within a frame they keep
their order in the file, and no two frames may share both times. A noise column left empty (or `nan`)
means "not given". `kind` is a landmark type's name or its value, or an alias that `field.LandmarkType.parse`
takes (`L`, `T`, `X`, `post`, `penalty`, `center`, `centre`, `centre_mark`; any case, `-` or a space for `_`):

| kind           | value |     | kind           | value |
|----------------|-------|-----|----------------|-------|
| `GOALPOST`     | 0     |     | `X_CROSSING`   | 3     |
| `L_CROSSING`   | 1     |     | `PENALTY_MARK` | 4     |
| `T_CROSSING`   | 2     |     | `CENTER_MARK`  | 5     |

The CSV writer writes kinds by name and a noise that was not given as an empty cell.
"""

from __future__ import annotations

import csv
import math
import os
import zipfile
import zlib
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from field import LandmarkType
from motion_models.base import MAX_STEP_DT
from sensing.observations import Observations

if TYPE_CHECKING:
    from _csv import Reader as _CsvReader

from mcl.tools.logs.robot_log import MAX_TIME, LogError, ReadReport, RobotLog, VisionFrame

FORMAT_VERSION = 1
INT64_RANGE = (-(2**63), 2**63 - 1)
# deflate writes at least one bit per 258 bytes: a member claiming more per compressed byte is corrupt
_DEFLATE_MAX_RATIO = 1032

_JOINT_UNIT = "_rad"


@dataclass(frozen=True)
class _Stream:
    """A stream of the log: its times and value arrays on `RobotLog`, and its CSV file.

    `blocks` pairs each value array with its CSV columns; None stands for one column per joint.
    """

    name: str
    times: str
    blocks: tuple[tuple[str, tuple[str, ...] | None], ...]

    @property
    def file(self) -> str:
        return f"{self.name}.csv"

    @property
    def keys(self) -> list[str]:
        return [self.times] + [values for values, _ in self.blocks]

    def block_columns(self, joint_names: Sequence[str]) -> list[tuple[str, ...]]:
        return [
            tuple(f"{name}{_JOINT_UNIT}" for name in joint_names) if columns is None else columns
            for _, columns in self.blocks
        ]


_STREAMS = (
    _Stream("odometry", "odometry_times", (("odometry", ("x_m", "y_m", "yaw_rad")),)),
    _Stream("commands", "command_times", (("commands", ("vx_m_s", "vy_m_s", "omega_rad_s")),)),
    _Stream(
        "imu",
        "imu_times",
        (
            ("gyro", ("gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s")),
            ("acceleration", ("acceleration_x_m_s2", "acceleration_y_m_s2", "acceleration_z_m_s2")),
        ),
    ),
    _Stream("joint_commands", "joint_command_times", (("joint_commands", None),)),
    _Stream("joint_readings", "joint_reading_times", (("joint_readings", None),)),
    _Stream("truth", "truth_times", (("truth", ("x_m", "y_m", "theta_rad")),)),
)
_JOINT_STREAMS = tuple(stream for stream in _STREAMS if stream.blocks[0][1] is None)

# What a value must be: a test on an array, and what a failing value is told.
_RULES: dict[str, tuple[Callable[[np.ndarray], np.ndarray], str]] = {
    "finite": (np.isfinite, "must be finite"),
    "time": (
        lambda v: np.isfinite(v) & (np.abs(v) <= MAX_TIME),
        f"must be finite and within MAX_TIME = {MAX_TIME:g} s of origin_ns",
    ),
    "nonnegative": (lambda v: np.isfinite(v) & (v >= 0), "must be finite and >= 0"),
    "noise": (lambda v: np.isnan(v) | (np.isfinite(v) & (v > 0)), "must be > 0 (or empty / NaN: not given)"),
    "kind": (lambda v: np.isin(v, [member.value for member in LandmarkType]), "is not a landmark type value"),
}

# The landmark arrays: Observations field, NPZ key, CSV column, rule.
_LANDMARK_FIELDS = (
    ("kinds", "vision_kinds", "kind", "kind"),
    ("ranges", "vision_ranges", "range_m", "nonnegative"),
    ("bearings", "vision_bearings", "bearing_rad", "finite"),
    ("range_sigmas", "vision_range_sigmas", "range_sigma_m", "noise"),
    ("bearing_sigmas", "vision_bearing_sigmas", "bearing_sigma_rad", "noise"),
)
_FRAME_COLUMNS = ("stamp_s", "received_s")
_LINE_COLUMNS = ("x_m", "y_m")
_VISION_KEYS = (
    "vision_stamps",
    "vision_received",
    "vision_landmark_counts",
    "vision_line_point_counts",
    "vision_line_points",
) + tuple(key for _, key, _, _ in _LANDMARK_FIELDS)
_META_KEYS = ("format_version", "origin_ns")
_NPZ_KEYS = frozenset(_META_KEYS + ("joint_names",) + _VISION_KEYS + tuple(k for s in _STREAMS for k in s.keys))


# -- checks shared by both forms ----------------------------------------------------------------------------------
def _check_values(values: np.ndarray, rule: str, where: Callable[[tuple[int, ...]], str]) -> None:
    """Raise a LogError at the first value breaking `rule`; `where(index)` names its place in the file."""
    test, requirement = _RULES[rule]
    bad = ~test(values)
    if bad.any():
        index = tuple(int(i) for i in np.argwhere(bad)[0])
        raise LogError(f"{where(index)} = {values[index].item()!r} {requirement}")


def _check_order(
    times: np.ndarray, stream: str, where: Callable[[tuple[int, ...]], str], strictly: bool = True
) -> None:
    """Raise a LogError at the first time that does not follow its predecessor, or (`strictly`: the times of a
    timed stream) lies more than `MAX_STEP_DT` after it: a gap no motion step can span, which a replay would
    otherwise meet only when it builds that step."""
    steps = np.diff(times)
    bad = steps <= 0 if strictly else steps < 0
    if bad.any():
        i = int(np.argmax(bad)) + 1
        order = "increase" if strictly else "never decrease"
        raise LogError(
            f"{where((i,))} = {float(times[i])!r} s does not follow {float(times[i - 1])!r} s: "
            f"the times of {stream} must {order}"
        )
    if strictly and (steps > MAX_STEP_DT).any():
        i = int(np.argmax(steps > MAX_STEP_DT)) + 1
        raise LogError(
            f"{where((i,))} = {float(times[i])!r} s lies {float(steps[i - 1]):g} s after "
            f"{float(times[i - 1])!r} s: consecutive times of {stream} must be at most "
            f"MAX_STEP_DT = {MAX_STEP_DT:g} s apart (the longest motion step)"
        )


def _vision_frames(
    stamps: np.ndarray,
    received: np.ndarray,
    landmark_frames: np.ndarray,
    landmarks: dict[str, np.ndarray],
    line_frames: np.ndarray,
    line_points: np.ndarray,
    where: Callable[[int], str],
) -> tuple[VisionFrame, ...]:
    """The frames, given each landmark's and line point's frame index (their order within a frame is kept);
    a LogError naming the frame (`where(i)`) when `Observations` refuses its detections."""
    count = stamps.shape[0]

    def per_frame(frame_of: np.ndarray, arrays: list[np.ndarray]) -> list[list[np.ndarray]]:
        order = np.argsort(frame_of, kind="stable")
        bounds = np.cumsum(np.bincount(frame_of, minlength=count))[:-1]
        return [np.split(array[order], bounds) for array in arrays]

    kinds, ranges, bearings, range_sigmas, bearing_sigmas = per_frame(
        landmark_frames, [landmarks[name] for name, _, _, _ in _LANDMARK_FIELDS]
    )
    (points_per_frame,) = per_frame(line_frames, [line_points])
    frames = []
    for i in range(count):
        try:
            observations = Observations(
                kinds[i], ranges[i], bearings[i], range_sigmas[i], bearing_sigmas[i], line_points=points_per_frame[i]
            )
        except ValueError as error:
            raise LogError(f"{where(i)}: {error}") from None
        frames.append(VisionFrame(float(stamps[i]), float(received[i]), observations))
    return tuple(frames)


def _log(path: Path, arrays: dict) -> RobotLog:
    try:
        return RobotLog(**arrays)
    except ValueError as error:
        raise LogError(f"{path}: {error}") from None


def _report(path: Path, log: RobotLog, sources: dict[str, str]) -> ReadReport:
    """Rows read per stream that has any (vision: frames), and the keys or files each came from."""
    report = ReadReport(str(path))
    rows = {stream.name: int(getattr(log, stream.times).shape[0]) for stream in _STREAMS}
    rows["vision"] = len(log.vision)
    for name, source in sources.items():
        if rows[name]:
            report.messages[name] = rows[name]
            report.types[name] = source
    return report


# -- NPZ ----------------------------------------------------------------------------------------------------------
def write_npz(log: RobotLog, path: str | Path) -> None:
    """Write `log` to `path` as an NPZ file (the name is kept as given: no '.npz' is added)."""
    arrays: dict[str, np.ndarray] = {
        "format_version": np.int64(FORMAT_VERSION),
        "origin_ns": np.int64(log.origin_ns),
        "joint_names": np.array(log.joint_names, dtype=np.str_).reshape(-1),
    }
    for stream in _STREAMS:
        for key in stream.keys:
            arrays[key] = getattr(log, key)
    frames = log.vision
    arrays["vision_stamps"] = np.array([frame.stamp for frame in frames], dtype=np.float64)
    arrays["vision_received"] = np.array([frame.received for frame in frames], dtype=np.float64)
    arrays["vision_landmark_counts"] = np.array([len(frame.observations) for frame in frames], dtype=np.int64)
    arrays["vision_line_point_counts"] = np.array(
        [frame.observations.line_points.shape[0] for frame in frames], dtype=np.int64
    )
    for name, key, _, _ in _LANDMARK_FIELDS:
        dtype = np.int64 if name == "kinds" else np.float64
        arrays[key] = np.concatenate([getattr(frame.observations, name) for frame in frames] + [np.zeros(0, dtype)])
    arrays["vision_line_points"] = np.concatenate(
        [frame.observations.line_points for frame in frames] + [np.zeros((0, 2))]
    )
    with open(path, "wb") as file:
        np.savez(file, **arrays)  # type: ignore[arg-type]  # numpy's stub: a key could be allow_pickle


def read_npz(path: str | Path) -> tuple[RobotLog, ReadReport]:
    """Read a log written by `write_npz` (or by anyone following the module's table).

    Each array's `.npy` header (dtype, shape) is checked against the bytes its member holds before anything
    is allocated; keys of no stream are listed in the report without being read.
    """
    path = Path(path)
    try:
        with open(path, "rb") as file:
            if file.read(len(np.lib.format.MAGIC_PREFIX)) == np.lib.format.MAGIC_PREFIX:
                raise LogError(f"{path}: holds a single array, not an NPZ archive of named arrays")
            file.seek(0)
            with zipfile.ZipFile(file) as archive:
                members = {info.filename.removesuffix(".npy"): info for info in archive.infolist()}
                size = os.fstat(file.fileno()).st_size
                arrays = {
                    key: _npz_member(path, archive, key, info, size) if key in _NPZ_KEYS else None
                    for key, info in members.items()
                }
    except (FileNotFoundError, LogError):
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError) as error:
        # zipfile reports an unsupported zip version as NotImplementedError, a name not UTF-8 as ValueError
        raise LogError(f"{path}: not an NPZ file ({type(error).__name__}: {error})") from None
    return _NpzReader(path, arrays).read()


def _npz_member(path: Path, archive: zipfile.ZipFile, key: str, info: zipfile.ZipInfo, size: int) -> np.ndarray:
    """The array of one member, read only after its header and claimed sizes fit the file: its data is never
    given more memory than the member holds."""

    def fail(reason: str) -> LogError:
        return LogError(f"{path}: {key} {reason}")

    if info.flag_bits & 0x61:  # encrypted (bits 0 and 6), or compressed patched data (bit 5)
        raise fail("is encrypted or patched: numpy writes neither")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise fail(f"is compressed with zip method {info.compress_type}: numpy writes stored or deflated members")
    if info.compress_size > size or info.file_size > (
        info.compress_size if info.compress_type == zipfile.ZIP_STORED else _DEFLATE_MAX_RATIO * info.compress_size + 64
    ):
        raise fail(f"claims {info.file_size} bytes ({info.compress_size} compressed) in a file of {size} bytes")
    try:
        with archive.open(info) as member:
            version = np.lib.format.read_magic(member)
            if version == (1, 0):
                shape, fortran_order, dtype = np.lib.format.read_array_header_1_0(member)
            elif version in ((2, 0), (3, 0)):  # 3.0 differs in the header's text encoding only
                shape, fortran_order, dtype = np.lib.format.read_array_header_2_0(member)
            else:
                raise fail(f"is a .npy array of format version {version}, not 1, 2 or 3")
            if dtype.hasobject:
                raise fail(f"cannot be read: it holds Python objects (dtype {dtype}), and pickled data is not read")
            if any(length < 0 for length in shape):
                raise fail(f"has shape {shape}: a length is negative")
            count = math.prod(shape)
            needed = count * dtype.itemsize
            if count and dtype.itemsize == 0:
                raise fail(f"has {count} elements of dtype {dtype}, which holds nothing")
            available = info.file_size - member.tell()
            if needed > available:
                raise fail(f"has shape {shape} of {dtype}: {needed} bytes, but the member holds {available}")
            data = member.read(needed)
    except (ValueError, EOFError, zipfile.BadZipFile, zlib.error, UnicodeDecodeError) as error:
        if isinstance(error, LogError):
            raise
        # numpy's header checks (magic, version, a header that is not a dict of shape, fortran_order, descr)
        raise fail(f"cannot be read ({type(error).__name__}: {error})") from None
    if len(data) != needed:
        raise fail(f"has shape {shape} of {dtype}: {needed} bytes, but its data ends after {len(data)}")
    return np.frombuffer(data, dtype=dtype, count=count).reshape(shape, order="F" if fortran_order else "C")


class _NpzReader:
    """Checks the arrays of one NPZ file and turns them into a RobotLog."""

    def __init__(self, path: Path, arrays: dict[str, np.ndarray | None]) -> None:
        self.path = path
        self.arrays = arrays  # None for a key of no stream (not read)

    def where(self, key: str) -> Callable[[tuple[int, ...]], str]:
        return lambda index: f"{self.path}: {key}[{', '.join(map(str, index))}]"

    def array(self, key: str, shape: tuple[int | None, ...], rows_are: str = "", integer: bool = False) -> np.ndarray:
        """arrays[key] as float64 (int64 if `integer`) of `shape` (None: any length); `rows_are` says why.

        An empty (0,) array stands for an empty table too: a writer need not give it its columns.
        """
        array = self.present(key)
        if array.dtype.kind not in ("iu" if integer else "iuf"):
            raise LogError(
                f"{self.path}: {key} has dtype {array.dtype}, expected {'integers' if integer else 'numbers'}"
            )
        if integer and array.dtype.kind == "u" and array.size and int(array.max()) > INT64_RANGE[1]:
            index = tuple(int(i) for i in np.unravel_index(int(np.argmax(array)), array.shape))
            raise LogError(f"{self.where(key)(index)} = {int(array[index])} does not fit int64")
        if array.size == 0 and array.ndim == 1 and len(shape) == 2 and shape[1] is not None:
            array = array.reshape(0, shape[1])
        if array.ndim != len(shape) or any(want is not None and have != want for have, want in zip(array.shape, shape)):
            expected = ", ".join("any" if want is None else str(want) for want in shape)
            expected = f"({expected},)" if len(shape) == 1 else f"({expected})"
            raise LogError(
                f"{self.path}: {key} has shape {array.shape}, expected {expected}"
                + (f" ({rows_are})" if rows_are else "")
            )
        return array.astype(np.int64 if integer else np.float64)

    def present(self, key: str) -> np.ndarray:
        """arrays[key], which the reader read (a key of a stream it reads)."""
        array = self.arrays[key]
        if array is None:
            raise LogError(f"{self.path}: {key} is not one of the keys this reader reads")
        return array

    def scalar(self, key: str) -> int:
        if key not in self.arrays:
            raise LogError(f"{self.path}: the key {key} is missing: not a columnar log")
        return int(self.array(key, (), integer=True))

    def group(self, keys: Sequence[str], what: str) -> bool:
        """Whether the keys of one stream are there; a LogError when only some are."""
        present = [key for key in keys if key in self.arrays]
        if present and len(present) < len(keys):
            missing = [key for key in keys if key not in self.arrays]
            raise LogError(f"{self.path}: {what} has {', '.join(present)} but not {', '.join(missing)}")
        return bool(present)

    def read(self) -> tuple[RobotLog, ReadReport]:
        version = self.scalar("format_version")
        if version != FORMAT_VERSION:
            raise LogError(f"{self.path}: format_version = {version}, this reader reads version {FORMAT_VERSION}")
        fields: dict = {"origin_ns": self.scalar("origin_ns")}
        joint_names: tuple[str, ...] = ()
        if "joint_names" in self.arrays:
            names = self.present("joint_names")
            if names.dtype.kind not in "US" or names.ndim != 1:
                raise LogError(
                    f"{self.path}: joint_names has dtype {names.dtype} and shape {names.shape}, expected (n,) strings"
                )
            if names.dtype.kind == "U" and names.size and names.dtype.itemsize:
                # UTF-32 code units: numpy cannot make a str of one beyond U+10FFFF, nor is a surrogate text
                codes = names.astype(names.dtype.newbyteorder("<")).view("<u4").reshape(names.shape[0], -1)
                bad = (codes > 0x10FFFF) | ((codes >= 0xD800) & (codes <= 0xDFFF))
                if bad.any():
                    i, j = (int(k) for k in np.argwhere(bad)[0])
                    raise LogError(
                        f"{self.path}: joint_names[{i}] holds {int(codes[i, j]):#x}, not a Unicode character"
                    )
            try:
                joint_names = tuple(name.decode() if isinstance(name, bytes) else str(name) for name in names.tolist())
            except UnicodeDecodeError as error:
                raise LogError(f"{self.path}: joint_names holds a name that is not UTF-8 ({error})") from None
        fields["joint_names"] = joint_names
        sources = {}
        for stream in _STREAMS:
            if not self.group(stream.keys, stream.name):
                continue
            times = self.array(stream.times, (None,))
            _check_values(times, "time", self.where(stream.times))
            _check_order(times, stream.name, self.where(stream.times))
            fields[stream.times] = times
            rows_are = f"one row per {stream.times}" + (
                ", one column per joint_names entry" if stream in _JOINT_STREAMS else ""
            )
            for (key, _), columns in zip(stream.blocks, stream.block_columns(joint_names)):
                values = self.array(key, (times.shape[0], len(columns)), rows_are)
                _check_values(values, "finite", self.where(key))
                fields[key] = values
            sources[stream.name] = "npz " + ", ".join(stream.keys)
        if self.group(_VISION_KEYS, "vision"):
            fields["vision"] = self.vision()
            sources["vision"] = "npz vision_*"
        log = _log(self.path, fields)
        report = _report(self.path, log, sources)
        for key in sorted(set(self.arrays) - _NPZ_KEYS):
            report.drop(key, "not a key of the columnar format")
        return log, report

    def vision(self) -> tuple[VisionFrame, ...]:
        stamps = self.array("vision_stamps", (None,))
        received = self.array("vision_received", (stamps.shape[0],), "one per vision_stamps")
        for key, times in (("vision_stamps", stamps), ("vision_received", received)):
            _check_values(times, "time", self.where(key))
        _check_order(received, "vision", self.where("vision_received"), strictly=False)
        counts = {}
        for key in ("vision_landmark_counts", "vision_line_point_counts"):
            counts[key] = self.array(key, (stamps.shape[0],), "one per vision_stamps", integer=True)
            _check_values(counts[key], "nonnegative", self.where(key))
        # summed as Python integers: an int64 sum of corrupt counts could wrap around to the arrays' length
        landmark_total = sum(counts["vision_landmark_counts"].tolist())
        landmarks = {}
        for name, key, _, rule in _LANDMARK_FIELDS:
            landmarks[name] = self.array(
                key, (landmark_total,), "the sum of vision_landmark_counts", integer=name == "kinds"
            )
            _check_values(landmarks[name], rule, self.where(key))
        line_points = self.array(
            "vision_line_points",
            (sum(counts["vision_line_point_counts"].tolist()), 2),
            "the sum of vision_line_point_counts",
        )
        _check_values(line_points, "finite", self.where("vision_line_points"))
        frame_indices = np.arange(stamps.shape[0])
        return _vision_frames(
            stamps,
            received,
            np.repeat(frame_indices, counts["vision_landmark_counts"]),
            landmarks,
            np.repeat(frame_indices, counts["vision_line_point_counts"]),
            line_points,
            lambda i: f"{self.path}: vision frame {i} (vision_stamps[{i}])",
        )


# -- CSV ----------------------------------------------------------------------------------------------------------
def _cell_text(value: float) -> str:
    """A noise that was not given is an empty cell; every other number its shortest round-trip text."""
    return "" if np.isnan(value) else repr(float(value))


def _write_rows(path: Path, header: Sequence[str], rows) -> None:
    with open(path, "w", newline="", encoding="utf-8") as file:
        writer = csv.writer(file, lineterminator="\n")
        writer.writerow(header)
        writer.writerows(rows)


def write_csv(log: RobotLog, folder: str | Path) -> None:
    """Write `log` as the CSV files of the module's table into `folder` (created if needed).

    Every file of the format is written (a stream the log lacks as a header row alone); other files in the
    folder are left as they are.
    """
    folder = Path(folder)
    for name in log.joint_names:
        if not name or name != name.strip() or log.joint_names.count(name) > 1:
            raise LogError(
                f"joint name {name!r} cannot head a CSV column: joint names must be unique, "
                f"non-empty and not begin or end with white space"
            )
    keys = [(float(frame.stamp), float(frame.received)) for frame in log.vision]
    if len(set(keys)) != len(keys):
        stamp, received = next(key for key in keys if keys.count(key) > 1)
        raise LogError(
            f"two vision frames share stamp {stamp!r} s and received {received!r} s: the CSV form "
            f"tells frames apart by these times"
        )
    folder.mkdir(parents=True, exist_ok=True)
    _write_rows(
        folder / "meta.csv", ("key", "value"), [("format_version", FORMAT_VERSION), ("origin_ns", int(log.origin_ns))]
    )
    for stream in _STREAMS:
        header = ["t_s"] + [column for columns in stream.block_columns(log.joint_names) for column in columns]
        table = np.column_stack([getattr(log, key) for key in stream.keys])
        _write_rows(folder / stream.file, header, table.tolist())
    _write_rows(folder / "vision_frames.csv", _FRAME_COLUMNS, keys)
    landmark_rows: list[list[object]] = []
    line_rows: list[list[object]] = []
    for frame, (stamp, received) in zip(log.vision, keys):
        seen = frame.observations
        for kind, *numbers in zip(
            seen.kinds.tolist(), seen.ranges, seen.bearings, seen.range_sigmas, seen.bearing_sigmas
        ):
            landmark_rows.append([stamp, received, LandmarkType(kind).name] + [_cell_text(n) for n in numbers])
        line_rows.extend([stamp, received, x, y] for x, y in seen.line_points.tolist())
    _write_rows(
        folder / "vision_landmarks.csv",
        _FRAME_COLUMNS + tuple(column for _, _, column, _ in _LANDMARK_FIELDS),
        landmark_rows,
    )
    _write_rows(folder / "vision_lines.csv", _FRAME_COLUMNS + _LINE_COLUMNS, line_rows)


def _parse_noise(text: str) -> float:
    return float(text) if text.strip() else float("nan")


def _parse_kind(text: str) -> float:
    text = text.strip()
    return float(LandmarkType.parse(int(text) if text.lstrip("+-").isdigit() else text).value)


_PARSERS = {"kind": _parse_kind, "noise": _parse_noise}


@dataclass(frozen=True)
class _Table:
    """One CSV file's cells as arrays: `columns[name]` (one value per row), and each row's line in the file."""

    path: Path
    columns: dict[str, np.ndarray]
    lines: np.ndarray

    def where(self, column: str) -> Callable[[tuple[int, ...]], str]:
        return lambda index: f"{self.path}, line {self.lines[index[0]]}, column {column}"

    def __len__(self) -> int:
        return int(self.lines.shape[0])


@contextmanager
def _csv_rows(path: Path) -> Iterator[_CsvReader]:
    """A csv.reader over `path`; text that is not UTF-8 or not CSV is a LogError naming the file."""
    try:
        with open(path, newline="", encoding="utf-8") as file:
            yield csv.reader(file)
    except (csv.Error, UnicodeDecodeError) as error:
        raise LogError(f"{path}: not a UTF-8 CSV file ({error})") from None


def _read_header(path: Path) -> list[str]:
    with _csv_rows(path) as reader:
        header = next(reader, None)
    if not header:
        raise LogError(f"{path}: no header row (line 1 must name the columns)")
    return [name.strip() for name in header]


def _read_table(path: Path, rules: dict[str, str]) -> _Table:
    """The cells of `path`, whose header must name exactly the columns of `rules` (column -> rule)."""
    header = _read_header(path)
    for name in header:
        if header.count(name) > 1:
            raise LogError(f"{path}: column {name} appears twice in the header")
    missing = [name for name in rules if name not in header]
    if missing:
        raise LogError(f"{path}: missing column {', '.join(missing)} (the header is {','.join(header)})")
    unknown = [name for name in header if name not in rules]
    if unknown:
        raise LogError(f"{path}: unknown column {', '.join(unknown)} (expected {','.join(rules)})")
    parsers = [_PARSERS.get(rules[name], float) for name in header]
    rows, lines = [], []
    with _csv_rows(path) as reader:
        next(reader)
        for row in reader:
            if not row:
                continue
            if len(row) != len(header):
                raise LogError(f"{path}, line {reader.line_num}: {len(row)} cells, the header names {len(header)}")
            try:
                rows.append([parse(cell) for parse, cell in zip(parsers, row)])
            except ValueError:
                for name, parse, cell in zip(header, parsers, row):
                    try:
                        parse(cell)
                    except ValueError as error:
                        reason = error if rules[name] == "kind" else "not a number"
                        raise LogError(f"{path}, line {reader.line_num}, column {name}: {cell!r}: {reason}") from None
            lines.append(reader.line_num)
    cells = np.array(rows, dtype=np.float64).reshape(len(rows), len(header))
    table = _Table(path, {name: cells[:, i] for i, name in enumerate(header)}, np.array(lines, dtype=np.int64))
    for name, rule in rules.items():
        _check_values(table.columns[name], rule, table.where(name))
    return table


def _read_meta(path: Path) -> dict[str, int]:
    if not path.is_file():
        raise LogError(f"{path} is missing: the folder is not a columnar log (meta.csv holds its format_version)")
    meta = {}
    with _csv_rows(path) as reader:
        header = [name.strip() for name in next(reader, [])]
        if header != ["key", "value"]:
            raise LogError(f"{path}: the header is {','.join(header)!r}, expected 'key,value'")
        for row in reader:
            if not row:
                continue
            if len(row) != 2 or row[0].strip() not in _META_KEYS or row[0].strip() in meta:
                raise LogError(
                    f"{path}, line {reader.line_num}: {','.join(row)!r} is not one of the rows "
                    f"{', '.join(f'{key},<integer>' for key in _META_KEYS)} (each once)"
                )
            try:
                meta[row[0].strip()] = int(row[1])
            except ValueError:
                raise LogError(f"{path}, line {reader.line_num}, column value: {row[1]!r} is not an integer") from None
    for key in _META_KEYS:
        if key not in meta:
            raise LogError(f"{path}: the row {key},<integer> is missing")
    if meta["format_version"] != FORMAT_VERSION:
        raise LogError(f"{path}: format_version = {meta['format_version']}, this reader reads version {FORMAT_VERSION}")
    if not INT64_RANGE[0] <= meta["origin_ns"] <= INT64_RANGE[1]:
        raise LogError(
            f"{path}: origin_ns = {meta['origin_ns']} does not fit int64 (nanoseconds since the epoch, "
            f"as the NPZ form holds it)"
        )
    return meta


def _joint_names(folder: Path) -> tuple[str, ...]:
    """The joints named by the headers of the joint files (which must agree)."""
    named: dict[str, tuple[str, ...]] = {}
    for stream in _JOINT_STREAMS:
        path = folder / stream.file
        if not path.is_file():
            continue
        columns = [name for name in _read_header(path) if name != "t_s"]
        for column in columns:
            if not column.endswith(_JOINT_UNIT) or column == _JOINT_UNIT:
                raise LogError(
                    f"{path}: column {column} must be a joint name followed by {_JOINT_UNIT} (joint angles are radians)"
                )
        named[stream.file] = tuple(column[: -len(_JOINT_UNIT)] for column in columns)
    if len(set(named.values())) > 1:
        (first, first_names), (second, second_names) = named.items()
        raise LogError(
            f"{folder}: {first} names the joints {', '.join(first_names)} but {second} names {', '.join(second_names)}"
        )
    return next(iter(named.values()), ())


def _read_vision(folder: Path) -> tuple[VisionFrame, ...] | None:
    """The frames of the vision files, or None when there are none."""
    frames_path = folder / "vision_frames.csv"
    detection_paths = [folder / "vision_landmarks.csv", folder / "vision_lines.csv"]
    if not frames_path.is_file():
        for path in detection_paths:
            if path.is_file():
                raise LogError(f"{path} needs {frames_path.name}, the list of every frame's stamp_s and received_s")
        return None
    frames = _read_table(frames_path, dict.fromkeys(_FRAME_COLUMNS, "time"))
    stamps, received = frames.columns["stamp_s"], frames.columns["received_s"]
    _check_order(received, "vision", frames.where("received_s"), strictly=False)
    frame_of_key: dict[tuple[float, float], int] = {}
    for i, key in enumerate(zip(stamps.tolist(), received.tolist())):
        if key in frame_of_key:
            raise LogError(
                f"{frames_path}, line {frames.lines[i]}: a second frame with stamp_s = {key[0]!r} and "
                f"received_s = {key[1]!r} (line {frames.lines[frame_of_key[key]]})"
            )
        frame_of_key[key] = i

    def frame_indices(table: _Table) -> np.ndarray:
        indices = np.empty(len(table), dtype=np.int64)
        for row, key in enumerate(zip(table.columns["stamp_s"].tolist(), table.columns["received_s"].tolist())):
            if key not in frame_of_key:
                raise LogError(
                    f"{table.path}, line {table.lines[row]}: no frame in {frames_path.name} has "
                    f"stamp_s = {key[0]!r} and received_s = {key[1]!r}"
                )
            indices[row] = frame_of_key[key]
        return indices

    landmark_rules = dict.fromkeys(_FRAME_COLUMNS, "time") | {column: rule for _, _, column, rule in _LANDMARK_FIELDS}
    line_rules = dict.fromkeys(_FRAME_COLUMNS, "time") | dict.fromkeys(_LINE_COLUMNS, "finite")
    landmarks = {name: np.zeros(0) for name, _, _, _ in _LANDMARK_FIELDS}
    landmark_frames = line_frames = np.zeros(0, dtype=np.int64)
    line_points = np.zeros((0, 2))
    if detection_paths[0].is_file():
        table = _read_table(detection_paths[0], landmark_rules)
        landmarks = {name: table.columns[column] for name, _, column, _ in _LANDMARK_FIELDS}
        landmarks["kinds"] = landmarks["kinds"].astype(np.int64)
        landmark_frames = frame_indices(table)
    if detection_paths[1].is_file():
        table = _read_table(detection_paths[1], line_rules)
        line_points = np.column_stack([table.columns[column] for column in _LINE_COLUMNS])
        line_frames = frame_indices(table)
    return _vision_frames(
        stamps,
        received,
        landmark_frames,
        landmarks,
        line_frames,
        line_points,
        lambda i: f"{frames_path}, line {frames.lines[i]}: the frame's detections",
    )


def read_csv(folder: str | Path) -> tuple[RobotLog, ReadReport]:
    """Read a log written by `write_csv` (or by anyone following the module's table)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder} is not a folder")
    fields: dict = {"origin_ns": _read_meta(folder / "meta.csv")["origin_ns"], "joint_names": _joint_names(folder)}
    sources = {}
    for stream in _STREAMS:
        path = folder / stream.file
        if not path.is_file():
            continue
        blocks = stream.block_columns(fields["joint_names"])
        table = _read_table(path, {"t_s": "time"} | dict.fromkeys([c for columns in blocks for c in columns], "finite"))
        _check_order(table.columns["t_s"], stream.name, table.where("t_s"))
        fields[stream.times] = table.columns["t_s"]
        for (key, _), columns in zip(stream.blocks, blocks):
            # The empty block keeps the row count when there are no joints (and so no columns).
            fields[key] = np.column_stack([np.zeros((len(table), 0))] + [table.columns[c] for c in columns])
        sources[stream.name] = stream.file
    vision = _read_vision(folder)
    if vision is not None:
        fields["vision"] = vision
        sources["vision"] = "vision_frames.csv, vision_landmarks.csv, vision_lines.csv"
    log = _log(folder, fields)
    report = _report(folder, log, sources)
    known = {"meta.csv", "vision_frames.csv", "vision_landmarks.csv", "vision_lines.csv"} | {
        stream.file for stream in _STREAMS
    }
    for path in sorted(folder.glob("*.csv")):
        if path.name not in known:
            report.drop(path.name, "not a file of the columnar format")
    return log, report
