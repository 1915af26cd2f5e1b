"""A small humanoid (a NAO-type leg) walking straight or turning, with its sensors, for the velocity EKF.

    from demos.biped import simulate_walk, GaitParams, SensorParams, DisturbanceParams, RobotVariation, turning_gait

    run = simulate_walk(duration=28.0, seed=0)                          # the nominal robot, straight walk
    run = simulate_walk(28.0, seed=0, variation=RobotVariation())      # a robot drawn for this run (links ±5 %)
    run = simulate_walk(28.0, seed=0, variation=RobotVariation().with_chain_error(0.08))   # links ±8 %
    run = simulate_walk(28.0, seed=0, gait=turning_gait(28.0))          # straight, turn left, straight
    run = simulate_walk(28.0, seed=0, disturbances=DisturbanceParams(twist_probability=0.0))
    command = gait_command(run.gait, run.imu_time)                      # the walk request (vx, vy, ω)
    poses = field_poses(run, start=(-3.5, -1.0, 0.0))                   # the trunk's (x, y, θ) on a field

What is simulated. The trunk follows a smooth path (stand still, speed ramp, constant speed, optional turn),
with the sway, bounce, surge, lean and rocking of a walk; the feet are placed under the hips at the moments the
trunk passes over them, and swing between placements with a lift. Every kinematics sample, each leg's six joint
angles come from the numerical inverse kinematics of this run's own legs (`run.true_chains`). Sensors: an IMU
at the torso origin (accelerometer measuring specific force, gravity included, and gyroscope, each with white
noise, a per-run bias, a per-axis scale error and, for the gyro, a bias drift) at `imu_rate`; joint encoders
with play (backlash) quantized to `encoder_resolution` (300°/1024, a Dynamixel-class servo) at
`kinematics_rate`; four contact switches per foot at the sole corners, each reading wrong with probability
`contact_error`. Disturbances, drawn per support phase: foot twist (the support foot yawing about a random point
of its sole, permanently, or tilting about one edge of the sole and settling back) and limited slip (the support
foot sliding a few millimetres to centimetres).

The robot of each run. `draw_robot` draws its physical parameters from a `RobotVariation`: each leg's five
lengths within ±5 % of the published NAO dimensions (`proprioception.kinematics.NaoLegDimensions`), each joint's zero
within ±1°, each joint's play up to 0.6°, the IMU's noise σ 0.6-1.8 times the datasheet's (`SensorParams`), its
bias 0.5-2.5 (accelerometer) and 0.5-3 (gyro) times the datasheet's spread, a scale error within ±3 % per axis,
and a gyro bias random walk up to 3e-4 rad/s/√s. `RobotVariation.nominal()` (the default of `simulate_walk`) is
the robot of the drawings with the datasheet's sensors: its legs are the estimator's, which is what the nominal
column of the robustness table measures. Nothing here comes from the estimators' settings: this module does not
import `proprioception.velocity`, and the datasheet values and ranges are the simulator's own.

The simulation is kinematic: the trunk's motion is the truth and the legs follow it, so a twist or a slip moves
the foot, not the trunk. The NAO's coupling of the two hip yaw-pitch joints is not imposed. The random
disturbances, the sensor noise, the robot's draw and the gyro drift come from separate streams spawned from
the seed, so switching twist off leaves the noise identical, and two variations of one seed move the same robot
in the same directions. Same seed, same run, bit for bit.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from field.angles import wrap_angles
from proprioception.kinematics import LegChain, NaoLegDimensions, nao_leg, rotation_z

FINE_RATE = 3000.0  # Hz: truth grid; IMU and kinematics rates must divide it
GRAVITY = 9.81

# Sole outline of the NAO-like foot (sole frame: origin under the ankle, x forward), metres.
SOLE_X = (-0.05, 0.10)
SOLE_Y = (-0.04, 0.04)
CONTACT_SENSORS = np.array([[0.07, 0.03], [0.07, -0.03], [-0.03, 0.03], [-0.03, -0.03]])
LIFT_THRESHOLD = 1e-3  # a contact switch opens once its corner is this far above the floor


@dataclass(frozen=True)
class GaitParams:
    """Walk shape. Angles in radians, times in seconds, lengths in metres."""

    speed: float = 0.10
    step_period: float = 0.5
    double_support: float = 0.1
    step_height: float = 0.02
    foot_spacing: float = 0.05
    torso_height: float = 0.30
    bounce: float = 0.004
    lateral_sway: float = 0.015
    surge: float = 0.005
    lean: float = math.radians(3.0)
    roll_amplitude: float = math.radians(1.5)
    pitch_amplitude: float = math.radians(0.7)
    stand_time: float = 1.0
    ramp_time: float = 1.0
    turn_rate: float = 0.0
    turn_start: float = 0.0
    turn_end: float = 0.0
    turn_ramp: float = 1.0

    def __post_init__(self):
        for name in ("step_period", "double_support", "torso_height", "ramp_time", "turn_ramp"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)!r}")
        if not self.double_support < self.step_period:
            raise ValueError(f"double_support must be shorter than step_period, got {self.double_support!r}")
        if self.stand_time < 0.5:
            raise ValueError(
                f"stand_time must be at least 0.5 s (the estimators start from a standing robot), "
                f"got {self.stand_time!r}"
            )


def turning_gait(duration: float, turn_rate: float = 0.25, **kwargs) -> GaitParams:
    """Walk straight, turn left at `turn_rate` rad/s through the middle 40 % of the run, walk straight."""
    return GaitParams(turn_rate=turn_rate, turn_start=0.3 * duration, turn_end=0.7 * duration, **kwargs)


@dataclass(frozen=True)
class SensorParams:
    """Sensor rates (Hz) and the sensors' datasheet errors (standard deviations per sample; biases are constant
    per run, drawn N(0, bias²) per axis). A `RobotVariation` draws each run's errors around these."""

    imu_rate: float = 100.0
    kinematics_rate: float = 30.0
    accel_noise: float = 0.04
    accel_bias: float = 0.06
    gyro_noise: float = 0.007
    gyro_bias: float = 0.008
    encoder_resolution: float = math.radians(300.0 / 1024.0)
    contact_error: float = 0.02

    def __post_init__(self):
        for name in ("imu_rate", "kinematics_rate"):
            ratio = FINE_RATE / getattr(self, name)
            if not (ratio >= 1.0 and abs(ratio - round(ratio)) < 1e-9):
                raise ValueError(f"{name} must divide {FINE_RATE:g} Hz, got {getattr(self, name)!r}")
        for name in ("accel_noise", "accel_bias", "gyro_noise", "gyro_bias", "encoder_resolution", "contact_error"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} must be non-negative, got {getattr(self, name)!r}")


