"""What a tuning trial measures: one parameter set on one case (a log, or a scenario of the evaluation battery)
with one filter seed, and how the cases' figures combine into the number the search minimizes.

Cases:
- a log file (`LogCase(path, field)`): any log `mcl.tools.logs.read_log` reads (ROS 2 MCAP, the columnar .npz or CSV
  folder), replayed through the profile's `Localizer` (`mcl.tools.replay.replay`, starting anywhere in the own half);
- anything else with a `label` and an `evaluate(values, seed, particles)` method: the evaluation battery's
  scenarios are such cases (`demos.battery.BatteryCase`: `robocup-mcl eval`'s simulated run of a family and
  seed, driven as the battery drives it, game events included).

Objectives (`OBJECTIVES`), both minimized:
- "truth" (needs ground truth in every case): the mean over cases of
      fail share + RMSE position [m] + 0.25 · min(re-convergence, 30 s) / 30 s + SUPERB-wrong share,
  the battery's figures (`mcl.tools.evaluation`): the share of the time more than 0.5 m off or on the mirrored pose,
  the tracking error while not failed, the time to come back within 0.3 m and 20° after an event (a run that
  never does counts 0.25; a log has no event and counts 0), and the share of the SUPERB samples more than
  0.5 m off (quality honesty). Each term is 0 for a perfect localizer; a run that is lost all the time scores
  about 1;
- "evidence" (no ground truth needed): minus the mean log evidence per camera frame, pooled over the cases'
  frames: `Localizer.log_evidence`, the standard particle-filter estimate of the marginal likelihood of the
  detections (per frame the log of the weighted average particle likelihood, made a density over ranges and
  bearings by `LandmarkSensorModel.log_normalizer`, so that noise settings compare fairly). Guard it with
  held-out logs: it rewards a model that predicts the detections, and a model that fits the training logs'
  detections too closely shows on the held-out ones.
The figures of the other objective are computed too whenever they can be (the truth's, when the logs have it),
so that a study shows whether maximizing the evidence also lowers the error.
"""

from __future__ import annotations

import functools
import math
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

OBJECTIVES = ("truth", "evidence")
RECONVERGE_CAP = 30.0  # s: re-convergence counted up to this, and a "never" counts as this
RECONVERGE_WEIGHT = 0.25  # the loss of a run that never re-converges, in fail-share units


@dataclass(frozen=True)
class LogCase:
    """A log file to replay (`mcl.tools.logs.read_log` reads it in each worker, once), on the field `field` (a preset
    name or a field file, `field.io.field_by_name_or_path`), starting anywhere in the own half. `topics`: the
    MCAP log's topics (`mcl.tools.logs.mcap_io.Topics`; None: the defaults and discovery, as `read_log`).

    A case is anything with a `label` (for tables) and `evaluate(values, seed, particles) -> dict` that gives
    `evaluate_case`'s figures; it is pickled to the workers. The evaluation battery's scenarios are cases too
    (`demos.battery.BatteryCase`)."""

    path: str
    field: str = "spl"
    topics: Any = None

    @property
    def label(self) -> str:
        """The log's file name."""
        return os.path.basename(self.path.rstrip("/"))

    def evaluate(self, values: Mapping[str, Any], seed: int, particles: int = 500) -> dict:
        """The figures of the parameter set `values` on this log (see `evaluate_case`)."""
        from field.io import field_by_name_or_path
        from mcl.profile import Profile
        from mcl.tools.replay import replay

        log = _read(self.path, self.topics)
        field = field_by_name_or_path(self.field)
        localizer = Profile.from_values(values).localizer(field, seed=seed, n_particles=particles)
        result = replay(log, field, localizer=localizer)
        truth = None
        has = result.has_truth
        if has.any():
            codes = evaluation_codes(result.quality[has])
            truth = truth_figures(result.times[has], result.truth[has], result.estimates[has], codes, result.lost[has])
        return {
            "log_evidence": float(localizer.log_evidence),
            "evidence_frames": int(localizer.evidence_frames),
            "truth": truth,
        }


@functools.lru_cache(maxsize=64)
def _read(path: str, topics: Any = None):
    """A log, read once per process (the workers of a study read each log once)."""
    from mcl.tools.logs import read_log

    return read_log(path, topics=topics)[0]


