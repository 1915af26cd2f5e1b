"""Log-weight arithmetic: normalization with log-sum-exp and the effective sample size.

    from mcl.weights import normalize, weigh
    log_total, ess = normalize(log_weights, weights_out)   # weights_out = exp(log_weights - log_total)
    valid, native, log_total, ess = weigh(log_weights, log_likelihood, count, weights_out)

`weigh` is a correction's weight update in one kernel: the check for NaN and +inf, the prior-weighted mean
likelihood of the first `count` particles (`log_mean_likelihood`, for augmented MCL), and the normalization of
log_weights + log_likelihood (`normalize`), with the results of those functions bit for bit but a single exp
per particle where they take three; `reweigh` then stores the normalized log-weights. `weigh_chunked` (on
several threads) and `weigh_fast` (polynomial exp, vectorized) are the filter's opt-in variants: equal to
rounding.
"""

import math

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from field.moved import moved_names
from numerics.compile import variant

# The numpy twins moved to the package's `reference` module; their old names still work, with a warning.
__getattr__ = moved_names(__name__, {"normalize_reference": "mcl.reference.normalize"})


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


@numba.njit(cache=True)
def _scan(log_weights, log_likelihood, count, first, start, stop):
    """One scan over particles start..stop for the weight update: (valid, peak of the candidates log_weights +
    log_likelihood, peak of those among the first `count`, peak of the first `count` log-weights, whether those
    log-weights all equal `first`). valid is False at the first NaN or +inf log-likelihood (the scan stops)."""
    peak = peak_joint = peak_prior = -np.inf
    equal = True
    for i in range(start, stop):
        ll = log_likelihood[i]
        if np.isnan(ll) or ll == np.inf:
            return False, peak, peak_joint, peak_prior, equal
        candidate = log_weights[i] + ll
        if candidate > peak:
            peak = candidate
        if i < count:
            if candidate > peak_joint:
                peak_joint = candidate
            if log_weights[i] > peak_prior:
                peak_prior = log_weights[i]
            if log_weights[i] != first:
                equal = False
    return True, peak, peak_joint, peak_prior, equal


