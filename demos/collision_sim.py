"""The collision scenario: a walking robot whose leg servos lag their commands, and which runs into things.

    from demos.collision_sim import CollisionScenario, paper_case, random_collisions, simulate

    log = simulate(paper_case("single"), seed=0)   # Hoffmann 4.2: 10 s at 200 mm/s, one collision of ~2 s
    log.truth, log.mode, log.contact               # (T, 3) true pose, (T,) mobility state, (T,) contact side
    log.servo_commands, log.servo_readings         # (T, J) leg joint commands and servo readings [rad]

What is simulated, at 100 Hz:
- Gait: each leg's hip roll, hip pitch, knee pitch and ankle pitch follow a periodic pattern of the gait phase
  (one cycle of `cycle` seconds, legs half a cycle apart) whose amplitudes grow with the step lengths the walk
  request asks for, with a base lift for stepping in place.
- Servos: each reading follows its command `servo_delay` seconds late (whole frames) through a first-order lag
  (`servo_gain` of the remaining error closed per frame), plus reading noise and the encoder's quantization.
  Free walking therefore leaves a deviation between command and reading that grows with the joint speeds, i.e.
  with walking speed and gait phase (what the detector's reference learns). On a side in contact with an
  obstacle the joints of `held_joints` are held back (the servo reaches only part of its way each frame, with
  jolts); a push deflects the hip roll and pitch of the pushed side. Slipping feet unload the legs a little.
- Motion: when free, the walk request times a per-run scale error plus step-to-step noise and a small turn
  bias: a calibrated walking engine. Slippage: slower, heading disturbed; hindrance: slower; pushed: displaced
  sideways (and a little forward) and turned by an external velocity. Stopped: the held foot is a pivot. The
  free foot keeps stepping, at `stop_turn` (a share, interpolated by the event's severity) of the requested
  speed while it is on the ground, so the body turns about the held foot toward the obstacle at
  ω = share·|v| / foot_separation (averaged over a gait cycle; in pulses, one per step of the free leg), and its
  centre, half a foot separation from the pivot, moves on at |ω|·foot_separation / 2 in the walking direction.
  Held on both sides, there is no pivot and the robot stands.
- Camera: the walk scenario's panning camera (`demos.walk_sim`), landmark detections only.

Physics: `physics="nominal"` runs the scenario's fields as they are (one robot, one world). With
`physics="mismatch"` every run draws its robot and world from `MISMATCH_RANGES` (uniform, independently per
field; a pair's two ends each from its own range), from a generator of its own seeded by `robot_seed` (or the
run's seed), so that a robot's free walk and its collision runs share the robot:

    field                 nominal            per-run range (mismatch)
    foot_separation       0.12 m             0.07 .. 0.18 m
    cycle                 0.5 s              0.42 .. 0.68 s
    servo_delay           0.03 s             0.015 .. 0.065 s (2 to 7 frames at 100 Hz)
    servo_gain            0.55               0.35 .. 0.85
    reading_noise         0.0025 rad         0.001 .. 0.005 rad
    held_joints           hip pitch, knee,   any non-empty subset of the four joints
                          ankle
    scale_sigma           0.025              0.01 .. 0.05
    turn_bias_sigma       0.006 rad/s        0.002 .. 0.015 rad/s
    step_noise            0.045              0.02 .. 0.12
    hindrance_speed       (0.75, 0.22)       (0.55 .. 0.95, 0.0 .. 0.45)
    push_speed            (0.12, 0.45) m/s   (0.04 .. 0.28, 0.3 .. 0.8) m/s
    push_turn             0.7 rad/s          0.15 .. 1.3 rad/s
    stop_turn             (0.15, 0.55)       one share for both ends, 0.05 .. 1.05 (of |v| / foot_separation)
    slip_speed            (0.85, 0.45)       (0.65 .. 1.0, 0.05 .. 0.55)
    slip_turn             0.35 rad/s         0.08 .. 0.9 rad/s
    contact_hold          (0.3, 0.75)        (0.05 .. 0.4, 0.5 .. 0.95)
    ground_bumps          0.8 /s             0.3 .. 2.2 /s
    bump_size             0.011 rad          0.005 .. 0.02 rad

None of these values is taken from a motion model: the models' parameters are fitted from logs of this
simulator (`robocup-mcl fit adaptive`), and a test checks that no model default equals one of these numbers.

Ground truth for all of it: pose, mobility state and contact side per step, and the list of events.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from dataclasses import field as dataclass_field

import numpy as np

from field import Field, spl

from .walk_sim import CameraFrame, WalkScenario, _camera

FREE, SLIPPAGE, HINDRANCE, PUSHED, STOPPED = range(5)
MODE_NAMES = ("free", "slippage", "hindrance", "pushed", "stopped")
NO_CONTACT, LEFT, RIGHT, BOTH = range(4)
SIDE_NAMES = ("none", "left", "right", "both")
JOINTS = ("hip_roll", "hip_pitch", "knee_pitch", "ankle_pitch")
LEFT_LEG, RIGHT_LEG = 0, 1


@dataclass(frozen=True)
class CollisionEvent:
    """A period in a non-free mobility state. `side` is where the contact is (LEFT, RIGHT, BOTH; slippage has
    no contact). `severity` in [0, 1] scales the effect (how hard the robot is held, pushed or turned)."""

    start: float  # s
    duration: float  # s
    mode: int  # SLIPPAGE, HINDRANCE, PUSHED or STOPPED
    side: int  # NO_CONTACT, LEFT, RIGHT or BOTH
    severity: float = 0.5
    direction: float = 1.0  # +1 or -1: the sense of a slippage's turn

    @property
    def end(self) -> float:
        return self.start + self.duration


@dataclass(frozen=True)
class CollisionScenario:
    field: Field = dataclass_field(default_factory=spl)
    duration: float = 10.0  # s
    rate: float = 100.0  # Hz, motion, servo and filter rate
    command: tuple[float, float, float] | None = (0.2, 0.0, 0.0)  # constant walk request; None: varied
    events: tuple[CollisionEvent, ...] = ()
    start: tuple[float, float, float] | None = None  # None: random in the own half, facing up the field
    # gait
    cycle: float = 0.5  # s per gait cycle (each leg swings once)
    foot_separation: float = 0.12  # m, lateral distance between the feet (the stopped robot's pivot arm)
    # servos
    servo_delay: float = 0.03  # s between a command and the servo starting to act on it (whole frames)
    servo_gain: float = 0.55  # share of the remaining error a servo closes per frame
    reading_noise: float = 0.0025  # rad (1σ)
    quantization: float = math.radians(0.1)  # rad, encoder resolution
    held_joints: tuple[int, ...] = (1, 2, 3)  # indices into JOINTS: the joints an obstacle holds back
    # free-walking odometry error of a calibrated walking engine
    scale_sigma: float = 0.025  # per-run scale error of vx, vy, ω (1σ)
    turn_bias_sigma: float = 0.006  # rad/s (1σ), per run
    step_noise: float = 0.045  # relative step-to-step velocity noise
    # effects of the mobility states (per event, interpolated by its severity)
    hindrance_speed: tuple[float, float] = (0.75, 0.22)  # speed factor at severity 0 and 1
    push_speed: tuple[float, float] = (0.12, 0.45)  # m/s of the push at severity 0 and 1
    push_turn: float = 0.7  # rad/s at severity 1
    stop_turn: tuple[float, float] = (0.15, 0.55)  # the free foot's speed while stopped, share of the
    # request, at severity 0 and 1 (see the module doc)
    slip_speed: tuple[float, float] = (0.85, 0.45)
    slip_turn: float = 0.35  # rad/s at severity 1
    contact_hold: tuple[float, float] = (0.3, 0.75)  # share of a held servo's motion lost, severity 0..1,
    # on the forward swing (a third of it otherwise)
    ground_bumps: float = 0.8  # per second of walking: a foot landing hard jolts one joint
    bump_size: float = 0.011  # rad (1σ) of such a jolt
    physics: str = "nominal"  # "nominal": these fields; "mismatch": drawn per run (MISMATCH_RANGES)
    robot_seed: int | None = None  # seeds the per-run draw (None: the run's seed)
    # camera (landmark detections only)
    camera: WalkScenario = dataclass_field(default_factory=lambda: WalkScenario(kidnap_time=None))
    vision: bool = False


PHYSICS = ("nominal", "mismatch")
MISMATCH_RANGES: dict[str, tuple[float, float] | tuple[tuple[float, float], tuple[float, float]]] = {
    "foot_separation": (0.07, 0.18),
    "cycle": (0.42, 0.68),
    "servo_delay": (0.015, 0.065),
    "servo_gain": (0.35, 0.85),
    "reading_noise": (0.001, 0.005),
    "scale_sigma": (0.01, 0.05),
    "turn_bias_sigma": (0.002, 0.015),
    "step_noise": (0.02, 0.12),
    "hindrance_speed": ((0.55, 0.95), (0.0, 0.45)),
    "push_speed": ((0.04, 0.28), (0.3, 0.8)),
    "push_turn": (0.15, 1.3),
    "stop_turn": (0.05, 1.05),  # one share for both ends of the pair
    "slip_speed": ((0.65, 1.0), (0.05, 0.55)),
    "slip_turn": (0.08, 0.9),
    "contact_hold": ((0.05, 0.4), (0.5, 0.95)),
    "ground_bumps": (0.3, 2.2),
    "bump_size": (0.005, 0.02),
}
"""Per-run ranges of `physics="mismatch"` (uniform; for a pair, one range per end). `held_joints` is drawn as
well: any non-empty subset of the four joints of `JOINTS`."""


def draw_physics(scenario: CollisionScenario, seed: int) -> CollisionScenario:
    """The scenario a run simulates: itself for `physics="nominal"`; for "mismatch", its robot and world fields
    drawn from `MISMATCH_RANGES` by a generator seeded by `scenario.robot_seed` (or `seed`), so the same robot
    seed gives the same robot whatever the scenario's events and commands."""
    if scenario.physics not in PHYSICS:
        raise ValueError(f"physics = {scenario.physics!r} must be one of {PHYSICS}")
    if scenario.physics == "nominal":
        return scenario
    robot = seed if scenario.robot_seed is None else scenario.robot_seed
    rng = np.random.default_rng(np.random.SeedSequence([robot, 11]))
    drawn: dict = {}
    for name, bounds in MISMATCH_RANGES.items():
        if name == "stop_turn":
            share = float(rng.uniform(*bounds))
            drawn[name] = (share, share)
        elif isinstance(bounds[0], tuple):
            drawn[name] = tuple(float(rng.uniform(*end)) for end in bounds)
        else:
            drawn[name] = float(rng.uniform(*bounds))
    subsets = [mask for mask in range(1, 16)]
    mask = subsets[int(rng.integers(len(subsets)))]
    drawn["held_joints"] = tuple(j for j in range(4) if mask >> j & 1)
    return replace(scenario, **drawn)


