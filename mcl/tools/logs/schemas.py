"""ROS 2 message definitions of the messages a robot log carries, as the text of an MCAP `ros2msg` schema.

    from mcl.tools.logs.schemas import ODOMETRY, definition

    schema = writer.register_msgdef(ODOMETRY, definition(ODOMETRY))   # mcap_ros2.writer.Writer

An MCAP file written by ROS 2 carries each message type's definition with it, so a reader needs no ROS
install. The definition of a type is its own field lines, then every type it depends on (depth first, each
once), each after a line of 80 '=' and a line `MSG: pkg/Type` -- the layout rosbag2 writes.

`FIELDS` holds the field lines of every type here (ROS 2 Humble and later; the soccer messages are those of
ros-sports/soccer_interfaces: soccer_vision_3d_msgs, soccer_vision_attribute_msgs). Type names are accepted
in either spelling, `nav_msgs/msg/Odometry` (an MCAP schema name) or `nav_msgs/Odometry` (a field type);
`short_name` turns the first into the second.
"""

from __future__ import annotations

TIME = "builtin_interfaces/msg/Time"
HEADER = "std_msgs/msg/Header"
POINT = "geometry_msgs/msg/Point"
QUATERNION = "geometry_msgs/msg/Quaternion"
VECTOR3 = "geometry_msgs/msg/Vector3"
POSE = "geometry_msgs/msg/Pose"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_WITH_COVARIANCE = "geometry_msgs/msg/PoseWithCovariance"
POSE_WITH_COVARIANCE_STAMPED = "geometry_msgs/msg/PoseWithCovarianceStamped"
TWIST = "geometry_msgs/msg/Twist"
TWIST_WITH_COVARIANCE = "geometry_msgs/msg/TwistWithCovariance"
ODOMETRY = "nav_msgs/msg/Odometry"
JOINT_STATE = "sensor_msgs/msg/JointState"
IMU = "sensor_msgs/msg/Imu"
GOALPOST_ARRAY = "soccer_vision_3d_msgs/msg/GoalpostArray"
MARKING_ARRAY = "soccer_vision_3d_msgs/msg/MarkingArray"

SEPARATOR = "=" * 80

