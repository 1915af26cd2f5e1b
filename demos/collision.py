"""`robocup-mcl demo collision`: Hoffmann's experiments (section 4), reproduced and measured.

    robocup-mcl demo collision --case single --model adaptive --rrd recordings/collision.rrd   # one run
    robocup-mcl demo collision --case single --seeds 0-19          # both models, no vision, 20 seeds
    robocup-mcl demo collision --case single --seeds 0-19 --vision # with landmark observations
    robocup-mcl demo collision --detection                         # the collision detector alone
    robocup-mcl demo collision --particle-sweep 50,100,200,500     # claim (a): fewer particles
    robocup-mcl demo collision --cost                              # predict cost, adaptive / velocity-linear
    robocup-mcl demo collision --report [--json] [--save PATH]     # all of the figures of docs/papers/hoffmann.md
    robocup-mcl demo collision --tune-baseline [--seeds 2000-2019]  # velocity-linear's widening, training robots
    robocup-mcl demo collision --mismatch [--seeds 4000-4039]       # the robustness table, held-out robots

The robot walks forward at 200 mm/s for 10 s; the filter's particles all start at the true pose (section 4.1).
Cases: "none" (4.1), "single" (4.2: a collision of about 2 s on the left, during which the robot is held back,
then stopped and turning toward the obstacle), "double" (4.3: left, then right, in brief succession). Each
seed shifts the collision times (±0.5 s) and draws the severities. The collision percept comes from the
detector (`proprioception.collision`) fed with the simulated servo data, its reference learned from three minutes of
simulated free walking (seed 1000, never a test seed).

With vision, augmented MCL's injection is off unless `--injection` is given: the figures then show what the
motion model alone does for re-localization, as the paper argues it. (With injection on, a filter can also
recover by re-seeding; the relocalization's anchor is carried by the motion input, which does not know of the
turn a collision causes, so the re-seeded poses are weighed by a prior that is off by that turn: see the
README.)

Measured per run: grid entropy (eq. 27) of position and orientation each step; without vision, whether the true
pose lies inside the smallest region holding 95 % of the belief (`mcl.estimate.credible_region_contains`), at
each step from the collision's start on; with vision, the position error of the estimate and the time from the
collision's end until that error is below 0.2 m (0 when it never exceeded it).

Model mismatch. `--tune-baseline` runs velocity-linear with its β widened by `WIDENINGS` on training robots
(`TRAINING_SEEDS`, the simulator's mismatched physics: each robot drawn from `demos.collision_sim.MISMATCH_RANGES`)
and names the best factor for the 95 % region and for the log score without vision, and for the error with
vision and injection (`BASELINE_WIDEN` holds them). `--mismatch` runs the held-out robots (`HELD_OUT_SEEDS`):
the paper's model with its fitted parameters ("adaptive"), the pivot variant ("adaptive-pivot", `PIVOT_CREEP`),
the model with the settings the fit replaced ("adaptive-hand-set") and velocity-linear at its best region and
its best log score, at the nominal and the mismatched physics, per bin of the simulated stop turn
(`TURN_BINS`), then the particle sweep with vision and injection (`SWEEP_PARTICLES`). Each robot's detector
reference is learned from its own free walk (`robot_reference`). The log score is the log of the belief's
density at the true pose (`mcl.estimate.belief_log_density`), averaged over the steps from the collision on:
unlike the region, it ranks a tight cloud that holds the truth above a wide one.

Entropy grid: 5 cm cells and 5° bins. The paper does not give its grid; the filter's default (10 cm, 10°) is
coarser than the whole no-collision cloud of 100 particles for most of the run, which would make both models
score 0 bits.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time
from dataclasses import replace

import numpy as np

from field.angles import wrap_angles
from mcl import AugmentedMCL, Grid, ParticleFilter
from mcl.estimate import belief_log_density, credible_region_contains
from motion_models import AdaptiveMotion, MotionInput, VelocityLinear
from motion_models.adaptive import STATES, MobilityTransitions
from proprioception.collision import CollisionDetector, CollisionReference, detect, learn_reference
from sensing import LandmarkSensorModel

from .collision_sim import (
    BOTH,
    JOINTS,
    LEFT,
    RIGHT,
    SIDE_NAMES,
    SLIPPAGE,
    STOPPED,
    CollisionScenario,
    jitter_events,
    paper_case,
    random_collisions,
    simulate,
)
from .walk import parse_seeds

PIVOT_CREEP = 0.494  # the variant's stop_creep: results/adaptive_fit.json, "defaults", rounded as the β are
# The settings the fit replaced (hand-set before `robocup-mcl fit adaptive` fitted them): eq. 10's free-walking
# noise, and no way out of a collision state while the percept says "frequent" (the default "frequent" rates
# without their fitted episode ends). The variant "adaptive-hand-set".
HAND_SET_ODOMETRY = (1.0, 0.6, 0.6, 0.6)


def _hand_set() -> AdaptiveMotion:
    transitions = MobilityTransitions()
    frequent = tuple(entry for entry in transitions.frequent if entry[1] != "free")
    return AdaptiveMotion(odometry=HAND_SET_ODOMETRY, transitions=replace(transitions, frequent=frequent))


MODELS = {
    "velocity-linear": VelocityLinear,
    "adaptive": AdaptiveMotion,
    "adaptive-step": lambda: AdaptiveMotion(redraw="step"),
    "adaptive-pivot": lambda: AdaptiveMotion(stop_creep=PIVOT_CREEP),
    "adaptive-hand-set": _hand_set,
}
WIDENINGS = (
    1.0,
    2.0,
    4.0,
    8.0,
    12.0,
    16.0,
    24.0,
    32.0,
    48.0,
)  # velocity-linear's β times these, tuned on training seeds
TRAINING_SEEDS = "2000-2019"  # the robots the baseline is tuned on (the fit uses 2000-2039)
HELD_OUT_SEEDS = "4000-4039"  # the robots of the robustness table, run once
TURN_BINS = ((0.05, 0.4), (0.4, 0.7), (0.7, 1.05))  # the simulated stop turn, share of |v| / foot separation
SWEEP_PARTICLES = {"adaptive": (10, 50, 200), "velocity-linear": (10, 50, 200, 500)}  # with vision
# The widening of velocity-linear's β chosen on the training seeds (`--tune-baseline`,
# results/collision_baseline_tuning.json): for the truth inside the 95 % region and for the log score without
# vision, and for the position error with vision and injection.
BASELINE_WIDEN = {"containment": 24.0, "log_score": 16.0, "rmse": 16.0}


def make_model(model: str, widen: float = 1.0):
    """The motion model of a run: `MODELS[model]`, velocity-linear with its four β times `widen`."""
    if model == "velocity-linear":
        base = VelocityLinear()
        return replace(
            base, beta1=base.beta1 * widen, beta2=base.beta2 * widen, beta3=base.beta3 * widen, beta4=base.beta4 * widen
        )
    return MODELS[model]()


CASES = ("none", "single", "double")
GRID = Grid(position_cell=0.05, orientation_bins=72)
RELOCALIZED = 0.2  # m
REFERENCE_SEED = 1000  # the free walk the detector's reference is learned from


def free_walk_reference(seed: int = REFERENCE_SEED, duration: float = 180.0) -> CollisionReference:
    """The detector's reference, learned from `duration` s of simulated free walking at varied requests."""
    log = simulate(CollisionScenario(duration=duration, command=None), seed)
    return learn_reference(log.servo_commands, log.servo_readings, log.phase, log.commands, log.joint_sides)


