"""The walk scenario: a robot walking a varied path on a field, with a panning camera and ground truth.

    from demos.walk_sim import WalkScenario, simulate
    log = simulate(WalkScenario(), seed=0)      # log.truth (T, 3), log.commands (T, 3), log.frames

Motion at 100 Hz: the robot follows random waypoints (turning toward each, slowing in turns, with some
sideways drift in the request). Its true motion is not its request: a per-run scale error on each axis, a
turn bias, and step-to-step noise, as a walking engine's odometry differs from what it is asked. Camera at
30 Hz, 60° horizontal field of view on a head panning ±45° every 4 s: landmarks in view and range are
detected with a probability falling with range; range noise grows with the square of the range (a camera's
pitch error), bearing noise is constant; a few false positives per second of random type. With `lines`,
the frame also holds points on the visible field lines (same noise, some missed, a few false). At
`kidnap_time` the robot is carried `kidnap_distance` metres in a random direction (heading kept, as the
gyro keeps it); the motion input says nothing of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from dataclasses import field as dataclass_field

import numpy as np

from field import Field, LandmarkType, spl
from field.angles import wrap_angles
from sensing.observations import Observations


@dataclass(frozen=True)
class WalkingRobot:
    """The simulated robot, camera and walking engine that every walking simulator here shares (SI units).

    `WalkScenario` (a run as a list of steps and frames) and `StreamScenario` (a long run generated a chunk at
    a time) both take these values, so the walk demo, the tests, the battery and the soak simulate the same
    robot unless a scenario changes a value on purpose.
    """

    field: Field = dataclass_field(default_factory=spl)
    motion_rate: float = 100.0  # Hz
    camera_rate: float = 30.0  # Hz
    max_speed: float = 0.25  # m/s
    max_turn_rate: float = 0.8  # rad/s
    lateral_speed: float = 0.05  # m/s, amplitude of the sideways sway of the request
    field_of_view: float = math.radians(60.0)
    head_pan_amplitude: float = math.radians(45.0)
    head_pan_period: float = 4.0  # s
    min_range: float = 0.3  # m, closer landmarks are below the image
    max_range: float = 6.0  # m
    detection_near: float = 0.9  # detection probability at min_range ...
    detection_far: float = 0.3  # ... falling linearly to this at max_range
    range_noise_floor: float = 0.03  # m
    range_noise_growth: float = 0.015  # 1/m (σ_r = floor + growth·r²)
    bearing_noise: float = 0.03  # rad
    false_positive_rate: float = 0.15  # per camera frame
    step_noise: float = 0.05  # relative step-to-step velocity noise
    margin: float = 0.6  # m, waypoints and start stay this far inside the field


@dataclass(frozen=True)
class WalkScenario(WalkingRobot):
    """A walk of `duration` seconds with a kidnapping (see the module docstring); `simulate` runs it."""

    duration: float = 60.0
    lines: bool = False  # report points on detected field lines too
    line_max_range: float = 4.0  # m
    line_point_spacing: float = 0.15  # m between points reported along a line
    line_detection: float = 0.6  # probability that a visible line point is reported
    false_line_points: float = 1.0  # per camera frame (white things that are not lines)
    odometry_scale_sigma: float = 0.06  # per-run scale error of vx, vy, ω (1σ)
    turn_bias_sigma: float = 0.03  # rad/s, per-run drift while walking
    kidnap_time: float | None = 30.0  # s, None for no kidnapping
    kidnap_distance: float = 3.0  # m
    start_pose: tuple[float, float, float] | None = None  # where the robot starts (None: random, own half)


@dataclass(frozen=True)
class CameraFrame:
    step: int  # index of the motion step after which the frame arrives
    observations: Observations
    head_angle: float  # rad, relative to the body


@dataclass(frozen=True)
class WalkLog:
    scenario: WalkScenario
    dt: float
    times: np.ndarray  # (T,) time at the end of each motion step
    truth: np.ndarray  # (T, 3) true pose at the end of each step
    commands: np.ndarray  # (T, 3) walk request (vx, vy, ω) during each step
    frames: tuple[CameraFrame, ...]
    start: np.ndarray  # (3,) true pose at t = 0
    kidnap_step: int | None  # step at whose end the robot was carried away


def _detection_probability(s: WalkScenario, r: np.ndarray) -> np.ndarray:
    share = np.clip((r - s.min_range) / (s.max_range - s.min_range), 0.0, 1.0)
    p = s.detection_near + share * (s.detection_far - s.detection_near)
    return np.where((r >= s.min_range) & (r <= s.max_range), p, 0.0)


def _random_point(s: WalkScenario, rng: np.random.Generator, x_range=None) -> np.ndarray:
    hl, hw = s.field.half_length - s.margin, s.field.half_width - s.margin
    lo, hi = x_range if x_range is not None else (-hl, hl)
    return np.array([rng.uniform(lo, hi), rng.uniform(-hw, hw)])


def _line_points(
    s: WalkScenario, pose: np.ndarray, head: float, rng: np.random.Generator, candidates: np.ndarray
) -> np.ndarray:
    """Points on the visible lines, in the robot frame, with the camera's range and bearing noise."""
    d = candidates - pose[:2]
    r = np.hypot(d[:, 0], d[:, 1])
    bearing = wrap_angles(np.arctan2(d[:, 1], d[:, 0]) - pose[2])
    visible = (
        (np.abs(wrap_angles(bearing - head)) <= 0.5 * s.field_of_view)
        & (r >= s.min_range)
        & (r <= s.line_max_range)
        & (rng.random(r.shape[0]) < s.line_detection)
    )
    r, bearing = r[visible], bearing[visible]
    r = np.maximum(r + (s.range_noise_floor + s.range_noise_growth * r**2) * rng.standard_normal(r.shape[0]), 0)
    bearing = bearing + s.bearing_noise * rng.standard_normal(bearing.shape[0])
    n_false = rng.poisson(s.false_line_points)
    r = np.append(r, rng.uniform(s.min_range, s.line_max_range, n_false))
    bearing = np.append(bearing, head + rng.uniform(-0.5 * s.field_of_view, 0.5 * s.field_of_view, n_false))
    return np.column_stack([r * np.cos(bearing), r * np.sin(bearing)])


