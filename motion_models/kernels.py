"""The compiled kernels of motion by a displacement plus bounded robot-frame noise (`BoundedNoiseModel`), and
their plain numpy reference.

    from motion_models.kernels import move_with_noise, move_drawing_noise, move_range

`move_with_noise` moves every pose by (dx, dy, dθ) plus noise from pre-drawn variates
(`numerics.random.draw_variates`); `move_drawing_noise` draws the uniforms itself from the filter's generator
(the same results bit for bit); `move_range` moves a range of particles a block at a time (the filter's fused
step calls it block by block), `move_chunked` spreads the particles over threads (the same poses), and
`move_range_fast` is the opt-in fast-math variant (poses to rounding). A heading's cos and sin come from
`numerics.trig.sincos`, not from libm.

`move_range` and `move_range_fast` take three groups (tuples): displacement (dx, dy, dθ), the robot-frame
displacement; bounds (bound_x, bound_y, bound_θ), the noise bounds; draws (function, state), the bit generator's
handle (`numerics.random.bit_generator_handle`; (0, 0) when the variates are given).
"""

import numba
import numpy as np

from field.moved import moved_names
from numerics.random import draw_uniforms
from numerics.trig import FAST, SQRT3, fast_wrap, sincos, wrap

# The numpy twins moved to the package's `reference` module; their old names still work, with a warning.
__getattr__ = moved_names(__name__, {"move_with_noise_reference": "motion_models.reference.move_with_noise"})

DRAWS = 256  # particles per block of uniforms drawn at once
MOVE_WORK = 6 * DRAWS  # the scratch of `move_range` and `move_range_fast`
NO_WORK = np.empty(0)  # (from Python; a kernel passes np.empty(0): a global array is read-only there)


@numba.njit(cache=True, inline="always")
def _move_work(work):
    """`work` if it holds MOVE_WORK floats, else a new scratch."""
    return work if work.shape[0] >= MOVE_WORK else np.empty(MOVE_WORK)


@numba.njit(cache=True, error_model="numpy")
def _move_rows(rows, count, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, noise):
    """Rows x, y, θ of a block moved by the robot-frame displacement (dx, dy, dθ) plus the robot-frame noise from
    noise[3p:3p + 3] (a loop over the particles of separate rows vectorizes, with `sincos`; over (N, 3) rows it
    does not)."""
    if gaussian:
        sx = bound_x / SQRT3
        sy = bound_y / SQRT3
        st = bound_theta / SQRT3
        for p in range(count):
            _move_row(rows, p, dx, dy, dtheta, noise[3 * p] * sx, noise[3 * p + 1] * sy, noise[3 * p + 2] * st)
    else:
        for p in range(count):
            _move_row(
                rows,
                p,
                dx,
                dy,
                dtheta,
                (2.0 * noise[3 * p] - 1.0) * bound_x,
                (2.0 * noise[3 * p + 1] - 1.0) * bound_y,
                (2.0 * noise[3 * p + 2] - 1.0) * bound_theta,
            )


@numba.njit(cache=True, inline="always")
def _move_row(rows, p, dx, dy, dtheta, ex, ey, et):
    theta = rows[2, p]
    c, s = sincos(theta)
    mx = dx + ex
    my = dy + ey
    rows[0, p] += c * mx - s * my
    rows[1, p] += s * mx + c * my
    rows[2, p] = wrap(theta + dtheta + et)


@numba.njit(cache=True, inline="always")
def _move_blocks(source, out, start, stop, displacement, bounds, gaussian, variates, draws, work, fast):
    """`move_range` (`move_range_fast` when `fast`, a literal): a block of DRAWS particles at a time, copied into
    rows, moved there and copied out."""
    dx, dy, dtheta = displacement
    bound_x, bound_y, bound_theta = bounds
    function, state = draws
    work = _move_work(work)
    uniforms = work[: 3 * DRAWS]
    rows = work[3 * DRAWS : MOVE_WORK].reshape((3, DRAWS))
    for block in range(start, stop, DRAWS):
        end = min(block + DRAWS, stop)
        count = end - block
        if variates.shape[0] == 0:
            draw_uniforms(function, state, uniforms, 3 * count)
            noise = uniforms
        else:
            noise = variates[block:end].reshape(-1)
        for p in range(count):
            rows[0, p] = source[block + p, 0]
            rows[1, p] = source[block + p, 1]
            rows[2, p] = source[block + p, 2]
        if fast:
            _move_fast_rows(rows, count, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, noise)
        else:
            _move_rows(rows, count, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, noise)
        for p in range(count):
            out[block + p, 0] = rows[0, p]
            out[block + p, 1] = rows[1, p]
            out[block + p, 2] = rows[2, p]


