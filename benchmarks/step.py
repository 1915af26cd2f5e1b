"""The filter step of `robocup-mcl bench`, timed whole and phase by phase against plain numpy.

    from benchmarks.step import bench_setup, measure, time_size
    pf, u, observations = bench_setup(10_000)     # a filter, a motion input, 10 goalposts and 12 line points
    row = time_size(10_000, budget_s=0.2)         # full step and every phase, numba and numpy
    timed = measure({"a": f, "b": g}, budget_s=0.5)   # medians of f() and g(), called in turn

The step: predict (velocity-linear), correct with 10 detections of a 4-way ambiguous type (goalposts),
normalize and ESS, systematic resampling, estimate (dominant cluster), entropy. The numba step is timed
through the filter's public calls (`step` + `entropy`, resampling forced every step); the numpy step is
`benchmarks.reference.numpy_step`, the same computation in plain numpy. Each phase of `PHASES` pairs the numba call
the filter makes with its numpy twin (`mcl.reference`, `motion_models.reference`, a model's `numpy_twin()`);
phases that have no twin (recording) say so.
Timings: the candidates are called in turn (A, B, A, B, ...) and the median is taken, so a machine shared with
other work biases both alike; ratios compare figures of one run.
"""

from __future__ import annotations

import inspect
import math
import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from field import spl
from mcl import resampling
from mcl.filter import AugmentedMCL, ParticleFilter
from mcl.reference import gather_with_jitter as gather_with_jitter_reference
from mcl.reference import normalize as normalize_reference
from mcl.reference import summary_entropy as summary_entropy_reference
from mcl.reference import summary_estimate as summary_estimate_reference
from mcl.reference import systematic as systematic_reference
from mcl.resampling import gather_with_jitter, systematic
from mcl.weights import normalize
from motion_models import AdaptiveMotion, MotionInput, VelocityLinear
from motion_models.adaptive import VARIATES
from motion_models.reference import adaptive_move as adaptive_move_reference
from motion_models.reference import move_with_noise as move_with_noise_reference
from numerics.random import draw_variates
from numerics.trig import SQRT3
from proprioception.collision import NO_COLLISION, CollisionPercept
from sensing import LandmarkSensorModel, Observations
from sensing.lines import LineSensorModel

from .reference import issue_shaped_step, numpy_step, sample_injection_reference

TRUE_POSE = np.array([1.0, 0.5, 0.3])
# The fused resampling kernels the filter may call (resampling, copy and roughening in one pass, uniforms drawn
# in the kernel from the generator's bit generator), in order of preference; their leading parameters, and
# the scratch the benchmark knows how to fill for the ones after (what the filter passes when it wants none).
FUSED_KERNELS = ("resample_with_jitter", "systematic_with_jitter")
FUSED_LEADING = ["weights", "m", "source", "bounds", "out", "trig", "function", "state"]
FUSED_SCRATCH = {
    "counts": lambda m: np.zeros(m + 1, dtype=np.int64),  # zero between calls
    "coordinates": lambda m: np.empty((3, 0)),
}  # no split coordinates wanted


def fused_resampler():
    """(name, prepare) for the fused resampling kernel of `mcl.resampling`, or None when it has none.

    prepare(weights, m, source, bounds, out, rng) returns a zero-argument call that resamples m particles of
    `source` into `out` as the filter does: scratch allocated once, as the filter keeps it, and the cos and sin
    of the source headings known, as the step's scoring leaves them for the roughening (computed here once, from
    the headings `source` has now)."""
    from numerics import random as _kernels

    handle = getattr(_kernels, "bit_generator_handle", None)
    if handle is None:
        return None
    for name in FUSED_KERNELS:
        kernel = getattr(resampling, name, None)
        if kernel is None:
            continue
        try:
            parameters = list(inspect.signature(getattr(kernel, "py_func", kernel)).parameters)
        except (TypeError, ValueError):
            continue
        extra = parameters[len(FUSED_LEADING) :]
        if parameters[: len(FUSED_LEADING)] != FUSED_LEADING or not set(extra) <= set(FUSED_SCRATCH):
            continue

        def prepare(weights, m, source, bounds, out, rng, kernel=kernel, extra=tuple(extra)):
            function, state = handle(rng)
            scratch = tuple(FUSED_SCRATCH[name](m) for name in extra)
            trig = np.ascontiguousarray(np.stack([np.cos(source[:, 2]), np.sin(source[:, 2])], axis=1))
            return lambda: kernel(weights, m, source, bounds, out, trig, function, state, *scratch)

        return name, prepare
    return None


FUSED = fused_resampler()
COLLISION = CollisionPercept(left=True, s_rel_left=1.5, rate=0.3, recent_left=True)


