"""A footstep walk simulator: a small humanoid's omnidirectional walk, its odometries and motion capture.

    from demos.footstep_sim import simulate, SURFACES, save_log, load_log, truth_displacements

    log = simulate(duration=300.0, surface="grass", seed=0)   # a 5-minute joystick walk (Rouxel sec. IV-A)
    log.commanded, log.sensor, log.support, log.durations      # per step (K, 3), (K, 3), (K,), (K,)
    truth = truth_displacements(log)                           # (K, 3), from the motion capture at the swaps
    save_log(log, "walk.npz"); same = load_log("walk.npz")

The walk (Rouxel sec. II-B). An open-loop walk engine at 1.7 Hz, two steps a cycle, takes three gait commands
(forward and lateral step length, turn per step) that change only at support-foot swaps; a joystick driver
(`Driver`) varies them inside the acceleration limits that keep the robot up, mixing forward, lateral, turn,
backward and stops, and steers back when the robot nears the edge of the 2 m × 1.5 m capture area.

Where the real step differs from the commanded one (sec. IV-B 3, Fig. 8), each effect a parameter of `Robot`
(per robot), `Conditions` (per run) or `Surface`:
- leg inertia: the P-controlled servos cannot follow the swing (Fig. 2) and the leg overshoots, more for a
  faster (longer) swing: the real step is longer than commanded, in x, y and θ;
- backlash: gear play lets the swing leg go further in the swing direction, by up to `backlash`;
- a forward drift at zero command (the trunk leans forward) and a forward push when turning in place: "a
  stationary or slightly negative forward order may result in a forward motion";
- support-foot asymmetry: each leg turns (and advances) the robot by its own bias; a lateral step that opens
  the legs is longer than the one that closes them; a lateral step turns the robot a little;
- history: the body's momentum carries shares of the previous three real steps into the next one (the
  learned odometry's inputs hold steps t and t-1 only);
- the run: a forward and turn bias of the legs (servo warmth, battery), the ground's friction (slip spread /
  friction, drag · friction, and a systematic slide of the support foot, `SLIDE`·(1 - friction) of each leg
  step, unseen by the encoders);
- the surface: on artificial grass the flying foot drags in the grass (shorter, variable steps) and the legs
  move more irregularly; these irregularities are real leg motion, so the encoders see them: grass hurts the
  a-priori odometry, not the sensor-based one (sec. IV-B 4). Slip of the support foot moves the robot without
  the legs seeing it; the cleats slip more on carpet;
- the support swap, detected by the pressure sensors, jitters around the engine's timing, so each measured
  step holds a slightly different share of the motion (and of the head's lateral sway).

Robots and runs (model mismatch). `Robot()` and `Conditions()` are the nominal robot and run. `draw_robot(id,
spread)` draws robot number `id` of a fleet, `draw_conditions(run_seed, spread)` the conditions of a run: each
parameter uniform in its documented range (`ROBOT_RANGES`, `CONDITION_RANGES`) with both ends' distance from
the nominal value scaled by `spread` (0: nominal; 2 goes beyond the ranges), then kept physical (magnitudes
>= 0, friction >= `MIN_FRICTION`, the momentum shares summing to at most `MAX_MOMENTUM`). The ranges at
spread 1 (nominal in brackets):

| per robot | range | | per run | range |
|---|---|---|---|---|
| inertia_x, _speed | 0.12–0.32 (0.22), 2.5–7.5 /m (5) | | friction | 0.6–1.4 (1) |
| inertia_y, _theta | 0.08–0.28 (0.18), 0.04–0.2 (0.12) | | bias_forward | ±2.5 mm/step (0) |
| backlash, width | 3.5–8.5 mm (6), 2.5–5.5 mm (4) | | bias_turn | ±0.008 rad/step (0) |
| turn_push | 12–44 mm/rad (28) | | encoder_scale | ±4.5 % (0) |
| lateral_alternation, _turn | 0.15–0.45 (0.3), 0.3–0.9 rad/m (0.6) | | encoder_nonlinearity | ±15 % at 4 cm (0) |
| foot_turn left, right | −0.004–0.02 (0.008), −0.016–0.008 (−0.004) rad | | gyro_scale | ±1.5 % (0) |
| foot_forward left, right | −1.5–5.5 (2), −4.5–2.3 (−1.1) mm | | gyro_nonlinearity | ±4 % per rad/s (0) |
| momentum k-1, k-2, k-3 | 0.15–0.45 (0.3), 0–0.2 (0.09), 0–0.08 (0.04) | | | |
| sway, compliance | 12–28 mm (20), 0.04–0.12 (0.08) | | | |
| encoder_noise | 0.8–1.6 mm (1.2) | | | |
| gyro_bias_sigma, gyro_scale, gyro_noise | 0.4–1.2 mrad/s (0.8), −2–6 % (2), 3–7 mrad/√s (5) | | | |

The walk frequency (the engine's) and the motion capture are the same for every robot. Nothing here comes
from the learned odometry: the simulator imports no model, and no model default equals one of its constants
(tests/test_odometry_mismatch.py).

Odometries (sec. II-C). A priori ("simulation-based"): the kinematic model fed with the motor goal positions;
with the engine's foot placement, the head moves by exactly the commanded step, so `commanded` is both the
gait command and the a-priori displacement. Sensor-based: the kinematic model fed with the encoders between
the detected swaps, yaw from the integrated gyro: it misses the backlash (the encoders sit before the gears'
play), the leg compliance and the slip, so it underestimates distances; the run's kinematic calibration adds a
scale error and a gain that changes with the step length (`ENCODER_REFERENCE`); the gyro has a scale error
(the device's plus the run's), a gain that changes with the turn rate, white noise, and a small per-run bias
(what is left after calibrating it while standing). Ground truth: motion capture of the head at 100 Hz with
sub-millimetre noise (`MOCAP_NOISE`), read at the sample nearest each detected swap.

Log file (`save_log` / `load_log`): one `.npz` with `format` = "robocup-mcl footstep log", `format_version`
= 1, `surface`, `seed`, `step_period`, `swap_times` (K+1,), `swap_poses` (K+1, 3) motion capture at the
swaps, `support` (K,) ±1, `commanded` (K, 3), `sensor` (K, 3), `mocap_times` (M,), `mocap` (M, 3),
`truth` (M, 3) (noise-free head pose, for a camera). Same seed, same log, bit for bit.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace

import numpy as np

from field.angles import wrap_angles
from motion_models.footsteps import LEFT, RIGHT, FootstepEvent, displacements, integrate
from motion_models.lwpr import load_npz, save_npz_atomically

LOG_FORMAT = "robocup-mcl footstep log"
LOG_FORMAT_VERSION = 1
MOCAP_RATE = 100.0  # Hz, the OptiTrack rate of sec. IV-A
MOCAP_NOISE = (0.0005, 0.002)  # m, rad (1σ): the motion capture, the same for every robot


@dataclass(frozen=True)
class Robot:
    """One robot and its sensors (the nominal robot by default; `draw_robot` draws others from `ROBOT_RANGES`).
    Lengths in metres, angles in radians, per step."""

    walk_frequency: float = 1.7  # Hz, cycles of two steps (sec. IV-B 2): the walk engine's, every robot
    inertia_x: float = 0.22  # relative forward overshoot of a short swing ...
    inertia_speed: float = 5.0  # ... growing by this per metre of step (a faster swing lags more)
    inertia_y: float = 0.18  # relative lateral overshoot
    inertia_theta: float = 0.12  # relative turn overshoot
    backlash: float = 0.006  # m of extra swing from gear play, in the swing direction (x and y)
    backlash_width: float = 0.004  # m: steps shorter than this take up only part of the play
    turn_push: float = 0.028  # m forward per rad turned (turning in place walks forward)
    lateral_alternation: float = 0.3  # relative: the lateral step that opens the legs is longer
    lateral_turn: float = 0.6  # rad per m of lateral step (the sole's friction torque)
    foot_turn_left: float = 0.008  # rad per step on left support
    foot_turn_right: float = -0.004  # rad per step on right support
    foot_forward_left: float = 0.002  # m per step on left support
    foot_forward_right: float = -0.0011  # m per step on right support
    momentum_1: float = 0.3  # share of the real (leg) step k-1 carried into step k ...
    momentum_2: float = 0.09  # ... of step k-2 ...
    momentum_3: float = 0.04  # ... of step k-3 (the body's momentum spans several steps)
    sway: float = 0.02  # m, lateral head sway toward the support foot (zero at the swaps)
    compliance: float = 0.08  # relative: leg flex the encoders do not see
    encoder_noise: float = 0.0012  # m per step from 0.3° encoder resolution through the legs
    gyro_bias_sigma: float = 0.0008  # rad/s, per-run gyro bias left after the standing calibration (1σ)
    gyro_scale: float = 0.02  # gyro scale error of the device (a run adds `Conditions.gyro_scale`)
    gyro_noise: float = 0.005  # rad/√s white noise

    @property
    def step_period(self) -> float:
        """Seconds per step: two steps a walk cycle."""
        return 0.5 / self.walk_frequency

    @property
    def momentum(self) -> tuple[float, float, float]:
        """Shares of the real steps k-1, k-2, k-3 carried into step k."""
        return (self.momentum_1, self.momentum_2, self.momentum_3)


# Per-robot ranges: `draw_robot` draws each parameter uniformly in [low, high] (at spread 1; spread s scales the
# distance of both ends from the nominal value by s). Every nominal value lies inside its range.
ROBOT_RANGES: dict[str, tuple[float, float]] = {
    "inertia_x": (0.12, 0.32),
    "inertia_speed": (2.5, 7.5),
    "inertia_y": (0.08, 0.28),
    "inertia_theta": (0.04, 0.2),
    "backlash": (0.0035, 0.0085),
    "backlash_width": (0.0025, 0.0055),
    "turn_push": (0.012, 0.044),
    "lateral_alternation": (0.15, 0.45),
    "lateral_turn": (0.3, 0.9),
    "foot_turn_left": (-0.004, 0.02),
    "foot_turn_right": (-0.016, 0.008),
    "foot_forward_left": (-0.0015, 0.0055),
    "foot_forward_right": (-0.0045, 0.0023),
    "momentum_1": (0.15, 0.45),
    "momentum_2": (0.0, 0.2),
    "momentum_3": (0.0, 0.08),
    "sway": (0.012, 0.028),
    "compliance": (0.04, 0.12),
    "encoder_noise": (0.0008, 0.0016),
    "gyro_bias_sigma": (0.0004, 0.0012),
    "gyro_scale": (-0.02, 0.06),
    "gyro_noise": (0.003, 0.007),
}
MAX_MOMENTUM = 0.8  # the three momentum shares are scaled down to sum to at most this (a stable walk)


@dataclass(frozen=True)
class Conditions:
    """What changes from one run (log) to the next on the same robot; nominal values by default, drawn from
    `CONDITION_RANGES` by `draw_conditions`."""

    friction: float = 1.0  # relative grip of the ground: slip spread / friction, drag · friction,
    # and a systematic slide of SLIDE·(1 - friction) of each leg step
    bias_forward: float = 0.0  # m per step of the legs' forward motion (servo warmth, battery)
    bias_turn: float = 0.0  # rad per step of the legs' turn
    encoder_scale: float = 0.0  # relative error of the kinematic model (zero offsets after a repair)
    encoder_nonlinearity: float = 0.0  # relative gain change of the encoder step at a step of ENCODER_REFERENCE
    gyro_scale: float = 0.0  # run's gyro scale error, on top of `Robot.gyro_scale`
    gyro_nonlinearity: float = 0.0  # relative gyro gain change per rad/s of turn rate


CONDITION_RANGES: dict[str, tuple[float, float]] = {
    "friction": (0.6, 1.4),
    "bias_forward": (-0.0025, 0.0025),
    "bias_turn": (-0.008, 0.008),
    "encoder_scale": (-0.045, 0.045),
    "encoder_nonlinearity": (-0.15, 0.15),
    "gyro_scale": (-0.015, 0.015),
    "gyro_nonlinearity": (-0.04, 0.04),
}
SLIDE = 0.25  # relative slide of the support foot per unit of friction lost (unseen by the encoders)
ENCODER_REFERENCE = 0.04  # m: the step length at which `Conditions.encoder_nonlinearity` is the gain change
MIN_FRICTION = 0.2  # the friction drawn at large spreads is kept above this
# Physical limits of drawn values: magnitudes stay >= 0, friction >= MIN_FRICTION.
_NON_NEGATIVE = (
    "inertia_x",
    "inertia_speed",
    "inertia_y",
    "inertia_theta",
    "backlash",
    "turn_push",
    "lateral_alternation",
    "lateral_turn",
    "momentum_1",
    "momentum_2",
    "momentum_3",
    "sway",
    "compliance",
    "encoder_noise",
    "gyro_bias_sigma",
    "gyro_noise",
)
_ROBOT_STREAM, _CONDITIONS_STREAM = 7301, 7302


def _check_spread(spread: float) -> float:
    if isinstance(spread, bool) or not isinstance(spread, (int, float)) or not (math.isfinite(spread) and spread >= 0):
        raise ValueError(f"spread = {spread!r} must be a finite number >= 0")
    return float(spread)


def _draw(nominal, ranges: dict[str, tuple[float, float]], rng: np.random.Generator, spread: float) -> dict:
    """Each parameter of `ranges` drawn uniformly within its range scaled about the nominal value by `spread`.
    One uniform variate per parameter, in a fixed order: the same draw at every spread, only scaled."""
    out = {}
    for name, (low, high) in ranges.items():
        centre = getattr(nominal, name)
        u = rng.random()
        out[name] = float(centre + spread * ((low - centre) + u * (high - low)))
    return out


def draw_robot(robot_id: int, spread: float = 1.0) -> Robot:
    """Robot number `robot_id` of the fleet: every parameter of `ROBOT_RANGES` drawn (see `_draw`); spread 0
    gives the nominal robot. Different ids are different robots; the same id and spread, the same robot.

    Raises ValueError for an id that is not an integer >= 0 or a spread that is not a finite number >= 0."""
    if isinstance(robot_id, bool) or not isinstance(robot_id, (int, np.integer)) or robot_id < 0:
        raise ValueError(f"robot_id = {robot_id!r} must be an integer >= 0")
    spread = _check_spread(spread)
    values = _draw(Robot(), ROBOT_RANGES, np.random.default_rng([_ROBOT_STREAM, int(robot_id)]), spread)
    for name in _NON_NEGATIVE:
        values[name] = max(0.0, values[name])
    total = values["momentum_1"] + values["momentum_2"] + values["momentum_3"]
    if total > MAX_MOMENTUM:
        for name in ("momentum_1", "momentum_2", "momentum_3"):
            values[name] *= MAX_MOMENTUM / total
    values["backlash_width"] = max(values["backlash_width"], 1e-4)
    return replace(Robot(), **values)


def draw_conditions(run_seed: int, spread: float = 1.0) -> Conditions:
    """The conditions of run `run_seed`: every parameter of `CONDITION_RANGES` drawn (see `_draw`); spread 0
    gives the nominal conditions. Raises ValueError for a seed that is not an integer >= 0 or a bad spread."""
    if isinstance(run_seed, bool) or not isinstance(run_seed, (int, np.integer)) or run_seed < 0:
        raise ValueError(f"run_seed = {run_seed!r} must be an integer >= 0")
    spread = _check_spread(spread)
    values = _draw(Conditions(), CONDITION_RANGES, np.random.default_rng([_CONDITIONS_STREAM, int(run_seed)]), spread)
    values["friction"] = max(MIN_FRICTION, values["friction"])
    return Conditions(**values)


@dataclass(frozen=True)
class Surface:
    """What the ground does to the walk."""

    name: str
    forward_drift: float  # m per step at zero forward command (trunk lean, tuned for grass)
    drag: float  # relative step length lost to the flying foot dragging in grass
    drag_variation: float  # relative spread of that drag from step to step
    leg_noise: tuple[float, float, float]  # irregular leg motion per step (seen by the encoders) x, y, θ
    slip: tuple[float, float, float]  # support-foot slip per step (not seen by encoders; θ by gyro)
    timing_jitter: float  # s, spread of the detected swap around the engine's timing


CARPET = Surface(
    "carpet",
    forward_drift=0.003,
    drag=0.0,
    drag_variation=0.0,
    leg_noise=(0.002, 0.002, 0.008),
    slip=(0.0025, 0.0025, 0.006),
    timing_jitter=0.008,
)
GRASS = Surface(
    "grass",
    forward_drift=0.005,
    drag=0.12,
    drag_variation=0.5,
    leg_noise=(0.005, 0.004, 0.02),
    slip=(0.0015, 0.0015, 0.004),
    timing_jitter=0.012,
)
SURFACES = {"carpet": CARPET, "grass": GRASS}


@dataclass(frozen=True)
class Driver:
    """The joystick operator: gait command limits, how often the intent changes, the area to stay in."""

    forward: tuple[float, float] = (-0.03, 0.05)  # m per step
    lateral: float = 0.03  # m per step, either side
    turn: float = 0.3  # rad per step, either side
    ramp: tuple[float, float, float] = (0.008, 0.006, 0.05)  # largest change per step (stability)
    change_rate: float = 0.5  # new intent per second (on average)
    area: tuple[float, float] = (1.0, 0.75)  # half-sizes of the capture area (2 m × 1.5 m)
    margin: float = 0.3  # steer back when closer than this to the edge


@dataclass(frozen=True)
class FootstepLog:
    """One recorded walk (see the module docstring for the fields)."""

    surface: str
    seed: int
    step_period: float
    swap_times: np.ndarray  # (K+1,) s, swaps detected by the pressure sensors
    swap_poses: np.ndarray  # (K+1, 3) motion capture at the swaps
    support: np.ndarray  # (K,) LEFT (+1) / RIGHT (-1) during each step
    commanded: np.ndarray  # (K, 3) gait command = a-priori displacement of each step
    sensor: np.ndarray  # (K, 3) sensor-based displacement of each step
    mocap_times: np.ndarray  # (M,)
    mocap: np.ndarray  # (M, 3) motion capture of the head
    truth: np.ndarray  # (M, 3) noise-free head pose

    @property
    def durations(self) -> np.ndarray:
        """(K,) step durations between detected swaps [s]."""
        return np.diff(self.swap_times)

    @property
    def n_steps(self) -> int:
        return int(self.support.shape[0])

    def first(self, seconds: float) -> FootstepLog:
        """The steps that end within the first `seconds` (the learning sequence of sec. IV-B 2)."""
        k = int(np.searchsorted(self.swap_times, seconds, side="right")) - 1
        return self.steps(0, max(k, 0))

    def steps(self, start: int, stop: int) -> FootstepLog:
        """Steps start..stop-1 (the motion capture is kept whole)."""
        return replace(
            self,
            swap_times=self.swap_times[start : stop + 1],
            swap_poses=self.swap_poses[start : stop + 1],
            support=self.support[start:stop],
            commanded=self.commanded[start:stop],
            sensor=self.sensor[start:stop],
        )

    def events(self) -> list[FootstepEvent]:
        """The footstep event of every step, as a robot emits it at the swap ending the step (the step
        before the first counts as standing: zero displacement, one nominal period)."""
        durations = self.durations
        out = []
        for k in range(self.n_steps):
            prev = k - 1
            out.append(
                FootstepEvent(
                    support=int(self.support[k]),
                    commanded=tuple(self.commanded[k]),
                    previous_commanded=tuple(self.commanded[prev]) if prev >= 0 else (0.0, 0.0, 0.0),
                    sensor=tuple(self.sensor[k]),
                    previous_sensor=tuple(self.sensor[prev]) if prev >= 0 else (0.0, 0.0, 0.0),
                    duration=float(durations[k]),
                    previous_duration=float(durations[prev]) if prev >= 0 else self.step_period,
                )
            )
        return out


def truth_displacements(log: FootstepLog) -> np.ndarray:
    """The ground-truth footstep displacements (K, 3): motion capture at consecutive swaps (Fig. 3)."""
    return displacements(log.swap_poses)


# ---------------------------------------------------------------------------------------------------------
# The driver
# ---------------------------------------------------------------------------------------------------------
def _random_intent(d: Driver, rng: np.random.Generator) -> np.ndarray:
    """A new joystick intent, mixing the walk modes an operator explores the footstep space with."""
    lo, hi = d.forward
    mode = rng.choice(6, p=[0.3, 0.15, 0.15, 0.25, 0.1, 0.05])
    if mode == 0:  # forward, slightly curved
        return np.array([rng.uniform(0.015, hi), rng.uniform(-0.01, 0.01), rng.uniform(-0.1, 0.1)])
    if mode == 1:  # sideways
        return np.array(
            [rng.uniform(-0.01, 0.02), rng.choice([-1, 1]) * rng.uniform(0.01, d.lateral), rng.uniform(-0.05, 0.05)]
        )
    if mode == 2:  # turn in place (the operator's "zero" forward drifts slightly either way)
        return np.array([rng.uniform(-0.01, 0.005), 0.0, rng.choice([-1, 1]) * rng.uniform(0.1, d.turn)])
    if mode == 3:  # anything
        return np.array([rng.uniform(lo, hi), rng.uniform(-d.lateral, d.lateral), rng.uniform(-d.turn, d.turn)])
    if mode == 4:  # backward
        return np.array([rng.uniform(lo, -0.01), rng.uniform(-0.01, 0.01), rng.uniform(-0.1, 0.1)])
    return np.zeros(3)  # stop (walk in place)


def _homing_intent(d: Driver, pose: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Back toward the centre of the area: turn toward it, walk once roughly facing it."""
    to_centre = centre - pose[:2]
    bearing = math.remainder(math.atan2(to_centre[1], to_centre[0]) - pose[2], 2 * math.pi)
    forward = d.forward[1] * 0.8 * max(0.0, math.cos(bearing)) ** 2
    return np.array(
        [
            forward,
            0.5 * d.lateral * math.sin(bearing) * (abs(bearing) < 1.0),
            float(np.clip(0.8 * bearing, -d.turn, d.turn)),
        ]
    )


