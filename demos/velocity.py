"""The velocity-estimation experiment: the paper's four estimators on the simulated biped walk, with the EKF in
two variants: the paper's (state [g, v], "ekf") and one that also estimates the gyro bias ([g, v, b],
"ekf+bias").

    python -m demos.velocity                       # 28 s straight walk, twist and slip on, seed 0
    python -m demos.velocity --no-twist --json --seed 3 --duration 40

    from demos.velocity import main, run_estimators
    from demos.biped import simulate_walk
    result = run_estimators(simulate_walk(28.0, seed=0))   # dict of per-sample estimates and truth

Figures printed (all measured in this run, nothing fixed in advance):
1. Straight walk of `--duration` s (the paper's experiment, Section VI): the average forward velocity (IMU x
   axis, eq. 38 taken as a mean) of each estimator against the truth, and its error in percent; both EKFs again
   without the gyro samples of the standing period; the error of both EKFs over `--seeds` seeds.
2. RMSE of the 3-D velocity over quarters of the run, straight and turning walks, foot twist on and off,
   evaluated at the kinematics samples where a support foot is known (every estimator on the same samples).
3. Tilt (direction of gravity) error of both EKFs and of the IMU alone, in degrees, on the run of figure 1, and
   the error of each EKF's gyro bias at the start and at the end of that run.
4. Time per EKF prediction and correction of both EKFs, numba kernel against the numpy reference, replaying the
   inputs of the run of figure 1, with the largest difference between the two state sequences.

EKF noise parameters come from the simulated sensor specification, not from the results: σ_q is the standard
deviation of one accelerometer sample's error, noise and bias together; σ_v is the spread of a kinematic
velocity from encoder quantization (two readings differenced over 1/30 s, six joints, 0.3 m lever arm). σ_ω is
the gyro's noise and bias together for the paper's filter, which has no bias state, and the noise alone for the
filter that estimates the bias. That filter starts b at the mean gyro of the standing period with the standard
error of that mean; its random walk σ_b lets the bias move by its run-to-run spread (the sensor's `gyro_bias`,
0.005 rad/s) in an hour, σ_b = 0.005 / √3600 ≈ 8.3e-5 rad/s/√s. The simulated bias is constant in a run, so the
exact value would be 0; a positive one keeps b from freezing and stands for a real gyro's slow drift.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time as _time

import numpy as np

from demos.biped import BipedRun, DisturbanceParams, GaitParams, SensorParams, simulate_walk, turning_gait
from sensing.velocity import (ImuOnlyEstimator, LegOdometry, VelocityEKF, VelocityEKFParams, ekf_bias_predict_kernel,
                              ekf_bias_predict_reference, ekf_correct_kernel, ekf_correct_reference,
                              ekf_predict_kernel, ekf_predict_reference, tilt_error)

EKF_VARIANTS = ("ekf", "ekf+bias")                 # the paper's [g, v] filter; with the gyro bias, [g, v, b]
ESTIMATORS = ("imu", "kinematics", "kinematics+gyro") + EKF_VARIANTS
STANDING_SAMPLES_TIME = 0.5     # s of standing data that initialize gravity (eq. 1)
BIAS_DRIFT_TIME = 3600.0        # s over which the gyro bias may wander by its run-to-run spread


def ekf_params_for(sensors: SensorParams, estimate_gyro_bias: bool = False, lever_arm: float = 0.3,
                   n_joints: int = 6) -> VelocityEKFParams:
    """EKF noise from the sensor specification (see the module docstring)."""
    dt_kin = 1.0 / sensors.kinematics_rate
    rate_noise = sensors.encoder_resolution / math.sqrt(6.0) / dt_kin
    common = {"accel_noise": math.hypot(sensors.accel_noise, sensors.accel_bias),
              "velocity_noise": math.sqrt(n_joints) * lever_arm * rate_noise}
    if not estimate_gyro_bias:
        return VelocityEKFParams(gyro_noise=math.hypot(sensors.gyro_noise, sensors.gyro_bias),
                                 estimate_gyro_bias=False, **common)
    return VelocityEKFParams(gyro_noise=sensors.gyro_noise, estimate_gyro_bias=True,
                             initial_gyro_bias_std=sensors.gyro_bias,
                             gyro_bias_random_walk=sensors.gyro_bias / math.sqrt(BIAS_DRIFT_TIME), **common)


def default_variants(sensors: SensorParams) -> dict:
    """The two filters compared: the paper's (state [g, v]) and the one estimating the gyro bias ([g, v, b])."""
    return {"ekf": ekf_params_for(sensors, estimate_gyro_bias=False),
            "ekf+bias": ekf_params_for(sensors, estimate_gyro_bias=True)}


