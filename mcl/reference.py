"""The filter kernels' plain numpy twins, which the tests and the benchmark compare the compiled kernels with.

    from mcl import reference
    weights, log_total, ess = reference.normalize(log_weights)        # mcl.weights.normalize
    ancestors = reference.systematic(weights, m, rng)                  # mcl.resampling.systematic

Each function computes what the kernel of the same name in `mcl.weights`, `mcl.resampling`, `mcl.estimate`,
`mcl.latency`, `mcl.rivals` or `mcl.relocalization` computes (and the recording's colours), with numpy's arrays: the same random draws in the same order, and the
same results to rounding (bit for bit where its docstring says so). The filter calls them only on its reference engine
(`ParticleFilter(..., reference=True)`, `mcl.engine.ReferenceEngine`).
"""

from __future__ import annotations

import math

import numpy as np

from field.angles import TWO_PI, wrap_angles
from numerics.reference import sincos


def normalize(log_weights):
    """Numpy twin of `mcl.weights.normalize`: returns (weights, logsumexp, ESS)."""
    peak = np.max(log_weights)
    e = np.exp(log_weights - peak)
    total = e.sum()
    w = e / total
    return w, peak + math.log(total), 1.0 / np.sum(w * w)


def log_mean_likelihood(log_weights, log_likelihood, count):
    """Numpy twin of `mcl.weights.log_mean_likelihood`: log(Σ wᵢ pᵢ / Σ wᵢ) over the first `count` particles;
    -inf when none of them has a finite weight and likelihood."""
    prior = np.asarray(log_weights[:count], dtype=np.float64)
    joint = prior + np.asarray(log_likelihood[:count], dtype=np.float64)
    if count <= 0 or np.max(prior) == -np.inf or np.max(joint) == -np.inf:
        return -np.inf
    peak_prior, peak_joint = np.max(prior), np.max(joint)
    return float(
        peak_joint
        + math.log(np.sum(np.exp(joint - peak_joint)))
        - peak_prior
        - math.log(np.sum(np.exp(prior - peak_prior)))
    )


def gather_with_jitter(source, ancestors, bounds, uniforms):
    """Numpy twin of `mcl.resampling.gather_with_jitter`."""
    picked = source[ancestors].copy()
    noise = (2.0 * uniforms - 1.0) * bounds
    c, s = sincos(picked[:, 2])
    picked[:, 0] += c * noise[:, 0] - s * noise[:, 1]
    picked[:, 1] += s * noise[:, 0] + c * noise[:, 1]
    picked[:, 2] = wrap_angles(picked[:, 2] + noise[:, 2])
    return picked


def _searchsorted(weights: np.ndarray, points: np.ndarray) -> np.ndarray:
    cumulative = np.cumsum(weights)
    return np.minimum(np.searchsorted(cumulative, points, side="right"), weights.shape[0] - 1)


def systematic(weights, m, rng):
    return _searchsorted(np.asarray(weights, float), (rng.random() + np.arange(m)) / m)


def stratified(weights, m, rng):
    return _searchsorted(np.asarray(weights, float), (np.arange(m) + rng.random(m)) / m)


def multinomial(weights, m, rng):
    spacings = rng.standard_exponential(m + 1)
    running = np.cumsum(spacings)  # running[-1] is the sequential total, as the kernel sums it
    return _searchsorted(np.asarray(weights, float), running[:-1] / running[-1])


def residual(weights, m, rng):
    """Numpy twin of `mcl.resampling.residual`: ⌊M·wᵢ⌋ copies of each particle, the rest drawn multinomially
    from the residual weights (the same exponential draws)."""
    weights = np.asarray(weights, float)
    copies = np.minimum(np.floor(m * weights).astype(np.int64), m)
    excess = int(copies.sum()) - m
    if excess > 0:  # rounding in weights that sum to slightly more than one
        copies[np.argmax(copies)] -= excess
    rest = m - int(copies.sum())
    spacings = rng.standard_exponential(rest + 1)
    kept = np.repeat(np.arange(weights.shape[0]), copies)
    if rest <= 0:
        return kept
    remainder = m * weights - copies
    total = float(np.sum(remainder))
    remainder = remainder / total if total > 0.0 else np.full(weights.shape[0], 1.0 / weights.shape[0])
    running = np.cumsum(spacings)
    return np.concatenate([kept, _searchsorted(remainder, running[:-1] / running[-1])])


def _cells(values, origin, size, count):
    return np.clip(np.floor((values - origin) / size).astype(np.int64), 0, count - 1)


def grid_entropy(poses, weights, x_min, y_min, cell_size, nx, ny, n_theta):
    cx = _cells(poses[:, 0], x_min, cell_size, nx)
    cy = _cells(poses[:, 1], y_min, cell_size, ny)
    ct = _cells(poses[:, 2], -np.pi, 2 * np.pi / n_theta, n_theta)

    def bits(index, size):
        p = np.bincount(index, weights=weights, minlength=size)
        p = p[p > 0]
        return max(float(-(p * np.log2(p)).sum()), 0.0)

    return bits(cx * ny + cy, nx * ny), bits(ct, n_theta)


