"""The battery's team world (`demos.team_sim`): a ball, the robot's sightings of it, teammates' messages, and the
even-kidnapping families; and the old families' runs unchanged by it."""

import hashlib
import json
import math

import numpy as np
import pytest

from demos.battery_sim import EVEN_FAMILIES, FAMILIES, KIDNAP_DISTANCE, kidnap_mirror_log_odds, simulate
from demos.team_sim import BALL_CAMERA, WRONG_SECONDS, Ball
from field.angles import wrap_angles
from sensing.team import BallDetection, TeamMessage


def run_hash(run):
    """sha256 of everything the battery simulated before the team world existed (params without "team")."""
    h = hashlib.sha256()
    for name in ("times", "start", "truth", "body", "odometry", "walking", "moving"):
        h.update(np.ascontiguousarray(getattr(run, name)).tobytes())
    for f in run.frames:
        h.update(np.array([f.capture_time, f.arrival_time, f.head, f.arrival_step, f.real, f.false]).tobytes())
        for name in ("kinds", "ranges", "bearings"):
            h.update(np.ascontiguousarray(getattr(f.observations, name)).tobytes())
    h.update(repr(run.calls).encode())
    h.update(repr(run.windows).encode())
    params = {k: v for k, v in run.params.items() if k != "team"}
    h.update(json.dumps(params, sort_keys=True).encode())
    return h.hexdigest()


# Recorded with the simulator as it was before the team world was added (20 s runs).
OLD_RUNS = {
    ("tracking", 0): "2826fff28205b95f3d08b9d917a2c33428141be3b33255ce821eecdd48d09682",
    ("kidnap", 1): "8307b808339bc940838206408e99d0c3de8c66b09ccd98edd5bd8e1605a108c3",
    ("fall", 1): "f05a9318c7d7a3042d2016275ab99e099e34f08c7560ae5fdf8e3b83d334ceb6",
    ("false_bursts", 2): "3cecd437cb02967b0f443036d7cbad44df5166a2e2f5a0facac8666ba018c17c",
}


def message_key(message):
    """A message as plain values (its covariance is an array, which == cannot compare)."""
    cov = message.pose_covariance
    return (
        message.sender,
        message.time,
        message.pose,
        None if cov is None else cov.tolist(),
        message.confidence,
        message.is_goalkeeper,
        message.ball,
        message.ball_velocity,
        message.ball_age,
        message.clock_offset,
    )


def test_old_families_keep_their_codes_and_runs():
    assert FAMILIES[:9] == (
        "tracking",
        "kidnap",
        "kidnap_special",
        "kidnap_announced",
        "collision",
        "fall",
        "false_bursts",
        "blackout",
        "start_unknown",
    )
    assert FAMILIES[9:] == EVEN_FAMILIES
    for (family, seed), expected in OLD_RUNS.items():
        run = simulate(family, seed, 20.0)
        assert run_hash(run) == expected, (family, seed)
        # the team world is simulated, but says nothing
        team = run.params["team"]
        assert team["messages_on"] is False and run.messages == () and team["delivered"] == 0
        assert team["sent"] > 0 and len(run.team.sent) == team["sent"]
        assert len(run.ball_detections) == len(run.frames) and run.ball.shape == (run.truth.shape[0], 2)


def test_same_seed_same_team_world_bit_for_bit():
    a, b = simulate("kidnap_even_wrong", 3, 20.0), simulate("kidnap_even_wrong", 3, 20.0)
    assert np.array_equal(a.ball, b.ball) and np.array_equal(a.team.teammates, b.team.teammates)
    assert a.params == b.params
    assert a.ball_detections == b.ball_detections
    assert [(k, message_key(m)) for k, m in a.messages] == [(k, message_key(m)) for k, m in b.messages]
    json.dumps(a.params)  # JSON-ready
    c = simulate("kidnap_even_wrong", 4, 20.0)
    assert not np.array_equal(a.ball, c.ball)


@pytest.mark.parametrize("family", EVEN_FAMILIES)
def test_even_kidnappings_are_even(family):
    for seed in range(3):
        run = simulate(family, seed, 30.0)
        event = run.params["event"]
        assert event["type"] == "kidnap" and event["even"] is True
        odds = kidnap_mirror_log_odds(run.field, event)
        assert abs(odds) < math.log(2.0)
        k = event["step"]
        # (from: the pose after step k's own walking, then the jump)
        assert np.allclose(run.truth[k - 1], event["from"], atol=0.01)
        assert np.allclose(run.truth[k, :2], event["to"][:2])
        jump = float(np.hypot(*(run.truth[k, :2] - run.truth[k - 1, :2])))
        assert KIDNAP_DISTANCE[0] - 0.01 <= jump <= KIDNAP_DISTANCE[1] + 0.01
        assert np.abs(run.odometry[k, :2]).max() < 0.01  # unsignalled
        assert run.windows == ((event["time"], event["time"]),) and run.calls == ()
        team = run.params["team"]
        if family == "kidnap_even_silent":
            assert run.messages == () and team["messages_on"] is False and team["sent"] > 0
        else:
            assert run.messages and team["messages_on"] is True
        if family == "kidnap_even_wrong":
            assert 2 <= len(team["teammates"]) <= 4
    # the plain kidnapping's odds are not restricted (a clear case exists among few seeds)
    odds = [kidnap_mirror_log_odds(r.field, r.params["event"]) for r in (simulate("kidnap", s, 20.0) for s in range(4))]
    assert any(abs(o) >= math.log(2.0) for o in odds)


