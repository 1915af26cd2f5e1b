"""Hypothesis strategies for the library's inputs: fields, poses, particle sets, observations, camera views,
motion inputs and percepts, and the hostile values a refused call must reject."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from field import Field, LandmarkType, adultsize, kidsize, spl
from field.checks import LARGEST_ANGLE, LARGEST_COORDINATE, LARGEST_SIGMA, SMALLEST_SIGMA
from motion_models import FootstepEvent, MotionInput
from proprioception.collision import NO_COLLISION, CollisionPercept
from sensing import Observations
from sensing.view import CameraView

REFUSALS = (ValueError, TypeError)
"""The exceptions a refused call raises: the library's one error family (`field.checks.ArgumentTypeError` is
both)."""

_PRESETS = (spl, kidsize, adultsize)
_FIELDS: dict = {}


def _preset(make: Callable[[], Field]) -> Field:
    field = _FIELDS.get(make)
    if field is None:
        field = _FIELDS[make] = make()
    return field


def _carpet(field: Field, margin: float = 0.0) -> tuple[float, float, float, float]:
    """(x_min, x_max, y_min, y_max) of the field and its border strip, `margin` inside its edge."""
    if not isinstance(field, Field):
        raise TypeError(f"field = {field!r} must be a field.Field, not {type(field).__name__}")
    if not (
        isinstance(margin, (int, float)) and not isinstance(margin, bool) and math.isfinite(margin) and margin >= 0
    ):
        raise ValueError(f"margin = {margin!r} must be a finite number >= 0 (metres)")
    _, x_max, _, y_max = field.carpet
    half_x, half_y = x_max - margin, y_max - margin
    if half_x <= 0 or half_y <= 0:
        raise ValueError(f"margin = {margin!r} leaves nothing of the carpet of field {field.name!r}")
    return -half_x, half_x, -half_y, half_y


def _sizes(n) -> tuple[int, int]:
    """`n` as (low, high) counts: an int is exact, a pair a range."""
    if isinstance(n, (int, np.integer)) and not isinstance(n, bool):
        low = high = int(n)
    elif isinstance(n, tuple) and len(n) == 2 and all(isinstance(v, (int, np.integer)) for v in n):
        low, high = int(n[0]), int(n[1])
    else:
        raise TypeError(f"n = {n!r} must be an int or a (low, high) pair of ints")
    if not 1 <= low <= high:
        raise ValueError(f"n = {n!r} must be at least 1 (and low <= high)")
    return low, high


# -- strategies --------------------------------------------------------------------------------------------------
def fields() -> st.SearchStrategy[Field]:
    """The preset fields: spl, kidsize and adultsize (built once, shrinking toward spl).

    Returns
    -------
    hypothesis.strategies.SearchStrategy of field.Field
    """
    return st.sampled_from(_PRESETS).map(_preset)


def poses(field: Field, margin: float = 0.0) -> st.SearchStrategy[np.ndarray]:
    """Single poses (x, y, θ) on the carpet of `field`.

    Parameters
    ----------
    field : field.Field
        Positions lie on its carpet: the field and its border strip.
    margin : float, optional
        Distance [m] kept from the carpet's edge (default 0).

    Returns
    -------
    hypothesis.strategies.SearchStrategy of numpy.ndarray
        float64 arrays of shape (3,): finite, θ wrapped into (-π, π].
    """
    x_min, x_max, y_min, y_max = _carpet(field, margin)
    return st.tuples(
        st.floats(x_min, x_max), st.floats(y_min, y_max), st.floats(-math.pi, math.pi, exclude_min=True)
    ).map(lambda p: np.array(p, dtype=np.float64))


def _scale_poses(unit: np.ndarray, bounds: tuple[float, float, float, float]) -> np.ndarray:
    x_min, x_max, y_min, y_max = bounds
    out = np.empty_like(unit)
    out[:, 0] = np.minimum(x_min + unit[:, 0] * (x_max - x_min), x_max)
    out[:, 1] = np.minimum(y_min + unit[:, 1] * (y_max - y_min), y_max)
    theta = math.pi - unit[:, 2] * (2.0 * math.pi)  # unit in [0, 1): θ in (-π, π]
    out[:, 2] = np.where(theta <= -math.pi, math.pi, theta)
    return out


def pose_arrays(field: Field, n: int | tuple[int, int] = (1, 64), margin: float = 0.0) -> st.SearchStrategy:
    """Particle arrays (N, 3) on the carpet of `field`, as a filter and a motion model hold them.

    Parameters
    ----------
    field : field.Field
        Positions lie on its carpet (the field and its border strip).
    n : int or (int, int), optional
        The number of rows N: exactly `n`, or from `n[0]` to `n[1]` (default 1 to 64).
    margin : float, optional
        Distance [m] kept from the carpet's edge (default 0).

    Returns
    -------
    hypothesis.strategies.SearchStrategy of numpy.ndarray
        float64, C-contiguous, writeable arrays of shape (N, 3): finite, θ wrapped into (-π, π].
    """
    bounds = _carpet(field, margin)
    low, high = _sizes(n)
    unit = st.floats(0.0, 1.0, exclude_max=True)
    return (
        st.integers(low, high)
        .flatmap(lambda rows: hnp.arrays(np.float64, (rows, 3), elements=unit))
        .map(lambda a: _scale_poses(a, bounds))
    )


def particle_sets(field: Field, n: int | tuple[int, int] = (1, 64)) -> st.SearchStrategy:
    """Particle sets (poses, log_weights) that `ParticleFilter.set_particles` accepts.

    Parameters
    ----------
    field : field.Field
        Positions lie on its carpet.
    n : int or (int, int), optional
        The number of particles N: exactly `n` (give the filter's `n`), or a range (default 1 to 64).

    Returns
    -------
    hypothesis.strategies.SearchStrategy of tuple
        (poses, log_weights): poses as `pose_arrays` draws them, log_weights float64 (N,) unnormalized, within
        [-50, 10] or -inf, at least one of them finite.
    """
    weight = st.one_of(st.floats(-50.0, 10.0), st.floats(-50.0, 10.0), st.floats(-50.0, 10.0), st.just(-math.inf))

    def with_weights(p: np.ndarray) -> st.SearchStrategy:
        def finite_one(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            if not np.isfinite(w).any():
                w[0] = 0.0
            return p, w

        return hnp.arrays(np.float64, (p.shape[0],), elements=weight).map(finite_one)

    return pose_arrays(field, n).flatmap(with_weights)


def _kinds_on(field: Field) -> list[LandmarkType]:
    return [kind for kind in LandmarkType if np.asarray(field.landmarks_of(kind)).reshape(-1, 2).shape[0] > 0]


def _carpet_diagonal(field: Field) -> float:
    x_min, x_max, y_min, y_max = _carpet(field)
    return math.hypot(x_max - x_min, y_max - y_min)


def camera_views() -> st.SearchStrategy[CameraView]:
    """Camera views of a robot's head, as `observations(..., with_view=True)` attaches them.

    Returns
    -------
    hypothesis.strategies.SearchStrategy of sensing.view.CameraView
        Pan within ±2 rad, half field of view within [0.2, 1.2] rad, nearest range within [0, 0.5] m and
        farthest within [2, 10] m: one range for every landmark type, or a range per type (a mapping naming
        some types by name, with or without "others").
    """
    farthest = st.floats(2.0, 10.0)
    per_type = st.fixed_dictionaries(
        {}, optional={**{kind.name.lower(): farthest for kind in LandmarkType}, "others": farthest}
    ).filter(bool)
    return st.builds(
        CameraView,
        yaw=st.floats(-2.0, 2.0),
        half_fov=st.floats(0.2, 1.2),
        max_range=st.one_of(farthest, per_type),
        min_range=st.floats(0.0, 0.5),
    )


def observations(
    field: Field,
    max_detections: int = 8,
    with_sigmas: bool = False,
    *,
    min_detections: int = 0,
    max_range: float | None = None,
    max_line_points: int = 0,
    with_view: bool = False,
    seen_from: Sequence[float] | np.ndarray | None = None,
) -> st.SearchStrategy[Observations]:
    """Camera frames: `sensing.Observations` batches a sensor model for `field` accepts.

    Parameters
    ----------
    field : field.Field
        Every detection's type has a landmark on it.
    max_detections : int, optional
        The most landmark detections per batch (default 8).
    with_sigmas : bool, optional
        Also give each detection its own noise (range and bearing σ within [0.005, 1], each or neither, per
        detection); by default the sensor model's noise model decides (NaN, "not given").
    min_detections : int, optional
        The fewest landmark detections (default 0: empty frames too).
    max_range : float, optional
        The farthest range [m] (default: the diagonal of the carpet).
    max_line_points : int, optional
        The most field-line points (robot frame, within 6 m; default 0: none).
    with_view : bool, optional
        Attach a camera view (`sensing.view.CameraView`) to some batches (default False: none).
    seen_from : array_like, optional
        A pose (x, y, θ): the detections are then the field's landmarks as a robot there sees them, each
        range off by up to 5 % and each bearing by up to 0.05 rad, and the line points lie on the field's lines
        (within 2 cm) in that robot's frame; `max_range` does not apply. Default None: detections of any
        range and bearing, line points anywhere within 6 m.

    Returns
    -------
    hypothesis.strategies.SearchStrategy of sensing.Observations
        Typed detections with finite ranges in [0, max_range] and bearings in (-π, π].
    """
    if not 0 <= min_detections <= max_detections:
        raise ValueError(
            f"min_detections = {min_detections!r}, max_detections = {max_detections!r}: need "
            "0 <= min_detections <= max_detections"
        )
    kinds = _kinds_on(field)
    if not kinds and max_detections > 0:
        raise ValueError(f"field {field.name!r} has no landmarks to detect")
    far = _carpet_diagonal(field) if max_range is None else float(max_range)
    sigma = st.floats(0.005, 1.0)
    noise = (
        st.one_of(st.tuples(st.none(), st.none()), st.tuples(sigma, sigma)) if with_sigmas else st.just((None, None))
    )
    if seen_from is None:
        detection = st.tuples(
            st.sampled_from(kinds) if kinds else st.nothing(),
            st.floats(0.0, far),
            st.floats(-math.pi, math.pi, exclude_min=True),
            noise,
        )
        point = st.tuples(st.floats(-6.0, 6.0), st.floats(-6.0, 6.0))
    else:
        detection, point = _seen(field, seen_from, noise)
    points = st.lists(point, max_size=max_line_points) if max_line_points > 0 else st.just([])
    view = st.one_of(st.none(), camera_views()) if with_view else st.none()

    def build(args) -> Observations:
        rows, line_points, camera = args
        nan = math.nan
        batch = Observations.from_arrays(
            [int(r[0]) for r in rows],
            [r[1] for r in rows],
            [r[2] for r in rows],
            [nan if r[3][0] is None else r[3][0] for r in rows],
            [nan if r[3][1] is None else r[3][1] for r in rows],
            line_points=np.array(line_points, dtype=np.float64).reshape(-1, 2),
        )
        return batch if camera is None else batch.with_view(camera)

    return st.tuples(st.lists(detection, min_size=min_detections, max_size=max_detections), points, view).map(build)


def _seen(field: Field, pose, noise: st.SearchStrategy) -> tuple[st.SearchStrategy, st.SearchStrategy]:
    """Detections and line points as a robot at `pose` sees the field (see `observations`)."""
    x, y, theta = (float(v) for v in np.asarray(pose, dtype=np.float64).reshape(3))
    if not all(math.isfinite(v) for v in (x, y, theta)):
        raise ValueError(f"seen_from = {pose!r} must be a finite pose (x, y, θ)")
    landmarks = [
        (kind, float(p[0]), float(p[1]))
        for kind in _kinds_on(field)
        for p in np.asarray(field.landmarks_of(kind)).reshape(-1, 2)
    ]
    if not landmarks:
        raise ValueError(f"field {field.name!r} has no landmarks to detect")
    c, s = math.cos(theta), math.sin(theta)

    def detect(args):
        (kind, lx, ly), factor, offset, sigmas = args
        bearing = math.remainder(math.atan2(ly - y, lx - x) - theta + offset, 2.0 * math.pi)
        return kind, math.hypot(lx - x, ly - y) * factor, bearing if bearing > -math.pi else math.pi, sigmas

    def to_robot(args):
        (px, py), ex, ey = args
        dx, dy = px - x, py - y
        return c * dx + s * dy + ex, -s * dx + c * dy + ey

    on_lines = [tuple(p) for p in np.asarray(field.line_points(spacing=0.1)).tolist()]
    detection = st.tuples(st.sampled_from(landmarks), st.floats(0.95, 1.05), st.floats(-0.05, 0.05), noise).map(detect)
    point = st.tuples(st.sampled_from(on_lines), st.floats(-0.02, 0.02), st.floats(-0.02, 0.02)).map(to_robot)
    return detection, point


def edge_observations(field: Field | None = None, max_detections: int = 6) -> st.SearchStrategy[Observations]:
    """Frames at the edges of what `sensing.Observations` accepts: what a model must still score, or refuse
    with ValueError/TypeError.

    Parameters
    ----------
    field : field.Field, optional
        Unused for the values (any landmark type is drawn, also one the field lacks); kept for symmetry with
        `observations`.
    max_detections : int, optional
        The most detections per batch (default 6).

    Returns
    -------
    hypothesis.strategies.SearchStrategy of sensing.Observations
        Every landmark type; ranges of 0 and up to 1000 m; bearings up to ±100 rad; noises of 1e-6 and 1e3;
        line points up to 1000 m away, up to 40 of them; sometimes a camera view.
    """
    del field
    ranges = st.one_of(st.sampled_from([0.0, 5e-324, 1e-9, LARGEST_COORDINATE]), st.floats(0.0, LARGEST_COORDINATE))
    bearings = st.one_of(
        st.sampled_from([-LARGEST_ANGLE, LARGEST_ANGLE, math.pi, -math.pi, 0.0]),
        st.floats(-LARGEST_ANGLE, LARGEST_ANGLE),
    )
    sigmas = st.one_of(
        st.just(math.nan), st.sampled_from([SMALLEST_SIGMA, LARGEST_SIGMA]), st.floats(SMALLEST_SIGMA, LARGEST_SIGMA)
    )
    detection = st.tuples(st.sampled_from([kind.value for kind in LandmarkType]), ranges, bearings, sigmas, sigmas)
    coordinate = st.one_of(
        st.sampled_from([-LARGEST_COORDINATE, LARGEST_COORDINATE, 0.0]),
        st.floats(-LARGEST_COORDINATE, LARGEST_COORDINATE),
    )
    points = st.lists(st.tuples(coordinate, coordinate), max_size=40)

    def build(args) -> Observations:
        rows, line_points, camera = args
        kinds, ranges, bearings, range_sigmas, bearing_sigmas = (
            [list(column) for column in zip(*rows)] if rows else [[], [], [], [], []]
        )
        batch = Observations.from_arrays(
            kinds,
            ranges,
            bearings,
            range_sigmas,
            bearing_sigmas,
            line_points=np.array(line_points, dtype=np.float64).reshape(-1, 2),
        )
        return batch if camera is None else batch.with_view(camera)

    return st.tuples(st.lists(detection, max_size=max_detections), points, st.one_of(st.none(), camera_views())).map(
        build
    )


def collision_percepts() -> st.SearchStrategy[CollisionPercept]:
    """Collision percepts (`proprioception.collision.CollisionPercept`), `NO_COLLISION` often among them.

    Returns
    -------
    hypothesis.strategies.SearchStrategy of proprioception.collision.CollisionPercept
        Any sides, relative deviations within [0, 10], rates within [0, 1].
    """
    return st.one_of(
        st.just(NO_COLLISION),
        st.builds(
            CollisionPercept,
            left=st.booleans(),
            right=st.booleans(),
            s_rel_left=st.floats(0.0, 10.0),
            s_rel_right=st.floats(0.0, 10.0),
            rate=st.floats(0.0, 1.0),
            recent_left=st.booleans(),
            recent_right=st.booleans(),
        ),
    )


_STEP = st.tuples(st.floats(-0.08, 0.08), st.floats(-0.05, 0.05), st.floats(-0.4, 0.4))


def footstep_events() -> st.SearchStrategy[FootstepEvent]:
    """Support-foot swaps (`motion_models.FootstepEvent`) with the fields of both input sets.

    Returns
    -------
    hypothesis.strategies.SearchStrategy of motion_models.FootstepEvent
        Support +1 (left) or -1 (right); commanded and sensor-based steps within 8 cm, 5 cm and 0.4 rad;
        step durations within [0.1, 1] s.
    """
    return st.builds(
        FootstepEvent,
        support=st.sampled_from([1, -1]),
        commanded=_STEP,
        previous_commanded=_STEP,
        sensor=_STEP,
        previous_sensor=_STEP,
        duration=st.floats(0.1, 1.0),
        previous_duration=st.floats(0.1, 1.0),
    )


MOTION_KINDS = ("command", "odometry", "footstep", "any")


def motion_inputs(kind: str = "any", collision: bool = False, max_dt: float = 0.1) -> st.SearchStrategy:
    """Motion inputs (`motion_models.MotionInput`) of a walking robot, which the library's models accept.

    Parameters
    ----------
    kind : {"command", "odometry", "footstep", "any"}, optional
        "command": a walk request (vx within ±0.5 m/s, vy ±0.3 m/s, ω ±1.5 rad/s); "odometry": a measured
        step (dx within ±0.1 m, dy ±0.05 m, dθ ±0.5 rad); "footstep": odometry from the sensor-based step, with
        a `FootstepEvent` at most swaps (None between them); "any": any of the three (the default).
    collision : bool, optional
        Give each input a collision percept (`collision_percepts`), as `AdaptiveMotion` needs (default False:
        none).
    max_dt : float, optional
        The longest time step [s] (default 0.1); dt is drawn from [0, max_dt], for a measured step (odometry,
        footstep) 0 or at least 1 ms (a measured step over less is a clock glitch, which models may refuse).

    Returns
    -------
    hypothesis.strategies.SearchStrategy of motion_models.MotionInput
    """
    if kind not in MOTION_KINDS:
        raise ValueError(f"kind = {kind!r} must be one of {MOTION_KINDS}")
    if not (isinstance(max_dt, (int, float)) and 0 < max_dt <= 10.0):
        raise ValueError(f"max_dt = {max_dt!r} must be within (0, 10] s")
    dt = st.floats(0.0, float(max_dt))
    measured_dt = st.just(0.0) | st.floats(min(1e-3, float(max_dt)), float(max_dt))
    percept = collision_percepts() if collision else st.none()
    command = st.tuples(st.floats(-0.5, 0.5), st.floats(-0.3, 0.3), st.floats(-1.5, 1.5))
    odometry = st.tuples(st.floats(-0.1, 0.1), st.floats(-0.05, 0.05), st.floats(-0.5, 0.5))

    def footstep_input(dt_: float, event, step, percept_) -> MotionInput:
        return MotionInput(
            dt=dt_, odometry=event.sensor if event is not None else step, collision=percept_, footstep=event
        )

    by_kind = {
        "command": st.builds(MotionInput, dt=dt, command=command, collision=percept),
        "odometry": st.builds(MotionInput, dt=measured_dt, odometry=odometry, collision=percept),
        "footstep": st.builds(
            footstep_input, measured_dt, st.one_of(footstep_events(), footstep_events(), st.none()), _STEP, percept
        ),
    }
    if kind == "any":
        return st.one_of(*by_kind.values())
    return by_kind[kind]


def hostile_values() -> st.SearchStrategy[Any]:
    """Values no number, triple or pose argument of the library accepts: what a refused call must reject.

    NaN, ±inf, huge floats and integers (magnitude at least 1e7, up to 10**400), booleans, None, strings, bytes,
    complex numbers, plain objects, empty containers, and arrays that are empty, of the wrong shape, or full
    of NaN or inf. None is refused where a value is required; an optional argument takes it as "not given",
    and an observations argument takes None and empty sequences as "no detections".

    Returns
    -------
    hypothesis.strategies.SearchStrategy
    """
    arrays = [
        lambda: np.empty(0),
        lambda: np.empty((0, 3)),
        lambda: np.zeros((2, 2)),
        lambda: np.zeros((3, 3, 3)),
        lambda: np.full(3, np.nan),
        lambda: np.full((4, 3), np.inf),
        lambda: np.array(["x", "y", "z"]),
        lambda: np.zeros(2),
        lambda: np.zeros((5, 2)),
    ]
    huge = st.floats(allow_nan=False, allow_infinity=False).filter(lambda v: abs(v) >= 1e7)
    return st.one_of(
        st.sampled_from(
            [
                math.nan,
                math.inf,
                -math.inf,
                1e300,
                -1e300,
                1.7976931348623157e308,
                -1.7976931348623157e308,
                np.float64("nan"),
                np.float64("inf"),
            ]
        ),
        huge,
        st.integers(10**7, 10**400),
        st.integers(-(10**400), -(10**7)),
        st.none(),
        st.booleans(),
        st.text(max_size=4),
        st.binary(max_size=3),
        st.just(complex(1.0, 1.0)),
        st.builds(object),
        st.just({}),
        st.just(()),
        st.just([]),
        st.just(set()),
        st.lists(st.text(max_size=2), min_size=1, max_size=3),
        st.sampled_from(arrays).map(lambda make: make()),
    )


def hostile_motion_inputs() -> st.SearchStrategy[MotionInput]:
    """Motion inputs that `MotionInput` accepts but a model may not: what a model's `check` must refuse with
    ValueError/TypeError, or accept and then move by (finite poses, wrapped headings).

    Returns
    -------
    hypothesis.strategies.SearchStrategy of motion_models.MotionInput
        Inputs without command and odometry; with a collision or footstep field holding a hostile value
        (`hostile_values`); and the largest steps accepted (up to 99 m and 99 rad in one input, dt up to an
        hour), with a collision percept.
    """
    dt = st.floats(0.0, 0.1)
    command = st.tuples(st.floats(-0.5, 0.5), st.floats(-0.3, 0.3), st.floats(-1.5, 1.5))
    odometry = st.tuples(st.floats(-0.1, 0.1), st.floats(-0.05, 0.05), st.floats(-0.5, 0.5))
    largest_odometry = st.tuples(st.floats(-70.0, 70.0), st.floats(-70.0, 70.0), st.floats(-99.0, 99.0))

    def largest_command(dt_: float, share) -> MotionInput:
        vx, vy, w = (share[0] * 70.0 / dt_, share[1] * 70.0 / dt_, share[2] * 99.0 / dt_)
        return MotionInput(dt=dt_, command=(vx, vy, w), collision=NO_COLLISION)

    unit = st.floats(-1.0, 1.0)
    return st.one_of(
        st.builds(MotionInput, dt=dt),
        st.builds(MotionInput, dt=dt, collision=collision_percepts()),
        st.builds(MotionInput, dt=dt, command=command, collision=hostile_values()),
        st.builds(MotionInput, dt=dt, odometry=odometry, footstep=hostile_values()),
        st.builds(MotionInput, dt=dt, command=command, collision=collision_percepts(), footstep=hostile_values()),
        st.builds(MotionInput, dt=st.floats(0.0, 3600.0), odometry=largest_odometry, collision=collision_percepts()),
        st.builds(largest_command, st.floats(0.01, 3600.0), st.tuples(unit, unit, unit)),
    )
