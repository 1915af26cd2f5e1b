"""`robocup-mcl demo odometry`: learned footstep odometry (Rouxel et al.) on simulated walks, with its figures.

    robocup-mcl demo odometry [--surface carpet|grass|both] [--seed S] [--curve] [--filter] [--json]
    robocup-mcl demo odometry --train LOG.npz --save DIR [--seed S]     # train on a recorded log, save
    robocup-mcl demo odometry --record LOG.npz [--surface grass] [--seed S] [--duration 300]
    robocup-mcl demo odometry --mismatch [--spreads 0 0.5 1 2 1:0 0:1] [--json] [--save results/odometry_mismatch.json]

    from demos.odometry import evaluate, learning_curve, filter_comparison, mismatch, main

The paper's protocol (sec. IV-B 2-3) on `demos.footstep_sim` logs, per surface: five 5-minute joystick walks;
the three LWPR models of each input set learn on the first half of the first log (the meta-parameters in
`LWPRSettings` come from `robocup-mcl fit odometry`, on other robots' logs); the four other logs are cut into non-overlapping 20 s sequences, on each
of which the odometry restarts at the true pose and integrates its footstep displacements (the paper's
"re-integration", `motion_models.footsteps.integrate`). Figures: the mean Cartesian and angular drift from
the motion capture after 10 s and 20 s, with 95 % intervals (mean ± 1.96 standard errors), for the four
methods: a priori raw (the commanded steps), a priori learned (LWPR on the 7 command inputs), online raw (the
sensor-based steps), online learned (LWPR on the 9 sensor inputs); and the mean per-step error of each axis.

`--curve`: the learning curve (Fig. 7): the models learn on the first T seconds of the learning log, for T
from 10 s to the half; drift after 10 s on the test logs and the mean per-step forward error, per T.

`--filter`: the particle filter of `demos.walk` (landmark sensor model, the walk scenario's camera and
its noise, 500 particles, started around the true pose) on 60 s footstep walks across the SPL field, moved
by learned versus raw footstep odometry (`RawFootstepOdometry`: the raw step with its RMS error on the
learning set as noise), averaged over the walks: position RMSE and median error, heading RMSE, the share
of the time the estimate is more than 0.5 m off, and the worst error of all walks; with the camera on all
the time and with the camera looking away (no detections) for the second half of every 10 s, as while
watching the ball.
Particles move only at support swaps; the relocalization's dead-reckoned anchor follows the sensor yaw.

Seeds: log i of surface s is `simulate(seed=1000·seed + 10·s + i)`; the particle filter runs use seeds
derived from `seed` as well. Same seed, same figures, bit for bit (timings aside). These figures are on the
nominal simulator: one robot, the same for learning and test logs, nominal run conditions.

`--mismatch [--spreads R:C ...] [--save PATH]`: the robustness table, on robots unseen by any fit. Robots
are drawn from `demos.footstep_sim.ROBOT_RANGES` at R times the documented ranges and each log's conditions
from `CONDITION_RANGES` at C times (0:0 is the nominal simulator; by default 0:0, 0.5:0.5, 1:1, 2:2 and, to
tell the two apart, 1:0 and 0:1). Six training robots (`TRAIN_ROBOTS`, log
seeds `fleet_seed("train", ...)`, from 20000) are what `robocup-mcl fit odometry` fits LWPR's meta-parameters
and the linear baseline's setting on; four held-out robots (`TEST_ROBOTS`, seeds from 60000) with five 300 s
logs each are the test. Two regimes: "own", the paper's protocol on each test robot (learn on the first half of
its first log, test on its four other logs, each with its own conditions); "fleet", learned on the first halves
of the training robots' logs, none of the test robot's data. Methods: the raw odometry, the linear baseline
(`LinearCorrection`: least squares, the setting of `BASELINE`), LWPR (the paper's model, `LWPRSettings()`) and
the variant "lin+LWPR" (`LearnedFootstepOdometry.train(..., linear_stage=True)`: LWPR learning what the linear
map leaves). Figures: mean drift after 10 s over the 20 s sequences, and the change against the raw odometry
with a 95 % bootstrap interval over sequences (paired: the same resampled sequences for both methods).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from demos.footstep_sim import (
    SURFACES,
    Driver,
    FootstepLog,
    draw_conditions,
    draw_robot,
    load_log,
    save_log,
    simulate,
    truth_displacements,
)
from field.angles import wrap_angles
from motion_models.footsteps import LEFT, RIGHT, input_matrix, integrate
from motion_models.learned_odometry import LearnedFootstepOdometry, LinearStage, LWPRSettings, RawFootstepOdometry

METHODS = ("apriori_raw", "apriori_learned", "online_raw", "online_learned")
OTHER = ("apriori_learned_other", "online_learned_other")
OTHER_LABELS = {
    "apriori_learned_other": "a priori learned as a correction of the commanded step",
    "online_learned_other": "online learned on the true step itself, not its correction",
}
KINDS = ("apriori", "online")
# The linear baseline's setting per input set, chosen by `robocup-mcl fit odometry` (results/odometry_fit.json).
BASELINE = {"apriori": {"features": "inputs", "ridge": 0.0}, "online": {"features": "axis", "ridge": 0.001}}
N_LOGS = 5
LOG_SECONDS = 300.0
SEQUENCE_SECONDS = 20.0
HORIZONS = (10.0, 20.0)
CURVE_SECONDS = (10, 20, 30, 45, 60, 90, 120, 150)
Z95 = 1.959964
LOST = 0.5  # m: a filter whose estimate is farther than this from the truth has lost the robot


# ---------------------------------------------------------------------------------------------------------
# Data
# ---------------------------------------------------------------------------------------------------------
def log_seed(seed: int, surface: str, index: int) -> int:
    return 1000 * seed + 10 * list(SURFACES).index(surface) + index


def make_logs(surface: str, seed: int, n: int = N_LOGS, duration: float = LOG_SECONDS) -> list[FootstepLog]:
    return [simulate(duration, surface, log_seed(seed, surface, i)) for i in range(n)]


def step_inputs(log: FootstepLog, kind: str) -> np.ndarray:
    """The LWPR inputs of every step of `log` (K rows): the step before the first counts as standing (zero
    displacement, one nominal period, the other support foot), as `FootstepLog.events` has it."""
    support = np.concatenate(([RIGHT if log.support[0] == LEFT else LEFT], log.support))
    zero = np.zeros((1, 3))
    return input_matrix(
        kind,
        support,
        np.vstack([zero, log.commanded]),
        np.vstack([zero, log.sensor]),
        np.concatenate(([log.step_period], log.durations)),
    )


def train(log: FootstepLog, seed: int = 0, settings: LWPRSettings = LWPRSettings()) -> dict:
    """Both learned models and both calibrated raw models from one learning log."""
    truth = truth_displacements(log)
    out = {}
    for kind in KINDS:
        X = step_inputs(log, kind)
        out[f"{kind}_learned"] = LearnedFootstepOdometry.train(X, truth, kind, seed=seed, settings=settings)
        out[f"{kind}_raw"] = RawFootstepOdometry.calibrate(X, truth, kind)
    return out


def method_steps(log: FootstepLog, models: dict) -> dict:
    """Each method's footstep displacements (K, 3) on `log`."""
    steps = {"apriori_raw": log.commanded, "online_raw": log.sensor}
    for kind in KINDS:
        steps[f"{kind}_learned"] = models[f"{kind}_learned"].predict_steps(step_inputs(log, kind))[0]
    return steps


