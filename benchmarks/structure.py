"""The code's structure, measured: the figures of an architecture issue, from a command.

    python -m benchmarks.structure [--rev REV] [--json] [--save PATH] [--core FILE ...] [--soccer FILE ...]

Run from the repository root. It reads the Python sources of the library packages (every top-level directory
with an `__init__.py` except tests, demos and benchmarks) in the working tree, or with `--rev REV` in that git
revision (extracted with `git archive` into a temporary directory), and reports:

  private_imports    import statements in a library, demos or benchmarks module that reach into another
                     top-level package's private module (a dotted component `_x`) or import a private name
                     (`_x`, not a dunder) from it; relative imports resolved, `from __future__` ignored. The
                     ones reaching into third-party packages (and the standard library) are listed apart.
  cross_layer        imports from library modules to demos or benchmarks (and, apart, string-literal
                     `importlib.import_module`/`__import__` calls and "demos.x"-like strings, which hide them).
  lines              physical lines per library module and package; the `--core` and `--soccer` groups.
  longest_function   outside kernels and among kernels (a kernel: decorated with numba's njit/jit/vectorize,
                     or intrinsic/overload, called or not; imports resolved, typing.overload excluded).
  widest_parameters  the most parameters (*args and **kwargs one each, a leading self/cls not counted).
  largest_class      by lines and by methods (and the five largest by lines), and by code lines: the lines its
                     statements span, documentation (a bare string statement), blank lines and comment lines
                     between statements left out.
  paired_variants    functions named as another's variant (`*_reference`, `*_chunked`, `*_fast`, `*_compiled`):
                     how many, and which.
  import_contract    `lint-imports` on the tree when importlinter is installed and pyproject.toml has a
                     [tool.importlinter] section; otherwise null, with the reason.

Only the standard library: ast, not an import of the analysed code, so any revision can be measured.
"""

from __future__ import annotations

import argparse
import ast
import importlib.util
import io
import json
import os
import re
import subprocess
import sys
import tarfile
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, as the tomli package
    import tomli as tomllib

EXCLUDED = ("tests", "demos", "benchmarks")  # top-level packages that are not the library
CONSUMERS = ("demos", "benchmarks")  # the layers the library must not import
KERNEL_NAMES = ("njit", "intrinsic", "overload")  # a decorator whose dotted name ends in one of these...
NUMBA_KERNEL_NAMES = ("jit", "vectorize")  # ...or is numba's jit / vectorize
NOT_KERNEL_ROOTS = ("typing", "typing_extensions")  # typing.overload is a stub, not a kernel
DEFAULT_CORE = ("mcl/filter.py",)
OPTIONAL_CORE = ("mcl/particles.py", "mcl/summary.py", "mcl/step.py", "mcl/contracts.py")
DEFAULT_SOCCER = ()
OPTIONAL_SOCCER = ("mcl/relocalization.py", "mcl/soccer.py")
TOP = 5


class StructureError(Exception):
    """A one-line failure of the command (exit 1)."""


# ----------------------------------------------------------------------------------------------------- reading


@dataclass
class Module:
    path: str  # relative to the tree's root, posix
    parts: tuple[str, ...]  # the module's dotted name, split (a package's __init__ is the package)
    package: str  # its top-level package
    is_init: bool
    lines: int
    tree: ast.Module | None
    aliases: dict[str, str] = field(default_factory=dict)  # local name -> dotted origin, from its imports

    @property
    def package_parts(self) -> tuple[str, ...]:
        return self.parts if self.is_init else self.parts[:-1]


def physical_lines(data: bytes) -> int:
    """Physical lines, as `wc -l` counts them, plus a last line without its newline."""
    return data.count(b"\n") + (1 if data and not data.endswith(b"\n") else 0)


def top_level_packages(root: Path) -> list[str]:
    """Every top-level directory of `root` with an `__init__.py`, sorted."""
    return sorted(
        p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith(".") and (p / "__init__.py").is_file()
    )


def project_names(root: Path) -> set[str]:
    """Top-level names that belong to the project: its packages, the excluded directories and root modules."""
    names = set(top_level_packages(root))
    names |= {name for name in EXCLUDED if (root / name).is_dir()}
    names |= {p.stem for p in root.glob("*.py")}
    return names


