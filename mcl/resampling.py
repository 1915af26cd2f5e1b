"""Resampling schemes, all under one signature: ``indices = scheme(weights, M, rng)``.

    from mcl.resampling import systematic, SCHEMES
    ancestors = systematic(weights, len(weights), rng)     # int64 (M,), sorted by ancestor

`weights` are normalized (sum to one); `M` is the number of offspring; `rng` a numpy Generator. Each scheme
is unbiased: particle i has M·wᵢ offspring on average. Systematic (the default) has the lowest variance and
keeps every particle with M·wᵢ >= 1; stratified draws one uniform per stratum; residual keeps ⌊M·wᵢ⌋ copies
and draws the rest multinomially; multinomial draws M independent ancestors. Each is one pass in numba over
variates drawn beforehand; their plain numpy twins, which the tests compare with, are in `mcl.reference`.

The filter resamples with `resample_with_jitter` (`systematic_with_jitter` allocates its scratch):
systematic resampling, the copy from the ancestors and the roughening jitter in one pass, drawing its
uniforms in the kernel from the filter's generator (see `numerics.random.next_double`); the same
particles, bit for bit, as `systematic` followed by `gather_with_jitter` on `rng.random((M, 3))`, without
the ancestor array or the variate array.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from field.moved import moved_names
from numerics.random import draw_uniforms, next_double, parallel_uniforms
from numerics.trig import sincos, wrap

# The numpy twins moved to the package's `reference` module; their old names still work, with a warning.
__getattr__ = moved_names(
    __name__,
    {
        "gather_with_jitter_reference": "mcl.reference.gather_with_jitter",
        "systematic_reference": "mcl.reference.systematic",
        "stratified_reference": "mcl.reference.stratified",
        "multinomial_reference": "mcl.reference.multinomial",
    },
)


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


def systematic(weights: np.ndarray, m: int, rng: np.random.Generator, out: np.ndarray | None = None) -> np.ndarray:
    """One uniform u0 ~ U[0, 1), then the points (u0 + k)/M: the lowest-variance scheme.

    out: an int64 array of M to write the ancestors into (kept across calls, so that resampling allocates
    nothing: fresh memory costs more than the resampling itself at a million particles); returned.
    """
    weights = _check(weights, m)
    m = int(m)
    if out is None:
        return _systematic_in_place(weights, m, rng.random(), np.zeros(m, dtype=np.int64))
    if (
        not isinstance(out, np.ndarray)
        or out.dtype != np.int64
        or out.shape != (m,)
        or not out.flags.c_contiguous
        or not out.flags.writeable
    ):
        raise ValueError(f"out must be a writeable contiguous int64 array of shape ({m},)")
    out.fill(0)
    return _systematic_in_place(weights, m, rng.random(), out)


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
def jitter_pose(x, y, theta, c, s, u0, u1, u2, bound_x, bound_y, bound_theta):
    """(x, y, θ) moved by a uniform jitter on ±bounds in its own frame (c, s = cos θ, sin θ) from uniforms u."""
    ex = (2.0 * u0 - 1.0) * bound_x
    ey = (2.0 * u1 - 1.0) * bound_y
    return x + c * ex - s * ey, y + s * ex + c * ey, wrap(theta + (2.0 * u2 - 1.0) * bound_theta)


@numba.njit(cache=True)
def gather_with_jitter(source, ancestors, bounds, uniforms, out):
    """out[k] = source[ancestors[k]] moved by a uniform jitter on ±bounds in the ancestor's own frame.

    uniforms (M, 3) on [0, 1). The copy and the jitter (roughening) in one pass.
    """
    bx, by, bt = bounds[0], bounds[1], bounds[2]
    for k in range(ancestors.shape[0]):
        i = ancestors[k]
        theta = source[i, 2]
        c, s = sincos(theta)
        out[k, 0], out[k, 1], out[k, 2] = jitter_pose(
            source[i, 0], source[i, 1], theta, c, s, uniforms[k, 0], uniforms[k, 1], uniforms[k, 2], bx, by, bt
        )
    return out


# -- systematic resampling without a merge loop -------------------------------------------------------------------
# The merge in `_systematic` advances j while the point (u0 + k)/M lies at or beyond the running total C_j: a
# branch taken a data-dependent number of times per offspring, mispredicted about once per particle. The
# same ancestors follow from counting instead: particle j < N-1 is passed by the points at or beyond C_j,
# i.e. by every point from c_j = #{k : (u0 + k)/M < C_j} on, so the ancestor of point k is the number of
# particles with c_j <= k, a running sum over a histogram of the c_j. c_j is ceil(C_j·M - u0) unless that
# number lies within 1e-4 of an integer, where the comparisons that define it are made exactly as the merge
# makes them; so the ancestors equal the merge's bit for bit, with C_j the same running sum. (The float error
# of C_j·M - u0 is about M·2⁻⁵², far below the margin for any M a filter uses.)


@numba.njit(cache=True, inline="always")
def _passed_count(cumulative, m, u0):
    """c = #{k : (u0 + k)/M < cumulative}, as `_passed_counts` finds it."""
    t = cumulative * m - u0
    if abs(t - np.rint(t)) < 1e-4:
        c = min(max(math.ceil(t), 0), m)
        while c > 0 and (u0 + (c - 1)) / m >= cumulative:
            c -= 1
        while c < m and (u0 + c) / m < cumulative:
            c += 1
        return c
    return int(min(max(np.ceil(t), 0.0), float(m)))  # (in floats: one conversion to an integer)


