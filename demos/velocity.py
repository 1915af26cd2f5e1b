"""The velocity-estimation experiment: the paper's four estimators on the simulated biped walk.

    python -m demos.velocity                       # 28 s straight walk, twist and slip on, seed 0
    python -m demos.velocity --no-twist --json --seed 3 --duration 40

    from demos.velocity import main, run_estimators
    from demos.biped import simulate_walk
    result = run_estimators(simulate_walk(28.0, seed=0))   # dict of per-sample estimates and truth

Figures printed (all measured in this run, nothing fixed in advance):
1. Straight walk of `--duration` s (the paper's experiment, Section VI): the average forward velocity (IMU x
   axis, eq. 38 taken as a mean) of each estimator against the truth, and its error in percent; the EKF again
   without removing the gyro bias measured while standing; the EKF error over `--seeds` seeds.
2. RMSE of the 3-D velocity over quarters of the run, straight and turning walks, foot twist on and off,
   evaluated at the kinematics samples where a support foot is known (all four estimators on the same samples).
3. Tilt (direction of gravity) error of the EKF, in degrees, on the run of figure 1.
4. Time per EKF prediction and correction, numba kernel against the numpy reference, replaying the inputs of
   the run of figure 1, with the largest difference between the two state sequences.

EKF noise parameters come from the simulated sensor specification, not from the results: σ_ω and σ_q are the
standard deviations of one IMU sample's error, noise and bias together; σ_v is the spread of a kinematic
velocity from encoder quantization (two readings differenced over 1/30 s, six joints, 0.3 m lever arm).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time as _time

import numpy as np

from demos.biped import BipedRun, DisturbanceParams, GaitParams, SensorParams, simulate_walk, turning_gait
from sensing.velocity import (ImuOnlyEstimator, LegOdometry, VelocityEKF, VelocityEKFParams, ekf_correct_kernel,
                              ekf_correct_reference, ekf_predict_kernel, ekf_predict_reference, tilt_error)

ESTIMATORS = ("imu", "kinematics", "kinematics+gyro", "ekf")
STANDING_SAMPLES_TIME = 0.5     # s of standing data that initialize gravity (eq. 1)


def ekf_params_for(sensors: SensorParams, lever_arm: float = 0.3, n_joints: int = 6) -> VelocityEKFParams:
    """EKF noise from the sensor specification (see the module docstring)."""
    dt_kin = 1.0 / sensors.kinematics_rate
    rate_noise = sensors.encoder_resolution / math.sqrt(6.0) / dt_kin
    return VelocityEKFParams(
        gyro_noise=math.hypot(sensors.gyro_noise, sensors.gyro_bias),
        accel_noise=math.hypot(sensors.accel_noise, sensors.accel_bias),
        velocity_noise=math.sqrt(n_joints) * lever_arm * rate_noise,
    )


def run_estimators(run: BipedRun, params: VelocityEKFParams | None = None, backend: str = "numba",
                   zero_gyro: bool = True) -> dict:
    """Run the four estimators over one simulated walk; returns per-sample estimates, truth and the EKF inputs.

    All start from the first `STANDING_SAMPLES_TIME` seconds, when the robot stands still (eq. 1); with
    `zero_gyro` the mean gyro of that period is taken as its bias and removed, for every estimator.
    """
    params = params or ekf_params_for(run.sensors)
    n0 = int(np.searchsorted(run.imu_time, STANDING_SAMPLES_TIME, side="right")) - 1
    t0 = float(run.imu_time[n0])
    standing = run.accel[: n0 + 1]
    standing_gyro = run.gyro[: n0 + 1] if zero_gyro else None
    imu_only = ImuOnlyEstimator.from_standing(standing, t0, gyro_samples=standing_gyro)
    ekf = VelocityEKF.from_standing(standing, t0, params=params, backend=backend, gyro_samples=standing_gyro)
    odometry = LegOdometry(run.chains, ekf)
    n_imu = run.imu_time.shape[0]
    imu_v = np.full((n_imu, 3), np.nan)
    imu_g = np.full((n_imu, 3), np.nan)
    ekf_v = np.full((n_imu, 3), np.nan)
    ekf_g = np.full((n_imu, 3), np.nan)
    imu_v[n0], imu_g[n0] = imu_only.velocity, imu_only.gravity
    ekf_v[n0], ekf_g[n0] = ekf.velocity, ekf.gravity
    kin_first = int(np.searchsorted(run.kin_time, t0, side="left"))
    n_kin = run.kin_time.shape[0]
    kin = {name: np.full((n_kin, 3), np.nan) for name in ESTIMATORS}
    foot = np.full(n_kin, -1)
    events = []                                  # EKF inputs in order, for the timing replay
    i, k = n0 + 1, kin_first
    while i < n_imu or k < n_kin:
        if k >= n_kin or (i < n_imu and run.imu_time[i] <= run.kin_time[k]):
            odometry.imu(run.imu_time[i], run.gyro[i], run.accel[i])
            imu_only.update(run.imu_time[i], run.gyro[i], run.accel[i])
            events.append(("predict", run.imu_time[i] - run.imu_time[i - 1], run.gyro[i] - ekf.gyro_bias,
                           run.accel[i]))
            imu_v[i], imu_g[i] = imu_only.velocity, imu_only.gravity
            ekf_v[i], ekf_g[i] = ekf.velocity, ekf.gravity
            i += 1
        else:
            sample = odometry.kinematics(run.kin_time[k], run.joint_angles[k], run.contacts[k])
            foot[k] = sample.foot
            if sample.foot >= 0:
                events.append(("correct", sample.velocity_kinematic_gyro))
                kin["kinematics"][k] = sample.velocity_kinematic
                kin["kinematics+gyro"][k] = sample.velocity_kinematic_gyro
            kin["ekf"][k] = ekf.velocity
            kin["imu"][k] = imu_only.velocity
            k += 1
    return {"t0": t0, "n0": n0, "imu_velocity": imu_v, "imu_gravity": imu_g, "ekf_velocity": ekf_v,
            "ekf_gravity": ekf_g, "kin": kin, "foot": foot, "events": events, "params": params,
            "initial_state": np.concatenate([standing.mean(axis=0), np.zeros(3)]),
            "initial_covariance": np.diag([params.initial_gravity_std ** 2] * 3
                                          + [params.initial_velocity_std ** 2] * 3)}


def average_forward_velocity(run: BipedRun, result: dict) -> dict:
    """Figure 1: mean of v_x (IMU frame) per estimator and of the truth over the same samples."""
    out = {}
    n0 = result["n0"]
    for name in ESTIMATORS:
        if name in ("imu", "ekf"):
            est = result[f"{name}_velocity"][n0:, 0]
            true = run.true_velocity[n0:, 0]
        else:
            valid = result["foot"] >= 0
            est = result["kin"][name][valid, 0]
            true = run.true_kin_velocity[valid, 0]
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
    for name in ESTIMATORS:
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
    """Figure 3: EKF tilt error in degrees (and the IMU-only one for comparison)."""
    n0 = result["n0"]
    out = {}
    for name in ("ekf", "imu"):
        err = np.degrees(tilt_error(result[f"{name}_gravity"][n0:], run.true_gravity[n0:]))
        out[name] = {"mean_deg": float(err.mean()), "rms_deg": float(np.sqrt(np.mean(err ** 2))),
                     "max_deg": float(err.max()), "final_deg": float(err[-1])}
    return out


def timing(result: dict, repeats: int = 3) -> dict:
    """Figure 4: replay the EKF inputs through the numba kernels and the numpy references, timing each call."""
    p = result["params"]
    events = result["events"]

    def replay(kind):
        state = result["initial_state"].copy()
        cov = result["initial_covariance"].copy()
        t_predict = t_correct = 0
        n_predict = n_correct = 0
        states = np.empty((len(events), 6))
        clock = _time.perf_counter_ns
        for e, event in enumerate(events):
            if event[0] == "predict":
                _, dt, gyro, accel = event
                start = clock()
                if kind == "numba":
                    ekf_predict_kernel(state, cov, gyro, accel, dt, p.gyro_noise, p.accel_noise, p.exact_jacobian)
                else:
                    state, cov = ekf_predict_reference(state, cov, gyro, accel, dt, p.gyro_noise, p.accel_noise,
                                                       p.exact_jacobian)
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


def _format(report: dict) -> str:
    lines = []
    f1 = report["average_forward_velocity"]
    lines.append(f"Figure 1. Average forward velocity, {report['duration']:.0f} s straight walk "
                 f"(seed {report['seed']}, twist {'on' if report['twist'] else 'off'}, "
                 f"slip {'on' if report['slip'] else 'off'})")
    lines.append(f"  {'estimator':<17}{'estimate cm/s':>14}{'truth cm/s':>12}{'error %':>10}")
    for name in ESTIMATORS:
        r = f1[name]
        lines.append(f"  {name:<17}{100 * r['estimate_m_s']:>14.2f}{100 * r['truth_m_s']:>12.2f}"
                     f"{r['error_percent']:>10.1f}")
    r = report["ekf_gyro_not_zeroed"]
    lines.append(f"  {'ekf, raw gyro':<17}{100 * r['estimate_m_s']:>14.2f}{100 * r['truth_m_s']:>12.2f}"
                 f"{r['error_percent']:>10.1f}   (gyro bias not removed while standing)")
    ekf_err = f1["ekf"]["error_percent"]
    lines.append(f"  EKF goal <= 5 %: {'met' if ekf_err <= 5.0 else 'MISSED'} ({ekf_err:.1f} %)")
    spread = report["seed_spread"]
    lines.append(f"  Same walk, seeds {spread['seeds'][0]}-{spread['seeds'][-1]}, EKF error %: "
                 + ", ".join(f"{x:.1f}" for x in spread["ekf_error_percent"])
                 + f"  (median {np.median(spread['ekf_error_percent']):.1f}, max {max(spread['ekf_error_percent']):.1f}"
                 + f"; kinematics+gyro median {np.median(spread['kinematics_gyro_error_percent']):.1f})")
    lines.append("")
    lines.append("Figure 2. Velocity RMSE (cm/s) over quarters of the run, at kinematics samples with a support foot")
    for key, block in report["rmse"].items():
        windows = block["windows_s"]
        header = "".join(f"{f'{a:.0f}-{b:.0f} s':>10}" for a, b in windows)
        lines.append(f"  {key}")
        lines.append(f"    {'estimator':<17}{header}{'all':>10}")
        for name in ESTIMATORS:
            lines.append(f"    {name:<17}" + "".join(f"{100 * x:>10.2f}" for x in block[name]))
        best_single = min(block[name][-1] for name in ESTIMATORS[:3])
        lines.append(f"    EKF below every single-source estimate: {'yes' if block['ekf'][-1] < best_single else 'NO'}"
                     f"; IMU-only growing: {'yes' if all(np.diff(block['imu'][:-1]) > 0) else 'NO'}")
    lines.append("")
    tilt = report["tilt"]
    lines.append("Figure 3. Tilt (gravity direction) error, degrees, run of figure 1")
    for name in ("ekf", "imu"):
        r = tilt[name]
        lines.append(f"  {name:<17} mean {r['mean_deg']:.3f}  rms {r['rms_deg']:.3f}  max {r['max_deg']:.3f}  "
                     f"final {r['final_deg']:.3f}")
    lines.append("")
    tm = report["timing"]
    lines.append(f"Figure 4. Time per EKF step, run of figure 1 ({tm['predictions']} predictions, "
                 f"{tm['corrections']} corrections; best of 3 replays)")
    lines.append(f"  {'':<12}{'predict us':>12}{'correct us':>12}")
    lines.append(f"  {'numba':<12}{tm['numba_predict_us']:>12.2f}{tm['numba_correct_us']:>12.2f}")
    lines.append(f"  {'reference':<12}{tm['reference_predict_us']:>12.2f}{tm['reference_correct_us']:>12.2f}")
    lines.append(f"  speed-up: predict x{tm['reference_predict_us'] / tm['numba_predict_us']:.0f}, "
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
    report = {"seed": seed, "duration": duration, "twist": twist, "slip": slip,
              "average_forward_velocity": average_forward_velocity(straight, result),
              "tilt": tilt_figures(straight, result), "rmse": {}}
    raw = average_forward_velocity(straight, run_estimators(straight, zero_gyro=False))
    report["ekf_gyro_not_zeroed"] = raw["ekf"]
    spread = {"seeds": list(range(seed, seed + n_seeds)), "ekf_error_percent": [],
              "kinematics_gyro_error_percent": []}
    for other in spread["seeds"]:
        if other == seed:
            figures = report["average_forward_velocity"]
        else:
            other_run = simulate_walk(duration, other, gait=GaitParams(), disturbances=disturbances(twist))
            figures = average_forward_velocity(other_run, run_estimators(other_run))
        spread["ekf_error_percent"].append(figures["ekf"]["error_percent"])
        spread["kinematics_gyro_error_percent"].append(figures["kinematics+gyro"]["error_percent"])
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
    report["timing"] = timing(result)
    report["ekf_params"] = {k: getattr(result["params"], k) for k in
                            ("gyro_noise", "accel_noise", "velocity_noise", "exact_jacobian")}
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
