"""The code keeps the project's lint and format rules: ruff, configured once in pyproject.toml ([tool.ruff]),
over the whole tree (the packages, tests, demos, benchmarks and docs' hooks).

`test_format` checks `ruff format --check`: `make format` formats the tree.
"""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytest.importorskip("ruff", reason="ruff is in the test extra: pip install -e '.[test]'")


def ruff(*arguments: str) -> subprocess.CompletedProcess:
    """ruff (the one installed beside this Python) over the project, with the project's configuration."""
    return subprocess.run(
        [sys.executable, "-m", "ruff", *arguments], cwd=ROOT, capture_output=True, text=True, timeout=600
    )


def test_the_configuration_is_in_pyproject_only():
    assert not (ROOT / "ruff.toml").exists() and not (ROOT / ".ruff.toml").exists()
    assert "[tool.ruff]" in (ROOT / "pyproject.toml").read_text()


def test_ruff_check_finds_nothing():
    done = ruff("check", "--output-format", "concise", "--no-cache", ".")
    assert done.returncode == 0, done.stdout[-6000:] + done.stderr[-2000:]


def test_ruff_check_reads_the_configuration(tmp_path):
    # an unused import (pyflakes), imports out of order (isort) and an old-style annotation (Python 3.10's
    # idioms): all found with the project's rules
    probe = tmp_path / "probe.py"
    probe.write_text(
        "import sys\nimport os\nfrom typing import Optional\n\n\n"
        "def f(x: Optional[int]) -> None:\n    print(sys.argv, x)\n",
        encoding="utf-8",
    )
    done = ruff(
        "check", "--output-format", "concise", "--no-cache", "--config", str(ROOT / "pyproject.toml"), str(probe)
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert all(rule in done.stdout for rule in ("F401", "I001", "UP0")), done.stdout  # UP007 or UP045


def test_format():
    done = ruff("format", "--check", "--no-cache", ".")
    assert done.returncode == 0, done.stdout[-6000:] + done.stderr[-2000:]