def run_estimators(run: BipedRun, params: dict | None = None, backend: str = "numba",
                   zero_gyro: bool = True) -> dict:
    """Run the estimators over one simulated walk; returns per-sample estimates, truth and the EKF inputs.

    `params` maps a name to the VelocityEKFParams of one EKF (default: `default_variants`); each EKF has its own
    `LegOdometry`, and the kinematic estimates are those of the first. All start from the first
    `STANDING_SAMPLES_TIME` seconds, when the robot stands still (eq. 1); with `zero_gyro` the gyro samples of
    that period are given to every estimator (the mean removed as the bias, or the bias state started there).
    Per EKF `name`: `{name}_velocity`, `{name}_gravity`, `{name}_gyro_bias` (IMU rate), and under `kin`, `events`,
    `params`, `initial_state`, `initial_covariance`.
    """
    params = default_variants(run.sensors) if params is None else dict(params)
    if not params:
        raise ValueError("params must name at least one EKF")
    names = tuple(params)
    n0 = int(np.searchsorted(run.imu_time, STANDING_SAMPLES_TIME, side="right")) - 1
    t0 = float(run.imu_time[n0])
    standing = run.accel[: n0 + 1]
    standing_gyro = run.gyro[: n0 + 1] if zero_gyro else None
    imu_only = ImuOnlyEstimator.from_standing(standing, t0, gyro_samples=standing_gyro)
    filters = {name: VelocityEKF.from_standing(standing, t0, params=p, backend=backend, gyro_samples=standing_gyro)
               for name, p in params.items()}
    odometries = {name: LegOdometry(run.chains, ekf) for name, ekf in filters.items()}
    n_imu = run.imu_time.shape[0]
    result = {"t0": t0, "n0": n0, "ekf_names": names, "params": params, "events": {},
              "initial_state": {name: ekf.state for name, ekf in filters.items()},
              "initial_covariance": {name: ekf.covariance for name, ekf in filters.items()}}
    for name in ("imu",) + names:
        for quantity in ("velocity", "gravity", "gyro_bias"):
            result[f"{name}_{quantity}"] = np.full((n_imu, 3), np.nan)
    result["imu_velocity"][n0], result["imu_gravity"][n0] = imu_only.velocity, imu_only.gravity
    for name, ekf in filters.items():
        result[f"{name}_velocity"][n0], result[f"{name}_gravity"][n0] = ekf.velocity, ekf.gravity
        result[f"{name}_gyro_bias"][n0] = ekf.gyro_bias
        result["events"][name] = []              # EKF inputs in order, for the timing replay
    kin_first = int(np.searchsorted(run.kin_time, t0, side="left"))
    n_kin = run.kin_time.shape[0]
    kin = {name: np.full((n_kin, 3), np.nan) for name in ("imu", "kinematics", "kinematics+gyro") + names}
    foot = np.full(n_kin, -1)
    i, k = n0 + 1, kin_first
    while i < n_imu or k < n_kin:
        if k >= n_kin or (i < n_imu and run.imu_time[i] <= run.kin_time[k]):
            imu_only.update(run.imu_time[i], run.gyro[i], run.accel[i])
            result["imu_velocity"][i], result["imu_gravity"][i] = imu_only.velocity, imu_only.gravity
            dt = run.imu_time[i] - run.imu_time[i - 1]
            for name, ekf in filters.items():
                # The bias filter takes the raw gyro (it subtracts its own b); the paper's, the zeroed one.
                gyro = run.gyro[i] if ekf.params.estimate_gyro_bias else run.gyro[i] - ekf.gyro_bias
                odometries[name].imu(run.imu_time[i], run.gyro[i], run.accel[i])
                result["events"][name].append(("predict", dt, gyro, run.accel[i]))
                result[f"{name}_velocity"][i], result[f"{name}_gravity"][i] = ekf.velocity, ekf.gravity
                result[f"{name}_gyro_bias"][i] = ekf.gyro_bias
            i += 1
        else:
            for e, (name, odometry) in enumerate(odometries.items()):
                sample = odometry.kinematics(run.kin_time[k], run.joint_angles[k], run.contacts[k])
                if sample.foot >= 0:
                    result["events"][name].append(("correct", sample.velocity_kinematic_gyro))
                if e == 0:
                    foot[k] = sample.foot
                    if sample.foot >= 0:
                        kin["kinematics"][k] = sample.velocity_kinematic
                        kin["kinematics+gyro"][k] = sample.velocity_kinematic_gyro
                kin[name][k] = filters[name].velocity
            kin["imu"][k] = imu_only.velocity
            k += 1
    result["kin"] = kin
    result["foot"] = foot
    return result


