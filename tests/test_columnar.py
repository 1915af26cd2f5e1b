"""The columnar log format: NPZ and CSV round trips, hand-written files, and bad files named precisely."""

import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from field import LandmarkType
from mcl.tools.logs import LogError, RobotLog, VisionFrame
from mcl.tools.logs.columnar import FORMAT_VERSION, read_csv, read_npz, write_csv, write_npz
from sensing.observations import Observations

values = st.floats(-1e6, 1e6, allow_nan=False)
noises = st.one_of(st.just(math.nan), st.floats(1e-4, 10.0))
joint_name_text = st.text("abcXYZ_019 ,\"'.-", min_size=1, max_size=8).filter(lambda n: n == n.strip())


@st.composite
def increasing_times(draw, max_rows=4):
    steps = draw(st.lists(st.floats(1e-3, 5.0), max_size=max_rows))
    return draw(st.floats(-10.0, 10.0)) + np.cumsum(steps)


@st.composite
def stream(draw, columns, max_rows=4):
    times = draw(increasing_times(max_rows))
    table = draw(
        st.lists(st.lists(values, min_size=columns, max_size=columns), min_size=times.shape[0], max_size=times.shape[0])
    )
    return times, np.array(table, dtype=np.float64).reshape(times.shape[0], columns)


@st.composite
def observations(draw):
    count = draw(st.integers(0, 3))
    landmark = st.tuples(
        st.sampled_from(list(LandmarkType)), st.floats(0.0, 20.0), st.floats(-math.pi, math.pi), noises, noises
    )
    rows = draw(st.lists(landmark, min_size=count, max_size=count))
    coordinates = st.floats(-1e3, 1e3, allow_nan=False)  # line points within 1 km (MAX_RANGE)
    points = draw(st.lists(st.tuples(coordinates, coordinates), max_size=3))
    columns = list(zip(*rows)) if rows else [[]] * 5
    return Observations(
        np.array([int(kind) for kind in columns[0]], dtype=np.int64),
        *columns[1:],
        line_points=np.array(points).reshape(-1, 2),
    )


