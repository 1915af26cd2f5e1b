"""Invariants of a `mcl.ParticleFilter` as plain functions that raise AssertionError naming what broke: weights
normalized, poses finite and wrapped, a refused call leaves the state unchanged, same seed same run."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from mcl.tools.testing.strategies import REFUSALS
from motion_models import MotionInput

if TYPE_CHECKING:
    from mcl.filter import ParticleFilter


def assert_poses_finite_and_wrapped(poses: ArrayLike | ParticleFilter) -> None:
    """Assert that particles are an (N, 3) array of finite poses with headings wrapped into [-π, π].

    Parameters
    ----------
    poses : array_like or ParticleFilter
        The particles (N, 3), or an object with a `poses` attribute (a filter).

    Raises
    ------
    AssertionError
        Naming the first row that is not finite or not wrapped, or the wrong shape.
    """
    if hasattr(poses, "poses") and not isinstance(poses, np.ndarray):
        poses = poses.poses
    array = np.asarray(poses)
    assert array.ndim == 2 and array.shape[1] == 3, f"poses must have shape (N, 3), got {array.shape}"
    assert array.dtype.kind == "f", f"poses must be floats, got dtype {array.dtype}"
    finite = np.isfinite(array).all(axis=1)
    if not finite.all():
        i = int(np.argmin(finite))
        raise AssertionError(
            f"poses[{i}] = {array[i].tolist()!r} is not finite ({int((~finite).sum())} of {array.shape[0]} rows)"
        )
    wrapped = np.abs(array[:, 2]) <= math.pi
    if not wrapped.all():
        i = int(np.argmin(wrapped))
        raise AssertionError(
            f"poses[{i}] = {array[i].tolist()!r}: heading not wrapped into [-π, π] "
            f"({int((~wrapped).sum())} of {array.shape[0]} rows)"
        )


def assert_weights_normalized(pf: ParticleFilter, tolerance: float = 1e-9) -> None:
    """Assert that a filter's weights are a probability distribution matching its log-weights.

    Parameters
    ----------
    pf : ParticleFilter
        Read through `weights`, `log_weights` (and `n`, when it has one).
    tolerance : float, optional
        Largest accepted |Σ w - 1| (default 1e-9); exp(log_weights) must equal the weights to the same
        tolerance per particle (relative 1e-9).

    Raises
    ------
    AssertionError
        Naming what is off: shape, NaN, negative or infinite weights, their sum, NaN or +inf log-weights, or
        weights that are not exp(log_weights).
    """
    weights = np.asarray(pf.weights)
    log_weights = np.asarray(pf.log_weights)
    n = getattr(pf, "n", weights.shape[0] if weights.ndim else 0)
    assert weights.shape == (n,), f"weights must have shape ({n},), got {weights.shape}"
    assert log_weights.shape == (n,), f"log_weights must have shape ({n},), got {log_weights.shape}"
    bad = ~(np.isfinite(weights) & (weights >= 0))
    if bad.any():
        i = int(np.argmax(bad))
        raise AssertionError(
            f"weights[{i}] = {float(weights[i])!r}: weights must be finite and >= 0 ({int(bad.sum())} are not)"
        )
    total = float(np.sum(weights, dtype=np.float64))
    assert abs(total - 1.0) <= tolerance, f"weights sum to {total!r}, not 1 (tolerance {tolerance:g})"
    bad = np.isnan(log_weights) | np.isposinf(log_weights)
    if bad.any():
        i = int(np.argmax(bad))
        raise AssertionError(f"log_weights[{i}] = {float(log_weights[i])!r}: NaN or +inf log-weight")
    with np.errstate(over="ignore", under="ignore"):
        expected = np.exp(log_weights)
    off = ~np.isclose(expected, weights, rtol=1e-9, atol=tolerance)
    if off.any():
        i = int(np.argmax(off))
        raise AssertionError(
            f"weights[{i}] = {float(weights[i])!r} but exp(log_weights[{i}]) = "
            f"{float(expected[i])!r}: the log-weights are not the logarithms of the normalized "
            "weights"
        )


def _frozen(value) -> Any:
    """A hashable, bit-exact image of a generator state (ints, strings, arrays, nested dicts)."""
    if isinstance(value, dict):
        return tuple(sorted((str(k), _frozen(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return tuple(_frozen(v) for v in value)
    if isinstance(value, np.ndarray):
        return ("array", value.dtype.str, value.shape, np.ascontiguousarray(value).tobytes())
    if isinstance(value, (float, np.floating)):
        return ("float", np.float64(value).tobytes())
    if isinstance(value, np.generic):
        return value.item()
    return value


def _copy(array: Any) -> np.ndarray | None:
    return None if array is None else _copy_array(array)


def _copy_array(array: Any) -> np.ndarray:
    out = np.array(array, copy=True)
    out.flags.writeable = False
    return out


def _array_difference(name: str, a: np.ndarray | None, b: np.ndarray | None) -> str | None:
    """Where two arrays differ in any bit (None when they are the same)."""
    if a is None or b is None:
        return None if a is None and b is None else f"{name}: {a!r} -> {b!r}"
    if a.shape != b.shape or a.dtype != b.dtype:
        return f"{name}: {a.dtype} {a.shape} -> {b.dtype} {b.shape}"
    if a.size == 0:
        return None
    left = np.ascontiguousarray(a).view(np.uint8).reshape(a.size, a.dtype.itemsize)
    right = np.ascontiguousarray(b).view(np.uint8).reshape(b.size, b.dtype.itemsize)
    differ = (left != right).any(axis=1)
    if not differ.any():
        return None
    flat = int(np.argmax(differ))
    index = np.unravel_index(flat, a.shape)
    where = ", ".join(str(int(i)) for i in index)
    return (
        f"{name}[{where}]: {a[index].item()!r} -> {b[index].item()!r} ({int(differ.sum())} of {a.size} entries differ)"
    )


def _scalar_difference(name: str, a, b) -> str | None:
    if isinstance(a, float) or isinstance(b, float):
        if (
            isinstance(a, (int, float))
            and isinstance(b, (int, float))
            and np.float64(a).tobytes() == np.float64(b).tobytes()
        ):
            return None
    elif a == b:
        return None
    return f"{name}: {a!r} -> {b!r}"


@dataclass(frozen=True, eq=False)
class FilterSnapshot:
    """Everything a filter shows, copied: what `snapshot` returns and `assert_unchanged` compares bit for bit.

    Attributes
    ----------
    poses, log_weights, weights : numpy.ndarray
        Read-only copies of the particles (N, 3), their log-weights (N,) and normalized weights (N,).
    rng_state : tuple
        The state of the filter's random generator (`pf.rng.bit_generator.state`), frozen.
    motion_state : numpy.ndarray or None
        A copy of the stateful motion model's per-particle state (`pf.motion_state`), or None.
    scalars : tuple of (str, object)
        w_slow, w_fast, ess, frame_fit, resampled, injected, resampling, resample_threshold, augmented, and the
        relocalization's `tracking`, as the filter shows them.
    roughening : numpy.ndarray or None
        A copy of the roughening's standard deviations.
    anchor : numpy.ndarray or None
        The relocalization's anchor, when it shows one.
    estimate : tuple or None
        (pose, covariance, weight) of `pf.estimate()`, or None when the snapshot was taken without it.
    """

    poses: np.ndarray
    log_weights: np.ndarray
    weights: np.ndarray
    rng_state: tuple
    motion_state: np.ndarray | None
    scalars: tuple
    roughening: np.ndarray | None
    anchor: np.ndarray | None
    estimate: tuple | None

    @property
    def w_slow(self) -> float:
        """Augmented MCL's long-term average likelihood."""
        return dict(self.scalars)["w_slow"]

    @property
    def w_fast(self) -> float:
        """Augmented MCL's short-term average likelihood."""
        return dict(self.scalars)["w_fast"]

    def differences(self, other: FilterSnapshot) -> list[str]:
        """What differs from `other`, one line per field (an empty list: the same, bit for bit).

        Parameters
        ----------
        other : FilterSnapshot
            The snapshot to compare with (usually a later one of the same filter).

        Returns
        -------
        list of str
            One line per field that differs, with its first differing entry (this snapshot's value, then
            `other`'s).

        Raises
        ------
        TypeError
            If `other` is not a `FilterSnapshot`.
        """
        if not isinstance(other, FilterSnapshot):
            raise TypeError(f"other = {other!r} must be a FilterSnapshot, not {type(other).__name__}")
        found = []
        for name in ("poses", "log_weights", "weights", "motion_state", "roughening", "anchor"):
            difference = _array_difference(name, getattr(self, name), getattr(other, name))
            if difference:
                found.append(difference)
        if self.rng_state != other.rng_state:
            found.append("rng_state: the random generator has drawn numbers (its state changed)")
        mine, theirs = dict(self.scalars), dict(other.scalars)
        for name in sorted(set(mine) | set(theirs)):
            difference = _scalar_difference(name, mine.get(name), theirs.get(name))
            if difference:
                found.append(difference)
        before, after = self.estimate, other.estimate
        if (before is None) != (after is None):
            found.append(f"estimate: {before!r} -> {after!r}")
        elif before is not None and after is not None:
            for label, a, b in zip(("estimate.pose", "estimate.covariance"), before[:2], after[:2]):
                difference = _array_difference(label, a, b)
                if difference:
                    found.append(difference)
            difference = _scalar_difference("estimate.weight", before[2], after[2])
            if difference:
                found.append(difference)
        return found

    def __eq__(self, other) -> bool:
        return isinstance(other, FilterSnapshot) and not self.differences(other)

    __hash__ = None  # type: ignore[assignment]