# ---------------------------------------------------------------------------------------------------------
# The continuous head trajectory
# ---------------------------------------------------------------------------------------------------------
def _sinc(a: np.ndarray) -> np.ndarray:
    safe = np.where(np.abs(a) > 1e-9, a, 1.0)
    return np.where(np.abs(a) > 1e-9, np.sin(safe) / safe, 1.0 - a * a / 6.0)


def _head_poses(
    t: np.ndarray, period: float, trunk: np.ndarray, steps: np.ndarray, support: np.ndarray, sway: float
) -> np.ndarray:
    """Head pose at times t: trunk pose at the step's nominal start, composed with the constant-twist arc
    covering share u of the step (chord sin(uh)/(uh) turned by uh, h = dθ/2, as `MotionInput.displacement`),
    plus the lateral sway A·sin(πu) toward the support foot."""
    k = np.clip(np.floor(t / period).astype(np.int64), 0, steps.shape[0] - 1)
    u = t / period - k
    s = steps[k]
    h = 0.5 * s[:, 2]
    # Body-frame velocity of the arc that ends exactly at (dx, dy, dθ) after u = 1.
    c, sn, chord = np.cos(h), np.sin(h), _sinc(h)
    vx = (c * s[:, 0] + sn * s[:, 1]) / chord
    vy = (-sn * s[:, 0] + c * s[:, 1]) / chord
    hu = u * h
    cu, su, chord_u = np.cos(hu), np.sin(hu), u * _sinc(hu)
    lx = chord_u * (cu * vx - su * vy)
    ly = chord_u * (su * vx + cu * vy) + sway * support[k] * np.sin(math.pi * u)
    base = trunk[k]
    cb, sb = np.cos(base[:, 2]), np.sin(base[:, 2])
    out = np.empty((t.shape[0], 3))
    out[:, 0] = base[:, 0] + cb * lx - sb * ly
    out[:, 1] = base[:, 1] + sb * lx + cb * ly
    out[:, 2] = wrap_angles(base[:, 2] + u * s[:, 2])
    return out