# ---------------------------------------------------------------------------------------------------------
# The drift protocol
# ---------------------------------------------------------------------------------------------------------
def sequence_drifts(log: FootstepLog, steps: dict, sequence: float = SEQUENCE_SECONDS, horizons=HORIZONS) -> dict:
    """Per method and horizon, the Cartesian [m] and angular [rad] drift on each non-overlapping sequence:
    the odometry restarts at the swap that opens the sequence and integrates until the swap nearest
    start + horizon; the truth is the motion capture at those swaps."""
    times = log.swap_times
    out = {m: {h: ([], []) for h in horizons} for m in steps}
    n_sequences = int((times[-1] - times[0] + 1e-9) // sequence)
    for j in range(n_sequences):
        start_time = times[0] + j * sequence
        i0 = int(np.searchsorted(times, start_time - 1e-9))
        origin = log.swap_poses[i0]
        for h in horizons:
            i1 = int(np.argmin(np.abs(times - (start_time + h))))
            if i1 <= i0 or abs(times[i1] - (start_time + h)) > log.step_period:
                continue
            true_end = _relative(origin, log.swap_poses[i1])
            for m, d in steps.items():
                end = integrate(d[i0:i1])[-1]
                out[m][h][0].append(math.hypot(end[0] - true_end[0], end[1] - true_end[1]))
                out[m][h][1].append(abs(float(wrap_angles(end[2] - true_end[2]))))
    return out


def _relative(origin: np.ndarray, pose: np.ndarray) -> np.ndarray:
    c, s = math.cos(origin[2]), math.sin(origin[2])
    d = pose[:2] - origin[:2]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], float(wrap_angles(pose[2] - origin[2]))])


def _stat(values) -> dict:
    v = np.asarray(values, dtype=np.float64)
    half = Z95 * v.std(ddof=1) / math.sqrt(v.size) if v.size > 1 else float("nan")
    return {"mean": float(v.mean()), "ci95": float(half), "n": int(v.size)}


