"""Numba kernels shared by the motion models, and their plain numpy references.

Kernels take pre-drawn variates (drawn from the filter's one Generator by `draw_variates`), so a kernel is a
deterministic function of its inputs and its numpy twin reproduces it from the same variates. (Passing the
Generator itself into numba costs about 10 µs of unboxing per call, more than the whole kernel at N = 100.)
"""
import math

import numba
import numpy as np

from field.angles import wrap_angle, wrap_angles

SQRT3 = math.sqrt(3.0)


def draw_variates(rng, n: int, gaussian: bool) -> np.ndarray:
    """The (n, 3) variates `move_with_noise` consumes: standard normals, or uniforms on [0, 1)."""
    return rng.standard_normal((n, 3)) if gaussian else rng.random((n, 3))


@numba.njit(cache=True)
def move_with_noise(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates):
    """Apply the robot-frame displacement (dx, dy, dtheta) to every pose, then add robot-frame noise.

    The noise of axis k is uniform on [-bound_k, bound_k] (Hoffmann eq. 10) from uniform variates u as
    (2u - 1)·bound, or, with `gaussian`, normal with the same variance (sigma = bound / sqrt(3)), so that
    switching the distribution keeps the spread. `variates` (N, 3) come from `draw_variates`.
    """
    if gaussian:
        sx = bound_x / SQRT3
        sy = bound_y / SQRT3
        st = bound_theta / SQRT3
    for i in range(poses.shape[0]):
        if gaussian:
            ex = variates[i, 0] * sx
            ey = variates[i, 1] * sy
            et = variates[i, 2] * st
        else:
            ex = (2.0 * variates[i, 0] - 1.0) * bound_x
            ey = (2.0 * variates[i, 1] - 1.0) * bound_y
            et = (2.0 * variates[i, 2] - 1.0) * bound_theta
        theta = poses[i, 2]
        c = math.cos(theta)
        s = math.sin(theta)
        mx = dx + ex
        my = dy + ey
        poses[i, 0] += c * mx - s * my
        poses[i, 1] += s * mx + c * my
        poses[i, 2] = wrap_angle(theta + dtheta + et)


def move_with_noise_reference(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates):
    """Plain numpy twin of `move_with_noise` (the same variates give the same poses)."""
    if gaussian:
        noise = variates * (np.array([bound_x, bound_y, bound_theta]) / SQRT3)
    else:
        noise = (2.0 * variates - 1.0) * np.array([bound_x, bound_y, bound_theta])
    theta = poses[:, 2].copy()
    c, s = np.cos(theta), np.sin(theta)
    mx = dx + noise[:, 0]
    my = dy + noise[:, 1]
    poses[:, 0] += c * mx - s * my
    poses[:, 1] += s * mx + c * my
    poses[:, 2] = wrap_angles(theta + dtheta + noise[:, 2])
