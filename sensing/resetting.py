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
the heading: `mcl.relocalization` scores these poses and decides which to inject. Plain numpy (it runs only
when a filter injects); deterministic: no random draws.
"""
from __future__ import annotations

import math

import numpy as np

from field.angles import wrap_angles

from .observations import Observations

MAX_DETECTIONS = 8      # detections used per frame (the closest ones): 28 pairs at most


def poses_from_pairs(model, observations: Observations, gate: float = 3.0, slack: float = 0.1,
                     max_detections: int = MAX_DETECTIONS) -> np.ndarray:
    """Every pose (P, 3) that sees two of the frame's detections where they were seen, one per consistent
    association of the pair with landmarks of their types (see the module docstring). Needs a landmark
    model with `candidates(kind)` and `range_sigma(ranges)`; empty (0, 3) with fewer than two detections."""
    observations = Observations.coerce(observations)
    m = len(observations)
    if m < 2:
        return np.empty((0, 3))
    ranges = observations.ranges
    order = np.argsort(ranges, kind="stable")[:max_detections]      # near detections are the precise ones
    kinds = observations.kinds[order]
    ranges = ranges[order]
    bearings = observations.bearings[order]
    given = observations.range_sigmas[order]
    range_sigmas = np.where(np.isnan(given), model.range_sigma(ranges), given)
    points = np.column_stack([ranges * np.cos(bearings), ranges * np.sin(bearings)])
    out = []
    count = len(order)
    for i in range(count - 1):
        candidates_i = model.candidates(int(kinds[i]))
        if candidates_i.shape[0] == 0:
            continue
        for j in range(i + 1, count):
            candidates_j = model.candidates(int(kinds[j]))
            if candidates_j.shape[0] == 0:
                continue
            seen = points[j] - points[i]
            seen_length = math.hypot(seen[0], seen[1])
            if seen_length < 1e-6:
                continue
            # every (landmark for i, landmark for j) association, as (Ki·Kj, 2) arrays
            li = np.repeat(candidates_i, candidates_j.shape[0], axis=0)
            lj = np.tile(candidates_j, (candidates_i.shape[0], 1))
            apart = lj - li
            length = np.hypot(apart[:, 0], apart[:, 1])
            tolerance = gate * math.hypot(range_sigmas[i], range_sigmas[j]) + slack
            keep = (np.abs(length - seen_length) <= tolerance) & (length > 1e-6)
            if not keep.any():
                continue
            li, lj, apart = li[keep], lj[keep], apart[keep]
            theta = np.arctan2(apart[:, 1], apart[:, 0]) - math.atan2(seen[1], seen[0])
            cos, sin = np.cos(theta), np.sin(theta)
            middle_seen = 0.5 * (points[i] + points[j])
            middle = 0.5 * (li + lj)
            poses = np.empty((theta.shape[0], 3))
            poses[:, 0] = middle[:, 0] - (cos * middle_seen[0] - sin * middle_seen[1])
            poses[:, 1] = middle[:, 1] - (sin * middle_seen[0] + cos * middle_seen[1])
            poses[:, 2] = wrap_angles(theta)
            out.append(poses)
    if not out:
        return np.empty((0, 3))
    return np.concatenate(out)
