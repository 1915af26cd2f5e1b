"""Angles without libm: wrapping, and sin, cos and atan2 by polynomials that vectorize and give the same bits on
every machine, with their plain numpy twins.

    from numerics.trig import wrap, sincos, atan2_poly, FAST

`sincos` and `atan2_poly` are inlined into their callers and compiled with the caller's flags: plain IEEE
arithmetic in the default kernels (where they equal their numpy twins bit for bit) and fast-math (`FAST`) in
the opt-in fast kernels (to rounding).
"""

import math

import numba
import numpy as np

from field.moved import moved_names

from .compile import variant

# The numpy twins moved to the package's `reference` module; their old names still work, with a warning.
__getattr__ = moved_names(
    __name__, {"sincos_reference": "numerics.reference.sincos", "atan2_poly_reference": "numerics.reference.atan2_poly"}
)

SQRT3 = math.sqrt(3.0)
TWO_PI = 2.0 * math.pi
# fast-math without assuming no NaN / inf: the flags of every opt-in fast kernel
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}


@numba.njit(cache=True, inline="always")
def wrap(a):
    """`field.angles.wrap_angle`, bit for bit (the floor of the same quotient kept as a float: no conversion to
    an integer and back), written with selects so that loops over particles vectorize."""
    r = a - TWO_PI * np.floor((a + math.pi) / TWO_PI)
    r = r + TWO_PI if r <= -math.pi else r
    return r - TWO_PI if r > math.pi else r


@numba.njit(cache=True, fastmath=FAST, inline="always")
def fast_wrap(a):
    """`field.angles.wrap_angle` to rounding, branch-free."""
    r = a - TWO_PI * np.floor((a + math.pi) * (1.0 / TWO_PI))
    r = r + TWO_PI if r <= -math.pi else r
    return r - TWO_PI if r > math.pi else r


# -- sin and cos without libm ----------------------------------------------------------------------------------------
# A particle's heading needs its cos and sin at every motion update and every scoring. libm's are one call each,
# which no loop can vectorize, and their last bits depend on the C library's version. `sincos` is the fdlibm
# polynomial kernel after a Cody-Waite reduction by π/2, written branch-free so that a loop over particles
# vectorizes: for |x| <= 100 it is within 2.3·10⁻¹⁶ of the exact values (within one unit in the last place of
# libm's, which it equals in about three cases of four). It is inlined, so it is compiled with its caller's flags:
# plain IEEE arithmetic in the default kernels, where it gives the same bits on every machine as its numpy twin
# `numerics.reference.sincos`, and fast-math in the `fast=True` kernels.
_PIO2_HIGH = 1.57079632673412561417e00  # the first 33 bits of π/2
_PIO2_LOW = 6.07710050650619224932e-11  # π/2 - _PIO2_HIGH
_TWO_OVER_PI = 6.36619772367581382433e-01
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@numba.njit(cache=True, inline="always")
def sincos(x):
    """(cos x, sin x) within 2.3·10⁻¹⁶ for |x| <= 100, branch-free (vectorizes); `numerics.reference.sincos` bit for bit
    in kernels compiled without fast-math."""
    k = np.floor(x * _TWO_OVER_PI + 0.5)  # the nearest multiple of π/2 (either one at a tie)
    r = (x - k * _PIO2_HIGH) - k * _PIO2_LOW
    z = r * r
    s = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    c = 1.0 - 0.5 * z + z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
    quadrant = k - 4.0 * np.floor(k * 0.25)  # k mod 4, kept in floats (AVX2 has no double → int64)
    odd = (quadrant == 1.0) | (quadrant == 3.0)
    sine = c if odd else s
    cosine = s if odd else c
    sine = -sine if quadrant >= 2.0 else sine
    cosine = -cosine if (quadrant == 1.0) | (quadrant == 2.0) else cosine
    return cosine, sine


@numba.njit(cache=True, inline="always")
def moved_back(x, y, theta, dx, dy, dtheta):
    """The pose (x, y, θ) moved back by (dx, dy, dθ), a motion given in the frame of the earlier pose: where a
    particle was when detections now arriving were captured (`mcl.latency.move_back` for one pose, bit for bit)."""
    earlier = theta - dtheta
    c, s = sincos(earlier)
    return x - (c * dx - s * dy), y - (s * dx + c * dy), wrap(earlier)


