"""How a sensor model offers its likelihood to the filter's fused compiled step.

    from sensing.fused import FusedLikelihoodKernels

A sensor model with a `fused_likelihood()` method that returns a `FusedLikelihoodKernels` is scored inside the
filter's one compiled call per step (predict, likelihood, weights, resampling, estimate): the filter moves the
particles a block at a time and calls the model's `score` on each block while it is in cache. Any model can
offer it, the landmark model does (`sensing.landmarks`), and a model that returns None (or has no such method)
is scored through its `log_likelihood`, with the same results. The kernels are numba-compiled functions
(`numba.njit`; with `cache=True` they are compiled once per machine), passed to the filter's kernels as
arguments, so the filter compiles its step once for each kind of model it meets.

The calling convention (every argument is positional; `params` and the frame are tuples the model chooses):

    inputs(observations) -> tuple          # in Python, per frame: the arrays the kernels need (no copies)
    prepare(inputs, params) -> (frame, missing)
        # compiled, once per frame: everything `score` needs (a flat tuple of arrays and numbers: numba's
        # parallel loops take no nested tuples); `missing` is the index of the first detection the model
        # cannot score (the filter then calls `check` to raise, changing nothing), or -1
    workspace(frame, columns) -> np.ndarray
        # compiled, once per call (per thread): scratch for scoring up to `columns` particles at a time
    score(poses, trig, start, count, work, since, fast, frame, out) -> None
        # compiled, per block: out[start:start + count] = the log-likelihoods of poses[start:start + count]
        # (finite or -inf). trig (2, ≥ count): trig[0, p], trig[1, p] = cos, sin of the heading of
        # poses[start + p], computed by the filter (contiguous rows: a loop over them vectorizes). since: (dx, dy,
        # dθ) when the detections were captured before the particles moved (score each particle moved back by
        # it, as `mcl.latency.move_back` moves it), or an empty array. fast: the filter's `fast` option (the
        # model may score to rounding instead of bit for bit when True).

The results must equal `log_likelihood` bit for bit when `fast` is False, since the filter picks either path
by what the frame needs (`mcl.tools.testing.assert_fused_likelihood` checks it).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from typing import Any, NamedTuple

import numba
import numpy as np

from numerics.compile import variant
from numerics.trig import moved_back, sincos

NO_SINCE = np.empty(0)
"""`since` for detections captured now: nothing to move back."""


class FusedLikelihoodKernels(NamedTuple):
    """A sensor model's compiled likelihood, in the calling convention of the module docstring."""

    prepare: Any  # numba dispatcher: (inputs, params) -> (frame, missing)
    workspace: Any  # numba dispatcher: (frame, columns) -> scratch array
    score: Any  # numba dispatcher: (poses, trig, start, count, work, since, fast, frame, out)
    params: tuple  # the model's constants, as the kernels take them
    inputs: Callable[[Any], tuple]  # observations -> the frame's arrays


# -- one compiled per-particle log-likelihood ----------------------------------------------------------------------
# The simplest way for a sensor model to reach the fused step: one compiled function that scores one particle,
#
#     particle_log_likelihood(x, y, cos_theta, sin_theta, frame) -> float      (numba.njit; finite or -inf)
#
# given the particle's position [m] and the cos and sin of its heading, and the frame `prepare` made. It knows
# nothing of the filter's blocks, heading cache, camera latency or `fast` option: `per_particle_kernels` wraps it
# in the calling convention above, with a `score` (compiled once per function, `numerics.compile.variant`) that
# moves each particle back to the frame's capture when the detections are late, as `mcl.latency.move_back`
# does, and hands it the headings' cos and sin the filter computed (to rounding with `fast`, else bit for bit
# those of `numerics.trig.sincos`). A model's `log_likelihood` that loops over the particles with the same
# function and `numerics.trig.sincos` then gives what the fused step gives, bit for bit
# (`per_particle_log_likelihood` is that loop).

particle_log_likelihood = None  # bound by `per_particle_kernels` in the template below


