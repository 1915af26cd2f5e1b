"""Figures of merit for a localizer's run against the truth: pure numpy on arrays, no simulation inside.

    from mcl.tools.evaluation import evaluate, pool_counts
    figures = evaluate(times, truth, estimates, quality, lost, windows=[(t0, t1)])

Inputs, one row per truth sample (100 Hz): `times` (M,) [s], `truth` and `estimates` (M, 3) poses (x, y, θ);
estimates taken at other times are put on the truth's grid with `hold_last`. `quality` (M,) codes
(`QUALITY_CODE`: SUPERB 0, OKAY 1, POOR 2, UNSURE_HALF 3, as `quality_codes` makes them from `Quality`
members), `lost` (M,)
bools (`Localizer.is_lost`), `windows` the events' (start, end) times.

What each figure means (the thresholds are the module's constants):
- position error, heading error (wrapped to [0, π]);
- mirrored: within 0.5 m and 45° of the mirrored truth (−x, −y, θ+π) but not within 0.5 m and 45° of the truth;
- failed: position error > 0.5 m, or mirrored; `fail_share` is the failed share of the samples;
- (re)converged: the start of the first stretch of at least 1 s with position error < 0.3 m and heading error
  < 20°, in seconds after the start (t = 0) or after an event window's end; inf when there is none ("never");
- on the mirror: the run holds a stretch of at least 2 s that is mirrored throughout; `mirrored_share` is the
  mirrored share of the samples;
- tracking RMSE: position and heading RMSE over the samples that have not failed;
- quality: per level, how many samples are at that level and how many of them have a position error > 0.5 m
  (the level's "wrong" share); SUPERB coverage: of the samples within 0.3 m, the share that are SUPERB;
- lost recall: samples inside an episode of more than 2 s with position error > 1 m, counted from 2 s after
  the episode starts, and how many of them are `lost`; lost false alarms: samples within 0.3 m, and how many of
  them are `lost`.
Counts are kept as (hits, of) pairs so that a family's or a battery's figures pool its runs' samples.
"""

from __future__ import annotations

import math

import numpy as np

from field.angles import wrap_angles
from mcl.localizer import Quality

QUALITY_LEVELS = (Quality.SUPERB, Quality.OKAY, Quality.POOR, Quality.UNSURE_HALF)
QUALITY_CODE = {level: code for code, level in enumerate(QUALITY_LEVELS)}
FAIL_POSITION = 0.5  # m
MIRROR_POSITION = 0.5  # m
MIRROR_HEADING = math.radians(45.0)
CONVERGED_POSITION = 0.3  # m
CONVERGED_HEADING = math.radians(20.0)
CONVERGED_HOLD = 1.0  # s
ON_MIRROR_HOLD = 2.0  # s
WRONG_POSITION = 0.5  # m, a quality level's "wrong" samples
TRACKED_POSITION = 0.3  # m, the samples SUPERB coverage and false alarms count
LOST_POSITION = 1.0  # m
LOST_EPISODE = 2.0  # s
_EPS = 1e-9


def quality_codes(levels) -> np.ndarray:
    """(M,) int8 codes of a sequence of `Quality` members (SUPERB 0, OKAY 1, POOR 2, UNSURE_HALF 3)."""
    return np.fromiter((QUALITY_CODE[level] for level in levels), dtype=np.int8)


