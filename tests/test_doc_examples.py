"""Every Python block of the README and of the documentation pages runs as written, and prints what the page
shows.

The conventions of the pages (docs/test-suite.md, "The docs' examples"):

- The Python blocks of one page run in order in one namespace (a module of its own), so a page may build on
  its earlier blocks; each block is a test of its own, named by page and line.
- A ```` ```text ```` block right after a Python block (nothing but blank lines between) is what the block prints:
  compared line by line (trailing spaces aside). Figures whose last digits depend on the CPU are printed
  rounded by the example itself, so the comparison is exact.
- `<!-- not run: REASON -->` on the line before a Python block: the block cannot run here (a robot's own data
  or driver); it is reported as skipped with its reason, and there are few of them
  (`test_the_blocks_not_run_are_few_and_say_why`).
- `<!-- file: NAME -->` on the line before any block: the block is a file the page's examples read; it is
  written as NAME into the page's working directory before the page's first block runs.

The blocks run in a fresh working directory per page that holds those files and a link to the repository's
`results/` (the examples that read a results file name it as from the clone's root). An import under a
module's old name (a DeprecationWarning of `field.moved`) fails the block: the docs use the new names.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import sys
import types
import warnings
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").rglob("*.md"))
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```[ \t]*$", flags=re.M | re.S)
NOT_RUN = re.compile(r"<!-- not run: (.+?) -->\s*$")
FILE = re.compile(r"<!-- file: ([\w./-]+) -->\s*$")
MOST_NOT_RUN = 4


@dataclass
class Block:
    page: Path
    line: int
    code: str
    output: str | None = None  # the ```text block right after it
    not_run: str | None = None  # the reason given by the marker before it

    @property
    def name(self) -> str:
        page = self.page.relative_to(ROOT).as_posix() if self.page.is_relative_to(ROOT) else self.page.name
        return f"{page}:{self.line}"


def _line_before(text: str, position: int) -> str:
    lines = text[:position].rstrip("\n").rsplit("\n", 1)
    return lines[-1] if lines else ""


def parse(page: Path) -> tuple[list[Block], dict[str, str]]:
    """The page's Python blocks, in order, and the files its `<!-- file: -->` markers name."""
    text = page.read_text(encoding="utf-8")
    fences = list(FENCE.finditer(text))
    blocks: list[Block] = []
    files: dict[str, str] = {}
    for i, fence in enumerate(fences):
        before = _line_before(text, fence.start())
        named = FILE.search(before)
        if named:
            files[named.group(1)] = fence.group(2)
        if fence.group(1) != "python":
            continue
        block = Block(page, text.count("\n", 0, fence.start()) + 1, fence.group(2))
        marker = NOT_RUN.search(before)
        block.not_run = marker.group(1).strip() if marker else None
        if i + 1 < len(fences):
            following = fences[i + 1]
            if following.group(1) == "text" and not text[fence.end() : following.start()].strip():
                block.output = following.group(2)
        blocks.append(block)
    return blocks, files


PARSED = {page: parse(page) for page in PAGES}
BLOCKS = [block for blocks, _ in PARSED.values() for block in blocks]


@contextlib.contextmanager
def _cwd(directory: Path):
    before = os.getcwd()
    os.chdir(directory)
    try:
        yield
    finally:
        os.chdir(before)


