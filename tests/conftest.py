"""Shared test settings: hypothesis profiles, stale numba caches, and small fixtures.

"ci" (the default) draws the same 60 examples per property on every run, so a red CI always means a
change did it; "thorough" (HYPOTHESIS_PROFILE=thorough) draws 1 000 fresh ones to explore.

numba keys a cached kernel by its own source file's time stamp and size only: a kernel whose callee in another
file changed would load its old machine code, and the tests would test the code before the change. So before
anything imports a kernel, a change to any of the project's source files (their stamps, against the last run's)
drops every cached kernel of the project, and the run compiles them again. (An installed copy does not need
this: installing writes every file anew.)
"""
import hashlib
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

settings.register_profile("ci", max_examples=60, deadline=None, derandomize=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("thorough", max_examples=1000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("field", "sensing", "motion_models", "mcl", "demos")
SOURCES_STAMP = ROOT / ".numba-sources"


def forget_stale_numba_caches(root: Path = ROOT, stamp: Path = SOURCES_STAMP) -> bool:
    """Remove the project's cached kernels (*.nbi, *.nbc) when a source file changed since the stamp was
    written, and write it; returns whether they were removed."""
    digest = hashlib.sha256()
    for path in sorted(p for package in PACKAGES for p in (root / package).rglob("*.py")):
        status = path.stat()
        digest.update(f"{path.relative_to(root)}:{status.st_mtime_ns}:{status.st_size}\n".encode())
    fingerprint = digest.hexdigest()
    if stamp.exists() and stamp.read_text() == fingerprint:
        return False
    for package in PACKAGES:
        for cached in (root / package).rglob("*.nb[ic]"):
            cached.unlink(missing_ok=True)
    stamp.write_text(fingerprint)
    return True


forget_stale_numba_caches()


@pytest.fixture(scope="session")
def spl_field():
    from field import spl
    return spl()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