def _camera(
    s: WalkScenario, pose: np.ndarray, head: float, rng: np.random.Generator, line_candidates: np.ndarray | None = None
) -> Observations:
    kinds, ranges, bearings = [], [], []
    half_fov = 0.5 * s.field_of_view
    for kind in LandmarkType:
        points = np.asarray(s.field.landmarks_of(kind))
        if points.shape[0] == 0:
            continue
        d = points - pose[:2]
        r = np.hypot(d[:, 0], d[:, 1])
        bearing = wrap_angles(np.arctan2(d[:, 1], d[:, 0]) - pose[2])
        visible = np.abs(wrap_angles(bearing - head)) <= half_fov
        detected = visible & (rng.random(r.shape[0]) < _detection_probability(s, r))
        for i in np.flatnonzero(detected):
            sigma_r = s.range_noise_floor + s.range_noise_growth * r[i] ** 2
            kinds.append(int(kind))
            ranges.append(max(0.0, r[i] + sigma_r * rng.standard_normal()))
            bearings.append(bearing[i] + s.bearing_noise * rng.standard_normal())
    for _ in range(rng.poisson(s.false_positive_rate)):
        kinds.append(int(rng.choice([int(t) for t in LandmarkType])))
        ranges.append(rng.uniform(s.min_range, 0.6 * s.max_range))
        bearings.append(head + rng.uniform(-half_fov, half_fov))
    points = None if line_candidates is None else _line_points(s, pose, head, rng, line_candidates)
    return Observations.from_arrays(
        kinds, ranges, wrap_angles(np.array(bearings, dtype=np.float64)), line_points=points
    )