ROBOT_WALK_OFFSET = 100_000  # a robot's own free walk runs on seed + this (its robot drawn from `seed`)


@functools.lru_cache(maxsize=256)  # a reference per robot (1.4 KB); the tables cycle through 20 robots
def robot_reference(physics: str, seed: int) -> CollisionReference:
    """The detector's reference for the robot of a run: with nominal physics the one robot's free walk
    (`free_walk_reference`); with mismatched physics the robot drawn for `seed` walks freely for three minutes
    (its own servo noise, on seed + `ROBOT_WALK_OFFSET`) and the reference is learned from that, as a team
    learns it on each robot."""
    if physics == "nominal":
        return free_walk_reference()
    log = simulate(
        CollisionScenario(duration=180.0, command=None, physics=physics, robot_seed=seed), seed + ROBOT_WALK_OFFSET
    )
    return learn_reference(log.servo_commands, log.servo_readings, log.phase, log.commands, log.joint_sides)


def case_scenario(case: str, seed: int, vision: bool = False, physics: str = "nominal") -> CollisionScenario:
    """The paper's case with this seed's collision times and severities (and, with `physics="mismatch"`, the
    robot and world drawn for this seed)."""
    scenario = paper_case(case, vision=vision, physics=physics)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 3]))
    return replace(scenario, events=jitter_events(scenario.events, rng))


def run_case(
    case: str,
    model: str,
    seed: int,
    reference: CollisionReference | None,
    particles: int = 100,
    vision: bool = False,
    rrd: str | None = None,
    containment: bool | None = None,
    injection: bool = False,
    physics: str = "nominal",
    widen: float = 1.0,
) -> dict:
    """One run of a case with one model; returns the figures (and per-step series under "series"). With
    `reference` None, the detector's reference is the run's robot's own (`robot_reference`)."""
    scenario = case_scenario(case, seed, vision, physics)
    log = simulate(scenario, seed)
    if reference is None:
        reference = robot_reference(physics, seed)
    motion = make_model(model, widen)
    pf = ParticleFilter(
        scenario.field,
        motion,
        LandmarkSensorModel(scenario.field),
        n_particles=particles,
        seed=seed,
        grid=GRID,
        augmented=AugmentedMCL() if injection else None,
    )
    pf.reset_around(log.start, sigma=(0.0, 0.0, 0.0))
    detector = CollisionDetector(reference)
    containment = (not vision) if containment is None else containment
    recorder = None
    if rrd:
        from mcl.tools.recording import Recorder

        recorder = Recorder(rrd, scenario.field, particles_every=2, blueprint=collision_blueprint())
        _style_series(recorder)
    n = log.times.shape[0]
    estimates = np.empty((n, 3))
    entropy = np.empty((n, 2))
    s_rel = np.empty((n, 2))
    belief = np.full((n, 5), np.nan)
    contained = np.zeros(n, dtype=bool)
    log_density = np.zeros(n)
    frames = {frame.step: frame for frame in log.frames}
    stateful = pf.motion_state is not None
    started = time.perf_counter()
    for k in range(n):
        percept = detector.update(log.servo_commands[k], log.servo_readings[k], log.phase[k], log.commands[k])
        s_rel[k] = (percept.s_rel_left, percept.s_rel_right)
        pf.predict(MotionInput(dt=log.dt, command=tuple(log.commands[k]), collision=percept))
        frame = frames.get(k)
        if frame is not None:
            pf.correct(frame.observations)
        estimates[k] = pf.estimate().pose
        h = pf.entropy()
        entropy[k] = (h.position, h.orientation)
        if stateful:
            belief[k] = motion.state_belief(pf.motion_state, pf.weights)
        if containment:
            contained[k] = credible_region_contains(pf.poses, pf.weights, log.truth[k])
            log_density[k] = belief_log_density(pf.poses, pf.weights, log.truth[k])
        if recorder is not None:
            recorder.log_step(
                k,
                float(log.times[k]),
                pf,
                truth=log.truth[k],
                observations=frame.observations if frame is not None else None,
                entropy=h,
            )
            values = {
                "proprioception/s_rel/left": s_rel[k, 0],
                "proprioception/s_rel/right": s_rel[k, 1],
                "proprioception/collision_threshold": 1.0,
            }
            if stateful:
                values.update({f"motion/state_belief/{name}": belief[k, i] for i, name in enumerate(STATES)})
            recorder.log_scalars(values)
            hit = bool(percept.left or percept.right)
            recorder.log_change(
                "collision",
                hit,
                "collision detected (S_rel > 1)" if hit else "no collision",
                level="WARN" if hit else "INFO",
                initial=False,
            )
    elapsed = time.perf_counter() - started
    if recorder is not None:
        recorder.close()
    result = summarize(
        case,
        model,
        seed,
        particles,
        vision,
        log,
        estimates,
        entropy,
        contained if containment else None,
        belief,
        s_rel,
        elapsed,
        rrd,
    )
    stops = [e for e in log.events if e.mode == STOPPED]
    low, high = log.scenario.stop_turn
    share = low + stops[0].severity * (high - low) if stops else None
    mean = np.average(pf.poses[:, :2], weights=pf.weights, axis=0)
    spread = math.sqrt(float(np.average(((pf.poses[:, :2] - mean) ** 2).sum(axis=1), weights=pf.weights)))
    if containment:
        start = log.events[0].start if log.events else 1.0
        result["log_score"] = float(log_density[log.times > start].mean())
    result.update(
        physics=physics,
        widen=widen,
        stop_turn_share=share,
        foot_separation_m=float(log.scenario.foot_separation),
        final_spread_m=spread,
    )
    return result


