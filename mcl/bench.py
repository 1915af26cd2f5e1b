"""`robocup-mcl bench`: time one full filter step, phase by phase, against the same step in plain numpy.

    robocup-mcl bench [--sizes 100,1000,...] [--exact] [--json]

The step: predict (velocity-linear), correct with 10 detections of a 4-way ambiguous type (goalposts),
normalize and ESS, systematic resampling, estimate (dominant cluster), entropy. The numba step is timed
through the filter's public calls (`step` + `entropy`, resampling forced every step) and phase by phase;
the numpy step (`mcl.reference.numpy_step`) in the same run, on the same particles. Also: the start-up of
a fresh process that must compile every kernel (empty numba cache), and of one that finds the cache.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

from field import spl
from motion_models import MotionInput, VelocityLinear
from sensing import LandmarkSensorModel, Observations

from .filter import ParticleFilter
from .reference import PHASES, numpy_step
from .weights import normalize

SIZES = (100, 1_000, 10_000, 100_000, 1_000_000)
TRUE_POSE = np.array([1.0, 0.5, 0.3])


def bench_setup(n: int, bearing_model: str = "von_mises", seed: int = 0):
    """A filter of n particles around TRUE_POSE, a motion input, and 10 goalpost detections."""
    field = spl()
    sensor = LandmarkSensorModel(field, bearing_model=bearing_model)
    pf = ParticleFilter(field, VelocityLinear(), sensor, n_particles=n, seed=seed, resample_threshold=1.0,
                        augmented=None)
    pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
    rng = np.random.default_rng(seed + 1)
    posts = field.landmarks_of("goalpost")
    picks = posts[rng.integers(0, len(posts), 10)]
    d = picks - TRUE_POSE[:2]
    ranges = np.hypot(d[:, 0], d[:, 1]) + 0.05 * rng.standard_normal(10)
    bearings = np.arctan2(d[:, 1], d[:, 0]) - TRUE_POSE[2] + 0.03 * rng.standard_normal(10)
    observations = Observations.from_arrays(["goalpost"] * 10, ranges, bearings)
    return pf, MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)), observations


def _repetitions(n: int) -> int:
    return int(max(3, min(2000, 3e6 / max(n, 1))))


def time_numba(n: int, bearing_model: str = "von_mises") -> dict:
    pf, u, obs = bench_setup(n, bearing_model)
    pf.step(u, obs), pf.entropy()  # warm up (compiled or loaded from the cache)
    reps = _repetitions(n)
    clock = time.perf_counter
    start = clock()
    for _ in range(reps):
        pf.step(u, obs)
        pf.entropy()
    full = (clock() - start) / reps
    phases = dict.fromkeys(PHASES, 0.0)
    for _ in range(reps):
        t0 = clock()
        pf.predict(u)
        t1 = clock()
        log_likelihood = pf.sensor_model.log_likelihood(pf.poses, obs, out=pf._log_likelihood)
        t2 = clock()
        normalize(pf.log_weights + log_likelihood, pf._weights)
        t3 = clock()
        pf._resample(0, obs)
        t4 = clock()
        pf.estimate()
        t5 = clock()
        pf.entropy()
        t6 = clock()
        for name, a, b in zip(PHASES, (t0, t1, t2, t3, t4, t5), (t1, t2, t3, t4, t5, t6)):
            phases[name] += b - a
    return {"full_step_s": full, "phases_s": {k: v / reps for k, v in phases.items()}, "repetitions": reps}


def time_numpy(n: int) -> dict:
    pf, u, obs = bench_setup(n)
    numpy_step(pf, u, obs)
    reps = max(2, _repetitions(n) // 10)
    phases: dict = {}
    start = time.perf_counter()
    for _ in range(reps):
        numpy_step(pf, u, obs, phases)
    full = (time.perf_counter() - start) / reps
    return {"full_step_s": full, "phases_s": {k: phases[k] / reps for k in PHASES}, "repetitions": reps}


_PROBE = ("import time; t = time.perf_counter(); from mcl.bench import bench_setup; "
          "pf, u, obs = bench_setup(1000); pf.step(u, obs); pf.entropy(); "
          "print(time.perf_counter() - t)")


def time_startup() -> dict:
    """Wall time of a fresh process to its first full step: with an empty numba cache, then with the cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        result = {}
        for label in ("cold_cache_s", "warm_cache_s"):
            start = time.perf_counter()
            out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True)
            result[label] = time.perf_counter() - start
            result[label.replace("_s", "_in_python_s")] = float(out.stdout.strip().splitlines()[-1])
    result["compile_s"] = result["cold_cache_s"] - result["warm_cache_s"]
    return result


