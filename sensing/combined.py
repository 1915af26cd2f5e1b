"""Several sensor models as one: their log-likelihoods add (the detections are independent given the pose).

    from sensing import CombinedSensorModel, LandmarkSensorModel, LineSensorModel
    model = CombinedSensorModel((LandmarkSensorModel(field), LineSensorModel(field)))

Sensor resetting (`sample_poses`) is delegated to the first model that offers it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .observations import Observations


@dataclass(frozen=True, eq=False)
class CombinedSensorModel:
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
        for model in self.models:
            model.check(observations)

    def terms(self, observations: Observations) -> int:
        return sum(getattr(model, "terms", len)(observations) for model in self.models)

    def log_likelihood(self, poses: np.ndarray, observations: Observations,
                       out: np.ndarray | None = None) -> np.ndarray:
        out = np.zeros(poses.shape[0]) if out is None else out
        out[:] = 0.0
        part = np.empty(poses.shape[0])
        for model in self.models:
            out += model.log_likelihood(poses, observations, out=part)
        return out

    def sample_poses(self, observations: Observations, n: int, rng: np.random.Generator, **kwargs) -> np.ndarray:
        for model in self.models:
            sampler = getattr(model, "sample_poses", None)
            if sampler is not None:
                return sampler(observations, n, rng, **kwargs)
        return np.empty((0, 3))