STATE_COLORS = ((80, 220, 120), (80, 200, 255), (255, 200, 40), (255, 80, 200), (230, 60, 60))


def _style_series(recorder) -> None:
    import rerun as rr

    for name, color in zip(STATES, STATE_COLORS):
        recorder.stream.log(f"motion/state_belief/{name}", rr.SeriesLines(names=name, colors=[color]), static=True)
    for path, name, color in (
        ("proprioception/s_rel/left", "S_rel left", (80, 160, 255)),
        ("proprioception/s_rel/right", "S_rel right", (255, 140, 40)),
        ("proprioception/collision_threshold", "threshold", (150, 150, 150)),
    ):
        recorder.stream.log(path, rr.SeriesLines(names=name, colors=[color]), static=True)


def collision_blueprint():
    from mcl.tools.recording import default_blueprint

    return default_blueprint(
        (
            ("/entropy", "entropy [bits]"),
            ("/proprioception", "S_rel (collision when > 1)"),
            ("/motion/state_belief", "mobility state belief"),
            ("/error", "error [m, rad]"),
        )
    )


def summarize(
    case, model, seed, particles, vision, log, estimates, entropy, contained, belief, s_rel, elapsed, rrd
) -> dict:
    times = log.times
    events = log.events
    collision_start = events[0].start if events else None
    collision_end = events[-1].end if events else None
    position_error = np.hypot(*(estimates[:, :2] - log.truth[:, :2]).T)
    heading_error = np.abs(wrap_angles(estimates[:, 2] - log.truth[:, 2]))
    seconds = np.arange(1, int(round(times[-1])) + 1)
    at_second = np.searchsorted(times, seconds - 1e-9)
    result = {
        "case": case,
        "model": model,
        "seed": seed,
        "particles": particles,
        "vision": vision,
        "collision_start_s": collision_start,
        "collision_end_s": collision_end,
        "entropy_position_bits": [float(entropy[i, 0]) for i in at_second],
        "entropy_orientation_bits": [float(entropy[i, 1]) for i in at_second],
        "final_position_error_m": float(position_error[-1]),
        "final_heading_error_deg": math.degrees(float(heading_error[-1])),
        "position_rmse_m": float(np.sqrt(np.mean(position_error**2))),
        "ms_per_step": 1e3 * elapsed / times.shape[0],
        "rrd": rrd,
    }
    after = times > (collision_start if collision_start is not None else 1.0)
    if contained is not None:
        result["contained_share"] = float(contained[after].mean())
    if collision_start is not None:
        result["position_rmse_after_collision_m"] = float(np.sqrt(np.mean(position_error[after] ** 2)))
        result["max_position_error_m"] = float(position_error[after].max())
    if vision and collision_end is not None:
        from_end = np.flatnonzero(times >= collision_end)
        below = from_end[position_error[from_end] < RELOCALIZED]
        # 0 when the first step after the collision's end is already within RELOCALIZED.
        result["relocalization_s"] = None if below.size == 0 else float(times[below[0]] - times[from_end[0]])
    if not np.isnan(belief).all():
        result["state_belief_at_end_of_collision"] = (
            None
            if collision_end is None
            else dict(zip(STATES, belief[min(np.searchsorted(times, collision_end), len(times) - 1)].round(3).tolist()))
        )
        result["free_belief_at_end"] = float(belief[-1, 0])
    result["series"] = {
        "times": times,
        "entropy": entropy,
        "s_rel": s_rel,
        "belief": belief,
        "position_error": position_error,
        "contained": contained,
    }
    return result


# -- the detector's figures -------------------------------------------------------------------------------
def detection_figures(
    reference: CollisionReference | None,
    seeds=(0, 1, 2),
    minutes: float = 10.0,
    within: float = 0.3,
    physics: str = "nominal",
) -> dict:
    """Collision detection on long simulated walks (varied requests, random collisions of every kind and side).

    With `physics="mismatch"` each seed is a robot drawn by the mismatched physics, detected with the reference
    learned from its own free walk (`robot_reference`; `reference` is then unused), and the figures are also
    given per subset of the joints the obstacle holds ("by_held_joints").

    detected: share of contact episodes (hindrance, stop, push; slippage has no contact) with a collision
    percept within `within` s of the start; side correct: share of detected episodes whose side (eq. 26, from
    the percept's recent sides, `within` s after the first detection) is the true one; false alarms: rising
    edges of the percept outside every episode (and the 0.5 s after it), per minute of free walking.
    """
    detected = episodes = side_ok = false_alarms = 0
    free_frames = 0
    delays = []
    confusion: dict[str, int] = {}
    by_joints: dict[str, list[int]] = {}
    for seed in seeds:
        rng = np.random.default_rng(np.random.SeedSequence([seed, 7]))
        duration = 60.0 * minutes
        events = random_collisions(duration, rng)
        log = simulate(
            CollisionScenario(duration=duration, command=None, events=events, physics=physics, robot_seed=seed), seed
        )
        robot = robot_reference(physics, seed) if physics == "mismatch" else reference
        out = detect(robot, log.servo_commands, log.servo_readings, log.phase, log.commands)
        joints = "+".join(JOINTS[j] for j in log.scenario.held_joints)
        tally = by_joints.setdefault(joints, [0, 0])
        collision = out["collision"].any(axis=1)
        start_times = log.times - log.dt
        busy = np.zeros(start_times.shape[0], dtype=bool)
        for event in events:
            busy |= (start_times >= event.start) & (start_times < event.end + 0.5)
        rising = collision & ~np.r_[False, collision[:-1]]
        false_alarms += int((rising & ~busy).sum())
        free_frames += int((~busy).sum())
        for group in _episodes(events):
            first = group[0]
            if first.mode == SLIPPAGE:
                continue
            episodes += 1
            tally[0] += 1
            window = np.flatnonzero((start_times >= first.start) & (start_times < first.start + within) & collision)
            if window.size == 0:
                continue
            detected += 1
            tally[1] += 1
            delays.append(float(start_times[window[0]] - first.start))
            k = min(window[0] + int(round(within / log.dt)), start_times.shape[0] - 1)
            left, right = out["recent"][k]
            side = BOTH if (left and right) else LEFT if left else RIGHT if right else 0
            side_ok += int(side == first.side)
            key = f"{SIDE_NAMES[first.side]}->{SIDE_NAMES[side]}"
            confusion[key] = confusion.get(key, 0) + 1
    free_minutes = free_frames / 100.0 / 60.0
    return {
        "seeds": list(seeds),
        "minutes_per_seed": minutes,
        "episodes": episodes,
        "detected_share": detected / episodes if episodes else None,
        "median_delay_s": float(np.median(delays)) if delays else None,
        "side_correct_share": side_ok / detected if detected else None,
        "false_alarms": false_alarms,
        "free_minutes": free_minutes,
        "false_alarms_per_minute": false_alarms / free_minutes if free_minutes else None,
        "side_confusion": dict(sorted(confusion.items())),
        "physics": physics,
        "by_held_joints": {
            joints: {"episodes": n, "detected_share": hit / n if n else None}
            for joints, (n, hit) in sorted(by_joints.items())
        },
    }


