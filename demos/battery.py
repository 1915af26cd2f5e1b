"""`robocup-mcl eval`: the localizer on a battery of scenarios it was not tuned on.

    robocup-mcl eval [--families tracking,kidnap,...] [--split train|holdout|both] [--seeds 10]
                     [--duration 60] [--particles 500] [--jobs 2] [--team auto|on|off] [--progress] [--json]
                     [--save PATH]

Each family (see `demos.battery_sim`) is run on K seeds per split: training seeds 0..K-1 (tune on these),
held-out seeds 1000..1000+K-1 (report on these; the default). Every run is simulated independently of the
filter, then driven through `mcl.localizer.Localizer` as a team's code drives it: its defaults and
`--particles` particles, started with `anywhere_in_own_half()`; per 100 Hz step `motion(t, odometry)`, then
the step's game events (`penalty_return()`, `manual_placement()`, `fallen()`, `got_up()`), then every camera
frame that arrived during the step, `observe(detections, capture_time=)` (a frame captured before the last
reset is refused by the localizer and counted as dropped); then the pose, quality and `is_lost` are sampled.

The table per family (figures defined in `mcl.tools.evaluation`), median and worst over the runs:
- converge [s]: from t = 0 to the first second-long stretch within 0.3 m and 20°; "never" counts the runs
  without one (start_unknown's figure of interest);
- reconverge [s]: the same, from the end of the event (kidnapping, placement, collision, getting up, the last
  burst's or the blackout's end; the worst over a run's windows); for collisions also over the stuck runs
  whose odometry ran at least 0.5 m ahead;
- fail share: the share of time with position error > 0.5 m or on the mirrored pose; mirrored share: on the
  mirrored pose (−x, −y, θ+π) only; on mirror: runs that held the mirrored pose for 2 s or more;
- RMSE position [m] and heading [°]: over the samples that have not failed;
- pooled over the family's samples: for SUPERB, OKAY and POOR, the share of samples at that level with error
  > 0.5 m (quality says it is good when it is not); SUPERB coverage: the share of samples within 0.3 m that
  are SUPERB; lost recall: of the samples 2 s into an episode of > 2 s with error > 1 m, the share flagged
  `is_lost`; lost false alarms: of the samples within 0.3 m, the share flagged `is_lost`.
The overall section pools the quality and lost figures of every run. `--json` writes everything to stdout
(each run's figures and drawn parameters, the family aggregates); `--save PATH` writes the same to a file.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, fields
from multiprocessing import get_context

import numpy as np

from field import spl
from mcl.localizer import Localizer, Quality, QualityThresholds
from mcl.profile import Profile
from mcl.relocalization import RelocalizationPrior, SoccerRelocalization
from mcl.rivals import RivalSettings
from mcl.tools.evaluation import (
    CONVERGED_HEADING,
    CONVERGED_POSITION,
    FAIL_POSITION,
    QUALITY_CODE,
    QUALITY_LEVELS,
    evaluate,
    first_stretch,
    lost_episodes,
    median_worst,
    mirrored,
    pool_counts,
    pose_errors,
)
from motion_models import MotionInput
from sensing import LandmarkSensorModel
from sensing.view import CameraView

from .battery_sim import FAMILIES, BatteryRun, kidnap_mirror_log_odds, simulate
from .team_sim import deliveries

TRAIN_FIRST = 0
HOLDOUT_FIRST = 1000
SPLITS = ("train", "holdout")
MAX_SEEDS = HOLDOUT_FIRST - TRAIN_FIRST  # keeps the two splits disjoint
STRONG_EXCESS = 0.5  # m: collisions whose odometry ran this far ahead, reported apart
MIRROR_CLEAR = 2.0  # odds of truth against mirror that count as telling them apart
CORRECT_HOLD = 2.0  # s of correct tracking that end an even kidnapping's recovery
UNSURE_AFTER = 2.0  # s after a kidnapping from which the quality must doubt the half
END_HOLD = 1.0  # s: a run ends on the mirror when its last second is mirrored


def split_seeds(split: str, k: int) -> list[int]:
    """The K seeds of a split: train 0..K-1, holdout 1000..1000+K-1."""
    if split not in SPLITS:
        raise ValueError(f"split = {split!r} must be one of {', '.join(SPLITS)}")
    first = TRAIN_FIRST if split == "train" else HOLDOUT_FIRST
    return list(range(first, first + k))


def quality_thresholds(values: dict) -> QualityThresholds:
    """`QualityThresholds(**values)`, where a name "rivals.NAME" sets a number of its `RivalSettings`."""
    rivals = {name.partition(".")[2]: v for name, v in values.items() if name.startswith("rivals.")}
    own = {name: v for name, v in values.items() if not name.startswith("rivals.")}
    return QualityThresholds(**own, **({"rivals": RivalSettings(**rivals)} if rivals else {}))


def make_localizer(
    field,
    seed: int,
    particles: int = 500,
    prior: dict | None = None,
    quality: dict | None = None,
    sensor: dict | None = None,
    profile: Profile | None = None,
) -> Localizer:
    """The localizer under test: `Localizer` with its defaults (or `profile`'s settings), except the
    `RelocalizationPrior`, `QualityThresholds` and `LandmarkSensorModel` fields named in `prior`, `quality` and
    `sensor` (for measuring variants; the report says so). `particles` wins over the profile's."""
    options = profile.localizer_options(field) if profile is not None else {}
    base = profile.sections if profile is not None else {}
    if prior:
        options["relocalization"] = SoccerRelocalization(
            RelocalizationPrior(**{**base.get("relocalization", {}), **prior})
        )
    if quality:
        options["quality"] = quality_thresholds(
            {
                **base.get("quality", {}),
                **{f"rivals.{name}": value for name, value in base.get("rivals", {}).items()},
                **quality,
            }
        )
    if sensor:
        options["sensor_model"] = LandmarkSensorModel(field, **{**base.get("sensor", {}), **sensor})
    options.update(n_particles=particles, seed=seed)
    return Localizer(field, **options)


def camera_view(run: BatteryRun, frame) -> CameraView:
    """The frame's view as the robot knows it: its head's pan at capture, its camera's field of view and its
    vision's range limits (the run's drawn camera)."""
    p = run.params
    return CameraView(frame.head, 0.5 * math.radians(p["fov_deg"]), p["max_range"], p["min_range"])


def localize(
    run: BatteryRun,
    particles: int = 500,
    prior: dict | None = None,
    quality: dict | None = None,
    view: bool = False,
    sensor: dict | None = None,
    profile: Profile | None = None,
    filter_seed: int | None = None,
    team: bool | None = None,
) -> dict:
    """Drive a `Localizer` through the run (see the module docstring); returns estimates (T, 3), quality
    codes (T,), lost (T,), dropped frames, the log evidence of the frames used (`Localizer.log_evidence`, and
    how many), the steps at which the team's evidence changed the robot's side, and the seconds the loop took.
    The filter's seed is `filter_seed`, by default the run's seed. team: feed the teammates' messages and the
    robot's ball sightings (`Localizer.team_message`, `observe(..., ball=)`); None: when the run's messages are
    on (the team families). With True in a family whose messages are off, the messages its team world sent and
    did not lose are delivered (`team_deliveries`)."""
    loc = make_localizer(
        run.field, run.seed if filter_seed is None else filter_seed, particles, prior, quality, sensor, profile
    )
    if team is None:
        team = bool(run.params.get("team", {}).get("messages_on", False))
    loc.anywhere_in_own_half()
    n = run.times.shape[0]
    frames_at: dict[int, list] = {}
    balls = run.ball_detections if team and run.ball_detections else (None,) * len(run.frames)
    for frame, ball in zip(run.frames, balls):
        frames_at.setdefault(frame.arrival_step, []).append((frame, ball))
    messages_at: dict[int, list] = {}
    for step, message in team_deliveries(run) if team else ():
        messages_at.setdefault(step, []).append(message)
    flips: list[int] = []
    calls_at: dict[int, list] = {}
    for call in run.calls:
        calls_at.setdefault(call.step, []).append(getattr(loc, call.name))
    estimates = np.empty((n, 3))
    quality = np.empty(n, dtype=np.int8)
    lost = np.empty(n, dtype=bool)
    codes = QUALITY_CODE
    dropped = 0
    dt = run.dt
    times = run.times.tolist()
    odometry = [tuple(row) for row in run.odometry.tolist()]
    started = time.perf_counter()
    for k in range(n):
        changed = loc.counts["side changed by the team"]  # a side change comes with a report, or as time passes
        loc.motion(times[k], MotionInput(dt, odometry=odometry[k]))
        for call in calls_at.get(k, ()):
            call()
        for frame, ball in frames_at.get(k, ()):
            try:
                loc.observe(
                    frame.observations,
                    capture_time=frame.capture_time,
                    view=camera_view(run, frame) if view else None,
                    ball=ball,
                )
            except ValueError:
                dropped += 1  # captured before the last reset (the localizer refuses it)
        if team:
            for message in messages_at.get(k, ()):
                try:
                    loc.team_message(message)
                except ValueError:
                    dropped += 1  # sent before the localizer's past window (a very late message)
        if loc.counts["side changed by the team"] != changed:
            flips.append(k)
        estimates[k] = loc.pose().pose
        quality[k] = codes[loc.quality()]
        lost[k] = loc.is_lost
    return {
        "estimates": estimates,
        "quality": quality,
        "lost": lost,
        "dropped_frames": dropped,
        "log_evidence": loc.log_evidence,
        "evidence_frames": loc.evidence_frames,
        "team_flips": flips,
        "team": team,
        "loop_s": time.perf_counter() - started,
    }


def team_deliveries(run: BatteryRun) -> tuple:
    """The run's (arrival step, TeamMessage) deliveries: its own when its messages are on, else those its team
    world sent and did not lose (for feeding the team to a family that runs without it: a variant)."""
    if run.messages or run.team is None:
        return run.messages
    return deliveries(run.team.sent, run.times.shape[0])


@functools.lru_cache(maxsize=256)
def _simulated(family: str, seed: int, duration: float) -> BatteryRun:
    """A run, simulated once per process (a tuning study's workers localize each run many times)."""
    return simulate(family, seed, duration)


@dataclass(frozen=True)
class BatteryCase:
    """A battery run as a case of `robocup-mcl tune` (`mcl.tools.tuning`): the run of `family` and `seed`, `duration`
    seconds long, localized with a parameter set as the battery localizes it (game events included)."""

    family: str
    seed: int
    duration: float = 60.0

    @property
    def label(self) -> str:
        """ "family/seed"."""
        return f"{self.family}/{self.seed}"

    def evaluate(self, values: dict, seed: int, particles: int = 500) -> dict:
        """The figures of the parameter set `values` ({"section.setting": value}) with filter seed `seed`:
        "log_evidence", "evidence_frames" and the truth's (`mcl.tools.tuning.truth_figures`)."""
        from mcl.tools.tuning import truth_figures

        run = _simulated(self.family, self.seed, float(self.duration))
        out = localize(run, particles, profile=Profile.from_values(values), filter_seed=seed)
        return {
            "log_evidence": float(out["log_evidence"]),
            "evidence_frames": int(out["evidence_frames"]),
            "truth": truth_figures(run.times, run.truth, out["estimates"], out["quality"], out["lost"], run.windows),
        }


def _jsonable(value):
    """Plain JSON data: inf/NaN become None, numpy scalars Python numbers, tuples lists."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def kidnap_class(log_odds: float | None) -> str:
    """A kidnapping by what the robot could know (the simulator's own law, `kidnap_mirror_log_odds`): "clear"
    when the truth is at least MIRROR_CLEAR times as probable as its mirror image, "mirror" when the mirror
    image is that much more probable, "even" in between."""
    odds = math.inf if log_odds is None else log_odds  # (JSON has no infinity: certain, the mirror undrawable)
    return "clear" if odds >= math.log(MIRROR_CLEAR) else "mirror" if odds <= -math.log(MIRROR_CLEAR) else "even"


def side_figures(run: BatteryRun, out: dict) -> dict:
    """The figures of the field's symmetry for one run: for a kidnapping, the seconds from its end until
    `CORRECT_HOLD` seconds of correct tracking (within 0.3 m and 20°) are complete, and, of the steps from
    `UNSURE_AFTER` seconds after it that are on the mirror, how many the quality flagged (UNSURE_HALF or lost);
    for every run, the side changes made by the team's evidence and how many of them went from the right pose
    to the mirror image."""
    position, heading = pose_errors(run.truth, out["estimates"])
    mirror = mirrored(run.truth, out["estimates"])
    flips = out["team_flips"]
    last = run.times >= run.times[-1] - END_HOLD + 1e-9
    figures = {
        "team": out["team"],
        "team_flips": len(flips),
        "ends_on_mirror": bool(mirror[last].all()),
        # a flip from the right pose onto the mirror image (near the centre mark the two overlap: not one)
        "flips_to_mirror": sum(
            1
            for k in flips
            if k > 0
            and position[k - 1] <= FAIL_POSITION
            and not mirror[k - 1]
            and mirror[k]
            and position[k] > FAIL_POSITION
        ),
    }
    if run.params["event"]["type"] in ("kidnap", "kidnap_special") and run.windows:
        end = run.windows[0][1]
        good = (position < CONVERGED_POSITION) & (heading < CONVERGED_HEADING)
        figures["correct_2s_s"] = first_stretch(run.times, good, end, CORRECT_HOLD) + CORRECT_HOLD
        due = mirror & (run.times >= end + UNSURE_AFTER)
        unsure = out["quality"] == QUALITY_CODE[Quality.UNSURE_HALF]
        doubted = unsure | out["lost"]
        figures["mirror_steps"] = int(due.sum())
        figures["mirror_steps_doubted"] = int((due & doubted).sum())
        # the steps `is_lost` should have flagged and did not, split by what the quality said instead: on the
        # mirror image and UNSURE_HALF (the pose known up to the field's symmetry, which is not lost), or not
        missed = lost_episodes(run.times, position) & ~out["lost"]
        figures["recall_missed"] = int(missed.sum())
        figures["recall_missed_mirror_unsure"] = int((missed & mirror & unsure).sum())
    return figures


def run_case(
    family: str,
    seed: int,
    duration: float = 60.0,
    particles: int = 500,
    prior: dict | None = None,
    quality: dict | None = None,
    view: bool = False,
    sensor: dict | None = None,
    profile: Profile | None = None,
    filter_seed: int | None = None,
    team: bool | None = None,
) -> dict:
    """Simulate one run, localize it, and return its figures (JSON-ready; "never" is None). view: pass each
    frame's camera view to `observe` (`camera_view`); profile, filter_seed, team: as `localize`."""
    run = simulate(family, seed, duration)
    out = localize(run, particles, prior, quality, view, sensor, profile, filter_seed, team)
    figures = evaluate(run.times, run.truth, out["estimates"], out["quality"], out["lost"], run.windows)
    figures.update(side_figures(run, out))
    heading = figures.pop("rmse_heading_rad")
    figures["rmse_heading_deg"] = None if heading is None else math.degrees(heading)
    event = run.params["event"]
    figures["kidnap_log_odds"] = kidnap_mirror_log_odds(run.field, event)
    if figures["kidnap_log_odds"] is not None:
        figures["kidnap_class"] = kidnap_class(figures["kidnap_log_odds"])
    figures.update(
        {
            "family": family,
            "seed": seed,
            "field": run.field.name,
            "event": event["type"],
            "excess_m": event.get("excess"),
            "windows": run.windows,
            "frames": len(run.frames),
            "dropped_frames": out["dropped_frames"],
            "loop_s": out["loop_s"],
            "log_evidence": out["log_evidence"],
            "evidence_frames": out["evidence_frames"],
            "params": run.params,
        }
    )
    return _jsonable(figures)


def _never(value) -> float:
    return math.inf if value is None else value


def summarize_family(runs: list[dict]) -> dict:
    """A family's aggregates over its runs (medians, worsts, counts, pooled quality and lost figures)."""
    out: dict = {"runs": len(runs), "fields": {}}
    for r in runs:
        out["fields"][r["field"]] = out["fields"].get(r["field"], 0) + 1

    def times(rows, key):
        values = [_never(r[key]) for r in rows if key in r and not (key == "reconverge_s" and not r["windows"])]
        median, worst, count = median_worst(values)
        return {"median": median, "worst": worst, "never": sum(v == math.inf for v in values), "runs": count}

    out["converge_s"] = times(runs, "converge_s")
    out["reconverge_s"] = times(runs, "reconverge_s")
    strong = [r for r in runs if r.get("excess_m") is not None and r["excess_m"] >= STRONG_EXCESS]
    if any(r.get("excess_m") is not None for r in runs):
        out["reconverge_strong_excess_s"] = times(strong, "reconverge_s")
    for key in ("fail_share", "mirrored_share", "rmse_position_m", "rmse_heading_deg"):
        median, worst, count = median_worst([r[key] for r in runs])
        out[key] = {"median": median, "worst": worst, "runs": count}
    out["on_mirror"] = sum(bool(r["on_mirror"]) for r in runs)
    kidnaps = [r for r in runs if r.get("event") in ("kidnap", "kidnap_special")]
    if kidnaps:
        # The kidnappings by what the robot could know (`kidnap_class`); of each class, how many runs ended on
        # the mirror, its own pooled quality and lost figures, and how long until 2 s of correct tracking.
        out["kidnap_odds"] = {}
        for key in ("clear", "even", "mirror"):
            members = [r for r in kidnaps if kidnap_class(r.get("kidnap_log_odds")) == key]
            median, worst, count = median_worst([_never(r.get("correct_2s_s")) for r in members])
            out["kidnap_odds"][key] = {
                "runs": len(members),
                "on_mirror": sum(bool(r["on_mirror"]) for r in members),
                "ends_on_mirror": sum(bool(r.get("ends_on_mirror")) for r in members),
                "pooled": pool_counts(members),
                "correct_2s_s": {
                    "median": median,
                    "worst": worst,
                    "runs": count,
                    "never": sum(_never(r.get("correct_2s_s")) == math.inf for r in members),
                },
                "mirror_steps": sum(r.get("mirror_steps", 0) for r in members),
                "mirror_steps_doubted": sum(r.get("mirror_steps_doubted", 0) for r in members),
                "recall_missed": sum(r.get("recall_missed", 0) for r in members),
                "recall_missed_mirror_unsure": sum(r.get("recall_missed_mirror_unsure", 0) for r in members),
            }
    out["team_runs"] = sum(bool(r.get("team")) for r in runs)
    out["team_flips"] = sum(r.get("team_flips", 0) for r in runs)
    out["flips_to_mirror"] = sum(r.get("flips_to_mirror", 0) for r in runs)
    # the quality's promise holds in every run, not only over all of them: the worst run's wrong share per level
    out["wrong_by_run"] = {}
    for level in ("SUPERB", "OKAY"):
        shares = [
            r["quality"][level]["wrong"] / r["quality"][level]["steps"] for r in runs if r["quality"][level]["steps"]
        ]
        out["wrong_by_run"][level] = {
            "worst": max(shares) if shares else None,
            "runs": len(shares),
            "over_1": sum(v > 0.01 for v in shares),
            "over_5": sum(v > 0.05 for v in shares),
        }
    out["pooled"] = pool_counts(runs)
    out["dropped_frames"] = sum(r["dropped_frames"] for r in runs)
    return out


def _percent(value) -> str:
    return "–" if value is None else f"{100 * value:.1f} %"


def share_text(hits: int, of: int) -> str:
    return "–" if not of else f"{100 * hits / of:.1f} %"


def format_family(name: str, s: dict) -> list[str]:
    """The table of one family's aggregates (`summarize_family`), as lines."""
    fields = ", ".join(f"{f} {n}" for f, n in sorted(s["fields"].items()))
    lines = [f"{name} ({s['runs']} runs: {fields})", f"  {'':<34}{'median':>10}{'worst':>10}   never"]

    def row_times(label, t):
        if not t["runs"]:
            lines.append(f"  {label:<34}{'–':>10}{'–':>10}")
            return
        lines.append(f"  {label:<34}{_fmt_time(t['median']):>10}{_fmt_time(t['worst']):>10}   {t['never']}/{t['runs']}")

    def row_values(label, v, fmt):
        if not v["runs"]:
            lines.append(f"  {label:<34}{'–':>10}{'–':>10}")
            return
        lines.append(f"  {label:<34}{fmt(v['median']):>10}{fmt(v['worst']):>10}")

    row_times("converge from start [s]", s["converge_s"])
    row_times("reconverge after event [s]", s["reconverge_s"])
    if "reconverge_strong_excess_s" in s:
        row_times(f"  stuck, odometry ≥ {STRONG_EXCESS} m ahead [s]", s["reconverge_strong_excess_s"])
    row_values("fail share", s["fail_share"], _percent)
    row_values("mirrored share", s["mirrored_share"], _percent)
    lines.append(f"  {'runs on the mirror (≥ 2 s)':<34}{s['on_mirror']:>10}")
    if "kidnap_odds" in s:
        k = s["kidnap_odds"]
        lines.append(
            f"    {'split by the kidnap law odds:':<32}truth ≥ {MIRROR_CLEAR:g}:1 {k['clear']['on_mirror']}/"
            f"{k['clear']['runs']}, even {k['even']['on_mirror']}/{k['even']['runs']}, mirror ≥ "
            f"{MIRROR_CLEAR:g}:1 {k['mirror']['on_mirror']}/{k['mirror']['runs']}"
        )
        clear, even = k["clear"], k["even"]
        if clear["runs"]:
            lines.append(
                f"    {'clear kidnaps: lost recall':<32}{_percent(clear['pooled']['recall']['share']):>10}"
                f"   false alarms {_percent(clear['pooled']['false_alarm']['share'])}"
            )
            lines.append(
                f"    {'clear: missed, mirror & unsure':<32}"
                f"{share_text(clear['recall_missed_mirror_unsure'], clear['recall_missed']):>10}   of "
                f"{clear['recall_missed']} missed steps (on the mirror image, UNSURE_HALF)"
            )
        if even["runs"]:
            lines.append(
                f"    {'even kidnaps: end on the mirror':<32}{even['ends_on_mirror']:>10}   of {even['runs']} "
                f"(the last {END_HOLD:g} s mirrored)"
            )
            c = even["correct_2s_s"]
            doubted = share_text(even["mirror_steps_doubted"], even["mirror_steps"])
            lines.append(
                f"    {'even kidnaps: to 2 s correct [s]':<32}{_fmt_time(c['median']):>10}"
                f"{_fmt_time(c['worst']):>10}   {c['never']}/{c['runs']}"
            )
            lines.append(
                f"    {'even: on the mirror, doubted':<32}{doubted:>10}   of {even['mirror_steps']} steps "
                f"(UNSURE_HALF or lost, from {UNSURE_AFTER:g} s after)"
            )
    if s.get("team_runs"):
        lines.append(
            f"  {'side changes by the team':<34}{s['team_flips']:>10}   to the mirror: "
            f"{s['flips_to_mirror']} ({s['team_runs']} runs with messages)"
        )
    for level, limit in (("SUPERB", "over_1"), ("OKAY", "over_5")):
        w = s["wrong_by_run"][level]
        lines.append(
            f"  {level + ' wrong, worst run':<34}{_percent(w['worst']):>10}   runs over "
            f"{'1' if limit == 'over_1' else '5'} %: {w[limit]}/{w['runs']}"
        )
    row_values("tracking RMSE position [m]", s["rmse_position_m"], lambda v: f"{v:.3f}")
    row_values("tracking RMSE heading [°]", s["rmse_heading_deg"], lambda v: f"{v:.1f}")
    lines += _pooled_lines(s["pooled"])
    return lines


def _fmt_time(value) -> str:
    return "never" if value is None or value == math.inf else f"{value:.2f}"


def _pooled_lines(p: dict) -> list[str]:
    lines = []
    for level in QUALITY_LEVELS:
        q = p[level.name]
        lines.append(f"  {level.name + ' wrong (err > 0.5 m)':<34}{_percent(q['share']):>10}   of {q['steps']} steps")
    c = p["superb_coverage"]
    lines.append(f"  {'SUPERB coverage (of err < 0.3 m)':<34}{_percent(c['share']):>10}   of {c['steps']} steps")
    r = p["recall"]
    lines.append(f"  {'lost recall (err > 1 m, > 2 s)':<34}{_percent(r['share']):>10}   of {r['steps']} steps")
    f = p["false_alarm"]
    lines.append(f"  {'lost false alarms (err < 0.3 m)':<34}{_percent(f['share']):>10}   of {f['steps']} steps")
    return lines


def run_battery(
    families,
    splits,
    k: int,
    duration: float = 60.0,
    particles: int = 500,
    jobs: int = 2,
    progress: bool = False,
    prior: dict | None = None,
    quality: dict | None = None,
    view: bool = False,
    sensor: dict | None = None,
    profile: Profile | None = None,
    team: bool | None = None,
) -> dict:
    """Run every family × split × seed; returns the results (JSON-ready): per split, per family, the runs
    (sorted by seed) and their summary, and the overall pooled figures. view, profile: as `run_case`."""
    cases = [(split, family, seed) for split in splits for seed in split_seeds(split, k) for family in families]
    from mcl.tools.cli_checks import progress_bar

    bar = progress_bar(enabled=progress, total=len(cases), desc="eval", unit="run")
    results: dict = {}
    started = time.perf_counter()

    def keep(case, result):
        split, family, seed = case
        results.setdefault(split, {}).setdefault(family, []).append(result)
        bar.set_postfix_str(f"{family} seed {seed}", refresh=False)
        bar.update(1)

    if jobs <= 1:
        for case in cases:
            keep(
                case, run_case(case[1], case[2], duration, particles, prior, quality, view, sensor, profile, None, team)
            )
    else:
        with ProcessPoolExecutor(max_workers=jobs, mp_context=get_context("spawn")) as pool:
            futures = {
                pool.submit(
                    run_case, family, seed, duration, particles, prior, quality, view, sensor, profile, None, team
                ): (split, family, seed)
                for split, family, seed in cases
            }
            for future in as_completed(futures):
                keep(futures[future], future.result())
    bar.close()
    out: dict = {
        "particles": particles,
        "duration_s": duration,
        "seeds_per_family": k,
        "jobs": jobs,
        "variant": {"prior": dict(prior or {}), "quality": dict(quality or {}), "sensor": dict(sensor or {})},
        "profile": None if profile is None else {"source": profile.source, "values": profile.values()},
        "view": bool(view),
        "team": team,
        "splits": {},
    }
    for split in splits:
        per_family = {}
        everything = []
        for family in families:
            runs = sorted(results[split][family], key=lambda r: r["seed"])
            everything += runs
            per_family[family] = {"summary": summarize_family(runs), "runs": runs}
        out["splits"][split] = {
            "seeds": split_seeds(split, k),
            "families": per_family,
            "overall": {"runs": len(everything), "pooled": pool_counts(everything)},
        }
    out["elapsed_s"] = time.perf_counter() - started
    return _jsonable(out)


def format_report(results: dict) -> str:
    """The printed report: per split, a table per family, then the overall pooled figures."""
    lines = []
    for split, data in results["splits"].items():
        seeds = data["seeds"]
        variant = results.get("variant") or {}
        changed = [
            f"{name}={value}"
            for group in ("prior", "quality", "sensor")
            for name, value in variant.get(group, {}).items()
        ]
        profile = results.get("profile")
        if profile:
            changed = [f"profile {profile['source'] or '(unnamed)'}"] + changed
        setting = f"VARIANT ({', '.join(changed)})" if changed else "Localizer defaults"
        setting += ", frames with their camera view" if results.get("view") else ", detections only (no view)"
        if results.get("team"):
            setting += "; VARIANT: the team's messages and the ball fed in every family (--team on)"
        elif results.get("team") is False:
            setting += "; VARIANT: no team messages in any family (--team off)"
        lines.append(
            f"split {split}: seeds {seeds[0]}–{seeds[-1]} per family, {results['particles']} particles, "
            f"{results['duration_s']:g} s runs, {setting}, start anywhere_in_own_half()"
        )
        lines.append("")
        for family, f in data["families"].items():
            lines += format_family(family, f["summary"])
            lines.append("")
        overall = data["overall"]
        lines.append(f"overall, {split} ({overall['runs']} runs), pooled over every step:")
        lines += _pooled_lines(overall["pooled"])
        lines.append("")
    lines.append(f"total time {results['elapsed_s']:.1f} s ({results['jobs']} jobs)")
    return "\n".join(lines)


def headline(results: dict, split: str) -> dict:
    """Per family, the headline figures of a results file's split: re-convergence median / worst / never
    (event runs), fail share median / worst, runs on the mirror, tracking RMSE medians; and the pooled quality
    figures (`overall`)."""
    data = results["splits"][split]
    out = {}
    for family, f in data["families"].items():
        runs = f["runs"]
        events = [_never(r["reconverge_s"]) for r in runs if r["event"] not in (None, "none")]
        fails = [r["fail_share"] for r in runs]
        positions = [r["rmse_position_m"] for r in runs if r["rmse_position_m"] is not None]
        headings = [r["rmse_heading_deg"] for r in runs if r["rmse_heading_deg"] is not None]
        out[family] = {
            "reconverge_median_s": float(np.median(events)) if events else None,
            "reconverge_worst_s": max(events) if events else None,
            "never": sum(math.isinf(v) for v in events),
            "fail_median": float(np.median(fails)),
            "fail_worst": max(fails),
            "on_mirror": sum(bool(r["on_mirror"]) for r in runs),
            "rmse_position_m": float(np.median(positions)) if positions else None,
            "rmse_heading_deg": float(np.median(headings)) if headings else None,
        }
    pooled = data["overall"]["pooled"]
    out["overall"] = {
        name: pooled[key]["share"]
        for name, key in (
            ("superb_wrong", "SUPERB"),
            ("okay_wrong", "OKAY"),
            ("superb_coverage", "superb_coverage"),
            ("lost_recall", "recall"),
            ("lost_false_alarms", "false_alarm"),
        )
    }
    return out


def format_comparison(base: dict, current: dict, split: str, names=("base", "current")) -> str:
    """Two results files side by side (`--compare`): per family the headline figures, then the quality."""
    a, b = headline(base, split), headline(current, split)

    def seconds(v):
        return "–" if v is None else ("never" if math.isinf(v) else f"{v:.2f}")

    def number(v, scale=1.0, digits=1):
        return "–" if v is None else f"{scale * v:.{digits}f}"

    lines = [
        f"split {split}: {names[0]} | {names[1]}",
        f"{'family':<17} {'reconverge median / worst [s], never':>40} {'fail median / worst':>27} "
        f"{'on mirror':>11} {'RMSE m / °':>23}",
    ]
    for family in a:
        if family == "overall":
            continue
        x, y = a[family], b[family]
        reconverge = (
            f"{seconds(x['reconverge_median_s'])} / {seconds(x['reconverge_worst_s'])}, {x['never']} | "
            f"{seconds(y['reconverge_median_s'])} / {seconds(y['reconverge_worst_s'])}, {y['never']}"
        )
        fail = (
            f"{100 * x['fail_median']:.1f} / {100 * x['fail_worst']:.0f} | "
            f"{100 * y['fail_median']:.1f} / {100 * y['fail_worst']:.0f} %"
        )
        rmse = (
            f"{number(x['rmse_position_m'], digits=3)}/{number(x['rmse_heading_deg'])} | "
            f"{number(y['rmse_position_m'], digits=3)}/{number(y['rmse_heading_deg'])}"
        )
        lines.append(f"{family:<17} {reconverge:>40} {fail:>27} {x['on_mirror']:>4} | {y['on_mirror']:<4} {rmse:>23}")
    lines.append(
        "quality, pooled: "
        + "; ".join(
            f"{name.replace('_', ' ')} {number(a['overall'][name], 100)} | {number(b['overall'][name], 100)} %"
            for name in a["overall"]
        )
    )
    return "\n".join(lines)


def _overrides(parser, option: str, items: list[str], kind, build=None) -> dict:
    """NAME=VALUE strings as a dict of numbers, checked against the dataclass `kind`'s numeric fields by
    building one (`build(**values)`, default `kind(**values)`; exit 2 when wrong)."""

    def numbers(cls) -> dict:
        return {f.name: f for f in fields(cls) if f.init and f.type in (int, float, "int", "float")}

    names = numbers(kind)
    if kind is QualityThresholds:  # and the numbers of its rivals' settings, as rivals.NAME
        names.update({f"rivals.{name}": f for name, f in numbers(RivalSettings).items()})
    out: dict = {}
    for item in items:
        name, _, text = item.partition("=")
        name = name.strip()
        if name not in names or not text:
            parser.error(f"{option} {item!r}: expected NAME=VALUE with NAME one of {', '.join(names)}")
        try:
            value = float(text)
        except ValueError:
            parser.error(f"{option} {item!r}: {text!r} is not a number")
        out[name] = int(value) if names[name].type in (int, "int") and value.is_integer() else value
    try:
        (build or kind)(**out)
    except (TypeError, ValueError) as error:
        parser.error(f"{option}: {error}")
    return out


PROG = "robocup-mcl eval"


def parse_families(parser: argparse.ArgumentParser, text: str) -> list[str]:
    """The families of a comma-separated `--families` value, each once, in the order given; `parser.error`
    (exit 2) for an unknown one or none."""
    families = [f.strip() for f in text.split(",") if f.strip()]
    unknown = [f for f in families if f not in FAMILIES]
    if not families or unknown:
        parser.error(
            f"--families: unknown {', '.join(map(repr, unknown)) or 'empty list'}; choose from {', '.join(FAMILIES)}"
        )
    return list(dict.fromkeys(families))


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, description, positive_int

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument(
        "--families", default=",".join(FAMILIES), help=f"comma-separated, from: {', '.join(FAMILIES)} (default: all)"
    )
    parser.add_argument(
        "--split",
        default="holdout",
        choices=("train", "holdout", "both"),
        help="training seeds 0..K-1, held-out seeds 1000..1000+K-1, or both (default holdout)",
    )
    parser.add_argument("--seeds", type=positive_int, default=10, help="seeds per family and split (default 10)")
    parser.add_argument("--duration", type=float, default=60.0, help="seconds per run (default 60, at least 10)")
    parser.add_argument("--particles", type=positive_int, default=500, help="particles (default 500)")
    parser.add_argument("--jobs", type=positive_int, default=2, help="worker processes (default 2)")
    parser.add_argument(
        "--progress",
        action="store_true",
        help="progress bar on stderr even when it is not a terminal (not with --json or --no-progress)",
    )
    parser.add_argument(
        "--prior",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a variant: set a field of mcl.relocalization.RelocalizationPrior (repeatable)",
    )
    parser.add_argument(
        "--quality",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a variant: set a field of mcl.localizer.QualityThresholds, or rivals.NAME a number of its "
        "mcl.rivals.RivalSettings (repeatable)",
    )
    parser.add_argument(
        "--sensor",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a variant: set a number of sensing.LandmarkSensorModel (repeatable)",
    )
    parser.add_argument(
        "--profile",
        metavar="TOML",
        help="the localizer's settings from a profile file (mcl.profile; `robocup-mcl tune` writes them)",
    )
    parser.add_argument(
        "--view",
        action="store_true",
        help="pass each frame's camera view (head pan, field of view, ranges) to observe()",
    )
    parser.add_argument(
        "--team",
        choices=("auto", "on", "off"),
        default="auto",
        help="feed the team's messages and the robot's ball sightings: in the team families only "
        "(auto, the default), in every family (on, a variant), in none (off, a variant)",
    )
    parser.add_argument(
        "--compare",
        nargs=2,
        metavar=("BASE", "CURRENT"),
        help="print two saved results files side by side (for the split given) and run nothing",
    )
    parser.add_argument("--json", action="store_true", help="the results as JSON on stdout instead of tables")
    parser.add_argument("--save", metavar="PATH", help="also write the JSON results to PATH")
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """The command line (see the module docstring); exit 2 on bad arguments."""
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    if args.compare:
        files = []
        for path in args.compare:
            try:
                with open(path, encoding="utf-8") as handle:
                    files.append(json.load(handle))
            except (OSError, ValueError) as error:
                parser.error(f"--compare {path}: {error}")
        split = "holdout" if args.split == "both" else args.split
        if not all(split in f.get("splits", {}) for f in files):
            parser.error(f"--compare: both files need the {split} split (--split)")
        if args.json:
            print(
                json.dumps(
                    {"split": split, "base": headline(files[0], split), "current": headline(files[1], split)}, indent=2
                )
            )
        else:
            print(format_comparison(files[0], files[1], split, tuple(os.path.basename(p) for p in args.compare)))
        return 0
    families = parse_families(parser, args.families)
    if args.seeds > MAX_SEEDS:
        parser.error(f"--seeds {args.seeds} must be at most {MAX_SEEDS} (training and held-out seeds stay apart)")
    from mcl.tools.cli_checks import check_duration, check_output_file, progress_wanted, save_json

    check_duration(parser, args.duration, 10.0)
    check_output_file(args.save, "--save", make_parents=False)  # before the battery runs, not after it
    prior = _overrides(parser, "--prior", args.prior, RelocalizationPrior)
    quality = _overrides(
        parser, "--quality", args.quality, QualityThresholds, lambda **values: quality_thresholds(values)
    )
    sensor = _overrides(
        parser, "--sensor", args.sensor, LandmarkSensorModel, lambda **values: LandmarkSensorModel(spl(), **values)
    )
    profile = None
    if args.profile:
        try:
            profile = Profile.load(args.profile)
        except OSError as error:
            parser.error(f"--profile {args.profile}: {error.strerror or error}")
        except ValueError as error:
            parser.error(f"--profile {error}")
    splits = list(SPLITS) if args.split == "both" else [args.split]
    progress = progress_wanted(args, force=args.progress)
    # Compile (or load) the kernels here, once, before the workers start: the first run on a machine says so
    # and shows its progress, and the workers load them from numba's cache instead of each compiling them.
    from .walk import warm_up_walk
    from .walk_sim import WalkScenario

    warm = warm_up_walk(WalkScenario(), "velocity-linear", view=args.view, progress=progress)
    results = run_battery(
        families,
        splits,
        args.seeds,
        args.duration,
        args.particles,
        args.jobs,
        progress=progress,
        prior=prior,
        quality=quality,
        view=args.view,
        sensor=sensor,
        profile=profile,
        team={"auto": None, "on": True, "off": False}[args.team],
    )
    results.update(warm.as_dict())
    text = json.dumps(results, indent=2)
    save_json(args.save, results)
    if args.json:
        print(text)
    else:
        print(format_report(results))
        if args.save:
            print(f"results written to {args.save}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
