"""Play a robot's MCAP log to its ROS topics, and listen to the node's answers: what the tests and
`robocup-mcl node bench` drive the node with.

    robocup-mcl node play game.mcap --rate 1          # every topic whose message type imports here

    player = LogPlayer("game.mcap", context=ctx)      # rclpy initialised in ctx
    listener = PoseListener(context=ctx)              # spun by an executor in a thread
    player.play(rate=1.0)                             # returns {odometry stamp ns: wall time sent}

The player publishes each message of the log at its log time (relative to the first, divided by `rate`), in
log-time order, and at the same log time the camera messages before the odometry, as `robocup-mcl replay`
takes them ("motion, then the frames that arrived by then"). `repeat` plays the log again right after itself,
with every header stamp moved on by the log's length (and one odometry period), so the localizer's clock never
goes back: an hour from a minute-long log. Messages of a type that does not import here are left out (listed in
`skipped`). Publishers are reliable with a queue of 100 (the node's subscriptions match).
"""

from __future__ import annotations

import importlib
import math
import threading
import time
from collections import deque
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import argparse

PROG = "robocup-mcl node play"
PARTICLE_SNAPSHOTS = 240  # particle messages the listener keeps (two minutes at the node's default 2 Hz)
PUBLISHED_SNAPSHOTS = 24  # of them, about this many go into `PoseListener.published`
ODOMETRY_TOPIC = "/motion_odometry"
TEAM_TOPIC = "/robocup_mcl/team"  # the node's team_topic by default


def message_class(type_name: str) -> Any:
    """The generated Python class of `pkg/msg/Type` (or `pkg/Type`); ImportError when it is not installed."""
    parts = type_name.split("/")
    module = importlib.import_module(f"{parts[0]}.msg")
    return getattr(module, parts[-1])


class LogPlayer:
    """Publishes an MCAP log's messages on their topics (see the module docstring).

    Parameters
    ----------
    path : str
        The MCAP log.
    context : rclpy.context.Context or None, default None
        The rclpy context (already initialised).
    seconds : float or None, default None
        Play at most this many seconds of the log (None: all of it).
    odometry_topic : str, default "/motion_odometry"
        The topic whose send times `play` returns (its messages' stamps as keys).
    """

    def __init__(
        self, path: str, context: Any = None, seconds: float | None = None, odometry_topic: str = ODOMETRY_TOPIC
    ) -> None:
        import rclpy
        from mcap.reader import make_reader
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rclpy.serialization import deserialize_message

        self.node = rclpy.create_node("robocup_mcl_player", context=context)
        self.odometry_topic = odometry_topic
        self.skipped: dict[str, str] = {}
        classes: dict[str, Any] = {}
        rows = []
        with open(path, "rb") as stream:
            for schema, channel, message in make_reader(stream).iter_messages(log_time_order=True):
                topic = channel.topic
                if topic in self.skipped:
                    continue
                if topic not in classes:
                    type_name = schema.name if schema is not None else "(no schema)"
                    try:
                        classes[topic] = message_class(type_name)
                    except (ImportError, AttributeError):
                        self.skipped[topic] = type_name
                        continue
                rows.append(
                    (
                        message.log_time,
                        topic != odometry_topic,
                        topic,
                        deserialize_message(message.data, classes[topic]),
                    )
                )
        if not rows:
            raise ValueError(f"{path}: no message of a type that imports here")
        first = rows[0][0]
        if seconds is not None:
            rows = [row for row in rows if row[0] - first <= seconds * 1e9]
        rows.sort(key=lambda row: (row[0], not row[1]))  # at one log time: the camera, then odometry
        self.messages = [(log_ns - first, topic, message) for log_ns, _, topic, message in rows]
        self.duration_ns = self.messages[-1][0]
        odometry = [t for t, topic, _ in self.messages if topic == odometry_topic]
        self.period_ns = int(odometry[1] - odometry[0]) if len(odometry) > 1 else 10_000_000
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.publishers = {topic: self.node.create_publisher(classes[topic], topic, qos) for topic in classes}

    def add_team_messages(self, rate: float, topic: str = TEAM_TOPIC, bad_every: int = 0) -> tuple[int, int]:
        """Play a teammate's broadcasts too (robocup_mcl_msgs/TeamMessage on `topic`), `rate` a second: player 2,
        at (0, 0, 0) with confidence 0.5 and no ball (no side evidence), stamped as the odometry message before
        it; every `bad_every`-th has a NaN x (0: none). Returns (messages, bad ones) per lap."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        team_message = message_class("robocup_mcl_msgs/TeamMessage")
        period = round(1e9 / rate)
        rows, stamp, next_ns, count, bad = [], None, 0, 0, 0
        for offset_ns, row_topic, message in self.messages:
            if row_topic == self.odometry_topic:
                stamp = message.header.stamp
            while stamp is not None and offset_ns >= next_ns:
                count += 1
                msg = team_message(sender=2, x=0.0, y=0.0, theta=0.0, confidence=0.5)
                msg.header.frame_id = "map"
                msg.header.stamp.sec, msg.header.stamp.nanosec = stamp.sec, stamp.nanosec
                if bad_every and count % bad_every == 0:
                    msg.x = math.nan
                    bad += 1
                rows.append((next_ns, topic, msg))
                next_ns += period
        self.messages = sorted(self.messages + rows, key=lambda row: row[0])  # stable: the log's order kept
        self.publishers[topic] = self.node.create_publisher(
            team_message, topic, QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        )
        return count, bad

    def wait_for_subscribers(self, topics: list[str], timeout: float) -> bool:
        """Wait until each of `topics` has a subscriber; False on timeout."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if all(self.publishers[t].get_subscription_count() > 0 for t in topics if t in self.publishers):
                return True
            time.sleep(0.05)
        return False

    def play(self, rate: float = 1.0, repeat: int = 1) -> dict[int, float]:
        """Publish the log `repeat` times at `rate` times real time; returns {odometry stamp [ns]: the
        `time.perf_counter()` it was published at}."""
        sent: dict[int, float] = {}
        shift_ns = self.duration_ns + self.period_ns
        start = time.perf_counter()
        for lap in range(repeat):
            for offset_ns, topic, message in self.messages:
                due = start + (lap * shift_ns + offset_ns) / 1e9 / rate
                pause = due - time.perf_counter()
                if pause > 0:
                    time.sleep(pause)
                header = getattr(message, "header", None)
                if header is not None and lap:  # each lap moves the stamps of the one before on
                    stamp = header.stamp.sec * 1_000_000_000 + header.stamp.nanosec + shift_ns
                    header.stamp.sec, header.stamp.nanosec = divmod(stamp, 1_000_000_000)
                self.publishers[topic].publish(message)
                if topic == self.odometry_topic and header is not None:
                    sent[header.stamp.sec * 1_000_000_000 + header.stamp.nanosec] = time.perf_counter()
        return sent

    def close(self) -> None:
        """Destroy the player's node."""
        self.node.destroy_node()


