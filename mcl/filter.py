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

The filter owns its particles (`mcl.particles.Particles`: named arrays), its summary (`mcl.summary.Summary`:
the estimate and the entropy, cached) and an engine (`mcl.engine.Engine`, chosen when the filter is built:
serial or on threads, with or without fast-math) that runs each stage on them; this module is the algorithm
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

The fused step. With a bounded-noise motion model (velocity-linear, constant, or any `BoundedNoiseModel`) and
a sensor model that offers its likelihood as compiled kernels (`fused_likelihood`, in the calling convention
of `sensing.fused`), the engine runs a correction (after a prediction, in `step`) as one call into compiled
code (`mcl.step`): predict, likelihood, weights, resampling, the histograms the estimate and the entropy
share, and the estimate, with the random numbers drawn in the kernels from the filter's generator.
`mcl.contracts.fast_path(motion_model, sensor_model)` says whether a pair of models gets it. The results are
those of the stages one by one, bit for bit (tests/test_fast_step.py runs both side by side). A step that
injects draws the injected poses and finishes in a second call; the rare branches (other resampling schemes,
stateful motion models, threads with injection, particles that explain nothing) take the stages one by one.
`fast=True` and `threads=n` trade the last bits for speed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from operator import attrgetter
from typing import Any, Generic, TypeVar, overload

import numpy as np

from field import Field
from field.checks import ArgumentTypeError, integer, real
from motion_models.base import MotionInput, MotionModel
from numerics.frozen import keeps_arrays_frozen
from sensing.observations import Observations

from .augmented import AugmentedMCL, Injection
from .contracts import Relocalization, SensorModel, lacks
from .engine import Engine, ReferenceEngine
from .latency import check_since, move_forward
from .particles import Particles, check_pose, check_poses, check_sigma
from .relocalization import SoccerRelocalization, region_bounds
from .resampling import SCHEMES
from .step import NO_VARIATES, STEP_INVALID, STEP_MISSING, STEP_RESAMPLE, STEP_UNEXPLAINED
from .summary import Entropy, Estimate, Grid, Summary

# A sensor model's defect, not a refused input (the library's models give finite or -inf log-likelihoods for
# every input they accept): `correct` then changes nothing, `step` has moved the particles already.
_INVALID_LIKELIHOODS = "sensor model returned NaN or +inf log-likelihoods"
_MOVED = "; the particles moved by u (the prediction ran), their weights are unchanged"
MAX_PARTICLES = 10**7
"""The most particles a filter may have (about 2 GB of buffers); more is refused with a ValueError."""
MAX_THREADS = 1024


T = TypeVar("T")


class _Fixed(Generic[T]):
    """A read-only attribute of the filter, found along `path` ("_particles.n"): fixed when the filter is built.
    Setting it raises AttributeError with `refusal` (which says what to do instead)."""

    def __init__(self, path: str, refusal: str = "") -> None:
        self.get = attrgetter(path)
        self.refusal = refusal

    def __set_name__(self, owner: type, name: str) -> None:
        self.refusal = self.refusal or f"ParticleFilter.{name} is fixed when the filter is built"

    @overload
    def __get__(self, obj: None, kind: type | None = None) -> _Fixed[T]: ...
    @overload
    def __get__(self, obj: object, kind: type | None = None) -> T: ...
    def __get__(self, obj, kind=None):
        return self if obj is None else self.get(obj)

    def __set__(self, obj: object, value: object) -> None:
        raise AttributeError(self.refusal)


class _Setting(Generic[T]):
    """A setting of the filter that may change between steps: `check` validates (and converts) a new value,
    kept as the attribute's name with a leading underscore."""

    def __init__(self, check: Callable[[Any], T]) -> None:
        self.check = check
        self.slot = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.slot = "_" + name

    @overload
    def __get__(self, obj: None, kind: type | None = None) -> _Setting[T]: ...
    @overload
    def __get__(self, obj: object, kind: type | None = None) -> T: ...
    def __get__(self, obj, kind=None):
        return self if obj is None else getattr(obj, self.slot)

    def __set__(self, obj: object, value: Any) -> None:
        setattr(obj, self.slot, self.check(value))


