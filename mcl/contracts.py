"""What the filter asks of its models: the contracts, in one place.

    from mcl.contracts import MotionModel, SensorModel, capabilities

The filter core knows a model only by these. Two are required:

- `MotionModel`: `check(u)` refuses a `MotionInput` the model cannot use (ValueError naming the field) and
  `predict(poses, u, rng)` moves the (N, 3) poses in place, drawing from `rng` only.
- `SensorModel`: `check(observations)` refuses what the model cannot score and `log_likelihood(poses,
  observations, out=None)` returns (N,) log-likelihoods (finite or -inf), up to a constant shared by all poses.

(`MotionModel` is defined with the motion models' input, `motion_models.base`, and re-exported here.) The
filter's third collaborator, which poses to inject and what tells the two field halves apart, has a contract
too: `Relocalization` (`mcl.relocalization.SoccerRelocalization` is the default).

Each optional capability is a small protocol; a model offers it by having the method (no registration, no
base class), and the filter uses it when it is there:

| capability          | protocol             | what the filter does with it                                         |
|---------------------|----------------------|----------------------------------------------------------------------|
| fused likelihood    | `FusedLikelihood`    | scores inside its one compiled call per step (`sensing.fused`)        |
| per-term fit        | `TermCount`          | augmented MCL's average likelihood per term (default: per detection)  |
| sensor resetting    | `SensorResetting`    | injects poses drawn from the detections (`mcl.relocalization`)        |
| negative information| `ViewScoring`        | scores a frame with a camera view through `log_likelihood`            |
| per-particle state  | `ParticleState`      | keeps a state per particle through resampling (`predict(..., state=)`)|
| bounded noise       | `BoundedNoise`       | moves the particles in its own kernels (`motion_models.kernels`)      |

The bounded-noise fast path also needs the model's `predict` to be exactly that motion: a model gets it by
subclassing `motion_models.base.BoundedNoiseModel` without overriding `predict` or `check` (its `predict` is
the kernels' motion, so the two paths agree bit for bit). `capabilities(model)` says what a model offers and
`fast_path(motion_model, sensor_model)` whether a filter with them takes the fused step;
`mcl.tools.testing.check_motion_model` and `check_sensor_model` check a model against its contract.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from motion_models.base import BoundedNoiseModel, MotionInput, MotionModel
from sensing.fused import FusedLikelihoodKernels
from sensing.observations import Observations

__all__ = [
    "MotionModel",
    "SensorModel",
    "Relocalization",
    "FusedLikelihood",
    "FusedLikelihoodKernels",
    "TermCount",
    "SensorResetting",
    "ViewScoring",
    "ParticleState",
    "BoundedNoise",
    "capabilities",
    "moves_by_bounded_noise",
    "fused_kernels",
    "numpy_twin",
    "fast_path",
    "REQUIRED_METHODS",
    "lacks",
]


@runtime_checkable
class SensorModel(Protocol):
    """A sensor model: scores particles by a frame's observations."""

    def check(self, observations: Observations) -> None:
        """Raise ValueError if the model cannot score `observations`; change nothing.

        Parameters
        ----------
        observations : Observations
            One camera frame's detections.

        Raises
        ------
        ValueError
            If the model cannot score `observations` (naming what it lacks).
        """

    def log_likelihood(
        self, poses: np.ndarray, observations: Observations, out: np.ndarray | None = None
    ) -> np.ndarray:
        """(N,) log-likelihoods of `observations` at `poses` (N, 3): finite or -inf, never NaN or +inf.

        Parameters
        ----------
        poses : np.ndarray
            (N, 3) float64 particle poses (x [m], y [m], θ [rad]) in the field frame.
        observations : Observations
            One camera frame's detections.
        out : np.ndarray or None, optional
            (N,) float64 array to write the result into; None (the default) allocates one.

        Returns
        -------
        np.ndarray
            (N,) log-likelihoods, up to a constant shared by all poses (`out` when given).
        """