@dataclass(frozen=True)
class CollisionLog:
    scenario: CollisionScenario
    dt: float
    times: np.ndarray  # (T,) time at the end of each step
    truth: np.ndarray  # (T, 3) true pose at the end of each step
    start: np.ndarray  # (3,) true pose at t = 0
    commands: np.ndarray  # (T, 3) walk request (vx, vy, ω)
    phase: np.ndarray  # (T,) gait phase in [0, 1)
    servo_commands: np.ndarray  # (T, 8) joint commands: left leg JOINTS, then right leg JOINTS [rad]
    servo_readings: np.ndarray  # (T, 8) servo readings [rad]
    joint_sides: np.ndarray  # (8,) LEFT_LEG or RIGHT_LEG per joint
    mode: np.ndarray  # (T,) true mobility state (FREE ... STOPPED)
    contact: np.ndarray  # (T,) true contact side (NO_CONTACT, LEFT, RIGHT, BOTH)
    events: tuple[CollisionEvent, ...]
    frames: tuple[CameraFrame, ...]


def paper_case(case: str, vision: bool = False, **overrides) -> CollisionScenario:
    """Hoffmann section 4: 10 s forward at 200 mm/s; "none" (4.1), "single" (4.2: one collision of about 2 s,
    on the left, during which the robot is first held back and then stopped, turning toward the obstacle),
    "double" (4.3: left, then right, in brief succession). Event times are nominal; `jitter_events` varies them.
    """
    if case == "none":
        events: tuple[CollisionEvent, ...] = ()
    elif case == "single":
        events = (CollisionEvent(3.0, 0.4, HINDRANCE, LEFT, 0.5), CollisionEvent(3.4, 1.6, STOPPED, LEFT, 0.6))
    elif case == "double":
        events = (
            CollisionEvent(3.0, 0.3, HINDRANCE, LEFT, 0.5),
            CollisionEvent(3.3, 0.9, STOPPED, LEFT, 0.6),
            CollisionEvent(4.8, 0.3, HINDRANCE, RIGHT, 0.5),
            CollisionEvent(5.1, 0.9, STOPPED, RIGHT, 0.6),
        )
    else:
        raise ValueError(f"case = {case!r} must be 'none', 'single' or 'double'")
    return CollisionScenario(events=events, vision=vision, **overrides)


