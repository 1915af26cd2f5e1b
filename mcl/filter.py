"""The particle filter: Monte Carlo localization on a soccer field.

    from field import spl
    from mcl import ParticleFilter
    from motion_models import MotionInput, VelocityLinear
    from sensing import LandmarkSensorModel, LandmarkObservation

    pf = ParticleFilter(spl(), VelocityLinear(), LandmarkSensorModel(spl()), n_particles=500, seed=0)
    pf.reset_uniform("own_half")
    pf.predict(MotionInput(dt=0.01, command=(0.2, 0.0, 0.0)))
    pf.correct([LandmarkObservation("goalpost", range=4.6, bearing=0.2)])
    est = pf.estimate()          # est.pose [x, y, θ], est.covariance (3, 3), est.weight
    h = pf.entropy()             # h.position, h.orientation in bits

The filter knows the motion and sensor models only through their contracts (`mcl.contracts`: `check`/`predict`,
`check`/`log_likelihood`, and the optional capabilities it uses when a model offers them). Every public call
validates its input before it changes anything: a rejected call raises ValueError and leaves the filter exactly
as it was.

The filter is a particle set (`mcl.particles.ParticleSet`: the particles, their weights and the step's buffers)
and a belief summary (`mcl.summary.BeliefSummary`: the estimate and the entropy, cached); this module is the loop
that moves, weighs and resamples them, and augmented MCL's injection. The soccer rules (regions, heading
reference, mirror guard, which poses to inject) are `mcl.relocalization`.

Resampling happens when the effective sample size falls below `resample_threshold`·N, or when augmented MCL
(Thrun et al., Probabilistic Robotics, table 8.3) asks for fresh particles: w_slow and w_fast track the
average likelihood per detection, and 1 - (w_fast/w_slow)/ratio_threshold of the particles are injected
(a dead-band: plain augmented MCL, ratio_threshold = 1, injects after every false positive); and as in
sensor resetting, 1 - w_fast/fit_threshold when the fit is poor in absolute terms, which is what finds the
robot from a uniform start (where w_slow is as poor as w_fast). Freshly injected particles are left out of
that average: they explain the detections badly and would ask for ever more injection.

Which particles are injected is the relocalization's choice (`mcl.relocalization`, given as
`relocalization=`; `SoccerRelocalization` by default): candidates that explain the current detections, from
pairs and single detections with any heading and a few uniform ones, weighed by how well they explain the
frame and by a prior (continuity with the last confident pose, the heading kept, the placement region) that
is evidence with a weight, never a gate. At most `max_fraction` of the particles are replaced per correction
until the filter has been confident after a reset, `max_fraction_tracking` afterwards.

Stateful motion models. A motion model with a `particle_state(n)` method (the adaptive model's mobility state:
a jump-Markov particle filter) gets a per-particle state array that the filter keeps beside the poses: it is
passed to `predict(poses, u, rng, state=...)`, follows each particle through resampling, and starts fresh for
reset and injected particles. `pf.motion_state` shows it (read-only).

Speed. With a bounded-noise motion model (velocity-linear, constant, or any `BoundedNoiseModel`) and a sensor
model that offers its likelihood as compiled kernels (`fused_likelihood`: the landmark model with the
max-mixture, or any model in the calling convention of `sensing.fused`), `step` and `correct` are one call into
compiled code (`mcl.step`, compiled once for each kind of sensor model): predict, likelihood, weights,
resampling, the histograms the estimate and the entropy share, and the estimate, with the random numbers drawn
in the kernels from the filter's generator. `mcl.contracts.fast_path(motion_model, sensor_model)` says whether
a pair of models gets it. The results
are those of the plain sequence of calls bit for bit (tests/test_fast_step.py runs both side by side). A step
that injects draws the injected poses (`_sample_injection`: numpy's draws, compiled placement) and finishes in
a second call (`mcl.step.resample_and_summarize`); the rare branches (other resampling schemes, stateful motion
models, threads with injection, particles that explain nothing) fall back to that sequence. Buffers are kept
across steps. `fast=True` (vectorized polynomials for sin, cos and exp, reassociated sums) and `threads=n` (chunks of
particles on n threads) trade the last bits for speed; `benchmarks.reference.compiled_phases` cuts the compiled
step into its stages for the benchmark.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Sequence

import numba
import numpy as np

from field import Field
from field.checks import LARGEST_ANGLE, LARGEST_COORDINATE, LARGEST_SIGMA, ArgumentTypeError, integer, real, reals
from motion_models.base import MotionInput, MotionModel
from motion_models.kernels import NO_WORK, move_chunked, move_range, move_range_fast
from numerics.chunks import balanced_chunk
from numerics.random import bit_generator_handle, draw_variates, parallel_uniforms
from numerics.trig import SQRT3
from sensing.fused import FusedLikelihoodKernels
from sensing.observations import Observations

from .contracts import Relocalization, SensorModel, fused_kernels, lacks, moves_by_bounded_noise
from .latency import move_back, move_forward
from .relocalization import SoccerRelocalization, region_bounds
from .resampling import SCHEMES, gather_offspring_rows, gather_with_jitter, resample_with_jitter
from .particles import ParticleSet, check_pose, check_poses
from .step import (NO_SINCE, NO_VARIATES, STEP_INVALID, STEP_MISSING, STEP_RESAMPLE, STEP_UNEXPLAINED, StepKernels,
                   fused_step, resample_and_summarize)
from .summary import BeliefSummary, Entropy, Estimate, Grid
from .weights import log_mean_likelihood, reweigh, weigh

# A sensor model's defect, not a refused input (the library's models give finite or -inf log-likelihoods for
# every input they accept): `correct` then changes nothing, `step` has moved the particles already.
_INVALID_LIKELIHOODS = "sensor model returned NaN or +inf log-likelihoods"
_MOVED = "; the particles moved by u (the prediction ran), their weights are unchanged"
MAX_PARTICLES = 10**7
"""The most particles a filter may have (about 2 GB of buffers); more is refused with a ValueError."""
MAX_THREADS = 1024


@dataclass(frozen=True)
class AugmentedMCL:
    """Augmented MCL parameters: averaging rates of w_slow and w_fast (0 < alpha_slow << alpha_fast <= 1).

    Parameters
    ----------
    alpha_slow : float, default 0.002
        Averaging rate of w_slow, the long-term average likelihood per detection.
    alpha_fast : float, default 0.1
        Averaging rate of w_fast, the short-term one (0 < alpha_slow < alpha_fast <= 1).
    ratio_threshold : float, default 0.5
        Inject 1 - (w_fast/w_slow)/ratio_threshold of the particles, in [0, 1]: only when the short-term fit
        drops below this share of the long-term one (1.0 is plain augmented MCL).
    fit_threshold : float, default 0.2
        Also inject 1 - w_fast/fit_threshold when the fit is poor in absolute terms (sensor resetting),
        >= 0; 0 switches it off.
    max_fraction : float, default 0.25
        Never replace more than this share of the particles at once, in [0, 1].
    max_fraction_tracking : float, default 0.05
        Nor more than this once the filter has been confident (the relocalization's `tracking`), in [0, 1].

    Raises
    ------
    ValueError
        If a value is out of its range (the comments below say why each default is what it is).
    """

    alpha_slow: float = 0.002
    alpha_fast: float = 0.1
    ratio_threshold: float = 0.5         # inject 1 - (w_fast/w_slow)/ratio_threshold of the particles: only
                                         # when the short-term fit drops below this share of the long-term
                                         # one (1.0 is plain augmented MCL, which reacts to every false
                                         # positive in a frame with a single detection)
    fit_threshold: float = 0.2           # also inject 1 - w_fast/fit_threshold when the fit is poor in absolute
                                         # terms (sensor resetting, Lenser & Veloso 2000): a perfect match
                                         # scores 1 per detection with sensing.LandmarkSensorModel. Below the
                                         # 1st percentile of w_fast while tracking (0.29 over every frame of
                                         # `robocup-mcl demo walk --seeds 0-9`), so it rarely fires then;
                                         # 0 switches it off
    max_fraction: float = 0.25           # never replace more than this share of the particles at once ...
    max_fraction_tracking: float = 0.05  # ... nor more than this once the filter has been confident (the
                                         # relocalization's `tracking`): a streak of false positives must not
                                         # dissolve a correct cluster (at 25 % a frame, 90 % of it is gone in 8
                                         # frames); the injected poses are chosen among many candidates for how
                                         # well they explain the frame, so few are needed

    def __post_init__(self) -> None:
        real("alpha_slow", self.alpha_slow)
        real("alpha_fast", self.alpha_fast)
        if not (0 < self.alpha_slow < self.alpha_fast <= 1):
            raise ValueError(f"alpha_slow = {self.alpha_slow!r}, alpha_fast = {self.alpha_fast!r}: "
                             "need 0 < alpha_slow < alpha_fast <= 1")
        for name in ("max_fraction", "max_fraction_tracking", "ratio_threshold"):
            real(name, getattr(self, name), 0.0, 1.0)
        real("fit_threshold", self.fit_threshold, 0.0)


class ParticleFilter(ParticleSet, BeliefSummary):
    """Monte Carlo localization: particles `poses` (N, 3) [x, y, θ] with `log_weights` (N,).

    After each correction with detections, `frame_log_likelihood` is the log of the weighted average
    likelihood of the particles that were not injected by the previous correction: the standard particle-filter
    estimate of log p(z_t | z_1..t-1), the frame's evidence in the sensor model's units (NaN before the first
    correction, -inf when no particle explains the frame); `frame_fit` is its per-detection geometric mean.

    Parameters
    ----------
    field : Field
        The field (bounds for resets, injection and the entropy grid).
    motion_model : MotionModel
        Any motion model (`motion_models`).
    sensor_model : SensorModel
        Any sensor model with `check(observations)` and `log_likelihood(poses, observations)`; optional:
        `terms(observations)` (independent terms scored, default: detections) and `sample_poses` (sensor
        resetting).
    n_particles : int, default 500
        N > 0 (at most `MAX_PARTICLES`).
    seed : int or None, default 0
        Seed of the filter's one random generator (same seed, same run); None seeds it from the operating
        system (a `numpy.random.SeedSequence` is taken too).
    resampling : str, default "systematic"
        "systematic", "stratified", "residual" or "multinomial".
    resample_threshold : float, default 0.5
        Resample when ESS < threshold·N (0..1).
    augmented : AugmentedMCL or None, default AugmentedMCL()
        Augmented MCL parameters, or None to switch injection off.
    grid : Grid, default Grid()
        Entropy and estimate grid parameters.
    roughening : tuple of float, default (0.02, 0.02, 0.02)
        Standard deviations (x [m], y [m], θ [rad]) of the uniform jitter added to resampled particles in
        their own frame (Gordon et al. 1993). Without it a standing robot, whose velocity-linear noise is zero
        (eq. 10), collapses onto copies of one particle after a few corrections. (0, 0, 0) switches it off.
    threads : int, default 1
        1 computes every step on one thread. With 2 or more, the compiled step, correction, prediction,
        estimate and entropy spread chunks of particles over that many threads, and take their sums chunk by
        chunk: the same results for any number of threads (and from run to run), equal to the one-thread
        results to rounding (a few units in the last place; resampling can differ where a point falls within
        rounding of a running total). Worth it from about N = 10⁵. At most `MAX_THREADS`.
    fast : bool, default False
        False keeps every result bit for bit as the plain kernels compute it. True compiles the step with
        fast-math: exp by a vectorized polynomial, the polynomial sin and cos (`numerics.trig.sincos`, which
        the default uses too) contracted into fused multiply-adds, and the sums of the weights and of the
        estimate reassociated: the same random draws, particles, weights and estimate equal to about 10⁻¹⁴
        after a step (and, like any rounding difference, a run that resamples drifts apart from the default
        one over many steps).
    relocalization : Relocalization or None, default None
        The soccer rules the filter resets and injects by (`mcl.contracts.Relocalization`); None makes a
        `mcl.relocalization.SoccerRelocalization` with its default prior.

    Raises
    ------
    ValueError
        If a number is out of range, `resampling` is unknown, or a model lacks a method of its contract.
    ArgumentTypeError
        If an argument has the wrong type (`field` not a `Field`, `fast` not a bool, ...); a ValueError too.
    """

    def __init__(self, field: Field, motion_model: MotionModel, sensor_model: SensorModel, n_particles: int = 500,
                 seed: int | None = 0, resampling: str = "systematic", resample_threshold: float = 0.5,
                 augmented: AugmentedMCL | None = AugmentedMCL(), grid: Grid = Grid(),
                 roughening: tuple[float, float, float] = (0.02, 0.02, 0.02), threads: int = 1,
                 fast: bool = False, relocalization: Relocalization | None = None) -> None:
        if not isinstance(field, Field):
            raise ArgumentTypeError(f"field = {field!r} must be a field.Field, not {type(field).__name__}")
        integer("n_particles", n_particles, 1, MAX_PARTICLES)
        if seed is not None and not isinstance(seed, np.random.SeedSequence):
            integer("seed", seed, 0)
        self.resampling = resampling                  # (the setters check them)
        self.resample_threshold = resample_threshold
        for name, obj, contract in (("motion_model", motion_model, MotionModel),
                                    ("sensor_model", sensor_model, SensorModel)):
            missing = lacks(obj, contract)
            if missing:
                raise ValueError(f"{name} = {obj!r} lacks {', '.join(missing)}")
        self.roughening = roughening
        integer("threads", threads, 1, MAX_THREADS)
        if not isinstance(fast, (bool, np.bool_)):
            raise ArgumentTypeError(f"fast = {fast!r} must be True or False, not {type(fast).__name__}")
        self._threads = int(threads)
        self._chunk = int(balanced_chunk(int(n_particles), _CHUNK))   # particles per chunk with threads > 1
        self._fast = bool(fast)
        self._thread_scope = _Threads(self._threads)
        self._field = field
        self.motion_model = motion_model
        self.sensor_model = sensor_model
        self._n = int(n_particles)
        self.augmented = augmented
        self.rng = np.random.default_rng(seed)
        self._set_up_grid(grid)
        self._allocate_buffers()
        self.w_slow = 0.0
        self.w_fast = 0.0
        self.frame_fit = math.nan     # the last correction's average likelihood per detection (augmented MCL)
        self.frame_log_likelihood = math.nan   # the last correction's log weighted average particle likelihood
        self.ess = float(self._n)
        self.resampled = False        # whether the last correction resampled
        self.injected = 0             # particles injected by the last correction
        self._bind_relocalization(SoccerRelocalization() if relocalization is None else relocalization)
        self._bind_motion_state()
        self.reset_uniform("field")

    def _allocate_buffers(self) -> None:
        """The particle set's buffers, the summary's, and the step's caches: a steady-state step allocates
        nothing that grows with N."""
        self._allocate_particles()
        self._allocate_summary()
        # the compiled step's particle arguments (`mcl.step`), the same arrays for the filter's life
        self._particle_group = (self._poses, self._log_weights, self._weights, self._log_likelihood, self._previous,
                                self._trig, self._counts, self._local_histograms)
        self._rng_handle: tuple | None = None           # (bit generator, its kernel handle)
        self._compiled_sensor_of: SensorModel | None = None   # the sensor model `_compiled_sensor` was asked of
        self._bounded_of: MotionModel | None = None                         # the motion model `_bounded` was asked of
        self._bounded = False                           # whether it moves as BoundedNoiseModel does
        self._compiled_sensor: FusedLikelihoodKernels | None = None
        self._fused_step: StepKernels | None = None     # `mcl.step.fused_step` of the sensor model's kernels

    def _bind_relocalization(self, relocalization) -> None:
        """Check and bind the relocalization (`mcl.contracts.Relocalization`) to the carpet."""
        missing = lacks(relocalization, Relocalization)
        if missing:
            raise ValueError(f"relocalization = {relocalization!r} lacks {', '.join(missing)}")
        self.relocalization = relocalization      # which poses to inject, and what tells them apart
        relocalization.bind((self._x_min, self._x_max, self._y_min, self._y_max))

    def __getstate__(self) -> dict:
        # Pickles and deep copies leave out the generator's kernel handle: it holds the addresses of this
        # filter's bit generator, and a copy that kept them would draw from (and advance) the original's.
        # The sensor model's compiled kernels are asked for again (a copy's sensor model is a copy too).
        state = self.__dict__.copy()
        state["_rng_handle"] = None
        state["_compiled_sensor_of"] = state["_compiled_sensor"] = state["_fused_step"] = None
        del state["_state_rows"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._bind_state_rows()

    @property
    def resampling(self) -> str:
        """The resampling scheme, one of `mcl.resampling.SCHEMES` (may be changed between steps)."""
        return self._resampling

    @resampling.setter
    def resampling(self, value: str) -> None:
        if not isinstance(value, str):
            raise ArgumentTypeError(f"resampling = {value!r} must be a string, one of {tuple(SCHEMES)}")
        if value not in SCHEMES:
            raise ValueError(f"resampling = {value!r} must be one of {tuple(SCHEMES)}")
        self._resampling = value

    @property
    def resample_threshold(self) -> float:
        """Resample when the ESS falls below this share of N, in [0, 1] (may be changed between steps)."""
        return self._resample_threshold

    @resample_threshold.setter
    def resample_threshold(self, value: float) -> None:
        self._resample_threshold = real("resample_threshold", value, 0.0, 1.0)

    @property
    def augmented(self) -> AugmentedMCL | None:
        """Augmented MCL's parameters, or None: no injection (may be changed between steps)."""
        return self._augmented

    @augmented.setter
    def augmented(self, value: AugmentedMCL | None) -> None:
        if value is not None and not isinstance(value, AugmentedMCL):
            raise ArgumentTypeError(f"augmented = {value!r} must be an AugmentedMCL or None, "
                                    f"not {type(value).__name__}")
        self._augmented = value

    @property
    def field(self) -> Field:
        """The field (fixed: the carpet's bounds, the grid and the injection region are made for it)."""
        return self._field

    @property
    def threads(self) -> int:
        """The number of threads the compiled step runs on (a constructor option)."""
        return self._threads

    @property
    def fast(self) -> bool:
        """Whether the compiled step computes sin, cos, exp and its sums the fast way (a constructor option)."""
        return self._fast

    @property
    def roughening(self) -> np.ndarray:
        """The roughening's standard deviations (x [m], y [m], θ [rad]), read-only (may be replaced between
        steps by three finite numbers >= 0)."""
        return self._roughening

    @roughening.setter
    def roughening(self, value) -> None:
        array = self._check_sigma(value, "roughening").copy()
        array.flags.writeable = False
        self._roughening = array

    # -- resets ------------------------------------------------------------------------------------------

    def reset_uniform(self, region: str | Sequence[float] = "field", heading: float | None = None,
                      heading_sigma: float = 0.0) -> None:
        """Spread the particles uniformly over a region ("field", "own_half", "opponent_half", or bounds).

        Injection stays in this region until the filter is first confident (see the module docstring).

        Parameters
        ----------
        region : str or sequence of float, default "field"
            A name of `mcl.relocalization.REGIONS` or bounds (x_min, x_max, y_min, y_max) [m].
        heading : float or None, default None
            None for uniform headings, else the headings' mean [rad].
        heading_sigma : float, default 0.0
            Standard deviation of the headings around `heading` [rad] (unused when `heading` is None).

        Raises
        ------
        ValueError
            If the region is unknown or its bounds are out of order, or a number is out of range.
        """
        bounds = region_bounds(self._field, region)
        if heading is not None:
            heading = real("heading", heading, -LARGEST_ANGLE, LARGEST_ANGLE)
            heading_sigma = real("heading_sigma", heading_sigma, 0.0, LARGEST_SIGMA)
        x_min, x_max, y_min, y_max = bounds
        poses = np.empty((self._n, 3))
        poses[:, 0] = self.rng.uniform(x_min, x_max, self._n)
        poses[:, 1] = self.rng.uniform(y_min, y_max, self._n)
        if heading is None:
            poses[:, 2] = self.rng.uniform(-math.pi, math.pi, self._n)
        else:
            poses[:, 2] = heading + heading_sigma * self.rng.standard_normal(self._n)
        self._set_particles(poses)
        self.relocalization.reset_region(bounds)
        self.w_slow = self.w_fast = 0.0

    def reset_around(self, pose: Sequence[float] | np.ndarray,
                     sigma: Sequence[float] | np.ndarray = (0.1, 0.1, 0.1)) -> None:
        """Normal particles around a known pose (x, y, θ) with standard deviations `sigma`.

        The pose is taken as known: its heading guides injection from now on (as after a confident sweep).

        Parameters
        ----------
        pose : sequence of float or numpy.ndarray
            (x [m], y [m], θ [rad]).
        sigma : sequence of float or numpy.ndarray, default (0.1, 0.1, 0.1)
            Standard deviations (x [m], y [m], θ [rad]), each finite and >= 0.

        Raises
        ------
        ValueError
            If the pose or a standard deviation is not finite or out of range.
        """
        pose = check_pose("pose", pose)
        sigma = self._check_sigma(sigma)
        self._set_particles(pose + sigma * self.rng.standard_normal((self._n, 3)))
        self.relocalization.reset_pose(pose)
        self.w_slow = self.w_fast = 0.0

    def reset_mirrored(self) -> None:
        """Mirror every particle through the centre mark: (x, y, θ) → (−x, −y, θ+π), weights kept."""
        self._mirror_particles()
        self.relocalization.mirror()

    def reset_candidates(self, poses: Sequence[Sequence[float]] | np.ndarray,
                         sigma: Sequence[float] | np.ndarray = (0.1, 0.1, 0.1),
                         region: str | Sequence[float] = "field") -> None:
        """Spread the particles evenly over several candidate poses (K, 3), normal around each with `sigma`.

        For a placement whose pose the rules fix up to a choice the robot cannot know (which touchline, which
        kick-off position). Injection stays inside `region` with uniform headings until the filter is
        confident again (as after `reset_uniform`): the candidates' headings differ, so no single heading
        reference guides it yet.

        Parameters
        ----------
        poses : array_like
            (K, 3) candidate poses (x [m], y [m], θ [rad]), K >= 1; particle i goes to candidate i mod K.
        sigma : sequence of float or numpy.ndarray, default (0.1, 0.1, 0.1)
            Standard deviations (x [m], y [m], θ [rad]) around each candidate.
        region : str or sequence of float, default "field"
            Where injection stays until the filter is confident: a name of `mcl.relocalization.REGIONS` or
            bounds (x_min, x_max, y_min, y_max) [m].

        Raises
        ------
        ValueError
            If there is no candidate, a pose or standard deviation is out of range, or the region is unknown.
        """
        candidates = check_poses("poses", poses)
        if candidates.shape[0] == 0:
            raise ValueError(f"poses = {poses!r} must be one or more (x, y, θ) poses")
        sigma = self._check_sigma(sigma)
        bounds = region_bounds(self._field, region)
        choice = np.arange(self._n) % candidates.shape[0]
        self._set_particles(candidates[choice] + sigma * self.rng.standard_normal((self._n, 3)))
        self.relocalization.reset_region(bounds)
        self.w_slow = self.w_fast = 0.0

    # -- the step ----------------------------------------------------------------------------------------
    # A bounded-noise motion model (velocity-linear, constant) and a sensor model that offers
    # `fused_likelihood` (the landmark model with the max-mixture) run inside the filter's own kernels:
    # `predict` draws its noise in the kernel, and `correct` and `step` are one call into compiled code
    # (`mcl.step.compiled_step`: predict, likelihood, weights, resampling, the summary histograms and the estimate).
    # Every path gives the particles, weights, draws and estimates of the plain sequence of calls bit for bit;
    # other models take that sequence.

    def predict(self, u: MotionInput) -> None:
        """Move every particle by the motion model.

        Parameters
        ----------
        u : MotionInput
            The motion since the last prediction (command or odometry over `u.dt` seconds).

        Raises
        ------
        ValueError
            If the motion model refuses `u` (the filter is left unchanged).
        """
        self._move(u)

    def _check_motion(self, u: MotionInput) -> None:
        if not isinstance(u, MotionInput):
            raise ArgumentTypeError(f"u = {u!r} must be a motion_models.MotionInput, not {type(u).__name__}")
        self.motion_model.check(u)

    def _kernel_motion(self, u: MotionInput) -> tuple[float, ...] | None:
        """Check `u` (as `_check_motion`); return (dx, dy, dθ, bound_x, bound_y, bound_θ) when the motion model
        moves as `BoundedNoiseModel` does (displacement plus bounded robot-frame noise), so the filter's
        kernels can move the particles themselves, else None."""
        if not isinstance(u, MotionInput):
            raise ArgumentTypeError(f"u = {u!r} must be a motion_models.MotionInput, not {type(u).__name__}")
        model = self.motion_model
        if model is not self._bounded_of:             # (asked once per motion model: this runs every step)
            self._bounded = moves_by_bounded_noise(model)
            self._bounded_of = model
        if self._motion_state is not None or not self._bounded:
            model.check(u)
            return None
        dx, dy, dtheta = u.displacement()           # BoundedNoiseModel.check
        bound_x, bound_y, bound_theta = model.noise_bounds(u)
        return float(dx), float(dy), float(dtheta), float(bound_x), float(bound_y), float(bound_theta)

    def _generator(self) -> tuple[int, int]:
        """The filter generator's handle for drawing in kernels (`numerics.random.bit_generator_handle`)."""
        bit_generator = self.rng.bit_generator
        handle = self._rng_handle
        if handle is None or handle[0] is not bit_generator:
            handle = self._rng_handle = (bit_generator, *bit_generator_handle(self.rng))
        return handle[1], handle[2]

    def _scores_view(self, observations: Observations) -> bool:
        """Whether the sensor model scores this frame's view (negative information), which the compiled step
        does not: such a frame is scored through `log_likelihood`."""
        if observations.view is None:
            return False
        scores_view = getattr(self.sensor_model, "scores_view", None)
        return bool(scores_view(observations)) if callable(scores_view) else False

    def _sensor_kernel(self) -> tuple | None:
        """The sensor model's fused-likelihood kernels (`mcl.contracts.fused_kernels`; None: score through
        `log_likelihood`)."""
        sensor_model = self.sensor_model
        if sensor_model is not self._compiled_sensor_of:
            self._compiled_sensor = fused_kernels(sensor_model)
            self._fused_step = None if self._compiled_sensor is None else fused_step(self._compiled_sensor)
            self._compiled_sensor_of = sensor_model
        return self._compiled_sensor

    def _move(self, u: MotionInput) -> None:
        motion = self._kernel_motion(u)             # checks u first
        if motion is None:
            if self._motion_state is None:
                self.motion_model.predict(self._poses, u, self.rng)
            else:
                self.motion_model.predict(self._poses, u, self.rng, state=self._motion_state)
            self.relocalization.carry(*u.displacement())
        else:
            self._move_compiled(motion)
            self.relocalization.carry(motion[0], motion[1], motion[2])
        self._changed()

    def _move_compiled(self, motion: tuple[float, ...]) -> None:
        """Move by (dx, dy, dθ, bounds) in the filter's kernels, with the noise the motion model would draw."""
        gaussian = bool(self.motion_model.gaussian)
        variates = draw_variates(self.rng, self._n, True, out=self._variates) if gaussian else NO_VARIATES
        if self._threads > 1:
            with self._thread_scope:
                if not gaussian:
                    variates = self._variates
                    parallel_uniforms(*self._generator(), variates.reshape(-1), 3 * self._n)
                move_chunked(self._poses, *motion, gaussian, variates, self._chunk)
        elif self._fast:
            move_range_fast(self._poses, self._poses, 0, self._n, motion[:3], motion[3:], gaussian, variates,
                            self._generator(), NO_WORK)
        else:
            move_range(self._poses, self._poses, 0, self._n, motion[:3], motion[3:], gaussian, variates,
                       self._generator(), NO_WORK)

    def correct(self, observations: Observations | Iterable | None,
                since: Sequence[float] | np.ndarray | None = None) -> None:
        """Weigh the particles by the detections, then resample (and inject) if needed.

        A frame that comes with its camera view (`Observations.view`) is also scored by the landmarks each
        particle puts in view that the frame did not report, when the sensor model does so (`scores_view`,
        negative information); such a frame is scored through the model's `log_likelihood`.

        Parameters
        ----------
        observations : Observations, iterable of LandmarkObservation, or None
            One camera frame's detections (coerced by `Observations.coerce`); None or empty changes nothing.
        since : sequence of float, numpy.ndarray or None, default None
            For detections captured earlier (camera latency), the robot's motion (dx [m], dy [m], dθ [rad])
            from their capture to now, in the robot frame at capture (`mcl.latency.MotionHistory.since`). Each
            particle is scored where it was at capture: moved back along `since`. None or (0, 0, 0): scored as
            it is.

        Raises
        ------
        ValueError
            If the sensor model refuses the detections, `since` is out of range, or the sensor model returns
            NaN or +inf log-likelihoods; the filter is left unchanged.
        """
        observations = Observations.coerce(observations)
        try:
            motion_since = self._check_since(since)   # before any kernel is prepared: a refusal changes nothing
        except ValueError:
            self.sensor_model.check(observations)     # the detections are checked first
            raise
        if len(observations) == 0 or self._sensor_kernel() is None or self._scores_view(observations):
            self.sensor_model.check(observations)
            self._correct(observations, motion_since)
            return
        self._step_compiled(None, observations, False, motion_since)

    @staticmethod
    def _check_since(since) -> np.ndarray | None:
        if since is None:
            return None
        if type(since) is tuple and len(since) == 3 and all(type(v) is float for v in since):
            # `MotionHistory.since` gives three floats: checked without numpy's calls on a tiny array
            if not (math.hypot(since[0], since[1]) <= LARGEST_COORDINATE and abs(since[2]) <= LARGEST_ANGLE):
                return ParticleFilter._check_since(list(since))       # raises, naming the rule
            return None if since == (0.0, 0.0, 0.0) else np.array(since)
        array = reals("since", since, 3)
        if math.hypot(array[0], array[1]) > LARGEST_COORDINATE or abs(array[2]) > LARGEST_ANGLE:
            raise ValueError(f"since = {since!r} must move at most {LARGEST_COORDINATE:g} m and turn at most "
                             f"{LARGEST_ANGLE:g} rad")
        return None if not array.any() else array

    def _correct(self, observations: Observations, since: np.ndarray | None = None) -> None:
        if observations.is_empty:
            return
        scored = self._poses
        if since is not None:
            move_back(self._poses, since, self._capture_poses)
            scored = self._capture_poses
        log_likelihood = np.asarray(self.sensor_model.log_likelihood(scored, observations, out=self._log_likelihood),
                                    dtype=np.float64)
        valid, native_log_average, log_evidence, ess = weigh(self._log_weights, log_likelihood,
                                                             self._n - self.injected, self._weights)
        if not valid:
            raise ValueError(_INVALID_LIKELIHOODS + "; filter left unchanged")
        terms = getattr(self.sensor_model, "terms", len)(observations)
        self.frame_log_likelihood = native_log_average
        if terms > 0:
            self.frame_fit = math.exp(native_log_average / terms)
        self._changed()
        if log_evidence == -np.inf:
            # Every particle has zero likelihood: the belief cannot explain the detections. Recover by
            # keeping the particles with uniform weights and replacing the largest allowed share by
            # injected ones; nothing else (no NaN) can come out of this.
            self._weights[:] = 1.0 / self._n
            self._resample(self._injection_count(1.0), observations, since)
            return
        reweigh(self._log_weights, log_likelihood, log_evidence)
        self.ess = ess
        fraction = 0.0
        if self._augmented is not None:
            fraction = self._update_augmented(native_log_average / terms) if terms > 0 else 0.0
        count = self._injection_count(fraction)
        if count > 0 or ess < self._resample_threshold * self._n:
            self._resample(count, observations, since)
        else:
            self.resampled = False
            self.injected = 0
        self._track_confidence()

    def step(self, u: MotionInput, observations: Observations | Iterable | None = None) -> Estimate:
        """predict(u), then correct(observations) when there are any; returns the estimate.

        Both inputs are validated before anything changes.

        Parameters
        ----------
        u : MotionInput
            The motion since the last step.
        observations : Observations, iterable of LandmarkObservation, or None, default None
            The detections of a camera frame taken now; None or empty: predict only.

        Returns
        -------
        Estimate
            `estimate()` after the step.

        Raises
        ------
        ValueError
            If the motion model refuses `u` or the sensor model the detections (nothing changed), or the
            sensor model returns NaN or +inf log-likelihoods (the particles have then moved, their weights
            are unchanged: the message says so).
        """
        observations = Observations.coerce(observations)
        if len(observations) == 0 or self._sensor_kernel() is None or self._scores_view(observations):
            self.sensor_model.check(observations)
            self._check_motion(u)
            self._move(u)
            try:
                self._correct(observations)
            except ValueError as error:
                if str(error).startswith(_INVALID_LIKELIHOODS):
                    raise ValueError(_INVALID_LIKELIHOODS + _MOVED) from None
                raise
            return self.estimate()
        try:
            motion = self._kernel_motion(u)
        except ValueError:
            self.sensor_model.check(observations)     # the detections are checked first
            raise
        if motion is None:
            self.sensor_model.check(observations)     # before moving in Python
            self._move(u)
        self._step_compiled(motion, observations, True)
        return self.estimate()

    def _step_compiled(self, motion: tuple | None, observations: Observations, in_step: bool,
                       since: np.ndarray | None = None) -> None:
        """[predict by `motion`,] correct(observations) [captured `since` ago]: one call into
        `mcl.step.compiled_step` (with the entropy, once `entropy()` has been asked for)."""
        n = self._n
        sensor = self._compiled_sensor
        move = motion is not None
        chunk = self._chunk if self._threads > 1 else 0
        gaussian = move and bool(self.motion_model.gaussian)
        variates = self._variates if chunk else NO_VARIATES
        if motion is None:                            # (not move)
            motion = _NO_MOTION
        elif gaussian:
            self.sensor_model.check(observations)     # before the noise is drawn
            variates = draw_variates(self.rng, n, True, out=self._variates)
        a = self._augmented
        if a is None:
            augmented, alpha_slow, alpha_fast, ratio_threshold, fit_threshold, cap = False, 0.0, 0.0, 1.0, 0.0, 0.0
        else:
            augmented, alpha_slow, alpha_fast = True, a.alpha_slow, a.alpha_fast
            ratio_threshold, fit_threshold = a.ratio_threshold, a.fit_threshold
            cap = a.max_fraction_tracking if self.relocalization.tracking else a.max_fraction
        terms = getattr(self.sensor_model, "terms", len)(observations)
        # Only an estimate the plain sequence of calls computes (after a correction with augmentation, or at the
        # end of `step`) may be computed here: computing one moves the hysteresis anchor `_previous_estimate`.
        want_estimate = in_step or a is not None
        mean = np.empty(3)
        covariance = np.empty((3, 3))
        weighting = (n - self.injected, terms, augmented, alpha_slow, alpha_fast, ratio_threshold, fit_threshold,
                     self.w_slow, self.w_fast, cap)
        resampling = (self._resample_threshold, self._resampling == "systematic" and (self._motion_state is None
                                                                                     or not chunk),
                      self._roughening, self._state_rows, self._state_scratch)
        fused = self._fused_step
        assert fused is not None and sensor is not None       # the fused path is taken only with both bound
        with self._thread_scope:
            (status, native_log_average, ess, w_slow, w_fast, fraction, resampled, weight, position,
             orientation) = fused.compiled_step(
                self._particle_group, (move, *motion, gaussian, variates), self._generator(),
                (sensor.params, sensor.inputs(observations)),
                weighting, resampling, self._summary_group(want_estimate, mean, covariance), chunk, self._fast,
                NO_SINCE if since is None else since)
        if status == STEP_MISSING:
            self.sensor_model.check(observations)     # raises, naming the detection; nothing has changed
            raise ValueError("the sensor model's fused kernels refuse a detection that its check() accepts; "
                             "filter left unchanged")
        if move:                                      # the particles have moved, whatever follows
            self.relocalization.carry(motion[0], motion[1], motion[2])
            self._changed()
        if status == STEP_INVALID:
            raise ValueError(_INVALID_LIKELIHOODS + (_MOVED if move else "; filter left unchanged"))
        self._changed()
        self.frame_log_likelihood = native_log_average
        if terms > 0:
            self.frame_fit = math.exp(native_log_average / terms)
        if status == STEP_UNEXPLAINED:
            self._weights[:] = 1.0 / n
            self._resample(self._injection_count(1.0), observations, since)
            return
        self.ess = ess
        if augmented and terms > 0:
            self.w_slow = w_slow
            self.w_fast = w_fast
        if status == STEP_RESAMPLE:
            count = self._injection_count(fraction)
            if count > 0 and self._threads == 1 and self._resampling == "systematic" and self._motion_state is None:
                self._finish_with_injection(count, observations, want_estimate, mean, covariance, since)
            else:
                self._resample(count, observations, since)
        else:
            self.resampled = resampled
            self.injected = 0
            self._summary_valid = True
            if want_estimate:                         # `_previous_estimate` was updated in the kernel
                self._estimate = Estimate(mean, covariance, weight)
                self._has_previous_estimate = True
            if self._entropy_wanted:
                self._entropy = Entropy(position, orientation)
        self._track_confidence()

    def _finish_with_injection(self, count: int, observations: Observations, want_estimate: bool,
                               mean: np.ndarray, covariance: np.ndarray, since: np.ndarray | None = None) -> None:
        """The end of a compiled step that injects (one thread, systematic resampling): `_resample` and the
        estimate and entropy that follow it, in one call into compiled code (`_resample_and_summarize`) after
        the injected poses are drawn. The same draws and results as `_resample` then `estimate()`/`entropy()`."""
        n = self._n
        injected = self._sample_injection(count, observations)
        if since is not None:                     # placed where the detections were captured: carried to now
            move_forward(injected, since, injected)
        keep = n - count
        weight, position, orientation = resample_and_summarize(
            self._weights, keep, self._previous, self._roughening, self._poses, self._trig, self._generator(),
            self._counts, injected, self._log_weights, self._summary_group(want_estimate, mean, covariance),
            self._fast)
        self.ess = float(n)
        self.resampled = True
        self.injected = count
        self._changed()
        self._summary_valid = True
        if want_estimate:
            self._estimate = Estimate(mean, covariance, weight)
            self._has_previous_estimate = True
        if self._entropy_wanted:
            self._entropy = Entropy(position, orientation)

    def _track_confidence(self) -> None:
        """Tell the relocalization what the correction left: the estimate, and whether the belief explains the
        detections as well as it usually does (w_fast at least `ratio_threshold` of
        w_slow: no injection asked for by a drop of the fit; an absolute level would depend on how noisy the
        camera is)."""
        if self._augmented is None:
            return
        estimate = self.estimate()
        if self.relocalization.confirm(estimate, self.w_fast >= self._augmented.ratio_threshold * self.w_slow):
            # The relocalization's prior puts the belief on the mirror side of the field, which the detections
            # cannot tell from this one (the field is point-symmetric): the particles go there, weights kept.
            self._mirror_particles()

    def _native_log_average(self, log_likelihood: np.ndarray) -> float:
        """log(Σ wᵢ pᵢ / Σ wᵢ) over the particles not injected by the previous resampling (prior weights).

        Freshly injected particles mostly explain the detections badly; counting them would lower the
        average, which asks for more injection: a feedback loop that tears a good cluster apart. They sit
        at the tail of the arrays until the next resampling.
        """
        return log_mean_likelihood(self._log_weights, log_likelihood, self._n - self.injected)

    def _update_augmented(self, log_average: float) -> float:
        """Update w_slow, w_fast with the per-detection average likelihood; return the injection share."""
        a = self._augmented
        assert a is not None                          # called with augmented MCL on only
        average = math.exp(log_average)
        if self.w_slow == 0.0:
            self.w_slow = self.w_fast = average
        else:
            self.w_slow += a.alpha_slow * (average - self.w_slow)
            self.w_fast += a.alpha_fast * (average - self.w_fast)
        relative = 1.0 - self.w_fast / (a.ratio_threshold * self.w_slow) if self.w_slow > 0 else 1.0
        absolute = 1.0 - self.w_fast / a.fit_threshold if a.fit_threshold > 0 else 0.0
        return max(0.0, relative, absolute)

    def _injection_count(self, fraction: float) -> int:
        if self._augmented is None:
            return 0
        a = self._augmented
        cap = a.max_fraction_tracking if self.relocalization.tracking else a.max_fraction
        return int(round(min(fraction, cap) * self._n))

    def _sample_injection(self, count: int, observations: Observations) -> np.ndarray:
        """`count` poses for augmented MCL to inject, as the relocalization proposes them (`propose`)."""
        return np.ascontiguousarray(self.relocalization.propose(count, observations, self.sensor_model, self.rng),
                                    dtype=np.float64)

    def _resample(self, count: int, observations: Observations, since: np.ndarray | None = None) -> None:
        injected = self._sample_injection(count, observations) if count > 0 else NO_VARIATES
        if since is not None and injected.shape[0]:
            # Sensor resetting placed them where the detections were captured: carry them to now.
            move_forward(injected, since, injected)
        keep = self._n - injected.shape[0]
        self._previous[:] = self._poses
        # Roughening: uniform jitter of standard deviation `roughening`, in each particle's own frame so that
        # it commutes with rotating the world, fused with the copy from the ancestors.
        bounds = self._roughening * SQRT3
        if self._resampling == "systematic":
            u0 = resample_with_jitter(self._weights, keep, self._previous, bounds, self._poses, _NO_TRIG,
                                      *self._generator(), self._counts, _NO_COORDINATES)
            if self._motion_state is not None:
                gather_offspring_rows(self._weights, keep, u0, self._counts, self._state_rows, self._state_scratch)
                self._motion_state[keep:] = self.motion_model.particle_state(self._n - keep)
        else:
            ancestors = SCHEMES[self._resampling](self._weights, keep, self.rng)
            gather_with_jitter(self._previous, ancestors, bounds,
                               draw_variates(self.rng, keep, False, out=self._variates), self._poses)
            if self._motion_state is not None:
                self._motion_state[:keep] = self._motion_state[ancestors]
                self._motion_state[keep:] = self.motion_model.particle_state(self._n - keep)
        self._poses[keep:] = injected
        self._log_weights[:] = -math.log(self._n)
        self._weights[:] = 1.0 / self._n
        self.ess = float(self._n)
        self.resampled = True
        self.injected = int(injected.shape[0])
        self._changed()


# -- the compiled step ---------------------------------------------------------------------------------------------
_CHUNK = 4096        # particles per chunk with threads > 1, about (`balanced_chunk`: a function of N alone, so the
                     # results do not depend on the threads)


class _Threads:
    """Run numba's parallel kernels on `threads` threads inside the block (at most NUMBA_NUM_THREADS); a filter
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


_NO_TRIG = np.empty((0, 2))
_NO_COORDINATES = np.empty((3, 0))
_NO_MOTION = (0.0,) * 6
