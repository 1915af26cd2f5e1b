"""Every cached numba kernel of the project really is cached: no "Cannot cache" warning, and a second process
loads every kernel from the cache instead of compiling it.

A kernel that numba cannot cache (it uses lifted code, or dynamic globals such as a large global array)
compiles again in every process; numba says so only with a NumbaWarning. Here fresh processes with an empty
NUMBA_CACHE_DIR import every project module and call every kernel family once through its public entry
points, with that warning turned into an error; then the test checks that every public
`@numba.njit(cache=True)` kernel (and every private one those calls reach) was compiled and saved its cache
index. A further process with the same cache repeats all the calls and checks that nothing was compiled.
A new public kernel that the calls below do not reach fails the test with its name: add a call that reaches
it to EXERCISE. Compiling everything takes a while, so the calls come in two parts that compile side by side
(the filter with its motion and sensor models; LWPR, the velocity EKF and the leg kinematics), one process
each.
"""
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

EXERCISE = r'''
import contextlib, importlib, inspect, io, json, os, pkgutil, sys, warnings

from numba.core.errors import NumbaWarning

# "Cannot cache compiled function ..." (numba.core.caching) and any other caching complaint fail the run.
warnings.filterwarnings("error", message=".*cach", category=NumbaWarning)

import numpy as np

PACKAGES = ("field", "numerics", "sensing", "motion_models", "mcl", "demos", "benchmarks")
modules = []
for package_name in PACKAGES:
    package = importlib.import_module(package_name)
    modules.append(package)
    for info in pkgutil.walk_packages(package.__path__, package_name + "."):
        modules.append(importlib.import_module(info.name))

from field import spl
from mcl import ParticleFilter
from sensing import LandmarkSensorModel, Observations
from motion_models import AdaptiveMotion, MotionInput, VelocityLinear

part = sys.argv[1]
field = spl()
rng = np.random.default_rng(0)
observations = Observations.from_arrays(["goalpost", "goalpost"], [3.0, 4.0], [0.2, -0.3])

if part in ("filter", "all"):
    from mcl.estimate import cluster_estimate, grid_entropy
    from mcl.filter import AugmentedMCL
    from mcl.latency import move_back, move_forward
    from mcl.resampling import SCHEMES, systematic_counted, systematic_with_jitter
    from mcl.weights import log_mean_likelihood, normalize
    from motion_models.kernels import move_drawing_noise, move_with_noise
    from numerics.random import bit_generator_handle, skip_doubles

    # The walk demo with field lines: velocity-linear, landmark and line likelihoods, normalize, augmented
    # MCL, systematic resampling with roughening, estimate, entropy.
    from demos.walk import main as walk_main
    with contextlib.redirect_stdout(io.StringIO()):
        walk_main(["--duration", "0.5", "--particles", "60", "--lines", "--json"])

    for bearing_model, mixture in (("von_mises", "max"), ("exact", "max"), ("exact", "sum")):
        for scheme in SCHEMES:
            pf = ParticleFilter(field, VelocityLinear(gaussian=scheme == "residual"),
                                LandmarkSensorModel(field, bearing_model=bearing_model, mixture=mixture),
                                n_particles=64, seed=1,
                                resampling=scheme, resample_threshold=1.0,
                                augmented=AugmentedMCL(fit_threshold=10.0))
            pf.step(MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)), observations)
            pf.correct(observations, since=(0.05, 0.0, 0.02))      # camera latency: moved back (and forward)
            pf.estimate(), pf.entropy()
    if "threads" in inspect.signature(ParticleFilter).parameters:      # the chunked, multi-threaded variants
        for bearing_model in ("von_mises", "exact"):
            threaded = ParticleFilter(field, VelocityLinear(), LandmarkSensorModel(field, bearing_model=bearing_model),
                                      n_particles=20_000, seed=3, resample_threshold=1.0, threads=2)
            threaded.step(MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)), observations)
            threaded.estimate(), threaded.entropy()
        threaded.predict(MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)))     # moved on threads alone

    from sensing.collision import CollisionPercept
    adaptive = ParticleFilter(field, AdaptiveMotion(), LandmarkSensorModel(field), n_particles=64, seed=2)
    percept = CollisionPercept(left=True, s_rel_left=1.5, rate=0.3, recent_left=True)
    adaptive.step(MotionInput(dt=0.01, command=(0.2, 0.0, 0.0), collision=percept), observations)
    from motion_models.adaptive import VARIATES, adaptive_move      # (predict draws in the kernel instead)
    model = AdaptiveMotion()
    arguments = model.kernel_arguments(MotionInput(dt=0.01, command=(0.2, 0.0, 0.0), collision=percept))
    adaptive_move(adaptive.poses.copy(), model.particle_state(64), *arguments, rng.random((64, VARIATES)))

    # A sensor model on the per-particle contract (`sensing.fused.per_particle_kernels`): its fused step,
    # with camera latency, and its `log_likelihood`.
    from sensing.goal_direction import GoalDirectionSensorModel
    goals = Observations.from_arrays(["goalpost", "goalpost"], [4.0, 4.0], [0.3, -2.6])
    goal_filter = ParticleFilter(field, VelocityLinear(), GoalDirectionSensorModel(field), n_particles=64, seed=5)
    goal_filter.step(MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)), goals)
    goal_filter.correct(goals, since=(0.05, 0.0, 0.02))
    goal_filter.sensor_model.log_likelihood(goal_filter.poses, goals)

    # Injection around a known pose (the relocalization's proposal: the single-detection sampler).
    injecting = ParticleFilter(field, VelocityLinear(), LandmarkSensorModel(field), n_particles=64, seed=4,
                               augmented=AugmentedMCL())
    injecting.reset_around((0.5, 0.5, 0.0))
    injecting._sample_injection(8, observations)
    injecting.sensor_model.explained((0.5, 0.5, 0.0), observations)      # the localizer's quality
    from sensing.view import CameraView                                  # ... and its negative information
    injecting.sensor_model.seen((0.5, 0.5, 0.0), observations, CameraView(0.0, 0.5, 5.0))
    injecting.sensor_model.log_likelihood(injecting.poses, observations.with_view(CameraView(0.0, 0.5, 5.0)))

    # Kernels that are public on their own (the tests compare them with their numpy twins) beside the fused
    # code the filter runs.
    poses = pf.poses.copy()
    out = np.empty_like(poses)
    move_back(poses, np.array([0.1, 0.0, 0.05]), out)
    move_forward(poses, np.array([0.1, 0.0, 0.05]), out)
    weights = np.full(len(poses), 1.0 / len(poses))
    log_weights = np.log(weights)
    normalize(log_weights, np.empty(len(poses)))
    log_mean_likelihood(log_weights, log_weights, len(poses))
    from mcl.recording import weight_colors                    # the recorded particles' colours
    weight_colors(weights)
    grid_entropy(poses, weights, -5.0, -3.5, 0.1, 100, 70, 36, np.empty(7000), np.empty(36))
    cluster_estimate(poses, weights, (-5.0, -3.5, 0.5, 20, 14, 8), (0.75, 0.8, 3), np.empty(20 * 14 * 8),
                     np.zeros(3), False, np.empty(3), np.empty((3, 3)))
    for scheme in SCHEMES.values():
        scheme(weights, len(weights), rng)
    systematic_with_jitter(weights, len(poses), poses, np.full(3, 0.02), out, np.empty((0, 2)),
                           *bit_generator_handle(rng))
    systematic_counted(weights, len(weights), 0.5, np.empty(len(weights), dtype=np.int64),
                       np.zeros(len(weights) + 1, dtype=np.int64))
    LandmarkSensorModel(field, bearing_model="exact").log_likelihood(poses, observations)
    move_with_noise(poses, 0.01, 0.0, 0.01, 0.001, 0.001, 0.001, False, rng.random((len(poses), 3)))
    move_drawing_noise(poses, 0.01, 0.0, 0.01, 0.001, 0.001, 0.001, *bit_generator_handle(rng))
    skip_doubles(3, *bit_generator_handle(rng))

if part in ("models", "all"):
    from motion_models.lwpr import LWPR
    from sensing.kinematics import nao_leg
    from sensing.velocity import (VelocityEKF, VelocityEKFParams, left_jacobian, rotation_derivative_at,
                                  rotation_matrix)

    model = LWPR(2, 1)
    for x in rng.uniform(-1, 1, (50, 2)):
        model.update(x, np.array([x[0] * x[1]]))
    model.predict(np.zeros(2)), model.predict(rng.uniform(-1, 1, (5, 2))), model.predict_conf(np.zeros(2))

    for bias in (True, False):
        ekf = VelocityEKF([0.0, 0.0, 9.81], 0.0, params=VelocityEKFParams(estimate_gyro_bias=bias))
        ekf.predict(0.01, [0.01, 0.0, 0.1], [0.0, 0.0, 9.81])
        ekf.correct([0.1, 0.0, 0.0])
    rotation_matrix([0.1, 0.2, 0.3]), left_jacobian([0.1, 0.2, 0.3])
    rotation_derivative_at([0.1, 0.2, 0.3], [1.0, 0, 0])

    leg = nao_leg("left")
    angles = np.zeros(leg.n_joints) + 0.1
    leg.velocities(angles, angles, (0.0, 0.0, 0.1))
    leg.velocities_batch(np.tile(angles, (3, 1)), np.tile(angles, (3, 1)), np.zeros((3, 3)))

# Every cached kernel defined in the project: compiled here or not, its cache index, cache misses.
from numba.core.registry import CPUDispatcher
report = {"kernels": [], "inlined": [], "compiled": [], "no_index": [], "cache_misses": {}}
for module in modules:
    for name, kernel in vars(module).items():
        if not (isinstance(kernel, CPUDispatcher) and kernel.py_func.__module__ == module.__name__
                and type(kernel._cache).__name__ != "NullCache"):
            continue
        label = f"{module.__name__}.{name}"
        report["kernels"].append(label)
        if kernel.targetoptions.get("inline") == "always":     # compiled inside its callers
            report["inlined"].append(label)
        if not kernel.signatures:
            continue
        report["compiled"].append(label)
        index = getattr(getattr(kernel._cache, "_cache_file", None), "_index_path", None)
        if index is not None and not os.path.exists(index):
            report["no_index"].append(label)
        misses = sum(kernel.stats.cache_misses.values())
        if misses:
            report["cache_misses"][label] = misses
print(json.dumps(report))
'''


