"""ROS 2 MCAP logs: round trips, the topic table, vision mapping, and every way a log can be broken.

Every file here is written by the real MCAP writers (ours, or mcap_ros2's with our schemas) and read by
the real reader.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap_ros2.writer import Writer as Ros2Writer

from field import LandmarkType
from mcl.tools.logs import LogError, RobotLog, VisionFrame, schemas
from mcl.tools.logs.mcap_io import PoseWriter, Topics, list_topics, read_mcap, read_poses, write_mcap
from sensing.observations import Observations

ORIGIN_NS = 1_700_000_000_000_000_000
SECOND = 1_000_000_000


def stamp(ns: int, frame_id: str = "odom") -> dict:
    return {"stamp": {"sec": ns // SECOND, "nanosec": ns % SECOND}, "frame_id": frame_id}


def odometry(ns: int, x: float, y: float = 0.0) -> dict:
    return {"header": stamp(ns), "pose": {"pose": {"position": {"x": x, "y": y, "z": 0.0}}}}


def write_raw(path, messages) -> None:
    """Write (topic, type, message dict, log time ns) with mcap_ros2's writer and our schemas, in the given order."""
    registered = {}
    with open(path, "wb") as file:
        writer = Ros2Writer(file)
        for topic, type_name, message, log_ns in messages:
            if type_name not in registered:
                registered[type_name] = writer.register_msgdef(type_name, schemas.definition(type_name))
            writer.write_message(topic, registered[type_name], message, log_time=log_ns)
        writer.finish()


def angle_difference(a, b):
    return np.remainder(np.asarray(a) - np.asarray(b) + math.pi, 2 * math.pi) - math.pi


def canonical(observations: Observations) -> np.ndarray:
    """The landmarks as sorted (kind, range, bearing) rows: a frame's order is not carried by the messages."""
    rows = np.stack([observations.kinds.astype(float), observations.ranges, observations.bearings], axis=1)
    return rows[np.lexsort(rows.T[::-1])]


