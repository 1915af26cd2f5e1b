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