def region_coverage(counts=(30, 100, 200), draws: int = 400, seed: int = 5) -> dict:
    """How often the 95 % region of `mcl.estimate.credible_region_contains` holds a pose drawn from the same
    distribution as its particles (a Gaussian cloud, σ 0.3 m, 0.2 m, 0.2 rad), with each particle's own kernel
    left out of the level (the estimate the tables use) and left in (the biased estimate of earlier figures),
    per particle count; `draws` clouds each."""
    rows = []
    for n in counts:
        rng = np.random.default_rng(seed)
        inside = {"leave_one_out": 0, "own_kernel_in": 0}
        sigma = np.array([0.3, 0.2, 0.2])
        for _ in range(draws):
            poses = rng.standard_normal((n, 3)) * sigma
            truth = rng.standard_normal(3) * sigma
            weights = np.ones(n)
            inside["leave_one_out"] += credible_region_contains(poses, weights, truth)
            inside["own_kernel_in"] += credible_region_contains(poses, weights, truth, leave_one_out=False)
        rows.append({"particles": n, **{k: v / draws for k, v in inside.items()}})
    return {"draws": draws, "seed": seed, "mass": 0.95, "rows": rows}


def _episodes(events):
    """Events that follow each other without a gap (a hindrance turning into a stop) form one episode."""
    groups = []
    for event in events:
        if groups and abs(groups[-1][-1].end - event.start) < 1e-9 and event.side == groups[-1][-1].side:
            groups[-1].append(event)
        else:
            groups.append([event])
    return groups


# -- aggregation ------------------------------------------------------------------------------------------
def _median(values):
    """Median with None (never happened, e.g. never re-localized) counted as infinitely late."""
    values = [math.inf if v is None else v for v in values]
    return float(np.median(values)) if values else None


def compare_entropy(runs_vl: list[dict], runs_adaptive: list[dict]) -> dict:
    """Case none: per second, median position entropy of both models, and the share of seeds on which the
    adaptive model's position entropy is below velocity-linear's at every second after the first."""
    per_second_vl = np.array([r["entropy_position_bits"] for r in runs_vl])
    per_second_ad = np.array([r["entropy_position_bits"] for r in runs_adaptive])
    below = (per_second_ad[:, 1:] < per_second_vl[:, 1:]).all(axis=1)
    return {
        "seconds": list(range(1, per_second_vl.shape[1] + 1)),
        "velocity_linear_median_bits": np.median(per_second_vl, axis=0).round(3).tolist(),
        "adaptive_median_bits": np.median(per_second_ad, axis=0).round(3).tolist(),
        "seeds_below_every_second_after_first": int(below.sum()),
        "seeds": int(below.size),
        "median_below_every_second_after_first": bool(
            (np.median(per_second_ad, axis=0)[1:] < np.median(per_second_vl, axis=0)[1:]).all()
        ),
    }


def case_summary(runs: list[dict]) -> dict:
    keys = (
        "contained_share",
        "relocalization_s",
        "position_rmse_after_collision_m",
        "max_position_error_m",
        "final_position_error_m",
        "final_heading_error_deg",
        "position_rmse_m",
        "ms_per_step",
    )
    summary = {}
    for key in keys:
        values = [r.get(key) for r in runs if key in r]
        if not values:
            continue
        numbers = [v for v in values if v is not None]
        summary[key] = {
            "median": _median(values),
            "mean": float(np.mean(numbers)) if numbers else None,
            "min": min(numbers) if numbers else None,
            "max": max(numbers) if numbers else None,
            "never": values.count(None),
        }
    return summary


def predict_cost(particles: int = 1000, steps: int = 2000, repeats: int = 5) -> dict:
    """Time per predict step at N particles, adaptive versus velocity-linear, interleaved in the same run."""
    from proprioception.collision import CollisionPercept

    percept = CollisionPercept(left=True, s_rel_left=2.0, rate=0.3, recent_left=True)
    u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.0), collision=percept)
    models = {"velocity-linear": VelocityLinear(), "adaptive": AdaptiveMotion()}
    best = {name: math.inf for name in models}
    rng = np.random.default_rng(0)
    poses = np.zeros((particles, 3))
    state = models["adaptive"].particle_state(particles)
    for name, model in models.items():  # compile and warm up
        model.predict(poses, u, rng, state=state) if name == "adaptive" else model.predict(poses, u, rng)
    for _ in range(repeats):
        for name, model in models.items():
            started = time.perf_counter()
            if name == "adaptive":
                for _ in range(steps):
                    model.predict(poses, u, rng, state=state)
            else:
                for _ in range(steps):
                    model.predict(poses, u, rng)
            best[name] = min(best[name], (time.perf_counter() - started) / steps)
    return {
        "particles": particles,
        "velocity_linear_us": 1e6 * best["velocity-linear"],
        "adaptive_us": 1e6 * best["adaptive"],
        "ratio": best["adaptive"] / best["velocity-linear"],
    }


def run_cases(
    cases, models, seeds, reference, particles, vision, injection: bool = False, progress: bool = False
) -> dict:
    """Every case with every model over `seeds` (progress: a bar over the runs on stderr)."""
    from mcl.tools.cli_checks import progress_bar

    out = {}
    bar = progress_bar(enabled=progress, total=len(cases) * len(models) * len(seeds), desc="collision", unit="run")
    for case in cases:
        out[case] = {}
        for model in models:
            runs = []
            for seed in seeds:
                bar.set_postfix_str(f"{case}, {model}, seed {seed}")
                runs.append(run_case(case, model, seed, reference, particles, vision, injection=injection))
                bar.update(1)
            out[case][model] = {"runs": runs, "summary": case_summary(runs)}
        if case == "none" and "velocity-linear" in models and "adaptive" in models:
            out[case]["entropy"] = compare_entropy(out[case]["velocity-linear"]["runs"], out[case]["adaptive"]["runs"])
    bar.close()
    return out