def stationary_mobility(model: AdaptiveMotion, u: MotionInput, n: int, rng: np.random.Generator) -> np.ndarray:
    """A particle state (n, 4) whose mobility states are drawn from the stationary distribution of the transitions
    that `u`'s percept selects (the mix a filter holds after a while in that condition), episode values uniform.
    Timed from there, the phase costs the same however many times it is called; from all-free states it would
    drift through the transient."""
    matrix = model.transitions.matrix(model.condition(u.collision), u.dt)
    values, vectors = np.linalg.eig(matrix.T)
    stationary = np.abs(np.real(vectors[:, np.argmin(np.abs(values - 1.0))]))
    state = model.particle_state(n)
    state[:, 0] = rng.choice(stationary.shape[0], size=n, p=stationary / stationary.sum())
    state[:, 1:] = rng.random((n, state.shape[1] - 1))
    return state


@dataclass(frozen=True)
class Phase:
    """One phase of the step: what the numba side calls, and its numpy twin (None: there is none)."""

    name: str
    description: str
    numba_entry: str
    numpy_entry: str | None


PHASES = (
    Phase(
        "predict_velocity_linear",
        "motion model: velocity-linear (Hoffmann eq. 10), variates drawn included",
        "VelocityLinear.predict",
        "motion_models.reference.move_with_noise",
    ),
    Phase(
        "predict_adaptive",
        "motion model: adaptive, five mobility states, during frequent collisions (Hoffmann "
        "eq. 11-26), the states in that condition's stationary mix",
        "AdaptiveMotion.predict(state=...)",
        "motion_models.reference.adaptive_move",
    ),
    Phase(
        "predict_adaptive_quiet",
        "motion model: adaptive, walking without collisions (every particle free)",
        "AdaptiveMotion.predict(state=...)",
        "motion_models.reference.adaptive_move",
    ),
    Phase(
        "likelihood_von_mises",
        "landmark likelihood, 10 goalposts, fast von Mises bearing term",
        "LandmarkSensorModel.log_likelihood",
        "LandmarkSensorModel.numpy_twin().log_likelihood",
    ),
    Phase(
        "likelihood_exact",
        "landmark likelihood, 10 goalposts, exact atan2 bearing term",
        "LandmarkSensorModel(bearing_model='exact').log_likelihood",
        "LandmarkSensorModel(bearing_model='exact').numpy_twin().log_likelihood",
    ),
    Phase(
        "likelihood_lines",
        "line likelihood field, 12 line points (sensing/lines.py)",
        "LineSensorModel.log_likelihood",
        "LineSensorModel.numpy_twin().log_likelihood",
    ),
    Phase(
        "normalize",
        "normalization (log-sum-exp) and ESS, prior log-weights + log-likelihood included",
        "mcl.weights.normalize",
        "mcl.reference.normalize",
    ),
    Phase(
        "resample",
        "systematic resampling and the roughening copy (gather with jitter), the headings' cos "
        "and sin known (the step's scoring leaves them)",
        f"mcl.resampling.{FUSED[0]} (fused, uniforms drawn in the kernel)"
        if FUSED
        else "mcl.resampling.systematic + gather_with_jitter",
        "mcl.reference.systematic + gather_with_jitter",
    ),
    Phase(
        "injection",
        "augmented-MCL injection of max_fraction (25 %) of N: half drawn from the detections "
        "(sensor resetting), half uniform over the field, headings around a trusted reference",
        "ParticleFilter._sample_injection (numpy's integers and normals, the rest compiled)",
        "benchmarks.reference.sample_injection_reference",
    ),
    Phase(
        "estimate",
        "estimate: dominant cluster (histogram seed, mean shift), weighted circular mean",
        "ParticleFilter.estimate (what it keeps dropped first)",
        "mcl.reference.summary_estimate",
    ),
    Phase(
        "entropy",
        "grid entropy, position and orientation (Hoffmann eq. 27); where the filter shares its "
        "histograms with the estimate, both phases include filling them",
        "ParticleFilter.entropy (what it keeps dropped first)",
        "mcl.reference.summary_entropy",
    ),
    Phase(
        "recording",
        "recording one step to Rerun (a temporary .rrd), particles logged every step",
        "mcl.tools.recording.Recorder.log_step",
        None,
    ),
)
PHASE_NAMES = tuple(p.name for p in PHASES)


