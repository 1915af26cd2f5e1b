"""Velocity and tilt of a legged robot from IMU, leg kinematics and foot contacts (Wawrzyński et al.).

    from proprioception.velocity import VelocityEKF, VelocityEKFParams, LegOdometry, planar_increment

    ekf = VelocityEKF.from_standing(accel_samples, time=t0, gyro_samples=gyro_samples)   # eq. 1, b from the gyro
    ekf.predict(t, gyro, accel)                                  # at the IMU rate, eq. 28–31, raw gyro
    ekf.correct(v_kg)                                            # at the kinematics rate, eq. 32–37
    dx, dy, dtheta = planar_increment(ekf.gravity, ekf.velocity, gyro - ekf.gyro_bias, dt)   # robot-frame odometry

    paper = VelocityEKFParams(estimate_gyro_bias=False, exact_jacobian=False)   # the paper's filter as written,
    ekf = VelocityEKF.from_standing(accel_samples, time=t0, params=paper)        # given the raw gyro

    odometry = LegOdometry((left_chain, right_chain), ekf)       # or let it pick the support foot
    odometry.imu(t, gyro, accel)
    sample = odometry.kinematics(t, joint_angles, contacts)      # predicts only when no foot is down

The four estimators of the paper: `ImuOnlyEstimator` (eq. 1–4), `kinematic_velocity` (eq. 5–10),
`kinematic_gyro_velocity` (eq. 11–14) and `VelocityEKF` (eq. 15–37). All work in the IMU's immobile frame: `g`
is the accelerometer reading at rest (pointing up, |g| ≈ 9.81 m/s²), `v` the IMU velocity over the ground.

The EKF prediction and correction run in numba kernels (`ekf_predict_kernel`, `ekf_correct_kernel`); the plain
numpy twins (`proprioception.reference`: `ekf_predict`, `ekf_correct`) compute the same thing and serve as reference.
Choices beyond the paper, all documented where they are made: the transition Jacobian F keeps the rotation
blocks that eq. 24 drops to first order (`exact_jacobian=False` gives eq. 24 verbatim); the covariance update
of eq. 37 is evaluated in Joseph form, equal in exact arithmetic, so P stays symmetric positive definite.

The gyro bias (not in the paper, on by default: `VelocityEKFParams(estimate_gyro_bias=True)`): the state is
[g, v, b], the IMU step turns g and v by ω̂ - b, and b is a slow random walk (`gyro_bias_random_walk`).
Without it, a bias left after zeroing the gyro on a standing robot keeps turning g, and the velocity follows
the corrections with a lag, which biases v. Its kernels are `ekf_bias_predict_kernel` and
`ekf_bias_jacobians_kernel` (numpy: `proprioception.reference.ekf_bias_predict`, `ekf_bias_jacobians`); the
correction is shared. The paper's filter as written is `estimate_gyro_bias=False, exact_jacobian=False` with
the raw gyro; giving `from_standing` the standing gyro samples (their mean subtracted) is a variant.

Bad input raises ValueError naming the field, and leaves the filter as it was: non-finite samples, a time that
does not advance, an IMU gap longer than `max_imu_gap`. With no foot on the ground the filter only predicts;
its velocity covariance grows and `is_stale` turns true after `max_prediction_time` without a correction.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from field.checks import LARGEST_SIGMA, SMALLEST_SIGMA, real
from field.moved import moved_names
from proprioception.kinematics import LegChain

__getattr__ = moved_names(
    __name__,
    {
        "imu_step_reference": "proprioception.reference.imu_step",
        "ekf_jacobians_reference": "proprioception.reference.ekf_jacobians",
        "ekf_predict_reference": "proprioception.reference.ekf_predict",
        "bias_imu_step_reference": "proprioception.reference.bias_imu_step",
        "ekf_bias_jacobians_reference": "proprioception.reference.ekf_bias_jacobians",
        "ekf_bias_predict_reference": "proprioception.reference.ekf_bias_predict",
        "ekf_correct_reference": "proprioception.reference.ekf_correct",
    },
)


# ---------------------------------------------------------------------------------------------------------
# f(β, x): x rotated by the rotation vector β, and its derivative at β = 0
# ---------------------------------------------------------------------------------------------------------
@numba.njit(cache=True, inline="always")
def _identity_plus_skew_terms(beta0, beta1, beta2, angle2, p, q, out):
    """out = I + p [β]× + q [β]×², with [β]×² = β βᵀ - |β|² I: the form of both R(β) and J(β)."""
    out[0, 0] = 1.0 + q * (beta0 * beta0 - angle2)
    out[1, 1] = 1.0 + q * (beta1 * beta1 - angle2)
    out[2, 2] = 1.0 + q * (beta2 * beta2 - angle2)
    out[0, 1] = -p * beta2 + q * beta0 * beta1
    out[1, 0] = p * beta2 + q * beta0 * beta1
    out[0, 2] = p * beta1 + q * beta0 * beta2
    out[2, 0] = -p * beta1 + q * beta0 * beta2
    out[1, 2] = -p * beta0 + q * beta1 * beta2
    out[2, 1] = p * beta0 + q * beta1 * beta2


@numba.njit(cache=True, inline="always")
def _so3_matrix_kernel(beta0, beta1, beta2, out, jacobian):
    """R(β) (Rodrigues) or, with `jacobian`, the left Jacobian J(β) of SO(3), written into out (3, 3)."""
    angle2 = beta0 * beta0 + beta1 * beta1 + beta2 * beta2
    if jacobian:
        if angle2 < 1e-12:
            # Taylor terms: (1 - cos θ)/θ² ≈ 1/2 - θ²/24, (θ - sin θ)/θ³ ≈ 1/6 - θ²/120.
            p = 0.5 - angle2 / 24.0
            q = 1.0 / 6.0 - angle2 / 120.0
        else:
            angle = math.sqrt(angle2)
            p = (1.0 - math.cos(angle)) / angle2
            q = (angle - math.sin(angle)) / (angle2 * angle)
    elif angle2 < 1e-16:
        # Taylor terms: sin(θ)/θ ≈ 1 - θ²/6, (1 - cos θ)/θ² ≈ 1/2 - θ²/24.
        p = 1.0 - angle2 / 6.0
        q = 0.5 - angle2 / 24.0
    else:
        angle = math.sqrt(angle2)
        p = math.sin(angle) / angle
        q = (1.0 - math.cos(angle)) / angle2
    # R = I + (sin θ/θ) [β]× + ((1 - cos θ)/θ²) [β]×²;  J = I + ((1 - cos θ)/θ²) [β]× + ((θ - sin θ)/θ³) [β]×².
    _identity_plus_skew_terms(beta0, beta1, beta2, angle2, p, q, out)


@numba.njit(cache=True)
def rotation_matrix_kernel(beta0, beta1, beta2, out):
    """Rotation matrix of the rotation vector β (Rodrigues), written into out (3, 3)."""
    _so3_matrix_kernel(beta0, beta1, beta2, out, False)


@numba.njit(cache=True)
def left_jacobian_kernel(beta0, beta1, beta2, out):
    """Left Jacobian J(β) of SO(3), written into out (3, 3): R(β + dβ) = R(J(β) dβ) R(β) to first order."""
    _so3_matrix_kernel(beta0, beta1, beta2, out, True)


def _so3_matrix(kernel, beta) -> np.ndarray:
    beta = np.asarray(beta, dtype=np.float64)
    out = np.empty((3, 3))
    kernel(beta[0], beta[1], beta[2], out)
    return out


def rotation_matrix(beta) -> np.ndarray:
    """Rotation matrix of the rotation vector β: f(β, x) = rotation_matrix(β) @ x."""
    return _so3_matrix(rotation_matrix_kernel, beta)


def left_jacobian(beta) -> np.ndarray:
    """Left Jacobian of SO(3) at the rotation vector β."""
    return _so3_matrix(left_jacobian_kernel, beta)


def rotate(beta, x) -> np.ndarray:
    """f(β, x) of the paper: x rotated about the rotation vector β."""
    return rotation_matrix(beta) @ np.asarray(x, dtype=np.float64)


def skew(x) -> np.ndarray:
    """[x]×, the matrix of eq. 26: skew(x) @ y = x × y."""
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def rotation_derivative(x) -> np.ndarray:
    """∂f(β, x)/∂β at β = 0, which is -[x]×.

    Eq. 26 prints +[x]×; the sign does not matter to the filter because C enters only through C·Cᵀ (eq. 31),
    and the finite-difference test checks this form.
    """
    return -skew(x)


def rotation_derivative_at(beta, x) -> np.ndarray:
    """∂f(β, x)/∂β at any β: -[f(β, x)]× J(β) (J the left Jacobian); at β = 0 it is `rotation_derivative`."""
    return -skew(rotate(beta, x)) @ left_jacobian(beta)


# ---------------------------------------------------------------------------------------------------------
# Kernels
# ---------------------------------------------------------------------------------------------------------
@numba.njit(cache=True)
def imu_step_kernel(state, gyro, accel, dt):
    """Eq. 2–4 (and 28–30) in place on state = [g, v]: gravity turned in two halves around the velocity step."""
    half = np.empty((3, 3))
    rotation_matrix_kernel(-gyro[0] * dt / 2.0, -gyro[1] * dt / 2.0, -gyro[2] * dt / 2.0, half)
    full = half @ half
    g_mid = half @ state[:3]  # eq. 2
    v_new = full @ state[3:]  # eq. 3, f(-ωδ, v) + (q - g)δ
    for k in range(3):
        state[3 + k] = v_new[k] + (accel[k] - g_mid[k]) * dt
    g_new = half @ g_mid  # eq. 4
    for k in range(3):
        state[k] = g_new[k]


@numba.njit(cache=True)
def ekf_jacobians_kernel(state, gyro, dt, sigma_w, sigma_q, exact, f_out, c_out):
    """F (eq. 24) and C (eq. 25–26) at the prior state, written into f_out (6, 6) and c_out (6, 6)."""
    f_out[:, :] = 0.0
    c_out[:, :] = 0.0
    if exact:
        half = np.empty((3, 3))
        rotation_matrix_kernel(-gyro[0] * dt / 2.0, -gyro[1] * dt / 2.0, -gyro[2] * dt / 2.0, half)
        full = half @ half
        for r in range(3):
            for c in range(3):
                f_out[r, c] = full[r, c]
                f_out[3 + r, 3 + c] = full[r, c]
                f_out[3 + r, c] = -half[r, c] * dt
    else:
        for k in range(3):
            f_out[k, k] = 1.0
            f_out[3 + k, 3 + k] = 1.0
            f_out[3 + k, k] = -dt
    g0, g1, g2 = state[0], state[1], state[2]
    v0, v1, v2 = state[3], state[4], state[5]
    # ∂f(β, x)/∂β = -[x]× (see `rotation_derivative`).
    dg = np.array([[0.0, g2, -g1], [-g2, 0.0, g0], [g1, -g0, 0.0]])
    dv = np.array([[0.0, v2, -v1], [-v2, 0.0, v0], [v1, -v0, 0.0]])
    for r in range(3):
        for c in range(3):
            c_out[r, c] = dg[r, c] * dt * sigma_w
            c_out[3 + r, c] = dv[r, c] * dt * sigma_w - dg[r, c] * dt * dt * sigma_w / 2.0
        c_out[3 + r, 3 + r] = -dt * sigma_q


@numba.njit(cache=True)
def propagate_covariance(cov, f, c):
    """cov ← F cov Fᵀ + C Cᵀ in place (eq. 31), exactly symmetric; skips the zeros of the sparse F."""
    n = cov.shape[0]
    fp = np.zeros((n, n))
    for i in range(n):
        for k in range(n):
            fik = f[i, k]
            if fik != 0.0:
                for j in range(n):
                    fp[i, j] += fik * cov[k, j]
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for k in range(n):
                acc += fp[i, k] * f[j, k] + c[i, k] * c[j, k]
            cov[i, j] = acc
            cov[j, i] = acc


@numba.njit(cache=True)
def ekf_predict_kernel(state, cov, gyro, accel, dt, sigma_w, sigma_q, exact):
    """EKF prediction in place: state by eq. 28–30, covariance by eq. 31 (P ← F P Fᵀ + C Cᵀ)."""
    f = np.empty((6, 6))
    c = np.empty((6, 6))
    ekf_jacobians_kernel(state, gyro, dt, sigma_w, sigma_q, exact, f, c)
    imu_step_kernel(state, gyro, accel, dt)
    propagate_covariance(cov, f, c)


@numba.njit(cache=True)
def _skew_times_kernel(x, m, scale, out, row):
    """out[row:row+3, 6:9] += scale · [x]× m."""
    for c in range(3):
        out[row + 0, 6 + c] += scale * (-x[2] * m[1, c] + x[1] * m[2, c])
        out[row + 1, 6 + c] += scale * (x[2] * m[0, c] - x[0] * m[2, c])
        out[row + 2, 6 + c] += scale * (-x[1] * m[0, c] + x[0] * m[1, c])


@numba.njit(cache=True)
def ekf_bias_jacobians_kernel(state, gyro, dt, sigma_w, sigma_q, sigma_b, exact, f_out, c_out):
    """F and C of the filter with state [g, v, b] at the prior state, into f_out (9, 9) and c_out (9, 9).

    The IMU step turns g and v by the corrected rate u = ω̂ - b; the bias is a random walk. F's bias columns
    are ∂[g, v]⁺/∂b = -∂[g, v]⁺/∂u. The gyro noise enters through the same u = ω̂ - b - ω̃, so C's gyro-noise
    columns are σ_ω times the bias columns of F. exact: every block exact, the bias columns through the left
    Jacobian of SO(3); not exact: eq. 24 and eq. 25 verbatim for [g, v], and the bias columns at u = 0 (which
    are then eq. 25's gyro columns over σ_ω). C's accelerometer columns are those of eq. 25; its bias columns
    σ_b √δ I, the random walk of b over δ.
    """
    f_out[:, :] = 0.0
    c_out[:, :] = 0.0
    u0, u1, u2 = gyro[0] - state[6], gyro[1] - state[7], gyro[2] - state[8]
    g = state[0:3].copy()
    v = state[3:6].copy()
    if exact:
        half = np.empty((3, 3))
        rotation_matrix_kernel(-u0 * dt / 2.0, -u1 * dt / 2.0, -u2 * dt / 2.0, half)
        full = half @ half
        for r in range(3):
            for c in range(3):
                f_out[r, c] = full[r, c]
                f_out[3 + r, 3 + c] = full[r, c]
                f_out[3 + r, c] = -half[r, c] * dt
        jac_full = np.empty((3, 3))
        jac_half = np.empty((3, 3))
        left_jacobian_kernel(-u0 * dt, -u1 * dt, -u2 * dt, jac_full)
        left_jacobian_kernel(-u0 * dt / 2.0, -u1 * dt / 2.0, -u2 * dt / 2.0, jac_half)
        # g⁺ = f(-uδ, g), v⁺ = f(-uδ, v) + (q - f(-uδ/2, g))δ, and ∂f(β, x)/∂β = -[f(β, x)]× J(β).
        _skew_times_kernel(full @ g, jac_full, -dt, f_out, 0)
        _skew_times_kernel(full @ v, jac_full, -dt, f_out, 3)
        _skew_times_kernel(half @ g, jac_half, dt * dt / 2.0, f_out, 3)
    else:
        for k in range(3):
            f_out[k, k] = 1.0
            f_out[3 + k, 3 + k] = 1.0
            f_out[3 + k, k] = -dt
        eye = np.eye(3)
        _skew_times_kernel(g, eye, -dt, f_out, 0)
        _skew_times_kernel(v, eye, -dt, f_out, 3)
        _skew_times_kernel(g, eye, dt * dt / 2.0, f_out, 3)
    root_dt = math.sqrt(dt)
    for r in range(6):
        for c in range(3):
            c_out[r, c] = f_out[r, 6 + c] * sigma_w
    for k in range(3):
        f_out[6 + k, 6 + k] = 1.0
        c_out[3 + k, 3 + k] = -dt * sigma_q
        c_out[6 + k, 6 + k] = root_dt * sigma_b


@numba.njit(cache=True)
def ekf_bias_predict_kernel(state, cov, gyro, accel, dt, sigma_w, sigma_q, sigma_b, exact):
    """Prediction of the filter with state [g, v, b], in place: eq. 28–30 with ω̂ - b, b kept; P ← F P Fᵀ + C Cᵀ.

    gyro is the raw sample ω̂; the state's bias is subtracted here.
    """
    f = np.empty((9, 9))
    c = np.empty((9, 9))
    ekf_bias_jacobians_kernel(state, gyro, dt, sigma_w, sigma_q, sigma_b, exact, f, c)
    corrected = np.empty(3)
    for k in range(3):
        corrected[k] = gyro[k] - state[6 + k]
    imu_step_kernel(state[:6], corrected, accel, dt)
    propagate_covariance(cov, f, c)


@numba.njit(cache=True)
def ekf_correct_kernel(state, cov, measured, sigma_v):
    """EKF correction in place with the velocity measurement v^KG (eq. 32–37), covariance in Joseph form.

    Any state whose entries 3–5 are the velocity: [g, v] (n = 6) or [g, v, b] (n = 9).
    """
    n = state.shape[0]
    # S = H P Hᵀ + σ_v² I (eq. 34), H = [0 I] (eq. 33); inverse by cofactors.
    s = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            s[r, c] = cov[3 + r, 3 + c]
        s[r, r] += sigma_v * sigma_v
    det = (
        s[0, 0] * (s[1, 1] * s[2, 2] - s[1, 2] * s[2, 1])
        - s[0, 1] * (s[1, 0] * s[2, 2] - s[1, 2] * s[2, 0])
        + s[0, 2] * (s[1, 0] * s[2, 1] - s[1, 1] * s[2, 0])
    )
    inv = np.empty((3, 3))
    inv[0, 0] = (s[1, 1] * s[2, 2] - s[1, 2] * s[2, 1]) / det
    inv[0, 1] = (s[0, 2] * s[2, 1] - s[0, 1] * s[2, 2]) / det
    inv[0, 2] = (s[0, 1] * s[1, 2] - s[0, 2] * s[1, 1]) / det
    inv[1, 0] = (s[1, 2] * s[2, 0] - s[1, 0] * s[2, 2]) / det
    inv[1, 1] = (s[0, 0] * s[2, 2] - s[0, 2] * s[2, 0]) / det
    inv[1, 2] = (s[0, 2] * s[1, 0] - s[0, 0] * s[1, 2]) / det
    inv[2, 0] = (s[1, 0] * s[2, 1] - s[1, 1] * s[2, 0]) / det
    inv[2, 1] = (s[0, 1] * s[2, 0] - s[0, 0] * s[2, 1]) / det
    inv[2, 2] = (s[0, 0] * s[1, 1] - s[0, 1] * s[1, 0]) / det
    gain = np.zeros((n, 3))  # K = P Hᵀ S⁻¹ (eq. 35)
    for i in range(n):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += cov[i, 3 + k] * inv[k, j]
            gain[i, j] = acc
    innovation = np.empty(3)  # eq. 32
    for k in range(3):
        innovation[k] = measured[k] - state[3 + k]
    for i in range(n):  # eq. 36
        acc = 0.0
        for k in range(3):
            acc += gain[i, k] * innovation[k]
        state[i] += acc
    # eq. 37 as (I - KH) P (I - KH)ᵀ + σ_v² K Kᵀ.
    a = np.zeros((n, n))
    for i in range(n):
        a[i, i] = 1.0
        for k in range(3):
            a[i, 3 + k] -= gain[i, k]
    ap = np.zeros((n, n))
    for i in range(n):
        for k in range(n):
            aik = a[i, k]
            if aik != 0.0:
                for j in range(n):
                    ap[i, j] += aik * cov[k, j]
    r2 = sigma_v * sigma_v
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for k in range(n):
                acc += ap[i, k] * a[j, k]
            for k in range(3):
                acc += r2 * gain[i, k] * gain[j, k]
            cov[i, j] = acc
            cov[j, i] = acc


# ---------------------------------------------------------------------------------------------------------
# Validation helpers
# ---------------------------------------------------------------------------------------------------------
_FLOAT64 = np.dtype(np.float64)


def _vector3(value, name: str) -> np.ndarray:
    """`value` as a finite float64 array (3,), C-contiguous (itself when it already is one, not a copy).

    Called on every IMU sample: the common case, a float64 (3,) array, is checked without numpy calls."""
    if type(value) is np.ndarray and value.dtype is _FLOAT64 and value.shape == (3,) and value.flags.c_contiguous:
        arr = value
    else:
        arr = np.asarray(value, dtype=np.float64)
        if arr.shape != (3,):
            raise ValueError(f"{name} must have shape (3,), got {arr.shape}")
        arr = np.ascontiguousarray(arr)
    x, y, z = arr.tolist()
    if not (abs(x) <= MAX_SAMPLE and abs(y) <= MAX_SAMPLE and abs(z) <= MAX_SAMPLE):
        raise ValueError(f"{name} must be finite and within ±{MAX_SAMPLE:g}, got {arr.tolist()}")
    return arr


def _time(value, name: str = "time") -> float:
    t = float(value)
    if not math.isfinite(t):
        raise ValueError(f"{name} must be finite, got {t}")
    return t


MAX_SAMPLE = 1e4
"""The largest |component| of a gyro (rad/s), accelerometer (m/s²) or velocity (m/s) sample: far beyond any IMU's
range, small enough that the filter's products stay finite."""


def _positive(value, name: str, low: float = 0.0) -> float:
    """A number within (low, LARGEST_SIGMA] (ValueError naming `name` otherwise)."""
    return real(name, value, low, LARGEST_SIGMA, low_open=True)


def _standing_samples(values, name: str) -> np.ndarray:
    """A standing robot's samples as a finite float64 array (N, 3), N >= 1 (one sample (3,) is one row)."""
    samples = np.asarray(values, dtype=np.float64)
    if samples.ndim == 1:
        samples = samples[None, :]
    if samples.ndim != 2 or samples.shape[1] != 3 or samples.shape[0] == 0:
        raise ValueError(f"{name} must have shape (N, 3) with N >= 1, got {samples.shape}")
    if not np.all(np.isfinite(samples)):
        raise ValueError(f"{name} must be finite")
    return samples


def _standing_gyro_bias(gyro_samples) -> np.ndarray:
    if gyro_samples is None:
        return np.zeros(3)
    return _standing_samples(gyro_samples, "gyro_samples").mean(axis=0)


def _standing_gravity(accel_samples) -> np.ndarray:
    gravity = _standing_samples(accel_samples, "accel_samples").mean(axis=0)  # eq. 1, averaged over the samples
    if np.linalg.norm(gravity) < 1.0:
        raise ValueError(f"accel_samples must show gravity (mean norm >= 1 m/s²), got {gravity.tolist()}")
    return gravity


# ---------------------------------------------------------------------------------------------------------
# Estimator 1: IMU only (eq. 1–4)
# ---------------------------------------------------------------------------------------------------------
class _GravityVelocityState:
    """The accessors of an estimator whose state starts with [g, v] (eq. 15), at time `_time`; copies."""

    _state: np.ndarray
    _time: float

    @property
    def time(self) -> float:
        return self._time

    @property
    def gravity(self) -> np.ndarray:
        return self._state[:3].copy()

    @property
    def velocity(self) -> np.ndarray:
        return self._state[3:6].copy()


class ImuOnlyEstimator(_GravityVelocityState):
    """Dead reckoning from the IMU (eq. 1–4): gravity turned by the gyro, velocity integrated from q - g."""

    def __init__(
        self, gravity, time: float, velocity=(0.0, 0.0, 0.0), max_imu_gap: float = 0.1, gyro_bias=(0.0, 0.0, 0.0)
    ):
        self._state = np.concatenate([_vector3(gravity, "gravity"), _vector3(velocity, "velocity")])
        self._time = _time(time)
        self.max_imu_gap = _positive(max_imu_gap, "max_imu_gap")
        self.gyro_bias = _vector3(gyro_bias, "gyro_bias").copy()

    @classmethod
    def from_standing(cls, accel_samples, time: float, gyro_samples=None, **kwargs) -> ImuOnlyEstimator:
        """Eq. 1: gravity from the accelerometer of a robot standing still (mean of the samples), v = 0.

        With `gyro_samples` of the same still period, their mean is taken as the gyro bias and subtracted
        from every later sample (an addition to the paper, which assumes an unbiased gyroscope).
        """
        return cls(_standing_gravity(accel_samples), time, gyro_bias=_standing_gyro_bias(gyro_samples), **kwargs)

    def update(self, time: float, gyro, accel) -> None:
        """Eq. 2–4 over the interval since the previous sample."""
        dt = _imu_interval(time, self._time, self.max_imu_gap)
        gyro = _vector3(gyro, "gyro") - self.gyro_bias
        accel = _vector3(accel, "accel")
        imu_step_kernel(self._state, gyro, accel, dt)
        self._time = float(time)


def _imu_interval(time, previous: float, max_gap: float) -> float:
    t = _time(time)
    dt = t - previous
    if not dt > 0.0:
        raise ValueError(
            f"time must be after the previous sample time {previous!r}, got {t!r} (IMU samples "
            "out of order or repeated)"
        )
    if dt > max_gap:
        raise ValueError(
            f"time {t!r} leaves a gap of {dt:.4g} s after the previous sample, more than "
            f"max_imu_gap = {max_gap!r} s: restart the estimator from a standing robot"
        )
    return dt


# ---------------------------------------------------------------------------------------------------------
# Estimators 2 and 3: kinematics (eq. 5–10) and kinematics with the gyroscope (eq. 11–14)
# ---------------------------------------------------------------------------------------------------------
def kinematic_velocity(chain: LegChain, angles, rates) -> np.ndarray:
    """Eq. 5–10: IMU velocity in its immobile frame from the support leg, assuming the foot does not move."""
    return chain.velocities(angles, rates)[0]


def kinematic_gyro_velocity(chain: LegChain, angles, rates, gyro) -> np.ndarray:
    """Eq. 11–14: as `kinematic_velocity`, with the foot's own rotation taken from the gyroscope."""
    return chain.velocities(angles, rates, gyro)[1]


# ---------------------------------------------------------------------------------------------------------
# Estimator 4: the EKF (eq. 15–37)
# ---------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class VelocityEKFParams:
    """Noise and limits of the EKF.

    gyro_noise, accel_noise: σ_ω (rad/s) and σ_q (m/s²) of eq. 22, standard deviations of one IMU sample's
    error; velocity_noise: σ_v (m/s) of eq. 27, that of one v^KG measurement. initial_gravity_std and
    initial_velocity_std give the starting covariance. An IMU gap longer than max_imu_gap (s) is refused;
    `is_stale` is true after max_prediction_time (s) without a correction. exact_jacobian keeps the rotation
    blocks of F (False: eq. 24 as printed).

    estimate_gyro_bias adds the gyro bias b to the state, [g, v, b] (not in the paper). The paper's filter as
    written is `estimate_gyro_bias=False, exact_jacobian=False`, given the raw gyro (no standing-sample bias
    subtracted: `VelocityEKF.from_standing` without `gyro_samples`). gyro_noise is, with the bias state, the
    white noise alone, since the bias is no longer noise. initial_gyro_bias_std (rad/s) is the bias's starting
    standard deviation when it is not measured from a standing robot (`VelocityEKF.from_standing` with gyro
    samples uses the standard error of their mean). gyro_bias_random_walk σ_b (rad/s/√s) is the bias's random
    walk: its variance grows by σ_b² δ per prediction.

    The noise defaults are the settings that `robocup-mcl fit ekf` fitted for the filter with the bias state
    (results/ekf_fit.json, variant "ekf+bias", rounded to three digits): σ_ω and σ_q from standing samples,
    σ_v and σ_b chosen on training walks of simulated NAO-type robots. Another robot needs its own fit.

    Parameters
    ----------
    gyro_noise, accel_noise, velocity_noise : float
        σ_ω (rad/s), σ_q (m/s²), σ_v (m/s).
    initial_gravity_std, initial_velocity_std, initial_gyro_bias_std : float
        Starting standard deviations of g (m/s²), v (m/s) and b (rad/s).
    max_imu_gap, max_prediction_time : float
        Seconds: the longest IMU gap accepted; the prediction time after which the filter is stale.
    exact_jacobian, estimate_gyro_bias : bool
        F with its rotation blocks; the [g, v, b] state.
    gyro_bias_random_walk : float
        σ_b, rad/s/√s.

    Raises
    ------
    ValueError
        When a standard deviation or a limit is not a finite positive number within the accepted range.
    """

    gyro_noise: float = 0.00998
    accel_noise: float = 0.0497
    velocity_noise: float = 0.00139
    initial_gravity_std: float = 0.210
    initial_velocity_std: float = 0.00139
    max_imu_gap: float = 0.1
    max_prediction_time: float = 1.0
    exact_jacobian: bool = True
    estimate_gyro_bias: bool = True
    initial_gyro_bias_std: float = 0.0168
    gyro_bias_random_walk: float = 0.000317

    def __post_init__(self):
        for name in (
            "gyro_noise",
            "accel_noise",
            "velocity_noise",
            "initial_gravity_std",
            "initial_velocity_std",
            "initial_gyro_bias_std",
        ):
            real(name, getattr(self, name), SMALLEST_SIGMA, LARGEST_SIGMA)
        for name in ("max_imu_gap", "max_prediction_time", "gyro_bias_random_walk"):
            _positive(getattr(self, name), name)

    @property
    def state_size(self) -> int:
        return 9 if self.estimate_gyro_bias else 6

    def initial_covariance(self, gyro_bias_std: float | None = None) -> np.ndarray:
        """The starting P: diagonal, from the initial standard deviations (bias: `gyro_bias_std` if given)."""
        variances = [self.initial_gravity_std**2] * 3 + [self.initial_velocity_std**2] * 3
        if self.estimate_gyro_bias:
            std = self.initial_gyro_bias_std if gyro_bias_std is None else gyro_bias_std
            variances += [std**2] * 3
        return np.diag(variances)


BACKENDS = ("numba", "reference")


class VelocityEKF(_GravityVelocityState):
    """The EKF of Section V: state [g, v] (eq. 15), prediction from the IMU, correction from v^KG.

    With `params.estimate_gyro_bias` the state is [g, v, b]: the gyro bias b is estimated and the IMU step
    uses ω̂ - b (`gyro_bias` is then the current estimate); without it, `gyro_bias` is a constant subtracted
    from every sample and the filter is the paper's. `backend` is "numba" (the kernels) or "reference" (the
    numpy twins); both give the same numbers to rounding. Accessors return copies.
    """

    def __init__(
        self,
        gravity,
        time: float,
        params: VelocityEKFParams = VelocityEKFParams(),
        velocity=(0.0, 0.0, 0.0),
        covariance=None,
        backend: str = "numba",
        gyro_bias=(0.0, 0.0, 0.0),
    ):
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        if not isinstance(params, VelocityEKFParams):
            raise ValueError(f"params must be a VelocityEKFParams, got {type(params).__name__}")
        self.params = params
        self.backend = backend
        bias = _vector3(gyro_bias, "gyro_bias").copy()
        self._state = np.concatenate([_vector3(gravity, "gravity"), _vector3(velocity, "velocity")])
        if params.estimate_gyro_bias:
            self._state = np.concatenate([self._state, bias])
        self._fixed_gyro_bias = bias
        n = params.state_size
        if covariance is None:
            covariance = params.initial_covariance()
        cov = np.array(covariance, dtype=np.float64)
        if cov.shape != (n, n) or not np.all(np.isfinite(cov)):
            raise ValueError(f"covariance must be a finite ({n}, {n}) matrix, got shape {cov.shape}")
        if not np.allclose(cov, cov.T) or np.linalg.eigvalsh((cov + cov.T) / 2.0).min() <= 0.0:
            raise ValueError("covariance must be symmetric positive definite")
        self._cov = np.ascontiguousarray((cov + cov.T) / 2.0)
        self._time = _time(time)
        self._last_correction = self._time
        self.n_predictions = 0
        self.n_corrections = 0

    @classmethod
    def from_standing(
        cls,
        accel_samples,
        time: float,
        params: VelocityEKFParams = VelocityEKFParams(),
        backend: str = "numba",
        gyro_samples=None,
    ) -> VelocityEKF:
        """Eq. 1: start from a robot standing still; gravity is the mean accelerometer sample, v = 0.

        With `gyro_samples` of the same still period, their mean is taken as the gyro bias. The paper's filter
        (eq. 15, no bias in the state) subtracts it from every later sample; what remains of the bias turns g
        steadily, which the velocity corrections can only follow with a lag, biasing v. With
        `params.estimate_gyro_bias` the mean starts the state's b, with the standard error of the mean,
        σ_ω / √N, as its standard deviation.
        """
        gravity = _standing_gravity(accel_samples)
        bias = _standing_gyro_bias(gyro_samples)
        covariance = None
        if params.estimate_gyro_bias and gyro_samples is not None:
            n_samples = np.asarray(gyro_samples, dtype=np.float64).reshape(-1, 3).shape[0]
            covariance = params.initial_covariance(params.gyro_noise / math.sqrt(n_samples))
        return cls(gravity, time, params=params, backend=backend, gyro_bias=bias, covariance=covariance)

    def predict(self, time: float, gyro, accel) -> None:
        """Prediction with the IMU sample taken at `time` (eq. 28–31), δ = time - previous time."""
        p = self.params
        dt = _imu_interval(time, self._time, p.max_imu_gap)
        gyro = _vector3(gyro, "gyro")
        accel = _vector3(accel, "accel")
        if p.estimate_gyro_bias:
            if self.backend == "numba":
                ekf_bias_predict_kernel(
                    self._state,
                    self._cov,
                    gyro,
                    accel,
                    dt,
                    p.gyro_noise,
                    p.accel_noise,
                    p.gyro_bias_random_walk,
                    p.exact_jacobian,
                )
            else:
                from proprioception import reference  # (the numpy twins import this module's rotations)

                self._state, self._cov = reference.ekf_bias_predict(
                    self._state,
                    self._cov,
                    gyro,
                    accel,
                    dt,
                    p.gyro_noise,
                    p.accel_noise,
                    p.gyro_bias_random_walk,
                    p.exact_jacobian,
                )
            self._time = float(time)
            self.n_predictions += 1
            return
        gyro = gyro - self._fixed_gyro_bias
        if self.backend == "numba":
            ekf_predict_kernel(self._state, self._cov, gyro, accel, dt, p.gyro_noise, p.accel_noise, p.exact_jacobian)
        else:
            from proprioception import reference

            self._state, self._cov = reference.ekf_predict(
                self._state, self._cov, gyro, accel, dt, p.gyro_noise, p.accel_noise, p.exact_jacobian
            )
        self._time = float(time)
        self.n_predictions += 1

    def correct(self, measured_velocity, noise: float | None = None) -> None:
        """Correction with a velocity v^KG of the IMU in its immobile frame (eq. 32–37), at the current time."""
        measured = _vector3(measured_velocity, "measured_velocity")
        sigma_v = self.params.velocity_noise if noise is None else real("noise", noise, SMALLEST_SIGMA, LARGEST_SIGMA)
        if self.backend == "numba":
            ekf_correct_kernel(self._state, self._cov, measured, sigma_v)
        else:
            from proprioception import reference

            self._state, self._cov = reference.ekf_correct(self._state, self._cov, measured, sigma_v)
        self._last_correction = self._time
        self.n_corrections += 1

    @property
    def gyro_bias(self) -> np.ndarray:
        """The bias subtracted from the gyro: the estimate b, or the constant one of the paper's filter."""
        if self.params.estimate_gyro_bias:
            return self._state[6:].copy()
        return self._fixed_gyro_bias.copy()

    @property
    def state(self) -> np.ndarray:
        """[g, v] or [g, v, b]."""
        return self._state.copy()

    @property
    def covariance(self) -> np.ndarray:
        return self._cov.copy()

    @property
    def time_since_correction(self) -> float:
        return self._time - self._last_correction

    @property
    def is_stale(self) -> bool:
        """True once the filter has only predicted for longer than `max_prediction_time`."""
        return self.time_since_correction > self.params.max_prediction_time


# ---------------------------------------------------------------------------------------------------------
# Support foot and the whole pipeline
# ---------------------------------------------------------------------------------------------------------
def support_foot(contacts, previous: int = -1, min_pressed: int = 2) -> int:
    """Index of the foot to use for kinematics, or -1 when none is on the ground.

    contacts: (n_feet, n_sensors) booleans. A foot is on the ground with at least `min_pressed` sensors
    pressed; among those, the most pressed wins, ties going to `previous` if it is among them, else the first.
    """
    pressed = np.asarray(contacts, dtype=bool).sum(axis=1)
    down = pressed >= min_pressed
    if not down.any():
        return -1
    best = pressed[down].max()
    candidates = np.flatnonzero(down & (pressed == best))
    if previous in candidates:
        return int(previous)
    return int(candidates[0])


class KinematicSample(NamedTuple):
    """One kinematics-rate result of `LegOdometry.kinematics`."""

    time: float
    foot: int  # index of the support leg, -1 when no correction was made
    velocity_kinematic: np.ndarray  # v^K (eq. 10), NaN when foot == -1
    velocity_kinematic_gyro: np.ndarray  # v^KG (eq. 14), NaN when foot == -1


class LegOdometry:
    """IMU samples drive the EKF prediction; joint encoders and foot contacts drive its correction.

    Joint rates are backward differences of consecutive encoder readings; the gyroscope of eq. 11 is the mean
    of the IMU samples since the previous kinematics sample, less the EKF's gyro bias (its current estimate
    when the EKF has one). A leg is used only if its foot was on the ground at both readings (`support_foot`).
    With no such leg the EKF only predicts.
    """

    def __init__(self, chains: Sequence[LegChain], ekf: VelocityEKF, min_pressed: int = 2):
        self.chains = tuple(chains)
        if not self.chains or not all(isinstance(c, LegChain) for c in self.chains):
            raise ValueError("chains must be a non-empty sequence of LegChain")
        self.ekf = ekf
        self.min_pressed = int(min_pressed)
        self._previous_time: float | None = None
        self._previous_angles: np.ndarray | None = None
        self._previous_down: np.ndarray | None = None
        self._previous_foot = -1
        self._gyro_sum = np.zeros(3)
        self._gyro_count = 0
        self._last_gyro = np.zeros(3)

    def imu(self, time: float, gyro, accel) -> None:
        """Prediction with one IMU sample."""
        self.ekf.predict(time, gyro, accel)
        gyro = np.asarray(gyro, dtype=np.float64)
        self._gyro_sum += gyro
        self._gyro_count += 1
        self._last_gyro = gyro.copy()

    def kinematics(self, time: float, angles, contacts) -> KinematicSample:
        """Correction from joint angles (n_legs, n_joints) and contacts (n_legs, n_sensors) read at `time`."""
        t = _time(time)
        n_legs = len(self.chains)
        angles = np.asarray(angles, dtype=np.float64)
        shape = (n_legs, self.chains[0].n_joints)
        if angles.shape != shape:
            raise ValueError(f"angles must have shape {shape}, got {angles.shape}")
        if not np.all(np.isfinite(angles)):
            raise ValueError(f"angles must be finite, got {angles.tolist()}")
        contacts = np.asarray(contacts)
        if contacts.ndim != 2 or contacts.shape[0] != n_legs:
            raise ValueError(f"contacts must have shape ({n_legs}, n_sensors), got {contacts.shape}")
        if self._previous_time is not None and not t > self._previous_time:
            raise ValueError(f"time must be after the previous kinematics time {self._previous_time!r}, got {t!r}")
        down = np.asarray(contacts, dtype=bool).sum(axis=1) >= self.min_pressed
        foot = -1
        nan = np.full(3, np.nan)
        vk, vkg = nan, nan
        if self._previous_time is not None and self._previous_angles is not None:  # set together
            usable = np.where((down & self._previous_down)[:, None], contacts, False)
            foot = support_foot(usable, self._previous_foot, self.min_pressed)
            if foot >= 0:
                dt = t - self._previous_time
                rates = (angles[foot] - self._previous_angles[foot]) / dt
                gyro = self._gyro_sum / self._gyro_count if self._gyro_count else self._last_gyro
                gyro = gyro - self.ekf.gyro_bias
                vk, vkg = self.chains[foot].velocities(angles[foot], rates, gyro)
                self.ekf.correct(vkg)
        self._previous_time = t
        self._previous_angles = angles.copy()
        self._previous_down = down
        self._previous_foot = foot if foot >= 0 else self._previous_foot
        self._gyro_sum = np.zeros(3)
        self._gyro_count = 0
        return KinematicSample(t, foot, vk, vkg)


# ---------------------------------------------------------------------------------------------------------
# Planar odometry for the motion models, and tilt
# ---------------------------------------------------------------------------------------------------------
def level_frame(gravity) -> np.ndarray:
    """Rows: the level frame's x (IMU x projected on the horizontal), y, z (up, along g), in IMU coordinates."""
    g = np.asarray(gravity, dtype=np.float64)
    up = g / np.linalg.norm(g, axis=-1, keepdims=True)
    ex = np.zeros_like(up)
    ex[..., 0] = 1.0
    forward = ex - up * up[..., :1]
    norm = np.linalg.norm(forward, axis=-1, keepdims=True)
    if np.any(norm < 1e-6):
        raise ValueError("gravity must not lie along the IMU x axis (the robot is standing on its nose or back)")
    forward = forward / norm
    left = np.cross(up, forward)
    return np.stack([forward, left, up], axis=-2)


def planar_increment(gravity, velocity, gyro, dt) -> np.ndarray:
    """Pose increment (dx, dy, dθ) in the robot frame at the start of a step of `dt` seconds.

    The velocity is levelled with the gravity estimate into the horizontal plane (x: the IMU's forward axis
    projected), the yaw rate is the gyro along gravity, and both are held constant over the step, so the
    robot moves along a circular arc. Accepts one sample (3,) or rows (N, 3) with dt scalar or (N,).
    """
    gravity = np.asarray(gravity, dtype=np.float64)
    velocity = np.asarray(velocity, dtype=np.float64)
    gyro = np.asarray(gyro, dtype=np.float64)
    dt = np.asarray(dt, dtype=np.float64)
    for name, arr in (("gravity", gravity), ("velocity", velocity), ("gyro", gyro)):
        if arr.shape[-1:] != (3,) or arr.ndim > 2:
            raise ValueError(f"{name} must have shape (3,) or (N, 3), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite")
    if not np.all(np.isfinite(dt)) or np.any(dt < 0.0):
        raise ValueError(f"dt must be finite and non-negative, got {dt.tolist()}")
    frame = level_frame(gravity)
    vx = np.sum(frame[..., 0, :] * velocity, axis=-1)
    vy = np.sum(frame[..., 1, :] * velocity, axis=-1)
    yaw_rate = np.sum(frame[..., 2, :] * gyro, axis=-1)
    dtheta = yaw_rate * dt
    # ∫₀^dt R(ωt) v dt = [[s, -(1-c)], [(1-c), s]] v / ω, written so it stays exact as ω → 0.
    small = np.abs(dtheta) < 1e-6
    safe = np.where(small, 1.0, dtheta)
    sin_term = np.where(small, 1.0 - dtheta**2 / 6.0, np.sin(safe) / safe) * dt
    cos_term = np.where(small, dtheta / 2.0 - dtheta**3 / 24.0, (1.0 - np.cos(safe)) / safe) * dt
    dx = sin_term * vx - cos_term * vy
    dy = cos_term * vx + sin_term * vy
    return np.stack(np.broadcast_arrays(dx, dy, dtheta), axis=-1)


def tilt_error(estimated_gravity, true_gravity) -> np.ndarray:
    """Angle (rad) between estimated and true gravity directions; rows allowed."""
    a = np.asarray(estimated_gravity, dtype=np.float64)
    b = np.asarray(true_gravity, dtype=np.float64)
    cos = np.sum(a * b, axis=-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    sin = np.linalg.norm(np.cross(a, b), axis=-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.arctan2(sin, cos)
