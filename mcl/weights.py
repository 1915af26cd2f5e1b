"""Log-weight arithmetic: normalization with log-sum-exp and the effective sample size.

    from mcl.weights import normalize
    log_total, ess = normalize(log_weights, weights_out)   # weights_out = exp(log_weights - log_total)
"""
import math

import numba
import numpy as np


@numba.njit(cache=True)
def normalize(log_weights, weights_out):
    """Normalize in one fused pass: weights_out ← exp(lw - logsumexp(lw)); returns (logsumexp, ESS).

    ESS = 1 / Σ wᵢ². With every log-weight -inf, returns (-inf, 0) and leaves weights_out untouched.
    """
    n = log_weights.shape[0]
    peak = -np.inf
    for i in range(n):
        if log_weights[i] > peak:
            peak = log_weights[i]
    if peak == -np.inf:
        return -np.inf, 0.0
    total = 0.0
    for i in range(n):
        e = math.exp(log_weights[i] - peak)
        weights_out[i] = e
        total += e
    inverse = 1.0 / total
    squares = 0.0
    for i in range(n):
        w = weights_out[i] * inverse
        weights_out[i] = w
        squares += w * w
    return peak + math.log(total), 1.0 / squares


def normalize_reference(log_weights):
    """Numpy twin: returns (weights, logsumexp, ESS)."""
    peak = np.max(log_weights)
    e = np.exp(log_weights - peak)
    total = e.sum()
    w = e / total
    return w, peak + math.log(total), 1.0 / np.sum(w * w)


@numba.njit(cache=True)
def log_mean_likelihood(log_weights, log_likelihood, count):
    """log(Σ wᵢ pᵢ / Σ wᵢ) over the first `count` particles, in one pass (log-sum-exp of both sums).

    Returns -inf when no particle of the `count` has a finite weight and likelihood.
    """
    peak_prior = -np.inf
    peak_joint = -np.inf
    for i in range(count):
        if log_weights[i] > peak_prior:
            peak_prior = log_weights[i]
        joint = log_weights[i] + log_likelihood[i]
        if joint > peak_joint:
            peak_joint = joint
    if peak_prior == -np.inf or peak_joint == -np.inf:
        return -np.inf
    prior = 0.0
    joint = 0.0
    for i in range(count):
        prior += math.exp(log_weights[i] - peak_prior)
        joint += math.exp(log_weights[i] + log_likelihood[i] - peak_joint)
    return peak_joint + math.log(joint) - peak_prior - math.log(prior)