def jitter_events(
    events: tuple[CollisionEvent, ...], rng: np.random.Generator, time_jitter: float = 0.5
) -> tuple[CollisionEvent, ...]:
    """The same story with a per-run shift of all start times (±time_jitter s) and fresh severities."""
    shift = rng.uniform(-time_jitter, time_jitter)
    return tuple(replace(e, start=e.start + shift, severity=float(rng.uniform(0.2, 1.0))) for e in events)


def random_collisions(
    duration: float, rng: np.random.Generator, mean_gap: float = 8.0, first: float = 3.0
) -> tuple[CollisionEvent, ...]:
    """Collisions of every kind and side at random times (exponential gaps of `mean_gap` s, at least 2 s
    of free walking between them), for measuring the detector: contact episodes are a hindrance that may turn
    into a stop, or a push; slippage episodes have no contact."""
    events = []
    t = first
    while True:
        t += rng.exponential(mean_gap)
        if t > duration - 3.0:
            break
        side = int(rng.choice([LEFT, RIGHT, BOTH], p=[0.4, 0.4, 0.2]))
        kind = rng.choice(["hindrance", "stop", "push", "slip"], p=[0.35, 0.3, 0.2, 0.15])
        severity = float(rng.uniform(0.0, 1.0))
        if kind == "hindrance":
            length = rng.uniform(0.4, 2.0)
            events.append(CollisionEvent(t, length, HINDRANCE, side, severity))
        elif kind == "stop":
            held = rng.uniform(0.2, 0.5)
            length = rng.uniform(0.8, 2.5)
            events.append(CollisionEvent(t, held, HINDRANCE, side, severity))
            events.append(CollisionEvent(t + held, length, STOPPED, side, severity))
            length += held
        elif kind == "push":
            length = rng.uniform(0.3, 0.8)
            events.append(CollisionEvent(t, length, PUSHED, LEFT if side == BOTH else side, severity))
        else:
            length = rng.uniform(0.3, 1.0)
            events.append(CollisionEvent(t, length, SLIPPAGE, NO_CONTACT, severity, float(rng.choice([-1.0, 1.0]))))
        t += length + 2.0
    return tuple(events)