def evaluate(surface: str, seed: int = 0, logs: list[FootstepLog] | None = None) -> dict:
    """The paper's protocol on one surface (see the module docstring)."""
    logs = make_logs(surface, seed) if logs is None else logs
    learn = logs[0].first(0.5 * (logs[0].swap_times[-1] - logs[0].swap_times[0]))
    models = train(learn, seed)
    # The other choice of target per input set (see motion_models.learned_odometry), for comparison.
    other = {kind: train(learn, seed, LWPRSettings(residual=kind != "online"))[f"{kind}_learned"] for kind in KINDS}
    pooled = {m: {h: ([], []) for h in HORIZONS} for m in (*METHODS, *OTHER)}
    step_errors = {m: [] for m in (*METHODS, *OTHER)}
    for log in logs[1:]:
        steps = method_steps(log, models)
        steps.update({f"{kind}_learned_other": other[kind].predict_steps(step_inputs(log, kind))[0] for kind in KINDS})
        truth = truth_displacements(log)
        for m in steps:
            step_errors[m].append(np.abs(steps[m] - truth))
        for m, per_h in sequence_drifts(log, steps).items():
            for h, (cart, ang) in per_h.items():
                pooled[m][h][0].extend(cart)
                pooled[m][h][1].extend(ang)
    drift = {
        m: {
            f"{h:g}s": {"cartesian_m": _stat(pooled[m][h][0]), "angular_deg": _stat(np.degrees(pooled[m][h][1]))}
            for h in HORIZONS
        }
        for m in pooled
    }
    per_step = {
        m: dict(
            zip(
                ("dx_mm", "dy_mm", "dtheta_deg"),
                (np.concatenate(step_errors[m]).mean(axis=0) * np.array([1e3, 1e3, 180 / math.pi])).tolist(),
            )
        )
        for m in pooled
    }
    learned = {kind: models[f"{kind}_learned"] for kind in KINDS}
    other_figures = {m: {"drift": drift.pop(m), "per_step_error": per_step.pop(m)} for m in OTHER}
    reduction = {
        kind: 1.0
        - drift[f"{kind}_learned"]["10s"]["cartesian_m"]["mean"] / drift[f"{kind}_raw"]["10s"]["cartesian_m"]["mean"]
        for kind in KINDS
    }
    return {
        "surface": surface,
        "seed": seed,
        "learning_steps": learn.n_steps,
        "learning_seconds": float(learn.swap_times[-1] - learn.swap_times[0]),
        "test_logs": len(logs) - 1,
        "test_steps": int(sum(log.n_steps for log in logs[1:])),
        "sequences": drift["online_raw"]["10s"]["cartesian_m"]["n"],
        "drift": drift,
        "per_step_error": per_step,
        "drift_reduction_10s": reduction,
        "other_targets": other_figures,
        "receptive_fields": {
            kind: {name: int(mod.num_rfs[0]) for name, mod in zip(("dx", "dy", "dtheta"), learned[kind].models)}
            for kind in KINDS
        },
        "_logs": logs,
        "_models": models,
    }


def learning_curve(surface: str, seed: int = 0, logs: list[FootstepLog] | None = None, seconds=CURVE_SECONDS) -> dict:
    """Drift after 10 s on the test logs and mean per-step forward error against seconds of learning."""
    logs = make_logs(surface, seed) if logs is None else logs
    rows = []
    tests = [(log, truth_displacements(log)) for log in logs[1:]]
    for t in seconds:
        models = train(logs[0].first(float(t)), seed)
        cart = {m: [] for m in METHODS}
        dx = {m: [] for m in METHODS}
        for log, truth in tests:
            steps = method_steps(log, models)
            for m, per_h in sequence_drifts(log, steps, horizons=(10.0,)).items():
                cart[m].extend(per_h[10.0][0])
                dx[m].append(np.abs(steps[m][:, 0] - truth[:, 0]))
        rows.append(
            {
                "seconds": t,
                "steps": logs[0].first(float(t)).n_steps,
                **{f"{m}_drift10_m": float(np.mean(cart[m])) for m in METHODS},
                **{f"{m}_dx_mm": float(1e3 * np.concatenate(dx[m]).mean()) for m in METHODS},
            }
        )
    return {"surface": surface, "seed": seed, "rows": rows}


# ---------------------------------------------------------------------------------------------------------
# The particle filter
# ---------------------------------------------------------------------------------------------------------
def filter_run(log: FootstepLog, model, seed: int, vision_gaps: bool, particles: int = 500) -> dict:
    """Run the particle filter over a field walk moved by `model` (a footstep motion model)."""
    from demos.walk_sim import WalkScenario, _camera
    from mcl import ParticleFilter
    from motion_models import MotionInput
    from sensing import LandmarkSensorModel

    scenario = WalkScenario()
    camera_rng = np.random.default_rng([seed, 1])
    pf = ParticleFilter(scenario.field, model, LandmarkSensorModel(scenario.field), n_particles=particles, seed=seed)
    pf.reset_around(log.truth[0], sigma=(0.1, 0.1, 0.05))
    events = log.events()
    swap_tick = np.rint(log.swap_times[1:] * 100.0).astype(np.int64)  # tick at whose end each step ends
    event_at = dict(zip(swap_tick.tolist(), events))
    dt = float(log.mocap_times[1] - log.mocap_times[0])
    camera_every = 1.0 / scenario.camera_rate
    next_frame = camera_every
    n = log.mocap_times.shape[0]
    errors = np.empty((n - 1, 2))
    for k in range(1, n):
        t = float(log.mocap_times[k])
        event = event_at.get(k)
        # The gyro-carried heading of the filter follows the sensor yaw at each swap.
        u = MotionInput(dt=dt, odometry=event.sensor if event is not None else (0.0, 0.0, 0.0), footstep=event)
        pf.predict(u)
        if t + 1e-9 >= next_frame:
            next_frame += camera_every
            head = scenario.head_pan_amplitude * math.sin(2 * math.pi * t / scenario.head_pan_period)
            observations = _camera(scenario, log.truth[k], head, camera_rng)
            if not (vision_gaps and (t % 10.0) >= 5.0):
                pf.correct(observations)
        estimate = pf.estimate().pose
        errors[k - 1] = (
            math.hypot(*(estimate[:2] - log.truth[k, :2])),
            abs(float(wrap_angles(estimate[2] - log.truth[k, 2]))),
        )
    return {
        "position_rmse_m": float(np.sqrt(np.mean(errors[:, 0] ** 2))),
        "position_median_m": float(np.median(errors[:, 0])),
        "heading_rmse_deg": math.degrees(float(np.sqrt(np.mean(errors[:, 1] ** 2)))),
        "max_position_error_m": float(errors[:, 0].max()),
        "lost_share": float(np.mean(errors[:, 0] > LOST)),
    }