def cluster_estimate(
    poses, weights, x_min, y_min, cell_size, nx, ny, n_theta, radius, angle_radius, iterations, previous=None
):
    """Numpy version of `mcl.estimate.cluster_estimate`: returns (mean (3,), cov (3, 3), weight)."""
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
            mask = ((d[:, :2] ** 2).sum(axis=1) <= radius**2) & (np.abs(d[:, 2]) <= angle_radius)
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
    mask = ((d[:, :2] ** 2).sum(axis=1) <= radius**2) & (np.abs(d[:, 2]) <= angle_radius)
    cov = np.zeros((3, 3))
    if total > 0:
        w = weights[mask] / total
        cov = (d[mask] * w[:, None]).T @ d[mask]
    mean[2] = float(wrap_angles(mean[2]))
    return mean, cov, float(total)


def summary_estimate(summary, poses, weights, use_previous: bool = True):
    """`cluster_estimate` on the grid of `summary` (`mcl.summary.Summary`: its cluster cells, the mean shift's
    kernel and its `shift_iterations`), from the summary's last estimate when it has one and `use_previous`: the
    numpy twin of the filter's estimate (`mcl.estimate.summary_estimate`). Returns (mean (3,), cov (3, 3),
    weight); the summary is left as it is."""
    g = summary.grid
    return cluster_estimate(
        poses,
        weights,
        summary.x_min,
        summary.y_min,
        g.cluster_cell,
        summary.cluster_nx,
        summary.cluster_ny,
        g.cluster_orientation_bins,
        g.cluster_radius,
        g.cluster_angle_radius,
        summary.shift_iterations,
        summary.previous.copy() if use_previous and summary.has_previous else None,
    )


def summary_entropy(summary, poses, weights):
    """`grid_entropy` on the entropy grid of `summary` (`mcl.summary.Summary`): the numpy twin of the filter's
    entropy (`mcl.estimate.summary_entropy`). Returns (position bits, orientation bits)."""
    g = summary.grid
    return grid_entropy(
        poses,
        weights,
        summary.x_min,
        summary.y_min,
        g.position_cell,
        summary.entropy_nx,
        summary.entropy_ny,
        g.orientation_bins,
    )


def move_back(poses: np.ndarray, displacement) -> np.ndarray:
    """Plain numpy twin of `mcl.latency.move_back`."""
    dx, dy, dtheta = displacement
    theta = poses[:, 2] - dtheta
    c, s = sincos(theta)
    return np.column_stack([poses[:, 0] - (c * dx - s * dy), poses[:, 1] - (s * dx + c * dy), wrap_angles(theta)])


def displaced(poses: np.ndarray, displacement) -> np.ndarray:
    """Plain numpy twin of `mcl.rivals.displaced`: each pose moved by (dx, dy, dθ) in its own frame, bit for bit."""
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    out = np.empty_like(poses)
    out[:, 0] = poses[:, 0] + c * displacement[0] - s * displacement[1]
    out[:, 1] = poses[:, 1] + s * displacement[0] + c * displacement[1]
    out[:, 2] = wrap_angles(poses[:, 2] + displacement[2])
    return out


def log_prior(poses, anchor, mixture, region):
    """Plain numpy twin of `mcl.relocalization.log_prior_kernel` (`SoccerRelocalization.log_prior`, whose
    `_prior_arguments` give anchor, mixture and region): the prior's log-density at each pose (N, 3), the same
    operations in the same order."""
    has_anchor, ax, ay, at = anchor
    track2, kidnap2, heading_sigma, kidnap_share, tail_share, heading_kept, uniform = mixture
    has_region, x_min, x_max, y_min, y_max, log_region_tail = region
    poses = np.asarray(poses, dtype=np.float64)
    if not has_anchor:
        log_density = np.full(poses.shape[0], math.log(uniform))
    else:
        d2 = (poses[:, 0] - ax) ** 2 + (poses[:, 1] - ay) ** 2
        turn = wrap_angles(poses[:, 2] - at)
        heading = np.exp(-0.5 * (turn / heading_sigma) ** 2) / (math.sqrt(TWO_PI) * heading_sigma)
        kidnap_heading = (1.0 - heading_kept) / TWO_PI + heading_kept * heading
        density = (
            (1.0 - kidnap_share - tail_share) * np.exp(-0.5 * d2 / track2) / (TWO_PI * track2) * heading
            + kidnap_share * np.exp(-0.5 * d2 / kidnap2) / (TWO_PI * kidnap2) * kidnap_heading
            + tail_share * uniform
        )
        log_density = np.log(density)
    if has_region:
        inside = (poses[:, 0] >= x_min) & (poses[:, 0] <= x_max) & (poses[:, 1] >= y_min) & (poses[:, 1] <= y_max)
        log_density = log_density + np.where(inside, 0.0, log_region_tail)
    return log_density


def weight_colors(weights, low, high):
    """Plain numpy twin of `mcl.tools.recording`'s colour kernel (`weight_colors`): (N, 3) uint8 RGB from `low`
    (the lightest) to `high` (the heaviest), relative to the heaviest, bit for bit."""
    top = float(weights.max()) if weights.size else 1.0
    level = np.clip(weights / top, 0.0, 1.0) if top > 0 else np.zeros_like(weights)
    return (low + level[:, None] * (high - low)).astype(np.uint8)
