"""Rival poses: a young estimate must explain the recent frames better than any other place does.

A particle filter started from a wide belief (a reset over the own half, a re-localization after a kidnapping)
collapses onto the first pose that explains a few detections. With few landmarks in view, a wrong pose can do
that: a corner is explained by any corner at the same range and bearing. Its cluster is then tight and holds the
whole weight, and the fit over the last frames is good, so everything the quality looks at says SUPERB while
the robot is metres away. The other places that explain the same detections are gone from the particle set.

`RivalPoses` keeps them beside the filter, for the quality only (the particles are never touched):

- Each frame proposes places from its detections: every pose that sees two detections where they were seen
  (`sensing.resetting.poses_from_pairs`) and poses drawn from single detections (the sensor model's
  `sample_poses`). Those at least `apart` m from the estimate and away from its mirror image (the mirror explains
  every detection exactly as well; the side odds speak for it) become rivals.
- A newborn rival is scored over the frames of the last `window` seconds: the rival and the estimate are both
  carried back along the same odometry to where each would have been at each frame's capture, and the rival's
  lead is the sum over those frames of its log-likelihood minus the estimate's, each shrunk by `TOLERANCE`
  (`beyond_tolerance`; the frame it was drawn from left out, since it was made to explain that one). From then on every frame adds to its lead. A rival whose lead falls below
  -log(`drop_odds`) is dropped; so is one that comes near the estimate or its mirror image.
- `log_odds` is how much better the estimate explains what was seen than the best rival: minus the largest lead
  (+inf without rivals). `QualityThresholds.superb_rival_odds` and `okay_rival_odds` ask for it.

Only a young track is checked: for `young` seconds after a reset, a re-localization, or a jump of the estimate
that no re-localization made (the dominant cluster changed between two frames; `Localizer` calls `new_track`;
not for a jump to the estimate's mirror image, which the rivals leave to the side odds).
A track that has explained the frames for longer has been tested against what the head saw while it panned, and
a kidnapping of it is the surprise's to detect (`Localizer.surprise`). Outside that time only the frames are kept
(a few bytes each), so the step's cost does not change.

Everything random comes from the rival tracker's own generator (seeded with the localizer's seed), so the same
seed gives the same quality, and the filter's own draws are untouched.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from field import Field
from field.angles import wrap_angle, wrap_angles
from field.checks import ArgumentTypeError, reals
from sensing.observations import Observations
from sensing.resetting import poses_from_pairs

from .latency import IDENTITY, compose

REFINE = 4  # jittered copies each rival is refined with per frame
BORN_REFINE = 3  # rounds a newborn rival is refined with on the frame it was drawn from
WINDOW_FRAMES = 30  # at most this many of the window's frames score a newborn rival
TOLERANCE = 1.0  # nats of a frame's log-likelihood difference that do not count (`beyond_tolerance`)


@dataclass(frozen=True)
class RivalSettings:
    """How `RivalPoses` looks for other places that explain the detections.

    Attributes
    ----------
    window : float, default 1.5
        Seconds of frames a newborn rival is scored over (> 0).
    young : float, default 6.0
        A track is checked against rivals for this many seconds after a reset or a re-localization (>= 0).
    candidates : int, default 200
        Poses drawn from single detections per frame (>= 0), besides every pose from a pair of detections.
    newborn : int, default 64
        Of these, at most this many new rivals per frame, those that explain the frame best (>= 1).
    keep : int, default 16
        At most this many rivals, the best leads kept (>= 1).
    drop_odds : float, default 1000.0
        A rival the estimate beats by these odds is dropped (> 1).
    apart : float, default 0.5
        A rival lies at least this far from the estimate [m] (> 0); nearer is the same place.
    mirror_apart : float, default 1.0
        ... and at least this far from the estimate's mirror image [m] (>= 0).
    jitter : tuple of float, default (0.05, 0.05, 0.03)
        (x [m], y [m], θ [rad]) standard deviations of the copies each rival is refined with on every frame.

    Raises
    ------
    ValueError
        If a value is out of its range (naming it).
    """

    window: float = 1.5
    young: float = 6.0
    candidates: int = 200
    newborn: int = 64
    keep: int = 16
    drop_odds: float = 1000.0
    apart: float = 0.5
    mirror_apart: float = 1.0
    jitter: tuple = (0.05, 0.05, 0.03)

    def __post_init__(self) -> None:
        reals("jitter", self.jitter, 3, low=0.0)  # three finite numbers >= 0
        for name, value in self.__dict__.items():
            if name == "jitter":
                continue
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} = {value!r} must be a finite number >= 0")
        for name in ("candidates", "newborn", "keep"):
            if not isinstance(getattr(self, name), int):
                raise ValueError(f"{name} = {getattr(self, name)!r} must be an int")
        if self.window <= 0 or self.apart <= 0 or self.keep < 1 or self.newborn < 1 or self.drop_odds <= 1:
            raise ValueError(
                f"window = {self.window!r}, apart = {self.apart!r} must be > 0, keep = {self.keep!r} and newborn = {self.newborn!r} >= 1 and "
                f"drop_odds = {self.drop_odds!r} > 1"
            )


def relative(origin: tuple[float, float, float], pose: tuple[float, float, float]) -> tuple[float, float, float]:
    """`pose` in the frame of `origin` (both (x, y, θ) in one frame): the displacement from origin to pose."""
    c, s = math.cos(origin[2]), math.sin(origin[2])
    dx, dy = pose[0] - origin[0], pose[1] - origin[1]
    return (c * dx + s * dy, -s * dx + c * dy, pose[2] - origin[2])


def displaced(poses: np.ndarray, displacement: tuple[float, float, float]) -> np.ndarray:
    """Each pose (N, 3) moved by `displacement` (dx, dy, dθ) in its own frame; headings wrapped.

    The headings' cosines and sines come from numpy, the rest from `displaced_kernel` (the same operations in the
    same order as its plain numpy twin, `mcl.reference.displaced`, bit for bit); a young track calls this some thirty times a
    frame."""
    poses = np.ascontiguousarray(poses, dtype=np.float64)
    out = np.empty_like(poses)
    dx, dy, dtheta = (float(v) for v in displacement)
    displaced_kernel(poses, np.cos(poses[:, 2]), np.sin(poses[:, 2]), dx, dy, dtheta, out)
    return out


@numba.njit(cache=True)
def displaced_kernel(poses, cos, sin, dx, dy, dtheta, out):
    """out[i] ← poses[i] moved by (dx, dy, dθ) in its own frame, given its heading's cos and sin; the heading
    wrapped (`wrap_angle`). Returns out."""
    for i in range(poses.shape[0]):
        out[i, 0] = poses[i, 0] + cos[i] * dx - sin[i] * dy
        out[i, 1] = poses[i, 1] + sin[i] * dx + cos[i] * dy
        out[i, 2] = wrap_angle(poses[i, 2] + dtheta)
    return out


def beyond_tolerance(difference: np.ndarray) -> np.ndarray:
    """A frame's log-likelihood differences, each shrunk toward 0 by `TOLERANCE` (and 0 within it): two poses a
    few centimetres apart both explain a frame, and the one the filter keeps correcting would otherwise win by
    the other's small offset, frame after frame; a place that explains the frames worse still falls behind."""
    return np.sign(difference) * np.maximum(np.abs(difference) - TOLERANCE, 0.0)


