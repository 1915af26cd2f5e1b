"""`python -m benchmarks.structure`: its figures on small synthetic trees written to tmp_path.

Nothing here reads the repository's own figures (they change with every restructuring); the one subprocess run
measures a synthetic tree too.
"""

import ast
import importlib.util
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from benchmarks import structure
from benchmarks.structure import analyse, main, parse_lint_imports, resolve

REPO = Path(__file__).resolve().parents[1]


def write(root: Path, files: dict[str, str]) -> Path:
    """`files` (relative path -> source) under `root`; every directory on the way a package."""
    for rel, source in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(source))
    return root


TREE = {
    "alpha/__init__.py": "",
    "alpha/_hidden.py": "def helper():\n    return 1\n",
    "alpha/core.py": """\
        from . import _hidden                       # within alpha: not counted
        from ._hidden import helper                 # within alpha: not counted
        from beta.tools import _secret, public      # another package's private name: counted
        import beta._impl.deep                      # another package's private module: counted
        from beta import __version__                # a dunder is not private
        from mcap_ros2._dynamic import TimeDefinition   # third-party
        from os import _exit                        # stdlib
        from __future__ import annotations
        """,
    "alpha/sub/__init__.py": "",
    "alpha/sub/leaf.py": """\
        from .. import core
        from ..core import thing
        from ...beta import x
        """,
    "beta/__init__.py": "__version__ = '1'\n",
    "beta/_impl/__init__.py": "",
    "beta/_impl/deep.py": "",
    "beta/tools.py": """\
        from ._impl import deep                     # relative, within beta: not counted
        from alpha.sub import leaf
        def _secret():
            pass
        public = 1
        """,
    "beta/late.py": """\
        def later():
            from demos.walk import run              # a library module importing demos: cross-layer
            import importlib
            importlib.import_module("benchmarks.bench")
            return {"walk": "demos.walk"}
        """,
    "demos/__init__.py": "",
    "demos/walk.py": "from alpha._hidden import helper\nfrom demos import _local\n",
    "tests/test_x.py": "from alpha._hidden import helper\n",  # tests are not scanned
}


@pytest.fixture
def tree(tmp_path):
    return write(tmp_path / "tree", TREE)


def by_file(listed: dict) -> dict[str, list[int]]:
    found: dict[str, list[int]] = {}
    for item in listed["items"]:
        found.setdefault(item["file"], []).append(item["line"])
    return found


def test_private_imports_across_packages_are_found_and_within_a_package_not(tree):
    report = analyse(tree, run_contract=False)
    private = report["private_imports"]
    assert report["packages"] == ["alpha", "beta"] and report["other_packages"] == ["demos"]
    assert by_file(private) == {"alpha/core.py": [3, 4], "demos/walk.py": [1]}
    assert private["count"] == 3
    assert private["list"][0] == "alpha/core.py:3: from beta.tools import _secret, public"
    names = {item["statement"]: item["private"] for item in private["items"]}
    assert names["import beta._impl.deep"] == ["_impl"]
    assert names["from beta.tools import _secret, public"] == ["_secret"]


def test_third_party_and_stdlib_private_imports_are_listed_apart(tree):
    private = analyse(tree, run_contract=False)["private_imports"]
    assert private["third_party"]["list"] == ["alpha/core.py:6: from mcap_ros2._dynamic import TimeDefinition"]
    assert private["stdlib"]["list"] == ["alpha/core.py:7: from os import _exit"]


def test_relative_imports_are_resolved(tmp_path):
    modules, errors = structure.read_modules(write(tmp_path, TREE), ["alpha"])
    assert errors == []
    leaf = next(m for m in modules if m.path == "alpha/sub/leaf.py")
    init = next(m for m in modules if m.path == "alpha/sub/__init__.py")
    assert resolve(leaf, 1, None) == "alpha.sub"
    assert resolve(leaf, 2, "core") == "alpha.core"
    assert resolve(init, 1, "leaf") == "alpha.sub.leaf"  # a package's __init__ is the package
    assert resolve(init, 2, None) == "alpha"
    assert resolve(leaf, 3, "beta") is None  # above the top-level package
    assert resolve(leaf, 0, "os.path") == "os.path"