def simulate(scenario: WalkScenario = WalkScenario(), seed: int = 0) -> WalkLog:
    """Run the scenario once; everything random comes from `seed`."""
    s = scenario
    rng = np.random.default_rng(seed)
    dt = 1.0 / s.motion_rate
    n_steps = int(round(s.duration * s.motion_rate))
    camera_every = s.motion_rate / s.camera_rate
    scale = 1.0 + s.odometry_scale_sigma * rng.standard_normal(3)
    turn_bias = s.turn_bias_sigma * rng.standard_normal()
    # Start in the own half (kick-off placement), facing roughly up the field.
    start = np.append(_random_point(s, rng, (-s.field.half_length + s.margin, -0.5)), rng.uniform(-1.5, 1.5))
    if s.start_pose is not None:  # drawn all the same, so that the rest of the run keeps its random numbers
        start = np.array(s.start_pose, dtype=np.float64)
    pose = start.copy()
    waypoint = _random_point(s, rng)
    lateral_phase = rng.uniform(0, 2 * math.pi)
    kidnap_step = None if s.kidnap_time is None else int(round(s.kidnap_time * s.motion_rate)) - 1
    times = np.arange(1, n_steps + 1) * dt
    truth = np.empty((n_steps, 3))
    commands = np.empty((n_steps, 3))
    frames = []
    line_candidates = s.field.line_points(spacing=s.line_point_spacing) if s.lines else None
    next_frame = camera_every
    for k in range(n_steps):
        t = times[k]
        d = waypoint - pose[:2]
        if np.hypot(*d) < 0.4:
            waypoint = _random_point(s, rng)
            d = waypoint - pose[:2]
        error = math.remainder(math.atan2(d[1], d[0]) - pose[2], 2 * math.pi)
        omega = float(np.clip(1.5 * error, -s.max_turn_rate, s.max_turn_rate))
        vx = s.max_speed * max(0.0, math.cos(error)) ** 2
        vy = s.lateral_speed * math.sin(0.4 * t + lateral_phase)
        command = np.array([vx, vy, omega])
        commands[k] = command
        walking = vx > 0.02
        true_velocity = command * scale * (1.0 + s.step_noise * rng.standard_normal(3))
        true_velocity[2] += turn_bias if walking else 0.0
        half = pose[2] + 0.5 * true_velocity[2] * dt
        c, sn = math.cos(half), math.sin(half)
        pose[0] += (c * true_velocity[0] - sn * true_velocity[1]) * dt
        pose[1] += (sn * true_velocity[0] + c * true_velocity[1]) * dt
        pose[2] = math.remainder(pose[2] + true_velocity[2] * dt, 2 * math.pi)
        if k == kidnap_step:
            pose[:2] = _kidnap_target(s, pose, rng)
            waypoint = _random_point(s, rng)
        truth[k] = pose
        if k + 1 >= next_frame:
            next_frame += camera_every
            head = s.head_pan_amplitude * math.sin(2 * math.pi * t / s.head_pan_period)
            frames.append(CameraFrame(k, _camera(s, pose, head, rng, line_candidates), head))
    return WalkLog(s, dt, times, truth, commands, tuple(frames), start, kidnap_step)


