"""The belief's summary: the pose estimate of the dominant cluster, and grid entropy (Hoffmann eq. 27).

    from mcl.estimate import cluster_estimate, grid_entropy, credible_region_contains

The field is point-symmetric, so a lost filter may hold two mirror modes; their mean is the centre of the
field, facing nowhere. The estimate is therefore the weighted circular mean of the dominant cluster: the
heaviest cell of a coarse (x, y, θ) histogram seeds a few rounds of mean shift with a flat kernel (heading
averaged as wrapped residuals about the current centre, the intrinsic circular mean), and the covariance is
that of the particles the kernel holds. The cluster's share of the weight is returned too.

Entropy is computed on a grid as in the paper, position and orientation separately, in bits:
H = -Σ p(sᵢ) log₂ p(sᵢ), p(sᵢ) the weight in cell i. It lies in [0, log₂(cells)] and is zero while every
particle shares one cell.

`credible_region_contains` tells whether a pose lies in the smallest region holding 95 % of the belief: the
check that the truth stays inside the particle cloud.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from field.angles import wrap_angle, wrap_angles


@numba.njit(cache=True, inline="always")
def _cell(value, origin, size, count):
    c = int(math.floor((value - origin) / size))
    if c < 0:
        return 0
    if c >= count:
        return count - 1
    return c


@numba.njit(cache=True)
def _kernel_mean(poses, weights, cx, cy, ct, radius, angle_radius):
    """Weighted mean of the particles within the flat kernel around (cx, cy, ct).

    The heading is the intrinsic circular mean: the centre plus the weighted mean of the wrapped residuals
    (one step of the Fréchet-mean iteration on the circle; repeated calls converge). Within the kernel's
    ±angle_radius this needs no trigonometry.
    """
    sx = 0.0
    sy = 0.0
    st = 0.0
    total = 0.0
    r2 = radius * radius
    for i in range(poses.shape[0]):
        dx = poses[i, 0] - cx
        dy = poses[i, 1] - cy
        dt = wrap_angle(poses[i, 2] - ct)
        if dx * dx + dy * dy > r2 or abs(dt) > angle_radius:
            continue
        w = weights[i]
        sx += w * dx
        sy += w * dy
        st += w * dt
        total += w
    if total <= 0.0:
        return cx, cy, ct, 0.0
    return cx + sx / total, cy + sy / total, wrap_angle(ct + st / total), total


@numba.njit(cache=True)
def cluster_estimate(poses, weights, x_min, y_min, cell_size, nx, ny, n_theta, radius, angle_radius,
                     iterations, histogram, previous, use_previous, out_mean, out_cov):
    """Mean and covariance of the dominant cluster; returns the cluster's weight.

    histogram: scratch of nx·ny·n_theta floats. out_mean (3,), out_cov (3, 3) are written. When the cluster
    grown from the heaviest cell holds less than half the weight and `use_previous`, the mean shift also
    starts from `previous` (the last estimate) and the heavier of the two clusters wins: a tight cluster
    split across cell boundaries then is not lost to a clump that fits in one cell.
    """
    histogram[:] = 0.0
    theta_size = 2.0 * math.pi / n_theta
    for i in range(poses.shape[0]):
        cx = _cell(poses[i, 0], x_min, cell_size, nx)
        cy = _cell(poses[i, 1], y_min, cell_size, ny)
        ct = _cell(poses[i, 2], -math.pi, theta_size, n_theta)
        histogram[(cx * ny + cy) * n_theta + ct] += weights[i]
    best = np.argmax(histogram)
    bt = best % n_theta
    by = (best // n_theta) % ny
    bx = best // (n_theta * ny)
    # Seed: the centre of the heaviest cell; the kernel is wider than a cell, so mean shift merges its
    # neighbours and walks to the mode.
    mx = x_min + (bx + 0.5) * cell_size
    my = y_min + (by + 0.5) * cell_size
    mt = -math.pi + (bt + 0.5) * theta_size
    total = 0.0
    for _ in range(iterations):
        mx, my, mt, total = _kernel_mean(poses, weights, mx, my, mt, radius, angle_radius)
    if use_previous and total < 0.5:
        px, py, pt, ptotal = previous[0], previous[1], previous[2], 0.0
        for _ in range(iterations):
            px, py, pt, ptotal = _kernel_mean(poses, weights, px, py, pt, radius, angle_radius)
        if ptotal > total:
            mx, my, mt, total = px, py, pt, ptotal
    # Covariance of the held particles, θ residual wrapped around the circular mean.
    cov = np.zeros((3, 3))
    r2 = radius * radius
    if total > 0.0:
        for i in range(poses.shape[0]):
            dx = poses[i, 0] - mx
            dy = poses[i, 1] - my
            dt = wrap_angle(poses[i, 2] - mt)
            if dx * dx + dy * dy > r2 or abs(dt) > angle_radius:
                continue
            w = weights[i] / total
            cov[0, 0] += w * dx * dx
            cov[0, 1] += w * dx * dy
            cov[0, 2] += w * dx * dt
            cov[1, 1] += w * dy * dy
            cov[1, 2] += w * dy * dt
            cov[2, 2] += w * dt * dt
    cov[1, 0] = cov[0, 1]
    cov[2, 0] = cov[0, 2]
    cov[2, 1] = cov[1, 2]
    out_mean[0] = mx
    out_mean[1] = my
    out_mean[2] = wrap_angle(mt)
    out_cov[:, :] = cov
    return total


@numba.njit(cache=True)
def _entropy_bits(histogram):
    h = 0.0
    for p in histogram:
        if p > 0.0:
            h -= p * math.log2(p)
    return max(h, 0.0)


@numba.njit(cache=True)
def grid_entropy(poses, weights, x_min, y_min, cell_size, nx, ny, n_theta, position_histogram,
                 orientation_histogram):
    """Position and orientation entropy in bits (Hoffmann eq. 27) on a grid; weights must sum to one.

    Particles beyond the grid count in its border cells. The histograms are scratch arrays of nx·ny and
    n_theta floats.
    """
    position_histogram[:] = 0.0
    orientation_histogram[:] = 0.0
    theta_size = 2.0 * math.pi / n_theta
    for i in range(poses.shape[0]):
        cx = _cell(poses[i, 0], x_min, cell_size, nx)
        cy = _cell(poses[i, 1], y_min, cell_size, ny)
        position_histogram[cx * ny + cy] += weights[i]
        orientation_histogram[_cell(poses[i, 2], -math.pi, theta_size, n_theta)] += weights[i]
    return _entropy_bits(position_histogram), _entropy_bits(orientation_histogram)


# -- plain numpy references -----------------------------------------------------------------------------------
def _cells(values, origin, size, count):
    return np.clip(np.floor((values - origin) / size).astype(np.int64), 0, count - 1)


def grid_entropy_reference(poses, weights, x_min, y_min, cell_size, nx, ny, n_theta):
    cx = _cells(poses[:, 0], x_min, cell_size, nx)
    cy = _cells(poses[:, 1], y_min, cell_size, ny)
    ct = _cells(poses[:, 2], -np.pi, 2 * np.pi / n_theta, n_theta)

    def bits(index, size):
        p = np.bincount(index, weights=weights, minlength=size)
        p = p[p > 0]
        return max(float(-(p * np.log2(p)).sum()), 0.0)

    return bits(cx * ny + cy, nx * ny), bits(ct, n_theta)


def cluster_estimate_reference(poses, weights, x_min, y_min, cell_size, nx, ny, n_theta, radius, angle_radius,
                               iterations, previous=None):
    """Numpy version of `cluster_estimate`: returns (mean (3,), cov (3, 3), weight)."""
    theta_size = 2 * np.pi / n_theta
    cx = _cells(poses[:, 0], x_min, cell_size, nx)
    cy = _cells(poses[:, 1], y_min, cell_size, ny)
    ct = _cells(poses[:, 2], -np.pi, theta_size, n_theta)
    histogram = np.bincount((cx * ny + cy) * n_theta + ct, weights=weights, minlength=nx * ny * n_theta)
    best = int(np.argmax(histogram))
    bt, by, bx = best % n_theta, (best // n_theta) % ny, best // (n_theta * ny)
    mean = np.array([x_min + (bx + 0.5) * cell_size, y_min + (by + 0.5) * cell_size, -np.pi + (bt + 0.5) * theta_size])
    def shift(mean):
        total = 0.0
        for _ in range(iterations):
            d = np.column_stack([poses[:, 0] - mean[0], poses[:, 1] - mean[1], wrap_angles(poses[:, 2] - mean[2])])
            mask = ((d[:, :2] ** 2).sum(axis=1) <= radius ** 2) & (np.abs(d[:, 2]) <= angle_radius)
            w = weights[mask]
            total = w.sum()
            if total <= 0:
                return mean, 0.0
            step = (w[:, None] * d[mask]).sum(axis=0) / total
            mean = np.array([mean[0] + step[0], mean[1] + step[1], float(wrap_angles(mean[2] + step[2]))])
        return mean, total

    mean, total = shift(mean)
    if previous is not None and total < 0.5:
        other, other_total = shift(np.asarray(previous, dtype=np.float64))
        if other_total > total:
            mean, total = other, other_total
    d = np.column_stack([poses[:, 0] - mean[0], poses[:, 1] - mean[1], wrap_angles(poses[:, 2] - mean[2])])
    mask = ((d[:, :2] ** 2).sum(axis=1) <= radius ** 2) & (np.abs(d[:, 2]) <= angle_radius)
    cov = np.zeros((3, 3))
    if total > 0:
        w = weights[mask] / total
        cov = (d[mask] * w[:, None]).T @ d[mask]
    mean[2] = float(wrap_angles(mean[2]))
    return mean, cov, float(total)


def credible_region_contains(poses: np.ndarray, weights: np.ndarray, pose, mass: float = 0.95,
                             min_bandwidth: tuple[float, float, float] = (0.005, 0.005, 0.005)) -> bool:
    """Whether `pose` (x, y, θ) lies inside the smallest region holding `mass` of the belief.

    The belief's density is a weighted kernel density estimate over the particles (Gaussian kernels, diagonal
    bandwidths by Scott's rule from the weighted spread, never below `min_bandwidth`, heading differences
    wrapped). The smallest region holding `mass` is where the density exceeds the level at which the particles
    above it hold `mass` of the weight (the highest-density region, estimated from the sample); the pose is
    inside when its density reaches that level. O(N²): meant for evaluation, not for the robot's loop.
    """
    poses = np.asarray(poses, dtype=np.float64)
    weights = np.asarray(weights, dtype=np.float64)
    pose = np.asarray(pose, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3 or weights.shape != (poses.shape[0],) or pose.shape != (3,):
        raise ValueError(f"poses (N, 3), weights (N,) and pose (3,) expected, got {poses.shape}, {weights.shape}, "
                         f"{pose.shape}")
    if not (0 < mass < 1):
        raise ValueError(f"mass = {mass!r} must be within (0, 1)")
    weights = weights / weights.sum()
    n_effective = 1.0 / float(np.sum(weights ** 2))
    centre = np.array([weights @ poses[:, 0], weights @ poses[:, 1],
                       math.atan2(weights @ np.sin(poses[:, 2]), weights @ np.cos(poses[:, 2]))])
    residual = poses - centre
    residual[:, 2] = wrap_angles(residual[:, 2])
    spread = np.sqrt(weights @ residual ** 2)
    bandwidth = np.maximum(spread * n_effective ** (-1.0 / 7.0), np.asarray(min_bandwidth))   # Scott, d = 3

    def density(points: np.ndarray) -> np.ndarray:
        difference = points[:, None, :] - poses[None, :, :]
        difference[..., 2] = wrap_angles(difference[..., 2])
        return np.exp(-0.5 * np.sum((difference / bandwidth) ** 2, axis=-1)) @ weights

    at_particles = density(poses)
    order = np.argsort(-at_particles, kind="stable")
    held = np.cumsum(weights[order])
    level = at_particles[order[min(int(np.searchsorted(held, mass)), order.size - 1)]]
    return bool(density(pose[None, :])[0] >= level)
