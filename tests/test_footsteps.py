"""Footstep displacements and their integration, the footstep event, and the footstep walk simulator."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from demos.footstep_sim import CARPET, GRASS, Robot, load_log, save_log, simulate, truth_displacements
from field.angles import wrap_angles
from motion_models.footsteps import LEFT, RIGHT, FootstepEvent, displacements, input_matrix, integrate

coordinate = st.floats(-20, 20, allow_nan=False)
heading = st.floats(-math.pi, math.pi, allow_nan=False)
trajectories = st.lists(st.tuples(coordinate, coordinate, heading), min_size=1, max_size=40).map(
    lambda rows: np.array(rows, dtype=np.float64)
)
steps_strategy = st.lists(
    st.tuples(st.floats(-0.2, 0.2), st.floats(-0.2, 0.2), st.floats(-3.0, 3.0)), min_size=0, max_size=40
).map(lambda rows: np.array(rows, dtype=np.float64).reshape(-1, 3))


def assert_poses_close(a, b, tol=1e-9):
    assert a.shape == b.shape
    np.testing.assert_allclose(a[:, :2], b[:, :2], atol=tol, rtol=0)
    assert np.all(np.abs(wrap_angles(a[:, 2] - b[:, 2])) < tol)


# -- displacements and integration ------------------------------------------------------------------------------
@given(trajectories)
def test_integrating_the_displacements_of_a_trajectory_gives_it_back(poses):
    steps = displacements(poses)
    assert steps.shape == (poses.shape[0] - 1, 3)
    assert np.all((steps[:, 2] > -math.pi) & (steps[:, 2] <= math.pi))
    assert_poses_close(integrate(steps, start=poses[0]), poses, tol=1e-8)


@given(steps_strategy, st.tuples(coordinate, coordinate, heading))
def test_displacements_of_an_integrated_walk_are_the_steps(steps, start):
    poses = integrate(steps, start)
    assert poses.shape == (steps.shape[0] + 1, 3)
    assert np.all((poses[:, 2] > -math.pi) & (poses[:, 2] <= math.pi))
    back = displacements(poses)
    np.testing.assert_allclose(back[:, :2], steps[:, :2], atol=1e-9)
    np.testing.assert_allclose(wrap_angles(back[:, 2] - steps[:, 2]), 0.0, atol=1e-9)


def test_displacement_is_in_the_frame_of_the_earlier_pose():
    # Facing +y, the robot moves to the left in the field (-x): that is 1 m forward, 0.5 m right of it.
    poses = np.array([[1.0, 2.0, math.pi / 2], [1.5, 3.0, math.pi]])
    np.testing.assert_allclose(displacements(poses), [[1.0, -0.5, math.pi / 2]], atol=1e-12)
    # Four steps of 1 m with a quarter turn each walk a square back to the start.
    square = integrate([[1.0, 0.0, math.pi / 2]] * 4)
    assert_poses_close(square[[0, -1]], np.zeros((2, 3)), tol=1e-12)
    np.testing.assert_allclose(square[1:4, :2], [[1, 0], [1, 1], [0, 1]], atol=1e-12)


@pytest.mark.parametrize(
    "bad,match", [(np.zeros((3, 2)), "shape"), (np.zeros(3), "shape"), (np.array([[0, 0, 0], [np.nan, 0, 0]]), "row 1")]
)
def test_bad_poses_and_steps_are_rejected(bad, match):
    with pytest.raises(ValueError, match=match):
        displacements(bad)
    with pytest.raises(ValueError, match=match):
        integrate(bad)
    with pytest.raises(ValueError, match="start"):
        integrate(np.zeros((2, 3)), start=(0.0, math.inf, 0.0))


# -- the footstep event ------------------------------------------------------------------------------------------
def test_event_inputs_are_the_papers_lists():
    event = FootstepEvent(
        support=RIGHT,
        commanded=(0.04, 0.01, 0.1),
        previous_commanded=(0.03, 0.0, 0.05),
        sensor=(0.035, 0.008, 0.11),
        previous_sensor=(0.02, 0.001, 0.04),
        duration=0.3,
        previous_duration=0.28,
    )
    np.testing.assert_array_equal(event.inputs("apriori"), [0.04, 0.01, 0.1, 0.03, 0.0, 0.05, -1.0])
    np.testing.assert_array_equal(event.inputs("online"), [0.035, 0.008, 0.11, 0.02, 0.001, 0.04, -1.0, 0.3, 0.28])


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"support": 0}, "support"),
        ({"support": True}, "support"),
        ({"commanded": (0.1, math.nan, 0.0)}, "commanded"),
        ({"commanded": (0.1, 0.0)}, "commanded"),
        ({"sensor": "abc"}, "sensor"),
        ({"duration": -0.1}, "duration"),
        ({"previous_duration": math.inf}, "previous_duration"),
    ],
)
def test_bad_events_are_rejected(kwargs, match):
    base = {"support": LEFT, "commanded": (0.04, 0.0, 0.0)}
    with pytest.raises(ValueError, match=match):
        FootstepEvent(**{**base, **kwargs})


def test_online_inputs_need_the_sensor_fields():
    event = FootstepEvent(support=LEFT, commanded=(0.04, 0.0, 0.0), sensor=(0.03, 0.0, 0.0), duration=0.3)
    assert event.inputs("apriori").shape == (7,)
    with pytest.raises(ValueError, match="previous_sensor, previous_duration"):
        event.inputs("online")
    with pytest.raises(ValueError, match="kind"):
        event.inputs("sideways")


def test_input_matrix_rows_match_the_events():
    log = simulate(10.0, CARPET, seed=3)
    events = log.events()
    for kind in ("apriori", "online"):
        X = input_matrix(kind, log.support, log.commanded, log.sensor, log.durations)
        assert X.shape == (log.n_steps - 1, {"apriori": 7, "online": 9}[kind])
        for k in (1, 5, log.n_steps - 1):
            np.testing.assert_array_equal(X[k - 1], events[k].inputs(kind))
    with pytest.raises(ValueError, match="support"):
        input_matrix("apriori", np.zeros(log.n_steps), log.commanded)


# -- the simulator -----------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def logs():
    return {name: simulate(120.0, surface, seed=1) for name, surface in (("carpet", CARPET), ("grass", GRASS))}


def test_same_seed_same_log_bit_for_bit(logs):
    again = simulate(120.0, GRASS, seed=1)
    for name in ("swap_times", "swap_poses", "support", "commanded", "sensor", "mocap"):
        np.testing.assert_array_equal(getattr(again, name), getattr(logs["grass"], name))
    assert not np.array_equal(simulate(120.0, GRASS, seed=2).sensor[:50], again.sensor[:50])


def test_walk_rhythm_and_support_alternation(logs):
    log = logs["carpet"]
    period = 0.5 / 1.7
    assert log.n_steps == pytest.approx(120.0 / period, abs=2)
    assert abs(np.mean(log.durations) - period) < 2e-3
    assert set(np.unique(log.support)) == {LEFT, RIGHT} and np.all(log.support[1:] != log.support[:-1])
    # The gait command changes only at swaps, within the driver's acceleration limits.
    assert np.all(np.abs(np.diff(log.commanded, axis=0)) <= np.array([0.008, 0.006, 0.05]) + 1e-12)
    # The operator keeps the robot near the 2 m x 1.5 m capture area.
    assert np.all(np.abs(log.truth[:, 0]) < 1.3) and np.all(np.abs(log.truth[:, 1]) < 1.05)


def test_real_steps_are_longer_than_commanded_and_sensors_underestimate(logs):
    for log in logs.values():
        truth = truth_displacements(log)
        forward = log.commanded[:, 0] > 0.02
        # Leg inertia and backlash: real forward steps are longer than commanded ...
        assert np.mean(truth[forward, 0]) > 1.3 * np.mean(log.commanded[forward, 0])
        # ... and the encoders, behind the backlash, see less than the real step.
        assert np.mean(log.sensor[forward, 0]) < 0.9 * np.mean(truth[forward, 0])
        # A stationary or slightly negative forward order still walks forward (Rouxel Fig. 8).
        standing = np.abs(log.commanded[:, 0]) < 0.003
        assert np.mean(truth[standing, 0]) > 0.002
        # The gyro-based yaw is far better than the commanded one.
        assert np.mean(np.abs(log.sensor[:, 2] - truth[:, 2])) < 0.3 * np.mean(
            np.abs(log.commanded[:, 2] - truth[:, 2])
        )


def test_support_foot_asymmetry_turns_the_robot():
    # Walking straight ahead on command, the legs' turn biases differ: left-support steps turn more.
    from demos.footstep_sim import _leg_target

    r = Robot()
    left = _leg_target(r, CARPET, np.array([0.03, 0.0, 0.0]), LEFT, 0.0)
    right = _leg_target(r, CARPET, np.array([0.03, 0.0, 0.0]), RIGHT, 0.0)
    assert left[2] > 0 and left[2] + right[2] > 0


def test_grass_hurts_the_a_priori_odometry_more_than_the_sensor_based(logs):
    def per_step(log, steps):
        return np.mean(np.abs(steps - truth_displacements(log)), axis=0)

    carpet, grass = logs["carpet"], logs["grass"]
    leg_noise_ratio = GRASS.leg_noise[0] / CARPET.leg_noise[0]
    assert leg_noise_ratio > 2
    # The random part of the real step grows on grass: what commands cannot explain grows with it ...
    residual = {name: truth_displacements(log)[:, 2] - log.commanded[:, 2] for name, log in logs.items()}
    assert np.std(residual["grass"]) > np.std(residual["carpet"])
    # ... while the sensor-based odometry, which sees the legs, is about as good on both.
    assert abs(per_step(grass, grass.sensor)[0] - per_step(carpet, carpet.sensor)[0]) < 2e-3


def test_log_file_round_trip_and_bad_files(tmp_path, logs):
    log = logs["carpet"]
    path = tmp_path / "walk.npz"
    save_log(log, path)
    back = load_log(path)
    assert back.surface == "carpet" and back.seed == 1
    for name in ("swap_times", "swap_poses", "support", "commanded", "sensor", "mocap", "truth"):
        np.testing.assert_array_equal(getattr(back, name), getattr(log, name))
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(path.read_bytes()[:2000])
    with pytest.raises(ValueError, match="truncated"):
        load_log(truncated)
    fields = dict(np.load(path))
    fields["format_version"] = np.array(99)
    np.savez(tmp_path / "future.npz", **fields)
    with pytest.raises(ValueError, match="format version 99"):
        load_log(tmp_path / "future.npz")
    fields["format_version"] = np.array(1)
    fields["sensor"] = fields["sensor"][:-3]
    np.savez(tmp_path / "short.npz", **fields)
    with pytest.raises(ValueError, match="inconsistent step counts"):
        load_log(tmp_path / "short.npz")


def test_simulator_rejects_bad_arguments():
    with pytest.raises(ValueError, match="surface"):
        simulate(10.0, "ice")
    with pytest.raises(ValueError, match="duration"):
        simulate(float("nan"))
