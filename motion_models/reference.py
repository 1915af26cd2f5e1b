"""The motion kernels' plain numpy twins, which the tests and the benchmark compare the compiled kernels with.

    from motion_models import reference
    reference.move_with_noise(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates)

The same variates give the same poses (and mobility states) as the kernels of the same name in
`motion_models.kernels` and `motion_models.adaptive`. (`motion_models.lwpr_reference` is LWPR's.)
"""

from __future__ import annotations

import math

import numpy as np

from field.angles import wrap_angles
from numerics.reference import sincos
from numerics.trig import SQRT3


def move_with_noise(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates):
    """Plain numpy twin of `motion_models.kernels.move_with_noise` (the same variates give the same poses)."""
    if gaussian:
        noise = variates * (np.array([bound_x, bound_y, bound_theta]) / SQRT3)
    else:
        noise = (2.0 * variates - 1.0) * np.array([bound_x, bound_y, bound_theta])
    theta = poses[:, 2].copy()
    c, s = sincos(theta)
    mx = dx + noise[:, 0]
    my = dy + noise[:, 1]
    poses[:, 0] += c * mx - s * my
    poses[:, 1] += s * mx + c * my
    poses[:, 2] = wrap_angles(theta + dtheta + noise[:, 2])


def adaptive_move(poses, state, cumulative, vx, vy, omega, dt, side, params, redraw_each_step, variates):
    """Plain numpy twin of `motion_models.adaptive.adaptive_move` (the same variates give the same poses and states)."""
    beta1, beta2, beta3, beta4, beta5, beta6, beta7, beta_turn, separation, odo1, odo2, odo3, odo4, creep = params
    old = state[:, 0].astype(np.int64)
    new = (variates[:, 0][:, None] >= cumulative[old]).sum(axis=1)
    renew = ((old == 0) & (new != 0)) | bool(redraw_each_step)
    state[renew, 1:4] = variates[renew, 1:4]
    state[:, 0] = new
    e1, e2, e3 = state[:, 1], state[:, 2], state[:, 3]
    n = poses.shape[0]
    ex, ey, w = np.full(n, vx), np.full(n, vy), np.full(n, omega)
    px, py = np.zeros(n), np.zeros(n)
    slip, hinder, pushed, stopped = new == 1, new == 2, new == 3, new == 4
    factor = np.where(slip, beta1 + (1 - beta1) * e1, np.where(hinder, beta3 + (1 - beta3) * e1, 1.0))
    ex, ey = ex * factor, ey * factor
    w = np.where(slip, omega + beta2 * (2 * e2 - 1), w)
    w = np.where(hinder, omega * (beta4 + (1 - beta4) * e2), w)
    alpha = np.pi * (2 * e1 - 1)
    cos_alpha, sin_alpha = sincos(alpha)
    px = np.where(pushed, beta5 * e2 * cos_alpha, 0.0)
    py = np.where(pushed, beta5 * e2 * sin_alpha, 0.0)
    w = np.where(pushed, omega + beta6 * (2 * e3 - 1), w)
    creep_share = 0.0 if math.isnan(side) else creep * abs(side)
    walk_on = creep_share * e1 if creep_share != 0.0 else np.zeros(n)
    ex, ey = np.where(stopped, vx * walk_on, ex), np.where(stopped, vy * walk_on, ey)
    speed = math.hypot(vx, vy)
    turn = speed / separation * side * beta_turn * e1 if not math.isnan(side) else beta7 * (2 * e1 - 1)
    w = np.where(stopped, turn, w)
    walked = np.hypot(ex, ey)
    bounds = np.column_stack([odo1 * walked * dt, odo2 * walked * dt, (odo3 * walked + odo4 * np.abs(w)) * dt])
    noise = (2 * variates[:, 4:7] - 1) * bounds
    half = 0.5 * w * dt
    safe = np.where(np.abs(half) > 1e-9, half, 1.0)
    chord = np.where(np.abs(half) > 1e-9, sincos(safe)[1] / safe, 1.0)
    dx = (ex + px) * dt * chord + noise[:, 0]
    dy = (ey + py) * dt * chord + noise[:, 1]
    theta = poses[:, 2].copy()
    c, s = sincos(theta + half)
    poses[:, 0] += c * dx - s * dy
    poses[:, 1] += s * dx + c * dy
    poses[:, 2] = wrap_angles(theta + w * dt + noise[:, 2])
