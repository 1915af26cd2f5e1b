"""What `robocup-mcl bench` measures in fresh processes, and the description of the machine.

    from benchmarks.system import machine, time_startup, time_demo_walk, numpy_without_avx512, memory

- `machine()`: CPU model, cores, SIMD flags, python/numpy/numba versions, load average.
- `time_startup()`: a fresh process to its first step with an empty numba cache (it compiles every kernel
  the step uses), then one that finds the cache.
- `time_demo_walk()`: wall time of `robocup-mcl demo walk --duration 0.1` (10 steps) with the cache found.
- `numpy_without_avx512()`: the numpy step in a process with numpy's AVX-512 dispatch switched off
  (NPY_DISABLE_CPU_FEATURES), for the numba/numpy ratio without it.
- `memory()`: tracemalloc's view of one step at N = 10⁴ and 10⁵, in a process with numba's allocation
  counters on (NUMBA_NRT_STATS): scratch memory per step, memory kept per step, numba allocations per step.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from importlib import metadata
from pathlib import Path

import numpy as np

SIMD_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512bw", "avx512vl")


# -- the machine -----------------------------------------------------------------------------------------------
def _cpuinfo() -> dict:
    model, flags = None, set()
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return {"model": platform.processor() or platform.machine(), "flags": None}
    for line in text.splitlines():
        key, _, value = line.partition(":")
        key = key.strip()
        if key in ("model name", "Model", "cpu model") and model is None:
            model = value.strip()
        elif key in ("flags", "Features") and not flags:
            flags = set(value.split())
    return {
        "model": model or platform.processor() or platform.machine(),
        "flags": {flag: flag in flags for flag in SIMD_FLAGS} if flags else None,
    }


def numpy_cpu_dispatch() -> tuple[list[str], dict[str, bool]]:
    """numpy's runtime-dispatched CPU features and which features this CPU has, as numpy sees them."""
    try:
        from numpy._core import _multiarray_umath as umath
    except ImportError:  # numpy 1.x
        from numpy.core import _multiarray_umath as umath
    return list(getattr(umath, "__cpu_dispatch__", [])), dict(getattr(umath, "__cpu_features__", {}))


def _version(package: str) -> str | None:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return None


def machine() -> dict:
    import numba

    cpu = _cpuinfo()
    dispatch, features = numpy_cpu_dispatch()
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    return {
        "cpu_model": cpu["model"],
        "cpus": os.cpu_count(),
        "cpus_usable": usable,
        "simd_flags": cpu["flags"],
        "machine": platform.machine(),
        "system": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "llvmlite": _version("llvmlite"),
        "rerun_sdk": _version("rerun-sdk"),
        "numba_threads": numba.config.NUMBA_NUM_THREADS,
        "numba_threading_layer": numba.config.THREADING_LAYER,
        "numpy_cpu_dispatch": dispatch,
        "numpy_cpu_features_on": sorted(k for k, v in features.items() if v),
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        # numba's code-generation target when set (NUMBA_CPU_NAME, NUMBA_CPU_FEATURES), e.g. to time the
        # kernels as compiled for a robot's instruction set on this machine; None: this machine's own
        "numba_cpu_name": numba.config.CPU_NAME,
        "numba_cpu_features": numba.config.CPU_FEATURES,
        # Intel's SVML, which numba uses for vectorized exp, sin, atan2... in fast-math loops: only when the
        # library is installed (intel-cmplr-lib-rt) and llvmlite's LLVM was built with numba's SVML patch
        # (conda's is; PyPI's wheels are not, so a pip install never uses it)
        "numba_svml": bool(numba.config.USING_SVML),
        "llvmlite_svml": _llvmlite_svml(),
    }


def _llvmlite_svml() -> bool | None:
    """Whether llvmlite's LLVM can use SVML (None: this llvmlite cannot say)."""
    try:
        from llvmlite.binding import targets

        return bool(targets.has_svml())
    except (ImportError, AttributeError):
        return None