class PoseListener:
    """Records the node's poses (with the `time.perf_counter()` each arrived), its /tf messages, its quality
    changes, the sizes of its particle messages and its field markers (latched: received however late the
    listener starts). Spin `node` with an executor (`spin_in_thread`)."""

    def __init__(
        self,
        context: Any = None,
        pose_topic: str = "/robocup_mcl/pose",
        quality_topic: str = "/robocup_mcl/quality",
        particles_topic: str = "/robocup_mcl/particles",
        field_topic: str = "/robocup_mcl/field",
    ) -> None:
        import rclpy
        from geometry_msgs.msg import PoseArray, PoseWithCovarianceStamped
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String
        from tf2_msgs.msg import TFMessage

        self.node = rclpy.create_node("robocup_mcl_listener", context=context)
        self.poses: list[tuple[int, float, tuple[float, float, float]]] = []  # (stamp ns, arrival, pose)
        self.transforms: list[tuple[int, str, str]] = []
        self.qualities: list[str] = []
        self.particle_counts: list[int] = []  # poses in each particles message
        self.field_markers: list[tuple[str, int, int]] = []  # (namespace, id, type) of the last MarkerArray
        # the last MarkerArray's geometry: (namespace, id, type, points [(x, y)], position (x, y), scale x)
        self.field_geometry: list[tuple[str, int, int, list[tuple[float, float]], tuple[float, float], float]] = []
        # the latest particle messages: (stamp ns, [(x, y, θ)]), at most `PARTICLE_SNAPSHOTS` of them
        self.particle_snapshots: deque[tuple[int, list[tuple[float, float, float]]]] = deque(maxlen=PARTICLE_SNAPSHOTS)
        self.nonfinite_poses = 0  # poses whose position, orientation or covariance holds a NaN or an infinity
        self.nonfinite_transforms = 0  # the same for the /tf transforms' translations and rotations
        self._lock = threading.Lock()
        self.pose_sub = self.node.create_subscription(PoseWithCovarianceStamped, pose_topic, self._pose, 100)
        self.node.create_subscription(TFMessage, "/tf", self._tf, QoSProfile(depth=100))
        self.node.create_subscription(
            String,
            quality_topic,
            lambda m: self.qualities.append(m.data),
            QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL),
        )
        self.node.create_subscription(PoseArray, particles_topic, self._particles, 10)
        try:
            marker_array = message_class("visualization_msgs/MarkerArray")
        except ImportError:  # the field is not listened to where the message is not installed
            pass
        else:
            self.node.create_subscription(
                marker_array,
                field_topic,
                self._field,
                QoSProfile(
                    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
                ),
            )
        self._executor: Any = None
        self._thread: threading.Thread | None = None

    def _pose(self, msg: Any) -> None:
        from mcl.tools.formats import ros_to_pose

        arrived = time.perf_counter()
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        values = [p.x, p.y, p.z, q.x, q.y, q.z, q.w, *msg.pose.covariance]
        if not all(math.isfinite(v) for v in values):
            self.nonfinite_poses += 1
            return
        stamp, pose, _ = ros_to_pose(msg)
        with self._lock:
            self.poses.append((stamp, arrived, (float(pose[0]), float(pose[1]), float(pose[2]))))

    def _particles(self, msg: Any) -> None:
        from mcl.tools.formats import quaternion_to_yaw

        self.particle_counts.append(len(msg.poses))
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        self.particle_snapshots.append(
            (
                stamp,
                [
                    (
                        float(p.position.x),
                        float(p.position.y),
                        quaternion_to_yaw(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w),
                    )
                    for p in msg.poses
                ],
            )
        )

    def _field(self, msg: Any) -> None:
        self.field_markers = [(marker.ns, int(marker.id), int(marker.type)) for marker in msg.markers]
        self.field_geometry = [
            (
                marker.ns,
                int(marker.id),
                int(marker.type),
                [(float(point.x), float(point.y)) for point in marker.points],
                (float(marker.pose.position.x), float(marker.pose.position.y)),
                float(marker.scale.x),
            )
            for marker in msg.markers
        ]

    def published(self) -> dict:
        """What the listener heard, as JSON-ready values (`robocup-mcl node figure` draws it): the field's markers
        (namespace, id, visualization_msgs/Marker type, points, position, scale x), the poses (stamp ns, x, y, θ),
        about `PUBLISHED_SNAPSHOTS` of the latest particle messages, evenly spaced, and the last (positions to 0.1 mm),
        and the quality changes."""
        with self._lock:
            poses = [[stamp, *(round(v, 5) for v in pose)] for stamp, _, pose in self.poses]
        snapshots = list(self.particle_snapshots)
        kept = snapshots[:: max(1, len(snapshots) // PUBLISHED_SNAPSHOTS)]
        if snapshots and kept[-1] is not snapshots[-1]:
            kept.append(snapshots[-1])
        return {
            "field_markers": [
                {"ns": ns, "id": i, "type": kind, "points": points, "position": position, "scale_x": scale}
                for ns, i, kind, points, position, scale in self.field_geometry
            ],
            "poses": poses,
            "particles": [
                {"stamp_ns": stamp, "poses": [[round(v, 4) for v in pose] for pose in poses]} for stamp, poses in kept
            ],
            "quality_changes": list(self.qualities),
        }

    def _tf(self, msg: Any) -> None:
        for transform in msg.transforms:
            t, r = transform.transform.translation, transform.transform.rotation
            if not all(math.isfinite(v) for v in (t.x, t.y, t.z, r.x, r.y, r.z, r.w)):
                self.nonfinite_transforms += 1
            stamp = transform.header.stamp.sec * 1_000_000_000 + transform.header.stamp.nanosec
            self.transforms.append((stamp, transform.header.frame_id, transform.child_frame_id))

    def spin_in_thread(self, context: Any = None) -> None:
        """Spin the listener with a `SingleThreadedExecutor` in a daemon thread."""
        from rclpy.executors import SingleThreadedExecutor

        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except Exception:  # noqa: BLE001 - the executor stops when the context shuts down
            pass

    def close(self) -> None:
        """Stop the executor (2 s at most), destroy the node, join the thread."""
        if self._executor is not None:
            self._executor.shutdown(timeout_sec=2)
        self.node.destroy_node()
        if self._thread is not None:
            self._thread.join(timeout=5)


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    import argparse

    from mcl.tools.cli_checks import NO_PROGRESS_HELP

    parser = argparse.ArgumentParser(
        prog=prog,
        description="Play a robot's MCAP log to its ROS 2 topics, in "
        "log-time order at its log times (camera messages before odometry at equal times).",
    )
    parser.add_argument("log", help="the MCAP log")
    parser.add_argument("--rate", type=float, default=1.0, help="multiple of real time (default 1)")
    parser.add_argument("--seconds", type=float, default=None, help="play at most this many seconds of the log")
    parser.add_argument("--repeat", type=int, default=1, help="play it this many times, stamps moved on (default 1)")
    parser.add_argument(
        "--wait",
        type=float,
        default=10.0,
        help="seconds to wait for a subscriber on the odometry topic before playing (default 10)",
    )
    parser.add_argument("--no-progress", action="store_true", help=NO_PROGRESS_HELP + "; this command shows none")
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl node play LOG` (see `--help`); returns the exit status."""
    from mcl.tools.cli_checks import CommandError
    from mcl.tools.ros.node import require_ros

    args = build_parser(prog).parse_args(argv)
    if not (args.rate > 0 and args.repeat >= 1):
        raise CommandError("--rate must be > 0 and --repeat >= 1")
    require_ros()
    import rclpy

    rclpy.init()
    try:
        player = LogPlayer(args.log, seconds=args.seconds)
        player.wait_for_subscribers([player.odometry_topic], args.wait)
        sent = player.play(args.rate, args.repeat)
        print(
            f"played {len(player.messages) * args.repeat} messages ({len(sent)} odometry) of {args.log}"
            + (f"; left out (type not installed): {player.skipped}" if player.skipped else "")
        )
        player.close()
    finally:
        if rclpy.ok():
            rclpy.shutdown()
    return 0
