"""Sensor resetting from pairs of detections: every pose that explains two landmark detections at once.

    from sensing import LandmarkSensorModel
    from sensing.resetting import poses_from_pairs

    model = LandmarkSensorModel(field)
    poses = poses_from_pairs(model, observations)     # (P, 3): one pose per consistent association

One detection (range r, bearing b) of a landmark type with K landmarks puts the robot on K circles, any
heading; two detections fix the pose for each choice of which landmark each one is. For detections i and j
seen at q_i, q_j in the robot frame and landmarks l_i, l_j in the field frame, the heading is
θ = angle(l_j − l_i) − angle(q_j − q_i) and the position the one that maps the midpoint of q onto the midpoint
of l. A choice is kept when the two distances agree, |‖l_j − l_i‖ − ‖q_j − q_i‖| within `gate` standard
deviations of the two range errors (plus `slack` metres): a pair of real detections always keeps its true
association, and on the point-symmetric field its mirror (−x, −y, θ + π) too.

This is the proposal that lets a lost filter consider every pose that explains what the camera sees, whatever
the heading: `mcl.relocalization` scores these poses and decides which to inject. `pair_poses` is the compiled
kernel, `sensing.reference.pair_poses` its plain Python twin (the same poses in the same order, bit for bit); no random
draws.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from field.angles import wrap_angle
from field.moved import moved_names

from . import reference as twins
from .observations import Observations

# The numpy twins moved to the package's `reference` module; their old names still work, with a warning.
__getattr__ = moved_names(__name__, {"pair_poses_reference": "sensing.reference.pair_poses"})

MAX_DETECTIONS = 8  # detections used per frame (the closest ones): 28 pairs at most


def _nearest(model, observations: Observations, max_detections: int):
    """The `max_detections` nearest detections: kinds, robot-frame points (D, 2), range σ (the detection's own
    or the model's)."""
    order = np.argsort(observations.ranges, kind="stable")[:max_detections]
    ranges = observations.ranges[order]
    bearings = observations.bearings[order]
    given = observations.range_sigmas[order]
    range_sigmas = np.where(np.isnan(given), model.range_sigma(ranges), given)
    points = np.column_stack([ranges * np.cos(bearings), ranges * np.sin(bearings)])
    return np.ascontiguousarray(observations.kinds[order]), np.ascontiguousarray(points), range_sigmas


def poses_from_pairs(
    model,
    observations: Observations,
    gate: float = 3.0,
    slack: float = 0.1,
    max_detections: int = MAX_DETECTIONS,
    reference: bool = False,
) -> np.ndarray:
    """Every pose (P, 3) that sees two of the frame's detections where they were seen, one per consistent
    association of the pair with landmarks of their types (see the module docstring). Needs a landmark
    model with `landmark_table` and `range_sigma(ranges)`; empty (0, 3) with fewer than two detections.
    reference: compute them with `sensing.reference.pair_poses` (plain Python, the same bits) instead of the kernel."""
    observations = Observations.coerce(observations)
    if len(observations) < 2:
        return np.empty((0, 3))
    table, offsets = model.landmark_table
    kinds, points, range_sigmas = _nearest(model, observations, max_detections)
    compute = twins.pair_poses if reference else pair_poses
    return compute(table, offsets, kinds, points, range_sigmas, float(gate), float(slack))


@numba.njit(cache=True)
def pair_poses(table, offsets, kinds, points, range_sigmas, gate, slack):
    """The poses of every consistent association of every pair (i < j) of detections, pairs in order and, in
    each pair, landmark i's candidates outer and landmark j's inner (as `sensing.reference.pair_poses`). `table` and
    `offsets` as `LandmarkSensorModel.landmark_table`; `points` (D, 2) the detections in the robot frame."""
    count = kinds.shape[0]
    total = 0
    for i in range(count - 1):
        for j in range(i + 1, count):
            total += (offsets[kinds[i] + 1] - offsets[kinds[i]]) * (offsets[kinds[j] + 1] - offsets[kinds[j]])
    out = np.empty((total, 3))
    n = 0
    for i in range(count - 1):
        for j in range(i + 1, count):
            seen_x = points[j, 0] - points[i, 0]
            seen_y = points[j, 1] - points[i, 1]
            seen_length = math.hypot(seen_x, seen_y)
            if seen_length < 1e-6:
                continue
            seen_angle = math.atan2(seen_y, seen_x)
            middle_seen_x = 0.5 * (points[i, 0] + points[j, 0])
            middle_seen_y = 0.5 * (points[i, 1] + points[j, 1])
            tolerance = gate * math.hypot(range_sigmas[i], range_sigmas[j]) + slack
            for a in range(offsets[kinds[i]], offsets[kinds[i] + 1]):
                for b in range(offsets[kinds[j]], offsets[kinds[j] + 1]):
                    apart_x = table[b, 0] - table[a, 0]
                    apart_y = table[b, 1] - table[a, 1]
                    length = math.hypot(apart_x, apart_y)
                    if not (abs(length - seen_length) <= tolerance and length > 1e-6):
                        continue
                    theta = math.atan2(apart_y, apart_x) - seen_angle
                    c = math.cos(theta)
                    s = math.sin(theta)
                    middle_x = 0.5 * (table[a, 0] + table[b, 0])
                    middle_y = 0.5 * (table[a, 1] + table[b, 1])
                    out[n, 0] = middle_x - (c * middle_seen_x - s * middle_seen_y)
                    out[n, 1] = middle_y - (s * middle_seen_x + c * middle_seen_y)
                    out[n, 2] = wrap_angle(theta)
                    n += 1
    return out[:n].copy()
