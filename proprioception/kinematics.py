"""Leg kinematics in the Denavit–Hartenberg convention, from the foot up to the IMU (Wawrzyński eq. 5–14).

    from proprioception.kinematics import LegChain, nao_leg

    left = nao_leg("left")                       # NAO leg, joints ordered foot → trunk (see `NAO_JOINT_NAMES`)
    pose = left.forward(angles)                  # 4x4 pose of the IMU in the sole frame
    v_k, v_kg = left.velocities(angles, rates, gyro)   # eq. 10 and eq. 14, in the IMU frame

    custom = LegChain.from_dh([(theta0, a, d, alpha), ...], imu_position=..., imu_rotation=...)

Conventions (the paper's, Section III). The chain runs from the foot (the paper's link 1) to the link that
carries the IMU (link n+1). Joint i (1-based) is described by the DH row (θ_i, a_i, d_i, α_i); the transform
from frame i to frame i-1 is Rz(θ_i)·Tz(d_i)·Tx(a_i)·Rx(α_i), joint i turns about z of frame i-1, and the
joint angle given by the caller is added to the row's θ_i (an offset). DH frame 0 is fixed to the foot; its
pose in the sole frame (`base_rotation`, `base_position`) lets the foot frame be a level frame on the sole,
x forward, z up. The IMU pose in the last frame is `imu_position` (p_{n+1}, which the paper takes as 0 in eq. 5)
and `imu_rotation`, whose columns are the IMU axes w^x, w^y, w^z in the last link.

Two printed signs of the paper are not followed, because the finite-difference tests contradict them:
eq. 8 is computed as v_i = R_i v_{i+1} + θ̇_i (z_i × p_i) (the print has p_i × z_i), and the joint axis in
eq. 12 is the joint's own axis z_i (the print writes w_i^z, the IMU's z axis).

Velocities are those of the IMU with respect to the ground, in the IMU's immobile frame, assuming the sole
frame's origin does not move (eq. 10), or that it only turns, at the rate the gyroscope sees (eq. 13–14).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np

from field.checks import real, reals
from numerics.frozen import keeps_arrays_frozen

NAO_JOINT_NAMES = ("AnkleRoll", "AnklePitch", "KneePitch", "HipPitch", "HipRoll", "HipYawPitch")
"""Joint order of the NAO preset, foot → trunk (the NAOqi order, reversed); prefix L or R for the side."""

# Aldebaran's published NAO leg dimensions, in metres.
NAO_HIP_OFFSET_Y = 0.050
NAO_HIP_OFFSET_Z = 0.085
NAO_THIGH_LENGTH = 0.100
NAO_TIBIA_LENGTH = 0.1029
NAO_FOOT_HEIGHT = 0.04519


@dataclass(frozen=True)
class NaoLegDimensions:
    """The five lengths (metres) of a NAO-type leg; the defaults are Aldebaran's published dimensions.

    Parameters
    ----------
    hip_offset_y : float
        Lateral distance of each hip from the torso's middle.
    hip_offset_z : float
        Height of the torso origin above the hips.
    thigh : float
        Hip to knee.
    tibia : float
        Knee to ankle.
    foot_height : float
        Ankle above the sole.

    Raises
    ------
    ValueError
        When a length is not finite and positive.
    """

    hip_offset_y: float = NAO_HIP_OFFSET_Y
    hip_offset_z: float = NAO_HIP_OFFSET_Z
    thigh: float = NAO_THIGH_LENGTH
    tibia: float = NAO_TIBIA_LENGTH
    foot_height: float = NAO_FOOT_HEIGHT

    def __post_init__(self) -> None:
        for name in ("hip_offset_y", "hip_offset_z", "thigh", "tibia", "foot_height"):
            real(name, getattr(self, name), 0.0, low_open=True)  # metres, finite and > 0

    def scaled(self, factors) -> NaoLegDimensions:
        """The dimensions multiplied one by one by `factors`.

        Parameters
        ----------
        factors : sequence of 5 floats
            Factors in the field order (hip_offset_y, hip_offset_z, thigh, tibia, foot_height).

        Returns
        -------
        NaoLegDimensions
            The scaled dimensions.

        Raises
        ------
        ValueError
            When `factors` is not five finite positive numbers.
        """
        f = reals("factors", factors, 5, low=0.0)
        if np.any(f == 0.0):
            raise ValueError(f"factors = {np.asarray(factors).tolist()} must be five finite numbers > 0")
        return NaoLegDimensions(*(float(v) * float(k) for v, k in zip(self.as_tuple(), f)))

    def as_tuple(self) -> tuple[float, float, float, float, float]:
        """The five lengths in the field order.

        Returns
        -------
        tuple of 5 floats
            (hip_offset_y, hip_offset_z, thigh, tibia, foot_height).
        """
        return (self.hip_offset_y, self.hip_offset_z, self.thigh, self.tibia, self.foot_height)


# ---------------------------------------------------------------------------------------------------------
# Small rotation helpers (numba and numpy)
# ---------------------------------------------------------------------------------------------------------
def rotation_x(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_y(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def axis_angle(axis, angle: float) -> np.ndarray:
    """Rotation matrix of `angle` about the unit vector `axis` (Rodrigues)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * (kx @ kx)


