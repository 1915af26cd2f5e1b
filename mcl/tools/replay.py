"""Replay a robot's log through the filter: estimates, errors against ground truth, a recording, poses out.

    from field import spl
    from mcl.tools.logs import read_log
    from mcl.tools.replay import replay

    log, report = read_log("game.mcap")              # ROS 2 MCAP, or the columnar .npz / CSV folder
    result = replay(log, spl(), particles=500, rrd="game.rrd", poses_out="poses.mcap")
    print(result.summary())                          # errors (when the log has truth), speed, what was dropped

or from the shell: `robocup-mcl replay game.mcap --field kidsize --rrd game.rrd --out poses.mcap`.

The replay is the robot's loop (`mcl.localizer.Localizer`) driven by the log in arrival order:
- motion: each odometry message moves the filter by the odometry change since the previous one (in the robot
  frame); a log without odometry moves it by the walk command, held from one command to the next (and the
  last one until the log ends);
- vision: each camera frame corrects the filter when it arrives, scored at its capture time (the header
  stamp) unless latency compensation is off;
- after every motion step the estimate, its covariance, the quality and the "lost" flag are kept (and
  written to the recording and the pose output).
Events at the same instant (within 1 µs): motion first, then vision. Nothing is skipped silently: what the
localizer could not use is counted in `result.dropped` with its reason.

A log that cannot drive a replay is refused before anything runs (`check_inputs`, a `LogError`; the command
exits with status 1 and names what is missing): one with no motion input (neither two odometry poses nor a walk
command) or no camera frame with a detection (the estimates would be the start belief moved by dead
reckoning). For an MCAP log the reader picks each stream's topic by name, or by message type when the default
topic is absent and exactly one topic of the log has the type (`mcl.tools.logs.mcap_io`); the report lists every
choice and how it was made (`report.topics`, under "topics" in the JSON).

The estimates written with `--out poses.npz` (`poses_out`; numpy's `np.load`), one row per motion step:

- `times` (M,) float64 [s]: the end of each motion step (the odometry message's stamp, or the next walk
  command's time), in seconds after `origin_ns`;
- `poses` (M, 3) float64 [m, m, rad]: the estimate x, y, θ in the field frame, θ in (-π, π];
- `covariances` (M, 3, 3) float64 [m², m·rad, rad²]: the estimate's covariance over (x, y, θ);
- `quality` (M,) int8: 2 superb, 1 okay, 0 poor, 3 unsure of the half (`QUALITY_CODES`);
- `lost` (M,) bool: the "lost" flag (`Localizer.is_lost`);
- `origin_ns` () int64 [ns since the Unix epoch]: what t = 0 is, the log's origin. For an MCAP log that is
  the log time of its first message (any topic), or the origin a file written by `write_mcap` records; for
  the columnar format, its `origin_ns`. Times are header stamps relative to it, so a stamp taken before the
  first message was logged gives a negative time.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from field import Field
from field.angles import wrap_angles
from mcl.latency import SAME_TIME
from mcl.localizer import Localizer, Quality
from mcl.tools.logs import LogError, ReadReport, RobotLog
from motion_models import ConstantNoise, MotionInput, VelocityLinear

if TYPE_CHECKING:
    import argparse

    from mcl.numba_cache import WarmUp
    from mcl.tools.logs.mcap_io import Topics

MODELS = {"velocity-linear": VelocityLinear, "constant": ConstantNoise}
STARTS = ("own_half", "field", "initial", "penalty")
QUALITY_CODES = {Quality.SUPERB: 2, Quality.OKAY: 1, Quality.POOR: 0, Quality.UNSURE_HALF: 3}
MAX_NOTES = 10
LONG_STEP = 0.5  # s: a motion step this long is a gap in the log, worth a note
WRONG = 0.5  # m: an estimate this far from the truth is wrong (for the quality flag's figures)


@dataclass
class ReplayResult:
    """Per motion step: `times` (M,), `estimates` (M, 3), `covariances` (M, 3, 3), `weights` (M,) the dominant
    cluster's share of the weight, `quality` (M,) codes
    (2 superb, 1 okay, 0 poor, 3 unsure of the half), `lost` (M,), `entropy` (M, 2) position/orientation bits,
    `truth` (M, 3) (NaN where the log has none); `dropped` {reason: count}; `frames_used`; `elapsed` seconds of replay.

    Attributes
    ----------
    times : np.ndarray
        (M,) float64 end of each motion step [s], in the log's time (seconds after its `origin_ns`).
    estimates : np.ndarray
        (M, 3) float64 estimate after each step (x [m], y [m], θ [rad]) in the field frame.
    covariances : np.ndarray
        (M, 3, 3) float64 covariance of each estimate over (x, y, θ) [m², m·rad, rad²].
    weights : np.ndarray
        (M,) float64 share of the weight the estimate's dominant cluster holds.
    quality : np.ndarray
        (M,) int8 quality codes (`QUALITY_CODES`: 2 superb, 1 okay, 0 poor, 3 unsure of the half).
    lost : np.ndarray
        (M,) bool: the localizer's "lost" flag after each step.
    entropy : np.ndarray
        (M, 2) float64 entropy of the belief [bits]: position, orientation.
    truth : np.ndarray
        (M, 3) float64 ground truth at each step's time (x [m], y [m], θ [rad]); NaN where the log has none.
    dropped : dict of str to int
        What the localizer could not use, counted by reason (and the camera frames after the last motion step).
    notes : list of str
        The first few events worth a look (at most `MAX_NOTES`, then a line saying more were left out), with
        their times.
    frames_used : int
        Camera frames that corrected the filter.
    elapsed : float
        Wall-clock time of the replay [s].
    log_duration : float
        Length of the log [s].
    log_evidence : float
        The localizer's `log_evidence` over the frames used (its estimate of how probable the detections are
        under its settings; `mcl.tools.tuning`), summed over `evidence_frames` frames.
    evidence_frames : int
        How many frames it sums.
    """

    times: np.ndarray
    estimates: np.ndarray
    covariances: np.ndarray
    weights: np.ndarray
    quality: np.ndarray
    lost: np.ndarray
    entropy: np.ndarray
    truth: np.ndarray
    dropped: dict[str, int] = dataclass_field(default_factory=dict)
    notes: list[str] = dataclass_field(default_factory=list)  # the first few events worth a look, with times
    frames_used: int = 0
    elapsed: float = 0.0
    log_duration: float = 0.0
    log_evidence: float = 0.0
    evidence_frames: int = 0

    @property
    def has_truth(self) -> np.ndarray:
        """(M,) bool: steps with ground truth (the log's truth covers their time)."""
        return ~np.isnan(self.truth[:, 0])

    @property
    def position_errors(self) -> np.ndarray:
        """(M,) distance [m] of each estimate from the truth; NaN where the log has none."""
        return np.hypot(*(self.estimates[:, :2] - self.truth[:, :2]).T)

    @property
    def heading_errors(self) -> np.ndarray:
        """(M,) absolute heading error [rad] of each estimate against the truth, within [0, π]; NaN where the log
        has none."""
        return np.abs(wrap_angles(self.estimates[:, 2] - self.truth[:, 2]))

    def figures(self) -> dict:
        """Speed, quality shares and, with ground truth, the errors (NaN-free figures only)."""
        steps = self.times.shape[0]
        out = {
            "steps": steps,
            "frames_used": self.frames_used,
            "dropped": dict(self.dropped),
            "notes": list(self.notes),
            "log_seconds": self.log_duration,
            "replay_seconds": self.elapsed,
            "real_time_factor": self.log_duration / self.elapsed if self.elapsed > 0 else None,
            "quality_share": {
                q.value: float(np.mean(self.quality == code)) if steps else 0.0 for q, code in QUALITY_CODES.items()
            },
            "lost_share": float(np.mean(self.lost)) if steps else 0.0,
            "log_evidence_per_frame": (
                self.log_evidence / self.evidence_frames
                if self.evidence_frames and math.isfinite(self.log_evidence)
                else None
            ),
        }
        has_truth = self.has_truth
        if has_truth.any():
            position, heading = self.position_errors[has_truth], self.heading_errors[has_truth]
            out["position_error_m"] = {
                "median": float(np.median(position)),
                "p95": float(np.percentile(position, 95)),
                "rmse": float(np.sqrt(np.mean(position**2))),
            }
            out["heading_error_deg"] = {
                "median": math.degrees(float(np.median(heading))),
                "p95": math.degrees(float(np.percentile(heading, 95))),
            }
            # How honest the quality flag is: the share of each level's steps whose error exceeds 0.5 m.
            wrong = position > WRONG
            quality = self.quality[has_truth]
            out["wrong_share_by_quality"] = {
                q.value: float(np.mean(wrong[quality == code])) if (quality == code).any() else None
                for q, code in QUALITY_CODES.items()
            }
        return out

    def summary(self) -> str:
        """The figures (`figures`) as a few lines of text: speed, quality shares, errors against the truth (when
        the log has it), what was dropped, and the notes."""
        f = self.figures()
        lines = [
            f"{f['steps']} steps, {f['frames_used']} camera frames used, "
            f"{f['log_seconds']:.1f} s of log in {f['replay_seconds']:.1f} s"
            + (f" ({f['real_time_factor']:.1f}x real time)" if f["real_time_factor"] else "")
        ]
        shares = ", ".join(f"{name} {100 * share:.0f} %" for name, share in f["quality_share"].items())
        lines.append(f"quality: {shares}; lost {100 * f['lost_share']:.0f} % of the time")
        if "position_error_m" in f:
            p, h = f["position_error_m"], f["heading_error_deg"]
            lines.append(
                f"error against truth: position median {p['median']:.3f} m, p95 {p['p95']:.3f} m, "
                f"RMSE {p['rmse']:.3f} m; heading median {h['median']:.1f}°, p95 {h['p95']:.1f}°"
            )
            wrong = ", ".join(
                f"{name} {100 * share:.1f} %"
                for name, share in f["wrong_share_by_quality"].items()
                if share is not None
            )
            lines.append(f"steps more than {WRONG} m off, by quality: {wrong}")
        for reason, count in sorted(self.dropped.items()):
            lines.append(f"dropped {count}: {reason}")
        lines += [f"note: {note}" for note in self.notes]
        return "\n".join(lines)


def check_inputs(
    log: RobotLog, report: ReadReport | None = None, topics: Topics | None = None, require_vision: bool = True
) -> None:
    """Raise `LogError` when `log` cannot drive a replay: it has no motion input (neither two or more odometry
    poses nor a walk command), or (with `require_vision`) no camera frame with a detection. The message names
    what is missing; with the MCAP reader's `report` and the `topics` it was read with (default `Topics()`),
    also which topic each of those streams was read from, or looked for, and the options that name a topic.

    Parameters
    ----------
    log : RobotLog
        The log to replay.
    report : ReadReport or None, optional
        The reader's report on `log`; with an MCAP log's report the message also says where each missing stream
        was looked for. None (the default): the message names what is missing only.
    topics : mcl.tools.logs.mcap_io.Topics or None, optional
        The topics the MCAP log was read with; None (the default) for `Topics()`.
    require_vision : bool, optional
        Whether a camera frame with a detection is required (default True).

    Raises
    ------
    LogError
        If the log has no motion input or (with `require_vision`) no camera frame with a detection; the message
        starts with the report's path when there is a report.
    """
    problems = []
    if log.odometry_times.shape[0] < 2 and log.command_times.shape[0] == 0:
        problems.append(
            (
                "no motion input: the log has neither odometry (two or more poses) nor walk commands, "
                "so nothing moves the filter",
                ("odometry", "commands"),
            )
        )
    if require_vision and not any(not frame.observations.is_empty for frame in log.vision):
        seen = f"{len(log.vision)} camera frames, none with a detection" if log.vision else "no camera frames"
        problems.append(
            (
                f"no detections: the log has {seen}, so nothing corrects the filter (the estimates "
                f"would be the start belief moved by dead reckoning)",
                ("goalposts", "markings"),
            )
        )
    if not problems:
        return
    messages = []
    for text, streams in problems:
        if report is not None and report.path.endswith(".mcap"):
            options = " or ".join(f"--topic-{stream}" for stream in streams)
            text += (
                "; "
                + "; ".join(_stream_source(stream, report, topics) for stream in streams)
                + f"; name a topic with {options} (--list shows the log's topics)"
            )
        messages.append(text)
    where = "" if report is None else f"{report.path}: "
    raise LogError(where + "; and ".join(messages))


def _stream_source(stream: str, report: ReadReport, topics: Topics | None) -> str:
    """Where an MCAP log's `stream` came from, or was looked for, for `check_inputs`'s message."""
    from mcl.tools.logs.mcap_io import DISCOVERY_TYPES, Topics

    if stream in report.topics:
        topic, how = report.topics[stream]
        dropped = sum(count for (where, _), count in report.dropped.items() if where == topic)
        return (
            f"{stream}: {topic} (chosen by {'type' if how == 'type' else 'name'}), "
            f"{report.messages.get(topic, 0)} messages, {dropped} dropped"
        )
    topic = getattr(topics if topics is not None else Topics(), stream)
    if not topic:
        return f"{stream}: not read (its topic is '')"
    return f"{stream}: no topic {topic} and none of type {' or '.join(DISCOVERY_TYPES[stream])} in the log"


def motion_events(log: RobotLog) -> tuple[np.ndarray, list[MotionInput]]:
    """The motion steps a log drives the filter with: end times (M,) and their `MotionInput`s.

    Odometry when the log has at least two odometry poses (the change between consecutive ones, in the robot
    frame of the earlier one, with the command in force); otherwise the walk commands held until the next
    command (the last one until the log's end). LogError when the log has neither.

    Parameters
    ----------
    log : RobotLog
        The log.

    Returns
    -------
    times : np.ndarray
        (M,) float64 end of each motion step [s], in the log's time.
    inputs : list of MotionInput
        The M motion inputs, one per step.

    Raises
    ------
    LogError
        If the log has neither two or more odometry poses nor a walk command.
    """
    if log.odometry_times.shape[0] >= 2:
        t, pose = log.odometry_times, log.odometry
        d = np.diff(pose[:, :2], axis=0)
        c, s = np.cos(pose[:-1, 2]), np.sin(pose[:-1, 2])
        local = np.column_stack(
            [c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], wrap_angles(np.diff(pose[:, 2]))]
        )
        dts = np.diff(t)
        commands = _commands_at(log, t[:-1])
        inputs = [
            MotionInput(
                dt=float(dts[k]), odometry=tuple(local[k]), command=None if commands is None else tuple(commands[k])
            )
            for k in range(dts.shape[0])
        ]
        return t[1:], inputs
    if log.command_times.shape[0] >= 1:
        t = log.command_times
        end = max(log.end_time, float(t[-1]))
        ends = np.append(t[1:], end) if end > t[-1] + SAME_TIME else t[1:]
        dts = ends - t[: ends.shape[0]]
        inputs = [MotionInput(dt=float(dts[k]), command=tuple(log.commands[k])) for k in range(ends.shape[0])]
        return ends, inputs
    raise LogError("the log has neither odometry (two or more poses) nor walk commands: nothing moves the filter")


