"""Resampling schemes, all under one signature: ``indices = scheme(weights, M, rng)``.

    from mcl.resampling import systematic, SCHEMES
    ancestors = systematic(weights, len(weights), rng)     # int64 (M,), sorted by ancestor

`weights` are normalized (sum to one); `M` is the number of offspring; `rng` a numpy Generator. Each scheme
is unbiased: particle i has M·wᵢ offspring on average. Systematic (the default) has the lowest variance and
keeps every particle with M·wᵢ >= 1; stratified draws one uniform per stratum; residual keeps ⌊M·wᵢ⌋ copies
and draws the rest multinomially; multinomial draws M independent ancestors. Each is one pass in numba over
variates drawn beforehand; the `*_reference` functions are plain numpy twins that the tests compare with.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from field.angles import wrap_angle, wrap_angles


@numba.njit(cache=True, inline="always")
def _advance(weights, u, j, cumulative):
    """Move the merge cursor (index j, running sum `cumulative` up to j) to the particle whose slice holds u."""
    last = weights.shape[0] - 1
    while u >= cumulative and j < last:
        j += 1
        cumulative += weights[j]
    return j, cumulative


@numba.njit(cache=True)
def _inverse_cdf(weights, points, out):
    """Ancestors of sorted points in [0, 1): one merge pass over the running sum of the weights."""
    j, cumulative = 0, weights[0]
    for k in range(points.shape[0]):
        j, cumulative = _advance(weights, points[k], j, cumulative)
        out[k] = j
    return out


@numba.njit(cache=True)
def _systematic(weights, m, u0, out):
    j, cumulative = 0, weights[0]
    for k in range(m):
        j, cumulative = _advance(weights, (u0 + k) / m, j, cumulative)
        out[k] = j
    return out


@numba.njit(cache=True)
def _stratified(weights, uniforms, out):
    m = uniforms.shape[0]
    j, cumulative = 0, weights[0]
    for k in range(m):
        j, cumulative = _advance(weights, (k + uniforms[k]) / m, j, cumulative)
        out[k] = j
    return out


@numba.njit(cache=True)
def _sorted_uniforms(exponentials):
    """len-1 sorted uniforms in O(M): normalized running sums of exponential spacings."""
    m = exponentials.shape[0] - 1
    total = 0.0
    for k in range(m + 1):
        total += exponentials[k]
    out = np.empty(m)
    running = 0.0
    for k in range(m):
        running += exponentials[k]
        out[k] = running / total
    return out


@numba.njit(cache=True)
def _multinomial(weights, exponentials, out):
    return _inverse_cdf(weights, _sorted_uniforms(exponentials), out)


@numba.njit(cache=True)
def _residual(weights, copies, exponentials, out):
    n = weights.shape[0]
    m = out.shape[0]
    filled = 0
    residual = np.empty(n)
    for i in range(n):
        for _ in range(copies[i]):
            out[filled] = i
            filled += 1
        residual[i] = m * weights[i] - copies[i]
    rest = m - filled
    if rest > 0:
        total = residual.sum()
        for i in range(n):
            residual[i] = residual[i] / total if total > 0.0 else 1.0 / n
        _inverse_cdf(residual, _sorted_uniforms(exponentials), out[filled:])
    return out


def _check(weights: np.ndarray, m: int) -> np.ndarray:
    weights = np.ascontiguousarray(weights, dtype=np.float64)
    if weights.ndim != 1 or weights.shape[0] == 0:
        raise ValueError(f"weights must be a non-empty 1-D array, got shape {weights.shape}")
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 0:
        raise ValueError(f"M = {m!r} must be an integer >= 0")
    return weights


def systematic(weights: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    """One uniform u0 ~ U[0, 1), then the points (u0 + k)/M: the lowest-variance scheme."""
    weights = _check(weights, m)
    return _systematic(weights, int(m), rng.random(), np.empty(int(m), dtype=np.int64))


def stratified(weights: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    """One uniform in each stratum [k/M, (k+1)/M)."""
    weights = _check(weights, m)
    return _stratified(weights, rng.random(int(m)), np.empty(int(m), dtype=np.int64))


def multinomial(weights: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    """M independent draws (returned sorted by ancestor)."""
    weights = _check(weights, m)
    return _multinomial(weights, rng.standard_exponential(int(m) + 1), np.empty(int(m), dtype=np.int64))


def residual(weights: np.ndarray, m: int, rng: np.random.Generator) -> np.ndarray:
    """⌊M·wᵢ⌋ copies of each particle, the remainder drawn multinomially from the residual weights."""
    weights = _check(weights, m)
    copies = np.floor(int(m) * weights).astype(np.int64)
    copies = np.minimum(copies, int(m))
    excess = copies.sum() - int(m)
    if excess > 0:  # rounding in weights that sum to slightly more than one
        copies[np.argmax(copies)] -= excess
    rest = int(m) - int(copies.sum())
    return _residual(weights, copies, rng.standard_exponential(rest + 1), np.empty(int(m), dtype=np.int64))


@numba.njit(cache=True)
def gather_with_jitter(source, ancestors, bounds, uniforms, out):
    """out[k] = source[ancestors[k]] moved by a uniform jitter on ±bounds in the ancestor's own frame.

    uniforms (M, 3) on [0, 1). The copy and the jitter (roughening) in one pass.
    """
    for k in range(ancestors.shape[0]):
        i = ancestors[k]
        theta = source[i, 2]
        ex = (2.0 * uniforms[k, 0] - 1.0) * bounds[0]
        ey = (2.0 * uniforms[k, 1] - 1.0) * bounds[1]
        c = math.cos(theta)
        s = math.sin(theta)
        out[k, 0] = source[i, 0] + c * ex - s * ey
        out[k, 1] = source[i, 1] + s * ex + c * ey
        out[k, 2] = wrap_angle(theta + (2.0 * uniforms[k, 2] - 1.0) * bounds[2])
    return out


def gather_with_jitter_reference(source, ancestors, bounds, uniforms):
    """Numpy twin of `gather_with_jitter`."""
    picked = source[ancestors].copy()
    noise = (2.0 * uniforms - 1.0) * bounds
    c, s = np.cos(picked[:, 2]), np.sin(picked[:, 2])
    picked[:, 0] += c * noise[:, 0] - s * noise[:, 1]
    picked[:, 1] += s * noise[:, 0] + c * noise[:, 1]
    picked[:, 2] = wrap_angles(picked[:, 2] + noise[:, 2])
    return picked


SCHEMES = {"systematic": systematic, "stratified": stratified, "residual": residual, "multinomial": multinomial}


# -- plain numpy references (the same variates, the same order) -------------------------------------------------
def _searchsorted(weights: np.ndarray, points: np.ndarray) -> np.ndarray:
    cumulative = np.cumsum(weights)
    return np.minimum(np.searchsorted(cumulative, points, side="right"), weights.shape[0] - 1)


def systematic_reference(weights, m, rng):
    return _searchsorted(np.asarray(weights, float), (rng.random() + np.arange(m)) / m)


def stratified_reference(weights, m, rng):
    return _searchsorted(np.asarray(weights, float), (np.arange(m) + rng.random(m)) / m)


def multinomial_reference(weights, m, rng):
    spacings = rng.standard_exponential(m + 1)
    running = np.cumsum(spacings)  # running[-1] is the sequential total, as the kernel sums it
    return _searchsorted(np.asarray(weights, float), running[:-1] / running[-1])