# -- round trip -----------------------------------------------------------------------------------------------
@st.composite
def robot_logs(draw):
    def times(max_size=6):
        ticks = sorted(draw(st.sets(st.integers(0, 20 * SECOND), max_size=max_size)))
        return np.array(ticks, dtype=np.float64) / 1e9

    def rows(n, columns, low=-20.0, high=20.0):
        values = draw(st.lists(st.floats(low, high), min_size=n * columns, max_size=n * columns))
        return np.array(values, dtype=np.float64).reshape(n, columns)

    def poses(n):
        return np.concatenate([rows(n, 2), rows(n, 1, -3.1, 3.1)], axis=1)

    names = tuple(draw(st.lists(st.text("abcxyz_", min_size=1, max_size=6), unique=True, max_size=3)))
    odometry_times, command_times, imu_times, truth_times = times(), times(), times(), times()
    reading_times = times() if names else np.zeros(0)
    command_joint_times = times() if names else np.zeros(0)
    frames = []
    frame_stamps = sorted(draw(st.sets(st.integers(0, 20 * SECOND), max_size=4)))
    latency = draw(st.integers(0, SECOND // 5))  # one camera: frames arrive in the order they were taken
    for frame_stamp in frame_stamps:
        n = draw(st.integers(0, 6))
        kinds = draw(st.lists(st.sampled_from(list(LandmarkType)), min_size=n, max_size=n))
        observations = Observations.from_arrays(
            kinds,
            rows(1, n, 0.1, 12.0)[0],
            rows(1, n, -3.1, 3.1)[0],
            line_points=rows(draw(st.integers(0, 3)), 2, -9.0, 9.0),
        )
        frames.append(VisionFrame(frame_stamp / 1e9, (frame_stamp + latency) / 1e9, observations))
    frames.sort(key=lambda frame: frame.received)
    return RobotLog(
        origin_ns=draw(st.integers(ORIGIN_NS, ORIGIN_NS + 1000 * SECOND)),
        odometry_times=odometry_times,
        odometry=poses(len(odometry_times)),
        command_times=command_times,
        commands=rows(len(command_times), 3),
        imu_times=imu_times,
        gyro=rows(len(imu_times), 3),
        acceleration=rows(len(imu_times), 3),
        joint_names=names,
        joint_reading_times=reading_times,
        joint_readings=rows(len(reading_times), len(names)),
        joint_command_times=command_joint_times,
        joint_commands=rows(len(command_joint_times), len(names)),
        truth_times=truth_times,
        truth=poses(len(truth_times)),
        vision=tuple(frames),
    )


def assert_same_log(back: RobotLog, log: RobotLog) -> None:
    """Values to float64 rounding (vision landmarks to 1e-9), times to the nanosecond they are written at."""
    assert back.origin_ns == log.origin_ns
    for times in (
        "odometry_times",
        "command_times",
        "imu_times",
        "truth_times",
        "joint_reading_times",
        "joint_command_times",
    ):
        np.testing.assert_allclose(getattr(back, times), getattr(log, times), rtol=0, atol=1e-9, err_msg=times)
    np.testing.assert_allclose(back.commands, log.commands, rtol=0, atol=0)
    np.testing.assert_allclose(back.gyro, log.gyro, rtol=0, atol=0)
    np.testing.assert_allclose(back.acceleration, log.acceleration, rtol=0, atol=0)
    for name in ("odometry", "truth"):
        np.testing.assert_allclose(getattr(back, name)[:, :2], getattr(log, name)[:, :2], rtol=0, atol=1e-12)
        assert np.abs(angle_difference(getattr(back, name)[:, 2], getattr(log, name)[:, 2])).max(initial=0) < 1e-12
    if log.joint_reading_times.shape[0]:  # names travel with the readings
        assert back.joint_names == log.joint_names
        for name in ("joint_readings", "joint_commands"):
            np.testing.assert_array_equal(getattr(back, name), getattr(log, name), err_msg=name)
    assert len(back.vision) == len(log.vision)
    for got, want in zip(back.vision, log.vision):
        assert got.stamp == pytest.approx(want.stamp, abs=1e-9)
        assert got.received == pytest.approx(want.received, abs=1e-9)
        np.testing.assert_allclose(canonical(got.observations), canonical(want.observations), rtol=0, atol=1e-9)
        np.testing.assert_allclose(got.observations.line_points, want.observations.line_points, rtol=0, atol=1e-12)


@settings(max_examples=8)
@given(log=robot_logs())
def test_write_then_read_gives_the_same_log(tmp_path_factory, log):
    path = tmp_path_factory.mktemp("round") / "log.mcap"
    write_mcap(log, path)
    back, report = read_mcap(path)
    assert report.complete and report.dropped == {}
    assert_same_log(back, log)


def full_log() -> RobotLog:
    t = np.arange(5) * 0.1
    rng = np.random.default_rng(7)
    observations = Observations.from_arrays(
        list(LandmarkType),
        [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
        [0.1, -0.2, 0.3, 3.0, -3.0, 0.5],
        line_points=[[1.0, 2.0], [3.0, 4.0]],
    )
    return RobotLog(
        origin_ns=ORIGIN_NS,
        odometry_times=t,
        odometry=rng.uniform(-1, 1, (5, 3)),
        command_times=t,
        commands=rng.uniform(-1, 1, (5, 3)),
        imu_times=t,
        gyro=rng.uniform(-1, 1, (5, 3)),
        acceleration=rng.uniform(-1, 1, (5, 3)),
        joint_names=("head_pan", "l_knee"),
        joint_command_times=t,
        joint_commands=rng.uniform(-1, 1, (5, 2)),
        joint_reading_times=t,
        joint_readings=rng.uniform(-1, 1, (5, 2)),
        truth_times=t,
        truth=rng.uniform(-1, 1, (5, 3)),
        vision=(VisionFrame(0.15, 0.2, observations),),
    )


def test_round_trip_of_every_stream_on_other_topics(tmp_path):
    log = full_log()
    topics = Topics(odometry="/odom", goalposts="/vision/goalposts")
    write_mcap(log, tmp_path / "log.mcap", topics)
    back, report = read_mcap(tmp_path / "log.mcap", topics)
    assert_same_log(back, log)
    assert report.messages["/odom"] == 5 and report.types["/odom"] == schemas.ODOMETRY
    assert report.missing == []


# -- list_topics ----------------------------------------------------------------------------------------------
def test_list_topics_from_the_summary_and_from_a_truncated_file(tmp_path):
    write_mcap(full_log(), tmp_path / "log.mcap")
    rows = {row["topic"]: row for row in list_topics(tmp_path / "log.mcap")}
    topics = Topics()
    assert set(rows) == {getattr(topics, stream) for stream in Topics.STREAMS}
    assert rows["/motion_odometry"] == {
        "topic": "/motion_odometry",
        "type": schemas.ODOMETRY,
        "count": 5,
        "first_s": 0.0,
        "last_s": pytest.approx(0.4),
    }
    assert rows["/goal_posts_relative"]["first_s"] == pytest.approx(0.2)  # log time: arrival
    data = (tmp_path / "log.mcap").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[:-40])  # no footer, no summary
    assert list_topics(tmp_path / "cut.mcap") == list(rows.values())


# -- vision ---------------------------------------------------------------------------------------------------
def point(x, y):
    return {"x": x, "y": y, "z": 0.0}


def test_vision_kinds_segments_and_frames(tmp_path):
    header = stamp(ORIGIN_NS + SECOND, "base_footprint")
    goalposts = {"header": header, "posts": [{"bb": {"center": {"position": point(3.0, 4.0)}}}]}
    markings = {
        "header": header,
        "intersections": [{"center": point(1.0, 0.0), "num_rays": rays} for rays in (2, 3, 4, 5)],
        "ellipses": [
            {"diameter": 0.12, "center": {"position": point(0.0, 2.0)}},
            {"diameter": 1.5, "center": {"position": point(-1.0, 0.0)}},
        ],
        "segments": [
            {"start": point(0.0, 0.0), "end": point(0.45, 0.0)},
            {"start": point(2.0, 2.0), "end": point(2.0, 2.0)},
        ],
    }
    later = {"header": stamp(ORIGIN_NS + 2 * SECOND, "base_footprint"), "posts": []}
    write_raw(
        tmp_path / "v.mcap",
        [
            ("/goal_posts_relative", schemas.GOALPOST_ARRAY, goalposts, ORIGIN_NS + SECOND + 30_000_000),
            ("/markings_relative", schemas.MARKING_ARRAY, markings, ORIGIN_NS + SECOND + 50_000_000),
            ("/goal_posts_relative", schemas.GOALPOST_ARRAY, later, ORIGIN_NS + 2 * SECOND + 10_000_000),
        ],
    )
    log, report = read_mcap(tmp_path / "v.mcap")
    assert report.dropped == {("/markings_relative", "intersection with 5 rays"): 1}
    assert len(log.vision) == 2
    frame = log.vision[0]
    assert frame.stamp == pytest.approx(-0.03) and frame.received == pytest.approx(0.02)  # origin: first log time
    obs = frame.observations
    assert obs.kinds.tolist() == [
        LandmarkType.GOALPOST,
        LandmarkType.L_CROSSING,
        LandmarkType.T_CROSSING,
        LandmarkType.X_CROSSING,
        LandmarkType.PENALTY_MARK,
        LandmarkType.CENTER_MARK,
    ]
    np.testing.assert_allclose(obs.ranges, [5.0, 1.0, 1.0, 1.0, 2.0, 1.0])
    np.testing.assert_allclose(obs.bearings, [math.atan2(4, 3), 0, 0, 0, math.pi / 2, math.pi])
    np.testing.assert_allclose(obs.line_points, [[0.0, 0.0], [0.15, 0.0], [0.3, 0.0], [0.45, 0.0], [2.0, 2.0]])
    assert log.vision[1].observations.is_empty


# -- broken files ---------------------------------------------------------------------------------------------
def long_log(n=120) -> RobotLog:
    t = np.arange(n) * 10_000_000 / 1e9  # on the nanosecond grid, so times read back exactly
    rng = np.random.default_rng(3)
    return RobotLog(
        origin_ns=ORIGIN_NS,
        odometry_times=t,
        odometry=rng.uniform(-1, 1, (n, 3)),
        imu_times=t,
        gyro=rng.uniform(-1, 1, (n, 3)),
        acceleration=rng.uniform(-1, 1, (n, 3)),
    )


def test_a_truncated_file_gives_the_messages_before_the_break(tmp_path):
    log = long_log()
    write_mcap(log, tmp_path / "log.mcap", chunk_size=1500)
    data = (tmp_path / "log.mcap").read_bytes()
    header_end = 8 + 9 + int.from_bytes(data[9:17], "little")  # magic, then the Header record
    read_counts = []
    for cut in np.linspace(header_end, len(data) - 1, 25).astype(int):
        (tmp_path / "cut.mcap").write_bytes(data[:cut])
        back, report = read_mcap(tmp_path / "cut.mcap")
        assert report.stop_reason is not None and not report.complete
        k = len(back.odometry_times)
        np.testing.assert_array_equal(back.odometry_times, log.odometry_times[:k])
        np.testing.assert_allclose(back.odometry[:, :2], log.odometry[:k, :2], rtol=0, atol=1e-15)
        np.testing.assert_array_equal(back.gyro, log.gyro[: len(back.imu_times)])
        if k:
            assert report.stopped_at == pytest.approx(max(back.odometry_times[-1], back.imu_times[-1]))
        read_counts.append(k)
    assert read_counts == sorted(read_counts) and read_counts[0] == 0 and read_counts[-1] == len(log.odometry_times)
    assert any(0 < k < len(log.odometry_times) for k in read_counts)
    with pytest.raises(LogError, match="not an MCAP file"):  # cut inside the header
        (tmp_path / "cut.mcap").write_bytes(data[: header_end - 3])
        read_mcap(tmp_path / "cut.mcap")


def test_a_corrupt_chunk_stops_the_read_there(tmp_path):
    write_mcap(long_log(), tmp_path / "log.mcap", chunk_size=1500)
    data = bytearray((tmp_path / "log.mcap").read_bytes())
    data[len(data) // 2] ^= 0xFF
    (tmp_path / "bad.mcap").write_bytes(bytes(data))
    back, report = read_mcap(tmp_path / "bad.mcap")
    assert report.stop_reason is not None
    assert 0 < len(back.odometry_times) < 120


@pytest.mark.parametrize("content", [b"", b"hello, this is not a log\n" * 20, b"\x89MCAP0\r\n" + b"\x00" * 3])
def test_a_file_that_is_not_mcap_is_rejected(tmp_path, content):
    (tmp_path / "garbage.mcap").write_bytes(content)
    with pytest.raises(LogError, match="not an MCAP file"):
        read_mcap(tmp_path / "garbage.mcap")
    with pytest.raises(LogError, match="not an MCAP file"):
        list_topics(tmp_path / "garbage.mcap")


# -- topics ---------------------------------------------------------------------------------------------------
def test_a_missing_topic_is_an_error_only_when_named(tmp_path):
    write_raw(tmp_path / "o.mcap", [("/odom", schemas.ODOMETRY, odometry(ORIGIN_NS, 1.0), ORIGIN_NS)])
    log, report = read_mcap(tmp_path / "o.mcap", Topics(odometry="/odom"))
    assert len(log.odometry_times) == 1 and "/cmd_vel" in report.missing and "not in the log" in report.summary()
    with pytest.raises(LogError, match=r"/motion_odom.*has: /odom"):
        read_mcap(tmp_path / "o.mcap", Topics().override(odometry="/motion_odom", imu=None))
    assert Topics(odometry="odom").odometry == "/odom"  # ROS resolves it in the root namespace
    assert Topics(odometry="odom", truth="", imu=Topics.imu).required == {"odometry"}
    with pytest.raises(ValueError, match="teleport"):
        Topics().override(teleport="/x")
    with pytest.raises(ValueError, match="more than one stream"):
        Topics(commands="/motion_odometry")


RENAMED = Topics(
    odometry="/odom",
    commands="/walk/cmd_vel",
    imu="/imu/raw",
    goalposts="/vision/posts",
    markings="/vision/markings",
    truth="/sim/truth",
    joint_commands="",
)


def test_a_default_topic_the_log_lacks_is_found_by_its_type(tmp_path):
    log = full_log()
    write_mcap(log, tmp_path / "renamed.mcap", RENAMED)
    back, report = read_mcap(tmp_path / "renamed.mcap")
    for name in (
        "odometry_times",
        "odometry",
        "command_times",
        "commands",
        "imu_times",
        "gyro",
        "acceleration",
        "joint_reading_times",
        "joint_readings",
    ):
        np.testing.assert_allclose(getattr(back, name), getattr(log, name), rtol=0, atol=1e-9, err_msg=name)
    assert len(back.vision) == 1
    np.testing.assert_allclose(canonical(back.vision[0].observations), canonical(log.vision[0].observations), atol=1e-9)
    assert report.topics == {
        "odometry": ("/odom", "type"),
        "commands": ("/walk/cmd_vel", "type"),
        "joint_states": ("/joint_states", "default name"),
        "imu": ("/imu/raw", "type"),
        "goalposts": ("/vision/posts", "type"),
        "markings": ("/vision/markings", "type"),
    }
    # Ground truth is never guessed from a pose topic, and a JointState topic is not taken for the commands.
    assert not back.has_truth and back.joint_command_times.shape == (0,)
    assert report.missing == ["/joint_commands", "/ground_truth"]
    summary = report.summary()
    assert "odometry from /odom (by type: the log's only nav_msgs/msg/Odometry topic)" in summary
    assert "joint states from /joint_states (by name, the default)" in summary
    assert report.to_json()["topics"]["commands"] == {"topic": "/walk/cmd_vel", "by": "type"}
    _, named = read_mcap(tmp_path / "renamed.mcap", Topics(truth="/sim/truth", odometry="/odom"))
    assert named.topics["truth"] == ("/sim/truth", "name") and named.topics["odometry"] == ("/odom", "name")


def test_several_topics_of_a_missing_streams_type_are_an_error_naming_them(tmp_path):
    write_raw(
        tmp_path / "two.mcap",
        [
            ("/odom", schemas.ODOMETRY, odometry(ORIGIN_NS, 1.0), ORIGIN_NS),
            ("/odometry/filtered", schemas.ODOMETRY, odometry(ORIGIN_NS, 2.0), ORIGIN_NS),
        ],
    )
    with pytest.raises(
        LogError,
        match=r"/motion_odometry \(odometry\) is not in the log.*2 topics carry "
        r"nav_msgs/Odometry: /odom, /odometry/filtered; choose one with "
        r"--topic-odometry",
    ):
        read_mcap(tmp_path / "two.mcap")
    log, report = read_mcap(tmp_path / "two.mcap", Topics(odometry="/odometry/filtered"))
    assert log.odometry[:, 0].tolist() == [2.0] and report.topics["odometry"] == ("/odometry/filtered", "name")
    # The default topic, when there, is read whatever else the log holds.
    write_raw(
        tmp_path / "default.mcap",
        [
            ("/odom", schemas.ODOMETRY, odometry(ORIGIN_NS, 1.0), ORIGIN_NS),
            ("/motion_odometry", schemas.ODOMETRY, odometry(ORIGIN_NS, 3.0), ORIGIN_NS),
        ],
    )
    log, report = read_mcap(tmp_path / "default.mcap")
    assert log.odometry[:, 0].tolist() == [3.0] and report.topics["odometry"] == ("/motion_odometry", "default name")
    # Joint readings and commands share a type: two JointState topics and no /joint_states cannot be told apart.
    write_mcap(full_log(), tmp_path / "joints.mcap", Topics(joint_states="/js", joint_commands="/jc"))
    with pytest.raises(LogError, match=r"/jc, /js; choose one with --topic-joint-states"):
        read_mcap(tmp_path / "joints.mcap")
    log, _ = read_mcap(tmp_path / "joints.mcap", Topics(joint_states="/js", joint_commands="/jc"))
    assert log.joint_names == ("head_pan", "l_knee")


def test_a_topic_of_the_wrong_type_is_an_error_naming_both(tmp_path):
    twist = {"linear": point(0.1, 0.0), "angular": point(0.0, 0.0)}
    write_raw(tmp_path / "w.mcap", [("/motion_odometry", schemas.TWIST, twist, ORIGIN_NS)])
    with pytest.raises(LogError, match=r"/motion_odometry carries geometry_msgs/msg/Twist.*nav_msgs/Odometry"):
        read_mcap(tmp_path / "w.mcap")


# -- what is dropped ------------------------------------------------------------------------------------------
def test_backwards_duplicate_repeated_and_non_finite_messages_are_dropped_and_counted(tmp_path):
    topic, ms = "/motion_odometry", 1_000_000
    sequence = [
        (0, 0.0),
        (100, 1.0),
        (100, 1.0),
        (50, 0.5),
        (200, 2.0),
        (200, 2.5),
        (300, float("nan")),
        (400, 4.0),
        (100, 1.0),
    ]
    write_raw(
        tmp_path / "d.mcap",
        [
            (topic, schemas.ODOMETRY, odometry(ORIGIN_NS + t * ms, x), ORIGIN_NS + i * ms)
            for i, (t, x) in enumerate(sequence)
        ],
    )
    log, report = read_mcap(tmp_path / "d.mcap")
    assert report.dropped == {
        (topic, "duplicate"): 2,
        (topic, "time went backwards"): 1,
        (topic, "same stamp as the previous message"): 1,
        (topic, "non-finite value"): 1,
    }
    np.testing.assert_allclose(log.odometry_times, [0.0, 0.1, 0.2, 0.4])
    np.testing.assert_allclose(log.odometry[:, 0], [0.0, 1.0, 2.0, 4.0])
    assert report.messages[topic] == len(sequence)


def test_a_stamp_more_than_the_longest_motion_step_ahead_is_dropped_and_counted(tmp_path):
    """A stamp two hours after the previous one (a clock jump) is dropped, as the columnar reader refuses it: no
    replay step could span it, and the messages after it that follow the earlier ones are kept."""
    topic, ms = "/motion_odometry", 1_000_000
    stamps = [0, 10, 7_200_000, 20, 30]  # [ms]: the third two hours ahead
    write_raw(
        tmp_path / "j.mcap",
        [
            (topic, schemas.ODOMETRY, odometry(ORIGIN_NS + t * ms, float(i)), ORIGIN_NS + i * ms)
            for i, t in enumerate(stamps)
        ],
    )
    log, report = read_mcap(tmp_path / "j.mcap")
    assert report.dropped == {(topic, "more than MAX_STEP_DT = 3600 s after the previous message"): 1}
    np.testing.assert_allclose(log.odometry_times, [0.0, 0.01, 0.02, 0.03])
    np.testing.assert_allclose(log.odometry[:, 0], [0.0, 1.0, 3.0, 4.0])


def test_a_gap_is_reported(tmp_path):
    write_raw(
        tmp_path / "g.mcap",
        [
            ("/motion_odometry", schemas.ODOMETRY, odometry(ORIGIN_NS + ns, 0.0), ORIGIN_NS + ns)
            for ns in (0, SECOND // 10, 25 * SECOND // 10, 26 * SECOND // 10)
        ],
    )
    _, report = read_mcap(tmp_path / "g.mcap", gap=1.0)
    assert report.gaps == [("/motion_odometry", pytest.approx(0.1), pytest.approx(2.4))]
    assert read_mcap(tmp_path / "g.mcap", gap=3.0)[1].gaps == []
    with pytest.raises(ValueError, match="gap"):
        read_mcap(tmp_path / "g.mcap", gap=0.0)


def test_joint_commands_are_mapped_by_name_and_held(tmp_path):
    def joints(ns, names, positions):
        return {"header": stamp(ns, ""), "name": names, "position": positions}

    write_raw(
        tmp_path / "j.mcap",
        [
            ("/joint_states", schemas.JOINT_STATE, joints(ORIGIN_NS, ["a", "b", "c"], [0.1, 0.2, 0.3]), ORIGIN_NS),
            ("/joint_commands", schemas.JOINT_STATE, joints(ORIGIN_NS + 1, ["c", "a"], [3.0, 1.0]), ORIGIN_NS + 1),
            ("/joint_commands", schemas.JOINT_STATE, joints(ORIGIN_NS + 2, ["b", "zz"], [2.0, 9.0]), ORIGIN_NS + 2),
            (
                "/joint_states",
                schemas.JOINT_STATE,
                joints(ORIGIN_NS + 3, ["c", "b", "a"], [3.3, 2.2, 1.1]),
                ORIGIN_NS + 3,
            ),
            ("/joint_states", schemas.JOINT_STATE, joints(ORIGIN_NS + 4, ["a", "b"], [0.0, 0.0]), ORIGIN_NS + 4),
        ],
    )
    log, report = read_mcap(tmp_path / "j.mcap")
    assert log.joint_names == ("a", "b", "c")
    np.testing.assert_array_equal(log.joint_commands, [[1.0, 0.2, 3.0], [1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(log.joint_readings, [[0.1, 0.2, 0.3], [1.1, 2.2, 3.3]])
    assert report.dropped == {("/joint_states", "lacks joint c"): 1}


# -- poses out ------------------------------------------------------------------------------------------------
def test_pose_writer_output_reads_back(tmp_path):
    covariance = np.array([[0.04, 0.01, 0.002], [0.01, 0.09, -0.003], [0.002, -0.003, 0.25]])
    with PoseWriter(tmp_path / "p.mcap", origin_ns=ORIGIN_NS) as poses:
        poses.write(0.5, [1.0, -2.0, 3.0], covariance)
        poses.write(ORIGIN_NS + SECOND, np.array([1.5, -2.0, -3.0]), covariance * 2)
    stamps, got, covariances = read_poses(tmp_path / "p.mcap")
    assert stamps.tolist() == [ORIGIN_NS + SECOND // 2, ORIGIN_NS + SECOND]
    np.testing.assert_allclose(got, [[1.0, -2.0, 3.0], [1.5, -2.0, -3.0]], atol=1e-12)
    np.testing.assert_allclose(covariances, [covariance, covariance * 2])
    # The same file read as ground truth: PoseWithCovarianceStamped is accepted there.
    log, _ = read_mcap(tmp_path / "p.mcap", Topics().override(truth="/robocup_mcl/pose"))
    np.testing.assert_allclose(log.truth_times, [0.0, 0.5])
    with PoseWriter(tmp_path / "q.mcap") as poses, pytest.raises(ValueError, match="pose"):
        poses.write(1, [0.0, float("nan"), 0.0], covariance)


def test_schema_definitions_carry_their_dependencies_once():
    text = schemas.definition(schemas.MARKING_ARRAY)
    assert text.count("MSG: geometry_msgs/Point\n") == 1
    assert text.startswith("std_msgs/Header header\n")
    assert "MSG: soccer_vision_attribute_msgs/Confidence\nfloat32 CONFIDENCE_UNKNOWN=-1" in text
    with pytest.raises(ValueError, match="type_name"):
        schemas.definition("std_msgs/String")
