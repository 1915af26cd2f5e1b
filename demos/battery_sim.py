"""The evaluation battery's world: a humanoid walking on a RoboCup field, its odometry, its camera, and the
game's mishaps, simulated independently of the filter under test.

    from demos.battery_sim import FAMILIES, simulate
    run = simulate("kidnap", seed=1003, duration=60.0)
    run.truth (T, 3), run.odometry (T, 3), run.frames, run.calls, run.windows, run.params
    run.ball (T, 2), run.ball_detections (one per frame), run.messages ((arrival_step, TeamMessage), ...)

Nothing here comes from the filter, its motion models or its sensor models: the simulator has its own walk,
its own odometry errors and its own camera, each drawn per run from ranges wider than a filter assumes
(`RANGES`). Everything random comes from one `numpy.random.Generator` seeded by (seed, family): the same
seed gives the same run, bit for bit. The field is `FIELDS[seed % 3]`, so consecutive seeds cover all three.

A run, at 100 Hz (`DT`):
- truth: the pose at the end of every step (`start` at t = 0). The robot walks toward random waypoints at least
  `INSIDE` m inside the field lines (0.1–0.35 m/s, turn rates up to 1 rad/s, slowing to turn), stops, turns on
  the spot and sidesteps, with a gait's lateral and yaw sway, and acceleration limits;
- body: what the walking engine does in each step (robot frame); the truth follows it unless the robot is
  stuck or lying, and events may move the truth without it (a kidnapping, a spin, a fall);
- odometry: the body motion as the robot measures it: a scale error per axis (±15 %), a turn bias while
  walking (±0.1 rad/s), a slow random walk of the velocity error, and white noise per step; zero while lying;
- frames: camera frames at 15–30 Hz, each with its capture time, its arrival (capture + 0–100 ms latency)
  and the motion step after which it arrives; detections of the field's landmarks inside a 50–90° view on a
  panning head (0–60°, 2–6 s), within a 4–8 m range, each seen with probability 0.4–0.95, range noise
  σ = a + b·r or σ = a + c·r² (law drawn per run), bearing noise 0.01–0.08 rad, and 0–0.3 false detections
  per frame of a random type inside the view. No noise figures are passed with the detections;
- calls: the game events a team's code would report (`Localizer` methods without arguments, after a step);
- windows: (start, end) times of the event, from whose end the reconvergence is counted;
- params: every drawn number (JSON-ready);
- the team world (`demos.team_sim`, its manual there): a ball that rolls and is kicked (`ball`, per step), the
  robot's own ball detection in each camera frame (`ball_detections`, aligned with `frames`: a
  `sensing.team.BallDetection` or None), and 1–4 teammates that walk, see the ball and broadcast
  `sensing.team.TeamMessage`s, delivered late, lossy and out of order (`messages`: (arrival_step, message)
  sorted by arrival; feed each after that motion step); `team` holds the rest (teammates' truth, every message
  sent), `params["team"]` its drawn numbers. It is drawn last, from a generator of its own seeded by (seed,
  family, `TEAM_STREAM`), so the rest of a run does not depend on it. The ball and the teammates are simulated
  in every family; messages are delivered only in `kidnap_even_team` and `kidnap_even_wrong`.

Families (`FAMILIES`): the event happens at a random 35–55 % of the run; every run starts in the own half.
tracking (none), kidnap (unsignaled, 1–4 m, any heading change), kidnap_special (1–4 m, heading change 0°,
+90°, −90° or 180° by seed), kidnap_announced (penalty return or manual placement, alternating by seed),
collision (stuck while the odometry walks on 0.3–1 m, or spun by 30–120° in 0.5 s, alternating by seed),
fall (moved up to 0.3 m and ±90°, 2–5 s lying), false_bursts (2–4 bursts of 1–3 s with 3–8 false detections
per frame and 70 % of the real ones suppressed), blackout (10–20 s without detections), start_unknown (no
event; starts anywhere in the own half, also right at the centre line, with any heading);
and, appended so that the families above keep their seeds, the even kidnappings: an unsignalled kidnapping
(event type `kidnap` with `even` set) by `kidnap`'s law but kept only where the mirror image is about as
probable (|`kidnap_mirror_log_odds`| < log 2, by rejection; the robot starts and walks in the middle of the
field, `EVEN_BOX`, until then, since only there is such a landing point; the kidnapping waits for one):
kidnap_even_team (teammates' messages on), kidnap_even_wrong (2–4 teammates, one of them wrongly on its mirror
pose, and sure of it, for 10–40 s around the kidnapping), kidnap_even_silent (the same, no message delivered).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from field import Field, LandmarkType, preset
from field.angles import wrap_angles
from mcl.tools.logs import RobotLog, VisionFrame
from sensing.observations import Observations

from .team_sim import TeamWorld, simulate_team

FAMILIES = (
    "tracking",
    "kidnap",
    "kidnap_special",
    "kidnap_announced",
    "collision",
    "fall",
    "false_bursts",
    "blackout",
    "start_unknown",
    # appended, so that the families above keep their codes and seeds
    "kidnap_even_team",
    "kidnap_even_wrong",
    "kidnap_even_silent",
)
EVEN_FAMILIES = ("kidnap_even_team", "kidnap_even_wrong", "kidnap_even_silent")
FIELDS = ("spl", "kidsize", "adultsize")
DT = 0.01  # s, the motion and truth rate (100 Hz)
INSIDE = 0.3  # m, waypoints, kidnapping targets and placements stay this far inside the field lines
SPECIAL_TURNS = (0.0, 90.0, -90.0, 180.0)  # degrees, kidnap_special's heading changes, cycled by seed

# The ranges every run draws from (uniform); see the module docstring.
RANGES = {
    "max_speed": (0.15, 0.35),  # m/s, the fastest leg of the run; each leg walks at 0.1..max_speed
    "max_turn": (0.4, 1.0),  # rad/s
    "step_frequency": (1.4, 2.6),  # Hz, the gait's sway
    "sway_lateral": (0.0, 0.05),  # m/s, amplitude of the lateral sway velocity
    "sway_yaw": (0.0, 0.04),  # rad, amplitude of the heading sway
    "odometry_scale": (0.85, 1.15),  # per axis: measured = scale · true
    "turn_bias": (-0.1, 0.1),  # rad/s, added to the measured turn while the legs step
    "drift_sigma": (0.0, 0.02),  # m/s (x, y) and rad/s (θ): stationary σ of the velocity error's walk
    "drift_time": (2.0, 10.0),  # s, its correlation time
    "step_noise": (0.0, 0.15),  # relative white noise of each step's measurement
    "camera_rate": (15.0, 30.0),  # Hz
    "latency": (0.0, 0.1),  # s, capture to arrival
    "latency_jitter": (0.0, 0.015),  # s, ± per frame (the latency stays within 0–0.1 s)
    "fov_deg": (50.0, 90.0),  # horizontal field of view
    "pan_amplitude_deg": (0.0, 60.0),
    "pan_period": (2.0, 6.0),  # s
    "max_range_share": (0.45, 0.65),  # of the field length, then clipped to MAX_RANGE
    "min_range": (0.2, 0.5),  # m, closer landmarks are below the image
    "detection": (0.4, 0.95),  # probability per visible landmark and frame
    "range_a": (0.02, 0.15),  # m
    "range_b": (0.02, 0.10),  # σ_r = a + b·r  (law "linear")
    "range_c": (0.005, 0.04),  # 1/m, σ_r = a + c·r²  (law "quadratic")
    "bearing_sigma": (0.01, 0.08),  # rad
    "false_rate": (0.0, 0.3),  # false detections per frame (Poisson mean)
}
MAX_RANGE = (4.0, 8.0)  # m
EVENT_AT = (0.35, 0.55)  # share of the run
KIDNAP_DISTANCE = (1.0, 4.0)  # m
STUCK_SECONDS = (1.5, 4.0)
STUCK_EXCESS = (0.3, 1.0)  # m the odometry runs ahead while stuck
STUCK_SPEED = (0.1, 0.35)  # m/s the walking engine reports while stuck
SPIN_DEG = (30.0, 120.0)
SPIN_SECONDS = 0.5
FALL_SHIFT = (0.0, 0.3)  # m
FALL_TURN_DEG = 90.0  # ± heading change
FALL_SECONDS = 0.5  # the fall itself
LYING = (2.0, 5.0)  # s
BURSTS = (2, 4)  # number of false-detection bursts
BURST_SECONDS = (1.0, 3.0)
BURST_GAP = (3.0, 8.0)  # s between bursts
BURST_RATE = (3.0, 8.0)  # false detections per frame inside a burst
BURST_KEEP = 0.3  # share of the real detections a burst lets through
BLACKOUT = (10.0, 20.0)  # s
EVEN_ODDS = math.log(2.0)  # an even kidnapping: |kidnap_mirror_log_odds| below this
EVEN_BOX = (2.2, 1.8)  # m, half extents of the middle of the field the even families walk in
# until the kidnapping (only there does an even landing point exist)
EVEN_TRIES = 200  # landing points tried per attempt (the law's own draws, then rejected)
EVEN_RETRY_STEPS = 20  # when none is even, the kidnapping waits this many steps and tries again
TEAM_STREAM = 7  # the team world's generator: SeedSequence([seed, family code, 7])

_KINDS = tuple(LandmarkType)


@dataclass(frozen=True)
class Frame:
    """One camera frame: taken at `capture_time`, delivered at `arrival_time`, i.e. after motion step
    `arrival_step`; `head` the pan angle [rad]; `real` and `false` count its true and false detections."""

    capture_time: float
    arrival_time: float
    arrival_step: int
    head: float
    observations: Observations
    real: int
    false: int


@dataclass(frozen=True)
class Call:
    """A game event for the localizer: method `name` (no arguments), called after motion step `step`."""

    step: int
    name: str


@dataclass(frozen=True)
class BatteryRun:
    """One simulated run (see the module docstring). Arrays are per motion step k, covering the step that ends
    at times[k] = (k + 1)·dt: truth (T, 3), body (T, 3) and odometry (T, 3) robot-frame increments, walking (T,)
    whether the legs step (the odometry reports), moving (T,) whether the truth follows the body. The team
    world (`demos.team_sim`): ball (T, 2) the ball's truth; ball_detections, one per frame (aligned with
    `frames`), a `sensing.team.BallDetection` or None; messages, (arrival_step, `sensing.team.TeamMessage`)
    sorted by arrival, each to be given after that motion step (empty unless the family's messages are on);
    team, the rest of it (`demos.team_sim.TeamWorld`). They default to empty for runs made without it."""

    family: str
    seed: int
    field: Field
    dt: float
    times: np.ndarray
    start: np.ndarray
    truth: np.ndarray
    body: np.ndarray
    odometry: np.ndarray
    walking: np.ndarray
    moving: np.ndarray
    frames: tuple[Frame, ...]
    calls: tuple[Call, ...]
    windows: tuple[tuple[float, float], ...]
    params: dict
    ball: np.ndarray | None = None
    ball_detections: tuple = ()
    messages: tuple = ()
    team: TeamWorld | None = None


def family_code(family: str) -> int:
    """A stable number for a family name (the second half of the run's seed)."""
    if family not in FAMILIES:
        raise ValueError(f"family = {family!r} is unknown; choose from {', '.join(FAMILIES)}")
    return zlib.crc32(family.encode())


def field_for(seed: int) -> Field:
    """The field a seed plays on: FIELDS[seed % 3]."""
    return preset(FIELDS[seed % len(FIELDS)])


def _u(rng: np.random.Generator, key: str) -> float:
    lo, hi = RANGES[key]
    return float(rng.uniform(lo, hi))


def _draw_parameters(rng: np.random.Generator, field: Field) -> dict:
    """The run's robot, odometry and camera, in a fixed drawing order."""
    p = {key: _u(rng, key) for key in ("max_speed", "max_turn", "step_frequency", "sway_lateral", "sway_yaw")}
    p["odometry_scale"] = [float(v) for v in rng.uniform(*RANGES["odometry_scale"], 3)]
    p["turn_bias"] = _u(rng, "turn_bias")
    p["drift_sigma"] = [float(v) for v in rng.uniform(*RANGES["drift_sigma"], 3)]
    for key in (
        "drift_time",
        "step_noise",
        "camera_rate",
        "latency",
        "latency_jitter",
        "fov_deg",
        "pan_amplitude_deg",
        "pan_period",
    ):
        p[key] = _u(rng, key)
    p["pan_phase"] = float(rng.uniform(0.0, 2.0 * math.pi))
    p["camera_phase"] = float(rng.uniform(0.0, 1.0))  # first capture, in frame intervals
    p["max_range"] = float(np.clip(_u(rng, "max_range_share") * field.dims.length, *MAX_RANGE))
    for key in ("min_range", "detection", "range_a"):
        p[key] = _u(rng, key)
    p["range_law"] = "linear" if rng.random() < 0.5 else "quadratic"
    p["range_growth"] = _u(rng, "range_b" if p["range_law"] == "linear" else "range_c")
    p["bearing_sigma"] = _u(rng, "bearing_sigma")
    p["false_rate"] = _u(rng, "false_rate")
    return p


def _inside_point(rng: np.random.Generator, field: Field, x_range=None) -> np.ndarray:
    hl, hw = field.half_length - INSIDE, field.half_width - INSIDE
    lo, hi = x_range if x_range is not None else (-hl, hl)
    return np.array([rng.uniform(lo, hi), rng.uniform(-hw, hw)])


def _is_inside(field: Field, xy) -> bool:
    return abs(xy[0]) <= field.half_length - INSIDE and abs(xy[1]) <= field.half_width - INSIDE


def _box_point(rng: np.random.Generator, field: Field, x_range=None) -> np.ndarray:
    """A point in the middle of the field (`EVEN_BOX`, inside the field lines by `INSIDE`)."""
    bx, by = min(EVEN_BOX[0], field.half_length - INSIDE), min(EVEN_BOX[1], field.half_width - INSIDE)
    lo, hi = x_range if x_range is not None else (-bx, bx)
    return np.array([rng.uniform(max(lo, -bx), min(hi, bx)), rng.uniform(-by, by)])


def _start_pose(rng: np.random.Generator, field: Field, family: str, seed: int) -> np.ndarray:
    hl = field.half_length
    if family in EVEN_FAMILIES:
        return np.append(_box_point(rng, field, (-hl, -0.5)), rng.uniform(-math.pi / 2, math.pi / 2))
    if family == "start_unknown":
        # Half the seeds right at the centre line (where the own-half prior's edge is), any heading.
        x_range = (-0.8, -0.05) if seed % 2 == 0 else (-hl + INSIDE, -0.05)
        return np.append(_inside_point(rng, field, x_range), rng.uniform(-math.pi, math.pi))
    return np.append(_inside_point(rng, field, (-hl + INSIDE, -0.5)), rng.uniform(-math.pi / 2, math.pi / 2))


def _plan_event(rng: np.random.Generator, family: str, seed: int, duration: float, n_steps: int) -> dict:
    """When and what happens (anything depending on where the robot is then is drawn at that moment)."""
    at = float(rng.uniform(*EVENT_AT)) * duration
    step = min(max(int(round(at / DT)) - 1, 0), n_steps - 1)
    last = n_steps - 1 - int(round(1.0 / DT))  # events end at least 1 s before the run does
    plan: dict = {"type": "none"}
    if family in ("tracking", "start_unknown"):
        return plan
    plan = {"type": family, "step": step, "time": (step + 1) * DT}
    if family in EVEN_FAMILIES:
        # An unsignalled kidnapping like `kidnap`'s, its landing point drawn by the same law but kept only when
        # the mirror image is about as probable (`_even_target`); the distance is drawn there.
        plan["type"] = "kidnap"
        plan["even"] = True
        plan["planned_step"] = step
        plan["turn_deg"] = float(rng.uniform(-180.0, 180.0))
    elif family in ("kidnap", "kidnap_special"):
        plan["distance"] = float(rng.uniform(*KIDNAP_DISTANCE))
        if family == "kidnap":
            plan["turn_deg"] = float(rng.uniform(-180.0, 180.0))
        else:
            plan["turn_deg"] = SPECIAL_TURNS[seed % len(SPECIAL_TURNS)]
    elif family == "kidnap_announced":
        plan["type"] = "penalty" if seed % 2 == 0 else "manual_placement"
        plan["side"] = 1 if rng.random() < 0.5 else -1
        plan["standing"] = float(rng.uniform(1.0, 3.0))
    elif family == "collision":
        if seed % 2 == 0:
            plan["type"] = "stuck"
            plan["excess_target"] = float(rng.uniform(*STUCK_EXCESS))
            plan["u_seconds"] = float(rng.random())  # where in the feasible durations
        else:
            plan["type"] = "spun"
            plan["turn_deg"] = float(rng.uniform(*SPIN_DEG)) * (1 if rng.random() < 0.5 else -1)
            plan["end_step"] = min(step + int(round(SPIN_SECONDS / DT)) - 1, last)
    elif family == "fall":
        plan["shift"] = float(rng.uniform(*FALL_SHIFT))
        plan["shift_direction"] = float(rng.uniform(-math.pi, math.pi))
        plan["turn_deg"] = float(rng.uniform(-FALL_TURN_DEG, FALL_TURN_DEG))
        plan["lying"] = float(rng.uniform(*LYING))
        plan["end_step"] = min(step + int(round(plan["lying"] / DT)), last)
    elif family == "false_bursts":
        plan["rate"] = float(rng.uniform(*BURST_RATE))
        bursts, t = [], plan["time"]
        for i in range(int(rng.integers(BURSTS[0], BURSTS[1] + 1))):
            length = float(rng.uniform(*BURST_SECONDS))
            gap = float(rng.uniform(*BURST_GAP))
            if i and t + length > last * DT:
                break
            bursts.append((t, min(t + length, last * DT)))
            t += length + gap
        plan["bursts"] = bursts
    elif family == "blackout":
        plan["length"] = float(rng.uniform(*BLACKOUT))
        plan["end"] = min(plan["time"] + plan["length"], (last + 1) * DT)
    return plan


def _kidnap_target(rng: np.random.Generator, field: Field, xy: np.ndarray, distance: float) -> np.ndarray:
    """A point `distance` m away inside the field (another distance from the range if none fits)."""
    for attempt in range(100):
        d = distance if attempt < 50 else float(rng.uniform(*KIDNAP_DISTANCE))
        angles = rng.uniform(-math.pi, math.pi, 64)
        targets = xy + d * np.column_stack([np.cos(angles), np.sin(angles)])
        ok = (np.abs(targets[:, 0]) <= field.half_length - INSIDE) & (
            np.abs(targets[:, 1]) <= field.half_width - INSIDE
        )
        if ok.any():
            return targets[int(np.argmax(ok))]
    raise RuntimeError("no kidnapping target inside the field")


def _even_target(rng: np.random.Generator, field: Field, pose: np.ndarray) -> np.ndarray | None:
    """A landing point drawn by the kidnapping law (a distance uniform in `KIDNAP_DISTANCE`, a direction uniform
    among those landing inside the field) conditioned on being even: |`kidnap_mirror_log_odds`| < `EVEN_ODDS`
    (rejection: up to `EVEN_TRIES` draws); None when none of them is."""
    start = [float(v) for v in pose]
    for _ in range(EVEN_TRIES):
        d = float(rng.uniform(*KIDNAP_DISTANCE))
        angles = rng.uniform(-math.pi, math.pi, 64)
        targets = pose[:2] + d * np.column_stack([np.cos(angles), np.sin(angles)])
        ok = (np.abs(targets[:, 0]) <= field.half_length - INSIDE) & (
            np.abs(targets[:, 1]) <= field.half_width - INSIDE
        )
        if not ok.any():
            continue
        target = targets[int(np.argmax(ok))]
        odds = kidnap_mirror_log_odds(
            field, {"type": "kidnap", "from": start, "to": [float(target[0]), float(target[1]), 0.0]}
        )
        if odds is not None and abs(odds) < EVEN_ODDS:
            return target
    return None


def kidnap_mirror_log_odds(field: Field, event: dict) -> float | None:
    """For a kidnapping (`kidnap`, `kidnap_special`): the log odds of the true landing pose against its mirror
    image (−x, −y, θ + π) under this simulator's own kidnapping law, knowing the exact pose it started from;
    None for other events. The even families' kidnappings are of type `kidnap` (with `even` set): the same law
    restricted to landing points whose odds are within ±`EVEN_ODDS`, a set closed under the mirror, so the same
    odds. The filter never sees this: the battery reports with it which runs on the mirror
    the robot could have told apart at all.

    The law: a distance uniform in `KIDNAP_DISTANCE`, a direction uniform among those that land inside the
    field, and a heading change that the mirror cannot be told from (uniform over the circle, or `SPECIAL_TURNS`,
    which is closed under a half turn). So the odds are those of the two landing points' densities,
    1 / (d · share of the circle of radius d inside the field), and +inf when the mirror image lies at a
    distance the law never draws."""
    if event.get("type") not in ("kidnap", "kidnap_special") or "to" not in event:
        return None
    start = np.asarray(event["from"][:2], dtype=np.float64)
    land = np.asarray(event["to"][:2], dtype=np.float64)
    angles = np.linspace(-math.pi, math.pi, 720, endpoint=False)
    directions = np.column_stack([np.cos(angles), np.sin(angles)])

    def density(point: np.ndarray) -> float:
        d = float(math.hypot(*(point - start)))
        if not KIDNAP_DISTANCE[0] - 1e-9 <= d <= KIDNAP_DISTANCE[1] + 1e-9:
            return 0.0
        ring = start + d * directions
        inside = float(
            (
                (np.abs(ring[:, 0]) <= field.half_length - INSIDE) & (np.abs(ring[:, 1]) <= field.half_width - INSIDE)
            ).mean()
        )
        return 1.0 / (d * max(inside, 1.0 / angles.shape[0]))

    truth, mirror = density(land), density(-land)
    if mirror == 0.0:
        return math.inf
    if truth == 0.0:
        return -math.inf
    return math.log(truth / mirror)


class _Walker:
    """The robot's behaviour: a mode (walk to a waypoint, stop, turn on the spot, sidestep) and its command."""

    def __init__(self, rng: np.random.Generator, field: Field, p: dict) -> None:
        self.rng, self.field, self.p = rng, field, p
        self.mode = "stop"
        self.until = 0.0
        self.waypoint = np.zeros(2)
        self.speed = 0.0
        self.turn_to = 0.0
        self.turn_rate = 0.0
        self.side = 0.0
        self.box = False  # waypoints in the middle of the field (`EVEN_BOX`) instead of anywhere

    def stand(self, t: float, seconds: float) -> None:
        self.mode, self.until = "stop", t + seconds

    def choose(self, t: float, pose: np.ndarray) -> None:
        rng, p = self.rng, self.p
        u = rng.random()
        if u < 0.55:
            self.mode, self.until = "walk", t + 30.0
            self.waypoint = _box_point(rng, self.field) if self.box else _inside_point(rng, self.field)
            self.speed = float(rng.uniform(0.1, max(p["max_speed"], 0.1)))
        elif u < 0.7:
            self.stand(t, float(rng.uniform(0.5, 2.5)))
        elif u < 0.85:
            angle = float(rng.uniform(math.pi / 4, math.pi)) * (1 if rng.random() < 0.5 else -1)
            self.turn_rate = float(rng.uniform(0.5, 1.0)) * p["max_turn"]
            self.mode, self.until = "turn", t + abs(angle) / self.turn_rate + 1.0
            self.turn_to = pose[2] + angle
        else:
            # Sideways toward the middle of the field, so a sidestep never leaves it.
            left = np.array([-math.sin(pose[2]), math.cos(pose[2])])
            sign = 1.0 if float(left @ -pose[:2]) >= 0 else -1.0
            self.side = sign * float(rng.uniform(0.05, 0.15))
            self.mode, self.until = "side", t + float(rng.uniform(1.0, 3.0))

    def command(self, t: float, pose: np.ndarray) -> tuple[float, float, float]:
        if self.mode == "walk":
            d = self.waypoint - pose[:2]
            if math.hypot(d[0], d[1]) < 0.25 or t >= self.until:
                self.choose(t, pose)
                return self.command(t, pose)
            error = math.remainder(math.atan2(d[1], d[0]) - pose[2], 2 * math.pi)
            omega = max(-self.p["max_turn"], min(self.p["max_turn"], 1.5 * error))
            return self.speed * max(0.0, math.cos(error)) ** 2, 0.0, omega
        if t >= self.until:
            self.choose(t, pose)
            return self.command(t, pose)
        if self.mode == "turn":
            error = math.remainder(self.turn_to - pose[2], 2 * math.pi)
            if abs(error) < 0.05:
                self.until = t
            return 0.0, 0.0, max(-self.turn_rate, min(self.turn_rate, 2.0 * error))
        if self.mode == "side":
            return 0.0, self.side, 0.0
        return 0.0, 0.0, 0.0


def _walk(rng: np.random.Generator, field: Field, p: dict, plan: dict, start: np.ndarray, n_steps: int):
    """Truth (T + 1, 3 with the start), body increments, walking and moving masks; fills the plan's drawn
    event details (targets, the stuck speed)."""
    truth = np.empty((n_steps + 1, 3))
    truth[0] = start
    body = np.zeros((n_steps, 3))
    walking = np.zeros(n_steps, dtype=bool)
    moving = np.ones(n_steps, dtype=bool)
    external = np.zeros((n_steps, 3))  # world-frame motion the odometry does not see
    teleports: dict[int, str] = {}
    lying = np.zeros(n_steps, dtype=bool)
    forced: dict[int, tuple[float, float, float]] = {}
    kind = plan["type"]
    k0 = plan.get("step", -1)
    even = bool(plan.get("even"))
    if kind in ("kidnap", "kidnap_special", "penalty", "manual_placement") and not even:
        teleports[k0] = kind
    elif kind == "stuck":
        scale_x = p["odometry_scale"][0]
        # Durations for which the engine's speed (the reported excess over the duration, unscaled) is feasible.
        lo = max(STUCK_SECONDS[0], plan["excess_target"] / (STUCK_SPEED[1] * scale_x))
        hi = min(STUCK_SECONDS[1], plan["excess_target"] / (STUCK_SPEED[0] * scale_x))
        seconds = lo + plan.pop("u_seconds") * (hi - lo)
        n = int(round(seconds / DT))
        plan["seconds"] = n * DT
        plan["speed"] = plan["excess_target"] / (n * DT * scale_x)
        plan["end_step"] = min(k0 + n - 1, n_steps - 1)
        moving[k0 : plan["end_step"] + 1] = False
        for k in range(k0, plan["end_step"] + 1):
            forced[k] = (plan["speed"], 0.0, 0.0)
    elif kind == "spun":
        n = plan["end_step"] - k0 + 1
        external[k0 : k0 + n, 2] = math.radians(plan["turn_deg"]) / n
    elif kind == "fall":
        n = max(1, min(int(round(FALL_SECONDS / DT)), plan["end_step"] - k0 + 1))
        shift = plan["shift"] * np.array([math.cos(plan["shift_direction"]), math.sin(plan["shift_direction"])])
        external[k0 : k0 + n, :2] = shift / n
        external[k0 : k0 + n, 2] = math.radians(plan["turn_deg"]) / n
        lying[k0 : plan["end_step"] + 1] = True
        moving[k0 : plan["end_step"] + 1] = False
    walker = _Walker(rng, field, p)
    walker.box = even
    walker.stand(0.0, float(rng.uniform(0.0, 1.0)))
    pending = even  # an even kidnapping not done yet: tried from its step on, every EVEN_RETRY_STEPS
    pose = start.copy()
    velocity = np.zeros(3)
    limits = np.array([0.6, 0.6, 3.0]) * DT  # m/s², m/s², rad/s² (times dt): the engine's acceleration
    two_pi_f = 2.0 * math.pi * p["step_frequency"]
    sway_phase = float(rng.uniform(0.0, 2.0 * math.pi))
    for k in range(n_steps):
        t = k * DT
        if lying[k]:
            velocity[:] = 0.0
            increment = (0.0, 0.0, 0.0)
            if k == plan["end_step"]:
                walker.stand(t, float(rng.uniform(0.5, 1.5)))
        else:
            command = forced.get(k)
            if command is None:
                command = walker.command(t, pose)
                velocity += np.clip(np.asarray(command) - velocity, -limits, limits)
            else:
                velocity[:] = command
            stepping = abs(velocity[0]) + abs(velocity[1]) > 0.01 or abs(velocity[2]) > 0.05
            vx, vy, omega = velocity
            if stepping:
                phase = two_pi_f * t + sway_phase
                vy += p["sway_lateral"] * math.sin(phase)
                omega += p["sway_yaw"] * two_pi_f * math.cos(phase)
            walking[k] = stepping
            half = 0.5 * omega * DT
            c, s = math.cos(half), math.sin(half)
            increment = ((c * vx - s * vy) * DT, (s * vx + c * vy) * DT, omega * DT)
        body[k] = increment
        if moving[k]:
            c, s = math.cos(pose[2]), math.sin(pose[2])
            pose[0] += c * increment[0] - s * increment[1]
            pose[1] += s * increment[0] + c * increment[1]
            pose[2] += increment[2]
        pose += external[k]
        if pending and k >= k0 and (k - k0) % EVEN_RETRY_STEPS == 0:
            target = _even_target(rng, field, pose)
            if target is not None or k + EVEN_RETRY_STEPS >= n_steps - int(round(1.0 / DT)):
                if target is None:  # never even before the run's end (not seen): a plain kidnapping
                    plan["even"] = False
                    target = _kidnap_target(rng, field, pose[:2], float(rng.uniform(*KIDNAP_DISTANCE)))
                plan["step"], plan["time"] = k, (k + 1) * DT
                plan["from"] = [float(v) for v in pose]
                plan["distance"] = float(math.hypot(*(target - pose[:2])))
                pose = np.array([target[0], target[1], pose[2] + math.radians(plan["turn_deg"])])
                plan["to"] = [float(v) for v in pose]
                walker.box, pending = False, False
        if k in teleports:
            pose = _teleport(rng, field, plan, pose)
            if teleports[k] in ("penalty", "manual_placement"):
                walker.stand(t, plan["standing"])
        pose[2] = math.remainder(pose[2], 2 * math.pi)
        truth[k + 1] = pose
    return truth, body, walking, moving


def _teleport(rng: np.random.Generator, field: Field, plan: dict, pose: np.ndarray) -> np.ndarray:
    kind = plan["type"]
    hl, hw = field.half_length, field.half_width
    if kind in ("kidnap", "kidnap_special"):
        xy = _kidnap_target(rng, field, pose[:2], plan["distance"])
        plan["distance"] = float(math.hypot(*(xy - pose[:2])))
        new = np.array([xy[0], xy[1], pose[2] + math.radians(plan["turn_deg"])])
    elif kind == "penalty":
        side = plan["side"]
        new = np.array(
            [
                -hl + field.dims.penalty_mark_distance + rng.uniform(-0.1, 0.1),
                side * (hw - rng.uniform(0.0, 0.1)),
                -side * math.pi / 2 + rng.uniform(-0.1, 0.1),
            ]
        )
    else:
        xy = _inside_point(rng, field, (-hl + INSIDE, -INSIDE))
        new = np.array([xy[0], xy[1], rng.uniform(-0.3, 0.3)])
    plan["from"] = [float(v) for v in pose]
    plan["to"] = [float(v) for v in new]
    return new


def _odometry(
    rng: np.random.Generator, p: dict, body: np.ndarray, walking: np.ndarray, lying: np.ndarray
) -> np.ndarray:
    """The measured increments: scale, turn bias while stepping, a correlated velocity error, white noise."""
    n = body.shape[0]
    rho = math.exp(-DT / p["drift_time"])
    shocks = rng.standard_normal((n, 3)) * (np.asarray(p["drift_sigma"]) * math.sqrt(1.0 - rho * rho))
    drift = np.empty((n, 3))
    state = rng.standard_normal(3) * np.asarray(p["drift_sigma"])
    for k in range(n):  # a first-order recursion (6000 small steps: cheap)
        state = rho * state + shocks[k]
        drift[k] = state
    white = rng.standard_normal((n, 3)) * (p["step_noise"] * np.abs(body) + np.array([5e-5, 5e-5, 1e-4]))
    odometry = body * np.asarray(p["odometry_scale"]) + white
    odometry += walking[:, None] * (drift + np.array([0.0, 0.0, p["turn_bias"]])) * DT
    odometry[lying] = 0.0
    return odometry


def _camera(
    rng: np.random.Generator, field: Field, p: dict, plan: dict, truth: np.ndarray, n_steps: int
) -> tuple[Frame, ...]:
    """Every frame of the run, in arrival order (all frames' detections drawn at once)."""
    duration = n_steps * DT
    interval = 1.0 / p["camera_rate"]
    captures = np.arange(p["camera_phase"] * interval, duration, interval)
    latency = np.clip(
        p["latency"] + rng.uniform(-1.0, 1.0, captures.shape[0]) * p["latency_jitter"], *RANGES["latency"]
    )
    arrivals = captures + latency
    steps = np.ceil(arrivals / DT - 1e-9).astype(np.int64) - 1
    keep = steps < n_steps
    captures, arrivals, steps = captures[keep], arrivals[keep], np.maximum(steps[keep], 0)
    order = np.argsort(arrivals, kind="stable")
    captures, arrivals, steps = captures[order], arrivals[order], steps[order]
    n_frames = captures.shape[0]
    heads = math.radians(p["pan_amplitude_deg"]) * np.sin(2 * math.pi * captures / p["pan_period"] + p["pan_phase"])
    poses = truth[np.clip(np.rint(captures / DT).astype(np.int64), 0, n_steps)]
    burst = np.zeros(n_frames, dtype=bool)
    blind = np.zeros(n_frames, dtype=bool)
    for start, end in plan.get("bursts", ()):
        burst |= (captures >= start) & (captures <= end)
    if plan["type"] == "blackout":
        blind = (captures >= plan["time"]) & (captures <= plan["end"])
    # Landmarks: every frame against every landmark.
    points = np.concatenate([field.landmarks_of(kind) for kind in _KINDS])
    kinds = np.concatenate([np.full(field.landmarks_of(kind).shape[0], int(kind), np.int64) for kind in _KINDS])
    d = points[None, :, :] - poses[:, None, :2]
    r = np.hypot(d[..., 0], d[..., 1])
    bearing = wrap_angles(np.arctan2(d[..., 1], d[..., 0]) - poses[:, 2:3])
    half_fov = 0.5 * math.radians(p["fov_deg"])
    visible = (
        (np.abs(wrap_angles(bearing - heads[:, None])) <= half_fov) & (r >= p["min_range"]) & (r <= p["max_range"])
    )
    chance = p["detection"] * np.where(burst, BURST_KEEP, 1.0)
    detected = visible & (rng.random(r.shape) < chance[:, None]) & ~blind[:, None]
    growth = r if p["range_law"] == "linear" else r * r
    sigma_r = p["range_a"] + p["range_growth"] * growth
    ranges = np.maximum(r + sigma_r * rng.standard_normal(r.shape), 0.0)
    bearings = wrap_angles(bearing + p["bearing_sigma"] * rng.standard_normal(r.shape))
    # False detections: a random type at a random range and bearing inside the view.
    rate = np.where(burst, plan.get("rate", 0.0), p["false_rate"])
    n_false = np.where(blind, 0, rng.poisson(rate))
    total = int(n_false.sum())
    false_kinds = np.asarray([int(k) for k in _KINDS], np.int64)[rng.integers(0, len(_KINDS), total)]
    false_ranges = rng.uniform(p["min_range"], p["max_range"], total)
    owner = np.repeat(np.arange(n_frames), n_false)
    false_bearings = wrap_angles(heads[owner] + rng.uniform(-half_fov, half_fov, total))
    bounds = np.concatenate([[0], np.cumsum(n_false)])
    frames = []
    for i in range(n_frames):
        seen = np.flatnonzero(detected[i])
        a, b = bounds[i], bounds[i + 1]
        observations = Observations.from_arrays(
            np.concatenate([kinds[seen], false_kinds[a:b]]),
            np.concatenate([ranges[i, seen], false_ranges[a:b]]),
            np.concatenate([bearings[i, seen], false_bearings[a:b]]),
        )
        frames.append(
            Frame(
                float(captures[i]),
                float(arrivals[i]),
                int(steps[i]),
                float(heads[i]),
                observations,
                int(seen.shape[0]),
                int(b - a),
            )
        )
    return tuple(frames)


def _calls_and_windows(plan: dict) -> tuple[tuple[Call, ...], tuple[tuple[float, float], ...]]:
    kind = plan["type"]
    if kind == "none":
        return (), ()
    k0, t0 = plan["step"], plan["time"]
    if kind in ("kidnap", "kidnap_special"):
        return (), ((t0, t0),)
    if kind == "penalty":
        return (Call(k0, "penalty_return"),), ((t0, t0),)
    if kind == "manual_placement":
        return (Call(k0, "manual_placement"),), ((t0, t0),)
    if kind in ("stuck", "spun"):
        return (), ((t0, (plan["end_step"] + 1) * DT),)
    if kind == "fall":
        return (Call(k0, "fallen"), Call(plan["end_step"], "got_up")), ((t0, (plan["end_step"] + 1) * DT),)
    if kind == "false_bursts":
        return (), tuple((float(a), float(b)) for a, b in plan["bursts"])
    return (), ((t0, float(plan["end"])),)  # blackout


def simulate(family: str, seed: int, duration: float = 60.0, overrides: dict | None = None) -> BatteryRun:
    """One run of `family` with `seed` (an int >= 0), `duration` seconds long (at least 5 s). `overrides`
    replaces drawn parameters (keys of `params`, e.g. {"odometry_scale": [1.2, 1.2, 1.2]}) after they are
    drawn, so everything else the seed draws stays the same (the team world has its own generator and is not
    overridden)."""
    code = family_code(family)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed = {seed!r} must be an integer >= 0")
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration >= 5.0):
        raise ValueError(f"duration = {duration!r} must be at least 5 s")
    seed = int(seed)
    rng = np.random.default_rng(np.random.SeedSequence([seed, code]))
    field = field_for(seed)
    n_steps = int(round(duration / DT))
    p = _draw_parameters(rng, field)
    unknown = sorted(set(overrides or {}) - set(p))
    if unknown:
        raise ValueError(f"overrides: {', '.join(unknown)} are not drawn parameters; known: {', '.join(p)}")
    p.update(overrides or {})
    start = _start_pose(rng, field, family, seed)
    plan = _plan_event(rng, family, seed, duration, n_steps)
    truth, body, walking, moving = _walk(rng, field, p, plan, start, n_steps)
    lying = np.zeros(n_steps, dtype=bool)
    if plan["type"] == "fall":
        lying[plan["step"] : plan["end_step"] + 1] = True
    odometry = _odometry(rng, p, body, walking, lying)
    if plan["type"] == "stuck":
        steps = slice(plan["step"], plan["end_step"] + 1)
        plan["excess"] = float(math.hypot(odometry[steps, 0].sum(), odometry[steps, 1].sum()))
    frames = _camera(rng, field, p, plan, truth, n_steps)
    calls, windows = _calls_and_windows(plan)
    # The team world last, from a generator of its own: the run above is the same with or without it.
    team_rng = np.random.default_rng(np.random.SeedSequence([seed, code, TEAM_STREAM]))
    team = simulate_team(
        team_rng,
        field,
        DT,
        truth,
        frames,
        p["fov_deg"],
        teammates=(2, 4) if family == "kidnap_even_wrong" else (1, 4),
        messages_on=family in ("kidnap_even_team", "kidnap_even_wrong"),
        wrong=family == "kidnap_even_wrong",
        kidnap_time=plan.get("time"),
        blind=(plan["time"], plan["end"]) if plan["type"] == "blackout" else None,
    )
    params = {
        "family": family,
        "seed": seed,
        "field": field.name,
        "duration": n_steps * DT,
        "start": [float(v) for v in start],
        **p,
        "event": plan,
        "team": team.params,
    }
    return BatteryRun(
        family,
        seed,
        field,
        DT,
        (np.arange(n_steps) + 1) * DT,
        start,
        truth[1:],
        body,
        odometry,
        walking,
        moving,
        frames,
        calls,
        windows,
        params,
        team.ball,
        team.ball_detections,
        team.messages,
        team,
    )


def as_robot_log(run: BatteryRun) -> RobotLog:
    """The run as a robot would log it (`mcl.tools.logs.RobotLog`): the odometry as cumulative poses in the odom
    frame (one message per step, starting at t = 0), each camera frame with its capture stamp and arrival time,
    and the truth per step. Game events (`run.calls`) are not part of a log: a replay starts anywhere in the own
    half, as the battery does, and knows nothing of them."""
    n = run.odometry.shape[0]
    poses = np.zeros((n + 1, 3))
    x = y = theta = 0.0
    for k, (dx, dy, dtheta) in enumerate(run.odometry.tolist()):
        c, s = math.cos(theta), math.sin(theta)
        x, y, theta = x + c * dx - s * dy, y + s * dx + c * dy, theta + dtheta
        poses[k + 1] = (x, y, theta)
    poses[:, 2] = wrap_angles(poses[:, 2])
    times = np.concatenate([[0.0], run.times])
    vision = tuple(VisionFrame(f.capture_time, f.arrival_time, f.observations) for f in run.frames)
    return RobotLog(odometry_times=times, odometry=poses, vision=vision, truth_times=run.times, truth=run.truth)
