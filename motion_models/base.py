"""The motion model interface: what a model takes (`MotionInput`) and what it must do (`MotionModel`).

    from motion_models import MotionInput, VelocityLinear

    u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1))        # walk request: vx, vy [m/s], omega [rad/s]
    VelocityLinear().predict(poses, u, rng)                  # poses (N, 3) updated in place

A model reads the fields of `MotionInput` it needs and raises `ValueError` naming the missing one.
Every field is in SI units and in the robot frame (+x forward, +y left).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from field.checks import LARGEST_ANGLE, ArgumentTypeError, real, reals
from numerics.random import draw_variates

from .kernels import move_with_noise

# The largest pose change one motion input may ask for: far beyond any robot's step (a field is at most 22 m
# long), small enough that every pose a filter computes from it stays finite. A larger one is refused with a
# ValueError naming the input, before any filter state changes.
MAX_STEP_DISTANCE = 100.0  # m, |(dx, dy)|
MAX_STEP_TURN = LARGEST_ANGLE  # rad, |dθ|
MAX_STEP_DT = 3600.0  # s: one step of at most an hour (a log's longest gap)


def _finite_triple(name: str, value: Any) -> tuple[float, float, float] | None:
    if value is None:
        return None
    if type(value) is tuple and len(value) == 3 and all(type(v) is float and math.isfinite(v) for v in value):
        return value  # the common case, without numpy
    return tuple(float(v) for v in reals(name, value, 3))  # type: ignore[return-value]


@dataclass(frozen=True)
class MotionInput:
    """What the robot did since the previous filter step.

    dt:        time since the previous step [s], finite, >= 0 and at most `MAX_STEP_DT` (an hour).
    The pose change the input implies (`displacement()`) must be finite and at most `MAX_STEP_DISTANCE` (100 m)
    and `MAX_STEP_TURN` (100 rad): anything larger is refused here, so no filter computes a non-finite pose.
    command:   the walk request m = (vx, vy, omega) [m/s, m/s, rad/s] (Hoffmann eq. 4).
    odometry:  measured pose change (dx, dy, dtheta) [m, m, rad] in the robot frame at the previous pose.
    collision: a collision percept (used by collision-aware models).
    footstep:  a support-foot swap event (used by footstep models).

    Parameters
    ----------
    dt : float
        Time since the previous step [s], within [0, `MAX_STEP_DT`].
    command : tuple of float or None, optional
        The walk request (vx [m/s], vy [m/s], omega [rad/s]); None (the default) when not known.
    odometry : tuple of float or None, optional
        Measured pose change (dx [m], dy [m], dtheta [rad]) in the robot frame; None (the default) when not
        measured.
    collision : object, optional
        A collision percept (`proprioception.collision`) for collision-aware models; default None.
    footstep : object, optional
        A support-foot swap event (`motion_models.footsteps.FootstepEvent`) for footstep models; default None.

    Raises
    ------
    ValueError
        If `dt` is out of range, `command` or `odometry` is not three finite numbers, or the implied pose
        change is too large (naming the field).
    """

    dt: float
    command: tuple[float, float, float] | None = None
    odometry: tuple[float, float, float] | None = None
    collision: Any = None
    footstep: Any = None

    def __post_init__(self) -> None:
        dt = real("dt", self.dt, 0.0, MAX_STEP_DT)
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "command", _finite_triple("command", self.command))
        object.__setattr__(self, "odometry", _finite_triple("odometry", self.odometry))
        if self.odometry is not None or self.command is not None:
            try:
                dx, dy, dtheta = self.displacement()
            except (ValueError, OverflowError):  # sin/cos of an infinite turn
                dx = dy = dtheta = math.inf
            name = "odometry" if self.odometry is not None else f"dt = {dt!r} with command"
            value = self.odometry if self.odometry is not None else self.command
            distance = math.hypot(dx, dy)
            if not (distance <= MAX_STEP_DISTANCE and abs(dtheta) <= MAX_STEP_TURN):
                raise ValueError(
                    f"{name} = {value!r} moves the robot by {distance:.3g} m and {dtheta:.3g} rad in "
                    f"one step; at most {MAX_STEP_DISTANCE:g} m and {MAX_STEP_TURN:g} rad are accepted"
                )

    def displacement(self) -> tuple[float, float, float]:
        """The intended pose change (dx, dy, dtheta) in the robot frame: odometry if given, else dt * command.

        A command is integrated exactly along its constant-velocity arc (the chord, turned by half the
        turn), so that a curved walk request lands where the robot would be at any step length.
        """
        if self.odometry is not None:
            return self.odometry
        if self.command is None:
            raise ValueError("MotionInput has neither command nor odometry: the model needs one of them")
        vx, vy, omega = self.command
        half_turn = 0.5 * omega * self.dt
        # The chord of a constant-velocity arc: length |v|·dt·sin(h)/h, direction turned by h = ω·dt/2.
        chord = math.sin(half_turn) / half_turn if abs(half_turn) > 1e-9 else 1.0 - half_turn * half_turn / 6.0
        c, s = chord * math.cos(half_turn), chord * math.sin(half_turn)
        return ((c * vx - s * vy) * self.dt, (s * vx + c * vy) * self.dt, omega * self.dt)


@runtime_checkable
class MotionModel(Protocol):
    """Moves particles by one motion input. Implementations are frozen dataclasses."""

    def check(self, u: MotionInput) -> None:
        """Raise ValueError if `u` lacks what this model needs. Must not draw random numbers.

        Parameters
        ----------
        u : MotionInput
            One control period's motion input.

        Raises
        ------
        ValueError
            If `u` lacks what the model needs (naming the field).
        """

    def predict(self, poses: np.ndarray, u: MotionInput, rng: np.random.Generator) -> None:
        """Update `poses` (N, 3) float64 C-contiguous in place.

        Parameters
        ----------
        poses : np.ndarray
            (N, 3) float64 C-contiguous, writeable particle poses (x [m], y [m], θ [rad]), moved in place.
        u : MotionInput
            One control period's motion input.
        rng : np.random.Generator
            The only source of randomness.
        """


def check_poses(poses: np.ndarray) -> None:
    """The particle array contract shared by every model (see DESIGN.md: float64 (N, 3) C-contiguous)."""
    if not isinstance(poses, np.ndarray) or poses.dtype != np.float64 or poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(
            f"poses must be a float64 array of shape (N, 3), got {getattr(poses, 'dtype', type(poses))} "
            f"{getattr(poses, 'shape', '')}"
        )
    if not poses.flags.c_contiguous or not poses.flags.writeable:
        raise ValueError("poses must be C-contiguous and writeable (models update them in place)")


MAX_NOISE_PARAMETER = 100.0
"""The largest noise parameter a model accepts (a rate per second, or noise per unit of speed or motion): fifty
times any default. With a step's bounds it keeps one step's noise within 4·10⁵ m or rad, where every pose
stays finite and every heading wraps exactly."""


# -- the noise's dependence on the update rate ------------------------------------------------------------------
REFERENCE_DT = 0.01
"""The update period [s] the default noise parameters were chosen at (a 100 Hz loop): with
`noise_rate="per_second"` a model's noise at this period is exactly its per-step form."""
REFERENCE_DT_TOLERANCE = 1e-9
"""A period within this many seconds of `REFERENCE_DT` counts as it: timestamps differenced in floating point
give 0.010000000000000009 s for a 100 Hz loop, and a factor of 1 - 4·10⁻¹⁶ would change every bit downstream."""
SHORTEST_NOISE_DT = 1e-4
"""The shortest period [s] the per-second scaling assumes (a 10 kHz loop): a shorter one (a zero dt from a clock
glitch, with odometry) is scaled as this one, so the factor stays at most sqrt(REFERENCE_DT / SHORTEST_NOISE_DT)
= 10 and every bound finite."""
NOISE_RATES = ("per_second", "per_step")
"""The values of a model's `noise_rate`: how its noise parameters depend on the update rate.

"per_second" (the default): the parameters set the spread accumulated per second of motion, whatever the
update rate. Each step's noise is the per-step form scaled by `noise_rate_factor(dt)` = sqrt(REFERENCE_DT / dt):
independent per-step draws add their variances, so over T seconds the spread is that of T / REFERENCE_DT steps
at the reference period. A 10 s walk spreads the same at 30, 100 and 200 Hz.

"per_step": the paper's form as written (Hoffmann eq. 10): each step's half-width is Δt·β·|v|, so the spread
accumulated over T seconds scales with sqrt(Δt·T) and the parameters hold for one update rate only (scale β by
sqrt(REFERENCE_DT / Δt) to keep a spread at another)."""


