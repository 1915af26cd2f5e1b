"""What the adaptive motion model perceives besides the walk request: the collision percept.

    from motion_models.percepts import CollisionPercept, NO_COLLISION

`proprioception.collision.CollisionDetector` produces one per frame from the servos' commands and readings (and
`proprioception.collision` re-exports both names); `MotionInput.collision` carries it to `AdaptiveMotion`. The type
lives with the models that take it, so that the sensing layer depends on the motion models and not the reverse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CollisionPercept:
    """What the detector says about one frame.

    left, right:        a collision on that side now (S_rel > 1)
    s_rel_left/right:   the relative deviations S_rel = D / R
    rate:               share of the recent frames (the detector's `recent_frames`) with a collision
    recent_left/right:  the side(s) of the latest collision, while it is recent
    """

    left: bool = False
    right: bool = False
    s_rel_left: float = 0.0
    s_rel_right: float = 0.0
    rate: float = 0.0
    recent_left: bool = False
    recent_right: bool = False

    def __post_init__(self) -> None:
        for name in ("s_rel_left", "s_rel_right", "rate"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float, np.floating)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} = {value!r} must be a finite number >= 0")
        if self.rate > 1:
            raise ValueError(f"rate = {self.rate!r} must be within [0, 1]")

    @property
    def collision(self) -> bool:
        return self.left or self.right

    @property
    def side(self) -> int | None:
        """c(z_c) of Hoffmann eq. 26 over the recent frames: +1 left, -1 right, 0 both, None for no collision."""
        if self.recent_left and self.recent_right:
            return 0
        if self.recent_left:
            return 1
        if self.recent_right:
            return -1
        return None


NO_COLLISION = CollisionPercept()
