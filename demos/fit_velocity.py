"""Fit the velocity EKF's noise settings from training walks: `robocup-mcl fit ekf`.

    robocup-mcl fit ekf --save results/ekf_fit.json          # the file `robocup-mcl demo velocity` reads
    robocup-mcl fit ekf --seeds 3 --duration 8 --json        # a small fit, printed as JSON

    from demos.fit_velocity import fit_noise, standing_statistics
    fit = fit_noise(runs)                                    # runs: demos.biped.BipedRun, with their truth

The training walks are simulated robots drawn per walk (`demos.biped.RobotVariation()`: links within ±5 %,
joint zeros, backlash, IMU noise, bias, scale and gyro drift per run), on the seeds `TRAINING_SEEDS` of
`demos.velocity`; no figure is ever computed on them. What a team can record, and what is taken from it:

1. Standing (the robot still before it walks: no truth needed). The accelerometer's and the gyro's white noise
   σ_q, σ_ω: the spread of the samples about each walk's own mean, pooled over walks and axes. The raw gyro's
   RMS, bias included: σ_ω of the paper's filter, which takes the gyro as zero-mean noise (eq. 16-18). The
   spread of the standing gyro means over walks: the bias's starting σ (`initial_gyro_bias_std`). The spread of
   the standing accelerometer's magnitude about 9.81 m/s²: the starting σ of g (`initial_gravity_std`).
2. Walking with a truth reference (motion capture, here the simulator's trunk velocity). σ_v: the RMS error of
   the kinematics+gyro velocity (eq. 14) against the truth, at the samples with a support foot. Then, per
   filter, a grid around these values: σ_v × (1/64, 1/32, ..., 1, 2), eight factors of two, and a second factor, σ_ω × (1, 3, 10) for the
   filters without a bias state, and the bias random walk σ_b = (bias spread / √duration) × (0.01, 0.1, 1) for
   the one with it: the same 24 settings per filter. The criterion is the headline figure, the mean over the
   training walks of the average-forward-velocity error; the smallest wins (the first on a tie). `initial_velocity_std` is taken
   equal to the chosen σ_v.
3. Kinematics+gyro has no noise settings; its one choice, the gyro less its standing mean or the raw gyro (eq.
   11-14 use the gyro only for the foot's own rotation), is made by the same criterion on the same walks.
"""

from __future__ import annotations

import argparse
import dataclasses
import math

import numpy as np

from demos.biped import GRAVITY, BipedRun, RobotVariation, simulate_walk
from demos.velocity import (
    EKF_VARIANTS,
    LABELS,
    TRAINING_SEEDS,
    VARIANT_SETTINGS,
    average_forward_velocity,
    run_estimators,
    variant_params,
)

VELOCITY_FACTORS = (1.0 / 64.0, 1.0 / 32.0, 1.0 / 16.0, 0.125, 0.25, 0.5, 1.0, 2.0)
GYRO_FACTORS = (1.0, 3.0, 10.0)
DRIFT_FACTORS = (0.01, 0.1, 1.0)
NOISE_FIELDS = (
    "gyro_noise",
    "accel_noise",
    "velocity_noise",
    "initial_gravity_std",
    "initial_velocity_std",
    "initial_gyro_bias_std",
    "gyro_bias_random_walk",
)
"""The fields of VelocityEKFParams that the fit sets (the others are limits and the filter's structure)."""


def _standing_index(run: BipedRun) -> np.ndarray:
    """IMU samples taken while the robot stands still, before it starts walking."""
    return np.flatnonzero(run.imu_time < run.gait.stand_time)


def standing_statistics(runs: list[BipedRun]) -> dict:
    """Step 1 of the module docstring: noise and bias spreads from the standing samples of `runs`."""
    if not runs:
        raise ValueError("runs must hold at least one walk")
    accel_var, gyro_var, gyro_square, gyro_means, magnitudes, counts = [], [], [], [], [], []
    for run in runs:
        index = _standing_index(run)
        if index.size < 10:
            raise ValueError(f"a walk stands for {index.size} IMU samples; at least 10 are needed")
        accel, gyro = run.accel[index], run.gyro[index]
        accel_var.append(np.var(accel, axis=0, ddof=1).mean())
        gyro_var.append(np.var(gyro, axis=0, ddof=1).mean())
        gyro_square.append(np.mean(gyro**2))
        gyro_means.append(gyro.mean(axis=0))
        magnitudes.append(float(np.linalg.norm(accel.mean(axis=0))))
        counts.append(index.size)
    gyro_noise = math.sqrt(float(np.mean(gyro_var)))
    # The spread of the means, less what the white noise alone puts into a mean of N samples.
    mean_square = float(np.mean(np.square(gyro_means)))
    bias_spread = math.sqrt(max(mean_square - gyro_noise**2 / float(np.mean(counts)), mean_square / 4.0))
    return {
        "walks": len(runs),
        "samples_per_walk": counts,
        "accel_noise": math.sqrt(float(np.mean(accel_var))),
        "gyro_noise": gyro_noise,
        "gyro_rms_raw": math.sqrt(float(np.mean(gyro_square))),
        "gyro_bias_spread": bias_spread,
        "gravity_magnitude_spread": math.sqrt(float(np.mean((np.asarray(magnitudes) - GRAVITY) ** 2))),
    }


