"""How much of the public API carries numpydoc docstrings and complete type hints, and how long `import mcl` takes.

    python -m benchmarks.api_coverage [--json] [--save PATH] [--misses N]

The public API is what a team imports: the names in `__all__` of `mcl`, `motion_models`, `sensing`, `field`,
`mcl.contracts`, `mcl.tools.logs` and `mcl.tools.testing`, and the public names defined in `mcl.localizer`,
`mcl.relocalization`, `mcl.tools.recording` and `mcl.tools.replay` (no leading underscore). For a class, its public methods
and properties defined in the class count too (not what it inherits from outside the project).

- **numpydoc**: the object has a docstring; a function or method that takes arguments (other than self/cls)
  documents them in a ``Parameters`` section, and a class with constructor arguments documents them in its own
  or its ``__init__``'s ``Parameters`` or ``Attributes`` section.
- **typed**: every parameter but self/cls is annotated, and the return is (``__init__`` and property setters
  excepted).

`import mcl` is timed in a fresh interpreter, with the heavy packages it loads listed (rerun, scipy, mcap,
hypothesis, numba, matplotlib, tqdm). scipy counts when one of its public subpackages (scipy.linalg,
scipy.ndimage, ...) is loaded: `import numba` itself imports the top package and its private helpers (a version
check), which the library cannot avoid.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import inspect
import json
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

from mcl.tools.cli_checks import save_json

ALL_OF = ("mcl", "motion_models", "sensing", "field", "mcl.contracts", "mcl.tools.logs", "mcl.tools.testing")
DEFINED_IN = ("mcl.localizer", "mcl.relocalization", "mcl.tools.recording", "mcl.tools.replay")
HEAVY = ("rerun", "scipy", "mcap", "mcap_ros2", "hypothesis", "numba", "matplotlib", "tqdm")
PARAMETER_SECTIONS = ("Parameters\n", "Attributes\n")


@dataclass
class Entry:
    """One public object: its dotted name, kind, and what it lacks."""

    name: str
    kind: str
    numpydoc: bool
    typed: bool
    missing: list[str] = field(default_factory=list)


def public_names() -> list[tuple[str, object]]:
    """(dotted name, object) of every public module-level name, in a stable order, without repeats."""
    seen: dict[int, str] = {}
    found = []
    for module_name in ALL_OF + DEFINED_IN:
        module = importlib.import_module(module_name)
        if module_name in ALL_OF:
            names = list(getattr(module, "__all__", []))
        else:
            names = [
                n
                for n, v in vars(module).items()
                if not n.startswith("_")
                and getattr(v, "__module__", None) == module_name
                and (inspect.isclass(v) or inspect.isfunction(v))
            ]
        for name in names:
            value = getattr(module, name)
            if not (inspect.isclass(value) or inspect.isfunction(value) or callable(value)):
                continue  # constants: documented where they are defined
            if id(value) in seen:
                continue
            seen[id(value)] = f"{module_name}.{name}"
            found.append((f"{module_name}.{name}", value))
    return found


def _arguments(function) -> list[inspect.Parameter]:
    try:
        signature = inspect.signature(function)
    except (TypeError, ValueError):
        return []
    return [p for p in signature.parameters.values() if p.name not in ("self", "cls")]


def _documents_parameters(doc: str | None) -> bool:
    return bool(doc) and any(section in inspect.cleandoc(doc) for section in PARAMETER_SECTIONS)


def _typed(function, returns: bool = True) -> tuple[bool, list[str]]:
    """Whether every argument and the return are annotated; the names that are not."""
    function = inspect.unwrap(function)
    py_function = getattr(function, "py_func", function)  # a numba dispatcher's Python function
    try:
        signature = inspect.signature(py_function)
    except (TypeError, ValueError):
        return True, []
    missing = [
        p.name
        for p in signature.parameters.values()
        if p.name not in ("self", "cls") and p.annotation is inspect.Parameter.empty
    ]
    if returns and signature.return_annotation is inspect.Signature.empty:
        missing.append("return")
    return not missing, missing


def check_function(name: str, function, kind: str = "function", owner=None) -> Entry:
    """Numpydoc and hints of one function, or of a method of the class `owner` (whose docstring it may inherit
    from the method it overrides, as the API reference shows it)."""
    target = getattr(function, "py_func", function)
    doc = inspect.getdoc(getattr(owner, name.rsplit(".", 1)[-1]) if owner is not None else target)
    arguments = _arguments(target)
    numpydoc = bool(doc) and (not arguments or _documents_parameters(doc))
    typed, untyped = _typed(target, returns=name.rsplit(".", 1)[-1] != "__init__")
    missing = ([] if doc else ["docstring"]) + ([] if numpydoc or not doc else ["Parameters section"])
    missing += [f"hint: {n}" for n in untyped]
    return Entry(name, kind, numpydoc, typed, missing)


def check_class(name: str, cls) -> list[Entry]:
    """The class itself (its docstring documents the constructor) and its public methods and properties."""
    init = cls.__dict__.get("__init__")
    is_data = dataclasses.is_dataclass(cls)
    protocol = getattr(cls, "_is_protocol", False)
    arguments = _arguments(cls) if (init is not None or is_data) and not protocol else []
    doc = cls.__doc__
    documented = _documents_parameters(doc) or (init is not None and _documents_parameters(init.__doc__))
    numpydoc = bool(doc) and (not arguments or documented)
    if is_data:
        fields_missing = [f.name for f in dataclasses.fields(cls) if f.type in (None, inspect.Parameter.empty)]
        typed, untyped = not fields_missing, fields_missing
    elif init is not None and not protocol:
        typed, untyped = _typed(init, returns=False)
    else:
        typed, untyped = True, []
    missing = ([] if doc else ["docstring"]) + ([] if numpydoc or not doc else ["Parameters/Attributes section"])
    missing += [f"hint: {n}" for n in untyped]
    entries = [Entry(name, "class", numpydoc, typed, missing)]
    for member, value in cls.__dict__.items():
        if member.startswith("_"):
            continue
        if isinstance(value, property):
            doc_ok = bool(value.fget and value.fget.__doc__)
            typed_ok, untyped = _typed(value.fget) if value.fget else (True, [])
            entries.append(
                Entry(
                    f"{name}.{member}",
                    "property",
                    doc_ok,
                    typed_ok,
                    ([] if doc_ok else ["docstring"]) + [f"hint: {n}" for n in untyped],
                )
            )
        elif isinstance(value, (staticmethod, classmethod)):
            entries.append(check_function(f"{name}.{member}", value.__func__, "method", cls))
        elif inspect.isfunction(value):
            entries.append(check_function(f"{name}.{member}", value, "method", cls))
    return entries


def coverage() -> dict:
    """Every public object's entry and the shares."""
    entries: list[Entry] = []
    for name, value in public_names():
        if inspect.isclass(value):
            entries += check_class(name, value)
        else:
            entries.append(check_function(name, value))
    n = len(entries)
    numpydoc = sum(e.numpydoc for e in entries)
    typed = sum(e.typed for e in entries)
    return {
        "objects": n,
        "numpydoc": numpydoc,
        "numpydoc_share": numpydoc / n if n else 1.0,
        "typed": typed,
        "typed_share": typed / n if n else 1.0,
        "both": sum(e.numpydoc and e.typed for e in entries),
        "misses": [dataclasses.asdict(e) for e in entries if not (e.numpydoc and e.typed)],
    }


