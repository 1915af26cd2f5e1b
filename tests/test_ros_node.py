"""The live node over DDS (`robocup-mcl node bench`): a held-out-like log played to the node in its own process,
inside a network namespace with only the loopback; and, without ROS, the commands say what to install.

The DDS test runs only where the `ros` extra and the generated messages are installed (`make ros`, which runs
these tests with its own environment) and a loopback-only namespace can be made (root, unshare); it skips
otherwise, saying why. It asserts what the node did, never how fast: the figures come from
`robocup-mcl node bench --json --save results/ros_*.json`."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import pytest

from mcl.tools.ros.bench import namespace_command
from mcl.tools.ros.node import ros_available

ORIGIN_NS = 1_750_000_000_000_000_000


def _dds_or_skip():
    missing = ros_available()
    if missing:
        pytest.skip(f"ROS 2 is not installed here ({missing})")
    if namespace_command(["true"]) is None:
        pytest.skip("cannot make a loopback-only network namespace here (needs root, unshare and ip)")


@pytest.fixture(scope="module")
def log_path(tmp_path_factory):
    from demos.battery_sim import as_robot_log, simulate
    from mcl.tools.logs.mcap_io import write_mcap

    run = simulate("tracking", 1011, 6.0)  # a held-out-like seed (the battery's held-out range)
    path = tmp_path_factory.mktemp("ros") / "tracking_1011.mcap"
    write_mcap(dataclasses.replace(as_robot_log(run), origin_ns=ORIGIN_NS), path)
    return path, run.field.name


def test_the_node_answers_a_played_log_over_dds(log_path):
    _dds_or_skip()
    path, field = log_path
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "mcl.tools.cli",
            "node",
            "bench",
            str(path),
            "--field",
            field,
            "--particles",
            "100",
            "--seed",
            "2",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout)
    assert result["odometry_sent"] == 601 and result["poses_expected"] == 600
    assert result["poses_received"] > 0 and result["poses_received"] + result["poses_dropped"] >= 600
    assert result["tf_frames"] == ["map->odom"] and result["tf_messages"] > 0
    assert result["quality_changes"] and set(result["quality_changes"]) <= {"superb", "okay", "poor", "unsure_half"}
    node = result["node"]
    assert node["received"]["/motion_odometry"] == result["poses_received"] + 1 or result["poses_dropped"]
    assert node["frames_used"] > 0 and node["cpu_seconds"] > 0
    assert node["ordering"] == "source timestamps"
    assert result["replay"]["compared"] == result["poses_received"]
    # the particles at 2 Hz (the default), all of them in each message; the field once, latched
    assert result["particle_messages"] >= 5 and result["particles_per_message"] == [100]
    assert result["field_markers"] == {"centre_circle": 1, "goalposts": 4, "lines": 1, "marks": 3}
    assert node["published"]["/robocup_mcl/field"] == 1


def test_the_node_answers_without_source_timestamps_as_on_humble(log_path):
    """use_source_timestamps false: callbacks of the message alone, as Humble's rclpy calls them; frames ordered
    by the order taken and their header stamps."""
    _dds_or_skip()
    path, field = log_path
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "mcl.tools.cli",
            "node",
            "bench",
            str(path),
            "--field",
            field,
            "--particles",
            "100",
            "--seed",
            "2",
            "--no-source-timestamps",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout)
    node = result["node"]
    assert node["ordering"] == "receive order and header stamps"
    assert result["poses_received"] > 0 and result["poses_received"] + result["poses_dropped"] >= 600
    assert node["frames_used"] > 0 and result["replay"]["compared"] == result["poses_received"]


def test_team_messages_over_dds_reach_the_localizer_and_bad_ones_are_dropped(log_path, tmp_path):
    """A teammate's broadcasts (robocup_mcl_msgs/TeamMessage) at 10 Hz beside the log, every third with a NaN x:
    the node receives them all, gives the good ones to the localizer, counts the bad ones by kind and drops
    them, and no pose it publishes holds a NaN. The node records the run (--rrd): the file reads back with one
    estimate per pose published."""
    _dds_or_skip()
    rrd = tmp_path / "live.rrd"
    path, field = log_path
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "mcl.tools.cli",
            "node",
            "bench",
            str(path),
            "--field",
            field,
            "--particles",
            "100",
            "--team-rate",
            "10",
            "--team-bad-every",
            "3",
            "--rrd",
            str(rrd),
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout)
    sent, bad = result["team_messages_sent"], result["team_messages_bad_sent"]
    assert sent >= 59 and bad == sent // 3
    node = result["node"]
    assert node["received"]["/robocup_mcl/team"] == sent
    assert node["not_used"]["team message"] == sent - bad
    assert node["not_used"]["team message: pose"] == bad
    assert result["nonfinite_poses"] == 0 and result["poses_received"] > 0
    assert result["shutdown"]["completed"]
    recording = result["rrd"]["file"]
    assert "error" not in recording and recording["recordings"] == 1
    assert recording["estimate_rows"] == node["published"]["/robocup_mcl/pose"] > 0


def test_without_ros_the_commands_say_what_to_install(tmp_path):
    if ros_available() is None:
        pytest.skip("ROS 2 is installed here: the commands run")
    for argv in (["node"], ["node", "play", str(tmp_path / "x.mcap")]):
        done = subprocess.run(
            [sys.executable, "-m", "mcl.tools.cli", *argv], capture_output=True, text=True, timeout=120
        )
        assert done.returncode == 1 and "make ros" in done.stderr and done.stderr.count("\n") == 1, done.stderr
