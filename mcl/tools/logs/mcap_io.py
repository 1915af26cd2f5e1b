"""ROS 2 MCAP robot logs: read into a `RobotLog`, write one back, and write the filter's poses.

    from mcl.tools.logs.mcap_io import Topics, list_topics, read_mcap, write_mcap, PoseWriter

    for row in list_topics("game.mcap"):                  # topic, type, count, first_s, last_s
        print(row)
    log, report = read_mcap("game.mcap", Topics(odometry="/odom"))    # a topic named must be there
    print(report.summary())
    with PoseWriter("poses.mcap", origin_ns=log.origin_ns) as poses:
        poses.write(t, pose, covariance)                    # t [s] from origin_ns, pose (3,), covariance (3, 3)

No ROS install is needed: an MCAP file carries its message definitions (`ros2msg` schemas), which
mcap_ros2 parses and `mcl.tools.logs.cdr` turns into compiled decoders (mcap_ros2's messages, several times
faster); `write_mcap` writes the definitions of `mcl.tools.logs.schemas` with the messages.

Streams, their default topics and the message types accepted (`Topics`; a topic set to "" is not read):

| stream | default topic | types |
|---|---|---|
| odometry | /motion_odometry | nav_msgs/Odometry: x, y and the yaw of the pose |
| commands | /cmd_vel | geometry_msgs/Twist (log time as stamp) or TwistStamped: (linear.x, linear.y, angular.z) |
| joint_commands | /joint_commands | sensor_msgs/JointState (name, position), bitbots_msgs/JointCommand |
| joint_states | /joint_states | sensor_msgs/JointState |
| imu | /imu/data | sensor_msgs/Imu: angular_velocity, linear_acceleration |
| goalposts | /goal_posts_relative | soccer_vision_3d_msgs/GoalpostArray |
| markings | /markings_relative | soccer_vision_3d_msgs/MarkingArray |
| truth | /ground_truth | geometry_msgs/PoseStamped or PoseWithCovarianceStamped |
| pose_out | /robocup_mcl/pose | written by `PoseWriter`: geometry_msgs/PoseWithCovarianceStamped |

The defaults follow the Humanoid League's ROS 2 stacks: the walking engine's odometry on /motion_odometry
(as the Hamburg Bit-Bots publish it: the motion the legs made, which is what the motion model wants, not a
fused /odom), the walk request on /cmd_vel, /joint_states and /imu/data as robot_state_publisher and IMU
drivers publish them, and the output topics of soccer_ipm (ros-sports), which projects detections onto
the ground in the robot frame. Joint commands and ground truth have no common name: /joint_commands (a
JointState, the plain ROS form) and /ground_truth are plain choices.

Reading (times are float64 seconds from `origin_ns`: the first message's log time, or the origin a file
written by `write_mcap` records, so a round trip keeps every time):
- capture time is the header stamp, arrival the MCAP log time; messages are taken in log-time order.
- vision: a goalpost is a GOALPOST at the range and bearing of its bounding box centre (x, y); an
  intersection of 2, 3 or 4 rays (`num_rays`) an L_, T_ or X_CROSSING (any other count is dropped and
  counted, one a detection); an ellipse of diameter < 0.5 m a PENALTY_MARK, a larger one the CENTER_MARK
  at its centre; a segment becomes line points every 0.15 m at most, both ends included (one point for a
  segment of zero length; a segment longer than 30 m, `MAX_SEGMENT_LENGTH`, is dropped and counted). A
  frame's order: goalposts, then intersections, then ellipses. Confidences are ignored. A GoalpostArray and
  a MarkingArray with the same stamp are one camera frame, received at the later log time; a frame whose
  detections `Observations` refuses is left out, its messages counted. Detections are taken as given in the
  robot frame (the header's frame_id is not transformed).
- joints: the names and their order are those of the first message on the joint_states topic; commands
  are mapped by name, a joint a command leaves out keeps its previous command (until its first command,
  its latest reading); command names the readings lack are ignored. A bitbots_msgs/JointCommand is read
  by its joint_names and positions fields.
- nothing is skipped silently: every message not used is counted in `report.dropped` under (topic,
  reason): "cannot decode ...", "non-finite value", "duplicate" (same topic, stamp and bytes),
  "time went backwards", "same stamp as the previous message" (also: stamps that are one float64 time in
  seconds from the origin), a stamp more than `MAX_STEP_DT` (an hour, the longest motion step) after the
  previous accepted one of its topic (the columnar reader refuses such a log), joint and vision reasons, and those of a message type the file defines unlike
  ROS ("no field ... in the message", "a field holds str, not a number", "... not an array").
- a gap longer than `gap` seconds between accepted messages of a topic is listed in `report.gaps`.
- a truncated or corrupt file yields everything before the break; `report.stop_reason` says what broke and
  `report.stopped_at` is the log time [s] of the last message read. Sizes a file claims (records, chunks,
  compressed frames, CDR lengths, offsets) are checked against its bytes before anything is allocated or
  sought. A topic the user named (one that is not its default, `Topics.required`) that the log lacks, a
  topic of an unexpected type, or a file that is not MCAP raise `LogError`; arguments of the wrong type
  raise TypeError.
- a default topic the log lacks is looked for by its message type: when exactly one topic of the log (not
  already read for another stream) carries a type the stream is found by (`DISCOVERY_TYPES`: every accepted
  type, except that joint commands are found only as bitbots_msgs/JointCommand, since a JointState topic may
  as well be the readings, and ground truth is never guessed: another pose topic may be an estimate), that
  topic is read. Several such topics are a `LogError` listing them (name one with `Topics`, or
  `--topic-<stream>` on the command line); none leaves the stream empty and its default topic listed in
  `report.missing`. `report.topics` says, for every stream read, its topic and how it was chosen: "name"
  (named in `Topics`), "default name" or "type".

Writing (`write_mcap`): one message per row of every non-empty stream, header stamp = capture time, log
time = the stamp (arrival for vision), frame ids "odom" (odometry), "map" (truth), "base_footprint"
(vision), "imu_frame" (IMU, its orientation marked as not given: orientation_covariance[0] = -1). A vision
frame is one GoalpostArray and one MarkingArray with its stamp: crossings as intersections with rays at
right angles (2, 3 or 4), the penalty mark as an ellipse of 0.1 m and the centre mark of 1.5 m, and each
line point as a segment of zero length (so it reads back as exactly that point). Range/bearing noises are
not carried. Times are written to the nanosecond.

`PoseWriter` writes `mcl.tools.formats.pose_to_ros` messages: the ROS 6x6 (x, y, z, roll, pitch, yaw) row-major
covariance holds the filter's 3x3 in the x, y, yaw rows and columns and 1e6 ("unknown") as the variance
of z, roll and pitch (`unestimated_variance=0.0` gives nav2_amcl's zeros). `read_poses` reads them back.
"""

from __future__ import annotations

import bisect
import hashlib
import math
import os
import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass, fields, replace
from dataclasses import field as dataclass_field
from typing import IO, Any, ClassVar, cast