def rotation_log(rotation: np.ndarray) -> np.ndarray:
    """Rotation vector (axis times angle) of a rotation matrix."""
    cos_angle = min(1.0, max(-1.0, (np.trace(rotation) - 1.0) / 2.0))
    angle = math.acos(cos_angle)
    skew = np.array([rotation[2, 1] - rotation[1, 2], rotation[0, 2] - rotation[2, 0], rotation[1, 0] - rotation[0, 1]])
    if angle < 1e-9:
        return 0.5 * skew
    if math.pi - angle < 1e-6:
        # Near π the skew part vanishes: take the axis from the symmetric part.
        sym = (rotation + np.eye(3)) / 2.0
        axis = sym[:, int(np.argmax(np.diag(sym)))]
        return angle * axis / np.linalg.norm(axis)
    return angle / (2.0 * math.sin(angle)) * skew


def dh_transform(theta: float, a: float, d: float, alpha: float) -> np.ndarray:
    """4x4 transform of one DH row: Rz(θ)·Tz(d)·Tx(a)·Rx(α) (frame i expressed in frame i-1)."""
    transform = np.eye(4)
    transform[:3, :3] = rotation_z(theta) @ rotation_x(alpha)
    transform[:3, 3] = [a * math.cos(theta), a * math.sin(theta), d]
    return transform


@numba.njit(cache=True, inline="always")
def _cross(u0, u1, u2, w0, w1, w2):
    return u1 * w2 - u2 * w1, u2 * w0 - u0 * w2, u0 * w1 - u1 * w0


@numba.njit(cache=True)
def leg_velocities_kernel(chain, angles, rates, gyro, out_vk, out_vkg):
    """Eq. 5–14 for one sample: IMU velocity from the leg, in the IMU frame, into out_vk (eq. 10), out_vkg (14).

    chain: the leg's arrays (theta_offset, a, d, alpha, base_rotation, base_position, imu_rotation,
    imu_position), as `LegChain.kernel_chain` gives them. Walks the chain from the IMU down to the foot, carrying the IMU position p (eq. 5, 7), its velocity relative
    to the current frame (eq. 6, 8), the IMU axes (eq. 9) and the link's angular velocity (eq. 11, 12).
    """
    theta_offset, a, d, alpha, base_rotation, base_position, imu_rotation, imu_position = chain
    n = a.shape[0]
    p = imu_position.copy()  # eq. 5 (p_{n+1}; zero when the IMU sits at the frame origin)
    v = np.zeros(3)  # eq. 6
    w = imu_rotation.copy()  # columns w^x, w^y, w^z
    omega = imu_rotation @ gyro  # eq. 11
    for j in range(n - 1, -1, -1):
        theta = angles[j] + theta_offset[j]
        ct, st = math.cos(theta), math.sin(theta)
        ca, sa = math.cos(alpha[j]), math.sin(alpha[j])
        rot = np.empty((3, 3))
        rot[0, 0] = ct
        rot[0, 1] = -st * ca
        rot[0, 2] = st * sa
        rot[1, 0] = st
        rot[1, 1] = ct * ca
        rot[1, 2] = -ct * sa
        rot[2, 0] = 0.0
        rot[2, 1] = sa
        rot[2, 2] = ca
        # l_i: origin of frame i (paper numbering) seen from frame i-1 but expressed in frame i axes.
        lp = np.empty(3)
        lp[0] = a[j] + p[0]
        lp[1] = d[j] * sa + p[1]
        lp[2] = d[j] * ca + p[2]
        p = rot @ lp  # eq. 7
        cx, cy, cz = _cross(0.0, 0.0, 1.0, p[0], p[1], p[2])
        v = rot @ v  # eq. 8: rotated, plus the joint's own motion z × p
        v[0] += rates[j] * cx
        v[1] += rates[j] * cy
        v[2] += rates[j] * cz
        w = rot @ w  # eq. 9
        omega = rot @ omega  # eq. 12
        omega[2] -= rates[j]
    # Foot link: from DH frame 0 to the sole frame (rigid, no joint).
    p = base_position + base_rotation @ p
    v = base_rotation @ v
    w = base_rotation @ w
    omega = base_rotation @ omega
    ox, oy, oz = _cross(omega[0], omega[1], omega[2], p[0], p[1], p[2])
    vkg0 = v[0] + ox  # eq. 13
    vkg1 = v[1] + oy
    vkg2 = v[2] + oz
    for k in range(3):
        out_vk[k] = v[0] * w[0, k] + v[1] * w[1, k] + v[2] * w[2, k]  # eq. 10
        out_vkg[k] = vkg0 * w[0, k] + vkg1 * w[1, k] + vkg2 * w[2, k]  # eq. 14