@dataclass(frozen=True)
class DisturbanceParams:
    """Per support phase: probability of a foot twist and of a slip, and their ranges (degrees, m, s)."""

    twist_probability: float = 0.25
    yaw_twist_deg: tuple[float, float] = (3.0, 10.0)
    tilt_twist_deg: tuple[float, float] = (2.0, 5.0)
    twist_duration: tuple[float, float] = (0.15, 0.3)
    slip_probability: float = 0.15
    slip_distance: tuple[float, float] = (0.005, 0.02)
    slip_duration: tuple[float, float] = (0.1, 0.2)

    def __post_init__(self):
        for name in ("twist_probability", "slip_probability"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)!r}")


@dataclass(frozen=True)
class RobotVariation:
    """How far one simulated robot is from its drawings and its sensors from their datasheet: the ranges from
    which `draw_robot` draws the physical parameters of each run (uniformly unless said otherwise).

    link_length_error: each of the leg's five lengths (`NaoLegDimensions`), each leg on its own, is the published
    one times 1 + U(-e, e). joint_zero_error (rad): each joint's zero is off by U(-z, z). backlash (rad): each
    joint's play, a width drawn in the range; the reading stays put until the joint has taken up the play.
    accel_noise_factor, gyro_noise_factor: the run's white-noise σ is the datasheet's times a factor drawn in the
    range. accel_bias_factor, gyro_bias_factor: the run's constant bias is N(0, 1) per axis times the datasheet
    bias times a factor drawn in the range. accel_scale_error, gyro_scale_error: per axis, the sensor reads
    (1 + U(-s, s)) times the true value. gyro_bias_drift (rad/s/√s): the gyro bias also walks randomly within
    the run, with a σ drawn in the range.

    `RobotVariation.nominal()` is the robot of the drawings and the datasheet (no draw moves anything); the
    default is the standard variation of the figures; `with_chain_error(e)` the same with links ±e and joint
    zeros ±`JOINT_ZERO_PER_LINK_ERROR`·e.
    """

    link_length_error: float = 0.05
    joint_zero_error: float = math.radians(1.0)
    backlash: tuple[float, float] = (0.0, math.radians(0.6))
    accel_noise_factor: tuple[float, float] = (0.6, 1.8)
    gyro_noise_factor: tuple[float, float] = (0.6, 1.8)
    accel_bias_factor: tuple[float, float] = (0.5, 2.5)
    gyro_bias_factor: tuple[float, float] = (0.5, 3.0)
    accel_scale_error: float = 0.03
    gyro_scale_error: float = 0.03
    gyro_bias_drift: tuple[float, float] = (0.0, 3e-4)

    def __post_init__(self):
        for name in ("link_length_error", "joint_zero_error", "accel_scale_error", "gyro_scale_error"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and 0.0 <= value < 0.5):
                raise ValueError(f"{name} must be in [0, 0.5), got {value!r}")
        for name in (
            "backlash",
            "accel_noise_factor",
            "gyro_noise_factor",
            "accel_bias_factor",
            "gyro_bias_factor",
            "gyro_bias_drift",
        ):
            value = getattr(self, name)
            if not (
                isinstance(value, tuple)
                and len(value) == 2
                and all(math.isfinite(v) for v in value)
                and 0.0 <= value[0] <= value[1]
            ):
                raise ValueError(f"{name} must be a range (low, high) with 0 <= low <= high, got {value!r}")

    @classmethod
    def nominal(cls) -> RobotVariation:
        """The robot of the drawings with the datasheet's sensors: every range a single point."""
        return cls(
            link_length_error=0.0,
            joint_zero_error=0.0,
            backlash=(0.0, 0.0),
            accel_noise_factor=(1.0, 1.0),
            gyro_noise_factor=(1.0, 1.0),
            accel_bias_factor=(1.0, 1.0),
            gyro_bias_factor=(1.0, 1.0),
            accel_scale_error=0.0,
            gyro_scale_error=0.0,
            gyro_bias_drift=(0.0, 0.0),
        )

    def with_chain_error(self, error: float) -> RobotVariation:
        """These ranges with the links ±`error` and the joint zeros ±`JOINT_ZERO_PER_LINK_ERROR`·`error`."""
        return dataclasses.replace(
            self, link_length_error=float(error), joint_zero_error=JOINT_ZERO_PER_LINK_ERROR * float(error)
        )