def test_messages_are_valid_sorted_and_lost_at_the_drawn_rate():
    out_of_order = 0
    for seed in range(4):
        run = simulate("kidnap_even_team", seed, 30.0)
        team = run.params["team"]
        n_steps = run.truth.shape[0]
        numbers = [m["number"] for m in team["teammates"]]
        assert len(set(numbers + [team["own_number"]])) == len(numbers) + 1
        assert all(1 <= v <= 6 for v in numbers + [team["own_number"]])
        assert 1 <= len(numbers) <= 4
        steps = [k for k, _ in run.messages]
        assert steps == sorted(steps) and all(0 <= k < n_steps for k in steps)
        assert all(isinstance(m, TeamMessage) for _, m in run.messages)
        delivered = [s for s in run.team.sent if not s.lost and s.arrival_step < n_steps]
        assert len(delivered) == len(run.messages) == team["delivered"]
        for s in delivered:
            k = s.arrival_step
            assert run.times[k] >= s.arrival_time - 1e-9 and (k == 0 or run.times[k - 1] < s.arrival_time)
            assert s.message.received_time == pytest.approx(s.send_time, abs=1e-9)  # the robot's clock
            assert 0.0 <= s.arrival_time - s.send_time <= team["latency_max"] + 1e-12
        received = [m.received_time for _, m in run.messages]
        out_of_order += sum(b < a for a, b in zip(received, received[1:]))
        # the loss rate as drawn (binomial, 4 σ)
        lost = np.array([s.lost for s in run.team.sent])
        p = team["loss"]
        assert abs(lost.mean() - p) <= 4 * math.sqrt(p * (1 - p) / lost.size) + 0.02
        # ball reports: only recent sightings, near the truth for a teammate that is not wrong
        by_number = {m["number"]: m for m in team["teammates"]}
        errors = []
        for s in run.team.sent:
            m = s.message
            if m.ball is None:
                assert m.ball_age == 0.0 and s.true_ball is None
                continue
            assert 0.0 <= m.ball_age <= by_number[m.sender]["max_age"]
            assert (m.ball_velocity is not None) == by_number[m.sender]["reports_velocity"]
            # its error: its pose error (carried out to the ball by its heading error) and its own noise
            mate = by_number[m.sender]
            r = mate["ball_range"]
            scale = (
                1.5 * mate["bias_position"]
                + r * (1.5 * mate["bias_heading"] + mate["bearing_sigma"] + 0.1)
                + mate["range_sigma"]
            )
            errors.append(math.dist(m.ball, s.true_ball) / scale)
            assert (m.pose_covariance is None) == (by_number[m.sender]["states"] == "confidence")
        assert errors and np.median(errors) < 1.0 and max(errors) < 5.0
    assert out_of_order > 0  # latency reorders some messages


def test_the_wrong_teammate_reports_the_mirror_during_its_interval():
    checked = 0
    for seed in range(3):
        run = simulate("kidnap_even_wrong", seed, 30.0)
        wrong = run.params["team"]["wrong"]
        kidnap = run.params["event"]["time"]
        assert wrong["start"] <= kidnap <= wrong["end"]
        assert wrong["end"] - wrong["start"] <= WRONG_SECONDS[1] + 1e-9
        assert (
            wrong["end"] - wrong["start"] >= WRONG_SECONDS[0] - 1e-9
            or wrong["start"] == 0.0
            or wrong["end"] == run.params["duration"]
        )
        for s in run.team.sent:
            m = s.message
            inside = wrong["start"] <= s.send_time <= wrong["end"]
            if m.sender != wrong["number"]:
                assert not s.wrong
                continue
            if not inside or not s.wrong:
                # (its last look may fall just before the interval)
                assert not inside or s.send_time - wrong["start"] < 0.1
                continue
            mirror = np.array([-s.true_pose[0], -s.true_pose[1]])
            assert np.hypot(*(np.array(m.pose[:2]) - mirror)) < 0.5
            assert abs(wrap_angles(m.pose[2] - s.true_pose[2] - math.pi)) < 0.3
            if m.pose_covariance is None:  # sure of itself
                assert m.confidence >= 0.9
            else:
                assert m.pose_sigmas()[0] <= 0.1 + 1e-12
            if m.ball is not None and wrong["start"] <= m.sighting_time <= wrong["end"]:
                # at the point image of the ball, off by its own sighting noise only
                mate = next(t for t in run.params["team"]["teammates"] if t["number"] == m.sender)
                noise = 0.1 + mate["range_sigma"] + mate["ball_range"] * (0.1 + mate["bearing_sigma"])
                truth = np.asarray(s.true_ball)
                assert math.dist(m.ball, -truth) < 4 * noise
                if np.hypot(*truth) > 2 * noise:
                    assert math.dist(m.ball, -truth) < math.dist(m.ball, truth)
                checked += 1
    assert checked > 10


