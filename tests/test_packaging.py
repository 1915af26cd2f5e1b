"""What the package promises about its surroundings: the Python versions it runs on (`requires-python`, checked
with vermin over the library's source) and an `import mcl` that stays light (no Rerun, MCAP, Hypothesis,
matplotlib or scipy submodule loaded until a feature needs it)."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LIBRARY = ("mcl", "motion_models", "sensing", "field", "numerics")
MINIMUM = "3.10"

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib


def test_requires_python_is_the_minimum_vermin_checks():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert project["requires-python"] == f">={MINIMUM}"
    assert f"Programming Language :: Python :: {MINIMUM}" in project["classifiers"]


def test_the_library_needs_no_feature_newer_than_the_minimum():
    pytest.importorskip("vermin", reason="vermin is in the test extra: pip install -e '.[test]'")
    # vermin runs as its console script (the package has no __main__), installed beside this interpreter
    vermin = shutil.which("vermin", path=str(Path(sys.executable).parent)) or shutil.which("vermin")
    assert vermin, "vermin is importable but its command is not on PATH"
    done = subprocess.run(
        [vermin, f"--target={MINIMUM}-", "--no-tips", "--violations", "--eval-annotations", *LIBRARY],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stdout + done.stderr


# Loaded by `import numba` itself (its scipy version check imports the top package and private helpers only);
# a public scipy subpackage (scipy.linalg, scipy.ndimage, ...) in sys.modules means the library imported it.
PROBE = """
import json, sys, time
start = time.perf_counter()
import {module}
seconds = time.perf_counter() - start
heavy = sorted({{name.split(".")[0] for name in sys.modules
                 if name.split(".")[0] in ("rerun", "mcap", "mcap_ros2", "hypothesis", "matplotlib", "tqdm")}}
               | {{name for name in sys.modules if name.startswith("scipy.") and not name.split(".")[1].startswith("_")
                  and name.split(".")[1] not in ("version", "__config__")}})
print(json.dumps({{"heavy": heavy, "seconds": seconds}}))
"""


def probe(module: str) -> dict:
    done = subprocess.run(
        [sys.executable, "-c", PROBE.format(module=module)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    return json.loads(done.stdout.splitlines()[-1])


@pytest.mark.parametrize("module", ["mcl", "motion_models", "sensing", "field"])
def test_importing_the_library_loads_no_heavy_package(module):
    assert probe(module)["heavy"] == []


def test_the_probe_sees_a_heavy_import():
    # the check above can fail: a module that imports scipy.ndimage at load time is caught
    assert "scipy.ndimage" in probe("scipy.ndimage")["heavy"]