JOINT_ZERO_PER_LINK_ERROR = math.radians(20.0)  # rad per unit of link error: ±1° of joint zero at links ±5 %


@dataclass(frozen=True)
class RobotDraw:
    """The physical parameters of one simulated run, drawn by `draw_robot`.

    dimensions and joint_offsets per leg (0 = left); backlash (2, 6) rad; accel_noise, gyro_noise (σ per sample);
    accel_bias_scale, gyro_bias_scale (the factors on the datasheet bias); accel_scale, gyro_scale (3,) (1 + error
    per axis); gyro_bias_drift (rad/s/√s).
    """

    dimensions: tuple[NaoLegDimensions, NaoLegDimensions]
    joint_offsets: np.ndarray
    backlash: np.ndarray
    accel_noise: float
    gyro_noise: float
    accel_bias_scale: float
    gyro_bias_scale: float
    accel_scale: np.ndarray
    gyro_scale: np.ndarray
    gyro_bias_drift: float

    def as_dict(self) -> dict:
        """The draw as plain numbers (for results files)."""
        return {
            "dimensions_m": [list(d.as_tuple()) for d in self.dimensions],
            "joint_offsets_rad": self.joint_offsets.tolist(),
            "backlash_rad": self.backlash.tolist(),
            "accel_noise": self.accel_noise,
            "gyro_noise": self.gyro_noise,
            "accel_bias_scale": self.accel_bias_scale,
            "gyro_bias_scale": self.gyro_bias_scale,
            "accel_scale": self.accel_scale.tolist(),
            "gyro_scale": self.gyro_scale.tolist(),
            "gyro_bias_drift": self.gyro_bias_drift,
        }


def _in_range(low_high: tuple[float, float], u: float) -> float:
    low, high = low_high
    return low + u * (high - low)