def load_average() -> list[float] | None:
    return list(os.getloadavg()) if hasattr(os, "getloadavg") else None


# -- fresh processes -------------------------------------------------------------------------------------------
_PROBE = (
    "import time; t = time.perf_counter(); from benchmarks.step import bench_setup; "
    "pf, u, obs = bench_setup(1000); pf.step(u, obs); pf.entropy(); "
    "print(time.perf_counter() - t)"
)


def _run(args: list[str], env: dict, timeout: float = 600.0) -> tuple[float, subprocess.CompletedProcess]:
    start = time.perf_counter()
    done = subprocess.run(args, env=env, capture_output=True, text=True, timeout=timeout)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(args[:3])} ... exited with {done.returncode}: {done.stderr.strip()[-800:]}")
    return elapsed, done


def _cached_run(command: list[str], env: dict) -> tuple[float, int, str]:
    """Wall time of a process, how many kernels it compiled (numba's cache log: each compiled kernel is saved
    to the cache), and its last line of output."""
    elapsed, done = _run(command, dict(env, NUMBA_DEBUG_CACHE="1"))
    lines = done.stdout.strip().splitlines()
    compiled = sum("[cache] data saved" in line for line in lines)
    output = [line for line in lines if not line.startswith("[cache]")]
    return elapsed, compiled, output[-1] if output else ""


def _cache_found(runs: list[tuple[float, int, str]]) -> tuple[list[tuple[float, int, str]], str]:
    """The runs that compiled nothing (they found every kernel in the cache); all runs, with a note, if none."""
    clean = [run for run in runs if run[1] == 0]
    if clean:
        return clean, ""
    return runs, (
        f"every run compiled kernels ({', '.join(str(run[1]) for run in runs)}): the cache did not hold "
        "them (sources changed during the run?); these figures include compiling"
    )


def time_startup(cold: bool = True, warm_runs: int = 2) -> dict:
    """Wall time of a fresh process to its first full step (import, set-up, step, entropy).

    cold: first with an empty NUMBA_CACHE_DIR (every kernel the step uses compiles), then `warm_runs` times
    with that cache found; compile_s = cold - warm. Without `cold`, only processes that find the cache this
    process uses (its kernels are loaded or compiled already). A run that compiled a kernel does not count as
    one that found the cache (numba's cache log says which did)."""
    result: dict = {
        "cold_cache_s": None,
        "cold_cache_in_python_s": None,
        "compile_s": None,
        "kernels_compiled_cold": None,
    }
    with tempfile.TemporaryDirectory(prefix="robocup-mcl-numba-") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache) if cold else dict(os.environ)
        command = [sys.executable, "-c", _PROBE]
        if cold:
            elapsed, compiled, last = _cached_run(command, env)
            result.update(cold_cache_s=elapsed, cold_cache_in_python_s=float(last), kernels_compiled_cold=compiled)
        runs = [_cached_run(command, env) for _ in range(warm_runs)]
    found, note = _cache_found(runs)
    result["warm_cache_s"] = statistics.median(run[0] for run in found)
    result["warm_cache_in_python_s"] = statistics.median(float(run[2]) for run in found)
    result["warm_runs_s"] = [run[0] for run in runs]
    result["warm_runs_compiled"] = [run[1] for run in runs]
    result["note"] = note
    if cold:
        result["compile_s"] = result["cold_cache_s"] - result["warm_cache_s"]
    return result


def _cli() -> list[str]:
    script = Path(sys.executable).with_name("robocup-mcl")
    return [str(script)] if script.exists() else [sys.executable, "-m", "mcl.tools.cli"]


