"""The landmark sensor model: each particle's log-likelihood of a batch of range-bearing detections.

    from field import spl
    from sensing import LandmarkSensorModel
    model = LandmarkSensorModel(spl())                 # bearing_model="von_mises" (fast) or "exact"
    log_likelihood = model.log_likelihood(poses, observations)     # (N,), up to a shared constant

Detections of one type are ambiguous (four goalposts, ten T crossings): each detection is associated, per
particle, with the landmark of its type that explains it best (the maximum over candidates). Per detection
and particle, with r̂ and b̂ the range and bearing of a candidate seen from the particle,

    ℓ = max( best_k [ -½((r - r̂_k)/σ_r)² + bearing term ],  log outlier_weight )

The outlier term is a floor, so a false positive costs every particle about the same instead of wiping out
the right ones. This is the max-mixture of Olson & Agarwal (RSS 2012): it needs no exp or log per detection
and differs from the sum-mixture log(exp(best) + outlier_weight) (`mixture="sum"`) by at most log 2, at the
floor. Range noise grows with range as for a camera at height h: a pitch error δ moves the ground
point by δ·(h² + r²)/h, hence by default σ_r(r) = range_noise_floor + range_noise_growth·r². A linear term
(`range_noise_linear`) gives the general law σ_r(r) = a + b·r + c·r², so constant (b = c = 0), linear (c = 0)
and quadratic growth can all be expressed.

Two bearing terms: "exact", -½(wrap(b - b̂)/σ_b)², needs one atan2 per particle and candidate; "von_mises",
κ(cos(b - b̂) - 1) with κ = 1/σ_b², which equals the Gaussian to second order in the error and is computed from
the candidate's unit direction in the robot frame with no atan2. Either way the geometry from a particle to
its candidates (distance, direction) is computed once and reused by every detection of that type: the two
moves that made this kernel several times faster (the benchmark reports by how much, and how far the two
bearing terms' normalized weights differ).

Log-likelihoods are unnormalized: a perfect match scores 0 per detection. Constants shared by all
particles cancel in the weights; the filter's augmented-MCL average uses the per-detection mean.

Kernels. `landmark_log_likelihood` computes every variant particle by particle. The default variant (von Mises,
max-mixture) runs in `von_mises_log_likelihood`, which takes the particles a block at a time so that its
loops vectorize across particles, with the same results bit for bit (see the comment above it);
`prepare_detections` turns a batch into its per-detection constants, grouped by type, once per call. A
compiled filter step calls `fused_score` (which runs `score_block`) on each block of particles itself
(`fused_likelihood`, in the calling convention of `sensing.fused`). The exact bearing
term with the max-mixture runs in blocks too (`exact_log_likelihood`; `score_block_exact`, which a compiled
filter step calls the same way), with a polynomial atan2 that vectorizes (`numerics.trig.atan2_poly`)
and the detections' bearings wrapped once: equal to the particle-by-particle kernel, which takes libm's atan2,
to rounding, and about 4.5 times faster.

The kernels that take a batch of detections take their arguments in groups (tuples), each built in one place:

    landmarks  (table, offsets, table_kinds): the landmarks sorted by type, where each type starts, and each
               landmark's type value (`LandmarkSensorModel.landmark_group`)
    batch      (kinds, ranges, bearings, range_sigmas, bearing_sigmas): a frame's detections (`detection_batch`)
    noise      (range_noise_floor, range_noise_growth, bearing_sigma): the noise law
               (`LandmarkSensorModel.noise_group`; the growth a float c or the pair (b, c), `range_noise_sigma`)
    pose       (x, y, θ): one pose
    gate       (gate, range_slack, bearing_slack): how many σ a detection may lie from a landmark, σ widened by
               the slacks (`gate_group`)
    view       (yaw, half_fov, min_range, max_ranges): the camera's view, `max_ranges[v]` the farthest range of
               landmark type value v (`view_group`)
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import TYPE_CHECKING

import numba
import numpy as np
from numba.core import types as numba_types
from numba.extending import overload

from field import Field, LandmarkType
from field.angles import TWO_PI, wrap_angle
from field.checks import LARGEST_SIGMA, SMALLEST_SIGMA, ArgumentTypeError, real
from field.moved import moved_methods, moved_names
from numerics.compile import variant
from numerics.frozen import keeps_arrays_frozen
from numerics.random import bounded_integers, draw_handles, draw_uniforms
from numerics.trig import FAST, atan2_poly, moved_back, sincos, sincos_rows_as

from . import reference
from .fused import FusedLikelihoodKernels
from .observations import Observations
from .view import CameraView

# The numpy twins moved to the package's `reference` module; their old names still work, with a warning.
__getattr__ = moved_names(__name__, {"landmark_log_likelihood_reference": "sensing.reference.landmark_log_likelihood"})

BEARING_MODELS = ("von_mises", "exact")


# -- the range noise law -------------------------------------------------------------------------------------------
# The kernels take the law as (range_noise_floor, range_noise_growth): the growth is a float c, for
# σ_r = floor + c·r², or the pair (b, c), for σ_r = floor + b·r + c·r² (b is
# `LandmarkSensorModel.range_noise_linear`). The model always passes the pair, so that models with and without a
# linear term share one compiled specialization: with b = 0 the term b·r is 0 (ranges are finite), and floor + 0 is
# floor, so σ_r is bit for bit floor + c·r².
def range_noise_sigma(r, range_noise_floor, range_noise_growth):
    """σ_r [m] at range r [m] (a number or an array): floor + growth·r² for a float growth [1/m], and
    floor + b·r + c·r² for growth = (b, c) (b dimensionless, c [1/m]). In compiled code the overload below picks
    the form by the type of `range_noise_growth` and is inlined: the same operations in the same order."""
    if isinstance(range_noise_growth, tuple):
        linear, quadratic = range_noise_growth
        return range_noise_floor + linear * r + quadratic * r * r
    return range_noise_floor + range_noise_growth * r * r


@overload(range_noise_sigma, inline="always")
def _range_noise_sigma_compiled(r, range_noise_floor, range_noise_growth):
    if isinstance(range_noise_growth, numba_types.BaseTuple):

        def law(r, range_noise_floor, range_noise_growth):
            return range_noise_floor + range_noise_growth[0] * r + range_noise_growth[1] * r * r

        return law

    def quadratic_law(r, range_noise_floor, range_noise_growth):
        return range_noise_floor + range_noise_growth * r * r

    return quadratic_law


@numba.njit(cache=True)
def landmark_log_likelihood(poses, landmarks, batch, noise, exact, sum_mixture, log_outlier, out):
    """out[i] = Σ_detections max(max_k score_ik, log outlier) for every particle i (the max-mixture), or
    with `sum_mixture`, Σ log(exp(max_k score_ik) + outlier).

    landmarks, batch, noise: the groups of the module docstring. The candidates of type t are
    table[offsets[t]:offsets[t+1]]. A NaN sigma means "use the noise model":
    σ_r = `range_noise_sigma(r, range_noise_floor, range_noise_growth)` (growth the pair (b, c), or a float c).
    Detections are grouped by type first, so the geometry to a type's candidates is computed once per
    particle and shared by all its detections.
    """
    # The headings' cos and sin, here without fast-math (the bits of the block kernels' `load_block`), for
    # TRIG_CHUNK particles at a time: scratch of a fixed size, whatever N.
    n = poses.shape[0]
    trig = np.empty((min(n, TRIG_CHUNK), 2))
    for start in range(0, n, TRIG_CHUNK):
        stop = min(start + TRIG_CHUNK, n)
        for i in range(start, stop):
            trig[i - start, 0], trig[i - start, 1] = sincos(poses[i, 2])
        chunk = (
            poses[start:stop],
            trig[: stop - start],
            landmarks,
            batch,
            noise,
            exact,
            sum_mixture,
            log_outlier,
            out[start:stop],
        )
        if exact or sum_mixture:
            _landmark_log_likelihood_fast(*chunk)
        else:
            _landmark_log_likelihood(*chunk)


TRIG_CHUNK = 4096  # particles per call of the general kernel from `landmark_log_likelihood`


# The default variant (von Mises, max-mixture) in plain IEEE arithmetic, no fast-math: the same bits on every
# machine, and those of the block kernels below.
@numba.njit(cache=True)
def _landmark_log_likelihood(poses, trig, landmarks, batch, noise, exact, sum_mixture, log_outlier, out):
    """`landmark_log_likelihood` with the cos and sin of each heading given in trig (N, 2)."""
    _general_likelihood(poses, trig, landmarks, batch, noise, exact, sum_mixture, log_outlier, out)


# The exact bearing term and the sum-mixture with fast-math (`FAST` leaves out the no-NaN and no-inf
# assumptions: the kernel tests for NaN, "noise not given", and starts its maximum at -inf): 16 % faster for
# the exact term, whose results may then differ in the last bits from one machine to another (fused
# multiply-adds where the processor has them). `LandmarkSensorModel` runs the exact term with the max-mixture
# in blocks instead (`exact_log_likelihood`); this kernel scores it with the sum-mixture, and as the reference.
_landmark_log_likelihood_fast = variant(_landmark_log_likelihood.py_func, "fast", fastmath=FAST)
"""`_landmark_log_likelihood` compiled with fast-math."""


@numba.njit(cache=True, inline="always")
def _general_likelihood(poses, trig, landmarks, batch, noise, exact, sum_mixture, log_outlier, out):
    """The body of both (inlined: compiled with each one's flags)."""
    table, offsets, _ = landmarks
    kinds, ranges, bearings, range_sigmas, bearing_sigmas = batch
    range_noise_floor, range_noise_growth, bearing_sigma = noise
    m = kinds.shape[0]
    order = np.argsort(kinds, kind="mergesort")
    obs_range = np.empty(m)
    obs_bearing = np.empty(m)
    range_weight = np.empty(m)  # -½/σ_r²
    bearing_cos = np.empty(m)  # κ cos b (von Mises)  or  -½/σ_b² (exact)
    bearing_sin = np.empty(m)  # κ sin b (von Mises)
    bearing_offset = np.empty(m)  # -κ (von Mises)  or  0 (exact)
    group_kind = np.empty(m, dtype=np.int64)
    group_start = np.empty(m + 1, dtype=np.int64)
    n_groups = 0
    max_k = 0
    for j in range(m):
        o = order[j]
        r = ranges[o]
        sr = range_sigmas[o]
        if np.isnan(sr):
            sr = range_noise_sigma(r, range_noise_floor, range_noise_growth)  # `LandmarkSensorModel.range_sigma`
        sb = bearing_sigmas[o]
        if np.isnan(sb):
            sb = bearing_sigma
        obs_range[j] = r
        obs_bearing[j] = bearings[o]
        range_weight[j] = -0.5 / (sr * sr)
        kappa = 1.0 / (sb * sb)
        if exact:
            bearing_cos[j] = -0.5 * kappa
            bearing_sin[j] = 0.0
            bearing_offset[j] = 0.0
        else:
            # κ(cos(b - b̂) - 1) = κ cos b · cos b̂ + κ sin b · sin b̂ - κ, with (cos b̂, sin b̂) = (ux, uy)
            bearing_cos[j] = kappa * math.cos(bearings[o])
            bearing_sin[j] = kappa * math.sin(bearings[o])
            bearing_offset[j] = -kappa
        kind = kinds[o]
        if n_groups == 0 or group_kind[n_groups - 1] != kind:
            group_kind[n_groups] = kind
            group_start[n_groups] = j
            n_groups += 1
            max_k = max(max_k, offsets[kind + 1] - offsets[kind])
    group_start[n_groups] = m
    dist = np.empty(max_k)
    ux = np.empty(max_k)
    uy = np.empty(max_k)
    expected_bearing = np.empty(max_k)
    outlier = math.exp(log_outlier)
    for i in range(poses.shape[0]):
        x = poses[i, 0]
        y = poses[i, 1]
        c = trig[i, 0]
        s = trig[i, 1]
        total = 0.0
        product = 1.0
        pending = 0
        for g in range(n_groups):
            kind = group_kind[g]
            first = offsets[kind]
            n_cand = offsets[kind + 1] - first
            # Geometry to each candidate, once per particle and type.
            for k in range(n_cand):
                dxw = table[first + k, 0] - x
                dyw = table[first + k, 1] - y
                rx = c * dxw + s * dyw
                ry = -s * dxw + c * dyw
                d = math.sqrt(rx * rx + ry * ry)
                dist[k] = d
                if d > 1e-12:
                    inverse = 1.0 / d
                    ux[k] = rx * inverse
                    uy[k] = ry * inverse
                else:
                    ux[k] = 1.0
                    uy[k] = 0.0
                if exact:
                    expected_bearing[k] = math.atan2(ry, rx)
            for j in range(group_start[g], group_start[g + 1]):
                r = obs_range[j]
                wr = range_weight[j]
                best = -np.inf
                if exact:
                    for k in range(n_cand):
                        er = r - dist[k]
                        eb = wrap_angle(obs_bearing[j] - expected_bearing[k])
                        best = max(best, wr * er * er + bearing_cos[j] * eb * eb)
                else:
                    bc = bearing_cos[j]
                    bs = bearing_sin[j]
                    for k in range(n_cand):  # branch-free, so LLVM can vectorize over the candidates
                        er = r - dist[k]
                        best = max(best, wr * er * er + bc * ux[k] + bs * uy[k])
                    best += bearing_offset[j]
                if not sum_mixture:
                    total += max(best, log_outlier)
                    continue
                # log(exp(best) + outlier), accumulated as a product: one exp per detection and one log
                # per 16 detections instead of an exp and a log each. Each factor lies in (outlier, 1 +
                # outlier], so 16 of them cannot underflow.
                product *= math.exp(best) + outlier
                pending += 1
                if pending == 16:
                    total += math.log(product)
                    product = 1.0
                    pending = 0
        out[i] = total + math.log(product)
    return out


# -- the default model (von Mises bearing, max-mixture) in blocks of particles -------------------------------------
# `landmark_log_likelihood` above computes every variant particle by particle. The kernels below compute the
# default variant, the one the filter runs every frame, bit for bit as that kernel does: the same operations
# in the same order, in plain IEEE arithmetic (no fast-math, no fused multiply-add), so nothing is left to the
# compiler's choice and the results are the same on every machine, whichever way LLVM arranges the loops. (A
# fused multiply-add spelled out is one instruction with FMA3, but a call into libm's fma on a processor
# without it, such as the NAO's Atom: compiled for its instruction set, this scoring was several times slower
# with them than without.) They work on a block at a time,
# with the candidates' geometry and the running maxima in rows over the block, so that every inner loop runs
# over particles and vectorizes (four particles per AVX2 instruction). The maxima alternate between two rows
# (`BEST`), because a row that is read and written in the same loop becomes a masked store, which is slow on
# AMD processors.

BLOCK = 128  # particles per block: the rows below stay in L1
X, Y, COS, SIN, TOTAL, BEST = 0, 1, 2, 3, 4, 5  # rows of the block work array; BEST takes rows 5 and 6
GEOMETRY = 7  # then, for each candidate k of the widest type: distance, unit x, unit y (rows 7 + 3k ...)


@numba.njit(cache=True)
def prepare_detections(
    kinds,
    ranges,
    bearings,
    range_sigmas,
    bearing_sigmas,
    offsets,
    range_noise_floor,
    range_noise_growth,
    bearing_sigma,
    exact=False,
):
    """The per-detection constants of the von Mises max-mixture (with `exact`, of the exact bearing term's),
    grouped by type.

    Returns (detections (m, 5): range, -½/σ_r², κ cos b, κ sin b, -κ (exact: range, -½/σ_r², -½κ, b, 0); groups
    (g, 3): type, first row, end row; missing): detections sorted by type (stable), as `landmark_log_likelihood`
    sums them, and `missing`, the first detection whose type has no landmark on the field (-1 if none).
    range_noise_growth: c, or the pair (b, c) of a law with a linear term (`range_noise_sigma`).
    """
    m = kinds.shape[0]
    missing = -1
    for j in range(m):
        if offsets[kinds[j] + 1] == offsets[kinds[j]]:
            missing = j
            break
    order = np.argsort(kinds, kind="mergesort")
    detections = np.empty((m, 5))
    groups = np.empty((m, 3), dtype=np.int64)
    n_groups = 0
    for j in range(m):
        o = order[j]
        r = ranges[o]
        sr = range_sigmas[o]
        if np.isnan(sr):
            sr = range_noise_sigma(r, range_noise_floor, range_noise_growth)
        sb = bearing_sigmas[o]
        if np.isnan(sb):
            sb = bearing_sigma
        kappa = 1.0 / (sb * sb)
        detections[j, 0] = r
        detections[j, 1] = -0.5 / (sr * sr)
        if exact:
            detections[j, 2] = -0.5 * kappa
            detections[j, 3] = wrap_angle(bearings[o])
            detections[j, 4] = 0.0
        else:
            detections[j, 2] = math.cos(bearings[o]) * kappa
            detections[j, 3] = math.sin(bearings[o]) * kappa
            detections[j, 4] = -kappa
        kind = kinds[o]
        if n_groups == 0 or groups[n_groups - 1, 0] != kind:
            groups[n_groups, 0] = kind
            groups[n_groups, 1] = j
            n_groups += 1
        groups[n_groups - 1, 2] = j + 1
    return detections, groups[:n_groups], missing


@numba.njit(cache=True)
def block_work(offsets, groups, columns):
    """The work array `score_block` needs for up to `columns` (<= BLOCK) particles: GEOMETRY rows plus 3 per
    candidate of the widest detected type."""
    widest = 0
    for g in range(groups.shape[0]):
        widest = max(widest, offsets[groups[g, 0] + 1] - offsets[groups[g, 0]])
    return np.empty((GEOMETRY + 3 * widest, columns))


@numba.njit(cache=True)
def load_block(poses, start, count, work, trig, fast=False):
    """Rows X, Y, COS, SIN of the work array from poses[start:start + count] (row TOTAL holds the headings
    meanwhile); cos and sin also into trig[start:start + count] when trig has rows (for a later pass over the
    same poses). fast: `sincos` compiled with fast-math (to rounding)."""
    for p in range(count):
        work[X, p] = poses[start + p, 0]
        work[Y, p] = poses[start + p, 1]
        work[TOTAL, p] = poses[start + p, 2]
    sincos_rows_as(work[TOTAL], work[COS], work[SIN], count, fast)
    if trig.shape[0] > 0:
        for p in range(count):
            trig[start + p, 0] = work[COS, p]
            trig[start + p, 1] = work[SIN, p]


@numba.njit(cache=True, error_model="numpy")
def _move_rows_back(work, count, dx, dy, dtheta):
    for p in range(count):
        work[X, p], work[Y, p], work[TOTAL, p] = moved_back(work[X, p], work[Y, p], work[TOTAL, p], dx, dy, dtheta)


@numba.njit(cache=True)
def move_block_back(work, count, displacement, fast=False):
    """Rows X, Y, COS, SIN of a work array that `load_block` loaded (row TOTAL still holding the headings),
    moved back by `displacement` (dx, dy, dθ, in the frame of the earlier pose): the operations of
    `mcl.latency.move_back`, then of `load_block`, so that the block scores as the moved-back poses would, bit
    for bit. Scores detections captured before the particles moved (camera latency) without writing the
    moved-back poses anywhere (a loop over rows, which vectorizes)."""
    _move_rows_back(work, count, displacement[0], displacement[1], displacement[2])
    sincos_rows_as(work[TOTAL], work[COS], work[SIN], count, fast)


def _score_block_body(work, count, table, offsets, detections, groups, log_outlier):
    """Row TOTAL of the work array: the log-likelihood (max-mixture) of the block's `count` particles, whose rows
    X, Y, COS, SIN are loaded. One source, two kernels (`numerics.compile.variant`, EXACT bound to a constant,
    so that each compiles only its own branches):

    - `score_block`, the von Mises bearing term: bit for bit `landmark_log_likelihood` with exact = sum_mixture =
      False. The geometry rows hold each candidate's distance and unit direction in the robot frame.
    - `score_block_exact`, the exact bearing term, -½(wrap(b - b̂)/σ_b)² (`prepare_detections` with exact made the
      detections, their bearings b wrapped): the rows hold the distance and the bearing b̂ (`atan2_poly`), and
      the error b - b̂, within [-2π, 2π], is wrapped by two selects, so that every loop vectorizes.
      `landmark_log_likelihood` with exact = True, sum_mixture = False to rounding (that kernel takes libm's
      atan2 and fast-math).
    """
    for p in range(count):
        work[TOTAL, p] = 0.0
    for g in range(groups.shape[0]):
        kind = groups[g, 0]
        first = offsets[kind]
        n_cand = offsets[kind + 1] - first
        # Geometry to each candidate, once per particle and type, in the robot frame.
        for k in range(n_cand):
            tx = table[first + k, 0]
            ty = table[first + k, 1]
            row = GEOMETRY + 3 * k
            for p in range(count):
                dxw = tx - work[X, p]
                dyw = ty - work[Y, p]
                c = work[COS, p]
                s = work[SIN, p]
                rx = c * dxw + s * dyw
                ry = -s * dxw + c * dyw
                if EXACT:
                    work[row, p] = math.sqrt(rx * rx + ry * ry)
                    work[row + 1, p] = atan2_poly(ry, rx)
                else:
                    d = math.sqrt(rx * rx + ry * ry)
                    inverse = 1.0 / d
                    far = d > 1e-12
                    work[row, p] = d
                    work[row + 1, p] = inverse * rx if far else 1.0
                    work[row + 2, p] = inverse * ry if far else 0.0
        for j in range(groups[g, 1], groups[g, 2]):
            r = detections[j, 0]
            wr = detections[j, 1]
            second = detections[j, 2]  # von Mises: bc; exact: wb
            third = detections[j, 3]  # von Mises: bs; exact: the bearing b
            for p in range(count):
                work[BEST, p] = -np.inf
            for k in range(n_cand):
                row = GEOMETRY + 3 * k
                source = BEST + k % 2
                target = BEST + 1 - k % 2
                for p in range(count):
                    er = r - work[row, p]
                    if EXACT:
                        eb = third - work[row + 1, p]  # in [-2π, 2π]: b is wrapped, atan2 in [-π, π]
                        eb = eb - TWO_PI if eb > math.pi else eb
                        eb = eb + TWO_PI if eb <= -math.pi else eb
                        score = wr * er * er + second * eb * eb
                    else:
                        score = wr * er * er + second * work[row + 1, p] + third * work[row + 2, p]
                    best = work[source, p]
                    work[target, p] = score if score > best else best
            last = BEST + n_cand % 2
            if EXACT:
                for p in range(count):
                    best = work[last, p]
                    work[TOTAL, p] += log_outlier if log_outlier > best else best
            else:
                offset = detections[j, 4]
                for p in range(count):
                    best = work[last, p] + offset
                    work[TOTAL, p] += log_outlier if log_outlier > best else best


EXACT = False  # bound by each variant (`numerics.compile.variant`)
score_block = variant(_score_block_body, "von_mises", {"EXACT": False}, error_model="numpy")
score_block_exact = variant(_score_block_body, "exact", {"EXACT": True}, error_model="numpy")


# -- the fused step's kernels (`sensing.fused`: the calling convention) -------------------------------------------
@numba.njit(cache=True)
def fused_prepare(inputs, params):
    """`prepare` of `LandmarkSensorModel.fused_likelihood`: the frame (table, offsets, the detections and their
    groups by type (`prepare_detections`), log outlier weight, exact) and the first detection whose type has no
    landmark (-1 if none)."""
    kinds, ranges, bearings, range_sigmas, bearing_sigmas = inputs
    _, offsets, range_noise_floor, range_noise_growth, bearing_sigma, _, exact = params
    detections, groups, missing = prepare_detections(
        kinds,
        ranges,
        bearings,
        range_sigmas,
        bearing_sigmas,
        offsets,
        range_noise_floor,
        range_noise_growth,
        bearing_sigma,
        exact,
    )
    return (params[0], offsets, detections, groups, params[5], exact), missing


@numba.njit(cache=True)
def fused_workspace(frame, columns):
    """`workspace`: the work array `score_block` needs for `columns` particles (`block_work`)."""
    return block_work(frame[1], frame[3], columns)


@numba.njit(cache=True)
def fused_score(poses, trig, start, count, work, since, fast, frame, out):
    """`score`: out[start:start + count] = the log-likelihoods of poses[start:start + count] (trig[0, p],
    trig[1, p]: cos and sin of the heading of poses[start + p]), moved back by `since` when it has rows, by
    `score_block` (or `score_block_exact`)."""
    table, offsets, detections, groups, log_outlier, exact = frame
    for p in range(count):
        work[X, p] = poses[start + p, 0]
        work[Y, p] = poses[start + p, 1]
        work[TOTAL, p] = poses[start + p, 2]
    for p in range(count):
        work[COS, p] = trig[0, p]
        work[SIN, p] = trig[1, p]
    if since.shape[0] > 0:
        move_block_back(work, count, since, fast)
    if exact:
        score_block_exact(work, count, table, offsets, detections, groups, log_outlier)
    else:
        score_block(work, count, table, offsets, detections, groups, log_outlier)
    for p in range(count):
        out[start + p] = work[TOTAL, p]


def detection_batch(observations: Observations) -> tuple:
    """The group `batch` of the kernels (kinds, ranges, bearings, range_sigmas, bearing_sigmas): the detections'
    arrays, as `fused_prepare` (its `inputs`) and the batch kernels take them."""
    return (
        observations.kinds,
        observations.ranges,
        observations.bearings,
        observations.range_sigmas,
        observations.bearing_sigmas,
    )


@numba.njit(cache=True)
def von_mises_log_likelihood(poses, table, offsets, detections, groups, log_outlier, out, trig):
    """out[i] = the von Mises max-mixture log-likelihood of particle i (`prepare_detections` made the
    detections); cos and sin of each heading also into trig (N, 2) when it has rows."""
    n = poses.shape[0]
    work = block_work(offsets, groups, min(n, BLOCK))
    for start in range(0, n, BLOCK):
        count = min(BLOCK, n - start)
        load_block(poses, start, count, work, trig)
        score_block(work, count, table, offsets, detections, groups, log_outlier)
        for p in range(count):
            out[start + p] = work[TOTAL, p]
    return out


@numba.njit(cache=True)
def exact_log_likelihood(poses, table, offsets, detections, groups, log_outlier, out):
    """out[i] = the exact-bearing max-mixture log-likelihood of particle i (`prepare_detections` with exact made
    the detections), a block of particles at a time (`score_block_exact`)."""
    n = poses.shape[0]
    work = block_work(offsets, groups, min(n, BLOCK))
    for start in range(0, n, BLOCK):
        count = min(BLOCK, n - start)
        load_block(poses, start, count, work, np.empty((0, 2)))
        score_block_exact(work, count, table, offsets, detections, groups, log_outlier)
        for p in range(count):
            out[start + p] = work[TOTAL, p]
    return out


def _one_call_body(poses, landmarks, batch, noise, log_outlier, out):
    """`LandmarkSensorModel.log_likelihood` with the max-mixture in one call (landmarks, batch, noise: the module
    docstring's groups); returns the first detection whose type has no landmark on the field (nothing written),
    or -1. One source, two kernels (`numerics.compile.variant`, EXACT bound): `_von_mises_log_likelihood`, the
    default variant, and `_exact_log_likelihood`, the exact bearing term."""
    table, offsets, _ = landmarks
    kinds, ranges, bearings, range_sigmas, bearing_sigmas = batch
    range_noise_floor, range_noise_growth, bearing_sigma = noise
    detections, groups, missing = prepare_detections(
        kinds,
        ranges,
        bearings,
        range_sigmas,
        bearing_sigmas,
        offsets,
        range_noise_floor,
        range_noise_growth,
        bearing_sigma,
        EXACT,
    )
    if missing < 0:
        if EXACT:
            exact_log_likelihood(poses, table, offsets, detections, groups, log_outlier, out)
        else:
            von_mises_log_likelihood(poses, table, offsets, detections, groups, log_outlier, out, np.empty((0, 2)))
    return missing


_von_mises_log_likelihood = variant(_one_call_body, "von_mises", {"EXACT": False})
_exact_log_likelihood = variant(_one_call_body, "exact", {"EXACT": True})


_NO_ANGLES = np.empty(0)


@numba.njit(cache=True)
def first_missing(offsets, kinds):
    """The first detection whose landmark type has no landmark (offsets[k] == offsets[k + 1]), or -1."""
    for i in range(kinds.shape[0]):
        if offsets[kinds[i] + 1] == offsets[kinds[i]]:
            return i
    return -1


@numba.njit(cache=True)
def reset_choices(integers, function, state, m, detection, uniforms):
    """The integer and uniform draws of `LandmarkSensorModel.sample_poses`: detection[:] ← rng.integers(0, m,
    size) (`bounded_integers`; integers from `integers_function`), then uniforms[:] ← rng.random(size), from the
    bit generator at `state` (function, state: `bit_generator_handle`)."""
    bounded_integers(integers, state, m, detection)
    draw_uniforms(function, state, uniforms, uniforms.shape[0])


@numba.njit(inline="always")
def _detection_sigmas(j, batch, noise, range_slack, bearing_slack):
    """(σ_r, σ_b) of detection j of `batch`: its own, else the model's (`noise`; σ_r at its range), each widened
    by its slack (the gates of `explained_detections` and `landmarks_in_view`; 0 for `sensor_reset_poses`)."""
    _, ranges, _, range_sigmas, bearing_sigmas = batch
    range_noise_floor, range_noise_growth, bearing_sigma = noise
    range_sigma = range_sigmas[j]
    if math.isnan(range_sigma):
        range_sigma = range_noise_sigma(ranges[j], range_noise_floor, range_noise_growth)
    sigma = bearing_sigmas[j]
    if math.isnan(sigma):
        sigma = bearing_sigma
    return range_sigma + range_slack, sigma + bearing_slack


@numba.njit(cache=True)
def sensor_reset_poses(landmarks, batch, noise, draws, heading_noise, out):
    """out[i] (M, 3): the pose that sees a landmark of detection `detection[i]`'s type (the one `landmark[i]`, a
    uniform on [0, 1), picks) at the detection's range and bearing with noise. landmarks, batch, noise: the
    module docstring's groups; draws: (detection, landmark, angles, normals); heading_noise: (heading,
    heading_sigma).
    The headings: `angles` (M) when it has M entries (uniforms on [0, 1): headings uniform on [-π, π)), else
    heading + heading_sigma · normals[:M]; then M normals for the ranges and M for the bearings. Range and
    bearing σ: the detection's own, or the model's (`range_noise_sigma`: floor + growth·r², or floor + b·r + c·r²
    with growth = (b, c); bearing_sigma) where NaN. Returns out."""
    table, offsets, _ = landmarks
    kinds, ranges, bearings, _, _ = batch
    detection, landmark, angles, normals = draws
    heading, heading_sigma = heading_noise
    m = out.shape[0]
    uniform_heading = angles.shape[0] == m
    first = 0 if uniform_heading else m
    for i in range(m):
        j = detection[i]
        kind = kinds[j]
        start = offsets[kind]
        k = start + np.int64(math.floor(landmark[i] * (offsets[kind + 1] - start)))
        if uniform_heading:
            theta = -math.pi + (math.pi - -math.pi) * angles[i]  # rng.uniform(-π, π)
        else:
            theta = heading + heading_sigma * normals[i]
        range_sigma, sigma = _detection_sigmas(j, batch, noise, 0.0, 0.0)
        r = max(ranges[j] + range_sigma * normals[first + i], 0.0)
        direction = theta + (bearings[j] + sigma * normals[first + m + i])
        out[i, 0] = table[k, 0] - r * math.cos(direction)
        out[i, 1] = table[k, 1] - r * math.sin(direction)
        out[i, 2] = wrap_angle(theta)
    return out


@numba.njit(cache=True)
def explained_detections(landmarks, pose, batch, noise, gate, out):
    """out[j] ← whether a landmark of detection j's type lies within `gate` standard deviations of where the
    pose (x, y, θ) would see it, range and bearing errors together (landmarks, pose, batch, noise, gate: the
    module docstring's groups; `LandmarkSensorModel.explained`; numpy twin
    `LandmarkSensorModel.numpy_twin().explained`). Returns out."""
    table, offsets, _ = landmarks
    x, y, theta = pose
    kinds, ranges, bearings, _, _ = batch
    gate_sigmas, range_slack, bearing_slack = gate
    limit = gate_sigmas * gate_sigmas
    for j in range(kinds.shape[0]):
        r = ranges[j]
        range_sigma, sigma = _detection_sigmas(j, batch, noise, range_slack, bearing_slack)
        found = False
        for k in range(offsets[kinds[j]], offsets[kinds[j] + 1]):
            dx = table[k, 0] - x
            dy = table[k, 1] - y
            range_error = (r - math.hypot(dx, dy)) / range_sigma
            bearing_error = wrap_angle(bearings[j] - (math.atan2(dy, dx) - theta)) / sigma
            if range_error**2 + bearing_error**2 <= limit:
                found = True
                break
        out[j] = found
    return out


# Negative information: a landmark in view counts as seen when a detection of its type lies within VIEW_GATE
# standard deviations, the model's σ widened by these slacks (the noise model is a guess; a pose a little off
# should still see what it sees).
VIEW_GATE = 3.0
VIEW_RANGE_SLACK = 0.1  # m
VIEW_BEARING_SLACK = 0.03  # rad


def gate_group(gate: float, range_slack: float, bearing_slack: float) -> tuple[float, float, float]:
    """The group `gate` of the kernels: (gate, range_slack, bearing_slack) as floats."""
    return float(gate), float(range_slack), float(bearing_slack)


def view_group(view: CameraView) -> tuple[float, float, float, np.ndarray]:
    """The group `view` of the kernels: (yaw, half_fov, min_range, max_ranges) of a `CameraView`, max_ranges
    (`CameraView.max_ranges`) the farthest range of each landmark type, indexed by the type's value (`max_range`
    for every type when the view gives one number: the same comparisons, bit for bit)."""
    return view.yaw, view.half_fov, view.min_range, view.max_ranges


@numba.njit(inline="always")
def _view_counts(landmarks, pose, batch, noise, gate, view):
    """(expected, seen) for one pose: see `landmarks_in_view`."""
    table, _, table_kinds = landmarks
    x, y, theta = pose
    kinds, ranges, bearings, _, _ = batch
    gate_sigmas, range_slack, bearing_slack = gate
    yaw, half_fov, min_range, max_ranges = view
    limit = gate_sigmas * gate_sigmas
    expected = 0
    seen = 0
    # In view: the angle between the landmark and the optical axis (θ + yaw) is at most half_fov, tested as
    # d·axis >= |d|·cos(half_fov), without an atan2 per landmark (half_fov <= π).
    axis_x = math.cos(theta + yaw)
    axis_y = math.sin(theta + yaw)
    cos_half = math.cos(half_fov)
    for k in range(table.shape[0]):
        dx = table[k, 0] - x
        dy = table[k, 1] - y
        r = math.hypot(dx, dy)
        if r < min_range or r > max_ranges[table_kinds[k]] or dx * axis_x + dy * axis_y < r * cos_half:
            continue
        bearing = math.atan2(dy, dx) - theta
        expected += 1
        for j in range(kinds.shape[0]):
            if kinds[j] != table_kinds[k]:
                continue
            range_sigma, sigma = _detection_sigmas(j, batch, noise, range_slack, bearing_slack)
            range_error = (ranges[j] - r) / range_sigma
            bearing_error = wrap_angle(bearings[j] - bearing) / sigma
            if range_error**2 + bearing_error**2 <= limit:
                seen += 1
                break
    return expected, seen


@numba.njit(cache=True)
def landmarks_in_view(landmarks, pose, batch, noise, gate, view, out):
    """out[0] ← how many landmarks the pose (x, y, θ) puts inside the view (bearing within `half_fov` of `yaw`,
    range within [min_range, max_ranges[its type value]]); out[1] ← how many of those a detection of their type
    lies within `gate` standard deviations of (range and bearing errors together; σ: the detection's own, else
    the model's at the detected range, plus the slacks, as `explained_detections`). landmarks, pose, batch, noise,
    gate, view: the module docstring's groups (`table_kinds[k]` is landmark k's type value).
    (`LandmarkSensorModel.seen`; numpy twin `LandmarkSensorModel.numpy_twin().seen`.) Returns out."""
    expected, seen = _view_counts(landmarks, pose, batch, noise, gate, view)
    out[0] = expected
    out[1] = seen
    return out


@numba.njit(cache=True)
def add_missed_in_view(poses, landmarks, batch, noise, gate, view, log_miss, out):
    """out[i] += log_miss × the landmarks pose i puts inside the view that no detection of their type explains
    (`landmarks_in_view`'s expected − seen; landmarks, batch, noise, gate, view: the module docstring's groups):
    negative information (`LandmarkSensorModel.log_likelihood` with a view; numpy twin
    `LandmarkSensorModel.numpy_twin().missed_in_view`). Returns out."""
    for i in range(poses.shape[0]):
        expected, seen = _view_counts(landmarks, (poses[i, 0], poses[i, 1], poses[i, 2]), batch, noise, gate, view)
        out[i] += (expected - seen) * log_miss
    return out


_LOG_SQRT_TWO_PI_INV = -0.5 * math.log(TWO_PI)


@functools.lru_cache(maxsize=256)
def _log_bearing_constant(bearing_model: str, sigma: float) -> float:
    """log of the bearing term's normalizing constant at σ_b = `sigma` (`LandmarkSensorModel.log_normalizer`):
    −log(2π·I0(κ)·e^(−κ)) with κ = 1/σ² for "von_mises", −log(√(2π)·σ) for "exact"."""
    if bearing_model == "von_mises":
        from scipy.special import i0e

        return -math.log(TWO_PI * float(i0e(1.0 / (sigma * sigma))))
    return _LOG_SQRT_TWO_PI_INV - math.log(sigma)


@keeps_arrays_frozen
@dataclass(frozen=True, eq=False)
class LandmarkSensorModel:
    """Range-bearing landmark likelihood for a field. Frozen; parameters in SI units.

    Range noise: σ_r(r) = range_noise_floor + range_noise_linear·r + range_noise_growth·r², with
    range_noise_floor a [m] > 0, range_noise_linear b (dimensionless) >= 0 and range_noise_growth c [1/m] >= 0.
    The default (a = 0.05 m, b = 0, c = 0.02 /m) is a camera's pitch error, growing with r²; constant noise
    (b = c = 0), linear growth (c = 0) and any mix of the three terms can be expressed as well.

    Parameters
    ----------
    field : Field
        The field whose landmarks are scored.
    range_noise_floor : float, default 0.05
        a [m] > 0 of σ_r.
    range_noise_growth : float, default 0.02
        c [1/m] >= 0 of σ_r.
    bearing_sigma : float, default 0.05
        σ_b [rad], the same at every range.
    bearing_model : str, default "von_mises"
        "von_mises" (no atan2) or "exact".
    outlier_weight : float, default 0.01
        The likelihood floor of one detection relative to a perfect match (false positives).
    mixture : str, default "max"
        "max" (the floor as a maximum) or "sum" (added as a mixture component).
    range_noise_linear : float, default 0.0
        b (dimensionless) >= 0 of σ_r.
    detection_rate : float, default 0.2
        Negative information, for a frame that comes with its camera view (`Observations.view`): the
        probability that a landmark inside the view (shrunk to `view_inset`, `CameraView.inset`) is reported.
        Each landmark a pose puts there that no detection of its type explains (within 3 σ, σ widened by
        `VIEW_RANGE_SLACK` and `VIEW_BEARING_SLACK`) multiplies that pose's likelihood by 1 − detection_rate.
        Low by default: robots, occlusion and the detector hide many landmarks, and a wrong pose that explains
        a few detections (aliasing) usually expects several that were not reported. 0 turns it off; a frame
        without a view, or without any detection (a blind camera says nothing), is scored without it.
    view_inset : float, default 0.8
        Within (0, 1].
    """

    field: Field
    range_noise_floor: float = 0.05
    range_noise_growth: float = 0.02
    bearing_sigma: float = 0.05
    bearing_model: str = "von_mises"
    outlier_weight: float = 0.01
    mixture: str = "max"
    range_noise_linear: float = 0.0
    detection_rate: float = 0.2
    view_inset: float = 0.8
    _table: np.ndarray = dataclass_field(init=False, repr=False)
    _offsets: np.ndarray = dataclass_field(init=False, repr=False)
    _table_kinds: np.ndarray = dataclass_field(init=False, repr=False)
    _landmarks: tuple = dataclass_field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.field, Field):
            raise ArgumentTypeError(f"field = {self.field!r} must be a field.Field, not {type(self.field).__name__}")
        # Noises within [SMALLEST_SIGMA, LARGEST_SIGMA]; the growth with range keeps σ_r finite (at most 10⁹ m)
        # at any range a detection may have (`MAX_RANGE`, 1 km).
        for name in ("range_noise_floor", "bearing_sigma"):
            real(name, getattr(self, name), SMALLEST_SIGMA, LARGEST_SIGMA)
        real("outlier_weight", self.outlier_weight, 0.0, 1.0, low_open=True)
        real("detection_rate", self.detection_rate, 0.0, 1.0, high_open=True)
        real("view_inset", self.view_inset, 0.0, 1.0, low_open=True)
        real("range_noise_growth", self.range_noise_growth, 0.0, LARGEST_SIGMA)
        real("range_noise_linear", self.range_noise_linear, 0.0, LARGEST_SIGMA)
        if not isinstance(self.mixture, str) or not isinstance(self.bearing_model, str):
            raise ArgumentTypeError(
                f"mixture = {self.mixture!r}, bearing_model = {self.bearing_model!r} must be strings"
            )
        if self.mixture not in ("max", "sum"):
            raise ValueError(f"mixture = {self.mixture!r} must be 'max' or 'sum'")
        if self.bearing_model not in BEARING_MODELS:
            raise ValueError(f"bearing_model = {self.bearing_model!r} must be one of {BEARING_MODELS}")
        kinds = sorted(LandmarkType, key=lambda t: t.value)
        blocks = [np.asarray(self.field.landmarks_of(t), dtype=np.float64).reshape(-1, 2) for t in kinds]
        offsets = np.zeros(max(t.value for t in kinds) + 2, dtype=np.int64)
        for t, block in zip(kinds, blocks):
            offsets[t.value + 1] = block.shape[0]
        offsets = np.cumsum(offsets).astype(np.int64)
        table = np.ascontiguousarray(np.concatenate(blocks, axis=0))
        table.flags.writeable = False
        offsets.flags.writeable = False
        object.__setattr__(self, "_table", table)
        object.__setattr__(self, "_offsets", offsets)
        table_kinds = np.repeat(np.arange(offsets.shape[0] - 1, dtype=np.int64), np.diff(offsets))
        table_kinds.flags.writeable = False
        object.__setattr__(self, "_table_kinds", table_kinds)
        object.__setattr__(self, "_landmarks", (table, offsets, table_kinds))

    # -- noise model --------------------------------------------------------------------------------------
    def range_sigma(self, ranges: np.ndarray) -> np.ndarray:
        """σ_r [m] at the given ranges [m]: floor + linear·r + growth·r² (the kernels' `range_noise_sigma`).

        Parameters
        ----------
        ranges : numpy.ndarray
            Ranges [m], any shape.

        Returns
        -------
        numpy.ndarray
            σ_r [m], the shape of `ranges`.
        """
        ranges = np.asarray(ranges, dtype=np.float64)
        return range_noise_sigma(ranges, self.range_noise_floor, self._range_noise_growth())

    def _range_noise_growth(self) -> tuple[float, float]:
        """The kernels' `range_noise_growth` argument: the pair (b, c), b = 0 without a linear term (the same σ_r
        as floor + c·r², bit for bit: see `range_noise_sigma`)."""
        return float(self.range_noise_linear), float(self.range_noise_growth)

    def noise_group(self) -> tuple:
        """The group `noise` of the kernels: (range_noise_floor, range_noise_growth, bearing_sigma), the growth as
        `_range_noise_growth` gives it."""
        return float(self.range_noise_floor), self._range_noise_growth(), float(self.bearing_sigma)

    @property
    def landmark_group(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The group `landmarks` of the kernels (read-only arrays): (table, offsets, table_kinds), the
        `landmark_table` and each landmark's type value."""
        return self._landmarks

    def candidates(self, kind: LandmarkType | int) -> np.ndarray:
        """The landmarks of one type: (K, 2) [x, y] rows of `landmark_table` (read-only).

        Parameters
        ----------
        kind : LandmarkType or int
            The type, or its value.

        Returns
        -------
        numpy.ndarray
            (K, 2) positions [m]; K = 0 when the field has none of that type.
        """
        k = int(kind)
        return self._table[self._offsets[k] : self._offsets[k + 1]]

    def explained(
        self,
        pose: Sequence[float] | np.ndarray,
        observations: Observations,
        gate: float = 3.0,
        range_slack: float = 0.0,
        bearing_slack: float = 0.0,
    ) -> np.ndarray:
        """Which detections (bool per detection) the pose (x, y, θ) explains: a landmark of the detection's type
        lies within `gate` standard deviations, in range and bearing together (σ: the detection's own, else
        the model's, plus the slacks). Compiled (`explained_detections`); numpy twin `numpy_twin().explained`.

        Parameters
        ----------
        pose : sequence of float or numpy.ndarray
            (x [m], y [m], θ [rad]).
        observations : Observations
            One frame's detections (coerced by `Observations.coerce`).
        gate : float, default 3.0
            Standard deviations within which a detection matches a landmark.
        range_slack : float, default 0.0
            Added to the range σ [m].
        bearing_slack : float, default 0.0
            Added to the bearing σ [rad].

        Returns
        -------
        numpy.ndarray
            (n,) bool, one per detection.
        """
        observations = Observations.coerce(observations)
        self.check(observations)
        return explained_detections(
            self._landmarks,
            (float(pose[0]), float(pose[1]), float(pose[2])),
            detection_batch(observations),
            self.noise_group(),
            gate_group(gate, range_slack, bearing_slack),
            np.empty(len(observations), dtype=np.bool_),
        )

    def chance_explained(
        self,
        observations: Observations,
        area: float,
        gate: float = 3.0,
        range_slack: float = 0.0,
        bearing_slack: float = 0.0,
    ) -> np.ndarray:
        """The chance (per detection) that a pose drawn at random over `area` m² explains the detection, as
        `explained` says with the same gate and slacks: the gate's ellipse around one landmark of the
        detection's type covers π·gate²·σ_r·(r·σ_b) m² of the positions that would see it there (σ: the
        detection's own, else the model's, plus the slacks; r its range), so with n landmarks of the type the
        chance is about n times that over `area`, at most 1. A far, noisy detection of a type with many
        landmarks is explained from almost anywhere, and says little about whether a pose is right; a near one
        says much.

        Parameters
        ----------
        observations : Observations
            One frame's detections (coerced by `Observations.coerce`).
        area : float
            The area the random pose is drawn over [m²] (the carpet's, say), > 0.
        gate, range_slack, bearing_slack : float
            As `explained`.

        Returns
        -------
        numpy.ndarray
            (n,) float in [0, 1], one per detection.

        Raises
        ------
        ValueError
            If `area` is not a finite number > 0, or the detections are refused (`check`).
        """
        area = real("area", area, 0.0, low_open=True)
        gate, range_slack, bearing_slack = gate_group(gate, range_slack, bearing_slack)
        observations = Observations.coerce(observations)
        self.check(observations)
        range_sigmas, bearing_sigmas = self._sigmas(observations)
        offsets = self._offsets.tolist()
        scale = math.pi * gate * gate / area
        out = np.empty(len(observations))
        # a few detections a frame: plain Python is quicker than numpy's calls on arrays this small
        for j, (kind, r, range_sigma, bearing_sigma) in enumerate(
            zip(
                observations.kinds.tolist(),
                observations.ranges.tolist(),
                range_sigmas.tolist(),
                bearing_sigmas.tolist(),
            )
        ):
            count = offsets[kind + 1] - offsets[kind]
            chance = count * scale * (range_sigma + range_slack) * (bearing_sigma + bearing_slack) * r
            out[j] = min(max(chance, 0.0), 1.0)
        return out

    def seen(
        self,
        pose: Sequence[float] | np.ndarray,
        observations: Observations,
        view: CameraView,
        gate: float = 3.0,
        range_slack: float = 0.0,
        bearing_slack: float = 0.0,
    ) -> tuple[int, int]:
        """Negative information: (expected, seen), how many landmarks the pose (x, y, θ) puts inside the camera's
        `view` (`sensing.view.CameraView`), and how many of those a detection of their type lies within `gate`
        standard deviations of (σ as in `explained`). A right pose sees most of what it expects; a wrong pose
        that happens to explain a few detections (aliasing) usually expects landmarks the frame did not report.
        Compiled (`landmarks_in_view`); numpy twin `numpy_twin().seen`.

        Parameters
        ----------
        pose : sequence of float or numpy.ndarray
            (x [m], y [m], θ [rad]).
        observations : Observations
            One frame's detections (coerced by `Observations.coerce`).
        view : CameraView
            Where the camera looked.
        gate : float, default 3.0
            Standard deviations within which a detection matches a landmark.
        range_slack : float, default 0.0
            Added to the range σ [m].
        bearing_slack : float, default 0.0
            Added to the bearing σ [rad].

        Returns
        -------
        tuple of int
            (expected, seen).

        Raises
        ------
        ArgumentTypeError
            If `view` is not a `CameraView` (a ValueError too).
        """
        observations = Observations.coerce(observations)
        self.check(observations)
        if not isinstance(view, CameraView):
            raise ArgumentTypeError(f"view = {view!r} must be a sensing.view.CameraView, not {type(view).__name__}")
        out = landmarks_in_view(
            self._landmarks,
            (float(pose[0]), float(pose[1]), float(pose[2])),
            detection_batch(observations),
            self.noise_group(),
            gate_group(gate, range_slack, bearing_slack),
            view_group(view),
            np.zeros(2, dtype=np.int64),
        )
        return int(out[0]), int(out[1])

    @property
    def landmark_table(self) -> tuple[np.ndarray, np.ndarray]:
        """The landmarks as the kernels take them (read-only): `table` (L, 2) [x, y] sorted by type, and
        `offsets`, so that the landmarks of type value k are table[offsets[k]:offsets[k + 1]]."""
        return self._table, self._offsets

    def check(self, observations: Observations) -> None:
        """Raise ValueError if a detection's type has no landmark on this field.

        Parameters
        ----------
        observations : Observations
            One frame's detections.

        Raises
        ------
        ValueError
            Naming the first detection whose type the field lacks.
        """
        kinds = observations.kinds
        if kinds.shape[0] == 0:  # (a frame without detections: no compiled call)
            return
        i = first_missing(self._offsets, kinds)
        if i >= 0:
            raise ValueError(
                f"observation {i}: field {self.field.name!r} has no landmark of type {LandmarkType(int(kinds[i])).name}"
            )

    def terms(self, observations: Observations) -> int:
        """How many independent terms the likelihood sums: one per landmark detection.

        Parameters
        ----------
        observations : Observations
            One frame's detections.

        Returns
        -------
        int
            The number of detections.
        """
        return len(observations)

    def log_normalizer(self, observations: Observations) -> float:
        """The log of the constant that turns this frame's likelihood (`log_likelihood`, relative: a perfect
        match scores 1 per detection) into a density over the detections' ranges [m] and bearings [rad].

        Per detection j, with σ_r and σ_b its noise at the observed range: the range term's Gaussian constant
        −log(√(2π)·σ_r), the bearing term's −log(2π·I0(κ)·e^(−κ)) with κ = 1/σ_b² ("von_mises") or
        −log(√(2π)·σ_b) ("exact"), and the outlier floor read as a uniform density over every bearing and the
        ranges up to the carpet's diagonal (A = 2π·diagonal): the frame's density is the relative likelihood
        times Π_j c_j / (1 + c_j·outlier_weight·A). Exact for one candidate landmark of the type and the "sum"
        mixture; an upper bound of the mass otherwise. The frame's evidence under the filter (the log of the
        weighted average particle likelihood) plus this constant is comparable between sensor settings, which
        `mcl.localizer.Localizer.log_evidence` sums. Negative information (a frame's view) is not included.

        Parameters
        ----------
        observations : Observations
            One frame's detections (coerced by `Observations.coerce`).

        Returns
        -------
        float
            The constant's log (0.0 for a frame without detections).
        """
        observations = Observations.coerce(observations)
        self.check(observations)
        if len(observations) == 0:
            return 0.0
        # Per detection in plain Python (a frame holds a few): this runs in the robot's loop, on every frame.
        dims = self.field.dims
        diagonal = math.hypot(dims.length + 2 * dims.border_strip_width, dims.width + 2 * dims.border_strip_width)
        log_outlier_mass = math.log(self.outlier_weight * TWO_PI * diagonal)
        growth = self._range_noise_growth()
        total = 0.0
        for r, given_r, given_b in zip(
            observations.ranges.tolist(), observations.range_sigmas.tolist(), observations.bearing_sigmas.tolist()
        ):
            range_sigma = given_r if given_r == given_r else range_noise_sigma(r, self.range_noise_floor, growth)
            bearing_sigma = given_b if given_b == given_b else self.bearing_sigma
            log_c = (
                _LOG_SQRT_TWO_PI_INV - math.log(range_sigma) + _log_bearing_constant(self.bearing_model, bearing_sigma)
            )
            x = log_c + log_outlier_mass  # log(c·outlier_weight·A); log(1 + e^x) without overflow
            total += log_c - (x + math.log1p(math.exp(-x)) if x > 0 else math.log1p(math.exp(x)))
        return total

    def _sigmas(self, observations: Observations) -> tuple[np.ndarray, np.ndarray]:
        range_sigmas = np.where(
            np.isnan(observations.range_sigmas), self.range_sigma(observations.ranges), observations.range_sigmas
        )
        bearing_sigmas = np.where(
            np.isnan(observations.bearing_sigmas), self.bearing_sigma, observations.bearing_sigmas
        )
        return range_sigmas, bearing_sigmas

    # -- likelihood ---------------------------------------------------------------------------------------
    def log_likelihood(
        self, poses: np.ndarray, observations: Observations, out: np.ndarray | None = None
    ) -> np.ndarray:
        """Log-likelihood of `observations` for each pose in `poses` (N, 3); shape (N,).

        Parameters
        ----------
        poses : numpy.ndarray
            (N, 3) poses (x [m], y [m], θ [rad]).
        observations : Observations
            One frame's detections (coerced by `Observations.coerce`).
        out : numpy.ndarray or None, default None
            (N,) float64 array to write into; None allocates one.

        Returns
        -------
        numpy.ndarray
            (N,) log-likelihoods (`out` when given).

        Raises
        ------
        ValueError
            If a detection's type has no landmark on this field.
        """
        observations = Observations.coerce(observations)
        n = poses.shape[0]
        if out is None:
            out = np.empty(n)
        if self.mixture == "max":
            # The type check runs inside the kernel, before anything is written; check() then names the culprit.
            kernel = _von_mises_log_likelihood if self.bearing_model == "von_mises" else _exact_log_likelihood
            if (
                kernel(
                    poses,
                    self._landmarks,
                    detection_batch(observations),
                    self.noise_group(),
                    math.log(self.outlier_weight),
                    out,
                )
                >= 0
            ):
                self.check(observations)
        else:
            self.check(observations)
            if len(observations) == 0:
                out[:] = 0.0
                return out
            landmark_log_likelihood(
                poses,
                self._landmarks,
                detection_batch(observations),
                self.noise_group(),
                self.bearing_model == "exact",
                self.mixture == "sum",
                math.log(self.outlier_weight),
                out,
            )
        if observations.view is not None and self.scores_view(observations):
            view = observations.view.inset(self.view_inset)
            add_missed_in_view(
                poses,
                self._landmarks,
                detection_batch(observations),
                self.noise_group(),
                gate_group(VIEW_GATE, VIEW_RANGE_SLACK, VIEW_BEARING_SLACK),
                view_group(view),
                math.log1p(-self.detection_rate),
                out,
            )
        return out

    def scores_view(self, observations: Observations) -> bool:
        """Whether the likelihood of `observations` includes negative information: the frame has a view, at
        least one detection, and `detection_rate` > 0. The filter's compiled step scores without it, so the
        filter scores such a frame through `log_likelihood`.

        Parameters
        ----------
        observations : Observations
            One frame's detections.
        """
        return observations.view is not None and self.detection_rate > 0 and observations.kinds.shape[0] > 0

    def numpy_twin(self) -> reference.LandmarkTwin:
        """This model computed in plain numpy (`sensing.reference.LandmarkTwin`): `log_likelihood`, `explained`,
        `seen`, `missed_in_view` and `sample_poses` with the parameters and results of this model's calls, for
        the reference engine and the tests. The twin reads this model; it copies nothing."""
        return reference.LandmarkTwin(self)

    if not TYPE_CHECKING:  # the deprecated names (a type checker would accept any attribute after a __getattr__)
        __getattr__ = moved_methods(
            "LandmarkSensorModel",
            {
                f"{name}_reference": (
                    f"numpy_twin().{name}",
                    lambda model, name=name: getattr(model.numpy_twin(), name),
                )
                for name in ("log_likelihood", "explained", "seen", "missed_in_view", "sample_poses")
            },
        )

    def fused_likelihood(self) -> FusedLikelihoodKernels | None:
        """This model's likelihood for the filter's fused compiled step (`sensing.fused`): `fused_prepare`,
        `fused_workspace` and `fused_score` with params (table, offsets, range_noise_floor, range_noise_growth,
        bearing_sigma, log outlier_weight, exact); None for the sum mixture, which the filter scores through
        `log_likelihood`. A subclass that changes `log_likelihood` must return None. range_noise_growth is the
        pair (range_noise_linear, c) (`range_noise_sigma`). A frame with a camera view is scored through
        `log_likelihood` (`scores_view`)."""
        if self.mixture != "max":
            return None
        params = (
            self._table,
            self._offsets,
            float(self.range_noise_floor),
            self._range_noise_growth(),
            float(self.bearing_sigma),
            math.log(self.outlier_weight),
            self.bearing_model == "exact",
        )
        return FusedLikelihoodKernels(fused_prepare, fused_workspace, fused_score, params, detection_batch)

    # -- sensor resetting ---------------------------------------------------------------------------------
    def sample_poses(
        self,
        observations: Observations,
        n: int,
        rng: np.random.Generator,
        heading: float | None = None,
        heading_sigma: float = 0.3,
    ) -> np.ndarray:
        """Draw `n` poses that explain one detection each (sensor resetting, Lenser & Veloso 2000).

        Each pose: a random detection, a random landmark of its type, a heading (normal around `heading`, or
        uniform when None), a noisy range and bearing; the robot stands where it would see that landmark
        there. With a known heading this samples the few places consistent with a detection instead of the
        whole field. Returns (n, 3); empty when there are no detections.

        The draws are numpy's (`rng.integers`, `rng.random`, then `rng.uniform` or `rng.standard_normal` for
        the headings, `rng.standard_normal` for the ranges and bearings): the integers and uniforms drawn in
        a kernel from the generator's own bit generator (`reset_choices`, the numbers numpy would give), the
        normals by numpy, and the poses come from them in one compiled pass (`sensor_reset_poses`): bit for
        bit `numpy_twin().sample_poses`.

        Parameters
        ----------
        observations : Observations
            One frame's detections (coerced by `Observations.coerce`).
        n : int
            How many poses to draw; 0 or less draws none.
        rng : numpy.random.Generator
            The generator drawn from.
        heading : float or None, default None
            The robot's heading, if known [rad]: headings are drawn normal around it; None: uniform.
        heading_sigma : float, default 0.3
            Standard deviation of the headings around `heading` [rad].

        Returns
        -------
        numpy.ndarray
            (n, 3) poses (x [m], y [m], θ [rad]); (0, 3) when there are no detections.
        """
        observations = Observations.coerce(observations)
        self.check(observations)
        m = len(observations)
        if m == 0 or n <= 0:
            return np.empty((0, 3))
        n = int(n)
        uniform_heading = heading is None
        heading_mean = 0.0 if heading is None else heading
        detection = np.empty(n, dtype=np.int64)
        # The landmarks' n uniforms, then the headings' n when uniform (rng.uniform(-π, π, n) is -π + 2π·u on
        # these): one stream, so rng.random(n) twice is rng.random(2n).
        uniforms = np.empty(2 * n if uniform_heading else n)
        function, state, integers = draw_handles(rng)  # (m <= INTEGERS_LIMIT: far more than fit in memory)
        reset_choices(integers, function, state, m, detection, uniforms)
        landmark = uniforms[:n]
        if uniform_heading:
            angles = uniforms[n:]
            normals = rng.standard_normal(2 * n)  # = the ranges' n, then the bearings' n
            heading_mean, heading_sigma = 0.0, 0.0
        else:
            angles = _NO_ANGLES
            normals = rng.standard_normal(3 * n)  # = the headings' n, the ranges' n, the bearings' n
        return sensor_reset_poses(
            self._landmarks,
            detection_batch(observations),
            self.noise_group(),
            (detection, landmark, angles, normals),
            (float(heading_mean), float(heading_sigma)),
            np.empty((n, 3)),
        )