def field_walk(surface: str, seed: int, duration: float = 60.0) -> FootstepLog:
    """A footstep walk over the SPL field (kept 0.6 m inside the lines), starting in the own half."""
    from field import spl

    f = spl()
    rng = np.random.default_rng([seed, 2])
    start = (
        rng.uniform(-f.half_length + 0.6, -0.5),
        rng.uniform(-f.half_width + 0.6, f.half_width - 0.6),
        rng.uniform(-1.5, 1.5),
    )
    driver = Driver(area=(f.half_length - 0.6, f.half_width - 0.6), margin=0.5, change_rate=0.3)
    return simulate(duration, surface, seed=10_000 + seed, driver=driver, start=start)


def filter_comparison(surface: str, models: dict, seed: int = 0, runs: int = 3) -> dict:
    """Tracking error of the particle filter with learned versus raw footstep odometry (both input sets)."""
    out = {}
    for gaps in (False, True):
        per_method = {m: [] for m in METHODS}
        for r in range(runs):
            log = field_walk(surface, 100 * seed + r)
            for m in METHODS:
                per_method[m].append(filter_run(log, models[m], seed=100 * seed + r, vision_gaps=gaps))
        out["vision_gaps" if gaps else "vision"] = {
            m: {
                key: float((np.max if key.startswith("max") else np.mean)([run[key] for run in per_method[m]]))
                for key in per_method[m][0]
            }
            for m in METHODS
        }
    out["runs"] = runs
    return out


# ---------------------------------------------------------------------------------------------------------
# Model mismatch: robots unseen in training, runs that differ, the linear baseline
# ---------------------------------------------------------------------------------------------------------
# (robot, run) spreads: multiples of the documented ranges of demos.footstep_sim (0: nominal); the last two
# rows vary only the robots or only the runs.
SPREADS = ((0.0, 0.0), (0.5, 0.5), (1.0, 1.0), (2.0, 2.0), (1.0, 0.0), (0.0, 1.0))
TRAIN_ROBOTS = tuple(range(6))  # robot ids whose logs fit the meta-parameters and the baseline
TEST_ROBOTS = tuple(range(100, 104))  # held-out robot ids: never in any fit
TEST_LOGS = 5  # logs per test robot: the first's first half learns, the others test
REGIMES = ("own", "fleet")
REGIME_LABELS = {
    "own": "learned on the test robot's own first log (the paper's protocol)",
    "fleet": "learned on the training robots only, none of the test robot's data",
}
MISMATCH_METHODS = ("raw", "linear", "lwpr", "variant")
METHOD_LABELS = {"raw": "raw", "linear": "linear", "lwpr": "LWPR", "variant": "lin+LWPR"}
VARIANT_LINEAR = {"features": "inputs", "ridge": 0.0}  # the variant's `LinearStage`: every input, no penalty
BOOTSTRAP = 2000
PAPER_REDUCTION = {"apriori": 0.76, "online": 0.58}  # Rouxel sec. IV-B: 62.0 → 14.8 cm, 24.5 → 10.3 cm
BOOTSTRAP_SEED = 29


def fleet_seed(split: str, surface: str, robot: int, index: int) -> int:
    """Seed of log `index` of `robot` on `surface`: training logs from 20000, held-out test logs from 60000."""
    base = {"train": 20_000, "test": 60_000}[split]
    return base + 1000 * list(SURFACES).index(surface) + 10 * (robot % 100) + index


def fleet_log(
    split: str, surface: str, robot: int, index: int, spread: float | tuple[float, float], duration: float = LOG_SECONDS
) -> FootstepLog:
    """One log of robot `robot` under the run's own conditions (drawn from its seed); `spread` is one number
    for both or a pair (robot spread, run spread)."""
    robot_spread, run_spread = spread if isinstance(spread, tuple) else (spread, spread)
    seed = fleet_seed(split, surface, robot, index)
    return simulate(
        duration, surface, seed, robot=draw_robot(robot, robot_spread), conditions=draw_conditions(seed, run_spread)
    )