import numpy as np
from mcap.exceptions import EndOfFile, McapError, UnsupportedCompressionError
from mcap.records import Channel, Chunk, Header, Message, MessageIndex, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk
from mcap_ros2.writer import Writer as Ros2Writer

from field import LandmarkType
from mcl.tools.formats import (
    UNESTIMATED_VARIANCE,
    covariance3_to_ros6,
    pose_to_ros,
    pose_to_ros_pose,
    ros_pose_to_pose,
    ros_to_pose,
)
from mcl.tools.logs import schemas
from mcl.tools.logs.cdr import DecoderFactory
from mcl.tools.logs.robot_log import LogError, ReadReport, RobotLog, VisionFrame
from motion_models.base import MAX_STEP_DT
from sensing.observations import Observations

try:
    import zstandard
except ImportError:  # without zstandard, a zstd chunk is unsupported (an McapError)
    zstandard = None  # type: ignore[assignment]  # an optional package, None when it is not installed
try:
    import lz4.frame as lz4_frame
except ImportError:  # without lz4, an lz4 chunk is unsupported
    lz4_frame = None

# What a truncated or corrupt file raises while its records are read: mcap's own errors (EndOfFile,
# a record longer than the file, bad magic), a record cut inside a field (struct), a bad checksum, a chunk
# that does not decompress (zstd; lz4 reports a corrupt frame as RuntimeError), a name that is not UTF-8.
BROKEN_FILE_ERRORS = (McapError, CRCValidationError, struct.error, RuntimeError, UnicodeDecodeError) + (
    (zstandard.ZstdError,) if zstandard is not None else ()
)
# What decoding one message's CDR bytes raises when they do not fit the schema.
_DECODE_ERRORS = (McapError, struct.error, ValueError, IndexError, UnicodeDecodeError, NotImplementedError)

ORIGIN_METADATA = "robocup_mcl.origin"
MCAP0_MAGIC = b"\x89MCAP0\r\n"
FOOTER_RECORD_BYTES = 1 + 8 + 20  # opcode, length, then summary start, summary offset start, CRC
MAX_CHUNK_BYTES = 1 << 30  # a chunk claiming more (uncompressed) is taken for corrupt
_FAR_AHEAD = f"more than MAX_STEP_DT = {MAX_STEP_DT:g} s after the previous message"
_DECOMPRESS_BLOCK = 1 << 20  # [bytes] a chunk is decompressed this much at a time
SEGMENT_SPACING = 0.15  # [m] the largest distance between line points sampled along a segment
MAX_SEGMENT_LENGTH = 30.0  # [m] a longer segment (no field line is seen that long) is dropped, not sampled
PENALTY_MARK_MAX_DIAMETER = 0.5  # [m] a smaller ellipse is the penalty mark, a larger one the centre circle
PENALTY_MARK_DIAMETER = 0.1  # [m] written for a penalty mark
CENTER_CIRCLE_DIAMETER = 1.5  # [m] written for the centre mark
CROSSING_RAYS = {2: LandmarkType.L_CROSSING, 3: LandmarkType.T_CROSSING, 4: LandmarkType.X_CROSSING}
VISION_FRAME_ID = "base_footprint"


@dataclass(frozen=True)
class Topics:
    """The topic of each stream (see the module docstring for the defaults and why); "" skips a stream.

    A topic that is not its default was named by the user, so it must be in the log: `read_mcap` raises
    `LogError` when it is not (`required` lists those streams); a default topic the log lacks is just an
    empty stream. A name without its leading '/' gets one, as ROS resolves it in the root namespace.
    `override(**topics)` is a copy with some topics changed (None leaves one as it is).
    """

    odometry: str = "/motion_odometry"
    commands: str = "/cmd_vel"
    joint_commands: str = "/joint_commands"
    joint_states: str = "/joint_states"
    imu: str = "/imu/data"
    goalposts: str = "/goal_posts_relative"
    markings: str = "/markings_relative"
    truth: str = "/ground_truth"
    pose_out: str = "/robocup_mcl/pose"

    STREAMS: ClassVar[tuple[str, ...]] = (
        "odometry",
        "commands",
        "joint_commands",
        "joint_states",
        "imu",
        "goalposts",
        "markings",
        "truth",
    )

    def __post_init__(self) -> None:
        for name in (f.name for f in fields(self)):
            topic = getattr(self, name)
            if not isinstance(topic, str) or topic != topic.strip() or any(c.isspace() for c in topic):
                raise ValueError(f"Topics.{name} = {topic!r} must be a topic name (or '' to skip the stream)")
            if topic and not topic.startswith("/"):
                object.__setattr__(self, name, "/" + topic)
        used = [getattr(self, name) for name in self.STREAMS if getattr(self, name)]
        repeated = sorted({topic for topic in used if used.count(topic) > 1})
        if repeated:
            raise ValueError(f"Topics: {repeated!r} given to more than one stream")

    @property
    def required(self) -> frozenset[str]:
        """The streams whose topic is not the default (and not ''): they must be in the log."""
        defaults = {f.name: f.default for f in fields(self)}
        return frozenset(name for name in self.STREAMS if getattr(self, name) not in ("", defaults[name]))

    def override(self, **topics: str | None) -> Topics:
        """A copy with these topics set; a None value leaves its topic as it is (handy with argparse)."""
        known = {f.name for f in fields(self)}
        for name in topics:
            if name not in known:
                raise ValueError(f"Topics.override: {name!r} is not a stream ({', '.join(sorted(known))})")
        return replace(self, **{name: topic for name, topic in topics.items() if topic is not None})

    def by_stream(self) -> dict[str, str]:
        """stream -> topic for the streams to read (those with a topic)."""
        return {name: getattr(self, name) for name in self.STREAMS if getattr(self, name)}


ACCEPTED_TYPES: dict[str, tuple[str, ...]] = {
    "odometry": ("nav_msgs/Odometry",),
    "commands": ("geometry_msgs/Twist", "geometry_msgs/TwistStamped"),
    "joint_commands": ("sensor_msgs/JointState", "bitbots_msgs/JointCommand"),
    "joint_states": ("sensor_msgs/JointState",),
    "imu": ("sensor_msgs/Imu",),
    "goalposts": ("soccer_vision_3d_msgs/GoalpostArray",),
    "markings": ("soccer_vision_3d_msgs/MarkingArray",),
    "truth": ("geometry_msgs/PoseStamped", "geometry_msgs/PoseWithCovarianceStamped"),
}

# The types a stream's topic is found by when its default topic is absent (see the module docstring): not
# JointState for joint commands (it may as well be the readings), nothing for ground truth.
DISCOVERY_TYPES: dict[str, tuple[str, ...]] = {
    **{stream: types for stream, types in ACCEPTED_TYPES.items() if stream not in ("joint_commands", "truth")},
    "joint_commands": ("bitbots_msgs/JointCommand",),
}