def _commands_at(log: RobotLog, times: np.ndarray) -> np.ndarray | None:
    """The walk command in force at each time (the latest at or before it), or None without commands."""
    if log.command_times.shape[0] == 0:
        return None
    index = np.searchsorted(log.command_times, times + SAME_TIME, side="right") - 1
    commands = log.commands[np.clip(index, 0, None)].copy()
    commands[index < 0] = 0.0
    return commands


def replay(
    log: RobotLog,
    field: Field,
    model: str = "velocity-linear",
    particles: int = 500,
    seed: int = 0,
    compensate_latency: bool = True,
    history: float = 1.0,
    start: str | Sequence[float] | np.ndarray = "own_half",
    rrd: str | None = None,
    poses_out: str | None = None,
    record_every: int = 5,
    progress: bool = False,
    localizer: Localizer | None = None,
    require_vision: bool = True,
) -> ReplayResult:
    """Run the log through a `Localizer` and collect the estimates (see the module docstring).

    A log without motion input, or (unless `require_vision` is False: dead reckoning from `start`) without a
    camera frame with a detection, raises `LogError` (`check_inputs`).

    Parameters
    ----------
    log : RobotLog
        The log to replay.
    field : Field
        The field the robot plays on.
    model : str, optional
        The motion model, a key of `MODELS`: "velocity-linear" (the default) or "constant".
    particles : int, optional
        Number of particles (default 500).
    seed : int, optional
        Seed of the filter's random generator (default 0).
    compensate_latency : bool, optional
        Score each camera frame at its capture time (the default) rather than when it arrives.
    history : float, optional
        Seconds of motion kept for late camera frames (default 1.0).
    start : str or sequence of float or np.ndarray, optional
        Where the belief starts: "own_half" (the default; uniform, kick-off side), "field" (uniform),
        "initial" (`initial_placement`: the touchlines), "penalty" (`penalty_return`), or a pose
        (x [m], y [m], θ [rad]).
    rrd : str or None, optional
        Write a Rerun recording to this file; None (the default) writes none.
    poses_out : str or None, optional
        Write the estimates to this file: .mcap (PoseWithCovarianceStamped), .csv (the SPL convention: mm,
        rad) or .npz (the arrays of the module docstring); None (the default) writes none.
    record_every : int, optional
        Record the particles every this many steps (`Recorder`'s `particles_every`; default 5).
    progress : bool, optional
        Show a progress bar on stderr (default False).
    localizer : Localizer or None, optional
        A localizer to use instead of the one built from `model`, `particles`, `seed`, `history` and
        `compensate_latency`; None (the default) builds one.
    require_vision : bool, optional
        Refuse a log without a camera frame with a detection (default True); False replays dead reckoning
        from `start`.

    Returns
    -------
    ReplayResult
        The estimates per motion step, what was dropped, and the timing.

    Raises
    ------
    ValueError
        If `model` or `start` is unknown, `poses_out` has another suffix than .mcap, .csv or .npz, or a value
        is out of range; `LogError` (a ValueError) if the log cannot drive a replay (`check_inputs`).
    """
    if model not in MODELS:
        raise ValueError(f"model = {model!r} must be one of {tuple(MODELS)}")
    check_inputs(log, require_vision=require_vision)
    times, inputs = motion_events(log)
    if localizer is None:
        localizer = Localizer(
            field,
            MODELS[model](),
            n_particles=particles,
            seed=seed,
            history=history,
            compensate_latency=compensate_latency,
        )
    _start(localizer, start)
    recorder = None
    if rrd:
        from mcl.tools.recording import Recorder, default_blueprint

        recorder = Recorder(
            rrd,
            field,
            particles_every=record_every,
            origin_ns=log.origin_ns,
            blueprint=default_blueprint(
                (
                    ("/entropy", "entropy [bits]"),
                    ("/error", "error [m, rad]"),
                    ("/localization", "quality (2 superb, 1 okay, 0 poor, 3 unsure of the half), lost"),
                )
            ),
        )
    writer = _pose_writer(poses_out, log.origin_ns) if poses_out else None
    m = times.shape[0]
    estimates, covariances, weights = np.empty((m, 3)), np.empty((m, 3, 3)), np.empty(m)
    quality, lost = np.empty(m, dtype=np.int8), np.zeros(m, dtype=bool)
    entropy = np.empty((m, 2))
    truth = log.truth_at(times)
    frames = log.vision
    next_frame, frames_used = 0, 0
    bar = _progress_bar(times, progress)
    notes: list[str] = []

    def note(text: str) -> None:
        if len(notes) < MAX_NOTES:
            notes.append(text)
        elif len(notes) == MAX_NOTES:
            notes.append("(further notes left out)")

    evidence_before, frames_before = localizer.log_evidence, localizer.evidence_frames
    started = time.perf_counter()
    try:
        for k in range(m):
            t = float(times[k])
            if inputs[k].dt > LONG_STEP:
                note(
                    f"motion step of {inputs[k].dt:.2f} s ending at {t:.3f} s (a gap in the motion stream): "
                    "integrated as one step"
                )
            localizer.motion(t, inputs[k])
            step_observations = None
            while next_frame < len(frames) and frames[next_frame].received <= t + SAME_TIME:
                frame = frames[next_frame]
                next_frame += 1
                try:
                    if localizer.observe(frame.observations, capture_time=frame.stamp):
                        frames_used += 1
                        step_observations = frame.observations
                except ValueError as error:  # counted by the localizer
                    note(f"camera frame arriving at {frame.received:.3f} s dropped: {error}")
            estimate = localizer.pose()
            h = localizer.entropy()
            estimates[k], covariances[k], weights[k] = estimate.pose, estimate.covariance, estimate.weight
            quality[k] = QUALITY_CODES[localizer.quality()]
            lost[k] = localizer.is_lost
            entropy[k] = (h.position, h.orientation)
            if recorder is not None:
                recorder.log_step(
                    k,
                    t,
                    localizer.filter,
                    truth=None if np.isnan(truth[k, 0]) else truth[k],
                    observations=step_observations,
                    entropy=h,
                )
                recorder.log_scalars({"localization/quality": float(quality[k]), "localization/lost": float(lost[k])})
                if k == 0:
                    recorder.log_event("reset", f"the belief starts: {start if isinstance(start, str) else 'a pose'}")
                recorder.log_change("quality", localizer.quality().value, f"quality {localizer.quality().value}")
                recorder.log_change(
                    "lost", bool(lost[k]), "lost" if lost[k] else "no longer lost", level="WARN" if lost[k] else "INFO"
                )
            if writer is not None:
                writer.write(t, estimate.pose, estimate.covariance, localizer.quality(), bool(lost[k]))
            if bar is not None:
                bar.update(t - bar.n)
    finally:
        if recorder is not None:
            recorder.close()
        if writer is not None:
            writer.close()
        if bar is not None:
            bar.close()
    elapsed = time.perf_counter() - started
    dropped = dict(localizer.counts)
    if next_frame < len(frames):
        dropped["camera frame after the last motion step"] = len(frames) - next_frame
    return ReplayResult(
        times,
        estimates,
        covariances,
        weights,
        quality,
        lost,
        entropy,
        truth,
        dropped,
        notes,
        frames_used,
        elapsed,
        log.duration,
        localizer.log_evidence - evidence_before,
        localizer.evidence_frames - frames_before,
    )


