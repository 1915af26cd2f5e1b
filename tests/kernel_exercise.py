"""Calls every cached kernel family of the project once through its public entry points, then prints a JSON
report of the project's cached kernels: which compiled (or loaded), which have no cache index, which missed the
cache. `python tests/kernel_exercise.py PARTS` with PARTS "filter" (the walk demo, the fused step with each
landmark bearing model and resampling scheme, the threaded step, the adaptive motion model's step), "sensors"
(injection, the kernels public on their own), "models" (LWPR, the velocity EKF, the leg kinematics), "extension"
(the goal-direction model: a sensor model on the per-particle contract), a comma-separated list of them, or
"all". "filter" and "sensors,models,extension" take about as long to compile: the test session runs them side
by side, one per core (tests/conftest.py, `WARMUP_PARTS`). No kernel should compile in both: two processes
compiling one kernel at once both pay for it (the cache keeps one), so each family belongs to one lane, and
"extension", whose fused step calls the kernels that "filter" compiles first, comes last in its lane, by which
time it finds them in the cache.

tests/test_numba_cache.py runs it against an empty NUMBA_CACHE_DIR; the test session's controller runs it
against the project's own cache before its parallel workers start (tests/conftest.py), so that the workers load
these kernels instead of each compiling them.
"""

import contextlib
import importlib
import inspect
import io
import json
import os
import pkgutil
import sys
import warnings

from numba.core.errors import NumbaWarning

from mcl.numba_cache import PACKAGES, serialize_cache_access

serialize_cache_access()  # other processes may share the cache (the test session's workers)

# "Cannot cache compiled function ..." (numba.core.caching) and any other caching complaint fail the run.
warnings.filterwarnings("error", message=".*cach", category=NumbaWarning)

import numpy as np

modules = []
for package_name in PACKAGES:
    package = importlib.import_module(package_name)
    modules.append(package)
    for info in pkgutil.walk_packages(package.__path__, package_name + "."):
        modules.append(importlib.import_module(info.name))

from field import spl
from mcl import ParticleFilter
from mcl.filter import AugmentedMCL
from mcl.resampling import SCHEMES
from motion_models import AdaptiveMotion, MotionInput, VelocityLinear
from proprioception.collision import CollisionPercept
from sensing import LandmarkSensorModel, Observations

part = sys.argv[1]
parts = {"filter", "sensors", "models", "extension"} if part == "all" else set(part.split(","))
field = spl()
rng = np.random.default_rng(0)
observations = Observations.from_arrays(["goalpost", "goalpost"], [3.0, 4.0], [0.2, -0.3])
percept = CollisionPercept(left=True, s_rel_left=1.5, rate=0.3, recent_left=True)  # the adaptive model's input


if "filter" in parts:
    # The walk demo with field lines: velocity-linear, landmark and line likelihoods, normalize, augmented
    # MCL, systematic resampling with roughening, estimate, entropy.
    from demos.walk import main as walk_main

    with contextlib.redirect_stdout(io.StringIO()):
        walk_main(["--duration", "0.5", "--particles", "60", "--lines", "--json"])
    # A fused step and a correction with camera latency for each landmark bearing model and mixture and each
    # resampling scheme.
    for bearing_model, mixture in (("von_mises", "max"), ("exact", "max"), ("exact", "sum")):
        for scheme in SCHEMES:
            pf = ParticleFilter(
                field,
                VelocityLinear(gaussian=scheme == "residual"),
                LandmarkSensorModel(field, bearing_model=bearing_model, mixture=mixture),
                n_particles=64,
                seed=1,
                resampling=scheme,
                resample_threshold=1.0,
                augmented=AugmentedMCL(fit_threshold=10.0),
            )
            pf.step(MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)), observations)
            pf.correct(observations, since=(0.05, 0.0, 0.02))  # camera latency: moved back (and forward)
            pf.estimate(), pf.entropy()
    if "threads" in inspect.signature(ParticleFilter).parameters:  # the chunked, multi-threaded variants
        for bearing_model in ("von_mises", "exact"):
            threaded = ParticleFilter(
                field,
                VelocityLinear(),
                LandmarkSensorModel(field, bearing_model=bearing_model),
                n_particles=20_000,
                seed=3,
                resample_threshold=1.0,
                threads=2,
            )
            threaded.step(MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)), observations)
            threaded.estimate(), threaded.entropy()
        threaded.predict(MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)))  # moved on threads alone

    # The adaptive motion model's step: its draws in the kernel, and the fused correction compiled above (in this
    # lane, so that the other does not compile the same step at the same time).
    adaptive = ParticleFilter(field, AdaptiveMotion(), LandmarkSensorModel(field), n_particles=64, seed=2)
    adaptive.step(MotionInput(dt=0.01, command=(0.2, 0.0, 0.0), collision=percept), observations)