def test_a_relative_import_into_another_package_private_module_is_counted(tmp_path):
    """alpha/sub/m.py's `from .._x import y` is alpha._x (not counted); demos' relative one is demos'."""
    root = write(
        tmp_path,
        {
            "alpha/__init__.py": "",
            "alpha/_x.py": "",
            "alpha/sub/__init__.py": "",
            "alpha/sub/m.py": "from .._x import y\n",
            "demos/__init__.py": "",
            "demos/_shared.py": "",
            "demos/run.py": "from ._shared import z\n",
        },
    )
    assert analyse(root, run_contract=False)["private_imports"]["count"] == 0
    (root / "demos" / "run.py").write_text("from ._shared import z\nfrom alpha.sub import _m\n")
    assert analyse(root, run_contract=False)["private_imports"]["list"] == ["demos/run.py:2: from alpha.sub import _m"]


def test_cross_layer_imports_and_the_dynamic_ones(tree):
    cross = analyse(tree, run_contract=False)["cross_layer"]
    assert cross["list"] == ["beta/late.py:2: from demos.walk import run"]
    assert cross["dynamic"]["list"] == ["beta/late.py:4: importlib.import_module('benchmarks.bench')"]
    assert cross["module_name_strings"]["list"] == ["beta/late.py:5: 'demos.walk'"]


KERNELS = {
    "k/__init__.py": "",
    "k/code.py": """\
        import functools
        import typing
        import numba
        import numba as nb
        from numba import njit as fast, jit
        from numba.extending import intrinsic, overload

        @numba.njit(cache=True)
        def a(x):
            return x

        @fast
        def b(x):
            return x

        @nb.vectorize(["f8(f8)"])
        def c(x):
            return x

        @jit(nopython=True)
        def d(x):
            return x

        @intrinsic
        def e(typingctx, x):
            return None

        @overload(len)
        def f(x):
            def impl(x):
                return 0
            return impl

        @typing.overload
        def g(x: int) -> int: ...

        @functools.cache
        def h(x):
            y = x
            z = y
            w = z
            return w
        """,
}


def test_a_njit_decorated_function_counts_as_a_kernel(tmp_path):
    modules, _ = structure.read_modules(write(tmp_path, KERNELS), ["k"])
    functions, _ = structure.definitions(next(m for m in modules if m.path == "k/code.py"))
    kernel = {f.name: f.kernel for f in functions}
    assert kernel == {
        "a": True,
        "b": True,
        "c": True,
        "d": True,
        "e": True,
        "f": True,
        "f.<locals>.impl": True,
        "g": False,
        "h": False,
    }


def test_the_longest_function_outside_kernels_and_among_them(tmp_path):
    report = analyse(write(tmp_path, KERNELS), run_contract=False)
    assert report["longest_function"]["outside_kernels"] == {
        "name": "h",
        "file": "k/code.py",
        "line": 38,
        "lines": 5,
        "parameters": 1,
    }
    longest_kernel = report["longest_function"]["kernels"]
    assert (longest_kernel["name"], longest_kernel["lines"]) == ("f", 4)


def test_the_widest_parameter_list(tmp_path):
    root = write(
        tmp_path,
        {
            "p/__init__.py": "",
            "p/m.py": """\
            import numba

            def narrow(a, b):
                pass

            class Wide:
                def method(self, a, b, c, /, d, *args, e, f, **kwargs):   # 8: self not counted
                    pass

                @classmethod
                def make(cls, a, b, c):
                    pass

            def seven(a, b, c, d, e, f, g):
                pass

            @numba.njit
            def kernel(a, b, c, d, e, f, g, h, i, j):
                pass
            """,
        },
    )
    widest = analyse(root, run_contract=False)["widest_parameters"]
    assert widest["outside_kernels"]["widest"]["name"] == "Wide.method"
    assert widest["outside_kernels"]["widest"]["parameters"] == 8
    assert [(f["name"], f["parameters"]) for f in widest["outside_kernels"]["top"]] == [
        ("Wide.method", 8),
        ("seven", 7),
        ("Wide.make", 3),
        ("narrow", 2),
    ]
    assert widest["kernels"]["widest"]["name"] == "kernel" and widest["kernels"]["widest"]["parameters"] == 10


