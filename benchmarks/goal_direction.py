"""The fused step with a sensor model that reaches it through one per-particle log-likelihood, against a
built-in model: the goal-direction model (`sensing.goal_direction`, two goal bearings a frame) beside the
landmark model (`sensing.landmarks`, the same two goals seen as their four posts, range and bearing).

    python -m benchmarks.goal_direction          # one line: ns per particle of each, and their ratios

Two figures per model, the best of a few rounds over the frames, per particle: the likelihood stage of the
fused step alone (`predict_and_score` copying the particles and scoring them, as the step does it), and the
whole step (`ParticleFilter.step`: resampling every step, threshold 1, no injection, velocity-linear motion,
one thread). The whole step also depends on the belief each model leaves: the two goal bearings pin the
robot down less than the four posts' ranges and bearings, and a wider belief costs the summary more.
"""

from __future__ import annotations

import math
import time

import numpy as np

from field import spl
from mcl import ParticleFilter
from mcl.contracts import fused_kernels
from mcl.step import NO_SINCE, STEP_BLOCK, fused_step
from motion_models import MotionInput, VelocityLinear
from sensing import LandmarkSensorModel, Observations
from sensing.goal_direction import GoalDirectionSensorModel

TRUE_POSE = np.array([1.0, 0.5, 0.3])


def _frames(field, rng, count: int) -> tuple[list, list]:
    """`count` frames of each: the two goals' centre bearings, and the four goalposts' ranges and bearings."""
    goals, posts = [], []
    landmarks = field.landmarks_of("goalpost")
    for _ in range(count):
        bearings = [
            math.atan2(-TRUE_POSE[1], gx - TRUE_POSE[0]) - TRUE_POSE[2] + 0.05 * rng.standard_normal()
            for gx in (field.half_length, -field.half_length)
        ]
        goals.append(Observations.from_arrays(["goalpost"] * 2, [4.0] * 2, bearings))
        d = landmarks - TRUE_POSE[:2]
        posts.append(
            Observations.from_arrays(
                ["goalpost"] * len(landmarks),
                np.hypot(d[:, 0], d[:, 1]) + 0.05 * rng.standard_normal(len(d)),
                np.arctan2(d[:, 1], d[:, 0]) - TRUE_POSE[2] + 0.03 * rng.standard_normal(len(d)),
            )
        )
    return goals, posts


def _ns_per_particle(pf: ParticleFilter, frames: list, rounds: int) -> float:
    u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1))
    best = math.inf
    for _ in range(rounds):
        start = time.perf_counter()
        for frame in frames:
            pf.step(u, frame)
        best = min(best, (time.perf_counter() - start) / len(frames))
    return best / pf.n * 1e9


def _likelihood_ns_per_particle(model, poses: np.ndarray, frames: list, rounds: int) -> float:
    kernels = fused_kernels(model)
    assert kernels is not None  # both models offer the fused likelihood
    score = fused_step(kernels).predict_and_score
    n = poses.shape[0]
    scratch, trig, out = np.empty_like(poses), np.empty((n, 2)), np.empty(n)
    copying = (False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False, np.empty((0, 3)))
    prepared = [kernels.prepare(kernels.inputs(frame), kernels.params)[0] for frame in frames]
    best = math.inf
    for _ in range(rounds):
        start = time.perf_counter()
        for frame in prepared:
            score(
                poses,
                scratch,
                trig,
                out,
                copying,
                (0, 0),
                frame,
                kernels.workspace(frame, STEP_BLOCK),
                0,
                n,
                False,
                NO_SINCE,
            )
        best = min(best, (time.perf_counter() - start) / len(prepared))
    return best / n * 1e9


def time_goal_direction(n: int = 10_000, frames: int = 50, rounds: int = 5) -> dict:
    """ns per particle of the likelihood stage and of the whole fused step with each model, and the
    goal-direction model's ratios to the landmark model's ({"likelihood": {...}, "step": {...}}, each with
    "goal_direction", "landmarks", "ratio")."""
    field = spl()
    goals, posts = _frames(field, np.random.default_rng(1), frames)
    timings: dict = {"likelihood": {}, "step": {}}
    for name, model, batch in (
        ("goal_direction", GoalDirectionSensorModel(field), goals),
        ("landmarks", LandmarkSensorModel(field), posts),
    ):
        pf = ParticleFilter(
            field, VelocityLinear(), model, n_particles=n, seed=0, resample_threshold=1.0, augmented=None
        )
        pf.reset_around(TRUE_POSE, (0.3, 0.3, 0.2))
        poses = pf.poses.copy()
        _likelihood_ns_per_particle(model, poses, batch[:1], 1)  # compiled before the clock runs
        timings["likelihood"][name] = _likelihood_ns_per_particle(model, poses, batch, rounds)
        pf.step(MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)), batch[0])
        timings["step"][name] = _ns_per_particle(pf, batch, rounds)
    for figures in timings.values():
        figures["ratio"] = figures["goal_direction"] / figures["landmarks"]
    return timings


def main() -> None:
    """Print the benchmark's line."""
    t = time_goal_direction()
    like, step = t["likelihood"], t["step"]
    print(
        f"10 000 particles, ns/particle, goal direction (2 bearings) / landmarks (4 goalposts): likelihood "
        f"{like['goal_direction']:.1f} / {like['landmarks']:.1f} (ratio {like['ratio']:.2f}), fused step "
        f"{step['goal_direction']:.1f} / {step['landmarks']:.1f} (ratio {step['ratio']:.2f})"
    )


if __name__ == "__main__":
    main()