def _joint_commands(phase: float, command: np.ndarray, cycle: float, out: np.ndarray) -> None:
    """Leg joint commands for one frame (left leg JOINTS, then right leg JOINTS).

    Step lengths per cycle set the amplitudes; the knee and ankle lift during the swing half of each leg's
    cycle, with a base lift so that stepping in place moves the legs too.
    """
    step_x = command[0] * cycle
    step_y = command[1] * cycle
    step_turn = command[2] * cycle
    for leg in (LEFT_LEG, RIGHT_LEG):
        leg_phase = 2.0 * math.pi * (phase + 0.5 * leg)
        sign = 1.0 if leg == LEFT_LEG else -1.0
        swing = max(0.0, math.sin(leg_phase))
        base = 4 * leg
        out[base + 0] = sign * 0.04 * math.sin(leg_phase) + 1.2 * step_y * math.sin(leg_phase) + sign * 0.05 * step_turn
        out[base + 1] = -0.35 - 1.6 * step_x * math.cos(leg_phase) - 0.3 * swing
        out[base + 2] = 0.7 + (0.25 + 1.2 * math.hypot(step_x, step_y)) * swing
        out[base + 3] = -0.35 + 1.6 * step_x * math.cos(leg_phase) * 0.5 - 0.2 * swing


