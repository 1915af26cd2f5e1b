"""`LearnedFootstepOdometry`: footstep displacements corrected by three LWPR models (Rouxel et al. sec. III-C).

    from motion_models import MotionInput
    from motion_models.footsteps import FootstepEvent, input_matrix
    from motion_models.learned_odometry import LearnedFootstepOdometry, RawFootstepOdometry

    X = input_matrix("online", support, commanded, sensor, durations)       # (K-1, 9) from a recorded log
    model = LearnedFootstepOdometry.train(X, truth[1:], "online", seed=0)   # truth: (K, 3) displacements
    model.save("odometry_model/"); model = LearnedFootstepOdometry.load("odometry_model/")
    mean, sigma = model.predict_steps(X)              # (m, 3) predicted displacements and their noise
    model.predict(poses, MotionInput(dt=0.01, odometry=event.sensor, footstep=event), rng)

Three single-output LWPR models predict the true forward, lateral and turn displacement of the step that
ends at a support swap, each from the same inputs (the paper's simplification: the three are independent
given the inputs):
- "apriori" (7 inputs): the commanded displacement of steps t and t-1 and the support foot, R⁷ → R;
- "online" (9 inputs): the sensor-based displacement of steps t and t-1, the support foot, and the two step
  durations, R⁹ → R.
Input and output scales (`norm_in`, `norm_out`) are the training data's standard deviations, so one set of
LWPR meta-parameters (`LWPRSettings`) serves both input sets.

Targets. The a-priori models learn the true step itself, as the paper states. The online models learn its
correction, truth minus the sensor-based step (inputs 0-2), and add the sensor step back (the paper's
"corrective function", same inputs, same output): the gyro's yaw is already within a fraction of a degree
of the truth per step, and LWPR's local models, asked for the whole step, lose that precision. These targets
are fixed, not searched by `robocup-mcl fit odometry`; `robocup-mcl demo odometry` prints the test figures of
the other choice next to each (`LWPRSettings.residual` overrides it).

In the filter (`predict`), particles move only when `u.footstep` holds a `FootstepEvent`: by the predicted
displacement plus Gaussian robot-frame noise whose standard deviation per axis is LWPR's confidence bound
(`predict_conf`) times `noise_scale`, never below `min_sigma`. Between swaps (`u.footstep is None`) poses are
left unchanged. Where no receptive field covers the inputs (a step unlike any in training), LWPR knows
nothing: the model then falls back to the raw displacement (inputs 0-2) with the raw odometry's RMS error on
the training data as noise (`fallback_sigma`). `RawFootstepOdometry` is the same motion model without
learning: the raw displacement with a constant noise calibrated on training data, for comparisons.

Update rate. Both models draw their noise once per step of the gait (a support swap), never per filter step:
the spread of a walk depends on the steps taken, not on how often the filter runs, so they have no
`noise_rate` (unlike `VelocityLinear`, whose noise is drawn every filter step).

A linear stage (`train(..., linear_stage=True)`, a variant, not the paper's model): a least-squares affine map
of all the inputs to the true step (`LinearStage`), then LWPR learning what it leaves (truth minus the linear
step); where no receptive field covers the inputs, the linear step alone. On the a priori inputs this gave the
lowest 10 s drift of the methods `robocup-mcl demo odometry --mismatch` compares ("lin+LWPR" there). The stage
is saved with the models (the metadata's optional key "linear").

Errors: inputs of the wrong dimension, non-finite training data or too few samples, an event that lacks
what the input set needs, and a model directory that is incomplete, truncated or of another format version
raise ValueError naming the problem. `load` checks the metadata file (at most `MAX_META_FILE_BYTES`, a JSON
object with exactly the keys `save` writes, each of its type and range, model files named without a directory)
before it reads a model; a problem raises ValueError naming the file and the key. Training builds new models
and returns a new holder only when done; `updated` trains copies: a holder's models are never left
half-updated. The same data and seed give the same models, bit for bit.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from field.checks import show as _short_repr
from numerics.frozen import keeps_arrays_frozen
from numerics.trig import SQRT3

from .base import MotionInput, check_poses
from .footsteps import INPUT_KINDS, N_INPUTS, FootstepEvent
from .kernels import move_with_noise
from .lwpr import LWPR

OUTPUTS = ("dx", "dy", "dtheta")
MODEL_FORMAT = "robocup-mcl learned footstep odometry"
MODEL_FORMAT_VERSION = 1
META_FILE = "footstep_odometry.json"
MAX_META_FILE_BYTES = 1 << 20
"""Largest metadata file `LearnedFootstepOdometry.load` reads, in bytes (1 MiB; `save` writes about 500)."""
_META_KEYS = (
    "format",
    "format_version",
    "inputs",
    "n_inputs",
    "models",
    "fallback_sigma",
    "noise_scale",
    "min_sigma",
    "residual",
)
_OPTIONAL_META_KEYS = ("linear",)  # written only for a holder with a linear stage
_LINEAR_KEYS = ("mean_in", "scale_in", "mean_out", "weights")
MIN_SAMPLES = 10
NO_FIELD = 1e19  # LWPR's bound where no receptive field is active is 1e20·norm_out


@dataclass(frozen=True)
class LWPRSettings:
    """LWPR meta-parameters for the footstep models, in units of the normalized inputs (one standard deviation
    of the training data).

    The defaults of `init_D`, `init_alpha`, `w_gen` and `penalty` are the values `robocup-mcl fit odometry`
    chose (results/odometry_fit.json): a search on training logs only, each robot's models learning on the
    first half of a log and scored by the drift after 10 s on its second half, as the paper tunes its
    meta-parameters (sec. IV-B 2). The other fields are not searched.

    Parameters
    ----------
    init_D : float, optional
        Initial distance metric of a new receptive field (times the identity), > 0; default 1 (fitted).
    init_alpha : float, optional
        Learning rate of the distance metric, > 0; default 10^-0.5 ≈ 0.316 (fitted).
    w_gen : float, optional
        A new receptive field is added where no field is activated above this, > 0; default 0.1 (fitted).
    penalty : float, optional
        Distance-metric shrinkage (larger keeps fields broad); default 1e-4 (fitted).
    init_lambda, final_lambda : float, optional
        Forgetting factor at the start and its limit; defaults 0.995 and 0.9999 (early estimates do not linger
        after a few epochs).
    epochs : int, optional
        Passes over the learning set, each in a fresh order from the seed, >= 1; default 10.
    residual : bool or None, optional
        Learn truth - raw (inputs 0-2) and add the raw step back; None (the default): for the online inputs
        only (see the module docstring).
    input_floor : float, optional
        Smallest input scale (a constant input would divide by zero), > 0; default 1e-3.

    Raises
    ------
    ValueError
        If a value is out of its range.
    """

    init_D: float = 1.0  # fitted
    init_alpha: float = 10**-0.5  # fitted
    w_gen: float = 0.1  # fitted
    penalty: float = 1e-4  # fitted
    init_lambda: float = 0.995
    final_lambda: float = 0.9999
    epochs: int = 10
    residual: bool | None = None
    input_floor: float = 1e-3  # smallest input scale (a constant input would divide by zero)

    def __post_init__(self) -> None:
        for name in ("init_D", "init_alpha", "w_gen", "input_floor"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value!r} must be a finite number > 0")
        if not (isinstance(self.epochs, int) and self.epochs >= 1):
            raise ValueError(f"epochs = {self.epochs!r} must be an integer >= 1")
        if self.residual not in (None, True, False):
            raise ValueError(f"residual = {self.residual!r} must be None, True or False")

    def residual_for(self, kind: str) -> bool:
        """Whether the models of input set `kind` learn the correction of the raw step (None: online only)."""
        return kind == "online" if self.residual is None else bool(self.residual)


def _check_kind(kind: str) -> None:
    if kind not in INPUT_KINDS:
        raise ValueError(f"inputs = {kind!r} must be one of {INPUT_KINDS}")


def _training_arrays(inputs, targets, kind: str) -> tuple[np.ndarray, np.ndarray]:
    _check_kind(kind)
    X = np.asarray(inputs, dtype=np.float64)
    Y = np.asarray(targets, dtype=np.float64)
    n_in = N_INPUTS[kind]
    if X.ndim != 2 or X.shape[1] != n_in:
        raise ValueError(f"inputs must have shape (n, {n_in}) for the {kind} input set, got shape {X.shape}")
    if Y.shape != (X.shape[0], 3):
        raise ValueError(f"targets must have shape ({X.shape[0]}, 3) (dx, dy, dθ per input row), got {Y.shape}")
    if X.shape[0] < MIN_SAMPLES:
        raise ValueError(f"inputs hold {X.shape[0]} samples; training needs at least {MIN_SAMPLES}")
    for name, A in (("inputs", X), ("targets", Y)):
        bad = ~np.isfinite(A).all(axis=1)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise ValueError(f"{name} must be finite: row {row} is {A[row].tolist()} ({int(bad.sum())} bad rows)")
    return X, Y


def _sigma_triple(name: str, value) -> tuple[float, float, float]:
    try:
        triple = tuple(float(v) for v in value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} = {_short_repr(value)} must be three numbers") from None
    if len(triple) != 3 or not all(math.isfinite(v) and v >= 0 for v in triple):
        raise ValueError(f"{name} = {_short_repr(value)} must be three finite numbers >= 0")
    return triple


def _raw_rms(X: np.ndarray, Y: np.ndarray) -> tuple[float, float, float]:
    """RMS error of the raw displacement (inputs 0-2) against the truth, per axis."""
    return tuple(float(v) for v in np.sqrt(np.mean((Y - X[:, :3]) ** 2, axis=0)))  # type: ignore[return-value]


@keeps_arrays_frozen
@dataclass(frozen=True)
class LinearStage:
    """A least-squares affine map of the inputs to the step: mean_out + ((x - mean_in) / scale_in) @ weights.

    Parameters
    ----------
    mean_in, scale_in : numpy.ndarray
        (n,) the inputs' means and standard deviations (scale_in finite and > 0).
    mean_out : numpy.ndarray
        (3,) the steps' mean (dx [m], dy [m], dθ [rad]).
    weights : numpy.ndarray
        (n, 3) the weights of the standardized inputs.

    Raises
    ------
    ValueError
        If a shape does not fit n inputs or a value is not finite.
    """

    mean_in: np.ndarray
    scale_in: np.ndarray
    mean_out: np.ndarray
    weights: np.ndarray

    def __post_init__(self) -> None:
        arrays = {}
        for name in _LINEAR_KEYS:
            try:
                value = np.array(getattr(self, name), dtype=np.float64)
            except (TypeError, ValueError, OverflowError):
                raise ValueError(f"{name} = {_short_repr(getattr(self, name))} must be an array of numbers") from None
            if not np.isfinite(value).all():
                raise ValueError(f"{name} must be finite")
            value.flags.writeable = False
            arrays[name] = value
        n = arrays["mean_in"].shape[0] if arrays["mean_in"].ndim == 1 else -1
        shapes = {"mean_in": (n,), "scale_in": (n,), "mean_out": (3,), "weights": (n, 3)}
        for name, shape in shapes.items():
            if n < 1 or arrays[name].shape != shape:
                raise ValueError(
                    f"{name} has shape {arrays[name].shape}; a linear stage of n >= 1 inputs needs "
                    "mean_in (n,), scale_in (n,), mean_out (3,), weights (n, 3)"
                )
        if not (arrays["scale_in"] > 0).all():
            raise ValueError("scale_in must be > 0")
        for name, value in arrays.items():
            object.__setattr__(self, name, value)

    @property
    def n_in(self) -> int:
        return int(self.mean_in.shape[0])

    @classmethod
    def fit(cls, inputs: np.ndarray, targets: np.ndarray, ridge: float = 0.0, per_axis: bool = False) -> LinearStage:
        """Least squares of targets (m, 3) on standardized inputs (m, n), with an offset per output and the
        penalty `ridge`·m on the weights (not the offsets); the minimum-norm solution where an input is constant.
        `per_axis`: each output from its own raw-step input alone (inputs 0-2: a scale and an offset per axis)
        instead of from every input. Raises ValueError for a ridge that is not finite and >= 0."""
        if not (math.isfinite(ridge) and ridge >= 0):
            raise ValueError(f"ridge = {ridge!r} must be a finite number >= 0")
        X = np.asarray(inputs, dtype=np.float64)
        Y = np.asarray(targets, dtype=np.float64)
        mean_in, scale_in = X.mean(axis=0), np.maximum(X.std(axis=0), 1e-9)
        Z = (X - mean_in) / scale_in
        mean_out = Y.mean(axis=0)
        weights = np.zeros((X.shape[1], 3))
        for j in range(3):
            cols = [j] if per_axis else list(range(X.shape[1]))
            A = Z[:, cols]
            gram = A.T @ A + ridge * X.shape[0] * np.eye(len(cols))
            right = A.T @ (Y[:, j] - mean_out[j])
            try:
                weights[cols, j] = np.linalg.solve(gram, right)
            except np.linalg.LinAlgError:
                weights[cols, j] = np.linalg.lstsq(gram, right, rcond=None)[0]
        return cls(mean_in, scale_in, mean_out, weights)

    def predict(self, inputs: np.ndarray) -> np.ndarray:
        """The linear steps (m, 3) of input rows (m, n)."""
        return self.mean_out + ((inputs - self.mean_in) / self.scale_in) @ self.weights

    def as_dict(self) -> dict:
        """The stage as lists of floats (what `save` writes; floats round-trip exactly through JSON)."""
        return {name: getattr(self, name).tolist() for name in _LINEAR_KEYS}


class _FootstepMotion:
    """The motion model interface both footstep models share: at a support swap every pose moves by the step's
    displacement and noise standard deviations (`_step`: the learned prediction, or the event's raw
    displacement) with Gaussian robot-frame noise; between swaps nothing moves."""

    inputs: str

    def _step(self, event: FootstepEvent) -> tuple[Any, Any]:
        """The step's (dx, dy, dθ) displacement and (x, y, θ) noise standard deviations."""
        raise NotImplementedError

    def check(self, u: MotionInput) -> None:
        """Raise ValueError unless `u.footstep` is None or a FootstepEvent with this input set's fields.

        Parameters
        ----------
        u : MotionInput
            As `motion_models.base.MotionModel.check`.
        """
        _check_footstep(u, self.inputs)

    def predict(self, poses: np.ndarray, u: MotionInput, rng: np.random.Generator) -> None:
        """At a support swap, move every pose by the step (the learned prediction, or the event's raw
        displacement) plus N(0, σ²) robot-frame noise; between swaps, leave the poses (and the generator)
        untouched.

        Parameters
        ----------
        poses, u, rng
            As `motion_models.base.MotionModel.predict`; `u.footstep` (None between swaps) drives the motion.
            ValueError when `poses` breaks the particle array contract or `u` fails `check`.
        """
        check_poses(poses)
        self.check(u)
        if u.footstep is None:
            return
        mean, sigma = self._step(u.footstep)
        _move_gaussian(poses, mean, sigma, rng)