def halves(log: FootstepLog) -> tuple[FootstepLog, FootstepLog]:
    """The first half of a log (learning) and the rest (the paper's meta-parameter tuning set)."""
    first = log.first(0.5 * (log.swap_times[-1] - log.swap_times[0]))
    return first, log.steps(first.n_steps, log.n_steps)


@dataclass(frozen=True)
class LinearCorrection:
    """The baseline a team would try first: the true step as a linear (affine) function of the inputs, fitted by
    ridge-regularized least squares per axis (`motion_models.learned_odometry.LinearStage`). `features` "axis":
    each axis of the raw step alone (a scale and an offset per axis); "inputs": all the inputs of the input set
    (the LWPR inputs)."""

    kind: str
    features: str
    stage: LinearStage

    @classmethod
    def fit(
        cls, X: np.ndarray, Y: np.ndarray, kind: str, features: str = "inputs", ridge: float = 0.0
    ) -> LinearCorrection:
        """Least squares on standardized inputs with penalty `ridge`·n on the weights (not the offsets)."""
        if features not in ("axis", "inputs"):
            raise ValueError(f"features = {features!r} must be 'axis' or 'inputs'")
        return cls(kind, features, LinearStage.fit(X, Y, ridge, per_axis=features == "axis"))

    @property
    def weights(self) -> np.ndarray:
        """(n_in, 3) the weights of the standardized inputs, zero where an axis does not use an input."""
        return self.stage.weights

    def predict_steps(self, X: np.ndarray) -> tuple[np.ndarray, None]:
        """The corrected steps (m, 3) of inputs (m, n_in) (no noise model: None)."""
        return self.stage.predict(X), None


def train_methods(learn: list[FootstepLog], kind: str, settings: LWPRSettings, baseline: dict, seed: int = 0) -> dict:
    """LWPR, the linear baseline and the variant for input set `kind`, learned on the pooled steps of `learn`."""
    X = np.vstack([step_inputs(log, kind) for log in learn])
    Y = np.vstack([truth_displacements(log) for log in learn])
    return {
        "linear": LinearCorrection.fit(X, Y, kind, **baseline[kind]),
        "lwpr": LearnedFootstepOdometry.train(X, Y, kind, seed=seed, settings=settings),
        "variant": LearnedFootstepOdometry.train(X, Y, kind, seed=seed, settings=settings, linear_stage=True),
    }


def sequence_errors(log: FootstepLog, kind: str, models: dict) -> dict:
    """Per method ("raw" and each of `models`), the Cartesian drift [m] after 10 s of every sequence of `log`."""
    X = step_inputs(log, kind)
    steps = {"raw": X[:, :3], **{m: model.predict_steps(X)[0] for m, model in models.items()}}
    return {m: per_h[10.0][0] for m, per_h in sequence_drifts(log, steps, horizons=(10.0,)).items()}


def reduction_interval(drifts: dict, method: str, reference: str = "raw", rng_seed: int = BOOTSTRAP_SEED) -> dict:
    """1 - mean(method) / mean(reference) over paired sequences, with a 95 % bootstrap interval (resampling
    sequences, `BOOTSTRAP` times, from `rng_seed`)."""
    a, b = np.asarray(drifts[method]), np.asarray(drifts[reference])
    idx = np.random.default_rng(rng_seed).integers(0, a.size, (BOOTSTRAP, a.size))
    boot = 1.0 - a[idx].mean(axis=1) / b[idx].mean(axis=1)
    low, high = np.percentile(boot, [2.5, 97.5])
    return {"mean": float(1.0 - a.mean() / b.mean()), "ci95": [float(low), float(high)]}


def mismatch_cell(
    surface: str, spread: tuple[float, float], settings: LWPRSettings, baseline: dict, seed: int = 0
) -> dict:
    """Both regimes and both input sets at one spread on one surface (see `mismatch`)."""
    fleet_learn = [halves(fleet_log("train", surface, r, 0, spread))[0] for r in TRAIN_ROBOTS]
    fleet = {kind: train_methods(fleet_learn, kind, settings, baseline, seed) for kind in KINDS}
    drifts = {regime: {kind: {m: [] for m in MISMATCH_METHODS} for kind in KINDS} for regime in REGIMES}
    for robot in TEST_ROBOTS:
        logs = [fleet_log("test", surface, robot, i, spread) for i in range(TEST_LOGS)]
        own = {kind: train_methods([halves(logs[0])[0]], kind, settings, baseline, seed) for kind in KINDS}
        for log in logs[1:]:
            for regime, models in (("own", own), ("fleet", fleet)):
                for kind in KINDS:
                    for m, values in sequence_errors(log, kind, models[kind]).items():
                        drifts[regime][kind][m].extend(values)
    rows = []
    for regime in REGIMES:
        for kind in KINDS:
            d = drifts[regime][kind]
            rows.append(
                {
                    "surface": surface,
                    "robot_spread": spread[0],
                    "run_spread": spread[1],
                    "regime": regime,
                    "kind": kind,
                    "sequences": len(d["raw"]),
                    "drift10_cm": {m: 100 * float(np.mean(d[m])) for m in MISMATCH_METHODS},
                    "reduction": {m: reduction_interval(d, m) for m in MISMATCH_METHODS[1:]},
                    "lwpr_vs_linear": reduction_interval(d, "lwpr", "linear"),
                }
            )
    return {"rows": rows}


