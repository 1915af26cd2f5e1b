"""The per-call costs `robocup-mcl bench` reports beside the filter step: LWPR and the velocity EKF.

    from mcl.bench_models import time_lwpr, time_ekf

LWPR (`motion_models.lwpr`), 2 inputs and 1 output: the model of the cross benchmark (`demos.lwpr_cross`) after
its 20 training epochs; µs per `update` in steady state and per `predict` of one point, as that benchmark
times them (best of a few repetitions, validation and numba dispatch included). The velocity EKF
(`sensing.velocity.VelocityEKF`): µs per `predict` (one IMU sample) and per `correct` (one leg-kinematics
velocity), public calls with their validation, for the default filter (gyro bias in the state, 9 states)
and the paper's (6 states).
"""
from __future__ import annotations

import numpy as np

from .bench_step import measure


def time_lwpr(seed: int = 0) -> dict:
    from demos.lwpr_cross import make_model, run_seed

    warm = make_model()           # load (or compile) the kernels outside the timings
    warm.update(np.zeros(2), np.zeros(1))
    warm.predict(np.zeros(2))
    run = run_seed(seed)
    return {"inputs": 2, "outputs": 1, "receptive_fields": run["num_rfs"], "nmse": run["nmse"],
            "update_us": run["us_per_update"], "predict_us": run["us_per_predict"],
            "predict_batched_us_per_point": run["us_per_predict_batched"],
            "method": "demos.lwpr_cross.run_seed: the cross benchmark's model after 20 epochs, best of repetitions"}


def time_ekf(budget_s: float = 0.3) -> dict:
    from sensing.velocity import VelocityEKF, VelocityEKFParams

    gravity = np.array([0.0, 0.0, 9.81])
    gyro, accel = np.array([0.01, -0.02, 0.3]), np.array([0.1, 0.05, 9.8])
    measured = np.array([0.2, 0.01, 0.0])
    result = {}
    for label, params in (("default", VelocityEKFParams()),
                          ("paper", VelocityEKFParams(estimate_gyro_bias=False))):
        ekf = VelocityEKF(gravity, 0.0, params=params)
        clock = {"t": 0.0}

        def predict(ekf=ekf, clock=clock):
            clock["t"] += 0.01
            ekf.predict(clock["t"], gyro, accel)

        timed = measure({"predict": predict, "correct": lambda ekf=ekf: ekf.correct(measured)}, budget_s,
                        min_samples=20)
        result[label] = {"state_size": params.state_size, "predict_us": 1e6 * timed["predict"]["s"],
                         "correct_us": 1e6 * timed["correct"]["s"]}
    return result
