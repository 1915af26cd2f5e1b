"""Robot logs: what a robot recorded, read from ROS 2 MCAP or the plain columnar format, and poses written back.

    from mcl.logs import RobotLog, read_log

    log, report = read_log("game.mcap")       # or "game.npz", or a folder of CSV files: the columnar format
    print(report.summary())                   # what was read, dropped (and why), where a broken log stopped

`RobotLog` (`mcl.logs.robot_log`) is the one in-memory form every reader returns and every writer takes: one
array per stream, times in seconds from the log's origin. `mcl.logs.mcap_io` reads and writes ROS 2 MCAP
without a ROS install (the message schemas travel inside the file); `mcl.logs.columnar` is the format for teams
without ROS.
"""
from __future__ import annotations

import os
from pathlib import Path

from .robot_log import LogError, ReadReport, RobotLog, VisionFrame

__all__ = ["RobotLog", "VisionFrame", "ReadReport", "LogError", "read_log", "write_log"]


def read_log(path: str | os.PathLike, topics=None, gap: float = 1.0) -> tuple[RobotLog, ReadReport]:
    """Read a log by its name: `.mcap` (ROS 2, `topics` = `mcap_io.Topics`), `.npz`, or a folder of CSV files."""
    path = Path(path)
    if path.is_dir():
        from .columnar import read_csv
        return read_csv(path)
    if not path.exists():
        raise LogError(f"{path}: no such file or folder")
    if path.suffix == ".npz":
        from .columnar import read_npz
        return read_npz(path)
    if path.suffix == ".mcap":
        from .mcap_io import Topics, read_mcap
        return read_mcap(path, topics or Topics(), gap=gap)
    raise LogError(f"{path}: not a log this library reads (.mcap, .npz, or a folder of CSV files)")


def write_log(log: RobotLog, path: str | os.PathLike, topics=None) -> None:
    """Write a log by its name: `.mcap`, `.npz`, or (any other name) a folder of CSV files."""
    path = Path(path)
    if path.suffix == ".mcap":
        from .mcap_io import Topics, write_mcap
        write_mcap(log, path, topics or Topics())
    elif path.suffix == ".npz":
        from .columnar import write_npz
        write_npz(log, path)
    else:
        from .columnar import write_csv
        write_csv(log, path)