def check_noise_rate(value: Any) -> str:
    """`value` if it is one of `NOISE_RATES`; ValueError naming `noise_rate` otherwise (TypeError,
    `field.checks.ArgumentTypeError`, unless it is a string)."""
    if not isinstance(value, str):
        raise ArgumentTypeError(
            f"noise_rate = {value!r} must be a string, one of {NOISE_RATES}, not {type(value).__name__}"
        )
    if value not in NOISE_RATES:
        raise ValueError(f"noise_rate = {value!r} must be one of {NOISE_RATES}")
    return value


def noise_rate_factor(dt: float, noise_rate: str = "per_second") -> float:
    """The factor on a step's per-step noise (half-widths, or standard deviations) for a step of `dt` seconds.

    "per_step": 1.0. "per_second": sqrt(REFERENCE_DT / dt), exactly 1.0 at `REFERENCE_DT` (within
    `REFERENCE_DT_TOLERANCE`), so a filter at 100 Hz moves its particles bit for bit as with "per_step"; a dt
    below `SHORTEST_NOISE_DT` is scaled as that (the factor is at most 10).

    Parameters
    ----------
    dt : float
        The step's period [s], >= 0.
    noise_rate : str, optional
        One of `NOISE_RATES`; default "per_second".

    Returns
    -------
    float
        The factor, > 0.
    """
    if noise_rate == "per_step" or abs(dt - REFERENCE_DT) <= REFERENCE_DT_TOLERANCE:
        return 1.0
    return math.sqrt(REFERENCE_DT / max(dt, SHORTEST_NOISE_DT))


