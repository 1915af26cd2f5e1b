"""Stale numba caches in a source checkout.

numba keys a cached kernel by its own source file's time stamp and size only. After an edit to a callee in
another file, the caller would load its old machine code: a demo, a benchmark or a test would run the code
before the edit. So in a source checkout (a clone, or an editable install of one) the command line and the
tests call `forget_stale_numba_caches` before any kernel runs: when a source file of the project has changed
since the last call (their stamps against `.numba-sources`, which it writes), it drops every cached kernel of
the project, and the run compiles them again (about a minute). A clone's first run writes the stamp; the
runs after it find the caches it left, so `make demo` then `make test` compiles once.

An installed copy does not need this (installing writes every file anew) and is left alone: the checkout is
recognized by the project's `pyproject.toml` beside the packages.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("field", "numerics", "motion_models", "sensing", "mcl", "demos", "benchmarks")
SOURCES_STAMP = ".numba-sources"


def forget_stale_numba_caches(root: Path = ROOT, stamp: Path | None = None) -> bool:
    """Remove the project's cached kernels (*.nbi, *.nbc under `root`'s packages) when a source file changed
    since `stamp` (default: root/.numba-sources) was written, and write it; returns whether they were removed."""
    stamp = root / SOURCES_STAMP if stamp is None else stamp
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


def is_source_checkout(root: Path = ROOT) -> bool:
    """Whether `root` is this project's source tree (its pyproject.toml names robocup-mcl)."""
    try:
        return 'name = "robocup-mcl"' in (root / "pyproject.toml").read_text()
    except OSError:
        return False


def guard_source_checkout(root: Path = ROOT) -> bool:
    """`forget_stale_numba_caches` when running from a source checkout (nothing otherwise, nor when the tree
    is read-only); returns whether cached kernels were dropped."""
    if not is_source_checkout(root):
        return False
    try:
        return forget_stale_numba_caches(root)
    except OSError:
        return False
