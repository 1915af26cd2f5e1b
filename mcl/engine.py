"""The engine that runs the filter's stages on its particles: chosen when the filter is built.

    from mcl.engine import Engine
    engine = Engine(particles, summary, threads=1, fast=False)     # what ParticleFilter builds
    engine.predict(motion_model, u, rng)
    log_likelihood = engine.likelihood(sensor_model, observations, since)
    valid, native, log_evidence, ess = engine.weigh(log_likelihood, count)
    engine.reweigh(log_likelihood, log_evidence)
    engine.resample("systematic", injected, roughening, rng)
    estimate, entropy = engine.estimate(), engine.entropy()

`mcl.ParticleFilter` writes the algorithm (predict, weigh, resample, inject, summarize) and calls its engine
for each stage; the engine knows how the stages run: in the compiled kernels of `mcl.weights`,
`mcl.resampling`, `mcl.estimate` and `motion_models.kernels`, serial or in chunks over `threads` threads, with
or without fast-math (`fast`), options fixed when the engine is built. The stages are public so that a
benchmark can time them one by one on a filter's own buffers (`ParticleFilter.engine`).

When the models allow it (a bounded-noise motion model, `mcl.contracts.moves_by_bounded_noise`, and a sensor
model that offers compiled kernels, `mcl.contracts.fused_kernels`), the engine also runs predict, likelihood,
weights, resampling and the summary as one call into compiled code (`fused_step`, `mcl.step`), with the results
of the stages one by one bit for bit. `fuses` says whether a frame can be corrected that way: frames the
sensor model scores with its camera view (negative information) cannot.

`ReferenceEngine` runs the same stages in numpy (the twins of `mcl.reference`) and never fuses them:
`ParticleFilter(..., reference=True)`, slow, for reading and for tests that compare the compiled filter with it.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numba
import numpy as np

from field.checks import ArgumentTypeError
from motion_models.base import MotionInput
from motion_models.kernels import NO_WORK, move_chunked, move_range, move_range_fast
from motion_models.reference import move_with_noise as move_with_noise_reference
from numerics.chunks import balanced_chunk
from numerics.random import bit_generator_handle, draw_variates, parallel_uniforms
from numerics.trig import SQRT3
from sensing.observations import Observations

from . import reference
from .contracts import fused_kernels, moves_by_bounded_noise, numpy_twin
from .estimate import (
    summary_entropy,
    summary_estimate,
    summary_estimate_chunked,
    summary_estimate_fast,
    summary_fill,
    summary_fill_chunked,
)
from .latency import move_back
from .particles import Particles
from .resampling import SCHEMES, gather_offspring_rows, gather_with_jitter, resample_with_jitter
from .step import (
    NO_SINCE,
    NO_VARIATES,
    STEP_DONE,
    STEP_INVALID,
    STEP_MISSING,
    StepKernels,
    fused_step,
    resample_and_summarize,
    summarize,
)
from .summary import Entropy, Estimate, Summary
from .weights import reweigh, weigh

_CHUNK = 4096  # particles per chunk with threads > 1, about (`balanced_chunk`: a function of N alone, so the
# results do not depend on the threads)
_NO_TRIG = np.empty((0, 2))
_NO_COORDINATES = np.empty((3, 0))
_NO_MOTION = (0.0,) * 6
_NO_MEAN, _NO_COVARIANCE = np.empty(3), np.empty((3, 3))  # out_mean, out_cov of a summary without estimate


class _Threads:
    """Run numba's parallel kernels on `threads` threads inside the block (at most NUMBA_NUM_THREADS); an engine
    on one thread runs no parallel kernel, and its block sets nothing."""

    def __init__(self, threads: int) -> None:
        self.active = threads > 1
        self.threads = min(threads, numba.config.NUMBA_NUM_THREADS)
        self.previous = self.threads

    def __enter__(self) -> None:
        if self.active:
            self.previous = numba.get_num_threads()
            if self.previous != self.threads:
                numba.set_num_threads(self.threads)

    def __exit__(self, *exc) -> None:
        if self.active and self.previous != self.threads:
            numba.set_num_threads(self.previous)


class FusedOutcome(NamedTuple):
    """What `Engine.fused_step` computed (see `mcl.step.compiled_step`)."""

    status: int  # one of `mcl.step`'s STEP_* codes
    native_log_average: float
    ess: float
    w_slow: float
    w_fast: float
    fraction: float  # the injection share augmented MCL asks for
    resampled: bool


class Engine:
    """Runs the filter's stages on `particles` and `summary` (see the module docstring).

    Parameters
    ----------
    particles : Particles
        The filter's particle set: the arrays the stages work in.
    summary : Summary
        The filter's summary: the histograms, the cached estimate and entropy.
    threads : int, default 1
        1: every stage on one thread. More: the stages spread chunks of particles over that many threads and
        take their sums chunk by chunk (`mcl.ParticleFilter`'s `threads`).
    fast : bool, default False
        Compile options with fast-math (`mcl.ParticleFilter`'s `fast`).
    """

    reference = False  # whether the stages run in numpy (`ReferenceEngine`)

    def __init__(self, particles: Particles, summary: Summary, threads: int = 1, fast: bool = False) -> None:
        self.particles = particles
        self.summary = summary
        self.threads = threads
        self.fast = fast
        self.chunk = int(balanced_chunk(particles.n, _CHUNK)) if threads > 1 else 0
        self.scope = _Threads(threads)
        p = particles
        # the compiled step's particle arguments (`mcl.step`), the same arrays for the engine's life
        self._group = (p.poses, p.log_weights, p.weights, p.log_likelihood, p.previous, p.trig, p.counts, summary.local)
        self._handle: tuple | None = None  # (bit generator, its kernel handle)
        self._bounded_of: Any = None  # the motion model `_bounded` was asked of
        self._bounded = False  # whether it moves as BoundedNoiseModel does
        self._sensor_of: Any = None  # the sensor model `_kernels` were asked of
        self._kernels: Any = None  # its `FusedLikelihoodKernels`, or None
        self._step: StepKernels | None = None  # `mcl.step.fused_step` of those kernels

    def __getstate__(self) -> dict:
        # Pickles and deep copies leave out the generator's kernel handle: it holds the addresses of the
        # filter's bit generator, and a copy that kept them would draw from (and advance) the original's.
        # The sensor model's compiled kernels are asked for again (a copy's sensor model is a copy too).
        state = self.__dict__.copy()
        state["_handle"] = state["_sensor_of"] = state["_kernels"] = state["_step"] = None
        return state

    def generator(self, rng: np.random.Generator) -> tuple[int, int]:
        """The handle of `rng` for drawing in kernels (`numerics.random.bit_generator_handle`)."""
        bit_generator = rng.bit_generator
        handle = self._handle
        if handle is None or handle[0] is not bit_generator:
            handle = self._handle = (bit_generator, *bit_generator_handle(rng))
        return handle[1], handle[2]

    # -- predict -------------------------------------------------------------------------------------------------
    def motion(self, motion_model: Any, u: MotionInput) -> tuple[float, ...] | None:
        """Check `u` by the motion model; return (dx, dy, dθ, bound_x, bound_y, bound_θ) when the model moves as
        `BoundedNoiseModel` does (displacement plus bounded robot-frame noise) and keeps no per-particle state,
        so that the engine's kernels move the particles themselves, else None."""
        if not isinstance(u, MotionInput):
            raise ArgumentTypeError(f"u = {u!r} must be a motion_models.MotionInput, not {type(u).__name__}")
        if motion_model is not self._bounded_of:  # (asked once per motion model: this runs every step)
            self._bounded = moves_by_bounded_noise(motion_model)
            self._bounded_of = motion_model
        if self.particles.motion_state is not None or not self._bounded:
            motion_model.check(u)
            return None
        dx, dy, dtheta = u.displacement()  # BoundedNoiseModel.check
        bound_x, bound_y, bound_theta = motion_model.noise_bounds(u)
        return float(dx), float(dy), float(dtheta), float(bound_x), float(bound_y), float(bound_theta)

    def predict(
        self, motion_model: Any, u: MotionInput, rng: np.random.Generator, motion: tuple[float, ...] | None = None
    ) -> None:
        """Move every particle by the motion model (by `motion`, `Engine.motion`'s answer for `u`, when given),
        with the noise drawn from `rng`."""
        p = self.particles
        if motion is None:
            if p.motion_state is None:
                motion_model.predict(p.poses, u, rng)
            else:
                motion_model.predict(p.poses, u, rng, state=p.motion_state)
            return
        gaussian = bool(motion_model.gaussian)
        variates = draw_variates(rng, p.n, True, out=p.variates) if gaussian else NO_VARIATES
        if self.threads > 1:
            with self.scope:
                if not gaussian:
                    variates = p.variates
                    parallel_uniforms(*self.generator(rng), variates.reshape(-1), 3 * p.n)
                move_chunked(p.poses, *motion, gaussian, variates, self.chunk)
        else:
            move = move_range_fast if self.fast else move_range
            move(p.poses, p.poses, 0, p.n, motion[:3], motion[3:], gaussian, variates, self.generator(rng), NO_WORK)

    # -- weigh ---------------------------------------------------------------------------------------------------
    def likelihood(self, sensor_model: Any, observations: Observations, since: np.ndarray | None) -> np.ndarray:
        """The sensor model's log-likelihood of each particle (where it was at capture, moved back along
        `since`, when given), in the particles' buffer."""
        p = self.particles
        scored = p.poses
        if since is not None:
            move_back(p.poses, since, p.capture_poses)
            scored = p.capture_poses
        return np.asarray(sensor_model.log_likelihood(scored, observations, out=p.log_likelihood), dtype=np.float64)

    def weigh(self, log_likelihood: np.ndarray, count: int) -> tuple[bool, float, float, float]:
        """The weight update's sums (`mcl.weights.weigh`) into the normalized weights: (valid, native log
        average over the first `count` particles, log evidence, ESS); the log-weights are left as they are."""
        p = self.particles
        return weigh(p.log_weights, log_likelihood, count, p.weights)

    def reweigh(self, log_likelihood: np.ndarray, log_evidence: float) -> None:
        """The normalized posterior log-weights: log_weights + log_likelihood - log_evidence."""
        reweigh(self.particles.log_weights, log_likelihood, log_evidence)

    # -- resample ------------------------------------------------------------------------------------------------
    def resample(self, scheme: str, injected: np.ndarray, roughening: np.ndarray, rng: np.random.Generator) -> None:
        """Draw N - len(injected) particles by `scheme` (`mcl.resampling.SCHEMES`) from the weights, roughened
        by uniform jitter of standard deviations `roughening` in each particle's own frame, then `injected` with
        fresh motion state; equal weights."""
        p = self.particles
        keep = p.n - injected.shape[0]
        p.previous[:] = p.poses
        bounds = roughening * SQRT3
        if scheme == "systematic":
            u0 = resample_with_jitter(
                p.weights, keep, p.previous, bounds, p.poses, _NO_TRIG, *self.generator(rng), p.counts, _NO_COORDINATES
            )
            if p.motion_state is not None:
                gather_offspring_rows(p.weights, keep, u0, p.counts, p.state_rows, p.state_scratch)
        else:
            ancestors = SCHEMES[scheme](p.weights, keep, rng)
            gather_with_jitter(p.previous, ancestors, bounds, draw_variates(rng, keep, False, out=p.variates), p.poses)
            if p.motion_state is not None:
                p.motion_state[:keep] = p.motion_state[ancestors]
        p.take_injected(keep, injected)

    # -- summarize -----------------------------------------------------------------------------------------------
    def fill(self) -> None:
        """The summary's histograms of the particles as they are, unless they are already."""
        s, p = self.summary, self.particles
        if not s.valid:
            if self.threads > 1:
                with self.scope:
                    summary_fill_chunked(
                        s.parameters, p.poses, p.weights, s.coordinates, s.histograms, s.bitmaps, s.local, self.chunk
                    )
            else:
                summary_fill(s.parameters, p.poses, p.weights, s.coordinates, s.histograms, s.bitmaps)
            s.valid = True

    def estimate(self) -> Estimate:
        """The summary's estimate (`mcl.estimate`: the dominant cluster), cached until the particles change."""
        s = self.summary
        if s.estimate is None:
            s.estimate = self._dominant_cluster()
            s.has_previous = True
        return s.estimate

    def entropy(self) -> Entropy:
        """The summary's grid entropy, cached until the particles change; from now on the compiled step
        computes it too."""
        s = self.summary
        s.entropy_wanted = True
        if s.entropy is None:
            s.entropy = self._grid_entropy()
        return s.entropy

    def _dominant_cluster(self) -> Estimate:
        """The dominant cluster of the particles as they are; the estimate's hysteresis anchor
        (`Summary.previous`) moves to it."""
        s, p = self.summary, self.particles
        mean, cov = np.empty(3), np.empty((3, 3))
        if self.threads == 1 and not s.valid:
            # One dispatch: the histograms, the estimate and (once asked for) the entropy.
            weight, position, orientation = summarize(p.poses, p.weights, s.group(True, mean, cov), self.fast)
            s.keep(None, position, orientation)
        else:
            self.fill()
            arguments = (s.parameters, s.coordinates, p.weights, s.histograms, s.bitmaps, s.previous, s.has_previous)
            if self.threads > 1:
                with self.scope:
                    weight = summary_estimate_chunked(*arguments, mean, cov, self.chunk)
            else:
                weight = (summary_estimate_fast if self.fast else summary_estimate)(*arguments, mean, cov)
            s.previous[:] = mean
        return Estimate(mean, cov, float(weight))

    def _grid_entropy(self) -> Entropy:
        """The grid entropy of the particles as they are."""
        s, p = self.summary, self.particles
        if self.threads == 1 and not s.valid:
            # One dispatch: the histograms and the entropy (no estimate: it would move the hysteresis anchor).
            _, position, orientation = summarize(
                p.poses,
                p.weights,
                s.group(False, _NO_MEAN, _NO_COVARIANCE, use_previous=False, want_entropy=True),
                self.fast,
            )
            s.valid = True
        else:
            self.fill()
            position, orientation = summary_entropy(s.parameters, s.histograms, s.bitmaps)
        return Entropy(float(position), float(orientation))

    # -- the fused step ------------------------------------------------------------------------------------------
    def fuses(self, sensor_model: Any, observations: Observations) -> bool:
        """Whether `fused_step` can correct by this frame: it has detections, the sensor model offers compiled
        kernels, and it does not score the frame's camera view (negative information)."""
        if len(observations) == 0:
            return False
        if sensor_model is not self._sensor_of:
            self._kernels = fused_kernels(sensor_model)
            self._step = None if self._kernels is None else fused_step(self._kernels)
            self._sensor_of = sensor_model
        if self._kernels is None:
            return False
        if observations.view is None:
            return True
        scores_view = getattr(sensor_model, "scores_view", None)
        return not (callable(scores_view) and bool(scores_view(observations)))

    def fused_step(
        self,
        motion_model: Any,
        motion: tuple[float, ...] | None,
        sensor_model: Any,
        observations: Observations,
        weighting: tuple,
        resampling: tuple,
        want_estimate: bool,
        since: np.ndarray | None,
        rng: np.random.Generator,
    ) -> FusedOutcome:
        """[predict by `motion` (`Engine.motion`),] likelihood, weights, augmented MCL's rates, resampling without
        injection and the summary in one call (`mcl.step.compiled_step`, after `fuses` said yes). `weighting`
        as `compiled_step` takes it; `resampling` (scheme, threshold, roughening). The summary keeps the
        estimate (when `want_estimate`) and the entropy it computed, when the step is done."""
        p, s = self.particles, self.summary
        kernels, step = self._kernels, self._step
        assert kernels is not None and step is not None  # `fuses` said yes
        move = motion is not None
        chunk = self.chunk
        gaussian = move and bool(motion_model.gaussian)
        variates = p.variates if chunk else NO_VARIATES
        if motion is None:
            motion = _NO_MOTION
        elif gaussian:
            sensor_model.check(observations)  # before the noise is drawn
            variates = draw_variates(rng, p.n, True, out=p.variates)
        scheme, threshold, roughening = resampling
        can_resample = scheme == "systematic" and (p.motion_state is None or not chunk)
        mean, covariance = np.empty(3), np.empty((3, 3))
        with self.scope:
            (status, native, ess, w_slow, w_fast, fraction, resampled, weight, position, orientation) = (
                step.compiled_step(
                    self._group,
                    (move, *motion, gaussian, variates),
                    self.generator(rng),
                    (kernels.params, kernels.inputs(observations)),
                    weighting,
                    (threshold, can_resample, roughening, p.state_rows, p.state_scratch),
                    s.group(want_estimate, mean, covariance),
                    chunk,
                    self.fast,
                    NO_SINCE if since is None else since,
                )
            )
        if status != STEP_MISSING and (move or status != STEP_INVALID):
            s.changed()  # the particles moved, or their weights changed
        if status == STEP_DONE:  # `previous` was moved to the estimate in the kernel
            s.keep(Estimate(mean, covariance, weight) if want_estimate else None, position, orientation)
        return FusedOutcome(status, native, ess, w_slow, w_fast, fraction, resampled)

    def resample_and_summarize(
        self, injected: np.ndarray, roughening: np.ndarray, want_estimate: bool, rng: np.random.Generator
    ) -> None:
        """After a fused step that asks for injection (one thread, systematic resampling): `resample` of the
        scored particles and the summary that follows, in one call into compiled code; the same draws and
        results as `resample` then `estimate` and `entropy`."""
        p, s = self.particles, self.summary
        mean, covariance = np.empty(3), np.empty((3, 3))
        weight, position, orientation = resample_and_summarize(
            p.weights,
            p.n - injected.shape[0],
            p.previous,
            roughening,
            p.poses,
            p.trig,
            self.generator(rng),
            p.counts,
            injected,
            p.log_weights,
            s.group(want_estimate, mean, covariance),
            self.fast,
        )
        s.changed()
        s.keep(Estimate(mean, covariance, weight) if want_estimate else None, position, orientation)

    def resamples_fused(self, scheme: str) -> bool:
        """Whether a fused step's injection can finish in `resample_and_summarize` (one thread, systematic
        resampling, no per-particle motion state)."""
        return self.threads == 1 and scheme == "systematic" and self.particles.motion_state is None


class ReferenceEngine(Engine):
    """The filter's stages in plain numpy, one by one: what `Engine` computes, with the same random draws in the
    same order and the same results to rounding. The weights, the resampling, the estimate and the entropy are
    the numpy twins of the kernels (`mcl.reference`); a bounded-noise motion model moves the particles by
    `motion_models.reference.move_with_noise`, and a sensor model that offers a numpy twin (`numpy_twin()`, whose
    `log_likelihood` scores them: the landmark and line models do); other models are called through their contracts
    (`predict`, `log_likelihood`). One thread, no fast-math, no fused step.

    Parameters
    ----------
    particles : Particles
        The filter's particle set: the arrays the stages work in.
    summary : Summary
        The filter's summary: the cached estimate and entropy (its histograms are not used).
    """

    reference = True

    def __init__(self, particles: Particles, summary: Summary) -> None:
        super().__init__(particles, summary, threads=1, fast=False)

    def predict(
        self, motion_model: Any, u: MotionInput, rng: np.random.Generator, motion: tuple[float, ...] | None = None
    ) -> None:
        """`Engine.predict` in numpy for a bounded-noise model (`motion`, `Engine.motion`'s answer, given: the
        variates the model's own `predict` draws, then `motion_models.reference.move_with_noise`); otherwise the
        motion model's own `predict`."""
        if motion is None:
            super().predict(motion_model, u, rng)
            return
        p = self.particles
        gaussian = bool(motion_model.gaussian)
        variates = draw_variates(rng, p.n, gaussian)
        dx, dy, dtheta, bound_x, bound_y, bound_theta = motion
        move_with_noise_reference(p.poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates)

    def likelihood(self, sensor_model: Any, observations: Observations, since: np.ndarray | None) -> np.ndarray:
        """`Engine.likelihood` in numpy: the particles moved back along `since` by `mcl.reference.move_back`, scored
        by the sensor model's numpy twin when it has one (`numpy_twin().log_likelihood`; else its `log_likelihood`)."""
        score = getattr(numpy_twin(sensor_model), "log_likelihood", None)
        if not callable(score):
            return super().likelihood(sensor_model, observations, since)
        p = self.particles
        scored = p.poses if since is None else reference.move_back(p.poses, since)
        p.log_likelihood[:] = score(scored, observations)
        return p.log_likelihood

    def fuses(self, sensor_model: Any, observations: Observations) -> bool:
        """Never: every stage is a call of its own."""
        return False

    def resamples_fused(self, scheme: str) -> bool:
        """Never: resampling and the summary are calls of their own."""
        return False

    def weigh(self, log_likelihood: np.ndarray, count: int) -> tuple[bool, float, float, float]:
        """`Engine.weigh` in numpy: (valid, native log average over the first `count`, log evidence, ESS)."""
        p = self.particles
        log_likelihood = np.asarray(log_likelihood, dtype=np.float64)
        if np.isnan(log_likelihood).any() or np.isposinf(log_likelihood).any():
            return False, 0.0, 0.0, 0.0
        native = reference.log_mean_likelihood(p.log_weights, log_likelihood, count)
        candidates = p.log_weights + log_likelihood
        if np.max(candidates) == -np.inf:
            return True, native, -np.inf, 0.0
        weights, log_evidence, ess = reference.normalize(candidates)
        p.weights[:] = weights
        return True, native, float(log_evidence), float(ess)

    def reweigh(self, log_likelihood: np.ndarray, log_evidence: float) -> None:
        """`Engine.reweigh` in numpy."""
        p = self.particles
        p.log_weights[:] = p.log_weights + log_likelihood - log_evidence

    def resample(self, scheme: str, injected: np.ndarray, roughening: np.ndarray, rng: np.random.Generator) -> None:
        """`Engine.resample` in numpy: the scheme's ancestors, then the roughening's jitter."""
        p = self.particles
        keep = p.n - injected.shape[0]
        ancestors = getattr(reference, scheme)(p.weights, keep, rng)
        previous = p.poses.copy()
        uniforms = draw_variates(rng, keep, False)
        p.poses[:keep] = reference.gather_with_jitter(previous, ancestors, roughening * SQRT3, uniforms)
        if p.motion_state is not None:
            p.motion_state[:keep] = p.motion_state[ancestors]
        p.take_injected(keep, injected)

    def _dominant_cluster(self) -> Estimate:
        """`Engine`'s dominant cluster in numpy (`mcl.reference.summary_estimate`); the hysteresis anchor moves
        to it."""
        mean, cov, weight = reference.summary_estimate(self.summary, self.particles.poses, self.particles.weights)
        self.summary.previous[:] = mean
        return Estimate(mean, cov, float(weight))

    def _grid_entropy(self) -> Entropy:
        """`Engine`'s grid entropy in numpy (`mcl.reference.summary_entropy`)."""
        position, orientation = reference.summary_entropy(self.summary, self.particles.poses, self.particles.weights)
        return Entropy(float(position), float(orientation))