def _start(localizer: Localizer, start: str | Sequence[float] | np.ndarray) -> None:
    if isinstance(start, str):
        if start not in STARTS:
            raise ValueError(f"start = {start!r} must be one of {STARTS} or a pose (x, y, θ)")
        if start in ("own_half", "field"):
            localizer.filter.reset_uniform(start)
        elif start == "initial":
            localizer.initial_placement()
        else:
            localizer.penalty_return()
    else:
        localizer.place(start)


class _PoseOutput:
    """Writes each step's estimate in the format the file name asks for."""

    def __init__(self, path: Path, origin_ns: int) -> None:
        self.path, self.origin_ns = path, origin_ns
        self.rows: list[tuple] = []
        self._mcap = None
        if path.suffix == ".mcap":
            from mcl.tools.logs.mcap_io import PoseWriter

            self._mcap = PoseWriter(path)
            self._mcap.__enter__()

    def write(self, t: float, pose: np.ndarray, covariance: np.ndarray, quality: Quality, lost: bool) -> None:
        if self._mcap is not None:
            self._mcap.write(self.origin_ns + int(round(t * 1e9)), pose, covariance)
        else:
            self.rows.append((t, *pose, *covariance.reshape(-1), QUALITY_CODES[quality], lost))

    def close(self) -> None:
        if self._mcap is not None:
            self._mcap.__exit__(None, None, None)
            return
        rows = np.array(self.rows, dtype=np.float64).reshape(-1, 15)
        if self.path.suffix == ".npz":
            np.savez(
                self.path,
                times=rows[:, 0],
                poses=rows[:, 1:4],
                covariances=rows[:, 4:13].reshape(-1, 3, 3),
                quality=rows[:, 13].astype(np.int8),
                lost=rows[:, 14].astype(bool),
                origin_ns=self.origin_ns,
            )
            return
        from mcl.tools.formats import pose_to_spl

        with open(self.path, "w") as out:
            out.write("t_s,x_mm,y_mm,theta_rad,sigma_x_mm,sigma_y_mm,sigma_theta_rad,quality,lost\n")
            for row in rows:
                x_mm, y_mm, theta = pose_to_spl(row[1:4])
                cov = row[4:13].reshape(3, 3)
                sx, sy, st = (math.sqrt(max(cov[i, i], 0.0)) for i in range(3))
                quality = {code: q.value for q, code in QUALITY_CODES.items()}[int(row[13])]
                out.write(
                    f"{row[0]:.6f},{x_mm:.1f},{y_mm:.1f},{theta:.5f},{1e3 * sx:.1f},{1e3 * sy:.1f},"
                    f"{st:.5f},{quality},{int(row[14])}\n"
                )