def hold_last(grid_times, times, values) -> np.ndarray:
    """`values` (N, ...) taken at increasing `times` (N,), held at their last value onto `grid_times` (M,):
    row m is the last value taken at or before grid_times[m] (NaN before the first)."""
    grid_times = np.asarray(grid_times, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    index = np.searchsorted(np.asarray(times, dtype=np.float64), grid_times + _EPS, side="right") - 1
    out = values[np.maximum(index, 0)].copy()
    out[index < 0] = np.nan
    return out


def pose_errors(truth, estimates) -> tuple[np.ndarray, np.ndarray]:
    """Position error [m] and absolute heading error [rad, wrapped to 0..π], (M,) each."""
    truth = np.asarray(truth, dtype=np.float64)
    estimates = np.asarray(estimates, dtype=np.float64)
    position = np.hypot(estimates[:, 0] - truth[:, 0], estimates[:, 1] - truth[:, 1])
    heading = np.abs(wrap_angles(estimates[:, 2] - truth[:, 2]))
    return position, heading


def near(truth, estimates, position: float, heading: float) -> np.ndarray:
    """(M,) whether each estimate is within `position` m and `heading` rad of the truth."""
    p, h = pose_errors(truth, estimates)
    return (p < position) & (h < heading)


def mirrored(truth, estimates) -> np.ndarray:
    """(M,) near the mirrored truth (−x, −y, θ+π) and not near the truth (0.5 m and 45° each)."""
    truth = np.asarray(truth, dtype=np.float64)
    image = np.column_stack([-truth[:, 0], -truth[:, 1], wrap_angles(truth[:, 2] + math.pi)])
    return near(image, estimates, MIRROR_POSITION, MIRROR_HEADING) & ~near(
        truth, estimates, MIRROR_POSITION, MIRROR_HEADING
    )


def failed(truth, estimates) -> np.ndarray:
    """(M,) position error > 0.5 m, or mirrored."""
    position, _ = pose_errors(truth, estimates)
    return (position > FAIL_POSITION) | mirrored(truth, estimates)


def sample_period(times) -> float:
    """The truth grid's spacing [s] (the median step; 0.01 for fewer than two samples)."""
    times = np.asarray(times, dtype=np.float64)
    return float(np.median(np.diff(times))) if times.shape[0] > 1 else 0.01


def runs_of(mask) -> tuple[np.ndarray, np.ndarray]:
    """Maximal stretches of True in `mask`: (starts, ends) index arrays, each stretch is [start, end)."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(m[1:] != m[:-1])
    return edges[0::2], edges[1::2]


def has_stretch(times, mask, seconds: float) -> bool:
    """Whether `mask` holds a stretch of True samples lasting at least `seconds` (samples × the period)."""
    starts, ends = runs_of(mask)
    return bool(((ends - starts) * sample_period(times) >= seconds - _EPS).any())


def first_stretch(times, mask, since: float = 0.0, seconds: float = CONVERGED_HOLD) -> float:
    """Seconds from `since` to the start of the first stretch of True samples (among those at or after
    `since`) that lasts at least `seconds`; inf when there is none. A stretch that begins before `since`
    counts from `since` on."""
    times = np.asarray(times, dtype=np.float64)
    first = int(np.searchsorted(times, since - _EPS, side="left"))
    period = sample_period(times)
    starts, ends = runs_of(np.asarray(mask, dtype=bool)[first:])
    long_enough = np.flatnonzero((ends - starts) * period >= seconds - _EPS)
    if not long_enough.size:
        return math.inf
    return float(max(times[first + starts[long_enough[0]]] - since, 0.0))


def convergence_time(times, position_error, heading_error, since: float = 0.0) -> float:
    """Seconds from `since` until the first stretch of >= 1 s with error < 0.3 m and < 20° starts (inf: never)."""
    good = (np.asarray(position_error) < CONVERGED_POSITION) & (np.asarray(heading_error) < CONVERGED_HEADING)
    return first_stretch(times, good, since, CONVERGED_HOLD)


def tracking_rmse(position_error, heading_error, fail) -> tuple[float | None, float | None]:
    """Position [m] and heading [rad] RMSE over the samples that have not failed (None: every sample failed)."""
    ok = ~np.asarray(fail, dtype=bool)
    if not ok.any():
        return None, None
    p = np.asarray(position_error)[ok]
    h = np.asarray(heading_error)[ok]
    return float(np.sqrt(np.mean(p * p))), float(np.sqrt(np.mean(h * h)))


def quality_counts(quality, position_error) -> dict:
    """Per level name: {"steps": samples at the level, "wrong": of them with error > 0.5 m}; and
    "superb_coverage": {"steps": samples within 0.3 m, "superb": of them SUPERB}."""
    quality = np.asarray(quality)
    wrong = np.asarray(position_error) > WRONG_POSITION
    out = {}
    for level in QUALITY_LEVELS:
        at = quality == QUALITY_CODE[level]
        out[level.name] = {"steps": int(at.sum()), "wrong": int((at & wrong).sum())}
    tracked = np.asarray(position_error) < TRACKED_POSITION
    out["superb_coverage"] = {
        "steps": int(tracked.sum()),
        "superb": int((tracked & (quality == QUALITY_CODE[Quality.SUPERB])).sum()),
    }
    return out


def lost_episodes(times, position_error) -> np.ndarray:
    """(M,) the samples `is_lost` should flag: inside a stretch of more than 2 s with error > 1 m, from 2 s
    after the stretch starts (its first sample counts as 0 s)."""
    period = sample_period(times)
    due = np.zeros(np.asarray(position_error).shape[0], dtype=bool)
    starts, ends = runs_of(np.asarray(position_error) > LOST_POSITION)
    delay = int(math.ceil(LOST_EPISODE / period - 1e-6))
    for start, end in zip(starts, ends):
        if (end - start) * period > LOST_EPISODE + _EPS:
            due[start + delay : end] = True
    return due


def lost_counts(times, position_error, lost) -> dict:
    """{"recall": {"steps": samples due (see `lost_episodes`), "lost": of them lost},
    "false_alarm": {"steps": samples within 0.3 m, "lost": of them lost}}."""
    lost = np.asarray(lost, dtype=bool)
    due = lost_episodes(times, position_error)
    calm = np.asarray(position_error) < TRACKED_POSITION
    return {
        "recall": {"steps": int(due.sum()), "lost": int((due & lost).sum())},
        "false_alarm": {"steps": int(calm.sum()), "lost": int((calm & lost).sum())},
    }


def share(hits: int, of: int) -> float | None:
    """hits / of, None when there is nothing to count."""
    return hits / of if of else None


def evaluate(times, truth, estimates, quality, lost, windows=()) -> dict:
    """Every figure of one run (see the module docstring). Times in seconds, angles in radians; "never"
    is inf. Keys: converge_s, reconverge_s (the worst over `windows`; None without windows),
    reconverge_each_s, fail_share, mirrored_share, on_mirror, rmse_position_m, rmse_heading_rad,
    quality (`quality_counts`), lost (`lost_counts`), samples."""
    times = np.asarray(times, dtype=np.float64)
    truth = np.asarray(truth, dtype=np.float64)
    estimates = np.asarray(estimates, dtype=np.float64)
    if truth.shape != estimates.shape or truth.ndim != 2 or truth.shape[1] != 3 or times.shape != truth.shape[:1]:
        raise ValueError(
            f"times {times.shape}, truth {truth.shape} and estimates {estimates.shape} must be (M,), (M, 3) and (M, 3)"
        )
    position, heading = pose_errors(truth, estimates)
    mirror = mirrored(truth, estimates)
    fail = (position > FAIL_POSITION) | mirror
    each = [convergence_time(times, position, heading, since=end) for _, end in windows]
    rmse_p, rmse_h = tracking_rmse(position, heading, fail)
    return {
        "samples": int(times.shape[0]),
        "converge_s": convergence_time(times, position, heading, since=0.0),
        "reconverge_s": max(each) if each else None,
        "reconverge_each_s": each,
        "fail_share": float(fail.mean()),
        "mirrored_share": float(mirror.mean()),
        "on_mirror": has_stretch(times, mirror, ON_MIRROR_HOLD),
        "rmse_position_m": rmse_p,
        "rmse_heading_rad": rmse_h,
        "quality": quality_counts(quality, position),
        "lost": lost_counts(times, position, lost),
    }


def pool_counts(figures) -> dict:
    """The quality and lost counts of several runs' `evaluate` results, summed, with their shares:
    {"SUPERB"/"OKAY"/"POOR": {"steps", "wrong", "share"}, "superb_coverage": {"steps", "superb", "share"},
    "recall": {"steps", "lost", "share"}, "false_alarm": {"steps", "lost", "share"}}."""
    figures = list(figures)
    out: dict = {}
    for key, hit in [(level.name, "wrong") for level in QUALITY_LEVELS] + [("superb_coverage", "superb")]:
        steps = sum(f["quality"][key]["steps"] for f in figures)
        hits = sum(f["quality"][key][hit] for f in figures)
        out[key] = {"steps": steps, hit: hits, "share": share(hits, steps)}
    for key in ("recall", "false_alarm"):
        steps = sum(f["lost"][key]["steps"] for f in figures)
        hits = sum(f["lost"][key]["lost"] for f in figures)
        out[key] = {"steps": steps, "lost": hits, "share": share(hits, steps)}
    return out


def median_worst(values, worst=max) -> tuple[float | None, float | None, int]:
    """(median, worst, count) of the values that are not None (inf counts as a value: "never");
    (None, None, 0) for none."""
    kept = [float(v) for v in values if v is not None]
    if not kept:
        return None, None, 0
    return float(np.median(kept)), float(worst(kept)), len(kept)
