"""Every cached numba kernel of the project really is cached: no "Cannot cache" warning, and a second process
loads every kernel from the cache instead of compiling it.

A kernel that numba cannot cache (it uses lifted code, or dynamic globals such as a large global array)
compiles again in every process; numba says so only with a NumbaWarning. Here fresh processes with an empty
NUMBA_CACHE_DIR import every project module and call every kernel family once through its public entry
points, with that warning turned into an error; then the test checks that every public
`@numba.njit(cache=True)` kernel (and every private one those calls reach) was compiled and saved its cache
index. A further process with the same cache repeats all the calls and checks that nothing was compiled.
A new public kernel that the calls do not reach fails the test with its name: add a call that reaches it to
tests/kernel_exercise.py. Compiling everything takes a while, so the calls come in two parts that compile side
by side (the filter with its motion and sensor models; LWPR, the velocity EKF and the leg kinematics), one
process each. In a parallel session (`make test`) that starts from an empty cache (a fresh clone) the controller
has already run both parts against the cache its workers share (tests/conftest.py); the test checks their
reports, and runs the second process against that cache, instead of compiling everything once more. In a
parallel session whose cache held kernels already (the sources unchanged since it was filled: `make demo`
before `make test`), the second process alone runs against it; what no call reaches is then left to the next
session that starts empty (CI's fresh clone, or any change of a source file, which drops the cache).
"""

import json
import os
import subprocess
import sys
from pathlib import Path

from conftest import WARMUP_PARTS, warmup_report

ROOT = Path(__file__).resolve().parents[1]

EXERCISE = Path(__file__).resolve().parent / "kernel_exercise.py"