# -- timing ----------------------------------------------------------------------------------------------------
def measure(
    work: dict[str, Callable[[], object]],
    budget_s: float,
    min_samples: int = 3,
    max_samples: int = 300,
    sample_s: float = 2e-4,
) -> dict[str, dict]:
    """Median seconds per call of each zero-argument callable, called in turn (A, B, A, B, ...).

    Each callable is called once to warm up (numba compiles or loads its cache there), once more to estimate
    its cost (a sample too when it took more than 50 ms); a sample is then as many calls as last about
    `sample_s` (at least one), and each callable gets about `budget_s` worth of samples (between `min_samples`
    and `max_samples`), spread evenly over the rounds.
    Returns {name: {"s": median, "samples": count, "calls_per_sample": k, "spread": interquartile / median}}.
    """
    clock = time.perf_counter
    cost = {}
    for name, fn in work.items():
        fn()
        start = clock()
        fn()
        cost[name] = max(clock() - start, 1e-9)
    calls = {name: max(1, int(sample_s / c)) for name, c in cost.items()}
    samples = {name: int(min(max_samples, max(min_samples, budget_s / (cost[name] * calls[name])))) for name in work}
    # A slow call's cost estimate is a sample already (it is what repetitions would measure).
    times: dict[str, list[float]] = {
        name: [cost[name]] if calls[name] == 1 and cost[name] > 0.05 else [] for name in work
    }
    rounds = max(samples.values(), default=0)
    for r in range(rounds):
        for name, fn in work.items():
            if len(times[name]) >= math.ceil((r + 1) * samples[name] / rounds):
                continue
            k = calls[name]
            start = clock()
            for _ in range(k):
                fn()
            times[name].append((clock() - start) / k)
    result = {}
    for name, values in times.items():
        median = statistics.median(values)
        quartiles = statistics.quantiles(values, n=4) if len(values) >= 2 else [median, median, median]
        result[name] = {
            "s": median,
            "samples": len(values),
            "calls_per_sample": calls[name],
            "spread": (quartiles[2] - quartiles[0]) / median if median > 0 else 0.0,
        }
    return result


# -- the scene -------------------------------------------------------------------------------------------------
def bench_setup(n: int, bearing_model: str = "von_mises", seed: int = 0, motion_model=None, **filter_options):
    """A filter of n particles around TRUE_POSE, a motion input, and 10 goalpost detections.

    Resampling every step (threshold 1), injection off unless `augmented` is given: the step does the same work
    every time. The motion model is velocity-linear unless given; the motion input reports no collision.
    `filter_options` go to `ParticleFilter`; its threads option, if it has one, is 1 unless given.
    """
    option = threads_option()
    if option is not None:
        filter_options.setdefault(option, 1)
    filter_options.setdefault("augmented", None)
    field = spl()
    sensor = LandmarkSensorModel(field, bearing_model=bearing_model)
    pf = ParticleFilter(
        field,
        motion_model or VelocityLinear(),
        sensor,
        n_particles=n,
        seed=seed,
        resample_threshold=1.0,
        **filter_options,
    )
    pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
    rng = np.random.default_rng(seed + 1)
    posts = field.landmarks_of("goalpost")
    picks = posts[rng.integers(0, len(posts), 10)]
    d = picks - TRUE_POSE[:2]
    ranges = np.hypot(d[:, 0], d[:, 1]) + 0.05 * rng.standard_normal(10)
    bearings = np.arctan2(d[:, 1], d[:, 0]) - TRUE_POSE[2] + 0.03 * rng.standard_normal(10)
    observations = Observations.from_arrays(["goalpost"] * 10, ranges, bearings, line_points=line_points(field, rng))
    return pf, MotionInput(dt=0.01, command=(0.2, 0.0, 0.1), collision=NO_COLLISION), observations


def line_points(field, rng: np.random.Generator, count: int = 12, reach: float = 3.0) -> np.ndarray:
    """`count` points on the field lines within `reach` of TRUE_POSE, in its robot frame, with 2 cm noise."""
    points = field.line_points(spacing=0.1)
    d = points - TRUE_POSE[:2]
    near = points[np.hypot(d[:, 0], d[:, 1]) <= reach]
    chosen = near[np.linspace(0, near.shape[0] - 1, count).round().astype(np.int64)] - TRUE_POSE[:2]
    c, s = math.cos(TRUE_POSE[2]), math.sin(TRUE_POSE[2])
    robot = np.stack([c * chosen[:, 0] + s * chosen[:, 1], -s * chosen[:, 0] + c * chosen[:, 1]], axis=1)
    return robot + 0.02 * rng.standard_normal(robot.shape)


def threads_option() -> str | None:
    """The name of `ParticleFilter`'s threads option, if it has one."""
    parameters = inspect.signature(ParticleFilter).parameters
    for name in ("threads", "n_threads", "num_threads", "workers"):
        if name in parameters:
            return name
    return None


# -- the full step ---------------------------------------------------------------------------------------------
def stepping(pf: ParticleFilter, u: MotionInput, observations: Observations) -> Callable[[], None]:
    """One full step of `pf` through the filter's public calls: `step` (predict, correct, resample, estimate)
    and `entropy`."""

    def step():
        pf.step(u, observations)
        pf.entropy()

    return step