def kinematic_velocity_error(runs: list[BipedRun], results: list[dict]) -> float:
    """RMS per component of kinematics+gyro's velocity against the truth, at the samples with a support foot."""
    squares = []
    for run, result in zip(runs, results):
        valid = result["foot"] >= 0
        squares.append((result["kin"]["kinematics+gyro"][valid] - run.true_kin_velocity[valid]) ** 2)
    return math.sqrt(float(np.mean(np.concatenate(squares))))


def _grid(variant: str, standing: dict, sigma_v: float, duration: float) -> list[dict]:
    """The 24 settings of one filter tried on the training walks."""
    settings = []
    for fv in VELOCITY_FACTORS:
        for second in range(3):
            noise = {
                "velocity_noise": sigma_v * fv,
                "initial_velocity_std": sigma_v * fv,
                "accel_noise": standing["accel_noise"],
                "initial_gravity_std": standing["gravity_magnitude_spread"],
                "initial_gyro_bias_std": standing["gyro_bias_spread"],
            }
            if VARIANT_SETTINGS[variant]["estimate_gyro_bias"]:
                noise["gyro_noise"] = standing["gyro_noise"]
                noise["gyro_bias_random_walk"] = (
                    standing["gyro_bias_spread"] / math.sqrt(duration) * DRIFT_FACTORS[second]
                )
            else:
                gyro = standing["gyro_noise"] if VARIANT_SETTINGS[variant]["zero_gyro"] else standing["gyro_rms_raw"]
                noise["gyro_noise"] = gyro * GYRO_FACTORS[second]
                noise["gyro_bias_random_walk"] = standing["gyro_bias_spread"] / math.sqrt(duration)
            settings.append(noise)
    return settings


def fit_noise(runs: list[BipedRun]) -> dict:
    """Steps 1-3 of the module docstring on the training walks `runs`; returns the fit (the JSON's content)."""
    if not runs:
        raise ValueError("runs must hold at least one walk")
    standing = standing_statistics(runs)
    duration = float(runs[0].imu_time[-1])
    # A first pass with a placeholder σ_v gives the kinematic estimates (they do not depend on the filter).
    placeholder = {"ekf": variant_params({"velocity_noise": 1.0}, "ekf")}
    first = [run_estimators(run, placeholder, kinematics_zero_gyro=True) for run in runs]
    sigma_v = kinematic_velocity_error(runs, first)
    out: dict = {
        "standing": standing,
        "kinematic_velocity_rms_error": sigma_v,
        "duration": duration,
        "criterion": "mean over the training walks of the average-forward-velocity error, percent",
        "grid": {},
        "variants": {},
        "training_error_percent": {},
    }
    for variant in EKF_VARIANTS:
        settings = _grid(variant, standing, sigma_v, duration)
        params = {f"{variant} #{i}": variant_params(noise, variant) for i, noise in enumerate(settings)}
        zero = {name: VARIANT_SETTINGS[variant]["zero_gyro"] for name in params}
        errors = np.zeros((len(runs), len(settings)))
        for r, run in enumerate(runs):
            figures = average_forward_velocity(run, run_estimators(run, params, zero_gyro=zero))
            errors[r] = [figures[name]["error_percent"] for name in params]
        score = errors.mean(axis=0)
        best = int(np.argmin(score))
        out["grid"][variant] = [{**settings[i], "mean_error_percent": float(score[i])} for i in range(len(settings))]
        chosen = variant_params(settings[best], variant)
        out["variants"][variant] = dataclasses.asdict(chosen)
        out["training_error_percent"][variant] = errors[:, best].tolist()
    kinematics = {}
    for zeroed in (True, False):
        results = first if zeroed else [run_estimators(run, placeholder, kinematics_zero_gyro=False) for run in runs]
        kinematics[zeroed] = [
            average_forward_velocity(run, res)["kinematics+gyro"]["error_percent"] for run, res in zip(runs, results)
        ]
    zeroed_best = bool(np.mean(kinematics[True]) <= np.mean(kinematics[False]))
    out["kinematics_zero_gyro"] = zeroed_best
    out["kinematics_gyro_mean_error_percent"] = {
        "zeroed": float(np.mean(kinematics[True])),
        "raw": float(np.mean(kinematics[False])),
    }
    out["training_error_percent"]["kinematics+gyro"] = kinematics[zeroed_best]
    return out