# ---------------------------------------------------------------------------------------------------------
# Header stamps (poses and covariances convert with mcl.tools.formats)


def _stamp_ns(header: Any) -> int:
    sec, nanosec = header.stamp.sec, header.stamp.nanosec
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in (sec, nanosec)):
        raise _Drop("the header stamp is not integer sec and nanosec")
    if not (-(2**31) <= sec < 2**31 and 0 <= nanosec < 2**32):
        raise _Drop("the header stamp does not fit builtin_interfaces/Time (int32 sec, uint32 nanosec)")
    return sec * 1_000_000_000 + nanosec


def _header(stamp_ns: int, frame_id: str) -> dict[str, Any]:
    seconds, nanoseconds = divmod(int(stamp_ns), 1_000_000_000)
    return {"stamp": {"sec": seconds, "nanosec": nanoseconds}, "frame_id": frame_id}


# ---------------------------------------------------------------------------------------------------------
# Scanning a file's records, to the end or to where it breaks


class _ExactReads:
    """A file whose reads return every byte asked for or raise EndOfFile, so that a record cut by the end
    of the file fails where it breaks instead of coming back short (and a corrupt length asking for more
    than the file holds fails before anything is allocated); a seek outside the file (a corrupt offset in
    the footer or an index) raises McapError."""

    def __init__(self, file, size: int) -> None:
        self._file = file
        self._size = size

    def read(self, size: int = -1) -> bytes:
        position = self._file.tell()
        if size > self._size - position:
            raise EndOfFile(
                f"the file ends {size - (self._size - position)} bytes before the end of a record "
                f"(a record read from byte {position})"
            )
        return self._file.read(size)

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        base = {os.SEEK_SET: 0, os.SEEK_CUR: self._file.tell(), os.SEEK_END: self._size}[whence]
        if not 0 <= base + offset <= self._size:
            raise McapError(f"an offset points at byte {base + offset}, outside the file ({self._size} bytes)")
        return self._file.seek(base + offset)

    def tell(self) -> int:
        return self._file.tell()


@dataclass
class _Scan:
    schemas: dict[int, Schema] = dataclass_field(default_factory=dict)
    channels: dict[int, Channel] = dataclass_field(default_factory=dict)
    kept: dict[int, list[Message]] = dataclass_field(default_factory=dict)  # channel id -> messages
    counts: dict[int, int] = dataclass_field(default_factory=dict)
    first_ns: dict[int, int] = dataclass_field(default_factory=dict)
    last_ns: dict[int, int] = dataclass_field(default_factory=dict)
    orphans: int = 0  # messages on a channel never defined
    origin_ns: int | None = None  # from the metadata write_mcap leaves
    last_read_ns: int | None = None  # log time of the last message read, in file order
    stop_reason: str | None = None

    @property
    def start_ns(self) -> int | None:
        return min(self.first_ns.values()) if self.first_ns else None

    def type_of(self, channel: Channel) -> str:
        schema = self.schemas.get(channel.schema_id)
        return schema.name if schema is not None else "(no schema)"

    def topics(self) -> list[str]:
        return sorted({channel.topic for channel in self.channels.values()})


def _origin_from(metadata: Metadata) -> int | None:
    """The origin `write_mcap` records, or None when the record does not hold one (an integer of nanoseconds
    from -2^63 to the largest MCAP log time, 2^64 - 1)."""
    try:
        origin = int(metadata.metadata["origin_ns"])
    except (KeyError, ValueError, TypeError):
        return None
    return origin if -(2**63) <= origin < 2**64 else None


def _decompressed(chunk: Chunk) -> bytes:
    """A chunk's records, decompressed a block at a time: memory grows with the data that comes out, never
    beyond the chunk's claimed uncompressed size (a corrupt or hostile size claimed in the chunk or in its
    compressed frame's header is not allocated up front, as the decompressors' one-call forms would)."""
    if chunk.compression == "zstd":
        if zstandard is None:
            raise UnsupportedCompressionError("zstd")
        reader = zstandard.ZstdDecompressor().stream_reader(chunk.data)

        def read() -> bytes:
            return reader.read(_DECOMPRESS_BLOCK)
    elif chunk.compression == "lz4":
        if lz4_frame is None:
            raise UnsupportedCompressionError("lz4")
        decompressor, pending = lz4_frame.LZ4FrameDecompressor(), [chunk.data]

        def read() -> bytes:
            if decompressor.eof or (decompressor.needs_input and not pending):
                return b""
            return decompressor.decompress(pending.pop() if pending else b"", max_length=_DECOMPRESS_BLOCK)
    else:
        return chunk.data  # uncompressed (mcap reads an unknown compression as none)
    blocks, size = [], 0
    while block := read():
        size += len(block)
        if size > chunk.uncompressed_size:
            raise McapError(f"a chunk decompresses to more than the {chunk.uncompressed_size} bytes it claims")
        blocks.append(block)
    return b"".join(blocks)


def _unchunked(records: Iterable) -> Iterable:
    """The records with each chunk opened, after checking its claimed size, and decompressed by
    `_decompressed` (a corrupt size must not make the decompressor ask for gigabytes)."""
    for record in records:
        if not isinstance(record, Chunk):
            yield record
            continue
        if record.uncompressed_size > MAX_CHUNK_BYTES:
            raise McapError(f"a chunk claims {record.uncompressed_size} bytes uncompressed")
        try:
            data = _decompressed(record)
            inner = breakup_chunk(replace(record, compression="", data=data), validate_crc=True)
        except (MemoryError, OverflowError) as error:
            raise McapError(f"a chunk's compressed data is corrupt ({type(error).__name__})") from None
        yield from inner


def _scan(path: str, keep_topics: set[str], keep_types: frozenset[str] = frozenset()) -> _Scan:
    """Read every record in file order, keeping the messages of `keep_topics` and of the channels whose message
    type (short name, `schemas.short_name`) is in `keep_types`, until the footer or a break."""
    scan = _Scan()
    kept_channels: set[int] = set()
    size = os.path.getsize(path)
    with open(path, "rb") as file:
        records = StreamReader(
            cast(IO[bytes], _ExactReads(file, size)),
            emit_chunks=True,
            validate_crcs=True,
            record_size_limit=max(size, 1),
        ).records
        try:
            first = next(records)
        except (StopIteration,) + BROKEN_FILE_ERRORS as error:
            raise LogError(
                f"{path} is not an MCAP file (it does not start with the MCAP magic and a header): "
                f"{type(error).__name__}: {error}"
            ) from None
        if not isinstance(first, Header):
            raise LogError(f"{path} is not an MCAP file: its first record is a {type(first).__name__}, not a Header")
        try:
            for record in _unchunked(records):
                if isinstance(record, Message):
                    channel = scan.channels.get(record.channel_id)
                    if channel is None:
                        scan.orphans += 1
                        continue
                    cid = record.channel_id
                    scan.counts[cid] = scan.counts.get(cid, 0) + 1
                    scan.first_ns[cid] = min(scan.first_ns.get(cid, record.log_time), record.log_time)
                    scan.last_ns[cid] = max(scan.last_ns.get(cid, record.log_time), record.log_time)
                    scan.last_read_ns = record.log_time
                    if cid in kept_channels:
                        scan.kept.setdefault(cid, []).append(record)
                elif isinstance(record, Schema):
                    scan.schemas[record.id] = record
                elif isinstance(record, Channel):
                    scan.channels[record.id] = record
                    if record.topic in keep_topics or (
                        keep_types and schemas.short_name(scan.type_of(record)) in keep_types
                    ):
                        kept_channels.add(record.id)
                    else:
                        kept_channels.discard(record.id)
                elif isinstance(record, Metadata) and record.name == ORIGIN_METADATA:
                    scan.origin_ns = _origin_from(record)
        except BROKEN_FILE_ERRORS as error:
            scan.stop_reason = f"{type(error).__name__}: {error}".rstrip(": ")
    return scan


