"""Argument checks shared by every package: one family of errors, one way of wording them.

A value of the wrong kind raises `ArgumentTypeError` naming the argument and the type expected; a value of the
right kind outside what the library accepts raises `ValueError` naming the argument, the value and the rule.
`ArgumentTypeError` is a `TypeError` and also a `ValueError`, so that a robot's loop that catches ValueError
catches every refused call. Every public entry point checks its arguments with these before it changes anything.

    from field.checks import real, integer, reals

    dt = real("dt", dt, low=0.0, high=3600.0)          # a float, or TypeError / ValueError
    n = integer("n_particles", n, low=1, high=10**7)
    sigma = reals("sigma", sigma, 3, low=0.0)          # a float64 array of shape (3,)
"""

from __future__ import annotations

import math
import numbers
import reprlib

import numpy as np

SMALLEST_SIGMA = 1e-6
"""The smallest standard deviation the library accepts for a noise (m or rad). Below it the likelihoods of a
metre's error underflow; no camera or odometry is that exact."""

LARGEST_SIGMA = 1e3
"""The largest standard deviation accepted for a noise (m or rad): far beyond any field; larger ones overflow
the squares the likelihoods are computed from."""


LARGEST_COORDINATE = 1e3
"""The largest |x| or |y| of a pose or point the library accepts (m): far beyond any field and its surroundings."""

LARGEST_ANGLE = 100.0
"""The largest |angle| accepted for a heading, bearing or turn (rad); angles are wrapped into (-π, π] after."""


class ArgumentTypeError(TypeError, ValueError):
    """An argument of the wrong type: a TypeError, and a ValueError like every other refused call."""


_SHORT = reprlib.Repr()
_SHORT.maxlevel = 3
_SHORT.maxstring = _SHORT.maxlong = _SHORT.maxother = 100


def show(value) -> str:
    """`repr(value)` for an error message: at most about 100 characters and 3 levels of nesting (an array by its
    shape and dtype), so that a huge value, or a deeply nested one read from a file, cannot blow up the message
    (or the recursion limit) of the error that reports it."""
    if isinstance(value, np.ndarray):
        if value.ndim:
            return f"<array of shape {value.shape}, dtype {value.dtype}>"
        value = value.item()
    try:
        return _SHORT.repr(value)
    except Exception:  # an int beyond Python's digit limit, a broken __repr__, ...
        return f"<{type(value).__name__}>"


def _is_real(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _bounds_text(low, high, low_open, high_open) -> str:
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {low:g}")
    if high is not None:
        parts.append(f"{'<' if high_open else '<='} {high:g}")
    return " and ".join(parts)


def real(
    name: str,
    value,
    low: float | None = None,
    high: float | None = None,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """`value` as a finite float within [low, high] (open ends with `low_open`, `high_open`).

    TypeError unless `value` is a real number (int, float, numpy number; not bool); ValueError unless it is
    finite and within the bounds."""
    if type(value) is float:  # the common case, checked without the number ABCs
        number = value
    elif not _is_real(value):
        raise ArgumentTypeError(f"{name} = {show(value)} must be a number, not {type(value).__name__}")
    else:
        try:
            number = float(value)
        except OverflowError:
            number = math.inf if value > 0 else -math.inf
    if (
        math.isfinite(number)
        and (low is None or number > low or (number == low and not low_open))
        and (high is None or number < high or (number == high and not high_open))
    ):
        return number
    bounds = _bounds_text(low, high, low_open, high_open)
    raise ValueError(f"{name} = {show(value)} must be finite{' and ' + bounds if bounds else ''}")


def integer(name: str, value, low: int | None = None, high: int | None = None) -> int:
    """`value` as an int within [low, high]: TypeError unless an integer (not bool), ValueError outside."""
    if not isinstance(value, numbers.Integral) or isinstance(value, (bool, np.bool_)):
        raise ArgumentTypeError(f"{name} = {show(value)} must be an integer, not {type(value).__name__}")
    number = int(value)
    if (low is not None and number < low) or (high is not None and number > high):
        raise ValueError(f"{name} = {show(value)} must be an integer {_bounds_text(low, high, False, False)}")
    return number


def reals(name: str, value, length: int, low: float | None = None, high: float | None = None) -> np.ndarray:
    """`value` as a float64 array of `length` finite numbers within [low, high].

    TypeError unless `value` is a sequence or array of real numbers; ValueError for another length or shape,
    or a number that is not finite or outside the bounds."""
    if isinstance(value, (str, bytes, dict)) or _is_real(value) or value is None:
        raise ArgumentTypeError(f"{name} = {show(value)} must be {length} numbers, not {type(value).__name__}")
    try:
        items = list(value) if not isinstance(value, np.ndarray) else value
        array = np.asarray(items)
    except TypeError:
        raise ArgumentTypeError(f"{name} = {show(value)} must be {length} numbers") from None
    if array.dtype.kind not in "iuf" and not (array.dtype.kind == "O" and all(_is_real(v) for v in array.flat)):
        raise ArgumentTypeError(f"{name} = {show(value)} must be {length} numbers")
    if array.shape != (length,):
        raise ValueError(f"{name} = {show(value)} must be {length} numbers, got shape {array.shape}")
    try:
        array = array.astype(np.float64)
    except OverflowError:
        raise ValueError(f"{name} = {show(value)} must be {length} finite numbers") from None
    rule = f"must be {length} finite numbers"
    bounds = _bounds_text(low, high, False, False)
    if bounds:
        rule += f" {bounds}"
    if (
        not np.isfinite(array).all()
        or (low is not None and (array < low).any())
        or (high is not None and (array > high).any())
    ):
        raise ValueError(f"{name} = {show(value)} {rule}")
    return array
