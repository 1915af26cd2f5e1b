"""`robocup-mcl node bench LOG`: the node in its own process, a log played to it over DDS, its answers timed.

    robocup-mcl node bench game.mcap --field kidsize --json --save results/ros_bench.json
    robocup-mcl node bench game.mcap --repeat 60 --save results/ros_soak.json      # an hour from a minute

DDS stays on this machine: the bench runs only in a network namespace whose one interface is the loopback
(started as root, it re-runs itself under `unshare --net` with `lo` up; elsewhere it refuses), with
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, ROS_LOCALHOST_ONLY=1 and a private ROS_DOMAIN_ID as well.

It starts `robocup-mcl node` (its kernels warmed up first), plays the log with `mcl.tools.ros.player.LogPlayer` once
the node's subscriptions are matched, and records the poses with `PoseListener`. Figures:
- latency: from the player publishing an odometry message to the listener receiving the pose with its stamp
  (one process, one clock: `time.perf_counter`), median, p90, p99 and max [ms];
- drops: odometry messages sent that no pose answered (the first odometry message of a run only starts it);
- CPU: the node's CPU seconds over its wall seconds (`--stats`), and its callbacks' durations;
- soak: the poses and /tf transforms holding a NaN or an infinity (none are recorded as poses), the node's
  resident memory (VmRSS of /proc/PID/status) sampled every `--rss-interval` seconds while the log plays, and
  its growth from the first to the last ten minutes (a sixth of the run each, when the run is shorter than an
  hour), and the node's shutdown: the signal sent (`--stop-signal`), whether the node exited by itself with
  status 0 (within 15 s) and its statistics file was written, and how long that took;
- `--rrd PATH`: the node records the run to a Rerun file, and times that part of each odometry callback
  apart (`NodeCore.recording_seconds`): the callback's median and p99 with the recording and without its part,
  in the same run and under the same load, and their ratios; the file is read back (size, rows). That the
  recording changes no estimate shows in the comparison with the replay;
- `--trace-order`: the order the node took the messages in against the order they were published in
  (`order_analysis`), and a core fed the node's order;
- `--team-rate HZ` (and `--team-bad-every N`): a teammate's broadcasts played beside the log
  (`LogPlayer.add_team_messages`): how many were sent, received and given to the localizer;
- `--published PATH`: what the listener heard (the field's markers, every pose, particle messages) as JSON, for
  `robocup-mcl node figure`;
- the replay: the node's poses against `robocup-mcl replay`'s for the same log, settings and seed, by stamp
  (first lap): the share that are equal bit for bit and the largest distance. The node applies a camera frame
  with the odometry message after its arrival, as the replay does; a frame that DDS delivers after the
  odometry message published just after it is applied one step later than in the replay.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import argparse

PROG = "robocup-mcl node bench"
ISOLATED_VARIABLE = "ROBOCUP_MCL_NETNS"
READY_TIMEOUT = 300.0  # s: the node's start, kernels compiled on a first run included


def loopback_only() -> bool:
    """Whether this process's network namespace has no interface but the loopback."""
    try:  # /proc/net/dev lists the reading process's namespace (sysfs may show the host's)
        lines = Path("/proc/net/dev").read_text().splitlines()[2:]
    except OSError:
        return False
    return {line.split(":")[0].strip() for line in lines} <= {"lo"}


def namespace_command(argv: list[str]) -> list[str] | None:
    """`argv` wrapped to run in a new network namespace with only `lo` up, or None when this machine cannot make
    one (not root, no unshare or ip, or unshare refused)."""
    unshare, ip = shutil.which("unshare"), shutil.which("ip")
    if unshare is None or ip is None or os.geteuid() != 0:
        return None
    probe = subprocess.run([unshare, "--net", ip, "link", "set", "lo", "up"], capture_output=True, timeout=20)
    if probe.returncode != 0:
        return None
    return [unshare, "--net", "sh", "-c", f'{ip} link set lo up && exec "$@"', "sh", *argv]


