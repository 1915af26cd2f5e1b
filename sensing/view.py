"""Where the camera looked when a frame was taken: what the frame could have seen.

    from sensing.view import CameraView

    view = CameraView(yaw=head_pan, half_fov=math.radians(30), max_range=6.0, min_range=0.3)
    loc.observe(observations, capture_time=t_image, view=view)

A frame's detections say what was seen. The view says what *could* have been seen: a landmark inside the
camera's horizontal field of view, between `min_range` (closer ones are below the image) and `max_range` (the
vision does not report farther ones). From the estimated pose, the landmarks inside the view should mostly be
detected; when the estimate expects many that the frame did not report, the estimate is probably wrong, even
when every detection it did get fits (perceptual aliasing: a wrong pose that explains a few detections). This
is *negative information*; `LandmarkSensorModel.seen` counts it and `mcl.localizer`'s quality uses it.

All angles in the robot frame (x forward, y left), radians; ranges in metres. A team knows its head's pan
angle (the joint reading at capture time), its camera's field of view and roughly how far its vision detects
landmarks; the view is optional everywhere it is taken.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from field.checks import LARGEST_ANGLE, LARGEST_COORDINATE, real


@dataclass(frozen=True)
class CameraView:
    """The camera's view for one frame, in the robot frame.

    yaw:       rad, the bearing of the optical axis (the head's pan), within ±100 rad; kept wrapped to (-π, π]
    half_fov:  rad, half the horizontal field of view, within (0, π]
    max_range: m, the farthest landmark the vision reports, within (0, 1000]
    min_range: m, the nearest (closer ones are below the image), within [0, max_range)

    A bad value raises ValueError naming it (TypeError for a wrong type, `field.checks.ArgumentTypeError`).
    """

    yaw: float
    half_fov: float
    max_range: float
    min_range: float = 0.0

    def __post_init__(self) -> None:
        yaw = real("yaw", self.yaw, -LARGEST_ANGLE, LARGEST_ANGLE)
        object.__setattr__(self, "yaw", math.remainder(yaw, 2.0 * math.pi))
        object.__setattr__(self, "half_fov", real("half_fov", self.half_fov, 0.0, math.pi, low_open=True))
        max_range = real("max_range", self.max_range, 0.0, LARGEST_COORDINATE, low_open=True)
        object.__setattr__(self, "max_range", max_range)
        object.__setattr__(self, "min_range", real("min_range", self.min_range, 0.0, max_range, high_open=True))

    def inset(self, share: float) -> "CameraView":
        """The view shrunk to `share` (0, 1] of its half field of view and of its range span (the nearest range
        moved out and the farthest in by the same share): the part of the view where a landmark is expected
        even with a small error in the pose or in the view."""
        share = real("share", share, 0.0, 1.0, low_open=True)
        margin = 0.5 * (1.0 - share) * (self.max_range - self.min_range)
        return CameraView(self.yaw, share * self.half_fov, self.max_range - margin, self.min_range + margin)