def scaled(bounds: tuple[float, float, float], factor: float) -> tuple[float, float, float]:
    """`bounds` times `factor`, returned unchanged (the same floats) when `factor` is 1.0."""
    if factor == 1.0:
        return bounds
    return (bounds[0] * factor, bounds[1] * factor, bounds[2] * factor)


def check_nonnegative(obj, names: tuple[str, ...]) -> None:
    """Validate that each named parameter of a frozen model is a number within [0, `MAX_NOISE_PARAMETER`]."""
    for name in names:
        real(name, getattr(obj, name), 0.0, MAX_NOISE_PARAMETER)


class BoundedNoiseModel:
    """Shared behaviour of the models that move by the input's displacement plus robot-frame noise.

    A subclass (a frozen dataclass with a `gaussian` field and a `noise_rate` field, one of `NOISE_RATES`)
    defines `noise_bounds(u)`: the half-widths of the uniform noise per axis (or, with `gaussian`, sqrt(3)
    times its standard deviation), its per-step form scaled by `noise_rate_factor(u.dt, noise_rate)`.
    """

    gaussian: bool

    def check(self, u: MotionInput) -> None:
        """Raise ValueError if `u` has neither a command nor odometry (it has no displacement).

        Parameters
        ----------
        u : MotionInput
            As `MotionModel.check`; ValueError when it has neither `command` nor `odometry`.
        """
        u.displacement()

    def noise_bounds(self, u: MotionInput) -> tuple[float, float, float]:
        """The uniform noise's half-widths (x [m], y [m], θ [rad]) for `u` (with `gaussian`, sqrt(3) times the
        standard deviations); each subclass defines them (`mcl.contracts.BoundedNoise`).

        Parameters
        ----------
        u : MotionInput
            The period's motion input.
        """
        raise NotImplementedError

    def predict(self, poses: np.ndarray, u: MotionInput, rng: np.random.Generator) -> None:
        """Move `poses` in place by the input's displacement plus robot-frame noise within `noise_bounds(u)`.

        Parameters
        ----------
        poses, u, rng
            As `MotionModel.predict`; ValueError when `poses` breaks the particle array contract or `u` has no
            displacement.
        """
        check_poses(poses)
        dx, dy, dtheta = u.displacement()
        bx, by, bt = self.noise_bounds(u)
        move_with_noise(
            poses, dx, dy, dtheta, bx, by, bt, self.gaussian, draw_variates(rng, poses.shape[0], self.gaussian)
        )
