"""The ROS node's logic without ROS (`mcl.tools.ros.core`, `mcl.tools.ros.parameters`): messages decoded from an MCAP log,
fed in the order the log has them, give `robocup-mcl replay`'s estimates bit for bit; the game events; the
parameters' checks; and `robocup-mcl node` without the ROS wheels says what to install in one line."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from demos.battery_sim import as_robot_log, simulate
from mcl.tools.logs.mcap_io import write_mcap
from mcl.tools.replay import replay
from mcl.tools.ros.core import NodeCore, map_to_odom
from mcl.tools.ros.parameters import NodeSettings

ORIGIN_NS = 1_750_000_000_000_000_000  # a stamp of our time: the log's t = 0


@pytest.fixture(scope="module")
def battery_log(tmp_path_factory):
    """A held-out-like battery run (family kidnap, seed 1007) as a robot's MCAP log, and its RobotLog."""
    run = simulate("kidnap", 1007, 12.0)
    log = dataclasses.replace(as_robot_log(run), origin_ns=ORIGIN_NS)
    path = tmp_path_factory.mktemp("ros") / "kidnap_1007.mcap"
    write_mcap(log, path)
    return path, log, run.field.name


def decoded_messages(path):
    """(log time, topic, decoded message) in log-time order, camera messages before odometry at equal times."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        rows = [
            (message.log_time, channel.topic, decoded)
            for _, channel, message, decoded in reader.iter_decoded_messages()
        ]
    return sorted(rows, key=lambda row: (row[0], row[1] == "/motion_odometry"))


def test_the_core_gives_the_replay_s_estimates_bit_for_bit(battery_log):
    path, log, field_name = battery_log
    settings = NodeSettings(field=field_name, particles=200, seed=3)
    core = NodeCore(settings, origin_ns=log.origin_ns)
    outputs = []
    for _, topic, message in decoded_messages(path):
        if topic == "/motion_odometry":
            out = core.odometry(message)
            if out is not None:
                outputs.append(out)
        elif topic == "/goal_posts_relative":
            core.goalposts(message)
        elif topic == "/markings_relative":
            core.markings(message)
    from mcl.tools.logs import read_log

    read, _ = read_log(str(path))
    result = replay(read, settings.localizer().field, particles=200, seed=3)
    assert len(outputs) == result.times.shape[0] > 1000
    poses = np.array([out.pose for out in outputs])
    assert np.array_equal(poses, result.estimates)
    assert np.array_equal(np.array([out.covariance for out in outputs]), result.covariances)
    assert core.frames_used == result.frames_used > 100
    assert [out.stamp_ns for out in outputs] == [read.origin_ns + round(t * 1e9) for t in result.times]


def feed(core, path):
    """The log's messages through `core` in the log's order; the outputs of the odometry messages."""
    outputs = []
    for _, topic, message in decoded_messages(path):
        if topic == "/motion_odometry":
            out = core.odometry(message)
            if out is not None:
                outputs.append(out)
        elif topic == "/goal_posts_relative":
            core.goalposts(message)
        elif topic == "/markings_relative":
            core.markings(message)
    return outputs


def test_a_recording_of_the_run_reads_back_and_changes_no_estimate(battery_log, tmp_path):
    """`NodeCore.record` (the node's --rrd): the estimates are those of a run without it, bit for bit; the .rrd
    holds one estimate per odometry message on the messages' header stamps, the particles every 4th step,
    the detections of the steps that used a camera frame, and the quality."""
    import rerun.chunk as rrc

    from mcl.tools.recording import LOG_TIMELINE

    path, log, field_name = battery_log
    settings = NodeSettings(field=field_name, particles=200, seed=3)
    plain = feed(NodeCore(settings, origin_ns=log.origin_ns), path)
    core = NodeCore(settings, origin_ns=log.origin_ns)
    rrd = tmp_path / "live.rrd"
    core.record(str(rrd), every=4)
    recorded = feed(core, path)
    core.close()
    assert np.array_equal(np.array([o.pose for o in recorded]), np.array([o.pose for o in plain]))
    assert np.array_equal(np.array([o.covariance for o in recorded]), np.array([o.covariance for o in plain]))
    assert not any("recording" in reason for reason in core.all_counts())
    steps: dict[str, list[int]] = {}
    stamps: list[int] = []
    for chunk in rrc.RrdReader(str(rrd)).stream():
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        steps.setdefault(chunk.entity_path, []).extend(batch.column(batch.schema.names.index("step")).to_pylist())
        if chunk.entity_path == "/robot/estimate":
            column = batch.column(batch.schema.names.index(LOG_TIMELINE)).cast("int64")
            stamps.extend(column.to_pylist())
    n = len(plain)
    assert sorted(steps["/robot/estimate"]) == list(range(n))
    assert sorted(steps["/particles"]) == list(range(0, n, 4))
    # the detections (not the line points) of a step's last frame used
    assert set(steps["/observations"]) <= {k for k, o in enumerate(plain) if o.frames_used}
    assert len(steps["/observations"]) > 100
    assert "/events" in steps and sorted(steps["/localization/quality"]) == list(range(n))
    assert sorted(stamps) == [o.stamp_ns for o in plain]
    with pytest.raises(ValueError, match="every"):
        core.record(str(tmp_path / "other.rrd"), every=0)


def test_map_to_odom_composes_with_the_odometry_pose_to_the_estimate():
    estimate, odometry = np.array([1.0, -2.0, 2.5]), np.array([0.3, 0.7, -1.2])
    x, y, theta = map_to_odom(estimate, odometry)
    c, s = math.cos(theta), math.sin(theta)
    back = (x + c * odometry[0] - s * odometry[1], y + s * odometry[0] + c * odometry[1], theta + odometry[2])
    assert np.allclose(back[:2], estimate[:2]) and math.isclose(
        math.remainder(back[2] - estimate[2], math.tau), 0, abs_tol=1e-12
    )


def _state(game_state, penalized=False):
    return SimpleNamespace(game_state=game_state, penalized=penalized)


def test_game_state_events():
    core = NodeCore(NodeSettings(particles=50))
    assert core.game_state(_state(0)) == ["initial_placement"]
    assert core.game_state(_state(0)) == []
    assert core.game_state(_state(3)) == []
    assert core.game_state(_state(3, True)) == ["penalized"] and core.localizer.is_penalized
    assert core.game_state(_state(3, False)) == ["penalty_return"] and not core.localizer.is_penalized
    off = NodeCore(NodeSettings(particles=50, game_events=False))
    assert off.game_state(_state(0)) == []


def test_events_and_a_known_pose():
    core = NodeCore(NodeSettings(particles=100))
    core.event("fallen")
    assert core.localizer.is_fallen
    core.event("got_up")
    with pytest.raises(ValueError, match="event = 'jump'"):
        core.event("jump")
    pose = SimpleNamespace(
        header=SimpleNamespace(stamp=SimpleNamespace(sec=1, nanosec=0), frame_id="map"),
        pose=SimpleNamespace(
            pose=SimpleNamespace(
                position=SimpleNamespace(x=1.0, y=-0.5, z=0.0), orientation=SimpleNamespace(x=0.0, y=0.0, z=0.0, w=1.0)
            ),
            covariance=[0.0] * 36,
        ),
    )
    core.initial_pose(pose)
    assert np.allclose(core.localizer.pose().pose[:2], (1.0, -0.5), atol=0.1)
    assert core.all_counts()["event place"] == 1


@pytest.mark.parametrize(
    "values, match",
    [
        ({"particles": 0}, "particles = 0"),
        ({"model": "x"}, "model = 'x'"),
        ({"history": -1.0}, "history = -1.0"),
        ({"start": "z"}, "start = 'z'"),
        ({"particles": "5"}, "particles = '5' must be a int"),
        ({"nope": 1}, "unknown parameters"),
        ({"pose_topic": "a b"}, "pose_topic"),
    ],
)
def test_bad_parameters_are_refused_by_name(values, match):
    with pytest.raises(ValueError, match=match):
        NodeSettings.from_dict(values)


def test_the_field_markers_are_the_field_s_own_geometry():
    from field import LandmarkType, preset
    from mcl.tools.ros.core import CIRCLE_SEGMENTS, field_markers

    field = preset("kidsize")
    markers = field_markers(field)
    by_namespace = {}
    for marker in markers:
        by_namespace.setdefault(marker.namespace, []).append(marker)
    assert sorted(by_namespace) == ["centre_circle", "goalposts", "lines", "marks"]
    for group in by_namespace.values():
        assert [m.marker_id for m in group] == list(range(len(group)))
    (lines,) = by_namespace["lines"]
    assert lines.shape == "line_list" and lines.width == field.dims.line_width
    assert np.array_equal(lines.points.reshape(-1, 2, 2), field.segments)
    (circle,) = by_namespace["centre_circle"]
    assert circle.shape == "line_strip" and circle.points.shape == (CIRCLE_SEGMENTS + 1, 2)
    assert np.array_equal(circle.points[0], circle.points[-1])
    assert np.allclose(np.hypot(*circle.points.T), field.center_circle[2])
    posts = by_namespace["goalposts"]
    assert np.array_equal(np.array([m.points[0] for m in posts]), field.landmarks_of(LandmarkType.GOALPOST))
    assert all(m.shape == "cylinder" and m.width == field.dims.goalpost_diameter and m.height > 0 for m in posts)
    marks = np.array([m.points[0] for m in by_namespace["marks"]])
    assert np.array_equal(
        marks,
        np.concatenate([field.landmarks_of(LandmarkType.PENALTY_MARK), field.landmarks_of(LandmarkType.CENTER_MARK)]),
    )


def test_the_particles_are_the_filter_s_a_copy():
    core = NodeCore(NodeSettings(particles=120, seed=1))
    particles = core.particles()
    assert particles.shape == (120, 3) and np.array_equal(particles, core.localizer.filter.poses)
    particles[:] = 0.0
    assert not np.array_equal(particles, core.localizer.filter.poses)


def test_the_output_rates_and_topics_are_parameters():
    settings = NodeSettings()
    assert (settings.particles_rate, settings.particles_topic, settings.field_topic) == (
        2.0,
        "/robocup_mcl/particles",
        "/robocup_mcl/field",
    )
    with pytest.raises(ValueError, match="particles_rate = -1.0"):
        NodeSettings(particles_rate=-1.0)


def test_without_send_times_a_frame_captured_after_the_odometry_stamp_waits(battery_log):
    """Humble's rclpy gives no send times: a frame taken before an odometry message whose stamp is older than
    the frame's capture is kept for the next step."""
    path, log, field_name = battery_log
    rows = decoded_messages(path)
    odometry = [m for _, topic, m in rows if topic == "/motion_odometry"]
    goalposts = [m for _, topic, m in rows if topic == "/goal_posts_relative"]
    markings = {
        m.header.stamp.sec * 10**9 + m.header.stamp.nanosec: m for _, topic, m in rows if topic == "/markings_relative"
    }
    frame = next(
        g
        for g in goalposts
        if (g.header.stamp.sec * 10**9 + g.header.stamp.nanosec) in markings
        and g.header.stamp.sec * 10**9 + g.header.stamp.nanosec > stamp_of(odometry[2])
    )
    capture = frame.header.stamp.sec * 10**9 + frame.header.stamp.nanosec
    before = [m for m in odometry if stamp_of(m) < capture]
    after = next(m for m in odometry if stamp_of(m) >= capture)
    core = NodeCore(NodeSettings(field=field_name, particles=100), origin_ns=log.origin_ns)
    core.odometry(before[-2])
    core.goalposts(frame)
    core.markings(markings[capture])
    assert core.odometry(before[-1]).frames_used == 0  # captured after this stamp: not yet
    assert core.odometry(after).frames_used == 1
    # with send times, the send times decide (today's behaviour where rclpy gives them)
    core = NodeCore(NodeSettings(field=field_name, particles=100), origin_ns=log.origin_ns)
    core.odometry(before[-2], sent_ns=1)
    core.goalposts(frame, sent_ns=2)
    core.markings(markings[capture], sent_ns=2)
    assert core.odometry(before[-1], sent_ns=3).frames_used == 1


def stamp_of(message):
    return message.header.stamp.sec * 10**9 + message.header.stamp.nanosec


def test_callbacks_take_message_info_only_where_rclpy_gives_it():
    import importlib.util

    from mcl.tools.ros.node import Statistics, message_info_supported

    assert message_info_supported() == (importlib.util.find_spec("rclpy") is not None)  # Kilted here, or none
    seen = []
    stats = Statistics()
    stats.timed("/a", lambda message, sent_ns: seen.append((message, sent_ns)), with_info=False)("m")
    stats.timed("/b", lambda message, sent_ns: seen.append((message, sent_ns)))("n", {"source_timestamp": 7})
    assert seen == [("m", None), ("n", 7)] and stats.received == {"/a": 1, "/b": 1}


def test_the_statistics_set_the_recording_apart_from_the_callback():
    """The node's statistics time each odometry callback and the part its recording took, in the same calls: the
    callback without that part is the difference (no timing is asserted, only the bookkeeping)."""
    from mcl.tools.ros.node import Statistics

    stats = Statistics()
    stats.recording_topic = "/odom"
    callback = stats.timed("/odom", lambda message, sent_ns: stats.recording.append(0.0), with_info=False)
    for _ in range(5):
        callback(object())
    assert "recording" not in stats.as_dict({})  # nothing recorded: no figures
    stats.recording[2] = 1e-9
    figures = stats.as_dict({})["recording"]
    assert figures["callback_median_ms"] >= figures["callback_without_median_ms"]
    assert set(figures) >= {"median_ratio", "p99_ratio", "total_ratio"}
    counting = Statistics(keep_durations=False)  # the node without --stats: counts only, no growing arrays
    counting.timed("/odom", lambda message, sent_ns: None, with_info=False)(object())
    assert counting.received == {"/odom": 1} and counting.as_dict({})["callbacks"] == {}


def test_the_figure_draws_what_the_node_published(tmp_path):
    """`robocup-mcl node figure` draws the JSON of `node bench --published` (here a small hand-made one)."""
    pytest.importorskip("matplotlib")
    from mcl.tools.ros.figure import main

    published = {
        "field_markers": [
            {"ns": "lines", "id": 0, "type": 5, "points": [[-4.5, -3], [4.5, -3]], "position": [0, 0], "scale_x": 0.05},
            {
                "ns": "centre_circle",
                "id": 0,
                "type": 4,
                "points": [[0.75, 0], [0, 0.75], [-0.75, 0]],
                "position": [0, 0],
                "scale_x": 0.05,
            },
            {"ns": "goalposts", "id": 0, "type": 3, "points": [], "position": [4.5, 1.3], "scale_x": 0.1},
        ],
        "poses": [[ORIGIN_NS + k * 10_000_000, 0.01 * k, 0.0, 0.1] for k in range(300)],
        "particles": [{"stamp_ns": ORIGIN_NS + 2_000_000_000, "poses": [[0.2, 0.1, 0.0], [0.3, -0.1, 1.0]]}],
        "quality_changes": ["okay"],
    }
    path = tmp_path / "published.json"
    path.write_text(__import__("json").dumps(published))
    assert main([str(path), "--out", str(tmp_path / "node.png"), "--at", "1.5"]) == 0
    assert (tmp_path / "node.png").stat().st_size > 1000


def team_msg(sec=5, **values):
    """A robocup_mcl_msgs/TeamMessage as an object with its fields (a good one unless `values` say otherwise)."""
    fields = {
        "sender": 2,
        "is_goalkeeper": False,
        "x": -1.0,
        "y": 0.5,
        "theta": 0.3,
        "has_pose_covariance": True,
        "pose_covariance": [0.04, 0.0, 0.0, 0.0, 0.04, 0.0, 0.0, 0.0, 0.01],
        "confidence": -1.0,
        "has_ball": True,
        "ball_x": 1.0,
        "ball_y": -0.5,
        "has_ball_velocity": True,
        "ball_vx": 0.2,
        "ball_vy": 0.0,
        "ball_age": 0.1,
        "has_ball_covariance": False,
        "ball_covariance": [0.0] * 4,
        "clock_offset": 0.0,
        **values,
    }
    header = SimpleNamespace(stamp=SimpleNamespace(sec=sec, nanosec=0), frame_id=fields.pop("frame_id", "map"))
    return SimpleNamespace(header=header, **fields)


def test_a_team_message_is_the_localizer_s_team_message_field_for_field():
    from mcl.tools.ros.core import TEAM_MESSAGE_FIELDS, team_message

    msg = team_msg()
    assert set(vars(msg)) == set(TEAM_MESSAGE_FIELDS)
    out = team_message(msg, 5.0)
    assert (out.sender, out.time, out.pose, out.is_goalkeeper) == (2, 5.0, (-1.0, 0.5, 0.3), False)
    assert np.array_equal(out.pose_covariance, np.diag([0.04, 0.04, 0.01])) and out.confidence is None
    assert (out.ball, out.ball_velocity, out.ball_age, out.ball_covariance) == ((1.0, -0.5), (0.2, 0.0), 0.1, None)
    bare = team_message(team_msg(has_pose_covariance=False, confidence=0.7, has_ball=False, ball_age=3.0), 1.0)
    assert bare.pose_covariance is None and bare.confidence == 0.7 and bare.ball is None and bare.ball_age == 0.0
    core = NodeCore(NodeSettings(particles=100, player_number=1), origin_ns=0)
    assert core.team(team_msg()) and core.localizer.counts["team message"] == 1


@pytest.mark.parametrize(
    "values, kind",
    [
        ({"x": float("nan")}, "pose"),
        ({"theta": float("inf")}, "pose"),
        ({"confidence": float("nan")}, "confidence"),
        ({"confidence": 1.5, "has_pose_covariance": False}, "confidence"),
        ({"sender": 0}, "sender"),
        ({"sender": 1}, "refused by the localizer"),  # the robot's own number
        ({"frame_id": "odom"}, "frame_id"),
        ({"pose_covariance": [1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0]}, "pose_covariance"),
        ({"pose_covariance": [1.0] * 4}, "cannot reshape"),
        ({"ball_age": -1.0}, "ball_age"),
        ({"ball_x": 1e12}, "ball"),
        ({"sec": 10**6}, "refused by the localizer"),  # sent far in the robot's future
    ],
)
def test_a_bad_team_message_is_counted_by_kind_and_dropped(values, kind):
    core = NodeCore(NodeSettings(particles=100, player_number=1), origin_ns=0)
    core.localizer.motion(5.0, __import__("motion_models").MotionInput(dt=0.01, odometry=(0.0, 0.0, 0.0)))
    before = core.localizer.pose().pose.copy()
    sec = values.pop("sec", 5)
    assert not core.team(team_msg(sec, **values))
    (reason,) = [k for k in core.counts if k.startswith("team message")]
    assert kind in reason, reason
    assert core.localizer.counts.get("team message", 0) == 0
    assert np.array_equal(core.localizer.pose().pose, before)


def test_two_thousand_random_team_messages_never_raise_nor_make_the_estimate_nan():
    rng = np.random.default_rng(42)
    core = NodeCore(NodeSettings(particles=100, player_number=1), origin_ns=0)
    specials = [float("nan"), float("inf"), -float("inf"), 1e300, -1e-300, 0.0, -1.0]

    def value():
        return specials[rng.integers(len(specials))] if rng.random() < 0.3 else float(rng.normal(0.0, 3.0))

    from motion_models import MotionInput

    used = 0
    for k in range(2000):
        core.localizer.motion(0.01 * (k + 1), MotionInput(dt=0.01, odometry=(0.001, 0.0, 0.0)))
        fields = {
            name: value()
            for name in ("x", "y", "theta", "confidence", "ball_x", "ball_y", "ball_vx", "ball_vy", "ball_age")
        }
        fields.update(
            sender=int(rng.integers(0, 25)),
            has_pose_covariance=bool(rng.random() < 0.5),
            pose_covariance=[value() for _ in range(int(rng.choice([9, 9, 9, 4, 0])))],
            has_ball=bool(rng.random() < 0.7),
            has_ball_covariance=bool(rng.random() < 0.3),
            ball_covariance=[value() for _ in range(4)],
            clock_offset=value() if rng.random() < 0.1 else 0.0,
            frame_id=str(rng.choice(["map", "", "odom"])),
        )
        used += core.team(team_msg(int(rng.integers(0, 30)), **fields))
        assert np.all(np.isfinite(core.localizer.pose().pose))
    dropped = sum(n for reason, n in core.counts.items() if reason.startswith("team message"))
    assert used + dropped == 2000 and dropped > 1000
    assert len([r for r in core.counts if r.startswith("team message")]) < 40  # counted by kind, not by value


def test_each_kind_of_drop_is_logged_once():
    from collections import Counter

    from mcl.tools.ros.node import log_new_drops

    counts: Counter = Counter()
    logged: list[str] = []

    def callback(message, sent_ns):
        counts[message] += 1

    wrapped = log_new_drops(callback, counts, logged.append)
    for message in ["team message: pose", "team message: pose", "event fallen", "odometry: time went backwards"]:
        wrapped(message, None)
    assert logged == [
        "dropped: team message: pose (logged once; counted from now on)",
        "dropped: odometry: time went backwards (logged once; counted from now on)",
    ]
    assert counts["team message: pose"] == 2