def draw_robot(
    seed: int, sensors: SensorParams = SensorParams(), variation: RobotVariation = RobotVariation()
) -> RobotDraw:
    """The physical parameters of run `seed`, drawn from `variation` around the drawings and `sensors`.

    The draw uses its own stream of the seed and a fixed number of variates, all uniform in [0, 1) and mapped to
    the ranges afterwards, so two variations of the same seed move the same robot in the same directions, by
    amounts proportional to their ranges (the columns of a robustness table compare like with like), and the
    walk and its sensor noise do not depend on the variation.
    """
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(3)[2])
    u_links = rng.random((2, 5))
    u_zeros = rng.random((2, 6))
    u_play = rng.random((2, 6))
    u_imu = rng.random(7)
    u_accel_scale = rng.random(3)
    u_gyro_scale = rng.random(3)
    published = NaoLegDimensions()
    e = variation.link_length_error
    dims = tuple(published.scaled(1.0 + e * (2.0 * u_links[leg] - 1.0)) for leg in range(2))
    return RobotDraw(
        dimensions=(dims[0], dims[1]),
        joint_offsets=variation.joint_zero_error * (2.0 * u_zeros - 1.0),
        backlash=variation.backlash[0] + u_play * (variation.backlash[1] - variation.backlash[0]),
        accel_noise=sensors.accel_noise * _in_range(variation.accel_noise_factor, u_imu[0]),
        gyro_noise=sensors.gyro_noise * _in_range(variation.gyro_noise_factor, u_imu[1]),
        accel_bias_scale=_in_range(variation.accel_bias_factor, u_imu[2]),
        gyro_bias_scale=_in_range(variation.gyro_bias_factor, u_imu[3]),
        accel_scale=1.0 + variation.accel_scale_error * (2.0 * u_accel_scale - 1.0),
        gyro_scale=1.0 + variation.gyro_scale_error * (2.0 * u_gyro_scale - 1.0),
        gyro_bias_drift=_in_range(variation.gyro_bias_drift, u_imu[4]),
    )


def _backlash(angles: np.ndarray, play: np.ndarray) -> np.ndarray:
    """The reading of joints with play (full width `play`, per joint) following `angles` (M, 2, 6): it moves
    only once the joint has taken up half the play on either side (a play operator), starting centred."""
    out = np.empty_like(angles)
    reading = angles[0].copy()
    half = play / 2.0
    for k in range(angles.shape[0]):
        reading = np.clip(reading, angles[k] - half, angles[k] + half)
        out[k] = reading
    return out


@dataclass(frozen=True, eq=False)
class BipedRun:
    """Sensor streams and truth of one simulated walk. Legs are indexed 0 = left, 1 = right.

    IMU rate: imu_time (N,), gyro, accel (N, 3) as measured; true_velocity, true_gravity, true_omega (N, 3) in
    the IMU frame (gravity as the accelerometer sees it at rest, pointing up); trunk_position (N, 3) and
    trunk_yaw (N,) in the world. Kinematics rate: kin_time (M,), joint_angles (M, 2, 6) as the encoders read
    them and true_joint_angles, contacts (M, 2, 4) switch readings, true_contact (M, 2), twist and slip (M, 2)
    (episode under way on that foot), true_kin_velocity (M, 3).
    """

    imu_time: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    true_velocity: np.ndarray
    true_gravity: np.ndarray
    true_omega: np.ndarray
    trunk_position: np.ndarray
    trunk_yaw: np.ndarray
    kin_time: np.ndarray
    joint_angles: np.ndarray
    true_joint_angles: np.ndarray
    contacts: np.ndarray
    true_contact: np.ndarray
    twist: np.ndarray
    slip: np.ndarray
    true_kin_velocity: np.ndarray
    true_chains: tuple[LegChain, LegChain]
    gait: GaitParams
    sensors: SensorParams
    disturbances: DisturbanceParams
    robot: RobotDraw
    episodes: list = field(default_factory=list)


# ---------------------------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------------------------
def _smoother(x):
    """C² ramp from 0 (x ≤ 0) to 1 (x ≥ 1)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def _cumtrapz(y, dt):
    out = np.zeros_like(y)
    out[1:] = np.cumsum((y[1:] + y[:-1]) * (dt / 2.0), axis=0)
    return out


def _euler_zyx(yaw, pitch, roll):
    """Rotation matrices Rz(yaw)·Ry(pitch)·Rx(roll), vectorized (N, 3, 3)."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    r = np.empty(yaw.shape + (3, 3))
    r[..., 0, 0] = cy * cp
    r[..., 0, 1] = cy * sp * sr - sy * cr
    r[..., 0, 2] = cy * sp * cr + sy * sr
    r[..., 1, 0] = sy * cp
    r[..., 1, 1] = sy * sp * sr + cy * cr
    r[..., 1, 2] = sy * sp * cr - cy * sr
    r[..., 2, 0] = -sp
    r[..., 2, 1] = cp * sr
    r[..., 2, 2] = cp * cr
    return r


def _rotation_about(axis, angle):
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * (kx @ kx)


def _pose(rotation, position):
    t = np.eye(4)
    t[:3, :3] = rotation
    t[:3, 3] = position
    return t