_SCALARS = (
    "w_slow",
    "w_fast",
    "ess",
    "frame_fit",
    "resampled",
    "injected",
    "resampling",
    "resample_threshold",
    "augmented",
    "n",
)


def snapshot(pf: ParticleFilter, estimate: bool = True) -> FilterSnapshot:
    """Capture a filter's whole observable state.

    Parameters
    ----------
    pf : ParticleFilter
        Read through its public attributes only: poses, log_weights, weights, rng, motion_state, w_slow,
        w_fast, ess, frame_fit, resampled, injected, resampling, resample_threshold, augmented, roughening,
        relocalization (tracking, anchor) and estimate().
    estimate : bool, optional
        Include `pf.estimate()` (default True). The filter caches the estimate; computing it when it is not
        cached moves the estimate's hysteresis anchor, as a robot asking for the estimate would. Give False to
        leave the filter exactly as it is. The estimate is left out (None) while a pose is not finite: the
        filter's summaries assume finite poses, and `assert_poses_finite_and_wrapped` reports such poses.

    Returns
    -------
    FilterSnapshot
        Compare two with `assert_unchanged` (or ``==``; `FilterSnapshot.differences` lists what differs).
    """
    relocalization = getattr(pf, "relocalization", None)
    scalars = []
    for name in _SCALARS:
        if hasattr(pf, name):
            value = getattr(pf, name)
            scalars.append((name, value.item() if isinstance(value, np.generic) else value))
    if relocalization is not None and hasattr(relocalization, "tracking"):
        scalars.append(("relocalization.tracking", bool(relocalization.tracking)))
    anchor = getattr(relocalization, "anchor", None) if relocalization is not None else None
    roughening = getattr(pf, "roughening", None)
    summary = None
    if estimate and np.isfinite(np.asarray(pf.poses)).all():
        e = pf.estimate()
        summary = (
            _copy(np.asarray(e.pose, dtype=np.float64)),
            _copy(np.asarray(e.covariance, dtype=np.float64)),
            float(e.weight),
        )
    motion_state = getattr(pf, "motion_state", None)
    return FilterSnapshot(
        poses=_copy_array(pf.poses),
        log_weights=_copy_array(pf.log_weights),
        weights=_copy_array(pf.weights),
        rng_state=_frozen(pf.rng.bit_generator.state),
        motion_state=_copy(motion_state),
        scalars=tuple(scalars),
        roughening=_copy(roughening),
        anchor=_copy(anchor),
        estimate=summary,
    )