# -- the weight update: one source, a serial and a chunked kernel ------------------------------------------------------
def _weigh_body(log_weights, log_likelihood, count, weights_out, chunk=0):
    """A correction's weight update; returns (valid, native, log_total, ess).

    valid: False when a log-likelihood is NaN or +inf (then nothing is written and the rest is meaningless).
    native: `log_mean_likelihood(log_weights, log_likelihood, count)`.
    log_total, ess: `normalize(log_weights + log_likelihood, weights_out)` (weights_out written unless every
    candidate is -inf). log_weights itself is left as it is: `reweigh` normalizes it.

    Equal to those functions bit for bit: the exponentials of the candidates that `normalize` sums are the
    ones `log_mean_likelihood` sums over the first `count` particles when both share the peak (the running
    total read at `count`); with equal prior log-weights (after resampling) each prior term is exp(0) = 1, so
    the prior sum is `count` exactly. Otherwise the missing sum is taken as those functions take it.

    One source, two kernels (`numerics.compile.variant`): `weigh` takes every sum in index order (one chunk);
    `weigh_chunked` takes each sum chunk by chunk (within a chunk in index order, then over the chunks in
    order), the chunks of `chunk` particles spread over threads: the same results for any number of threads,
    `weigh`'s bit for bit when chunk >= N (0.0 + a sum is that sum), and otherwise equal to rounding. The
    exponentials' loop stops at `count` and goes on from there, so that it reads the share of the first `count`
    without a branch per particle. `weigh_fast` (below) is the fast-math kernel.
    """
    n = log_weights.shape[0]
    if ONE_CHUNK:
        chunk = max(n, 1)
    chunks = max(1, (n + chunk - 1) // chunk)
    peaks = np.full((chunks, 3), -np.inf)  # all, joint (first `count`), prior (first `count`)
    flags = np.zeros((chunks, 2), dtype=np.bool_)  # invalid, unequal prior
    first = log_weights[0] if n > 0 else 0.0
    for t in numba.prange(chunks):
        valid, peak, peak_joint, peak_prior, equal = _scan(
            log_weights, log_likelihood, count, first, t * chunk, min(n, (t + 1) * chunk)
        )
        peaks[t, 0] = peak
        peaks[t, 1] = peak_joint
        peaks[t, 2] = peak_prior
        flags[t, 0] = not valid
        flags[t, 1] = not equal
    peak = -np.inf
    peak_joint = -np.inf
    peak_prior = -np.inf
    equal_prior = True
    for t in range(chunks):
        if flags[t, 0]:
            return False, 0.0, 0.0, 0.0
        peak = max(peak, peaks[t, 0])
        peak_joint = max(peak_joint, peaks[t, 1])
        peak_prior = max(peak_prior, peaks[t, 2])
        equal_prior = equal_prior and not flags[t, 1]
    sums = np.zeros((chunks, 3))  # exp total, its share of the first `count`, a third sum
    if peak > -np.inf:
        for t in numba.prange(chunks):
            start = t * chunk
            stop = min(n, start + chunk)
            split = min(max(count, start), stop)
            total = 0.0
            for i in range(start, split):
                e = math.exp(log_weights[i] + log_likelihood[i] - peak)
                weights_out[i] = e
                total += e
            sums[t, 1] = total
            for i in range(split, stop):
                e = math.exp(log_weights[i] + log_likelihood[i] - peak)
                weights_out[i] = e
                total += e
            sums[t, 0] = total
    native = -np.inf
    if peak_prior > -np.inf and peak_joint > -np.inf:
        joint = 0.0
        if peak_joint == peak:
            for t in range(chunks):
                if t * chunk < count:
                    joint += sums[t, 1]
        else:
            for t in numba.prange(chunks):
                part = 0.0
                for i in range(t * chunk, min(count, (t + 1) * chunk)):
                    part += math.exp(log_weights[i] + log_likelihood[i] - peak_joint)
                sums[t, 1] = part
            for t in range(chunks):
                joint += sums[t, 1]
        if equal_prior:
            prior = float(count)
        else:
            for t in numba.prange(chunks):
                part = 0.0
                for i in range(t * chunk, min(count, (t + 1) * chunk)):
                    part += math.exp(log_weights[i] - peak_prior)
                sums[t, 2] = part
            prior = 0.0
            for t in range(chunks):
                prior += sums[t, 2]
        native = peak_joint + math.log(joint) - peak_prior - math.log(prior)
    if peak == -np.inf:
        return True, native, -np.inf, 0.0
    total = 0.0
    for t in range(chunks):
        total += sums[t, 0]
    inverse = 1.0 / total
    for t in numba.prange(chunks):
        squares = 0.0
        for i in range(t * chunk, min(n, (t + 1) * chunk)):
            w = weights_out[i] * inverse
            weights_out[i] = w
            squares += w * w
        sums[t, 2] = squares
    squares = 0.0
    for t in range(chunks):
        squares += sums[t, 2]
    return True, native, peak + math.log(total), 1.0 / squares


ONE_CHUNK = True  # bound by each variant (`numerics.compile.variant`)
weigh = variant(_weigh_body, "serial", {"ONE_CHUNK": True})
weigh_chunked = variant(_weigh_body, "chunked", {"ONE_CHUNK": False}, parallel=True)


def _reweigh_body(log_weights, log_likelihood, log_total, chunk=0):
    """log_weights ← log_weights + log_likelihood - log_total: the normalized posterior log-weights, elementwise
    (the same numbers in one chunk, `reweigh`, or in chunks of `chunk` on threads, `reweigh_chunked`)."""
    n = log_weights.shape[0]
    if ONE_CHUNK:
        chunk = max(n, 1)
    for t in numba.prange(max(1, (n + chunk - 1) // chunk)):
        for i in range(t * chunk, min(n, (t + 1) * chunk)):
            log_weights[i] = log_weights[i] + log_likelihood[i] - log_total


reweigh = variant(_reweigh_body, "serial", {"ONE_CHUNK": True})
reweigh_chunked = variant(_reweigh_body, "chunked", {"ONE_CHUNK": False}, parallel=True)


# -- the opt-in fast variant -------------------------------------------------------------------------------------------
# With `ParticleFilter(fast=True)`: the exponentials by a polynomial (no libm call, so the loops vectorize) and
# the sums reassociated (vectorized). Equal to `weigh` to about 10⁻¹⁵ relative.
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}  # fast-math without assuming no NaN / inf
_LOG2E = 1.44269504088896338700e00
_LN2_HIGH = 6.93147180369123816490e-01
_LN2_LOW = 1.90821492927058770002e-10


_EXPONENT_SHIFTER = 4503599627370496.0 + 1023.0  # 2⁵² plus the exponent bias


@intrinsic
def _double_bits(typingctx, value):
    signature = types.int64(types.float64)

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return signature, codegen


@intrinsic
def _bits_to_double(typingctx, bits):
    signature = types.float64(types.int64)

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return signature, codegen


@numba.njit(cache=True, fastmath=FAST, inline="always")
def fast_exp(x):
    """exp(x) for x <= 0, 0 below -745.2; branch-free (vectorizes).

    Compiled plainly it is within 4.8·10⁻¹⁶ relative (two units in the last place). Under the fast-math flags
    of its callers (`FAST`), reassociation folds the two-part reduction by ln 2 into one, and the relative error
    grows with |x|: within 6·10⁻¹⁶ + 3.5·10⁻¹⁷·|x| (1.6·10⁻¹⁵ at x = -40, 2.4·10⁻¹⁴ at -708). As a weight
    relative to the largest (x <= 0), the error is below 2.3·10⁻¹⁶ absolute: a weight near 1 is accurate,
    and one whose error is large in relative terms is negligible."""
    x = x if x > -745.2 else -745.2
    k = np.floor(x * _LOG2E + 0.5)
    r = (x - k * _LN2_HIGH) - k * _LN2_LOW  # |r| <= ln 2 / 2
    p = 1.0 + r * (
        1.0
        + r
        * (
            1.0 / 2
            + r
            * (
                1.0 / 6
                + r
                * (
                    1.0 / 24
                    + r
                    * (
                        1.0 / 120
                        + r
                        * (
                            1.0 / 720
                            + r
                            * (
                                1.0 / 5040
                                + r
                                * (
                                    1.0 / 40320
                                    + r * (1.0 / 362880 + r * (1.0 / 3628800 + r * (1.0 / 39916800 + r / 479001600)))
                                )
                            )
                        )
                    )
                )
            )
        )
    )
    half = np.floor(k * 0.5)  # 2ᵏ as two normal powers of two, for k down to -1075
    # Their biased exponents e (integers in [0, 2¹¹)) are the low bits of the double 2⁵² + e, which a shift
    # by 52 moves into place: no conversion to an integer, which AVX2 has no vector instruction for.
    first = _bits_to_double(_double_bits(half + _EXPONENT_SHIFTER) << 52)
    second = _bits_to_double(_double_bits(k - half + _EXPONENT_SHIFTER) << 52)
    return p * first * second


@numba.njit(cache=True, fastmath=FAST, error_model="numpy")
def _exp_terms(log_weights, log_likelihood, peak, out, start, stop):
    total = 0.0
    for i in range(start, stop):
        e = fast_exp(log_weights[i] + log_likelihood[i] - peak)
        out[i] = e
        total += e
    return total


@numba.njit(cache=True, fastmath=FAST, error_model="numpy")
def _exp_sum(values, more, peak, stop):
    """Σ exp(values[i] + more[i] - peak) over i < stop (more: the same shape, or no entries for none)."""
    total = 0.0
    if more.shape[0] == 0:
        for i in range(stop):
            total += fast_exp(values[i] - peak)
    else:
        for i in range(stop):
            total += fast_exp(values[i] + more[i] - peak)
    return total


@numba.njit(cache=True, fastmath=FAST, error_model="numpy")
def _scale_and_squares(weights, inverse):
    squares = 0.0
    for i in range(weights.shape[0]):
        w = weights[i] * inverse
        weights[i] = w
        squares += w * w
    return squares


@numba.njit(cache=True)
def weigh_fast(log_weights, log_likelihood, count, weights_out):
    """`weigh` with `fast_exp` and reassociated sums (equal to rounding)."""
    n = log_weights.shape[0]
    first = log_weights[0] if n > 0 else 0.0
    valid, peak, peak_joint, peak_prior, equal_prior = _scan(log_weights, log_likelihood, count, first, 0, n)
    if not valid:
        return False, 0.0, 0.0, 0.0
    total = 0.0
    joint = 0.0
    if peak > -np.inf:
        joint = _exp_terms(log_weights, log_likelihood, peak, weights_out, 0, count)
        total = joint + _exp_terms(log_weights, log_likelihood, peak, weights_out, count, n)
    native = -np.inf
    if peak_prior > -np.inf and peak_joint > -np.inf:
        if peak_joint != peak:
            joint = _exp_sum(log_weights, log_likelihood, peak_joint, count)
        prior = float(count) if equal_prior else _exp_sum(log_weights, log_likelihood[:0], peak_prior, count)
        native = peak_joint + math.log(joint) - peak_prior - math.log(prior)
    if peak == -np.inf:
        return True, native, -np.inf, 0.0
    squares = _scale_and_squares(weights_out, 1.0 / total)
    return True, native, peak + math.log(total), 1.0 / squares
