"""Collision detection by sensor-actuator comparison (proprioception.collision) on synthetic and simulated servo data."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from demos.collision_sim import BOTH, HINDRANCE, LEFT, RIGHT, STOPPED, CollisionEvent, CollisionScenario, simulate
from proprioception.collision import (
    NO_COLLISION,
    CollisionDetector,
    CollisionPercept,
    CollisionReference,
    detect,
    estimate_delays,
    learn_reference,
)


@pytest.fixture(scope="module")
def free_walk():
    return simulate(CollisionScenario(duration=90.0, command=None), seed=2000)


@pytest.fixture(scope="module")
def reference(free_walk):
    log = free_walk
    return learn_reference(log.servo_commands, log.servo_readings, log.phase, log.commands, log.joint_sides)


def test_delay_estimate_recovers_a_pure_delay():
    rng = np.random.default_rng(0)
    t = np.arange(2000) * 0.01
    commands = np.column_stack([np.sin(2 * np.pi * 1.7 * t + p) for p in rng.uniform(0, 6, 4)])
    readings = np.empty_like(commands)
    delays = np.array([0, 2, 5, 7])
    for j, d in enumerate(delays):
        readings[d:, j] = commands[: commands.shape[0] - d, j]
        readings[:d, j] = commands[0, j]
    assert (estimate_delays(commands, readings + 1e-4 * rng.standard_normal(readings.shape), 10) == delays).all()


def test_reference_grows_with_walking_speed(reference):
    # Faster walking moves the joints faster, so free walking deviates more: the learned reference says so.
    phases = np.linspace(0, 1, 10, endpoint=False)
    slow = reference.reference(phases, np.full(10, reference.speeds[0])).sum()
    fast = reference.reference(phases, np.full(10, reference.speeds[-1])).sum()
    assert fast > slow > 0
    assert reference.speeds.size >= 3


def test_quiet_on_free_walking_and_fires_on_a_collision(reference):
    free = simulate(CollisionScenario(duration=60.0, command=None), seed=2001)
    out = detect(reference, free.servo_commands, free.servo_readings, free.phase, free.commands)
    alarms = out["collision"].any(axis=1)
    onsets = int((alarms & ~np.r_[False, alarms[:-1]]).sum())
    assert onsets <= 2, f"{onsets} false alarms in a minute of free walking"

    events = (
        CollisionEvent(3.0, 1.5, HINDRANCE, LEFT, 0.6),
        CollisionEvent(6.0, 1.5, STOPPED, RIGHT, 0.6),
        CollisionEvent(9.0, 1.0, HINDRANCE, BOTH, 0.6),
    )
    log = simulate(CollisionScenario(duration=12.0, events=events), seed=2002)
    out = detect(reference, log.servo_commands, log.servo_readings, log.phase, log.commands)
    start_times = log.times - log.dt
    for event in events:
        window = (start_times >= event.start) & (start_times < event.start + 0.3)
        assert out["collision"][window].any(), f"{event} not detected within 0.3 s"
        during = (start_times >= event.start) & (start_times < event.end)
        hit = out["collision"][during].any(axis=0)
        expected = {LEFT: (True, False), RIGHT: (False, True), BOTH: (True, True)}[event.side]
        assert tuple(hit) == expected, f"{event}: sides {hit}"
    quiet = (start_times > 1.0) & (start_times < 2.9)
    assert not out["collision"][quiet].any()


def test_online_detector_equals_batch(reference):
    events = (CollisionEvent(1.0, 1.0, STOPPED, LEFT, 0.5), CollisionEvent(2.5, 0.8, HINDRANCE, RIGHT, 0.4))
    log = simulate(CollisionScenario(duration=5.0, events=events), seed=2003)
    detector = CollisionDetector(reference)
    percepts = [
        detector.update(log.servo_commands[k], log.servo_readings[k], log.phase[k], log.commands[k])
        for k in range(log.times.shape[0])
    ]
    out = detect(reference, log.servo_commands, log.servo_readings, log.phase, log.commands)
    s_rel = np.array([[p.s_rel_left, p.s_rel_right] for p in percepts])
    np.testing.assert_allclose(s_rel, out["s_rel"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose([p.rate for p in percepts], out["rate"], atol=1e-12)
    assert (np.array([[p.recent_left, p.recent_right] for p in percepts]) == out["recent"]).all()
    assert any(p.side == 1 for p in percepts) and any(p.side == -1 for p in percepts)


def test_side_follows_the_latest_collision():
    # Hoffmann eq. 26: +1 left, -1 right, 0 both, and no side without a recent collision.
    assert CollisionPercept(recent_left=True).side == 1
    assert CollisionPercept(recent_right=True).side == -1
    assert CollisionPercept(recent_left=True, recent_right=True).side == 0
    assert NO_COLLISION.side is None and not NO_COLLISION.collision


def test_rejected_update_leaves_the_detector_unchanged(reference, free_walk):
    log = free_walk
    a, b = CollisionDetector(reference), CollisionDetector(reference)
    joints = reference.n_joints
    for k in range(40):
        args = (log.servo_commands[k], log.servo_readings[k], log.phase[k], log.commands[k])
        if k == 20:
            bad_reading = log.servo_readings[k].copy()
            bad_reading[3] = np.nan
            with pytest.raises(ValueError, match="finite"):
                a.update(log.servo_commands[k], bad_reading, log.phase[k], log.commands[k])
            with pytest.raises(ValueError, match="shape"):
                a.update(log.servo_commands[k][: joints - 1], log.servo_readings[k], log.phase[k], log.commands[k])
            with pytest.raises(ValueError, match="walk_command"):
                a.update(*args[:3], (0.1, 0.0))
        assert a.update(*args) == b.update(*args)


def test_bad_training_data(free_walk):
    log = free_walk
    with pytest.raises(ValueError, match="same shape|shape"):
        learn_reference(log.servo_commands, log.servo_readings[:, :7], log.phase, log.commands, log.joint_sides)
    readings = log.servo_readings.copy()
    readings[100, 2] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        learn_reference(log.servo_commands, readings, log.phase, log.commands, log.joint_sides)
    with pytest.raises(ValueError, match="too little free walking"):
        learn_reference(
            log.servo_commands[:150], log.servo_readings[:150], log.phase[:150], log.commands[:150], log.joint_sides
        )
    with pytest.raises(ValueError, match="no right joint"):
        learn_reference(log.servo_commands, log.servo_readings, log.phase, log.commands, np.zeros(8, dtype=int))
    with pytest.raises(ValueError, match="CollisionReference"):
        CollisionDetector("reference.npz")


def test_reference_save_load(reference, tmp_path):
    path = tmp_path / "reference.npz"
    reference.save(path)
    loaded = CollisionReference.load(path)
    phases, speeds = np.linspace(0, 1, 37), np.linspace(0, 0.4, 37)
    np.testing.assert_array_equal(loaded.reference(phases, speeds), reference.reference(phases, speeds))
    (tmp_path / "broken.npz").write_bytes(path.read_bytes()[:100])
    with pytest.raises(ValueError):
        CollisionReference.load(tmp_path / "broken.npz")


@given(st.floats(0.0, 1.0, exclude_max=True), st.floats(0.0, 1.0))
def test_reference_is_positive_and_finite_everywhere(phase, speed):
    reference = _cached_reference()
    value = reference.reference(phase, speed)
    assert value.shape == (2,) and np.isfinite(value).all() and (value > 0).all()


_CACHE: dict = {}


def _cached_reference():
    if "reference" not in _CACHE:
        log = simulate(CollisionScenario(duration=40.0, command=None), seed=2004)
        _CACHE["reference"] = learn_reference(
            log.servo_commands, log.servo_readings, log.phase, log.commands, log.joint_sides, min_samples=5
        )
    return _CACHE["reference"]


def test_percept_validates():
    with pytest.raises(ValueError, match="rate"):
        CollisionPercept(rate=1.5)
    with pytest.raises(ValueError, match="s_rel_left"):
        CollisionPercept(s_rel_left=math.nan)


def test_paper_experiments_end_to_end():
    """Hoffmann section 4 on three seeds: the adaptive model's cloud holds the true pose while walking freely
    (its free-walking noise is fitted to hold 95 % of the training robots' errors over 5 s, which makes it about
    as wide as velocity-linear's: the paper's tighter free-walking cloud is not claimed) and after a collision;
    velocity-linear's does not after a collision."""
    from demos.collision import free_walk_reference, run_case

    reference = free_walk_reference()
    seeds = (0, 1, 2)
    none_ad = [run_case("none", "adaptive", seed, reference) for seed in seeds]
    assert np.mean([r["contained_share"] for r in none_ad]) >= 0.9
    single_vl = [run_case("single", "velocity-linear", seed, reference) for seed in seeds]
    single_ad = [run_case("single", "adaptive", seed, reference) for seed in seeds]
    single_pivot = [run_case("single", "adaptive-pivot", seed, reference) for seed in seeds]
    # The simulated stop pivots about the held foot, which the paper's model (v' = 0) does not know: its cloud
    # holds the truth less often than the pivot variant's, and far more often than velocity-linear's.
    assert np.mean([r["contained_share"] for r in single_ad]) >= 0.6
    assert np.mean([r["contained_share"] for r in single_pivot]) >= 0.8
    assert np.mean([r["contained_share"] for r in single_vl]) <= 0.3
    for run in single_ad:
        assert run["state_belief_at_end_of_collision"]["free"] < 0.5
        assert run["free_belief_at_end"] > 0.9