def assert_unchanged(before: FilterSnapshot, after: FilterSnapshot, what: str = "the filter") -> None:
    """Assert that two snapshots are equal bit for bit.

    Parameters
    ----------
    before, after : FilterSnapshot
        From `snapshot`.
    what : str, optional
        What the message calls the object (default "the filter").

    Raises
    ------
    AssertionError
        Listing every field that changed, with the first entry that differs.
    """
    differences = before.differences(after)
    if differences:
        raise AssertionError(f"{what} changed: " + "; ".join(differences))


def assert_refused_leaves_state(
    pf: ParticleFilter, call: Callable[..., Any], *args: Any, exceptions: tuple = REFUSALS, **kwargs: Any
) -> BaseException:
    """Assert that `call(*args, **kwargs)` is refused and leaves the filter exactly as it was.

    Parameters
    ----------
    pf : ParticleFilter
        The filter whose `snapshot` must be the same before and after.
    call : callable
        Usually a bound method of `pf`, e.g. ``pf.step``; any callable that should refuse its arguments.
    *args, **kwargs
        Passed to `call`.
    exceptions : tuple of exception types, optional
        What a refusal may raise (default ValueError and TypeError).

    Returns
    -------
    BaseException
        The exception the call raised (to check its message).

    Raises
    ------
    AssertionError
        When the call returns normally, raises another exception, raises one without a message, or changes
        anything a snapshot shows.
    """
    before = snapshot(pf)
    name = getattr(call, "__qualname__", None) or repr(call)
    try:
        call(*args, **kwargs)
    except exceptions as error:
        caught = error
    except Exception as error:
        raise AssertionError(
            f"{name} raised {type(error).__name__}: {error}; a refused call must raise one of "
            f"{tuple(e.__name__ for e in exceptions)}"
        ) from error
    else:
        raise AssertionError(
            f"{name}{_show_args(args, kwargs)} was accepted; it should have been refused "
            f"with one of {tuple(e.__name__ for e in exceptions)}"
        )
    assert str(caught), f"{name} raised {type(caught).__name__} without a message"
    after = snapshot(pf)
    differences = before.differences(after)
    if differences:
        raise AssertionError(
            f"{name} was refused ({type(caught).__name__}: {caught}) but changed the filter: " + "; ".join(differences)
        )
    return caught


