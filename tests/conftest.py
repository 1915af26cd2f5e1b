"""Shared test settings: hypothesis profiles, stale numba caches, parallel workers, and small fixtures.

"ci" (the default) draws the same 60 examples per property on every run, so a red CI always means a
change did it; "thorough" (HYPOTHESIS_PROFILE=thorough) draws 1 000 fresh ones to explore.

Before any test runs a kernel, `mcl.numba_cache.guard_source_checkout` drops the project's cached kernels if a
source file changed since the last run (numba keys a cached kernel by its own file only: a kernel whose callee
in another file changed would load its old machine code, and the tests would test the code before the change).
With parallel workers (`pytest -n 2`, as `make test` runs) only the controller does this, once, before the
workers start.

Parallel workers share the project's numba cache. Every process of the session takes numba's cache entries
under a lock (`mcl.numba_cache.serialize_cache_access`), and before the workers start the controller compiles
every kernel family once into that cache (tests/kernel_exercise.py, in two lanes side by side, one per core),
so that the workers load those kernels instead of each compiling them. The exercise's reports are kept for
tests/test_numba_cache.py (in the directory named by MCL_KERNEL_WARMUP), which checks them instead of compiling
everything a second time when the warm-up started from an empty cache (a fresh clone, or sources changed since
the last run). MCL_KERNEL_WARMUP=0 skips the warm-up (each worker then compiles what it needs).
"""

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from mcl.numba_cache import PACKAGES, guard_source_checkout, serialize_cache_access

ROOT = Path(__file__).resolve().parent.parent
WARMUP_VARIABLE = "MCL_KERNEL_WARMUP"
WARMUP_PARTS = ("filter", "sensors,models,extension")  # about equal compile times, no kernel in both

settings.register_profile(
    "ci", max_examples=60, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile("thorough", max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

serialize_cache_access()
if "PYTEST_XDIST_WORKER" not in os.environ:  # a worker: the controller has guarded the caches
    guard_source_checkout()


def _controller_of_workers(config) -> bool:
    """Whether this process is the controller of parallel workers (pytest-xdist's -n with at least one)."""
    return (
        not hasattr(config, "workerinput")
        and getattr(config.option, "dist", "no") != "no"
        and bool(getattr(config.option, "numprocesses", 0))
    )


RAY_SKIP = (
    "starts Ray, which listens on every network interface: run only in a loopback-only network namespace "
    "(make test makes one where it can, tests/loopback_only.sh)"
)


def pytest_collection_modifyitems(config, items):
    """Tests marked `ray` skip unless the session's network namespace has no interface but the loopback."""
    from mcl.tools.ros.bench import loopback_only

    if loopback_only():
        return
    for item in items:
        if item.get_closest_marker("ray") is not None:
            item.add_marker(pytest.mark.skip(reason=RAY_SKIP))


def pytest_configure(config):
    """The controller compiles the kernels once into the shared cache before its workers start (see the module
    docstring); each part's exit code, output and time go to a directory the workers find in MCL_KERNEL_WARMUP."""
    config.addinivalue_line("markers", f"ray: {RAY_SKIP}")
    if not _controller_of_workers(config) or os.environ.get(WARMUP_VARIABLE) == "0":
        return
    folder = Path(tempfile.mkdtemp(prefix="mcl-kernel-warmup-"))
    started = time.time()
    # an empty cache (a fresh clone, or one whose sources changed): the exercise compiles every kernel from
    # nothing, which tests/test_numba_cache.py can then check instead of compiling everything once more
    empty = not os.environ.get("NUMBA_CACHE_DIR") and not any(
        True for package in PACKAGES for _ in (ROOT / package).rglob("*.nbi")
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    env.pop(WARMUP_VARIABLE, None)
    processes = {
        part: subprocess.Popen(
            [sys.executable, str(ROOT / "tests" / "kernel_exercise.py"), part],
            cwd=ROOT,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for part in WARMUP_PARTS
    }
    for part, process in processes.items():
        try:
            stdout, stderr = process.communicate(timeout=900)
        except subprocess.TimeoutExpired:
            process.kill()
            stdout, stderr = process.communicate()
        warmup_report(folder, part).write_text(
            json.dumps({"returncode": process.returncode, "stdout": stdout, "stderr": stderr[-20_000:]})
        )
    seconds = time.time() - started
    (folder / "session.json").write_text(json.dumps({"started": started, "seconds": seconds, "empty": empty}))
    os.environ[WARMUP_VARIABLE] = str(folder)  # inherited by the workers, started after this hook
    config._mcl_kernel_warmup = (folder, seconds)


def warmup_report(folder: Path, part: str) -> Path:
    """Where the warm-up keeps a part's report (exit code, output and time) in `folder`."""
    return folder / f"{part.replace(',', '+')}.json"


def pytest_unconfigure(config):
    warmup = getattr(config, "_mcl_kernel_warmup", None)
    if warmup is not None:
        shutil.rmtree(warmup[0], ignore_errors=True)
        os.environ.pop(WARMUP_VARIABLE, None)


@pytest.fixture(scope="session")
def spl_field():
    from field import spl

    return spl()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def pytest_sessionfinish(session):
    """A worker hands the fuzz suite's table (when test_fuzz ran in it) to the controller, which prints it."""
    report = getattr(sys.modules.get("test_fuzz"), "REPORT", None)
    if report and hasattr(session.config, "workeroutput"):
        session.config.workeroutput["fuzz_report"] = list(report)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    report = getattr(node, "workeroutput", {}).get("fuzz_report")
    if report:
        node.config._mcl_fuzz_report = report


def pytest_terminal_summary(terminalreporter, config):
    """The kernel warm-up's time (parallel runs), and the fuzz suite's counts per target when tests/test_fuzz.py
    ran in this process (its table, as the runner printed it)."""
    warmup = getattr(config, "_mcl_kernel_warmup", None)
    if warmup is not None:
        terminalreporter.write_line(
            f"kernels compiled (or loaded) for the workers in {warmup[1]:.0f} s before "
            f"they started ({', '.join(WARMUP_PARTS)} side by side)"
        )
    report = getattr(sys.modules.get("test_fuzz"), "REPORT", None) or getattr(config, "_mcl_fuzz_report", None)
    if report:
        terminalreporter.write_sep("-", "fuzz suite (CI profile)")
        for line in report:
            terminalreporter.write_line(line)