def _record_at(file, offset: int, size: int):
    if not 0 <= offset < size:
        raise McapError(f"an index points at byte {offset}, outside the file ({size} bytes)")
    file.seek(offset)
    return next(StreamReader(cast(IO[bytes], _ExactReads(file, size)), skip_magic=True, record_size_limit=size).records)


def _topics_from_summary(path: str) -> list[dict] | None:
    """The topic table from the summary section and message indexes, or None when the file has none."""
    from mcap.reader import SeekingReader

    size = os.path.getsize(path)
    if size < 2 * len(MCAP0_MAGIC) + FOOTER_RECORD_BYTES:
        return None  # too short to hold a header and a footer: the scan says what it is
    with open(path, "rb") as file:
        try:
            summary = SeekingReader(cast(IO[bytes], _ExactReads(file, size)), record_size_limit=size).get_summary()
            if summary is None or summary.statistics is None:
                return None
            first: dict[int, int] = {}
            last: dict[int, int] = {}
            for chunk_index in summary.chunk_indexes:
                for channel_id, offset in chunk_index.message_index_offsets.items():
                    index = _record_at(file, offset, size)
                    if not isinstance(index, MessageIndex):
                        return None
                    for log_time, _ in index.records:
                        first[channel_id] = min(first.get(channel_id, log_time), log_time)
                        last[channel_id] = max(last.get(channel_id, log_time), log_time)
            origin = summary.statistics.message_start_time
            for metadata_index in summary.metadata_indexes:
                if metadata_index.name == ORIGIN_METADATA:
                    metadata = _record_at(file, metadata_index.offset, size)
                    found = _origin_from(metadata) if isinstance(metadata, Metadata) else None
                    if found is not None:
                        origin = found
        except BROKEN_FILE_ERRORS:
            return None
    counts = summary.statistics.channel_message_counts
    rows = []
    for channel_id, channel in summary.channels.items():
        count = counts.get(channel_id, 0)
        if count and channel_id not in first:  # messages outside chunks: the index cannot place them
            return None
        schema = summary.schemas.get(channel.schema_id)
        rows.append(
            _topic_row(
                channel.topic,
                schema.name if schema else "(no schema)",
                count,
                first.get(channel_id),
                last.get(channel_id),
                origin,
            )
        )
    return rows


def _topic_row(
    topic: str, type_name: str, count: int, first_ns: int | None, last_ns: int | None, origin_ns: int
) -> dict:
    def seconds(ns: int | None) -> float | None:
        return None if ns is None else (ns - origin_ns) / 1e9

    return {"topic": topic, "type": type_name, "count": count, "first_s": seconds(first_ns), "last_s": seconds(last_ns)}


def _mcap_path(path: str | os.PathLike) -> str:
    """`path` as a str; TypeError when it is not a name, LogError for a folder."""
    if not isinstance(path, (str, os.PathLike)) or not isinstance(os.fspath(path), str):
        raise TypeError(f"path = {path!r} must be a file name (str or os.PathLike)")
    path = os.fspath(path)
    if os.path.isdir(path):
        raise LogError(f"{path} is a folder, not an MCAP file")
    return path


def list_topics(path: str | os.PathLike) -> list[dict]:
    """The topics of an MCAP file: dicts of topic, type, count, first_s, last_s, sorted by topic.

    Times are log times in seconds from the log's origin (as `read_mcap` gives them); None for a topic
    without messages. Read from the summary section; a file without one (a truncated file, say) is
    scanned instead, and then the counts cover what could be read before the break.
    """
    path = _mcap_path(path)
    rows = _topics_from_summary(path)
    if rows is None:
        scan = _scan(path, set())
        origin = scan.origin_ns if scan.origin_ns is not None else (scan.start_ns or 0)
        rows = [
            _topic_row(
                channel.topic,
                scan.type_of(channel),
                scan.counts.get(cid, 0),
                scan.first_ns.get(cid),
                scan.last_ns.get(cid),
                origin,
            )
            for cid, channel in scan.channels.items()
        ]
    merged: dict[str, dict] = {}
    for row in rows:  # a topic recorded on two channels is one row
        seen = merged.get(row["topic"])
        if seen is None:
            merged[row["topic"]] = row
            continue
        seen["count"] += row["count"]
        for key, pick in (("first_s", min), ("last_s", max)):
            values = [v for v in (seen[key], row[key]) if v is not None]
            seen[key] = pick(values) if values else None
    return [merged[topic] for topic in sorted(merged)]


# ---------------------------------------------------------------------------------------------------------
# Reading: decode, convert, check order, assemble


class _Drop(Exception):
    """A message that cannot be used; the argument is the reason counted in the report.

    A message whose type the file defines differently from ROS (a field missing, or of another kind: a text
    where a number belongs) is dropped as well: the value functions below read fields by name and check
    what they find (`_finite`, `_sequence`), and `_accept` counts a missing field.
    """


@dataclass
class _Accepted:
    stamp_ns: int
    log_ns: int
    value: Any


def _finite(values: Iterable[Any]) -> list[float]:
    """The values as floats; _Drop for one that is not a number (as a field of another type gives) or not
    finite."""
    values = list(values)
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise _Drop(f"a field holds {type(v).__name__}, not a number")
    values = [float(v) for v in values]
    if not all(math.isfinite(v) for v in values):
        raise _Drop("non-finite value")
    return values


def _sequence(value: Any, what: str) -> list:
    """`value` when it is an array field (a list); _Drop otherwise."""
    if not isinstance(value, list):
        raise _Drop(f"{what} is {type(value).__name__}, not an array")
    return value


def _pose_value(pose: Any) -> list[float]:
    _finite(
        [
            pose.position.x,
            pose.position.y,
            pose.orientation.x,
            pose.orientation.y,
            pose.orientation.z,
            pose.orientation.w,
        ]
    )
    try:
        return ros_pose_to_pose(pose).tolist()
    except ValueError as error:  # a quaternion of zero length
        raise _Drop(f"unusable pose: {error}") from None


def _odometry_value(msg: Any) -> list[float]:
    return _pose_value(msg.pose.pose)