def _score_particles(poses, trig, start, count, work, since, fast, frame, out):
    """(A template: `per_particle_kernels` binds `particle_log_likelihood`.)"""
    if since.shape[0] == 0:
        for p in range(count):
            i = start + p
            out[i] = particle_log_likelihood(poses[i, 0], poses[i, 1], trig[0, p], trig[1, p], frame)
    else:
        for p in range(count):
            i = start + p
            x, y, theta = moved_back(poses[i, 0], poses[i, 1], poses[i, 2], since[0], since[1], since[2])
            c, s = sincos(theta)
            out[i] = particle_log_likelihood(x, y, c, s, frame)


@numba.njit(cache=True)
def _no_workspace(frame, columns):
    return np.empty(0)


def _function_key(function) -> str:
    """A compiled function's qualified name and a hash of its bytecode (its compiled variants' cache name)."""
    source = getattr(function, "py_func", None)
    if source is None:
        raise TypeError(f"{function!r} must be a numba.njit function (the fused step calls it from compiled code)")
    digest = hashlib.sha256(source.__code__.co_code + repr(source.__code__.co_consts).encode()).hexdigest()[:12]
    return f"{source.__module__}.{source.__qualname__}.{digest}"


_COMPILED: dict[str, tuple[Any, Any]] = {}  # key -> (score, loop) for each per-particle function


def _compiled(log_likelihood: Any) -> tuple[Any, Any]:
    key = _function_key(log_likelihood)
    kernels = _COMPILED.get(key)
    if kernels is None:
        names = {"particle_log_likelihood": log_likelihood}
        kernels = _COMPILED[key] = (variant(_score_particles, key, names), variant(_loop, key, names))
    return kernels


def per_particle_kernels(
    prepare: Any, log_likelihood: Any, params: tuple, inputs: Callable[[Any], tuple]
) -> FusedLikelihoodKernels:
    """A sensor model's fused kernels from one compiled per-particle log-likelihood (see above).

    Parameters
    ----------
    prepare : numba dispatcher
        (inputs, params) -> (frame, missing), as in the calling convention of the module docstring: compiled,
        once per frame; `frame` a flat tuple of arrays and numbers.
    log_likelihood : numba dispatcher
        (x, y, cos_theta, sin_theta, frame) -> float: one particle's log-likelihood of the frame.
    params : tuple
        The model's constants, as `prepare` takes them.
    inputs : callable
        observations -> the frame's arrays, as `prepare` takes them.

    Returns
    -------
    FusedLikelihoodKernels
        What the model's `fused_likelihood()` returns.

    Raises
    ------
    TypeError
        If `log_likelihood` is not a numba.njit function.
    """
    return FusedLikelihoodKernels(prepare, _no_workspace, _compiled(log_likelihood)[0], params, inputs)


def _loop(poses, frame, out):
    """(A template: `per_particle_log_likelihood` binds `particle_log_likelihood`.)"""
    for i in range(poses.shape[0]):
        c, s = sincos(poses[i, 2])
        out[i] = particle_log_likelihood(poses[i, 0], poses[i, 1], c, s, frame)


def per_particle_log_likelihood(
    log_likelihood: Any, poses: np.ndarray, frame: tuple, out: np.ndarray | None = None
) -> np.ndarray:
    """Every particle's log-likelihood by a per-particle function (see above), with the cos and sin of each
    heading from `numerics.trig.sincos`: what the fused step's `score` gives them, bit for bit.

    Parameters
    ----------
    log_likelihood : numba dispatcher
        (x, y, cos_theta, sin_theta, frame) -> float.
    poses : numpy.ndarray
        (N, 3) poses (x [m], y [m], θ [rad]).
    frame : tuple
        What the model's `prepare` made of the frame.
    out : numpy.ndarray or None, default None
        (N,) where to write; None: a new array.

    Returns
    -------
    numpy.ndarray
        (N,) log-likelihoods (`out`).
    """
    poses = np.ascontiguousarray(poses, dtype=np.float64)
    out = np.empty(poses.shape[0]) if out is None else out
    _compiled(log_likelihood)[1](poses, frame, out)
    return out