def evaluation_codes(replay_codes) -> np.ndarray:
    """Quality codes of a replay (`mcl.tools.replay.QUALITY_CODES`: 2 superb, 1 okay, 0 poor, 3 unsure of the
    half) as `mcl.tools.evaluation` codes them (`QUALITY_CODE`: 0 superb, 1 okay, 2 poor, 3 unsure of the
    half), level by level."""
    from mcl.tools.evaluation import QUALITY_CODE
    from mcl.tools.replay import QUALITY_CODES

    table = np.empty(len(QUALITY_CODES), dtype=np.int8)
    for level, code in QUALITY_CODES.items():
        table[code] = QUALITY_CODE[level]
    return table[np.asarray(replay_codes, dtype=np.intp)]


def truth_figures(times, truth, estimates, quality_codes, lost, windows=()) -> dict:
    """The "truth" objective's figures of one run (`mcl.tools.evaluation.evaluate` on the samples with truth;
    quality as `mcl.tools.evaluation` codes) and its `loss`."""
    from mcl.tools.evaluation import evaluate

    figures = evaluate(times, truth, estimates, quality_codes, lost, windows)
    superb = figures["quality"]["SUPERB"]
    superb_wrong = superb["wrong"] / superb["steps"] if superb["steps"] else 0.0
    reconverge = figures["reconverge_s"]
    reconverge_term = 0.0 if reconverge is None else min(reconverge, RECONVERGE_CAP) / RECONVERGE_CAP
    rmse = figures["rmse_position_m"]
    loss = figures["fail_share"] + (0.0 if rmse is None else rmse) + RECONVERGE_WEIGHT * reconverge_term + superb_wrong
    return {
        "fail_share": figures["fail_share"],
        "rmse_position_m": rmse,
        "reconverge_s": None if reconverge is None or math.isinf(reconverge) else reconverge,
        "never": reconverge is not None and math.isinf(reconverge),
        "superb_wrong": superb_wrong,
        "loss": loss,
    }


def evaluate_case(case: Any, values: Mapping[str, Any], seed: int, particles: int = 500) -> dict:
    """The figures of the parameter set `values` ({"section.setting": value}, an `mcl.profile.Profile`'s) on
    `case` with filter seed `seed` and `particles` particles (unless the values set localizer.particles):
    "log_evidence", "evidence_frames", "seconds" and, with ground truth, `truth_figures` under "truth" (None
    without)."""
    started = time.perf_counter()
    n = int(values.get("localizer.particles", particles))
    result = dict(case.evaluate(values, seed, n))
    result["seconds"] = time.perf_counter() - started
    return result


def combine(objective: str, results: Sequence[dict]) -> float:
    """The number the search minimizes, from every case × seed result of one trial (see the module docstring).
    Raises ValueError for "truth" when a result has no ground truth."""
    if objective == "truth":
        if any(r["truth"] is None for r in results):
            raise ValueError("the truth objective needs ground truth in every log (use --objective evidence)")
        return float(np.mean([r["truth"]["loss"] for r in results]))
    if objective == "evidence":
        frames = sum(r["evidence_frames"] for r in results)
        if frames == 0:
            return math.inf
        total = sum(r["log_evidence"] for r in results)
        return -total / frames if math.isfinite(total) else math.inf
    raise ValueError(f"objective = {objective!r} must be one of {', '.join(OBJECTIVES)}")


def summary(results: Sequence[dict]) -> dict:
    """Pooled figures of several results: the mean log evidence per frame (None when a frame was explained by no
    particle: -inf) and, where every result has truth,
    the mean fail share, RMSE, SUPERB-wrong share, runs that never re-converged and the truth loss."""
    frames = sum(r["evidence_frames"] for r in results)
    evidence = sum(r["log_evidence"] for r in results)
    out: dict = {
        "evidence_per_frame": evidence / frames if frames and math.isfinite(evidence) else None,
        "frames": frames,
    }
    if results and all(r["truth"] is not None for r in results):
        t = [r["truth"] for r in results]
        rmse = [x["rmse_position_m"] for x in t if x["rmse_position_m"] is not None]
        out.update(
            fail_share=float(np.mean([x["fail_share"] for x in t])),
            rmse_position_m=float(np.mean(rmse)) if rmse else None,
            superb_wrong=float(np.mean([x["superb_wrong"] for x in t])),
            never=sum(bool(x["never"]) for x in t),
            truth_loss=float(np.mean([x["loss"] for x in t])),
        )
    return out