# ---------------------------------------------------------------------------------------------------------
# The walk
# ---------------------------------------------------------------------------------------------------------
def _leg_target(
    r: Robot, g: Surface, command: np.ndarray, support: int, drag: float, c: Conditions = Conditions()
) -> np.ndarray:
    """Where the legs take the robot for this command and support foot, before momentum and noise."""
    cx, cy, ct = command
    left = support == LEFT
    # Inertia: the servo lag makes the swing overshoot, relatively more for a longer (faster) swing.
    gain_x = 1.0 + r.inertia_x + r.inertia_speed * abs(cx) - drag
    # Lateral: the step whose swing foot leads in the direction of motion opens the legs (longer).
    opening = -support * math.copysign(1.0, cy) if cy != 0.0 else 0.0
    gain_y = 1.0 + r.inertia_y + r.lateral_alternation * opening - drag
    x = (
        gain_x * cx
        + r.backlash * math.tanh(cx / r.backlash_width)
        + g.forward_drift
        + r.turn_push * abs(ct)
        + (r.foot_forward_left if left else r.foot_forward_right)
        + c.bias_forward
    )
    y = gain_y * cy + r.backlash * math.tanh(cy / r.backlash_width)
    theta = (
        (1.0 + r.inertia_theta) * ct
        + (r.foot_turn_left if left else r.foot_turn_right)
        + r.lateral_turn * cy
        + c.bias_turn
    )
    return np.array([x, y, theta])


