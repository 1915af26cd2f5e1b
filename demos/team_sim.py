"""The battery's team world: a ball that rolls, the robot's own sightings of it, and teammates that walk, see
it, and broadcast what they believe — simulated independently of the filter, like `demos.battery_sim`.

    from demos.battery_sim import simulate
    run = simulate("kidnap_even_wrong", seed=3, duration=60.0)
    run.ball                       # (T, 2) the ball's truth after each motion step
    run.ball_detections            # per camera frame (aligned with run.frames): sensing.team.BallDetection or None
    run.messages                   # ((arrival_step, TeamMessage), ...) sorted by arrival: feed each after that step
    run.team                       # TeamWorld: the teammates' truth, every message sent (lost ones too), ...
    run.params["team"]             # every number drawn here (JSON-ready)

`demos.battery_sim.simulate` calls `simulate_team` after the rest of the run is simulated, with a generator of
its own, seeded by (seed, family code, 7): the robot's walk, odometry and camera are the same with or without
the team world, bit for bit. Nothing here comes from the filter (`mcl.side`, the localizer's settings): the
ranges below are this simulator's own, wider than a filter assumes; the filter gets no noise figures.

The world, at the motion rate (dt):
- the ball starts on the centre mark and rolls with a friction deceleration (`BALL["deceleration"]`, per run).
  Unseen players kick it at random times (a Poisson rate per run, any direction); the robot kicks it when its
  feet are within `KICK_REACH` of a slow ball (a rate per run, along its heading), teammates likewise (toward
  the opponent goal). A kick's speed is uniform in `KICK_SPEED`. A ball over a touchline or a goal line outside
  the posts is placed on that line where it crossed it (throw-in, goal kick: the game puts it back in, and here
  it stays on the line, at rest); a ball over a goal line between the posts is a goal: back to the centre mark.
  Players do not block the ball: it rolls through them;
- the robot's ball detections: in each camera frame, the ball is seen when it lies inside the frame's view (the
  run's field of view around the head's pan) and within the ball's own range (`BALL_CAMERA`), with a detection
  probability, a range scale error, range noise σ = a + b·r and bearing noise, all drawn per run; a share of
  frames (0–5 %) shows a false ball somewhere in the view instead; no ball during a blackout;
- teammates (1–4, or 2–4 with a wrong one): field players walk toward the ball (the nearest of them) or toward
  their home position pulled toward the ball; a goalkeeper (drawn) stays near its own goal (x near
  −half_length) and only leaves it for a ball close by. Each has a speed limit, a localization error (a slowly
  varying bias, an Ornstein–Uhlenbeck process, plus white noise; magnitudes drawn per teammate), a ball range
  and noise of its own, and looks for the ball at 10 Hz (in any direction: it turns its head; seen with a
  probability of its own when within its range). Wherever it walks, it never leaves the field;
- messages: each teammate sends at an irregular 1–5 Hz (its own rate, each interval jittered by ±50 %): its pose
  estimate, a stated uncertainty — a covariance or a confidence (drawn per teammate), its scale off the true
  error by a factor of 0.3–3 (over- or under-confident) — whether it is the goalkeeper, its last ball estimate
  (placed through its pose estimate at that sighting; with a velocity for some), and the sighting's age; no
  ball when it never saw it or longer ago than its `max_age`. A share of messages (0–60 % per run) is lost;
  each takes 0–`latency_max` s to arrive (`latency_max` 0–0.5 s per run), so some arrive out of order. In some runs each teammate's clock is
  off by a constant that the message states (`clock_offset`); `received_time` is on the robot's clock;
- a wrong teammate (`wrong=True`): for 10–40 s around the kidnapping, one teammate believes the point mirror of
  its pose, (x, y, θ) → (−x, −y, θ + π), and says so with high confidence; its ball reports land at the point
  image of where it sees the ball (the interval is clipped to the run, so it may be shorter at its ends).

`Ball` is the ball's physics alone (for a hand-made case: place it, kick it, step it).

A message sent at time t arrives at t + latency; it is delivered after the first motion step k whose end
times[k] = (k + 1)·dt is not before that, like a camera frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from field import Field
from field.angles import wrap_angles
from sensing.team import BallDetection, TeamMessage

# The ranges the team world draws from (uniform unless said otherwise); see the module docstring.
BALL = {
    "deceleration": (0.3, 1.5),  # m/s², the rolling friction
    "kick_rate": (0.03, 0.2),  # kicks per second by unseen players (opponents, the referee's drop)
    "robot_kick_rate": (0.3, 2.0),  # per second while the robot's feet are at a slow ball
}
KICK_SPEED = (0.5, 4.0)  # m/s, per kick
KICK_REACH = 0.25  # m, feet to ball centre for a kick
KICKABLE = 0.5  # m/s, a ball faster than this is not kicked by a player
KICK_COOLDOWN = 1.0  # s between two kicks of one player
TEAMMATE_KICK_RATE = 1.0  # per second while a teammate's feet are at a slow ball
BALL_CAMERA = {
    "range": (3.0, 7.0),  # m, the farthest the robot's camera finds the ball
    "min_range": (0.1, 0.3),  # m, closer is below the image
    "detection": (0.5, 0.98),  # probability per frame with the ball in view and range
    "range_scale": (0.9, 1.1),  # measured range = scale · true range + noise (a camera pitch error)
    "range_a": (0.02, 0.2),  # m
    "range_b": (0.03, 0.15),  # σ_r = a + b·r
    "bearing_sigma": (0.01, 0.1),  # rad
    "false_rate": (0.0, 0.05),  # share of frames with a false ball
}
TEAMMATES = (1, 4)  # how many (a run with a wrong teammate: at least 2)
GOALKEEPER_CHANCE = 0.5  # that one of them is the goalkeeper
PLAYER_NUMBERS = (1, 6)
TEAMMATE = {
    "speed": (0.15, 0.4),  # m/s
    "turn": (0.6, 1.2),  # rad/s
    "ball_range": (2.5, 6.0),  # m
    "see": (0.4, 0.95),  # probability per look at a ball in range
    "range_sigma": (0.05, 0.4),  # m, its ball range noise (plus 10 % of the range)
    "bearing_sigma": (0.02, 0.15),  # rad
    "bias_position": (0.02, 0.4),  # m, stationary σ of its pose bias (x and y)
    "bias_heading": (0.01, 0.2),  # rad
    "bias_time": (2.0, 15.0),  # s, the bias's correlation time
    "noise_share": (0.1, 0.5),  # white noise σ as a share of the bias σ
    "stated_scale": (0.3, 3.0),  # stated σ / true σ (log-uniform)
    "rate": (1.0, 5.0),  # Hz, messages
    "max_age": (2.0, 5.0),  # s, an older sighting is not reported
    "velocity_sigma": (0.1, 0.6),  # m/s, its ball velocity estimate's noise (when it reports one)
}
VELOCITY_CHANCE = 0.5  # that a teammate reports a ball velocity
COVARIANCE_CHANCE = 0.5  # that a teammate states a covariance (else a confidence)
LOSS = (0.0, 0.6)  # share of messages lost, per run
LATENCY = (0.0, 0.5)  # s, each message's latency is uniform in [0, latency_max], per run
CLOCK_OFFSET_CHANCE = 0.3  # runs whose teammates' clocks are off by a constant
CLOCK_OFFSET = 100.0  # s, ± that constant, per teammate
WRONG_SECONDS = (10.0, 40.0)  # the wrong teammate's interval, which covers the kidnapping
WRONG_SIGMA = {"position": (0.03, 0.1), "heading": (0.02, 0.06), "confidence": (0.9, 1.0)}
LOOK_STEPS = 10  # motion steps between two looks of a teammate for the ball (10 Hz)
GOALKEEPER_DEPTH = (0.3, 0.8)  # m in front of its goal line
GOALKEEPER_RUSH = 1.2  # m, a ball this close to its spot draws the goalkeeper out


@dataclass(frozen=True)
class SentMessage:
    """One message as sent, with what the robot never sees: when it was sent and arrives (robot's clock), the
    motion step after which it is delivered (`n_steps` or more: after the run), whether it is lost, whether
    the sender was wrong (mirrored) then, its true pose, and the true ball at its reported sighting."""

    message: TeamMessage
    send_time: float
    arrival_time: float
    arrival_step: int
    lost: bool
    wrong: bool
    true_pose: tuple[float, float, float]
    true_ball: tuple[float, float] | None


def deliveries(sent, n_steps: int) -> tuple:
    """The (arrival step, TeamMessage) deliveries of the messages `sent` that are not lost and arrive within the
    run's `n_steps` steps, in the order they arrive (step, then time, then sender)."""
    kept = sorted(
        (s for s in sent if not s.lost and s.arrival_step < n_steps),
        key=lambda s: (s.arrival_step, s.arrival_time, s.message.sender),
    )
    return tuple((s.arrival_step, s.message) for s in kept)


@dataclass(frozen=True)
class TeamWorld:
    """The simulated team world of one run (see the module docstring). Arrays per motion step k (the end of step
    k, like the run's truth): `ball` (T, 2) and `ball_velocity` (T, 2); `teammates` (n, T, 3) their true poses,
    numbered `numbers`; `ball_detections` aligned with the run's frames and `ball_false` (n_frames,) whether
    that frame's detection is a false ball; `sent` every message in send order; `messages` the delivered ones,
    (arrival_step, TeamMessage) sorted by arrival step and time (empty when messages are off); `goals` the times
    [s] of the goals; `params` every drawn number (JSON-ready)."""

    ball: np.ndarray
    ball_velocity: np.ndarray
    ball_detections: tuple
    ball_false: np.ndarray
    numbers: tuple[int, ...]
    goalkeeper: int | None
    teammates: np.ndarray
    sent: tuple[SentMessage, ...]
    messages: tuple
    goals: tuple[float, ...]
    params: dict


class Ball:
    """The ball on `field`: rolls with a constant friction `deceleration` [m/s²], is put back on a line it rolls
    over, and on the centre mark after a goal. `step(dt)` moves it and says what happened."""

    def __init__(self, field: Field, deceleration: float, position=(0.0, 0.0)) -> None:
        self.field = field
        self.deceleration = float(deceleration)
        self.position = np.array(position, dtype=np.float64)
        self.velocity = np.zeros(2)

    @property
    def speed(self) -> float:
        return math.hypot(self.velocity[0], self.velocity[1])

    def kick(self, speed: float, direction: float) -> None:
        """Set it rolling at `speed` [m/s] toward `direction` [rad] (a kick replaces any motion)."""
        self.velocity = speed * np.array([math.cos(direction), math.sin(direction)])

    def step(self, dt: float) -> str | None:
        """Roll for `dt` seconds; "goal" (now on the centre mark), "out" (now on the line, at rest) or None."""
        speed = self.speed
        if speed == 0.0:
            return None
        new_speed = max(speed - self.deceleration * dt, 0.0)
        old = self.position.copy()
        # Constant deceleration: the distance covered is the mean of the two speeds times dt.
        self.position = old + self.velocity * (0.5 * (speed + new_speed) / speed * dt)
        self.velocity = self.velocity * (new_speed / speed)
        hl, hw = self.field.half_length, self.field.half_width
        x, y = self.position
        if abs(x) > hl:
            # Where it crossed the goal line (the crossing point along this step's straight path).
            edge = math.copysign(hl, x)
            share = (edge - old[0]) / (x - old[0])
            y_cross = old[1] + share * (y - old[1])
            if abs(y_cross) < 0.5 * self.field.dims.goal_inner_width:
                self.position = np.zeros(2)
                self.velocity = np.zeros(2)
                return "goal"
            self.position = np.array([edge, min(max(y_cross, -hw), hw)])
            self.velocity = np.zeros(2)
            return "out"
        if abs(y) > hw:
            edge = math.copysign(hw, y)
            share = (edge - old[1]) / (y - old[1])
            self.position = np.array([old[0] + share * (x - old[0]), edge])
            self.velocity = np.zeros(2)
            return "out"
        return None


def _u(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    return float(rng.uniform(*bounds))


def _draw_teammates(rng: np.random.Generator, field: Field, count: int, wrong: bool) -> tuple[int, list[dict]]:
    """The robot's number and each teammate's parameters, in a fixed drawing order."""
    lo, hi = PLAYER_NUMBERS
    numbers = [int(v) for v in rng.permutation(np.arange(lo, hi + 1))[: count + 1]]
    own = numbers[0]
    keeper = rng.random() < GOALKEEPER_CHANCE
    hl, hw = field.half_length, field.half_width
    mates = []
    for i in range(count):
        m: dict[str, Any] = {
            key: _u(rng, TEAMMATE[key])
            for key in (
                "speed",
                "turn",
                "ball_range",
                "see",
                "range_sigma",
                "bearing_sigma",
                "bias_position",
                "bias_heading",
                "bias_time",
                "noise_share",
                "rate",
                "max_age",
                "velocity_sigma",
            )
        }
        lo_s, hi_s = TEAMMATE["stated_scale"]
        m["stated_scale"] = float(math.exp(rng.uniform(math.log(lo_s), math.log(hi_s))))
        m["states"] = "covariance" if rng.random() < COVARIANCE_CHANCE else "confidence"
        m["reports_velocity"] = bool(rng.random() < VELOCITY_CHANCE)
        m["goalkeeper"] = bool(keeper and i == 0)
        m["wrong"] = False
        if m["goalkeeper"]:
            m["home"] = [-hl + _u(rng, GOALKEEPER_DEPTH), 0.0]
        else:
            m["home"] = [float(rng.uniform(-0.8 * hl, 0.3 * hl)), float(rng.uniform(-0.7 * hw, 0.7 * hw))]
        m["number"] = numbers[i + 1]
        mates.append(m)
    # The goalkeeper wears number 1 when the robot does not.
    if keeper and own != 1:
        holder = next((m for m in mates if m["number"] == 1), None)
        if holder is not None:
            holder["number"] = mates[0]["number"]
        mates[0]["number"] = 1
    if wrong:
        mates[int(rng.integers(0, count))]["wrong"] = True
    return own, mates


def _play(
    rng: np.random.Generator, field: Field, dt: float, robot: np.ndarray, mates: list[dict], ball_params: dict
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[float], dict]:
    """The ball and the teammates, step by step (they interact through kicks): ball (T + 1, 2), its velocity
    (T + 1, 2), teammates (n, T + 1, 3) with the start at index 0; the goals' times; kick and out counts."""
    n_steps = robot.shape[0] - 1
    n = len(mates)
    hl, hw = field.half_length, field.half_width
    goal_half = 0.5 * field.dims.goal_inner_width
    ball = Ball(field, ball_params["deceleration"])
    balls = np.zeros((n_steps + 1, 2))
    velocities = np.zeros((n_steps + 1, 2))
    poses = np.zeros((n, n_steps + 1, 3))
    state = []
    for i, m in enumerate(mates):
        home = np.asarray(m["home"])
        xy = home if m["goalkeeper"] else home + rng.uniform(-0.5, 0.5, 2)
        xy = np.clip(xy, [-hl + 0.1, -hw + 0.1], [hl - 0.1, hw - 0.1])
        state.append([float(xy[0]), float(xy[1]), float(rng.uniform(-0.5, 0.5))])
        poses[i, 0] = state[i]
    # The random numbers of the step loop, drawn at once: the unseen kicks and each player's chance to kick.
    chances = rng.random((n_steps, n + 2))
    cooldown = [0.0] * (n + 1)  # the robot, then each teammate
    goals: list[float] = []
    counts = {"kicks": 0, "outs": 0}
    field_players = [i for i, m in enumerate(mates) if not m["goalkeeper"]]
    for k in range(n_steps):
        t = (k + 1) * dt
        bx, by = float(ball.position[0]), float(ball.position[1])
        # Who walks to the ball: the field player nearest to it; the others hold their position.
        striker = min(field_players, key=lambda i: (state[i][0] - bx) ** 2 + (state[i][1] - by) ** 2, default=None)
        for i, m in enumerate(mates):
            x, y, theta = state[i]
            if m["goalkeeper"]:
                spot = (m["home"][0], max(-goal_half, min(goal_half, 0.5 * by)))
                near = math.hypot(bx - spot[0], by - spot[1]) < GOALKEEPER_RUSH
                target = (bx, by) if near else spot
            elif i == striker:
                target = (bx, by)
            else:
                hx, hy = m["home"]
                target = (hx + 0.3 * (bx - hx), hy + 0.3 * (by - hy))
            dx, dy = target[0] - x, target[1] - y
            distance = math.hypot(dx, dy)
            # Toward the target while far, else face the ball; forward speed falls off with the heading error.
            aim = math.atan2(dy, dx) if distance > 0.15 else math.atan2(by - y, bx - x)
            error = math.remainder(aim - theta, 2 * math.pi)
            omega = max(-m["turn"], min(m["turn"], 2.0 * error))
            v = min(m["speed"], distance) * max(0.0, math.cos(error)) ** 2 if distance > 0.15 else 0.0
            x = min(max(x + v * math.cos(theta) * dt, -hl), hl)
            y = min(max(y + v * math.sin(theta) * dt, -hw), hw)
            state[i] = [x, y, math.remainder(theta + omega * dt, 2 * math.pi)]
            poses[i, k + 1] = state[i]
        # Kicks: unseen players at any time; the robot and the teammates when their feet are at a slow ball.
        if chances[k, 0] < ball_params["kick_rate"] * dt:
            ball.kick(_u(rng, KICK_SPEED), float(rng.uniform(-math.pi, math.pi)))
            counts["kicks"] += 1
        elif ball.speed < KICKABLE:
            players: list[tuple[Any, float, dict | None]] = [(robot[k + 1], ball_params["robot_kick_rate"], None)]
            players += [(state[i], TEAMMATE_KICK_RATE, m) for i, m in enumerate(mates)]
            for j, (pose, rate, mate) in enumerate(players):
                if (
                    t < cooldown[j]
                    or chances[k, j + 1] >= rate * dt
                    or math.hypot(pose[0] - bx, pose[1] - by) > KICK_REACH
                ):
                    continue
                if mate is None:  # the robot: along its heading
                    direction = float(pose[2]) + float(rng.uniform(-0.3, 0.3))
                else:  # a teammate: toward the opponent goal
                    spread = 0.8 if mate["goalkeeper"] else 0.4
                    direction = math.atan2(-by, hl - bx) + float(rng.uniform(-spread, spread))
                ball.kick(_u(rng, KICK_SPEED), direction)
                cooldown[j] = t + KICK_COOLDOWN
                counts["kicks"] += 1
                break
        event = ball.step(dt)
        if event == "goal":
            goals.append(t)
        elif event == "out":
            counts["outs"] += 1
        balls[k + 1] = ball.position
        velocities[k + 1] = ball.velocity
    return balls, velocities, poses, goals, counts


def _robot_ball(
    rng: np.random.Generator,
    dt: float,
    robot: np.ndarray,
    balls: np.ndarray,
    frames,
    fov_deg: float,
    blind: tuple[float, float] | None,
) -> tuple[tuple, np.ndarray, dict]:
    """The robot's ball detection in each frame (all frames at once), whether it is a false ball, the drawn
    camera parameters."""
    c = {key: _u(rng, bounds) for key, bounds in BALL_CAMERA.items()}
    n_frames = len(frames)
    n_steps = robot.shape[0] - 1
    captures = np.array([f.capture_time for f in frames], dtype=np.float64)
    heads = np.array([f.head for f in frames], dtype=np.float64)
    index = np.clip(np.rint(captures / dt).astype(np.int64), 0, n_steps)
    poses, points = robot[index], balls[index]
    d = points - poses[:, :2]
    r = np.hypot(d[:, 0], d[:, 1])
    bearing = wrap_angles(np.arctan2(d[:, 1], d[:, 0]) - poses[:, 2])
    half_fov = 0.5 * math.radians(fov_deg)
    visible = (np.abs(wrap_angles(bearing - heads)) <= half_fov) & (r >= c["min_range"]) & (r <= c["range"])
    seen = visible & (rng.random(n_frames) < c["detection"])
    ranges = np.maximum(c["range_scale"] * r + (c["range_a"] + c["range_b"] * r) * rng.standard_normal(n_frames), 0.0)
    bearings = wrap_angles(bearing + c["bearing_sigma"] * rng.standard_normal(n_frames))
    # A false ball (a robot's foot, a white spot) replaces the frame's detection, somewhere in the view.
    false = rng.random(n_frames) < c["false_rate"]
    false_ranges = rng.uniform(c["min_range"], c["range"], n_frames)
    false_bearings = wrap_angles(heads + rng.uniform(-half_fov, half_fov, n_frames))
    if blind is not None:
        dark = (captures >= blind[0]) & (captures <= blind[1])
        seen &= ~dark
        false &= ~dark
    detections: list[BallDetection | None] = []
    for i in range(n_frames):
        if false[i]:
            detections.append(BallDetection(float(false_ranges[i]), float(false_bearings[i])))
        elif seen[i]:
            detections.append(BallDetection(float(ranges[i]), float(bearings[i])))
        else:
            detections.append(None)
    return tuple(detections), false, c


def _pose_errors(rng: np.random.Generator, m: dict, n_looks: int, look_dt: float) -> np.ndarray:
    """A teammate's localization error (n_looks, 3) at its looks: an Ornstein–Uhlenbeck bias plus white noise."""
    sigma = np.array([m["bias_position"], m["bias_position"], m["bias_heading"]])
    rho = math.exp(-look_dt / m["bias_time"])
    shocks = rng.standard_normal((n_looks, 3)) * sigma * math.sqrt(1.0 - rho * rho)
    bias = np.empty((n_looks, 3))
    state = rng.standard_normal(3) * sigma
    for g in range(n_looks):
        state = rho * state + shocks[g]
        bias[g] = state
    return bias + rng.standard_normal((n_looks, 3)) * sigma * m["noise_share"]


def _messages(
    rng: np.random.Generator,
    dt: float,
    duration: float,
    n_steps: int,
    balls: np.ndarray,
    velocities: np.ndarray,
    poses: np.ndarray,
    mates: list[dict],
    comm: dict,
    wrong_interval: tuple[float, float] | None,
) -> list[SentMessage]:
    """Every teammate's looks for the ball and messages; the messages in send order (all teammates)."""
    look_dt = LOOK_STEPS * dt
    looks = np.arange(0, n_steps + 1, LOOK_STEPS)  # indices into the (T + 1) arrays
    look_times = looks * dt
    n_looks = looks.shape[0]
    sent: list[SentMessage] = []
    for i, m in enumerate(mates):
        truth = poses[i, looks]
        error = _pose_errors(rng, m, n_looks, look_dt)
        believed = truth + error
        wrong = np.zeros(n_looks, dtype=bool)
        if m.get("wrong") and wrong_interval is not None:
            wrong = (look_times >= wrong_interval[0]) & (look_times <= wrong_interval[1])
            # The point mirror of its truth, off by a small share of its error (it is sure of itself).
            believed[wrong] = (
                np.column_stack([-truth[wrong, :2], truth[wrong, 2:] + math.pi]) + error[wrong] * m["noise_share"]
            )
        believed[:, 2] = wrap_angles(believed[:, 2])
        # Its looks for the ball, placed on the field through what it believes.
        d = balls[looks] - truth[:, :2]
        r = np.hypot(d[:, 0], d[:, 1])
        seen = (r <= m["ball_range"]) & (rng.random(n_looks) < m["see"])
        bearing = np.arctan2(d[:, 1], d[:, 0]) - truth[:, 2]
        r_m = np.maximum(r + (m["range_sigma"] + 0.1 * r) * rng.standard_normal(n_looks), 0.0)
        b_m = bearing + m["bearing_sigma"] * rng.standard_normal(n_looks)
        angle = believed[:, 2] + b_m
        ball_est = believed[:, :2] + r_m[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
        # Its velocity estimate turns with its heading error (a mirrored teammate reports it reversed).
        turn = believed[:, 2] - truth[:, 2]
        v = velocities[looks]
        c, s = np.cos(turn), np.sin(turn)
        velocity_est = np.column_stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1]]) + m[
            "velocity_sigma"
        ] * rng.standard_normal((n_looks, 2))
        last = np.maximum.accumulate(np.where(seen, np.arange(n_looks), -1))
        # What it says about its own error: the true σ scaled by its over- or under-confidence.
        true_position = m["bias_position"] * math.hypot(1.0, m["noise_share"])
        true_heading = m["bias_heading"] * math.hypot(1.0, m["noise_share"])
        # When it sends: an irregular rate, each interval jittered by ±50 %.
        interval = 1.0 / m["rate"]
        count = int(duration / (0.5 * interval)) + 2
        times = float(rng.uniform(0.0, interval)) + np.concatenate(
            [[0.0], np.cumsum(interval * rng.uniform(0.5, 1.5, count))]
        )
        times = times[times < duration]
        lost = rng.random(times.shape[0]) < comm["loss"]
        latency = rng.uniform(0.0, comm["latency_max"], times.shape[0])
        jitter = np.exp(0.2 * rng.standard_normal(times.shape[0]))  # its stated σ wanders a little
        # What it states while wrong (sure of itself), per message.
        wrong_position, wrong_heading, wrong_confidence = (
            np.asarray(rng.uniform(WRONG_SIGMA[key][0], WRONG_SIGMA[key][1], times.shape[0]))
            for key in ("position", "heading", "confidence")
        )
        for j, t in enumerate(times.tolist()):
            g = min(int(t / look_dt + 1e-9), n_looks - 1)  # its last look at or before t
            step = min(int(round(t / dt)), n_steps)
            pose_truth = poses[i, step]
            # Its pose now: the truth now, off by its error at its last look (mirrored when wrong then).
            if wrong[g]:
                pose = np.array([-pose_truth[0], -pose_truth[1], pose_truth[2] + math.pi]) + error[g] * m["noise_share"]
                sp, sh = float(wrong_position[j]), float(wrong_heading[j])
                confidence = float(wrong_confidence[j])
            else:
                pose = pose_truth + error[g]
                sp = max(true_position * m["stated_scale"] * float(jitter[j]), 0.01)
                sh = max(true_heading * m["stated_scale"] * float(jitter[j]), 0.005)
                # The message's own reading of a confidence (sensing.team.TeamMessage.pose_sigmas), inverted.
                confidence = min(max((2.0 - sp) / 1.95, 0.0), 1.0)
            covariance = np.diag([sp * sp, sp * sp, sh * sh]) if m["states"] == "covariance" else None
            h = int(last[g])
            age = max(t - float(look_times[h]), 0.0) if h >= 0 else math.inf
            has_ball = age <= m["max_age"]
            offset = m["clock_offset"]
            message = TeamMessage(
                sender=m["number"],
                time=t - offset,
                pose=(float(pose[0]), float(pose[1]), float(pose[2])),
                pose_covariance=covariance,
                confidence=None if covariance is not None else confidence,
                is_goalkeeper=m["goalkeeper"],
                ball=(float(ball_est[h, 0]), float(ball_est[h, 1])) if has_ball else None,
                ball_velocity=(
                    (float(velocity_est[h, 0]), float(velocity_est[h, 1]))
                    if has_ball and m["reports_velocity"]
                    else None
                ),
                ball_age=float(age) if has_ball else 0.0,
                clock_offset=offset,
            )
            arrival = t + float(latency[j])
            arrival_step = max(int(math.ceil(arrival / dt - 1e-9)) - 1, 0)
            true_ball = balls[looks[h]] if has_ball else None
            sent.append(
                SentMessage(
                    message,
                    t,
                    arrival,
                    arrival_step,
                    bool(lost[j]),
                    bool(wrong[g]),
                    (float(pose_truth[0]), float(pose_truth[1]), float(pose_truth[2])),
                    None if true_ball is None else (float(true_ball[0]), float(true_ball[1])),
                )
            )
    sent.sort(key=lambda s: (s.send_time, s.message.sender))
    return sent