def mismatch(
    surfaces=("carpet", "grass"),
    spreads=SPREADS,
    settings: LWPRSettings = LWPRSettings(),
    baseline: dict | None = None,
    seed: int = 0,
    progress: bool = False,
) -> dict:
    """The robustness table: on held-out robots (`TEST_ROBOTS`), drift after 10 s of the raw odometry, the
    linear baseline and LWPR, learned on the test robot's own first log ("own") or on the training robots
    ("fleet"), at each robot and run parameter spread (0: the nominal simulator) and surface."""
    from mcl.tools.cli_checks import progress_bar

    baseline = BASELINE if baseline is None else baseline
    rows = []
    cells = [(s, x) for s in surfaces for x in spreads]
    for surface, spread in progress_bar(cells, enabled=progress, desc="mismatch", unit="cell"):
        rows.extend(mismatch_cell(surface, spread, settings, baseline, seed)["rows"])
    goals = {
        "half": "LWPR cuts the drift after 10 s by at least half (the goal of docs/papers/rouxel.md)",
        "paper": "LWPR cuts it as much as the paper reports: a priori -76 %, online -58 % (Rouxel sec. IV-B)",
    }
    for row in rows:
        cut = row["reduction"]["lwpr"]["mean"]
        row["goals"] = {
            "half": "met" if cut >= 0.5 else "missed",
            "paper": "met" if cut >= PAPER_REDUCTION[row["kind"]] else "missed",
        }
    return {
        "goals": goals,
        "protocol": {
            "train_robots": list(TRAIN_ROBOTS),
            "test_robots": list(TEST_ROBOTS),
            "test_logs_per_robot": TEST_LOGS,
            "log_seconds": LOG_SECONDS,
            "sequence_seconds": SEQUENCE_SECONDS,
            "bootstrap": BOOTSTRAP,
            "settings": dataclasses.asdict(settings),
            "baseline": baseline,
            "variant_linear": VARIANT_LINEAR,
        },
        "rows": rows,
    }


def _print_mismatch(result: dict) -> None:
    print(
        "drift after 10 s [cm] on held-out robots; change of the 10 s drift [%] against the raw odometry (and of "
        "LWPR against the linear baseline), with its 95 % bootstrap interval over sequences"
    )
    names = MISMATCH_METHODS[1:]
    for regime in REGIMES:
        print(f"\n{regime}: {REGIME_LABELS[regime]}")
        print(
            f"{'surface':<7} {'spread':>7} {'inputs':<7} {'seq':>4} "
            + " ".join(f"{METHOD_LABELS[m]:>8}" for m in MISMATCH_METHODS)
            + "  "
            + " ".join(f"{METHOD_LABELS[m] + ' vs raw':>17}" for m in names)
            + f" {'LWPR vs linear':>17}"
        )
        for row in result["rows"]:
            if row["regime"] != regime:
                continue
            cells = [row["reduction"][m] for m in names] + [row["lwpr_vs_linear"]]
            text = [
                f"{-100 * c['mean']:+4.0f} [{-100 * c['ci95'][1]:+4.0f},{-100 * c['ci95'][0]:+4.0f}]" for c in cells
            ]
            spread = f"{row['robot_spread']:g}/{row['run_spread']:g}"
            print(
                f"{row['surface']:<7} {spread:>7} {row['kind']:<7} {row['sequences']:>4} "
                + " ".join(f"{row['drift10_cm'][m]:>8.1f}" for m in MISMATCH_METHODS)
                + "  "
                + " ".join(f"{t:>17}" for t in text)
            )
    for key, text in result["goals"].items():
        missed = [
            f"{r['surface']} {r['robot_spread']:g}/{r['run_spread']:g} {r['regime']} {r['kind']}"
            for r in result["rows"]
            if r["goals"][key] == "missed"
        ]
        print(
            f"\ngoal: {text}: met in {len(result['rows']) - len(missed)} of {len(result['rows'])} rows"
            + (f"; missed in: {', '.join(missed)}" if missed else "")
        )
    print(
        "\n(spread R/C: multiples of the documented robot (R) and run (C) parameter ranges of demos.footstep_sim;"
        " 0/0 is the nominal simulator, every robot and run alike)"
    )


# ---------------------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------------------
LABELS = {
    "apriori_raw": "a priori raw",
    "apriori_learned": "a priori learned",
    "online_raw": "online raw",
    "online_learned": "online learned",
}


