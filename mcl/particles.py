"""The particle set: N poses with their log-weights and normalized weights, a stateful motion model's state per
particle, and the buffers a step works in.

    from mcl.particles import ParticleSet, check_pose, check_poses

`ParticleSet` is the part of `mcl.ParticleFilter` that holds the particles (the filter is a `ParticleSet` and
a `mcl.summary.BeliefSummary`): the arrays, kept across steps so that a steady-state step allocates nothing that
grows with N, their read-only views, and the calls that replace or disturb them (`set_particles`, `diffuse`).
Every change calls `_changed()` (the summary's cached estimate and entropy are stale), and a change that
breaks the estimate's continuity `_forget_anchor()`, both from `BeliefSummary`; `diffuse` draws from the
filter's generator `rng`. The particles' motion and scoring are the filter's loop (`mcl.filter`).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np

from field.angles import wrap_angles
from field.checks import LARGEST_ANGLE, LARGEST_COORDINATE, LARGEST_SIGMA, ArgumentTypeError, reals

from .weights import normalize

if TYPE_CHECKING:
    from field import Field

_NO_STATE = np.empty((0, 0))      # no per-particle motion state


def check_pose(name: str, pose) -> np.ndarray:
    """A pose (x, y, θ) as float64 (3,): |x|, |y| at most `LARGEST_COORDINATE`, |θ| at most `LARGEST_ANGLE`."""
    array = reals(name, pose, 3)
    if max(abs(array[0]), abs(array[1])) > LARGEST_COORDINATE or abs(array[2]) > LARGEST_ANGLE:
        raise ValueError(f"{name} = {pose!r} must be within {LARGEST_COORDINATE:g} m and {LARGEST_ANGLE:g} rad")
    return array

def check_poses(name: str, poses) -> np.ndarray:
    """Poses (K, 3) (or one (3,)) as float64 (K, 3), each within the bounds of `check_pose`."""
    if isinstance(poses, (str, bytes, dict)) or poses is None or np.ndim(poses) == 0:
        raise ArgumentTypeError(f"{name} = {poses!r} must be (x, y, θ) poses, not {type(poses).__name__}")
    try:
        array = np.array(poses, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ArgumentTypeError(f"{name} = {poses!r} must be (x, y, θ) poses") from None
    if array.ndim == 1 and array.shape[0] == 3:
        array = array.reshape(1, 3)
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"{name} must have shape (K, 3), got {array.shape}")
    inside = (np.isfinite(array).all(axis=1) & (np.abs(array[:, :2]) <= LARGEST_COORDINATE).all(axis=1)
              & (np.abs(array[:, 2]) <= LARGEST_ANGLE))
    if not inside.all():
        i = int(np.argmin(inside))
        raise ValueError(f"{name}[{i}] = {array[i].tolist()!r} must be finite, within {LARGEST_COORDINATE:g} m "
                         f"and {LARGEST_ANGLE:g} rad")
    return array


class ParticleSet:
    """N particles: `poses` (N, 3) [x, y, θ], `log_weights` (N,), `weights` (N,), a stateful motion model's
    `motion_state`, and the step's buffers (see the module docstring)."""

    # Set by the filter that is also a `BeliefSummary` (`mcl.filter.ParticleFilter`), declared for type checkers.
    _n: int
    _field: Field
    motion_model: Any              # a MotionModel, whose optional capabilities (`particle_state`) are looked up
    rng: np.random.Generator
    _changed: Callable[[], None]
    _forget_anchor: Callable[[], None]

    def _allocate_particles(self) -> None:
        """The particles and the buffers a step works in (N = `self._n`)."""
        self._poses = np.zeros((self._n, 3))
        self._log_weights = np.full(self._n, -math.log(self._n))
        self._weights = np.full(self._n, 1.0 / self._n)
        self._log_likelihood = np.empty(self._n)
        self._previous = np.empty((self._n, 3))          # the particles before resampling (the copy's source)
        self._capture_poses = np.empty((self._n, 3))
        self._trig = np.empty((self._n, 2))              # cos, sin of the scored headings, for the roughening
        self._variates = np.empty((self._n, 3))          # drawn Gaussian motion noise, resampling variates
        self._counts = np.zeros(self._n + 1, dtype=np.int64)   # resampling scratch (zero between uses)

    def _bind_motion_state(self) -> None:
        """A stateful motion model's per-particle state (`mcl.contracts.ParticleState`), kept beside the poses."""
        motion_model = self.motion_model
        self._motion_state = None
        if callable(getattr(motion_model, "particle_state", None)):
            self._motion_state = np.ascontiguousarray(motion_model.particle_state(self._n))
            if self._motion_state.shape[:1] != (self._n,):
                raise ValueError(f"motion_model.particle_state({self._n}) must have {self._n} rows, "
                                 f"got shape {self._motion_state.shape}")
        # The state as rows (a view), and rows to gather it through, for the kernels that resample
        self._bind_state_rows()
        self._state_scratch = np.empty_like(self._state_rows)

    def _bind_state_rows(self) -> None:
        """The motion state as rows: a view, which the kernels that resample gather through (a copy's own)."""
        self._state_rows = _NO_STATE if self._motion_state is None else self._motion_state.reshape(self._n, -1)

    @property
    def n(self) -> int:
        """The number of particles N (fixed: the filter's arrays are made for it)."""
        return self._n

    @property
    def poses(self) -> np.ndarray:
        """The particles, (N, 3) [x, y, θ]: the filter's own array, which its kernels work in. Replace them
        with `set_particles` (validated; the kernels trust the array's shape)."""
        return self._poses

    @poses.setter
    def poses(self, value) -> None:
        raise AttributeError("ParticleFilter.poses cannot be rebound: use set_particles(poses, log_weights), "
                             "which checks them")

    @property
    def log_weights(self) -> np.ndarray:
        """The particles' log-weights, (N,): the filter's own array (normalized with `weights`). Replace them
        with `set_particles`."""
        return self._log_weights

    @log_weights.setter
    def log_weights(self, value) -> None:
        raise AttributeError("ParticleFilter.log_weights cannot be rebound: use set_particles(poses, log_weights), "
                             "which checks them and normalizes the weights")

    @property
    def weights(self) -> np.ndarray:
        """Normalized weights (a read-only view)."""
        view = self._weights.view()
        view.flags.writeable = False
        return view

    @property
    def motion_state(self) -> np.ndarray | None:
        """The stateful motion model's per-particle state (a read-only view), or None for a stateless model."""
        if self._motion_state is None:
            return None
        view = self._motion_state.view()
        view.flags.writeable = False
        return view

    def _set_particles(self, poses: np.ndarray) -> None:
        self._forget_anchor()
        if self._motion_state is not None:
            self._motion_state[:] = self.motion_model.particle_state(self._n)
        self._poses[:] = poses
        self._poses[:, 2] = wrap_angles(self._poses[:, 2])
        self._log_weights[:] = -math.log(self._n)
        self._weights[:] = 1.0 / self._n
        self.ess = float(self._n)
        self._changed()

    def _mirror_particles(self) -> None:
        """Every particle through the centre mark, weights kept; the estimate's hysteresis starts afresh."""
        self._poses[:] = self._field.mirror_poses(self._poses)
        self._forget_anchor()
        self._changed()

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
        sigma = self._check_sigma(sigma)
        noisy = self._poses + sigma * self.rng.standard_normal((self._n, 3))
        self._poses[:] = noisy
        self._poses[:, 2] = wrap_angles(self._poses[:, 2])
        self._forget_anchor()
        self._changed()

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
        try:
            factors = np.asarray(log_factors, dtype=np.float64)
        except (TypeError, ValueError):
            raise ArgumentTypeError(f"log_factors = {log_factors!r} must be an array of numbers") from None
        if factors.shape != (self._n,) or np.isnan(factors).any() or np.isposinf(factors).any():
            raise ValueError(f"log_factors must have shape ({self._n},) with no NaN or +inf")
        combined = self._log_weights + factors
        if not np.isfinite(combined).any():
            raise ValueError("log_factors would leave no particle with a finite weight")
        total, self.ess = normalize(combined, self._weights)
        self._log_weights[:] = combined - total
        self._changed()

    @staticmethod
    def _check_sigma(sigma, name: str = "sigma") -> np.ndarray:
        return reals(name, sigma, 3, 0.0, LARGEST_SIGMA)

    def set_particles(self, poses: Sequence[Sequence[float]] | np.ndarray,
                      log_weights: Sequence[float] | np.ndarray | None = None,
                      motion_state: np.ndarray | None = None) -> None:
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
        poses = check_poses("poses", poses)
        if motion_state is not None:
            if self._motion_state is None:
                raise ValueError("motion_state given, but the motion model keeps no per-particle state")
            try:
                motion_state = np.asarray(motion_state, dtype=self._motion_state.dtype)
            except (TypeError, ValueError):
                raise ArgumentTypeError(f"motion_state = {motion_state!r} must be an array of numbers") from None
            if motion_state.shape != self._motion_state.shape or not np.isfinite(motion_state).all():
                raise ValueError(f"motion_state must be finite with shape {self._motion_state.shape}, "
                                 f"got {motion_state.shape}")
        if poses.shape != (self._n, 3):
            raise ValueError(f"poses must have shape ({self._n}, 3), got {poses.shape}")
        if log_weights is not None:
            try:
                log_weights = np.asarray(log_weights, dtype=np.float64)
            except (TypeError, ValueError):
                raise ArgumentTypeError(f"log_weights = {log_weights!r} must be an array of numbers") from None
            if (log_weights.shape != (self._n,) or np.isnan(log_weights).any() or np.isposinf(log_weights).any()
                    or not (log_weights > -np.inf).any()):
                raise ValueError("log_weights must have shape (N,), no NaN or +inf, and at least one finite entry")
        self._set_particles(poses)
        if motion_state is not None and self._motion_state is not None:    # (checked above: both or neither)
            self._motion_state[:] = motion_state
        if log_weights is not None:
            total, self.ess = normalize(log_weights, self._weights)
            self._log_weights[:] = log_weights - total