def _start(part: str, cache_dir: Path | None) -> subprocess.Popen:
    """The exercise's `part` in a fresh process, with `cache_dir` as NUMBA_CACHE_DIR (None: the cache as the
    session has it, the project's own unless NUMBA_CACHE_DIR is set)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = str(cache_dir)
    return subprocess.Popen(
        [sys.executable, str(EXERCISE), part],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _report(process: subprocess.Popen) -> dict:
    stdout, stderr = process.communicate(timeout=600)
    return _checked(process.returncode, stdout, stderr)


def _checked(returncode: int, stdout: str, stderr: str) -> dict:
    assert "Cannot cache" not in stderr, stderr[-3000:]
    assert returncode == 0, stderr[-3000:]
    return json.loads(stdout.strip().splitlines()[-1])


def _session() -> dict | None:
    """What the session's controller wrote of its warm-up (tests/conftest.py): when it started, how long it took,
    and whether the cache was empty; None when it ran none."""
    folder = os.environ.get("MCL_KERNEL_WARMUP")
    if not folder or folder == "0" or not (Path(folder) / "session.json").exists():
        return None
    return {"folder": Path(folder), **json.loads((Path(folder) / "session.json").read_text())}


def _session_warmup() -> tuple[list[dict], float] | None:
    """The reports of the parts the session's controller ran before its parallel workers started, against an
    empty cache, the one the workers share (tests/conftest.py), and when it started them; None when it did not
    run them, or the cache held kernels already (a kernel loaded with its callees leaves them uncompiled)."""
    session = _session()
    if session is None or not session["empty"]:
        return None
    parts = [json.loads(warmup_report(session["folder"], lane).read_text()) for lane in WARMUP_PARTS]
    return [_checked(part["returncode"], part["stdout"], part["stderr"]) for part in parts], session["started"]


def _sources() -> dict[str, float]:
    """Modification time of every project module, by module name."""
    times = {}
    for package in ("field", "numerics", "sensing", "motion_models", "mcl", "demos", "benchmarks"):
        for path in (ROOT / package).rglob("*.py"):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            times[module.removesuffix(".__init__")] = path.stat().st_mtime
    return times


def _warm_session() -> bool:
    """Whether the session's controller ran the parts against a cache that already held kernels (a tree tested
    or run before, whose sources did not change since: `make demo` then `make test` on a fresh clone)."""
    session = _session()
    return session is not None and not session["empty"]


def test_every_kernel_is_cached_and_found_again(tmp_path):
    # In a parallel session whose cache was empty, the controller has run both parts already, against the cache
    # the workers share: their reports are checked here, and the second process runs against that cache.
    # In a parallel session whose cache held kernels already, the controller's parts have filled it: one process
    # repeats every call against it and must compile nothing, and save every index (what no call reaches is
    # checked where the cache starts empty: a fresh clone, as CI's, or any change of a source file, which drops
    # the cache). Otherwise both parts run here against an empty cache of the test's own.
    if _warm_session():
        before = _sources()
        again = _report(_start("all", None))
        assert again["no_index"] == [], f"compiled but no cache index written: {again['no_index']}"
        edited = {module for module, stamp in _sources().items() if before.get(module) != stamp}
        misses = {k: n for k, n in again["cache_misses"].items() if k.rsplit(".", 1)[0] not in edited}
        assert misses == {}, f"compiled again although cached: {misses}"
        return
    warmup = _session_warmup()
    if warmup is None:
        before, cache = _sources(), tmp_path
        parts = [_start(lane, cache) for lane in WARMUP_PARTS]  # the exercise's lanes side by side: two cores
        reports = [_report(process) for process in parts]
    else:
        reports, started = warmup
        before = {module: stamp for module, stamp in _sources().items() if stamp < started}
        cache = None
    kernels = set(reports[0]["kernels"])
    assert len(kernels) > 20
    compiled = set().union(*(set(r["compiled"]) for r in reports))
    inlined = set(reports[0]["inlined"])
    public = {label for label in kernels if not label.rsplit(".", 1)[1].startswith("_")}
    # A private kernel no public call reaches never compiles in a run (dead code, or on its way in or out).
    missing = sorted(public - compiled - inlined)
    assert missing == [], f"cached kernels no call in EXERCISE reaches (add one): {missing}"
    no_index = sorted(set().union(*(set(r["no_index"]) for r in reports)))
    assert no_index == [], f"compiled but no cache index written: {no_index}"
    again = _report(_start("all", cache))
    # A module edited while the test ran has a stale cache by right (numba keys the cache on the source file).
    after = _sources()
    edited = {module for module, stamp in after.items() if before.get(module) != stamp}
    misses = {label: count for label, count in again["cache_misses"].items() if label.rsplit(".", 1)[0] not in edited}
    assert misses == {}, f"compiled again although cached: {misses}"


def test_a_changed_source_file_drops_the_cached_kernels(tmp_path):
    """`mcl.numba_cache.forget_stale_numba_caches`: numba would load a kernel's old machine code when only a
    callee in another file changed, so any change to a source file drops every cached kernel (and nothing
    else)."""
    from mcl.numba_cache import PACKAGES, forget_stale_numba_caches

    for package in PACKAGES:
        (tmp_path / package / "__pycache__").mkdir(parents=True)
        (tmp_path / package / "kernels.py").write_text("x = 1\n")
    cached = [tmp_path / "mcl" / "__pycache__" / name for name in ("step-12.py311.nbi", "step-12.py311.0.nbc")]
    kept = tmp_path / "mcl" / "__pycache__" / "kernels.cpython-311.pyc"
    stamp = tmp_path / ".numba-sources"

    def cache():
        for path in (*cached, kept):
            path.write_bytes(b"cached")

    cache()
    assert forget_stale_numba_caches(tmp_path, stamp)  # no stamp yet: dropped
    assert not any(path.exists() for path in cached) and kept.exists() and stamp.exists()
    cache()
    assert not forget_stale_numba_caches(tmp_path, stamp)  # nothing changed: kept
    assert all(path.exists() for path in cached)
    (tmp_path / "sensing" / "kernels.py").write_text("x = 22\n")  # a callee in another package changed
    assert forget_stale_numba_caches(tmp_path, stamp)
    assert not any(path.exists() for path in cached) and kept.exists()


def test_only_a_source_checkout_is_guarded(tmp_path):
    """`guard_source_checkout` drops stale caches in the project's own tree, and leaves an installed copy (no
    pyproject.toml of the project beside the packages) alone."""
    from mcl.numba_cache import PACKAGES, SOURCES_STAMP, guard_source_checkout

    for package in PACKAGES:
        (tmp_path / package / "__pycache__").mkdir(parents=True)
        (tmp_path / package / "kernels.py").write_text("x = 1\n")
    cached = tmp_path / "field" / "__pycache__" / "kernel-3.py311.nbi"
    cached.write_bytes(b"cached")
    assert not guard_source_checkout(tmp_path)  # an installed copy: left alone
    assert cached.exists() and not (tmp_path / SOURCES_STAMP).exists()
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "another-project"\n')
    assert not guard_source_checkout(tmp_path) and cached.exists()
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "robocup-mcl"\n')
    assert guard_source_checkout(tmp_path)  # the project's tree, no stamp yet
    assert not cached.exists() and (tmp_path / SOURCES_STAMP).exists()
    cached.write_bytes(b"cached")
    assert not guard_source_checkout(tmp_path) and cached.exists()  # nothing changed since


def test_the_command_line_guards_the_caches_before_running_anything(monkeypatch):
    """`robocup-mcl` calls the guard first, so that a demo or a benchmark run from a checkout after an edit runs
    the edited kernels."""
    import mcl.tools.cli

    calls = []
    monkeypatch.setattr(mcl.tools.cli, "guard_source_checkout", lambda: calls.append("guard"))
    assert mcl.tools.cli.main(["--help"]) == 0
    assert calls == ["guard"]


SAVES = 200
SAVER = r"""
import sys
from pathlib import Path

