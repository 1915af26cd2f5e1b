"""Motion models: how particles move between filter steps, all behind one interface.

    from motion_models import MotionInput, ConstantNoise, VelocityLinear, AdaptiveMotion

    u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1))   # or odometry=(dx, dy, dtheta)
    VelocityLinear().predict(poses, u, rng)             # poses (N, 3), updated in place

`AdaptiveMotion` (Hoffmann's five mobility states) also needs `MotionInput.collision`, a
`motion_models.percepts.CollisionPercept` (which `proprioception.collision.CollisionDetector` makes), and keeps a state
per particle (the filter carries it). `LearnedFootstepOdometry`
(Rouxel et al.) moves particles at support-foot swaps, from `MotionInput.footstep` (a `FootstepEvent`).

A model is a frozen dataclass with `check(u)` (raise ValueError if `u` lacks what it needs) and
`predict(poses, u, rng)`; the filter in `mcl` knows it by that contract and its optional capabilities
(`mcl.contracts`). A model that moves by the input's displacement plus bounded noise subclasses
`base.BoundedNoiseModel` and gets the filter's fused step (`motion_models.kernels`). A new model is a new module
here or in a team's own package (docs/extending.md).
"""

from .adaptive import AdaptiveMotion, MobilityTransitions
from .base import MotionInput, MotionModel
from .constant import ConstantNoise
from .footsteps import FootstepEvent
from .learned_odometry import LearnedFootstepOdometry, RawFootstepOdometry
from .velocity_linear import VelocityLinear

__all__ = [
    "MotionInput",
    "MotionModel",
    "ConstantNoise",
    "VelocityLinear",
    "AdaptiveMotion",
    "MobilityTransitions",
    "FootstepEvent",
    "LearnedFootstepOdometry",
    "RawFootstepOdometry",
]
