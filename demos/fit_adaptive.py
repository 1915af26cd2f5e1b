"""`robocup-mcl fit adaptive`: the adaptive motion model's collision terms (β of Hoffmann eq. 14-26) from training logs.

    robocup-mcl fit adaptive --seeds 2000-2039 --json --save results/adaptive_fit.json

The training logs are what a team records on its robots: per robot (one per seed, drawn by the collision
simulator's mismatched physics, `demos.collision_sim.MISMATCH_RANGES`), three minutes of free walking to learn
the collision detector's reference, then `--minutes` of walking at varied requests with collisions of every
kind and side (`demos.collision_sim.random_collisions`). From each log the fit reads only the walk request, the
ground-truth pose (as a motion-capture system gives it), the mobility state of each frame (as one annotates it
from video) and the detector's percepts; never the simulator's parameters.

Principle. Each annotated episode (a stretch of frames in one mobility state, at least `MIN_EPISODE` s long) gives
its rates from the motion capture: the mean robot-frame velocity and turn rate over the episode, against the
mean request. The model draws each rand() of eq. 14-26 once per episode (`redraw="episode"`), uniformly over a
range; each range is set to cover the share `--coverage` (default 0.95) of the episodes' rates seen in
training, i.e. a lower bound is the (1 - coverage) quantile and an upper bound the coverage quantile:

    β1     slippage: speed share |v_true| / |v_request|, lower bound               (eq. 14)
    β2     slippage: |ω_true - ω_request| [rad/s], upper bound                     (eq. 15)
    β3     hindrance: speed share, lower bound                                     (eq. 16)
    β4     hindrance: turn share ω_true / ω_request (requests turning at least
           `MIN_TURN`), lower bound                                                (eq. 17)
    β5     pushed: |v_true - v_request| [m/s], upper bound                         (eq. 19)
    β6     pushed: |ω_true - ω_request| [rad/s], upper bound                       (eq. 22)
    β7     stopped, no side in the percept (or both): |ω_true| [rad/s], upper bound (eq. 24)
    β_turn stopped, with the percept's side c: c·ω_true / (|v_request| / w), upper bound, for the model's
           w = `FOOT_SEPARATION` (eq. 25 takes β_turn / w: only the ratio is identified)
    stop_creep  stopped, with a side: the speed share along the request (the variant "adaptive-pivot"),
           upper bound

Shares are clipped to [0, `MAX_SHARE`] (the model takes β1, β3, β4 in [0, 1)).

Episode ends. The detector's "frequent" condition (the share of the last 60 frames with a collision at or above
the model's `frequent_rate`) outlasts the contact by up to half a second, so an episode often ends while the
percept still says "frequent"; the paper's chain has no way out of a collision state there, and a cloud that
stays stopped while the robot walks on loses it. The rates of the episode ends (slippage, hindrance, pushed,
stopped -> free) are therefore measured per percept condition: the maximum-likelihood rate of a Markov chain
seen frame by frame, the number of ends divided by the time spent in the state under that condition
("end_rates" in the JSON, every condition). The model takes those of the "frequent" condition
(`FITTED_CONDITION`); its other rates stay settings. Taking the "collision" condition's too was measured on
the training robots and held the truth less often when the robot turned fast, because that condition is
also the one the percept passes through on its way back to quiet.

Free walking (eq. 10). On the stretches of `--horizon` seconds in which the robot walked freely and the
detector was quiet, the error of the motion capture's pose against the request dead-reckoned from the
stretch's first pose, in the robot frame of the dead-reckoned pose (x, y, θ). Eq. 10 draws independent noise
each step, so over a stretch its spread is β·sqrt(dt·H·mean(s²)/3) for the step rate 1/dt and the stretch's
speed terms s (|v| for x and y, `ODOMETRY_SHAPE`'s θ mix of |v| and |ω| for θ). Each of x, y and θ is scaled
so that ±z times that spread (z the two-sided normal quantile of `--coverage`) holds the share `--coverage`
of the stretches' errors: β1 and β2 each, β3 and β4 by one factor that keeps their ratio in `ODOMETRY_SHAPE`.
A calibrated robot's per-run scale error and turn bias grow with the stretch while the model's noise grows
with its square root, so the fit holds at `--horizon` and is wider than needed on shorter stretches. The
values hold at the 100 Hz loop the logs are recorded at (scale by sqrt(0.01 s / dt) at another rate).

The defaults of `motion_models.AdaptiveMotion` are these values rounded to `DIGITS` decimals ("defaults" in
the JSON; the transition rates' in "transitions"). The other transition rates and `frequent_rate` are not
fitted here (they stay the model's documented settings).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np

from field.angles import wrap_angles
from proprioception.collision import detect

from .collision_sim import (
    FREE,
    HINDRANCE,
    MODE_NAMES,
    PUSHED,
    SLIPPAGE,
    STOPPED,
    CollisionLog,
    CollisionScenario,
    random_collisions,
    simulate,
)
from .walk import parse_seeds

TRAINING_SEEDS = "2000-2039"
MIN_EPISODE = 0.2  # s: shorter annotated stretches are left out (too short for a mean velocity)
MIN_SPEED = 0.03  # m/s: an episode whose request is slower gives no speed share
MIN_TURN = 0.1  # rad/s: an episode whose request turns less gives no turn share
MAX_SHARE = 0.99
FOOT_SEPARATION = 0.1  # m, the model's w (eq. 25); β_turn is fitted for it
DIGITS = 3
HORIZON = 5.0  # s: the free-walking stretches the odometry noise is fitted on
FREQUENT_RATE = 0.25  # the model's frequent_rate (a setting, not fitted): the percept conditions' split
CONDITIONS = ("quiet", "collision", "frequent")
FITTED_CONDITION = "frequent"  # the condition whose episode-end rates the model takes (see the docstring)
ODOMETRY_SHAPE = (1.0, 0.6, 0.6, 0.6)  # eq. 10's earlier settings; the fit keeps their β3 : β4 (θ's mix)
FITTED = ("beta1", "beta2", "beta3", "beta4", "beta5", "beta6", "beta7", "beta_turn", "stop_creep")
LOWER = ("beta1", "beta3", "beta4")  # lower bounds of their ranges; the others are upper bounds


def training_log(seed: int, minutes: float) -> tuple[CollisionLog, np.ndarray, np.ndarray]:
    """One robot's training log (seed `seed`): the collision walk, the detector's percept side per frame
    (+1 left, -1 right, 0 both, NaN none) and its rate (the share of the recent frames with a collision), the
    detector's reference learned from the robot's own free walk."""
    from .collision import robot_reference

    reference = robot_reference("mismatch", seed)
    duration = 60.0 * minutes
    events = random_collisions(duration, np.random.default_rng(np.random.SeedSequence([seed, 13])))
    scenario = replace(
        CollisionScenario(duration=duration, command=None, physics="mismatch", robot_seed=seed), events=events
    )
    log = simulate(scenario, seed)
    percepts = detect(reference, log.servo_commands, log.servo_readings, log.phase, log.commands)
    recent = percepts["recent"]
    side = np.where(recent[:, 0] & recent[:, 1], 0.0, np.where(recent[:, 0], 1.0, np.where(recent[:, 1], -1.0, np.nan)))
    return log, side, percepts["rate"]


def percept_conditions(rate: np.ndarray, frequent_rate: float = FREQUENT_RATE) -> np.ndarray:
    """Per frame, the index into `CONDITIONS` of the percept's condition, as `AdaptiveMotion.condition` says it."""
    return np.where(rate >= frequent_rate, 2, np.where(rate > 0, 1, 0))