@numba.njit(cache=True, error_model="numpy")
def sincos_rows(angles, cos_out, sin_out, count):
    """cos_out[:count], sin_out[:count] = cos, sin of angles[:count] (`sincos`; contiguous rows: the loop
    vectorizes)."""
    for p in range(count):
        cos_out[p], sin_out[p] = sincos(angles[p])


sincos_rows_fast = variant(sincos_rows.py_func, "fast", fastmath=FAST, error_model="numpy")
"""`sincos_rows` compiled with fast-math (to rounding)."""


@numba.njit(cache=True, inline="always")
def sincos_rows_as(angles, cos_out, sin_out, count, fast):
    """`sincos_rows_fast` when `fast`, else `sincos_rows` (the kernels' `fast` option)."""
    if fast:
        sincos_rows_fast(angles, cos_out, sin_out, count)
    else:
        sincos_rows(angles, cos_out, sin_out, count)


# -- atan2 without libm ----------------------------------------------------------------------------------------------
# The exact bearing term needs the direction of each candidate landmark as an angle: one atan2 per particle and
# candidate. libm's is a call (about 24 ns in a loop over 2·10⁶ points) that no loop can vectorize. `atan2_poly`
# is fdlibm's atan kernel (its polynomial on three ranges of [0, 1], each with its own offset) on the smaller of
# |y|/|x| and |x|/|y|, then the quadrant, all written with selects, so that a loop over particles vectorizes
# (about 4 ns a point). Within two units in the last place of libm's atan2, equal to it in about three cases of
# four; the signs of zeros as atan2's. Inlined: compiled with its caller's flags; in plain IEEE arithmetic it
# gives the bits of its numpy twin `numerics.reference.atan2_poly` on every machine.
_AT0, _AT1, _AT2 = 3.33333333333329318027e-01, -1.99999999998764832476e-01, 1.42857142725034663711e-01
_AT3, _AT4, _AT5 = -1.11111104054623557880e-01, 9.09088713343650656196e-02, -7.69187620504482999495e-02
_AT6, _AT7, _AT8 = 6.66107313738753120669e-02, -5.83357013379057348645e-02, 4.97687799461593236017e-02
_AT9, _AT10 = -3.65315727442169155270e-02, 1.62858201153657823623e-02
_ATAN_HALF_HIGH, _ATAN_HALF_LOW = 4.63647609000806093515e-01, 2.26987774529616870924e-17  # atan(1/2)
_ATAN_ONE_HIGH, _ATAN_ONE_LOW = 7.85398163397448278999e-01, 3.06161699786838301793e-17  # atan(1)
_HALF_PI_HIGH, _HALF_PI_LOW = 1.57079632679489655800e00, 6.12323399573676603587e-17
_PI_HIGH, _PI_LOW = 3.14159265358979311600e00, 1.22464679914735317720e-16


@numba.njit(cache=True, inline="always")
def atan2_poly(y, x):
    """atan2(y, x) in [-π, π] for finite x and y, branch-free (vectorizes); `numerics.reference.atan2_poly` bit for bit in
    kernels compiled without fast-math. Zeros give ±0 or ±π as atan2 does; NaN in, NaN out."""
    ax = abs(x)
    ay = abs(y)
    steep = ay > ax
    numerator = ax if steep else ay
    denominator = ay if steep else ax
    a = numerator / denominator  # in [0, 1]
    a = a if numerator > 0.0 else numerator + 0.0 * denominator  # 0/0 is 0 here; NaN stays NaN
    upper = a >= 0.6875
    middle = (a >= 0.4375) & (a < 0.6875)
    t = (a - 1.0 if upper else (2.0 * a - 1.0 if middle else a)) / (a + 1.0 if upper else (2.0 + a if middle else 1.0))
    high = _ATAN_ONE_HIGH if upper else (_ATAN_HALF_HIGH if middle else 0.0)
    low = _ATAN_ONE_LOW if upper else (_ATAN_HALF_LOW if middle else 0.0)
    z = t * t
    w = z * z
    s1 = z * (_AT0 + w * (_AT2 + w * (_AT4 + w * (_AT6 + w * (_AT8 + w * _AT10)))))
    s2 = w * (_AT1 + w * (_AT3 + w * (_AT5 + w * (_AT7 + w * _AT9))))
    r = high - ((t * (s1 + s2) - low) - t)  # atan(a), in [0, π/4]
    r = (_HALF_PI_HIGH - r) + _HALF_PI_LOW if steep else r
    r = (_PI_HIGH - r) + _PI_LOW if math.copysign(1.0, x) < 0.0 else r
    return math.copysign(r, y)