def _start(part: str, cache_dir: Path) -> subprocess.Popen:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir), PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-c", EXERCISE, part], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _report(process: subprocess.Popen) -> dict:
    stdout, stderr = process.communicate(timeout=600)
    assert "Cannot cache" not in stderr, stderr[-3000:]
    assert process.returncode == 0, stderr[-3000:]
    return json.loads(stdout.strip().splitlines()[-1])


def _sources() -> dict[str, float]:
    """Modification time of every project module, by module name."""
    times = {}
    for package in ("field", "numerics", "sensing", "motion_models", "mcl", "demos", "benchmarks"):
        for path in (ROOT / package).rglob("*.py"):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            times[module.removesuffix(".__init__")] = path.stat().st_mtime
    return times


def test_every_kernel_is_cached_and_found_again(tmp_path):
    before = _sources()
    parts = [_start(part, tmp_path) for part in ("filter", "models")]   # side by side: two cores
    reports = [_report(process) for process in parts]
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
    again = _report(_start("all", tmp_path))
    # A module edited while the test ran has a stale cache by right (numba keys the cache on the source file).
    after = _sources()
    edited = {module for module, stamp in after.items() if before.get(module) != stamp}
    misses = {label: count for label, count in again["cache_misses"].items()
              if label.rsplit(".", 1)[0] not in edited}
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
    assert forget_stale_numba_caches(tmp_path, stamp)              # no stamp yet: dropped
    assert not any(path.exists() for path in cached) and kept.exists() and stamp.exists()
    cache()
    assert not forget_stale_numba_caches(tmp_path, stamp)          # nothing changed: kept
    assert all(path.exists() for path in cached)
    (tmp_path / "sensing" / "kernels.py").write_text("x = 22\n")   # a callee in another package changed
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
    assert not guard_source_checkout(tmp_path)                      # an installed copy: left alone
    assert cached.exists() and not (tmp_path / SOURCES_STAMP).exists()
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "another-project"\n')
    assert not guard_source_checkout(tmp_path) and cached.exists()
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "robocup-mcl"\n')
    assert guard_source_checkout(tmp_path)                          # the project's tree, no stamp yet
    assert not cached.exists() and (tmp_path / SOURCES_STAMP).exists()
    cached.write_bytes(b"cached")
    assert not guard_source_checkout(tmp_path) and cached.exists()  # nothing changed since


def test_the_command_line_guards_the_caches_before_running_anything(monkeypatch):
    """`robocup-mcl` calls the guard first, so that a demo or a benchmark run from a checkout after an edit runs
    the edited kernels."""
    import mcl.cli

    calls = []
    monkeypatch.setattr(mcl.cli, "guard_source_checkout", lambda: calls.append("guard"))
    assert mcl.cli.main(["--help"]) == 0
    assert calls == ["guard"]