def _names(result: dict) -> tuple:
    return ("imu", "kinematics", "kinematics+gyro") + tuple(result["ekf_names"])


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
        out[name] = {"estimate_m_s": mean_est, "truth_m_s": mean_true,
                     "error_percent": 100.0 * abs(mean_est - mean_true) / abs(mean_true)}
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
        out[name] = {"mean_deg": float(err.mean()), "rms_deg": float(np.sqrt(np.mean(err ** 2))),
                     "max_deg": float(err.max()), "final_deg": float(err[-1])}
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
            ekf_bias_predict_kernel(state, cov, gyro, accel, dt, p.gyro_noise, p.accel_noise,
                                    p.gyro_bias_random_walk, p.exact_jacobian)

        def predict_reference(state, cov, gyro, accel, dt):
            return ekf_bias_predict_reference(state, cov, gyro, accel, dt, p.gyro_noise, p.accel_noise,
                                              p.gyro_bias_random_walk, p.exact_jacobian)
    else:
        def predict_kernel(state, cov, gyro, accel, dt):
            ekf_predict_kernel(state, cov, gyro, accel, dt, p.gyro_noise, p.accel_noise, p.exact_jacobian)

        def predict_reference(state, cov, gyro, accel, dt):
            return ekf_predict_reference(state, cov, gyro, accel, dt, p.gyro_noise, p.accel_noise,
                                         p.exact_jacobian)

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
                    state, cov = ekf_correct_reference(state, cov, event[1], p.velocity_noise)
                t_correct += clock() - start
                n_correct += 1
            states[e] = state
        return t_predict / max(n_predict, 1) / 1e3, t_correct / max(n_correct, 1) / 1e3, states, n_predict, n_correct

    replay("numba")                                   # compile (or load from cache) outside the timing
    best = {}
    for kind in ("numba", "reference"):
        runs = [replay(kind) for _ in range(repeats)]
        best[kind] = (min(r[0] for r in runs), min(r[1] for r in runs), runs[0][2], runs[0][3], runs[0][4])
    diff = float(np.max(np.abs(best["numba"][2] - best["reference"][2])))
    return {"numba_predict_us": best["numba"][0], "numba_correct_us": best["numba"][1],
            "reference_predict_us": best["reference"][0], "reference_correct_us": best["reference"][1],
            "predictions": best["numba"][3], "corrections": best["numba"][4], "max_state_difference": diff}


