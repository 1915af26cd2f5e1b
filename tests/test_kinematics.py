"""Tests for proprioception.kinematics: DH forward kinematics, the NAO preset, eq. 5–14, inverse kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proprioception.kinematics import LegChain, axis_angle, nao_leg, nao_leg_reference_pose, rotation_x, rotation_z


def planar_arm(l1=1.0, l2=0.5) -> LegChain:
    return LegChain.from_dh([(0.0, l1, 0.0, 0.0), (0.0, l2, 0.0, 0.0)])


def random_chain(rng, n=5) -> LegChain:
    rows = np.column_stack(
        [rng.uniform(-1, 1, n), rng.uniform(-0.2, 0.2, n), rng.uniform(-0.2, 0.2, n), rng.uniform(-math.pi, math.pi, n)]
    )
    base = axis_angle(rng.normal(size=3), rng.uniform(0, 3))
    imu = axis_angle(rng.normal(size=3), rng.uniform(0, 3))
    return LegChain.from_dh(
        rows,
        base_rotation=base,
        base_position=rng.uniform(-0.1, 0.1, 3),
        imu_rotation=imu,
        imu_position=rng.uniform(-0.1, 0.1, 3),
    )


# --- forward kinematics against hand-computed poses -----------------------------------------------------
def test_planar_two_link_arm_hand_computed():
    arm = planar_arm()
    pose = arm.forward([math.pi / 2, -math.pi / 2])
    np.testing.assert_allclose(pose[:3, 3], [0.5, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(pose[:3, :3], np.eye(3), atol=1e-15)
    pose = arm.forward([0.3, 0.4])
    np.testing.assert_allclose(
        pose[:3, 3], [math.cos(0.3) + 0.5 * math.cos(0.7), math.sin(0.3) + 0.5 * math.sin(0.7), 0.0], atol=1e-15
    )
    np.testing.assert_allclose(pose[:3, :3], rotation_z(0.7), atol=1e-15)


def test_single_row_with_offset_twist_and_theta_offset():
    # θ = π/2 (offset π/4 plus joint π/4), a = 0.2, d = 0.3, α = π/2.
    chain = LegChain.from_dh([(math.pi / 4, 0.2, 0.3, math.pi / 2)])
    pose = chain.forward([math.pi / 4])
    np.testing.assert_allclose(pose[:3, 3], [0.0, 0.2, 0.3], atol=1e-15)
    np.testing.assert_allclose(pose[:3, :3], [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-15)


def test_base_and_imu_mounts_compose():
    base = rotation_x(0.3)
    chain = LegChain.from_dh(
        [(0.0, 1.0, 0.0, 0.0)],
        base_rotation=base,
        base_position=(0.0, 0.0, 2.0),
        imu_rotation=rotation_z(0.5),
        imu_position=(0.1, 0.0, 0.0),
    )
    pose = chain.forward([0.0])
    np.testing.assert_allclose(pose[:3, 3], np.array([0, 0, 2.0]) + base @ [1.1, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(pose[:3, :3], base @ rotation_z(0.5), atol=1e-15)


def test_nao_zero_pose_and_dimensions():
    for side, y in (("left", -0.05), ("right", 0.05)):
        pose = nao_leg(side).forward(np.zeros(6))
        np.testing.assert_allclose(pose[:3, 3], [0.0, y, 0.04519 + 0.1029 + 0.100 + 0.085], atol=1e-14)
        np.testing.assert_allclose(pose[:3, :3], np.eye(3), atol=1e-14)


def test_nao_dh_matches_joint_axes_directly():
    rng = np.random.default_rng(1)
    for side in ("left", "right"):
        leg = nao_leg(side, imu_offset=(0.01, -0.02, 0.03))
        for _ in range(20):
            q = rng.uniform(-1.0, 1.0, 6)
            np.testing.assert_allclose(leg.forward(q), nao_leg_reference_pose(side, q, (0.01, -0.02, 0.03)), atol=1e-13)


def test_nao_knee_bends_forward():
    # Positive knee (NAOqi) with compensating hip and ankle pitch lowers the trunk and keeps it upright.
    pose = nao_leg("left").forward([0.0, -0.5, 1.0, -0.5, 0.0, 0.0])
    assert pose[2, 3] < 0.333
    np.testing.assert_allclose(pose[:3, :3], np.eye(3), atol=1e-12)


# --- eq. 5–14 by finite differences ---------------------------------------------------------------------
@pytest.mark.parametrize("which", ["nao-left", "nao-right", "random"])
def test_eq8_kinematic_velocity_matches_finite_difference(which):
    rng = np.random.default_rng(2)
    chain = {
        "nao-left": nao_leg("left"),
        "nao-right": nao_leg("right", (0.0, 0.01, 0.02)),
        "random": random_chain(rng),
    }[which]
    h = 1e-6
    for _ in range(10):
        q = rng.uniform(-0.8, 0.8, chain.n_joints)
        qd = rng.uniform(-2.0, 2.0, chain.n_joints)
        pose = chain.forward(q)
        world_velocity = (chain.forward(q + h * qd)[:3, 3] - chain.forward(q - h * qd)[:3, 3]) / (2 * h)
        vk, vkg = chain.velocities(q, qd, gyro=(0.0, 0.0, 0.0))
        expected = pose[:3, :3].T @ world_velocity
        np.testing.assert_allclose(vk, expected, atol=1e-8)


def test_eq13_eq14_remove_foot_rotation():
    """The foot turns about its origin at Ω while the joints move: v^KG equals the truth, v^K does not."""
    rng = np.random.default_rng(3)
    chain = nao_leg("left")
    h = 1e-6
    for _ in range(10):
        q = rng.uniform(-0.5, 0.5, 6)
        qd = rng.uniform(-1.0, 1.0, 6)
        omega_foot = rng.uniform(-1.0, 1.0, 3)

        def world(t):
            return axis_angle(omega_foot, np.linalg.norm(omega_foot) * t) @ chain.forward(q + qd * t)[:3, :]

        now = world(0.0)
        plus, minus = world(h), world(-h)
        velocity = now[:3, :3].T @ (plus[:3, 3] - minus[:3, 3]) / (2 * h)
        rot_dot = (plus[:3, :3] - minus[:3, :3]) / (2 * h)
        omega_skew = now[:3, :3].T @ rot_dot  # body angular velocity, as a gyro reads it
        gyro = np.array([omega_skew[2, 1], omega_skew[0, 2], omega_skew[1, 0]])
        vk, vkg = chain.velocities(q, qd, gyro)
        np.testing.assert_allclose(vkg, velocity, atol=1e-7)
        assert np.linalg.norm(vk - velocity) > 1e-3


def test_imu_positions_eq7():
    chain = nao_leg("left")
    q = np.array([0.1, -0.3, 0.7, -0.4, 0.05, -0.1])
    p = chain.imu_positions(q)
    assert p.shape == (9, 3)
    np.testing.assert_allclose(p[0], chain.forward(q)[:3, 3], atol=1e-15)  # foot (sole) frame
    np.testing.assert_allclose(p[-1], 0.0)  # eq. 5
    np.testing.assert_allclose(p[-2], chain.imu_position, atol=1e-15)  # last link


def test_batch_matches_single():
    rng = np.random.default_rng(4)
    chain = nao_leg("right")
    q = rng.uniform(-0.5, 0.5, (7, 6))
    qd = rng.uniform(-1, 1, (7, 6))
    gyro = rng.uniform(-1, 1, (7, 3))
    vk, vkg = chain.velocities_batch(q, qd, gyro)
    for i in range(7):
        a, b = chain.velocities(q[i], qd[i], gyro[i])
        np.testing.assert_array_equal(vk[i], a)
        np.testing.assert_array_equal(vkg[i], b)


# --- inverse kinematics ---------------------------------------------------------------------------------
def test_inverse_kinematics_round_trip():
    rng = np.random.default_rng(5)
    for side in ("left", "right"):
        leg = nao_leg(side)
        for _ in range(10):
            q = np.array([0.0, -0.45, 0.9, -0.45, 0.0, 0.0]) + rng.uniform(-0.2, 0.2, 6)
            target = leg.forward(q)
            solved = leg.inverse(target, q + rng.uniform(-0.1, 0.1, 6))
            np.testing.assert_allclose(leg.forward(solved), target, atol=1e-10)


def test_inverse_kinematics_out_of_reach():
    leg = nao_leg("left")
    target = np.eye(4)
    target[2, 3] = 1.0
    with pytest.raises(ValueError, match="out of reach"):
        leg.inverse(target, np.zeros(6), max_iterations=20)


# --- bad input ------------------------------------------------------------------------------------------
def test_wrong_length_and_nan_are_rejected():
    leg = nao_leg("left")
    with pytest.raises(ValueError, match="angles"):
        leg.forward(np.zeros(5))
    with pytest.raises(ValueError, match="rates"):
        leg.velocities(np.zeros(6), np.zeros(7))
    with pytest.raises(ValueError, match="angles must be finite"):
        leg.velocities([0, 0, np.nan, 0, 0, 0], np.zeros(6))
    with pytest.raises(ValueError, match="gyro"):
        leg.velocities(np.zeros(6), np.zeros(6), [0.0, np.inf, 0.0])
    with pytest.raises(ValueError, match="side"):
        nao_leg("middle")
    with pytest.raises(ValueError, match="imu_rotation"):
        LegChain.from_dh([(0, 1, 0, 0)], imu_rotation=2 * np.eye(3))
    with pytest.raises(ValueError, match="a must have shape"):
        LegChain([0.0, 0.0], [1.0], [0.0, 0.0], [0.0, 0.0])


def test_chain_is_immutable():
    leg = nao_leg("left")
    with pytest.raises(ValueError):
        leg.a[0] = 1.0
    with pytest.raises(AttributeError):
        leg.name = "other"