def _inverse(displacement: tuple[float, float, float]) -> tuple[float, float, float]:
    return relative(displacement, IDENTITY)


class RivalPoses:
    """Other places that explain the recent detections, and how much better the estimate explains them (see the
    module docstring). One per `Localizer`; it drives it.

    Parameters
    ----------
    settings : RivalSettings
        As given.
    seed : int or None
        Seeds the generator that draws candidates from single detections.
    """

    def __init__(self, settings: RivalSettings, seed: int | None) -> None:
        if not isinstance(settings, RivalSettings):
            raise ArgumentTypeError(f"rivals = {settings!r} must be an mcl.rivals.RivalSettings or None")
        self.settings = settings
        self._rng = np.random.default_rng(seed)
        self._odometry = IDENTITY  # the robot's dead-reckoned pose in an odometry frame of its own
        self._frames: deque = deque()  # (capture time, observations, odometry pose on arrival, motion since capture)
        self._poses = np.empty((0, 3))  # the rivals, where they are at `_moved_to`
        self._moved_to = IDENTITY
        self._lead = np.empty(0)
        self._track_start: float | None = None
        self._near: tuple[np.ndarray, float, tuple[float, float, float]] | None = None

    @property
    def log_odds(self) -> float:
        """How much better (log odds) the estimate explains the frames than the best rival; +inf without one."""
        return -float(self._lead.max()) if self._lead.size else math.inf

    @property
    def poses(self) -> tuple[np.ndarray, np.ndarray]:
        """The rivals (R, 3), where they are now (carried along the odometry since the last frame), with their
        leads (R,) over the estimate in log odds, best first (new arrays)."""
        order = np.argsort(-self._lead, kind="stable")
        now = displaced(self._poses, relative(self._moved_to, self._odometry)) if self._lead.size else self._poses
        return now[order], self._lead[order].copy()

    def moved(self, displacement: tuple[float, float, float]) -> None:
        """The robot moved by `displacement` (dx, dy, dθ) in its own frame, by odometry."""
        self._odometry = compose(self._odometry, displacement)

    def new_track(
        self, time: float | None, forget_frames: bool = False, near: tuple[np.ndarray, float] | None = None
    ) -> None:
        """The estimate starts a new track at `time` (a reset, or a re-localization): rivals are looked for again.
        forget_frames: also drop the frames kept (a reset: what came before says nothing of the new belief).
        near: (poses (K, 3), radius [m]) after a reset around candidate poses: a rival must lie within `radius` of
        one of them (a place the reset ruled out is no rival; a known pose has none); None: anywhere."""
        self._track_start = time
        # a rival moves with the robot's odometry, so it stays within the robot's displacement since the reset
        # of where it stood then (`_add`)
        self._near = None if near is None else (near[0], near[1], self._odometry)
        self._poses, self._lead = np.empty((0, 3)), np.empty(0)
        if forget_frames:
            self._frames.clear()

    def frame(
        self,
        sensor_model: Any,
        observations: Observations,
        estimate: np.ndarray,
        since: tuple[float, float, float] | None,
        time: float,
        field: Field,
    ) -> float:
        """A frame captured at `time` (`since`: the robot's displacement from the capture to now, None: none),
        scored after the correction whose estimate (x, y, θ) is now `estimate`; new rivals only on `field`'s
        carpet. Returns `log_odds`."""
        if len(observations) == 0:
            return self.log_odds
        s = self.settings
        self._frames.append((time, observations, self._odometry, since))  # the pose at capture when needed
        while self._frames and self._frames[0][0] < time - s.window:
            self._frames.popleft()
        if self._track_start is None:
            self._track_start = time
        if time - self._track_start >= s.young:
            if self._lead.size:
                self._poses, self._lead = np.empty((0, 3)), np.empty(0)
            return math.inf
        estimate = np.asarray(estimate, dtype=np.float64).reshape(1, 3)
        back = self._back(self._frames[-1])  # from now to the capture, in the robot frame
        estimate_ll = float(sensor_model.log_likelihood(displaced(estimate, back), observations)[0])
        if self._poses.shape[0]:
            self._poses = displaced(self._poses, relative(self._moved_to, self._odometry))
            self._poses, scores = self._refine(self._poses, sensor_model, observations, back)
            self._lead = self._lead + beyond_tolerance(scores - estimate_ll)
        self._moved_to = self._odometry
        self._add(self._candidates(sensor_model, observations, back), estimate, sensor_model, observations, back, field)
        self._prune(estimate)
        return self.log_odds

    def _refine(
        self, poses: np.ndarray, sensor_model: Any, observations: Observations, back
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each pose moved to the best of itself and `REFINE` jittered copies on this frame (the estimate is
        corrected by every frame; a rival left where it was born would lose to it by its own offset alone).
        Returns the poses (R, 3) and their log-likelihoods of the frame (R,)."""
        count = poses.shape[0]
        tries = np.repeat(poses[None], REFINE + 1, axis=0)
        tries[1:] += self._rng.standard_normal((REFINE, count, 3)) * np.asarray(self.settings.jitter)
        tries[..., 2] = wrap_angles(tries[..., 2])
        flat = tries.reshape(-1, 3)
        scores = np.asarray(sensor_model.log_likelihood(displaced(flat, back), observations)).reshape(REFINE + 1, count)
        best = np.argmax(scores, axis=0)  # the first of equals: the pose itself
        return tries[best, np.arange(count)], scores[best, np.arange(count)]

    def _candidates(self, sensor_model: Any, observations: Observations, back) -> np.ndarray:
        """Poses that explain this frame, moved to now."""
        parts = []
        if len(observations) >= 2 and getattr(sensor_model, "landmark_table", None) is not None:
            parts.append(poses_from_pairs(sensor_model, observations))
        sampler = getattr(sensor_model, "sample_poses", None)
        if self.settings.candidates and callable(sampler):
            parts.append(np.asarray(sampler(observations, self.settings.candidates, self._rng, heading=None), float))
        if not parts:
            return np.empty((0, 3))
        return displaced(np.concatenate(parts).reshape(-1, 3), _inverse(back))

    def _back(self, frame: tuple) -> tuple[float, float, float]:
        """Where the robot was at a kept frame's capture, in its frame now."""
        _, _, odometry, since = frame  # the odometry pose when the frame came, and the motion since its capture
        at_capture = odometry if since is None else compose(odometry, _inverse(since))
        return relative(self._odometry, at_capture)

    def _apart(self, poses: np.ndarray, estimate: np.ndarray) -> np.ndarray:
        s = self.settings
        mirror = Field.mirror_poses(estimate)[0]
        return (np.hypot(poses[:, 0] - estimate[0, 0], poses[:, 1] - estimate[0, 1]) > s.apart) & (
            np.hypot(poses[:, 0] - mirror[0], poses[:, 1] - mirror[1]) > s.mirror_apart
        )

    def _add(
        self, candidates: np.ndarray, estimate: np.ndarray, sensor_model: Any, observations: Observations, back, field
    ) -> None:
        """New rivals from this frame's `candidates` (its `observations`, captured `back` from now), scored over
        the earlier frames."""
        candidates = candidates[self._apart(candidates, estimate) & field.contains(candidates[:, :2])]
        if self._near is not None and candidates.shape[0]:
            poses, radius, since = self._near
            radius += math.hypot(self._odometry[0] - since[0], self._odometry[1] - since[1])
            gap = np.hypot(candidates[:, None, 0] - poses[None, :, 0], candidates[:, None, 1] - poses[None, :, 1])
            candidates = candidates[(gap <= radius).any(axis=1)]
        if candidates.shape[0] and self._poses.shape[0]:  # one rival per place
            gap = np.hypot(
                candidates[:, None, 0] - self._poses[None, :, 0], candidates[:, None, 1] - self._poses[None, :, 1]
            )
            candidates = candidates[(gap > self.settings.apart).all(axis=1)]
        if not candidates.shape[0]:
            return
        scores = np.zeros(candidates.shape[0])
        for _ in range(BORN_REFINE):  # drawn with the detections' noise: refined on their frame first
            candidates, scores = self._refine(candidates, sensor_model, observations, back)
        if candidates.shape[0] > self.settings.newborn:  # the best on their frame (the first of equals)
            candidates = candidates[np.argsort(-scores, kind="stable")[: self.settings.newborn]]
        # scored over the earlier frames (not the one they were drawn from), at most `WINDOW_FRAMES` of them
        # spread evenly, together with the estimate: one call per frame
        earlier = list(self._frames)[:-1]
        if len(earlier) > WINDOW_FRAMES:
            earlier = [earlier[int(i)] for i in np.linspace(0, len(earlier) - 1, WINDOW_FRAMES)]
        both = np.concatenate([candidates, estimate])
        lead = np.zeros(candidates.shape[0])
        for frame in earlier:
            scores = np.asarray(sensor_model.log_likelihood(displaced(both, self._back(frame)), frame[1]))
            lead += beyond_tolerance(scores[:-1] - scores[-1])
        self._poses = np.concatenate([self._poses, candidates])
        self._lead = np.concatenate([self._lead, lead])

    def _prune(self, estimate: np.ndarray) -> None:
        if not self._lead.size:
            return
        keep = self._apart(self._poses, estimate) & (self._lead > -math.log(self.settings.drop_odds))
        poses, lead = self._poses[keep], self._lead[keep]
        if lead.size > self.settings.keep:
            best = np.argsort(-lead, kind="stable")[: self.settings.keep]
            poses, lead = poses[best], lead[best]
        self._poses, self._lead = poses, lead