POSE_SUFFIXES = (".mcap", ".csv", ".npz")


def _pose_writer(path, origin_ns: int) -> _PoseOutput:
    path = Path(path)
    if path.suffix not in POSE_SUFFIXES:
        raise ValueError(f"poses_out = {str(path)!r} must end in one of {POSE_SUFFIXES}")
    path.parent.mkdir(parents=True, exist_ok=True)
    return _PoseOutput(path, origin_ns)


def _progress_bar(times: np.ndarray, enabled: bool):
    """A bar over the log's seconds on stderr (`mcl.tools.cli_checks.progress_bar`; None when not `enabled`): its rate
    is the replay's speed in seconds of log per second, i.e. in multiples of real time."""
    if not enabled:
        return None
    from mcl.tools.cli_checks import progress_bar

    total = float(times[-1]) if times.shape[0] else 0.0
    return progress_bar(
        enabled=True,
        total=total,
        desc="replay",
        unit="s",
        bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.1f}/{total:.1f} s of log "
        "[{elapsed}<{remaining}, {rate_noinv_fmt} = x real time]",
    )


def _field(name: str) -> Field:
    """The field `--field` names: a preset or a field file (`field.io.field_by_name_or_path`)."""
    from field.io import field_by_name_or_path

    return field_by_name_or_path(name)


