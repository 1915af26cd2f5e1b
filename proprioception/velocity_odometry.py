"""Odometry for the motion models from the velocity EKF: IMU-rate planar increments, summed per filter step.

    from proprioception.velocity_odometry import EKFOdometry, PlanarOdometry, compose_increments
    from motion_models import MotionInput

    odometry = EKFOdometry(LegOdometry(chains, ekf))       # wraps the EKF pipeline of proprioception.velocity
    odometry.imu(t, gyro, accel)                             # every IMU sample (raw gyro, as LegOdometry takes)
    odometry.kinematics(t, joint_angles, contacts)           # every kinematics sample
    step = odometry.take()                                   # at the filter's rate: what happened since the last take
    pf.predict(MotionInput(dt=step.dt, odometry=step.odometry))

What it computes. Each IMU sample ends an interval δ = tᵢ - tᵢ₋₁. Over that interval the robot moves by
`proprioception.velocity.planar_increment(g, v, ω̂ᵢ - b, δ)`: the EKF velocity v and gravity g as they stand at the
start of the interval (the state before the prediction with sample i, any correction in between included),
v levelled with g into the horizontal plane, and the yaw rate the bias-corrected gyro along g, held over δ as a
circular arc. That is the pose change in the robot frame at tᵢ₋₁, the frame `MotionInput.odometry` asks for:
x is the IMU's forward axis projected on the floor, y left, θ counter-clockwise about the vertical. The
heading therefore comes from the gyro (less the EKF's bias), not from the velocity.

`PlanarOdometry` composes these increments in SE(2), (x, y, θ) ∘ (dx, dy, dθ), so that a filter step at any
rate gets the exact sum of what the IMU saw since the previous step; `take()` returns it and starts a new
sum. `compose_increments` does the same for an array of increments (dead reckoning). The pose change's
heading is wrapped to (-π, π] on output only; inside a sum it is kept whole.

The robot's position is the IMU's (the trunk's): the walk's sway and surge are in the increments, as they
are in the IMU's truth. Nothing here is random; the same samples give the same increments, bit for bit.

Errors: a `ValueError` naming the field and value (non-finite samples, a time that does not advance, an IMU
gap longer than the EKF's `max_imu_gap`), raised before anything changes: a rejected sample leaves the EKF
and the running sum as they were.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from proprioception.velocity import KinematicSample, LegOdometry, _vector3, planar_increment


class OdometryIncrement(NamedTuple):
    """The pose change since the previous `take()`: dt seconds, (dx, dy, dtheta) in the robot frame at the start.

    dtheta is wrapped to (-π, π]; `samples` counts the IMU intervals summed. `odometry` is the triple that
    `motion_models.MotionInput(dt=..., odometry=...)` takes.
    """

    dt: float
    dx: float
    dy: float
    dtheta: float
    samples: int

    @property
    def odometry(self) -> tuple[float, float, float]:
        return (self.dx, self.dy, self.dtheta)


def _wrap(angle: float) -> float:
    """(-π, π], the project's convention (math.remainder gives [-π, π]; -π is moved to π)."""
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def _seconds(value, name: str) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} must be a number of seconds") from None


def _duration(value, name: str = "dt") -> float:
    dt = _seconds(value, name)
    if not (math.isfinite(dt) and dt >= 0.0):
        raise ValueError(f"{name} = {value!r} must be finite and >= 0")
    return dt


