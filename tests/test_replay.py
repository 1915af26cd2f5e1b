"""`robocup-mcl replay` on logs whose topics differ from the defaults, logs it cannot replay, and `--out .npz`.

Every log here is a real MCAP file written by `write_mcap` from the walk scenario and read by the real reader
through the command's entry point.
"""

import json
from dataclasses import replace

import numpy as np
import pytest

from demos.walk_log import to_robot_log
from demos.walk_sim import WalkScenario, simulate
from field import spl
from mcl.tools.logs import LogError, RobotLog, read_log
from mcl.tools.logs.mcap_io import Topics, write_mcap
from mcl.tools.replay import check_inputs, main, replay

FIELD = spl()
RENAMED = Topics(
    odometry="/robot/odom",
    commands="/walk/cmd_vel",
    goalposts="/vision/goalposts",
    markings="/vision/markings",
    truth="/sim/truth",
)


@pytest.fixture(scope="module")
def walk_log():
    """The walk scenario as a log with commands, odometry (the true motion), vision and truth."""
    sim = simulate(replace(WalkScenario(), duration=4.0, kidnap_time=None), 11)
    log = to_robot_log(sim, latency=0.03)
    return replace_streams(log, odometry_times=log.truth_times, odometry=log.truth)


def replace_streams(log: RobotLog, **streams) -> RobotLog:
    fields = dict(
        origin_ns=log.origin_ns,
        odometry_times=log.odometry_times,
        odometry=log.odometry,
        command_times=log.command_times,
        commands=log.commands,
        vision=log.vision,
        truth_times=log.truth_times,
        truth=log.truth,
    )
    return RobotLog(**{**fields, **streams})


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_a_log_with_renamed_topics_is_replayed_from_the_topics_of_the_right_types(tmp_path, capsys, walk_log):
    path = tmp_path / "renamed.mcap"
    write_mcap(walk_log, path, RENAMED)
    code, out, err = run(
        capsys,
        path,
        "--json",
        "--particles",
        200,
        "--seed",
        3,
        "--topic-truth",
        "/sim/truth",
        "--start=" + ",".join(str(v) for v in walk_log.truth[0]),
    )
    assert code == 0, err
    report = json.loads(out)
    assert report["log"]["topics"] == {
        "odometry": {"topic": "/robot/odom", "by": "type"},
        "commands": {"topic": "/walk/cmd_vel", "by": "type"},
        "goalposts": {"topic": "/vision/goalposts", "by": "type"},
        "markings": {"topic": "/vision/markings", "by": "type"},
        "truth": {"topic": "/sim/truth", "by": "name"},
    }
    figures = report["replay"]
    late = figures["dropped"].get("camera frame after the last motion step", 0)
    assert figures["frames_used"] + late == len(walk_log.vision) and late <= 1
    assert figures["position_error_m"]["median"] < 0.15 and figures["heading_error_deg"]["median"] < 5.0
    # The same estimates as replaying the log in memory.
    log, _ = read_log(path, topics=Topics(truth="/sim/truth"))
    direct = replay(walk_log, FIELD, particles=200, seed=3, start=tuple(walk_log.truth[0]))
    np.testing.assert_allclose(
        replay(log, FIELD, particles=200, seed=3, start=tuple(walk_log.truth[0])).estimates, direct.estimates, atol=1e-9
    )
    # Without --json the choices are printed.
    code, out, _ = run(capsys, path, "--particles", 50)
    assert code == 0 and "odometry from /robot/odom (by type" in out and "goalposts from /vision/goalposts" in out


def test_a_log_without_motion_input_is_refused_naming_what_is_missing(tmp_path, capsys, walk_log):
    path = tmp_path / "still.mcap"
    still = replace_streams(
        walk_log,
        odometry_times=np.zeros(0),
        odometry=np.zeros((0, 3)),
        command_times=np.zeros(0),
        commands=np.zeros((0, 3)),
    )
    write_mcap(still, path, RENAMED)
    code, out, err = run(capsys, path, "--particles", 50, "--out", tmp_path / "poses.npz")
    assert code == 1 and out == ""
    assert "no motion input" in err and "neither odometry" in err
    assert "odometry: no topic /motion_odometry and none of type nav_msgs/Odometry" in err
    assert "commands: no topic /cmd_vel" in err and "--topic-odometry or --topic-commands" in err
    assert not (tmp_path / "poses.npz").exists()
    with pytest.raises(LogError, match="no motion input"):
        replay(still, FIELD, particles=50)