WARM_UP_PARTICLES = 16


def warm_up_collision(case: str, models, reference, vision: bool, injection: bool = False, progress: bool = False):
    """Compile (or load from numba's cache) the kernels the runs reach, one model at a time, on short runs of a few
    particles, before anything is timed; returns the `mcl.numba_cache.WarmUp` (a machine's first run says so on
    stderr, and "compiled in N s" after)."""
    from mcl.estimate import summary_fill
    from mcl.numba_cache import warm_up
    from motion_models.adaptive import adaptive_move_drawing
    from motion_models.kernels import move_range

    stages = [
        (
            f"{model} model",
            lambda model=model: run_case(case, model, 0, reference, WARM_UP_PARTICLES, vision, injection=injection),
        )
        for model in models
    ]
    return warm_up(stages, (move_range, adaptive_move_drawing, summary_fill), progress=progress)


def particle_sweep(counts, seeds, reference, cases=("single", "double"), baseline: int = 500) -> dict:
    """Claim (a): the smallest particle count at which the adaptive model, with vision, is as accurate as
    velocity-linear at `baseline` particles (median over seeds and cases of the position RMSE from the
    collision's start on)."""

    def accuracy(model, n):
        runs = [run_case(case, model, seed, reference, n, vision=True) for case in cases for seed in seeds]
        return _median([r["position_rmse_after_collision_m"] for r in runs]), _median(
            [r["relocalization_s"] for r in runs]
        )

    target, target_reloc = accuracy("velocity-linear", baseline)
    rows = []
    needed = None
    for n in sorted(counts):
        rmse, reloc = accuracy("adaptive", n)
        rows.append({"particles": n, "median_rmse_m": rmse, "median_relocalization_s": reloc})
        if needed is None and rmse is not None and rmse <= target:
            needed = n
    return {
        "velocity_linear": {"particles": baseline, "median_rmse_m": target, "median_relocalization_s": target_reloc},
        "adaptive": rows,
        "adaptive_particles_needed": needed,
        "cases": list(cases),
        "seeds": list(seeds),
    }


# -- mismatch: the baseline tuned, the robustness table -------------------------------------------------
def _median_of(runs: list[dict], key: str):
    return _median([r[key] for r in runs]) if runs else None


def tune_baseline(
    seeds, cases=("single", "double"), widenings=WIDENINGS, particles: int = 100, progress: bool = False
) -> dict:
    """Velocity-linear's widening on training robots (mismatched physics): per factor, the median share of
    steps with the truth inside the 95 % region (no vision) and the median position RMSE from the collision on
    (vision, augmented MCL's injection on), both at `particles`; the best factor for each."""
    from mcl.tools.cli_checks import progress_bar

    bar = progress_bar(enabled=progress, total=2 * len(widenings) * len(cases) * len(seeds), desc="tuning", unit="run")
    rows = []
    for widen in widenings:
        contained, rmse = [], []
        for case in cases:
            for seed in seeds:
                contained.append(
                    run_case(case, "velocity-linear", seed, None, particles, physics="mismatch", widen=widen)
                )
                rmse.append(
                    run_case(
                        case,
                        "velocity-linear",
                        seed,
                        None,
                        particles,
                        vision=True,
                        injection=True,
                        physics="mismatch",
                        widen=widen,
                    )
                )
                bar.update(2)
        rows.append(
            {
                "widen": widen,
                "contained_share_median": _median_of(contained, "contained_share"),
                "log_score_median": _median_of(contained, "log_score"),
                "rmse_after_collision_median_m": _median_of(rmse, "position_rmse_after_collision_m"),
            }
        )
    bar.close()
    best_contained = max(rows, key=lambda r: r["contained_share_median"])["widen"]
    best_score = max(rows, key=lambda r: r["log_score_median"])["widen"]
    best_rmse = min(rows, key=lambda r: r["rmse_after_collision_median_m"])["widen"]
    return {
        "seeds": list(seeds),
        "cases": list(cases),
        "particles": particles,
        "rows": rows,
        "best": {"containment": best_contained, "log_score": best_score, "rmse": best_rmse},
    }


def _turn_bin(share: float | None) -> str | None:
    for low, high in TURN_BINS:
        if share is not None and low <= share < high + 1e-12:
            return f"{low:g}-{high:g}"
    return None