@numba.njit(cache=True)
def leg_velocities_batch_kernel(chain, angles, rates, gyro, out_vk, out_vkg):
    """`leg_velocities_kernel` over rows of (N, n) angles and rates and (N, 3) gyro samples."""
    for i in range(angles.shape[0]):
        leg_velocities_kernel(chain, angles[i], rates[i], gyro[i], out_vk[i], out_vkg[i])


# ---------------------------------------------------------------------------------------------------------
# The chain
# ---------------------------------------------------------------------------------------------------------
def _readonly(x, shape, name) -> np.ndarray:
    arr = np.array(x, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    arr.setflags(write=False)
    return arr


def _check_rotation(rotation: np.ndarray, name: str) -> None:
    if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-9) or np.linalg.det(rotation) < 0.0:
        raise ValueError(f"{name} must be a proper rotation matrix, got {rotation.tolist()}")


@keeps_arrays_frozen
@dataclass(frozen=True, eq=False)
class LegChain:
    """A leg as a DH chain from the foot to the IMU link; see the module docstring for the frames.

    Arrays are read-only float64. `theta_offset`, `a`, `d`, `alpha` have one entry per joint (foot → trunk).
    """

    theta_offset: np.ndarray
    a: np.ndarray
    d: np.ndarray
    alpha: np.ndarray
    base_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    base_position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    imu_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    imu_position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    joint_names: tuple[str, ...] = ()
    name: str = "leg"

    def __post_init__(self):
        theta_offset = np.array(self.theta_offset, dtype=np.float64).reshape(-1)
        n = theta_offset.shape[0]
        if n < 1:
            raise ValueError(f"theta_offset must have at least one joint, got {n}")
        set_ = object.__setattr__
        set_(self, "theta_offset", _readonly(theta_offset, (n,), "theta_offset"))
        for name in ("a", "d", "alpha"):
            set_(self, name, _readonly(np.asarray(getattr(self, name), dtype=np.float64).reshape(-1), (n,), name))
        set_(self, "base_rotation", _readonly(self.base_rotation, (3, 3), "base_rotation"))
        set_(self, "base_position", _readonly(self.base_position, (3,), "base_position"))
        set_(self, "imu_rotation", _readonly(self.imu_rotation, (3, 3), "imu_rotation"))
        set_(self, "imu_position", _readonly(self.imu_position, (3,), "imu_position"))
        _check_rotation(self.base_rotation, "base_rotation")
        _check_rotation(self.imu_rotation, "imu_rotation")
        names = tuple(self.joint_names) if self.joint_names else tuple(f"joint{i + 1}" for i in range(n))
        if len(names) != n:
            raise ValueError(f"joint_names must name {n} joints, got {len(names)}")
        set_(self, "joint_names", names)

    @classmethod
    def from_dh(cls, rows, **kwargs) -> LegChain:
        """Chain from DH rows (θ offset, a, d, α), one per joint, foot → trunk; other fields by keyword."""
        table = np.asarray(rows, dtype=np.float64)
        if table.ndim != 2 or table.shape[1] != 4:
            raise ValueError(f"rows must be a sequence of (theta, a, d, alpha), got shape {table.shape}")
        return cls(table[:, 0], table[:, 1], table[:, 2], table[:, 3], **kwargs)

    @property
    def n_joints(self) -> int:
        return self.a.shape[0]

    # --- validation --------------------------------------------------------------------------------------
    def _joint_vector(self, values, name: str) -> np.ndarray:
        arr = np.asarray(values, dtype=np.float64)
        if arr.shape != (self.n_joints,):
            raise ValueError(f"{name} must have shape ({self.n_joints},) for {self.name}, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite, got {arr.tolist()}")
        return np.ascontiguousarray(arr)

    # --- forward kinematics ------------------------------------------------------------------------------
    def frames(self, angles) -> np.ndarray:
        """Poses in the sole frame of DH frames 0..n and of the IMU: (n+2, 4, 4)."""
        angles = self._joint_vector(angles, "angles")
        out = np.empty((self.n_joints + 2, 4, 4))
        pose = np.eye(4)
        pose[:3, :3] = self.base_rotation
        pose[:3, 3] = self.base_position
        out[0] = pose
        for j in range(self.n_joints):
            pose = pose @ dh_transform(angles[j] + self.theta_offset[j], self.a[j], self.d[j], self.alpha[j])
            out[j + 1] = pose
        imu = np.eye(4)
        imu[:3, :3] = self.imu_rotation
        imu[:3, 3] = self.imu_position
        out[-1] = pose @ imu
        return out

    def forward(self, angles) -> np.ndarray:
        """4x4 pose of the IMU in the sole frame."""
        return self.frames(angles)[-1]

    def imu_positions(self, angles) -> np.ndarray:
        """IMU position p_i in every frame, eq. 5–7: row 0 the sole frame, row j+1 DH frame j, last the IMU (n+3, 3)."""
        frames = self.frames(angles)
        imu = frames[-1, :3, 3]
        return np.array([imu] + [f[:3, :3].T @ (imu - f[:3, 3]) for f in frames[:-1]] + [np.zeros(3)])

    def jacobian(self, angles) -> np.ndarray:
        """Geometric Jacobian (6, n) of the IMU pose in the sole frame: rows (linear velocity, angular)."""
        frames = self.frames(angles)
        tip = frames[-1, :3, 3]
        jac = np.empty((6, self.n_joints))
        for j in range(self.n_joints):
            axis = frames[j, :3, 2]
            jac[:3, j] = np.cross(axis, tip - frames[j, :3, 3])
            jac[3:, j] = axis
        return jac

    # --- velocities (eq. 5–14) ---------------------------------------------------------------------------
    def kernel_chain(self) -> tuple[np.ndarray, ...]:
        """The group `chain` of the velocity kernels: (theta_offset, a, d, alpha, base_rotation, base_position,
        imu_rotation, imu_position)."""
        return (
            self.theta_offset,
            self.a,
            self.d,
            self.alpha,
            self.base_rotation,
            self.base_position,
            self.imu_rotation,
            self.imu_position,
        )

    def velocities(self, angles, rates, gyro=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """(v^K, v^KG): IMU velocity in its immobile frame from the leg alone (eq. 10) and with the gyro (eq. 14)."""
        angles = self._joint_vector(angles, "angles")
        rates = self._joint_vector(rates, "rates")
        gyro = np.asarray(gyro, dtype=np.float64)
        if gyro.shape != (3,) or not np.all(np.isfinite(gyro)):
            raise ValueError(f"gyro must be 3 finite numbers, got {np.asarray(gyro).tolist()}")
        vk, vkg = np.empty(3), np.empty(3)
        leg_velocities_kernel(self.kernel_chain(), angles, rates, gyro, vk, vkg)
        return vk, vkg

    def velocities_batch(self, angles, rates, gyro) -> tuple[np.ndarray, np.ndarray]:
        """`velocities` over rows: angles, rates (N, n), gyro (N, 3) → v^K, v^KG (N, 3)."""
        angles = np.ascontiguousarray(angles, dtype=np.float64)
        rates = np.ascontiguousarray(rates, dtype=np.float64)
        gyro = np.ascontiguousarray(gyro, dtype=np.float64)
        n = self.n_joints
        if angles.ndim != 2 or angles.shape[1] != n:
            raise ValueError(f"angles must have shape (N, {n}), got {angles.shape}")
        if rates.shape != angles.shape:
            raise ValueError(f"rates must have shape {angles.shape}, got {rates.shape}")
        if gyro.shape != (angles.shape[0], 3):
            raise ValueError(f"gyro must have shape ({angles.shape[0]}, 3), got {gyro.shape}")
        for name, arr in (("angles", angles), ("rates", rates), ("gyro", gyro)):
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{name} must be finite")
        vk = np.empty((angles.shape[0], 3))
        vkg = np.empty((angles.shape[0], 3))
        leg_velocities_batch_kernel(self.kernel_chain(), angles, rates, gyro, vk, vkg)
        return vk, vkg

    # --- inverse kinematics ------------------------------------------------------------------------------
    def inverse(self, target, initial, *, tolerance: float = 1e-11, max_iterations: int = 100) -> np.ndarray:
        """Joint angles putting the IMU at the 4x4 `target` pose (in the sole frame), by damped Newton steps.

        Starts from `initial` (the branch found is the one nearest to it). Raises ValueError when the pose
        cannot be reached to `tolerance`.
        """
        target = np.asarray(target, dtype=np.float64)
        if target.shape != (4, 4) or not np.all(np.isfinite(target)):
            raise ValueError(f"target must be a finite 4x4 pose, got shape {target.shape}")
        angles = self._joint_vector(initial, "initial").copy()
        damping = 1e-6
        error_norm = np.inf
        for _ in range(max_iterations):
            pose = self.forward(angles)
            error = np.concatenate([target[:3, 3] - pose[:3, 3], rotation_log(target[:3, :3] @ pose[:3, :3].T)])
            error_norm = float(np.linalg.norm(error))
            if error_norm < tolerance:
                return angles
            jac = self.jacobian(angles)
            step = np.linalg.solve(jac.T @ jac + damping * np.eye(self.n_joints), jac.T @ error)
            angles = angles + step
        raise ValueError(
            f"target is out of reach of {self.name}: residual {error_norm:.3g} after {max_iterations} iterations"
        )


def nao_leg(
    side: str = "left",
    imu_offset=(0.0, 0.0, 0.0),
    dimensions: NaoLegDimensions = NaoLegDimensions(),
    joint_offsets=None,
) -> LegChain:
    """The NAO leg from Aldebaran's published dimensions, joints foot → trunk (`NAO_JOINT_NAMES`).

    Angles are NAOqi joint angles: at zero the leg hangs straight with the sole level under the hip. Axes in
    the torso frame (x forward, y left, z up): roll joints about +x, pitch joints about +y, hip yaw-pitch
    about (0, 1, -1)/√2 for the left leg and (0, 1, 1)/√2 for the right. The sole frame is level at zero,
    origin under the ankle, x forward. The IMU frame is the torso frame shifted by `imu_offset` (metres,
    torso axes); the torso origin is 85 mm above the hips, midway between them.

    Parameters
    ----------
    side : str
        "left" or "right".
    imu_offset : sequence of 3 floats
        The IMU's position in the torso frame, metres.
    dimensions : NaoLegDimensions
        The leg's lengths (default: the published ones). Another leg of the same kind, e.g. one whose links
        differ from the drawings, is `nao_leg(side, dimensions=NaoLegDimensions(...))`.
    joint_offsets : sequence of 6 floats or None
        Radians added to each joint's zero (foot → trunk), e.g. an encoder's zero that is off; None: none.

    Returns
    -------
    LegChain
        The leg as a DH chain with the IMU pose set.

    Raises
    ------
    ValueError
        On an unknown side, a `dimensions` that is not a NaoLegDimensions, or joint offsets that are not six
        finite numbers.
    """
    if side not in ("left", "right"):
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")
    if not isinstance(dimensions, NaoLegDimensions):
        raise ValueError(f"dimensions must be a NaoLegDimensions, got {type(dimensions).__name__}")
    offsets = np.zeros(6) if joint_offsets is None else reals("joint_offsets", joint_offsets, 6)  # radians
    dims = dimensions
    mirror = 1.0 if side == "left" else -1.0
    half_pi = math.pi / 2.0
    # Reversing the chain (trunk relative to foot) turns each joint the other way, so every DH z axis
    # points against the NAO joint axis and the DH angle equals the NAOqi angle.
    rows = [
        (0.0, 0.0, 0.0, half_pi),  # ankle roll: z0 = -x, x1 = up
        (0.0, dims.tibia, 0.0, 0.0),  # ankle pitch: z1 = -y, up the tibia to the knee
        (0.0, dims.thigh, 0.0, 0.0),  # knee pitch: z2 = -y, up the thigh to the hip
        (0.0, 0.0, 0.0, -half_pi),  # hip pitch: z3 = -y, to z4 = -x
        (mirror * math.pi / 4.0, 0.0, 0.0, half_pi),  # hip roll: z4 = -x, to z5 = -(yaw-pitch axis)
        (0.0, 0.0, 0.0, 0.0),  # hip yaw-pitch: frame 6 is fixed to the torso
    ]
    base_rotation = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # columns x0 = up, y0 = y, z0 = -x
    prefix = "L" if side == "left" else "R"
    provisional = LegChain.from_dh(rows, base_rotation=base_rotation, base_position=(0.0, 0.0, dims.foot_height))
    # IMU pose in the last DH frame, from the zero pose: torso straight above the sole.
    last = provisional.frames(np.zeros(6))[-2]
    torso = np.eye(4)
    torso[:3, 3] = np.asarray(imu_offset, dtype=np.float64) + (
        0.0,
        -mirror * dims.hip_offset_y,
        dims.foot_height + dims.tibia + dims.thigh + dims.hip_offset_z,
    )
    imu_in_last = np.linalg.inv(last) @ torso
    rotation = imu_in_last[:3, :3]
    # Remove rounding so the rotation check is exact.
    u, _, vt = np.linalg.svd(rotation)
    rotation = u @ vt
    # Joint offsets go in after the IMU pose is fixed: the leg's zero pose moves, the torso stays on the chain.
    rows = [(theta + float(offset), a, d, alpha) for (theta, a, d, alpha), offset in zip(rows, offsets)]
    return LegChain.from_dh(
        rows,
        base_rotation=base_rotation,
        base_position=(0.0, 0.0, dims.foot_height),
        imu_rotation=rotation,
        imu_position=imu_in_last[:3, 3],
        joint_names=tuple(prefix + name for name in NAO_JOINT_NAMES),
        name=f"NAO {side} leg",
    )


def nao_leg_reference_pose(side: str, angles, imu_offset=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Pose of the NAO IMU in the sole frame from the joint axes directly (no DH): an independent check."""
    mirror = 1.0 if side == "left" else -1.0
    q_ankle_roll, q_ankle_pitch, q_knee, q_hip_pitch, q_hip_roll, q_hip_yaw_pitch = np.asarray(angles, float)

    def rot(r):
        t = np.eye(4)
        t[:3, :3] = r
        return t

    def trans(x, y, z):
        t = np.eye(4)
        t[:3, 3] = (x, y, z)
        return t

    yaw_pitch_axis = np.array([0.0, 1.0, -mirror]) / math.sqrt(2.0)
    # Torso → sole with NAOqi angles, then inverted.
    torso_to_sole = (
        trans(0.0, mirror * NAO_HIP_OFFSET_Y, -NAO_HIP_OFFSET_Z)
        @ rot(axis_angle(yaw_pitch_axis, q_hip_yaw_pitch))
        @ rot(rotation_x(q_hip_roll))
        @ rot(rotation_y(q_hip_pitch))
        @ trans(0.0, 0.0, -NAO_THIGH_LENGTH)
        @ rot(rotation_y(q_knee))
        @ trans(0.0, 0.0, -NAO_TIBIA_LENGTH)
        @ rot(rotation_y(q_ankle_pitch))
        @ rot(rotation_x(q_ankle_roll))
        @ trans(0.0, 0.0, -NAO_FOOT_HEIGHT)
    )
    imu = trans(*np.asarray(imu_offset, dtype=np.float64))
    return np.linalg.inv(torso_to_sole) @ imu