def training_walks(seeds, duration: float, progress: bool = False) -> list[BipedRun]:
    """The training walks: straight, twist and slip on, robots drawn with `RobotVariation()`."""
    from mcl.tools.cli_checks import progress_bar

    runs = []
    for seed in progress_bar(list(seeds), enabled=progress, desc="training walks", unit="walk"):
        runs.append(simulate_walk(duration, seed, variation=RobotVariation()))
    return runs


def format_fit(fit: dict) -> str:
    """The fit as text: the standing statistics, σ_v, each filter's chosen settings and training error."""
    st = fit["standing"]
    seeds = fit["training_seeds"]
    lines = [
        f"EKF noise settings fitted on training seeds {seeds[0]}-{seeds[-1]} ({len(seeds)} straight walks of "
        f"{fit['duration']:.0f} s, robots drawn per walk: links +-{100 * fit['variation']['link_length_error']:.0f} %)",
        f"  standing: accel noise {st['accel_noise']:.4f} m/s^2, gyro noise {st['gyro_noise']:.5f} rad/s, "
        f"raw gyro rms {st['gyro_rms_raw']:.5f} rad/s,",
        f"            gyro bias spread {st['gyro_bias_spread']:.5f} rad/s, |g| spread "
        f"{st['gravity_magnitude_spread']:.4f} m/s^2",
        f"  kinematics+gyro velocity error against the truth (rms per component): "
        f"{100 * fit['kinematic_velocity_rms_error']:.2f} cm/s",
        f"  criterion: {fit['criterion']}",
    ]
    width = max(len(LABELS[name]) for name in EKF_VARIANTS) + 2
    lines.append(
        f"  {'filter':<{width}}{'sigma_v':>9}{'sigma_w':>10}{'sigma_q':>9}{'sigma_b':>10}"
        f"{'mean err %':>12}{'median':>8}{'max':>7}"
    )
    for name in EKF_VARIANTS:
        p = fit["variants"][name]
        e = fit["training_error_percent"][name]
        lines.append(
            f"  {LABELS[name]:<{width}}{p['velocity_noise']:>9.4f}{p['gyro_noise']:>10.5f}"
            f"{p['accel_noise']:>9.4f}"
            + (f"{p['gyro_bias_random_walk']:>10.2e}" if p["estimate_gyro_bias"] else f"{'-':>10}")
            + f"{np.mean(e):>12.2f}{np.median(e):>8.2f}{np.max(e):>7.2f}"
        )
    k = fit["kinematics_gyro_mean_error_percent"]
    e = fit["training_error_percent"]["kinematics+gyro"]
    lines.append(
        f"  {'kinematics+gyro':<{width}}gyro {'zeroed' if fit['kinematics_zero_gyro'] else 'raw'} "
        f"(mean error {k['zeroed']:.2f} % zeroed, {k['raw']:.2f} % raw); median {np.median(e):.2f}, "
        f"max {np.max(e):.2f}"
    )
    return "\n".join(lines)


PROG = "robocup-mcl fit ekf"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument("--json", action="store_true", help="print the fit as JSON")
    add_save_option(parser)
    parser.add_argument(
        "--seeds",
        type=int,
        default=len(TRAINING_SEEDS),
        help=f"how many training walks, the first of seeds {TRAINING_SEEDS[0]}-{TRAINING_SEEDS[-1]} "
        f"(default {len(TRAINING_SEEDS)})",
    )
    parser.add_argument("--duration", type=float, default=28.0, help="seconds of each training walk")
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl fit ekf` (see --help); returns the exit status."""
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    from mcl.tools.cli_checks import check_output_file, progress_wanted, save_and_print

    check_output_file(args.save, "--save")
    if not 1 <= args.seeds <= len(TRAINING_SEEDS):
        parser.error(f"--seeds must be within 1-{len(TRAINING_SEEDS)}, got {args.seeds}")
    if not (math.isfinite(args.duration) and args.duration >= 4.0):
        parser.error(f"--duration must be at least 4 s, got {args.duration}")
    seeds = list(TRAINING_SEEDS[: args.seeds])
    runs = training_walks(seeds, args.duration, progress=progress_wanted(args))
    fit = {"training_seeds": seeds, "variation": dataclasses.asdict(RobotVariation()), **fit_noise(runs)}
    fit["fields"] = list(NOISE_FIELDS)
    save_and_print(fit, args.save, args.json, lambda result: print(format_fit(result)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