def read_modules(root: Path, packages: list[str]) -> tuple[list[Module], list[str]]:
    """The `.py` files under each of `packages`, parsed; and the files that did not parse."""
    modules, errors = [], []
    for package in packages:
        for file in sorted((root / package).rglob("*.py")):
            rel = file.relative_to(root)
            if any(part == "__pycache__" or part.startswith(".") for part in rel.parts):
                continue
            data = file.read_bytes()
            try:
                tree = ast.parse(data, filename=str(rel))
            except (SyntaxError, ValueError) as error:
                tree = None
                errors.append(f"{rel.as_posix()}: {type(error).__name__}: {error}")
            parts = rel.with_suffix("").parts
            is_init = parts[-1] == "__init__"
            module = Module(
                rel.as_posix(), parts[:-1] if is_init else parts, package, is_init, physical_lines(data), tree
            )
            if tree is not None:
                module.aliases = import_aliases(module)
            modules.append(module)
    return modules, errors


# ----------------------------------------------------------------------------------------------------- imports


def resolve(module: Module, level: int, name: str | None) -> str | None:
    """The absolute module of `from <level dots><name> import ...` in `module`; None if it leaves the tree."""
    if level == 0:
        return name
    base = module.package_parts
    if level - 1 >= len(base):  # above the top-level package
        return None
    base = base[: len(base) - (level - 1)]
    return ".".join(base + ((name,) if name else ())) or None