def simulate(
    duration: float = 300.0,
    surface: str | Surface = "grass",
    seed: int = 0,
    robot: Robot = Robot(),
    driver: Driver = Driver(),
    start=(0.0, 0.0, 0.0),
    centre=(0.0, 0.0),
    conditions: Conditions = Conditions(),
) -> FootstepLog:
    """Walk for `duration` seconds on `surface` with `robot` under the run's `conditions`, driven by the
    joystick `driver`; everything random comes from `seed` (separate streams for the driver, the walk, the
    sensors and the motion capture). The defaults are the nominal robot and conditions."""
    g = SURFACES.get(surface) if isinstance(surface, str) else surface
    if not isinstance(g, Surface):
        raise ValueError(f"surface = {surface!r} must be one of {tuple(SURFACES)} or a Surface")
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration >= 2.0):
        raise ValueError(f"duration = {duration!r} must be finite and >= 2 s")
    if not isinstance(robot, Robot) or not isinstance(conditions, Conditions):
        raise ValueError(f"robot = {robot!r} must be a Robot and conditions = {conditions!r} Conditions")
    if not conditions.friction > 0:
        raise ValueError(f"conditions.friction = {conditions.friction!r} must be > 0")
    r, d, c = robot, driver, conditions
    momentum = np.array(r.momentum)
    slide = SLIDE * (1.0 - c.friction)
    period = r.step_period
    driver_rng, walk_rng, sensor_rng, mocap_rng = (
        np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(4)
    )
    n_nominal = int(math.ceil(duration / period)) + 2
    centre_xy = np.asarray(centre, dtype=np.float64)
    half = np.asarray(d.area) - d.margin

    commands = np.zeros((n_nominal, 3))
    support = np.where(np.arange(n_nominal) % 2 == 0, LEFT, RIGHT).astype(np.int64)
    legs = np.zeros((n_nominal, 3))  # what the legs did (seen by the encoders, backlash aside)
    slips = np.zeros((n_nominal, 3))
    trunk = np.zeros((n_nominal + 1, 3))
    trunk[0] = start
    previous_command = np.zeros(3)
    previous_legs = np.zeros((momentum.size, 3))  # the real (leg) steps k-1, k-2, k-3
    intent = np.zeros(3)
    ramp = np.asarray(d.ramp)
    limits_lo = np.array([d.forward[0], -d.lateral, -d.turn])
    limits_hi = np.array([d.forward[1], d.lateral, d.turn])
    change_probability = d.change_rate * period
    for k in range(n_nominal):
        pose = trunk[k]
        # The operator watches the robot (the truth) and brings it back before it leaves the area.
        if np.any(np.abs(pose[:2] - centre_xy) > half):
            intent = _homing_intent(d, pose, centre_xy)
        elif driver_rng.random() < change_probability:
            intent = _random_intent(d, driver_rng)
        command = np.clip(previous_command + np.clip(intent - previous_command, -ramp, ramp), limits_lo, limits_hi)
        commands[k] = command
        drag = c.friction * g.drag * max(0.0, 1.0 + g.drag_variation * walk_rng.standard_normal())
        target = _leg_target(r, g, command, int(support[k]), drag, c)
        # Momentum: the body keeps shares of the previous three real steps.
        legs[k] = (
            momentum @ previous_legs
            + (1.0 - momentum.sum()) * target
            + np.asarray(g.leg_noise) * walk_rng.standard_normal(3)
        )
        # The support foot slips at random, more on a slippery ground, and slides back by a share of the step.
        slips[k] = np.asarray(g.slip) / c.friction * walk_rng.standard_normal(3)
        slips[k, :2] -= slide * legs[k, :2]
        trunk[k + 1] = integrate((legs[k] + slips[k])[None, :], trunk[k])[1]
        previous_command = command
        previous_legs = np.vstack([legs[k][None, :], previous_legs[:-1]])

    # Detected swaps: the engine's timing plus the pressure sensors' jitter (the first swap starts the log).
    nominal = np.arange(n_nominal + 1) * period
    jitter = np.clip(g.timing_jitter * sensor_rng.standard_normal(n_nominal + 1), -0.3 * period, 0.3 * period)
    jitter[0] = 0.0
    swap_times = nominal + jitter
    n_swaps = int(np.searchsorted(swap_times, duration, side="right"))
    swap_times = swap_times[:n_swaps]
    steps = legs + slips
    head_at_swaps = _head_poses(swap_times, period, trunk, steps, support, r.sway)
    interval = displacements(head_at_swaps)  # what really happened between detected swaps
    n_steps = n_swaps - 1
    step_support = support[:n_steps]
    durations = np.diff(swap_times)

    # Sensor-based odometry: encoders through the kinematic model see the interval's motion minus the
    # support foot's slip, minus the backlash they sit behind and the leg compliance, through the run's
    # kinematic calibration (a scale error and a gain that changes with the step length); yaw from the gyro,
    # whose gain changes with the turn rate.
    gyro_bias = r.gyro_bias_sigma * sensor_rng.standard_normal()
    seen = interval[:, :2] - slips[:n_steps, :2]
    legs_seen = seen * (1.0 - r.compliance) - r.backlash * np.tanh(seen / r.backlash_width)
    gain = 1.0 + c.encoder_scale + c.encoder_nonlinearity * np.abs(legs_seen) / ENCODER_REFERENCE
    sensor = np.empty((n_steps, 3))
    sensor[:, :2] = legs_seen * gain + r.encoder_noise * sensor_rng.standard_normal((n_steps, 2))
    rate = np.abs(interval[:, 2]) / durations
    sensor[:, 2] = (
        interval[:, 2] * (1.0 + r.gyro_scale + c.gyro_scale + c.gyro_nonlinearity * rate)
        + gyro_bias * durations
        + r.gyro_noise * np.sqrt(durations) * sensor_rng.standard_normal(n_steps)
    )

    # Motion capture of the head at 100 Hz, read at the sample nearest each detected swap.
    mocap_times = np.arange(int(math.floor(duration * MOCAP_RATE)) + 1) / MOCAP_RATE
    truth = _head_poses(mocap_times, period, trunk, steps, support, r.sway)
    noise = mocap_rng.standard_normal((mocap_times.shape[0], 3)) * np.array([*[MOCAP_NOISE[0]] * 2, MOCAP_NOISE[1]])
    mocap = truth + noise
    mocap[:, 2] = wrap_angles(mocap[:, 2])
    nearest = np.clip(np.rint(swap_times * MOCAP_RATE).astype(np.int64), 0, mocap_times.shape[0] - 1)
    return FootstepLog(
        surface=g.name,
        seed=int(seed),
        step_period=period,
        swap_times=swap_times,
        swap_poses=mocap[nearest],
        support=step_support.astype(np.int64),
        commanded=commands[:n_steps].copy(),
        sensor=sensor,
        mocap_times=mocap_times,
        mocap=mocap,
        truth=truth,
    )