def rerun_isolated(module: str, argv: list[str], opens: str) -> int | None:
    """None when this process's namespace has only the loopback; else run `python -m module argv` inside a new
    loopback-only namespace and return its exit status. A CommandError when the namespace has other interfaces
    although it was made for this (`ISOLATED_VARIABLE`), or when no namespace can be made: `opens` names what
    is then not started ("DDS", "the viewer and the browser")."""
    from mcl.tools.cli_checks import CommandError

    if loopback_only():
        return None
    if os.environ.get(ISOLATED_VARIABLE):
        raise CommandError(f"the namespace has interfaces besides the loopback; refusing to start {opens}")
    wrapped = namespace_command([sys.executable, "-m", module, *argv])
    if wrapped is None:
        raise CommandError(
            "cannot make a loopback-only network namespace here (needs root, unshare and ip); "
            f"not starting {opens} on the machine's network"
        )
    return subprocess.run(wrapped, env={**os.environ, ISOLATED_VARIABLE: "1"}).returncode


def dds_environment(domain: int) -> dict[str, str]:
    """The environment for DDS on the loopback only: discovery range, localhost-only and a private domain."""
    return {
        **os.environ,
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "ROS_LOCALHOST_ONLY": "1",
        "ROS_DOMAIN_ID": str(domain),
        "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
    }


def _percentiles(values: list[float]) -> dict[str, float | None]:
    import numpy as np

    if not values:
        return {"median": None, "p90": None, "p99": None, "max": None}
    array = np.asarray(values) * 1e3
    return {
        "median": float(np.median(array)),
        "p90": float(np.percentile(array, 90)),
        "p99": float(np.percentile(array, 99)),
        "max": float(array.max()),
    }