def _command_value(msg: Any) -> list[float]:
    twist = msg.twist if hasattr(msg, "twist") else msg
    return _finite([twist.linear.x, twist.linear.y, twist.angular.z])


def _imu_value(msg: Any) -> list[float]:
    gyro, accel = msg.angular_velocity, msg.linear_acceleration
    return _finite([gyro.x, gyro.y, gyro.z, accel.x, accel.y, accel.z])


def _truth_value(msg: Any) -> list[float]:
    return _pose_value(msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose)


def _joint_value(msg: Any) -> dict[str, float]:
    names = getattr(msg, "name", None)
    if names is None:  # a bitbots_msgs/JointCommand
        names, positions = msg.joint_names, msg.positions
    else:
        positions = msg.position
    names, positions = _sequence(names, "the joint names"), _sequence(positions, "the joint positions")
    if not all(isinstance(name, str) for name in names):
        raise _Drop("a joint name is not text")
    if len(names) != len(positions):
        raise _Drop(f"{len(names)} joint names but {len(positions)} positions")
    return dict(zip(names, _finite(positions)))


def _xy(point: Any) -> tuple[float, float]:
    point = getattr(point, "position", point)  # an older soccer_vision_3d_msgs gives a Pose
    return point.x, point.y


def _goalpost_value(msg: Any) -> tuple[list, list, list[str]]:
    points = [_xy(post.bb.center) for post in _sequence(msg.posts, "posts")]
    _finite(v for p in points for v in p)
    return [(LandmarkType.GOALPOST, x, y) for x, y in points], [], []


def _segment_points(start: tuple[float, float], end: tuple[float, float]) -> list[tuple[float, float]]:
    length = math.hypot(end[0] - start[0], end[1] - start[1])
    if length == 0.0:
        return [start]
    count = math.ceil(length / SEGMENT_SPACING)
    return [
        (start[0] + (end[0] - start[0]) * i / count, start[1] + (end[1] - start[1]) * i / count)
        for i in range(count + 1)
    ]


def _marking_value(msg: Any) -> tuple[list, list, list[str]]:
    landmarks, item_drops = [], []
    for intersection in _sequence(msg.intersections, "intersections"):
        rays = intersection.num_rays
        if isinstance(rays, bool) or not isinstance(rays, int):
            raise _Drop(f"num_rays holds {type(rays).__name__}, not an integer")
        kind = CROSSING_RAYS.get(rays)
        if kind is None:
            item_drops.append(f"intersection with {rays} rays")
            continue
        landmarks.append((kind, *_xy(intersection.center)))
    for ellipse in _sequence(msg.ellipses, "ellipses"):
        (diameter,) = _finite([ellipse.diameter])
        kind = LandmarkType.PENALTY_MARK if diameter < PENALTY_MARK_MAX_DIAMETER else LandmarkType.CENTER_MARK
        landmarks.append((kind, *_xy(ellipse.center)))
    line_points = []
    for segment in _sequence(msg.segments, "segments"):
        start, end = _xy(segment.start), _xy(segment.end)
        _finite(start + end)
        if math.hypot(end[0] - start[0], end[1] - start[1]) > MAX_SEGMENT_LENGTH:
            item_drops.append(f"segment longer than {MAX_SEGMENT_LENGTH:g} m")
            continue
        line_points.extend(_segment_points(start, end))
    _finite(v for item in landmarks for v in item[1:])
    return landmarks, line_points, item_drops


_VALUE_OF: dict[str, Callable[[Any], Any]] = {
    "odometry": _odometry_value,
    "commands": _command_value,
    "imu": _imu_value,
    "truth": _truth_value,
    "joint_states": _joint_value,
    "joint_commands": _joint_value,
    "goalposts": _goalpost_value,
    "markings": _marking_value,
}


def _accept(
    topic: str, stream: str, messages: list[tuple[Message, Any]], report: ReadReport, origin_ns: int
) -> list[_Accepted]:
    """Decode and convert a topic's messages (in log-time order); drop, counting why, those not usable.

    Stamps must increase in float64 seconds from `origin_ns` too (as `RobotLog` holds them): far from the
    origin, stamps a few nanoseconds apart are one time."""
    accepted: list[_Accepted] = []
    seen: set[bytes] = set()
    value_of = _VALUE_OF[stream]
    for message, decode in messages:
        try:
            decoded = decode(message.data)
        except _DECODE_ERRORS as error:
            report.drop(topic, f"cannot decode: {type(error).__name__}")
            continue
        try:
            header = getattr(decoded, "header", None)
            stamp = _stamp_ns(header) if header is not None else message.log_time
            value = value_of(decoded)
        except _Drop as drop:
            report.drop(topic, str(drop))
            continue
        except AttributeError as error:  # the file defines the message type without a field read here
            report.drop(topic, f"no field {error.name or error} in the message (its schema is not the ROS one)")
            continue
        fingerprint = hashlib.blake2b(
            stamp.to_bytes(16, "little", signed=True) + bytes(message.data), digest_size=16
        ).digest()
        if fingerprint in seen:
            report.drop(topic, "duplicate")
            continue
        seen.add(fingerprint)
        if accepted and stamp < accepted[-1].stamp_ns:
            report.drop(topic, "time went backwards")
            continue
        if accepted and (
            stamp == accepted[-1].stamp_ns or (stamp - origin_ns) / 1e9 == (accepted[-1].stamp_ns - origin_ns) / 1e9
        ):
            report.drop(topic, "same stamp as the previous message")
            continue
        if accepted and (stamp - accepted[-1].stamp_ns) / 1e9 > MAX_STEP_DT:
            report.drop(topic, _FAR_AHEAD)
            continue
        if stream in ("goalposts", "markings"):
            for reason in value[2]:
                report.drop(topic, reason)
        accepted.append(_Accepted(stamp, message.log_time, value))
    return accepted


def _seconds(ns: Iterable[int], origin_ns: int) -> np.ndarray:
    return np.array([(n - origin_ns) / 1e9 for n in ns], dtype=np.float64)


def _rows(accepted: list[_Accepted], columns: int) -> np.ndarray:
    return np.array([a.value for a in accepted], dtype=np.float64).reshape(len(accepted), columns)


