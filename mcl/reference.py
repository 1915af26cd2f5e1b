"""The filter step in plain numpy: the reference the numba kernels are tested against and benchmarked with.

    from mcl.reference import numpy_step

Each phase calls the `*_reference` twin of the kernel the filter uses; with the same generator state the
results agree with the filter's to rounding (the draws are the same, in the same order).
"""
from __future__ import annotations

import numpy as np

from motion_models._kernels import draw_variates, move_with_noise_reference
from motion_models.base import MotionInput
from sensing.observations import Observations

from .estimate import cluster_estimate_reference, grid_entropy_reference
from .resampling import gather_with_jitter_reference, systematic_reference
from .weights import normalize_reference


def numpy_step(pf, u: MotionInput, observations: Observations, timings: dict | None = None) -> dict:
    """One full step on a copy of `pf`'s particles, in numpy: predict, likelihood, normalize + ESS,
    systematic resampling, estimate, entropy. Uses (and advances) `pf.rng`. Returns the results; adds the
    seconds of each phase to `timings` when given."""
    import time

    clock = time.perf_counter
    marks = [clock()]
    poses = pf.poses.copy()
    bounds = pf.motion_model.noise_bounds(u)
    gaussian = pf.motion_model.gaussian
    move_with_noise_reference(poses, *u.displacement(), *bounds, gaussian, draw_variates(pf.rng, pf.n, gaussian))
    marks.append(clock())
    log_likelihood = pf.sensor_model.log_likelihood_reference(poses, observations)
    marks.append(clock())
    weights, log_total, ess = normalize_reference(pf.log_weights + log_likelihood)
    marks.append(clock())
    ancestors = systematic_reference(weights, pf.n, pf.rng)
    poses = gather_with_jitter_reference(poses, ancestors, pf.roughening * np.sqrt(3.0),
                                         draw_variates(pf.rng, pf.n, False))
    weights = np.full(pf.n, 1.0 / pf.n)
    marks.append(clock())
    g = pf.grid
    mean, cov, cluster_weight = cluster_estimate_reference(
        poses, weights, pf._x_min, pf._y_min, g.cluster_cell, pf._cluster_nx, pf._cluster_ny,
        g.cluster_orientation_bins, g.cluster_radius, g.cluster_angle_radius, 3,
        pf._previous_estimate if pf._has_previous_estimate else None)
    marks.append(clock())
    entropy = grid_entropy_reference(poses, weights, pf._x_min, pf._y_min, g.position_cell, pf._entropy_nx,
                                     pf._entropy_ny, g.orientation_bins)
    marks.append(clock())
    if timings is not None:
        for name, a, b in zip(PHASES, marks[:-1], marks[1:]):
            timings[name] = timings.get(name, 0.0) + (b - a)
    return {"poses": poses, "log_likelihood": log_likelihood, "ess": ess, "log_total": log_total,
            "mean": mean, "covariance": cov, "cluster_weight": cluster_weight, "entropy": entropy}


PHASES = ("predict", "likelihood", "normalize", "resample", "estimate", "entropy")