def _parse_start(text: str):
    if text in STARTS:
        return text
    try:
        pose = tuple(float(v) for v in text.split(","))
    except ValueError:
        pose = ()
    if len(pose) != 3:
        raise ValueError(f"--start {text!r} must be one of {STARTS} or x,y,theta")
    return pose


PROG = "robocup-mcl replay"
WARM_UP_PARTICLES = 64
WARM_UP_STEPS = 200  # motion steps of the log the warm-up localizer follows (about 2 s at 100 Hz)


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line.

    Parameters
    ----------
    prog : str, optional
        The program name its usage line shows; default "robocup-mcl replay".

    Returns
    -------
    argparse.ArgumentParser
        The parser of `robocup-mcl replay`'s arguments.
    """
    import argparse

    from mcl.tools.cli_checks import NO_PROGRESS_HELP

    parser = argparse.ArgumentParser(
        prog=prog,
        description="Replay a robot's log (ROS 2 MCAP, .npz, or a CSV folder) through the filter: "
        "estimates, errors against ground truth, a Rerun recording, poses out.",
    )
    parser.add_argument("log", help="the log: .mcap, .npz, or a folder of CSV files")
    parser.add_argument("--list", action="store_true", help="list the log's topics (MCAP) and stop")
    parser.add_argument(
        "--field", default="spl", help="spl, kidsize, adultsize, or a field file (.toml/.json) (default spl)"
    )
    parser.add_argument(
        "--model",
        choices=sorted(MODELS),
        default=None,
        help="the motion model (default velocity-linear; not with --profile, which sets it)",
    )
    parser.add_argument("--particles", type=int, default=None, help="particles (default 500, or the profile's)")
    parser.add_argument(
        "--profile",
        metavar="TOML",
        help="the localizer's settings from a profile (mcl.profile; `robocup-mcl tune` writes "
        "them); --particles, --seed, --history and --no-latency given here win over it",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the filter (default 0)")
    parser.add_argument(
        "--start",
        default="own_half",
        help=f"initial belief: {', '.join(STARTS)}, or a pose x,y,theta (default own_half)",
    )
    parser.add_argument(
        "--no-latency", action="store_true", help="score camera frames as if current (default: at their capture time)"
    )
    parser.add_argument(
        "--history", type=float, default=None, help="seconds of motion kept for late frames (default 1)"
    )
    parser.add_argument("--gap", type=float, default=1.0, help="report gaps longer than this [s] (default 1)")
    parser.add_argument("--rrd", help="write a Rerun recording here")
    parser.add_argument(
        "--out",
        help="write the estimates here: .mcap (PoseWithCovarianceStamped), .csv (SPL convention: mm, rad), .npz",
    )
    parser.add_argument("--json", action="store_true", help="print the figures and the read report as JSON")
    parser.add_argument(
        "--progress",
        choices=("auto", "on", "off"),
        default="auto",
        help="progress bar on stderr (auto: when stderr is a terminal and without --json)",
    )
    parser.add_argument("--no-progress", action="store_true", help=NO_PROGRESS_HELP + "; as --progress off")
    add_topic_options(parser)
    return parser


def add_topic_options(parser: argparse.ArgumentParser) -> None:
    """Add `--topic-<stream>` for each stream an MCAP log is read from (`mcl.tools.logs.mcap_io.Topics`) to `parser`;
    `topics_from_args` reads them back."""
    from dataclasses import fields

    from mcl.tools.logs.mcap_io import DISCOVERY_TYPES, Topics

    defaults = Topics()
    for f in fields(Topics):
        if f.name != "pose_out":
            found = "; when the log lacks it, its only topic of the type" if f.name in DISCOVERY_TYPES else ""
            parser.add_argument(
                f"--topic-{f.name.replace('_', '-')}",
                dest=f"topic_{f.name}",
                help=f"topic of the {f.name.replace('_', ' ')} (default {getattr(defaults, f.name)}"
                f"{found}; '' reads none)",
            )


def topics_from_args(args: argparse.Namespace) -> Topics | None:
    """The `Topics` the `--topic-*` options of `add_topic_options` name; None when none was given."""
    from dataclasses import fields

    from mcl.tools.logs.mcap_io import Topics

    given = {
        f.name: getattr(args, f"topic_{f.name}")
        for f in fields(Topics)
        if f.name != "pose_out" and getattr(args, f"topic_{f.name}", None) is not None
    }
    return Topics(**given) if given else None


def warm_up_replay(
    log: RobotLog,
    field: Field,
    model: str,
    compensate_latency: bool = True,
    history: float = 1.0,
    progress: bool = False,
) -> WarmUp:
    """Compile (or load from numba's cache) the kernels a replay reaches, on a throw-away localizer of a few
    particles, before the replay is timed; returns the `mcl.numba_cache.WarmUp`. The filter's groups of kernels
    come one by one (`mcl.numba_cache.filter_stages`, with the log's first motion step and first frame with
    detections), then the localizer follows the log's first motion steps and frames.

    Parameters
    ----------
    log : RobotLog
        The log the replay will run (its first `WARM_UP_STEPS` motion steps and their frames are followed).
    field : Field
        The replay's field.
    model : str
        The replay's motion model, a key of `MODELS`.
    compensate_latency : bool, optional
        As `replay` (default True).
    history : float, optional
        As `replay` [s] (default 1.0).
    progress : bool, optional
        Show the warm-up's progress on stderr (default False).

    Returns
    -------
    mcl.numba_cache.WarmUp
        How long the warm-up took and whether the kernels were cached or compiled.

    Raises
    ------
    LogError
        If the log has no motion input (`motion_events`).
    """
    from mcl.numba_cache import filter_kernels, filter_stages, warm_up

    times, inputs = motion_events(log)

    def fresh() -> Localizer:
        made = Localizer(
            field,
            MODELS[model](),
            n_particles=WARM_UP_PARTICLES,
            seed=0,
            history=history,
            compensate_latency=compensate_latency,
        )
        made.filter.reset_uniform("own_half")
        return made

    localizer, follower = fresh(), fresh()
    frames = [frame for frame in log.vision if len(frame.observations) > 0]
    stages = filter_stages(localizer.filter, inputs[0], frames[0].observations) if frames else []

    def follow():
        next_frame = 0
        for k in range(min(WARM_UP_STEPS, len(inputs))):
            t = float(times[k])
            follower.motion(t, inputs[k])
            while next_frame < len(log.vision) and log.vision[next_frame].received <= t + SAME_TIME:
                frame = log.vision[next_frame]
                next_frame += 1
                try:
                    follower.observe(frame.observations, capture_time=frame.stamp)
                except ValueError:
                    pass
            follower.pose()
            follower.entropy()
            follower.quality()

    stages.append(("the log's first seconds", follow))
    return warm_up(stages, filter_kernels(localizer.filter), progress=progress)


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl replay LOG ...` (see `robocup-mcl replay --help`).

    Parameters
    ----------
    argv : list of str or None, optional
        The command's arguments; None (the default) reads them from `sys.argv`.
    prog : str, optional
        The program name usage and error lines show; default "robocup-mcl replay".

    Returns
    -------
    int
        The exit status: 0 on success, 1 when the log or an option cannot be used (one line on stderr). A
        malformed command line exits with status 2 (argparse's `SystemExit`).
    """
    import json

    from mcl.tools.cli_checks import CommandError, check_output_file, one_line, progress_wanted
    from mcl.tools.logs import read_log
    from mcl.tools.logs.mcap_io import list_topics

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    if args.particles is not None and args.particles <= 0:
        parser.error(f"--particles {args.particles} must be > 0")
    try:
        if args.list:
            rows = list_topics(args.log)
            if args.json:
                json.dump(rows, sys.stdout, indent=2)
                print()
            else:
                for row in rows:
                    print(f"{row['topic']:<32} {row['type']:<48} {row['count']:>8} messages")
            return 0
        topics = topics_from_args(args)
        field = _field(args.field)
        start = _parse_start(args.start)
        # Outputs checked before the log is read and replayed (a long log takes minutes): mcl.tools.cli_checks.
        if args.out and Path(args.out).suffix not in POSE_SUFFIXES:
            raise CommandError(f"--out {args.out}: must end in one of {', '.join(POSE_SUFFIXES)}")
        check_output_file(args.rrd, "--rrd")
        check_output_file(args.out, "--out")
        log, report = read_log(args.log, topics=topics, gap=args.gap)
        check_inputs(log, report, topics)
        progress = args.progress != "off" and progress_wanted(
            args, force=args.progress == "on", no_progress=args.no_progress
        )
        history = 1.0 if args.history is None else args.history
        model = args.model or "velocity-linear"
        localizer = None
        if args.profile:
            from mcl.profile import Profile

            if args.model is not None:
                raise CommandError("--model and --profile: the profile sets the motion model (its [motion])")
            overrides: dict = {"seed": args.seed}
            if args.particles is not None:
                overrides["n_particles"] = args.particles
            if args.history is not None:
                overrides["history"] = args.history
            if args.no_latency:
                overrides["compensate_latency"] = False
            localizer = Profile.load(args.profile).localizer(field, **overrides)
        warm = warm_up_replay(log, field, model, not args.no_latency, history, progress)
        result = replay(
            log,
            field,
            model=model,
            particles=args.particles or 500,
            seed=args.seed,
            compensate_latency=not args.no_latency,
            history=history,
            start=start,
            rrd=args.rrd,
            poses_out=args.out,
            progress=progress,
            localizer=localizer,
        )
    except (ValueError, OSError) as error:
        print(f"robocup-mcl replay: {one_line(error)}", file=sys.stderr)
        return 1
    if args.json:
        json.dump(
            {"log": report.to_json(), "replay": result.figures(), "rrd": args.rrd, "out": args.out, **warm.as_dict()},
            sys.stdout,
            indent=2,
        )
        print()
        return 0
    print(report.summary())
    print(result.summary())
    print(f"warm-up: {warm.summary()}, not counted in the replay's speed")
    if args.rrd:
        print(f"recording written to {args.rrd} (open it with: rerun {args.rrd})")
    if args.out:
        print(f"estimates written to {args.out}")
    return 0