@dataclass
class _Support:
    """One support phase of one foot: planned placement and its disturbances."""

    land: float
    lift: float
    x: float
    y: float
    yaw: float
    yaw_twist: tuple | None = None  # (start, duration, pivot_local (2,), angle)
    tilt_twist: tuple | None = None  # (start, duration, point_local (3,), axis_local (3,), angle)
    slip: tuple | None = None  # (start, duration, displacement (2,))

    def base(self):
        return _pose(rotation_z(self.yaw), (self.x, self.y, 0.0))

    def pose(self, t):
        """Sole pose in the world at time t within (or after) this support phase."""
        pose = self.base()
        if self.yaw_twist is not None:
            start, duration, pivot_local, angle = self.yaw_twist
            a = angle * float(_smoother((t - start) / duration))
            pivot = pose[:3, :3] @ np.array([pivot_local[0], pivot_local[1], 0.0]) + pose[:3, 3]
            turn = _pose(rotation_z(a), pivot - rotation_z(a) @ pivot)
            pose = turn @ pose
        if self.slip is not None:
            start, duration, displacement = self.slip
            s = float(_smoother((t - start) / duration))
            pose[:2, 3] += s * np.asarray(displacement)
        if self.tilt_twist is not None:
            start, duration, point, axis, angle = self.tilt_twist
            tau = (t - start) / duration
            if 0.0 < tau < 1.0:
                a = angle * math.sin(math.pi * tau) ** 2
                rot = _rotation_about(axis, a)
                pose = pose @ _pose(rot, point - rot @ point)
        return pose

    def twist_active(self, t):
        out = False
        if self.yaw_twist is not None:
            out |= self.yaw_twist[0] <= t <= self.yaw_twist[0] + self.yaw_twist[1]
        if self.tilt_twist is not None:
            out |= self.tilt_twist[0] <= t <= self.tilt_twist[0] + self.tilt_twist[1]
        return out

    def slip_active(self, t):
        return self.slip is not None and self.slip[0] <= t <= self.slip[0] + self.slip[1]