LABELS = {"ekf": "ekf (paper)", "ekf+bias": "ekf + gyro bias"}


def _format(report: dict) -> str:
    lines = []
    f1 = report["average_forward_velocity"]
    variants = tuple(report["ekf_names"])
    names = ("imu", "kinematics", "kinematics+gyro") + variants
    label = {name: LABELS.get(name, name) for name in names}
    width = max(19, max(len(label[name] + ', raw gyro') for name in variants) + 2)
    lines.append(f"Figure 1. Average forward velocity, {report['duration']:.0f} s straight walk "
                 f"(seed {report['seed']}, twist {'on' if report['twist'] else 'off'}, "
                 f"slip {'on' if report['slip'] else 'off'})")
    lines.append(f"  {'estimator':<{width}}{'estimate cm/s':>14}{'truth cm/s':>12}{'error %':>10}")
    for name in names:
        r = f1[name]
        lines.append(f"  {label[name]:<{width}}{100 * r['estimate_m_s']:>14.2f}{100 * r['truth_m_s']:>12.2f}"
                     f"{r['error_percent']:>10.1f}")
    for name in variants:
        r = report["ekf_gyro_not_zeroed"][name]
        lines.append(f"  {label[name] + ', raw gyro':<{width}}{100 * r['estimate_m_s']:>14.2f}"
                     f"{100 * r['truth_m_s']:>12.2f}{r['error_percent']:>10.1f}   (no standing gyro samples)")
    spread = report["seed_spread"]
    seeds = spread["seeds"]
    lines.append(f"  EKF error % over seeds {seeds[0]}-{seeds[-1]} (goal <= 5 %):")
    for name in variants:
        errors = spread[f"{name}_error_percent"]
        missed = [s for s, e in zip(seeds, errors) if e > 5.0]
        lines.append(f"    {label[name]:<{width - 2}}" + ", ".join(f"{x:.1f}" for x in errors)
                     + f"  (median {np.median(errors):.1f}, max {max(errors):.1f}; goal "
                     + ("met on every seed)" if not missed else f"MISSED on seed{'s' if len(missed) > 1 else ''} "
                        + ", ".join(str(s) for s in missed) + ")"))
    errors = spread["kinematics+gyro_error_percent"]
    lines.append(f"    {'kinematics+gyro':<{width - 2}}median {np.median(errors):.1f}, max {max(errors):.1f}")
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
        lines.append(f"    EKF below every single-source estimate: {below}"
                     f"; IMU-only growing: {'yes' if all(np.diff(block['imu'][:-1]) > 0) else 'NO'}")
    lines.append("")
    tilt = report["tilt"]
    lines.append("Figure 3. Tilt (gravity direction) error, degrees, run of figure 1; "
                 "gyro bias error, mrad/s (x, y, z)")
    for name in variants + ("imu",):
        r = tilt[name]
        lines.append(f"  {label.get(name, name):<{width}}mean {r['mean_deg']:.3f}  rms {r['rms_deg']:.3f}  "
                     f"max {r['max_deg']:.3f}  final {r['final_deg']:.3f}")
    for name in variants:
        r = tilt[name]
        start = ", ".join(f"{x:+.2f}" for x in r["start_gyro_bias_error_mrad_s"])
        final = ", ".join(f"{x:+.2f}" for x in r["final_gyro_bias_error_mrad_s"])
        lines.append(f"  {label[name]:<{width}}bias error at start ({start}), at the end ({final})")
    lines.append("")
    first = report["timing"][variants[0]]
    lines.append(f"Figure 4. Time per EKF step, run of figure 1 ({first['predictions']} predictions, "
                 f"{first['corrections']} corrections; best of 3 replays)")
    lines.append(f"  {'':<{width + 12}}{'predict us':>12}{'correct us':>12}")
    for name in variants:
        tm = report["timing"][name]
        for kind in ("numba", "reference"):
            lines.append(f"  {label[name] + ', ' + kind:<{width + 12}}{tm[f'{kind}_predict_us']:>12.2f}"
                         f"{tm[f'{kind}_correct_us']:>12.2f}")
        lines.append(f"  {'':<{width + 12}}speed-up: "
                     f"predict x{tm['reference_predict_us'] / tm['numba_predict_us']:.0f}, "
                     f"correct x{tm['reference_correct_us'] / tm['numba_correct_us']:.0f}; "
                     f"largest state difference {tm['max_state_difference']:.2e}")
    return "\n".join(lines)