class PageRun:
    """The blocks of one page run so far, in their module, in the page's working directory."""

    def __init__(self, page: Path, directory: Path) -> None:
        # A module importable by name: numba's cache of a kernel defined on a page names the module, and loads it
        # by that name in later runs. docs/extending.md's is `extending_example`, as tests/test_extending.py has
        # it, so that the two share the cached kernels.
        name = re.sub(r"\W", "_", page.stem) + "_example"
        self.module = sys.modules.setdefault(name, types.ModuleType(name))
        self.module.__file__ = str(page)
        self.directory = directory
        (directory / "results").symlink_to(ROOT / "results", target_is_directory=True)
        for name, content in PARSED[page][1].items():
            (directory / name).parent.mkdir(parents=True, exist_ok=True)
            (directory / name).write_text(content, encoding="utf-8")
        self.ran = 0

    def run(self, block: Block) -> str:
        """What the block prints; an import under an old module name fails it."""
        out = io.StringIO()
        with _cwd(self.directory), contextlib.redirect_stdout(out), warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", DeprecationWarning)
            exec(compile(block.code, str(block.page), "exec"), self.module.__dict__)
        moved = [
            str(w.message)
            for w in caught
            if issubclass(w.category, DeprecationWarning) and " moved to " in str(w.message)
        ]
        assert not moved, f"{block.name} imports an old name: {moved[0]}"
        return out.getvalue()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    made: dict[Path, PageRun] = {}

    def get(page: Path) -> PageRun:
        if page not in made:
            made[page] = PageRun(page, tmp_path_factory.mktemp(page.stem))
        return made[page]

    return get


def _compared(text: str) -> list[str]:
    """The lines, without trailing spaces or leading and trailing blank lines."""
    return [line.rstrip() for line in text.splitlines()] and "\n".join(
        line.rstrip() for line in text.splitlines()
    ).strip("\n").splitlines()


@pytest.mark.parametrize("block", BLOCKS, ids=[block.name for block in BLOCKS])
def test_the_block_runs_and_prints_what_the_page_shows(block, runs):
    if block.not_run:
        pytest.skip(f"not run: {block.not_run}")
    page = runs(block.page)
    blocks = PARSED[block.page][0]
    index = blocks.index(block)
    while page.ran < index:  # the page's earlier blocks first (run alone with -k, say)
        earlier = blocks[page.ran]
        page.ran += 1
        if not earlier.not_run:
            page.run(earlier)
    page.ran = index + 1
    assert_prints(block, page.run(block))


def assert_prints(block: Block, printed: str) -> None:
    """What the block printed is what the page shows after it (when it shows anything)."""
    if block.output is not None:
        assert _compared(printed) == _compared(block.output), (
            f"{block.name} printed\n{printed}\nwhile the page shows\n{block.output}"
        )


def test_the_blocks_not_run_are_few_and_say_why(capsys):
    not_run = [block for block in BLOCKS if block.not_run]
    with capsys.disabled():
        print(
            f"\ndocs' Python blocks: {len(BLOCKS)}, run {len(BLOCKS) - len(not_run)} "
            f"(output compared: {sum(b.output is not None for b in BLOCKS if not b.not_run)}), "
            f"not run {len(not_run)}:"
        )
        for block in not_run:
            print(f"  {block.name}: {block.not_run}")
    assert len(not_run) <= MOST_NOT_RUN
    for block in not_run:
        assert len(block.not_run.split()) >= 3, f"{block.name}: say why it is not run"
        assert block.output is None, f"{block.name} is not run, so what it prints cannot be shown"


def test_every_python_block_of_every_page_is_collected():
    """The parser sees each fenced Python block (none hidden by an indented or odd fence), and each marker
    stands right before the block it speaks of."""
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        assert len(PARSED[page][0]) == len(re.findall(r"^```python\s*$", text, flags=re.M)), page
        assert not re.search(r"^[ \t]+```python", text, flags=re.M), f"{page}: an indented Python block is not run"
        for marker in re.finditer(r"<!-- (?:not run|file):[^\n]*-->\s*\n(.*)", text):
            assert marker.group(1).startswith("```"), f"{page}: {marker.group(0)!r} is not right before a block"
    assert len(BLOCKS) >= 15 and any(b.page.name == "README.md" for b in BLOCKS)


def test_a_wrong_output_fails(tmp_path):
    """The comparison can fail: a page whose shown output differs from what its block prints."""
    page = tmp_path / "page.md"
    page.write_text("```python\nprint(1 + 1)\n```\n\n```text\n3\n```\n", encoding="utf-8")
    (block,), _ = parse(page)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(block.code, {})
    assert block.output == "3\n" and out.getvalue() == "2\n"
    with pytest.raises(AssertionError, match="while the page shows"):
        assert_prints(block, out.getvalue())
    assert_prints(block, "3\n   \n")
