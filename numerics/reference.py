"""The polynomial sin, cos and atan2 of `numerics.trig` in plain numpy: the same operations elementwise, so
the same bits on every machine; the tests compare the kernels with them.

    from numerics import reference
    c, s = reference.sincos(angles)
    a = reference.atan2_poly(y, x)
"""

from __future__ import annotations

import numpy as np

from .trig import (
    _AT0,
    _AT1,
    _AT2,
    _AT3,
    _AT4,
    _AT5,
    _AT6,
    _AT7,
    _AT8,
    _AT9,
    _AT10,
    _ATAN_HALF_HIGH,
    _ATAN_HALF_LOW,
    _ATAN_ONE_HIGH,
    _ATAN_ONE_LOW,
    _C1,
    _C2,
    _C3,
    _C4,
    _C5,
    _C6,
    _HALF_PI_HIGH,
    _HALF_PI_LOW,
    _PI_HIGH,
    _PI_LOW,
    _PIO2_HIGH,
    _PIO2_LOW,
    _S1,
    _S2,
    _S3,
    _S4,
    _S5,
    _S6,
    _TWO_OVER_PI,
)


def sincos(x) -> tuple[np.ndarray, np.ndarray]:
    """Numpy twin of `numerics.trig.sincos`: the same operations, elementwise, so the same bits."""
    x = np.asarray(x, dtype=np.float64)
    k = np.floor(x * _TWO_OVER_PI + 0.5)
    r = (x - k * _PIO2_HIGH) - k * _PIO2_LOW
    z = r * r
    s = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    c = 1.0 - 0.5 * z + z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
    quadrant = k - 4.0 * np.floor(k * 0.25)
    odd = (quadrant == 1.0) | (quadrant == 3.0)
    sine = np.where(odd, c, s)
    cosine = np.where(odd, s, c)
    return (np.where((quadrant == 1.0) | (quadrant == 2.0), -cosine, cosine), np.where(quadrant >= 2.0, -sine, sine))


def atan2_poly(y, x) -> np.ndarray:
    """Numpy twin of `numerics.trig.atan2_poly`: the same operations, elementwise, so the same bits."""
    y = np.asarray(y, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    ax = np.abs(x)
    ay = np.abs(y)
    steep = ay > ax
    numerator = np.where(steep, ax, ay)
    denominator = np.where(steep, ay, ax)
    with np.errstate(invalid="ignore", divide="ignore"):
        a = numerator / denominator
    a = np.where(numerator > 0.0, a, numerator + 0.0 * denominator)
    upper = a >= 0.6875
    middle = (a >= 0.4375) & (a < 0.6875)
    t = np.where(upper, a - 1.0, np.where(middle, 2.0 * a - 1.0, a)) / np.where(
        upper, a + 1.0, np.where(middle, 2.0 + a, 1.0)
    )
    high = np.where(upper, _ATAN_ONE_HIGH, np.where(middle, _ATAN_HALF_HIGH, 0.0))
    low = np.where(upper, _ATAN_ONE_LOW, np.where(middle, _ATAN_HALF_LOW, 0.0))
    z = t * t
    w = z * z
    s1 = z * (_AT0 + w * (_AT2 + w * (_AT4 + w * (_AT6 + w * (_AT8 + w * _AT10)))))
    s2 = w * (_AT1 + w * (_AT3 + w * (_AT5 + w * (_AT7 + w * _AT9))))
    r = high - ((t * (s1 + s2) - low) - t)
    r = np.where(steep, (_HALF_PI_HIGH - r) + _HALF_PI_LOW, r)
    r = np.where(np.copysign(1.0, x) < 0.0, (_PI_HIGH - r) + _PI_LOW, r)
    return np.copysign(r, y)