def mismatch_table(
    seeds, cases=("single", "double"), particles: int = 100, counts=None, progress: bool = False
) -> dict:
    """The robustness table on held-out robots: per case, the share of steps with the truth inside the 95 %
    region (no vision, `particles`), median over seeds, at the nominal simulator and with mismatched physics
    (all seeds, and per bin of the simulated stop turn), for the paper's model with fitted β, the variants and
    velocity-linear at its best widening; then, with vision and injection on, the median position RMSE from the
    collision on at each particle count for the adaptive model, the pivot variant and the best velocity-linear,
    and the smallest count at which velocity-linear is as accurate as the adaptive model at each count."""
    from mcl.tools.cli_checks import progress_bar

    counts = SWEEP_PARTICLES if counts is None else counts
    baselines = dict.fromkeys((BASELINE_WIDEN["containment"], BASELINE_WIDEN["log_score"]))  # once each
    models = (("adaptive", 1.0), ("adaptive-pivot", 1.0), ("adaptive-hand-set", 1.0)) + tuple(
        ("velocity-linear", w) for w in baselines
    )
    sweep_models = (("adaptive", 1.0), ("velocity-linear", BASELINE_WIDEN["rmse"]))
    total = len(cases) * len(seeds) * (2 * len(models) + sum(len(counts[m]) for m, _ in sweep_models))
    bar = progress_bar(enabled=progress, total=total, desc="mismatch", unit="run")
    containment: dict = {}
    sweep: dict = {}
    runs_out: list[dict] = []
    for case in cases:
        containment[case] = {}
        for model, widen in models:
            label = model if model != "velocity-linear" else f"velocity-linear x{widen:g}"
            row: dict = {}
            for physics in ("nominal", "mismatch"):
                runs = []
                for seed in seeds:
                    runs.append(run_case(case, model, seed, None, particles, physics=physics, widen=widen))
                    bar.update(1)
                runs_out += [_brief(r) for r in runs]
                row[physics] = _share_summary(runs)
                if physics == "mismatch":
                    row["bins"] = {
                        f"{low:g}-{high:g}": _share_summary(
                            [r for r in runs if _turn_bin(r["stop_turn_share"]) == f"{low:g}-{high:g}"]
                        )
                        for low, high in TURN_BINS
                    }
            containment[case][label] = row
    for model, widen in sweep_models:
        label = model if model != "velocity-linear" else f"velocity-linear x{widen:g}"
        sweep[label] = {}
        for n in counts[model]:
            runs = []
            for case in cases:
                for seed in seeds:
                    runs.append(
                        run_case(
                            case, model, seed, None, n, vision=True, injection=True, physics="mismatch", widen=widen
                        )
                    )
                    bar.update(1)
            sweep[label][str(n)] = {
                "rmse_median_m": _median_of(runs, "position_rmse_after_collision_m"),
                "relocalization_median_s": _median_of(runs, "relocalization_s"),
            }
    bar.close()
    baseline = f"velocity-linear x{BASELINE_WIDEN['rmse']:g}"
    meets = {}
    for n in counts["adaptive"]:
        target = sweep["adaptive"][str(n)]["rmse_median_m"]
        meets[str(n)] = next(
            (int(m) for m in counts["velocity-linear"] if sweep[baseline][str(m)]["rmse_median_m"] <= target), None
        )
    goals = {}
    vl = f"velocity-linear x{BASELINE_WIDEN['containment']:g}"
    vl_score = f"velocity-linear x{BASELINE_WIDEN['log_score']:g}"
    for case in cases:
        for label in ("adaptive", "adaptive-pivot"):
            row, base, scored = containment[case][label], containment[case][vl], containment[case][vl_score]
            cells = [row["mismatch"]] + [c for c in row["bins"].values() if c["median"] is not None]
            bases = [base["mismatch"]] + [c for c in base["bins"].values() if c["median"] is not None]
            scores = [scored["mismatch"]] + [c for c in scored["bins"].values() if c["median"] is not None]
            goals[f"{case}/{label}"] = {
                "at_least_80_percent_everywhere": all(c["median"] >= 0.8 for c in cells),
                "contained_above_velocity_linear_everywhere": all(
                    c["median"] > b["median"] for c, b in zip(cells, bases)
                ),
                "log_score_above_velocity_linear_everywhere": all(
                    c["log_score_median"] > b["log_score_median"] for c, b in zip(cells, scores)
                ),
            }
    return {
        "seeds": list(seeds),
        "cases": list(cases),
        "particles": particles,
        "turn_bins": [list(b) for b in TURN_BINS],
        "goals": goals,
        "baseline_widen": dict(BASELINE_WIDEN),
        "containment": containment,
        "sweep": sweep,
        "baseline_particles_to_meet_adaptive": meets,
        "goal_contained_share": 0.8,
        "runs": runs_out,
    }


def _share_summary(runs: list[dict]) -> dict:
    shares = [r["contained_share"] for r in runs]
    return {
        "seeds": len(shares),
        "median": float(np.median(shares)) if shares else None,
        "min": float(min(shares)) if shares else None,
        "log_score_median": _median_of(runs, "log_score"),
        "final_error_median_m": _median_of(runs, "final_position_error_m"),
        "final_spread_median_m": _median_of(runs, "final_spread_m"),
    }


def _brief(run: dict) -> dict:
    keys = (
        "case",
        "model",
        "seed",
        "physics",
        "widen",
        "stop_turn_share",
        "foot_separation_m",
        "contained_share",
        "log_score",
        "final_position_error_m",
        "final_spread_m",
    )
    return {k: run.get(k) for k in keys}


def print_tuning(t: dict) -> None:
    print(
        f"velocity-linear widened, training robots {t['seeds'][0]}-{t['seeds'][-1]} (mismatched physics), "
        f"cases {', '.join(t['cases'])}, {t['particles']} particles:"
    )
    print(
        "  widen  truth in 95% region  log score  (no vision, medians)  position RMSE after collision "
        "(vision+injection)"
    )
    for row in t["rows"]:
        print(
            f"  x{row['widen']:<5g} {100 * row['contained_share_median']:>19.0f}%  {row['log_score_median']:>9.2f}"
            f"  {'':>20}  {row['rmse_after_collision_median_m']:>9.3f} m"
        )
    print(
        f"  best: x{t['best']['containment']:g} for the region, x{t['best']['log_score']:g} for the log score, "
        f"x{t['best']['rmse']:g} for the error"
    )


def print_mismatch(m: dict) -> None:
    bins = [f"{low:g}-{high:g}" for low, high in m["turn_bins"]]
    print(
        f"truth inside the 95% region, share of the steps from the collision on, median over held-out robots "
        f"{m['seeds'][0]}-{m['seeds'][-1]} ({m['particles']} particles, no vision; [n] seeds in a bin; goal "
        f">= {100 * m['goal_contained_share']:.0f}%):"
    )
    for case, by_model in m["containment"].items():
        print(
            f"case {case}:{'':<20}nominal  mismatch  "
            + "  ".join(f"turn {b:<9}" for b in bins)
            + "  cloud spread at the end (mismatch, median)"
        )
        for label, row in by_model.items():
            cells = [f"{100 * row['nominal']['median']:>6.0f}%", f"{100 * row['mismatch']['median']:>7.0f}%"]
            for b in bins:
                cell = row["bins"][b]
                text = "—" if cell["median"] is None else f"{100 * cell['median']:.0f}%"
                cells.append(f"{text:>5} [{cell['seeds']:>2}]   ")
            print(f"  {label:<24}" + "  ".join(cells) + f"  {row['mismatch']['final_spread_median_m']:.2f} m")
    print(
        "log score (the log of the belief's density at the true pose, mean over the steps from the collision on; "
        "median over robots; higher is better):"
    )
    for case, by_model in m["containment"].items():
        print(f"case {case}:{'':<20}nominal  mismatch  " + "  ".join(f"turn {b:<9}" for b in bins))
        for label, row in by_model.items():
            cells = [f"{row['nominal']['log_score_median']:>7.2f}", f"{row['mismatch']['log_score_median']:>8.2f}"]
            for b in bins:
                cell = row["bins"][b]
                cells.append(
                    f"{'—' if cell['median'] is None else format(cell['log_score_median'], '.2f'):>6}"
                    f" [{cell['seeds']:>2}]  "
                )
            print(f"  {label:<24}" + "  ".join(cells))
    print(
        f"goal (mismatched physics, all seeds and every stop-turn bin): truth inside >= 80%, and a log score above "
        f"velocity-linear x{m['baseline_widen']['log_score']:g} (its best log score on the training robots):"
    )
    for key, goal in m["goals"].items():
        print(
            f"  {key:<24} >= 80%: {'met' if goal['at_least_80_percent_everywhere'] else 'MISSED'}; log score "
            f"above velocity-linear: {'met' if goal['log_score_above_velocity_linear_everywhere'] else 'MISSED'}"
            f"; truth inside more often than velocity-linear x{m['baseline_widen']['containment']:g}: "
            f"{'yes' if goal['contained_above_velocity_linear_everywhere'] else 'no'}"
        )
    print(
        f"with vision and injection, mismatched physics, median position RMSE from the collision on (cases "
        f"{', '.join(m['cases'])}):"
    )
    counts = sorted({int(c) for row in m["sweep"].values() for c in row})
    print(f"  {'particles':<24}" + "".join(f"{c:>8}" for c in counts))
    for label, row in m["sweep"].items():
        print(
            f"  {label:<24}"
            + "".join(f"{row[str(c)]['rmse_median_m']:>8.3f}" if str(c) in row else f"{'':>8}" for c in counts)
        )
    meets = m["baseline_particles_to_meet_adaptive"]
    print(
        f"  particles velocity-linear x{m['baseline_widen']['rmse']:g} needs to be as accurate as the adaptive "
        "model at N: "
        + ", ".join(f"N = {n}: {f'more than {counts[-1]}' if v is None else v}" for n, v in meets.items())
    )


