"""Angle wrapping to (-π, π], the convention for every heading in the project.

    from field.angles import wrap_angle, wrap_angles   # scalar (numba-callable) and array forms

Both compute the same floor-based formula, so a kernel and its numpy reference agree bit for bit, and an angle
already in range comes back unchanged.
"""

import math

import numba
import numpy as np

TWO_PI = 2.0 * math.pi


@numba.njit(cache=True, inline="always")
def wrap_angle(a: float) -> float:
    """Wrap one angle to (-π, π]."""
    r = a - TWO_PI * math.floor((a + math.pi) / TWO_PI)
    if r <= -math.pi:
        r += TWO_PI
    elif r > math.pi:
        r -= TWO_PI
    return r


def wrap_angles(a) -> np.ndarray:
    """Wrap an array of angles to (-π, π]."""
    a = np.asarray(a, dtype=np.float64)
    r = a - TWO_PI * np.floor((a + np.pi) / TWO_PI)
    r = np.where(r <= -np.pi, r + TWO_PI, r)
    return np.where(r > np.pi, r - TWO_PI, r)