def test_ball_stays_on_the_field_and_kicks_happen():
    for family, seed in (("tracking", 0), ("kidnap_even_team", 1), ("kidnap_even_silent", 2)):
        run = simulate(family, seed, 30.0)
        hl, hw = run.field.half_length, run.field.half_width
        assert (np.abs(run.ball[:, 0]) <= hl + 1e-12).all() and (np.abs(run.ball[:, 1]) <= hw + 1e-12).all()
        assert run.params["team"]["kicks"] > 0 and np.ptp(run.ball, axis=0).max() > 0.5
        assert (np.abs(run.team.teammates[..., 0]) <= hl).all() and (np.abs(run.team.teammates[..., 1]) <= hw).all()
        for t in run.team.goals:  # after a goal, the centre mark
            k = int(round(t / run.dt)) - 1
            assert np.array_equal(run.ball[k], [0.0, 0.0])
        keeper = [m for m in run.params["team"]["teammates"] if m["goalkeeper"]]
        for m in keeper:  # the goalkeeper stays near its own goal
            i = run.team.numbers.index(m["number"])
            assert (run.team.teammates[i, :, 0] < -hl + 2.5).all()


def test_ball_goal_and_lines():
    from demos.battery_sim import field_for

    field = field_for(0)
    hl, hw = field.half_length, field.half_width
    # into the goal between the posts: back to the centre mark, at rest
    ball = Ball(field, 0.5, position=(hl - 1.0, 0.2))
    ball.kick(3.0, 0.0)
    events = [ball.step(0.01) for _ in range(200)]
    assert events.count("goal") == 1 and "out" not in events
    assert np.array_equal(ball.position, [0.0, 0.0]) and ball.speed == 0.0
    # over the goal line outside the posts: on the line where it crossed, at rest
    ball = Ball(field, 0.5, position=(hl - 0.5, hw - 0.5))
    ball.kick(2.0, 0.3)
    events = [ball.step(0.01) for _ in range(200)]
    assert events.count("out") == 1 and ball.position[0] == hl and abs(ball.position[1]) <= hw
    assert ball.speed == 0.0
    # over a touchline
    ball = Ball(field, 0.5, position=(1.0, -hw + 0.5))
    ball.kick(2.0, -math.pi / 2)
    events = [ball.step(0.01) for _ in range(200)]
    assert events.count("out") == 1 and ball.position[1] == -hw and ball.position[0] == pytest.approx(1.0)
    # friction: rolls v² / 2a and stops
    ball = Ball(field, 1.0)
    ball.kick(2.0, math.pi / 2 - 1.0)
    for _ in range(300):
        ball.step(0.01)
    assert ball.speed == 0.0 and np.hypot(*ball.position) == pytest.approx(2.0, abs=0.03)


def test_ball_detections_only_inside_the_view():
    total = false_total = frames = 0
    for family, seed in (("tracking", 0), ("kidnap_even_team", 1), ("blackout", 2)):
        run = simulate(family, seed, 30.0)
        p, camera = run.params, run.params["team"]["ball_camera"]
        half_fov = 0.5 * math.radians(p["fov_deg"])
        truth = np.vstack([run.start, run.truth])
        ball = np.vstack([[0.0, 0.0], run.ball])
        assert len(run.ball_detections) == len(run.frames)
        frames += len(run.frames)
        for frame, detection, false in zip(run.frames, run.ball_detections, run.team.ball_false):
            if detection is None:
                continue
            assert isinstance(detection, BallDetection)
            assert detection.range_sigma is None and detection.bearing_sigma is None  # no noise figures
            total += 1
            off = abs(wrap_angles(detection.bearing - frame.head))
            if false:
                false_total += 1
                assert off <= half_fov + 1e-9 and detection.range <= camera["range"] + 1e-9
                continue
            k = min(int(round(frame.capture_time / run.dt)), run.truth.shape[0])
            d = ball[k] - truth[k, :2]
            r = float(np.hypot(*d))
            bearing = wrap_angles(math.atan2(d[1], d[0]) - truth[k, 2])
            assert abs(wrap_angles(bearing - frame.head)) <= half_fov + 1e-9  # the true ball in view
            assert camera["min_range"] <= r <= camera["range"]
            assert off <= half_fov + 5 * camera["bearing_sigma"]
        if p["event"]["type"] == "blackout":
            dark = [
                d
                for f, d in zip(run.frames, run.ball_detections)
                if p["event"]["time"] <= f.capture_time <= p["event"]["end"]
            ]
            assert dark and all(d is None for d in dark)
        for key, bounds in BALL_CAMERA.items():
            assert bounds[0] <= camera[key] <= bounds[1]
    assert total > 50 and false_total <= 0.05 * frames + 4 * math.sqrt(0.05 * frames)
