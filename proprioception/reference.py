"""The velocity EKF's plain numpy twins, which the tests compare the compiled kernels with and
`VelocityEKF(..., backend="numpy")` runs.

    from proprioception import reference
    state, cov = reference.ekf_predict(state, cov, gyro, accel, dt, sigma_w, sigma_q)   # ekf_predict_kernel
    state, cov = reference.ekf_correct(state, cov, measured, sigma_v)                   # ekf_correct_kernel

Each function computes what the kernel of the same name in `proprioception.velocity` computes (`*_kernel`), with
numpy's arrays: the same results to rounding. The rotations come from `proprioception.velocity` (`rotate`,
`rotation_matrix`, `rotation_derivative`, `rotation_derivative_at`).
"""

from __future__ import annotations

import math

import numpy as np

from proprioception.velocity import rotate, rotation_derivative, rotation_derivative_at, rotation_matrix


def imu_step(state, gyro, accel, dt) -> np.ndarray:
    """Eq. 2–4 in numpy, returning the new [g, v]."""
    state = np.asarray(state, dtype=np.float64)
    gyro = np.asarray(gyro, dtype=np.float64)
    g_mid = rotate(-gyro * dt / 2.0, state[:3])
    v = rotate(-gyro * dt, state[3:]) + (np.asarray(accel, dtype=np.float64) - g_mid) * dt
    return np.concatenate([rotate(-gyro * dt / 2.0, g_mid), v])


def ekf_jacobians(state, gyro, dt, sigma_w, sigma_q, exact=True) -> tuple[np.ndarray, np.ndarray]:
    """F (eq. 24, or its exact form) and C (eq. 25) in numpy."""
    state = np.asarray(state, dtype=np.float64)
    gyro = np.asarray(gyro, dtype=np.float64)
    eye = np.eye(3)
    if exact:
        half = rotation_matrix(-gyro * dt / 2.0)
        full = half @ half
        f = np.block([[full, np.zeros((3, 3))], [-half * dt, full]])
    else:
        f = np.block([[eye, np.zeros((3, 3))], [-eye * dt, eye]])
    dg = rotation_derivative(state[:3])
    dv = rotation_derivative(state[3:])
    c = np.block(
        [[dg * dt * sigma_w, np.zeros((3, 3))], [dv * dt * sigma_w - dg * dt**2 * sigma_w / 2.0, -eye * dt * sigma_q]]
    )
    return f, c


def ekf_predict(state, cov, gyro, accel, dt, sigma_w, sigma_q, exact=True):
    """Numpy twin of `ekf_predict_kernel`: returns (state, covariance)."""
    f, c = ekf_jacobians(state, gyro, dt, sigma_w, sigma_q, exact)
    new_cov = f @ cov @ f.T + c @ c.T
    return imu_step(state, gyro, accel, dt), (new_cov + new_cov.T) / 2.0


def bias_imu_step(state, gyro, accel, dt) -> np.ndarray:
    """The IMU step of the state [g, v, b] in numpy: eq. 2–4 with the rate ω̂ - b; b unchanged."""
    state = np.asarray(state, dtype=np.float64)
    corrected = np.asarray(gyro, dtype=np.float64) - state[6:]
    return np.concatenate([imu_step(state[:6], corrected, accel, dt), state[6:]])


def ekf_bias_jacobians(state, gyro, dt, sigma_w, sigma_q, sigma_b, exact=True) -> tuple[np.ndarray, np.ndarray]:
    """F and C of the filter with state [g, v, b] in numpy (see `ekf_bias_jacobians_kernel`)."""
    state = np.asarray(state, dtype=np.float64)
    corrected = np.asarray(gyro, dtype=np.float64) - state[6:]
    g, v = state[:3], state[3:6]
    f6, _ = ekf_jacobians(state[:6], corrected, dt, sigma_w, sigma_q, exact)
    if exact:
        # -∂[g, v]⁺/∂u with g⁺ = f(-uδ, g), v⁺ = f(-uδ, v) + (q - f(-uδ/2, g))δ.
        full, half = -corrected * dt, -corrected * dt / 2.0
        f_gb = rotation_derivative_at(full, g) * dt
        f_vb = rotation_derivative_at(full, v) * dt - rotation_derivative_at(half, g) * dt**2 / 2.0
    else:
        f_gb = rotation_derivative(g) * dt
        f_vb = rotation_derivative(v) * dt - rotation_derivative(g) * dt**2 / 2.0
    f_b = np.vstack([f_gb, f_vb])
    f = np.block([[f6, f_b], [np.zeros((3, 6)), np.eye(3)]])
    c = np.zeros((9, 9))
    c[:6, :3] = f_b * sigma_w
    c[3:6, 3:6] = -np.eye(3) * dt * sigma_q
    c[6:, 6:] = np.eye(3) * math.sqrt(dt) * sigma_b
    return f, c


def ekf_bias_predict(state, cov, gyro, accel, dt, sigma_w, sigma_q, sigma_b, exact=True):
    """Numpy twin of `ekf_bias_predict_kernel`: returns (state, covariance)."""
    f, c = ekf_bias_jacobians(state, gyro, dt, sigma_w, sigma_q, sigma_b, exact)
    new_cov = f @ cov @ f.T + c @ c.T
    return bias_imu_step(state, gyro, accel, dt), (new_cov + new_cov.T) / 2.0


def ekf_correct(state, cov, measured, sigma_v):
    """Numpy twin of `ekf_correct_kernel`: returns (state, covariance)."""
    n = state.shape[0]
    h = np.zeros((3, n))  # eq. 33, H = [0 I] (and 0 for the bias)
    h[:, 3:6] = np.eye(3)
    s = h @ cov @ h.T + np.eye(3) * sigma_v**2
    gain = np.linalg.solve(s, h @ cov).T  # P Hᵀ S⁻¹ (S and P symmetric)
    new_state = state + gain @ (np.asarray(measured, dtype=np.float64) - state[3:6])
    a = np.eye(n) - gain @ h
    new_cov = a @ cov @ a.T + sigma_v**2 * gain @ gain.T
    return new_state, (new_cov + new_cov.T) / 2.0