def full_step_work(n: int, bearing_model: str = "von_mises", **filter_options) -> Callable[[], object]:
    """`stepping` on `bench_setup`'s filter."""
    return stepping(*bench_setup(n, bearing_model, **filter_options))


def injecting_setup(n: int):
    """`bench_setup` with augmented MCL injecting every step: the detections' fit stays below `fit_threshold`
    and the pose is known (`reset_around` takes TRUE_POSE as the relocalization's anchor), so 5 % of N
    (`max_fraction_tracking`) are replaced each step, chosen by `mcl.relocalization` among candidates drawn
    from the detections."""
    return bench_setup(n, augmented=AugmentedMCL(fit_threshold=1e9))


def injecting_step_work(n: int) -> Callable[[], object]:
    """`stepping` on `injecting_setup`'s filter."""
    return stepping(*injecting_setup(n))


def adaptive_setup(n: int):
    """`bench_setup` with Hoffmann's adaptive motion model in place of velocity-linear, walking without
    collisions: its predict is its own kernel, the rest the compiled step, whose resampling carries each
    particle's mobility state to its offspring."""
    return bench_setup(n, motion_model=AdaptiveMotion())


def adaptive_step_work(n: int) -> Callable[[], object]:
    """`stepping` on `adaptive_setup`'s filter."""
    return stepping(*adaptive_setup(n))


def issue_step_work(n: int, **filter_options) -> Callable[[], object]:
    """The issue's step shape (`benchmarks.reference.issue_shaped_step`: no roughening, no estimate) on the filter's
    kernels and buffers."""
    pf, u, observations = bench_setup(n, **filter_options)
    return issue_shaped_step(pf, u, observations)


def fast_option() -> bool:
    """Whether `ParticleFilter` has the fast-math option."""
    return "fast" in inspect.signature(ParticleFilter).parameters


def numpy_step_work(n: int) -> Callable[[], object]:
    """The same step in plain numpy (`benchmarks.reference.numpy_step`, on a copy of the particles)."""
    pf, u, observations = bench_setup(n)
    return lambda: numpy_step(pf, u, observations)


# -- the phases ------------------------------------------------------------------------------------------------
def _forget_summary(pf: ParticleFilter) -> None:
    """Drop what the filter keeps until its particles change (the estimate, the histograms it shares with the
    entropy), so that the next call computes it."""
    pf.summary.changed()


def fresh_estimate(pf: ParticleFilter):
    """`pf.estimate()` computed anew."""
    _forget_summary(pf)
    return pf.estimate()


def fresh_entropy(pf: ParticleFilter):
    """`pf.entropy()` computed anew."""
    _forget_summary(pf)
    return pf.entropy()


