"""Augmented MCL (Thrun et al., Probabilistic Robotics, table 8.3): when a filter injects fresh particles.

`AugmentedMCL` holds the parameters; `Injection` one filter's running averages, w_slow and w_fast, of the
likelihood per scored term, and the number of particles a correction asks to replace. The filter
(`mcl.filter.ParticleFilter`) owns one `Injection`; its fused step (`mcl.step`) computes the same update in
compiled code from `Injection.kernel_arguments`.

    from mcl.augmented import AugmentedMCL, Injection

    params, injection = AugmentedMCL(), Injection()
    share = injection.update(params, log_average=-0.4)      # the share of the particles to inject
    count = injection.count(params, share, n=500, tracking=False)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from field.checks import real


@dataclass(frozen=True)
class AugmentedMCL:
    """Augmented MCL parameters: averaging rates of w_slow and w_fast (0 < alpha_slow << alpha_fast <= 1).

    Parameters
    ----------
    alpha_slow : float, default 0.002
        Averaging rate of w_slow, the long-term average likelihood per detection.
    alpha_fast : float, default 0.1
        Averaging rate of w_fast, the short-term one (0 < alpha_slow < alpha_fast <= 1).
    ratio_threshold : float, default 0.5
        Inject 1 - (w_fast/w_slow)/ratio_threshold of the particles, in [0, 1]: only when the short-term fit
        drops below this share of the long-term one (1.0 is plain augmented MCL).
    fit_threshold : float, default 0.2
        Also inject 1 - w_fast/fit_threshold when the fit is poor in absolute terms (sensor resetting),
        >= 0; 0 switches it off.
    max_fraction : float, default 0.25
        Never replace more than this share of the particles at once, in [0, 1].
    max_fraction_tracking : float, default 0.05
        Nor more than this once the filter has been confident (the relocalization's `tracking`), in [0, 1].

    Raises
    ------
    ValueError
        If a value is out of its range (the comments below say why each default is what it is).
    """

    alpha_slow: float = 0.002
    alpha_fast: float = 0.1
    # Below 1 (plain augmented MCL), so that one false positive in a frame with a single detection does not
    # inject: only a drop of the short-term fit below this share of the long-term one does.
    ratio_threshold: float = 0.5
    # Sensor resetting (Lenser & Veloso 2000): a perfect match scores 1 per detection with
    # sensing.LandmarkSensorModel; this lies below what w_fast reaches while tracking, so it fires when lost.
    fit_threshold: float = 0.2
    max_fraction: float = 0.25
    # Once tracking, a streak of false positives must not dissolve a correct cluster (at 25 % a frame, 90 % of
    # it is gone in 8 frames); the injected poses are chosen for how well they explain the frame, so few do.
    max_fraction_tracking: float = 0.05

    def update(self, w_slow: float, w_fast: float, log_average: float) -> tuple[float, float, float]:
        """w_slow and w_fast moved towards exp(log_average), the frame's average likelihood per detection (set
        to it at the first frame, w_slow = 0), and the share of the particles to inject that they ask for."""
        average = math.exp(log_average)
        if w_slow == 0.0:
            w_slow = w_fast = average
        else:
            w_slow += self.alpha_slow * (average - w_slow)
            w_fast += self.alpha_fast * (average - w_fast)
        relative = 1.0 - w_fast / (self.ratio_threshold * w_slow) if w_slow > 0 else 1.0
        absolute = 1.0 - w_fast / self.fit_threshold if self.fit_threshold > 0 else 0.0
        return w_slow, w_fast, max(0.0, relative, absolute)

    def cap(self, tracking: bool) -> float:
        """The largest share of the particles one correction may replace: `max_fraction_tracking` once the
        filter has been confident (`tracking`), else `max_fraction`."""
        return self.max_fraction_tracking if tracking else self.max_fraction

    def __post_init__(self) -> None:
        real("alpha_slow", self.alpha_slow)
        real("alpha_fast", self.alpha_fast)
        if not (0 < self.alpha_slow < self.alpha_fast <= 1):
            raise ValueError(
                f"alpha_slow = {self.alpha_slow!r}, alpha_fast = {self.alpha_fast!r}: "
                "need 0 < alpha_slow < alpha_fast <= 1"
            )
        for name in ("max_fraction", "max_fraction_tracking", "ratio_threshold"):
            real(name, getattr(self, name), 0.0, 1.0)
        real("fit_threshold", self.fit_threshold, 0.0)


class Injection:
    """One filter's augmented-MCL state: w_slow and w_fast, the long- and short-term averages of the likelihood
    per scored term (0 before the first correction and after a reset)."""

    def __init__(self) -> None:
        self.w_slow = 0.0
        self.w_fast = 0.0

    def restart(self) -> None:
        """The averages start afresh (a reset)."""
        self.w_slow = self.w_fast = 0.0

    def update(self, params: AugmentedMCL, log_average: float) -> float:
        """Fold in a correction's average log-likelihood per term; returns the share of particles it asks to
        inject (`AugmentedMCL.update`)."""
        self.w_slow, self.w_fast, share = params.update(self.w_slow, self.w_fast, log_average)
        return share

    @staticmethod
    def count(params: AugmentedMCL | None, share: float, n: int, tracking: bool) -> int:
        """How many of `n` particles to inject for `share`, within the cap (`AugmentedMCL.cap`); none without
        augmented MCL."""
        return 0 if params is None else int(round(min(share, params.cap(tracking)) * n))

    def kernel_arguments(self, params: AugmentedMCL | None, tracking: bool) -> tuple:
        """The fused step's augmented-MCL arguments (`mcl.step`): whether it is on, alpha_slow, alpha_fast,
        ratio_threshold, fit_threshold, w_slow, w_fast and the cap."""
        if params is None:
            return (False, 0.0, 0.0, 1.0, 0.0, self.w_slow, self.w_fast, 0.0)
        return (
            True,
            params.alpha_slow,
            params.alpha_fast,
            params.ratio_threshold,
            params.fit_threshold,
            self.w_slow,
            self.w_fast,
            params.cap(tracking),
        )

    def fits(self, params: AugmentedMCL) -> bool:
        """Whether the belief explains the detections as well as it usually does: w_fast at least
        `ratio_threshold` of w_slow (no injection asked for by a drop of the fit; an absolute level would
        depend on how noisy the camera is)."""
        return self.w_fast >= params.ratio_threshold * self.w_slow
