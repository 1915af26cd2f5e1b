"""Re-localization on a soccer field: which fresh hypotheses a lost filter injects, and what the robot knows
that tells a pose from its mirror.

    from mcl import ParticleFilter
    from mcl.relocalization import RelocalizationPrior, SoccerRelocalization

    pf = ParticleFilter(field, motion, sensor, relocalization=SoccerRelocalization(RelocalizationPrior()))

The particle filter (`mcl.filter`) decides *how many* particles to replace (augmented MCL: when the
detections are poorly explained); this module decides *which*. It is the one place where soccer knowledge
enters the filter, and it enters as evidence with a weight, never as a gate:

1. **Every pose that explains the detections is a candidate, whatever its heading.** The candidates are the
   poses that explain two detections at once (`sensing.resetting.poses_from_pairs`: every consistent
   association, so the true pose and its mirror both), poses that explain one detection with a heading drawn
   from the whole circle (the sensor model's `sample_poses`), and a few uniform over the carpet. A kidnap
   that turns the robot cannot put the true pose beyond reach.
2. **Each candidate is weighed by how well it explains the whole frame and by a prior** (sampling-importance-
   resampling: `pool` candidates per injected particle, each with its mirror image, `count` of them drawn in
   proportion to likelihood × prior). The prior is what the robot knows of where it can be, around the
   *anchor*: the last confident pose that explained the detections, carried forward by the motion inputs as
   dead reckoning. It mixes three parts (`RelocalizationPrior`): not moved (normal of `track_sigma` and
   `track_heading_sigma`, widened by `drift` of the distance dead-reckoned since); carried, pushed or spun
   (`kidnap_share`: normal of `kidnap_sigma`, the heading kept for a share `heading_kept` and any heading
   otherwise, since odometry does not see a carried or spun robot turn); anywhere (`tail_share`, so that no
   pose on the carpet is ruled out). Before the filter has been confident after a reset over a region (the
   own half at kick-off), a pose outside the region gets `region_tail` of the prior.
3. **The prior alone tells a pose from its mirror** (−x, −y, θ + π), which explains every detection exactly as
   well. Of each candidate pair, the side the prior prefers by more than `mirror_odds` is injected alone;
   closer odds inject both, in proportion. When a confident estimate settles somewhere new (`confirm`: for
   `jump_corrections` corrections in a row), the prior weighs it against its mirror image; if the mirror image
   is the more probable by more than `mirror_odds`, the filter mirrors its particles (the likelihood cannot
   tell the two apart, so that is exact). The odds are kept (`mirror_log_odds`) for `mcl.localizer`'s quality,
   as the smaller of the prior's odds and the odds of position alone (`heading_kept` = 0): how sure the filter
   may be must not rest on a heading reference that the event may have destroyed.
4. **The anchor is evidence too.** It follows the estimate only while the estimate is confident and explains
   the detections, whatever its heading: a kidnap may turn the robot. Resets set it: a known pose
   (`reset_pose`) sets it, a region (`reset_region`) clears it.

The filter knows this class only by its methods (`bind`, `reset_region`, `reset_pose`, `mirror`, `carry`,
`confirm`, `propose`, and the attribute `tracking`), so a team with other rules writes another class with the
same methods (`mcl.contracts.Relocalization`). The soccer rules live here: the named regions a belief is spread
over (`REGIONS`, `region_bounds`), the heading reference, the mirror guard. The design, the alternatives measured
and the limits: docs/relocalization.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from field import Field
from field.angles import wrap_angle, wrap_angles
from field.checks import LARGEST_COORDINATE, reals
from sensing.observations import Observations
from sensing.resetting import poses_from_pairs

from . import reference as twins
from .contracts import numpy_twin
from .resampling import systematic

TWO_PI = 2.0 * math.pi
KIDNAP_AMBIGUITY = 3.0  # a pose and its mirror image within this ratio of distances from the anchor: ambiguous


REGIONS = ("field", "own_half", "opponent_half")
"""The named regions a belief can be spread over (the own half is x < 0: the team plays towards +x)."""


def region_bounds(field: Field, region: str | Sequence[float] | np.ndarray) -> tuple[float, float, float, float]:
    """(x_min, x_max, y_min, y_max) of a named region of `field` (`REGIONS`) or of given bounds (checked).

    Parameters
    ----------
    field : Field
        The field whose halves the named regions are.
    region : str or sequence of float or np.ndarray
        A name of `REGIONS` ("field", "own_half", "opponent_half"), or bounds (x_min, x_max, y_min, y_max) [m]
        in the field frame, each finite.

    Returns
    -------
    tuple of float
        (x_min, x_max, y_min, y_max) [m]: the named region within the field lines, or the bounds as floats.

    Raises
    ------
    ValueError
        If the name is not one of `REGIONS`, the bounds are not four finite numbers within the coordinate
        limits, or x_min >= x_max or y_min >= y_max; TypeError (`field.checks.ArgumentTypeError`) if `region`
        is neither a name nor a sequence of numbers.
    """
    hl, hw = field.half_length, field.half_width
    if isinstance(region, str):
        if region not in REGIONS:
            raise ValueError(f"region = {region!r} must be one of {REGIONS} or (x_min, x_max, y_min, y_max)")
        return {"field": (-hl, hl, -hw, hw), "own_half": (-hl, 0.0, -hw, hw), "opponent_half": (0.0, hl, -hw, hw)}[
            region
        ]
    x_min, x_max, y_min, y_max = (float(v) for v in reals("region", region, 4, -LARGEST_COORDINATE, LARGEST_COORDINATE))
    if x_min >= x_max or y_min >= y_max:
        raise ValueError(f"region = {region!r} must have x_min < x_max and y_min < y_max")
    return x_min, x_max, y_min, y_max


@dataclass(frozen=True)
class RelocalizationPrior:
    """Where the robot can be, given the anchor (its last confident pose, dead-reckoned since): a mixture of
    three densities over (x, y, θ) (see the module docstring).

    Parameters
    ----------
    kidnap_share : float, optional
        Prior probability that something odometry did not see moved the robot (carried, pushed, spun): then its
        position is normal around the anchor with `kidnap_sigma`. Within [0, 1]; default 0.1.
    kidnap_sigma : float, optional
        Spread of that position [m], > 0; default 2.5.
    heading_kept : float, optional
        Share of such displacements that keep the heading (normal of `track_heading_sigma` around the
        anchor's); the rest turn the robot by any angle. Evidence, not a gate: a carried robot's heading
        usually survives, a pushed or spun one's does not. Within [0, 1]; default 0.5.
    tail_share : float, optional
        Prior probability of anywhere on the carpet, any heading: no pose is ruled out. Within (0, 1], and
        `kidnap_share` + `tail_share` < 1; default 0.01.
    track_sigma : float, optional
        Otherwise (1 − kidnap_share − tail_share) the robot is where the anchor says, normal with this spread
        in position [m] (and `track_heading_sigma` in heading); > 0; default 0.3.
    track_heading_sigma : float, optional
        The spread in heading [rad] of that part (and of a kidnap that keeps the heading); > 0; default 0.3.
    drift : float, optional
        Share of the distance dead-reckoned since the anchor that widens both position sigmas; within [0, 1];
        default 0.3.
    region_tail : float, optional
        Prior factor outside the placement region, before the first confident estimate after it; within
        (0, 1]; default 0.05.
    pool : int, optional
        Candidates drawn per injected particle (each also with its mirror image), >= 1; default 4.
    pair_share : float, optional
        Share of the candidates taken from detection pairs (when a frame has two or more); within [0, 1];
        default 0.6.
    uniform_share : float, optional
        Share of the candidates uniform over the carpet; within [0, 1], and `pair_share` + `uniform_share`
        <= 1; default 0.1.
    jitter : tuple of float, optional
        (x [m], y [m], θ [rad]) standard deviations of the normal noise added to each injected candidate,
        each finite and >= 0; default (0.03, 0.03, 0.03).
    mirror_odds : float, optional
        A candidate whose prior beats its mirror image's by more than this is injected without the mirror
        image (and the other way round); closer odds inject both. Finite and >= 1; default 2.0.
    jump_corrections : int, optional
        Corrections in a row a confident estimate away from the anchor must hold (within 0.5 m and 0.5 rad
        from one to the next) before it becomes the anchor; >= 1; default 10.
    confident_weight : float, optional
        Share of the belief the estimate's cluster must hold to be confident (with 0.3 m, 0.2 rad); within
        [0, 1]; default 0.8.
    confident_corrections : int, optional
        Corrections in a row the estimate must be confident before the placement region is lifted and
        injection is capped at the filter's tracking share; >= 1; default 120.

    Raises
    ------
    ValueError
        If a value is out of its range (naming it), or the shares add up as above they must not.
    """

    kidnap_share: float = 0.1
    kidnap_sigma: float = 2.5
    heading_kept: float = 0.5
    tail_share: float = 0.01
    track_sigma: float = 0.3
    track_heading_sigma: float = 0.3
    drift: float = 0.3
    region_tail: float = 0.05
    pool: int = 4
    pair_share: float = 0.6
    uniform_share: float = 0.1
    jitter: tuple = (0.03, 0.03, 0.03)
    mirror_odds: float = 2.0
    jump_corrections: int = 10
    confident_weight: float = 0.8
    confident_corrections: int = 120

    def __post_init__(self) -> None:
        for name in ("kidnap_sigma", "track_sigma", "track_heading_sigma"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value!r} must be a finite number > 0")
        for name in (
            "kidnap_share",
            "heading_kept",
            "tail_share",
            "confident_weight",
            "drift",
            "region_tail",
            "pair_share",
            "uniform_share",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and 0 <= value <= 1):
                raise ValueError(f"{name} = {value!r} must be within [0, 1]")
        if self.tail_share <= 0 or self.region_tail <= 0:
            raise ValueError(
                f"tail_share = {self.tail_share!r}, region_tail = {self.region_tail!r} must be > 0: "
                "a prior of zero would be a gate"
            )
        if self.kidnap_share + self.tail_share >= 1:
            raise ValueError(f"kidnap_share + tail_share = {self.kidnap_share + self.tail_share!r} must be < 1")
        if self.pair_share + self.uniform_share > 1:
            raise ValueError(f"pair_share + uniform_share = {self.pair_share + self.uniform_share!r} must be <= 1")
        for name in ("pool", "jump_corrections", "confident_corrections"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} = {value!r} must be an integer >= 1")
        if not (
            isinstance(self.mirror_odds, (int, float)) and math.isfinite(self.mirror_odds) and self.mirror_odds >= 1
        ):
            raise ValueError(f"mirror_odds = {self.mirror_odds!r} must be a finite number >= 1")
        jitter = np.asarray(self.jitter, dtype=np.float64)
        if jitter.shape != (3,) or not np.isfinite(jitter).all() or (jitter < 0).any():
            raise ValueError(f"jitter = {self.jitter!r} must be three finite numbers >= 0")


class SoccerRelocalization:
    """The soccer field's re-localization rules as evidence (see the module docstring); one per filter.

    Parameters
    ----------
    prior : RelocalizationPrior, optional
        The prior's parameters; default `RelocalizationPrior()`.

    Attributes
    ----------
    prior : RelocalizationPrior
        As given.
    travelled : float
        Distance [m] dead-reckoned since the anchor was confirmed.
    region : tuple of float or None
        The placement region (x_min, x_max, y_min, y_max) [m] until the filter is first confident after a reset
        over it; None otherwise.
    tracking : bool
        Whether the filter has been confident since the last reset.
    mirror_log_odds : float
        The prior's log odds of the last re-localized pose against its mirror image (+inf: none since a known
        pose): how sure the filter can be that it is not on the mirror (see `confirm`).
    relocalizations : int
        How many re-localized poses `confirm` has accepted (a pose away from the anchor that held): a change
        tells that the estimate moved somewhere new.
    kidnapped : bool
        Whether a re-localized pose since the last reset lay beyond the anchor's drift (`tracking_share` < 1/2)
        with its mirror image about as far from the anchor (within a factor `KIDNAP_AMBIGUITY`): its
        `mirror_log_odds` then rest on the prior's kidnap law, not on continuity, and so does continuity with it
        afterwards. False after a reset.
    jumped : bool
        Whether a re-localized pose since the last reset lay beyond the anchor's drift at all (the robot was
        moved unseen: pushed far, carried, or the estimate had been wrong): its `mirror_log_odds` then rest on
        the distance part of the kidnap law, however far the mirror image lies. False after a reset.

    Raises
    ------
    ValueError
        If `prior` is not a `RelocalizationPrior`.
    """

    def __init__(self, prior: RelocalizationPrior = RelocalizationPrior()) -> None:
        if not isinstance(prior, RelocalizationPrior):
            raise ValueError(f"prior = {prior!r} must be an mcl.relocalization.RelocalizationPrior")
        self.prior = prior
        self._anchor: list[float] | None = None  # last confident pose, dead-reckoned since
        self.travelled = 0.0  # m dead-reckoned since the anchor was confirmed
        self.region: tuple[float, float, float, float] | None = None
        self.tracking = False  # confident once since the last reset
        self._pending: list[float] | None = None  # a confident estimate away from the anchor, not yet accepted
        self._pending_count = 0
        # the prior's log odds of the last re-localized pose against its mirror image (+inf: none since a known
        # pose): how sure the filter can be that it is not on the mirror (see `confirm`)
        self.mirror_log_odds = math.inf
        self._streak = 0
        self._carpet = (-1.0, 1.0, -1.0, 1.0)
        self.relocalizations = 0  # re-localized poses accepted so far (`confirm`)
        self.kidnapped = False  # a re-localized pose since the reset rested on the kidnap law
        self.jumped = False  # a re-localized pose since the reset lay beyond the anchor's drift

    @property
    def anchor(self) -> np.ndarray | None:
        """The anchor (x, y, θ): the last confident pose that explained the detections, dead-reckoned since
        (None after a reset over a region, until the first one)."""
        return None if self._anchor is None else np.array(self._anchor)

    @property
    def carpet(self) -> tuple[float, float, float, float]:
        """The carpet's bounds (x_min, x_max, y_min, y_max), as the filter gave them (`bind`)."""
        return self._carpet

    def bind(self, carpet: tuple[float, float, float, float]) -> None:
        """The carpet's bounds (x_min, x_max, y_min, y_max): where uniform candidates are drawn.

        Parameters
        ----------
        carpet : tuple of float
            (x_min, x_max, y_min, y_max) [m] of the carpet, in the field frame.
        """
        x_min, x_max, y_min, y_max = (float(v) for v in carpet)
        self._carpet = (x_min, x_max, y_min, y_max)

    # -- what the filter tells it -------------------------------------------------------------------------
    def reset_region(self, bounds: Sequence[float]) -> None:
        """The robot is somewhere in `bounds` (x_min, x_max, y_min, y_max), nothing else known.

        Parameters
        ----------
        bounds : sequence of float
            (x_min, x_max, y_min, y_max) [m] of the region the particles were spread over (the placement
            region until the filter is confident).
        """
        x_min, x_max, y_min, y_max = (float(v) for v in bounds)
        self.region = (x_min, x_max, y_min, y_max)
        self.mirror_log_odds = math.inf
        self.kidnapped = False
        self.jumped = False
        self._anchor = None
        self.travelled = 0.0
        self.tracking = False
        self._streak = 0
        self._pending = None

    def reset_pose(self, pose: Sequence[float] | np.ndarray) -> None:
        """The robot is at `pose` (x, y, θ): the anchor, trusted at once.

        Parameters
        ----------
        pose : sequence of float or np.ndarray
            (x [m], y [m], θ [rad]) the particles were set around; the heading is wrapped to [-π, π].
        """
        self._anchor = [float(pose[0]), float(pose[1]), math.remainder(float(pose[2]), TWO_PI)]
        self.travelled = 0.0
        self.region = None
        self.mirror_log_odds = math.inf
        self.kidnapped = False
        self.jumped = False
        self.tracking = True
        self._streak = 0
        self._pending = None

    def mirror(self) -> None:
        """The belief was mirrored through the centre mark: so is the anchor (and the region)."""
        if self._anchor is not None:
            x, y, theta = self._anchor
            self._anchor = [-x, -y, math.remainder(theta + math.pi, TWO_PI)]
        if self.region is not None:
            x_min, x_max, y_min, y_max = self.region
            self.region = (-x_max, -x_min, -y_max, -y_min)

    def carry(self, dx: float, dy: float, dtheta: float) -> None:
        """Dead-reckon the anchor by a robot-frame displacement (the motion input of a step).

        Parameters
        ----------
        dx, dy, dtheta : float
            As `mcl.contracts.Relocalization.carry`: displacement [m] and rotation [rad] in the robot frame.
        """
        anchor = self._anchor
        if anchor is None:
            return
        c, s = math.cos(anchor[2]), math.sin(anchor[2])
        anchor[0] += c * dx - s * dy
        anchor[1] += s * dx + c * dy
        anchor[2] = math.remainder(anchor[2] + dtheta, TWO_PI)
        self.travelled += math.hypot(dx, dy)

    def confirm(self, estimate: Any, explains: bool) -> bool:
        """After a correction: the filter's estimate (`mcl.filter.Estimate`: pose, covariance, the dominant
        cluster's weight) and whether the belief explains the detections. Returns whether the filter should
        mirror its particles through the centre mark.

        The estimate is confident when its cluster is tight (0.3 m, 0.2 rad) and holds `confident_weight` of
        the belief.

        A confident estimate that explains the detections becomes the anchor. When it lies beyond the tracking
        part of the prior (3 σ from the dead-reckoned anchor, or there was no anchor), the filter has
        re-localized, and the prior weighs the new pose against its mirror image, which explains every
        detection exactly as well: when the mirror image is the more probable by more than `mirror_odds`, the
        belief belongs there (returns True, and the anchor is the mirror image). `mirror_log_odds` keeps the
        odds of the pose kept against its mirror image, the smaller of the prior's and those of position alone
        (`log_prior(..., heading_kept=0)`): nothing seen afterwards can change them.

        Parameters
        ----------
        estimate : mcl.Estimate
            The filter's estimate after the correction (its `pose` and `is_confident` are used).
        explains : bool
            Whether the belief explains the frame's detections as usual.

        Returns
        -------
        bool
            True when the filter should mirror its particles through the centre mark.
        """
        flip = False
        confident = estimate.is_confident(weight=self.prior.confident_weight)
        if confident and explains:
            pose = estimate.pose.tolist()
            anchor = self._anchor
            jumped = True
            if anchor is not None:
                sigma = math.hypot(self.prior.track_sigma, self.prior.drift * self.travelled)
                jumped = math.hypot(pose[0] - anchor[0], pose[1] - anchor[1]) > 3 * sigma
            if jumped:
                # a new place must hold for `jump_corrections` corrections in a row before it counts: early in
                # a re-localization a wrong cluster can be tight and fit a few detections for a moment
                previous = self._pending
                if (
                    previous is not None
                    and math.hypot(pose[0] - previous[0], pose[1] - previous[1]) <= 0.5
                    and abs(math.remainder(pose[2] - previous[2], TWO_PI)) <= 0.5
                ):
                    self._pending_count += 1
                else:
                    self._pending_count = 1
                self._pending = pose
                if self._pending_count < self.prior.jump_corrections:
                    return self._count_streak(confident, flip)
                mirror = [-pose[0], -pose[1], math.remainder(pose[2] + math.pi, TWO_PI)]
                pair = np.array([pose, mirror])
                log_prior = self.log_prior(pair)
                odds = float(log_prior[0] - log_prior[1])
                # odds that rest on the kidnap law (the pose is no drift of the anchor, and its mirror image
                # about as far from the anchor) are only as good as that law: the side belief trusts them less
                # (and continuity with such a pose is no surer: it holds until the next reset)
                self.kidnapped = self.kidnapped or self._kidnap_odds(pose, mirror)
                self.jumped = self.jumped or anchor is not None
                # the same odds without the heading reference: how far position alone tells the pair apart
                log_prior = self.log_prior(pair, heading_kept=0.0)
                position_odds = float(log_prior[0] - log_prior[1])
                if odds < -math.log(self.prior.mirror_odds):
                    pose, odds, position_odds, flip = mirror, -odds, -position_odds, True
                # How sure the filter may be: the odds must hold whether or not the heading reference survived
                # the event (a carried, pushed or spun robot may have been turned any way).
                self.mirror_log_odds = min(odds, position_odds)
                self.relocalizations += 1
            self._anchor = pose
            self.travelled = 0.0
            self._pending = None
        else:
            self._pending = None
        return self._count_streak(confident, flip)

    def holds(self, pose: Sequence[float] | np.ndarray) -> bool:
        """Whether `pose` (x, y, θ) lies where the anchor says, up to its drift: within 3 σ of it, σ the tracking
        spread widened by the distance dead-reckoned since (as `confirm` decides that a pose jumped). True
        without an anchor (there is no pose to have left).

        Parameters
        ----------
        pose : sequence of float or np.ndarray
            (x [m], y [m], θ [rad]).
        """
        anchor = self._anchor
        if anchor is None:
            return True
        sigma = math.hypot(self.prior.track_sigma, self.prior.drift * self.travelled)
        return math.hypot(float(pose[0]) - anchor[0], float(pose[1]) - anchor[1]) <= 3.0 * sigma

    def tracking_share(self, pose: Sequence[float] | np.ndarray) -> float:
        """The share of the prior's density at `pose` (x, y, θ) that its tracking part holds (the robot where the
        anchor says, up to drift), against the kidnap and anywhere parts; 0 without an anchor.

        Parameters
        ----------
        pose : sequence of float or np.ndarray
            (x [m], y [m], θ [rad]).

        Returns
        -------
        float
            Within [0, 1].
        """
        if self._anchor is None:
            return 0.0
        anchor, mixture, _ = self._prior_arguments()
        _, ax, ay, at = anchor
        track2, kidnap2, heading_sigma, kidnap_share, tail_share, heading_kept, uniform = mixture
        d2 = (float(pose[0]) - ax) ** 2 + (float(pose[1]) - ay) ** 2
        turn = math.remainder(float(pose[2]) - at, TWO_PI)
        heading = math.exp(-0.5 * (turn / heading_sigma) ** 2) / (math.sqrt(TWO_PI) * heading_sigma)
        tracking = (1.0 - kidnap_share - tail_share) * math.exp(-0.5 * d2 / track2) / (TWO_PI * track2) * heading
        kidnap = (
            kidnap_share
            * math.exp(-0.5 * d2 / kidnap2)
            / (TWO_PI * kidnap2)
            * ((1.0 - heading_kept) / TWO_PI + heading_kept * heading)
        )
        total = tracking + kidnap + tail_share * uniform
        return tracking / total if total > 0 else 0.0

    def _kidnap_odds(self, pose: list[float], mirror: list[float]) -> bool:
        """Whether the odds of `pose` against `mirror` rest on the kidnap law: the pose is no drift of the anchor
        (`tracking_share` < 1/2) and the two lie about as far from it (within `KIDNAP_AMBIGUITY`)."""
        anchor = self._anchor
        if anchor is None or self.tracking_share(pose) >= 0.5:
            return False
        near = math.hypot(pose[0] - anchor[0], pose[1] - anchor[1])
        far = math.hypot(mirror[0] - anchor[0], mirror[1] - anchor[1])
        return max(near, far) <= KIDNAP_AMBIGUITY * max(min(near, far), 1e-9)

    def _count_streak(self, confident: bool, flip: bool) -> bool:
        if self.tracking:
            return flip
        self._streak = self._streak + 1 if confident else 0
        if self._streak >= self.prior.confident_corrections:
            self.tracking = True
            self.region = None
        return flip

    # -- what it gives the filter -------------------------------------------------------------------------
    def _prior_arguments(self, heading_kept: float | None = None) -> tuple:
        """The prior's parameters as `log_prior_kernel` takes them, in its three groups anchor, mixture and
        region (`heading_kept`: instead of the prior's)."""
        p = self.prior
        x_min, x_max, y_min, y_max = self._carpet
        uniform = 1.0 / ((x_max - x_min) * (y_max - y_min) * TWO_PI)
        widen = (p.drift * self.travelled) ** 2
        anchor = (0.0, 0.0, 0.0) if self._anchor is None else tuple(self._anchor)
        region = (0.0, 0.0, 0.0, 0.0) if self.region is None else tuple(self.region)
        return (
            (self._anchor is not None, *anchor),
            (
                p.track_sigma**2 + widen,
                p.kidnap_sigma**2 + widen,
                p.track_heading_sigma,
                p.kidnap_share,
                p.tail_share,
                p.heading_kept if heading_kept is None else heading_kept,
                uniform,
            ),
            (self.region is not None, *region, math.log(p.region_tail)),
        )

    def log_prior(self, poses: np.ndarray, heading_kept: float | None = None, *, reference: bool = False) -> np.ndarray:
        """The prior's log-density at each pose (N, 3) (see `RelocalizationPrior`); without an anchor, uniform
        (times `region_tail` outside the placement region). heading_kept: instead of the prior's (0: a
        displacement odometry did not see says nothing of the heading). Compiled (`log_prior_kernel`); the numpy
        twin is `mcl.reference.log_prior` (`reference=True`).

        Parameters
        ----------
        poses : np.ndarray
            (N, 3) poses (x [m], y [m], θ [rad]) in the field frame.
        heading_kept : float or None, optional
            Share of unseen displacements that keep the heading, instead of the prior's `heading_kept`; None
            (the default) takes the prior's.
        reference : bool, default False
            Compute it with the numpy twin instead of the kernel (for tests; equal to rounding).

        Returns
        -------
        np.ndarray
            (N,) float64 log-densities.
        """
        poses = np.ascontiguousarray(poses, dtype=np.float64)
        if reference:
            return twins.log_prior(poses, *self._prior_arguments(heading_kept))
        return log_prior_kernel(poses, *self._prior_arguments(heading_kept), np.empty(poses.shape[0]))

    def propose(
        self,
        count: int,
        observations: Observations,
        sensor_model: Any,
        rng: np.random.Generator,
        reference: bool = False,
    ) -> np.ndarray:
        """`count` poses (count, 3) to inject: candidates drawn from the detections, weighed by how well they
        explain the whole frame and by the prior, `count` of them drawn in proportion (systematic).
        reference: use the plain twins (the sensor model's `numpy_twin().sample_poses`, `poses_from_pairs(...,
        reference=True)`), for tests.

        Parameters
        ----------
        count : int
            How many poses to propose; none when <= 0.
        observations : Observations
            The frame that triggered the injection.
        sensor_model : SensorModel
            The filter's sensor model: scores the candidates (`log_likelihood`); its `sample_poses` (sensor
            resetting) and `landmark_table` (pairs of detections), when it has them, draw candidates.
        rng : np.random.Generator
            The only source of randomness.
        reference : bool, optional
            Use the plain numpy twins (default False).

        Returns
        -------
        np.ndarray
            (count, 3) float64 poses (x [m], y [m], θ [rad]), headings wrapped; (0, 3) when `count` <= 0.
        """
        p = self.prior
        if count <= 0:
            return np.empty((0, 3))
        pool = p.pool * count  # candidates before their mirror images are added
        parts = []
        n_pairs = 0
        if len(observations) >= 2 and getattr(sensor_model, "landmark_table", None) is not None:
            pairs = poses_from_pairs(sensor_model, observations, reference=reference)
            n_pairs = min(pairs.shape[0], int(round(p.pair_share * pool)), pool - 1)
            if n_pairs:
                parts.append(pairs if n_pairs == pairs.shape[0] else pairs[rng.permutation(pairs.shape[0])[:n_pairs]])
        n_uniform = max(1, int(round(p.uniform_share * pool)))
        sampler = getattr(numpy_twin(sensor_model) if reference else sensor_model, "sample_poses", None)
        n_single = pool - n_pairs - n_uniform
        if n_single > 0 and sampler is not None and len(observations) > 0:
            parts.append(np.asarray(sampler(observations, n_single, rng, heading=None), dtype=np.float64))
        else:
            n_uniform = pool - n_pairs  # at least one: a uniform candidate is always on the carpet
        x_min, x_max, y_min, y_max = self.region if self.region is not None and not parts else self._carpet
        uniform = np.empty((n_uniform, 3))
        uniform[:, 0] = rng.uniform(x_min, x_max, n_uniform)
        uniform[:, 1] = rng.uniform(y_min, y_max, n_uniform)
        uniform[:, 2] = rng.uniform(-math.pi, math.pi, n_uniform)
        parts.append(uniform)
        # Every candidate with its mirror image: the two explain the frame equally well, so only the prior
        # tells them apart, and it does so exactly (not by which of the two the draws happened to hit).
        base = np.concatenate(parts)
        candidates = np.concatenate([base, Field.mirror_poses(base)])
        x_min, x_max, y_min, y_max = self._carpet
        on_carpet = (
            (candidates[:, 0] >= x_min)
            & (candidates[:, 0] <= x_max)
            & (candidates[:, 1] >= y_min)
            & (candidates[:, 1] <= y_max)
        )
        log_prior = self.log_prior(candidates)
        # Of a twin pair, the side the prior prefers by more than `mirror_odds` is kept alone: the likelihood
        # cannot tell the two apart, and a few particles' noise would otherwise decide which cluster grows.
        # Closer than that, both are kept, in proportion to their prior.
        half = base.shape[0]
        margin = log_prior[:half] - log_prior[half:]
        drop = np.concatenate([margin < -math.log(p.mirror_odds), margin > math.log(p.mirror_odds)])
        score = np.where(drop, -np.inf, log_prior)
        if len(observations) > 0:
            score = score + np.asarray(sensor_model.log_likelihood(candidates, observations), dtype=np.float64)
        score = np.where(on_carpet & np.isfinite(score), score, -np.inf)
        if not np.isfinite(score).any():  # nothing explains anything: any candidate on the carpet
            score = np.where(on_carpet, 0.0, -np.inf)
        weights = np.exp(score - score.max())
        weights /= weights.sum()
        injected = candidates[systematic(weights, count, rng)] + np.asarray(p.jitter) * rng.standard_normal((count, 3))
        injected[:, 2] = wrap_angles(injected[:, 2])
        return injected