class _Linked(Generic[T]):
    """An attribute of the filter that one of its parts keeps, found along `path` ("_injection.w_slow")."""

    def __init__(self, path: str) -> None:
        self.part, _, self.name = path.rpartition(".")

    @overload
    def __get__(self, obj: None, kind: type | None = None) -> _Linked[T]: ...
    @overload
    def __get__(self, obj: object, kind: type | None = None) -> T: ...
    def __get__(self, obj, kind=None):
        return self if obj is None else getattr(getattr(obj, self.part), self.name)

    def __set__(self, obj: object, value: T) -> None:
        setattr(getattr(obj, self.part), self.name, value)


def _check_field_and_seed(field: object, n_particles: object, seed: object) -> None:
    if not isinstance(field, Field):
        raise ArgumentTypeError(f"field = {field!r} must be a field.Field, not {type(field).__name__}")
    integer("n_particles", n_particles, 1, MAX_PARTICLES)
    if seed is not None and not isinstance(seed, np.random.SeedSequence):
        integer("seed", seed, 0)


def _check_engine_options(threads: object, fast: object, reference: object) -> None:
    integer("threads", threads, 1, MAX_THREADS)
    for name, value in (("fast", fast), ("reference", reference)):
        if not isinstance(value, (bool, np.bool_)):
            raise ArgumentTypeError(f"{name} = {value!r} must be True or False, not {type(value).__name__}")
    if reference and (threads != 1 or fast):
        raise ValueError(
            f"reference = True runs in numpy on one thread: threads = {threads!r} must be 1 and fast False"
        )


def _check_contract(name: str, obj: object, contract: type) -> None:
    missing = lacks(obj, contract)
    if missing:
        raise ValueError(f"{name} = {obj!r} lacks {', '.join(missing)}")


def _scheme(value: Any) -> str:
    if not isinstance(value, str):
        raise ArgumentTypeError(f"resampling = {value!r} must be a string, one of {tuple(SCHEMES)}")
    if value not in SCHEMES:
        raise ValueError(f"resampling = {value!r} must be one of {tuple(SCHEMES)}")
    return value


def _threshold(value: Any) -> float:
    return real("resample_threshold", value, 0.0, 1.0)


def _augmented(value: Any) -> AugmentedMCL | None:
    if value is not None and not isinstance(value, AugmentedMCL):
        raise ArgumentTypeError(f"augmented = {value!r} must be an AugmentedMCL or None, not {type(value).__name__}")
    return value


def _roughening(value: Any) -> np.ndarray:
    array = check_sigma(value, "roughening").copy()
    array.flags.writeable = False
    return array