def rss_bytes(pid: int) -> int | None:
    """The resident memory of process `pid` [bytes] (VmRSS in /proc/PID/status), or None when it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


class RssSampler:
    """Samples a process's resident memory every `interval` seconds in a daemon thread: `samples` holds
    (seconds since `start`, bytes)."""

    def __init__(self, pid: int, interval: float) -> None:
        import threading

        self.pid, self.interval = pid, interval
        self.samples: list[tuple[float, int]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._started = 0.0

    def start(self) -> None:
        self._started = time.monotonic()
        self._thread.start()

    def _run(self) -> None:
        while True:
            value = rss_bytes(self.pid)
            if value is not None:
                self.samples.append((time.monotonic() - self._started, value))
            if self._stop.wait(self.interval):
                return

    def stop(self) -> None:
        """Take a last sample and stop."""
        self._stop.set()
        self._thread.join(timeout=5)
        value = rss_bytes(self.pid)
        if value is not None:
            self.samples.append((time.monotonic() - self._started, value))


def rss_summary(samples: list[tuple[float, int]], window: float = 600.0) -> dict:
    """Memory over a run from `RssSampler.samples`: the mean of the first and of the last `window` seconds
    (a sixth of the run each when it is shorter than six windows) [MB], the growth between them [MB and %],
    the least and the most, and a least-squares slope [MB per hour]."""
    import numpy as np

    if not samples:
        return {"samples": 0}
    times = np.array([t for t, _ in samples])
    mb = np.array([b for _, b in samples]) / 1e6
    duration = float(times[-1] - times[0])
    width = min(window, duration / 6) if duration > 0 else 0.0
    first = mb[times <= times[0] + width]
    last = mb[times >= times[-1] - width]
    slope = float(np.polyfit(times, mb, 1)[0] * 3600) if len(samples) > 2 and duration > 0 else None
    return {
        "samples": len(samples),
        "seconds": duration,
        "window_s": width,
        "first_window_mb": float(first.mean()),
        "last_window_mb": float(last.mean()),
        "growth_mb": float(last.mean() - first.mean()),
        "growth_percent": float(100 * (last.mean() - first.mean()) / first.mean()),
        "min_mb": float(mb.min()),
        "max_mb": float(mb.max()),
        "slope_mb_per_hour": slope,
        "series": [[round(float(t), 1), round(float(m), 2)] for t, m in zip(times, mb)],
    }


def stop_node(node: subprocess.Popen, signal_name: str, stats_path: Path) -> dict:
    """Send `signal_name` (SIGINT or SIGTERM) to the node and wait 15 s for it to exit by itself; then
    SIGTERM (5 s more) and SIGKILL. Returns what happened."""
    sent = time.monotonic()
    node.send_signal(getattr(signal, signal_name))
    escalated = None
    try:
        node.wait(timeout=15)
    except subprocess.TimeoutExpired:
        escalated = "SIGTERM"
        node.terminate()
        try:
            node.wait(timeout=5)
        except subprocess.TimeoutExpired:
            escalated = "SIGKILL"
            node.kill()
            node.wait()
    return {
        "signal": signal_name,
        "exit_status": node.returncode,
        "seconds": time.monotonic() - sent,
        "escalated_to": escalated,
        "stats_written": stats_path.exists(),
        "completed": escalated is None and node.returncode == 0 and stats_path.exists(),
    }


def compare_with_replay(
    log_path: str, settings: Any, poses: dict[int, tuple[float, float, float]], seconds: float | None
) -> dict:
    """The node's poses (by stamp) against `mcl.tools.replay.replay` of the same log and settings: how many stamps both
    have, the share equal bit for bit, the largest distance [m]."""
    import numpy as np

    from mcl.tools.logs import read_log
    from mcl.tools.replay import replay

    log, _ = read_log(log_path)
    result = replay(
        log,
        settings.localizer().field,
        model=settings.model,
        particles=settings.particles,
        seed=settings.seed,
        history=settings.history,
        compensate_latency=settings.compensate_latency,
        start=settings.start,
        localizer=settings.localizer() if settings.profile else None,
    )
    stamps = [log.origin_ns + round(t * 1e9) for t in result.times]
    same, distances, first, at = 0, [], None, []
    for t, stamp, estimate in zip(result.times, stamps, result.estimates):
        pose = poses.get(stamp)
        if pose is None:
            continue
        # x and y travel as they are; the heading through a quaternion (its last bits may change)
        equal = (float(estimate[0]), float(estimate[1])) == pose[:2] and abs(
            math.remainder(float(estimate[2]) - pose[2], math.tau)
        ) < 1e-9
        same += int(equal)
        if not equal and first is None:
            first = float(t)
        distances.append(float(np.hypot(estimate[0] - pose[0], estimate[1] - pose[1])))
        at.append(float(t))
    return {
        "compared": len(distances),
        "equal_share": same / len(distances) if distances else None,
        "first_difference_s": first,
        "max_distance_m": max(distances) if distances else None,
        "max_distance_at_s": at[int(np.argmax(distances))] if distances else None,
        "median_distance_m": float(np.median(distances)) if distances else None,
    }


def run(args: argparse.Namespace, node_argv: list[str]) -> dict:
    """Start the node, play the log, collect the figures (see the module docstring)."""
    import rclpy
    from rclpy.context import Context

    from mcl.tools.ros.player import LogPlayer, PoseListener

    env = dds_environment(args.domain)
    os.environ.update(
        {
            k: env[k]
            for k in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY", "ROS_DOMAIN_ID", "RMW_IMPLEMENTATION")
        }
    )
    stats_path = Path(tempfile.mkdtemp(prefix="robocup-mcl-node-")) / "stats.json"
    # the node's stderr goes to a file: a pipe nobody reads during a long run would fill and block it
    stderr_path = stats_path.with_name("stderr.txt")
    trace_path = stats_path.with_name("taken.json")
    if args.trace_order:
        node_argv = [*node_argv, "--trace-order", str(trace_path)]
    with open(stderr_path, "w", encoding="utf-8") as stderr_file:
        node = subprocess.Popen(
            [sys.executable, "-m", "mcl.tools.ros.node", *node_argv, "--stats", str(stats_path)],
            env=env,
            stderr=stderr_file,
            text=True,
        )
    sampler = RssSampler(node.pid, args.rss_interval)
    shutdown: dict = {}
    context = Context()
    rclpy.init(context=context)
    player = listener = None
    try:
        player = LogPlayer(args.log, context=context, seconds=args.seconds)
        team = player.add_team_messages(args.team_rate, bad_every=args.team_bad_every) if args.team_rate else (0, 0)
        published_order, by_key = [], {}  # the first lap's order, and its messages by (topic, stamp)
        for _, topic, message in player.messages:
            if hasattr(message, "header"):
                key = (topic, message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec)
                published_order.append(key)
                by_key[key] = message
        listener = PoseListener(context=context)
        listener.spin_in_thread(context)
        deadline = time.monotonic() + READY_TIMEOUT
        topics = [
            t for t in player.publishers if t in ("/motion_odometry", "/goal_posts_relative", "/markings_relative")
        ]
        while time.monotonic() < deadline and node.poll() is None:
            if player.wait_for_subscribers(topics, 0.2) and listener.pose_sub.get_publisher_count() > 0:
                break
        if node.poll() is not None:
            raise RuntimeError(f"the node stopped before the log was played: {stderr_path.read_text()[-2000:]}")
        time.sleep(0.5)  # the node's subscriptions matched: let the discovery settle
        sampler.start()
        started = time.perf_counter()
        sent = player.play(args.rate, args.repeat)
        played = time.perf_counter() - started
        time.sleep(1.0)  # the last answers
        sampler.stop()
    finally:
        shutdown = stop_node(node, args.stop_signal, stats_path)
        if listener is not None:
            listener.close()
        if player is not None:
            player.close()
        if rclpy.ok(context=context):
            rclpy.shutdown(context=context)
    stats = json.loads(stats_path.read_text()) if stats_path.exists() else {}
    answered = {stamp: (arrived, pose) for stamp, arrived, pose in listener.poses}
    latencies = [answered[stamp][0] - at for stamp, at in sent.items() if stamp in answered]
    expected = len(sent) - 1
    from mcl.tools.ros.parameters import NodeSettings

    settings = NodeSettings.from_dict(
        {k: v for k, v in vars(args).items() if k in NodeSettings.__dataclass_fields__ and v is not None}
    )
    order = None
    if args.trace_order:
        taken = [(topic, stamp) for topic, stamp in json.loads(trace_path.read_text())] if trace_path.exists() else []
        order = order_analysis(published_order, taken, by_key, settings, {s: p for s, (_, p) in answered.items()})
    return {
        "order": order,
        "log": args.log,
        "rate": args.rate,
        "repeat": args.repeat,
        "log_seconds_played": played * args.rate,
        "wall_seconds_played": played,
        "particles": settings.particles,
        "field": settings.field,
        "odometry_sent": len(sent),
        "poses_received": len(answered),
        "poses_expected": expected,
        "poses_dropped": max(expected - len([s for s in sent if s in answered]), 0),
        "latency_ms": _percentiles(latencies),
        "tf_messages": len(listener.transforms),
        "tf_frames": sorted({f"{parent}->{child}" for _, parent, child in listener.transforms}),
        "quality_changes": listener.qualities,
        "skipped_topics": player.skipped,
        "particle_messages": len(listener.particle_counts),
        "particles_per_message": sorted(set(listener.particle_counts)),
        "field_markers": {
            ns: sum(1 for n, _, _ in listener.field_markers if n == ns)
            for ns in sorted({n for n, _, _ in listener.field_markers})
        },
        "team_messages_sent": team[0] * args.repeat,
        "team_messages_bad_sent": team[1] * args.repeat,
        "nonfinite_poses": listener.nonfinite_poses,
        "nonfinite_transforms": listener.nonfinite_transforms,
        "rss": rss_summary(sampler.samples),
        "shutdown": shutdown,
        "node": stats,
        "replay": compare_with_replay(args.log, settings, {s: p for s, (_, p) in answered.items()}, args.seconds),
        "_published": listener.published(),
    }


def order_analysis(
    published: list[tuple[str, int]],
    taken: list[tuple[str, int | None]],
    messages: dict[tuple[str, int], Any],
    settings: Any,
    node_poses: dict[int, tuple[float, float, float]],
    odometry_topic: str = "/motion_odometry",
) -> dict:
    """How the order the node took the messages in differs from the order they were published in, and whether
    that order explains the node's poses.

    For each camera message: the odometry messages published before it and those the node took before it.
    Fewer taken than published: the node took the frame before an odometry message published earlier ("early":
    without send times the frame then corrects the filter one step before the replay does); more: after one
    published later ("late"). Then a `NodeCore` without send times is fed the messages in the node's order, in
    this process: its poses against the node's (the same bit for bit when the order is all that differs)."""
    from mcl.tools.ros.core import NodeCore

    cameras = (settings.goalposts_topic, settings.markings_topic)

    def odometry_before(order: list) -> dict[tuple[str, int], int]:
        count, out = 0, {}
        for topic, stamp in order:
            if topic == odometry_topic:
                count += 1
            elif topic in cameras and stamp is not None:
                out[(topic, stamp)] = count
        return out

    sent, took = odometry_before(published), odometry_before(taken)
    first = min(stamp for _, stamp in published)
    early = [key for key in sent if key in took and took[key] < sent[key]]
    late = [key for key in sent if key in took and took[key] > sent[key]]

    def feed(order: list) -> tuple[dict[int, tuple[float, float, float]], dict[int, int]]:
        """A core without send times fed `order`: its poses by stamp, and the step each frame corrected at."""
        core = NodeCore(settings)
        core.applied = []
        poses: dict[int, tuple[float, float, float]] = {}
        for topic, stamp in order:
            message = messages.get((topic, stamp)) if stamp is not None else None
            if message is None:
                continue
            if topic == odometry_topic:
                out = core.odometry(message)
                if out is not None:
                    poses[out.stamp_ns] = (float(out.pose[0]), float(out.pose[1]), float(out.pose[2]))
            elif topic == settings.goalposts_topic:
                core.goalposts(message)
            elif topic == settings.markings_topic:
                core.markings(message)
        return poses, dict(core.applied)

    poses, applied = feed(taken)
    _, applied_in_order = feed(published)  # the publisher's order: the replay's steps
    moved = sorted(
        (capture, applied[capture] - step) for capture, step in applied_in_order.items() if applied.get(capture) != step
    )
    missing = [capture for capture in applied_in_order if capture not in applied]
    both = [stamp for stamp in node_poses if stamp in poses]
    same = sum(
        1
        for stamp in both
        if node_poses[stamp][:2] == poses[stamp][:2]
        and abs(math.remainder(node_poses[stamp][2] - poses[stamp][2], math.tau)) < 1e-9
    )
    return {
        "camera_messages": len(sent),
        "taken_early": len(early),
        "taken_late": len(late),
        "first_early_s": (min(stamp for _, stamp in early) - first) / 1e9 if early else None,
        "first_late_s": (min(stamp for _, stamp in late) - first) / 1e9 if late else None,
        "frames_applied": len(applied_in_order),
        "frames_applied_at_another_step": len(moved),
        "frames_applied_earlier": sum(1 for _, shift in moved if shift < 0),
        "frames_not_applied": len(missing),
        "first_frame_at_another_step_s": (moved[0][0] - first) / 1e9 if moved else None,
        "core_in_node_order_compared": len(both),
        "core_in_node_order_equal_share": same / len(both) if both else None,
    }