@numba.njit(cache=True)
def log_prior_kernel(poses, anchor, mixture, region, out):
    """out[i] ← the prior's log-density at poses[i] (`SoccerRelocalization.log_prior`; numpy twin
    `mcl.reference.log_prior`, the same operations in the same order). Returns out.

    Its parameters come in three groups (`SoccerRelocalization._prior_arguments` builds them):

        anchor   (has_anchor, ax, ay, at): whether there is an anchor pose, and that pose
        mixture  (track2, kidnap2, heading_sigma, kidnap_share, tail_share, heading_kept, uniform): the
                 tracking and kidnap components' variances and shares, and the uniform density
        region   (has_region, x_min, x_max, y_min, y_max, log_region_tail): the placement region
    """
    has_anchor, ax, ay, at = anchor
    track2, kidnap2, heading_sigma, kidnap_share, tail_share, heading_kept, uniform = mixture
    has_region, x_min, x_max, y_min, y_max, log_region_tail = region
    for i in range(poses.shape[0]):
        if has_anchor:
            d2 = (poses[i, 0] - ax) ** 2 + (poses[i, 1] - ay) ** 2
            turn = wrap_angle(poses[i, 2] - at)
            heading = math.exp(-0.5 * (turn / heading_sigma) ** 2) / (math.sqrt(TWO_PI) * heading_sigma)
            kidnap_heading = (1.0 - heading_kept) / TWO_PI + heading_kept * heading
            density = (
                (1.0 - kidnap_share - tail_share) * math.exp(-0.5 * d2 / track2) / (TWO_PI * track2) * heading
                + kidnap_share * math.exp(-0.5 * d2 / kidnap2) / (TWO_PI * kidnap2) * kidnap_heading
                + tail_share * uniform
            )
            value = math.log(density)
        else:
            value = math.log(uniform)
        if has_region:
            x = poses[i, 0]
            y = poses[i, 1]
            inside = (x >= x_min) & (x <= x_max) & (y >= y_min) & (y <= y_max)
            value = value + (0.0 if inside else log_region_tail)
        out[i] = value
    return out