@numba.njit(cache=True)
def move_range(source, out, start, stop, displacement, bounds, gaussian, variates, draws, work):
    """out[i] = source[i] moved by displacement (dx, dy, dθ) plus noise within bounds (bound_x, bound_y,
    bound_θ), for i in [start, stop) (out may be source).

    The noise of particle i comes from variates[i] when `variates` has rows, else from three uniforms drawn
    here from the bit generator draws (function, state) (x, y, θ in that order, as `rng.random((n, 3))` lays
    them out; uniform noise only). work: scratch of MOVE_WORK floats kept by a caller that moves a block at a
    time (`NO_WORK`: allocated here).
    """
    _move_blocks(source, out, start, stop, displacement, bounds, gaussian, variates, draws, work, False)


@numba.njit(cache=True)
def move_with_noise(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates):
    """Apply the robot-frame displacement (dx, dy, dtheta) to every pose, then add robot-frame noise.

    The noise of axis k is uniform on [-bound_k, bound_k] (Hoffmann eq. 10) from uniform variates u as
    (2u - 1)·bound, or, with `gaussian`, normal with the same variance (sigma = bound / sqrt(3)), so that
    switching the distribution keeps the spread. `variates` (N, 3) come from `draw_variates`.
    """
    displacement, bounds = (dx, dy, dtheta), (bound_x, bound_y, bound_theta)
    move_range(poses, poses, 0, poses.shape[0], displacement, bounds, gaussian, variates, (0, 0), np.empty(0))


@numba.njit(cache=True)
def move_drawing_noise(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, function, state):
    """`move_with_noise` with uniform noise whose variates are drawn in the kernel from a bit generator
    (`bit_generator_handle`): the same poses as `move_with_noise(..., False, rng.random((N, 3)))`."""
    displacement, bounds = (dx, dy, dtheta), (bound_x, bound_y, bound_theta)
    move_range(
        poses, poses, 0, poses.shape[0], displacement, bounds, False, np.empty((0, 3)), (function, state), np.empty(0)
    )


@numba.njit(cache=True, parallel=True)
def move_chunked(poses, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, variates, chunk):
    """`move_with_noise` with chunks of `chunk` particles on several threads (elementwise: the same poses)."""
    n = poses.shape[0]
    displacement, bounds = (dx, dy, dtheta), (bound_x, bound_y, bound_theta)
    for t in numba.prange(max(1, (n + chunk - 1) // chunk)):
        start, stop = t * chunk, min(n, (t + 1) * chunk)
        move_range(poses, poses, start, stop, displacement, bounds, gaussian, variates, (0, 0), np.empty(0))


# -- the opt-in fast variant ----------------------------------------------------------------------------------------
# `move_range_fast`: the same polynomial sin and cos and a branch-free wrap, compiled with fast-math (contracted
# into fused multiply-adds, reassociated): the same draws, the poses to rounding. The filter uses it only with
# `fast=True`.


@numba.njit(cache=True, fastmath=FAST, error_model="numpy")
def _move_fast_rows(rows, count, dx, dy, dtheta, bound_x, bound_y, bound_theta, gaussian, noise):
    """Rows x, y, θ of a block moved (a loop over the particles of separate rows vectorizes; over (N, 3) rows
    it does not)."""
    if gaussian:
        scale_x = bound_x / SQRT3
        scale_y = bound_y / SQRT3
        scale_theta = bound_theta / SQRT3
        shift_x = shift_y = shift_theta = 0.0
    else:
        scale_x = 2.0 * bound_x
        scale_y = 2.0 * bound_y
        scale_theta = 2.0 * bound_theta
        shift_x, shift_y, shift_theta = bound_x, bound_y, bound_theta
    for p in range(count):
        ex = noise[3 * p] * scale_x - shift_x
        ey = noise[3 * p + 1] * scale_y - shift_y
        et = noise[3 * p + 2] * scale_theta - shift_theta
        theta = rows[2, p]
        c, s = sincos(theta)
        mx = dx + ex
        my = dy + ey
        rows[0, p] += c * mx - s * my
        rows[1, p] += s * mx + c * my
        rows[2, p] = fast_wrap(theta + dtheta + et)


@numba.njit(cache=True)
def move_range_fast(source, out, start, stop, displacement, bounds, gaussian, variates, draws, work):
    """`move_range` with fast-math: the same draws, the poses to rounding."""
    _move_blocks(source, out, start, stop, displacement, bounds, gaussian, variates, draws, work, True)
