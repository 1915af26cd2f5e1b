"""The collision scenario: a walking robot whose leg servos lag their commands, and which runs into things.

    from demos.collision_sim import CollisionScenario, paper_case, random_collisions, simulate

    log = simulate(paper_case("single"), seed=0)   # Hoffmann 4.2: 10 s at 200 mm/s, one collision of ~2 s
    log.truth, log.mode, log.contact               # (T, 3) true pose, (T,) mobility state, (T,) contact side
    log.servo_commands, log.servo_readings         # (T, J) leg joint commands and servo readings [rad]

What is simulated, at 100 Hz:
- Gait: each leg's hip roll, hip pitch, knee pitch and ankle pitch follow a periodic pattern of the gait phase
  (one cycle of `cycle` seconds, legs half a cycle apart) whose amplitudes grow with the step lengths the walk
  request asks for, with a base lift for stepping in place.
- Servos: each reading follows its command with a delay of `delay_frames` frames and a first-order lag, plus
  reading noise and the encoder's quantization. Free walking therefore leaves a deviation between command and
  reading that grows with the joint speeds, i.e. with walking speed and gait phase (what the detector's
  reference learns). On a side in contact with an obstacle the hip and knee are held back (the servo reaches
  only part of its way each frame, with jolts); a push deflects the hip roll and pitch of the pushed side.
  Slipping feet unload the legs a little (small extra noise).
- Motion: when free, the walk request times a per-run scale error plus step-to-step noise and a small turn
  bias: a calibrated walking engine (Hoffmann cites the gait calibration that makes free odometry precise).
  The five mobility states move the robot as Hoffmann section 3.1 describes them: slippage (slower, heading
  disturbed), hindrance (slower), pushed (displaced and turned by an external velocity), stopped (no
  translation, turning toward the obstacle like a differential drive vehicle whose legs on the contact side
  are held, at a share of v / w), free.
- Camera: the walk scenario's panning camera (`demos.walk_sim`), landmark detections only.

Ground truth for all of it: pose, mobility state and contact side per step, and the list of events.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field as dataclass_field, replace

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

    start: float          # s
    duration: float       # s
    mode: int             # SLIPPAGE, HINDRANCE, PUSHED or STOPPED
    side: int             # NO_CONTACT, LEFT, RIGHT or BOTH
    severity: float = 0.5
    direction: float = 1.0  # +1 or -1: the sense of a slippage's turn

    @property
    def end(self) -> float:
        return self.start + self.duration


@dataclass(frozen=True)
class CollisionScenario:
    field: Field = dataclass_field(default_factory=spl)
    duration: float = 10.0               # s
    rate: float = 100.0                  # Hz, motion, servo and filter rate
    command: tuple[float, float, float] | None = (0.2, 0.0, 0.0)   # constant walk request; None: varied
    events: tuple[CollisionEvent, ...] = ()
    start: tuple[float, float, float] | None = None   # None: random in the own half, facing up the field
    # gait
    cycle: float = 0.6                   # s per gait cycle (each leg swings once)
    foot_separation: float = 0.1         # m, lateral distance between the feet (w of Hoffmann eq. 25)
    # servos
    delay_frames: int = 3                # frames between a command and the servo starting to act on it
    servo_gain: float = 0.6              # share of the remaining error a servo closes per frame
    reading_noise: float = 0.002         # rad (1σ)
    quantization: float = math.radians(0.1)   # rad, encoder resolution
    # free-walking odometry error of a calibrated walking engine
    scale_sigma: float = 0.02            # per-run scale error of vx, vy, ω (1σ)
    turn_bias_sigma: float = 0.005       # rad/s (1σ), per run
    step_noise: float = 0.05             # relative step-to-step velocity noise
    # effects of the mobility states (per event, scaled by its severity)
    hindrance_speed: tuple[float, float] = (0.7, 0.2)   # speed factor at severity 0 and 1
    push_speed: tuple[float, float] = (0.15, 0.4)       # m/s of the push at severity 0 and 1
    push_turn: float = 0.6                               # rad/s at severity 1
    stopped_turn: tuple[float, float] = (0.1, 0.45)     # turn rate as a share of v / w at severity 0 and 1
    slip_speed: tuple[float, float] = (0.9, 0.5)
    slip_turn: float = 0.4                               # rad/s at severity 1
    contact_hold: tuple[float, float] = (0.2, 0.7)      # share of a held servo's motion lost, severity 0..1,
                                                         # on the forward swing (a third of it otherwise)
    ground_bumps: float = 1.0            # per second of walking: a foot landing hard jolts one joint
    bump_size: float = 0.012             # rad (1σ) of such a jolt
    # camera (landmark detections only)
    camera: WalkScenario = dataclass_field(default_factory=lambda: WalkScenario(kidnap_time=None))
    vision: bool = False


@dataclass(frozen=True)
class CollisionLog:
    scenario: CollisionScenario
    dt: float
    times: np.ndarray            # (T,) time at the end of each step
    truth: np.ndarray            # (T, 3) true pose at the end of each step
    start: np.ndarray            # (3,) true pose at t = 0
    commands: np.ndarray         # (T, 3) walk request (vx, vy, ω)
    phase: np.ndarray            # (T,) gait phase in [0, 1)
    servo_commands: np.ndarray   # (T, 8) joint commands: left leg JOINTS, then right leg JOINTS [rad]
    servo_readings: np.ndarray   # (T, 8) servo readings [rad]
    joint_sides: np.ndarray      # (8,) LEFT_LEG or RIGHT_LEG per joint
    mode: np.ndarray             # (T,) true mobility state (FREE ... STOPPED)
    contact: np.ndarray          # (T,) true contact side (NO_CONTACT, LEFT, RIGHT, BOTH)
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
        events = (CollisionEvent(3.0, 0.3, HINDRANCE, LEFT, 0.5), CollisionEvent(3.3, 0.9, STOPPED, LEFT, 0.6),
                  CollisionEvent(4.8, 0.3, HINDRANCE, RIGHT, 0.5), CollisionEvent(5.1, 0.9, STOPPED, RIGHT, 0.6))
    else:
        raise ValueError(f"case = {case!r} must be 'none', 'single' or 'double'")
    return CollisionScenario(events=events, vision=vision, **overrides)


def jitter_events(events: tuple[CollisionEvent, ...], rng: np.random.Generator,
                  time_jitter: float = 0.5) -> tuple[CollisionEvent, ...]:
    """The same story with a per-run shift of all start times (±time_jitter s) and fresh severities."""
    shift = rng.uniform(-time_jitter, time_jitter)
    return tuple(replace(e, start=e.start + shift, severity=float(rng.uniform(0.2, 1.0))) for e in events)


def random_collisions(duration: float, rng: np.random.Generator, mean_gap: float = 8.0,
                      first: float = 3.0) -> tuple[CollisionEvent, ...]:
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
        out[base + 0] = sign * 0.04 * math.sin(leg_phase) + 1.2 * step_y * math.sin(leg_phase) \
            + sign * 0.05 * step_turn
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
    s = scenario
    rng = np.random.default_rng(seed)
    motion_rng, servo_rng, camera_rng = (np.random.default_rng(child) for child in
                                         np.random.SeedSequence(seed).spawn(3))
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
    history = np.tile(current, (s.delay_frames + 1, 1))
    frame_command = np.empty(8)
    for k in range(n):
        t = k * dt     # the step covers [t, t + dt)
        command = np.array(s.command if s.command is not None else _varied_command(t, command_phases))
        commands[k] = command
        phase[k] = (phase0 + t / s.cycle) % 1.0
        _joint_commands(phase[k], command, s.cycle, frame_command)
        joint_commands[k] = frame_command
        history = np.roll(history, -1, axis=0)
        history[-1] = frame_command
        target = history[0]                    # the command `delay_frames` frames ago
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
                        # Hip and knee held back by the obstacle, with jolts as the leg bumps into it.
                        gain[4 * leg + 1] *= 1.0 - hold
                        gain[4 * leg + 2] *= 1.0 - hold
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
                c = {LEFT: 1.0, RIGHT: -1.0}.get(event.side, 0.0)    # Hoffmann eq. 26
                speed = math.hypot(command[0], command[1])
                velocity[:2] = 0.0
                velocity[2] = c * _lerp(s.stopped_turn, share) * speed / s.foot_separation
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
    return CollisionLog(s, dt, times, truth, start, commands, phase, joint_commands, readings, joint_sides,
                        mode, contact, tuple(s.events), tuple(frames))