def read_back(path: str) -> dict:
    """What a node's .rrd holds: its size [bytes], its recording ids, and the rows of the estimate and of the
    particles (an error's text when it does not read)."""
    out: dict[str, Any] = {"path": path, "bytes": os.path.getsize(path) if os.path.exists(path) else None}
    try:
        import rerun.chunk as rrc

        reader = rrc.RrdReader(path)
        rows: dict[str, int] = {}
        for chunk in reader.stream():
            if not chunk.is_static and chunk.entity_path in ("/robot/estimate", "/particles"):
                rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.to_record_batch().num_rows
        out["recordings"] = len(reader.recordings())
        out["estimate_rows"] = rows.get("/robot/estimate", 0)
        out["particle_rows"] = rows.get("/particles", 0)
    except Exception as error:  # noqa: BLE001 - reported, not raised: the figures of the runs still count
        out["error"] = f"{type(error).__name__}: {error}"
    return out


def recording_overhead(result: dict, path: str) -> dict:
    """The recording's cost on the odometry callback, from the node's statistics of a run with `--rrd`, and the
    file read back."""
    return {**result["node"].get("recording", {}), "file": read_back(path)}


def summary(result: dict) -> None:
    """Print the figures for a reader."""
    latency, node = result["latency_ms"], result["node"]
    print(
        f"{result['log']}: {result['log_seconds_played']:.1f} s of log at {result['rate']:g}x, "
        f"{result['particles']} particles"
    )
    print(
        f"poses: {result['poses_received']} of {result['poses_expected']} expected, {result['poses_dropped']} dropped"
    )
    if latency["median"] is not None:
        print(
            f"latency odometry -> pose: median {latency['median']:.2f} ms, p90 {latency['p90']:.2f} ms, "
            f"p99 {latency['p99']:.2f} ms, max {latency['max']:.2f} ms"
        )
    if node.get("ordering"):
        print(f"the node ordered camera frames against odometry by {node['ordering']}")
    if node.get("cpu_share") is not None:
        print(
            f"node CPU: {100 * node['cpu_share']:.1f} % of one core ({node['cpu_seconds']:.1f} s over "
            f"{node['wall_seconds']:.1f} s)"
        )
    odometry = node.get("callbacks", {}).get("/motion_odometry")
    if odometry:
        print(
            f"the node's odometry callback (motion, frames, publishing): median {odometry['median_ms']:.2f} ms, "
            f"p99 {odometry['p99_ms']:.2f} ms, max {odometry['max_ms']:.2f} ms"
        )
    if result.get("particle_messages") is not None:
        print(
            f"particles: {result['particle_messages']} messages of {result['particles_per_message']} poses; "
            f"field markers: {result['field_markers']}"
        )
    replay = result["replay"]
    if replay["compared"]:
        first = replay.get("first_difference_s")
        print(
            f"against the replay: {replay['compared']} poses, {100 * replay['equal_share']:.1f} % equal bit for bit"
            + (
                f" (first difference at {first:.2f} s), median distance {replay['median_distance_m']:.4f} m,"
                if first is not None
                else ","
            )
            + f" largest distance {replay['max_distance_m']:.4f} m"
        )
    if result.get("team_messages_sent"):
        received = node.get("received", {}).get("/robocup_mcl/team", 0)
        used = node.get("not_used", {}).get("team message", 0)
        print(
            f"team messages: {result['team_messages_sent']} sent ({result['team_messages_bad_sent']} bad), "
            f"{received} received, {used} given to the localizer"
        )
    print(
        f"poses or transforms with a NaN or an infinity: {result['nonfinite_poses']} poses, "
        f"{result['nonfinite_transforms']} transforms"
    )
    rss = result.get("rss", {})
    if rss.get("samples"):
        print(
            f"node memory (RSS, {rss['samples']} samples over {rss['seconds']:.0f} s): "
            f"{rss['first_window_mb']:.1f} MB in the first {rss['window_s']:.0f} s, "
            f"{rss['last_window_mb']:.1f} MB in the last ({rss['growth_mb']:+.1f} MB, {rss['growth_percent']:+.2f} %), "
            f"range {rss['min_mb']:.1f}-{rss['max_mb']:.1f} MB"
        )
    shutdown = result.get("shutdown", {})
    if shutdown:
        print(
            f"shutdown on {shutdown['signal']}: "
            + ("completed" if shutdown["completed"] else "NOT completed")
            + f" in {shutdown['seconds']:.2f} s, exit status {shutdown['exit_status']}"
            + (f", escalated to {shutdown['escalated_to']}" if shutdown["escalated_to"] else "")
        )
    rrd = result.get("rrd")
    if rrd:
        if rrd.get("median_ratio") is not None:
            print(
                f"--rrd: odometry callback without the recording's part -> with it: median "
                f"{rrd['callback_without_median_ms']:.3f} -> {rrd['callback_median_ms']:.3f} ms "
                f"(x{rrd['median_ratio']:.2f}), p99 {rrd['callback_without_p99_ms']:.2f} -> "
                f"{rrd['callback_p99_ms']:.2f} ms (x{rrd['p99_ratio']:.2f}), all callbacks x{rrd['total_ratio']:.2f}"
            )
        print(
            f"--rrd: {rrd['file'].get('bytes')} bytes, {rrd['file'].get('estimate_rows')} estimates and "
            f"{rrd['file'].get('particle_rows')} particle rows read back"
            + (f" (error: {rrd['file']['error']})" if rrd["file"].get("error") else "")
        )
    order = result.get("order")
    if order:
        share = order["core_in_node_order_equal_share"]
        print(
            f"order taken: of {order['camera_messages']} camera messages, {order['taken_early']} taken before an "
            f"odometry message published before them (first at {order['first_early_s']} s), "
            f"{order['taken_late']} after one published after them (first at {order['first_late_s']} s); "
            f"of {order['frames_applied']} frames that corrected the filter in the published order, "
            f"{order['frames_applied_at_another_step']} did at another step in the node's "
            f"({order['frames_applied_earlier']} earlier, first captured at {order['first_frame_at_another_step_s']} s) "
            f"and {order['frames_not_applied']} not at all; a core fed "
            f"the node's order: {order['core_in_node_order_compared']} poses, "
            + (f"{100 * share:.1f} % equal to the node's" if share is not None else "none compared")
        )
    if node.get("not_used"):
        print(f"not used by the node: {node['not_used']}")


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    import argparse

    from mcl.tools.cli_checks import NO_PROGRESS_HELP, add_save_option

    parser = argparse.ArgumentParser(
        prog=prog,
        description="Play a robot's MCAP log to the live node over DDS, in a network namespace with "
        "only the loopback: latency from odometry to pose, drops, the node's CPU share, and its poses against the "
        "replay's.",
    )
    parser.add_argument("log", help="the MCAP log (robocup-mcl replay's topics)")
    parser.add_argument(
        "--field", default="spl", help="the node's field: spl, kidsize, adultsize or a file (default spl)"
    )
    parser.add_argument("--particles", type=int, default=500, help="the node's particles (default 500)")
    parser.add_argument("--seed", type=int, default=0, help="the node's seed (default 0)")
    parser.add_argument("--rate", type=float, default=1.0, help="play at this multiple of real time (default 1)")
    parser.add_argument("--seconds", type=float, default=None, help="play at most this many seconds of the log")
    parser.add_argument(
        "--repeat",
        type=int,
        default=1,
        help="play the log this many times in a row, stamps moved on (a soak; default 1)",
    )
    parser.add_argument(
        "--no-source-timestamps",
        action="store_true",
        help="run the node with use_source_timestamps false: frames ordered as on Humble (receive "
        "order and header stamps)",
    )
    parser.add_argument(
        "--stop-signal",
        choices=("SIGINT", "SIGTERM"),
        default="SIGINT",
        help="stop the node with this signal when the log has played (default SIGINT)",
    )
    parser.add_argument(
        "--rss-interval",
        type=float,
        default=5.0,
        help="sample the node's resident memory every this many seconds (default 5)",
    )
    parser.add_argument(
        "--rrd",
        metavar="PATH",
        help="the node records the run to this Rerun file: the recording's share of the odometry callback "
        "(ratio with and without it, in the same run), the file read back",
    )
    parser.add_argument("--record-every", type=int, default=5, help="with --rrd, the node's --record-every (default 5)")
    parser.add_argument(
        "--team-rate",
        type=float,
        default=0.0,
        help="also play a teammate's broadcasts (robocup_mcl_msgs/TeamMessage, no ball) this many times a "
        "second (default 0: none)",
    )
    parser.add_argument(
        "--team-bad-every",
        type=int,
        default=0,
        help="with --team-rate, make every N-th broadcast bad (a NaN x; default 0: none)",
    )
    parser.add_argument(
        "--trace-order",
        action="store_true",
        help="record the order the node took the messages in and compare it with the order they were "
        "published in (camera frames taken before or after an odometry message published before or after them), "
        "and feed a core the messages in the node's order (its poses against the node's); needs --repeat 1",
    )
    parser.add_argument(
        "--published",
        metavar="PATH",
        help="write what the listener heard from the node (the field's markers, every pose, the latest "
        "particle messages) to PATH as JSON: `robocup-mcl node figure PATH` draws it",
    )
    parser.add_argument("--domain", type=int, default=None, help="ROS_DOMAIN_ID (default: 100 + pid %% 100)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    add_save_option(parser)
    parser.add_argument("--no-progress", action="store_true", help=NO_PROGRESS_HELP + "; this command shows none")
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl node bench LOG` (see `--help`); returns the exit status."""
    from mcl.tools.cli_checks import CommandError, check_output_file, save_and_print
    from mcl.tools.ros.node import require_ros

    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser(prog).parse_args(argv)
    if not (args.rate > 0 and args.repeat >= 1 and args.particles > 0):
        raise CommandError("--rate must be > 0, --repeat >= 1 and --particles > 0")
    if not (args.team_rate >= 0 and args.team_bad_every >= 0):
        raise CommandError("--team-rate and --team-bad-every must be >= 0")
    if args.trace_order and args.repeat != 1:
        raise CommandError("--trace-order needs --repeat 1")
    if not args.rss_interval > 0:
        raise CommandError("--rss-interval must be > 0")
    if not os.path.isfile(args.log):
        raise CommandError(f"{args.log}: no such file")
    require_ros()
    check_output_file(args.save, "--save")
    check_output_file(args.rrd, "--rrd")
    check_output_file(args.published, "--published")
    if args.record_every < 1:
        raise CommandError("--record-every must be >= 1")
    status = rerun_isolated("mcl.tools.ros.bench", argv, "DDS")
    if status is not None:
        return status
    if args.domain is None:
        args.domain = 100 + os.getpid() % 100
    from mcl.numba_cache import guard_source_checkout

    guard_source_checkout()
    node_argv = ["--field", args.field, "--particles", str(args.particles), "--seed", str(args.seed)]
    if args.no_source_timestamps:
        node_argv.append("--no-use-source-timestamps")
    try:
        if args.rrd:
            node_argv += ["--rrd", os.path.abspath(args.rrd), "--record-every", str(args.record_every)]
        result = run(args, node_argv)
        if args.rrd:
            result["rrd"] = recording_overhead(result, os.path.abspath(args.rrd))
    except RuntimeError as error:  # the node or the player failed: their own messages say why
        raise CommandError(str(error)) from None
    published = result.pop("_published")
    if args.published:
        published.update(log=args.log, rate=args.rate, field=args.field, filter_particles=args.particles)
        Path(args.published).write_text(json.dumps(published) + "\n", encoding="utf-8")
    save_and_print(result, args.save, args.json, summary)
    return 0


if __name__ == "__main__":
    from mcl.tools.cli_checks import run_main

    raise SystemExit(run_main(main, "python -m mcl.tools.ros.bench"))
