"""Pose conversions to and from ROS messages, quaternions, ROS covariances, SPL messages and the venue frame."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from field.angles import wrap_angles
from mcl.tools.formats import (
    UNESTIMATED_VARIANCE,
    covariance3_to_ros6,
    pose_to_ros,
    pose_to_ros_pose,
    pose_to_spl,
    quaternion_to_yaw,
    ros6_to_covariance3,
    ros_pose_to_pose,
    ros_to_pose,
    spl_to_pose,
    team_to_venue_frame,
    venue_to_team_frame,
    yaw_to_quaternion,
)

coordinates = st.floats(-20.0, 20.0, allow_nan=False)
angles = st.floats(-50.0, 50.0, allow_nan=False)
wrapped_angles = st.floats(-math.pi, math.pi, allow_nan=False).filter(lambda a: a > -math.pi)
poses = st.tuples(coordinates, coordinates, angles).map(np.array)
stamps_ns = st.integers(0, 2**31 * 10**9 - 1)


def angle_difference(a, b):
    return np.abs(wrap_angles(np.asarray(a) - np.asarray(b)))


@st.composite
def covariances(draw, size=3):
    """Random symmetric positive semi-definite matrices."""
    factor = np.array(draw(st.lists(st.floats(-2.0, 2.0), min_size=size * size, max_size=size * size)))
    factor = factor.reshape(size, size)
    return factor @ factor.T


def message_as_object(message):
    """The dict as the attribute objects mcap_ros2's decoder returns."""
    if isinstance(message, dict):
        return SimpleNamespace(**{key: message_as_object(value) for key, value in message.items()})
    return message


# -- quaternions ------------------------------------------------------------------------------------------------
def test_quarter_turn_is_the_known_quaternion():
    half = math.sqrt(0.5)
    np.testing.assert_allclose(yaw_to_quaternion(math.pi / 2), (0.0, 0.0, half, half), atol=1e-15)
    assert quaternion_to_yaw(0.0, 0.0, half, half) == pytest.approx(math.pi / 2)
    assert quaternion_to_yaw(0.0, 0.0, 0.0, 1.0) == 0.0
    assert quaternion_to_yaw(0.0, 0.0, 1.0, 0.0) == math.pi  # half a turn lands on +π, not -π
    assert yaw_to_quaternion(-math.pi) == yaw_to_quaternion(math.pi)


@given(angles)
def test_yaw_survives_a_quaternion(yaw):
    quaternion = yaw_to_quaternion(yaw)
    assert math.hypot(*quaternion) == pytest.approx(1.0)
    assert quaternion[3] >= 0.0
    back = quaternion_to_yaw(*quaternion)
    assert -math.pi < back <= math.pi
    assert angle_difference(back, yaw) < 1e-12


@given(st.tuples(*[st.floats(-1.0, 1.0)] * 4).filter(lambda q: math.hypot(*q) > 1e-3))
def test_planar_quaternion_survives_a_yaw(components):
    x, y, z, w = 0.0, 0.0, components[2], components[3]
    if math.hypot(z, w) < 1e-3:
        return
    back = np.array(yaw_to_quaternion(quaternion_to_yaw(x, y, z, w)))
    unit = np.array([x, y, z, w]) / math.hypot(z, w)
    assert min(np.abs(back - unit).max(), np.abs(back + unit).max()) < 1e-12  # q and -q are one rotation


