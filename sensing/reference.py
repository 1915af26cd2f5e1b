"""The sensor kernels' plain numpy twins, which the tests and the benchmark compare the compiled kernels with.

    from sensing import reference
    out = reference.landmark_log_likelihood(poses, candidates_by_kind, kinds, ranges, bearings, ...)

Each function computes what the kernel it names computes (`sensing.landmarks`, `sensing.lines`,
`sensing.observations`, `sensing.resetting`), with numpy's arrays or Python's `math`: the same results to
rounding, bit for bit where its docstring says so. The models' `*_reference` methods and
`sample_poses(..., reference=True)` score and draw through them.
"""

from __future__ import annotations

import math

import numpy as np

from field.angles import wrap_angle, wrap_angles
from field.checks import LARGEST_SIGMA, SMALLEST_SIGMA
from numerics.reference import sincos

from .observations import MAX_BEARING, MAX_RANGE


def landmark_log_likelihood(
    poses,
    candidates_by_kind,
    kinds,
    ranges,
    bearings,
    range_sigmas,
    bearing_sigmas,
    exact,
    outlier_weight,
    sum_mixture=False,
):
    """Plain numpy version of `sensing.landmarks.landmark_log_likelihood`, one detection at a time (for tests
    and the benchmark)."""
    total = np.zeros(poses.shape[0])
    for kind, r, b, sr, sb in zip(kinds, ranges, bearings, range_sigmas, bearing_sigmas):
        cand = candidates_by_kind[int(kind)]
        d = cand[None, :, :] - poses[:, None, :2]  # (N, K, 2) in the field frame
        dist = np.hypot(d[..., 0], d[..., 1])
        expected = np.arctan2(d[..., 1], d[..., 0]) - poses[:, 2:3]
        error = wrap_angles(b - expected)
        score = -0.5 * ((r - dist) / sr) ** 2
        if exact:
            score = score - 0.5 * (error / sb) ** 2
        else:
            score = score + (np.cos(error) - 1.0) / sb**2
        best = score.max(axis=1)
        floor = math.log(outlier_weight)
        total += np.logaddexp(best, floor) if sum_mixture else np.maximum(best, floor)
    return total


def line_log_likelihood(poses, points, distance, x0, y0, cell, sigma, outlier_weight):
    """Plain numpy version of `sensing.lines.line_log_likelihood`."""
    c, s = sincos(poses[:, 2:3])
    gx = poses[:, 0:1] + c * points[None, :, 0] - s * points[None, :, 1]
    gy = poses[:, 1:2] + s * points[None, :, 0] + c * points[None, :, 1]
    col = np.floor((gx - x0) / cell).astype(np.int64)
    row = np.floor((gy - y0) / cell).astype(np.int64)
    inside = (col >= 0) & (col < distance.shape[1]) & (row >= 0) & (row < distance.shape[0])
    d = distance[np.clip(row, 0, distance.shape[0] - 1), np.clip(col, 0, distance.shape[1] - 1)]
    match = np.where(inside, np.exp(-0.5 * (d / sigma) ** 2), 0.0)
    return np.log(match + outlier_weight).sum(axis=1)


def first_invalid(kinds, ranges, bearings, range_sigmas, bearing_sigmas, is_kind) -> tuple[int, int]:
    """`sensing.observations.first_invalid` in numpy."""
    inside = (kinds >= 0) & (kinds < is_kind.shape[0])
    known = np.zeros(kinds.shape[0], dtype=bool)
    known[inside] = is_kind[kinds[inside]]
    failing = [
        ~known,
        ~np.isfinite(ranges),
        ~np.isfinite(bearings),
        ~((ranges >= 0) & (ranges <= MAX_RANGE) & (np.abs(bearings) <= MAX_BEARING)),
    ]
    for sigmas in (range_sigmas, bearing_sigmas):
        failing.append(~np.isnan(sigmas) & ~((sigmas >= SMALLEST_SIGMA) & (sigmas <= LARGEST_SIGMA)))
    for check, bad in enumerate(failing):
        if bad.any():
            return check, int(np.argmax(bad))
    return -1, -1


def pair_poses(table, offsets, kinds, points, range_sigmas, gate, slack):
    """Plain Python twin of `sensing.resetting.pair_poses`: the same poses in the same order, bit for bit (the same operations
    on the same floats, with Python's `math`, as the kernel's)."""
    out = []
    count = kinds.shape[0]
    for i in range(count - 1):
        for j in range(i + 1, count):
            seen_x = float(points[j, 0]) - float(points[i, 0])
            seen_y = float(points[j, 1]) - float(points[i, 1])
            seen_length = math.hypot(seen_x, seen_y)
            if seen_length < 1e-6:
                continue
            seen_angle = math.atan2(seen_y, seen_x)
            middle_seen_x = 0.5 * (float(points[i, 0]) + float(points[j, 0]))
            middle_seen_y = 0.5 * (float(points[i, 1]) + float(points[j, 1]))
            tolerance = gate * math.hypot(float(range_sigmas[i]), float(range_sigmas[j])) + slack
            for a in range(int(offsets[kinds[i]]), int(offsets[kinds[i] + 1])):
                for b in range(int(offsets[kinds[j]]), int(offsets[kinds[j] + 1])):
                    ax, ay, bx, by = (float(v) for v in (table[a, 0], table[a, 1], table[b, 0], table[b, 1]))
                    length = math.hypot(bx - ax, by - ay)
                    if not (abs(length - seen_length) <= tolerance and length > 1e-6):
                        continue
                    theta = math.atan2(by - ay, bx - ax) - seen_angle
                    c, s = math.cos(theta), math.sin(theta)
                    out.append(
                        (
                            0.5 * (ax + bx) - (c * middle_seen_x - s * middle_seen_y),
                            0.5 * (ay + by) - (s * middle_seen_x + c * middle_seen_y),
                            wrap_angle(theta),
                        )
                    )
    return np.array(out, dtype=np.float64).reshape(-1, 3)