def compose_increments(increments, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Chain robot-frame pose changes (N, 3) from the pose `start`; returns every pose after each (N, 3).

    Pose k+1 = pose k ∘ increment k: (x + cos θ·dx - sin θ·dy, y + sin θ·dx + cos θ·dy, θ + dθ). Headings
    in the output are wrapped to (-π, π]; the chain itself uses the unwrapped sum. With `start` a field pose,
    the rows are the dead-reckoned field poses.
    """
    inc = np.asarray(increments, dtype=np.float64)
    if inc.ndim != 2 or inc.shape[1] != 3:
        raise ValueError(f"increments must have shape (N, 3), got {inc.shape}")
    if not np.all(np.isfinite(inc)):
        raise ValueError("increments must be finite")
    x, y, theta = (float(v) for v in _vector3(start, "start"))
    out = np.empty_like(inc)
    for k in range(inc.shape[0]):
        c, s = math.cos(theta), math.sin(theta)
        x += c * inc[k, 0] - s * inc[k, 1]
        y += s * inc[k, 0] + c * inc[k, 1]
        theta += inc[k, 2]
        out[k] = (x, y, _wrap(theta))
    return out


class PlanarOdometry:
    """A running SE(2) sum of robot-frame pose increments, taken (and restarted) at the filter's rate."""

    def __init__(self) -> None:
        self._dx = 0.0
        self._dy = 0.0
        self._dtheta = 0.0
        self._dt = 0.0
        self._samples = 0

    def add(self, increment, dt: float) -> None:
        """Append one increment (dx, dy, dθ), expressed in the robot frame where the previous one ended."""
        increment = _vector3(increment, "increment")
        dt = _duration(dt)
        c, s = math.cos(self._dtheta), math.sin(self._dtheta)
        self._dx += c * increment[0] - s * increment[1]
        self._dy += s * increment[0] + c * increment[1]
        self._dtheta += float(increment[2])
        self._dt += dt
        self._samples += 1

    def add_sample(self, gravity, velocity, gyro, dt: float) -> np.ndarray:
        """Append the increment of one IMU interval (`proprioception.velocity.planar_increment`); returns it.

        gravity, velocity: the EKF state at the start of the interval (IMU frame); gyro: the yaw-carrying rate
        over the interval with the bias removed (rad/s, IMU frame); dt: the interval (s).
        """
        dt = _duration(dt)
        increment = planar_increment(gravity, velocity, gyro, dt)
        self.add(increment, dt)
        return increment

    def peek(self) -> OdometryIncrement:
        """The sum so far, without restarting it."""
        return OdometryIncrement(self._dt, self._dx, self._dy, _wrap(self._dtheta), self._samples)

    def take(self) -> OdometryIncrement:
        """The sum since the previous take (zero if nothing was added), and a fresh start."""
        out = self.peek()
        self.reset()
        return out

    def reset(self) -> None:
        self._dx = self._dy = self._dtheta = self._dt = 0.0
        self._samples = 0


class EKFOdometry:
    """`LegOdometry` (IMU → EKF prediction, kinematics → correction) with a `PlanarOdometry` sum of its motion.

    Feed it every IMU and kinematics sample in time order, exactly as a `LegOdometry`; call `take()` at the
    filter's rate. The first IMU sample after the EKF's start integrates from the EKF's start time.
    """

    def __init__(self, leg_odometry: LegOdometry) -> None:
        if not isinstance(leg_odometry, LegOdometry):
            raise ValueError(
                f"leg_odometry must be a proprioception.velocity.LegOdometry, got {type(leg_odometry).__name__}"
            )
        self.leg_odometry = leg_odometry
        self.sum = PlanarOdometry()

    @property
    def ekf(self):
        return self.leg_odometry.ekf

    def imu(self, time: float, gyro, accel) -> np.ndarray:
        """One IMU sample (raw gyro, as `LegOdometry.imu` takes): EKF prediction, and the interval's increment.

        The increment is computed from the state before the prediction (and validated) first, so a rejected
        sample changes neither the EKF nor the sum. Returns the increment (dx, dy, dθ).
        """
        ekf = self.ekf
        t = _seconds(time, "time")
        dt = t - ekf.time
        if not (math.isfinite(t) and dt > 0.0):
            raise ValueError(f"time must be finite and after the EKF time {ekf.time!r}, got {time!r}")
        raw = _vector3(gyro, "gyro")
        _vector3(accel, "accel")
        increment = planar_increment(ekf.gravity, ekf.velocity, raw - ekf.gyro_bias, dt)
        self.leg_odometry.imu(t, raw, accel)  # validates the gap; raises before changing anything
        self.sum.add(increment, dt)
        return increment

    def kinematics(self, time: float, angles, contacts) -> KinematicSample:
        """One kinematics sample: the EKF correction (see `LegOdometry.kinematics`)."""
        return self.leg_odometry.kinematics(time, angles, contacts)

    def take(self) -> OdometryIncrement:
        """The pose change since the previous take, for `MotionInput(dt=..., odometry=...)`; restarts the sum."""
        return self.sum.take()
