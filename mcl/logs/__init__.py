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

import math
import os
from pathlib import Path

import numpy as np

from .robot_log import LogError, ReadReport, RobotLog, VisionFrame

__all__ = ["RobotLog", "VisionFrame", "ReadReport", "LogError", "read_log", "write_log"]


def read_log(path: str | os.PathLike, topics=None, gap: float = 1.0) -> tuple[RobotLog, ReadReport]:
    """Read a log by its name: `.mcap` (ROS 2, `topics` = `mcap_io.Topics`), `.npz`, or a folder of CSV files.

    Whatever the file holds, the answer is a `RobotLog` or a `LogError` (a ValueError) naming the file and
    what is wrong with it. An argument of the wrong type raises TypeError, a bad `gap` (seconds, > 0) ValueError;
    both are checked whatever the log's form (`topics` and `gap` apply to MCAP logs only).
    """
    if not isinstance(path, (str, os.PathLike)) or not isinstance(os.fspath(path), str):
        raise TypeError(f"path = {path!r} must be a file or folder name (str or os.PathLike)")
    if isinstance(gap, (bool, np.bool_)) or not isinstance(gap, (int, float, np.integer, np.floating)):
        raise TypeError(f"gap = {gap!r} must be a number of seconds")
    if not (math.isfinite(gap) and gap > 0):
        raise ValueError(f"gap = {gap!r} must be a positive number of seconds")
    if topics is not None:
        from .mcap_io import Topics
        if not isinstance(topics, Topics):
            raise TypeError(f"topics = {topics!r} must be a mcl.logs.mcap_io.Topics (or None for the defaults)")
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
