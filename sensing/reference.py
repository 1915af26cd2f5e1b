"""The sensor kernels' plain numpy twins, which the tests and the benchmark compare the compiled kernels with.

    from sensing import reference
    out = reference.landmark_log_likelihood(poses, candidates_by_kind, kinds, ranges, bearings, ...)

Each function computes what the kernel it names computes (`sensing.landmarks`, `sensing.lines`,
`sensing.observations`, `sensing.resetting`), with numpy's arrays or Python's `math`: the same results to
rounding, bit for bit where its docstring says so. `LandmarkTwin` and `LineTwin` are the models computed with
them (a model's `numpy_twin()`), which the reference engine scores and draws through.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from field import LandmarkType
from field.angles import wrap_angle, wrap_angles
from field.checks import LARGEST_SIGMA, SMALLEST_SIGMA
from numerics.reference import sincos

from .observations import MAX_BEARING, MAX_RANGE, Observations
from .view import CameraView

if TYPE_CHECKING:  # the models import this module
    from .landmarks import LandmarkSensorModel
    from .lines import LineSensorModel


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


class LandmarkTwin:
    """A `sensing.LandmarkSensorModel` computed in plain numpy (`LandmarkSensorModel.numpy_twin()`): the model's
    compiled calls as numpy code, each with the parameters and the result of the call it names. The reference
    engine (`mcl.engine.ReferenceEngine`) scores and draws through it, and the tests compare the kernels with it.

    Parameters
    ----------
    model : LandmarkSensorModel
        The model whose settings and landmark table the twin reads (not copied: a twin follows its model).
    """

    def __init__(self, model: LandmarkSensorModel) -> None:
        self.model = model

    def explained(
        self,
        pose: Sequence[float] | np.ndarray,
        observations: Observations,
        gate: float = 3.0,
        range_slack: float = 0.0,
        bearing_slack: float = 0.0,
    ) -> np.ndarray:
        """`LandmarkSensorModel.explained` in plain numpy: the same parameters and result."""
        model = self.model
        observations = Observations.coerce(observations)
        model.check(observations)
        m = len(observations)
        explained = np.zeros(m, dtype=bool)
        x, y, theta = float(pose[0]), float(pose[1]), float(pose[2])
        range_sigmas, bearing_sigmas = model._sigmas(observations)
        range_sigmas = range_sigmas + range_slack
        bearing_sigmas = bearing_sigmas + bearing_slack
        for kind in np.unique(observations.kinds):
            rows = np.flatnonzero(observations.kinds == kind)
            landmarks = model.candidates(int(kind))
            dx = landmarks[:, 0] - x
            dy = landmarks[:, 1] - y
            range_error = (observations.ranges[rows, None] - np.hypot(dx, dy)[None, :]) / range_sigmas[rows, None]
            bearing_error = (
                wrap_angles(observations.bearings[rows, None] - (np.arctan2(dy, dx) - theta)[None, :])
                / bearing_sigmas[rows, None]
            )
            explained[rows] = (range_error**2 + bearing_error**2 <= gate * gate).any(axis=1)
        return explained

    def seen(
        self,
        pose: Sequence[float] | np.ndarray,
        observations: Observations,
        view: CameraView,
        gate: float = 3.0,
        range_slack: float = 0.0,
        bearing_slack: float = 0.0,
    ) -> tuple[int, int]:
        """`LandmarkSensorModel.seen` in plain numpy: the same parameters and result."""
        model = self.model
        observations = Observations.coerce(observations)
        model.check(observations)
        x, y, theta = float(pose[0]), float(pose[1]), float(pose[2])
        dx = model._table[:, 0] - x
        dy = model._table[:, 1] - y
        r = np.hypot(dx, dy)
        bearing = np.arctan2(dy, dx) - theta
        inside = (
            (r >= view.min_range)
            & (r <= view.max_ranges[model._table_kinds])
            & (np.abs(wrap_angles(bearing - view.yaw)) <= view.half_fov)
        )
        range_sigmas, bearing_sigmas = model._sigmas(observations)
        range_sigmas = range_sigmas + range_slack
        bearing_sigmas = bearing_sigmas + bearing_slack
        seen = 0
        for k in np.flatnonzero(inside):
            rows = observations.kinds == model._table_kinds[k]
            range_error = (observations.ranges[rows] - r[k]) / range_sigmas[rows]
            bearing_error = wrap_angles(observations.bearings[rows] - bearing[k]) / bearing_sigmas[rows]
            seen += bool((range_error**2 + bearing_error**2 <= gate * gate).any())
        return int(inside.sum()), seen

    def missed_in_view(self, poses: np.ndarray, observations: Observations) -> np.ndarray:
        """Plain numpy twin of the negative-information term `log_likelihood` adds (zeros when `scores_view` is
        False), for (N, 3) poses: (N,) log-likelihood terms."""
        from .landmarks import VIEW_BEARING_SLACK, VIEW_GATE, VIEW_RANGE_SLACK  # (landmarks imports this module)

        model = self.model
        poses = np.asarray(poses, dtype=np.float64)
        if observations.view is None or not model.scores_view(observations):
            return np.zeros(poses.shape[0])
        view = observations.view.inset(model.view_inset)
        missed = np.array(
            [
                np.subtract(*self.seen(pose, observations, view, VIEW_GATE, VIEW_RANGE_SLACK, VIEW_BEARING_SLACK))
                for pose in poses
            ],
            dtype=np.float64,
        )
        return missed * math.log1p(-model.detection_rate)

    def log_likelihood(self, poses: np.ndarray, observations: Observations) -> np.ndarray:
        """`LandmarkSensorModel.log_likelihood` in plain numpy (slow; for tests and the benchmark): the same parameters and result."""
        model = self.model
        observations = Observations.coerce(observations)
        model.check(observations)
        range_sigmas, bearing_sigmas = model._sigmas(observations)
        by_kind = {t.value: model.candidates(t) for t in LandmarkType}
        return landmark_log_likelihood(
            poses,
            by_kind,
            observations.kinds,
            observations.ranges,
            observations.bearings,
            range_sigmas,
            bearing_sigmas,
            model.bearing_model == "exact",
            model.outlier_weight,
            model.mixture == "sum",
        ) + self.missed_in_view(poses, observations)

    def sample_poses(
        self,
        observations: Observations,
        n: int,
        rng: np.random.Generator,
        heading: float | None = None,
        heading_sigma: float = 0.3,
    ) -> np.ndarray:
        """`LandmarkSensorModel.sample_poses` in plain numpy (the same parameters and result): the same draws
        give the same poses."""
        model = self.model
        observations = Observations.coerce(observations)
        model.check(observations)
        m = len(observations)
        if m == 0 or n <= 0:
            return np.empty((0, 3))
        range_sigmas, bearing_sigmas = model._sigmas(observations)
        j = rng.integers(0, m, size=n)
        kinds = observations.kinds[j]
        counts = model._offsets[kinds + 1] - model._offsets[kinds]
        k = model._offsets[kinds] + np.floor(rng.random(n) * counts).astype(np.int64)
        if heading is None:
            theta = rng.uniform(-math.pi, math.pi, n)
        else:
            theta = heading + heading_sigma * rng.standard_normal(n)
        r = np.maximum(observations.ranges[j] + range_sigmas[j] * rng.standard_normal(n), 0.0)
        b = observations.bearings[j] + bearing_sigmas[j] * rng.standard_normal(n)
        direction = theta + b
        poses = np.empty((n, 3))
        poses[:, 0] = model._table[k, 0] - r * np.cos(direction)
        poses[:, 1] = model._table[k, 1] - r * np.sin(direction)
        poses[:, 2] = wrap_angles(theta)
        return poses


class LineTwin:
    """A `sensing.LineSensorModel` computed in plain numpy (`LineSensorModel.numpy_twin()`).

    Parameters
    ----------
    model : LineSensorModel
        The model whose distance map and settings the twin reads.
    """

    def __init__(self, model: LineSensorModel) -> None:
        self.model = model

    def log_likelihood(self, poses: np.ndarray, observations: Observations) -> np.ndarray:
        """`LineSensorModel.log_likelihood` in plain numpy, from the distance map (exp per point): the same
        parameters and result to rounding."""
        model = self.model
        points = model.used_points(Observations.coerce(observations))
        if points.shape[0] == 0:
            return np.zeros(poses.shape[0])
        x0, y0 = model._origin
        return line_log_likelihood(
            poses, points, model._distance, x0, y0, model.resolution, model.sigma, model.outlier_weight
        )