def build_report(seed: int, duration: float, twist: bool, slip: bool, n_seeds: int = 5) -> dict:
    """Every figure, from fresh simulations."""
    base_disturbances = DisturbanceParams()
    slip_probability = base_disturbances.slip_probability if slip else 0.0

    def disturbances(twist_on):
        return DisturbanceParams(twist_probability=base_disturbances.twist_probability if twist_on else 0.0,
                                 slip_probability=slip_probability)

    straight = simulate_walk(duration, seed, gait=GaitParams(), disturbances=disturbances(twist))
    result = run_estimators(straight)
    variants = tuple(result["ekf_names"])
    report = {"seed": seed, "duration": duration, "twist": twist, "slip": slip, "ekf_names": list(variants),
              "average_forward_velocity": average_forward_velocity(straight, result),
              "tilt": tilt_figures(straight, result), "rmse": {}}
    raw = average_forward_velocity(straight, run_estimators(straight, zero_gyro=False))
    report["ekf_gyro_not_zeroed"] = {name: raw[name] for name in variants}
    spread = {"seeds": list(range(seed, seed + n_seeds)), "kinematics+gyro_error_percent": []}
    for name in variants:
        spread[f"{name}_error_percent"] = []
    for other in spread["seeds"]:
        if other == seed:
            figures = report["average_forward_velocity"]
        else:
            other_run = simulate_walk(duration, other, gait=GaitParams(), disturbances=disturbances(twist))
            figures = average_forward_velocity(other_run, run_estimators(other_run))
        for name in variants + ("kinematics+gyro",):
            spread[f"{name}_error_percent"].append(figures[name]["error_percent"])
    report["seed_spread"] = spread
    for walk in ("straight", "turning"):
        for twist_on in (True, False):
            gait = GaitParams() if walk == "straight" else turning_gait(duration)
            if walk == "straight" and twist_on == twist:
                run, res = straight, result
            else:
                run = simulate_walk(duration, seed, gait=gait, disturbances=disturbances(twist_on))
                res = run_estimators(run)
            report["rmse"][f"{walk} walk, twist {'on' if twist_on else 'off'}"] = rmse_windows(run, res)
    report["timing"] = {name: timing(result, name) for name in variants}
    report["ekf_params"] = {name: dataclasses.asdict(result["params"][name]) for name in variants}
    return report


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m demos.velocity", description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--duration", type=float, default=28.0, help="seconds of each simulated walk")
    parser.add_argument("--twist", action=argparse.BooleanOptionalAction, default=True,
                        help="foot twist episodes in the walk of figures 1, 3 and 4")
    parser.add_argument("--slip", action=argparse.BooleanOptionalAction, default=True,
                        help="limited slip episodes in every walk")
    parser.add_argument("--seeds", type=int, default=5,
                        help="figure 1 is also repeated for this many seeds from --seed, to show the spread")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be at least 1, got {args.seeds}")
    if not (math.isfinite(args.duration) and args.duration >= 4.0):
        parser.error(f"--duration must be at least 4 s, got {args.duration}")
    report = build_report(args.seed, args.duration, args.twist, args.slip, args.seeds)
    if args.json:
        json.dump(report, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        print(_format(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