@st.composite
def robot_logs(draw):
    joint_names = tuple(draw(st.lists(joint_name_text, unique=True, max_size=3)))
    fields = {"origin_ns": draw(st.integers(0, 2**62)), "joint_names": joint_names}
    for times_name, names, columns in (
        ("odometry_times", ("odometry",), 3),
        ("command_times", ("commands",), 3),
        ("imu_times", ("gyro", "acceleration"), 6),
        ("joint_command_times", ("joint_commands",), len(joint_names)),
        ("joint_reading_times", ("joint_readings",), len(joint_names)),
        ("truth_times", ("truth",), 3),
    ):
        times, table = draw(stream(columns))
        fields[times_name] = times
        for i, name in enumerate(names):
            fields[name] = table[:, 3 * i : 3 * i + columns // len(names)]
    received = draw(increasing_times(max_rows=4))
    fields["vision"] = tuple(
        VisionFrame(received_at - draw(st.floats(0.0, 0.2)), float(received_at), draw(observations()))
        for received_at in received
    )
    return RobotLog(**fields)


def assert_same_log(read, written):
    assert read.origin_ns == written.origin_ns
    assert read.joint_names == written.joint_names
    for name in (
        "odometry_times",
        "odometry",
        "command_times",
        "commands",
        "imu_times",
        "gyro",
        "acceleration",
        "joint_command_times",
        "joint_commands",
        "joint_reading_times",
        "joint_readings",
        "truth_times",
        "truth",
    ):
        np.testing.assert_array_equal(getattr(read, name), getattr(written, name), err_msg=name)
        assert getattr(read, name).shape == getattr(written, name).shape, name
    assert len(read.vision) == len(written.vision)
    for frame_read, frame_written in zip(read.vision, written.vision):
        assert (frame_read.stamp, frame_read.received) == (frame_written.stamp, frame_written.received)
        for name in ("kinds", "ranges", "bearings", "range_sigmas", "bearing_sigmas", "line_points"):
            np.testing.assert_array_equal(
                getattr(frame_read.observations, name), getattr(frame_written.observations, name), err_msg=name
            )
        assert frame_read.observations.kinds.dtype == np.int64


def sample_log():
    seen = Observations.from_arrays(
        ["goalpost", "t_crossing"], [1.0, 2.5], [0.1, -0.2], [0.1, math.nan], line_points=[[1.0, 2.0], [3.0, 4.0]]
    )
    return RobotLog(
        origin_ns=1_700_000_000_000_000_000,
        odometry_times=[0.0, 0.1, 0.2],
        odometry=[[0.0, 0.0, 0.0], [0.1, 0.0, 0.01], [0.2, 0.01, 0.02]],
        imu_times=[0.0, 0.01],
        gyro=np.zeros((2, 3)),
        acceleration=[[0, 0, 9.81]] * 2,
        joint_names=("HeadYaw", "HeadPitch"),
        joint_reading_times=[0.05],
        joint_readings=[[0.1, 0.2]],
        vision=(VisionFrame(0.0, 0.02, seen), VisionFrame(0.05, 0.07, Observations.empty())),
    )


@pytest.fixture
def csv_folder(tmp_path):
    write_csv(sample_log(), tmp_path / "log")
    return tmp_path / "log"


@pytest.fixture
def npz_path(tmp_path):
    write_npz(sample_log(), tmp_path / "log.npz")
    return tmp_path / "log.npz"


def replace_in(path, old, new):
    text = path.read_text()
    assert old in text, (old, text)
    path.write_text(text.replace(old, new, 1))


def rewrite_npz(path, **changes):
    """The NPZ at `path` with keys replaced (a value None removes the key)."""
    with np.load(path) as archive:
        arrays = {key: archive[key] for key in archive.files}
    for key, value in changes.items():
        if value is None:
            del arrays[key]
        else:
            arrays[key] = value
    with open(path, "wb") as file:
        np.savez(file, **arrays)


# -- round trips --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("write,read", [(write_npz, read_npz), (write_csv, read_csv)], ids=["npz", "csv"])
@settings(max_examples=25)
@given(log=robot_logs())
def test_log_survives_a_round_trip(write, read, log):
    with tempfile.TemporaryDirectory() as folder:
        write(log, Path(folder) / "game")
        read_back, report = read(Path(folder) / "game")
    assert_same_log(read_back, log)
    assert report.complete and not report.dropped


def test_report_counts_the_rows_of_each_stream(npz_path, csv_folder):
    for read in (read_npz(npz_path)[1], read_csv(csv_folder)[1]):
        assert read.messages == {"odometry": 3, "imu": 2, "joint_readings": 1, "vision": 2}


def test_empty_log_survives_both_forms(tmp_path):
    write_npz(RobotLog(), tmp_path / "empty.npz")
    write_csv(RobotLog(), tmp_path / "empty")
    for read in (read_npz(tmp_path / "empty.npz")[0], read_csv(tmp_path / "empty")[0]):
        assert_same_log(read, RobotLog())


def test_hand_written_csv_needs_only_what_it_has(tmp_path):
    (tmp_path / "meta.csv").write_text("key,value\norigin_ns,5\nformat_version,1\n")
    (tmp_path / "odometry.csv").write_text("yaw_rad, t_s ,x_m,y_m\n0.5,0.0,1,2\n\n0.25,1e-1,1.5,2.5\n")
    (tmp_path / "vision_frames.csv").write_text("stamp_s,received_s\n0.0,0.03\n0.1,0.13\n")
    (tmp_path / "vision_landmarks.csv").write_text(
        "stamp_s,received_s,kind,range_m,bearing_rad,range_sigma_m,bearing_sigma_rad\n"
        "0.1,0.13,4,1.0,0.0,nan,0.05\n0.1,0.13,goalpost,2.0,0.5,0.2,\n"
    )
    (tmp_path / "notes.csv").write_text("anything\n")
    log, report = read_csv(tmp_path)
    assert log.origin_ns == 5
    np.testing.assert_array_equal(log.odometry_times, [0.0, 0.1])
    np.testing.assert_array_equal(log.odometry, [[1.0, 2.0, 0.5], [1.5, 2.5, 0.25]])
    assert log.vision[0].observations.is_empty
    np.testing.assert_array_equal(log.vision[1].observations.kinds, [LandmarkType.PENALTY_MARK, LandmarkType.GOALPOST])
    np.testing.assert_array_equal(log.vision[1].observations.range_sigmas, [math.nan, 0.2])
    assert log.imu_times.shape == (0,) and log.joint_names == ()
    assert report.dropped == {("notes.csv", "not a file of the columnar format"): 1}


def test_hand_written_csv_may_name_kinds_by_alias(tmp_path):
    (tmp_path / "meta.csv").write_text("key,value\norigin_ns,5\nformat_version,1\n")
    (tmp_path / "vision_frames.csv").write_text("stamp_s,received_s\n0.1,0.13\n")
    rows = "".join(
        f"0.1,0.13,{kind},1.0,0.0,,\n" for kind in ("post", "L", "t-crossing", "X", "penalty mark", "centre")
    )
    (tmp_path / "vision_landmarks.csv").write_text(
        "stamp_s,received_s,kind,range_m,bearing_rad,range_sigma_m,bearing_sigma_rad\n" + rows
    )
    log, _ = read_csv(tmp_path)
    np.testing.assert_array_equal(log.vision[0].observations.kinds, np.arange(6))
    (tmp_path / "vision_landmarks.csv").write_text(
        "stamp_s,received_s,kind,range_m,bearing_rad,range_sigma_m,bearing_sigma_rad\n0.1,0.13,corner,1,0,,\n"
    )
    with pytest.raises(LogError, match=r"line 2.*'corner'.*aliases"):
        read_csv(tmp_path)


def test_hand_written_npz_may_leave_streams_out(tmp_path):
    with open(tmp_path / "log.npz", "wb") as file:
        np.savez(
            file,
            format_version=np.int32(1),
            origin_ns=np.int64(7),
            truth_times=np.float32([0.0, 0.5]),
            truth=np.float32([[1, 2, 3], [1, 2, 3]]),
            custom=np.zeros(2),
        )
    log, report = read_npz(tmp_path / "log.npz")
    np.testing.assert_array_equal(log.truth_times, [0.0, 0.5])
    assert log.odometry.shape == (0, 3) and log.vision == ()
    assert report.dropped == {("custom", "not a key of the columnar format"): 1}


# -- bad NPZ files ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "changes,match",
    [
        (dict(format_version=np.int64(FORMAT_VERSION + 1)), "format_version = 2, this reader reads version 1"),
        (dict(format_version=None), "format_version is missing"),
        (dict(origin_ns=np.float64(1.5)), "origin_ns has dtype float64, expected integers"),
        (dict(odometry=np.zeros((3, 2))), r"odometry has shape \(3, 2\), expected \(3, 3\)"),
        (dict(odometry=np.array(["a", "b", "c"])), "odometry has dtype <U1, expected numbers"),
        (dict(odometry=None), "odometry has odometry_times but not odometry"),
        (
            dict(odometry_times=np.array([0.0, 0.2, 0.1])),
            r"odometry_times\[2\] = 0.1 s does not follow 0.2 s: "
            r"the times of odometry must increase",
        ),
        (dict(imu_times=np.array([0.0, np.nan])), r"imu_times\[1\] = nan must be finite"),
        (
            dict(odometry_times=np.array([0.0, 0.1, 1e9])),
            r"odometry_times\[2\] = 1000000000.0 s lies 1e\+09 s after "
            r"0.1 s: consecutive times of odometry must be at most "
            r"MAX_STEP_DT = 3600 s apart",
        ),
        (dict(imu_times=np.array([0.0, 3600.5])), r"imu_times\[1\] = 3600.5 s lies 3600.5 s after 0.0 s"),
        (
            dict(joint_readings=np.zeros((1, 3))),
            r"joint_readings has shape \(1, 3\), expected \(1, 2\) "
            r"\(one row per joint_reading_times, one column per joint_names",
        ),
        (dict(joint_names=np.array([1, 2])), "joint_names has dtype int64"),
        (dict(vision_ranges=np.array([1.0, -2.0])), r"vision_ranges\[1\] = -2.0 must be finite and >= 0"),
        (dict(vision_kinds=np.array([0, 9])), r"vision_kinds\[1\] = 9 is not a landmark type value"),
        (dict(vision_range_sigmas=np.array([0.0, np.nan])), r"vision_range_sigmas\[0\] = 0.0 must be > 0"),
        (
            dict(vision_landmark_counts=np.array([2, 1])),
            r"vision_kinds has shape \(2,\), expected \(3,\) "
            r"\(the sum of vision_landmark_counts\)",
        ),
        (dict(vision_line_points=np.zeros((3, 2))), r"vision_line_points has shape \(3, 2\), expected \(2, 2\)"),
        (dict(vision_received=np.array([0.2, 0.1])), r"vision_received\[1\] = 0.1 s does not follow 0.2 s"),
        (dict(vision_stamps=None), "vision has .* but not vision_stamps"),
    ],
)
def test_bad_npz_is_named(npz_path, changes, match):
    rewrite_npz(npz_path, **changes)
    with pytest.raises(LogError, match=match) as error:
        read_npz(npz_path)
    assert str(npz_path) in str(error.value)