def _joint_streams(
    topics: dict[str, str], accepted: dict[str, list[_Accepted]], report: ReadReport, origin_ns: int
) -> dict[str, Any]:
    readings = accepted.get("joint_states", [])
    commands = accepted.get("joint_commands", [])
    source = readings or commands
    if not source:
        return {}
    names = tuple(source[0].value)
    reading_rows, reading_ns = [], []
    for item in readings:
        absent = [name for name in names if name not in item.value]
        if absent:
            report.drop(topics["joint_states"], f"lacks joint {absent[0]}")
            continue
        reading_rows.append([item.value[name] for name in names])
        reading_ns.append(item.stamp_ns)
    command_rows, command_ns = [], []
    current = [math.nan] * len(names)
    for item in commands:
        row = [item.value.get(name, current[i]) for i, name in enumerate(names)]
        if reading_ns:
            # A joint not commanded yet holds where it stands: its latest reading.
            latest = bisect.bisect_right(reading_ns, item.stamp_ns) - 1
            if latest >= 0:
                row = [reading_rows[latest][i] if math.isnan(v) else v for i, v in enumerate(row)]
        if any(math.isnan(v) for v in row):
            report.drop(
                topics["joint_commands"],
                f"joint {names[[math.isnan(v) for v in row].index(True)]} has no command or reading yet",
            )
            continue
        current = row
        command_rows.append(row)
        command_ns.append(item.stamp_ns)
    n = len(names)
    return {
        "joint_names": names,
        "joint_reading_times": _seconds(reading_ns, origin_ns),
        "joint_readings": np.array(reading_rows, dtype=np.float64).reshape(len(reading_rows), n),
        "joint_command_times": _seconds(command_ns, origin_ns),
        "joint_commands": np.array(command_rows, dtype=np.float64).reshape(len(command_rows), n),
    }


def _vision_frames(
    topics: dict[str, str], accepted: dict[str, list[_Accepted]], report: ReadReport, origin_ns: int
) -> tuple[VisionFrame, ...]:
    """The camera frames of the accepted vision messages; a frame whose detections `Observations` refuses (a
    landmark too far, say) is left out, each of its messages counted as dropped with the reason."""
    frames: dict[int, dict[str, Any]] = {}
    for stream in ("goalposts", "markings"):  # goalposts first: a frame's order
        for item in accepted.get(stream, []):
            frame = frames.setdefault(
                item.stamp_ns, {"received": item.log_ns, "landmarks": [], "points": [], "topics": []}
            )
            frame["received"] = max(frame["received"], item.log_ns)
            landmarks, points, _ = item.value
            frame["landmarks"].extend(landmarks)
            frame["points"].extend(points)
            frame["topics"].append(topics[stream])
    out = []
    for stamp_ns, frame in sorted(frames.items(), key=lambda entry: (entry[1]["received"], entry[0])):
        landmarks = frame["landmarks"]
        try:
            observations = Observations.from_arrays(
                [int(kind) for kind, _, _ in landmarks],
                [math.hypot(x, y) for _, x, y in landmarks],
                [math.atan2(y, x) for _, x, y in landmarks],
                line_points=np.array(frame["points"], dtype=np.float64).reshape(-1, 2),
            )
        except ValueError as error:
            for topic in frame["topics"]:
                report.drop(topic, f"detections refused: {error}")
            continue
        out.append(VisionFrame((stamp_ns - origin_ns) / 1e9, (frame["received"] - origin_ns) / 1e9, observations))
    return tuple(out)


def _decoder_for(channel: Channel, schema: Schema | None, factory: DecoderFactory):
    """The channel's decoder, or the reason its messages cannot be decoded."""
    if schema is None:
        return None, "cannot decode: the channel has no schema"
    try:
        decoder = factory.decoder_for(channel.message_encoding, schema)
    except Exception as error:  # the vendored ROS parser raises many kinds for a bad definition
        return None, f"cannot decode: the schema {schema.name} does not parse ({type(error).__name__})"
    if decoder is None:
        return None, (
            f"cannot decode: encoding {channel.message_encoding!r} with a {schema.encoding!r} "
            f"schema (only cdr with ros2msg)"
        )
    return decoder, None


def read_mcap(path: str | os.PathLike, topics: Topics = Topics(), gap: float = 1.0) -> tuple[RobotLog, ReadReport]:
    """Read a ROS 2 MCAP log into a `RobotLog`, and a `ReadReport` of what was read, dropped and why.

    `topics` names the topic of each stream (see `Topics`); `gap` [s] is the longest silence on a topic
    that is not listed in `report.gaps`. See the module docstring for how each message is read.
    """
    if isinstance(gap, (bool, np.bool_)) or not isinstance(gap, (int, float, np.integer, np.floating)):
        raise TypeError(f"gap = {gap!r} must be a number of seconds")
    if not (math.isfinite(gap) and gap > 0):
        raise ValueError(f"gap = {gap!r} must be a positive number of seconds")
    if not isinstance(topics, Topics):
        raise TypeError(f"topics = {topics!r} must be a Topics")
    path = _mcap_path(path)
    wanted = topics.by_stream()
    scan = _scan(path, set(wanted.values()), _DISCOVERY_KEEP)
    report = ReadReport(path)
    report.stop_reason = scan.stop_reason
    if scan.orphans:
        report.drop("(no channel)", "message on a channel the file never defines", scan.orphans)
    origin_ns = scan.origin_ns if scan.origin_ns is not None else (scan.start_ns or 0)
    if scan.last_read_ns is not None and scan.stop_reason is not None:
        report.stopped_at = (scan.last_read_ns - origin_ns) / 1e9

    factory = DecoderFactory()
    accepted: dict[str, list[_Accepted]] = {}
    chosen = _choose_topics(path, scan, topics, report)
    for stream, topic in chosen.items():
        channels = [(cid, channel) for cid, channel in scan.channels.items() if channel.topic == topic]
        messages: list[tuple[Message, Any]] = []
        for cid, channel in channels:
            type_name = scan.type_of(channel)
            if schemas.short_name(type_name) not in ACCEPTED_TYPES[stream]:
                raise LogError(
                    f"{path}: topic {topic} carries {type_name}, but the {stream} stream expects "
                    f"{' or '.join(ACCEPTED_TYPES[stream])}"
                )
            report.types[topic] = type_name
            kept = scan.kept.get(cid, [])
            decoder, reason = _decoder_for(channel, scan.schemas.get(channel.schema_id), factory)
            if decoder is None:
                if kept:
                    report.drop(topic, reason, len(kept))
                continue
            messages.extend((message, decoder) for message in kept)
        messages.sort(key=lambda entry: entry[0].log_time)  # stable: file order among equal log times
        report.messages[topic] = sum(scan.counts.get(cid, 0) for cid, _ in channels)
        accepted[stream] = _accept(topic, stream, messages, report, origin_ns)
        stamps = _seconds([a.stamp_ns for a in accepted[stream]], origin_ns)
        for i in np.flatnonzero(np.diff(stamps) > gap):
            report.gaps.append((topic, float(stamps[i]), float(stamps[i + 1] - stamps[i])))

    def times(stream: str) -> np.ndarray:
        return _seconds([a.stamp_ns for a in accepted.get(stream, [])], origin_ns)

    imu = _rows(accepted.get("imu", []), 6)
    try:
        log = RobotLog(
            origin_ns=origin_ns,
            odometry_times=times("odometry"),
            odometry=_rows(accepted.get("odometry", []), 3),
            command_times=times("commands"),
            commands=_rows(accepted.get("commands", []), 3),
            imu_times=times("imu"),
            gyro=imu[:, :3],
            acceleration=imu[:, 3:],
            truth_times=times("truth"),
            truth=_rows(accepted.get("truth", []), 3),
            vision=_vision_frames(chosen, accepted, report, origin_ns),
            **_joint_streams(chosen, accepted, report, origin_ns),
        )
    except LogError as error:
        raise LogError(f"{path}: {error}") from None
    return log, report