def test_recording_holds_the_state_belief_and_s_rel(tmp_path):
    """The collision demo's .rrd carries the belief over the mobility states and S_rel, as computed."""
    from demos.collision import free_walk_reference, run_case
    from test_end_to_end import scalar_series

    path = tmp_path / "collision.rrd"
    result = run_case("single", "adaptive", 0, free_walk_reference(), particles=50, rrd=str(path))
    series = result["series"]
    steps, stopped = scalar_series(path, "/motion/state_belief/stopped")
    assert np.array_equal(steps, np.arange(series["belief"].shape[0]))
    assert np.array_equal(stopped, series["belief"][:, 4]) and stopped.max() > 0.5
    _, s_rel_left = scalar_series(path, "/proprioception/s_rel/left")
    assert np.array_equal(s_rel_left, series["s_rel"][:, 0]) and s_rel_left.max() > 1.0


def test_collision_command_json(capsys):
    import json

    from mcl.tools.cli import main as cli_main

    assert cli_main(["demo", "collision", "--case", "single", "--seeds", "0-1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    block = out["no_vision"]["single"]
    assert set(block) == {"velocity-linear", "adaptive"}
    assert (
        block["adaptive"]["summary"]["contained_share"]["mean"]
        > block["velocity-linear"]["summary"]["contained_share"]["mean"]
    )
