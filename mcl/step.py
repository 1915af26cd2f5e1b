"""The filter's fused compiled step: predict, likelihood, weights, resampling and the summary in one call.

    from mcl.step import fused_step
    step = fused_step(sensor_model.fused_likelihood())    # compiled once per machine for each kind of model
    step.compiled_step(particles, motion, draws, sensor, weighting, resampling, summary, chunk, fast, since)

`compiled_step` runs what `ParticleFilter.predict`, `correct`, `estimate` and `entropy` compute, for a
bounded-noise motion model (`motion_models.base.BoundedNoiseModel`: the filter moves the particles with
`motion_models.kernels`) and any sensor model that offers its compiled likelihood (`sensing.fused`): the
model's kernels are called on each block of particles while it is in cache. The results are those of the plain
sequence of calls bit for bit (tests/test_fast_step.py runs both side by side).

One source, one compiled step per kind of sensor model. `predict_and_score`, `predict_and_score_chunked` and
`compiled_step` below are written once, in plain Python, calling the model's kernels by the names `prepare`,
`workspace` and `score`; `fused_step` compiles them with those names bound to a model's kernels
(`numerics.compile.variant`; numba inlines
and caches the result like any kernel: nothing is looked up while a step runs, and a filter with another kind
of model gets its own compiled step). The compiled code is cached per machine under a name that holds the
kernels' qualified names and a hash of their bytecode, so an edited kernel compiles anew (numba's cache does
not see edits in the functions a kernel calls; in a source checkout `mcl.numba_cache` drops every cached
kernel after any edit).

Its arguments come in groups (tuples), each built by the filter:

    particles   (poses, log_weights, weights, log_likelihood, scratch, trig, counts, local)
    motion      (move, dx, dy, dθ, bound_x, bound_y, bound_θ, gaussian, variates)
    draws       (function, state): the filter generator's handle (`numerics.random.bit_generator_handle`)
    sensor      (params, inputs): the model's constants and this frame's arrays (`sensing.fused`)
    weighting   (count, terms, augmented, alpha_slow, alpha_fast, ratio_threshold, fit_threshold, w_slow,
                 w_fast, cap)
    resampling  (resample_threshold, can_resample, roughening, state_rows, state_scratch)
    summary     (grid, coordinates, histograms, bitmaps, want_estimate, previous, use_previous, out_mean,
                 out_cov, want_entropy)

and then `chunk` (> 0: the threads variant), `fast` (fast-math) and `since` (camera latency).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numba
import numpy as np

from motion_models.kernels import MOVE_WORK, move_range, move_range_fast
from numerics.compile import variant
from numerics.random import parallel_uniforms
from numerics.trig import SQRT3, sincos_rows_as

from .estimate import (
    summary_entropy,
    summary_estimate,
    summary_estimate_chunked,
    summary_estimate_fast,
    summary_fill,
    summary_fill_chunked,
)
from .resampling import gather_offspring_rows, resample_with_jitter, resample_with_jitter_chunked
from .weights import reweigh, reweigh_chunked, weigh, weigh_chunked, weigh_fast

# The model's kernels, until `fused_step` binds them (the templates below call them by these names).
prepare = workspace = score = None

STEP_BLOCK = 128  # particles moved and scored at a time (the block and the model's scratch stay in L1)
NO_VARIATES = np.empty((0, 3))
NO_SINCE = np.empty(0)  # detections captured now: nothing to move back
# `compiled_step` status: done; a detection the model cannot score (nothing changed); NaN or +inf likelihoods
# (predicted only); no particle explains the detections; resampling (with injection) is left to Python.
STEP_DONE, STEP_MISSING, STEP_INVALID, STEP_UNEXPLAINED, STEP_RESAMPLE = range(5)


@numba.njit(cache=True)
def augmented_update(w_slow, w_fast, log_average, alpha_slow, alpha_fast, ratio_threshold, fit_threshold):
    """`mcl.augmented.AugmentedMCL.update` in compiled code: (w_slow, w_fast, injection share)."""
    average = math.exp(log_average)
    if w_slow == 0.0:
        w_slow = w_fast = average
    else:
        w_slow += alpha_slow * (average - w_slow)
        w_fast += alpha_fast * (average - w_fast)
    relative = 1.0 - w_fast / (ratio_threshold * w_slow) if w_slow > 0 else 1.0
    absolute = 1.0 - w_fast / fit_threshold if fit_threshold > 0 else 0.0
    fraction = 0.0  # max(0.0, relative, absolute), resolved as Python's max resolves it
    if relative > fraction:
        fraction = relative
    if absolute > fraction:
        fraction = absolute
    return w_slow, w_fast, fraction


@numba.njit(cache=True)
def resample_and_summarize(
    weights, keep, scratch, roughening, poses, trig, draws, counts, injected, log_weights, summary, fast
):
    """After `compiled_step` returned `STEP_RESAMPLE` for injection (one thread): systematic resampling of
    `keep` particles from `scratch` (the scored particles; trig their cos and sin) into poses[:keep] with
    roughening, `injected` into poses[keep:], uniform weights; then the summary (see `summarize`). Returns
    (estimate weight, position entropy, orientation entropy)."""
    n = poses.shape[0]
    bounds = np.empty(3)
    for axis in range(3):
        bounds[axis] = roughening[axis] * SQRT3
    resample_with_jitter(weights, keep, scratch, bounds, poses, trig, draws[0], draws[1], counts, np.empty((3, 0)))
    for i in range(n - keep):
        for axis in range(3):
            poses[keep + i, axis] = injected[i, axis]
    log_weights[:] = -math.log(n)
    weights[:] = 1.0 / n
    return summarize(poses, weights, summary, fast)


@numba.njit(cache=True)
def summarize(source, weights, summary, fast):
    """The end of a step on one thread: the summary histograms (of `source`, or of the coordinates the
    resampling wrote when it has no rows), the estimate when `want_estimate` (moving `previous` to it) and the
    entropy when `want_entropy`. Returns (estimate weight, position entropy, orientation entropy)."""
    (grid, coordinates, histograms, bitmaps, want_estimate, previous, use_previous, out_mean, out_cov, want_entropy) = (
        summary
    )
    summary_fill(grid, source, weights, coordinates, histograms, bitmaps)
    weight = 0.0
    if want_estimate:
        if fast:
            weight = summary_estimate_fast(
                grid, coordinates, weights, histograms, bitmaps, previous, use_previous, out_mean, out_cov
            )
        else:
            weight = summary_estimate(
                grid, coordinates, weights, histograms, bitmaps, previous, use_previous, out_mean, out_cov
            )
        previous[:] = out_mean
    position = orientation = 0.0
    if want_entropy:
        position, orientation = summary_entropy(grid, histograms, bitmaps)
    return weight, position, orientation


@numba.njit(cache=True)
def block_trig(poses, start, count, trig, rows, fast):
    """rows[1:3, :count] = (cos, sin) of the headings of poses[start:start + count] (contiguous rows, for the
    sensor model's `score`), and the same into trig[start:start + count] (for the roughening); rows (3, ≥ count)
    scratch. fast: `sincos` compiled with fast-math (to rounding)."""
    for p in range(count):
        rows[0, p] = poses[start + p, 2]
    sincos_rows_as(rows[0], rows[1], rows[2], count, fast)
    for p in range(count):
        trig[start + p, 0] = rows[1, p]
        trig[start + p, 1] = rows[2, p]


def predict_and_score(poses, scratch, trig, log_likelihood, motion, draws, frame, work, start, stop, fast, since):
    """Particles start..stop moved (or copied) from `poses` into `scratch` a block at a time, cos and sin of
    their headings computed once (given to the scoring as contiguous rows, kept in `trig` for the roughening),
    and scored there while in cache by the sensor model's `score` (`sensing.fused`) into `log_likelihood`.
    since: (dx, dy, dθ) when the detections were captured earlier (copying only): the model scores each
    particle where it was at capture (`trig` keeps its heading now)."""
    move, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates = motion
    move_work = np.empty(MOVE_WORK)
    rows = np.empty((3, STEP_BLOCK))
    for block in range(start, stop, STEP_BLOCK):
        end = min(block + STEP_BLOCK, stop)
        if not move:
            scratch[block:end] = poses[block:end]
        elif fast:
            move_range_fast(
                poses,
                scratch,
                block,
                end,
                (dx, dy, dtheta),
                (bound_x, bound_y, bound_theta),
                gaussian,
                variates,
                draws,
                move_work,
            )
        else:
            move_range(
                poses,
                scratch,
                block,
                end,
                (dx, dy, dtheta),
                (bound_x, bound_y, bound_theta),
                gaussian,
                variates,
                draws,
                move_work,
            )
        block_trig(scratch, block, end - block, trig, rows, fast)
        score(scratch, rows[1:3], block, end - block, work, since, fast, frame, log_likelihood)


def predict_and_score_chunked(poses, scratch, trig, log_likelihood, motion, frame, chunk, fast, since):
    """`predict_and_score` of all particles, the chunks on several threads (the noise drawn beforehand)."""
    n = poses.shape[0]
    no_draws = (0, 0)
    for t in numba.prange(max(1, (n + chunk - 1) // chunk)):
        work = workspace(frame, min(chunk, STEP_BLOCK))
        predict_and_score(
            poses,
            scratch,
            trig,
            log_likelihood,
            motion,
            no_draws,
            frame,
            work,
            t * chunk,
            min(n, (t + 1) * chunk),
            fast,
            since,
        )


@numba.njit(cache=True, parallel=True)
def _fill_chunked(first, first_value, second, second_value, chunk):
    n = first.shape[0]
    for t in numba.prange(max(1, (n + chunk - 1) // chunk)):
        first[t * chunk : min(n, (t + 1) * chunk)] = first_value
        second[t * chunk : min(n, (t + 1) * chunk)] = second_value


@numba.njit(cache=True, parallel=True)
def _copy_chunked(source, out, chunk):
    n = source.shape[0]
    for t in numba.prange(max(1, (n + chunk - 1) // chunk)):
        out[t * chunk : min(n, (t + 1) * chunk)] = source[t * chunk : min(n, (t + 1) * chunk)]


@numba.njit(cache=True)
def _weigh(log_weights, log_likelihood, count, weights, chunk, fast):
    if chunk > 0:
        return weigh_chunked(log_weights, log_likelihood, count, weights, chunk)
    if fast:
        return weigh_fast(log_weights, log_likelihood, count, weights)
    return weigh(log_weights, log_likelihood, count, weights)


@numba.njit(cache=True)
def _resample(particles, draws, resampling, variates, coordinates, chunk):
    """Systematic resampling with roughening from `scratch` into `poses` (and the summary's `coordinates`),
    uniform weights; returns the ESS."""
    poses, log_weights, weights, _, scratch, trig, counts, _ = particles
    _, _, roughening, state_rows, state_scratch = resampling
    n = poses.shape[0]
    bounds = np.empty(3)
    for axis in range(3):
        bounds[axis] = roughening[axis] * SQRT3
    if chunk > 0:
        resample_with_jitter_chunked(
            weights,
            n,
            scratch,
            bounds,
            poses,
            trig,
            draws[0],
            draws[1],
            counts,
            coordinates,
            variates.reshape(-1),
            chunk,
        )
        _fill_chunked(log_weights, -math.log(n), weights, 1.0 / n, chunk)
    else:
        u0 = resample_with_jitter(weights, n, scratch, bounds, poses, trig, draws[0], draws[1], counts, coordinates)
        if state_rows.shape[0] > 0:
            gather_offspring_rows(weights, n, u0, counts, state_rows, state_scratch)
        log_weights[:] = -math.log(n)
        weights[:] = 1.0 / n
    return float(n)


def compiled_step(particles, motion, draws, sensor, weighting, resampling, summary, chunk, fast, since):
    """predict (when `move`), the sensor model's likelihood, the weight update, augmented MCL's rates, systematic
    resampling with roughening, the summary histograms, the estimate and (when `want_entropy`) the entropy, as
    ParticleFilter.predict, correct and entropy compute them (the groups: see the module docstring). Returns
    (status, native log average, ESS, w_slow, w_fast, injection share, resampled, estimate weight, position
    entropy, orientation entropy: zero unless computed); with an estimate, `previous` becomes its mean.

    The particles are moved (or copied) block by block into `scratch` and scored there while they are in
    cache, with cos and sin of their headings kept in `trig` for the roughening; resampling then copies from
    `scratch` into `poses`, and without resampling `scratch` is copied back. variates: the Gaussian motion
    noise drawn beforehand; for uniform noise, no rows (drawn here), or with `chunk` a (N, 3) scratch.
    state_rows: a stateful motion model's per-particle state as rows (no rows: none), which resampling gathers
    from the ancestors through `state_scratch` (`mcl.resampling.gather_offspring_rows`; one thread only: with
    `chunk`, a filter with such state passes can_resample False and resamples in Python).

    chunk > 0: the threads variant. The particles go through the stages in chunks of `chunk` spread over
    threads, and every sum is taken chunk by chunk (`mcl.weights.weigh_chunked`,
    `mcl.resampling.resample_with_jitter_chunked`, `mcl.estimate.summary_estimate_chunked`): the same
    results for any number of threads, equal to the serial ones to rounding. `local`: the threads' fixed-point
    histograms (`mcl.estimate.summary_fill_chunked`).
    fast: sin, cos and exp by vectorized polynomials and the sums of the weights and of the estimate
    reassociated; the same draws, results equal to rounding.
    since: (dx, dy, dθ), the robot's motion since the detections were captured (no rows: captured now, or a
    predict): each particle is scored moved back by it, and resampled where it is now.
    """
    poses, log_weights, weights, log_likelihood, scratch, trig, counts, local = particles
    move, gaussian, variates = motion[0], motion[7], motion[8]
    params, inputs = sensor
    count, terms, augmented, alpha_slow, alpha_fast, ratio_threshold, fit_threshold, w_slow, w_fast, cap = weighting
    resample_threshold, can_resample = resampling[0], resampling[1]
    n = poses.shape[0]
    frame, missing = prepare(inputs, params)
    if missing >= 0:
        return STEP_MISSING, 0.0, 0.0, w_slow, w_fast, 0.0, False, 0.0, 0.0, 0.0
    if chunk > 0:
        if move and not gaussian:
            parallel_uniforms(draws[0], draws[1], variates.reshape(-1), 3 * n)
        predict_and_score_chunked(poses, scratch, trig, log_likelihood, motion, frame, chunk, fast, since)
    else:
        work = workspace(frame, min(n, STEP_BLOCK))
        predict_and_score(poses, scratch, trig, log_likelihood, motion, draws, frame, work, 0, n, fast, since)
    valid, native, log_evidence, ess = _weigh(log_weights, log_likelihood, count, weights, chunk, fast)
    if not valid or log_evidence == -np.inf:
        if move:
            poses[:, :] = scratch
        return (STEP_INVALID if not valid else STEP_UNEXPLAINED, native, 0.0, w_slow, w_fast, 0.0, False, 0.0, 0.0, 0.0)
    fraction = 0.0
    if augmented and terms > 0:
        w_slow, w_fast, fraction = augmented_update(
            w_slow, w_fast, native / terms, alpha_slow, alpha_fast, ratio_threshold, fit_threshold
        )
    # `Injection.count`: round(min(fraction, cap)·N) > 0, i.e. the product exceeds one half.
    inject = augmented and (cap if cap < fraction else fraction) * n > 0.5
    resample = ess < resample_threshold * n
    if inject or (resample and not can_resample):
        if move:
            poses[:, :] = scratch
        return STEP_RESAMPLE, native, ess, w_slow, w_fast, fraction, False, 0.0, 0.0, 0.0
    if resample:
        ess = _resample(particles, draws, resampling, variates, summary[1], chunk)
        source = NO_VARIATES  # the coordinates were written by the resampling
    else:
        if move:
            if chunk > 0:
                _copy_chunked(scratch, poses, chunk)
            else:
                poses[:, :] = scratch
        if chunk > 0:
            reweigh_chunked(log_weights, log_likelihood, log_evidence, chunk)
        else:
            reweigh(log_weights, log_likelihood, log_evidence)
        source = poses
    if chunk > 0:
        (
            grid,
            coordinates,
            histograms,
            bitmaps,
            want_estimate,
            previous,
            use_previous,
            out_mean,
            out_cov,
            want_entropy,
        ) = summary
        summary_fill_chunked(grid, source, weights, coordinates, histograms, bitmaps, local, chunk)
        weight = 0.0
        if want_estimate:
            weight = summary_estimate_chunked(
                grid, coordinates, weights, histograms, bitmaps, previous, use_previous, out_mean, out_cov, chunk
            )
            previous[:] = out_mean
        position = orientation = 0.0
        if want_entropy:
            position, orientation = summary_entropy(grid, histograms, bitmaps)
    else:
        weight, position, orientation = summarize(source, weights, summary, fast)
    return STEP_DONE, native, ess, w_slow, w_fast, fraction, resample, weight, position, orientation


# -- one compiled step per kind of sensor model ---------------------------------------------------------------------
class StepKernels(NamedTuple):
    """The compiled step for one kind of sensor model (`fused_step`)."""

    key: str
    compiled_step: Callable[..., Any]  # numba dispatchers
    predict_and_score: Callable[..., Any]
    predict_and_score_chunked: Callable[..., Any]


_STEPS: dict[str, StepKernels] = {}


def _kernel_key(kernels) -> str:
    """The kernels' qualified names and a hash of their bytecode: the name their compiled step is cached under."""
    digest = hashlib.sha256()
    names = []
    for kernel in (kernels.prepare, kernels.workspace, kernels.score):
        function = getattr(kernel, "py_func", None)
        if function is None:
            raise TypeError(f"{kernel!r} must be a numba.njit function (the fused step calls it from compiled code)")
        names.append(f"{function.__module__}.{function.__qualname__}")
        digest.update(function.__code__.co_code)
        digest.update(repr(function.__code__.co_consts).encode())
    return f"{names[2]}.{digest.hexdigest()[:12]}"


def fused_step(kernels) -> StepKernels:
    """The fused compiled step with `kernels` (`sensing.fused.FusedLikelihoodKernels`) bound: made once per
    kind of model and process, compiled once per machine (cached)."""
    key = _kernel_key(kernels)
    step = _STEPS.get(key)
    if step is None:
        names = {"prepare": kernels.prepare, "workspace": kernels.workspace, "score": kernels.score}
        names["predict_and_score"] = variant(predict_and_score, key, names)
        names["predict_and_score_chunked"] = variant(predict_and_score_chunked, key, names, parallel=True)
        step = _STEPS[key] = StepKernels(
            key, variant(compiled_step, key, names), names["predict_and_score"], names["predict_and_score_chunked"]
        )
    return step
