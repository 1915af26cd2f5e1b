"""The filter step in plain numpy, and the compiled step phase by phase: what the benchmark times.

    from benchmarks.reference import PHASES, numpy_step, compiled_phases, full_step, issue_shaped_step

    numpy_step(pf, u, observations, timings)     # the step in plain numpy, on a copy of pf's particles
    work = compiled_phases(pf, u, observations)  # {phase: callable}, the compiled step cut into its stages
    for name in PHASES:
        work[name]()                             # in this order; together one step that always resamples
    full_step(pf, u, observations)               # pf.step(u, observations) and pf.entropy(): one dispatch
    issue_shaped_step(pf, u, observations)()     # the C reference's shape: no roughening, no estimate
    sample_injection_reference(pf, count, observations)   # augmented MCL's injected poses, in numpy

`numpy_step` calls the numpy twin of each kernel the filter uses; with the same generator state its
results agree with the filter's to rounding (the draws are the same, in the same order).

`compiled_phases` calls, one dispatch each, the kernels that `mcl.step.compiled_step` runs in a single
dispatch, on the filter's own buffers and with its options (`fast`, `threads`): predict (moving the particles
into the scratch copy the likelihood scores), likelihood (and cos, sin of the headings for the roughening),
normalize (+ ESS and augmented MCL's average), resample (systematic, the copy and the roughening in one pass),
estimate (the shared histograms and the dominant cluster), entropy. Their sum is the fused step plus six
dispatches (about 1 µs each).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numba
import numpy as np

from mcl.contracts import fused_kernels
from mcl.estimate import (
    summary_entropy,
    summary_estimate,
    summary_estimate_chunked,
    summary_estimate_fast,
    summary_fill,
    summary_fill_chunked,
)
from mcl.reference import gather_with_jitter as gather_with_jitter_reference
from mcl.reference import normalize as normalize_reference
from mcl.reference import summary_entropy as summary_entropy_reference
from mcl.reference import summary_estimate as summary_estimate_reference
from mcl.reference import systematic as systematic_reference
from mcl.resampling import resample_with_jitter, resample_with_jitter_chunked, systematic_counted
from mcl.step import NO_SINCE, STEP_BLOCK, fused_step
from mcl.weights import weigh, weigh_chunked, weigh_fast
from motion_models.base import MotionInput
from motion_models.kernels import NO_WORK, move_chunked, move_range, move_range_fast
from motion_models.reference import move_with_noise as move_with_noise_reference
from numerics.compile import variant
from numerics.random import draw_variates, next_double, parallel_uniforms
from numerics.trig import SQRT3
from sensing.observations import Observations

PHASES = ("predict", "likelihood", "normalize", "resample", "estimate", "entropy")


def numpy_step(pf, u: MotionInput, observations: Observations, timings: dict | None = None) -> dict:
    """One full step on a copy of `pf`'s particles, in numpy: predict, likelihood, normalize + ESS,
    systematic resampling, estimate, entropy. Uses (and advances) `pf.rng`. Returns the results; adds the
    seconds of each phase to `timings` when given."""
    clock = time.perf_counter
    marks = [clock()]
    poses = pf.poses.copy()
    bounds = pf.motion_model.noise_bounds(u)
    gaussian = pf.motion_model.gaussian
    move_with_noise_reference(poses, *u.displacement(), *bounds, gaussian, draw_variates(pf.rng, pf.n, gaussian))
    marks.append(clock())
    log_likelihood = pf.sensor_model.numpy_twin().log_likelihood(poses, observations)
    marks.append(clock())
    weights, log_total, ess = normalize_reference(pf.log_weights + log_likelihood)
    marks.append(clock())
    ancestors = systematic_reference(weights, pf.n, pf.rng)
    poses = gather_with_jitter_reference(
        poses, ancestors, pf.roughening * np.sqrt(3.0), draw_variates(pf.rng, pf.n, False)
    )
    weights = np.full(pf.n, 1.0 / pf.n)
    marks.append(clock())
    mean, cov, cluster_weight = summary_estimate_reference(pf.summary, poses, weights)
    marks.append(clock())
    entropy = summary_entropy_reference(pf.summary, poses, weights)
    marks.append(clock())
    if timings is not None:
        for name, a, b in zip(PHASES, marks[:-1], marks[1:]):
            timings[name] = timings.get(name, 0.0) + (b - a)
    return {
        "poses": poses,
        "log_likelihood": log_likelihood,
        "ess": ess,
        "log_total": log_total,
        "mean": mean,
        "covariance": cov,
        "cluster_weight": cluster_weight,
        "entropy": entropy,
    }


# -- the issue's step shape ----------------------------------------------------------------------------------------
# The C reference the performance issue measures (about 53 ns per particle without atan2, 18 with -ffast-math)
# runs predict, 10 detections of a 4-way ambiguous type, normalize, ESS, systematic resampling and the grid
# entropy. The filter's step does two things more: it roughens the resampled particles (three more draws and a
# jitter each) and it computes the estimate (the dominant cluster by mean shift). `issue_shaped_step` runs the
# reference's shape with the filter's own kernels, so that the two can be compared like with like; the
# benchmark reports it beside the full step, never instead of it.


@numba.njit(cache=True)
def _resample_copy(weights, source, out, coordinates, ancestors, counts, u0):
    """Systematic resampling of all N particles from `source` into `out` (and the rows of `coordinates`): the
    ancestors by `mcl.resampling`'s counting, then a plain copy (no roughening). counts (N + 1,) zero on entry
    and on return; ancestors (N,) scratch."""
    systematic_counted(weights, weights.shape[0], u0, ancestors, counts)
    for k in range(ancestors.shape[0]):
        j = ancestors[k]
        for axis in range(3):
            out[k, axis] = source[j, axis]
            coordinates[axis, k] = source[j, axis]


# Bound by `numerics.compile.variant` in the template below: the sensor model's kernels and its fused step's
# predict_and_score.
prepare = workspace = predict_and_score = None


def _issue_shaped_kernel(
    poses,
    scratch,
    trig,
    log_likelihood,
    log_weights,
    weights,
    ancestors,
    counts,
    motion,
    draws,
    params,
    inputs,
    grid,
    coordinates,
    histograms,
    bitmaps,
    fast,
):
    """(A template: `issue_shaped_step` compiles it with the sensor model's kernels bound,
    `numerics.compile.variant`.)"""
    n = poses.shape[0]
    frame, _ = prepare(inputs, params)
    work = workspace(frame, min(n, STEP_BLOCK))
    predict_and_score(poses, scratch, trig, log_likelihood, motion, draws, frame, work, 0, n, fast, np.empty(0))
    if fast:
        _, _, _, ess = weigh_fast(log_weights, log_likelihood, n, weights)
    else:
        _, _, _, ess = weigh(log_weights, log_likelihood, n, weights)
    _resample_copy(weights, scratch, poses, coordinates, ancestors, counts, next_double(draws[0], draws[1]))
    log_weights[:] = -math.log(n)
    weights[:] = 1.0 / n
    summary_fill(grid, np.empty((0, 3)), weights, coordinates, histograms, bitmaps)
    position, orientation = summary_entropy(grid, histograms, bitmaps)
    return ess, position, orientation


def sample_injection_reference(pf, count: int, observations: Observations) -> np.ndarray:
    """Plain numpy twin of `ParticleFilter._sample_injection` (augmented MCL's injected poses): the same draws
    from `pf.rng`, the same poses bit for bit, with the sensor model's `numpy_twin().sample_poses`."""
    return pf.relocalization.propose(count, observations, pf.sensor_model, pf.rng, reference=True)


def issue_shaped_step(pf, u: MotionInput, observations: Observations) -> Callable[[], tuple]:
    """The performance issue's step shape on `pf`'s particles and buffers, one dispatch per call: predict
    (uniform noise drawn in the kernel), the landmark likelihood, normalize + ESS, systematic resampling of
    every particle (a plain copy: no roughening), the grid entropy. No estimate. The motion input is turned into
    numbers once; the detections' constants are prepared from the batch's arrays in every call, as the
    filter's step prepares them. Returns a callable giving (ESS before resampling, position entropy,
    orientation entropy). Needs what `compiled_phases` needs, with uniform motion noise, one thread."""
    motion = pf.engine.motion(pf.motion_model, u)
    sensor = fused_kernels(pf.sensor_model)
    if motion is None or sensor is None or pf.motion_model.gaussian or pf.threads > 1:
        raise ValueError(
            "issue_shaped_step needs a bounded uniform-noise motion model, a sensor model with "
            "fused_likelihood() and one thread"
        )
    observations = Observations.coerce(observations)
    pf.sensor_model.check(observations)
    fused = fused_step(sensor)
    kernel = variant(
        _issue_shaped_kernel,
        fused.key,
        {"prepare": sensor.prepare, "workspace": sensor.workspace, "predict_and_score": fused.predict_and_score},
    )
    inputs = sensor.inputs(observations)
    summary, p = pf.summary, pf.particles
    coordinates, histograms, bitmaps = summary.coordinates, summary.histograms, summary.bitmaps
    ancestors, counts = np.empty(pf.n, dtype=np.int64), np.zeros(pf.n + 1, dtype=np.int64)
    moving = (True, *motion, False, np.empty((0, 3)))

    def step():
        summary.changed()
        return kernel(
            pf.poses,
            p.previous,
            p.trig,
            p.log_likelihood,
            pf.log_weights,
            p.weights,
            ancestors,
            counts,
            moving,
            pf.engine.generator(pf.rng),
            sensor.params,
            inputs,
            summary.parameters,
            coordinates,
            histograms,
            bitmaps,
            pf.fast,
        )

    return step


def full_step(pf, u: MotionInput, observations: Observations):
    """The fused step through the public calls: `pf.step(u, observations)` (predict, correct, resampling when
    the ESS asks for it, estimate: one dispatch into compiled code) and `pf.entropy()`."""
    estimate = pf.step(u, observations)
    return estimate, pf.entropy()


def compiled_phases(pf, u: MotionInput, observations: Observations) -> dict[str, Callable[[], object]]:
    """The compiled step's stages as separate calls on `pf` (see the module docstring); call them in the
    order of PHASES. Needs what the fused step needs: a bounded-noise motion model (velocity-linear,
    constant) and a sensor model with `fused_likelihood` (the landmark model with the max-mixture); it
    resamples every time (the benchmark's setting, `resample_threshold=1`)."""
    motion = pf.engine.motion(pf.motion_model, u)
    sensor = fused_kernels(pf.sensor_model)
    if motion is None or sensor is None:
        raise ValueError(
            "compiled_phases needs a bounded-noise motion model and a sensor model with fused_likelihood()"
        )
    observations = Observations.coerce(observations)
    pf.sensor_model.check(observations)
    fused = fused_step(sensor)
    n = pf.n
    gaussian = bool(pf.motion_model.gaussian)
    chunk = pf.engine.chunk
    scope = pf.engine.scope
    p = pf.particles
    scratch = p.previous
    summary = pf.summary
    coordinates, histograms, bitmaps = summary.coordinates, summary.histograms, summary.bitmaps
    grid = pf.summary.parameters
    mean = np.empty(3)
    covariance = np.empty((3, 3))
    no_variates = np.empty((0, 3))

    def predict():
        function, generator = pf.engine.generator(pf.rng)
        variates = no_variates
        if gaussian:
            variates = draw_variates(pf.rng, n, True, out=p.variates)
        if chunk:
            with scope:
                if not gaussian:
                    variates = p.variates
                    parallel_uniforms(function, generator, variates.reshape(-1), 3 * n)
                scratch[:] = pf.poses
                move_chunked(scratch, *motion, gaussian, variates, chunk)
        elif pf.fast:
            move_range_fast(
                pf.poses, scratch, 0, n, motion[:3], motion[3:], gaussian, variates, (function, generator), NO_WORK
            )
        else:
            move_range(
                pf.poses, scratch, 0, n, motion[:3], motion[3:], gaussian, variates, (function, generator), NO_WORK
            )
        pf.relocalization.carry(motion[0], motion[1], motion[2])
        pf.summary.changed()

    def likelihood():
        frame, _ = sensor.prepare(sensor.inputs(observations), sensor.params)
        copying = (False, *motion, False, no_variates)
        if chunk:
            with scope:
                fused.predict_and_score_chunked(
                    scratch, scratch, p.trig, p.log_likelihood, copying, frame, chunk, pf.fast, NO_SINCE
                )
        else:
            work = sensor.workspace(frame, min(n, STEP_BLOCK))
            fused.predict_and_score(
                scratch, scratch, p.trig, p.log_likelihood, copying, (0, 0), frame, work, 0, n, pf.fast, NO_SINCE
            )

    def normalize():
        count = n - pf.injected
        if chunk:
            with scope:
                valid, native, log_total, ess = weigh_chunked(pf.log_weights, p.log_likelihood, count, p.weights, chunk)
        elif pf.fast:
            valid, native, log_total, ess = weigh_fast(pf.log_weights, p.log_likelihood, count, p.weights)
        else:
            valid, native, log_total, ess = weigh(pf.log_weights, p.log_likelihood, count, p.weights)
        if len(observations) > 0:
            pf.frame_fit = math.exp(native / len(observations))
        return ess

    def resample():
        bounds = pf.roughening * SQRT3
        function, generator = pf.engine.generator(pf.rng)
        if chunk:
            with scope:
                resample_with_jitter_chunked(
                    p.weights,
                    n,
                    scratch,
                    bounds,
                    pf.poses,
                    p.trig,
                    function,
                    generator,
                    p.counts,
                    coordinates,
                    p.variates.reshape(-1),
                    chunk,
                )
        else:
            resample_with_jitter(
                p.weights, n, scratch, bounds, pf.poses, p.trig, function, generator, p.counts, coordinates
            )
        pf.log_weights[:] = -math.log(n)
        p.weights[:] = 1.0 / n
        pf.ess = float(n)
        pf.resampled = True
        pf.injected = 0
        pf.summary.changed()

    def estimate():
        previous = pf.summary.previous
        use_previous = pf.summary.has_previous
        if chunk:
            with scope:
                summary_fill_chunked(
                    grid, no_variates, p.weights, coordinates, histograms, bitmaps, pf.summary.local, chunk
                )
                weight = summary_estimate_chunked(
                    grid, coordinates, p.weights, histograms, bitmaps, previous, use_previous, mean, covariance, chunk
                )
        else:
            summary_fill(grid, no_variates, p.weights, coordinates, histograms, bitmaps)
            kernel = summary_estimate_fast if pf.fast else summary_estimate
            weight = kernel(grid, coordinates, p.weights, histograms, bitmaps, previous, use_previous, mean, covariance)
        previous[:] = mean
        pf.summary.has_previous = True
        pf.summary.valid = True
        return weight

    def entropy():
        return summary_entropy(grid, histograms, bitmaps)

    return {
        "predict": predict,
        "likelihood": likelihood,
        "normalize": normalize,
        "resample": resample,
        "estimate": estimate,
        "entropy": entropy,
    }
