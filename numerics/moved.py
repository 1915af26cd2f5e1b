"""Names that moved to another module, still found where they were, with a DeprecationWarning.

    from numerics.moved import moved_names
    __getattr__ = moved_names(__name__, {"normalize_reference": "mcl.reference.normalize"})

A module sets `__getattr__` (PEP 562) to what `moved_names` returns: an old name is then looked up where it
lives now, when it is first asked for, and the warning says where.
"""
from __future__ import annotations

import importlib
import warnings
from typing import Any, Callable


def moved_names(module: str, moves: dict[str, str]) -> Callable[[str], Any]:
    """A module `__getattr__` that finds each old name of `moves` at its new place ("package.module.name").

    Parameters
    ----------
    module : str
        The module's name (`__name__`), for the messages.
    moves : dict of str to str
        Old name -> the qualified name it moved to.

    Returns
    -------
    callable
        `__getattr__(name)`: the moved object, with a DeprecationWarning; AttributeError for any other name.
    """
    def __getattr__(name: str) -> Any:
        target = moves.get(name)
        if target is None:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        warnings.warn(f"{module}.{name} moved to {target}", DeprecationWarning, stacklevel=2)
        where, _, attribute = target.rpartition(".")
        return getattr(importlib.import_module(where), attribute)
    return __getattr__
