"""`ConstantNoise`: odometry plus a fixed noise rate, whatever the speed.

    from motion_models import ConstantNoise, MotionInput
    model = ConstantNoise(rate_x=0.35, rate_y=0.2, rate_theta=0.3)
    model.predict(poses, MotionInput(dt=0.01, command=(0.2, 0.0, 0.0)), rng)

The pose change is the input's displacement (odometry, or dt * command); the noise added in the robot frame
is uniform on [-dt * rate_k, dt * rate_k] per axis (eq. 10 with the speed terms replaced by constants), or
Gaussian with the same variance. A standing robot diffuses too: that is this model's weakness, and the
reason for the velocity-linear one.

Update rate (`noise_rate`, as `VelocityLinear`'s). Drawn afresh every step, a half-width of dt·rate spreads
the particles over T seconds by sqrt(dt·T)·rate: the rates would hold at one update rate only. By default
(`noise_rate="per_second"`) each step's half-width is dt·rate·sqrt(REFERENCE_DT / dt), REFERENCE_DT = 0.01 s,
so the rates give the same spread per second at any update rate, and exactly dt·rate at 100 Hz;
`noise_rate="per_step"` is dt·rate as written.
"""

from __future__ import annotations

from dataclasses import dataclass

from .base import BoundedNoiseModel, MotionInput, check_noise_rate, check_nonnegative, noise_rate_factor, scaled


@dataclass(frozen=True)
class ConstantNoise(BoundedNoiseModel):
    """Noise bounds grow with time only. Rates in m/s (x, y) and rad/s (theta).

    Parameters
    ----------
    rate_x, rate_y : float, optional
        Noise half-width per second along and across the robot's heading [m/s]; defaults 0.35 and 0.2.
    rate_theta : float, optional
        Heading noise half-width per second [rad/s]; default 0.3.
    gaussian : bool, optional
        Gaussian noise of the same variance instead of uniform; default False.
    noise_rate : str, optional
        "per_second" (the default): the rates set the spread per second at any update rate (half-widths
        dt·rate·sqrt(0.01 s / dt), exactly dt·rate at 100 Hz); "per_step": dt·rate as written
        (`motion_models.base.NOISE_RATES`).

    Raises
    ------
    ValueError
        If a rate is not within [0, `MAX_NOISE_PARAMETER`] or `noise_rate` is not one of `NOISE_RATES`.
    """

    rate_x: float = 0.35
    rate_y: float = 0.2
    rate_theta: float = 0.3
    gaussian: bool = False
    noise_rate: str = "per_second"  # "per_second": the rates hold at any update rate; "per_step": dt·rate as written

    def __post_init__(self) -> None:
        check_nonnegative(self, ("rate_x", "rate_y", "rate_theta"))
        check_noise_rate(self.noise_rate)

    def noise_bounds(self, u: MotionInput) -> tuple[float, float, float]:
        """The half-widths dt·rate per axis, times `noise_rate_factor(u.dt, noise_rate)` (1 with "per_step"
        and at dt = 0.01 s).

        Parameters
        ----------
        u : MotionInput
            One control period's motion input (only `dt` is used).

        Returns
        -------
        tuple of float
            (dt·rate_x [m], dt·rate_y [m], dt·rate_theta [rad]), each times the factor.
        """
        return scaled(
            (u.dt * self.rate_x, u.dt * self.rate_y, u.dt * self.rate_theta), noise_rate_factor(u.dt, self.noise_rate)
        )
