"""Several sensor models as one: their log-likelihoods add (the detections are independent given the pose).

    from sensing import CombinedSensorModel, LandmarkSensorModel, LineSensorModel
    model = CombinedSensorModel((LandmarkSensorModel(field), LineSensorModel(field)))

Sensor resetting (`sample_poses`) is delegated to the first model that offers it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .observations import Observations


@dataclass(frozen=True, eq=False)
class CombinedSensorModel:
    """Several sensor models scored as one: the sum of their log-likelihoods.

    Parameters
    ----------
    models : tuple
        The sensor models (each with callable `check` and `log_likelihood`), at least one; any iterable is
        accepted and kept as a tuple.

    Raises
    ------
    ValueError
        If `models` is empty, or a model lacks `check` or `log_likelihood` (naming the model and what it lacks).
    """

    models: tuple

    def __post_init__(self) -> None:
        models = tuple(self.models)
        if not models:
            raise ValueError("models = () must name at least one sensor model")
        for i, model in enumerate(models):
            missing = [m for m in ("check", "log_likelihood") if not callable(getattr(model, m, None))]
            if missing:
                raise ValueError(f"models[{i}] = {model!r} lacks {', '.join(missing)}")
        object.__setattr__(self, "models", models)

    def check(self, observations: Observations) -> None:
        """Every model's `check`, in order: refuses what any of them cannot score.

        Parameters
        ----------
        observations : Observations
            One camera frame's detections.

        Raises
        ------
        ValueError
            If one of the models refuses `observations` (the first one's error).
        """
        for model in self.models:
            model.check(observations)

    def terms(self, observations: Observations) -> int:
        """How many independent terms the likelihood sums: the sum over the models of their `terms`, or of
        `len(observations)` for a model without one.

        Parameters
        ----------
        observations : Observations
            One camera frame's detections, passed to each model.

        Returns
        -------
        int
            The total number of terms (>= 0).
        """
        return sum(getattr(model, "terms", len)(observations) for model in self.models)

    def log_likelihood(
        self, poses: np.ndarray, observations: Observations, out: np.ndarray | None = None
    ) -> np.ndarray:
        """(N,) sum of the models' log-likelihoods of `observations` at `poses`.

        Parameters
        ----------
        poses, observations, out
            As `mcl.contracts.SensorModel.log_likelihood`; each model writes into a scratch array, and the sum
            goes into `out` when given.

        Returns
        -------
        np.ndarray
            (N,) summed log-likelihoods (`out` when given).
        """
        out = np.zeros(poses.shape[0]) if out is None else out
        out[:] = 0.0
        part = np.empty(poses.shape[0])
        for model in self.models:
            out += model.log_likelihood(poses, observations, out=part)
        return out

    def sample_poses(self, observations: Observations, n: int, rng: np.random.Generator, **kwargs: Any) -> np.ndarray:
        """(n, 3) poses drawn by the first model that has `sample_poses` (sensor resetting); none when no model
        has one.

        Parameters
        ----------
        observations, n, rng
            As `mcl.contracts.SensorResetting.sample_poses`.
        **kwargs : Any
            Passed on to that model's `sample_poses` (e.g. `heading`, `heading_sigma`).

        Returns
        -------
        np.ndarray
            (n, 3) float64 poses (x [m], y [m], θ [rad]) from the first model that samples; (0, 3) when none does.
        """
        for model in self.models:
            sampler = getattr(model, "sample_poses", None)
            if sampler is not None:
                return sampler(observations, n, rng, **kwargs)
        return np.empty((0, 3))