_DISCOVERY_KEEP = frozenset(type_name for types in DISCOVERY_TYPES.values() for type_name in types)


def _choose_topics(path: str, scan: _Scan, topics: Topics, report: ReadReport) -> dict[str, str]:
    """stream -> the topic to read it from, in `Topics.STREAMS` order, each choice noted in `report.topics`: the
    topic named in `topics` when the log has it (a named topic that is not its default must be there), else the
    only topic of a type the stream is found by (`DISCOVERY_TYPES`) that no other stream reads. Several such
    topics raise `LogError` listing them; none lists the default topic in `report.missing`."""
    wanted, required = topics.by_stream(), topics.required
    present = set(scan.topics())
    chosen: dict[str, str] = {}
    for stream, topic in wanted.items():
        if topic in present:
            chosen[stream] = topic
            report.topics[stream] = (topic, "name" if stream in required else "default name")
        elif stream in required:
            where = " (before the file broke)" if scan.stop_reason else ""
            raise LogError(
                f"{path}: topic {topic} ({stream}) is not in the log{where}; the log has: "
                f"{', '.join(scan.topics()) or 'no topics'}"
            )
    taken = set(chosen.values())
    for stream, topic in wanted.items():
        if stream in chosen:
            continue
        types = DISCOVERY_TYPES.get(stream, ())
        candidates = sorted(
            {
                channel.topic
                for channel in scan.channels.values()
                if channel.topic not in taken and schemas.short_name(scan.type_of(channel)) in types
            }
        )
        if len(candidates) > 1:
            option = f"--topic-{stream.replace('_', '-')}"
            raise LogError(
                f"{path}: topic {topic} ({stream}) is not in the log, and {len(candidates)} topics carry "
                f"{' or '.join(types)}: {', '.join(candidates)}; choose one with {option} TOPIC "
                f"(Topics.{stream} in Python), or {option} '' to read none"
            )
        if candidates:
            chosen[stream] = candidates[0]
            taken.add(candidates[0])
            report.topics[stream] = (candidates[0], "type")
        else:
            report.missing.append(topic)
    return {stream: chosen[stream] for stream in Topics.STREAMS if stream in chosen}


# ---------------------------------------------------------------------------------------------------------
# Writing


def _ray(heading: float) -> dict[str, float]:
    return {"x": math.cos(heading), "y": math.sin(heading), "z": 0.0}


def _vision_messages(observations: Observations, header: dict) -> tuple[dict, dict]:
    posts, intersections, ellipses = [], [], []
    rays_of = {kind: rays for rays, kind in CROSSING_RAYS.items()}
    for kind, r, b in zip(observations.kinds, observations.ranges, observations.bearings):
        x, y = float(r * math.cos(b)), float(r * math.sin(b))
        kind = LandmarkType(int(kind))
        if kind == LandmarkType.GOALPOST:
            posts.append(
                {"bb": {"center": {"position": {"x": x, "y": y, "z": 0.0}}, "size": {"x": 0.1, "y": 0.1, "z": 0.8}}}
            )
        elif kind in rays_of:
            rays = rays_of[kind]
            intersections.append(
                {
                    "center": {"x": x, "y": y, "z": 0.0},
                    "num_rays": rays,
                    "rays": [_ray(i * math.pi / 2) for i in range(rays)],
                }
            )
        else:
            diameter = PENALTY_MARK_DIAMETER if kind == LandmarkType.PENALTY_MARK else CENTER_CIRCLE_DIAMETER
            ellipses.append({"diameter": diameter, "center": {"position": {"x": x, "y": y, "z": 0.0}}})
    segments = [
        {"start": {"x": float(x), "y": float(y), "z": 0.0}, "end": {"x": float(x), "y": float(y), "z": 0.0}}
        for x, y in observations.line_points
    ]
    return (
        {"header": header, "posts": posts},
        {"header": header, "ellipses": ellipses, "intersections": intersections, "segments": segments},
    )


def write_mcap(log: RobotLog, path: str | os.PathLike, topics: Topics = Topics(), *, chunk_size: int = 1 << 20) -> None:
    """Write every non-empty stream of `log` to a ROS 2 MCAP file (see the module docstring for how).

    `chunk_size` [bytes] is how much the MCAP writer gathers before compressing a chunk: a file cut short
    loses at most its last chunk.
    """
    if not isinstance(log, RobotLog):
        raise ValueError(f"log = {log!r} must be a RobotLog")
    if not isinstance(topics, Topics):
        raise ValueError(f"topics = {topics!r} must be a Topics")
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size <= 0:
        raise ValueError(f"chunk_size = {chunk_size!r} must be a positive number of bytes")

    def ns(seconds: float) -> int:
        return log.origin_ns + int(round(float(seconds) * 1e9))

    pending: list[tuple[int, str, str, dict]] = []  # (log time, topic, type, message)

    def add(stream: str, type_name: str, times: np.ndarray, messages: Iterable[dict]) -> None:
        topic = getattr(topics, stream)
        if not topic:
            return
        for t, message in zip(times, messages):
            pending.append((ns(t), topic, type_name, message))

    def stamped(times: np.ndarray, frame_id: str) -> list[dict]:
        return [_header(ns(t), frame_id) for t in times]

    add(
        "odometry",
        schemas.ODOMETRY,
        log.odometry_times,
        (
            {"header": h, "child_frame_id": "base_footprint", "pose": {"pose": pose_to_ros_pose(p)}}
            for h, p in zip(stamped(log.odometry_times, "odom"), log.odometry)
        ),
    )
    add(
        "commands",
        schemas.TWIST,
        log.command_times,
        (
            {"linear": {"x": float(vx), "y": float(vy), "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": float(w)}}
            for vx, vy, w in log.commands
        ),
    )
    # An orientation covariance of -1 is sensor_msgs/Imu's "no orientation estimate".
    add(
        "imu",
        schemas.IMU,
        log.imu_times,
        (
            {
                "header": h,
                "orientation_covariance": [-1.0] + [0.0] * 8,
                "angular_velocity": dict(zip("xyz", map(float, g))),
                "linear_acceleration": dict(zip("xyz", map(float, a))),
            }
            for h, g, a in zip(stamped(log.imu_times, "imu_frame"), log.gyro, log.acceleration)
        ),
    )
    names = list(log.joint_names)
    for stream, times, values in (
        ("joint_states", log.joint_reading_times, log.joint_readings),
        ("joint_commands", log.joint_command_times, log.joint_commands),
    ):
        add(
            stream,
            schemas.JOINT_STATE,
            times,
            (
                {"header": h, "name": names, "position": [float(v) for v in row]}
                for h, row in zip(stamped(times, ""), values)
            ),
        )
    add(
        "truth",
        schemas.POSE_STAMPED,
        log.truth_times,
        ({"header": h, "pose": pose_to_ros_pose(p)} for h, p in zip(stamped(log.truth_times, "map"), log.truth)),
    )
    for frame in log.vision:
        goalposts, markings = _vision_messages(frame.observations, _header(ns(frame.stamp), VISION_FRAME_ID))
        for stream, type_name, message in (
            ("goalposts", schemas.GOALPOST_ARRAY, goalposts),
            ("markings", schemas.MARKING_ARRAY, markings),
        ):
            if getattr(topics, stream):
                pending.append((ns(frame.received), getattr(topics, stream), type_name, message))

    if pending and min(entry[0] for entry in pending) < 0:
        raise ValueError(
            f"log.origin_ns = {log.origin_ns}: some times fall before 1970 (MCAP log times are "
            f"unsigned nanoseconds since the epoch)"
        )
    pending.sort(key=lambda entry: entry[0])
    with open(os.fspath(path), "wb") as file:
        writer = Ros2Writer(file, chunk_size=chunk_size)
        writer.add_metadata(ORIGIN_METADATA, {"origin_ns": str(int(log.origin_ns))})
        registered: dict[str, Schema] = {}
        for log_ns, topic, type_name, message in pending:
            if type_name not in registered:
                registered[type_name] = writer.register_msgdef(type_name, schemas.definition(type_name))
            writer.write_message(topic, registered[type_name], message, log_time=log_ns, publish_time=log_ns)
        writer.finish()