class PhaseScene:
    """Everything the phases work on at one N: particles after a step, their weights, models, buffers."""

    def __init__(self, n: int, recording_dir: str | None = None):
        self.n = n
        pf, u, observations = bench_setup(n)
        pf.step(u, observations)
        if fresh_estimate(pf) is fresh_estimate(pf):
            raise RuntimeError(
                "ParticleFilter.estimate() does not recompute after summary.changed(): "
                "benchmarks.step._forget_summary needs the filter's new way to drop its estimate"
            )
        self.pf, self.u, self.observations = pf, u, observations
        self.rng = np.random.default_rng(7)
        field = pf.field
        self.velocity_linear = pf.motion_model
        self.adaptive = AdaptiveMotion()
        self.u_collision = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1), collision=COLLISION)
        self.von_mises = pf.sensor_model
        self.exact = LandmarkSensorModel(field, bearing_model="exact")
        self.lines = LineSensorModel(field)
        self.poses = {side: pf.poses.copy() for side in ("numba", "numpy")}
        self.u_quiet = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1), collision=NO_COLLISION)
        mix = stationary_mobility(self.adaptive, self.u_collision, n, np.random.default_rng(11))
        self.state = {side: mix.copy() for side in ("numba", "numpy")}
        self.state_quiet = {side: self.adaptive.particle_state(n) for side in ("numba", "numpy")}
        self.log_weights = pf.log_weights.copy()
        self.log_likelihood = self.von_mises.log_likelihood(pf.poses, self.observations)
        self.weights = np.empty(n)
        normalize(self.log_weights + self.log_likelihood, self.weights)
        self.out = np.empty(n)
        self.resampled = np.empty((n, 3))
        self.jitter = pf.roughening * SQRT3
        self.injected = int(round(AugmentedMCL().max_fraction * n))
        self.recording_dir = recording_dir
        self._recorder = None
        self._step = 0

    # numba side (what the filter calls) ------------------------------------------------------------------
    def numba_work(self) -> dict[str, Callable[[], object]]:
        pf, landmarks, n = self.pf, self.observations, self.n
        poses, state, quiet = self.poses["numba"], self.state["numba"], self.state_quiet["numba"]
        injecting = self.injecting_filter()

        if FUSED is not None:
            resample = FUSED[1](self.weights, n, poses, self.jitter, self.resampled, self.rng)
        else:

            def resample():
                ancestors = systematic(self.weights, n, self.rng)
                gather_with_jitter(poses, ancestors, self.jitter, draw_variates(self.rng, n, False), self.resampled)

        work = {
            "predict_velocity_linear": lambda: self.velocity_linear.predict(poses, self.u, self.rng),
            "predict_adaptive": lambda: self.adaptive.predict(poses, self.u_collision, self.rng, state=state),
            "predict_adaptive_quiet": lambda: self.adaptive.predict(poses, self.u_quiet, self.rng, state=quiet),
            "likelihood_von_mises": lambda: self.von_mises.log_likelihood(poses, landmarks, out=self.out),
            "likelihood_exact": lambda: self.exact.log_likelihood(poses, landmarks, out=self.out),
            "likelihood_lines": lambda: self.lines.log_likelihood(poses, self.observations, out=self.out),
            "normalize": lambda: normalize(self.log_weights + self.log_likelihood, self.weights),
            "resample": resample,
            "injection": lambda: injecting._sample_injection(self.injected, landmarks),
            "estimate": lambda: fresh_estimate(pf),
            "entropy": lambda: fresh_entropy(pf),
        }
        if self.recording_dir is not None:
            work["recording"] = self.record
        return work

    # numpy side (the references) -----------------------------------------------------------------------------
    def numpy_work(self) -> dict[str, Callable[[], object]]:
        pf, landmarks, n = self.pf, self.observations, self.n
        poses, state, quiet = self.poses["numpy"], self.state["numpy"], self.state_quiet["numpy"]
        injecting = self.injecting_filter()
        model = self.velocity_linear

        def predict_velocity_linear():
            move_with_noise_reference(
                poses,
                *self.u.displacement(),
                *model.noise_bounds(self.u),
                model.gaussian,
                draw_variates(self.rng, n, model.gaussian),
            )

        def predict_adaptive():
            adaptive_move_reference(
                poses, state, *self.adaptive.kernel_arguments(self.u_collision), self.rng.random((n, VARIATES))
            )

        def predict_adaptive_quiet():
            adaptive_move_reference(
                poses, quiet, *self.adaptive.kernel_arguments(self.u_quiet), self.rng.random((n, VARIATES))
            )

        def resample():
            ancestors = systematic_reference(self.weights, n, self.rng)
            gather_with_jitter_reference(poses, ancestors, self.jitter, draw_variates(self.rng, n, False))

        # The estimate and the entropy of the filter's own particles, as the numba side computes them.
        s = pf.summary

        def estimate():
            summary_estimate_reference(s, pf.poses, pf.weights, use_previous=False)

        def entropy():
            summary_entropy_reference(s, pf.poses, pf.weights)

        return {
            "predict_velocity_linear": predict_velocity_linear,
            "predict_adaptive": predict_adaptive,
            "predict_adaptive_quiet": predict_adaptive_quiet,
            "likelihood_von_mises": lambda: self.von_mises.numpy_twin().log_likelihood(poses, landmarks),
            "likelihood_exact": lambda: self.exact.numpy_twin().log_likelihood(poses, landmarks),
            "likelihood_lines": lambda: self.lines.numpy_twin().log_likelihood(poses, self.observations),
            "normalize": lambda: normalize_reference(self.log_weights + self.log_likelihood),
            "resample": resample,
            "injection": lambda: sample_injection_reference(injecting, self.injected, landmarks),
            "estimate": estimate,
            "entropy": entropy,
        }

    def injecting_filter(self) -> ParticleFilter:
        """A filter of N particles with augmented MCL whose pose is known (`reset_around` TRUE_POSE: the
        relocalization's anchor), on the scene's sensor model and generator, for the injection phase."""
        pf = ParticleFilter(
            self.pf.field, self.velocity_linear, self.von_mises, n_particles=self.n, seed=7, augmented=AugmentedMCL()
        )
        pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
        pf.rng = self.rng
        return pf

    def record(self):
        if self._recorder is None:
            from mcl.tools.recording import Recorder

            path = Path(self.recording_dir) / f"bench-{self.n}.rrd"
            self._recorder = Recorder(path, self.pf.field, particles_every=1)
        self._step += 1
        self._recorder.log_step(self._step, 0.01 * self._step, self.pf, truth=TRUE_POSE, observations=self.observations)

    def close(self):
        if self._recorder is not None:
            self._recorder.close()
            self._recorder = None


