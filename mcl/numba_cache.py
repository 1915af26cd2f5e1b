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

The first run. `warm_up` compiles a command's kernels before it measures anything, in groups (`filter_stages`
for a filter), and says so on stderr when numba's cache does not hold them for this machine (`kernels_cached`,
asked of a few kernels such as `filter_kernels(pf)`), with a progress bar over the groups and the time apart
("compiled in 41 s"). numba keeps its cache beside the sources (`__pycache__`), or under NUMBA_CACHE_DIR when
that is set; the staleness check above looks beside the sources only.

Processes side by side. numba's cache is not safe for two processes that save the same kernel at once: each
reads the kernel's index, picks the first free data file number, writes the index and then the data, so two
signatures saved together can end up with one process's index pointing at the other's machine code (a wrong
kernel loaded later, or a crash). `serialize_cache_access` puts a file lock around numba's index-and-data
save and load, so that processes sharing a cache (the test suite's parallel workers) see it whole.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("field", "numerics", "motion_models", "sensing", "proprioception", "mcl", "demos", "benchmarks")
"""The project's packages that hold cached kernels (tests/test_numba_cache.py checks that none is missing)."""
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


def serialize_cache_access() -> bool:
    """Make this process take a lock on a kernel's cache directory while it saves (exclusive) or loads (shared)
    an entry of numba's cache, so that processes compiling the same kernels side by side never interleave an
    index and its data (see the module docstring). Idempotent; returns whether the lock is in place (False
    where there is no `fcntl`, or numba's cache is laid out differently: then nothing changes).

    The lock is `flock` on the cache directory itself, held for the few milliseconds of a save or a load;
    a directory that does not exist yet (nothing to load) is not locked."""
    try:
        import fcntl
        import functools
        import os

        from numba.core.caching import IndexDataCacheFile
    except ImportError:
        return False
    if getattr(IndexDataCacheFile, "_serialized_by_robocup_mcl", False):
        return True
    if not all(hasattr(IndexDataCacheFile, name) for name in ("save", "load", "_load_index")):
        return False

    def locked(method, mode):
        @functools.wraps(method)
        def call(self, *args, **kwargs):
            try:
                directory = os.open(self._cache_path, os.O_RDONLY)
            except (AttributeError, OSError):
                return method(self, *args, **kwargs)
            try:
                fcntl.flock(directory, mode)
                return method(self, *args, **kwargs)
            finally:
                os.close(directory)  # closing it releases the lock

        return call

    IndexDataCacheFile.save = locked(IndexDataCacheFile.save, fcntl.LOCK_EX)
    IndexDataCacheFile.load = locked(IndexDataCacheFile.load, fcntl.LOCK_SH)
    IndexDataCacheFile._serialized_by_robocup_mcl = True
    return True


# The first run. numba compiles a kernel the first time it is called with given argument types and saves the
# machine code in its cache; a later process loads it (in about a second for the whole filter). A command
# therefore warms its kernels up before its measured loop (`warm_up`), so that a step time never counts the
# compilation: when the kernels are not yet cached for this machine it says so on stderr before compiling,
# shows which group of kernels is compiling (a progress bar, when bars are on), and reports the time apart.

FIRST_RUN_MESSAGE = (
    "compiling the filter's kernels once for this machine (a minute or more on a busy "
    "machine); later runs start at once"
)


def kernel_cached(dispatcher) -> bool | None:
    """Whether numba's cache holds machine code of the kernel `dispatcher` (a `numba.njit(cache=True)`
    function) for this machine and its current source: True or False, None when it cannot tell (no cache, or a
    numba whose cache is laid out differently).

    A cache index whose source stamp is stale (the kernel's file changed) counts as empty, as numba counts it;
    an entry for another CPU (a cache directory shared between machines) does not count."""
    try:
        from numba.core.registry import cpu_target

        cache = getattr(dispatcher, "_cache", None)
        index = getattr(cache, "_cache_file", None)
        if index is None:
            return None
        overloads = index._load_index()
        machine = cpu_target.target_context.codegen().magic_tuple()
        return any(isinstance(key, tuple) and len(key) > 1 and key[1] == machine for key in overloads)
    except Exception:  # noqa: BLE001 - numba's private layout changed: cannot tell, never an error
        return None


def kernels_cached(dispatchers) -> bool | None:
    """False when any of `dispatchers` is not cached for this machine (see `kernel_cached`), True when all
    are, None when it cannot tell for some and none is known to be missing."""
    states = [kernel_cached(dispatcher) for dispatcher in dispatchers]
    if False in states:
        return False
    return None if None in states or not states else True


def filter_kernels(pf) -> list:
    """The compiled kernels a `ParticleFilter` step runs first: the motion kernel, the fused step for its
    sensor model (when the model offers its compiled likelihood), the injection's resampling and the summary.
    What `first_run` asks the cache about: when these are cached, the rest of a run is too."""
    from motion_models.kernels import move_range

    from .contracts import fused_kernels
    from .estimate import summary_fill
    from .step import fused_step, resample_and_summarize

    kernels = [move_range, resample_and_summarize, summary_fill]
    sensor = fused_kernels(pf.sensor_model)
    if sensor is not None:
        kernels.append(fused_step(sensor).compiled_step)
    return kernels


def filter_stages(pf, u, observations) -> list[tuple[str, object]]:
    """The warm-up of a `ParticleFilter` `pf` in groups, as (label, call) pairs for `warm_up`: predict by the
    motion input `u`, correct with `observations` (the likelihood, the weights, resampling and injection), the
    estimate and the entropy, and the fused step. `pf` should be a throw-away filter (a few particles, its own
    seed) built like the one to be measured: the warm-up moves it and draws from its generator."""

    def correct():
        pf.correct(observations)
        pf.correct(observations)  # the second correction runs with the entropy asked for, as a loop does

    return [
        ("motion model", lambda: pf.predict(u)),
        ("sensor model, weights and resampling", correct),
        ("estimate and entropy", lambda: (pf.estimate(), pf.entropy())),
        ("fused step", lambda: pf.step(u, observations)),
    ]


class WarmUp:
    """What `warm_up` did: `seconds` it took, whether the kernels were `cached` before (True, False, or None
    when numba's cache could not tell), and `compiled`: whether it announced a compilation."""

    def __init__(self, seconds: float, cached: bool | None) -> None:
        self.seconds = seconds
        self.cached = cached

    @property
    def compiled(self) -> bool:
        return self.cached is False

    def as_dict(self) -> dict:
        """The figures for a command's --json output: compile_seconds (the warm-up's time: compiling, or
        loading the cached kernels) and kernels_cached."""
        return {"compile_seconds": self.seconds, "kernels_cached": self.cached}

    def summary(self) -> str:
        """One line for the command's report: "compiled in 41 s" or "kernels loaded from the cache in 0.8 s"."""
        if self.compiled:
            return f"compiled in {self.seconds:.0f} s"
        return f"kernels loaded from the cache in {self.seconds:.1f} s"


def first_run_decision(cached: bool | None, quiet: bool = False) -> tuple[bool, bool]:
    """(announce, expect_compiling) for kernels whose cache state is `cached` (see `kernels_cached`):
    announce the first-run message unless the kernels are known to be cached (or `quiet`); a state numba cannot
    tell is treated as compiling without the message (no false promise of a slow first run)."""
    compiling = cached is not True
    return cached is False and not quiet, compiling


def warm_up(stages, dispatchers=(), progress: bool = False, quiet: bool = False, stream=None) -> WarmUp:
    """Call each of `stages` ((label, call) pairs, e.g. `filter_stages`) once, so that the kernels they reach are
    compiled or loaded from the cache before anything is measured; returns a `WarmUp`.

    dispatchers: the kernels whose cache state decides (see `kernels_cached`; e.g. `filter_kernels(pf)`). When
    they are not cached, the first-run message goes to `stream` (stderr) first, unless `quiet`, and then "compiled
    in N s" after the last stage. progress: a bar over the stages on `stream`, its clock ticking while a group
    compiles (shown only when compiling: loading cached kernels takes about a second)."""
    import sys
    import threading
    import time

    stream = sys.stderr if stream is None else stream
    cached = kernels_cached(dispatchers) if dispatchers else None
    announce, compiling = first_run_decision(cached, quiet)
    if announce:
        print(f"robocup-mcl: {FIRST_RUN_MESSAGE}", file=stream, flush=True)
    stages = list(stages)
    bar = _stage_bar(len(stages), stream) if progress and compiling else None
    ticking = threading.Event()
    ticker = None
    if bar is not None:

        def tick():
            while not ticking.wait(1.0):
                bar.refresh()

        ticker = threading.Thread(target=tick, name="robocup-mcl compile clock", daemon=True)
        ticker.start()
    started = time.perf_counter()
    try:
        for label, call in stages:
            if bar is not None:
                bar.set_description_str(label, refresh=True)
            call()
            if bar is not None:
                bar.update(1)
    finally:
        seconds = time.perf_counter() - started
        ticking.set()
        if ticker is not None:
            ticker.join()
        if bar is not None:
            bar.close()
    result = WarmUp(seconds, cached)
    if announce:
        print(f"robocup-mcl: {result.summary()}", file=stream, flush=True)
    return result


def _stage_bar(total: int, stream):
    """A tqdm bar over the warm-up's groups (None without tqdm)."""
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(
        total=total,
        desc="",
        unit="group",
        file=stream,
        leave=False,
        dynamic_ncols=True,
        bar_format="compiling: {n}/{total} groups |{bar:20}| {elapsed} {desc}",
    )