@numba.njit(cache=True)
def _passed_counts(weights, m, u0, counts):
    """counts[c] = #{j < N-1 : c_j = c} (counts (M + 1,) zero on entry)."""
    cumulative = 0.0
    for j in range(weights.shape[0] - 1):
        cumulative += weights[j]  # 0 + w0 = w0: the merge's running total
        counts[_passed_count(cumulative, m, u0)] += 1


@numba.njit(cache=True)
def systematic_counted(weights, m, u0, out, counts):
    """`_systematic` by counting; counts (M + 1,) int64 zero on entry and on return."""
    _passed_counts(weights, m, u0, counts)
    ancestor = 0
    for k in range(m):
        ancestor += counts[k]
        counts[k] = 0
        out[k] = ancestor
    counts[m] = 0
    return out


@numba.njit(cache=True)
def _systematic_in_place(weights, m, u0, out):
    """`_systematic` by counting into `out` itself (M int64, zero on entry): the counts of c < M (a particle
    with c = M is passed by every point and is no one's ancestor), then their running sum in place."""
    cumulative = 0.0
    for j in range(weights.shape[0] - 1):
        cumulative += weights[j]
        c = _passed_count(cumulative, m, u0)
        if c < m:
            out[c] += 1
    ancestor = 0
    for k in range(m):
        ancestor += out[k]
        out[k] = ancestor
    return out


DRAWS = 256  # offspring per block of drawn uniforms


# `_place`, `_place_run` and `_place_range` take three groups (tuples): ancestors (source, trig), the particles
# resampled from and their headings' cos and sin (trig without rows: computed here); bounds (bx, by, bt), the
# roughening's half-widths; offspring (out, coordinates), where the offspring go (coordinates without columns:
# nowhere else).
@numba.njit(cache=True, inline="always")
def _place(ancestors, j, known, uniforms, u, bounds, offspring, k, split):
    """Offspring k of ancestor j: its pose jittered by uniforms[u:u + 3] (with the ancestor's cos/sin from
    `trig` when `known`), written to out[k] and, when `split`, to coordinates[:, k]."""
    source, trig = ancestors
    bx, by, bt = bounds
    out, coordinates = offspring
    theta = source[j, 2]
    if known:
        c = trig[j, 0]
        s = trig[j, 1]
    else:
        c, s = sincos(theta)
    x, y, theta = jitter_pose(
        source[j, 0], source[j, 1], theta, c, s, uniforms[u], uniforms[u + 1], uniforms[u + 2], bx, by, bt
    )
    out[k, 0] = x
    out[k, 1] = y
    out[k, 2] = theta
    if split:
        coordinates[0, k] = x
        coordinates[1, k] = y
        coordinates[2, k] = theta


@numba.njit(cache=True, inline="always")
def _place_run(ancestors, j, known, uniforms, u, bounds, offspring, first, stop, counts, split):
    """Offspring first..stop-1, their ancestors the running sum of `counts` from j (counts zeroed on the way),
    their uniforms from uniforms[u:]; returns the last ancestor. Called with literal `known` and `split`."""
    for k in range(first, stop):
        j += counts[k]
        counts[k] = 0
        _place(ancestors, j, known, uniforms, u + 3 * (k - first), bounds, offspring, k, split)
    return j


# Not inlined: `resample_with_jitter_chunked` calls it in a parallel loop, and numba's parallel loops lose the
# writes of an inlined function that writes through a tuple of arrays (the groups above); a call keeps them.
@numba.njit(cache=True)
def _place_range(ancestors, j, uniforms, u, bounds, offspring, first, stop, counts):
    """`_place_run` with `known` (trig has rows) and `split` (coordinates has columns) decided once, outside
    the loop: with a flag tested inside it, LLVM computes the cos and sin of the other branch anyway (they are
    speculatable intrinsics), which made the loop four times slower."""
    known = ancestors[1].shape[0] > 0
    if offspring[1].shape[1] > 0:
        if known:
            return _place_run(ancestors, j, True, uniforms, u, bounds, offspring, first, stop, counts, True)
        return _place_run(ancestors, j, False, uniforms, u, bounds, offspring, first, stop, counts, True)
    if known:
        return _place_run(ancestors, j, True, uniforms, u, bounds, offspring, first, stop, counts, False)
    return _place_run(ancestors, j, False, uniforms, u, bounds, offspring, first, stop, counts, False)