def time_size(n: int, budget_s: float, exact: bool = True, recording: bool = True, min_samples: int = 3) -> dict:
    """The full step (numba, numpy, and numba with the exact bearing term) and every phase at one N."""
    work = {
        "full_step/numba": full_step_work(n),
        "full_step/numpy": numpy_step_work(n),
        "issue_step/numba": issue_step_work(n),
        "injecting_step/numba": injecting_step_work(n),
        "adaptive_step/numba": adaptive_step_work(n),
    }
    if fast_option():
        work["full_step_fast/numba"] = full_step_work(n, fast=True)
        work["issue_step_fast/numba"] = issue_step_work(n, fast=True)
    if exact:
        work["full_step_exact/numba"] = full_step_work(n, "exact")
    errors = {}
    with tempfile.TemporaryDirectory(prefix="robocup-mcl-bench-") as directory:
        scene = PhaseScene(n, directory if recording else None)
        try:
            for side, table in (("numba", scene.numba_work()), ("numpy", scene.numpy_work())):
                for name, fn in table.items():
                    if name == "likelihood_exact" and not exact:
                        continue
                    try:  # a phase whose call fails is reported, the others are still timed
                        fn()
                    except Exception as error:
                        errors.setdefault(name, f"{side}: {type(error).__name__}: {error}")
                        continue
                    work[f"{name}/{side}"] = fn
            # One call per sample: every timed call follows calls of the other items, whatever it costs. (Samples
            # of about 0.2 ms made a sample of a 30 µs step one such call and six warm ones, and at N = 1 000 one
            # call or two depending on a single estimate of its cost: 0.17 against 0.12 ms on the same code.)
            timed = measure(work, budget_s, min_samples=min_samples, sample_s=0.0)
        finally:
            scene.close()
    # The same step called back to back (samples of about 20 ms of consecutive calls): caches and branch
    # predictors warm, as a loop that runs nothing but the step measures it.
    timed["full_step_back_to_back/numba"] = measure(
        {"step": work["full_step/numba"]}, budget_s, min_samples, sample_s=0.02
    )["step"]
    fast, slow = timed["full_step/numba"], timed["full_step/numpy"]
    row = {
        "n": n,
        "ns_per_particle": 1e9 * fast["s"] / n,
        "speedup": slow["s"] / fast["s"],
        "full_step": _pair(n, fast, slow),
        "phases": {},
    }
    for key, name in (
        ("full_step_back_to_back", "full_step_back_to_back/numba"),
        ("issue_step", "issue_step/numba"),
        ("injecting_step", "injecting_step/numba"),
        ("adaptive_step", "adaptive_step/numba"),
        ("full_step_fast", "full_step_fast/numba"),
        ("issue_step_fast", "issue_step_fast/numba"),
    ):
        if name in timed:
            row[key] = _pair(n, timed[name], None)
    if exact:
        row["full_step_exact_bearing"] = _pair(n, timed["full_step_exact/numba"], None)
    for phase in PHASES:
        if phase.name in errors:
            row["phases"][phase.name] = {"error": errors[phase.name]}
            continue
        numba_side = timed.get(f"{phase.name}/numba")
        if numba_side is None:
            continue
        row["phases"][phase.name] = _pair(n, numba_side, timed.get(f"{phase.name}/numpy"))
    return row


def _pair(n: int, numba_side: dict, numpy_side: dict | None) -> dict:
    """Seconds, ns per particle and the numpy/numba ratio of one timed item (numpy None: no twin)."""
    entry = {
        "numba_s": numba_side["s"],
        "numba_ns_per_particle": 1e9 * numba_side["s"] / n,
        "numba_samples": numba_side["samples"],
        "numba_spread": numba_side["spread"],
        "numba_calls_per_sample": numba_side["calls_per_sample"],
        "numpy_s": None,
        "numpy_ns_per_particle": None,
        "numpy_samples": 0,
        "speedup": None,
    }
    if numpy_side is not None:
        entry.update(
            numpy_s=numpy_side["s"],
            numpy_ns_per_particle=1e9 * numpy_side["s"] / n,
            numpy_samples=numpy_side["samples"],
            numpy_calls_per_sample=numpy_side["calls_per_sample"],
            speedup=numpy_side["s"] / numba_side["s"],
        )
    return entry


def numpy_full_step(sizes, budget_s: float) -> list[dict]:
    """Seconds per numpy step at each N (for the runs with numpy's CPU features switched off and on)."""
    rows = []
    for n in sizes:
        timed = measure({"numpy": numpy_step_work(n)}, budget_s, min_samples=1)["numpy"]
        rows.append({"n": n, "numpy_s": timed["s"], "samples": timed["samples"]})
    return rows