def _draw_disturbances(support: _Support, rng: np.random.Generator, params: DisturbanceParams) -> None:
    """Draw every variate (a fixed number per support, so the stream does not depend on the settings)."""
    u = rng.random(12)
    window_start, window_end = support.land + 0.05, support.lift - 0.05
    # Twist
    duration = params.twist_duration[0] + u[1] * (params.twist_duration[1] - params.twist_duration[0])
    duration = min(duration, window_end - window_start)
    start = window_start + u[2] * (window_end - window_start - duration)
    if u[0] < params.twist_probability and duration > 0.0:
        if u[3] < 0.5:
            pivot = np.array([SOLE_X[0] + u[4] * (SOLE_X[1] - SOLE_X[0]), SOLE_Y[0] + u[5] * (SOLE_Y[1] - SOLE_Y[0])])
            lo, hi = params.yaw_twist_deg
            angle = math.radians(lo + u[6] * (hi - lo)) * (1.0 if u[7] < 0.5 else -1.0)
            support.yaw_twist = (start, duration, pivot, angle)
        else:
            edge = int(u[4] * 4.0) % 4
            if edge == 0:
                point, axis = np.array([SOLE_X[0], 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
            elif edge == 1:
                point, axis = np.array([SOLE_X[1], 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
            elif edge == 2:
                point, axis = np.array([0.0, SOLE_Y[0], 0.0]), np.array([1.0, 0.0, 0.0])
            else:
                point, axis = np.array([0.0, SOLE_Y[1], 0.0]), np.array([1.0, 0.0, 0.0])
            lo, hi = params.tilt_twist_deg
            angle = math.radians(lo + u[6] * (hi - lo))
            # Turn the way that lifts the sole off the floor (the rest of the sole goes up, not down).
            centre = np.array([sum(SOLE_X) / 2.0, sum(SOLE_Y) / 2.0, 0.0])
            rot = _rotation_about(axis, angle)
            if (rot @ (centre - point))[2] < 0.0:
                angle = -angle
            support.tilt_twist = (start, duration, point, axis, angle)
    # Slip
    duration = params.slip_duration[0] + u[9] * (params.slip_duration[1] - params.slip_duration[0])
    duration = min(duration, window_end - window_start)
    start = window_start + u[10] * (window_end - window_start - duration)
    if u[8] < params.slip_probability and duration > 0.0:
        lo, hi = params.slip_distance
        distance = lo + u[11] * (hi - lo)
        heading = 2.0 * math.pi * u[7]
        support.slip = (start, duration, distance * np.array([math.cos(heading), math.sin(heading)]))


def _foot_pose(supports: list[_Support], t: float, step_height: float):
    """Sole pose of one foot at time t, and whether it is in a support phase (index or -1)."""
    for k, s in enumerate(supports):
        if s.land <= t <= s.lift:
            return s.pose(t), k
        if k + 1 < len(supports) and s.lift < t < supports[k + 1].land:
            nxt = supports[k + 1]
            tau = (t - s.lift) / (nxt.land - s.lift)
            start = s.pose(s.lift)
            yaw0 = math.atan2(start[1, 0], start[0, 0])
            p0 = start[:3, 3]
            p1 = np.array([nxt.x, nxt.y, 0.0])
            ramp = float(_smoother(tau))
            dyaw = (nxt.yaw - yaw0 + math.pi) % (2.0 * math.pi) - math.pi
            position = p0 + ramp * (p1 - p0)
            position[2] = step_height * (1.0 - math.cos(2.0 * math.pi * tau)) / 2.0
            return _pose(rotation_z(yaw0 + ramp * dyaw), position), -1
    raise ValueError(f"time {t!r} is outside the footstep plan")


# ---------------------------------------------------------------------------------------------------------
# The simulation
# ---------------------------------------------------------------------------------------------------------
def simulate_walk(
    duration: float = 28.0,
    seed: int = 0,
    gait: GaitParams = GaitParams(),
    sensors: SensorParams = SensorParams(),
    disturbances: DisturbanceParams = DisturbanceParams(),
    variation: RobotVariation | None = None,
) -> BipedRun:
    """Simulate `duration` seconds of walking (standing first for `gait.stand_time`).

    `variation` draws the robot of this run (`draw_robot`); None is `RobotVariation.nominal()`, the robot of the
    drawings with the datasheet's sensors.
    """
    duration = float(duration)
    if not (math.isfinite(duration) and duration > gait.stand_time):
        raise ValueError(f"duration must be longer than gait.stand_time = {gait.stand_time}, got {duration!r}")
    if variation is not None and not isinstance(variation, RobotVariation):
        raise ValueError(f"variation must be a RobotVariation or None, got {type(variation).__name__}")
    robot = draw_robot(seed, sensors, RobotVariation.nominal() if variation is None else variation)
    seeds = np.random.SeedSequence(seed).spawn(2)
    rng_world = np.random.default_rng(seeds[0])
    rng_sensor = np.random.default_rng(seeds[1])
    T, ds = gait.step_period, gait.double_support
    t_walk = gait.stand_time
    horizon = duration + 3.0 * T
    n_fine = int(round(horizon * FINE_RATE)) + 1
    dt = 1.0 / FINE_RATE
    t = np.arange(n_fine) * dt

    # Trunk path.
    envelope = _smoother((t - t_walk) / gait.ramp_time)
    speed = gait.speed * envelope
    yaw_rate = gait.turn_rate * (
        _smoother((t - gait.turn_start) / gait.turn_ramp) - _smoother((t - gait.turn_end) / gait.turn_ramp)
    )
    yaw = _cumtrapz(yaw_rate, dt)
    path = np.stack([_cumtrapz(speed * np.cos(yaw), dt), _cumtrapz(speed * np.sin(yaw), dt)], axis=1)

    # Footstep plan: step j ≥ 1 lands at land_j, the right foot on odd j, the left on even j.
    supports: list[list[_Support]] = [[], []]
    supports[0].append(_Support(-1.0, t_walk + T, -0.0, gait.foot_spacing, 0.0))
    supports[1].append(_Support(-1.0, t_walk, 0.0, -gait.foot_spacing, 0.0))
    j = 1
    while True:
        land = t_walk + (T - ds) + (j - 1) * T
        if land > duration + T:
            break
        mid = land + (T + ds) / 2.0
        foot = 1 if j % 2 == 1 else 0
        side = 1.0 if foot == 0 else -1.0
        heading = float(np.interp(mid, t, yaw))
        centre = np.array([np.interp(mid, t, path[:, 0]), np.interp(mid, t, path[:, 1])])
        xy = centre + side * gait.foot_spacing * np.array([-math.sin(heading), math.cos(heading)])
        support = _Support(land, land + T + ds, float(xy[0]), float(xy[1]), heading)
        _draw_disturbances(support, rng_world, disturbances)
        supports[foot].append(support)
        j += 1
    phase_ref = t_walk + (T - ds) + T + (T + ds) / 2.0  # mid-support of the first left step
    phase = (t - phase_ref) / T

    # Trunk pose: path plus the walk's oscillations, in the path frame.
    surge = gait.surge * envelope * np.sin(2.0 * math.pi * phase)
    sway = gait.lateral_sway * envelope * np.cos(math.pi * phase)
    height = gait.torso_height + gait.bounce * envelope * np.cos(2.0 * math.pi * phase)
    cy, sy = np.cos(yaw), np.sin(yaw)
    position = np.stack([path[:, 0] + cy * surge - sy * sway, path[:, 1] + sy * surge + cy * sway, height], axis=1)
    roll = gait.roll_amplitude * envelope * np.cos(math.pi * phase)
    pitch = gait.lean + gait.pitch_amplitude * envelope * np.sin(2.0 * math.pi * phase)
    rotation = _euler_zyx(yaw, pitch, roll)
    velocity = np.gradient(position, dt, axis=0, edge_order=2)
    acceleration = np.gradient(velocity, dt, axis=0, edge_order=2)
    roll_rate = np.gradient(roll, dt, edge_order=2)
    pitch_rate = np.gradient(pitch, dt, edge_order=2)
    yaw_rate_total = np.gradient(yaw, dt, edge_order=2)
    omega = np.stack(
        [
            roll_rate - yaw_rate_total * np.sin(pitch),
            pitch_rate * np.cos(roll) + yaw_rate_total * np.cos(pitch) * np.sin(roll),
            -pitch_rate * np.sin(roll) + yaw_rate_total * np.cos(pitch) * np.cos(roll),
        ],
        axis=1,
    )
    up = np.array([0.0, 0.0, GRAVITY])
    body_velocity = np.einsum("nji,nj->ni", rotation, velocity)
    body_gravity = np.einsum("nji,j->ni", rotation, up)
    body_specific_force = np.einsum("nji,nj->ni", rotation, acceleration + up)

    # IMU samples.
    imu_stride = int(round(FINE_RATE / sensors.imu_rate))
    n_imu = int(math.floor(duration * sensors.imu_rate + 1e-9)) + 1
    imu_index = np.arange(n_imu) * imu_stride
    accel_bias = rng_sensor.normal(0.0, 1.0, 3) * sensors.accel_bias * robot.accel_bias_scale
    gyro_bias = rng_sensor.normal(0.0, 1.0, 3) * sensors.gyro_bias * robot.gyro_bias_scale
    accel = (
        robot.accel_scale * body_specific_force[imu_index]
        + accel_bias
        + rng_sensor.normal(0.0, 1.0, (n_imu, 3)) * robot.accel_noise
    )
    gyro = robot.gyro_scale * omega[imu_index] + gyro_bias + rng_sensor.normal(0.0, 1.0, (n_imu, 3)) * robot.gyro_noise
    if robot.gyro_bias_drift > 0.0:
        # From a stream of its own, so the walk and the other sensor noise are the same with and without it.
        rng_drift = np.random.default_rng(np.random.SeedSequence(seed).spawn(4)[3])
        steps = rng_drift.normal(0.0, robot.gyro_bias_drift / math.sqrt(sensors.imu_rate), (n_imu, 3))
        steps[0] = 0.0
        gyro = gyro + np.cumsum(steps, axis=0)

    # Kinematics samples: inverse kinematics of both legs of this run's robot, encoders, contact switches.
    chains = tuple(
        nao_leg(side, dimensions=robot.dimensions[leg], joint_offsets=robot.joint_offsets[leg])
        for leg, side in enumerate(("left", "right"))
    )
    kin_stride = int(round(FINE_RATE / sensors.kinematics_rate))
    n_kin = int(math.floor(duration * sensors.kinematics_rate + 1e-9)) + 1
    kin_index = np.arange(n_kin) * kin_stride
    true_angles = np.empty((n_kin, 2, 6))
    true_contact = np.zeros((n_kin, 2), dtype=bool)
    switch_state = np.zeros((n_kin, 2, 4), dtype=bool)
    twist = np.zeros((n_kin, 2), dtype=bool)
    slip = np.zeros((n_kin, 2), dtype=bool)
    guess = [np.array([0.0, -0.45, 0.9, -0.45, 0.0, 0.0]) for _ in range(2)]
    sensor_points = np.column_stack([CONTACT_SENSORS, np.zeros(4), np.ones(4)])
    for k, i in enumerate(kin_index):
        trunk = _pose(rotation[i], position[i])
        for foot in range(2):
            sole, phase_index = _foot_pose(supports[foot], t[i], gait.step_height)
            target = np.linalg.solve(sole, trunk)
            angles = chains[foot].inverse(target, guess[foot])
            true_angles[k, foot] = angles
            guess[foot] = angles
            if phase_index >= 0:
                support = supports[foot][phase_index]
                true_contact[k, foot] = True
                heights = (sole @ sensor_points.T)[2]
                switch_state[k, foot] = heights < LIFT_THRESHOLD
                twist[k, foot] = support.twist_active(t[i])
                slip[k, foot] = support.slip_active(t[i])
    flips = rng_sensor.random((n_kin, 2, 4)) < sensors.contact_error
    contacts = switch_state ^ flips
    res = sensors.encoder_resolution
    read = _backlash(true_angles, robot.backlash) if np.any(robot.backlash > 0.0) else true_angles
    joint_angles = np.round(read / res) * res if res > 0.0 else read.copy()

    episodes = []
    for foot in range(2):
        for s in supports[foot]:
            if s.land > duration:
                continue
            if s.yaw_twist is not None:
                episodes.append(("yaw twist", foot, s.yaw_twist[0], s.yaw_twist[1], math.degrees(s.yaw_twist[3])))
            if s.tilt_twist is not None:
                episodes.append(("tilt twist", foot, s.tilt_twist[0], s.tilt_twist[1], math.degrees(s.tilt_twist[4])))
            if s.slip is not None:
                episodes.append(("slip", foot, s.slip[0], s.slip[1], float(np.linalg.norm(s.slip[2]))))
    episodes.sort(key=lambda e: e[2])

    return BipedRun(
        imu_time=t[imu_index],
        gyro=gyro,
        accel=accel,
        true_velocity=body_velocity[imu_index],
        true_gravity=body_gravity[imu_index],
        true_omega=omega[imu_index],
        trunk_position=position[imu_index],
        trunk_yaw=yaw[imu_index],
        kin_time=t[kin_index],
        joint_angles=joint_angles,
        true_joint_angles=true_angles,
        contacts=contacts,
        true_contact=true_contact,
        twist=twist,
        slip=slip,
        true_kin_velocity=body_velocity[kin_index],
        true_chains=(chains[0], chains[1]),
        gait=gait,
        sensors=sensors,
        disturbances=disturbances,
        robot=robot,
        episodes=episodes,
    )


# ---------------------------------------------------------------------------------------------------------
# The walk request and the walk on a field (additions for the odometry experiment; the simulation above is
# unchanged)
# ---------------------------------------------------------------------------------------------------------
def gait_command(gait: GaitParams, times) -> np.ndarray:
    """The walk request (vx, vy, ω) in the robot frame at `times` (s): what the trunk path of `simulate_walk`
    follows, without the walk's oscillations (sway, surge, bounce).

    The speed ramps up from `stand_time` over `ramp_time`, and the turn rate in and out around `turn_start`
    and `turn_end` over `turn_ramp`, by the same formulas as the simulation, so a walking engine given this
    request and executing it perfectly walks the simulated path; vy is always 0.
    """
    times = np.asarray(times, dtype=np.float64)
    if not np.all(np.isfinite(times)):
        raise ValueError("times must be finite")
    speed = gait.speed * _smoother((times - gait.stand_time) / gait.ramp_time)
    omega = gait.turn_rate * (
        _smoother((times - gait.turn_start) / gait.turn_ramp) - _smoother((times - gait.turn_end) / gait.turn_ramp)
    )
    return np.stack(np.broadcast_arrays(speed, np.zeros_like(speed), omega), axis=-1)


def field_poses(run: BipedRun, start) -> np.ndarray:
    """The trunk's planar pose (x, y, θ) at every IMU sample, on a field where the walk starts at `start`.

    The simulation's world has the trunk at the origin facing +x at t = 0; `start` (x, y, θ) in the field
    frame moves it there. θ is the trunk's yaw (the heading of its forward axis on the floor), wrapped to
    (-π, π].
    """
    start = np.asarray(start, dtype=np.float64)
    if start.shape != (3,) or not np.all(np.isfinite(start)):
        raise ValueError(f"start must be three finite numbers (x, y, θ), got {start.tolist()}")
    c, s = math.cos(start[2]), math.sin(start[2])
    x, y = run.trunk_position[:, 0], run.trunk_position[:, 1]
    return np.stack([start[0] + c * x - s * y, start[1] + s * x + c * y, wrap_angles(start[2] + run.trunk_yaw)], axis=1)