def quaternion_product(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


@given(wrapped_angles, st.floats(-1.4, 1.4), st.floats(-3.0, 3.0), st.floats(0.1, 10.0))
def test_yaw_of_a_tilted_quaternion_ignores_roll_and_pitch(yaw, pitch, roll, length):
    about_y = (0.0, math.sin(pitch / 2), 0.0, math.cos(pitch / 2))
    about_x = (math.sin(roll / 2), 0.0, 0.0, math.cos(roll / 2))
    tilted = quaternion_product(yaw_to_quaternion(yaw), quaternion_product(about_y, about_x))  # ZYX order
    assert angle_difference(quaternion_to_yaw(*(length * c for c in tilted)), yaw) < 1e-9


@pytest.mark.parametrize(
    "quaternion,match",
    [
        ((0.0, 0.0, 0.0, 0.0), "not a rotation"),
        ((0.0, 0.0, float("nan"), 1.0), "z = nan"),
        ((0.0, float("inf"), 0.0, 1.0), "y = inf"),
        ((0.0, 0.0, "0.5", 1.0), "z = '0.5'"),
    ],
)
def test_bad_quaternion_is_rejected(quaternion, match):
    with pytest.raises(ValueError, match=match):
        quaternion_to_yaw(*quaternion)


@pytest.mark.parametrize("yaw", [float("nan"), float("inf"), None, True])
def test_bad_yaw_is_rejected(yaw):
    with pytest.raises(ValueError, match="yaw"):
        yaw_to_quaternion(yaw)


# -- covariances ------------------------------------------------------------------------------------------------
def test_ros_covariance_layout():
    cov3 = np.array([[0.04, 0.01, 0.002], [0.01, 0.09, -0.003], [0.002, -0.003, 0.25]])
    full = covariance3_to_ros6(cov3).reshape(6, 6)
    assert full[0, 0] == 0.04 and full[1, 1] == 0.09 and full[5, 5] == 0.25
    assert full[0, 1] == full[1, 0] == 0.01
    assert full[0, 5] == full[5, 0] == 0.002 and full[1, 5] == full[5, 1] == -0.003
    np.testing.assert_array_equal(np.diag(full)[2:5], UNESTIMATED_VARIANCE)
    unused = np.ones((6, 6), bool)
    unused[np.ix_([0, 1, 5], [0, 1, 5])] = False
    np.fill_diagonal(unused, False)
    assert (full[unused] == 0.0).all()
    assert np.diag(covariance3_to_ros6(cov3, unestimated_variance=1.0).reshape(6, 6))[2:5].tolist() == [1.0] * 3


@given(covariances())
def test_covariance_survives_ros(cov3):
    full = covariance3_to_ros6(cov3)
    assert full.shape == (36,)
    np.testing.assert_array_equal(full.reshape(6, 6), full.reshape(6, 6).T)
    np.testing.assert_allclose(ros6_to_covariance3(full), cov3, rtol=0, atol=1e-15)


@given(covariances(size=6))
def test_ros_covariance_keeps_its_planar_block(full):
    planar = ros6_to_covariance3(full.reshape(36))
    np.testing.assert_allclose(planar, full[np.ix_([0, 1, 5], [0, 1, 5])], atol=1e-15)
    again = covariance3_to_ros6(planar).reshape(6, 6)
    np.testing.assert_allclose(again[np.ix_([0, 1, 5], [0, 1, 5])], full[np.ix_([0, 1, 5], [0, 1, 5])], atol=1e-15)
    np.testing.assert_array_equal(ros6_to_covariance3(full), planar)  # a (6, 6) matrix is taken too


@pytest.mark.parametrize(
    "function,matrix,match",
    [
        (covariance3_to_ros6, np.eye(2), r"cov3 has shape \(2, 2\)"),
        (covariance3_to_ros6, np.array([[1.0, 0.5, 0], [0.0, 1, 0], [0, 0, 1]]), r"not symmetric: \[0, 1\]"),
        (covariance3_to_ros6, np.diag([1.0, np.nan, 1.0]), r"cov3\[1, 1\] = nan"),
        (covariance3_to_ros6, np.diag([1.0, 1.0, -1.0]), r"cov3\[2, 2\] = -1.0"),
        (covariance3_to_ros6, [["a", 0, 0]] * 3, "must be an array of numbers"),
        (ros6_to_covariance3, np.eye(3), r"cov36 has shape \(3, 3\), expected \(36,\) or \(6, 6\)"),
        (ros6_to_covariance3, np.arange(36.0), "not symmetric"),
        (ros6_to_covariance3, np.full(36, np.inf), r"cov36\[0\] = inf"),
    ],
)
def test_bad_covariance_is_rejected(function, matrix, match):
    with pytest.raises(ValueError, match=match):
        function(matrix)


def test_rounding_asymmetry_is_forgiven_and_removed():
    cov3 = np.array([[0.04, 0.01, 0.0], [0.01 * (1 + 1e-14), 0.09, 0.0], [0.0, 0.0, 0.25]])
    full = covariance3_to_ros6(cov3).reshape(6, 6)
    np.testing.assert_array_equal(full, full.T)


def test_bad_filler_variance_is_rejected():
    with pytest.raises(ValueError, match="unestimated_variance = -1.0 must be >= 0"):
        covariance3_to_ros6(np.eye(3), unestimated_variance=-1.0)


def test_zero_filler_is_nav2_amcls_convention():
    full = covariance3_to_ros6(np.diag([1.0, 2.0, 3.0]), unestimated_variance=0.0)
    np.testing.assert_array_equal(full.reshape(6, 6), np.diag([1.0, 2.0, 0.0, 0.0, 0.0, 3.0]))


# -- ROS messages -----------------------------------------------------------------------------------------------
def test_ros_message_has_the_geometry_msgs_shape():
    message = pose_to_ros(
        [1.5, -2.0, math.pi / 2], np.diag([0.01, 0.02, 0.03]), 1_700_000_000_250_000_000, frame_id="field"
    )
    assert message["header"] == {"stamp": {"sec": 1_700_000_000, "nanosec": 250_000_000}, "frame_id": "field"}
    assert message["pose"]["pose"] == pose_to_ros_pose([1.5, -2.0, math.pi / 2])
    assert message["pose"]["pose"]["position"] == {"x": 1.5, "y": -2.0, "z": 0.0}
    orientation = message["pose"]["pose"]["orientation"]
    assert orientation["z"] == pytest.approx(math.sqrt(0.5)) and orientation["w"] == pytest.approx(math.sqrt(0.5))
    assert len(message["pose"]["covariance"]) == 36
    assert all(type(value) is float for value in message["pose"]["covariance"])


@given(poses, covariances(), stamps_ns, st.booleans())
def test_pose_survives_a_ros_message(pose, covariance, stamp_ns, as_object):
    message = pose_to_ros(pose, covariance, stamp_ns)
    stamp_back, pose_back, covariance_back = ros_to_pose(message_as_object(message) if as_object else message)
    assert stamp_back == stamp_ns
    np.testing.assert_array_equal(pose_back[:2], pose[:2])
    assert angle_difference(pose_back[2], pose[2]) < 1e-12
    np.testing.assert_allclose(covariance_back, covariance, atol=1e-15)


@given(st.tuples(coordinates, coordinates, wrapped_angles).map(np.array), covariances(), stamps_ns)
def test_ros_message_survives_a_pose(pose, covariance, stamp_ns):
    message = pose_to_ros(pose, covariance, stamp_ns)
    stamp_back, pose_back, covariance_back = ros_to_pose(message)
    again = pose_to_ros(pose_back, covariance_back, stamp_back)
    assert again["header"] == message["header"]
    assert again["pose"]["pose"]["position"] == message["pose"]["pose"]["position"]
    np.testing.assert_allclose(
        list(again["pose"]["pose"]["orientation"].values()),
        list(message["pose"]["pose"]["orientation"].values()),
        atol=1e-12,
    )
    np.testing.assert_allclose(again["pose"]["covariance"], message["pose"]["covariance"], atol=1e-15)


@given(poses)
def test_bare_pose_survives_ros(pose):
    odometry = message_as_object({"pose": {"pose": pose_to_ros_pose(pose)}})  # as in nav_msgs/Odometry
    back = ros_pose_to_pose(odometry.pose.pose)
    np.testing.assert_array_equal(back[:2], pose[:2])
    assert angle_difference(back[2], pose[2]) < 1e-12


def test_bare_pose_errors_use_the_given_name():
    with pytest.raises(ValueError, match="odometry.pose.pose.position.y is missing"):
        ros_pose_to_pose({"position": {"x": 0.0}}, "odometry.pose.pose")


def test_negative_stamp_borrows_a_second():
    message = pose_to_ros([0, 0, 0], np.eye(3), -1)
    assert message["header"]["stamp"] == {"sec": -1, "nanosec": 999_999_999}
    assert ros_to_pose(message)[0] == -1


@pytest.mark.parametrize(
    "arguments,match",
    [
        (([0, 0], np.eye(3), 0), r"pose has shape \(2,\)"),
        (([0, np.nan, 0], np.eye(3), 0), r"pose\[1\] = nan"),
        (([0, 0, 0], np.eye(4), 0), "cov3 has shape"),
        (([0, 0, 0], np.eye(3), 1.5), "stamp_ns = 1.5"),
        (([0, 0, 0], np.eye(3), 2**31 * 10**9), "stamp_ns"),
        (([0, 0, 0], np.eye(3), 0, 7), "frame_id = 7"),
    ],
)
def test_bad_pose_for_ros_is_rejected(arguments, match):
    with pytest.raises(ValueError, match=match):
        pose_to_ros(*arguments)


def edited(message, path, value):
    """A deep copy of `message` with path "a.b.c" set to `value` (or removed when value is None)."""
    import copy

    message = copy.deepcopy(message)
    *parents, last = path.split(".")
    target = message
    for name in parents:
        target = target[name]
    if value is None:
        del target[last]
    else:
        target[last] = value
    return message


@pytest.mark.parametrize(
    "path,value,match",
    [
        ("header.stamp.nanosec", None, "message.header.stamp.nanosec is missing"),
        ("header.stamp.nanosec", 10**9, r"nanosec = 1000000000 must be an integer in \[0, 1000000000\)"),
        ("header.stamp.sec", 1.5, "message.header.stamp.sec = 1.5"),
        ("pose.pose.position.x", float("nan"), "message.pose.pose.position.x = nan"),
        ("pose.pose.orientation", {"x": 0.0, "y": 0.0, "z": 0.0, "w": 0.0}, "orientation: .*not a rotation"),
        ("pose.pose.orientation.w", None, "message.pose.pose.orientation.w is missing"),
        ("pose.covariance", [0.0] * 35, r"message.pose.covariance: cov36 has shape \(35,\)"),
        ("pose", None, "message.pose is missing"),
    ],
)
def test_bad_ros_message_is_rejected(path, value, match):
    message = pose_to_ros([1.0, 2.0, 0.5], np.eye(3), 5)
    with pytest.raises(ValueError, match=match):
        ros_to_pose(edited(message, path, value))


# -- SPL messages -----------------------------------------------------------------------------------------------
def test_spl_speaks_millimetres():
    assert pose_to_spl([1.5, -0.25, 0.5]) == (1500.0, -250.0, 0.5)
    np.testing.assert_array_equal(spl_to_pose(1500.0, -250.0, 0.5), [1.5, -0.25, 0.5])
    assert pose_to_spl([0.0, 0.0, 3 * math.pi / 2])[2] == pytest.approx(-math.pi / 2)


@given(poses)
def test_pose_survives_spl(pose):
    x_mm, y_mm, theta = pose_to_spl(pose)
    for value in (x_mm, y_mm, theta):
        assert float(np.float32(value)) == value
    back = spl_to_pose(x_mm, y_mm, theta)
    np.testing.assert_allclose(back[:2], pose[:2], rtol=2**-23, atol=1e-9)
    assert angle_difference(back[2], pose[2]) < 1e-6


@given(*[st.floats(-20000.0, 20000.0, width=32)] * 2, st.floats(-3.0, 3.0, width=32))
def test_spl_survives_a_pose(x_mm, y_mm, theta):
    assert pose_to_spl(spl_to_pose(x_mm, y_mm, theta)) == (x_mm, y_mm, theta)


@pytest.mark.parametrize(
    "call,match",
    [
        (lambda: pose_to_spl([1.0, 2.0]), "pose has shape"),
        (lambda: pose_to_spl([1e36, 0.0, 0.0]), r"pose\[0\] = 1e\+36 m does not fit a float32"),
        (lambda: spl_to_pose(float("nan"), 0.0, 0.0), "x_mm = nan"),
        (lambda: spl_to_pose(0.0, "1", 0.0), "y_mm = '1'"),
        (lambda: spl_to_pose(0.0, 0.0, float("inf")), "theta = inf"),
    ],
)
def test_bad_spl_input_is_rejected(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# -- team and venue frames --------------------------------------------------------------------------------------
def test_venue_frame_mirrors_a_team_playing_right_to_left():
    pose = np.array([1.0, 2.0, 0.5])
    np.testing.assert_array_equal(team_to_venue_frame(pose, True), pose)
    np.testing.assert_allclose(team_to_venue_frame(pose, False), [-1.0, -2.0, 0.5 - math.pi])
    assert team_to_venue_frame(np.zeros((4, 3)), False).shape == (4, 3)


@given(st.lists(st.tuples(coordinates, coordinates, angles), min_size=1, max_size=5).map(np.array), st.booleans())
def test_poses_survive_the_venue_frame(team_poses, playing_left_to_right):
    back = venue_to_team_frame(team_to_venue_frame(team_poses, playing_left_to_right), playing_left_to_right)
    np.testing.assert_array_equal(back[:, :2], team_poses[:, :2])
    assert (angle_difference(back[:, 2], team_poses[:, 2]) < 1e-12).all()
    assert (back[:, 2] > -math.pi).all() and (back[:, 2] <= math.pi).all()


@pytest.mark.parametrize(
    "poses_,side,match",
    [
        (np.zeros((2, 2)), True, r"poses has shape \(2, 2\)"),
        (np.zeros((2, 3, 3)), True, "poses has shape"),
        ([[0.0, np.nan, 0.0]], False, r"poses\[0, 1\] = nan"),
        (np.zeros(3), "left", "playing_left_to_right = 'left'"),
    ],
)
def test_bad_venue_frame_input_is_rejected(poses_, side, match):
    with pytest.raises(ValueError, match=match):
        team_to_venue_frame(poses_, side)