@pytest.mark.parametrize("frames", ["none", "empty"])
def test_a_log_without_detections_is_refused_naming_what_is_missing(tmp_path, capsys, walk_log, frames):
    path = tmp_path / "blind.mcap"
    vision = (
        ()
        if frames == "none"
        else tuple(replace(f, observations=type(f.observations).empty()) for f in walk_log.vision)
    )
    write_mcap(replace_streams(walk_log, vision=vision), path, RENAMED)
    code, out, err = run(capsys, path, "--particles", 50)
    assert code == 1 and out == ""
    assert "no detections" in err and "--topic-goalposts or --topic-markings" in err
    if frames == "none":
        assert "no camera frames" in err
        assert "goalposts: no topic /goal_posts_relative and none of type soccer_vision_3d_msgs/GoalpostArray" in err
    else:
        assert f"{len(walk_log.vision)} camera frames, none with a detection" in err
        assert "goalposts: /vision/goalposts (chosen by type)" in err
    # Dead reckoning from a known start is still possible from Python.
    log, _ = read_log(path)
    assert replay(log, FIELD, particles=50, start=tuple(walk_log.truth[0]), require_vision=False).times.shape[0]


def merge(out_path, *sources) -> None:
    """One MCAP file with every message of `sources` (raw bytes, their schemas and channels), in log-time order."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    with open(out_path, "wb") as out:
        writer = Writer(out)
        writer.start()
        schema_ids, channel_ids, entries = {}, {}, []
        for source in sources:
            with open(source, "rb") as file:
                for schema, channel, message in make_reader(file).iter_messages():
                    if schema.name not in schema_ids:
                        schema_ids[schema.name] = writer.register_schema(schema.name, schema.encoding, schema.data)
                    if channel.topic not in channel_ids:
                        channel_ids[channel.topic] = writer.register_channel(
                            channel.topic, channel.message_encoding, schema_ids[schema.name]
                        )
                    entries.append((message.log_time, channel_ids[channel.topic], message.data))
        for log_time, channel_id, data in sorted(entries, key=lambda entry: entry[0]):
            writer.add_message(channel_id, log_time, data, log_time)
        writer.finish()


def test_two_odometry_topics_are_an_error_naming_both(tmp_path, capsys, walk_log):
    write_mcap(walk_log, tmp_path / "walk.mcap", RENAMED)
    write_mcap(
        replace_streams(walk_log, command_times=np.zeros(0), commands=np.zeros((0, 3)), vision=()),
        tmp_path / "fused.mcap",
        Topics(odometry="/odom/fused", truth=""),
    )
    merge(tmp_path / "both.mcap", tmp_path / "walk.mcap", tmp_path / "fused.mcap")
    code, out, err = run(capsys, tmp_path / "both.mcap", "--particles", 50)
    assert code == 1 and out == ""
    assert "2 topics carry nav_msgs/Odometry: /odom/fused, /robot/odom" in err and "--topic-odometry" in err
    code, out, err = run(capsys, tmp_path / "both.mcap", "--particles", 50, "--topic-odometry", "/robot/odom", "--json")
    assert code == 0, err
    assert json.loads(out)["log"]["topics"]["odometry"] == {"topic": "/robot/odom", "by": "name"}


def test_npz_output_holds_the_documented_arrays(tmp_path, capsys, walk_log):
    path = tmp_path / "walk.mcap"
    write_mcap(walk_log, path)
    code, _, err = run(capsys, path, "--particles", 50, "--out", tmp_path / "poses.npz")
    assert code == 0, err
    with np.load(tmp_path / "poses.npz") as poses:
        assert sorted(poses.files) == ["covariances", "lost", "origin_ns", "poses", "quality", "times"]
        m = poses["times"].shape[0]
        assert m == walk_log.odometry_times.shape[0] - 1  # one row per motion step
        assert poses["poses"].shape == (m, 3) and poses["covariances"].shape == (m, 3, 3)
        assert poses["quality"].dtype == np.int8 and poses["lost"].dtype == bool
        assert poses["origin_ns"].shape == () and int(poses["origin_ns"]) == walk_log.origin_ns
        np.testing.assert_allclose(poses["times"], walk_log.odometry_times[1:], atol=1e-9)
    assert check_inputs(walk_log) is None
