"""The velocity-estimation experiment: the paper's four estimators on simulated biped walks, with the EKF as the
paper wrote it and in the project's two variants.

    python -m demos.velocity                       # 28 s straight walk, twist and slip on, seed 0
    python -m demos.velocity --no-twist --json --seed 3 --duration 40
    robocup-mcl demo velocity --seeds 5 --rrd velocity.rrd     # the same, with a Rerun recording
    robocup-mcl demo velocity --mismatch --seeds 12            # the robustness table, seeds 1000-1011

    from demos.velocity import main, run_estimators
    from demos.biped import simulate_walk, RobotVariation
    result = run_estimators(simulate_walk(28.0, seed=0, variation=RobotVariation()))   # estimates and truth

The filters (`EKF_VARIANTS`, `VARIANT_SETTINGS`): "ekf (paper)", the paper's filter as written (state [g, v],
the raw gyro taken as zero-mean noise, F of eq. 24); "ekf variant: gyro zeroed standing", the same with the mean
gyro of the standing robot subtracted from every sample; "ekf variant: + gyro bias state", state [g, v, b], b
started at that mean, F with its rotation blocks. The baselines: the IMU alone (gyro zeroed standing), the
kinematics (eq. 10) and kinematics+gyro (eq. 14), on their own leg odometry, the gyro zeroed or raw as the fit
chose. Every estimator uses the published NAO legs (`ESTIMATOR_CHAINS`); the simulated robot's legs are drawn
per walk around them (`demos.biped.RobotVariation`), and so are its IMU's noise, bias, scale and drift.

The filters' noise settings come from `results/ekf_fit.json` (or `--fit PATH`), written by `robocup-mcl fit ekf`
from the training walks `TRAINING_SEEDS` (`demos.fit_velocity`); nothing here reads the simulator's
parameters. The figures refuse the training seeds.

Figures printed (all measured in this run, nothing fixed in advance), on robots drawn per walk with links within
±5 % (`--nominal`: the nominal robot):
1. Straight walk of `--duration` s (the paper's experiment, Section VI): the average forward velocity (IMU x
   axis, eq. 38 taken as a mean) of each estimator against the truth, and its error in percent; the error of
   the EKFs and of kinematics+gyro over `--seeds` seeds.
2. RMSE of the 3-D velocity over quarters of the run, straight and turning walks, foot twist on and off,
   evaluated at the kinematics samples where a support foot is known (every estimator on the same samples).
3. Tilt (direction of gravity) error of the EKFs and of the IMU alone, in degrees, on the run of figure 1, and
   the error of each EKF's gyro bias at the start and at the end of that run.
4. Time per EKF prediction and correction, numba kernel against the numpy reference, replaying the inputs of
   the run of figure 1, with the largest difference between the two state sequences.
5. The EKF as odometry for the particle filter (`proprioception.velocity_odometry`): the "ekf+bias" filter's velocity,
   levelled with its gravity estimate, and its bias-corrected gyro, summed over each filter step, against the
   commanded velocity. The walk (straight and turning, `--seeds` seeds) is placed on an SPL field
   (`PLACEMENTS`), the walk scenario's landmark camera (`demos.walk_sim`, its noise settings) gives a frame at
   every filter step (33.3 Hz: three IMU samples per step), and a ParticleFilter (VelocityLinear with its β
   scaled to the step, LandmarkSensorModel, `--particles`) runs once per odometry source, all on the same
   frames and from the same seed, started by `reset_around` the true start pose: the task is tracking, where
   odometry matters, not global localization, which the camera decides. Figures: position and heading RMSE
   over every filter step; the same with a sparse camera (one frame in `SPARSE_CAMERA_EVERY`, about 1 Hz);
   dead reckoning, the pose error at the end of the walk chaining the odometry alone from the true start.
   Sources: "ekf odometry"; "command", the gait's request as a walking engine with the walk scenario's
   execution error would have to be given it (a per-run scale per axis and a turn bias, from their own seed
   stream); "ideal command", the request the simulated trunk follows exactly (the simulator executes commands
   perfectly, so this is a bound, not a real robot's odometry).

With `--mismatch`, instead: the robustness table (`mismatch_table`), the average-forward-velocity error of every
estimator over straight walks from seed `HELD_OUT_FIRST_SEED`, on the nominal robot and on robots with links
within ±0, 2, 5 and 8 % (`MISMATCH_LEVELS`), median, worst, and the walks within the 5 % goal.

With `--rrd PATH`, a Rerun recording of the straight walk of `--seed`: the forward velocity of the truth and of
each estimator over time (`proprioception/forward_velocity/...`, the paper's Fig. 3), and figure 5's filter
with the EKF odometry (`particles`, `robot/estimate`, `robot/truth`, `observations`, `entropy/...`,
`error/...`) with the command filters' estimates (`robot/estimate_command`, `robot/estimate_ideal_command`,
`error/position_command`, `error/heading_command`) and the dead-reckoned poses (`robot/dead_reckoning/...`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time as _time
from pathlib import Path

import numpy as np

from demos.biped import (
    BipedRun,
    DisturbanceParams,
    GaitParams,
    RobotVariation,
    field_poses,
    gait_command,
    simulate_walk,
    turning_gait,
)
from demos.walk_sim import WalkScenario, _camera
from field.angles import wrap_angles
from mcl import ParticleFilter
from motion_models import MotionInput, VelocityLinear
from proprioception import reference as ekf_reference
from proprioception.kinematics import nao_leg
from proprioception.velocity import (
    ImuOnlyEstimator,
    LegOdometry,
    VelocityEKF,
    VelocityEKFParams,
    ekf_bias_predict_kernel,
    ekf_correct_kernel,
    ekf_predict_kernel,
    tilt_error,
)
from proprioception.velocity_odometry import EKFOdometry, compose_increments
from sensing import LandmarkSensorModel, Observations

EKF_VARIANTS = ("ekf", "ekf zeroed", "ekf+bias")
"""The filters compared: the paper's exactly as written, and the project's two variants (see `VARIANT_SETTINGS`)."""
BASELINES = ("imu", "kinematics", "kinematics+gyro")
ESTIMATORS = BASELINES + EKF_VARIANTS
LABELS = {
    "ekf": "ekf (paper)",
    "ekf zeroed": "ekf variant: gyro zeroed standing",
    "ekf+bias": "ekf variant: + gyro bias state",
    "imu": "imu alone",
    "kinematics": "kinematics",
    "kinematics+gyro": "kinematics+gyro",
}
VARIANT_SETTINGS = {
    # The paper's filter as written: state [g, v], the raw gyro (eq. 16-18 take it as zero-mean), F of eq. 24.
    "ekf": {"estimate_gyro_bias": False, "exact_jacobian": False, "zero_gyro": False},
    # The same with the mean gyro of the standing robot subtracted from every sample.
    "ekf zeroed": {"estimate_gyro_bias": False, "exact_jacobian": False, "zero_gyro": True},
    # The project's filter: state [g, v, b], b started at the standing mean, F with its rotation blocks.
    "ekf+bias": {"estimate_gyro_bias": True, "exact_jacobian": True, "zero_gyro": True},
}
STANDING_SAMPLES_TIME = 0.5  # s of standing data that initialize gravity (eq. 1)
TRAINING_SEEDS = tuple(range(100, 112))
"""Walks the noise settings are fitted on (`robocup-mcl fit ekf`); no figure is computed on them."""
HELD_OUT_FIRST_SEED = 1000  # the robustness table's walks: seeds 1000, 1001, ...
FIT_PATH = Path(__file__).resolve().parents[1] / "results" / "ekf_fit.json"
ESTIMATOR_CHAINS = (nao_leg("left"), nao_leg("right"))
"""The legs the estimators use: the published NAO dimensions (the simulated robot's legs are drawn around them)."""


def load_fit(path=None) -> dict:
    """The fit written by `robocup-mcl fit ekf --save PATH` (default `FIT_PATH`), as a dict."""
    path = FIT_PATH if path is None else Path(path)
    try:
        with open(path, encoding="utf-8") as stream:
            fit = json.load(stream)
    except OSError as error:
        raise ValueError(
            f"cannot read the EKF fit {path}: {error.strerror or error}; make it with "
            f"`robocup-mcl fit ekf --save {path}`"
        ) from None
    except json.JSONDecodeError as error:
        raise ValueError(f"the EKF fit {path} is not JSON: {error}") from None
    if not isinstance(fit, dict) or not isinstance(fit.get("variants"), dict):
        raise ValueError(f"the EKF fit {path} has no 'variants' table (written by `robocup-mcl fit ekf`)")
    missing = [name for name in EKF_VARIANTS if name not in fit["variants"]]
    if missing:
        raise ValueError(f"the EKF fit {path} lacks the variants {missing}")
    return fit


def ekf_params_for(fit: dict | None = None, variant: str = "ekf+bias") -> VelocityEKFParams:
    """The noise settings of EKF `variant` (one of `EKF_VARIANTS`) as fitted from training walks.

    `fit` is what `load_fit` returns (None: `load_fit()`, the results file). Nothing here reads the simulator's
    parameters: the settings are those `robocup-mcl fit ekf` chose on the training walks.
    """
    if variant not in EKF_VARIANTS:
        raise ValueError(f"variant must be one of {EKF_VARIANTS}, got {variant!r}")
    if fit is not None and not isinstance(fit, dict):
        raise ValueError(f"fit must be the dict of load_fit() (the fitted noise settings), got {type(fit).__name__}")
    fit = load_fit() if fit is None else fit
    fields = {f.name for f in dataclasses.fields(VelocityEKFParams)}
    values = {key: value for key, value in fit["variants"][variant].items() if key in fields}
    return VelocityEKFParams(**values)


def variant_params(noise: dict, variant: str) -> VelocityEKFParams:
    """VelocityEKFParams of `variant` with the noise settings `noise` (field name → value) and the variant's
    structure (`VARIANT_SETTINGS`)."""
    structure = {key: value for key, value in VARIANT_SETTINGS[variant].items() if key != "zero_gyro"}
    return VelocityEKFParams(**{**noise, **structure})


def default_variants(fit: dict | None = None) -> dict:
    """The three filters compared (`EKF_VARIANTS`), with their fitted noise settings."""
    fit = load_fit() if fit is None else fit
    return {name: ekf_params_for(fit, name) for name in EKF_VARIANTS}


def run_estimators(
    run: BipedRun,
    params: dict | None = None,
    backend: str = "numba",
    zero_gyro: dict | None = None,
    kinematics_zero_gyro: bool = True,
) -> dict:
    """Run the estimators over one simulated walk; returns per-sample estimates, truth and the EKF inputs.

    `params` maps a name to the VelocityEKFParams of one EKF (default: `default_variants()`); each EKF has its
    own `LegOdometry` on `ESTIMATOR_CHAINS` (the published legs, not the run's). All start from the first
    `STANDING_SAMPLES_TIME` seconds, when the robot stands still (eq. 1). `zero_gyro` maps an EKF's name to
    whether it is given the standing gyro samples (their mean removed as the bias, or the bias state started
    there); default `VARIANT_SETTINGS[name]["zero_gyro"]`, True for other names. The IMU alone takes them too;
    the kinematic estimates take them when `kinematics_zero_gyro` (their own leg odometry, the gyro less the
    standing mean, or raw). Per EKF `name`: `{name}_velocity`, `{name}_gravity`, `{name}_gyro_bias` (IMU rate),
    and under `kin`, `events`, `params`, `initial_state`, `initial_covariance`.
    """
    params = default_variants() if params is None else dict(params)
    if not params:
        raise ValueError("params must name at least one EKF")
    names = tuple(params)
    zeroed = {name: VARIANT_SETTINGS.get(name, {}).get("zero_gyro", True) for name in names}
    zeroed.update(zero_gyro or {})
    n0 = int(np.searchsorted(run.imu_time, STANDING_SAMPLES_TIME, side="right")) - 1
    t0 = float(run.imu_time[n0])
    standing = run.accel[: n0 + 1]
    standing_gyro = run.gyro[: n0 + 1]
    imu_only = ImuOnlyEstimator.from_standing(standing, t0, gyro_samples=standing_gyro)
    filters = {
        name: VelocityEKF.from_standing(
            standing, t0, params=p, backend=backend, gyro_samples=standing_gyro if zeroed[name] else None
        )
        for name, p in params.items()
    }
    odometries = {name: LegOdometry(ESTIMATOR_CHAINS, ekf) for name, ekf in filters.items()}
    # The kinematic baselines: a leg odometry of their own (its filter's output is not used; its constant gyro
    # bias is the standing mean, or zero).
    first = params[names[0]]
    baseline = LegOdometry(
        ESTIMATOR_CHAINS,
        VelocityEKF.from_standing(
            standing,
            t0,
            params=dataclasses.replace(first, estimate_gyro_bias=False),
            backend=backend,
            gyro_samples=standing_gyro if kinematics_zero_gyro else None,
        ),
    )
    n_imu = run.imu_time.shape[0]
    result = {
        "t0": t0,
        "n0": n0,
        "ekf_names": names,
        "params": params,
        "events": {},
        "zero_gyro": zeroed,
        "kinematics_zero_gyro": kinematics_zero_gyro,
        "initial_state": {name: ekf.state for name, ekf in filters.items()},
        "initial_covariance": {name: ekf.covariance for name, ekf in filters.items()},
    }
    for name in ("imu",) + names:
        for quantity in ("velocity", "gravity", "gyro_bias"):
            result[f"{name}_{quantity}"] = np.full((n_imu, 3), np.nan)
    result["imu_velocity"][n0], result["imu_gravity"][n0] = imu_only.velocity, imu_only.gravity
    for name, ekf in filters.items():
        result[f"{name}_velocity"][n0], result[f"{name}_gravity"][n0] = ekf.velocity, ekf.gravity
        result[f"{name}_gyro_bias"][n0] = ekf.gyro_bias
        result["events"][name] = []  # EKF inputs in order, for the timing replay
    kin_first = int(np.searchsorted(run.kin_time, t0, side="left"))
    n_kin = run.kin_time.shape[0]
    kin = {name: np.full((n_kin, 3), np.nan) for name in BASELINES + names}
    foot = np.full(n_kin, -1)
    i, k = n0 + 1, kin_first
    while i < n_imu or k < n_kin:
        if k >= n_kin or (i < n_imu and run.imu_time[i] <= run.kin_time[k]):
            imu_only.update(run.imu_time[i], run.gyro[i], run.accel[i])
            result["imu_velocity"][i], result["imu_gravity"][i] = imu_only.velocity, imu_only.gravity
            baseline.imu(run.imu_time[i], run.gyro[i], run.accel[i])
            dt = run.imu_time[i] - run.imu_time[i - 1]
            for name, ekf in filters.items():
                # The bias filter takes the raw gyro (it subtracts its own b); the others, the gyro less their
                # constant bias (the standing mean, or zero for the paper's filter).
                gyro = run.gyro[i] if ekf.params.estimate_gyro_bias else run.gyro[i] - ekf.gyro_bias
                odometries[name].imu(run.imu_time[i], run.gyro[i], run.accel[i])
                result["events"][name].append(("predict", dt, gyro, run.accel[i]))
                result[f"{name}_velocity"][i], result[f"{name}_gravity"][i] = ekf.velocity, ekf.gravity
                result[f"{name}_gyro_bias"][i] = ekf.gyro_bias
            i += 1
        else:
            sample = baseline.kinematics(run.kin_time[k], run.joint_angles[k], run.contacts[k])
            foot[k] = sample.foot
            if sample.foot >= 0:
                kin["kinematics"][k] = sample.velocity_kinematic
                kin["kinematics+gyro"][k] = sample.velocity_kinematic_gyro
            for name, odometry in odometries.items():
                sample = odometry.kinematics(run.kin_time[k], run.joint_angles[k], run.contacts[k])
                if sample.foot >= 0:
                    result["events"][name].append(("correct", sample.velocity_kinematic_gyro))
                kin[name][k] = filters[name].velocity
            kin["imu"][k] = imu_only.velocity
            k += 1
    result["kin"] = kin
    result["foot"] = foot
    return result


def _names(result: dict) -> tuple:
    return BASELINES + tuple(result["ekf_names"])


def average_forward_velocity(run: BipedRun, result: dict) -> dict:
    """Figure 1: mean of v_x (IMU frame) per estimator and of the truth over the same samples."""
    out = {}
    n0 = result["n0"]
    for name in _names(result):
        if name in ("kinematics", "kinematics+gyro"):
            valid = result["foot"] >= 0
            est = result["kin"][name][valid, 0]
            true = run.true_kin_velocity[valid, 0]
        else:
            est = result[f"{name}_velocity"][n0:, 0]
            true = run.true_velocity[n0:, 0]
        mean_est, mean_true = float(np.mean(est)), float(np.mean(true))
        out[name] = {
            "estimate_m_s": mean_est,
            "truth_m_s": mean_true,
            "error_percent": 100.0 * abs(mean_est - mean_true) / abs(mean_true),
        }
    return out


def rmse_windows(run: BipedRun, result: dict, n_windows: int = 4) -> dict:
    """Figure 2: RMSE (m/s) of the velocity vector per estimator over equal windows, at the common samples."""
    valid = result["foot"] >= 0
    t = run.kin_time
    edges = np.linspace(result["t0"], t[-1] + 1e-9, n_windows + 1)
    out = {}
    for name in _names(result):
        err = np.linalg.norm(result["kin"][name] - run.true_kin_velocity, axis=1)
        row = []
        for w in range(n_windows):
            mask = valid & (t >= edges[w]) & (t < edges[w + 1])
            row.append(float(np.sqrt(np.mean(err[mask] ** 2))))
        row.append(float(np.sqrt(np.mean(err[valid] ** 2))))
        out[name] = row
    out["windows_s"] = [[float(edges[w]), float(edges[w + 1])] for w in range(n_windows)]
    return out


def tilt_figures(run: BipedRun, result: dict) -> dict:
    """Figure 3: tilt error in degrees of each EKF and of the IMU alone; gyro bias error of each EKF.

    The bias error is the final `gyro_bias` of a filter against the run's true bias, taken as the mean of
    measured minus true rate over the whole run (its own error, σ/√N, is about 0.2 mrad/s).
    """
    n0 = result["n0"]
    out = {}
    true_bias = np.mean(run.gyro - run.true_omega, axis=0)
    for name in tuple(result["ekf_names"]) + ("imu",):
        err = np.degrees(tilt_error(result[f"{name}_gravity"][n0:], run.true_gravity[n0:]))
        out[name] = {
            "mean_deg": float(err.mean()),
            "rms_deg": float(np.sqrt(np.mean(err**2))),
            "max_deg": float(err.max()),
            "final_deg": float(err[-1]),
        }
        if name != "imu":
            out[name]["start_gyro_bias_error_mrad_s"] = (1e3 * (result[f"{name}_gyro_bias"][n0] - true_bias)).tolist()
            out[name]["final_gyro_bias_error_mrad_s"] = (1e3 * (result[f"{name}_gyro_bias"][-1] - true_bias)).tolist()
    return out


def timing(result: dict, name: str = "ekf", repeats: int = 3) -> dict:
    """Figure 4: replay the inputs of EKF `name` through the numba kernels and the numpy references, timing each."""
    p = result["params"][name]
    events = result["events"][name]
    if p.estimate_gyro_bias:

        def predict_kernel(state, cov, gyro, accel, dt):
            ekf_bias_predict_kernel(
                state, cov, gyro, accel, dt, p.gyro_noise, p.accel_noise, p.gyro_bias_random_walk, p.exact_jacobian
            )

        def predict_reference(state, cov, gyro, accel, dt):
            return ekf_reference.ekf_bias_predict(
                state, cov, gyro, accel, dt, p.gyro_noise, p.accel_noise, p.gyro_bias_random_walk, p.exact_jacobian
            )
    else:

        def predict_kernel(state, cov, gyro, accel, dt):
            ekf_predict_kernel(state, cov, gyro, accel, dt, p.gyro_noise, p.accel_noise, p.exact_jacobian)

        def predict_reference(state, cov, gyro, accel, dt):
            return ekf_reference.ekf_predict(state, cov, gyro, accel, dt, p.gyro_noise, p.accel_noise, p.exact_jacobian)

    def replay(kind):
        state = result["initial_state"][name].copy()
        cov = result["initial_covariance"][name].copy()
        t_predict = t_correct = 0
        n_predict = n_correct = 0
        states = np.empty((len(events), state.size))
        clock = _time.perf_counter_ns
        for e, event in enumerate(events):
            if event[0] == "predict":
                _, dt, gyro, accel = event
                start = clock()
                if kind == "numba":
                    predict_kernel(state, cov, gyro, accel, dt)
                else:
                    state, cov = predict_reference(state, cov, gyro, accel, dt)
                t_predict += clock() - start
                n_predict += 1
            else:
                start = clock()
                if kind == "numba":
                    ekf_correct_kernel(state, cov, event[1], p.velocity_noise)
                else:
                    state, cov = ekf_reference.ekf_correct(state, cov, event[1], p.velocity_noise)
                t_correct += clock() - start
                n_correct += 1
            states[e] = state
        return t_predict / max(n_predict, 1) / 1e3, t_correct / max(n_correct, 1) / 1e3, states, n_predict, n_correct

    replay("numba")  # compile (or load from cache) outside the timing
    best = {}
    for kind in ("numba", "reference"):
        runs = [replay(kind) for _ in range(repeats)]
        best[kind] = (min(r[0] for r in runs), min(r[1] for r in runs), runs[0][2], runs[0][3], runs[0][4])
    diff = float(np.max(np.abs(best["numba"][2] - best["reference"][2])))
    return {
        "numba_predict_us": best["numba"][0],
        "numba_correct_us": best["numba"][1],
        "reference_predict_us": best["reference"][0],
        "reference_correct_us": best["reference"][1],
        "predictions": best["numba"][3],
        "corrections": best["numba"][4],
        "max_state_difference": diff,
    }


# ---------------------------------------------------------------------------------------------------------
# Figure 5: the EKF as odometry for the particle filter, against the commanded velocity
# ---------------------------------------------------------------------------------------------------------
FILTER_EVERY = 3  # IMU samples per filter step: 100 Hz IMU → 33.3 Hz filter and camera
PLACEMENTS = {"straight": (-3.5, -1.0, 0.0), "turning": (-3.0, -2.0, 0.0)}  # field pose of the walk's start
ODOMETRY_SOURCES = ("ekf odometry", "command", "ideal command")
ODOMETRY_EKF = "ekf+bias"  # the EKF variant whose velocity and bias-corrected gyro make the odometry
RESET_SIGMA = (0.1, 0.1, 0.1)  # m, m, rad: the filter starts around the true start pose
CAMERA_STREAM, EXECUTION_STREAM = 1, 2  # seed streams: camera noise, the walking engine's execution error
MOTION_RATE_REFERENCE = 0.01  # s: the step for which VelocityLinear's β are set (its docstring)
SPARSE_CAMERA_EVERY = 33  # the sparse camera keeps one frame in 33: about one per second


def walk_gait(walk: str, duration: float) -> GaitParams:
    """The gait of a "straight" or "turning" walk of `duration` seconds."""
    if walk not in PLACEMENTS:
        raise ValueError(f"walk must be one of {tuple(PLACEMENTS)}, got {walk!r}")
    return GaitParams() if walk == "straight" else turning_gait(duration)


def filter_steps(run: BipedRun, n0: int, every: int = FILTER_EVERY) -> np.ndarray:
    """IMU indices of the filter steps: n0 (the start, no step) and every `every`-th sample after it."""
    if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
        raise ValueError(f"every must be an integer >= 1, got {every!r}")
    return np.arange(n0, run.imu_time.shape[0], every)


def ekf_odometry(run: BipedRun, steps: np.ndarray, params: VelocityEKFParams | None = None) -> np.ndarray:
    """The EKF odometry (M - 1, 3) between consecutive filter steps `steps` (IMU indices, steps[0] = start).

    One `EKFOdometry` over the whole run, samples in time order as in `run_estimators` (an IMU sample before a
    kinematics sample of the same time), started from the standing robot at steps[0] (eq. 1, gyro zeroed);
    `take()` right after the IMU sample of each filter step.
    """
    params = ekf_params_for(None, ODOMETRY_EKF) if params is None else params
    n0 = int(steps[0])
    t0 = float(run.imu_time[n0])
    ekf = VelocityEKF.from_standing(run.accel[: n0 + 1], t0, params=params, gyro_samples=run.gyro[: n0 + 1])
    odometry = EKFOdometry(LegOdometry(ESTIMATOR_CHAINS, ekf))
    is_step = np.zeros(run.imu_time.shape[0], dtype=bool)
    is_step[steps[1:]] = True
    out = np.empty((steps.shape[0] - 1, 3))
    m = 0
    n_kin = run.kin_time.shape[0]
    i, k = n0 + 1, int(np.searchsorted(run.kin_time, t0, side="left"))
    last = int(steps[-1])
    while i <= last:
        if k >= n_kin or run.imu_time[i] <= run.kin_time[k]:
            odometry.imu(run.imu_time[i], run.gyro[i], run.accel[i])
            if is_step[i]:
                out[m] = odometry.take().odometry
                m += 1
            i += 1
        else:
            odometry.kinematics(run.kin_time[k], run.joint_angles[k], run.contacts[k])
            k += 1
    return out


def execution_error(seed: int, scenario: WalkScenario = WalkScenario()) -> tuple[np.ndarray, float]:
    """Per-run error of the walking engine, as in the walk scenario: scale of (vx, vy, ω) and a turn bias (rad/s).

    Drawn from its own stream of `seed`, so the walk and its sensors are the same with and without it.
    """
    rng = np.random.default_rng([seed, EXECUTION_STREAM])
    scale = 1.0 + scenario.odometry_scale_sigma * rng.standard_normal(3)
    return scale, float(scenario.turn_bias_sigma * rng.standard_normal())


def commanded_velocity(
    run: BipedRun, steps: np.ndarray, seed: int, ideal: bool = False, scenario: WalkScenario = WalkScenario()
) -> np.ndarray:
    """The walk request (M - 1, 3) of each filter step: the gait's command at the step's middle.

    The simulated trunk follows the gait's request exactly (`gait_command`); a real walking engine does not.
    With `ideal` the command is that request; otherwise it is the request a walking engine with the walk
    scenario's execution error (`execution_error`: executed = scale · command + turn bias while walking) had
    to be given to walk the simulated path. The robot "walks" when the request's vx exceeds 0.02 m/s.
    """
    t = run.imu_time[steps]
    command = gait_command(run.gait, (t[:-1] + t[1:]) / 2.0)
    if ideal:
        return command
    scale, turn_bias = execution_error(seed, scenario)
    walking = command[:, 0] > 0.02
    out = command / scale
    out[:, 2] = (command[:, 2] - np.where(walking, turn_bias, 0.0)) / scale[2]
    return out


def camera_frames(truth: np.ndarray, times: np.ndarray, seed: int, scenario: WalkScenario = WalkScenario()) -> list:
    """One landmark camera frame per filter step (the walk scenario's camera and noise) at the true poses."""
    rng = np.random.default_rng([seed, CAMERA_STREAM])
    frames = []
    for pose, t in zip(truth, times):
        head = scenario.head_pan_amplitude * math.sin(2.0 * math.pi * t / scenario.head_pan_period)
        frames.append(_camera(scenario, pose, head, rng))
    return frames


def motion_model_for(dt: float) -> VelocityLinear:
    """VelocityLinear with its β scaled to the filter step: the noise is a random walk (its docstring)."""
    factor = math.sqrt(MOTION_RATE_REFERENCE / dt)
    base = VelocityLinear()
    return VelocityLinear(
        beta1=base.beta1 * factor, beta2=base.beta2 * factor, beta3=base.beta3 * factor, beta4=base.beta4 * factor
    )


def _pose_errors(estimates: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (
        np.hypot(estimates[:, 0] - truth[:, 0], estimates[:, 1] - truth[:, 1]),
        np.abs(wrap_angles(estimates[:, 2] - truth[:, 2])),
    )


def odometry_run(
    run: BipedRun, seed: int, walk: str, particles: int = 500, recorder=None, params: VelocityEKFParams | None = None
) -> dict:
    """Figure 5 for one walk: the filter and dead reckoning with each odometry source (`ODOMETRY_SOURCES`).

    The walk is placed on an SPL field at `PLACEMENTS[walk]`; a camera frame (the walk scenario's landmark
    camera) arrives at every filter step. Each source drives its own ParticleFilter (VelocityLinear scaled to
    the step, LandmarkSensorModel, `particles` particles, seed `seed`, started by `reset_around` the true
    start pose with `RESET_SIGMA`) on the same frames; and again with a sparse camera, which keeps one frame in
    `SPARSE_CAMERA_EVERY` (the rest empty). Dead reckoning chains the source's pose changes from the true
    start pose (the motion model's mean, no camera). Errors are taken at every filter step, against the
    trunk's pose. With a `mcl.tools.recording.Recorder`, the EKF odometry filter with the full camera is logged by
    `log_step` and the command filters' estimates beside it. `params`: the EKF's (default: the fitted
    `ODOMETRY_EKF`).
    """
    if walk not in PLACEMENTS:
        raise ValueError(f"walk must be one of {tuple(PLACEMENTS)}, got {walk!r}")
    scenario = WalkScenario()
    n0 = int(np.searchsorted(run.imu_time, STANDING_SAMPLES_TIME, side="right")) - 1
    steps = filter_steps(run, n0)
    if steps.shape[0] < 2:
        raise ValueError(f"the walk is too short for a filter step after {run.imu_time[n0]:.2f} s")
    truth = field_poses(run, PLACEMENTS[walk])[steps]
    times = run.imu_time[steps]
    dts = np.diff(times)
    frames = camera_frames(truth[1:], times[1:], seed, scenario)
    empty = Observations.from_arrays([], [], [])
    sparse = [frame if (m + 1) % SPARSE_CAMERA_EVERY == 0 else empty for m, frame in enumerate(frames)]
    odometry = ekf_odometry(run, steps, params)
    ideal = commanded_velocity(run, steps, seed, ideal=True, scenario=scenario)
    inputs = {
        "ekf odometry": [MotionInput(dt=dt, odometry=tuple(d)) for dt, d in zip(dts, odometry)],
        "command": [
            MotionInput(dt=dt, command=tuple(c))
            for dt, c in zip(dts, commanded_velocity(run, steps, seed, scenario=scenario))
        ],
        "ideal command": [MotionInput(dt=dt, command=tuple(c)) for dt, c in zip(dts, ideal)],
    }
    field = scenario.field
    sensor = LandmarkSensorModel(field)
    model = motion_model_for(float(dts[0]))
    dead = {
        source: compose_increments([u.displacement() for u in inputs[source]], truth[0]) for source in ODOMETRY_SOURCES
    }
    estimates = {}
    for camera, camera_frames_used in (("camera", frames), ("sparse camera", sparse)):
        filters = {}
        for source in ODOMETRY_SOURCES:
            pf = ParticleFilter(field, model, sensor, n_particles=particles, seed=seed)
            pf.reset_around(truth[0], sigma=RESET_SIGMA)
            filters[source] = pf
            estimates[camera, source] = np.empty((steps.shape[0] - 1, 3))
        for m, frame in enumerate(camera_frames_used):
            for source, pf in filters.items():
                pf.predict(inputs[source][m])
                pf.correct(frame)
                estimates[camera, source][m] = pf.estimate().pose
            if recorder is not None and camera == "camera":
                _record_filter_step(
                    recorder,
                    m + 1,
                    float(times[m + 1]),
                    filters,
                    truth[m + 1],
                    frame,
                    {source: estimates[camera, source] for source in ODOMETRY_SOURCES},
                    dead,
                    m,
                )
    out = {
        "walk": walk,
        "seed": seed,
        "start": list(PLACEMENTS[walk]),
        "steps": int(steps.shape[0] - 1),
        "path_length_m": float(np.sum(ideal[:, 0] * dts)),
        "turned_deg": float(np.degrees(run.trunk_yaw[steps[-1]] - run.trunk_yaw[n0])),
    }
    for source in ODOMETRY_SOURCES:
        figures = {}
        for camera, prefix in (("camera", ""), ("sparse camera", "sparse_camera_")):
            position, heading = _pose_errors(estimates[camera, source], truth[1:])
            figures[f"{prefix}position_rmse_m"] = float(np.sqrt(np.mean(position**2)))
            figures[f"{prefix}heading_rmse_deg"] = float(np.degrees(np.sqrt(np.mean(heading**2))))
            figures[f"{prefix}max_position_error_m"] = float(position.max())
        dead_position, dead_heading = _pose_errors(dead[source][-1:], truth[-1:])
        figures["dead_reckoning_position_m"] = float(dead_position[0])
        figures["dead_reckoning_heading_deg"] = float(np.degrees(dead_heading[0]))
        out[source] = figures
    return out


def summarize_odometry(runs: list[dict]) -> dict:
    """Median and maximum over seeds of each figure of each source."""
    out = {}
    for source in ODOMETRY_SOURCES:
        out[source] = {}
        for key in runs[0][source]:
            values = [r[source][key] for r in runs]
            out[source][key] = {"median": float(np.median(values)), "max": float(np.max(values))}
    return out


# --- recording ---------------------------------------------------------------------------------------------
FORWARD_VELOCITY = "proprioception/forward_velocity"
SERIES_STYLE = {
    "truth": ((240, 240, 240), "truth"),
    "imu": ((230, 80, 80), "IMU only"),
    "kinematics": ((80, 160, 255), "kinematics"),
    "kinematics_gyro": ((80, 220, 120), "kinematics+gyro"),
    "ekf": ((255, 200, 40), "EKF (paper)"),
    "ekf_zeroed": ((200, 160, 255), "EKF variant: gyro zeroed"),
    "ekf_bias": ((255, 120, 0), "EKF variant: + gyro bias state"),
}
OTHER_SOURCES = {
    "command": ("robot/estimate_command", (60, 140, 255)),
    "ideal command": ("robot/estimate_ideal_command", (200, 200, 255)),
}


def velocity_blueprint():
    from mcl.tools.recording import default_blueprint

    return default_blueprint(
        (
            (f"/{FORWARD_VELOCITY}", "forward velocity [m/s] (paper, Fig. 3)"),
            ("/error", "error [m, rad]"),
            ("/entropy", "entropy [bits]"),
        )
    )


def record_velocities(recorder, run: BipedRun, result: dict) -> None:
    """The paper's Fig. 3 as scalar series on the `time` timeline: forward velocity (IMU x axis) of the truth
    and of each estimator; the kinematic estimates at the kinematics samples with a support foot."""
    import rerun as rr

    stream = recorder.stream
    n0 = result["n0"]
    valid = result["foot"] >= 0
    series = {
        "truth": (run.imu_time[n0:], run.true_velocity[n0:, 0]),
        "imu": (run.imu_time[n0:], result["imu_velocity"][n0:, 0]),
        "kinematics": (run.kin_time[valid], result["kin"]["kinematics"][valid, 0]),
        "kinematics_gyro": (run.kin_time[valid], result["kin"]["kinematics+gyro"][valid, 0]),
        "ekf": (run.imu_time[n0:], result["ekf_velocity"][n0:, 0]),
        "ekf_zeroed": (run.imu_time[n0:], result["ekf zeroed_velocity"][n0:, 0]),
        "ekf_bias": (run.imu_time[n0:], result["ekf+bias_velocity"][n0:, 0]),
    }
    for name, (times, values) in series.items():
        color, label = SERIES_STYLE[name]
        path = f"{FORWARD_VELOCITY}/{name}"
        if name.startswith("kinematics"):
            stream.log(path, rr.SeriesPoints(names=label, colors=[color], marker_sizes=[1.5]), static=True)
        else:
            stream.log(path, rr.SeriesLines(names=label, colors=[color]), static=True)
        stream.send_columns(
            path,
            indexes=[rr.TimeColumn("time", duration=np.array(times, dtype=np.float64))],
            columns=rr.Scalars.columns(scalars=np.array(values, dtype=np.float64)),
        )
    for path, label, color in (
        ("error/position_command", "position, command [m]", (60, 140, 255)),
        ("error/heading_command", "heading, command [rad]", (160, 80, 255)),
    ):
        stream.log(path, rr.SeriesLines(names=label, colors=[color]), static=True)


def _arrow(pose: np.ndarray, color):
    import rerun as rr

    return rr.Arrows2D(
        origins=[pose[:2].copy()],
        vectors=[0.35 * np.array([math.cos(pose[2]), math.sin(pose[2])])],
        colors=[color],
        radii=0.02,
    )


def _record_filter_step(
    recorder, step: int, t: float, filters: dict, truth: np.ndarray, frame, estimates: dict, dead: dict, m: int
) -> None:
    """The EKF odometry filter through `Recorder.log_step`; the command filters' estimates and errors, and
    the dead-reckoned poses, beside it."""
    import rerun as rr

    recorder.log_step(step, t, filters["ekf odometry"], truth=truth, observations=frame)
    log = recorder.stream.log
    for source, (path, color) in OTHER_SOURCES.items():
        log(path, _arrow(estimates[source][m], color))
    position, heading = _pose_errors(estimates["command"][m : m + 1], truth[None, :])
    log("error/position_command", rr.Scalars(float(position[0])))
    log("error/heading_command", rr.Scalars(float(heading[0])))
    log("robot/dead_reckoning/ekf_odometry", _arrow(dead["ekf odometry"][m], (255, 160, 160)))
    log("robot/dead_reckoning/command", _arrow(dead["command"][m], (160, 200, 255)))


def write_recording(
    path: str,
    run: BipedRun,
    result: dict,
    seed: int,
    walk: str,
    particles: int,
    params: VelocityEKFParams | None = None,
) -> dict:
    """The .rrd of `--rrd`: Fig. 3's velocities of `run` and the filters on the same walk; returns figure 5's
    numbers for that walk (the same as without a recording). `params`: the odometry EKF's (`odometry_run`)."""
    from mcl.tools.recording import Recorder

    recorder = Recorder(path, WalkScenario().field, particles_every=5, blueprint=velocity_blueprint())
    try:
        record_velocities(recorder, run, result)
        return odometry_run(run, seed, walk, particles, recorder=recorder, params=params)
    finally:
        recorder.close()


def _robot_line(report: dict) -> str:
    """One line saying which robots were simulated and where the noise settings come from."""
    v = report["variation"]
    training = report.get("fit_training_seeds") or []
    fitted = (
        f"noise settings fitted on training seeds {training[0]}-{training[-1]} (robocup-mcl fit ekf)"
        if training
        else "noise settings from the fit file"
    )
    if v["link_length_error"] == 0.0 and v["backlash"][1] == 0.0 and v["accel_scale_error"] == 0.0:
        return f"Simulated robot: the nominal one (published legs, datasheet sensors); {fitted}."
    return (
        f"Simulated robots drawn per walk: links +-{100 * v['link_length_error']:.0f} %, joint zeros "
        f"+-{math.degrees(v['joint_zero_error']):.1f} deg, backlash up to {math.degrees(v['backlash'][1]):.1f} deg, "
        f"IMU noise, bias, scale and gyro drift per run (demos.biped.RobotVariation); {fitted}."
    )


def _format(report: dict) -> str:
    lines = []
    f1 = report["average_forward_velocity"]
    variants = tuple(report["ekf_names"])
    names = BASELINES + variants
    label = {name: LABELS.get(name, name) for name in names}
    width = max(19, max(len(label[name]) for name in names) + 2)
    lines.append(_robot_line(report))
    lines.append(
        f"Figure 1. Average forward velocity, {report['duration']:.0f} s straight walk "
        f"(seed {report['seed']}, twist {'on' if report['twist'] else 'off'}, "
        f"slip {'on' if report['slip'] else 'off'})"
    )
    lines.append(f"  {'estimator':<{width}}{'estimate cm/s':>14}{'truth cm/s':>12}{'error %':>10}")
    for name in names:
        r = f1[name]
        lines.append(
            f"  {label[name]:<{width}}{100 * r['estimate_m_s']:>14.2f}{100 * r['truth_m_s']:>12.2f}"
            f"{r['error_percent']:>10.1f}"
        )
    spread = report["seed_spread"]
    seeds = spread["seeds"]
    lines.append(f"  Error % over seeds {seeds[0]}-{seeds[-1]} (goal <= 5 %):")
    for name in variants + ("kinematics+gyro",):
        errors = spread[f"{name}_error_percent"]
        missed = [s for s, e in zip(seeds, errors) if e > 5.0]
        lines.append(
            f"    {label[name]:<{width}}"
            + ", ".join(f"{x:.1f}" for x in errors)
            + f"  (median {np.median(errors):.1f}, max {max(errors):.1f}; goal "
            + (
                "met on every seed)"
                if not missed
                else f"MISSED on seed{'s' if len(missed) > 1 else ''} " + ", ".join(str(s) for s in missed) + ")"
            )
        )
    lines.append("")
    lines.append("Figure 2. Velocity RMSE (cm/s) over quarters of the run, at kinematics samples with a support foot")
    for key, block in report["rmse"].items():
        windows = block["windows_s"]
        header = "".join(f"{f'{a:.0f}-{b:.0f} s':>10}" for a, b in windows)
        lines.append(f"  {key}")
        lines.append(f"    {'estimator':<{width}}{header}{'all':>10}")
        for name in names:
            lines.append(f"    {label[name]:<{width}}" + "".join(f"{100 * x:>10.2f}" for x in block[name]))
        best_single = min(block[name][-1] for name in names[:3])
        below = ", ".join(f"{label[name]} {'yes' if block[name][-1] < best_single else 'NO'}" for name in variants)
        lines.append(
            f"    EKF below every single-source estimate: {below}"
            f"; IMU-only growing: {'yes' if all(np.diff(block['imu'][:-1]) > 0) else 'NO'}"
        )
    lines.append("")
    tilt = report["tilt"]
    lines.append(
        "Figure 3. Tilt (gravity direction) error, degrees, run of figure 1; gyro bias error, mrad/s (x, y, z)"
    )
    for name in variants + ("imu",):
        r = tilt[name]
        lines.append(
            f"  {label.get(name, name):<{width}}mean {r['mean_deg']:.3f}  rms {r['rms_deg']:.3f}  "
            f"max {r['max_deg']:.3f}  final {r['final_deg']:.3f}"
        )
    for name in variants:
        r = tilt[name]
        start = ", ".join(f"{x:+.2f}" for x in r["start_gyro_bias_error_mrad_s"])
        final = ", ".join(f"{x:+.2f}" for x in r["final_gyro_bias_error_mrad_s"])
        lines.append(f"  {label[name]:<{width}}bias error at start ({start}), at the end ({final})")
    lines.append("")
    first = report["timing"][variants[0]]
    lines.append(
        f"Figure 4. Time per EKF step, run of figure 1 ({first['predictions']} predictions, "
        f"{first['corrections']} corrections; best of 3 replays)"
    )
    lines.append(f"  {'':<{width + 12}}{'predict us':>12}{'correct us':>12}")
    for name in variants:
        tm = report["timing"][name]
        for kind in ("numba", "reference"):
            lines.append(
                f"  {label[name] + ', ' + kind:<{width + 12}}{tm[f'{kind}_predict_us']:>12.2f}"
                f"{tm[f'{kind}_correct_us']:>12.2f}"
            )
        lines.append(
            f"  {'':<{width + 12}}speed-up: "
            f"predict x{tm['reference_predict_us'] / tm['numba_predict_us']:.0f}, "
            f"correct x{tm['reference_correct_us'] / tm['numba_correct_us']:.0f}; "
            f"largest state difference {tm['max_state_difference']:.2e}"
        )
    lines.append("")
    lines.extend(_format_odometry(report["odometry"]))
    return "\n".join(lines)


ODOMETRY_COLUMNS = (
    ("camera", "position_rmse_m", 100.0),
    ("camera", "heading_rmse_deg", 1.0),
    ("sparse camera", "sparse_camera_position_rmse_m", 100.0),
    ("sparse camera", "sparse_camera_heading_rmse_deg", 1.0),
    ("dead reckoning", "dead_reckoning_position_m", 100.0),
    ("dead reckoning", "dead_reckoning_heading_deg", 1.0),
)


def _format_odometry(odometry: dict) -> list[str]:
    seeds = odometry["seeds"]
    lines = [
        f"Figure 5. Particle filter on an SPL field with the EKF odometry ({LABELS[odometry['ekf']]}, levelled, "
        "summed per filter step)",
        f"  versus the commanded velocity: {odometry['particles']} particles at "
        f"{odometry['filter_rate_hz']:.1f} Hz, VelocityLinear, landmark camera every step (sparse: one frame "
        f"in {odometry['sparse_camera_every']}),",
        "  started around the true start pose; dead reckoning: the odometry alone from the true start pose, "
        "error at the end.",
        f"  Medians over seeds {seeds[0]}-{seeds[-1]} (max in brackets); position in cm, heading in degrees."
        if len(seeds) > 1
        else f"  Seed {seeds[0]} (medians and max of one run); position in cm, heading in degrees.",
    ]
    width = 16
    head1 = "".join(f"{group:^28}" for group in ("camera", "sparse camera", "dead reckoning"))
    head2 = "".join(f"{'position':>14}{'heading':>14}" for _ in range(3))
    for walk, block in odometry["walks"].items():
        first = block["runs"][0]
        lines.append(
            f"  {walk} walk ({first['path_length_m']:.2f} m walked, turning {first['turned_deg']:.0f} deg; "
            f"start at {tuple(first['start'])})"
        )
        lines.append(f"    {'':<{width}}{head1}")
        lines.append(f"    {'source':<{width}}{head2}")
        for source in odometry["sources"]:
            summary = block["summary"][source]
            cells = "".join(
                f"{scale * summary[key]['median']:>7.1f} ({scale * summary[key]['max']:>5.1f})"
                for _, key, scale in ODOMETRY_COLUMNS
            )
            lines.append(f"    {source:<{width}}{cells}")
        wins = []
        for _, key, _ in ODOMETRY_COLUMNS:
            better = sum(r["ekf odometry"][key] < r["command"][key] for r in block["runs"])
            wins.append(f"{better}/{len(block['runs'])}")
        lines.append(f"    {'ekf < command':<{width}}" + "".join(f"{w:>14}" for w in wins) + "   (seeds)")
    lines.append(
        "  'command': the request a walking engine with the walk scenario's execution error (per-run scale "
        "6 % per axis, turn bias"
    )
    lines.append(
        "  0.03 rad/s, 1 sigma) must be given to walk the simulated path. 'ideal command': the request the "
        "simulated trunk follows"
    )
    lines.append(
        "  exactly, a bound no real walking engine reaches. 'ekf < command': seeds on which the EKF odometry's "
        "figure is the smaller."
    )
    if odometry.get("rrd"):
        lines.append(f"  Recording of the straight walk, seed {seeds[0]}: {odometry['rrd']}")
    return lines


def build_report(
    seed: int,
    duration: float,
    twist: bool,
    slip: bool,
    n_seeds: int = 5,
    particles: int = 500,
    rrd: str | None = None,
    progress: bool = False,
    fit: dict | None = None,
    variation: RobotVariation | None = None,
) -> dict:
    """Every figure, from fresh simulations; with `rrd`, the recording of figures 1 and 5's straight walk.
    progress: a bar on stderr over the simulated walks and the figures. fit: the noise settings (default:
    `load_fit()`); variation: the simulated robots' ranges (default: `RobotVariation()`, links ±5 %)."""
    from mcl.tools.cli_checks import progress_bar

    fit = load_fit() if fit is None else fit
    variation = RobotVariation() if variation is None else variation
    bar = progress_bar(enabled=progress, total=n_seeds + 8, desc="velocity", unit="part")
    try:
        return _build_report(seed, duration, twist, slip, n_seeds, particles, rrd, bar, fit, variation)
    finally:
        bar.close()


def _build_report(seed, duration, twist, slip, n_seeds, particles, rrd, bar, fit, variation) -> dict:
    base_disturbances = DisturbanceParams()
    slip_probability = base_disturbances.slip_probability if slip else 0.0

    def disturbances(twist_on):
        return DisturbanceParams(
            twist_probability=base_disturbances.twist_probability if twist_on else 0.0,
            slip_probability=slip_probability,
        )

    def simulate(walk_seed, gait, twist_on):
        return simulate_walk(duration, walk_seed, gait=gait, disturbances=disturbances(twist_on), variation=variation)

    params = default_variants(fit)
    kinematics_zero_gyro = bool(fit.get("kinematics_zero_gyro", True))

    def estimate(run):
        return run_estimators(run, params, kinematics_zero_gyro=kinematics_zero_gyro)

    straight = simulate(seed, GaitParams(), twist)
    result = estimate(straight)
    variants = tuple(result["ekf_names"])
    report = {
        "seed": seed,
        "duration": duration,
        "twist": twist,
        "slip": slip,
        "ekf_names": list(variants),
        "labels": {name: LABELS[name] for name in ESTIMATORS},
        "variation": dataclasses.asdict(variation),
        "robot": straight.robot.as_dict(),
        "fit_training_seeds": fit.get("training_seeds"),
        "average_forward_velocity": average_forward_velocity(straight, result),
        "tilt": tilt_figures(straight, result),
        "rmse": {},
    }
    bar.update(2)
    walks = {("straight", seed): straight}  # the twist setting of figure 1, reused by figure 5
    spread = {"seeds": list(range(seed, seed + n_seeds)), "kinematics+gyro_error_percent": []}
    for name in variants:
        spread[f"{name}_error_percent"] = []
    for other in spread["seeds"]:
        if other == seed:
            figures = report["average_forward_velocity"]
        else:
            other_run = simulate(other, GaitParams(), twist)
            walks["straight", other] = other_run
            figures = average_forward_velocity(other_run, estimate(other_run))
        for name in variants + ("kinematics+gyro",):
            spread[f"{name}_error_percent"].append(figures[name]["error_percent"])
        bar.update(1)
    report["seed_spread"] = spread
    for walk in ("straight", "turning"):
        for twist_on in (True, False):
            gait = GaitParams() if walk == "straight" else turning_gait(duration)
            if walk == "straight" and twist_on == twist:
                run, res = straight, result
            else:
                run = simulate(seed, gait, twist_on)
                res = estimate(run)
                if twist_on == twist:
                    walks[walk, seed] = run
            report["rmse"][f"{walk} walk, twist {'on' if twist_on else 'off'}"] = rmse_windows(run, res)
            bar.update(1)
    report["timing"] = {name: timing(result, name) for name in variants}
    bar.update(1)
    report["ekf_params"] = {name: dataclasses.asdict(result["params"][name]) for name in variants}
    report["odometry"] = odometry_report(
        walks,
        result,
        spread["seeds"],
        duration,
        disturbances(twist),
        particles,
        rrd,
        variation=variation,
        params=params[ODOMETRY_EKF],
    )
    bar.update(1)
    return report


def odometry_report(
    walks: dict,
    result: dict,
    seeds: list[int],
    duration: float,
    disturbances: DisturbanceParams,
    particles: int = 500,
    rrd: str | None = None,
    variation: RobotVariation | None = None,
    params: VelocityEKFParams | None = None,
) -> dict:
    """Figure 5 over `seeds`, straight and turning walks; `walks` holds (walk, seed) runs already simulated
    (`result` is the estimators' run on the straight walk of seeds[0], recorded with `rrd`); other walks are
    simulated with `variation`; `params` are the odometry EKF's (default: the fitted `ODOMETRY_EKF`)."""
    out = {
        "filter_rate_hz": None,
        "particles": particles,
        "ekf": ODOMETRY_EKF,
        "sources": list(ODOMETRY_SOURCES),
        "placements": {walk: list(pose) for walk, pose in PLACEMENTS.items()},
        "reset_sigma": list(RESET_SIGMA),
        "sparse_camera_every": SPARSE_CAMERA_EVERY,
        "seeds": list(seeds),
        "walks": {},
    }
    for walk in PLACEMENTS:
        runs = []
        for s in seeds:
            run = walks.get((walk, s))
            if run is None:
                run = simulate_walk(
                    duration, s, gait=walk_gait(walk, duration), disturbances=disturbances, variation=variation
                )
            if rrd and walk == "straight" and s == seeds[0]:
                runs.append(write_recording(rrd, run, result, s, walk, particles, params))
            else:
                runs.append(odometry_run(run, s, walk, particles, params=params))
            out["filter_rate_hz"] = run.sensors.imu_rate / FILTER_EVERY
        out["walks"][walk] = {"runs": runs, "summary": summarize_odometry(runs)}
    out["rrd"] = rrd
    return out


# ---------------------------------------------------------------------------------------------------------
# The robustness table: every estimator against the simulated robot's distance from the estimator's model
# ---------------------------------------------------------------------------------------------------------
MISMATCH_LEVELS = (
    ("nominal", None),
    ("links +-0 %", 0.0),
    ("links +-2 %", 0.02),
    ("links +-5 %", 0.05),
    ("links +-8 %", 0.08),
)
"""Columns: the nominal robot (published legs, datasheet sensors), then `RobotVariation()` with the links (and the
joint zeros with them) drawn within ±e."""
TABLE_ESTIMATORS = EKF_VARIANTS + ("kinematics+gyro", "kinematics", "imu")
GOAL_PERCENT = 5.0


def level_variation(error: float | None) -> RobotVariation | None:
    """The simulated robots of one column of the table: None (the nominal robot) or links within ±`error`."""
    return None if error is None else RobotVariation().with_chain_error(error)


def mismatch_table(
    seeds: list[int], duration: float = 28.0, fit: dict | None = None, levels=MISMATCH_LEVELS, progress: bool = False
) -> dict:
    """Average-forward-velocity error (%) of every estimator over straight walks of `seeds` (twist and slip on),
    for each column of `levels` (name, link error or None), with the fitted noise settings `fit`."""
    from mcl.tools.cli_checks import progress_bar

    fit = load_fit() if fit is None else fit
    params = default_variants(fit)
    kinematics_zero_gyro = bool(fit.get("kinematics_zero_gyro", True))
    out: dict = {
        "seeds": list(seeds),
        "duration": duration,
        "goal_percent": GOAL_PERCENT,
        "fit_training_seeds": fit.get("training_seeds"),
        "estimators": list(TABLE_ESTIMATORS),
        "labels": {name: LABELS[name] for name in TABLE_ESTIMATORS},
        "levels": {},
    }
    bar = progress_bar(enabled=progress, total=len(levels) * len(seeds), desc="mismatch", unit="walk")
    try:
        for level, error in levels:
            variation = level_variation(error)
            errors: dict = {name: [] for name in TABLE_ESTIMATORS}
            for seed in seeds:
                run = simulate_walk(duration, seed, variation=variation)
                figures = average_forward_velocity(
                    run, run_estimators(run, params, kinematics_zero_gyro=kinematics_zero_gyro)
                )
                for name in TABLE_ESTIMATORS:
                    errors[name].append(figures[name]["error_percent"])
                bar.update(1)
            summary = {
                name: {
                    "median": float(np.median(v)),
                    "max": float(np.max(v)),
                    "within_goal": int(np.sum(np.asarray(v) <= GOAL_PERCENT)),
                }
                for name, v in errors.items()
            }
            beats = {
                name: int(np.sum(np.asarray(errors[name]) < np.asarray(errors["kinematics+gyro"])))
                for name in EKF_VARIANTS
            }
            out["levels"][level] = {
                "link_length_error": error,
                "variation": None if variation is None else dataclasses.asdict(variation),
                "error_percent": errors,
                "summary": summary,
                "ekf_below_kinematics_gyro": beats,
            }
    finally:
        bar.close()
    return out


def format_mismatch(table: dict) -> str:
    """The robustness table as text."""
    seeds = table["seeds"]
    training = table.get("fit_training_seeds") or []
    levels = list(table["levels"])
    width = max(len(label) for label in table["labels"].values()) + 2
    cell = 16
    lines = [
        f"Average forward velocity error %, {table['duration']:.0f} s straight walks (twist and slip on), "
        f"held-out seeds {seeds[0]}-{seeds[-1]} ({len(seeds)} walks),",
        "noise settings fitted on training seeds "
        + (f"{training[0]}-{training[-1]}" if training else "(see the fit file)")
        + f"; median (worst) per column, then walks within the goal (<= {table['goal_percent']:g} %).",
        "Columns: the nominal robot (published legs, datasheet sensors); then robots drawn per walk with links "
        "within +-e, joint zeros",
        "within +-(20 deg)*e, backlash, IMU noise, bias, scale and gyro drift per run (demos.biped.RobotVariation).",
        f"  {'estimator':<{width}}" + "".join(f"{level:>{cell}}" for level in levels),
    ]
    for name in table["estimators"]:
        cells = "".join(
            f"{table['levels'][lv]['summary'][name]['median']:>{cell - 8}.1f} "
            f"({table['levels'][lv]['summary'][name]['max']:>5.1f})"
            for lv in levels
        )
        lines.append(f"  {table['labels'][name]:<{width}}{cells}")
    lines.append(f"  within {table['goal_percent']:g} %")
    n = len(seeds)
    for name in table["estimators"]:
        cells = "".join(
            f"{str(table['levels'][lv]['summary'][name]['within_goal']) + '/' + str(n):>{cell}}" for lv in levels
        )
        lines.append(f"  {table['labels'][name]:<{width}}{cells}")
    lines.append("  walks where the EKF's error is below kinematics+gyro's")
    for name in EKF_VARIANTS:
        cells = "".join(
            f"{str(table['levels'][lv]['ekf_below_kinematics_gyro'][name]) + '/' + str(n):>{cell}}" for lv in levels
        )
        lines.append(f"  {table['labels'][name]:<{width}}{cells}")
    return "\n".join(lines)


PROG = "robocup-mcl demo velocity"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    add_save_option(parser)
    parser.add_argument(
        "--seed",
        type=int,
        default=None,
        help=f"seed of the first simulated walk (default 0; with --mismatch {HELD_OUT_FIRST_SEED}); "
        f"the training seeds {TRAINING_SEEDS[0]}-{TRAINING_SEEDS[-1]} are refused",
    )
    parser.add_argument("--duration", type=float, default=28.0, help="seconds of each simulated walk")
    parser.add_argument(
        "--twist",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="foot twist episodes in the walk of figures 1, 3 and 4",
    )
    parser.add_argument(
        "--slip", action=argparse.BooleanOptionalAction, default=True, help="limited slip episodes in every walk"
    )
    parser.add_argument(
        "--seeds",
        type=int,
        default=5,
        help="figures 1 and 5 (or the --mismatch table) are repeated for this many seeds from "
        "--seed, to show the spread",
    )
    parser.add_argument("--particles", type=int, default=500, help="particles of each filter of figure 5")
    parser.add_argument(
        "--rrd",
        metavar="PATH",
        help="write a Rerun recording: the velocities of figure 1 (the paper's Fig. 3) and the "
        "filters of figure 5 on the same straight walk",
    )
    parser.add_argument(
        "--mismatch",
        action="store_true",
        help="instead of figures 1-5, the robustness table: every estimator's average-velocity "
        "error on the nominal robot and on robots whose links are off by up to 0, 2, 5 and 8 %%",
    )
    parser.add_argument(
        "--nominal",
        action="store_true",
        help="figures 1-5 on the nominal robot (published legs, datasheet sensors) instead of "
        "robots drawn per walk with links within +-5 %%",
    )
    parser.add_argument(
        "--fit",
        metavar="PATH",
        default=None,
        help="the EKF noise settings written by `robocup-mcl fit ekf --save PATH` (default: results/ekf_fit.json)",
    )
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl demo velocity` (see --help); returns the exit status."""
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    from mcl.tools.cli_checks import check_input_file, check_output_file, progress_wanted, save_and_print

    check_output_file(args.save, "--save")
    if args.seeds < 1:
        parser.error(f"--seeds must be at least 1, got {args.seeds}")
    if args.particles < 1:
        parser.error(f"--particles must be at least 1, got {args.particles}")
    if not (math.isfinite(args.duration) and args.duration >= 4.0):
        parser.error(f"--duration must be at least 4 s, got {args.duration}")
    if args.mismatch and (args.rrd or args.nominal):
        parser.error("--mismatch makes the robustness table only: --rrd and --nominal do not apply")
    first = args.seed if args.seed is not None else (HELD_OUT_FIRST_SEED if args.mismatch else 0)
    seeds = list(range(first, first + args.seeds))
    training = sorted(set(seeds) & set(TRAINING_SEEDS))
    if training:
        parser.error(
            f"seeds {training} are training seeds (the noise settings were fitted on them); pick others with --seed"
        )
    check_output_file(args.rrd, "--rrd")  # before the simulations, not after them
    check_input_file(args.fit, "--fit")
    fit = load_fit(args.fit)
    if args.mismatch:
        save_and_print(
            mismatch_table(seeds, args.duration, fit, progress=progress_wanted(args)),
            args.save,
            args.json,
            lambda table: print(format_mismatch(table)),
        )
        return 0

    from .walk import warm_up_walk
    from .walk_sim import WalkScenario

    # The filter that takes the EKF's odometry: a machine's first run says it compiles its kernels.
    warm = warm_up_walk(WalkScenario(), "velocity-linear", progress=progress_wanted(args))
    report = build_report(
        first,
        args.duration,
        args.twist,
        args.slip,
        args.seeds,
        args.particles,
        args.rrd,
        progress=progress_wanted(args),
        fit=fit,
        variation=RobotVariation.nominal() if args.nominal else RobotVariation(),
    )
    report.update(warm.as_dict())
    save_and_print(report, args.save, args.json, lambda result: print(_format(result)))
    if args.rrd and not args.json:
        print(f"\nrecording written to {args.rrd} (open it with: rerun {args.rrd})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
