"""Tests for proprioception.velocity_odometry (EKF velocity → pose changes for the motion models) and figure 5 of the
velocity demo (the particle filter with that odometry)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rerun.chunk as rrc
from hypothesis import given
from hypothesis import strategies as st

from demos.biped import DisturbanceParams, SensorParams, field_poses, gait_command, simulate_walk, turning_gait
from motion_models import MotionInput
from proprioception.kinematics import nao_leg, rotation_x, rotation_y
from proprioception.velocity import LegOdometry, VelocityEKF, VelocityEKFParams
from proprioception.velocity_odometry import EKFOdometry, OdometryIncrement, PlanarOdometry, compose_increments

G = 9.81
DT = 0.01
TILT = rotation_y(0.12) @ rotation_x(0.06)  # IMU → level frame: a leaning trunk, no yaw (ZYX angles)


def level_to_imu(vector) -> np.ndarray:
    return TILT.T @ np.asarray(vector, dtype=np.float64)


def make_odometry(velocity_level=(0.0, 0.0, 0.0), gyro_bias=(0.0, 0.0, 0.0), params=VelocityEKFParams()):
    """An EKFOdometry on an EKF started from a tilted robot at rest (or moving at `velocity_level`)."""
    gravity = level_to_imu([0.0, 0.0, G])
    ekf = VelocityEKF(gravity, 0.0, params=params, velocity=level_to_imu(velocity_level), gyro_bias=gyro_bias)
    return EKFOdometry(LegOdometry((nao_leg("left"), nao_leg("right")), ekf))


def feed(odometry: EKFOdometry, n: int, gyro_level=(0.0, 0.0, 0.0), bias=(0.0, 0.0, 0.0), take_every: int = 3):
    """n IMU samples of a noise-free robot (no acceleration); takes every `take_every` samples."""
    accel = level_to_imu([0.0, 0.0, G])
    gyro = level_to_imu(gyro_level) + np.asarray(bias)
    taken = []
    for i in range(1, n + 1):
        odometry.imu(i * DT, gyro, accel)
        if i % take_every == 0:
            taken.append(odometry.take())
    return taken


# --- the running sum ------------------------------------------------------------------------------------
def test_standing_robot_gives_zero_increments():
    odometry = make_odometry()
    taken = feed(odometry, 300)
    assert len(taken) == 100
    for step in taken:
        assert step.odometry == (0.0, 0.0, 0.0)
        assert step.dt == pytest.approx(3 * DT, abs=1e-12) and step.samples == 3
    assert odometry.take() == OdometryIncrement(0.0, 0.0, 0.0, 0.0, 0)  # nothing since the last take


def test_constant_velocity_straight_walk_integrates_to_the_distance():
    speed, n = 0.2, 1000
    odometry = make_odometry(velocity_level=(speed, 0.0, 0.0))
    taken = feed(odometry, n, take_every=7)
    odometry_rest = odometry.take()  # 1000 = 7·142 + 6: the remainder is not lost
    steps = [t.odometry for t in taken] + [odometry_rest.odometry]
    pose = compose_increments(steps)[-1]
    np.testing.assert_allclose(pose, [speed * n * DT, 0.0, 0.0], atol=1e-9)
    assert sum(t.samples for t in taken) + odometry_rest.samples == n
    # Each filter step is a MotionInput's odometry.
    u = MotionInput(dt=taken[0].dt, odometry=taken[0].odometry)
    assert u.displacement() == pytest.approx((7 * DT * speed, 0.0, 0.0), abs=1e-12)


@pytest.mark.parametrize("turn_rate", [0.5, -1.3])
def test_turn_in_place_integrates_to_the_angle_and_removes_the_bias(turn_rate):
    bias = np.array([0.004, -0.003, 0.005])
    odometry = make_odometry(gyro_bias=bias, params=VelocityEKFParams(estimate_gyro_bias=False))
    n = 600  # 200 filter steps of 3 samples
    taken = feed(odometry, n, gyro_level=(0.0, 0.0, turn_rate), bias=bias)
    pose = compose_increments([t.odometry for t in taken])[-1]
    expected = math.remainder(turn_rate * n * DT, 2 * math.pi)
    assert pose[2] == pytest.approx(expected, abs=1e-9)
    np.testing.assert_allclose(pose[:2], 0.0, atol=1e-9)


def test_walking_arc_summed_at_any_rate_is_the_same_arc():
    speed, turn_rate, n = 0.15, 0.4, 600
    gravity, velocity = level_to_imu([0, 0, G]), level_to_imu([speed, 0, 0])
    gyro = level_to_imu([0, 0, turn_rate])
    radius = speed / turn_rate
    for every in (1, 3, 10, 600):
        total = PlanarOdometry()
        taken = []
        for i in range(1, n + 1):
            total.add_sample(gravity, velocity, gyro, DT)  # the velocity is constant in the robot frame
            if i % every == 0:
                taken.append(total.take().odometry)
        pose = compose_increments(taken)[-1]
        angle = turn_rate * n * DT
        np.testing.assert_allclose(pose, [radius * math.sin(angle), radius * (1 - math.cos(angle)), angle], atol=1e-12)


@given(
    st.lists(st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(-0.5, 0.5)), min_size=1, max_size=40),
    st.integers(1, 7),
)
def test_summing_in_groups_is_chaining_every_increment(increments, group):
    total = PlanarOdometry()
    sums = []
    for k, increment in enumerate(increments):
        total.add(increment, DT)
        if (k + 1) % group == 0:
            sums.append(total.take().odometry)
    if total.peek().samples:
        sums.append(total.take().odometry)
    grouped = compose_increments(sums, start=(1.0, -2.0, 3.0))[-1]
    direct = compose_increments(increments, start=(1.0, -2.0, 3.0))[-1]
    np.testing.assert_allclose(grouped[:2], direct[:2], atol=1e-12)
    assert math.remainder(grouped[2] - direct[2], 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    assert -math.pi < grouped[2] <= math.pi


def test_heading_is_wrapped_only_on_output():
    total = PlanarOdometry()
    for _ in range(4):
        total.add((0.0, 0.0, 1.0), DT)
    assert total.peek().dtheta == pytest.approx(4.0 - 2 * math.pi)
    total.add((1.0, 0.0, 0.0), DT)  # along the heading of 4 rad, not of its wrap
    step = total.take()
    assert (step.dx, step.dy) == pytest.approx((math.cos(4.0), math.sin(4.0)))


# --- bad input ------------------------------------------------------------------------------------------
def test_bad_samples_raise_and_leave_ekf_and_sum_untouched():
    odometry = make_odometry(velocity_level=(0.1, 0.0, 0.0))
    feed(odometry, 5, take_every=1000)
    state, cov, before = odometry.ekf.state, odometry.ekf.covariance, odometry.sum.peek()
    accel, gyro = level_to_imu([0, 0, G]), np.zeros(3)
    bad_calls = [
        ((0.05, gyro, accel), "time"),  # does not advance
        ((math.nan, gyro, accel), "time"),
        ((0.06, [0.0, math.nan, 0.0], accel), "gyro"),
        ((0.06, gyro, [0.0, 0.0]), "accel"),
        ((0.06, [0.0, 0.0], accel), "gyro"),
        ((5.0, gyro, accel), "max_imu_gap"),  # a gap the EKF refuses
        (("soon", gyro, accel), "time"),
    ]
    for args, name in bad_calls:
        with pytest.raises(ValueError, match=name):
            odometry.imu(*args)
        np.testing.assert_array_equal(odometry.ekf.state, state)
        np.testing.assert_array_equal(odometry.ekf.covariance, cov)
        assert odometry.sum.peek() == before
    odometry.imu(0.06, gyro, accel)  # and it carries on
    assert odometry.sum.peek().samples == before.samples + 1


def test_running_sum_rejects_bad_increments():
    total = PlanarOdometry()
    total.add((0.01, 0.0, 0.1), DT)
    before = total.peek()
    for increment, dt, name in (
        ((math.inf, 0, 0), DT, "increment"),
        ((0, 0), DT, "increment"),
        ((0, 0, 0), -DT, "dt"),
        ((0, 0, 0), math.nan, "dt"),
        ((0, 0, 0), "x", "dt"),
    ):
        with pytest.raises(ValueError, match=name):
            total.add(increment, dt)
        assert total.peek() == before
    with pytest.raises(ValueError, match="gravity"):
        total.add_sample([9.81, 0, 0], [0, 0, 0], [0, 0, 0], DT)  # IMU x axis vertical: no heading
    assert total.peek() == before
    with pytest.raises(ValueError, match="increments"):
        compose_increments(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="start"):
        compose_increments(np.zeros((3, 3)), start=(0, math.nan, 0))
    with pytest.raises(ValueError, match="leg_odometry"):
        EKFOdometry(object())


# --- on the simulated walk ------------------------------------------------------------------------------
QUIET = SensorParams(
    accel_noise=0.0, accel_bias=0.0, gyro_noise=0.0, gyro_bias=0.0, encoder_resolution=0.0, contact_error=0.0
)
CALM = DisturbanceParams(twist_probability=0.0, slip_probability=0.0)


@pytest.mark.parametrize("walk", ["straight", "turning"])
def test_dead_reckoning_of_a_clean_walk_follows_the_truth(walk):
    from demos.velocity import STANDING_SAMPLES_TIME, ekf_odometry, ekf_params_for, filter_steps, walk_gait

    run = simulate_walk(6.0, 2, gait=walk_gait(walk, 6.0), sensors=QUIET, disturbances=CALM)
    n0 = int(np.searchsorted(run.imu_time, STANDING_SAMPLES_TIME, side="right")) - 1
    steps = filter_steps(run, n0)
    increments = ekf_odometry(run, steps, ekf_params_for(variant="ekf+bias"))
    truth = field_poses(run, (1.0, -1.0, 2.5))[steps]
    dead = compose_increments(increments, truth[0])
    walked = np.sum(np.hypot(*np.diff(truth[:, :2], axis=0).T))
    assert walked > 0.4
    # Noise-free sensors: what remains is the kinematics' own error and holding v over each 10 ms interval.
    assert np.hypot(*(dead[-1, :2] - truth[-1, :2])) < 0.01 * walked
    assert abs(math.remainder(dead[-1, 2] - truth[-1, 2], 2 * math.pi)) < math.radians(0.2)
    if walk == "turning":
        assert abs(math.remainder(truth[-1, 2] - truth[0, 2], 2 * math.pi)) > math.radians(30)


def test_gait_command_is_the_path_the_trunk_follows():
    gait = turning_gait(6.0)
    run = simulate_walk(6.0, 0, gait=gait)
    command = gait_command(gait, run.imu_time)
    np.testing.assert_allclose(np.gradient(run.trunk_yaw, run.imu_time), command[:, 2], atol=1e-3)
    assert command[0].tolist() == [0.0, 0.0, 0.0] and command[-1, 0] == pytest.approx(gait.speed)
    poses = field_poses(run, (-3.0, -2.0, 3.0))
    np.testing.assert_allclose(poses[0], [-3.0, -2.0, 3.0])
    assert np.all(np.abs(poses[:, 2]) <= math.pi)
    with pytest.raises(ValueError, match="start"):
        field_poses(run, (0.0, 0.0))


def test_figure_5_is_deterministic_and_recorded(tmp_path):
    from demos.velocity import ODOMETRY_SOURCES, odometry_run, run_estimators, write_recording

    run = simulate_walk(5.0, 4)
    a = odometry_run(run, 4, "straight", particles=100)
    b = odometry_run(run, 4, "straight", particles=100)
    assert a == b
    for source in ODOMETRY_SOURCES:
        assert 0.0 < a[source]["position_rmse_m"] < 0.5
        assert a[source]["dead_reckoning_position_m"] >= 0.0
    assert a["ideal command"]["dead_reckoning_position_m"] < 0.02  # the trunk follows the request
    path = tmp_path / "velocity.rrd"
    recorded = write_recording(str(path), run, run_estimators(run), 4, "straight", 100)
    assert recorded == a  # recording changes nothing
    entities = {chunk.entity_path for chunk in rrc.RrdReader(str(path)).stream()}
    for name in ("truth", "imu", "kinematics", "kinematics_gyro", "ekf", "ekf_bias"):
        assert f"/proprioception/forward_velocity/{name}" in entities
    for expected in (
        "/robot/estimate",
        "/robot/truth",
        "/robot/estimate_command",
        "/particles",
        "/observations",
        "/error/position",
        "/error/position_command",
        "/robot/dead_reckoning/ekf_odometry",
    ):
        assert expected in entities
    assert rrc.RrdReader(str(path)).blueprints()


def test_demo_reports_figure_5_as_json(capsys):
    import json

    from demos.velocity import ODOMETRY_SOURCES, main

    assert main(["--json", "--duration", "5", "--seeds", "1", "--no-twist", "--particles", "100"]) == 0
    report = json.loads(capsys.readouterr().out)
    odometry = report["odometry"]
    assert odometry["particles"] == 100 and odometry["seeds"] == [0] and odometry["rrd"] is None
    assert odometry["filter_rate_hz"] == pytest.approx(100.0 / 3.0)
    for walk in ("straight", "turning"):
        block = odometry["walks"][walk]
        assert len(block["runs"]) == 1
        for source in ODOMETRY_SOURCES:
            for key in (
                "position_rmse_m",
                "heading_rmse_deg",
                "sparse_camera_position_rmse_m",
                "dead_reckoning_position_m",
                "dead_reckoning_heading_deg",
            ):
                assert block["summary"][source][key]["median"] == block["runs"][0][source][key]
    with pytest.raises(SystemExit):
        main(["--particles", "0"])