def import_time(rounds: int = 5) -> dict:
    """`import mcl` in fresh interpreters: the median wall time, and the heavy packages loaded."""
    code = (
        "import sys, time\nt = time.perf_counter()\nimport mcl\nt = time.perf_counter() - t\n"
        "scipy = any(n.startswith('scipy.') and n.split('.')[1] not in ('version', '__config__')\n"
        "            and not n.split('.')[1].startswith('_') for n in sys.modules)\n"
        f"print(t, ','.join(m for m in {HEAVY!r} if m in sys.modules and (m != 'scipy' or scipy)), "
        "len(sys.modules))"
    )
    times, loaded, modules = [], "", 0
    for _ in range(rounds):
        done = subprocess.run(
            [sys.executable, "-c", code],
            capture_output=True,
            text=True,
            check=True,
            cwd=Path(__file__).resolve().parent.parent,
        )
        seconds, loaded, count = done.stdout.split()[0], (done.stdout.split() + [""])[1], done.stdout.split()[-1]
        times.append(float(seconds))
        modules = int(count)
    times.sort()
    heavy = [] if loaded.isdigit() else [m for m in loaded.split(",") if m]
    return {"median_s": times[len(times) // 2], "rounds": rounds, "heavy_loaded": heavy, "modules_loaded": modules}


def report_text(result: dict, misses: int) -> str:
    c, i = result["coverage"], result["import"]
    lines = [
        f"public API: {c['objects']} objects (functions, classes, methods, properties)",
        f"  numpydoc docstrings: {c['numpydoc']} ({100 * c['numpydoc_share']:.1f} %)",
        f"  complete type hints: {c['typed']} ({100 * c['typed_share']:.1f} %)",
        f"  both:                {c['both']} ({100 * c['both'] / max(c['objects'], 1):.1f} %)",
        f"import mcl: {1e3 * i['median_s']:.0f} ms (median of {i['rounds']} fresh interpreters), "
        f"{i['modules_loaded']} modules; heavy packages loaded: {', '.join(i['heavy_loaded']) or 'none'}",
    ]
    if misses and c["misses"]:
        lines.append(f"first {min(misses, len(c['misses']))} of {len(c['misses'])} objects missing something:")
        lines += [f"  {m['name']}: {', '.join(m['missing'])}" for m in c["misses"][:misses]]
    return "\n".join(lines)


def build_parser(prog: str = "python -m benchmarks.api_coverage") -> argparse.ArgumentParser:
    """The command's argument parser."""
    parser = argparse.ArgumentParser(
        prog=prog,
        description="Numpydoc docstrings and type hints on the public API, and the time and weight of `import mcl`.",
    )
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--save", metavar="PATH", help="also write the JSON result to PATH")
    parser.add_argument(
        "--misses",
        type=int,
        default=20,
        metavar="N",
        help="list the first N objects that miss something (default 20; 0 for none)",
    )
    parser.add_argument(
        "--rounds", type=int, default=5, metavar="N", help="fresh interpreters to time `import mcl` in (default 5)"
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.rounds < 1 or args.misses < 0:
        raise SystemExit("api_coverage: --rounds must be >= 1 and --misses >= 0")
    result = {"coverage": coverage(), "import": import_time(args.rounds)}
    save_json(args.save, result)
    print(json.dumps(result, indent=1) if args.json else report_text(result, args.misses))
    return 0


if __name__ == "__main__":
    sys.exit(main())