# -- command line ---------------------------------------------------------------------------------------
def _strip(result):
    if isinstance(result, dict):
        return {k: _strip(v) for k, v in result.items() if k != "series"}
    if isinstance(result, list):
        return [_strip(v) for v in result]
    if isinstance(result, float) and math.isinf(result):
        return None  # JSON has no infinity: a median that never happened (see "never" counts)
    return result


def _fmt(value, unit="", digits=3):
    if value is None:
        return "—"
    return "never" if math.isinf(value) else f"{value:.{digits}f}{unit}"


def print_cases(results: dict, label: str) -> None:
    for case, by_model in results.items():
        print(f"case {case}, {label}:")
        if "entropy" in by_model:
            e = by_model["entropy"]
            print(
                "  position entropy [bits], median over seeds, at second " + " ".join(f"{s:>5}" for s in e["seconds"])
            )
            print("    velocity-linear" + " " * 28 + " ".join(f"{v:5.2f}" for v in e["velocity_linear_median_bits"]))
            print("    adaptive       " + " " * 28 + " ".join(f"{v:5.2f}" for v in e["adaptive_median_bits"]))
            print(
                f"  adaptive below velocity-linear at every second after the first: "
                f"{e['seeds_below_every_second_after_first']}/{e['seeds']} seeds"
            )
        for model, block in by_model.items():
            if model == "entropy":
                continue
            s = block["summary"]
            parts = [f"  {model:<16}"]
            if "contained_share" in s:
                parts.append(
                    f"truth in 95% region: median {100 * s['contained_share']['median']:.0f}%, "
                    f"mean {100 * s['contained_share']['mean']:.0f}%, min "
                    f"{100 * s['contained_share']['min']:.0f}% of steps"
                )
            if "relocalization_s" in s:
                parts.append(
                    f"relocalized (<{RELOCALIZED} m) after the collision: median "
                    f"{_fmt(s['relocalization_s']['median'], ' s', 2)}, max "
                    f"{_fmt(s['relocalization_s']['max'], ' s', 2)}, never {s['relocalization_s']['never']}"
                )
            if "position_rmse_after_collision_m" in s:
                parts.append(f"RMSE after collision start {_fmt(s['position_rmse_after_collision_m']['median'], ' m')}")
            parts.append(f"final error {_fmt(s['final_position_error_m']['median'], ' m')}")
            print("; ".join(parts))