def test_a_step_longer_than_any_motion_step_is_refused_at_load(tmp_path):
    # a 1e9 s step in a stream: refused by the reader, naming the file, not first by the replay's motion step
    from mcl.tools.logs import read_log
    from motion_models.base import MAX_STEP_DT

    log = sample_log()
    times = log.odometry_times.copy()
    times[1:] += 1e9
    path = tmp_path / "gap.npz"
    write_npz(log, path)
    rewrite_npz(path, odometry_times=times)
    before = path.read_bytes()
    with pytest.raises(LogError) as error:
        read_log(path)
    message = str(error.value)
    assert message.startswith(f"{path}: odometry_times[1] = ") and "\n" not in message
    assert f"at most MAX_STEP_DT = {MAX_STEP_DT:g} s apart" in message
    assert path.read_bytes() == before  # the refused read changed nothing
    # a step of exactly MAX_STEP_DT is a log's longest gap, and is read
    rewrite_npz(path, odometry_times=np.array([0.0, MAX_STEP_DT, MAX_STEP_DT + 0.1]))
    read, _ = read_log(path)
    assert read.odometry_times.tolist() == [0.0, MAX_STEP_DT, MAX_STEP_DT + 0.1]


def test_pickled_array_is_refused(npz_path):
    rewrite_npz(npz_path, joint_names=np.array(["HeadYaw", None], dtype=object))
    with pytest.raises(LogError, match="joint_names cannot be read"):
        read_npz(npz_path)