def _event_at(events: tuple[CollisionEvent, ...], t: float) -> CollisionEvent | None:
    for event in events:
        if event.start <= t < event.end:
            return event
    return None


def _lerp(pair: tuple[float, float], share: float) -> float:
    return pair[0] + share * (pair[1] - pair[0])


def _varied_command(t: float, phases: np.ndarray) -> np.ndarray:
    """A joystick-like request: speed between 0.05 and 0.25 m/s, some sideways walking, turning."""
    vx = 0.15 + 0.1 * math.sin(0.21 * t + phases[0])
    vy = 0.04 * math.sin(0.13 * t + phases[1])
    omega = 0.3 * math.sin(0.17 * t + phases[2])
    return np.array([vx, vy, omega])


def simulate(scenario: CollisionScenario, seed: int = 0) -> CollisionLog:
    """Run the scenario once; everything random comes from `seed` (same seed, same log, bit for bit)."""
    s = draw_physics(scenario, seed)
    delay_frames = int(round(s.servo_delay * s.rate))
    rng = np.random.default_rng(seed)
    motion_rng, servo_rng, camera_rng = (
        np.random.default_rng(child) for child in np.random.SeedSequence(seed).spawn(3)
    )
    dt = 1.0 / s.rate
    n = int(round(s.duration * s.rate))
    scale = 1.0 + s.scale_sigma * rng.standard_normal(3)
    turn_bias = s.turn_bias_sigma * rng.standard_normal()
    command_phases = rng.uniform(0, 2 * math.pi, 3)
    if s.start is None:
        start = np.array([rng.uniform(-3.5, -2.5), rng.uniform(-1.5, 1.5), rng.uniform(-0.4, 0.4)])
    else:
        start = np.array(s.start, dtype=np.float64)
    pose = start.copy()
    phase0 = rng.uniform(0, 1)
    times = np.arange(1, n + 1) * dt
    truth = np.empty((n, 3))
    commands = np.empty((n, 3))
    phase = np.empty(n)
    joint_commands = np.empty((n, 8))
    readings = np.empty((n, 8))
    mode = np.zeros(n, dtype=np.int8)
    contact = np.zeros(n, dtype=np.int8)
    joint_sides = np.repeat([LEFT_LEG, RIGHT_LEG], 4)
    frames = []
    camera_every = s.rate / s.camera.camera_rate
    next_frame = camera_every
    # Servo state: the position each servo has reached; starts settled on the first command.
    current = np.empty(8)
    first_command = np.array(s.command if s.command is not None else _varied_command(0.0, command_phases))
    _joint_commands(phase0, first_command, s.cycle, current)
    history = np.tile(current, (delay_frames + 1, 1))
    frame_command = np.empty(8)
    for k in range(n):
        t = k * dt  # the step covers [t, t + dt)
        command = np.array(s.command if s.command is not None else _varied_command(t, command_phases))
        commands[k] = command
        phase[k] = (phase0 + t / s.cycle) % 1.0
        _joint_commands(phase[k], command, s.cycle, frame_command)
        joint_commands[k] = frame_command
        history = np.roll(history, -1, axis=0)
        history[-1] = frame_command
        target = history[0]  # the command `delay_frames` frames ago
        event = _event_at(s.events, t)
        gain = np.full(8, s.servo_gain)
        offset = np.zeros(8)
        extra_noise = 0.0
        velocity = command * scale * (1.0 + s.step_noise * motion_rng.standard_normal(3))
        walking = abs(command[0]) + abs(command[1]) > 0.02
        velocity[2] += turn_bias if walking else 0.0
        if event is not None:
            mode[k] = event.mode
            contact[k] = event.side
            share = event.severity
            if event.mode in (HINDRANCE, STOPPED) or (event.mode == PUSHED):
                for leg, flag in ((LEFT_LEG, LEFT), (RIGHT_LEG, RIGHT)):
                    if event.side in (flag, BOTH):
                        # Held hardest while the leg swings forward into the obstacle.
                        forward = max(0.0, math.sin(2.0 * math.pi * (phase[k] + 0.5 * leg)))
                        hold = _lerp(s.contact_hold, share) * (1.0 + 2.0 * forward) / 3.0
                        # The held joints lag, with jolts as the leg bumps into the obstacle.
                        for joint in s.held_joints:
                            gain[4 * leg + joint] *= 1.0 - hold
                        if event.mode == PUSHED:
                            sign = 1.0 if leg == LEFT_LEG else -1.0
                            offset[4 * leg + 0] = -sign * (0.03 + 0.05 * share)
                            offset[4 * leg + 1] = 0.02 + 0.03 * share
            if event.mode == SLIPPAGE:
                extra_noise = 0.002
                velocity[:2] *= _lerp(s.slip_speed, share)
                velocity[2] += s.slip_turn * share * event.direction
            elif event.mode == HINDRANCE:
                velocity[:2] *= _lerp(s.hindrance_speed, share)
            elif event.mode == PUSHED:
                away = -1.0 if event.side == LEFT else 1.0
                push = _lerp(s.push_speed, share)
                velocity[1] += away * push
                velocity[0] += 0.3 * push
                velocity[2] += -away * s.push_turn * share
            elif event.mode == STOPPED:
                # Pivoting about the held foot: the free foot pushes while it is on the ground (its stance,
                # the half cycle its swing term is 0), the body turns about the held foot and its centre
                # moves on at half the foot separation times the turn rate.
                sense = {LEFT: 1.0, RIGHT: -1.0}.get(event.side, 0.0)
                free_leg = RIGHT_LEG if event.side == LEFT else LEFT_LEG
                stance = max(0.0, -math.sin(2.0 * math.pi * (phase[k] + 0.5 * free_leg)))
                speed = math.hypot(command[0], command[1])
                foot = _lerp(s.stop_turn, share) * speed * math.pi * stance  # a cycle's mean: share·|v|
                turn = sense * foot / s.foot_separation
                heading = velocity[:2] / max(math.hypot(velocity[0], velocity[1]), 1e-12)
                velocity[:2] = heading * abs(turn) * 0.5 * s.foot_separation
                velocity[2] = turn
        # Servos: a first-order approach toward the delayed command, slowed where held, plus deflection.
        current += gain * (target - current)
        jolt = np.where(gain < s.servo_gain, 0.01 * servo_rng.standard_normal(8), 0.0)
        if servo_rng.random() < s.ground_bumps * dt:
            jolt[servo_rng.integers(8)] += s.bump_size * servo_rng.standard_normal()
        noisy = current + offset + jolt + (s.reading_noise + extra_noise) * servo_rng.standard_normal(8)
        readings[k] = np.round(noisy / s.quantization) * s.quantization
        # Motion: integrate the true velocity along the arc's midpoint heading.
        half = pose[2] + 0.5 * velocity[2] * dt
        c, sn = math.cos(half), math.sin(half)
        pose[0] += (c * velocity[0] - sn * velocity[1]) * dt
        pose[1] += (sn * velocity[0] + c * velocity[1]) * dt
        pose[2] = math.remainder(pose[2] + velocity[2] * dt, 2 * math.pi)
        truth[k] = pose
        if s.vision and k + 1 >= next_frame:
            next_frame += camera_every
            head = s.camera.head_pan_amplitude * math.sin(2 * math.pi * t / s.camera.head_pan_period)
            frames.append(CameraFrame(k, _camera(replace(s.camera, field=s.field), pose, head, camera_rng), head))
    return CollisionLog(
        s,
        dt,
        times,
        truth,
        start,
        commands,
        phase,
        joint_commands,
        readings,
        joint_sides,
        mode,
        contact,
        tuple(s.events),
        tuple(frames),
    )