if "sensors" in parts:
    from mcl.estimate import cluster_estimate, grid_entropy
    from mcl.latency import move_back, move_forward
    from mcl.resampling import systematic_counted, systematic_with_jitter
    from mcl.weights import log_mean_likelihood, normalize
    from motion_models.adaptive import VARIATES, adaptive_move  # (the filter's predict draws in the kernel)
    from motion_models.kernels import move_drawing_noise, move_with_noise
    from numerics.random import bit_generator_handle, skip_doubles

    model = AdaptiveMotion()
    arguments = model.kernel_arguments(MotionInput(dt=0.01, command=(0.2, 0.0, 0.0), collision=percept))
    adaptive_move(rng.random((64, 3)), model.particle_state(64), *arguments, rng.random((64, VARIATES)))

    # Injection around a known pose (the relocalization's proposal: the single-detection sampler).
    injecting = ParticleFilter(
        field, VelocityLinear(), LandmarkSensorModel(field), n_particles=64, seed=4, augmented=AugmentedMCL()
    )
    injecting.reset_around((0.5, 0.5, 0.0))
    injecting._sample_injection(8, observations)
    injecting.sensor_model.explained((0.5, 0.5, 0.0), observations)  # the localizer's quality
    from sensing.view import CameraView  # ... and its negative information

    injecting.sensor_model.seen((0.5, 0.5, 0.0), observations, CameraView(0.0, 0.5, 5.0))
    injecting.sensor_model.log_likelihood(injecting.poses, observations.with_view(CameraView(0.0, 0.5, 5.0)))

    # Kernels that are public on their own (the tests compare them with their numpy twins) beside the fused
    # code the filter runs.
    poses = injecting.poses.copy()
    out = np.empty_like(poses)
    move_back(poses, np.array([0.1, 0.0, 0.05]), out)
    move_forward(poses, np.array([0.1, 0.0, 0.05]), out)
    weights = np.full(len(poses), 1.0 / len(poses))
    log_weights = np.log(weights)
    normalize(log_weights, np.empty(len(poses)))
    log_mean_likelihood(log_weights, log_weights, len(poses))
    from mcl.tools.recording import weight_colors  # the recorded particles' colours

    weight_colors(weights)
    grid_entropy(poses, weights, -5.0, -3.5, 0.1, 100, 70, 36, np.empty(7000), np.empty(36))
    cluster_estimate(
        poses,
        weights,
        (-5.0, -3.5, 0.5, 20, 14, 8),
        (0.75, 0.8, 3),
        np.empty(20 * 14 * 8),
        np.zeros(3),
        False,
        np.empty(3),
        np.empty((3, 3)),
    )
    for scheme in SCHEMES.values():
        scheme(weights, len(weights), rng)
    systematic_with_jitter(
        weights, len(poses), poses, np.full(3, 0.02), out, np.empty((0, 2)), *bit_generator_handle(rng)
    )
    systematic_counted(
        weights, len(weights), 0.5, np.empty(len(weights), dtype=np.int64), np.zeros(len(weights) + 1, dtype=np.int64)
    )
    LandmarkSensorModel(field, bearing_model="exact").log_likelihood(poses, observations)
    move_with_noise(poses, 0.01, 0.0, 0.01, 0.001, 0.001, 0.001, False, rng.random((len(poses), 3)))
    move_drawing_noise(poses, 0.01, 0.0, 0.01, 0.001, 0.001, 0.001, *bit_generator_handle(rng))
    skip_doubles(3, *bit_generator_handle(rng))
    from mcl.rivals import displaced  # the localizer's rival places, carried along the odometry

    displaced(poses, (0.1, 0.0, 0.05))

if "models" in parts:
    from motion_models.lwpr import LWPR
    from proprioception.kinematics import nao_leg
    from proprioception.velocity import (
        VelocityEKF,
        VelocityEKFParams,
        left_jacobian,
        rotation_derivative_at,
        rotation_matrix,
    )

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

if "extension" in parts:
    # A sensor model on the per-particle contract (`sensing.fused.per_particle_kernels`): its fused step,
    # with camera latency, and its `log_likelihood`.
    from sensing.goal_direction import GoalDirectionSensorModel

    goals = Observations.from_arrays(["goalpost", "goalpost"], [4.0, 4.0], [0.3, -2.6])
    goal_filter = ParticleFilter(field, VelocityLinear(), GoalDirectionSensorModel(field), n_particles=64, seed=5)
    goal_filter.step(MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)), goals)
    goal_filter.correct(goals, since=(0.05, 0.0, 0.02))
    goal_filter.sensor_model.log_likelihood(goal_filter.poses, goals)

# Every cached kernel defined in the project: compiled here or not, its cache index, cache misses.
from numba.core.registry import CPUDispatcher

report = {"kernels": [], "inlined": [], "compiled": [], "no_index": [], "cache_misses": {}}
for module in modules:
    for name, kernel in vars(module).items():
        if not (
            isinstance(kernel, CPUDispatcher)
            and kernel.py_func.__module__ == module.__name__
            and type(kernel._cache).__name__ != "NullCache"
        ):
            continue
        label = f"{module.__name__}.{name}"
        report["kernels"].append(label)
        if kernel.targetoptions.get("inline") == "always":  # compiled inside its callers
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