class PoseWriter:
    """Writes the filter's poses as geometry_msgs/PoseWithCovarianceStamped to an MCAP file.

        with PoseWriter("poses.mcap", origin_ns=log.origin_ns) as poses:
            poses.write(t, pose, covariance)

    `write(stamp, pose, covariance)`: `stamp` is an int of nanoseconds since the epoch, or a float of
    seconds from `origin_ns`; `pose` (3,) [x, y, θ] in `frame_id`; `covariance` (3, 3) over (x, y, θ).
    The message is `mcl.tools.formats.pose_to_ros`'s: the ROS 6x6 row-major covariance over (x, y, z, roll,
    pitch, yaw) holds the 3x3 in the x, y and yaw rows and columns, and `unestimated_variance` (default
    1e6, ROS's "unknown"; 0.0 for nav2_amcl's zeros) on the z, roll and pitch diagonal. The log time of
    each message is its stamp. Close it (or leave the `with`) to finish the file.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        topic: str = Topics.pose_out,
        frame_id: str = "map",
        origin_ns: int = 0,
        unestimated_variance: float = UNESTIMATED_VARIANCE,
    ) -> None:
        if not isinstance(topic, str) or not topic.startswith("/"):
            raise ValueError(f"topic = {topic!r} must be a topic name starting with '/'")
        if isinstance(origin_ns, bool) or not isinstance(origin_ns, (int, np.integer)):
            raise ValueError(f"origin_ns = {origin_ns!r} must be an integer of nanoseconds")
        if not isinstance(frame_id, str):
            raise ValueError(f"frame_id = {frame_id!r} must be a string")
        covariance3_to_ros6(np.zeros((3, 3)), unestimated_variance)  # rejects a bad value here, not later
        self.path, self.topic, self.frame_id = os.fspath(path), topic, frame_id
        self.origin_ns, self.unestimated_variance = int(origin_ns), float(unestimated_variance)
        self._file = open(self.path, "wb")
        self._writer = Ros2Writer(self._file)
        self._schema = self._writer.register_msgdef(
            schemas.POSE_WITH_COVARIANCE_STAMPED, schemas.definition(schemas.POSE_WITH_COVARIANCE_STAMPED)
        )
        self.count = 0

    def write(self, stamp: int | float, pose, covariance) -> None:
        """Write one pose (see the class docstring for the arguments)."""
        if self._file.closed:
            raise ValueError(f"PoseWriter({self.path!r}) is closed")
        if isinstance(stamp, (bool, np.bool_)) or not isinstance(stamp, (int, float, np.integer, np.floating)):
            raise ValueError(f"stamp = {stamp!r} must be int nanoseconds or float seconds")
        if isinstance(stamp, (float, np.floating)):
            if not math.isfinite(stamp):
                raise ValueError(f"stamp = {stamp!r} must be finite")
            stamp_ns = self.origin_ns + int(round(float(stamp) * 1e9))
        else:
            stamp_ns = int(stamp)
        if stamp_ns < 0:
            raise ValueError(f"stamp = {stamp!r} falls before 1970 (MCAP log times are unsigned)")
        message = pose_to_ros(pose, covariance, stamp_ns, self.frame_id, self.unestimated_variance)
        self._writer.write_message(self.topic, self._schema, message, log_time=stamp_ns, publish_time=stamp_ns)
        self.count += 1

    def close(self) -> None:
        """Finish the file (its summary and footer); closing twice is harmless."""
        if not self._file.closed:
            self._writer.finish()
            self._file.close()

    def __enter__(self) -> PoseWriter:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def read_poses(path: str | os.PathLike, topic: str = Topics.pose_out) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The poses on a PoseWithCovarianceStamped topic, such as `PoseWriter` writes, in log-time order.

    Returns stamps (K,) int64 nanoseconds since the epoch, poses (K, 3) [x, y, θ] and covariances (K, 3, 3).
    Raises `LogError` when the topic is not in the file or is of another type. A message that cannot be
    decoded or converted (a non-finite value, an asymmetric covariance) is left out: use `read_mcap`, with
    the topic as its truth, for a report of what was dropped.
    """
    path = _mcap_path(path)
    scan = _scan(path, {topic})
    channels = [(cid, channel) for cid, channel in scan.channels.items() if channel.topic == topic]
    if not channels:
        raise LogError(
            f"{path}: topic {topic} is not in the log; the log has: {', '.join(scan.topics()) or 'no topics'}"
        )
    factory = DecoderFactory()
    rows: list[tuple[int, int, np.ndarray, np.ndarray]] = []
    for cid, channel in channels:
        type_name = scan.type_of(channel)
        if schemas.short_name(type_name) != schemas.short_name(schemas.POSE_WITH_COVARIANCE_STAMPED):
            raise LogError(
                f"{path}: topic {topic} carries {type_name}, expected {schemas.POSE_WITH_COVARIANCE_STAMPED}"
            )
        decoder, _ = _decoder_for(channel, scan.schemas.get(channel.schema_id), factory)
        for message in scan.kept.get(cid, []) if decoder is not None else []:
            try:
                stamp_ns, pose, covariance = ros_to_pose(decoder(message.data))
            except _DECODE_ERRORS:
                continue
            rows.append((message.log_time, stamp_ns, pose, covariance))
    rows.sort(key=lambda row: row[0])
    return (
        np.array([row[1] for row in rows], dtype=np.int64),
        np.array([row[2] for row in rows], dtype=np.float64).reshape(-1, 3),
        np.array([row[3] for row in rows], dtype=np.float64).reshape(-1, 3, 3),
    )