@runtime_checkable
class Relocalization(Protocol):
    """Which poses augmented MCL injects, and the priors that tell a pose from its mirror image."""

    tracking: bool  # whether the filter has been confident since the last reset

    def bind(self, carpet: tuple[float, float, float, float]) -> None:
        """The carpet (x_min, x_max, y_min, y_max) the filter's particles live on.

        Parameters
        ----------
        carpet : tuple of float
            (x_min, x_max, y_min, y_max) [m] of the carpet, in the field frame.
        """

    def reset_region(self, bounds: tuple[float, float, float, float]) -> None:
        """The belief was spread over `bounds`: inject there until confident.

        Parameters
        ----------
        bounds : tuple of float
            (x_min, x_max, y_min, y_max) [m] of the region the particles were spread over.
        """

    def reset_pose(self, pose: np.ndarray) -> None:
        """The belief was set around a known pose.

        Parameters
        ----------
        pose : np.ndarray
            (3,) pose (x [m], y [m], θ [rad]) the particles were set around.
        """

    def mirror(self) -> None:
        """The particles were mirrored through the centre mark."""

    def carry(self, dx: float, dy: float, dtheta: float) -> None:
        """The robot moved by (dx, dy, dθ) in its frame.

        Parameters
        ----------
        dx, dy : float
            Displacement [m] in the robot frame (x forward, y left).
        dtheta : float
            Rotation [rad], counter-clockwise.
        """

    def confirm(self, estimate: Any, explains: bool) -> bool:
        """After a correction: the estimate, and whether the belief explains the detections as usual; True asks
        the filter to mirror its particles.

        Parameters
        ----------
        estimate : mcl.Estimate
            The filter's estimate after the correction.
        explains : bool
            Whether the belief explains the frame's detections as usual.

        Returns
        -------
        bool
            True to ask the filter to mirror its particles through the centre mark.
        """

    def propose(
        self, count: int, observations: Observations, sensor_model: Any, rng: np.random.Generator
    ) -> np.ndarray:
        """(count, 3) poses to inject, drawn from `rng`.

        Parameters
        ----------
        count : int
            How many poses to propose.
        observations : Observations
            The frame that triggered the injection.
        sensor_model : SensorModel
            The filter's sensor model (used when it offers `SensorResetting`).
        rng : np.random.Generator
            The only source of randomness.

        Returns
        -------
        np.ndarray
            (count, 3) float64 poses (x [m], y [m], θ [rad]).
        """


@runtime_checkable
class FusedLikelihood(Protocol):
    """Capability: the likelihood as compiled kernels the filter's fused step calls (`sensing.fused`)."""

    def fused_likelihood(self) -> FusedLikelihoodKernels | None:
        """The kernels and their constants, or None when this configuration has none."""


@runtime_checkable
class TermCount(Protocol):
    """Capability: how many independent terms a frame's likelihood sums (augmented MCL averages per term)."""

    def terms(self, observations: Observations) -> int:
        """The number of terms (>= 0).

        Parameters
        ----------
        observations : Observations
            One camera frame's detections.

        Returns
        -------
        int
            How many independent terms the frame's log-likelihood sums.
        """


@runtime_checkable
class SensorResetting(Protocol):
    """Capability: poses drawn from the detections themselves (Lenser and Veloso's sensor resetting)."""

    def sample_poses(
        self,
        observations: Observations,
        n: int,
        rng: np.random.Generator,
        heading: float | None = None,
        heading_sigma: float = 0.3,
    ) -> np.ndarray:
        """(n, 3) poses that explain `observations`, drawn from `rng`.

        Parameters
        ----------
        observations : Observations
            The frame whose detections the poses must explain.
        n : int
            How many poses to draw.
        rng : np.random.Generator
            The only source of randomness.
        heading : float or None, optional
            A known heading [rad] to draw around (e.g. from the IMU); None (the default) when unknown.
        heading_sigma : float, optional
            Standard deviation [rad] around `heading`; default 0.3.

        Returns
        -------
        np.ndarray
            (n, 3) float64 poses (x [m], y [m], θ [rad]).
        """


@runtime_checkable
class ViewScoring(Protocol):
    """Capability: negative information, the landmarks a frame's camera view should have shown."""

    def scores_view(self, observations: Observations) -> bool:
        """Whether `log_likelihood` of this frame includes its view (the fused step does not).

        Parameters
        ----------
        observations : Observations
            One camera frame's detections, with or without a camera view.

        Returns
        -------
        bool
            True when the frame's view adds negative information to `log_likelihood`.
        """


@runtime_checkable
class ParticleState(Protocol):
    """Capability: a state per particle that `predict(poses, u, rng, state=...)` reads and updates."""

    def particle_state(self, n: int) -> np.ndarray:
        """A fresh state for `n` particles (n rows); the filter gathers the rows through resampling.

        Parameters
        ----------
        n : int
            The number of particles.

        Returns
        -------
        np.ndarray
            An array with `n` rows, one state per particle.
        """


@runtime_checkable
class BoundedNoise(Protocol):
    """Capability: motion by the displacement of `MotionInput` plus bounded robot-frame noise (Hoffmann eq. 10)."""

    gaussian: bool

    def noise_bounds(self, u: MotionInput) -> tuple[float, float, float]:
        """The noise's half-widths (x [m], y [m], θ [rad]) for `u` (uniform; Gaussian of the same variance).

        Parameters
        ----------
        u : MotionInput
            One control period's motion input.

        Returns
        -------
        tuple of float
            The half-widths (x [m], y [m], θ [rad]).
        """


