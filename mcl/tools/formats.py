"""Our poses in the formats teams speak: ROS messages, the SPL team message, a venue-fixed frame.

    from mcl.tools.formats import pose_to_ros, ros_to_pose, pose_to_spl, spl_to_pose

    message = pose_to_ros(pose, covariance, stamp_ns=log.origin_ns + 1_500_000_000)
    stamp_ns, pose, covariance = ros_to_pose(message)     # a dict, or the object mcap_ros2 decodes
    x_mm, y_mm, theta = pose_to_spl(pose)                 # for the SPL message's float pose[3]

A pose is `[x, y, θ]` in the field frame (DESIGN.md): metres, origin at the centre mark, +x toward the goal
our team attacks, +y left, θ counter-clockwise from +x in (-π, π]. A covariance is the (3, 3) matrix over
(x, y, θ) in m² and rad². Every function here validates its input (finite numbers, shapes) and raises a
`ValueError` naming the bad field and value; every heading it returns is wrapped to (-π, π].

Conversions:

- `yaw_to_quaternion(yaw) -> (x, y, z, w)`: a rotation about +z, with w >= 0.
  `quaternion_to_yaw(x, y, z, w)`: the heading of the rotated +x axis seen from above (the yaw of a ZYX
  Euler decomposition), so a quaternion that also rolls or pitches gives its yaw. It need not be normalized;
  a zero or non-finite one is rejected. When the rotated +x axis points straight up or down there is no
  heading, and the result is arbitrary.
- `covariance3_to_ros6(cov3) -> (36,)`: the row-major covariance of a ROS `PoseWithCovariance` over
  (x, y, z, roll, pitch, yaw). z, roll and pitch are not estimated by a planar filter: their variances are
  set to `UNESTIMATED_VARIANCE` (1e6, "unknown", so a fusing filter such as robot_localization gives them no
  weight) and their covariances with everything else to 0; `unestimated_variance=0.0` writes nav2_amcl's
  zeros instead. `ros6_to_covariance3` reads back the (x, y, yaw) block and ignores the rest.
- `pose_to_ros(pose, covariance, stamp_ns, frame_id="map") -> dict` in the shape of
  `geometry_msgs/msg/PoseWithCovarianceStamped` (what an MCAP writer encodes), and `ros_to_pose(message)`
  reading it back from that dict or from any object with the same attributes. `pose_to_ros_pose` and
  `ros_pose_to_pose` do the same for the bare `geometry_msgs/msg/Pose` inside it (and inside
  `nav_msgs/msg/Odometry`).
- `pose_to_spl(pose) -> (x_mm, y_mm, theta_rad)`: the pose of the SPL GameController return message
  (`float pose[3]`): the same team-relative frame as ours, x and y in millimetres, θ in radians, each value
  rounded to float32. `spl_to_pose(x_mm, y_mm, theta)` is its inverse.
- `team_to_venue_frame(poses, playing_left_to_right)`: our frame is relative to the team (+x toward the goal
  it attacks), so it turns round at half time. A frame fixed to the venue (+x toward the right-hand goal as
  the GameController shows the field), such as an overhead tracker's ground truth or a shared visualizer's,
  equals ours while the team plays left to right and is its mirror through the centre mark,
  (x, y, θ) -> (-x, -y, θ + π), otherwise. `venue_to_team_frame` converts back.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from field import Field
from field.angles import wrap_angle, wrap_angles

UNESTIMATED_VARIANCE = 1.0e6
"""The variance written for z [m²], roll and pitch [rad²] of a ROS covariance: 'unknown'."""

# Indices of x, y and yaw in ROS's (x, y, z, roll, pitch, yaw) ordering.
_ROS_PLANAR_AXES = (0, 1, 5)
_NANOSECONDS_PER_SECOND = 1_000_000_000
_INT32_RANGE = (-(2**31), 2**31 - 1)


def _finite_number(name: str, value: object) -> float:
    if type(value) is float and math.isfinite(value):  # what a decoded message holds: no ABC check
        return value
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} = {value!r} must be a number")
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"{name} = {value!r} must be finite")
    return number


def _finite_array(name: str, value: object, *shapes: tuple[int, ...]) -> np.ndarray:
    """A float64 copy of `value`, finite and (when shapes are given) of one of `shapes`."""
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} must be an array of numbers") from None
    if shapes and array.shape not in shapes:
        raise ValueError(f"{name} has shape {array.shape}, expected {' or '.join(map(str, shapes))}")
    if not np.isfinite(array).all():
        index = tuple(int(i) for i in np.argwhere(~np.isfinite(array))[0])
        where = f"[{', '.join(map(str, index))}]" if index else ""
        raise ValueError(f"{name}{where} = {float(array[index])!r} must be finite")
    return array


def _checked_pose(pose: object) -> np.ndarray:
    """A (3,) float64 copy of `pose` with θ wrapped."""
    checked = _finite_array("pose", pose, (3,))
    checked[2] = wrap_angle(checked[2])
    return checked


def _checked_covariance(name: str, matrix: object, size: int, *shapes: tuple[int, ...]) -> np.ndarray:
    """`matrix` (in one of `shapes`) as a finite, exactly symmetric (size, size) float64 matrix, diagonal >= 0.

    Symmetry is checked to 1e-9 of the largest entry: a covariance computed as A P Aᵀ is off by rounding.
    """
    checked = _finite_array(name, matrix, *shapes).reshape(size, size)
    asymmetry = np.abs(checked - checked.T)
    if (asymmetry > 1e-9 * np.abs(checked).max(initial=0.0)).any():
        row, column = (int(i) for i in np.unravel_index(np.argmax(asymmetry), asymmetry.shape))
        raise ValueError(
            f"{name} is not symmetric: [{row}, {column}] = {float(checked[row, column])!r} but "
            f"[{column}, {row}] = {float(checked[column, row])!r}"
        )
    diagonal = np.diag(checked)
    if (diagonal < 0).any():
        i = int(np.argmax(diagonal < 0))
        raise ValueError(f"{name}[{i}, {i}] = {float(diagonal[i])!r} is a variance and must be >= 0")
    return (checked + checked.T) / 2.0


# -- quaternions ------------------------------------------------------------------------------------------------
def yaw_to_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """The unit quaternion (x, y, z, w) of a rotation by `yaw` [rad] about +z; w >= 0."""
    half = wrap_angle(_finite_number("yaw", yaw)) / 2.0
    return 0.0, 0.0, math.sin(half), math.cos(half)


def quaternion_to_yaw(x: float, y: float, z: float, w: float) -> float:
    """The heading [rad] in (-π, π] of the rotated +x axis: the yaw of the rotation, whatever its roll and pitch.

    The quaternion need not have unit length (both atan2 arguments scale with its squared norm).
    """
    x, y, z, w = (_finite_number(name, value) for name, value in zip("xyzw", (x, y, z, w)))
    # Scaling by the largest component keeps the squares below overflow; the heading does not change.
    scale = max(abs(x), abs(y), abs(z), abs(w))
    if scale == 0.0:
        raise ValueError("quaternion (x, y, z, w) = (0, 0, 0, 0) is not a rotation")
    x, y, z, w = x / scale, y / scale, z / scale, w / scale
    return float(wrap_angle(math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)))


# -- covariances ------------------------------------------------------------------------------------------------
def covariance3_to_ros6(cov3: object, unestimated_variance: float = UNESTIMATED_VARIANCE) -> np.ndarray:
    """The (36,) row-major ROS covariance over (x, y, z, roll, pitch, yaw) of an (x, y, θ) covariance.

    z, roll and pitch get `unestimated_variance` on the diagonal and no covariance with anything; 0.0 gives
    nav2_amcl's convention (a plane known exactly).
    """
    planar = _checked_covariance("cov3", cov3, 3, (3, 3))
    filler = _finite_number("unestimated_variance", unestimated_variance)
    if filler < 0:
        raise ValueError(f"unestimated_variance = {unestimated_variance!r} must be >= 0")
    full = np.diag([0.0, 0.0, filler, filler, filler, 0.0])
    full[np.ix_(_ROS_PLANAR_AXES, _ROS_PLANAR_AXES)] = planar
    return full.reshape(36)


def ros6_to_covariance3(cov36: object) -> np.ndarray:
    """The (3, 3) covariance over (x, y, θ) in a ROS (36,) row-major covariance (a (6, 6) one is taken too)."""
    full = _checked_covariance("cov36", cov36, 6, (36,), (6, 6))
    return np.ascontiguousarray(full[np.ix_(_ROS_PLANAR_AXES, _ROS_PLANAR_AXES)])


# -- ROS messages -----------------------------------------------------------------------------------------------
def pose_to_ros_pose(pose: object) -> dict:
    """A `geometry_msgs/msg/Pose` as a dict: position (z = 0) and the quaternion of θ."""
    checked = _checked_pose(pose)
    qx, qy, qz, qw = yaw_to_quaternion(checked[2])
    return {
        "position": {"x": float(checked[0]), "y": float(checked[1]), "z": 0.0},
        "orientation": {"x": qx, "y": qy, "z": qz, "w": qw},
    }


_MISSING = object()


def _member(message: object, path: str, root: str = "message") -> object:
    """message.a.b.c for path "a.b.c", through dict keys or attributes; a ValueError names what is missing."""
    value = message
    names = path.split(".")
    for depth, name in enumerate(names):
        value = value.get(name, _MISSING) if isinstance(value, dict) else getattr(value, name, _MISSING)
        if value is _MISSING:
            raise ValueError(f"{root}.{'.'.join(names[: depth + 1])} is missing")
    return value


def ros_pose_to_pose(pose_message: object, name: str = "pose") -> np.ndarray:
    """[x, y, θ] of a `geometry_msgs/msg/Pose` (a dict or an object): z is ignored, θ is the orientation's yaw.

    `name` is what errors call the message (e.g. "message.pose.pose").
    """
    x, y = (_finite_number(f"{name}.position.{axis}", _member(pose_message, f"position.{axis}", name)) for axis in "xy")
    orientation = [_member(pose_message, f"orientation.{axis}", name) for axis in "xyzw"]
    try:
        yaw = quaternion_to_yaw(*(_finite_number(axis, value) for axis, value in zip("xyzw", orientation)))
    except ValueError as error:
        raise ValueError(f"{name}.orientation: {error}") from None
    return np.array([x, y, yaw])


def pose_to_ros(
    pose: object,
    covariance: object,
    stamp_ns: int,
    frame_id: str = "map",
    unestimated_variance: float = UNESTIMATED_VARIANCE,
) -> dict:
    """A `geometry_msgs/msg/PoseWithCovarianceStamped` as a dict: header (stamp, frame_id) and pose.

    `stamp_ns` is integer nanoseconds since the epoch; the covariance is filled as `covariance3_to_ros6` does.
    """
    ros_pose = pose_to_ros_pose(pose)
    full_covariance = covariance3_to_ros6(covariance, unestimated_variance)
    if isinstance(stamp_ns, bool) or not isinstance(stamp_ns, numbers.Integral):
        raise ValueError(f"stamp_ns = {stamp_ns!r} must be an integer (nanoseconds)")
    seconds, nanoseconds = divmod(int(stamp_ns), _NANOSECONDS_PER_SECOND)
    if not _INT32_RANGE[0] <= seconds <= _INT32_RANGE[1]:
        raise ValueError(f"stamp_ns = {stamp_ns!r} does not fit a ROS time (int32 seconds)")
    if not isinstance(frame_id, str):
        raise ValueError(f"frame_id = {frame_id!r} must be a string")
    return {
        "header": {"stamp": {"sec": seconds, "nanosec": nanoseconds}, "frame_id": frame_id},
        "pose": {"pose": ros_pose, "covariance": full_covariance.tolist()},
    }


def ros_to_pose(message: object) -> tuple[int, np.ndarray, np.ndarray]:
    """(stamp_ns, pose (3,), covariance (3, 3)) of a `PoseWithCovarianceStamped`, given as a dict or an object.

    Position z and the z/roll/pitch parts of the covariance are ignored; θ is the orientation's yaw.
    """
    stamp = {}
    for name, limit in (("sec", None), ("nanosec", _NANOSECONDS_PER_SECOND)):
        value = _member(message, f"header.stamp.{name}")
        if (
            isinstance(value, bool)
            or not isinstance(value, numbers.Integral)
            or (limit is not None and not 0 <= int(value) < limit)
        ):
            raise ValueError(
                f"message.header.stamp.{name} = {value!r} must be an integer"
                + ("" if limit is None else f" in [0, {limit})")
            )
        stamp[name] = int(value)
    pose = ros_pose_to_pose(_member(message, "pose.pose"), "message.pose.pose")
    try:
        covariance = ros6_to_covariance3(_member(message, "pose.covariance"))
    except ValueError as error:
        raise ValueError(f"message.pose.covariance: {error}") from None
    return stamp["sec"] * _NANOSECONDS_PER_SECOND + stamp["nanosec"], pose, covariance


# -- SPL team communication -------------------------------------------------------------------------------------
def pose_to_spl(pose: object) -> tuple[float, float, float]:
    """(x [mm], y [mm], θ [rad]) for the SPL message's `float pose[3]`, each value rounded to float32."""
    checked = _checked_pose(pose)
    with np.errstate(over="ignore"):
        rounded = np.array([checked[0] * 1000.0, checked[1] * 1000.0, checked[2]]).astype(np.float32)
    if not np.isfinite(rounded).all():
        i = int(np.argmin(np.isfinite(rounded)))
        raise ValueError(f"pose[{i}] = {float(checked[i])!r} m does not fit a float32 in millimetres")
    x_mm, y_mm, theta = (float(value) for value in rounded)
    return x_mm, y_mm, theta