def _print_evaluation(r: dict) -> None:
    print(
        f"\n{r['surface']}: learned on {r['learning_steps']} steps ({r['learning_seconds']:.0f} s), tested on "
        f"{r['test_logs']} logs ({r['test_steps']} steps, {r['sequences']} sequences of 20 s)"
    )
    print(
        f"{'method':<17} {'drift 10 s [cm]':>17} {'drift 20 s [cm]':>17} {'angle 10 s [°]':>15} "
        f"{'angle 20 s [°]':>15} {'step err x/y [mm], θ [°]':>26}"
    )
    for m in METHODS:
        d, e = r["drift"][m], r["per_step_error"][m]
        cells = [
            f"{100 * d[h]['cartesian_m']['mean']:6.1f} ± {100 * d[h]['cartesian_m']['ci95']:4.1f}"
            for h in ("10s", "20s")
        ]
        cells += [f"{d[h]['angular_deg']['mean']:5.1f} ± {d[h]['angular_deg']['ci95']:4.1f}" for h in ("10s", "20s")]
        print(
            f"{LABELS[m]:<17} {cells[0]:>17} {cells[1]:>17} {cells[2]:>15} {cells[3]:>15} "
            f"{e['dx_mm']:8.1f} {e['dy_mm']:5.1f} {e['dtheta_deg']:5.2f}"
        )
    for m in OTHER:
        d, e = r["other_targets"][m]["drift"], r["other_targets"][m]["per_step_error"]
        print(
            f"  ({OTHER_LABELS[m]}: 10 s drift "
            f"{100 * d['10s']['cartesian_m']['mean']:.1f} cm, {d['10s']['angular_deg']['mean']:.1f}°; step error "
            f"{e['dx_mm']:.1f} / {e['dy_mm']:.1f} mm, {e['dtheta_deg']:.2f}°)"
        )
    red = r["drift_reduction_10s"]
    print(
        f"learning cuts the 10 s drift by {100 * red['apriori']:.0f} % (a priori) and {100 * red['online']:.0f} % "
        f"(online); receptive fields {r['receptive_fields']}"
    )


def _print_curve(c: dict) -> None:
    print(f"\nlearning curve ({c['surface']}): drift after 10 s [cm] | mean forward step error [mm]")
    print(
        f"{'learn s':>7} {'steps':>5}  "
        + " ".join(f"{LABELS[m]:>16}" for m in METHODS)
        + "  |  "
        + " ".join(f"{m.split('_')[0][:2]}-{m.split('_')[1][:3]:>3}" for m in METHODS)
    )
    for row in c["rows"]:
        print(
            f"{row['seconds']:>7} {row['steps']:>5}  "
            + " ".join(f"{100 * row[f'{m}_drift10_m']:>16.1f}" for m in METHODS)
            + "  |  "
            + " ".join(f"{row[f'{m}_dx_mm']:>6.1f}" for m in METHODS)
        )


def _print_filter(surface: str, f: dict) -> None:
    print(f"\nparticle filter on {f['runs']} field walks of 60 s ({surface}), 500 particles, start around the truth")
    for key, label in (("vision", "camera always on"), ("vision_gaps", "camera away 5 s in every 10 s")):
        print(f"  {label}:")
        for m in METHODS:
            v = f[key][m]
            print(
                f"    {LABELS[m]:<17} position RMSE {100 * v['position_rmse_m']:5.1f} cm, median "
                f"{100 * v['position_median_m']:4.1f} cm, heading RMSE {v['heading_rmse_deg']:4.1f}°, worst "
                f"{100 * v['max_position_error_m']:5.1f} cm, error > 0.5 m {100 * v['lost_share']:4.1f} % of the time"
            )


def _public(obj):
    if isinstance(obj, dict):
        return {k: _public(v) for k, v in obj.items() if not str(k).startswith("_")}
    return obj


def train_command(log_path: str, directory: str, seed: int, kinds=KINDS, half: bool = False) -> dict:
    """Train the models of each input set on a recorded log and save them under directory/<kind>/."""
    log = load_log(log_path)
    if half:
        log = log.first(0.5 * (log.swap_times[-1] - log.swap_times[0]))
    truth = truth_displacements(log)
    out = {"log": log_path, "surface": log.surface, "steps": log.n_steps, "saved": {}}
    for kind in kinds:
        model = LearnedFootstepOdometry.train(step_inputs(log, kind), truth, kind, seed=seed)
        path = f"{directory.rstrip('/')}/{kind}"
        model.save(path)
        out["saved"][kind] = {"directory": path, "receptive_fields": [int(m.num_rfs[0]) for m in model.models]}
    return out


PROG = "robocup-mcl demo odometry"