def simulate_team(
    rng: np.random.Generator,
    field: Field,
    dt: float,
    robot: np.ndarray,
    frames,
    fov_deg: float,
    teammates: tuple[int, int] = TEAMMATES,
    messages_on: bool = True,
    wrong: bool = False,
    kidnap_time: float | None = None,
    blind: tuple[float, float] | None = None,
) -> TeamWorld:
    """The team world of one run, drawn from `rng` alone.

    Parameters
    ----------
    rng : numpy.random.Generator
        The team world's own generator (the battery seeds it by (seed, family code, 7)).
    field : field.Field
    dt : float
        The motion step [s].
    robot : numpy.ndarray
        (T + 1, 3) the robot's true poses, the start at index 0 (step k ends at index k + 1).
    frames : sequence
        The run's camera frames (each with `capture_time` and `head`), in arrival order.
    fov_deg : float
        The camera's horizontal field of view.
    teammates : (int, int)
        How many teammates, drawn uniformly from this range (inclusive).
    messages_on : bool
        False: the messages are simulated (`sent`) but none is delivered.
    wrong : bool
        One teammate believes its mirror pose for 10–40 s covering `kidnap_time` (which must then be given).
    kidnap_time : float or None
        When the robot was kidnapped [s].
    blind : (float, float) or None
        A time interval in which the camera sees nothing (a blackout).
    """
    n_steps = robot.shape[0] - 1
    duration = n_steps * dt
    # The drawing order is fixed: ball, teammates, their communication, the wrong interval, then the play.
    ball_params = {key: _u(rng, bounds) for key, bounds in BALL.items()}
    count = int(rng.integers(max(teammates[0], 2 if wrong else 1), teammates[1] + 1))
    own, mates = _draw_teammates(rng, field, count, wrong)
    comm = {
        "loss": _u(rng, LOSS),
        "latency_max": _u(rng, LATENCY),
        "clock_offsets": bool(rng.random() < CLOCK_OFFSET_CHANCE),
    }
    for m in mates:
        m["clock_offset"] = float(rng.uniform(-CLOCK_OFFSET, CLOCK_OFFSET)) if comm["clock_offsets"] else 0.0
    wrong_interval = None
    if wrong:
        if kidnap_time is None:
            raise ValueError("a wrong teammate needs the kidnapping's time")
        length = _u(rng, WRONG_SECONDS)
        begin = max(kidnap_time - float(rng.uniform(0.2, 0.8)) * length, 0.0)
        wrong_interval = (begin, min(begin + length, duration))
    balls, velocities, poses, goals, counts = _play(rng, field, dt, robot, mates, ball_params)
    detections, ball_false, camera = _robot_ball(rng, dt, robot, balls, frames, fov_deg, blind)
    sent = _messages(rng, dt, duration, n_steps, balls, velocities, poses, mates, comm, wrong_interval)
    delivered = deliveries(sent, n_steps) if messages_on else ()
    keeper = next((m["number"] for m in mates if m["goalkeeper"]), None)
    params = {
        "messages_on": bool(messages_on),
        "own_number": own,
        "ball": ball_params,
        "ball_camera": camera,
        **comm,
        "teammates": mates,
        "wrong": None
        if wrong_interval is None
        else {
            "number": next(m["number"] for m in mates if m.get("wrong")),
            "start": float(wrong_interval[0]),
            "end": float(wrong_interval[1]),
        },
        "goals": [float(t) for t in goals],
        **counts,
        "sent": len(sent),
        "delivered": len(delivered),
    }
    return TeamWorld(
        balls[1:],
        velocities[1:],
        detections,
        ball_false,
        tuple(m["number"] for m in mates),
        keeper,
        poses[:, 1:],
        tuple(sent),
        delivered,
        tuple(goals),
        params,
    )
