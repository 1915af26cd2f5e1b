"""Results that a change of structure must leave bit for bit: the walk demo, the replay and the filter's
variants on fixed seeds, recorded once in `tests/data/same_results.npz` and compared by
`tests/test_same_results.py`.

    python tests/same_results.py --save     # record (only when results are meant to change; say why)

Each case returns named arrays (estimates, entropy, quality, final particles and weights) from public calls
only, so the cases keep running whatever moves inside the packages.
"""

from __future__ import annotations

import argparse
import platform
from dataclasses import replace
from pathlib import Path

import numpy as np

from demos.walk import run_walk
from demos.walk_log import to_robot_log
from demos.walk_sim import WalkScenario, simulate
from field import spl
from mcl import ParticleFilter
from mcl.tools.replay import replay
from motion_models import AdaptiveMotion, MotionInput, VelocityLinear
from proprioception.collision import NO_COLLISION, CollisionPercept
from sensing import LandmarkSensorModel

PATH = Path(__file__).parent / "data" / "same_results.npz"
SHORT = replace(WalkScenario(), duration=12.0, kidnap_time=6.0)


def _walk(model: str, seed: int, **options) -> dict[str, np.ndarray]:
    series = run_walk(model, 300, seed=seed, series=True, **options)["series"]
    return {"estimates": series["estimates"], "entropy": series["entropy"]}


def _filter_variant(seed: int, **options) -> dict[str, np.ndarray]:
    """The filter driven directly (predict, correct, estimate, entropy) on a simulated walk."""
    log = simulate(SHORT, seed)
    collide = isinstance(options.get("motion"), AdaptiveMotion)
    pf = ParticleFilter(
        SHORT.field,
        options.pop("motion", VelocityLinear()),
        LandmarkSensorModel(SHORT.field),
        n_particles=options.pop("particles", 400),
        seed=seed,
        **options,
    )
    pf.reset_uniform("own_half")
    frames = {frame.step: frame for frame in log.frames}
    n = log.times.shape[0]
    estimates, entropy = np.empty((n, 3)), np.empty((n, 2))
    for k in range(n):
        frame = frames.get(k)
        u = MotionInput(dt=log.dt, command=tuple(log.commands[k]), collision=_collision(k) if collide else None)
        if k % 2:
            pf.step(u, frame.observations if frame is not None else None)
        else:
            pf.predict(u)
            if frame is not None:
                pf.correct(frame.observations)
        estimates[k] = pf.estimate().pose
        h = pf.entropy()
        entropy[k] = (h.position, h.orientation)
    return {"estimates": estimates, "entropy": entropy, "poses": pf.poses.copy(), "weights": pf.weights.copy()}


def _collision(k: int) -> CollisionPercept:
    """A left-side collision from 3 s to 4 s and one on both sides from 8 s to 8.5 s (at 100 Hz)."""
    if 300 <= k < 400:
        return CollisionPercept(left=True, s_rel_left=1.5, rate=0.5, recent_left=True)
    if 800 <= k < 850:
        return CollisionPercept(
            left=True, right=True, s_rel_left=1.2, s_rel_right=1.3, rate=0.8, recent_left=True, recent_right=True
        )
    return NO_COLLISION


def _replay(seed: int) -> dict[str, np.ndarray]:
    log = to_robot_log(simulate(SHORT, seed), latency=0.05)
    result = replay(log, spl(), particles=300, seed=seed)
    return {
        "estimates": result.estimates,
        "entropy": result.entropy,
        "quality": result.quality.astype(np.int64),
        "lost": result.lost.astype(np.int64),
    }


CASES = {
    "walk_velocity_linear": lambda: _walk("velocity-linear", 3, scenario=SHORT),
    "walk_constant_lines_view": lambda: _walk("constant", 5, scenario=replace(SHORT, lines=True), view=True),
    "filter_threads_2": lambda: _filter_variant(7, threads=2),
    "filter_fast": lambda: _filter_variant(8, fast=True),
    "filter_adaptive_multinomial": lambda: _filter_variant(9, motion=AdaptiveMotion(), resampling="multinomial"),
    "replay_latency": lambda: _replay(4),
}

# Cases whose results are promised to rounding only (fast-math: how LLVM contracts and reassociates the arithmetic
# depends on the code around it), compared to 1e-9 relative.
TO_ROUNDING = {"filter_fast"}


def machine() -> str:
    """What the recorded bits may depend on: the processor and the numeric libraries."""
    import numba

    return f"{platform.machine()} {platform.processor()} numpy {np.__version__} numba {numba.__version__}"


def compute() -> dict[str, np.ndarray]:
    arrays = {}
    for name, case in CASES.items():
        for key, value in case().items():
            arrays[f"{name}/{key}"] = np.asarray(value)
    return arrays


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python tests/same_results.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--save", action="store_true", help=f"record the results in {PATH}")
    args = parser.parse_args(argv)
    arrays = compute()
    if args.save:
        PATH.parent.mkdir(exist_ok=True)
        np.savez_compressed(PATH, __machine__=np.array(machine()), **arrays)
        print(f"recorded {len(arrays)} arrays in {PATH}")
    else:
        for name, value in arrays.items():
            print(name, value.shape, value.dtype)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
