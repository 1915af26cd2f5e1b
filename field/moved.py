"""Modules and names that moved, still found by their old names with a DeprecationWarning.

    from field.moved import keep_old_names, moved_names
    keep_old_names({"mcl.replay": "mcl.tools.replay"})     # a module: in the package that held the old name
    __getattr__ = moved_names(__name__, {"normalize_reference": "mcl.reference.normalize"})   # a name
    __getattr__ = moved_methods("Model", {"seen_reference": ("numpy_twin().seen", lambda m: m.numpy_twin().seen)})

An import of an old name (or of anything below it: `mcl.logs.mcap_io`) gives the module at its new name, the
same module object, so classes and exceptions compare equal whichever name a caller used; `python -m` with an
old name runs the new module. Every package that moved modules out calls this once from its `__init__`.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from collections.abc import Callable
from types import CodeType, ModuleType
from typing import Any


def _warn(old: str, new: str, use: str = "import") -> None:
    warnings.warn(
        f"{old} moved to {new}: {use} it from there (the old name will be removed)", DeprecationWarning, stacklevel=3
    )


class _OldNames(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """A finder and loader for the old names of moved modules (first in `sys.meta_path`, so a submodule of
    an old name is never loaded a second time under that name)."""

    def __init__(self, moved: dict[str, str]) -> None:
        self.moved = dict(moved)

    def new_name(self, fullname: str) -> str | None:
        for old, new in self.moved.items():
            if fullname == old or fullname.startswith(old + "."):
                return new + fullname[len(old) :]
        return None

    def find_spec(self, fullname, path=None, target=None):
        new = self.new_name(fullname)
        if new is None:
            return None
        target = importlib.util.find_spec(new)
        if target is None:
            return None
        return importlib.machinery.ModuleSpec(fullname, self, is_package=target.submodule_search_locations is not None)

    def create_module(self, spec) -> ModuleType:
        new = self.new_name(spec.name)
        assert new is not None  # find_spec made this spec only for a moved name
        _warn(spec.name, new)
        return importlib.import_module(new)

    def exec_module(self, module: ModuleType) -> None:
        """Nothing to run: the module at the new name has run already."""

    def get_code(self, fullname: str) -> CodeType | None:
        """The new module's code, for `python -m OLD.NAME`."""
        new = self.new_name(fullname)
        spec = importlib.util.find_spec(new) if new else None
        loader = getattr(spec, "loader", None)
        return loader.get_code(new) if loader is not None and hasattr(loader, "get_code") else None


def keep_old_names(moved: dict[str, str]) -> None:
    """Keep the old dotted names in `moved` (old -> new) importable, each with a DeprecationWarning."""
    for finder in sys.meta_path:
        if isinstance(finder, _OldNames):
            finder.moved.update(moved)
            return
    sys.meta_path.insert(0, _OldNames(moved))


def moved_names(module: str, moves: dict[str, str | tuple[str, Callable[[], Any]]]) -> Callable[[str], Any]:
    """A module `__getattr__` (PEP 562) that finds each old name of `moves` at its new place.

    Parameters
    ----------
    module : str
        The module's name (`__name__`), for the messages.
    moves : dict of str to str or (str, callable)
        Old name -> the qualified name it moved to ("package.module.name"), or (what replaces it, said in the
        warning; a function of nothing that returns it) for a name that became a call with other arguments.

    Returns
    -------
    callable
        `__getattr__(name)`: the moved object, with a DeprecationWarning; AttributeError for any other name.
    """

    def __getattr__(name: str) -> Any:
        target = moves.get(name)
        if target is None:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        if isinstance(target, tuple):
            _warn(f"{module}.{name}", target[0], "call")
            return target[1]()
        _warn(f"{module}.{name}", target)
        where, _, attribute = target.rpartition(".")
        return getattr(importlib.import_module(where), attribute)

    return __getattr__


def moved_methods(owner: str, moves: dict[str, tuple[str, Callable[[Any], Any]]]) -> Callable[[Any, str], Any]:
    """A class `__getattr__` that finds each old method name of `moves` at its new place.

    Parameters
    ----------
    owner : str
        The class's name, for the messages.
    moves : dict of str to (str, callable)
        Old name -> (where it went, said in the warning; a function of the instance that returns it).

    Returns
    -------
    callable
        `__getattr__(self, name)`: the moved method, with a DeprecationWarning; AttributeError for any other
        name (it reads nothing of the instance, so copying and unpickling find nothing here).
    """

    def __getattr__(self: Any, name: str) -> Any:
        move = moves.get(name)
        if move is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        _warn(f"{owner}.{name}", f"{owner}.{move[0]}", "call")
        return move[1](self)

    return __getattr__
