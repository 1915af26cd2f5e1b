"""Robot logs: what a robot recorded, read from ROS 2 MCAP or the plain columnar format, and poses written back.

    from mcl.logs import RobotLog, read_log

    log, report = read_log("game.mcap")       # or "game.npz": the columnar format
    print(report.summary())                   # what was read, dropped (and why), where a broken log stopped

`RobotLog` (`mcl.logs.robot_log`) is the one in-memory form every reader returns and every writer takes: one
array per stream, times in seconds from the log's origin. `mcl.logs.mcap_io` reads and writes ROS 2 MCAP
without a ROS install (the message schemas travel inside the file); `mcl.logs.columnar` is the format for teams
without ROS.
"""
from .robot_log import LogError, ReadReport, RobotLog, VisionFrame

__all__ = ["RobotLog", "VisionFrame", "ReadReport", "LogError"]
