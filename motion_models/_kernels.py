"""Numba kernels shared by the motion models, and their plain numpy references.

Every kernel draws its variates from the `numpy.random.Generator` it is given, in a fixed order (particle by
particle, x then y then theta), so the numpy reference that draws the same arrays reproduces it bit for bit.
"""
import math

import numba
import numpy as np

from field.angles import wrap_angle, wrap_angles

SQRT3 = math.sqrt(3.0)


@numba.njit(cache=True)
def move_with_noise(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, rng):
    """Apply the robot-frame displacement (dx, dy, dtheta) to every pose, then add robot-frame noise.

    The noise of axis k is uniform on [-bound_k, bound_k] (Hoffmann eq. 10), or, with `gaussian`, normal with
    the same variance (sigma = bound / sqrt(3)), so that switching the distribution keeps the spread.
    """
    scale = 1.0 / SQRT3 if gaussian else 1.0
    for i in range(poses.shape[0]):
        if gaussian:
            ex = rng.standard_normal() * bound_x * scale
            ey = rng.standard_normal() * bound_y * scale
            et = rng.standard_normal() * bound_theta * scale
        else:
            ex = rng.uniform(-1.0, 1.0) * bound_x
            ey = rng.uniform(-1.0, 1.0) * bound_y
            et = rng.uniform(-1.0, 1.0) * bound_theta
        theta = poses[i, 2]
        c = math.cos(theta)
        s = math.sin(theta)
        mx = dx + ex
        my = dy + ey
        poses[i, 0] += c * mx - s * my
        poses[i, 1] += s * mx + c * my
        poses[i, 2] = wrap_angle(theta + dtheta + et)


def move_with_noise_reference(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, rng):
    """Plain numpy twin of `move_with_noise` (same draws, same order)."""
    n = poses.shape[0]
    if gaussian:
        noise = rng.standard_normal((n, 3)) * (np.array([bound_x, bound_y, bound_theta]) / SQRT3)
    else:
        noise = rng.uniform(-1.0, 1.0, (n, 3)) * np.array([bound_x, bound_y, bound_theta])
    theta = poses[:, 2].copy()
    c, s = np.cos(theta), np.sin(theta)
    mx = dx + noise[:, 0]
    my = dy + noise[:, 1]
    poses[:, 0] += c * mx - s * my
    poses[:, 1] += s * mx + c * my
    poses[:, 2] = wrap_angles(theta + dtheta + noise[:, 2])