@dataclass(frozen=True)
class LearnedFootstepOdometry(_FootstepMotion):
    """Three trained LWPR models (dx, dy, dθ) and how their predictions move particles.

    Build one with `train` or `load`; the LWPR objects must not be updated in place (use `updated`).

    Parameters
    ----------
    models : tuple of LWPR
        Three trained models (dx, dy, dθ), each mapping the input set to one output.
    inputs : str, optional
        The input set, "online" (9 inputs, the default) or "apriori" (7).
    fallback_sigma : tuple of float, optional
        Noise standard deviations (x [m], y [m], θ [rad]) of a step outside every receptive field (moved by
        its raw displacement); default (0.01, 0.01, 0.055).
    noise_scale : float, optional
        Factor on the models' confidence bounds to get the noise standard deviations, >= 0; default 1.
    min_sigma : tuple of float, optional
        The smallest noise standard deviations (x [m], y [m], θ [rad]); default (0.001, 0.001, 0.0045).
    residual : bool, optional
        Whether the models learned the correction of the raw displacement (added back); default False.
    linear : LinearStage or None, optional
        A linear stage the models correct (they then learned truth minus its step, `residual` True); its step
        replaces the raw displacement, also as the fallback outside every receptive field. Default None.

    Raises
    ------
    ValueError
        If the models are not three trained LWPR models for the input set, or a value is invalid.
    """

    models: tuple
    inputs: str = "online"
    fallback_sigma: tuple[float, float, float] = (0.01, 0.01, 0.055)
    noise_scale: float = 1.0
    min_sigma: tuple[float, float, float] = (0.001, 0.001, 0.0045)
    residual: bool = False
    linear: LinearStage | None = None

    def __post_init__(self) -> None:
        _check_kind(self.inputs)
        if not isinstance(self.residual, bool):
            raise ValueError(f"residual = {self.residual!r} must be True or False")
        if self.linear is not None:
            if not isinstance(self.linear, LinearStage):
                raise ValueError(f"linear = {_short_repr(self.linear)} must be a LinearStage or None")
            if self.linear.n_in != N_INPUTS[self.inputs]:
                raise ValueError(
                    f"linear maps {self.linear.n_in} inputs; the {self.inputs} input set has {N_INPUTS[self.inputs]}"
                )
            if not self.residual:
                raise ValueError("a linear stage needs residual=True (the models learn what the stage leaves)")
        models = tuple(self.models) if isinstance(self.models, (tuple, list)) else None
        if models is None or len(models) != 3 or not all(isinstance(m, LWPR) for m in models):
            raise ValueError(f"models = {self.models!r} must be three LWPR models (dx, dy, dθ)")
        for name, m in zip(OUTPUTS, models):
            if m.n_in != N_INPUTS[self.inputs] or m.n_out != 1:
                raise ValueError(
                    f"model {name!r} maps R^{m.n_in} → R^{m.n_out}; the {self.inputs} input set "
                    f"needs R^{N_INPUTS[self.inputs]} → R^1"
                )
            if m.n_data == 0:
                raise ValueError(f"model {name!r} is untrained: train it (LearnedFootstepOdometry.train) first")
        object.__setattr__(self, "models", models)
        object.__setattr__(self, "fallback_sigma", _sigma_triple("fallback_sigma", self.fallback_sigma))
        object.__setattr__(self, "min_sigma", _sigma_triple("min_sigma", self.min_sigma))
        if not _finite_number(self.noise_scale) >= 0:
            raise ValueError(f"noise_scale = {_short_repr(self.noise_scale)} must be a finite number >= 0")

    # -- training ---------------------------------------------------------------------------------------
    @classmethod
    def train(
        cls,
        inputs: ArrayLike,
        targets: ArrayLike,
        kind: str = "online",
        *,
        seed: int = 0,
        settings: LWPRSettings = LWPRSettings(),
        noise_scale: float = 1.0,
        linear_stage: bool = False,
    ) -> LearnedFootstepOdometry:
        """Train three new LWPR models on inputs (n, 7|9) and true displacements targets (n, 3).

        Everything is validated first; nothing is returned until all three models are trained.

        Parameters
        ----------
        inputs : array_like
            (n, 7) or (n, 9) float inputs (`motion_models.footsteps.input_matrix`) of the input set.
        targets : array_like
            (n, 3) true displacements (dx [m], dy [m], dθ [rad]) of the same steps.
        kind : str, optional
            The input set, "online" (the default) or "apriori".
        seed : int, optional
            Seeds the order of the training passes; default 0.
        settings : LWPRSettings, optional
            LWPR meta-parameters; default `LWPRSettings()`.
        noise_scale : float, optional
            Factor on the models' confidence bounds (see the class); default 1.
        linear_stage : bool, optional
            Fit a `LinearStage` first and let LWPR learn what it leaves (the variant of the module docstring);
            default False, the paper's model.

        Returns
        -------
        LearnedFootstepOdometry
            The trained holder; its `fallback_sigma` is the raw displacement's RMS error on the data.

        Raises
        ------
        ValueError
            If the arrays' shapes do not match the input set or a value is not finite.
        """
        X, Y = _training_arrays(inputs, targets, kind)
        if not isinstance(linear_stage, bool):
            raise ValueError(f"linear_stage = {_short_repr(linear_stage)} must be True or False")
        linear = LinearStage.fit(X, Y) if linear_stage else None
        if linear is not None:
            # LWPR learns "what the stage leaves + the raw step" as the correction of the raw step, so that
            # its own fallback, the raw step, maps to the linear step.
            Y = Y - linear.predict(X) + X[:, :3]
        residual = True if linear is not None else settings.residual_for(kind)
        fit = Y - X[:, :3] if residual else Y
        norm_in = np.maximum(X.std(axis=0), settings.input_floor)
        norm_out = np.maximum(fit.std(axis=0), 1e-6)
        models = []
        for j in range(3):
            m = LWPR(X.shape[1], 1)
            m.norm_in = norm_in
            m.norm_out = np.array([norm_out[j]])
            # init_D acts on x / norm_in: spherical in units of the data's spread.
            m.init_D = settings.init_D * np.eye(X.shape[1])
            m.init_alpha = settings.init_alpha * np.ones((X.shape[1], X.shape[1]))
            m.w_gen = settings.w_gen
            m.penalty = settings.penalty
            m.init_lambda = settings.init_lambda
            m.final_lambda = settings.final_lambda
            models.append(m)
        _fit(models, X, fit, seed, settings.epochs)
        return cls(tuple(models), kind, _raw_rms(X, Y), noise_scale, residual=residual, linear=linear)

    def updated(
        self, inputs: ArrayLike, targets: ArrayLike, *, seed: int = 0, epochs: int = 1
    ) -> LearnedFootstepOdometry:
        """A new holder whose models are copies of these trained further on (inputs, targets); this one is
        untouched (online learning without ever exposing a half-updated model).

        Parameters
        ----------
        inputs, targets
            As `train`, for the holder's input set.
        seed : int, optional
            Seeds the order of the training passes; default 0.
        epochs : int, optional
            Passes over the data, >= 1; default 1.

        Returns
        -------
        LearnedFootstepOdometry
            The new holder, with this one's settings.

        Raises
        ------
        ValueError
            If the arrays do not fit the input set or `epochs` is not an integer >= 1.
        """
        X, Y = _training_arrays(inputs, targets, self.inputs)
        if not (isinstance(epochs, int) and epochs >= 1):
            raise ValueError(f"epochs = {epochs!r} must be an integer >= 1")
        models = [m.copy() for m in self.models]
        if self.linear is not None:
            Y = Y - self.linear.predict(X) + X[:, :3]
        _fit(models, X, Y - X[:, :3] if self.residual else Y, seed, epochs)
        return LearnedFootstepOdometry(
            tuple(models),
            self.inputs,
            self.fallback_sigma,
            self.noise_scale,
            self.min_sigma,
            self.residual,
            self.linear,
        )

    # -- prediction -------------------------------------------------------------------------------------
    def predict_steps(self, inputs: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Predicted displacements (m, 3) and their noise standard deviations (m, 3) for input rows (m, n).

        Parameters
        ----------
        inputs : array_like
            (m, n) finite input rows, n = 7 ("apriori") or 9 ("online") as the holder's input set.

        Returns
        -------
        mean : np.ndarray
            (m, 3) displacements (dx [m], dy [m], dθ [rad]); the raw displacement outside every receptive field.
        sigma : np.ndarray
            (m, 3) noise standard deviations [m, m, rad]; `fallback_sigma` outside every receptive field.

        Raises
        ------
        ValueError
            If `inputs` has the wrong shape or a value that is not finite.
        """
        X = np.asarray(inputs, dtype=np.float64)
        n_in = N_INPUTS[self.inputs]
        if X.ndim != 2 or X.shape[1] != n_in:
            raise ValueError(f"inputs must have shape (m, {n_in}) for the {self.inputs} input set, got shape {X.shape}")
        if not np.isfinite(X).all():
            row = int(np.flatnonzero(~np.isfinite(X).all(axis=1))[0])
            raise ValueError(f"inputs must be finite: row {row} is {X[row].tolist()}")
        mean = np.empty((X.shape[0], 3))
        sigma = np.empty((X.shape[0], 3))
        for j, m in enumerate(self.models):
            y, conf = m.predict_conf(np.ascontiguousarray(X))
            mean[:, j], sigma[:, j] = y[:, 0], conf[:, 0]
        unknown = (sigma >= NO_FIELD * np.array([m.norm_out[0] for m in self.models])) | ~np.isfinite(mean)
        sigma = np.maximum(self.noise_scale * sigma, np.array(self.min_sigma))
        if self.residual:
            mean = mean + X[:, :3]
        # Outside every receptive field: the raw displacement with the raw odometry's error.
        mean = np.where(unknown, X[:, :3], mean)
        sigma = np.where(unknown, np.broadcast_to(np.array(self.fallback_sigma), sigma.shape), sigma)
        if self.linear is not None:
            mean = mean - X[:, :3] + self.linear.predict(X)
        return mean, sigma

    def predict_event(self, event: FootstepEvent) -> tuple[np.ndarray, np.ndarray]:
        """Predicted displacement (3,) and noise standard deviation (3,) of the step `event` ends.

        Parameters
        ----------
        event : FootstepEvent
            The support swap that ended the step.

        Returns
        -------
        mean : np.ndarray
            (3,) displacement (dx [m], dy [m], dθ [rad]).
        sigma : np.ndarray
            (3,) noise standard deviations [m, m, rad].

        Raises
        ------
        ValueError
            If `event` is not a `FootstepEvent` or lacks the holder's input set's fields.
        """
        if not isinstance(event, FootstepEvent):
            raise ValueError(f"footstep = {event!r} must be a motion_models.footsteps.FootstepEvent")
        mean, sigma = self.predict_steps(event.inputs(self.inputs)[None, :])
        return mean[0], sigma[0]

    def _step(self, event: FootstepEvent) -> tuple[np.ndarray, np.ndarray]:
        return self.predict_event(event)

    # -- files ------------------------------------------------------------------------------------------
    def save(self, directory: str | os.PathLike) -> None:
        """Write the three models and their settings into `directory` (created if needed). Each file is
        written to a temporary name and renamed; the metadata file, written last, names the models.

        Parameters
        ----------
        directory : str or os.PathLike
            The directory to write into (created if needed); files of a previous save are replaced.

        Raises
        ------
        OSError
            If a file cannot be written.
        """
        directory = os.fspath(directory)
        os.makedirs(directory, exist_ok=True)
        for name, m in zip(OUTPUTS, self.models):
            m.save(os.path.join(directory, f"{name}.npz"))
        meta = {
            "format": MODEL_FORMAT,
            "format_version": MODEL_FORMAT_VERSION,
            "inputs": self.inputs,
            "n_inputs": N_INPUTS[self.inputs],
            "models": {name: f"{name}.npz" for name in OUTPUTS},
            "fallback_sigma": list(self.fallback_sigma),
            "noise_scale": self.noise_scale,
            "min_sigma": list(self.min_sigma),
            "residual": self.residual,
        }
        if self.linear is not None:
            meta["linear"] = self.linear.as_dict()
        path = os.path.join(directory, META_FILE)
        tmp = f"{path}.tmp-{os.getpid()}"
        try:
            with open(tmp, "w") as f:
                json.dump(meta, f, indent=2)
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.remove(tmp)

    @classmethod
    def load(cls, directory: str | os.PathLike) -> LearnedFootstepOdometry:
        """Read a directory written by `save`. Missing, truncated or foreign files, another format version,
        and a metadata key that is unknown, missing or of the wrong type or value raise ValueError naming the
        file and the key (the metadata is checked before any model file is read); a directory that is not a
        str or os.PathLike raises TypeError.

        Parameters
        ----------
        directory : str or os.PathLike
            A directory written by `save`.

        Returns
        -------
        LearnedFootstepOdometry
            The holder, equal in its predictions to the one saved.

        Raises
        ------
        ValueError
            If a file is missing, unreadable or invalid (naming the file and the key).
        TypeError
            If `directory` is not a str or os.PathLike.
        """
        if not isinstance(directory, (str, os.PathLike)) or not isinstance(os.fspath(directory), str):
            raise TypeError(
                f"directory = {_short_repr(directory)} must be a str or os.PathLike, not {type(directory).__name__}"
            )
        directory = os.fspath(directory)
        path = os.path.join(directory, META_FILE)
        if not os.path.isfile(path):
            raise ValueError(f"{directory!r} holds no {META_FILE}: not a saved LearnedFootstepOdometry")
        meta = _read_meta(path)
        try:
            models = tuple(LWPR.load(os.path.join(directory, meta["models"][name])) for name in OUTPUTS)
        except FileNotFoundError as exc:
            raise ValueError(f"{directory!r} lacks a model file: {exc.filename}") from None
        except ValueError as exc:
            raise ValueError(f"{directory!r}: {exc}") from None
        try:
            linear = None if meta.get("linear") is None else LinearStage(**meta["linear"])
            return cls(
                models,
                meta["inputs"],
                meta["fallback_sigma"],
                meta["noise_scale"],
                meta["min_sigma"],
                meta["residual"],
                linear,
            )
        except ValueError as exc:
            raise ValueError(f"{path!r}: {exc}") from None


def _read_meta(path: str) -> dict:
    """The metadata of a saved model directory, every key checked (see `LearnedFootstepOdometry.load`)."""
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_META_FILE_BYTES + 1)
    except OSError as exc:
        raise ValueError(f"{path!r} cannot be read: {exc}") from None
    if len(data) > MAX_META_FILE_BYTES:
        raise ValueError(
            f"{path!r} holds more than MAX_META_FILE_BYTES = {MAX_META_FILE_BYTES} bytes; "
            "not a learned footstep odometry file"
        )
    try:
        meta = json.loads(data)
    except RecursionError:
        raise ValueError(f"{path!r} is not JSON that can be read: nested too deeply") from None
    except ValueError as exc:  # JSONDecodeError, bad UTF-8, a number beyond Python's digit limit
        raise ValueError(f"{path!r} is truncated or not JSON: {exc}") from None
    if not isinstance(meta, dict) or meta.get("format") != MODEL_FORMAT:
        shown = _short_repr(meta.get("format")) if isinstance(meta, dict) else f"a JSON {type(meta).__name__}"
        raise ValueError(f"{path!r} is not a learned footstep odometry file (format {shown})")
    version = meta.get("format_version")
    if isinstance(version, bool) or version != MODEL_FORMAT_VERSION:
        raise ValueError(
            f"{path!r} has format version {_short_repr(version)} (format_version); this version "
            f"of robocup-mcl reads version {MODEL_FORMAT_VERSION}"
        )
    for key in meta:
        if key not in _META_KEYS + _OPTIONAL_META_KEYS:
            raise ValueError(
                f"{path!r}: unknown key {_short_repr(key)} = {_short_repr(meta[key])} "
                f"(valid: {', '.join(_META_KEYS + _OPTIONAL_META_KEYS)})"
            )
    for key in _META_KEYS:
        if key not in meta:
            raise ValueError(f"{path!r} lacks the key {key!r}")

    def bad(key: str, must: str) -> ValueError:
        return ValueError(f"{path!r}: {key} = {_short_repr(meta[key])} must be {must}")

    kind = meta["inputs"]
    if not isinstance(kind, str) or kind not in INPUT_KINDS:
        raise bad("inputs", f"one of {INPUT_KINDS}")
    n_inputs = meta["n_inputs"]
    if isinstance(n_inputs, bool) or n_inputs != N_INPUTS[kind]:
        raise bad("n_inputs", f"{N_INPUTS[kind]}, the size of the {kind} input set")
    models = meta["models"]
    if not isinstance(models, dict) or sorted(models) != sorted(OUTPUTS):
        raise bad("models", f"a table of a model file name for each of {', '.join(OUTPUTS)}")
    for name in OUTPUTS:
        file = models[name]
        if not (
            isinstance(file, str)
            and 0 < len(file) <= 255
            and file not in (".", "..")
            and "\0" not in file
            and os.path.basename(file) == file
            and "/" not in file
            and os.sep not in file
        ):
            raise ValueError(
                f"{path!r}: models.{name} = {_short_repr(file)} must be the name of a file in the same directory"
            )
    for key in ("fallback_sigma", "min_sigma"):
        value = meta[key]
        if not (isinstance(value, list) and len(value) == 3 and all(_finite_number(v) >= 0 for v in value)):
            raise bad(key, "three finite numbers >= 0")
    if not _finite_number(meta["noise_scale"]) >= 0:
        raise bad("noise_scale", "a finite number >= 0")
    if not isinstance(meta["residual"], bool):
        raise bad("residual", "true or false")
    if "linear" in meta:
        _check_linear_meta(meta["linear"], N_INPUTS[kind], bad)
    return meta


def _check_linear_meta(linear, n_inputs: int, bad) -> None:
    """The metadata's "linear" table: exactly `_LINEAR_KEYS`, lists of finite numbers of the stage's shapes."""
    must = (
        f"a table of {', '.join(_LINEAR_KEYS)}: {n_inputs}, {n_inputs}, 3 and {n_inputs} rows of 3 finite "
        "numbers, scale_in > 0"
    )
    if not (isinstance(linear, dict) and sorted(linear) == sorted(_LINEAR_KEYS)):
        raise bad("linear", must)

    def numbers(value, count: int) -> bool:
        return isinstance(value, list) and len(value) == count and all(math.isfinite(_finite_number(v)) for v in value)

    ok = (
        numbers(linear["mean_in"], n_inputs)
        and numbers(linear["scale_in"], n_inputs)
        and numbers(linear["mean_out"], 3)
        and isinstance(linear["weights"], list)
        and len(linear["weights"]) == n_inputs
        and all(numbers(row, 3) for row in linear["weights"])
    )
    if not ok or not all(v > 0 for v in linear["scale_in"]):
        raise bad("linear", must)


def _finite_number(value) -> float:
    """`value` as a float if it is a finite int or float (not a boolean), else NaN."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return math.nan
    try:
        value = float(value)
    except OverflowError:
        return math.nan
    return value if math.isfinite(value) else math.nan


def _fit(models: list, X: np.ndarray, Y: np.ndarray, seed: int, epochs: int) -> None:
    """Update each model on every row, `epochs` times, each pass in a fresh order drawn from `seed`.
    The data were validated before, so no update can be rejected halfway."""
    rng = np.random.default_rng(seed)
    for _ in range(epochs):
        for i in rng.permutation(X.shape[0]):
            for j, m in enumerate(models):
                m.update(X[i], Y[i, j : j + 1])


def _move_gaussian(poses: np.ndarray, mean, sigma, rng: np.random.Generator) -> None:
    # move_with_noise's Gaussian mode takes bounds b with σ = b/√3 (same variance as uniform on [-b, b]).
    variates = rng.standard_normal((poses.shape[0], 3))
    move_with_noise(
        poses,
        float(mean[0]),
        float(mean[1]),
        float(mean[2]),
        float(sigma[0]) * SQRT3,
        float(sigma[1]) * SQRT3,
        float(sigma[2]) * SQRT3,
        True,
        variates,
    )


@dataclass(frozen=True)
class RawFootstepOdometry(_FootstepMotion):
    """The footstep displacement without learning: the event's commanded ("apriori") or sensor ("online")
    displacement plus constant Gaussian robot-frame noise `sigma` (m, m, rad) per step of the gait (drawn at a
    support swap, not per filter step: the same at any update rate).

    Parameters
    ----------
    inputs : str, optional
        "online" (the sensor displacement, the default) or "apriori" (the commanded one).
    sigma : tuple of float, optional
        Noise standard deviations (x [m], y [m], θ [rad]) per step; default (0.01, 0.01, 0.035).

    Raises
    ------
    ValueError
        If `inputs` is neither or `sigma` is not three finite numbers >= 0.
    """

    inputs: str = "online"
    sigma: tuple[float, float, float] = (0.01, 0.01, 0.035)

    def __post_init__(self) -> None:
        _check_kind(self.inputs)
        object.__setattr__(self, "sigma", _sigma_triple("sigma", self.sigma))

    @classmethod
    def calibrate(cls, inputs: ArrayLike, targets: ArrayLike, kind: str = "online") -> RawFootstepOdometry:
        """Noise = the raw displacement's RMS error against the truth on training data (bias included).

        Parameters
        ----------
        inputs, targets, kind
            As `LearnedFootstepOdometry.train`.

        Returns
        -------
        RawFootstepOdometry
            The model with `sigma` the per-axis RMS error.

        Raises
        ------
        ValueError
            If the arrays' shapes do not match the input set or a value is not finite.
        """
        X, Y = _training_arrays(inputs, targets, kind)
        return cls(kind, _raw_rms(X, Y))

    def _step(self, event: FootstepEvent) -> tuple[Any, tuple[float, float, float]]:
        return (event.commanded if self.inputs == "apriori" else event.sensor), self.sigma


def _check_footstep(u: MotionInput, inputs: str) -> None:
    if u.footstep is None:
        return
    if not isinstance(u.footstep, FootstepEvent):
        raise ValueError(f"footstep = {u.footstep!r} must be a motion_models.footsteps.FootstepEvent")
    u.footstep.inputs(inputs)