PROG = "robocup-mcl demo collision"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument(
        "--case",
        choices=CASES + ("all",),
        default="all",
        help="the experiment: no collision, a single or a double collision, or all (default all)",
    )
    parser.add_argument(
        "--model",
        choices=sorted(MODELS) + ["both"],
        default="both",
        help="the motion model, or both velocity-linear and adaptive (default both)",
    )
    parser.add_argument("--particles", type=int, default=None, help="default: 100 without vision, 500 with")
    parser.add_argument("--seed", type=int, default=0, help="seed of the run (default 0)")
    parser.add_argument("--seeds", help='several seeds: "0-19" or "0,3,5" (overrides --seed)')
    parser.add_argument("--vision", action="store_true", help="correct with landmark observations")
    parser.add_argument(
        "--injection",
        action="store_true",
        help="with --vision: augmented MCL's injection on (off by default: the motion model alone)",
    )
    parser.add_argument("--detection", action="store_true", help="the collision detector's figures only")
    parser.add_argument("--minutes", type=float, default=10.0, help="minutes per seed for --detection")
    parser.add_argument(
        "--physics",
        choices=("nominal", "mismatch"),
        default="nominal",
        help="--detection on the nominal robot, or on robots drawn by the mismatched physics, one "
        "per seed, each with the reference learned from its own free walk (default nominal)",
    )
    parser.add_argument("--particle-sweep", help='adaptive particle counts to try, e.g. "50,100,200,500"')
    parser.add_argument("--cost", action="store_true", help="predict cost, adaptive / velocity-linear, N = 1000")
    parser.add_argument("--report", action="store_true", help="every figure of docs/papers/hoffmann.md (takes minutes)")
    parser.add_argument(
        "--tune-baseline",
        action="store_true",
        help="velocity-linear's widening x"
        + ", x".join(f"{w:g}" for w in WIDENINGS)
        + f" on training robots (mismatched physics; --seeds, default {TRAINING_SEEDS})",
    )
    parser.add_argument(
        "--mismatch",
        action="store_true",
        help="the robustness table: nominal against mismatched physics, per simulated stop turn, "
        f"with the best velocity-linear and the particle sweep (--seeds, default {HELD_OUT_SEEDS})",
    )
    parser.add_argument(
        "--region-coverage",
        action="store_true",
        help="how often the 95%% region holds a pose drawn like its particles, at 30, 100 and 200 "
        "particles, with and without each particle's own kernel in the level",
    )
    parser.add_argument("--rrd", help="write a Rerun recording here (one case, one model, one seed)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")
    add_save_option(parser)
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl demo collision` (see --help); returns the exit status."""
    from mcl.tools.cli_checks import progress_wanted

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds) if args.seeds else [args.seed]
    except ValueError:
        parser.error(f"--seeds {args.seeds!r}: give seeds as 3, 0-9 or 1,4,7")
    cases = CASES if args.case == "all" else (args.case,)
    models = ("velocity-linear", "adaptive") if args.model == "both" else (args.model,)
    particles = args.particles or (500 if args.vision else 100)
    if particles <= 0:
        parser.error(f"--particles {particles} must be > 0")
    if args.rrd and (len(seeds) > 1 or len(cases) > 1 or len(models) > 1):
        parser.error("--rrd records one run: give --case, --model (not both) and --seed")
    from mcl.tools.cli_checks import check_output_file, save_json

    check_output_file(args.rrd, "--rrd")  # before the run, not after it
    check_output_file(args.save, "--save")
    reference = free_walk_reference()
    progress = progress_wanted(args)
    warm = warm_up_collision(cases[0], models, reference, args.vision, args.injection, progress)
    result: dict = {}
    if args.region_coverage:
        result["region_coverage"] = region_coverage()
    elif args.tune_baseline:
        result["baseline_tuning"] = tune_baseline(parse_seeds(args.seeds or TRAINING_SEEDS), progress=progress)
    elif args.mismatch:
        result["mismatch"] = mismatch_table(parse_seeds(args.seeds or HELD_OUT_SEEDS), progress=progress)
    elif args.report:
        report_seeds = parse_seeds(args.seeds) if args.seeds else list(range(20))
        result["detection"] = detection_figures(reference, minutes=args.minutes)
        result["no_vision"] = run_cases(
            CASES, ("velocity-linear", "adaptive", "adaptive-step"), report_seeds, reference, 100, False
        )
        result["vision"] = run_cases(
            ("single", "double"), ("velocity-linear", "adaptive"), report_seeds, reference, 500, True
        )
        result["vision_injection"] = run_cases(
            ("single", "double"), ("velocity-linear", "adaptive"), report_seeds, reference, 500, True, injection=True
        )
        result["particle_sweep"] = particle_sweep((10, 25, 50, 100, 200, 500), report_seeds, reference)
        result["cost"] = predict_cost()
    elif args.detection:
        result["detection"] = detection_figures(
            reference, seeds=seeds if args.seeds else (0, 1, 2), minutes=args.minutes, physics=args.physics
        )
    elif args.particle_sweep:
        counts = [int(c) for c in args.particle_sweep.split(",")]
        result["particle_sweep"] = particle_sweep(counts, seeds, reference)
    elif args.cost:
        result["cost"] = predict_cost()
    else:
        key = ("vision_injection" if args.injection else "vision") if args.vision else "no_vision"
        if args.rrd:
            run = run_case(
                cases[0], models[0], seeds[0], reference, particles, args.vision, args.rrd, injection=args.injection
            )
            result[key] = {cases[0]: {models[0]: {"runs": [run], "summary": case_summary([run])}}}
        else:
            result[key] = run_cases(
                cases, models, seeds, reference, particles, args.vision, args.injection, progress=progress
            )
    result.update(warm.as_dict())  # the warm-up's time, apart from every step time
    save_json(args.save, _strip(result))
    if args.json:
        json.dump(_strip(result), sys.stdout, indent=2)
        print()
        return 0
    if "detection" in result:
        d = result["detection"]
        robots = " (mismatched physics, a robot per seed)" if d.get("physics") == "mismatch" else ""
        print(
            f"collision detection{robots}, {len(d['seeds'])} × {d['minutes_per_seed']:.0f} min of simulated "
            f"walking, {d['episodes']} contact episodes:"
        )
        print(f"  detected within 0.3 s: {100 * d['detected_share']:.1f}% (median delay {d['median_delay_s']:.3f} s)")
        print(f"  side correct: {100 * d['side_correct_share']:.1f}%   (true->reported: {d['side_confusion']})")
        print(
            f"  false alarms: {d['false_alarms']} in {d['free_minutes']:.1f} min of free walking = "
            f"{d['false_alarms_per_minute']:.2f} per minute"
        )
        if d.get("physics") == "mismatch":
            print("  detected within 0.3 s, by the joints the obstacle holds (robots drawn by the mismatched physics):")
            for joints, row in d["by_held_joints"].items():
                share = "—" if row["detected_share"] is None else f"{100 * row['detected_share']:.0f}%"
                print(f"    {joints:<42} {share:>5} of {row['episodes']} episodes")
    for key, label in (
        ("no_vision", "no vision"),
        ("vision", "with vision"),
        ("vision_injection", "with vision and augmented MCL's injection"),
    ):
        if key in result:
            print_cases(result[key], label)
    if "region_coverage" in result:
        r = result["region_coverage"]
        print(
            f"the 95% region (kernel density over the particles) holds a pose drawn like its particles, share of "
            f"{r['draws']} clouds:"
        )
        print("  particles  own kernel left out (the tables)  own kernel left in (earlier figures)")
        for row in r["rows"]:
            print(
                f"  {row['particles']:>9}  {100 * row['leave_one_out']:>31.1f}%  {100 * row['own_kernel_in']:>35.1f}%"
            )
    if "baseline_tuning" in result:
        print_tuning(result["baseline_tuning"])
    if "mismatch" in result:
        print_mismatch(result["mismatch"])
    if "particle_sweep" in result:
        p = result["particle_sweep"]
        v = p["velocity_linear"]
        print(
            f"with vision, median position RMSE from the collision on (cases {', '.join(p['cases'])}, "
            f"{len(p['seeds'])} seeds):"
        )
        print(
            f"  velocity-linear at {v['particles']} particles: {_fmt(v['median_rmse_m'], ' m')} "
            f"(relocalized after {_fmt(v['median_relocalization_s'], ' s', 2)})"
        )
        for row in p["adaptive"]:
            print(
                f"  adaptive at {row['particles']:>4} particles: {_fmt(row['median_rmse_m'], ' m')} "
                f"(relocalized after {_fmt(row['median_relocalization_s'], ' s', 2)})"
            )
        print(f"  adaptive particles needed to match: {p['adaptive_particles_needed']}")
    if "cost" in result:
        c = result["cost"]
        print(
            f"predict at N = {c['particles']}: velocity-linear {c['velocity_linear_us']:.1f} µs, adaptive "
            f"{c['adaptive_us']:.1f} µs, ratio {c['ratio']:.2f}"
        )
    if args.rrd:
        print(f"recording written to {args.rrd} (open it with: rerun {args.rrd})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