def import_aliases(module: Module) -> dict[str, str]:
    """Local name -> dotted origin, from every import statement of `module` (for decorators' real names)."""
    aliases: dict[str, str] = {}
    for node in ast.walk(module.tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.asname:
                    aliases[alias.asname] = alias.name
                else:
                    top = alias.name.split(".")[0]
                    aliases[top] = top
        elif isinstance(node, ast.ImportFrom):
            base = resolve(module, node.level, node.module)
            if base is None:
                continue
            for alias in node.names:
                if alias.name != "*":
                    aliases[alias.asname or alias.name] = f"{base}.{alias.name}"
    return aliases


def is_private(name: str) -> bool:
    """`_x` or `__x`, not a dunder `__x__`."""
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def statement(node: ast.AST) -> str:
    return ast.unparse(node)


def imported_targets(module: Module, node: ast.Import | ast.ImportFrom) -> list[tuple[str, list[str]]] | None:
    """(absolute target module, its private parts) per module the statement reaches; None if unresolvable.

    A private part is a dotted path component or an imported name that `is_private`.
    """
    if isinstance(node, ast.Import):
        return [(alias.name, [part for part in alias.name.split(".") if is_private(part)]) for alias in node.names]
    base = resolve(module, node.level, node.module)
    if base is None:
        return None
    private = [part for part in base.split(".") if is_private(part)]
    private += [alias.name for alias in node.names if alias.name != "*" and is_private(alias.name)]
    return [(base, private)]


def origin_of(top: str, project: set[str]) -> str:
    if top in project:
        return "project"
    if top in sys.stdlib_module_names:
        return "stdlib"
    return "third_party"


def private_imports(modules: list[Module], project: set[str]) -> dict:
    """Import statements reaching into another top-level package's private parts, by where that package is from.

    One entry per statement and origin (project, third_party, stdlib); imports within the importer's own
    top-level package are not counted.
    """
    found: dict[str, list[dict]] = {"project": [], "third_party": [], "stdlib": []}
    unresolved = []
    for module in modules:
        if module.tree is None:
            continue
        for node in ast.walk(module.tree):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module == "__future__":
                continue
            targets = imported_targets(module, node)
            if targets is None:
                unresolved.append(f"{module.path}:{node.lineno}: {statement(node)}")
                continue
            by_origin: dict[str, dict] = {}
            for target, private in targets:
                top = target.split(".")[0]
                if not private or top == module.package:
                    continue
                entry = by_origin.setdefault(
                    origin_of(top, project),
                    {
                        "file": module.path,
                        "line": node.lineno,
                        "statement": statement(node),
                        "targets": [],
                        "private": [],
                    },
                )
                entry["targets"].append(target)
                entry["private"] += private
            for origin, entry in by_origin.items():
                found[origin].append(entry)
    result = _listed(found["project"])
    result["third_party"] = _listed(found["third_party"])
    result["stdlib"] = _listed(found["stdlib"])
    result["unresolved"] = unresolved
    return result


def _listed(entries: list[dict]) -> dict:
    entries = sorted(entries, key=lambda e: (e["file"], e["line"]))
    return {
        "count": len(entries),
        "items": entries,
        "list": [f"{e['file']}:{e['line']}: {e['statement']}" for e in entries],
    }


MODULE_STRING = re.compile(r"^({})(\.[A-Za-z_][A-Za-z0-9_]*)+$".format("|".join(CONSUMERS)))


def cross_layer(modules: list[Module]) -> dict:
    """Imports from library modules to demos or benchmarks; apart, the dynamic ones that ast can see."""
    imports, dynamic, strings = [], [], []
    for module in modules:
        if module.tree is None:
            continue
        for node in ast.walk(module.tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                targets = imported_targets(module, node) or []
                reached = [t for t, _ in targets if t.split(".")[0] in CONSUMERS]
                if reached:
                    imports.append(
                        {"file": module.path, "line": node.lineno, "statement": statement(node), "targets": reached}
                    )
            elif isinstance(node, ast.Call) and _is_import_call(node):
                target = node.args[0].value
                if target.split(".")[0] in CONSUMERS:
                    dynamic.append(
                        {"file": module.path, "line": node.lineno, "statement": statement(node), "targets": [target]}
                    )
            elif isinstance(node, ast.Constant) and isinstance(node.value, str) and MODULE_STRING.match(node.value):
                strings.append(
                    {"file": module.path, "line": node.lineno, "statement": repr(node.value), "targets": [node.value]}
                )
    dynamic_lines = {(e["file"], e["line"]) for e in dynamic}
    strings = [e for e in strings if (e["file"], e["line"]) not in dynamic_lines]
    result = _listed(imports)
    result["dynamic"] = _listed(dynamic)
    result["module_name_strings"] = _listed(strings)
    return result


def _is_import_call(node: ast.Call) -> bool:
    name = dotted(node.func)
    return (
        name in ("importlib.import_module", "import_module", "__import__")
        and bool(node.args)
        and isinstance(node.args[0], ast.Constant)
        and isinstance(node.args[0].value, str)
    )


# ----------------------------------------------------------------------------------------------- definitions


def dotted(node: ast.AST) -> str | None:
    """`a.b.c` of a Name/Attribute chain (a call's function for a called decorator); None otherwise."""
    if isinstance(node, ast.Call):
        node = node.func
    names = []
    while isinstance(node, ast.Attribute):
        names.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    names.append(node.id)
    return ".".join(reversed(names))


def is_kernel_decorator(decorator: ast.AST, aliases: dict[str, str]) -> bool:
    """numba.njit / njit / numba.jit / numba.vectorize / intrinsic / overload, called or not, imports resolved."""
    name = dotted(decorator)
    if name is None:
        return False
    head, _, rest = name.partition(".")
    resolved = aliases.get(head, head) + ("." + rest if rest else "")
    if resolved.split(".")[0] in NOT_KERNEL_ROOTS:
        return False
    for candidate in (name, resolved):
        parts = candidate.split(".")
        if parts[-1] in KERNEL_NAMES:
            return True
        if parts[-1] in NUMBA_KERNEL_NAMES and len(parts) > 1 and parts[0] == "numba":
            return True
    return False


@dataclass
class Function:
    name: str
    file: str
    line: int
    lines: int
    parameters: int
    kernel: bool

    def as_dict(self) -> dict:
        return {
            "name": self.name,
            "file": self.file,
            "line": self.line,
            "lines": self.lines,
            "parameters": self.parameters,
        }


@dataclass
class Class:
    name: str
    file: str
    line: int
    lines: int
    methods: int
    code_lines: int = 0

    def as_dict(self) -> dict:
        return {
            "name": self.name,
            "file": self.file,
            "line": self.line,
            "lines": self.lines,
            "methods": self.methods,
            "code_lines": self.code_lines,
        }


def code_lines(node: ast.AST) -> int:
    """The lines of `node` that hold code: each simple statement's lines, a compound statement's header (its
    decorators, and its lines up to its body), a docstring or any other bare string statement left out; so
    neither documentation nor the blank and comment lines between statements count."""
    covered: set[int] = set()
    for child in ast.walk(node):
        if not isinstance(child, ast.stmt):
            continue
        if isinstance(child, ast.Expr) and isinstance(child.value, ast.Constant) and isinstance(child.value.value, str):
            continue
        body = getattr(child, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.stmt):  # compound: its header
            for decorator in getattr(child, "decorator_list", ()):
                covered.update(range(decorator.lineno, decorator.end_lineno + 1))
            covered.update(range(child.lineno, max(child.lineno, body[0].lineno - 1) + 1))
        else:
            covered.update(range(child.lineno, child.end_lineno + 1))
    return len(covered)


def parameter_count(arguments: ast.arguments) -> int:
    """Positional, keyword-only, *args and **kwargs (one each); a leading self or cls is not counted."""
    positional = arguments.posonlyargs + arguments.args
    count = len(positional) + len(arguments.kwonlyargs) + bool(arguments.vararg) + bool(arguments.kwarg)
    if positional and positional[0].arg in ("self", "cls"):
        count -= 1
    return count


def definitions(module: Module) -> tuple[list[Function], list[Class]]:
    """Every function, method and class of `module`, nested ones too (a function inside a kernel is kernel code)."""
    functions, classes = [], []

    def visit(node: ast.AST, prefix: str, in_kernel: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                kernel = in_kernel or any(is_kernel_decorator(d, module.aliases) for d in child.decorator_list)
                functions.append(
                    Function(
                        prefix + child.name,
                        module.path,
                        child.lineno,
                        child.end_lineno - child.lineno + 1,
                        parameter_count(child.args),
                        kernel,
                    )
                )
                visit(child, f"{prefix}{child.name}.<locals>.", kernel)
            elif isinstance(child, ast.ClassDef):
                methods = sum(isinstance(c, (ast.FunctionDef, ast.AsyncFunctionDef)) for c in child.body)
                classes.append(
                    Class(
                        prefix + child.name,
                        module.path,
                        child.lineno,
                        child.end_lineno - child.lineno + 1,
                        methods,
                        code_lines(child),
                    )
                )
                visit(child, f"{prefix}{child.name}.", in_kernel)
            else:
                visit(child, prefix, in_kernel)

    if module.tree is not None:
        visit(module.tree, "", False)
    return functions, classes


def _first(items: list, key) -> dict | None:
    """The item with the largest key (ties: the first by file and line), as a dict; None if there is none."""
    ranked = sorted(items, key=lambda i: (-key(i), i.file, i.line))
    return ranked[0].as_dict() if ranked else None


def function_figures(functions: list[Function]) -> tuple[dict, dict]:
    longest, widest = {}, {}
    for group, members in (
        ("outside_kernels", [f for f in functions if not f.kernel]),
        ("kernels", [f for f in functions if f.kernel]),
    ):
        longest[group] = _first(members, lambda f: f.lines)
        ranked = sorted(members, key=lambda f: (-f.parameters, f.file, f.line))
        widest[group] = {
            "widest": ranked[0].as_dict() if ranked else None,
            "top": [f.as_dict() for f in ranked[:TOP]],
            "functions": len(members),
        }
    return longest, widest


# ------------------------------------------------------------------------------------------------------ lines


def group_lines(root: Path, members: list[str]) -> dict:
    """Total physical lines of `members` (files, or directories: their .py files) under `root`."""
    files, missing = [], []
    for member in members:
        path = root / member
        if path.is_dir():
            files += sorted(p for p in path.rglob("*.py") if "__pycache__" not in p.parts)
        elif path.is_file():
            files.append(path)
        else:
            missing.append(member)
    per_file = {p.relative_to(root).as_posix(): physical_lines(p.read_bytes()) for p in files}
    return {"members": per_file, "missing": missing, "lines": sum(per_file.values())}


def default_group(root: Path, required: tuple[str, ...], optional: tuple[str, ...]) -> list[str]:
    return list(required) + [m for m in optional if (root / m).exists()]


# --------------------------------------------------------------------------------------------- import contract


def import_contract(root: Path) -> tuple[dict | None, str | None]:
    """`lint-imports` on `root`: (kept, broken, violations...), or (None, why it did not run)."""
    if importlib.util.find_spec("importlinter") is None:
        return None, "importlinter is not installed"
    pyproject = root / "pyproject.toml"
    if not pyproject.is_file():
        return None, "the tree has no pyproject.toml"
    try:
        config = tomllib.loads(pyproject.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        return None, f"pyproject.toml does not parse: {error}"
    if "importlinter" not in config.get("tool", {}):
        return None, "pyproject.toml has no [tool.importlinter] section"
    script = Path(sys.executable).parent / "lint-imports"
    if not script.is_file():
        return None, f"{script} not found"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    try:
        run = subprocess.run(
            [str(script), "--no-cache"], cwd=root, env=env, capture_output=True, text=True, timeout=900
        )
    except (OSError, subprocess.TimeoutExpired) as error:
        return None, f"lint-imports did not run: {error}"
    parsed = parse_lint_imports(run.stdout)
    if parsed is None:
        last = (run.stderr.strip() or run.stdout.strip() or "no output").splitlines()[-1]
        return None, f"lint-imports output not understood (exit {run.returncode}): {last}"
    parsed["exit_code"] = run.returncode
    return parsed, None


def parse_lint_imports(output: str) -> dict | None:
    """Kept/broken counts, each contract's status and the violations (`- a -> b (l.N)` lines) of its output."""
    summary = re.search(r"^Contracts:\s*(\d+) kept,\s*(\d+) broken", output, re.MULTILINE)
    if summary is None:
        return None
    head, _, tail = output.partition(summary.group(0))
    contracts = {
        m.group(1): {"status": m.group(2).lower(), "violations": 0}
        for m in re.finditer(r"^(\S.*?)\s+(KEPT|BROKEN)\s*$", head, re.MULTILINE)
    }
    current, violations = None, 0
    lines = tail.splitlines()
    for i, line in enumerate(lines):
        if i + 1 < len(lines) and re.fullmatch(r"-{3,}", lines[i + 1].strip()) and line.strip():
            current = line.strip()
        elif re.match(r"^\s*-\s+\S+\s+->\s+\S+", line):
            violations += 1
            if current in contracts:
                contracts[current]["violations"] += 1
    return {
        "kept": int(summary.group(1)),
        "broken": int(summary.group(2)),
        "violations": violations,
        "contracts": [{"name": name, **value} for name, value in contracts.items()],
    }


# -------------------------------------------------------------------------------------------------- analysis


VARIANT_SUFFIXES = ("_reference", "_chunked", "_fast", "_compiled")


def paired_variants(functions: list[Function]) -> dict:
    """The functions whose names mark them as another's variant (VARIANT_SUFFIXES): count and list."""
    named = sorted((f for f in functions if f.name.endswith(VARIANT_SUFFIXES)), key=lambda f: (f.file, f.line))
    return {"count": len(named), "list": [f"{f.file}:{f.line} {f.name}" for f in named]}


def analyse(
    root: Path, core: list[str] | None = None, soccer: list[str] | None = None, run_contract: bool = True
) -> dict:
    """Every figure of the tree at `root` (see the module's docstring), as a JSON-ready dict."""
    root = Path(root)
    packages = top_level_packages(root)
    library = [p for p in packages if p not in EXCLUDED]
    consumers = [p for p in packages if p in CONSUMERS]
    project = project_names(root)
    library_modules, errors = read_modules(root, library)
    consumer_modules, consumer_errors = read_modules(root, consumers)

    functions, classes = [], []
    for module in library_modules:
        f, c = definitions(module)
        functions += f
        classes += c
    longest, widest = function_figures(functions)

    per_package = {p: sum(m.lines for m in library_modules if m.package == p) for p in library}
    core = default_group(root, DEFAULT_CORE, OPTIONAL_CORE) if core is None else core
    soccer = default_group(root, DEFAULT_SOCCER, OPTIONAL_SOCCER) if soccer is None else soccer

    contract, reason = import_contract(root) if run_contract else (None, "not asked for")
    return {
        "packages": library,
        "other_packages": consumers,
        "modules": len(library_modules),
        "private_imports": private_imports(library_modules + consumer_modules, project),
        "cross_layer": cross_layer(library_modules),
        "lines": {
            "total": sum(per_package.values()),
            "packages": per_package,
            "modules": {m.path: m.lines for m in library_modules},
            "groups": {"core": group_lines(root, core), "soccer": group_lines(root, soccer)},
        },
        "longest_function": longest,
        "widest_parameters": widest,
        "largest_class": {
            "by_lines": _first(classes, lambda c: c.lines),
            "by_methods": _first(classes, lambda c: c.methods),
            "by_code_lines": _first(classes, lambda c: c.code_lines),
            "classes": len(classes),
            "top": [c.as_dict() for c in sorted(classes, key=lambda c: -c.lines)[:5]],
        },
        "paired_variants": paired_variants(functions),
        "import_contract": contract,
        "import_contract_reason": reason,
        "parse_errors": errors + consumer_errors,
    }


# ------------------------------------------------------------------------------------------------------- git


def git(root: Path, *args: str, binary: bool = False) -> subprocess.CompletedProcess:
    try:
        return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=not binary)
    except OSError as error:
        raise StructureError(f"git did not run: {error}") from None


def checkout_prefix(root: Path) -> str:
    """`root`'s path inside its git checkout ('' at the top); StructureError if it is not in one."""
    run = git(root, "rev-parse", "--show-prefix")
    if run.returncode != 0:
        raise StructureError(f"{root} is not a git checkout")
    return run.stdout.strip()


def resolve_revision(root: Path, rev: str) -> dict:
    prefix = checkout_prefix(root)
    run = git(root, "rev-parse", "--verify", "--quiet", "--end-of-options", f"{rev}^{{commit}}")
    if run.returncode != 0 or not run.stdout.strip():
        raise StructureError(f"unknown revision {rev!r}")
    commit = run.stdout.strip()
    short = git(root, "rev-parse", "--short", commit).stdout.strip() or commit[:7]
    return {"name": rev, "commit": commit, "short": short, "prefix": prefix}


def extract(root: Path, revision: dict, into: Path) -> None:
    """The tree of `revision` (at `root`'s place in the checkout), written under `into` (git archive | tar -x)."""
    treeish = f"{revision['commit']}:{revision['prefix']}" if revision["prefix"] else revision["commit"]
    run = git(root, "archive", "--format=tar", treeish, binary=True)
    if run.returncode != 0:
        message = run.stderr.decode(errors="replace").strip().splitlines()
        raise StructureError(f"git archive {revision['name']} failed: {message[-1] if message else 'no message'}")
    with tarfile.open(fileobj=io.BytesIO(run.stdout)) as archive:
        if hasattr(tarfile, "data_filter"):
            archive.extractall(into, filter="data")
        else:  # pragma: no cover - Python before 3.11.4
            archive.extractall(into)


def working_tree(root: Path) -> dict:
    """What the working tree is: its HEAD and whether it differs from it, when it is a git checkout."""
    head = git(root, "rev-parse", "--short", "HEAD")
    if head.returncode != 0:
        return {"name": "working tree", "commit": None, "short": None, "modified": None}
    status = git(root, "status", "--porcelain", "--untracked-files=no", "--", ".")
    return {
        "name": "working tree",
        "commit": git(root, "rev-parse", "HEAD").stdout.strip(),
        "short": head.stdout.strip(),
        "modified": bool(status.stdout.strip()),
    }


def measure(
    root: Path, rev: str | None, core: list[str] | None, soccer: list[str] | None, run_contract: bool = True
) -> dict:
    root = Path(root).resolve()
    if not root.is_dir():
        raise StructureError(f"{root} is not a directory")
    if rev is None:
        report = {"root": str(root), "revision": working_tree(root)}
        report.update(analyse(root, core, soccer, run_contract))
        return report
    revision = resolve_revision(root, rev)
    with tempfile.TemporaryDirectory(prefix="structure-") as tmp:
        extract(root, revision, Path(tmp))
        report = {"root": str(root), "revision": {k: v for k, v in revision.items() if k != "prefix"}}
        report.update(analyse(Path(tmp), core, soccer, run_contract))
    return report


# ------------------------------------------------------------------------------------------------------ output


def _where(item: dict | None, figure: str) -> str:
    if item is None:
        return "-"
    return f"{item['name']} ({item['file']}:{item['line']}) {item[figure]} {figure}"


def _cut(text: str, width: int = 110) -> str:
    return text if len(text) <= width else text[: width - 3] + "..."


def render(report: dict) -> str:
    rev = report["revision"]
    if rev["name"] == "working tree":
        what = "working tree" + (
            f" (HEAD {rev['short']}{', modified' if rev['modified'] else ''})" if rev["short"] else ""
        )
    else:
        what = f"revision {rev['name']} ({rev['short']})"
    lines_ = report["lines"]
    private, cross = report["private_imports"], report["cross_layer"]
    longest, widest, largest = report["longest_function"], report["widest_parameters"], report["largest_class"]
    rows = [
        ("library packages", ", ".join(report["packages"]) + f"  ({report['modules']} modules)"),
        (
            "private imports",
            f"{private['count']} across the project's packages; third-party {private['third_party']['count']}, "
            f"stdlib {private['stdlib']['count']}",
        ),
        (
            "cross-layer imports",
            f"{cross['count']} library -> demos/benchmarks; dynamic {cross['dynamic']['count']}, "
            f"module-name strings {cross['module_name_strings']['count']}",
        ),
        ("lines", f"{lines_['total']} in the library: " + ", ".join(f"{p} {n}" for p, n in lines_["packages"].items())),
    ]
    for name, group in lines_["groups"].items():
        missing = f"; missing {', '.join(group['missing'])}" if group["missing"] else ""
        rows.append((f"{name} group", f"{group['lines']} lines ({', '.join(group['members']) or 'no file'}{missing})"))
    rows += [
        ("longest function", _where(longest["outside_kernels"], "lines")),
        ("longest kernel", _where(longest["kernels"], "lines")),
        ("widest parameters", _where(widest["outside_kernels"]["widest"], "parameters")),
        ("widest kernel", _where(widest["kernels"]["widest"], "parameters")),
        ("largest class", _where(largest["by_lines"], "lines")),
        ("most methods", _where(largest["by_methods"], "methods")),
        ("most code lines", _where(largest["by_code_lines"], "code_lines").replace("code_lines", "code lines")),
        (
            "largest classes",
            ", ".join(f"{c['name']} {c['lines']} ({c['code_lines']} code)" for c in largest["top"]) or "-",
        ),
        (
            "paired variants",
            f"{report['paired_variants']['count']} functions named *_reference, *_chunked, *_fast, *_compiled",
        ),
    ]
    contract = report["import_contract"]
    rows.append(
        (
            "import contract",
            f"{contract['kept']} kept, {contract['broken']} broken, {contract['violations']} violations"
            if contract
            else f"not run: {report['import_contract_reason']}",
        )
    )
    width = max(len(r[0]) for r in rows)
    out = [f"Structure of the {what}"] + [f"  {k:<{width}}  {v}" for k, v in rows]
    for title, listed in (("private imports", private), ("cross-layer imports", cross)):
        if listed["count"]:
            out += ["", f"{title}:"] + [f"  {_cut(line)}" for line in listed["list"]]
    if report["parse_errors"]:
        out += ["", "did not parse:"] + [f"  {e}" for e in report["parse_errors"]]
    return "\n".join(out)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m benchmarks.structure",
        description="Measure the code's structure (imports, lines, functions, classes).",
    )
    p.add_argument("--rev", help="measure this git revision instead of the working tree")
    p.add_argument("--json", action="store_true", help="print JSON instead of the table")
    p.add_argument("--save", metavar="PATH", help="write the JSON report to PATH (parent directories created)")
    p.add_argument(
        "--core",
        nargs="+",
        metavar="FILE",
        help="the core group's files or directories (default: mcl/filter.py, and mcl/particles.py, "
        "mcl/step.py, mcl/contracts.py where they exist)",
    )
    p.add_argument(
        "--soccer",
        nargs="+",
        metavar="FILE",
        help="the soccer group's files or directories (default: mcl/relocalization.py, mcl/soccer.py where they exist)",
    )
    p.add_argument("--root", default=".", help="the repository root (default: the current directory)")
    p.add_argument("--no-contract", action="store_true", help="do not run lint-imports")
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        report = measure(Path(args.root), args.rev, args.core, args.soccer, not args.no_contract)
        text = json.dumps(report, indent=2)
        if args.save:
            try:
                path = Path(args.save)
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text(text + "\n", encoding="utf-8")
            except OSError as error:
                raise StructureError(f"cannot write {args.save}: {error.strerror or error}") from None
    except StructureError as error:
        print(f"benchmarks.structure: {error}", file=sys.stderr)
        return 1
    print(text if args.json else render(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