# -- resampling against other libraries -----------------------------------------------------------------------
PEERS = (
    ("filterpy", "filterpy.monte_carlo", "systematic_resample"),
    ("particles", "particles.resampling", "systematic"),
)


def our_resamplers() -> dict[str, Callable]:
    """`mcl.resampling.systematic` and any other public systematic entry point of `mcl.resampling`, each
    wrapped as (weights, rng) -> ancestors; entries whose signature cannot be filled are left out."""
    entries = {"mcl.resampling.systematic": lambda weights, rng: systematic(weights, weights.shape[0], rng)}
    for name in sorted(dir(resampling)):
        fn = getattr(resampling, name)
        if (
            name.startswith("_")
            or "systematic" not in name
            or name in ("systematic", "systematic_reference")
            or not callable(fn)
        ):
            continue
        caller = _fill_signature(fn)
        if caller is not None:
            entries[f"mcl.resampling.{name}"] = caller
    return entries


def _fill_signature(fn) -> Callable | None:
    """A (weights, rng) caller for a resampling entry point, from its parameter names; None if unknown."""
    try:
        parameters = list(inspect.signature(fn).parameters.values())
    except (TypeError, ValueError):
        return None
    makers = []
    for p in parameters:
        name = p.name.lower()
        if name in ("weights", "w"):
            makers.append(lambda w, rng: w)
        elif name in ("m", "n", "count", "size"):
            makers.append(lambda w, rng: w.shape[0])
        elif name in ("rng", "generator", "random_state"):
            makers.append(lambda w, rng: rng)
        elif name in ("u0", "u", "offset", "uniform"):
            makers.append(lambda w, rng: rng.random())
        elif name in ("out", "ancestors", "indices", "out_indices"):
            makers.append(lambda w, rng: np.empty(w.shape[0], dtype=np.int64))
        elif p.default is not inspect.Parameter.empty or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            break
        else:
            return None
    return lambda weights, rng: fn(*(make(weights, rng) for make in makers))


def peer_resamplers() -> tuple[dict[str, Callable], dict[str, dict]]:
    """The other libraries' systematic resamplers as (weights, rng) -> ancestors, and what is installed."""
    import importlib
    from importlib import metadata

    callers, status = {}, {}
    for package, module_name, function in PEERS:
        label = f"{module_name}.{function}"
        try:
            module = importlib.import_module(module_name)
            fn = getattr(module, function)
        except Exception as error:  # an ImportError, or a library broken on this numpy
            reason = "not installed" if isinstance(error, ImportError) else f"fails to import: {error!r}"
            status[label] = {"package": package, "available": False, "note": reason, "version": None}
            continue
        try:
            version = metadata.version(package)
        except metadata.PackageNotFoundError:
            version = None
        status[label] = {"package": package, "available": True, "note": "", "version": version}
        if package == "filterpy":
            callers[label] = lambda weights, rng, fn=fn: fn(weights)  # draws from numpy.random
        else:
            callers[label] = lambda weights, rng, fn=fn: fn(weights, weights.shape[0])
    return callers, status


def _is_systematic(ancestors: np.ndarray, weights: np.ndarray) -> bool:
    """Systematic resampling gives each particle ⌊N·wᵢ⌋ or ⌈N·wᵢ⌉ offspring (up to rounding)."""
    n = weights.shape[0]
    counts = np.bincount(np.asarray(ancestors, dtype=np.int64), minlength=n)
    return bool(ancestors.shape[0] == n and np.all(np.abs(counts - n * weights) < 1.0 + 1e-6))


KEPT_OUT = "mcl.resampling.systematic(out=kept)"


