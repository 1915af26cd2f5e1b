"""Footstep displacements (Rouxel et al. section III-A, Fig. 3) and their inverse, and the footstep event.

    import numpy as np
    from motion_models.footsteps import FootstepEvent, displacements, integrate, LEFT, RIGHT

    steps = displacements(poses_at_swaps)          # (K+1, 3) poses -> (K, 3) [dx, dy, dθ] per step
    again = integrate(steps, start=poses_at_swaps[0])   # (K+1, 3): the trajectory back
    event = FootstepEvent(support=LEFT, commanded=(0.04, 0.0, 0.1), previous_commanded=(0.03, 0.0, 0.1),
                          sensor=(0.035, 0.002, 0.11), previous_sensor=(0.028, -0.001, 0.09),
                          duration=0.29, previous_duration=0.30)
    event.inputs("apriori")     # the 7 LWPR inputs of section III-C; event.inputs("online"): the 9

A footstep displacement is the change of the robot's reference pose between two consecutive support-foot
swaps, expressed in the robot frame at the earlier swap (+x forward, +y left): for poses p_k = (x, y, θ)
at the swaps, Δ_k = (R(-θ_k)·(x_{k+1} - x_k, y_{k+1} - y_k), wrap(θ_{k+1} - θ_k)). `integrate` composes
them back: the paper's "re-integration" of predicted footsteps (section III-D). Both are vectorized numpy;
the per-particle hot path of a footstep model is `motion_models.kernels.move_with_noise`.

Support foot: `LEFT` (+1) when the left foot is on the ground during the step, `RIGHT` (-1) otherwise; the
LWPR inputs use this ±1 value as the paper's binary support-foot variable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from field.angles import wrap_angles

from .base import _finite_triple

LEFT = 1
RIGHT = -1
INPUT_KINDS = ("apriori", "online")
N_INPUTS = {"apriori": 7, "online": 9}


def _poses_array(poses, name: str) -> np.ndarray:
    array = np.asarray(poses, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"{name} must have shape (K, 3), got shape {array.shape}")
    if not np.isfinite(array).all():
        row = int(np.flatnonzero(~np.isfinite(array).all(axis=1))[0])
        raise ValueError(f"{name} must be finite, row {row} is {array[row].tolist()}")
    return array


def displacements(poses) -> np.ndarray:
    """The displacement (dx, dy, dθ) of each step between consecutive poses (K+1, 3), in the frame of the
    earlier pose (Rouxel Fig. 3). Returns (K, 3); dθ is wrapped to (-π, π]."""
    p = _poses_array(poses, "poses")
    if p.shape[0] < 1:
        raise ValueError("poses must hold at least one pose")
    delta = p[1:, :2] - p[:-1, :2]
    c, s = np.cos(p[:-1, 2]), np.sin(p[:-1, 2])
    out = np.empty((p.shape[0] - 1, 3))
    out[:, 0] = c * delta[:, 0] + s * delta[:, 1]
    out[:, 1] = -s * delta[:, 0] + c * delta[:, 1]
    out[:, 2] = wrap_angles(p[1:, 2] - p[:-1, 2])
    return out


def integrate(steps, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Compose step displacements (K, 3) from `start` (x, y, θ): the poses at the K+1 swaps (K+1, 3).

    The inverse of `displacements`: the heading before step k is θ_0 + Σ_{j<k} dθ_j, and each step's
    (dx, dy) is turned by it. Headings are accumulated unwrapped and wrapped once at the end, so a long
    walk loses no precision to repeated wrapping.
    """
    d = _poses_array(steps, "steps")
    s0 = np.asarray(start, dtype=np.float64)
    if s0.shape != (3,) or not np.isfinite(s0).all():
        raise ValueError(f"start = {start!r} must be three finite numbers")
    heading = s0[2] + np.concatenate(([0.0], np.cumsum(d[:, 2])))
    c, s = np.cos(heading[:-1]), np.sin(heading[:-1])
    out = np.empty((d.shape[0] + 1, 3))
    out[0, :2] = s0[:2]
    out[1:, 0] = s0[0] + np.cumsum(c * d[:, 0] - s * d[:, 1])
    out[1:, 1] = s0[1] + np.cumsum(s * d[:, 0] + c * d[:, 1])
    out[:, 2] = wrap_angles(heading)
    return out


def _duration(name: str, value) -> float | None:
    if value is None:
        return None
    try:
        d = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} must be a number of seconds") from None
    if not (math.isfinite(d) and d > 0):
        raise ValueError(f"{name} = {value!r} must be finite and > 0")
    return d