def spl_to_pose(x_mm: float, y_mm: float, theta: float) -> np.ndarray:
    """The pose [x [m], y [m], θ [rad]] of an SPL message's (x [mm], y [mm], θ [rad])."""
    return _checked_pose(
        [_finite_number("x_mm", x_mm) / 1000.0, _finite_number("y_mm", y_mm) / 1000.0, _finite_number("theta", theta)]
    )


# -- team and venue frames --------------------------------------------------------------------------------------
def team_to_venue_frame(poses: object, playing_left_to_right: bool) -> np.ndarray:
    """Poses (3,) or (N, 3) in our team-relative frame, in the frame fixed to the venue (see the module doc).

    The venue frame's +x points toward the right-hand goal as the GameController shows the field; a team
    playing left to right attacks that goal, so its frame is the venue's, and otherwise its mirror.
    """
    if not isinstance(playing_left_to_right, (bool, np.bool_)):
        raise ValueError(f"playing_left_to_right = {playing_left_to_right!r} must be True or False")
    checked = _finite_array("poses", poses)
    if checked.ndim not in (1, 2) or checked.shape[-1] != 3:
        raise ValueError(f"poses has shape {checked.shape}, expected (3,) or (N, 3)")
    if playing_left_to_right:
        checked[..., 2] = wrap_angles(checked[..., 2])
        return checked
    return Field.mirror_poses(checked)


def venue_to_team_frame(poses: object, playing_left_to_right: bool) -> np.ndarray:
    """The inverse of `team_to_venue_frame` (the mirror through the centre mark is its own inverse)."""
    return team_to_venue_frame(poses, playing_left_to_right)