def time_resamplers(sizes, budget_s: float) -> dict:
    """Ns per particle of our systematic resampler(s), its numpy twin and the peers', on the weights of a
    corrected particle set, at each N; ratios are peer / ours (> 1: ours is faster)."""
    ours = our_resamplers()
    peers, peer_status = peer_resamplers()
    status = {label: {"package": "robocup-mcl", "available": True, "note": "", "version": None} for label in ours}
    status["mcl.resampling.systematic_reference"] = {
        "package": "robocup-mcl",
        "available": True,
        "note": "plain numpy twin",
        "version": None,
    }
    status.update(peer_status)
    candidates = dict(ours)
    status[KEPT_OUT] = {
        "package": "robocup-mcl",
        "available": True,
        "version": None,
        "note": "into an array kept across calls, as a filter resamples",
    }
    ours = [*ours, KEPT_OUT]
    fused_label = None if FUSED is None else f"mcl.resampling.{FUSED[0]}"
    if FUSED is not None:
        status[fused_label] = {
            "package": "robocup-mcl",
            "available": True,
            "version": None,
            "note": "what the filter calls: resampling, copy and roughening in one pass",
        }
        ours = [*ours, fused_label]
    candidates["mcl.resampling.systematic_reference"] = lambda weights, rng: systematic_reference(
        weights, weights.shape[0], rng
    )
    candidates.update(peers)
    rows = []
    for n in sizes:
        pf, _, observations = bench_setup(n)
        sensor = pf.sensor_model
        weights = np.empty(n)
        normalize(sensor.log_likelihood(pf.poses, observations), weights)
        if FUSED is not None:
            fused = FUSED[1](weights, n, pf.poses, pf.roughening * SQRT3, np.empty((n, 3)), np.random.default_rng(5))
            candidates[fused_label] = lambda weights, rng, fused=fused: fused()
        # the buffer is made once per size and kept across the calls, as a filter keeps its own
        candidates[KEPT_OUT] = lambda weights, rng, kept=np.empty(n, dtype=np.int64): systematic(  # noqa: B008
            weights, n, rng, out=kept
        )
        rng = np.random.default_rng(3)
        np.random.seed(3)
        usable, failures = {}, {}
        for label, fn in candidates.items():
            try:
                ancestors = np.asarray(fn(weights, rng))
                if label != fused_label and not _is_systematic(ancestors, weights):
                    failures[label] = "offspring counts are not systematic"
                usable[label] = lambda fn=fn: fn(weights, rng)
            except Exception as error:
                failures[label] = f"{type(error).__name__}: {error}"
        # Each sample is about 20 ms of consecutive calls of one resampler (all alike): back to back, as a
        # filter's resampling follows its weighting; with one call per sample, what ran before (filterpy's
        # third of a second) leaves the caches cold and the figure says more about memory than the resampler.
        timed = measure(usable, budget_s, sample_s=0.02)
        ns = {label: 1e9 * timed[label]["s"] / n if label in timed else None for label in status}
        best_ours = min(ns[label] for label in ours if ns.get(label) is not None)
        rows.append(
            {
                "n": n,
                "ns_per_particle": ns,
                "best_ours_ns_per_particle": best_ours,
                "ratio_to_ours": {label: (None if v is None else v / best_ours) for label, v in ns.items()},
                "problems": failures,
            }
        )
    return {"entries": status, "ours": list(ours), "rows": rows}


# -- threads ---------------------------------------------------------------------------------------------------
def time_threads(sizes, budget_s: float) -> dict:
    """Full step with two threads against one, at each N >= 10⁵ in `sizes`, if the filter offers threads."""
    option = threads_option()
    if option is None:
        return {"available": False, "note": "not available: ParticleFilter has no threads option", "rows": []}
    big = [n for n in sizes if n >= 100_000]
    result = {"available": True, "option": option, "rows": [], "note": ""}
    if not big:
        result["note"] = "not measured: no N >= 100000 among the sizes"
        return result
    import os

    import numba

    for n in big:
        timed = measure({"one": full_step_work(n, **{option: 1}), "two": full_step_work(n, **{option: 2})}, budget_s)
        result["rows"].append(
            {
                "n": n,
                "one_thread_s": timed["one"]["s"],
                "two_threads_s": timed["two"]["s"],
                "speedup": timed["one"]["s"] / timed["two"]["s"],
                "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
            }
        )
    try:
        result["threading_layer"] = numba.threading_layer()
    except ValueError:  # no parallel kernel ran
        result["threading_layer"] = None
    result["cpus_usable"] = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    busiest = max((row["load_average"][0] for row in result["rows"] if row["load_average"]), default=0.0)
    if busiest > result["cpus_usable"]:
        # Two threads need two free cores: with other work on the machine one of them waits at every barrier.
        # This benchmark itself accounts for 1 to 2 of the load.
        result["note"] = (
            f"machine busy while timed (load {busiest:.1f} on {result['cpus_usable']} cores, this "
            "benchmark included): the two-thread figures are not reliable"
        )
    return result


# -- accuracy of the fast bearing term -------------------------------------------------------------------------
def bearing_accuracy(n: int = 10_000) -> dict:
    """What the von Mises bearing term costs in accuracy: the total-variation distance between the normalized
    weights it gives and those of the exact term, on the same particles and detections (0 = identical)."""
    pf, _, observations = bench_setup(n)
    weights = {}
    for model in ("von_mises", "exact"):
        sensor = LandmarkSensorModel(pf.field, bearing_model=model)
        log_likelihood = sensor.log_likelihood(pf.poses, observations)
        w = np.exp(log_likelihood - log_likelihood.max())
        weights[model] = w / w.sum()
    return {"n": n, "total_variation": float(0.5 * np.abs(weights["von_mises"] - weights["exact"]).sum())}