@dataclass(frozen=True)
class FootstepEvent:
    """One support-foot swap: what the footstep models need about the step that just ended.

    support:            LEFT (+1) or RIGHT (-1), the foot on the ground during the step (pressure sensors).
    commanded:          the gait command of the step, as the displacement (dx, dy, dθ) [m, m, rad] the
                        kinematic model computes from the motor goal positions (the "simulation-based"
                        odometry of section III).
    previous_commanded: the same for the step before ((0, 0, 0) when standing before it).
    sensor:             the displacement from the joint encoders through the kinematic model, yaw from the
                        gyro (the "sensor-based" odometry); None for an a-priori-only event.
    previous_sensor:    the same for the step before.
    duration:           the step's duration between the two swaps the pressure sensors detected [s].
    previous_duration:  the same for the step before.

    Parameters
    ----------
    support : int
        `LEFT` (+1) or `RIGHT` (-1).
    commanded : tuple of float
        (dx [m], dy [m], dθ [rad]) of the step from the gait command.
    previous_commanded : tuple of float, optional
        The same for the step before; default (0, 0, 0).
    sensor, previous_sensor : tuple of float or None, optional
        Sensor-based (dx [m], dy [m], dθ [rad]) of the step and of the one before; default None.
    duration, previous_duration : float or None, optional
        Durations [s] of the step and of the one before; default None.

    Raises
    ------
    ValueError
        If `support` is neither foot, a displacement is not three finite numbers, or a duration is invalid.
    """

    support: int
    commanded: tuple[float, float, float]
    previous_commanded: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sensor: tuple[float, float, float] | None = None
    previous_sensor: tuple[float, float, float] | None = None
    duration: float | None = None
    previous_duration: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.support, bool) or self.support not in (LEFT, RIGHT):
            raise ValueError(f"support = {self.support!r} must be LEFT (+1) or RIGHT (-1)")
        object.__setattr__(self, "support", int(self.support))
        if self.commanded is None:
            raise ValueError("commanded = None: a footstep event needs the commanded displacement")
        for name in ("commanded", "previous_commanded", "sensor", "previous_sensor"):
            object.__setattr__(self, name, _finite_triple(name, getattr(self, name)))
        if self.previous_commanded is None:
            raise ValueError("previous_commanded = None: give (0, 0, 0) for a step from standing")
        for name in ("duration", "previous_duration"):
            object.__setattr__(self, name, _duration(name, getattr(self, name)))

    def has_online_inputs(self) -> bool:
        """Whether the event carries everything the 9 online inputs need."""
        return None not in (self.sensor, self.previous_sensor, self.duration, self.previous_duration)

    def inputs(self, kind: str) -> np.ndarray:
        """The LWPR input vector of section III-C: "apriori" (7) or "online" (9).

        apriori: Δ(x, y, θ)_t, Δ(x, y, θ)_{t-1} commanded, support foot.
        online:  Δ(x, y, θ)_t, Δ(x, y, θ)_{t-1} sensor-based, support foot, step durations t and t-1.

        Parameters
        ----------
        kind : str
            "apriori" or "online" (`INPUT_KINDS`).

        Returns
        -------
        np.ndarray
            (7,) or (9,) float64 input vector.

        Raises
        ------
        ValueError
            If `kind` is neither, or "online" and the event lacks a sensor displacement or a duration.
        """
        if kind == "apriori":
            return np.array([*self.commanded, *self.previous_commanded, float(self.support)])
        if kind == "online":
            sensor, previous_sensor = self.sensor, self.previous_sensor
            if sensor is None or previous_sensor is None or self.duration is None or self.previous_duration is None:
                missing = [
                    n
                    for n in ("sensor", "previous_sensor", "duration", "previous_duration")
                    if getattr(self, n) is None
                ]
                raise ValueError(f"footstep event lacks {', '.join(missing)}: the online inputs need them")
            return np.array([*sensor, *previous_sensor, float(self.support), self.duration, self.previous_duration])
        raise ValueError(f"kind = {kind!r} must be one of {INPUT_KINDS}")


def input_matrix(kind: str, support, commanded, sensor=None, duration=None) -> np.ndarray:
    """The LWPR inputs of steps 1..K-1 of a log (step 0 has no previous step): (K-1, 7) or (K-1, 9).

    Row k-1 equals `FootstepEvent(...).inputs(kind)` of step k built from rows k and k-1 of the arrays:
    support (K,), commanded (K, 3), sensor (K, 3), duration (K,).
    """
    if kind not in INPUT_KINDS:
        raise ValueError(f"kind = {kind!r} must be one of {INPUT_KINDS}")
    support = np.asarray(support, dtype=np.float64)
    if support.ndim != 1 or not np.isin(support, (LEFT, RIGHT)).all():
        raise ValueError(f"support must be a 1-D array of LEFT (+1) / RIGHT (-1), got {support!r:.80}")
    k = support.shape[0]
    if kind == "apriori":
        c = _poses_array(commanded, "commanded")
        if c.shape[0] != k:
            raise ValueError(f"commanded has {c.shape[0]} rows, support {k}")
        return np.column_stack([c[1:], c[:-1], support[1:]])
    if sensor is None or duration is None:
        raise ValueError("the online inputs need sensor and duration")
    s = _poses_array(sensor, "sensor")
    d = np.asarray(duration, dtype=np.float64)
    if s.shape[0] != k or d.shape != (k,):
        raise ValueError(f"sensor has {s.shape[0]} rows and duration shape {d.shape}; support has {k} rows")
    if not (np.isfinite(d).all() and (d > 0).all()):
        raise ValueError("duration must be finite and > 0")
    return np.column_stack([s[1:], s[:-1], support[1:], d[1:], d[:-1]])