def time_demo_walk(runs: int = 2) -> dict:
    """Wall time of `robocup-mcl demo walk --duration 0.1` (10 steps of 10 ms) in processes that find the numba
    cache: one run first fills the cache with whatever the demo needs beyond the benchmark, then `runs` timed;
    the median of those that compiled nothing."""
    command = _cli() + ["demo", "walk", "--duration", "0.1"]
    env = dict(os.environ)
    _run(command, env)
    timed = [_cached_run(command, env) for _ in range(runs)]
    found, note = _cache_found(timed)
    return {
        "command": "robocup-mcl demo walk --duration 0.1",
        "wall_s": statistics.median(run[0] for run in found),
        "runs_s": [run[0] for run in timed],
        "runs_compiled": [run[1] for run in timed],
        "note": note,
    }


def avx512_features() -> list[str]:
    """The names numpy accepts in NPY_DISABLE_CPU_FEATURES that switch its AVX-512 code paths off: those of
    its dispatch list (numpy refuses names that are not in it)."""
    dispatch, _ = numpy_cpu_dispatch()
    return [name for name in dispatch if name.startswith("AVX512") or name == "X86_V4"]


_NUMPY_PROBE = """
import json, sys
from benchmarks.step import numpy_full_step
from benchmarks.system import numpy_cpu_dispatch
sizes, budget = json.loads(sys.argv[1])
_, features = numpy_cpu_dispatch()
print(json.dumps({"features_on": sorted(k for k, v in features.items() if v),
                  "rows": numpy_full_step(sizes, budget)}))
"""


AVX512_MAX_N = 100_000  # the numpy step takes seconds beyond: four processes of it would dominate the run


def numpy_without_avx512(sizes, budget_s: float, rounds: int = 1) -> dict:
    """The numpy step timed in fresh processes with numpy's AVX-512 dispatch switched off, each followed by
    one with numpy as it is (A, B, A, B ... for `rounds`), medians per N <= AVX512_MAX_N; the ratio off / on
    compares the two."""
    sizes = [n for n in sizes if n <= AVX512_MAX_N]
    names = avx512_features()
    _, features = numpy_cpu_dispatch()
    has_avx512 = bool(features.get("AVX512F") or features.get("X86_V4"))
    result = {
        "NPY_DISABLE_CPU_FEATURES": " ".join(names),
        "cpu_has_avx512": has_avx512,
        "rows": [],
        "note": "" if has_avx512 else "this CPU has no AVX-512: numpy cannot use it either way",
    }
    if not names:
        result["note"] = "numpy dispatches no AVX-512 code on this build: nothing to switch off"
        return result
    if not sizes:
        result["note"] = f"not measured: no N <= {AVX512_MAX_N}"
        return result
    settings = {
        "off": dict(os.environ, NPY_DISABLE_CPU_FEATURES=" ".join(names)),
        "on": {k: v for k, v in os.environ.items() if k != "NPY_DISABLE_CPU_FEATURES"},
    }
    seconds: dict = {"off": {}, "on": {}}
    for _ in range(rounds):
        for label, env in settings.items():
            _, done = _run(
                [sys.executable, "-W", "error::ImportWarning", "-c", _NUMPY_PROBE, json.dumps([list(sizes), budget_s])],
                env,
            )
            probe = json.loads(done.stdout.strip().splitlines()[-1])
            if label == "off":
                result["features_still_on"] = sorted(set(probe["features_on"]) & set(names))
            for row in probe["rows"]:
                seconds[label].setdefault(row["n"], []).append(row["numpy_s"])
    for n in sizes:
        off, on = statistics.median(seconds["off"][n]), statistics.median(seconds["on"][n])
        result["rows"].append({"n": n, "numpy_s": off, "numpy_default_s": on, "off_over_on": off / on})
    return result


# -- memory ----------------------------------------------------------------------------------------------------
_MEMORY_PROBE = """
import json, sys
from benchmarks.system import memory_in_process
sizes, steps = json.loads(sys.argv[1])
print(json.dumps(memory_in_process(sizes, steps)))
"""