REQUIRED_METHODS: dict[type, tuple[str, ...]] = {
    MotionModel: ("check", "predict"),
    SensorModel: ("check", "log_likelihood"),
    Relocalization: ("bind", "reset_region", "reset_pose", "mirror", "carry", "confirm", "propose"),
}
"""The methods the filter calls on each required collaborator (what `lacks` checks before it takes one)."""


def lacks(obj: object, contract: type) -> list[str]:
    """The methods of `contract` (a key of `REQUIRED_METHODS`) that `obj` does not have as callables.

    Parameters
    ----------
    obj : object
        The would-be collaborator.
    contract : type
        `MotionModel`, `SensorModel` or `Relocalization`.

    Returns
    -------
    list of str
        The names of the missing methods, in the contract's order; empty when `obj` has them all.

    Raises
    ------
    KeyError
        If `contract` is not a key of `REQUIRED_METHODS`.
    """
    return [name for name in REQUIRED_METHODS[contract] if not callable(getattr(obj, name, None))]


_CAPABILITIES = (
    ("fused likelihood", FusedLikelihood),
    ("per-term fit", TermCount),
    ("sensor resetting", SensorResetting),
    ("negative information", ViewScoring),
    ("per-particle state", ParticleState),
    ("bounded noise", BoundedNoise),
)


def capabilities(model: object) -> tuple[str, ...]:
    """The optional capabilities `model` offers (by the protocols' names in the module docstring's table).

    Parameters
    ----------
    model : object
        A motion or sensor model.

    Returns
    -------
    tuple of str
        The capabilities' names ("fused likelihood", "per-term fit", ...), in the table's order.
    """
    return tuple(name for name, protocol in _CAPABILITIES if isinstance(model, protocol))


def moves_by_bounded_noise(model: object) -> bool:
    """Whether the filter may move the particles itself for `model`: a `BoundedNoiseModel` whose `predict` and
    `check` are the base class's (so that the kernels' motion is the model's, bit for bit).

    Parameters
    ----------
    model : object
        A motion model.

    Returns
    -------
    bool
        True when the filter's kernels may move the particles for `model`.
    """
    kind: Any = type(model)
    return (
        isinstance(model, BoundedNoiseModel)
        and kind.predict is BoundedNoiseModel.predict
        and kind.check is BoundedNoiseModel.check
    )


def numpy_twin(model: object) -> Any | None:
    """The model computed in plain numpy (its `numpy_twin()`, as the landmark and line models offer it: methods of
    the names and results of the model's own), or None when it offers none. The reference engine scores and
    draws through it.

    Parameters
    ----------
    model : object
        A sensor model.

    Returns
    -------
    object or None
        What the model's `numpy_twin()` returned; None when it has no such method.
    """
    offer = getattr(model, "numpy_twin", None)
    return offer() if callable(offer) else None


def fused_kernels(sensor_model: object) -> FusedLikelihoodKernels | None:
    """The sensor model's fused-likelihood kernels, or None (no such capability, or none in this configuration).

    Parameters
    ----------
    sensor_model : object
        A sensor model.

    Returns
    -------
    FusedLikelihoodKernels or None
        What the model's `fused_likelihood()` returned; None when it has no such method or returned None.

    Raises
    ------
    TypeError
        If `fused_likelihood` returns anything else (naming the model).
    """
    offer = getattr(sensor_model, "fused_likelihood", None)
    if not callable(offer):
        return None
    kernels = offer()
    if kernels is None:
        return None
    if not isinstance(kernels, FusedLikelihoodKernels):
        raise TypeError(
            f"{type(sensor_model).__name__}.fused_likelihood() must return a "
            f"sensing.fused.FusedLikelihoodKernels or None, not {type(kernels).__name__}"
        )
    return kernels


def fast_path(motion_model: object, sensor_model: object) -> dict[str, bool]:
    """Which parts of a filter step with these models run in the fused compiled call: {"motion": the filter
    moves the particles in its kernels, "likelihood": the sensor model is scored there, "step": both, so
    `step` is one call}. A stateful motion model (`ParticleState`) moves itself.

    Parameters
    ----------
    motion_model : object
        The filter's motion model.
    sensor_model : object
        The filter's sensor model.

    Returns
    -------
    dict of str to bool
        {"motion": ..., "likelihood": ..., "step": ...} as above.

    Raises
    ------
    TypeError
        If the sensor model's `fused_likelihood` returns neither kernels nor None (see `fused_kernels`).
    """
    motion = moves_by_bounded_noise(motion_model) and not isinstance(motion_model, ParticleState)
    likelihood = fused_kernels(sensor_model) is not None
    return {"motion": motion, "likelihood": likelihood, "step": motion and likelihood}
