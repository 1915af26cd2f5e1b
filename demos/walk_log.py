"""The walk scenario as a robot log: what the robot would have recorded, with a camera latency.

    from demos.walk_sim import WalkScenario, simulate
    from demos.walk_log import to_robot_log

    log = to_robot_log(simulate(WalkScenario(), seed=0), latency=0.08)
    # log.commands at the start of each 10 ms step, log.vision with stamp = capture and received = capture
    # + latency, log.truth at the end of each step (and the start pose at t = 0)

`mcl.tools.logs.mcap_io.write_mcap(log, "walk.mcap")` turns it into a ROS 2 MCAP file that `robocup-mcl replay`
reads like any robot's log.
"""

from __future__ import annotations

import numpy as np

from mcl.tools.logs import RobotLog, VisionFrame

from .walk_sim import WalkLog


def to_robot_log(walk: WalkLog, latency: float = 0.0, origin_ns: int = 1_700_000_000_000_000_000) -> RobotLog:
    """The walk as a `RobotLog`: walk commands (held over each step), vision frames arriving `latency` s after
    capture, ground truth. Times are seconds from the start of the walk."""
    if not (np.isfinite(latency) and latency >= 0):
        raise ValueError(f"latency = {latency!r} must be finite and >= 0")
    n = walk.times.shape[0]
    frames = tuple(
        VisionFrame(
            stamp=float(walk.times[f.step]), received=float(walk.times[f.step]) + latency, observations=f.observations
        )
        for f in walk.frames
    )
    return RobotLog(
        origin_ns=origin_ns,
        # k·dt: the same products as walk.times, so step ends and capture times match exactly
        command_times=np.arange(n) * walk.dt,
        commands=walk.commands,
        vision=frames,
        truth_times=np.concatenate([[0.0], walk.times]),
        truth=np.concatenate([walk.start[None, :], walk.truth]),
    )