def test_what_is_not_an_npz_is_named(tmp_path):
    (tmp_path / "garbage.npz").write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(LogError, match="garbage.npz: not an NPZ file"):
        read_npz(tmp_path / "garbage.npz")
    np.save(tmp_path / "single.npy", np.zeros(3))
    with pytest.raises(LogError, match="single.npy: holds a single array"):
        read_npz(tmp_path / "single.npy")
    with pytest.raises(FileNotFoundError):
        read_npz(tmp_path / "absent.npz")


# -- bad CSV folders ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "file,old,new,match",
    [
        (
            "meta.csv",
            "format_version,1",
            "format_version,2",
            r"meta.csv: format_version = 2, this reader reads version 1",
        ),
        (
            "meta.csv",
            "origin_ns,1700000000000000000",
            "origin_ns,1.7e18",
            r"meta.csv, line 3, column value: '1.7e18' is not an integer",
        ),
        ("meta.csv", "origin_ns", "origin", r"meta.csv, line 3: 'origin,1700000000000000000' is not one of the rows"),
        ("odometry.csv", "t_s,x_m,y_m,yaw_rad", "t_s,x_m,yaw_rad", r"odometry.csv: missing column y_m"),
        ("odometry.csv", "t_s,x_m,y_m,yaw_rad", "t_s,x_m,y_m,yaw_rad,z_m", r"odometry.csv: unknown column z_m"),
        ("odometry.csv", "t_s,x_m,y_m,yaw_rad", "t_s,x_m,x_m,yaw_rad", "column x_m appears twice"),
        (
            "odometry.csv",
            "0.1,0.1,0.0,0.01",
            "0.1,0.1,zero,0.01",
            r"odometry.csv, line 3, column y_m: 'zero': not a number",
        ),
        ("odometry.csv", "0.1,0.1,0.0,0.01", "0.1,0.1,0.0", r"odometry.csv, line 3: 3 cells, the header names 4"),
        (
            "odometry.csv",
            "0.1,0.1,0.0,0.01",
            "0.1,0.1,inf,0.01",
            r"odometry.csv, line 3, column y_m = inf must be finite",
        ),
        (
            "odometry.csv",
            "0.2,",
            "0.05,",
            r"odometry.csv, line 4, column t_s = 0.05 s does not follow 0.1 s: "
            r"the times of odometry must increase",
        ),
        ("imu.csv", "0.01,", "0.0,", r"imu.csv, line 3, column t_s = 0.0 s does not follow 0.0 s"),
        (
            "odometry.csv",
            "0.2,",
            "1000000000.0,",
            r"odometry.csv, line 4, column t_s = 1000000000.0 s lies 1e\+09 s "
            r"after 0.1 s: consecutive times of odometry must be at most",
        ),
        ("joint_readings.csv", "HeadPitch_rad", "HeadPitch", r"column HeadPitch must be a joint name followed by _rad"),
        (
            "joint_readings.csv",
            "HeadPitch_rad",
            "HeadRoll_rad",
            r"joint_commands.csv names the joints HeadYaw, HeadPitch but joint_readings.csv names HeadYaw, HeadRoll",
        ),
        (
            "vision_landmarks.csv",
            "GOALPOST",
            "CORNER_FLAG",
            r"vision_landmarks.csv, line 2, column kind: 'CORNER_FLAG': "
            r"landmark type 'CORNER_FLAG' is unknown",
        ),
        (
            "vision_landmarks.csv",
            "GOALPOST,1.0",
            "GOALPOST,-1.0",
            r"vision_landmarks.csv, line 2, column range_m = -1.0 must be finite and >= 0",
        ),
        (
            "vision_landmarks.csv",
            "0.1,\n",
            "-0.1,\n",
            r"vision_landmarks.csv, line 2, column range_sigma_m = -0.1 must "
            r"be > 0",
        ),
        (
            "vision_landmarks.csv",
            "0.0,0.02,T_CROSSING",
            "0.0,0.03,T_CROSSING",
            r"vision_landmarks.csv, line 3: no frame in vision_frames.csv has stamp_s = 0.0 and received_s = 0.03",
        ),
        ("vision_lines.csv", "0.0,0.02,3.0", "0.0,0.021,3.0", r"vision_lines.csv, line 3: no frame in vision_frames"),
        (
            "vision_frames.csv",
            "0.05,0.07",
            "0.0,0.02",
            r"vision_frames.csv, line 3: a second frame with stamp_s = 0.0 "
            r"and received_s = 0.02 \(line 2\)",
        ),
        (
            "vision_frames.csv",
            "0.05,0.07",
            "0.05,0.01",
            r"vision_frames.csv, line 3, column received_s = 0.01 s does "
            r"not follow 0.02 s: the times of vision must never decrease",
        ),
    ],
)
def test_bad_csv_is_named(csv_folder, file, old, new, match):
    replace_in(csv_folder / file, old, new)
    with pytest.raises(LogError, match=match) as error:
        read_csv(csv_folder)
    assert str(csv_folder) in str(error.value)


