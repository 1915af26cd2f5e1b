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

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

NO_SINCE = np.empty(0)
"""`since` for detections captured now: nothing to move back."""


class FusedLikelihoodKernels(NamedTuple):
    """A sensor model's compiled likelihood, in the calling convention of the module docstring."""

    prepare: Any                   # numba dispatcher: (inputs, params) -> (frame, missing)
    workspace: Any                 # numba dispatcher: (frame, columns) -> scratch array
    score: Any                     # numba dispatcher: (poses, trig, start, count, work, since, fast, frame, out)
    params: tuple                  # the model's constants, as the kernels take them
    inputs: Callable[[Any], tuple]  # observations -> the frame's arrays
