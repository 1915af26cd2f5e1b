"""The goal-direction sensor model: the bearing of a goal seen as a whole (the centre between its posts).

    from sensing.goal_direction import GoalDirectionSensorModel
    model = GoalDirectionSensorModel(spl(), bearing_sigma=0.1)
    pf = ParticleFilter(spl(), VelocityLinear(), model)
    pf.correct(Observations.from_arrays(["goalpost"], [4.0], [0.3]))     # a goal seen at bearing 0.3 rad

A vision system that finds a goal as a whole reports the bearing of its centre; the range of a goal that wide
is poor, and this model leaves it out. Each detection (of kind `goalpost`: the goal's) is scored against both
goal centres, the robot cannot tell its own goal from the other, as a max-mixture with an outlier floor:

    log p(b | x, y, θ) = max(max_g log N(wrap(b - bearing_g(x, y, θ)); 0, σ²), log outlier_weight)

summed over the frame's detections, σ the detection's bearing σ or the model's. The model offers the fused
compiled step one per-particle log-likelihood (`particle_log_likelihood`, `sensing.fused.per_particle_kernels`)
and nothing else: the filter's blocks, heading cache, camera latency and `fast` option stay the filter's.
`log_likelihood` runs the same function over the particles (so both paths give the same bits); `reference`
is its plain numpy twin, which the tests compare with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from field import Field, LandmarkType
from field.angles import wrap_angles
from field.checks import LARGEST_SIGMA, SMALLEST_SIGMA, real
from numerics.trig import atan2_poly

from .fused import FusedLikelihoodKernels, per_particle_kernels, per_particle_log_likelihood
from .observations import Observations

_HALF_LOG_TWO_PI = 0.5 * math.log(2.0 * math.pi)


@numba.njit(cache=True)
def prepare(inputs, params):
    """The frame (detections (m, 4): cos and sin of the bearing, 1/σ and the normal's log normalizer of each;
    goal centres (2, 2); log outlier weight) and the index of the first detection that is not a goal (-1:
    none)."""
    kinds, bearings, bearing_sigmas = inputs
    goals, bearing_sigma, log_outlier = params
    detections = np.empty((bearings.shape[0], 4))
    missing = -1
    for j in range(bearings.shape[0]):
        if kinds[j] != 0 and missing < 0:  # LandmarkType.GOALPOST
            missing = j
        sigma = bearing_sigma if np.isnan(bearing_sigmas[j]) else bearing_sigmas[j]
        detections[j, 0] = math.cos(bearings[j])
        detections[j, 1] = math.sin(bearings[j])
        detections[j, 2] = 1.0 / sigma
        detections[j, 3] = -math.log(sigma) - _HALF_LOG_TWO_PI
    return (detections, goals, log_outlier), missing


@numba.njit(cache=True, inline="always")
def particle_log_likelihood(x, y, cos_theta, sin_theta, frame):
    """The frame's log-likelihood for one particle at (x, y) heading (cos θ, sin θ): the contract of
    `sensing.fused.per_particle_kernels`."""
    detections, goals, log_outlier = frame
    total = 0.0
    for j in range(detections.shape[0]):
        best = log_outlier
        for g in range(goals.shape[0]):
            dx = goals[g, 0] - x
            dy = goals[g, 1] - y
            forward = cos_theta * dx + sin_theta * dy  # the goal in the robot's frame
            left = cos_theta * dy - sin_theta * dx
            # The angle from the detection's direction to the goal's, in [-π, π]: the bearing error, wrapped
            # (`atan2_poly`: branch-free, no call into libm).
            c, s = detections[j, 0], detections[j, 1]
            error = atan2_poly(c * left - s * forward, c * forward + s * left) * detections[j, 2]
            best = max(best, detections[j, 3] - 0.5 * error * error)
        total += best
    return total


def _inputs(observations: Observations) -> tuple:
    return observations.kinds, observations.bearings, observations.bearing_sigmas


@dataclass(frozen=True, eq=False)
class GoalDirectionSensorModel:
    """The bearing of a goal's centre, either goal (see the module docstring).

    Parameters
    ----------
    field : Field
        The field: its goals' centres are (±half_length, 0).
    bearing_sigma : float, default 0.1
        The bearing's standard deviation [rad] for a detection that gives none.
    outlier_weight : float, default 0.05
        The likelihood floor of a detection no goal explains (a false positive), in (0, 1].

    Raises
    ------
    ValueError
        If a number is out of range.
    """

    field: Field
    bearing_sigma: float = 0.1
    outlier_weight: float = 0.05

    def __post_init__(self) -> None:
        real("bearing_sigma", self.bearing_sigma, SMALLEST_SIGMA, LARGEST_SIGMA)
        real("outlier_weight", self.outlier_weight, 0.0, 1.0, low_open=True)

    @property
    def goals(self) -> np.ndarray:
        """The goals' centres, (2, 2) [m]."""
        half = self.field.half_length
        return np.array([[half, 0.0], [-half, 0.0]])

    def _params(self) -> tuple:
        return self.goals, float(self.bearing_sigma), math.log(self.outlier_weight)

    def check(self, observations: Observations) -> None:
        """Refuse a frame with a detection that is not a goal (kind `goalpost`).

        Raises
        ------
        ValueError
            Naming the first such detection.
        """
        observations = Observations.coerce(observations)
        others = np.flatnonzero(observations.kinds != LandmarkType.GOALPOST)
        if others.size:
            j = int(others[0])
            raise ValueError(
                f"detection {j} is a {LandmarkType(int(observations.kinds[j])).name}: the goal-direction "
                "model scores goals (kind goalpost) only"
            )

    def terms(self, observations: Observations) -> int:
        """The independent terms a frame scores: one per detection."""
        return len(Observations.coerce(observations))

    def log_likelihood(
        self, poses: np.ndarray, observations: Observations, out: np.ndarray | None = None
    ) -> np.ndarray:
        """log p(detections | pose) for each of the (N, 3) poses, in compiled code (`particle_log_likelihood`).

        Raises
        ------
        ValueError
            If a detection is not a goal (`check`).
        """
        observations = Observations.coerce(observations)
        self.check(observations)
        frame, _ = prepare(_inputs(observations), self._params())
        return per_particle_log_likelihood(particle_log_likelihood, poses, frame, out)

    def reference(self, poses: np.ndarray, observations: Observations) -> np.ndarray:
        """`log_likelihood` in plain numpy, as the module docstring writes it (to rounding: the kernel takes the
        angle between the detection's direction and the goal's, with `atan2_poly`)."""
        observations = Observations.coerce(observations)
        self.check(observations)
        poses = np.asarray(poses, dtype=np.float64)
        sigmas = np.where(np.isnan(observations.bearing_sigmas), self.bearing_sigma, observations.bearing_sigmas)
        total = np.zeros(poses.shape[0])
        for bearing, sigma in zip(observations.bearings, sigmas):
            best = np.full(poses.shape[0], math.log(self.outlier_weight))
            for gx, gy in self.goals:
                predicted = np.arctan2(gy - poses[:, 1], gx - poses[:, 0]) - poses[:, 2]
                error = wrap_angles(bearing - predicted) / sigma
                best = np.maximum(best, -0.5 * error * error - math.log(sigma) - _HALF_LOG_TWO_PI)
            total += best
        return total

    def fused_likelihood(self) -> FusedLikelihoodKernels:
        """This model's likelihood for the filter's fused step: `particle_log_likelihood` through
        `sensing.fused.per_particle_kernels`."""
        return per_particle_kernels(prepare, particle_log_likelihood, self._params(), _inputs)
