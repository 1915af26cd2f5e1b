"""Robot logs: what a robot recorded, read from ROS 2 MCAP or the plain columnar format, and poses written back.

    from mcl.tools.logs import RobotLog, read_log

    log, report = read_log("game.mcap")       # or "game.npz", or a folder of CSV files: the columnar format
    print(report.summary())                   # what was read, dropped (and why), where a broken log stopped

`RobotLog` (`mcl.tools.logs.robot_log`) is the one in-memory form every reader returns and every writer takes: one
array per stream, times in seconds from the log's origin. `mcl.tools.logs.mcap_io` reads and writes ROS 2 MCAP
without a ROS install (the message schemas travel inside the file); `mcl.tools.logs.columnar` is the format for teams
without ROS.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mcl.tools.logs.robot_log import LogError, ReadReport, RobotLog, VisionFrame

if TYPE_CHECKING:
    from mcl.tools.logs.mcap_io import Topics

__all__ = ["RobotLog", "VisionFrame", "ReadReport", "LogError", "read_log", "write_log"]


def read_log(path: str | os.PathLike, topics: Topics | None = None, gap: float = 1.0) -> tuple[RobotLog, ReadReport]:
    """Read a log by its name: `.mcap` (ROS 2, `topics` = `mcap_io.Topics`), `.npz`, or a folder of CSV files.

    Whatever the file holds, the answer is a `RobotLog` or a `LogError` (a ValueError) naming the file and
    what is wrong with it. An argument of the wrong type raises TypeError, a bad `gap` (seconds, > 0) ValueError;
    both are checked whatever the log's form (`topics` and `gap` apply to MCAP logs only).

    Parameters
    ----------
    path : str or os.PathLike
        A `.mcap` or `.npz` file, or a folder of CSV files.
    topics : Topics or None, default None
        The topic of each stream in an MCAP log (`mcl.tools.logs.mcap_io.Topics`); None: the default topics.
    gap : float, default 1.0
        The longest silence on an MCAP topic [s] that is not listed in `report.gaps`; > 0.

    Returns
    -------
    tuple of (RobotLog, ReadReport)
        The log, and what was read, dropped (and why) and where a broken log stopped.

    Raises
    ------
    LogError
        If the log is missing, of no form this library reads, or unreadable (a ValueError).
    TypeError
        If an argument has the wrong type.
    ValueError
        If `gap` is not a positive number of seconds.
    """
    if not isinstance(path, (str, os.PathLike)) or not isinstance(os.fspath(path), str):
        raise TypeError(f"path = {path!r} must be a file or folder name (str or os.PathLike)")
    if isinstance(gap, (bool, np.bool_)) or not isinstance(gap, (int, float, np.integer, np.floating)):
        raise TypeError(f"gap = {gap!r} must be a number of seconds")
    if not (math.isfinite(gap) and gap > 0):
        raise ValueError(f"gap = {gap!r} must be a positive number of seconds")
    if topics is not None:
        from mcl.tools.logs.mcap_io import Topics

        if not isinstance(topics, Topics):
            raise TypeError(f"topics = {topics!r} must be a mcl.tools.logs.mcap_io.Topics (or None for the defaults)")
    path = Path(path)
    if path.is_dir():
        from mcl.tools.logs.columnar import read_csv

        return read_csv(path)
    if not path.exists():
        raise LogError(f"{path}: no such file or folder")
    if path.suffix == ".npz":
        from mcl.tools.logs.columnar import read_npz

        return read_npz(path)
    if path.suffix == ".mcap":
        from mcl.tools.logs.mcap_io import Topics, read_mcap

        return read_mcap(path, topics or Topics(), gap=gap)
    raise LogError(f"{path}: not a log this library reads (.mcap, .npz, or a folder of CSV files)")


def write_log(log: RobotLog, path: str | os.PathLike, topics: Topics | None = None) -> None:
    """Write a log by its name: `.mcap`, `.npz`, or (any other name) a folder of CSV files.

    Parameters
    ----------
    log : RobotLog
        The log to write.
    path : str or os.PathLike
        Its name: a `.mcap` or `.npz` file, or any other name for a folder of CSV files.
    topics : Topics or None, default None
        The topic of each stream when writing MCAP (`mcl.tools.logs.mcap_io.Topics`); None: the default topics.
    """
    path = Path(path)
    if path.suffix == ".mcap":
        from mcl.tools.logs.mcap_io import Topics, write_mcap

        write_mcap(log, path, topics or Topics())
    elif path.suffix == ".npz":
        from mcl.tools.logs.columnar import write_npz

        write_npz(log, path)
    else:
        from mcl.tools.logs.columnar import write_csv

        write_csv(log, path)