def _show_args(args, kwargs) -> str:
    shown = [repr(a)[:60] for a in args] + [f"{k}={v!r}"[:60] for k, v in kwargs.items()]
    return f"({', '.join(shown)})"


def assert_same_seed_same_run(make_filter: Callable[[], Any], inputs: Iterable) -> None:
    """Assert that two filters from the same factory, driven by the same inputs, agree bit for bit.

    Parameters
    ----------
    make_filter : callable
        Returns a new filter each call, seeded the same way (``lambda: ParticleFilter(..., seed=3)``).
    inputs : iterable
        The steps: (MotionInput, Observations or None) pairs (a bare MotionInput is a step without
        observations), given to `pf.step` in order.

    Raises
    ------
    AssertionError
        When the factory returns the same object twice, or the two runs differ anywhere (poses, weights, the
        generator's state, the estimate, ...): the message names the step and the field.
    """
    steps = [(item, None) if isinstance(item, MotionInput) else tuple(item) for item in inputs]
    first, second = make_filter(), make_filter()
    assert first is not second, "make_filter returned the same filter twice: it must build a new one each call"
    # The first run entirely, then the second: state a model keeps between filters (a hidden counter, global
    # random numbers) shows as a difference.
    runs = []
    for pf in (first, second):
        trace = [snapshot(pf, estimate=False)]
        for u, z in steps:
            pf.step(u, z)
            trace.append(snapshot(pf))
        runs.append(trace)
    for k, (a, b) in enumerate(zip(*runs)):
        differences = a.differences(b)
        if differences:
            when = "after construction" if k == 0 else f"after step {k - 1} ({_show_args(steps[k - 1], {})})"
            raise AssertionError(f"two filters from the same factory differ {when}: " + "; ".join(differences))