@keeps_arrays_frozen
class ParticleFilter:
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
    reference : bool, default False
        True runs every stage in plain numpy (`mcl.engine.ReferenceEngine`: the twins of `mcl.reference`, the
        models through their contracts, a soccer relocalization's injection by its numpy route): the same
        random draws, results equal to the compiled filter's to rounding, many times slower. For reading the
        algorithm and for tests; only with threads = 1 and fast = False.

    Raises
    ------
    ValueError
        If a number is out of range, `resampling` is unknown, or a model lacks a method of its contract.
    ArgumentTypeError
        If an argument has the wrong type (`field` not a `Field`, `fast` not a bool, ...); a ValueError too.
    """

    def __init__(
        self,
        field: Field,
        motion_model: MotionModel,
        sensor_model: SensorModel,
        n_particles: int = 500,
        seed: int | None = 0,
        resampling: str = "systematic",
        resample_threshold: float = 0.5,
        augmented: AugmentedMCL | None = AugmentedMCL(),
        grid: Grid = Grid(),
        roughening: tuple[float, float, float] = (0.02, 0.02, 0.02),
        threads: int = 1,
        fast: bool = False,
        relocalization: Relocalization | None = None,
        reference: bool = False,
    ) -> None:
        _check_field_and_seed(field, n_particles, seed)
        self.resampling = resampling  # (the setters check them)
        self.resample_threshold = resample_threshold
        _check_contract("motion_model", motion_model, MotionModel)
        _check_contract("sensor_model", sensor_model, SensorModel)
        self.roughening = roughening
        _check_engine_options(threads, fast, reference)
        self._field = field
        self._n = int(n_particles)
        self.motion_model = motion_model
        self.sensor_model = sensor_model
        self.augmented = augmented
        self.rng = np.random.default_rng(seed)
        self._summary = Summary(field, grid, int(n_particles), int(threads))
        self._injection = Injection()  # augmented MCL's running averages
        self.frame_fit = self.frame_log_likelihood = math.nan  # the last correction's evidence (see above)
        self.ess = float(n_particles)
        self.resampled = False  # whether the last correction resampled
        self.injected = 0  # particles injected by the last correction
        self.relocalization = SoccerRelocalization() if relocalization is None else relocalization
        _check_contract("relocalization", self.relocalization, Relocalization)  # which poses to inject
        self.relocalization.bind(self._summary.carpet)
        self._particles = Particles(int(n_particles), motion_model)
        self._engine = (
            ReferenceEngine(self._particles, self._summary)
            if reference
            else Engine(self._particles, self._summary, int(threads), bool(fast))
        )
        self.reset_uniform("field")

    # -- the particles, the summary, the engine and the settings -----------------------------------------------

    n: _Fixed[int] = _Fixed("_particles.n")
    """The number of particles N (fixed: the filter's arrays are made for it)."""
    poses: _Fixed[np.ndarray] = _Fixed(
        "_particles.poses",
        "ParticleFilter.poses cannot be rebound: use set_particles(poses, log_weights), which checks them",
    )
    """The particles, (N, 3) [x, y, θ]: the filter's own array, which its kernels work in. Replace them with
    `set_particles` (validated; the kernels trust the array's shape)."""
    log_weights: _Fixed[np.ndarray] = _Fixed(
        "_particles.log_weights",
        "ParticleFilter.log_weights cannot be "
        "rebound: use set_particles(poses, log_weights), which checks them "
        "and normalizes the weights",
    )
    """The particles' log-weights, (N,): the filter's own array (normalized with `weights`). Replace them with
    `set_particles`."""
    particles: _Fixed[Particles] = _Fixed("_particles")
    """The particle set (`mcl.particles.Particles`: named arrays, which the engine works in); change it through
    the filter's calls, which keep the summary and the relocalization in step."""
    summary: _Fixed[Summary] = _Fixed("_summary")
    """The summary (`mcl.summary.Summary`): the grid's cells, the histograms, the cached estimate and entropy
    and the estimate's hysteresis anchor."""
    engine: _Fixed[Engine] = _Fixed("_engine")
    """The engine that runs the filter's stages on its particles (`mcl.engine`): its stage calls let a benchmark
    time them one by one."""
    grid: _Fixed[Grid] = _Fixed("_summary.grid")
    """The entropy and estimate grid (fixed: the filter's histograms are made for it)."""
    entropy_bounds: _Fixed[tuple[float, float]] = _Fixed("_summary.entropy_bounds")
    """The largest possible position and orientation entropies: log2 of the cell counts."""
    field: _Fixed[Field] = _Fixed("_field")
    """The field (fixed: the carpet's bounds, the grid and the injection region are made for it)."""
    threads: _Fixed[int] = _Fixed("_engine.threads")
    """The number of threads the compiled step runs on (a constructor option)."""
    fast: _Fixed[bool] = _Fixed("_engine.fast")
    """Whether the compiled step computes sin, cos, exp and its sums the fast way (a constructor option)."""
    reference: _Fixed[bool] = _Fixed("_engine.reference")
    """Whether every stage runs in plain numpy (`mcl.engine.ReferenceEngine`; a constructor option)."""
    resampling: _Setting[str] = _Setting(_scheme)
    """The resampling scheme, one of `mcl.resampling.SCHEMES` (may be changed between steps)."""
    resample_threshold: _Setting[float] = _Setting(_threshold)
    """Resample when the ESS falls below this share of N, in [0, 1] (may be changed between steps)."""
    augmented: _Setting[AugmentedMCL | None] = _Setting(_augmented)
    """Augmented MCL's parameters, or None: no injection (may be changed between steps)."""
    roughening: _Setting[np.ndarray] = _Setting(_roughening)
    """The roughening's standard deviations (x [m], y [m], θ [rad]), read-only (may be replaced between steps by
    three finite numbers >= 0)."""
    w_slow: _Linked[float] = _Linked("_injection.w_slow")
    """Augmented MCL's long-term average likelihood per scored term (`mcl.augmented.Injection`; 0 after a
    reset)."""
    w_fast: _Linked[float] = _Linked("_injection.w_fast")
    """Augmented MCL's short-term average likelihood per scored term."""
    _resampling: str  # the settings' checked values
    _resample_threshold: float
    _augmented: AugmentedMCL | None
    _roughening: np.ndarray

    @property
    def weights(self) -> np.ndarray:
        """Normalized weights (a read-only view)."""
        return _read_only(self._particles.weights)

    @property
    def motion_state(self) -> np.ndarray | None:
        """The stateful motion model's per-particle state (a read-only view), or None for a stateless model."""
        state = self._particles.motion_state
        return None if state is None else _read_only(state)

    # -- resets -------------------------------------------------------------------------------------------------

    def reset_uniform(
        self, region: str | Sequence[float] = "field", heading: float | None = None, heading_sigma: float = 0.0
    ) -> None:
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
        self._reset(self._particles.uniform_poses(bounds, self.rng, heading, heading_sigma))
        self.relocalization.reset_region(bounds)

    def reset_around(
        self, pose: Sequence[float] | np.ndarray, sigma: Sequence[float] | np.ndarray = (0.1, 0.1, 0.1)
    ) -> None:
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
        self._reset(self._particles.normal_poses(pose.reshape(1, 3), check_sigma(sigma), self.rng))
        self.relocalization.reset_pose(pose)

    def reset_mirrored(self) -> None:
        """Mirror every particle through the centre mark: (x, y, θ) → (−x, −y, θ+π), weights kept."""
        self._mirror()
        self.relocalization.mirror()

    def reset_candidates(
        self,
        poses: Sequence[Sequence[float]] | np.ndarray,
        sigma: Sequence[float] | np.ndarray = (0.1, 0.1, 0.1),
        region: str | Sequence[float] = "field",
    ) -> None:
        """Spread the particles evenly over several candidate poses (K, 3), normal around each with `sigma`.

        For a placement the rules fix up to a choice the robot cannot know (which touchline, which kick-off
        position). Injection stays inside `region`, any heading, until the filter is confident (`reset_uniform`).

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
        candidates = check_poses("poses", poses, at_least=1)
        sigma, bounds = check_sigma(sigma), region_bounds(self._field, region)
        self._reset(self._particles.normal_poses(candidates, sigma, self.rng))
        self.relocalization.reset_region(bounds)

    def diffuse(self, sigma: Sequence[float] | np.ndarray = (0.1, 0.1, 0.3)) -> None:
        """Widen the belief: add normal noise `sigma` (x [m], y [m], θ [rad]) to every particle, weights kept.

        For what moved the robot without odometry seeing it (a fall and getting up, a push while standing).

        Parameters
        ----------
        sigma : sequence of float or numpy.ndarray, default (0.1, 0.1, 0.3)
            Standard deviations of the noise (x [m], y [m], θ [rad]), each finite and >= 0.

        Raises
        ------
        ValueError
            If a standard deviation is negative, not finite or too large.
        """
        sigma = check_sigma(sigma)
        self._particles.diffuse(sigma, self.rng)
        self._summary.forget_anchor()

    def reweigh(self, log_factors: Sequence[float] | np.ndarray) -> None:
        """Multiply each particle's weight by exp(log_factors[i]) and normalize; poses and motion state kept.

        For evidence that does not come through the sensor model (the teammates' view of the ball weighing the
        field's two halves, `mcl.localizer`). Nothing is resampled.

        Parameters
        ----------
        log_factors : array_like
            (N,) log factors: finite or -inf, not NaN or +inf, and at least one particle kept (finite).

        Raises
        ------
        ValueError
            If the shape is wrong, a factor is NaN or +inf, or every factor is -inf (the filter is left as it
            was).
        """
        self.ess = self._particles.reweigh(log_factors)
        self._summary.changed()

    def set_particles(
        self,
        poses: Sequence[Sequence[float]] | np.ndarray,
        log_weights: Sequence[float] | np.ndarray | None = None,
        motion_state: np.ndarray | None = None,
    ) -> None:
        """Replace the particle set (N, 3) and optionally its log-weights (N,) and, for a stateful motion model,
        its per-particle state (fresh when not given); validated first.

        Parameters
        ----------
        poses : array_like
            (N, 3) poses (x [m], y [m], θ [rad]), N the filter's particle count.
        log_weights : array_like or None, default None
            (N,) log-weights, normalized here: no NaN or +inf, at least one finite. None: uniform weights.
        motion_state : numpy.ndarray or None, default None
            The motion model's per-particle state, of the shape the filter keeps (finite); None: fresh state.

        Raises
        ------
        ValueError
            If a shape is wrong, a value out of range, or `motion_state` is given for a motion model that
            keeps none (the particles are left unchanged).
        """
        ess = self._particles.replace(poses, log_weights, motion_state)
        self._summary.forget_anchor()
        self.ess = ess

    def _reset(self, poses: np.ndarray) -> None:
        """`_assign` for a reset: augmented MCL's averages start afresh too."""
        self._assign(poses)
        self._injection.restart()

    def _assign(self, poses: np.ndarray) -> None:
        """New poses with equal weights and fresh motion state; the estimate's hysteresis starts afresh."""
        self._particles.assign(poses)
        self._summary.forget_anchor()
        self.ess = float(self._n)

    def _mirror(self) -> None:
        """Every particle through the centre mark, weights kept; the estimate's hysteresis starts afresh."""
        self._particles.mirror(self._field)
        self._summary.forget_anchor()

    # -- the algorithm ------------------------------------------------------------------------------------------

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
        self._predict(u, self._engine.motion(self.motion_model, u))

    def _predict(self, u: MotionInput, motion: tuple[float, ...] | None) -> None:
        """Move the particles by `u` (checked: `motion` is the engine's answer for it) and carry the
        relocalization's anchors along."""
        self._engine.predict(self.motion_model, u, self.rng, motion)
        if motion is None:
            self.relocalization.carry(*u.displacement())
        else:
            self.relocalization.carry(motion[0], motion[1], motion[2])
        self._summary.changed()

    def correct(
        self, observations: Observations | Iterable | None, since: Sequence[float] | np.ndarray | None = None
    ) -> None:
        """Weigh the particles by the detections, then resample (and inject) if needed.

        A frame with its camera view (`Observations.view`) is also scored by the landmarks each particle puts in
        view that the frame did not report, when the sensor model does so (`scores_view`, negative information).

        Parameters
        ----------
        observations : Observations, iterable of LandmarkObservation, or None
            One camera frame's detections (coerced by `Observations.coerce`); None or empty changes nothing.
        since : sequence of float, numpy.ndarray or None, default None
            For detections captured earlier (camera latency), the robot's motion (dx [m], dy [m], dθ [rad])
            from their capture to now, in the robot frame at capture (`mcl.latency.MotionHistory.since`): each
            particle is scored where it was at capture, moved back along it. None or (0, 0, 0): as it is.

        Raises
        ------
        ValueError
            If the sensor model refuses the detections, `since` is out of range, or the sensor model returns
            NaN or +inf log-likelihoods; the filter is left unchanged.
        """
        observations = Observations.coerce(observations)
        motion_since = self._since(since, observations)
        if self._engine.fuses(self.sensor_model, observations):
            self._correct_fused(None, observations, False, motion_since)
        else:
            self.sensor_model.check(observations)
            self._correct(observations, motion_since)

    def step(self, u: MotionInput, observations: Observations | Iterable | None = None) -> Estimate:
        """predict(u), then correct(observations) when there are any; returns the estimate.

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
            If the motion model refuses `u` or the sensor model the detections (both are checked before anything
            changes), or the sensor model returns NaN or +inf log-likelihoods (the particles have then moved,
            their weights are unchanged: the message says so).
        """
        observations = Observations.coerce(observations)
        fused = self._engine.fuses(self.sensor_model, observations)
        motion = self._predict_checked(u, observations, fused)
        if fused:
            self._correct_fused(motion, observations, True)
        else:
            self._correct_moved(observations)
        return self.estimate()

    def _predict_checked(self, u: MotionInput, observations: Observations, fused: bool) -> tuple | None:
        """Check `u` and the detections (a refused call names the detection first), then predict unless the
        fused step will; returns the engine's motion for `u` (`Engine.motion`)."""
        try:
            motion = self._engine.motion(self.motion_model, u)
        except ValueError:
            self.sensor_model.check(observations)
            raise
        if not fused or motion is None:
            self.sensor_model.check(observations)  # before the particles move
            self._predict(u, motion)
        return motion

    def _correct_moved(self, observations: Observations) -> None:
        """`_correct` in a step, after the particles moved: a defect of the sensor model says that they did."""
        try:
            self._correct(observations)
        except ValueError as error:
            if str(error).startswith(_INVALID_LIKELIHOODS):
                raise ValueError(_INVALID_LIKELIHOODS + _MOVED) from None
            raise

    def _since(self, since, observations: Observations) -> np.ndarray | None:
        """`since` checked before any kernel is prepared (a refusal changes nothing; the detections are checked
        first): None when the detections were captured now."""
        try:
            return check_since(since)
        except ValueError:
            self.sensor_model.check(observations)
            raise

    def estimate(self) -> Estimate:
        """Weighted circular mean and covariance of the dominant cluster (cached until the particles change).

        When no cluster holds half the weight, the one around the previous estimate is preferred if it is
        the heavier (hysteresis: see `mcl.estimate.cluster_estimate`).

        Returns
        -------
        Estimate
            The pose [x, y, θ], its (3, 3) covariance and the cluster's share of the weight.
        """
        return self._engine.estimate()

    def entropy(self) -> Entropy:
        """Position and orientation entropy in bits on the grid (Hoffmann eq. 27), from the histograms the
        estimate shares (kept until the particles change).

        Returns
        -------
        Entropy
            `position` and `orientation`, in bits.
        """
        return self._engine.entropy()

    def _correct(self, observations: Observations, since: np.ndarray | None = None) -> None:
        """Weigh by the frame stage by stage: likelihood, weights, then resampling and injection if needed."""
        if observations.is_empty:
            return
        engine = self._engine
        log_likelihood = engine.likelihood(self.sensor_model, observations, since)
        valid, native_log_average, log_evidence, ess = engine.weigh(log_likelihood, self._n - self.injected)
        if not valid:
            raise ValueError(_INVALID_LIKELIHOODS + "; filter left unchanged")
        terms = getattr(self.sensor_model, "terms", len)(observations)
        self._weighed(native_log_average, terms)
        self._summary.changed()
        if log_evidence == -np.inf:
            self._unexplained(observations, since)
            return
        engine.reweigh(log_likelihood, log_evidence)
        self.ess = ess
        a = self._augmented
        fraction = self._injection.update(a, native_log_average / terms) if a is not None and terms > 0 else 0.0
        count = self._injection_count(fraction)
        if count > 0 or ess < self._resample_threshold * self._n:
            self._resample(count, observations, since)
        else:
            self.resampled = False
            self.injected = 0
        self._track_confidence()

    def _weighed(self, native_log_average: float, terms: int) -> None:
        """Keep the frame's evidence (`frame_log_likelihood`, and `frame_fit` per term scored)."""
        self.frame_log_likelihood = native_log_average
        if terms > 0:
            self.frame_fit = math.exp(native_log_average / terms)

    def _unexplained(self, observations: Observations, since: np.ndarray | None) -> None:
        """Every particle has zero likelihood: the belief cannot explain the detections. Recover by keeping the
        particles with uniform weights and replacing the largest allowed share by injected ones; nothing else
        (no NaN) can come out of this."""
        self._particles.weights[:] = 1.0 / self._n
        self._resample(self._injection_count(1.0), observations, since)

    def _correct_fused(
        self, motion: tuple | None, observations: Observations, in_step: bool, since: np.ndarray | None = None
    ) -> None:
        """[predict by `motion`,] correct(observations) [captured `since` ago] in the engine's fused step."""
        a = self._augmented
        terms = getattr(self.sensor_model, "terms", len)(observations)
        augmented = self._injection.kernel_arguments(a, self.relocalization.tracking)
        # Only an estimate the stages one by one compute (after a correction with augmentation, or at the end of
        # `step`) may be computed here: computing one moves the hysteresis anchor.
        want_estimate = in_step or a is not None
        outcome = self._engine.fused_step(
            self.motion_model,
            motion,
            self.sensor_model,
            observations,
            (self._n - self.injected, terms, *augmented),
            (self._resampling, self._resample_threshold, self._roughening),
            want_estimate,
            since,
            self.rng,
        )
        if outcome.status == STEP_MISSING:
            self.sensor_model.check(observations)  # raises, naming the detection; nothing has changed
            raise ValueError(
                "the sensor model's fused kernels refuse a detection that its check() accepts; filter left unchanged"
            )
        if motion is not None:  # the particles have moved, whatever follows
            self.relocalization.carry(motion[0], motion[1], motion[2])
        if outcome.status == STEP_INVALID:
            raise ValueError(_INVALID_LIKELIHOODS + (_MOVED if motion is not None else "; filter left unchanged"))
        self._weighed(outcome.native_log_average, terms)
        if outcome.status == STEP_UNEXPLAINED:
            self._unexplained(observations, since)
            return
        self.ess = outcome.ess
        if a is not None and terms > 0:
            self._injection.w_slow, self._injection.w_fast = outcome.w_slow, outcome.w_fast
        if outcome.status == STEP_RESAMPLE:
            count = self._injection_count(outcome.fraction)
            if count > 0 and self._engine.resamples_fused(self._resampling):
                self._inject_fused(count, observations, want_estimate, since)
            else:
                self._resample(count, observations, since)
        else:
            self.resampled = outcome.resampled
            self.injected = 0
        self._track_confidence()

    def _inject_fused(
        self, count: int, observations: Observations, want_estimate: bool, since: np.ndarray | None
    ) -> None:
        """The end of a fused step that injects: `_resample` and the summary that follows it, in one call."""
        injected = self._sample_injection(count, observations)
        if since is not None:  # placed where the detections were captured: carried to now
            move_forward(injected, since, injected)
        self._engine.resample_and_summarize(injected, self._roughening, want_estimate, self.rng)
        self.ess = float(self._n)
        self.resampled = True
        self.injected = count

    def _track_confidence(self) -> None:
        """Tell the relocalization what the correction left: the estimate, and whether the belief explains the
        detections as well as it usually does (`Injection.fits`)."""
        if self._augmented is None:
            return
        estimate = self.estimate()
        if self.relocalization.confirm(estimate, self._injection.fits(self._augmented)):
            # The relocalization's prior puts the belief on the mirror side of the field, which the detections
            # cannot tell from this one (the field is point-symmetric): the particles go there, weights kept.
            self._mirror()

    def _injection_count(self, fraction: float) -> int:
        """How many particles to inject for the share `fraction`, within the cap (none without augmented MCL)."""
        return Injection.count(self._augmented, fraction, self._n, self.relocalization.tracking)

    def _sample_injection(self, count: int, observations: Observations) -> np.ndarray:
        """`count` poses for augmented MCL to inject, as the relocalization proposes them (`propose`; a soccer
        relocalization by its numpy route on the reference engine)."""
        options = (
            {"reference": True} if self.reference and isinstance(self.relocalization, SoccerRelocalization) else {}
        )
        return np.ascontiguousarray(
            self.relocalization.propose(count, observations, self.sensor_model, self.rng, **options), dtype=np.float64
        )

    def _resample(self, count: int, observations: Observations, since: np.ndarray | None = None) -> None:
        """Resample N - count particles by the scheme and inject `count` the relocalization proposes."""
        injected = self._sample_injection(count, observations) if count > 0 else NO_VARIATES
        if since is not None and injected.shape[0]:
            # Sensor resetting placed them where the detections were captured: carry them to now.
            move_forward(injected, since, injected)
        self._engine.resample(self._resampling, injected, self._roughening, self.rng)
        self.ess = float(self._n)
        self.resampled = True
        self.injected = int(injected.shape[0])
        self._summary.changed()


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view