def memory_in_process(sizes, steps: int) -> list[dict]:
    """tracemalloc's figures of the benchmark step at each N (call with tracemalloc not yet started).

    filter_bytes: what building the filter allocated (its buffers). step_peak_bytes: the largest scratch
    memory of one step above what was allocated before it (its high-water mark, numpy and Python objects).
    retained_bytes_per_step: snapshot difference over `steps` steps, per step (> 0: the step keeps memory).
    numba_allocations_per_step: numba's allocations during the step (NUMBA_NRT_STATS; tracemalloc does not see
    them): the arrays made inside the kernels and the wrapper numba makes for each array handed to a kernel,
    which is most of them; None when the counters are off."""
    import tracemalloc

    from numba.core.runtime import rtsys

    from .step import bench_setup

    def numba_allocations():
        try:
            return rtsys.get_allocation_stats().alloc
        except RuntimeError:
            return None

    rows = []
    for n in sizes:
        pf, u, observations = bench_setup(n)
        for _ in range(3):  # warm up: kernels loaded, buffers grown, caches filled
            pf.step(u, observations)
            pf.entropy()
        tracemalloc.start()
        before = tracemalloc.get_traced_memory()[0]
        fresh, _, _ = bench_setup(n)
        filter_bytes = tracemalloc.get_traced_memory()[0] - before
        del fresh
        peaks = []
        for _ in range(5):
            current = tracemalloc.get_traced_memory()[0]
            tracemalloc.reset_peak()
            pf.step(u, observations)
            pf.entropy()
            peaks.append(tracemalloc.get_traced_memory()[1] - current)
        first = tracemalloc.take_snapshot()
        allocations = numba_allocations()
        for _ in range(steps):
            pf.step(u, observations)
            pf.entropy()
        allocations = None if allocations is None else (numba_allocations() - allocations) / steps
        second = tracemalloc.take_snapshot()
        tracemalloc.stop()
        own = [tracemalloc.Filter(False, tracemalloc.__file__)]  # tracemalloc's own bookkeeping
        first, second = first.filter_traces(own), second.filter_traces(own)
        differences = second.compare_to(first, "lineno")
        retained = sum(d.size_diff for d in differences)
        rows.append(
            {
                "n": n,
                "filter_bytes": filter_bytes,
                "step_peak_bytes": max(peaks),
                "step_peak_bytes_per_particle": max(peaks) / n,
                "retained_bytes_per_step": retained / steps,
                "steps": steps,
                "numba_allocations_per_step": allocations,
                "largest_retained": [
                    f"{d.traceback[0].filename.rsplit('/', 1)[-1]}:{d.traceback[0].lineno} {d.size_diff:+d} B"
                    for d in differences[:3]
                    if d.size_diff
                ],
            }
        )
    return rows


def memory(sizes=(10_000, 100_000), steps: int = 40) -> dict:
    """`memory_in_process` in a fresh process with numba's allocation counters on; whether the scratch memory
    of a step, or the number of arrays its kernels allocate, grows with N (from the smallest to the largest
    size: more than twice as large), and whether a step keeps memory (over 1 KiB per step)."""
    env = dict(os.environ, NUMBA_NRT_STATS="1")
    _, done = _run([sys.executable, "-c", _MEMORY_PROBE, json.dumps([list(sizes), steps])], env)
    rows = json.loads(done.stdout.strip().splitlines()[-1])
    small, large = rows[0], rows[-1]
    ratio = large["step_peak_bytes"] / max(small["step_peak_bytes"], 1)
    leak = max(row["retained_bytes_per_step"] for row in rows)
    counts = (small["numba_allocations_per_step"], large["numba_allocations_per_step"])
    return {
        "rows": rows,
        "sizes": list(sizes),
        "step_peak_ratio": ratio,
        "grows_with_n": bool(len(rows) > 1 and ratio > 2.0),
        "kernel_allocations_grow_with_n": bool(None not in counts and counts[1] > 2 * counts[0] + 10),
        "retains_memory": bool(leak > 1024),
        "note": "scratch memory per step from tracemalloc (numpy arrays and Python objects); numba's "
        "allocations (arrays made in kernels, wrappers of the arrays handed to them) are counted "
        "(numba_allocations_per_step) but not sized",
    }