from numba.core.caching import IndexDataCacheFile

from mcl.numba_cache import serialize_cache_access

folder, name, lock = Path(sys.argv[1]), sys.argv[2], sys.argv[3] == "lock"
if lock:
    assert serialize_cache_access()
cache = IndexDataCacheFile(cache_path=str(folder), filename_base="kernel-1.py311", source_stamp=("stamp", 1))
(folder / f"ready-{name}").touch()
while not (folder / "go").exists():           # both start saving together
    pass
for i in range(SAVES):
    cache.save((name, i), {"key": (name, i)})
""".replace("SAVES", str(SAVES))


def test_processes_saving_one_kernel_side_by_side_keep_its_index_whole(tmp_path):
    """numba saves a cache entry as: read the kernel's index, pick the first free data file, write the index, write
    the data. Two processes doing that at once (parallel test workers compiling one kernel) can lose each other's
    entries or pair a key with the other's data; under `serialize_cache_access` every entry saved is in the index
    and holds its own data."""
    from numba.core.caching import IndexDataCacheFile

    savers = [
        subprocess.Popen(
            [sys.executable, "-c", SAVER, str(tmp_path), name, "lock"],
            cwd=ROOT,
            env=dict(os.environ, PYTHONPATH=str(ROOT)),
            stderr=subprocess.PIPE,
            text=True,
        )
        for name in ("a", "b")
    ]
    while not all((tmp_path / f"ready-{name}").exists() for name in ("a", "b")):
        assert all(saver.poll() is None for saver in savers), [saver.stderr.read() for saver in savers]
    (tmp_path / "go").touch()
    for saver in savers:
        assert saver.wait(timeout=300) == 0, saver.stderr.read()
    cache = IndexDataCacheFile(cache_path=str(tmp_path), filename_base="kernel-1.py311", source_stamp=("stamp", 1))
    keys = [(name, i) for name in ("a", "b") for i in range(SAVES)]
    assert sorted(cache._load_index()) == sorted(keys)
    assert all(cache.load(key) == {"key": key} for key in keys)


def test_the_cache_lock_is_taken_on_the_cache_directory(tmp_path, monkeypatch):
    import fcntl

    from numba.core.caching import IndexDataCacheFile

    from mcl.numba_cache import serialize_cache_access

    assert serialize_cache_access() and serialize_cache_access()  # in place, and only once
    assert not hasattr(IndexDataCacheFile.save.__wrapped__, "__wrapped__")
    taken = []
    real_flock = fcntl.flock
    monkeypatch.setattr(
        fcntl,
        "flock",
        lambda fd, mode: (taken.append((os.readlink(f"/proc/self/fd/{fd}"), mode)), real_flock(fd, mode))[1],
    )
    cache = IndexDataCacheFile(cache_path=str(tmp_path), filename_base="kernel-1.py311", source_stamp=("stamp", 1))
    cache.save(("sig",), {"data": 1})
    assert cache.load(("sig",)) == {"data": 1}
    assert taken == [(str(tmp_path), fcntl.LOCK_EX), (str(tmp_path), fcntl.LOCK_SH)]


def test_every_package_with_cached_kernels_is_guarded():
    """The staleness guard and the kernel exercise cover every package of the project that caches a kernel: a
    package left out of `mcl.numba_cache.PACKAGES` would keep its callers' old machine code after an edit, and
    its kernels would go unchecked by the test above."""
    from mcl.numba_cache import PACKAGES, ROOT

    packages = [folder for folder in ROOT.iterdir() if (folder / "__init__.py").exists() and folder.name != "tests"]
    caching = {
        folder.name
        for folder in packages
        if any("cache=True" in path.read_text(encoding="utf-8") for path in folder.rglob("*.py"))
    }
    assert "proprioception" in caching and "mcl" in caching
    assert caching <= set(PACKAGES), f"packages with cached kernels missing from PACKAGES: {caching - set(PACKAGES)}"
