"""The particle set: N poses with their log-weights and normalized weights, a stateful motion model's state per
particle, and the buffers a step works in, as named arrays.

    from mcl.particles import Particles, check_pose, check_poses

`Particles` is what `mcl.ParticleFilter` owns of its particles: the arrays, kept across steps so that a
steady-state step allocates nothing that grows with N, and the calls that replace or disturb them (`assign`,
`replace`, `mirror`, `diffuse`, `reweigh`). It knows nothing of the summary or of the engine: the filter tells
its summary when the particles changed, and its engine (`mcl.engine`) moves, weighs and resamples the arrays.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from field.angles import wrap_angles
from field.checks import LARGEST_ANGLE, LARGEST_COORDINATE, LARGEST_SIGMA, ArgumentTypeError, real, reals

from .weights import normalize

_NO_STATE = np.empty((0, 0))  # no per-particle motion state


def check_pose(name: str, pose) -> np.ndarray:
    """A pose (x, y, θ) as float64 (3,): |x|, |y| at most `LARGEST_COORDINATE`, |θ| at most `LARGEST_ANGLE`."""
    array = reals(name, pose, 3)
    if max(abs(array[0]), abs(array[1])) > LARGEST_COORDINATE or abs(array[2]) > LARGEST_ANGLE:
        raise ValueError(f"{name} = {pose!r} must be within {LARGEST_COORDINATE:g} m and {LARGEST_ANGLE:g} rad")
    return array


def check_poses(name: str, poses, at_least: int = 0) -> np.ndarray:
    """Poses (K, 3) (or one (3,)) as float64 (K, 3), K >= `at_least`, each within the bounds of `check_pose`."""
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
    if array.shape[0] < at_least:
        raise ValueError(f"{name} = {poses!r} must be {at_least} or more (x, y, θ) poses")
    inside = (
        np.isfinite(array).all(axis=1)
        & (np.abs(array[:, :2]) <= LARGEST_COORDINATE).all(axis=1)
        & (np.abs(array[:, 2]) <= LARGEST_ANGLE)
    )
    if not inside.all():
        i = int(np.argmin(inside))
        raise ValueError(
            f"{name}[{i}] = {array[i].tolist()!r} must be finite, within {LARGEST_COORDINATE:g} m "
            f"and {LARGEST_ANGLE:g} rad"
        )
    return array


class Particles:
    """N particles as named arrays: `poses` (N, 3) [x, y, θ], `log_weights` (N,), `weights` (N,), a stateful motion
    model's `motion_state` (None for a stateless one), and the buffers a step works in.

    Parameters
    ----------
    n : int
        The number of particles (checked by the filter).
    motion_model : object
        The motion model; when it has `particle_state(n)` (`mcl.contracts.ParticleState`), each particle keeps
        a state it starts fresh with.

    Raises
    ------
    ValueError
        If the motion model's `particle_state(n)` does not have n rows.
    """

    def __init__(self, n: int, motion_model: Any) -> None:
        self.n = n
        self.motion_model = motion_model
        self.poses = np.zeros((n, 3))
        self.log_weights = np.full(n, -math.log(n))
        self.weights = np.full(n, 1.0 / n)
        self.log_likelihood = np.empty(n)
        self.previous = np.empty((n, 3))  # the particles before resampling (the copy's source)
        self.capture_poses = np.empty((n, 3))  # the particles moved back to a frame's capture (latency)
        self.trig = np.empty((n, 2))  # cos, sin of the scored headings, for the roughening
        self.variates = np.empty((n, 3))  # drawn Gaussian motion noise, resampling variates
        self.counts = np.zeros(n + 1, dtype=np.int64)  # resampling scratch (zero between uses)
        self.motion_state: np.ndarray | None = None
        if callable(getattr(motion_model, "particle_state", None)):
            self.motion_state = np.ascontiguousarray(motion_model.particle_state(n))
            if self.motion_state.shape[:1] != (n,):
                raise ValueError(
                    f"motion_model.particle_state({n}) must have {n} rows, got shape {self.motion_state.shape}"
                )
        self._bind_state_rows()
        self.state_scratch = np.empty_like(self.state_rows)

    def _bind_state_rows(self) -> None:
        # The motion state as rows: a view, which the kernels that resample gather through (a copy's own view).
        self.state_rows = _NO_STATE if self.motion_state is None else self.motion_state.reshape(self.n, -1)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        del state["state_rows"]  # a view of `motion_state`: made again, so that a copy's view is its own
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._bind_state_rows()

    def fresh_state(self, start: int = 0) -> None:
        """Fresh motion state for particles start..N (reset or injected particles); nothing for a stateless model."""
        if self.motion_state is not None:
            self.motion_state[start:] = self.motion_model.particle_state(self.n - start)

    def take_injected(self, keep: int, injected: np.ndarray) -> None:
        """After `keep` resampled particles: the `injected` poses behind them, with fresh motion state; equal
        weights for all."""
        self.fresh_state(keep)
        self.poses[keep:] = injected
        self.uniform_weights()

    def uniform_weights(self) -> None:
        """Equal weights 1/N."""
        self.log_weights[:] = -math.log(self.n)
        self.weights[:] = 1.0 / self.n

    def assign(self, poses: np.ndarray) -> None:
        """New poses (headings wrapped), equal weights and fresh motion state."""
        self.fresh_state()
        self.poses[:] = poses
        self.poses[:, 2] = wrap_angles(self.poses[:, 2])
        self.uniform_weights()

    def uniform_poses(
        self,
        bounds: tuple[float, float, float, float],
        rng: np.random.Generator,
        heading: float | None = None,
        heading_sigma: float = 0.0,
    ) -> np.ndarray:
        """N poses uniform over `bounds` (x_min, x_max, y_min, y_max) [m], drawn from `rng`: uniform headings, or
        normal ones around `heading` with `heading_sigma` [rad] (both checked first)."""
        if heading is not None:
            heading = real("heading", heading, -LARGEST_ANGLE, LARGEST_ANGLE)
            heading_sigma = real("heading_sigma", heading_sigma, 0.0, LARGEST_SIGMA)
        x_min, x_max, y_min, y_max = bounds
        poses = np.empty((self.n, 3))
        poses[:, 0] = rng.uniform(x_min, x_max, self.n)
        poses[:, 1] = rng.uniform(y_min, y_max, self.n)
        if heading is None:
            poses[:, 2] = rng.uniform(-math.pi, math.pi, self.n)
        else:
            poses[:, 2] = heading + heading_sigma * rng.standard_normal(self.n)
        return poses

    def normal_poses(self, centres: np.ndarray, sigma: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """N poses normal around `centres` (K, 3) with standard deviations `sigma` (3,), drawn from `rng`:
        particle i around centre i mod K."""
        return centres[np.arange(self.n) % centres.shape[0]] + sigma * rng.standard_normal((self.n, 3))

    def mirror(self, field) -> None:
        """Every particle through the centre mark of `field`, weights kept."""
        self.poses[:] = field.mirror_poses(self.poses)

    def diffuse(self, sigma: np.ndarray, rng: np.random.Generator) -> None:
        """Add normal noise of standard deviations `sigma` (checked) drawn from `rng` to every pose."""
        noisy = self.poses + sigma * rng.standard_normal((self.n, 3))
        self.poses[:] = noisy
        self.poses[:, 2] = wrap_angles(self.poses[:, 2])

    def reweigh(self, log_factors) -> float:
        """Multiply each weight by exp(log_factors[i]) and normalize; returns the ESS. Validated first.

        Raises
        ------
        ValueError
            If the shape is wrong, a factor is NaN or +inf, or every factor is -inf (nothing changes).
        """
        try:
            factors = np.asarray(log_factors, dtype=np.float64)
        except (TypeError, ValueError):
            raise ArgumentTypeError(f"log_factors = {log_factors!r} must be an array of numbers") from None
        if factors.shape != (self.n,) or np.isnan(factors).any() or np.isposinf(factors).any():
            raise ValueError(f"log_factors must have shape ({self.n},) with no NaN or +inf")
        combined = self.log_weights + factors
        if not np.isfinite(combined).any():
            raise ValueError("log_factors would leave no particle with a finite weight")
        total, ess = normalize(combined, self.weights)
        self.log_weights[:] = combined - total
        return ess

    def replace(self, poses, log_weights=None, motion_state=None) -> float:
        """`ParticleFilter.set_particles`: validated, then assigned; returns the ESS.

        Raises
        ------
        ValueError
            If a shape is wrong, a value out of range, or `motion_state` is given for a motion model that
            keeps none (the particles are left unchanged).
        """
        poses = check_poses("poses", poses)
        if motion_state is not None:
            if self.motion_state is None:
                raise ValueError("motion_state given, but the motion model keeps no per-particle state")
            try:
                motion_state = np.asarray(motion_state, dtype=self.motion_state.dtype)
            except (TypeError, ValueError):
                raise ArgumentTypeError(f"motion_state = {motion_state!r} must be an array of numbers") from None
            if motion_state.shape != self.motion_state.shape or not np.isfinite(motion_state).all():
                raise ValueError(
                    f"motion_state must be finite with shape {self.motion_state.shape}, got {motion_state.shape}"
                )
        if poses.shape != (self.n, 3):
            raise ValueError(f"poses must have shape ({self.n}, 3), got {poses.shape}")
        if log_weights is not None:
            try:
                log_weights = np.asarray(log_weights, dtype=np.float64)
            except (TypeError, ValueError):
                raise ArgumentTypeError(f"log_weights = {log_weights!r} must be an array of numbers") from None
            if (
                log_weights.shape != (self.n,)
                or np.isnan(log_weights).any()
                or np.isposinf(log_weights).any()
                or not (log_weights > -np.inf).any()
            ):
                raise ValueError("log_weights must have shape (N,), no NaN or +inf, and at least one finite entry")
        self.assign(poses)
        ess = float(self.n)
        if motion_state is not None and self.motion_state is not None:  # (checked above: both or neither)
            self.motion_state[:] = motion_state
        if log_weights is not None:
            total, ess = normalize(log_weights, self.weights)
            self.log_weights[:] = log_weights - total
        return ess


def check_sigma(sigma, name: str = "sigma") -> np.ndarray:
    """Three standard deviations (x [m], y [m], θ [rad]) as float64 (3,), each finite, >= 0 and not too large."""
    return reals(name, sigma, 3, 0.0, LARGEST_SIGMA)
