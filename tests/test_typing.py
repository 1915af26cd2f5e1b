"""The public API's type hints hold: mypy (configured in pyproject.toml, [tool.mypy]) checks the library's
packages without a single error, and it reads the hints (a call with the wrong types is an error).
"""

import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytest.importorskip("mypy", reason="mypy is in the test extra: pip install -e '.[test]'")


@pytest.fixture(scope="module")
def errors() -> Counter:
    """mypy's errors over the packages of [tool.mypy], counted by file."""
    done = subprocess.run(
        [sys.executable, "-m", "mypy", "--no-error-summary", "--hide-error-context"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode in (0, 1), done.stdout + done.stderr  # 2: mypy itself failed
    return Counter(m.group(1) for m in re.finditer(r"^([\w/]+\.py):\d+: error:", done.stdout, re.MULTILINE))


def test_the_packages_type_check_without_error(errors):
    assert not errors, f"{sum(errors.values())} mypy errors: {dict(errors)}"


def test_mypy_reads_the_hints(tmp_path):
    wrong = tmp_path / "wrong_types.py"
    wrong.write_text(
        "import field\nimport mcl\n\n"
        "pitch: int = field.preset('spl')\n"  # a Field, not an int
        "mcl.Estimate.is_confident(None, 'wide')\n",  # an estimate and a float, not None and a str
        encoding="utf-8",
    )
    done = subprocess.run(
        [sys.executable, "-m", "mypy", "--no-error-summary", str(wrong)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert 'Incompatible types in assignment (expression has type "Field", variable has type "int")' in done.stdout, (
        done.stdout
    )
    assert 'to "is_confident" of "Estimate" has incompatible type' in done.stdout, done.stdout