# Constants (NAME=value) and defaults (a third word) are part of a definition as ROS ships it; they do
# not change the wire format, but a definition that differs from ROS's would confuse other tools.
FIELDS: dict[str, tuple[str, ...]] = {
    "builtin_interfaces/Time": ("int32 sec", "uint32 nanosec"),
    "std_msgs/Header": ("builtin_interfaces/Time stamp", "string frame_id"),
    "geometry_msgs/Point": ("float64 x", "float64 y", "float64 z"),
    "geometry_msgs/Vector3": ("float64 x", "float64 y", "float64 z"),
    "geometry_msgs/Quaternion": ("float64 x 0", "float64 y 0", "float64 z 0", "float64 w 1"),
    "geometry_msgs/Pose": ("geometry_msgs/Point position", "geometry_msgs/Quaternion orientation"),
    "geometry_msgs/PoseStamped": ("std_msgs/Header header", "geometry_msgs/Pose pose"),
    "geometry_msgs/PoseWithCovariance": ("geometry_msgs/Pose pose", "float64[36] covariance"),
    "geometry_msgs/PoseWithCovarianceStamped": ("std_msgs/Header header", "geometry_msgs/PoseWithCovariance pose"),
    "geometry_msgs/Twist": ("geometry_msgs/Vector3 linear", "geometry_msgs/Vector3 angular"),
    "geometry_msgs/TwistWithCovariance": ("geometry_msgs/Twist twist", "float64[36] covariance"),
    "nav_msgs/Odometry": (
        "std_msgs/Header header",
        "string child_frame_id",
        "geometry_msgs/PoseWithCovariance pose",
        "geometry_msgs/TwistWithCovariance twist",
    ),
    "sensor_msgs/JointState": (
        "std_msgs/Header header",
        "string[] name",
        "float64[] position",
        "float64[] velocity",
        "float64[] effort",
    ),
    "sensor_msgs/Imu": (
        "std_msgs/Header header",
        "geometry_msgs/Quaternion orientation",
        "float64[9] orientation_covariance",
        "geometry_msgs/Vector3 angular_velocity",
        "float64[9] angular_velocity_covariance",
        "geometry_msgs/Vector3 linear_acceleration",
        "float64[9] linear_acceleration_covariance",
    ),
    "vision_msgs/BoundingBox3D": ("geometry_msgs/Pose center", "geometry_msgs/Vector3 size"),
    "soccer_vision_attribute_msgs/Confidence": ("float32 CONFIDENCE_UNKNOWN=-1", "float32 confidence -1"),
    "soccer_vision_attribute_msgs/Goalpost": (
        "uint8 SIDE_UNKNOWN=0",
        "uint8 SIDE_LEFT=1",
        "uint8 SIDE_RIGHT=2",
        "uint8 TEAM_UNKNOWN=0",
        "uint8 TEAM_OWN=1",
        "uint8 TEAM_OPPONENT=2",
        "uint8 side",
        "uint8 team",
    ),
    "soccer_vision_3d_msgs/Goalpost": (
        "vision_msgs/BoundingBox3D bb",
        "soccer_vision_attribute_msgs/Goalpost attributes",
        "soccer_vision_attribute_msgs/Confidence confidence",
    ),
    "soccer_vision_3d_msgs/GoalpostArray": ("std_msgs/Header header", "soccer_vision_3d_msgs/Goalpost[] posts"),
    "soccer_vision_3d_msgs/MarkingEllipse": (
        "float64 diameter",
        "geometry_msgs/Pose center",
        "soccer_vision_attribute_msgs/Confidence confidence",
    ),
    "soccer_vision_3d_msgs/MarkingIntersection": (
        "geometry_msgs/Point center",
        "int32 num_rays",
        "geometry_msgs/Vector3[] rays",
        "soccer_vision_attribute_msgs/Confidence confidence",
    ),
    "soccer_vision_3d_msgs/MarkingSegment": (
        "geometry_msgs/Point start",
        "geometry_msgs/Point end",
        "soccer_vision_attribute_msgs/Confidence confidence",
    ),
    "soccer_vision_3d_msgs/MarkingArray": (
        "std_msgs/Header header",
        "soccer_vision_3d_msgs/MarkingEllipse[] ellipses",
        "soccer_vision_3d_msgs/MarkingIntersection[] intersections",
        "soccer_vision_3d_msgs/MarkingSegment[] segments",
    ),
}


def short_name(type_name: str) -> str:
    """`pkg/msg/Type` -> `pkg/Type` (a name already short is returned as it is)."""
    parts = type_name.strip().split("/")
    return f"{parts[0]}/{parts[-1]}" if len(parts) == 3 and parts[1] == "msg" else type_name.strip()


def full_name(type_name: str) -> str:
    """`pkg/Type` -> `pkg/msg/Type`, the spelling rosbag2 gives an MCAP schema."""
    package, _, name = short_name(type_name).partition("/")
    return f"{package}/msg/{name}"


def _field_lines(type_name: str) -> tuple[str, ...]:
    try:
        return FIELDS[short_name(type_name)]
    except KeyError:
        raise ValueError(
            f"type_name = {type_name!r} is not one of the message types here: {', '.join(sorted(FIELDS))}"
        ) from None


def dependencies(type_name: str) -> list[str]:
    """The message types `type_name` uses, directly or not: depth first, each once (short names)."""
    found: list[str] = []

    def visit(name: str) -> None:
        for line in _field_lines(name):
            field_type = line.split()[0].split("[")[0]
            if "/" in field_type and field_type not in found:
                found.append(field_type)
                visit(field_type)

    visit(type_name)
    return found


def definition(type_name: str) -> str:
    """The `ros2msg` schema text of `type_name`: its fields, then each dependency's (see the module doc)."""
    parts = ["\n".join(_field_lines(type_name))]
    for dependency in dependencies(type_name):
        parts.append(f"{SEPARATOR}\nMSG: {dependency}\n" + "\n".join(FIELDS[dependency]))
    return "\n".join(parts) + "\n"