@numba.njit(cache=True)
def resample_with_jitter(weights, m, source, bounds, out, trig, function, state, counts, coordinates):
    """Systematic resampling of M particles from `source` into out[:M], with roughening; returns u0.

    Draws u0 and then three uniforms per offspring from the bit generator (function, state), the order of
    `systematic(weights, M, rng)` followed by `rng.random((M, 3))`, and gives what `gather_with_jitter` gives
    with them. trig (N, 2): cos and sin of each source heading when it has rows (computed otherwise).
    counts: (M + 1,) int64 scratch, zero on entry and on return. coordinates: when it has columns, (3, M) rows
    that receive x, y, θ of the offspring too.
    """
    u0 = next_double(function, state)
    _passed_counts(weights, m, u0, counts)
    bx, by, bt = bounds[0], bounds[1], bounds[2]
    uniforms = np.empty(3 * DRAWS)
    j = 0
    for start in range(0, m, DRAWS):
        count = min(DRAWS, m - start)
        draw_uniforms(function, state, uniforms, 3 * count)
        j = _place_range((source, trig), j, uniforms, 0, (bx, by, bt), (out, coordinates), start, start + count, counts)
    counts[m] = 0
    return u0


@numba.njit(cache=True)
def gather_offspring_rows(weights, m, u0, counts, rows, scratch):
    """rows[:M] ← the rows of the ancestors that `resample_with_jitter` with this u0 gave offspring 0..M-1
    (a stateful motion model's per-particle state follows its particles). counts: (M + 1,) int64 zero on entry
    and on return; scratch: at least M rows like `rows`."""
    _passed_counts(weights, m, u0, counts)
    j = 0
    for k in range(m):
        j += counts[k]
        counts[k] = 0
        for column in range(rows.shape[1]):
            scratch[k, column] = rows[j, column]
    counts[m] = 0
    rows[:m] = scratch[:m]


@numba.njit(cache=True)
def systematic_with_jitter(weights, m, source, bounds, out, trig, function, state):
    """`resample_with_jitter` with its scratch allocated here."""
    return resample_with_jitter(
        weights, m, source, bounds, out, trig, function, state, np.zeros(m + 1, dtype=np.int64), np.empty((3, 0))
    )


@numba.njit(cache=True, parallel=True)
def resample_with_jitter_chunked(
    weights, m, source, bounds, out, trig, function, state, counts, coordinates, uniforms, chunk
):
    """`resample_with_jitter` with the running total of the weights taken chunk by chunk (each chunk's total
    in index order, the chunks' in order, then each chunk's running sum on top of its prefix) and the chunks
    spread over threads: the same offspring for any number of threads; `resample_with_jitter`'s bit for bit
    when chunk >= N, otherwise the same unless a point falls within rounding of a running total. uniforms: a
    flat scratch of at least 3·M floats (the roughening's uniforms are drawn into it first, in parallel)."""
    u0 = next_double(function, state)
    parallel_uniforms(function, state, uniforms, 3 * m)
    n = weights.shape[0]
    passed = n - 1  # particles that the points can pass
    chunks = max(1, (passed + chunk - 1) // chunk)
    totals = np.zeros(chunks)
    for t in numba.prange(chunks):
        total = 0.0
        for j in range(t * chunk, min(passed, (t + 1) * chunk)):
            total += weights[j]
        totals[t] = total
    prefix = np.zeros(chunks)
    for t in range(1, chunks):
        prefix[t] = prefix[t - 1] + totals[t - 1]
    # Each chunk counts its particles; the count of its first c may be shared with the chunk before (c is
    # monotone), so it is kept aside and added afterwards, one chunk at a time.
    first = np.full(chunks, -1, dtype=np.int64)
    shared = np.zeros(chunks, dtype=np.int64)
    for t in numba.prange(chunks):
        running = 0.0
        for j in range(t * chunk, min(passed, (t + 1) * chunk)):
            running += weights[j]
            c = _passed_count(prefix[t] + running, m, u0)
            if first[t] < 0:
                first[t] = c
            if c == first[t]:
                shared[t] += 1
            else:
                counts[c] += 1
    for t in range(chunks):
        if first[t] >= 0:
            counts[first[t]] += shared[t]
    # The ancestor of point k is the running sum of the counts up to k: each chunk of points starts from the
    # sum of the counts before it.
    k_chunks = max(1, (m + chunk - 1) // chunk)
    starts = np.zeros(k_chunks, dtype=np.int64)
    for t in numba.prange(k_chunks):
        total = 0
        for k in range(t * chunk, min(m, (t + 1) * chunk)):
            total += counts[k]
        starts[t] = total
    running_start = 0
    for t in range(k_chunks):
        total = starts[t]
        starts[t] = running_start
        running_start += total
    bx, by, bt = bounds[0], bounds[1], bounds[2]
    for t in numba.prange(k_chunks):
        _place_range(
            (source, trig),
            starts[t],
            uniforms,
            3 * t * chunk,
            (bx, by, bt),
            (out, coordinates),
            t * chunk,
            min(m, (t + 1) * chunk),
            counts,
        )
    counts[m] = 0
    return u0


SCHEMES = {"systematic": systematic, "stratified": stratified, "residual": residual, "multinomial": multinomial}


# -- plain numpy references (the same variates, the same order) -------------------------------------------------
