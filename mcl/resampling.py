"""Resampling schemes, all under one signature: ``indices = scheme(weights, M, rng)``.

    from mcl.resampling import systematic, SCHEMES
    ancestors = systematic(weights, len(weights), rng)     # int64 (M,), sorted for systematic/stratified

`weights` are normalized (sum to one); `M` is the number of offspring; `rng` a numpy Generator. Each scheme
is unbiased: particle i has N·wᵢ offspring on average. Systematic (the default) has the lowest variance and
keeps every particle with N·wᵢ >= 1; stratified draws one uniform per stratum; residual keeps ⌊N·wᵢ⌋ copies
and draws the rest multinomially; multinomial draws M independent ancestors. Each is a single pass in numba;
`*_reference` functions are the plain numpy versions the tests compare with.
"""
from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _inverse_cdf(weights, sorted_uniforms, out):
    """Ancestors of sorted points in [0, 1): one merge pass over the cumulative weights."""
    n = weights.shape[0]
    j = 0
    cumulative = weights[0]
    for k in range(sorted_uniforms.shape[0]):
        u = sorted_uniforms[k]
        while u >= cumulative and j < n - 1:
            j += 1
            cumulative += weights[j]
        out[k] = j
    return out


@numba.njit(cache=True)
def _systematic(weights, m, rng, out):
    n = weights.shape[0]
    u0 = rng.random()
    j = 0
    cumulative = weights[0]
    for k in range(m):
        u = (u0 + k) / m
        while u >= cumulative and j < n - 1:
            j += 1
            cumulative += weights[j]
        out[k] = j
    return out


@numba.njit(cache=True)
def _stratified(weights, m, rng, out):
    n = weights.shape[0]
    j = 0
    cumulative = weights[0]
    for k in range(m):
        u = (k + rng.random()) / m
        while u >= cumulative and j < n - 1:
            j += 1
            cumulative += weights[j]
        out[k] = j
    return out


@numba.njit(cache=True)
def _sorted_uniforms(m, rng):
    """M sorted uniforms in O(M) from normalized cumulative exponential spacings."""
    spacings = np.empty(m + 1)
    total = 0.0
    for k in range(m + 1):
        total += -np.log(1.0 - rng.random())
        spacings[k] = total
    out = np.empty(m)
    for k in range(m):
        out[k] = spacings[k] / total
    return out


@numba.njit(cache=True)
def _multinomial(weights, m, rng, out):
    return _inverse_cdf(weights, _sorted_uniforms(m, rng), out)


@numba.njit(cache=True)
def _residual(weights, m, rng, out):
    n = weights.shape[0]
    residual = np.empty(n)
    filled = 0
    for i in range(n):
        scaled = m * weights[i]
        copies = int(np.floor(scaled))
        residual[i] = scaled - copies
        for _ in range(copies):
            if filled < m:
                out[filled] = i
                filled += 1
    rest = m - filled
    if rest > 0:
        total = residual.sum()
        if total <= 0.0:
            for i in range(n):
                residual[i] = 1.0 / n
        else:
            for i in range(n):
                residual[i] /= total
        _inverse_cdf(residual, _sorted_uniforms(rest, rng), out[filled:])
    return out


def _check(weights: np.ndarray, m: int) -> np.ndarray:
    weights = np.ascontiguousarray(weights, dtype=np.float64)
    if weights.ndim != 1 or weights.shape[0] == 0:
        raise ValueError(f"weights must be a non-empty 1-D array, got shape {weights.shape}")
    if not isinstance(m, (int, np.integer)) or m < 0:
        raise ValueError(f"M = {m!r} must be an integer >= 0")
    return weights


def systematic(weights: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    """One uniform u ~ U[0, 1/M), then the points u + k/M: the lowest-variance scheme."""
    weights = _check(weights, m)
    return _systematic(weights, int(m), rng, np.empty(int(m), dtype=np.int64))


def stratified(weights: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    """One uniform in each stratum [k/M, (k+1)/M)."""
    weights = _check(weights, m)
    return _stratified(weights, int(m), rng, np.empty(int(m), dtype=np.int64))


def multinomial(weights: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    """M independent draws (returned sorted by ancestor)."""
    weights = _check(weights, m)
    return _multinomial(weights, int(m), rng, np.empty(int(m), dtype=np.int64))


def residual(weights: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    """⌊M·wᵢ⌋ copies of each particle, the remainder drawn multinomially from the residual weights."""
    weights = _check(weights, m)
    return _residual(weights, int(m), rng, np.empty(int(m), dtype=np.int64))


SCHEMES = {"systematic": systematic, "stratified": stratified, "residual": residual, "multinomial": multinomial}


# -- plain numpy references (the same draws, the same order) ---------------------------------------------------
def _searchsorted(weights: np.ndarray, points: np.ndarray) -> np.ndarray:
    cumulative = np.cumsum(weights)
    return np.minimum(np.searchsorted(cumulative, points, side="right"), weights.shape[0] - 1)


def systematic_reference(weights, m, rng):
    return _searchsorted(np.asarray(weights, float), (rng.random() + np.arange(m)) / m)


def stratified_reference(weights, m, rng):
    return _searchsorted(np.asarray(weights, float), (np.arange(m) + rng.random(m)) / m)