def _kidnap_target(s: WalkScenario, pose: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    hl, hw = s.field.half_length - s.margin, s.field.half_width - s.margin
    for _ in range(1000):
        angle = rng.uniform(-math.pi, math.pi)
        target = pose[:2] + s.kidnap_distance * np.array([math.cos(angle), math.sin(angle)])
        if abs(target[0]) <= hl and abs(target[1]) <= hw:
            return target
    raise RuntimeError("no kidnapping target inside the field")


# -- a long walk, a chunk at a time ----------------------------------------------------------------------------
@dataclass(frozen=True)
class StreamScenario(WalkingRobot):
    """A long walk without end (the soak's hour), generated a chunk at a time by `WalkStream`: the shared robot
    and camera, a camera latency, and odometry with a per-run scale error and a relative noise per reading."""

    latency: float = 0.04  # s from capture to arrival of a frame
    odometry_scale_sigma: float = 0.03  # per-run scale error of the odometry on each axis (1σ)
    odometry_noise: float = 0.05  # relative noise of each odometry reading

    @property
    def dt(self) -> float:
        """The motion step [s]."""
        return 1.0 / self.motion_rate

    @property
    def latency_steps(self) -> int:
        """The latency in whole motion steps."""
        return int(round(self.latency * self.motion_rate))


@dataclass
class Chunk:
    """A stretch of the scenario: `truth` and `odometry` (n, 3) views of the stream's buffers; the camera frames
    captured in it: `capture_steps` (F,) global step indices, detections `kinds`, `ranges`, `bearings` with
    frame f's in [offsets[f], offsets[f + 1])."""

    first_step: int
    truth: np.ndarray
    odometry: np.ndarray
    capture_steps: np.ndarray
    kinds: np.ndarray
    ranges: np.ndarray
    bearings: np.ndarray
    offsets: np.ndarray


class WalkStream:
    """The scenario as a stream of chunks: the robot's path, its odometry and the camera frames."""

    def __init__(self, scenario: StreamScenario, seed: int, chunk_steps: int) -> None:
        s = self.scenario = scenario
        # Its own stream of random numbers, apart from the filter's (which is seeded with `seed` itself).
        self.rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x50A4]))
        self.step = 0
        self.truth = np.empty((chunk_steps, 3))
        self.odometry = np.empty((chunk_steps, 3))
        self.scale = 1.0 + s.odometry_scale_sigma * self.rng.standard_normal(3)
        self.phase = float(self.rng.uniform(0.0, 2.0 * math.pi))
        hl, hw = s.field.half_length, s.field.half_width
        side = 1.0 if self.rng.random() < 0.5 else -1.0  # which own touchline
        x = float(self.rng.uniform(-hl + s.margin, -0.5))
        heading = -side * math.pi / 2 + float(self.rng.normal(0.0, 0.05))
        self.start = np.array([x, side * hw, heading])
        self.pose = [x, side * hw, heading]
        self.waypoint = self._waypoint()
        kinds, points = [], []
        for kind in LandmarkType:
            at = np.asarray(s.field.landmarks_of(kind), dtype=np.float64).reshape(-1, 2)
            points.append(at)
            kinds.append(np.full(at.shape[0], int(kind), dtype=np.int64))
        self.landmarks = np.concatenate(points)
        self.landmark_kinds = np.concatenate(kinds)
        self.kind_values = np.array([int(kind) for kind in LandmarkType], dtype=np.int64)

    def _waypoint(self) -> tuple[float, float]:
        s = self.scenario
        hl, hw = s.field.half_length - s.margin, s.field.half_width - s.margin
        return float(self.rng.uniform(-hl, hl)), float(self.rng.uniform(-hw, hw))

    def next_chunk(self, n: int) -> Chunk:
        """The next `n` motion steps (n at most the buffers' length) and the frames captured during them."""
        s = self.scenario
        dt = s.dt
        noise = self.rng.standard_normal((n, 6)).tolist()
        truth, odometry = self.truth[:n], self.odometry[:n]
        x, y, th = self.pose
        wx, wy = self.waypoint
        sx, sy, sth = (float(v) for v in self.scale)
        for k in range(n):
            t = (self.step + k + 1) * dt
            dx, dy = wx - x, wy - y
            if dx * dx + dy * dy < 0.16:
                wx, wy = self._waypoint()
                dx, dy = wx - x, wy - y
            error = math.remainder(math.atan2(dy, dx) - th, 2.0 * math.pi)
            omega = max(-s.max_turn_rate, min(s.max_turn_rate, 1.5 * error))
            vx = s.max_speed * max(0.0, math.cos(error)) ** 2
            vy = s.lateral_speed * math.sin(0.4 * t + self.phase)
            e = noise[k]
            ddx = vx * (1.0 + s.step_noise * e[0]) * dt  # the true motion, robot frame
            ddy = vy * (1.0 + s.step_noise * e[1]) * dt
            dth = omega * (1.0 + s.step_noise * e[2]) * dt
            c, sn = math.cos(0.5 * dth), math.sin(0.5 * dth)
            ox, oy = c * ddx - sn * ddy, sn * ddx + c * ddy  # the pose change in the previous robot frame
            c, sn = math.cos(th), math.sin(th)
            x += c * ox - sn * oy
            y += sn * ox + c * oy
            th = math.remainder(th + dth, 2.0 * math.pi)
            truth[k, 0], truth[k, 1], truth[k, 2] = x, y, th
            odometry[k, 0] = ox * sx * (1.0 + s.odometry_noise * e[3])
            odometry[k, 1] = oy * sy * (1.0 + s.odometry_noise * e[4])
            odometry[k, 2] = dth * sth * (1.0 + s.odometry_noise * e[5])
        self.pose = [x, y, th]
        self.waypoint = (wx, wy)
        first = self.step
        self.step += n
        return Chunk(first, truth, odometry, *self._frames(first, truth))

    def _frames(self, first: int, truth: np.ndarray):
        """The camera frames captured during the steps from `first` (vectorized over the frames)."""
        s, rng = self.scenario, self.rng
        g = np.arange(first, first + truth.shape[0], dtype=np.int64)
        captured = ((g + 1) * s.camera_rate) // s.motion_rate > (g * s.camera_rate) // s.motion_rate
        steps = g[captured]
        poses = truth[steps - first]
        n_frames = steps.shape[0]
        head = s.head_pan_amplitude * np.sin(2.0 * math.pi * (steps + 1) * s.dt / s.head_pan_period)
        d = self.landmarks[None, :, :] - poses[:, None, :2]  # (F, L, 2)
        r = np.hypot(d[..., 0], d[..., 1])
        bearing = wrap_angles(np.arctan2(d[..., 1], d[..., 0]) - poses[:, 2:3])
        share = np.clip((r - s.min_range) / (s.max_range - s.min_range), 0.0, 1.0)
        probability = s.detection_near + share * (s.detection_far - s.detection_near)
        half_fov = 0.5 * s.field_of_view
        seen = (
            (np.abs(wrap_angles(bearing - head[:, None])) <= half_fov)
            & (r >= s.min_range)
            & (r <= s.max_range)
            & (rng.random(r.shape) < probability)
        )
        frame, landmark = np.nonzero(seen)
        true_range = r[frame, landmark]
        ranges = np.maximum(
            true_range
            + (s.range_noise_floor + s.range_noise_growth * true_range**2) * rng.standard_normal(true_range.shape[0]),
            0.0,
        )
        bearings = bearing[frame, landmark] + s.bearing_noise * rng.standard_normal(true_range.shape[0])
        kinds = self.landmark_kinds[landmark]
        false = rng.poisson(s.false_positive_rate, n_frames)
        false_frame = np.repeat(np.arange(n_frames), false)
        m = false_frame.shape[0]
        frame = np.concatenate([frame, false_frame])
        kinds = np.concatenate([kinds, self.kind_values[rng.integers(0, self.kind_values.shape[0], m)]])
        ranges = np.concatenate([ranges, rng.uniform(s.min_range, 0.6 * s.max_range, m)])
        bearings = np.concatenate([bearings, head[false_frame] + rng.uniform(-half_fov, half_fov, m)])
        order = np.argsort(frame, kind="stable")
        offsets = np.searchsorted(frame[order], np.arange(n_frames + 1))
        return steps, kinds[order], ranges[order], wrap_angles(bearings[order]), offsets