def test_the_largest_class_by_lines_and_by_methods(tmp_path):
    root = write(
        tmp_path,
        {
            "c/__init__.py": "",
            "c/m.py": """\
            class Long:
                '''Docs.'''

                x = 1
                y = 2
                z = 3

                def one(self):
                    pass


            class Many:
                def one(self): pass
                def two(self): pass
                def three(self): pass
            """,
        },
    )
    largest = analyse(root, run_contract=False)["largest_class"]
    assert (largest["by_lines"]["name"], largest["by_lines"]["lines"]) == ("Long", 9)
    assert (largest["by_methods"]["name"], largest["by_methods"]["methods"]) == ("Many", 3)
    # Long's code: its header, three assignments, the method's header and its pass (no docstring, no blanks)
    assert (largest["by_code_lines"]["name"], largest["by_code_lines"]["code_lines"]) == ("Long", 6)
    assert [c["code_lines"] for c in largest["top"]] == [6, 4]


def test_code_lines_leave_out_docstrings_blank_and_comment_lines_but_keep_a_multiline_statement():
    from benchmarks.structure import code_lines

    tree = ast.parse(
        textwrap.dedent(
            '''\
            @decorated(
                option=1,
            )
            class Filter:
                """Many
                lines
                of docs."""

                # a comment between statements
                n: int = 3
                """The attribute's docstring."""

                def step(self, a,
                         b):
                    """Docs."""
                    total = (a
                             + b)
                    return total
            '''
        )
    )
    # decorator 3, class header 1, n 1, def header 2, the assignment 2, return 1
    assert code_lines(tree.body[0]) == 10


def test_lines_per_module_package_and_group(tmp_path):
    root = write(
        tmp_path,
        {
            "mcl/__init__.py": "",
            "mcl/filter.py": "a = 1\nb = 2\nc = 3\n",
            "mcl/step.py": "a = 1\nb = 2",  # no final newline: still two lines
            "mcl/relocalization.py": "a = 1\n",
            "field/__init__.py": "x = 1\n",
        },
    )
    lines = analyse(root, run_contract=False)["lines"]
    assert lines["modules"] == {
        "field/__init__.py": 1,
        "mcl/__init__.py": 0,
        "mcl/filter.py": 3,
        "mcl/relocalization.py": 1,
        "mcl/step.py": 2,
    }
    assert lines["packages"] == {"field": 1, "mcl": 6} and lines["total"] == 7
    assert lines["groups"]["core"] == {"members": {"mcl/filter.py": 3, "mcl/step.py": 2}, "missing": [], "lines": 5}
    assert lines["groups"]["soccer"]["lines"] == 1
    given = analyse(root, core=["mcl", "mcl/gone.py"], soccer=[], run_contract=False)["lines"]["groups"]
    assert given["core"]["lines"] == 6 and given["core"]["missing"] == ["mcl/gone.py"]
    assert given["soccer"] == {"members": {}, "missing": [], "lines": 0}