def _spread(text: str) -> tuple[float, float]:
    """A --spreads value: "R" or "R:C", finite numbers >= 0."""
    try:
        values = tuple(float(v) for v in text.split(":"))
    except ValueError:
        values = ()
    if len(values) not in (1, 2) or not all(math.isfinite(v) and v >= 0 for v in values):
        raise argparse.ArgumentTypeError(f"{text!r} must be R or R:C, finite numbers >= 0")
    return (values[0], values[-1])


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument(
        "--surface", choices=("carpet", "grass", "both"), default="both", help="the walking surface (default both)"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the simulated walks (default 0)")
    parser.add_argument("--curve", action="store_true", help="the learning curve (drift against learning time)")
    parser.add_argument("--filter", action="store_true", help="particle filter: learned versus raw odometry")
    parser.add_argument("--filter-runs", type=int, default=3, help="field walks per surface for --filter")
    parser.add_argument("--json", action="store_true", help="print JSON instead of tables")
    parser.add_argument(
        "--record", metavar="LOG", help="simulate one walk (--surface, --seed, --duration) and write it as a .npz log"
    )
    parser.add_argument("--duration", type=float, default=LOG_SECONDS, help="seconds of walk for --record")
    parser.add_argument("--train", metavar="LOG", help="train on this recorded .npz log (needs --save)")
    parser.add_argument("--half", action="store_true", help="with --train: learn on the first half of the log")
    parser.add_argument(
        "--mismatch",
        action="store_true",
        help="the robustness table: held-out robots, the "
        "robot and run parameter spreads of demos.footstep_sim, the linear baseline",
    )
    parser.add_argument(
        "--spreads",
        type=_spread,
        nargs="+",
        default=list(SPREADS),
        metavar="R[:C]",
        help="with --mismatch: multiples of the documented robot (R) and run (C, default R) "
        "parameter ranges, each >= 0 (0:0 is the nominal simulator; default "
        f"{' '.join(f'{r:g}:{c:g}' for r, c in SPREADS)})",
    )
    parser.add_argument(
        "--save",
        metavar="PATH",
        help="with --train: save the models to PATH/apriori, "
        "PATH/online; with --mismatch: also write the JSON results to PATH",
    )
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl demo odometry` (see --help); returns the exit status."""
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    from mcl.tools.cli_checks import check_input_file, check_output_directory, check_output_file, save_and_print

    if args.mismatch:
        if args.train or args.record or args.curve or args.filter:
            parser.error("--mismatch goes alone (with --surface, --spreads, --seed, --json, --save)")
        from mcl.tools.cli_checks import progress_wanted

        check_output_file(args.save, "--save")
        surfaces = ("carpet", "grass") if args.surface == "both" else (args.surface,)
        result = mismatch(surfaces, tuple(args.spreads), seed=args.seed, progress=progress_wanted(args))
        save_and_print(result, args.save, args.json, _print_mismatch)
        return 0
    if args.train or args.save:
        if not (args.train and args.save):
            parser.error("--train LOG and --save DIR go together")
        check_input_file(args.train, "--train")  # before the training, not after it
        check_output_directory(args.save, "--save")
        try:
            result = train_command(args.train, args.save, args.seed, half=args.half)
        except ValueError as exc:
            print(f"robocup-mcl demo odometry: {exc}", file=sys.stderr)
            return 1
        print(
            json.dumps(result, indent=2)
            if args.json
            else f"trained on {result['steps']} steps of {args.train} ({result['surface']}): "
            + ", ".join(
                f"{k} → {v['directory']} (receptive fields dx/dy/dθ {v['receptive_fields']})"
                for k, v in result["saved"].items()
            )
        )
        return 0
    if args.record:
        check_output_file(args.record, "--record")
        surface = "grass" if args.surface == "both" else args.surface
        try:
            log = simulate(args.duration, surface, args.seed)
        except ValueError as exc:
            parser.error(str(exc))
        save_log(log, args.record)
        print(f"{log.n_steps} steps ({args.duration:g} s on {surface}, seed {args.seed}) written to {args.record}")
        return 0
    if args.filter_runs < 1:
        parser.error(f"--filter-runs {args.filter_runs} must be >= 1")
    surfaces = ["carpet", "grass"] if args.surface == "both" else [args.surface]
    from mcl.tools.cli_checks import progress_bar, progress_wanted

    from .lwpr_cross import warm_up_lwpr

    warm = warm_up_lwpr(progress_wanted(args))  # a machine's first run says it compiles LWPR's kernels
    started = time.perf_counter()
    result: dict = {"surfaces": {}, **warm.as_dict()}
    for surface in progress_bar(surfaces, enabled=progress_wanted(args), desc="odometry", unit="surface"):
        r = evaluate(surface, args.seed)
        entry = {"evaluation": r}
        if args.curve:
            entry["learning_curve"] = learning_curve(surface, args.seed, logs=r["_logs"])
        if args.filter:
            entry["filter"] = filter_comparison(surface, r["_models"], args.seed, args.filter_runs)
        result["surfaces"][surface] = entry
        if not args.json:
            _print_evaluation(r)
            if args.curve:
                _print_curve(entry["learning_curve"])
            if args.filter:
                _print_filter(surface, entry["filter"])
    result["seconds"] = time.perf_counter() - started
    if args.json:
        json.dump(_public(result), sys.stdout, indent=2)
        print()
    else:
        print(f"\n({result['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