def episode_ends(log: CollisionLog, rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per condition and collision state, the annotated episode ends (the state followed by free) and the time
    spent in the state [s], counted frame by frame under the condition of the frame the change shows in:
    arrays (3, 5) of counts and of seconds (column FREE unused)."""
    conditions = percept_conditions(rate)
    mode = log.mode.astype(np.int64)
    ends = np.zeros((len(CONDITIONS), 5))
    exposure = np.zeros((len(CONDITIONS), 5))
    np.add.at(exposure, (conditions[1:], mode[:-1]), log.dt)
    ended = (mode[:-1] != FREE) & (mode[1:] == FREE)
    np.add.at(ends, (conditions[1:][ended], mode[:-1][ended]), 1.0)
    exposure[:, FREE] = 0.0
    return ends, exposure


def fit_end_rates(ends: np.ndarray, exposure: np.ndarray, min_exposure: float = 10.0) -> dict:
    """Maximum-likelihood episode-end rates [1/s] per condition: {condition: {state: rate or None}}; None where
    the training logs spent less than `min_exposure` seconds in the state under the condition."""
    out: dict[str, dict[str, float | None]] = {}
    for c, condition in enumerate(CONDITIONS):
        out[condition] = {
            MODE_NAMES[s]: (float(ends[c, s] / exposure[c, s]) if exposure[c, s] >= min_exposure else None)
            for s in (SLIPPAGE, HINDRANCE, PUSHED, STOPPED)
        }
    return out


def free_walk_errors(log: CollisionLog, rate: np.ndarray, horizon: float = HORIZON) -> np.ndarray:
    """Errors of dead-reckoning the request over stretches of `horizon` s of free, quiet walking, one row per
    stretch (stretches do not overlap): x, y [m] and θ [rad] in the robot frame of the dead-reckoned pose, then
    the stretch's root mean square of |v| and of the θ mix of `ODOMETRY_SHAPE` (β3·|v| + β4·|ω|)."""
    steps = int(round(horizon / log.dt))
    quiet = (log.mode == FREE) & (rate == 0)
    rows = []
    k = 0
    while k + steps < quiet.size:
        if not quiet[k : k + steps + 1].all():
            k += 1
            continue
        pose = log.truth[k].copy()
        commands = log.commands[k + 1 : k + steps + 1]
        for vx, vy, omega in commands:
            half = pose[2] + 0.5 * omega * log.dt
            pose[0] += (math.cos(half) * vx - math.sin(half) * vy) * log.dt
            pose[1] += (math.sin(half) * vx + math.cos(half) * vy) * log.dt
            pose[2] += omega * log.dt
        dx, dy = log.truth[k + steps, :2] - pose[:2]
        c, s = math.cos(pose[2]), math.sin(pose[2])
        speed = np.hypot(commands[:, 0], commands[:, 1])
        mix = ODOMETRY_SHAPE[2] * speed + ODOMETRY_SHAPE[3] * np.abs(commands[:, 2])
        rows.append(
            (
                c * dx + s * dy,
                -s * dx + c * dy,
                float(wrap_angles(log.truth[k + steps, 2] - pose[2])),
                float(np.sqrt(np.mean(speed**2))),
                float(np.sqrt(np.mean(mix**2))),
            )
        )
        k += steps
    return np.array(rows).reshape(-1, 5)


def fit_odometry(errors: np.ndarray, dt: float, horizon: float, coverage: float = 0.95) -> tuple[float, ...]:
    """Eq. 10's β1..β4 from `free_walk_errors` rows (see the module docstring). Raises ValueError without a
    stretch to fit on."""
    if errors.shape[0] == 0:
        raise ValueError(
            f"no stretch of {horizon:g} s of free, quiet walking in the training logs; record longer "
            "logs or give a shorter --horizon"
        )
    z = float(_normal_quantile(0.5 + 0.5 * coverage))
    gain = math.sqrt(dt * horizon / 3.0)

    def scale(column: int, term: int) -> float:
        # The β that puts `coverage` of |error| / (term · gain) inside ±z of a normal spread.
        moving = errors[:, term] > 0
        if not moving.any():
            raise ValueError(f"no stretch of {horizon:g} s in the training logs walks at all; record walking")
        return float(np.quantile(np.abs(errors[moving, column]) / (errors[moving, term] * gain), coverage)) / z

    along, across, heading = scale(0, 3), scale(1, 3), scale(2, 4)  # heading: a factor on the shape's θ mix
    return (along, across, ODOMETRY_SHAPE[2] * heading, ODOMETRY_SHAPE[3] * heading)


def _normal_quantile(p: float) -> float:
    from scipy.stats import norm

    return float(norm.ppf(p))


def robot_frame_velocities(truth: np.ndarray, start: np.ndarray, dt: float) -> np.ndarray:
    """Per step (T, 3): the robot-frame velocity (vx, vy [m/s]) and turn rate [rad/s] from consecutive poses
    (the chord of each step rotated by its mid heading)."""
    previous = np.vstack([start[None, :], truth[:-1]])
    turn = wrap_angles(truth[:, 2] - previous[:, 2])
    mid = previous[:, 2] + 0.5 * turn
    dx, dy = truth[:, 0] - previous[:, 0], truth[:, 1] - previous[:, 1]
    c, s = np.cos(mid), np.sin(mid)
    return np.column_stack([(c * dx + s * dy) / dt, (-s * dx + c * dy) / dt, turn / dt])


def episode_rates(log: CollisionLog, side: np.ndarray, foot_separation: float = FOOT_SEPARATION) -> dict:
    """The per-episode rates of the module docstring, from one log: a dict of name -> list of floats."""
    velocity = robot_frame_velocities(log.truth, log.start, log.dt)
    rates: dict[str, list[float]] = {
        name: []
        for name in (
            "slip_speed",
            "slip_turn",
            "hinder_speed",
            "hinder_turn",
            "push_speed",
            "push_turn",
            "stop_turn_unknown",
            "stop_turn",
            "stop_creep",
        )
    }
    mode = log.mode.astype(np.int64)
    edges = np.flatnonzero(np.diff(mode)) + 1
    for first, stop in zip(np.r_[0, edges], np.r_[edges, mode.size]):
        state = int(mode[first])
        if state == FREE or (stop - first) * log.dt < MIN_EPISODE:
            continue
        true = velocity[first:stop].mean(axis=0)
        request = log.commands[first:stop].mean(axis=0)
        speed = math.hypot(request[0], request[1])
        true_speed = math.hypot(true[0], true[1])
        if state in (SLIPPAGE, HINDRANCE) and speed >= MIN_SPEED:
            rates["slip_speed" if state == SLIPPAGE else "hinder_speed"].append(true_speed / speed)
        if state == SLIPPAGE:
            rates["slip_turn"].append(abs(true[2] - request[2]))
        elif state == HINDRANCE and abs(request[2]) >= MIN_TURN:
            rates["hinder_turn"].append(true[2] / request[2])
        elif state == PUSHED:
            rates["push_speed"].append(math.hypot(true[0] - request[0], true[1] - request[1]))
            rates["push_turn"].append(abs(true[2] - request[2]))
        elif state == STOPPED:
            sides = side[first:stop]
            known = sides[np.isfinite(sides)]
            c = float(np.sign(known.sum())) if known.size and (known != 0).any() else 0.0
            if c == 0.0 or speed < MIN_SPEED:
                rates["stop_turn_unknown"].append(abs(true[2]))
            else:
                rates["stop_turn"].append(c * true[2] / (speed / foot_separation))
                rates["stop_creep"].append((true[0] * request[0] + true[1] * request[1]) / speed**2)
    return rates


def fit_betas(rates: dict, coverage: float = 0.95) -> dict[str, float]:
    """β from per-episode rates: each uniform range of eq. 14-26 covers the share `coverage` of the rates.

    Raises ValueError when coverage is not within (0.5, 1) or a rate has no episode.
    """
    if not (isinstance(coverage, float) and 0.5 < coverage < 1.0):
        raise ValueError(f"coverage = {coverage!r} must be a number within (0.5, 1)")
    sources = {
        "beta1": "slip_speed",
        "beta2": "slip_turn",
        "beta3": "hinder_speed",
        "beta4": "hinder_turn",
        "beta5": "push_speed",
        "beta6": "push_turn",
        "beta7": "stop_turn_unknown",
        "beta_turn": "stop_turn",
        "stop_creep": "stop_creep",
    }
    out = {}
    for name, source in sources.items():
        values = np.asarray(rates.get(source, []), dtype=np.float64)
        if values.size == 0:
            raise ValueError(f"no training episode gives {source} (needed for {name}); record longer logs")
        q = float(np.quantile(values, 1.0 - coverage if name in LOWER else coverage))
        out[name] = min(max(q, 0.0), MAX_SHARE) if name in LOWER else max(q, 0.0)
    return out


def fit(seeds, minutes: float = 3.0, coverage: float = 0.95, progress: bool = False, horizon: float = HORIZON) -> dict:
    """Record the training logs of `seeds`, pool their episodes, fit; the JSON of the command."""
    from mcl.tools.cli_checks import progress_bar

    if not (math.isfinite(minutes) and minutes > 0):
        raise ValueError(f"minutes = {minutes!r} must be > 0")
    if not (isinstance(horizon, (int, float)) and math.isfinite(horizon) and 0.1 <= horizon <= 60 * minutes):
        raise ValueError(f"horizon = {horizon!r} must be within [0.1, the log's length] seconds")
    pooled: dict[str, list[float]] = {}
    ends = np.zeros((len(CONDITIONS), 5))
    exposure = np.zeros((len(CONDITIONS), 5))
    errors = []
    dt = None
    bar = progress_bar(enabled=progress, total=len(seeds), desc="fit adaptive", unit="robot")
    for seed in seeds:
        log, side, rate = training_log(seed, minutes)
        for name, values in episode_rates(log, side).items():
            pooled.setdefault(name, []).extend(values)
        counted, seconds = episode_ends(log, rate)
        ends += counted
        exposure += seconds
        errors.append(free_walk_errors(log, rate, horizon))
        dt = log.dt
        bar.update(1)
    bar.close()
    fitted = fit_betas(pooled, coverage)
    end_rates = fit_end_rates(ends, exposure)
    stretches = np.vstack(errors)
    odometry = fit_odometry(stretches, float(dt), horizon, coverage)
    transitions = {f"{state}->free": rate for state, rate in end_rates[FITTED_CONDITION].items() if rate is not None}
    return {
        "seeds": list(seeds),
        "minutes_per_seed": minutes,
        "coverage": coverage,
        "foot_separation": FOOT_SEPARATION,
        "horizon_s": horizon,
        "free_walk_stretches": int(stretches.shape[0]),
        "odometry": list(odometry),
        "odometry_default": [round(b, DIGITS) for b in odometry],
        "end_rates": end_rates,
        "end_exposure_s": {
            c: {MODE_NAMES[s]: float(exposure[i, s]) for s in range(1, 5)} for i, c in enumerate(CONDITIONS)
        },
        "transitions": {"condition": FITTED_CONDITION, "rates": {k: round(v, DIGITS) for k, v in transitions.items()}},
        "episodes": {name: len(values) for name, values in pooled.items()},
        "rate_quantiles": {
            name: [float(v) for v in np.quantile(values, (0.05, 0.5, 0.95))]
            for name, values in pooled.items()
            if values
        },
        "fitted": fitted,
        "defaults": {name: round(value, DIGITS) for name, value in fitted.items()},
        "modes": list(MODE_NAMES),
    }


PROG = "robocup-mcl fit adaptive"


def build_parser(prog: str = PROG) -> argparse.ArgumentParser:
    """The command's argument parser, named `prog` in its usage line."""
    from mcl.tools.cli_checks import add_progress_option, add_save_option, description

    parser = argparse.ArgumentParser(prog=prog, description=description(__doc__))
    parser.add_argument(
        "--seeds", default=TRAINING_SEEDS, help=f'training robots (seeds), e.g. "2000-2039" (default {TRAINING_SEEDS})'
    )
    parser.add_argument(
        "--minutes", type=float, default=3.0, help="minutes of walking with collisions per robot (default 3)"
    )
    parser.add_argument(
        "--coverage",
        type=float,
        default=0.95,
        help="share of the training episodes' rates each range covers (default 0.95)",
    )
    parser.add_argument(
        "--horizon",
        type=float,
        default=HORIZON,
        help=f"seconds of free walking the odometry noise is fitted on (default {HORIZON:g})",
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")
    add_save_option(parser)
    add_progress_option(parser)
    return parser


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    """`robocup-mcl fit adaptive` (see --help); returns the exit status."""
    from mcl.tools.cli_checks import check_output_file, progress_wanted, save_and_print

    parser = build_parser(prog)
    args = parser.parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
    except ValueError:
        parser.error(f"--seeds {args.seeds!r}: give seeds as 3, 0-9 or 1,4,7")
    check_output_file(args.save, "--save")
    try:
        result = fit(seeds, args.minutes, args.coverage, progress_wanted(args), args.horizon)
    except ValueError as error:
        parser.error(str(error))
    save_and_print(result, args.save, args.json, lambda fitted: _print(fitted, len(seeds), args.minutes, args.coverage))
    return 0


def _print(result: dict, robots: int, minutes: float, coverage: float) -> None:
    print(
        f"adaptive motion model fitted on {robots} training robots × {minutes:g} min, ranges covering "
        f"{100 * coverage:.0f}% of the episodes' rates:"
    )
    for name in FITTED:
        print(f"  {name:<10} {result['fitted'][name]:.4f}  (default {result['defaults'][name]})")
    print("  episodes: " + ", ".join(f"{name} {count}" for name, count in result["episodes"].items()))
    print(
        f"episode ends (-> free) per second, maximum likelihood per percept condition (the model takes "
        f"{result['transitions']['condition']!r}):"
    )
    for condition, rates in result["end_rates"].items():
        print(
            f"  {condition:<10} "
            + ", ".join(
                f"{state} {'—' if rate is None else f'{rate:.3f}'} ({result['end_exposure_s'][condition][state]:.0f} s)"
                for state, rate in rates.items()
            )
        )
    print(
        f"free walking, eq. 10's β1..β4 on {result['free_walk_stretches']} stretches of {result['horizon_s']:g} s: "
        + ", ".join(f"{b:.4f}" for b in result["odometry"])
        + f"  (default {tuple(result['odometry_default'])})"
    )


if __name__ == "__main__":
    raise SystemExit(main())