# ---------------------------------------------------------------------------------------------------------
# The log file
# ---------------------------------------------------------------------------------------------------------
_ARRAYS = {
    "swap_times": 1,
    "swap_poses": 2,
    "support": 1,
    "commanded": 2,
    "sensor": 2,
    "mocap_times": 1,
    "mocap": 2,
    "truth": 2,
}


def save_log(log: FootstepLog, path: str | os.PathLike) -> None:
    """Write `log` as a versioned `.npz` (to a temporary file, then renamed: never a half-written log)."""
    fields = {name: getattr(log, name) for name in _ARRAYS}
    fields.update(
        format=np.array(LOG_FORMAT),
        format_version=np.array(LOG_FORMAT_VERSION),
        surface=np.array(log.surface),
        seed=np.array(log.seed),
        step_period=np.array(log.step_period),
    )
    save_npz_atomically(path, fields)


def load_log(path: str | os.PathLike) -> FootstepLog:
    """Read a log written by `save_log`. A truncated or foreign file, another format version, a missing
    field, inconsistent lengths or non-finite values raise ValueError naming the file and the problem."""
    path = os.fspath(path)
    data = load_npz(path, "a footstep log")
    for key in ("format", "format_version", "surface", "seed", "step_period", *_ARRAYS):
        if key not in data:
            raise ValueError(f"footstep log {path!r} lacks the field {key!r}")
    if str(data["format"]) != LOG_FORMAT:
        raise ValueError(f"{path!r} is not a footstep log (format {str(data['format'])!r})")
    if int(data["format_version"]) != LOG_FORMAT_VERSION:
        raise ValueError(
            f"footstep log {path!r} has format version {int(data['format_version'])}; this version "
            f"of robocup-mcl reads version {LOG_FORMAT_VERSION}"
        )
    for name, ndim in _ARRAYS.items():
        a = data[name]
        if a.ndim != ndim or (ndim == 2 and a.shape[1] != 3) or not np.isfinite(a).all():
            raise ValueError(
                f"footstep log {path!r}: field {name!r} must be finite with "
                f"{'shape (n, 3)' if ndim == 2 else 'one dimension'}, got shape {a.shape}"
            )
    k = data["support"].shape[0]
    if (
        k < 2
        or data["swap_times"].shape[0] != k + 1
        or data["swap_poses"].shape[0] != k + 1
        or data["commanded"].shape[0] != k
        or data["sensor"].shape[0] != k
    ):
        raise ValueError(
            f"footstep log {path!r}: inconsistent step counts (support {k}, swap_times "
            f"{data['swap_times'].shape[0]}, commanded {data['commanded'].shape[0]}, sensor "
            f"{data['sensor'].shape[0]}); need at least 2 steps"
        )
    if not np.isin(data["support"], (LEFT, RIGHT)).all():
        raise ValueError(f"footstep log {path!r}: field 'support' must hold only +1 (left) and -1 (right)")
    if not (np.diff(data["swap_times"]) > 0).all():
        raise ValueError(f"footstep log {path!r}: field 'swap_times' must increase")
    if data["mocap"].shape != data["truth"].shape or data["mocap"].shape[0] != data["mocap_times"].shape[0]:
        raise ValueError(f"footstep log {path!r}: mocap, truth and mocap_times differ in length")
    return FootstepLog(
        surface=str(data["surface"]),
        seed=int(data["seed"]),
        step_period=float(data["step_period"]),
        **{name: data[name].astype(np.int64 if name == "support" else np.float64) for name in _ARRAYS},
    )
