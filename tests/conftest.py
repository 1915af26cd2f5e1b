"""Shared test settings: hypothesis profiles, stale numba caches, and small fixtures.

"ci" (the default) draws the same 60 examples per property on every run, so a red CI always means a
change did it; "thorough" (HYPOTHESIS_PROFILE=thorough) draws 1 000 fresh ones to explore.

Before any test runs a kernel, `mcl.numba_cache.guard_source_checkout` drops the project's cached kernels if a
source file changed since the last run (numba keys a cached kernel by its own file only: a kernel whose callee
in another file changed would load its old machine code, and the tests would test the code before the change).
"""
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from mcl.numba_cache import guard_source_checkout

settings.register_profile("ci", max_examples=60, deadline=None, derandomize=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("thorough", max_examples=1000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

guard_source_checkout()


@pytest.fixture(scope="session")
def spl_field():
    from field import spl
    return spl()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def pytest_terminal_summary(terminalreporter):
    """The fuzz suite's counts per target, when tests/test_fuzz.py ran (its table, as the runner printed it)."""
    module = __import__("sys").modules.get("test_fuzz")
    report = getattr(module, "REPORT", None)
    if report:
        terminalreporter.write_sep("-", "fuzz suite (CI profile)")
        for line in report:
            terminalreporter.write_line(line)
