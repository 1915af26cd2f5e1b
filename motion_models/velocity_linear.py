"""`VelocityLinear`: the GermanTeam motion model, noise linear in the walking speed (Hoffmann eq. 7-10).

    from motion_models import VelocityLinear, MotionInput
    model = VelocityLinear()                       # documented defaults, see below
    model.predict(poses, MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)), rng)

Each particle moves by the requested displacement Δr = Δt·m (eq. 5) and then receives, in the robot frame,

    Δt · (β1|v| rand(-1,1),  β2|v| rand(-1,1),  (β3|v| + β4|ω|) rand(-1,1))              (eq. 10)

with |v| = sqrt(ẋ² + ẏ²) (eq. 9). `gaussian=True` draws normal noise of the same variance instead.
With odometry instead of a command, |v| and ω are the odometry's displacement divided by dt.

Units and defaults. We read eq. 10 in SI: β1, β2, β4 are dimensionless and β3 is in rad/m. The paper's
β'ᵢ = 8 ms·βᵢ (β'1 = 0.1 ms, β'2 = 0.02 ms, β'3 = 0.002 (rad/m) ms, β'4 = 0.2 ms) are ambiguous: read
literally they give β1 = 0.0125, an along-track spread of 0.07 % of the distance after one second, far too
tight for a walking robot; read with "ms" as a misprint for seconds they give β1 = 12.5, a spread of 65 %.
So the defaults below are chosen, not copied: at 100 Hz the along-track spread after one second of walking
is 10 % of the distance walked (β1 = 1.7; measured by `tests/test_motion_models.py`), lateral and
rotational terms keep the paper's ordering (β2 < β1, β4 dominant when turning).

Update rate (`noise_rate`). Eq. 10 as written draws a new noise every step, so over T seconds its spread
scales with sqrt(Δt·T): β chosen at 100 Hz would spread a walk by sqrt(3.3) times more at 30 Hz. By default
(`noise_rate="per_second"`) each step's half-widths are eq. 10's times sqrt(REFERENCE_DT / Δt), REFERENCE_DT =
0.01 s (`motion_models.base.noise_rate_factor`), so the β above hold at any update rate: a 10 s walk spreads
the same at 30, 100 and 200 Hz. At Δt = 0.01 s the factor is exactly 1 and the noise is eq. 10's, bit for bit.
`noise_rate="per_step"` is eq. 10 as written (the spread then depends on the rate; scale β by
sqrt(0.01 s / Δt) by hand).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .base import BoundedNoiseModel, MotionInput, check_noise_rate, check_nonnegative, noise_rate_factor, scaled


@dataclass(frozen=True)
class VelocityLinear(BoundedNoiseModel):
    """Hoffmann eq. 10 with documented SI defaults (see the module docstring).

    Parameters
    ----------
    beta1 : float, optional
        Along-track noise per unit speed; default 1.7.
    beta2 : float, optional
        Lateral noise per unit speed; default 1.0.
    beta3 : float, optional
        Heading noise per unit translational speed [rad/m]; default 1.0.
    beta4 : float, optional
        Heading noise per unit angular speed; default 1.0.
    gaussian : bool, optional
        Gaussian noise of the same variance instead of uniform; default False.
    noise_rate : str, optional
        "per_second" (the default): the β set the spread per second of walking at any update rate (eq. 10's
        half-widths times sqrt(0.01 s / Δt), exactly eq. 10 at 100 Hz); "per_step": eq. 10 as written, the
        β holding at one update rate (`motion_models.base.NOISE_RATES`).

    Raises
    ------
    ValueError
        If a β is not within [0, `MAX_NOISE_PARAMETER`] or `noise_rate` is not one of `NOISE_RATES`.
    """

    beta1: float = 1.7  # along-track noise per unit speed
    beta2: float = 1.0  # lateral noise per unit speed
    beta3: float = 1.0  # rad/m: heading noise per unit translational speed (drift while walking straight)
    beta4: float = 1.0  # heading noise per unit angular speed
    gaussian: bool = False
    noise_rate: str = "per_second"  # "per_second": the β hold at any update rate; "per_step": eq. 10 as written

    def __post_init__(self) -> None:
        check_nonnegative(self, ("beta1", "beta2", "beta3", "beta4"))
        check_noise_rate(self.noise_rate)

    def noise_bounds(self, u: MotionInput) -> tuple[float, float, float]:
        """The half-widths Δt·β|v|... of eq. 10 for this input, times `noise_rate_factor(u.dt, noise_rate)`
        (1 with "per_step" and at Δt = 0.01 s).

        Parameters
        ----------
        u : MotionInput
            One control period's motion input: its command (speed and turn rate) when given, else the
            displacement of its odometry.

        Returns
        -------
        tuple of float
            The half-widths (x [m], y [m], θ [rad]).

        Raises
        ------
        ValueError
            If `u` has neither a command nor odometry.
        """
        if u.command is not None:
            speed, omega = math.hypot(u.command[0], u.command[1]), abs(u.command[2])
            dt = u.dt
            bounds = (dt * self.beta1 * speed, dt * self.beta2 * speed, dt * (self.beta3 * speed + self.beta4 * omega))
        else:
            dx, dy, dtheta = u.displacement()
            # Δt·β·|v| with |v| = |Δ|/Δt: the odometry's own displacement sets the bound.
            distance = math.hypot(dx, dy)
            bounds = (self.beta1 * distance, self.beta2 * distance, self.beta3 * distance + self.beta4 * abs(dtheta))
        return scaled(bounds, noise_rate_factor(u.dt, self.noise_rate))
