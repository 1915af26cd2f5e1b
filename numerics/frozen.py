"""Read-only arrays that stay read-only when their holder is copied.

The models keep their tables and parameters as read-only numpy arrays: a caller cannot change them behind the
model's back, and the compiled kernels are specialized for read-only arrays. numpy's copies of an array
(`copy.deepcopy`, `pickle`, and so a Ray task's arguments) are writable, whatever the original was. A copied
model would then hand its kernels arguments of another numba type, and every kernel it reaches would compile a
second time on its first call (tens of seconds), besides holding arrays that a caller could change.

`keeps_arrays_frozen` makes a class's copies freeze again the arrays that were read-only in the original: those
held as attributes, or inside tuples held as attributes.

    @keeps_arrays_frozen
    @dataclass(frozen=True)
    class Table:
        rows: np.ndarray   # frozen in __post_init__

    copy.deepcopy(Table(...)).rows.flags.writeable   # False, as in the original
"""

from __future__ import annotations

from typing import Any, TypeVar

import numpy as np

_PATHS = "__frozen_arrays__"  # the state's key for the read-only arrays' paths
C = TypeVar("C", bound=type)


def frozen_paths(value: Any, path: tuple = ()) -> list[tuple]:
    """The paths (indices into nested tuples) of the read-only numpy arrays in `value`."""
    if isinstance(value, np.ndarray):
        return [] if value.flags.writeable else [path]
    if isinstance(value, tuple):
        return [found for i, item in enumerate(value) for found in frozen_paths(item, (*path, i))]
    return []


def _state(self) -> dict:
    state = dict(vars(self))
    state[_PATHS] = [(name, *path) for name, value in state.items() for path in frozen_paths(value)]
    return state


def _restore(self, state: dict) -> None:
    state = dict(state)
    paths = state.pop(_PATHS, ())
    vars(self).update(state)  # (a frozen dataclass's __setattr__ refuses; its __dict__ does not)
    for name, *path in paths:
        value = state[name]
        for i in path:
            value = value[i]
        value.flags.writeable = False


def keeps_arrays_frozen(cls: C) -> C:
    """Class decorator: copies (`copy.copy`, `copy.deepcopy`, `pickle`) of an instance freeze again every array
    that was read-only in the instance (an attribute, or an item of a tuple that is one). The class keeps its
    state in `__dict__` and defines no `__getstate__` or `__setstate__` of its own."""
    for name in ("__getstate__", "__setstate__"):
        if name in vars(cls):
            raise TypeError(f"{cls.__name__} defines {name} already")
    cls.__getstate__ = _state  # type: ignore[attr-defined]
    cls.__setstate__ = _restore  # type: ignore[attr-defined]
    return cls