def test_missing_csv_files_are_named(csv_folder, tmp_path):
    (csv_folder / "vision_frames.csv").unlink()
    with pytest.raises(LogError, match="vision_landmarks.csv needs vision_frames.csv"):
        read_csv(csv_folder)
    (csv_folder / "meta.csv").unlink()
    with pytest.raises(LogError, match="meta.csv is missing: the folder is not a columnar log"):
        read_csv(csv_folder)
    (csv_folder / "meta.csv").write_text("")
    with pytest.raises(LogError, match="meta.csv: the header is '', expected 'key,value'"):
        read_csv(csv_folder)
    (csv_folder / "meta.csv").write_text("key,value\nformat_version,1\n")
    with pytest.raises(LogError, match="the row origin_ns,<integer> is missing"):
        read_csv(csv_folder)
    (csv_folder / "meta.csv").write_text("key,value\nformat_version,1\norigin_ns,0\n")
    (csv_folder / "truth.csv").write_text("")
    with pytest.raises(LogError, match="truth.csv: no header row"):
        read_csv(csv_folder)
    with pytest.raises(FileNotFoundError):
        read_csv(tmp_path / "absent")


def test_what_is_not_csv_text_is_named(csv_folder):
    (csv_folder / "truth.csv").write_bytes(b"t_s,x_m,y_m,theta_rad\n\xff\xfe0,1,2,3\n")
    with pytest.raises(LogError, match="truth.csv: not a UTF-8 CSV file"):
        read_csv(csv_folder)


def test_csv_writer_refuses_what_csv_cannot_tell_apart(tmp_path):
    twins = RobotLog(vision=(VisionFrame(0.0, 0.1, Observations.empty()), VisionFrame(0.0, 0.1, Observations.empty())))
    with pytest.raises(LogError, match="two vision frames share stamp 0.0 s and received 0.1 s"):
        write_csv(twins, tmp_path / "twins")
    for names in (("a", "a"), ("",), (" a",)):
        log = RobotLog(joint_names=names, joint_command_times=[0.0], joint_commands=[[0.0] * len(names)])
        with pytest.raises(LogError, match="joint name"):
            write_csv(log, tmp_path / "joints")
    assert not (tmp_path / "twins").exists() and not (tmp_path / "joints").exists()


def test_csv_writer_replaces_an_older_log(tmp_path):
    write_csv(sample_log(), tmp_path)
    write_csv(RobotLog(origin_ns=3), tmp_path)
    assert_same_log(read_csv(tmp_path)[0], RobotLog(origin_ns=3))
    shutil.rmtree(tmp_path)