def machine() -> dict:
    return {"python": platform.python_version(), "machine": platform.machine(), "cpus": os.cpu_count(),
            "processor": platform.processor() or platform.uname().machine,
            "numpy": np.__version__, "numba": __import__("numba").__version__}


def bearing_accuracy(n: int = 10_000) -> dict:
    """What the von Mises bearing term costs in accuracy: the total-variation distance between the normalized
    weights it gives and those of the exact term, on the same particles and detections (0 = identical)."""
    pf, _, obs = bench_setup(n)
    weights = {}
    for model in ("von_mises", "exact"):
        sensor = LandmarkSensorModel(pf.field, bearing_model=model)
        log_likelihood = sensor.log_likelihood(pf.poses, obs)
        w = np.exp(log_likelihood - log_likelihood.max())
        weights[model] = w / w.sum()
    return {"n": n, "total_variation": float(0.5 * np.abs(weights["von_mises"] - weights["exact"]).sum())}


def run(sizes=SIZES, startup: bool = True, exact: bool = True) -> dict:
    rows = []
    for n in sizes:
        fast = time_numba(n)
        row = {"n": n, "numba": fast, "numpy": time_numpy(n)}
        row["speedup"] = row["numpy"]["full_step_s"] / fast["full_step_s"]
        row["ns_per_particle"] = 1e9 * fast["full_step_s"] / n
        if exact:
            row["numba_exact_bearing"] = time_numba(n, "exact")
        rows.append(row)
    result = {"machine": machine(), "threads": 1, "rows": rows}
    if exact:
        result["bearing_accuracy"] = bearing_accuracy()
    if startup:
        result["startup"] = time_startup()
    return result


def _format(result: dict) -> str:
    lines = [f"one full step (predict, 10 goalpost detections, normalize+ESS, resample, estimate, entropy); "
             f"python {result['machine']['python']}, numba {result['machine']['numba']}, one thread"]
    head = f"{'N':>9} {'numba':>10} {'ns/part.':>9} {'numpy':>10} {'speedup':>8} {'exact atan2':>12}  phases (numba, µs)"
    lines.append(head)
    for row in result["rows"]:
        phases = " ".join(f"{k}={1e6 * v:.1f}" for k, v in row["numba"]["phases_s"].items())
        exact = row.get("numba_exact_bearing")
        exact_text = f"{1e3 * exact['full_step_s']:.3f} ms" if exact else "-"
        lines.append(f"{row['n']:>9} {1e3 * row['numba']['full_step_s']:>7.3f} ms {row['ns_per_particle']:>9.0f} "
                     f"{1e3 * row['numpy']['full_step_s']:>7.3f} ms {row['speedup']:>7.1f}x {exact_text:>12}  {phases}")
    if "bearing_accuracy" in result:
        a = result["bearing_accuracy"]
        lines.append(f"von Mises versus exact bearing term: total-variation distance between the normalized weights "
                     f"{a['total_variation']:.4f} (N = {a['n']}, same particles and detections)")
    if "startup" in result:
        s = result["startup"]
        lines.append(f"start-up to the first step: empty numba cache {s['cold_cache_s']:.2f} s, "
                     f"cache found {s['warm_cache_s']:.2f} s (compile ≈ {s['compile_s']:.2f} s)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="robocup-mcl bench", description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default=",".join(str(n) for n in SIZES),
                        help="particle counts, comma-separated (default 100..1000000)")
    parser.add_argument("--no-startup", action="store_true", help="skip the start-up measurements")
    parser.add_argument("--no-exact", action="store_true", help="skip timing the exact (atan2) bearing term")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    try:
        sizes = [int(s) for s in args.sizes.split(",") if s.strip()]
    except ValueError:
        parser.error(f"--sizes {args.sizes!r} must be comma-separated integers")
    if not sizes or min(sizes) <= 0:
        parser.error(f"--sizes {args.sizes!r} must name particle counts > 0")
    result = run(sizes, startup=not args.no_startup, exact=not args.no_exact)
    if args.json:
        json.dump(result, sys.stdout, indent=2)
        print()
    else:
        print(_format(result))
    return 0