def test_json_output_parses_and_save_writes_the_file(tree, tmp_path, capsys):
    saved = tmp_path / "out" / "deeper" / "structure.json"
    assert main(["--root", str(tree), "--json", "--no-contract", "--save", str(saved)]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["private_imports"]["count"] == 3
    assert printed["revision"]["name"] == "working tree"
    assert json.loads(saved.read_text()) == printed


def test_the_table_names_the_figures(tree, capsys):
    assert main(["--root", str(tree), "--no-contract"]) == 0
    out = capsys.readouterr().out
    assert "private imports      3 across the project's packages; third-party 1, stdlib 1" in out
    assert "alpha/core.py:4: import beta._impl.deep" in out


def git(root: Path, *args: str) -> str:
    return subprocess.run(
        ["git", "-C", str(root), "-c", "user.name=t", "-c", "user.email=t@t", *args],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()


@pytest.fixture
def repo(tmp_path):
    root = write(
        tmp_path / "repo", {"alpha/__init__.py": "", "alpha/m.py": "from beta import _x\n", "beta/__init__.py": ""}
    )
    git(root, "init", "-q")
    git(root, "add", ".")
    git(root, "commit", "-q", "-m", "one")
    return root


def test_rev_measures_the_committed_tree_and_names_it(repo, capsys):
    (repo / "alpha" / "m.py").write_text("from beta import x\n")  # the working tree differs from HEAD
    commit = git(repo, "rev-parse", "HEAD")
    assert main(["--root", str(repo), "--rev", "HEAD", "--json", "--no-contract"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["revision"]["name"] == "HEAD" and report["revision"]["commit"] == commit
    assert commit.startswith(report["revision"]["short"])
    assert report["private_imports"]["list"] == ["alpha/m.py:1: from beta import _x"]
    assert main(["--root", str(repo), "--json", "--no-contract"]) == 0
    working = json.loads(capsys.readouterr().out)
    assert working["private_imports"]["count"] == 0 and working["revision"]["modified"] is True


def test_a_bad_revision_gives_exit_1_and_one_line(repo, capsys):
    assert main(["--root", str(repo), "--rev", "no-such-revision"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == "benchmarks.structure: unknown revision 'no-such-revision'\n"


def test_rev_outside_a_git_checkout_gives_exit_1_and_one_line(tmp_path, capsys):
    assert main(["--root", str(tmp_path), "--rev", "HEAD"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not a git checkout" in err


def test_runs_as_a_module(tree):
    run = subprocess.run(
        [sys.executable, "-m", "benchmarks.structure", "--root", str(tree), "--json", "--no-contract"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["cross_layer"]["count"] == 1


LINT_OUTPUT = """\
---------
Contracts
---------

Analyzed 6 files, 3 dependencies.
---------------------------------

Library does not import demos BROKEN
Layers BROKEN
Independent KEPT

Contracts: 1 kept, 2 broken.


----------------
Broken contracts
----------------

Library does not import demos
-----------------------------

lib is not allowed to import demos:

-   lib.x -> demos.a (l.1)

-   lib.y -> demos.b (l.1)


Layers
------

lib is not allowed to import demos:

- lib.z -> lib.w (l.3)
  lib.w -> demos.a (l.1)

"""


def test_lint_imports_output_is_parsed():
    parsed = parse_lint_imports(LINT_OUTPUT)
    assert parsed == {
        "kept": 1,
        "broken": 2,
        "violations": 3,
        "contracts": [
            {"name": "Library does not import demos", "status": "broken", "violations": 2},
            {"name": "Layers", "status": "broken", "violations": 1},
            {"name": "Independent", "status": "kept", "violations": 0},
        ],
    }
    assert parse_lint_imports("Error: no such package") is None


def test_no_contract_without_the_section(tree):
    contract, reason = structure.import_contract(tree)
    assert contract is None
    assert reason in ("importlinter is not installed", "the tree has no pyproject.toml")


@pytest.mark.skipif(importlib.util.find_spec("importlinter") is None, reason="importlinter is not installed")
def test_import_contract_runs_lint_imports_on_the_analysed_tree(tmp_path):
    """The tree's own packages, not the installed ones of the same name (its `demos` here)."""
    root = write(
        tmp_path,
        {
            "lib/__init__.py": "",
            "lib/x.py": "import demos.a\n",
            "lib/y.py": "",
            "demos/__init__.py": "",
            "demos/a.py": "",
            "pyproject.toml": """\
            [tool.importlinter]
            root_packages = ["lib", "demos"]

            [[tool.importlinter.contracts]]
            name = "Library does not import demos"
            type = "forbidden"
            source_modules = ["lib"]
            forbidden_modules = ["demos"]
            """,
        },
    )
    report = analyse(root)
    assert report["import_contract_reason"] is None
    contract = report["import_contract"]
    assert (contract["kept"], contract["broken"], contract["violations"]) == (0, 1, 1)
    assert not (root / ".import_linter_cache").exists()
