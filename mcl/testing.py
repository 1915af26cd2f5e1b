"""Property-based testing for teams: hypothesis strategies, filter invariants and model contract checks.

This module imports hypothesis, which the library itself does not need: install the `test` extra first::

    pip install robocup-mcl[test]

What it offers, all public:

- Strategies (hypothesis) for the library's inputs: `fields`, `poses`, `pose_arrays`, `particle_sets`,
  `observations`, `edge_observations`, `camera_views`, `motion_inputs`, `hostile_motion_inputs`,
  `collision_percepts`, `footstep_events`, and `hostile_values` (what a refused call must reject).
- Invariants of a `mcl.ParticleFilter`, plain functions that raise AssertionError with a message naming what
  broke: `assert_weights_normalized`, `assert_poses_finite_and_wrapped`, `snapshot` and `assert_unchanged`,
  `assert_refused_leaves_state`, `assert_same_seed_same_run`.
- Contract checks of any motion or sensor model, the library's or a team's own: `check_motion_model` and
  `check_sensor_model` draw examples with hypothesis and run `assert_motion_contract` and
  `assert_sensor_contract` on each. They use a model only through the interface the filter uses (`check`,
  `predict`, `particle_state`; `check`, `log_likelihood`, `terms`), never its private attributes.

A team's tests, parametrized over its own models (each check runs its own hypothesis search, so call it from
a plain test function, not from inside another ``@given`` test)::

    import pytest
    from field import spl
    from mcl import testing as mt
    from sensing import CombinedSensorModel, LandmarkSensorModel, LineSensorModel

    from our_robot.localization import OurOdometry, OurGoalModel

    FIELD = spl()
    MOTION_MODELS = [OurOdometry(), OurOdometry(noise=0.0)]
    SENSOR_MODELS = [OurGoalModel(FIELD), CombinedSensorModel((OurGoalModel(FIELD), LineSensorModel(FIELD)))]

    @pytest.mark.parametrize("model", MOTION_MODELS, ids=repr)
    def test_motion_model_contract(model):
        mt.check_motion_model(model, FIELD, strict=True)

    @pytest.mark.parametrize("model", SENSOR_MODELS, ids=repr)
    def test_sensor_model_contract(model):
        mt.check_sensor_model(model, FIELD)

`docs/testing.md` walks through a complete test file that also checks a configured filter.

Ranges. The strategies draw what a walking robot produces (commands up to 0.5 m/s, steps of a few
centimetres, detections within the carpet's diagonal); `hostile_motion_inputs` and `edge_observations` add
the extremes the library still accepts (a step of 99 m and 99 rad, ranges of 1000 m, bearings of 100 rad,
noises of 1e-6 and 1e3), and `hostile_values` what it refuses.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numpy.typing import ArrayLike

from field import Field, LandmarkType, adultsize, kidsize, spl
from field.checks import LARGEST_ANGLE, LARGEST_COORDINATE, LARGEST_SIGMA, SMALLEST_SIGMA
from motion_models import FootstepEvent, MotionInput
from sensing import Observations
from sensing.collision import NO_COLLISION, CollisionPercept
from sensing.view import CameraView

if TYPE_CHECKING:
    from mcl.contracts import MotionModel, SensorModel
    from mcl.filter import ParticleFilter

__all__ = [
    "REFUSALS",
    # strategies
    "fields", "poses", "pose_arrays", "particle_sets", "observations", "edge_observations", "camera_views",
    "motion_inputs", "hostile_motion_inputs", "collision_percepts", "footstep_events", "hostile_values",
    # filter invariants
    "assert_weights_normalized", "assert_poses_finite_and_wrapped", "FilterSnapshot", "snapshot",
    "assert_unchanged", "assert_refused_leaves_state", "assert_same_seed_same_run",
    # model contracts
    "ContractReport", "assert_motion_contract", "assert_sensor_contract", "check_motion_model",
    "check_sensor_model", "assert_fused_likelihood",
    # registered models
    "ENTRY_POINT_GROUPS", "RegisteredModel", "RegisteredReport", "register_motion_model", "register_sensor_model",
    "unregister", "registered_models", "check_registered",
]

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
    if not (isinstance(margin, (int, float)) and not isinstance(margin, bool) and math.isfinite(margin)
            and margin >= 0):
        raise ValueError(f"margin = {margin!r} must be a finite number >= 0 (metres)")
    border = field.dims.border_strip_width
    half_x, half_y = field.half_length + border - margin, field.half_width + border - margin
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
    return st.tuples(st.floats(x_min, x_max), st.floats(y_min, y_max),
                     st.floats(-math.pi, math.pi, exclude_min=True)).map(lambda p: np.array(p, dtype=np.float64))


def _scale_poses(unit: np.ndarray, bounds: tuple[float, float, float, float]) -> np.ndarray:
    x_min, x_max, y_min, y_max = bounds
    out = np.empty_like(unit)
    out[:, 0] = np.minimum(x_min + unit[:, 0] * (x_max - x_min), x_max)
    out[:, 1] = np.minimum(y_min + unit[:, 1] * (y_max - y_min), y_max)
    theta = math.pi - unit[:, 2] * (2.0 * math.pi)          # unit in [0, 1): θ in (-π, π]
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
    return st.integers(low, high).flatmap(
        lambda rows: hnp.arrays(np.float64, (rows, 3), elements=unit)).map(lambda a: _scale_poses(a, bounds))


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
    weight = st.one_of(st.floats(-50.0, 10.0), st.floats(-50.0, 10.0), st.floats(-50.0, 10.0),
                       st.just(-math.inf))

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
    per_type = st.fixed_dictionaries({}, optional={**{kind.name.lower(): farthest for kind in LandmarkType},
                                                   "others": farthest}).filter(bool)
    return st.builds(CameraView, yaw=st.floats(-2.0, 2.0), half_fov=st.floats(0.2, 1.2),
                     max_range=st.one_of(farthest, per_type), min_range=st.floats(0.0, 0.5))


def observations(field: Field, max_detections: int = 8, with_sigmas: bool = False, *, min_detections: int = 0,
                 max_range: float | None = None, max_line_points: int = 0, with_view: bool = False,
                 seen_from: Sequence[float] | np.ndarray | None = None) -> st.SearchStrategy[Observations]:
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
        raise ValueError(f"min_detections = {min_detections!r}, max_detections = {max_detections!r}: need "
                         "0 <= min_detections <= max_detections")
    kinds = _kinds_on(field)
    if not kinds and max_detections > 0:
        raise ValueError(f"field {field.name!r} has no landmarks to detect")
    far = _carpet_diagonal(field) if max_range is None else float(max_range)
    sigma = st.floats(0.005, 1.0)
    noise = st.one_of(st.tuples(st.none(), st.none()), st.tuples(sigma, sigma)) if with_sigmas \
        else st.just((None, None))
    if seen_from is None:
        detection = st.tuples(st.sampled_from(kinds) if kinds else st.nothing(), st.floats(0.0, far),
                              st.floats(-math.pi, math.pi, exclude_min=True), noise)
        point = st.tuples(st.floats(-6.0, 6.0), st.floats(-6.0, 6.0))
    else:
        detection, point = _seen(field, seen_from, noise)
    points = st.lists(point, max_size=max_line_points) if max_line_points > 0 else st.just([])
    view = st.one_of(st.none(), camera_views()) if with_view else st.none()

    def build(args) -> Observations:
        rows, line_points, camera = args
        nan = math.nan
        batch = Observations.from_arrays(
            [int(r[0]) for r in rows], [r[1] for r in rows], [r[2] for r in rows],
            [nan if r[3][0] is None else r[3][0] for r in rows], [nan if r[3][1] is None else r[3][1] for r in rows],
            line_points=np.array(line_points, dtype=np.float64).reshape(-1, 2))
        return batch if camera is None else batch.with_view(camera)

    return st.tuples(st.lists(detection, min_size=min_detections, max_size=max_detections), points,
                     view).map(build)


def _seen(field: Field, pose, noise: st.SearchStrategy) -> tuple[st.SearchStrategy, st.SearchStrategy]:
    """Detections and line points as a robot at `pose` sees the field (see `observations`)."""
    x, y, theta = (float(v) for v in np.asarray(pose, dtype=np.float64).reshape(3))
    if not all(math.isfinite(v) for v in (x, y, theta)):
        raise ValueError(f"seen_from = {pose!r} must be a finite pose (x, y, θ)")
    landmarks = [(kind, float(p[0]), float(p[1])) for kind in _kinds_on(field)
                 for p in np.asarray(field.landmarks_of(kind)).reshape(-1, 2)]
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
    detection = st.tuples(st.sampled_from(landmarks), st.floats(0.95, 1.05), st.floats(-0.05, 0.05),
                          noise).map(detect)
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
    bearings = st.one_of(st.sampled_from([-LARGEST_ANGLE, LARGEST_ANGLE, math.pi, -math.pi, 0.0]),
                         st.floats(-LARGEST_ANGLE, LARGEST_ANGLE))
    sigmas = st.one_of(st.just(math.nan), st.sampled_from([SMALLEST_SIGMA, LARGEST_SIGMA]),
                       st.floats(SMALLEST_SIGMA, LARGEST_SIGMA))
    detection = st.tuples(st.sampled_from([kind.value for kind in LandmarkType]), ranges, bearings, sigmas, sigmas)
    coordinate = st.one_of(st.sampled_from([-LARGEST_COORDINATE, LARGEST_COORDINATE, 0.0]),
                           st.floats(-LARGEST_COORDINATE, LARGEST_COORDINATE))
    points = st.lists(st.tuples(coordinate, coordinate), max_size=40)

    def build(args) -> Observations:
        rows, line_points, camera = args
        kinds, ranges, bearings, range_sigmas, bearing_sigmas = \
            [list(column) for column in zip(*rows)] if rows else [[], [], [], [], []]
        batch = Observations.from_arrays(kinds, ranges, bearings, range_sigmas, bearing_sigmas,
                                         line_points=np.array(line_points, dtype=np.float64).reshape(-1, 2))
        return batch if camera is None else batch.with_view(camera)

    return st.tuples(st.lists(detection, max_size=max_detections), points,
                     st.one_of(st.none(), camera_views())).map(build)


def collision_percepts() -> st.SearchStrategy[CollisionPercept]:
    """Collision percepts (`sensing.collision.CollisionPercept`), `NO_COLLISION` often among them.

    Returns
    -------
    hypothesis.strategies.SearchStrategy of sensing.collision.CollisionPercept
        Any sides, relative deviations within [0, 10], rates within [0, 1].
    """
    return st.one_of(st.just(NO_COLLISION), st.builds(
        CollisionPercept, left=st.booleans(), right=st.booleans(), s_rel_left=st.floats(0.0, 10.0),
        s_rel_right=st.floats(0.0, 10.0), rate=st.floats(0.0, 1.0), recent_left=st.booleans(),
        recent_right=st.booleans()))


_STEP = st.tuples(st.floats(-0.08, 0.08), st.floats(-0.05, 0.05), st.floats(-0.4, 0.4))


def footstep_events() -> st.SearchStrategy[FootstepEvent]:
    """Support-foot swaps (`motion_models.FootstepEvent`) with the fields of both input sets.

    Returns
    -------
    hypothesis.strategies.SearchStrategy of motion_models.FootstepEvent
        Support +1 (left) or -1 (right); commanded and sensor-based steps within 8 cm, 5 cm and 0.4 rad;
        step durations within [0.1, 1] s.
    """
    return st.builds(FootstepEvent, support=st.sampled_from([1, -1]), commanded=_STEP, previous_commanded=_STEP,
                     sensor=_STEP, previous_sensor=_STEP, duration=st.floats(0.1, 1.0),
                     previous_duration=st.floats(0.1, 1.0))


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
        return MotionInput(dt=dt_, odometry=event.sensor if event is not None else step, collision=percept_,
                           footstep=event)

    by_kind = {
        "command": st.builds(MotionInput, dt=dt, command=command, collision=percept),
        "odometry": st.builds(MotionInput, dt=measured_dt, odometry=odometry, collision=percept),
        "footstep": st.builds(footstep_input, measured_dt, st.one_of(footstep_events(), footstep_events(), st.none()),
                              _STEP, percept),
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
    arrays = [lambda: np.empty(0), lambda: np.empty((0, 3)), lambda: np.zeros((2, 2)), lambda: np.zeros((3, 3, 3)),
              lambda: np.full(3, np.nan), lambda: np.full((4, 3), np.inf), lambda: np.array(["x", "y", "z"]),
              lambda: np.zeros(2), lambda: np.zeros((5, 2))]
    huge = st.floats(allow_nan=False, allow_infinity=False).filter(lambda v: abs(v) >= 1e7)
    return st.one_of(
        st.sampled_from([math.nan, math.inf, -math.inf, 1e300, -1e300, 1.7976931348623157e308,
                         -1.7976931348623157e308, np.float64("nan"), np.float64("inf")]),
        huge,
        st.integers(10**7, 10**400), st.integers(-10**400, -10**7),
        st.none(), st.booleans(), st.text(max_size=4), st.binary(max_size=3),
        st.just(complex(1.0, 1.0)), st.builds(object), st.just({}), st.just(()), st.just([]), st.just(set()),
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


# -- invariants --------------------------------------------------------------------------------------------------
def assert_poses_finite_and_wrapped(poses: ArrayLike | ParticleFilter) -> None:
    """Assert that particles are an (N, 3) array of finite poses with headings wrapped into [-π, π].

    Parameters
    ----------
    poses : array_like or ParticleFilter
        The particles (N, 3), or an object with a `poses` attribute (a filter).

    Raises
    ------
    AssertionError
        Naming the first row that is not finite or not wrapped, or the wrong shape.
    """
    if hasattr(poses, "poses") and not isinstance(poses, np.ndarray):
        poses = poses.poses
    array = np.asarray(poses)
    assert array.ndim == 2 and array.shape[1] == 3, f"poses must have shape (N, 3), got {array.shape}"
    assert array.dtype.kind == "f", f"poses must be floats, got dtype {array.dtype}"
    finite = np.isfinite(array).all(axis=1)
    if not finite.all():
        i = int(np.argmin(finite))
        raise AssertionError(f"poses[{i}] = {array[i].tolist()!r} is not finite ({int((~finite).sum())} of "
                             f"{array.shape[0]} rows)")
    wrapped = np.abs(array[:, 2]) <= math.pi
    if not wrapped.all():
        i = int(np.argmin(wrapped))
        raise AssertionError(f"poses[{i}] = {array[i].tolist()!r}: heading not wrapped into [-π, π] "
                             f"({int((~wrapped).sum())} of {array.shape[0]} rows)")


def assert_weights_normalized(pf: ParticleFilter, tolerance: float = 1e-9) -> None:
    """Assert that a filter's weights are a probability distribution matching its log-weights.

    Parameters
    ----------
    pf : ParticleFilter
        Read through `weights`, `log_weights` (and `n`, when it has one).
    tolerance : float, optional
        Largest accepted |Σ w - 1| (default 1e-9); exp(log_weights) must equal the weights to the same
        tolerance per particle (relative 1e-9).

    Raises
    ------
    AssertionError
        Naming what is off: shape, NaN, negative or infinite weights, their sum, NaN or +inf log-weights, or
        weights that are not exp(log_weights).
    """
    weights = np.asarray(pf.weights)
    log_weights = np.asarray(pf.log_weights)
    n = getattr(pf, "n", weights.shape[0] if weights.ndim else 0)
    assert weights.shape == (n,), f"weights must have shape ({n},), got {weights.shape}"
    assert log_weights.shape == (n,), f"log_weights must have shape ({n},), got {log_weights.shape}"
    bad = ~(np.isfinite(weights) & (weights >= 0))
    if bad.any():
        i = int(np.argmax(bad))
        raise AssertionError(f"weights[{i}] = {float(weights[i])!r}: weights must be finite and >= 0 "
                             f"({int(bad.sum())} are not)")
    total = float(np.sum(weights, dtype=np.float64))
    assert abs(total - 1.0) <= tolerance, f"weights sum to {total!r}, not 1 (tolerance {tolerance:g})"
    bad = np.isnan(log_weights) | np.isposinf(log_weights)
    if bad.any():
        i = int(np.argmax(bad))
        raise AssertionError(f"log_weights[{i}] = {float(log_weights[i])!r}: NaN or +inf log-weight")
    with np.errstate(over="ignore", under="ignore"):
        expected = np.exp(log_weights)
    off = ~np.isclose(expected, weights, rtol=1e-9, atol=tolerance)
    if off.any():
        i = int(np.argmax(off))
        raise AssertionError(f"weights[{i}] = {float(weights[i])!r} but exp(log_weights[{i}]) = "
                             f"{float(expected[i])!r}: the log-weights are not the logarithms of the normalized "
                             "weights")


def _frozen(value) -> Any:
    """A hashable, bit-exact image of a generator state (ints, strings, arrays, nested dicts)."""
    if isinstance(value, dict):
        return tuple(sorted((str(k), _frozen(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return tuple(_frozen(v) for v in value)
    if isinstance(value, np.ndarray):
        return ("array", value.dtype.str, value.shape, np.ascontiguousarray(value).tobytes())
    if isinstance(value, (float, np.floating)):
        return ("float", np.float64(value).tobytes())
    if isinstance(value, np.generic):
        return value.item()
    return value


def _copy(array: Any) -> np.ndarray | None:
    return None if array is None else _copy_array(array)


def _copy_array(array: Any) -> np.ndarray:
    out = np.array(array, copy=True)
    out.flags.writeable = False
    return out


def _array_difference(name: str, a: np.ndarray | None, b: np.ndarray | None) -> str | None:
    """Where two arrays differ in any bit (None when they are the same)."""
    if a is None or b is None:
        return None if a is None and b is None else f"{name}: {a!r} -> {b!r}"
    if a.shape != b.shape or a.dtype != b.dtype:
        return f"{name}: {a.dtype} {a.shape} -> {b.dtype} {b.shape}"
    if a.size == 0:
        return None
    left = np.ascontiguousarray(a).view(np.uint8).reshape(a.size, a.dtype.itemsize)
    right = np.ascontiguousarray(b).view(np.uint8).reshape(b.size, b.dtype.itemsize)
    differ = (left != right).any(axis=1)
    if not differ.any():
        return None
    flat = int(np.argmax(differ))
    index = np.unravel_index(flat, a.shape)
    where = ", ".join(str(int(i)) for i in index)
    return (f"{name}[{where}]: {a[index].item()!r} -> {b[index].item()!r} ({int(differ.sum())} of {a.size} entries "
            "differ)")


def _scalar_difference(name: str, a, b) -> str | None:
    if isinstance(a, float) or isinstance(b, float):
        if isinstance(a, (int, float)) and isinstance(b, (int, float)) and \
                np.float64(a).tobytes() == np.float64(b).tobytes():
            return None
    elif a == b:
        return None
    return f"{name}: {a!r} -> {b!r}"


@dataclass(frozen=True, eq=False)
class FilterSnapshot:
    """Everything a filter shows, copied: what `snapshot` returns and `assert_unchanged` compares bit for bit.

    Attributes
    ----------
    poses, log_weights, weights : numpy.ndarray
        Read-only copies of the particles (N, 3), their log-weights (N,) and normalized weights (N,).
    rng_state : tuple
        The state of the filter's random generator (`pf.rng.bit_generator.state`), frozen.
    motion_state : numpy.ndarray or None
        A copy of the stateful motion model's per-particle state (`pf.motion_state`), or None.
    scalars : tuple of (str, object)
        w_slow, w_fast, ess, frame_fit, resampled, injected, resampling, resample_threshold, augmented, and the
        relocalization's `tracking`, as the filter shows them.
    roughening : numpy.ndarray or None
        A copy of the roughening's standard deviations.
    anchor : numpy.ndarray or None
        The relocalization's anchor, when it shows one.
    estimate : tuple or None
        (pose, covariance, weight) of `pf.estimate()`, or None when the snapshot was taken without it.
    """

    poses: np.ndarray
    log_weights: np.ndarray
    weights: np.ndarray
    rng_state: tuple
    motion_state: np.ndarray | None
    scalars: tuple
    roughening: np.ndarray | None
    anchor: np.ndarray | None
    estimate: tuple | None

    @property
    def w_slow(self) -> float:
        """Augmented MCL's long-term average likelihood."""
        return dict(self.scalars)["w_slow"]

    @property
    def w_fast(self) -> float:
        """Augmented MCL's short-term average likelihood."""
        return dict(self.scalars)["w_fast"]

    def differences(self, other: FilterSnapshot) -> list[str]:
        """What differs from `other`, one line per field (an empty list: the same, bit for bit).

        Parameters
        ----------
        other : FilterSnapshot
            The snapshot to compare with (usually a later one of the same filter).

        Returns
        -------
        list of str
            One line per field that differs, with its first differing entry (this snapshot's value, then
            `other`'s).

        Raises
        ------
        TypeError
            If `other` is not a `FilterSnapshot`.
        """
        if not isinstance(other, FilterSnapshot):
            raise TypeError(f"other = {other!r} must be a FilterSnapshot, not {type(other).__name__}")
        found = []
        for name in ("poses", "log_weights", "weights", "motion_state", "roughening", "anchor"):
            difference = _array_difference(name, getattr(self, name), getattr(other, name))
            if difference:
                found.append(difference)
        if self.rng_state != other.rng_state:
            found.append("rng_state: the random generator has drawn numbers (its state changed)")
        mine, theirs = dict(self.scalars), dict(other.scalars)
        for name in sorted(set(mine) | set(theirs)):
            difference = _scalar_difference(name, mine.get(name), theirs.get(name))
            if difference:
                found.append(difference)
        before, after = self.estimate, other.estimate
        if (before is None) != (after is None):
            found.append(f"estimate: {before!r} -> {after!r}")
        elif before is not None and after is not None:
            for label, a, b in zip(("estimate.pose", "estimate.covariance"), before[:2], after[:2]):
                difference = _array_difference(label, a, b)
                if difference:
                    found.append(difference)
            difference = _scalar_difference("estimate.weight", before[2], after[2])
            if difference:
                found.append(difference)
        return found

    def __eq__(self, other) -> bool:
        return isinstance(other, FilterSnapshot) and not self.differences(other)

    __hash__ = None  # type: ignore[assignment]


_SCALARS = ("w_slow", "w_fast", "ess", "frame_fit", "resampled", "injected", "resampling", "resample_threshold",
            "augmented", "n")


def snapshot(pf: ParticleFilter, estimate: bool = True) -> FilterSnapshot:
    """Capture a filter's whole observable state.

    Parameters
    ----------
    pf : ParticleFilter
        Read through its public attributes only: poses, log_weights, weights, rng, motion_state, w_slow,
        w_fast, ess, frame_fit, resampled, injected, resampling, resample_threshold, augmented, roughening,
        relocalization (tracking, anchor) and estimate().
    estimate : bool, optional
        Include `pf.estimate()` (default True). The filter caches the estimate; computing it when it is not
        cached moves the estimate's hysteresis anchor, as a robot asking for the estimate would. Give False to
        leave the filter exactly as it is. The estimate is left out (None) while a pose is not finite: the
        filter's summaries assume finite poses, and `assert_poses_finite_and_wrapped` reports such poses.

    Returns
    -------
    FilterSnapshot
        Compare two with `assert_unchanged` (or ``==``; `FilterSnapshot.differences` lists what differs).
    """
    relocalization = getattr(pf, "relocalization", None)
    scalars = []
    for name in _SCALARS:
        if hasattr(pf, name):
            value = getattr(pf, name)
            scalars.append((name, value.item() if isinstance(value, np.generic) else value))
    if relocalization is not None and hasattr(relocalization, "tracking"):
        scalars.append(("relocalization.tracking", bool(relocalization.tracking)))
    anchor = getattr(relocalization, "anchor", None) if relocalization is not None else None
    roughening = getattr(pf, "roughening", None)
    summary = None
    if estimate and np.isfinite(np.asarray(pf.poses)).all():
        e = pf.estimate()
        summary = (_copy(np.asarray(e.pose, dtype=np.float64)), _copy(np.asarray(e.covariance, dtype=np.float64)),
                   float(e.weight))
    motion_state = getattr(pf, "motion_state", None)
    return FilterSnapshot(
        poses=_copy_array(pf.poses), log_weights=_copy_array(pf.log_weights), weights=_copy_array(pf.weights),
        rng_state=_frozen(pf.rng.bit_generator.state), motion_state=_copy(motion_state), scalars=tuple(scalars),
        roughening=_copy(roughening), anchor=_copy(anchor), estimate=summary)


def assert_unchanged(before: FilterSnapshot, after: FilterSnapshot, what: str = "the filter") -> None:
    """Assert that two snapshots are equal bit for bit.

    Parameters
    ----------
    before, after : FilterSnapshot
        From `snapshot`.
    what : str, optional
        What the message calls the object (default "the filter").

    Raises
    ------
    AssertionError
        Listing every field that changed, with the first entry that differs.
    """
    differences = before.differences(after)
    if differences:
        raise AssertionError(f"{what} changed: " + "; ".join(differences))


def assert_refused_leaves_state(pf: ParticleFilter, call: Callable[..., Any], *args: Any,
                                exceptions: tuple = REFUSALS, **kwargs: Any) -> BaseException:
    """Assert that `call(*args, **kwargs)` is refused and leaves the filter exactly as it was.

    Parameters
    ----------
    pf : ParticleFilter
        The filter whose `snapshot` must be the same before and after.
    call : callable
        Usually a bound method of `pf`, e.g. ``pf.step``; any callable that should refuse its arguments.
    *args, **kwargs
        Passed to `call`.
    exceptions : tuple of exception types, optional
        What a refusal may raise (default ValueError and TypeError).

    Returns
    -------
    BaseException
        The exception the call raised (to check its message).

    Raises
    ------
    AssertionError
        When the call returns normally, raises another exception, raises one without a message, or changes
        anything a snapshot shows.
    """
    before = snapshot(pf)
    name = getattr(call, "__qualname__", None) or repr(call)
    try:
        call(*args, **kwargs)
    except exceptions as error:
        caught = error
    except Exception as error:
        raise AssertionError(f"{name} raised {type(error).__name__}: {error}; a refused call must raise one of "
                             f"{tuple(e.__name__ for e in exceptions)}") from error
    else:
        raise AssertionError(f"{name}{_show_args(args, kwargs)} was accepted; it should have been refused "
                             f"with one of {tuple(e.__name__ for e in exceptions)}")
    assert str(caught), f"{name} raised {type(caught).__name__} without a message"
    after = snapshot(pf)
    differences = before.differences(after)
    if differences:
        raise AssertionError(f"{name} was refused ({type(caught).__name__}: {caught}) but changed the filter: "
                             + "; ".join(differences))
    return caught


def _show_args(args, kwargs) -> str:
    shown = [repr(a)[:60] for a in args] + [f"{k}={v!r}"[:60] for k, v in kwargs.items()]
    return f"({', '.join(shown)})"


def assert_same_seed_same_run(make_filter: Callable[[], Any], inputs: Iterable) -> None:
    """Assert that two filters from the same factory, driven by the same inputs, agree bit for bit.

    Parameters
    ----------
    make_filter : callable
        Returns a new filter each call, seeded the same way (``lambda: ParticleFilter(..., seed=3)``).
    inputs : iterable
        The steps: (MotionInput, Observations or None) pairs (a bare MotionInput is a step without
        observations), given to `pf.step` in order.

    Raises
    ------
    AssertionError
        When the factory returns the same object twice, or the two runs differ anywhere (poses, weights, the
        generator's state, the estimate, ...): the message names the step and the field.
    """
    steps = [(item, None) if isinstance(item, MotionInput) else tuple(item) for item in inputs]
    first, second = make_filter(), make_filter()
    assert first is not second, "make_filter returned the same filter twice: it must build a new one each call"
    # The first run entirely, then the second: state a model keeps between filters (a hidden counter, global
    # random numbers) shows as a difference.
    runs = []
    for pf in (first, second):
        trace = [snapshot(pf, estimate=False)]
        for u, z in steps:
            pf.step(u, z)
            trace.append(snapshot(pf))
        runs.append(trace)
    for k, (a, b) in enumerate(zip(*runs)):
        differences = a.differences(b)
        if differences:
            when = "after construction" if k == 0 else f"after step {k - 1} ({_show_args(steps[k - 1], {})})"
            raise AssertionError(f"two filters from the same factory differ {when}: " + "; ".join(differences))


# -- model contracts ---------------------------------------------------------------------------------------------
@dataclass
class ContractReport:
    """What a contract check saw, counted over every example hypothesis ran (shrinking included).

    Attributes
    ----------
    examples : int
        Examples run.
    accepted, refused : int
        Inputs from the good strategy the model accepted and refused.
    hostile_accepted, hostile_refused : int
        Inputs from the hostile strategy the model accepted and refused.
    """

    examples: int = 0
    accepted: int = 0
    refused: int = 0
    hostile_accepted: int = 0
    hostile_refused: int = 0


def _name(model) -> str:
    return type(model).__name__


def _poses_copy(poses) -> np.ndarray:
    array = np.array(poses, dtype=np.float64, order="C", copy=True)
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"poses must have shape (N, 3), got {array.shape}")
    return array


def _fresh_state(model, n: int) -> np.ndarray | None:
    make = getattr(model, "particle_state", None)
    if not callable(make):
        return None
    try:
        state = np.ascontiguousarray(make(n))
    except Exception as error:
        raise AssertionError(f"{_name(model)}.particle_state({n}) raised {type(error).__name__}: {error}") from error
    assert state.ndim >= 1 and state.shape[0] == n, \
        f"{_name(model)}.particle_state({n}) must have {n} rows, got shape {state.shape}"
    return state


def _predict(model, poses: np.ndarray, u: MotionInput, seed: int, state: np.ndarray | None):
    rng = np.random.default_rng(seed)
    if state is None:
        model.predict(poses, u, rng)
    else:
        model.predict(poses, u, rng, state=state)
    return rng


def assert_motion_contract(model: MotionModel, poses: ArrayLike, u: MotionInput, seed: int = 0, *,
                           strict: bool = False) -> bool:
    """Check one motion input against a motion model's contract.

    `model.check(u)` either refuses with ValueError/TypeError (any other exception fails), or accepts; then
    `model.predict` on a copy of `poses` (with ``state=model.particle_state(N)`` when the model has
    `particle_state`) must not raise, must keep the (N, 3) float64 shape, give finite poses with headings in
    [-π, π], keep the state's rows (and keep it finite), and give the same poses, state and generator state,
    bit for bit, when run again from the same seed.

    Parameters
    ----------
    model : motion model
        Anything with `check(u)` and `predict(poses, u, rng)` (and optionally `particle_state(n)`).
    poses : array_like
        The particles (N, 3); not changed (the model moves a copy).
    u : motion_models.MotionInput
        The input.
    seed : int, optional
        Seed of the generators given to `predict` (default 0).
    strict : bool, optional
        Also require that `predict` refuses what `check` refuses (ValueError/TypeError), before it changes
        the poses, the state or the generator: a model used outside a filter must validate its input. A filter
        calls `check` first, so a model can keep the contract without this (default False).

    Returns
    -------
    bool
        Whether `check` accepted `u`.

    Raises
    ------
    AssertionError
        Naming the model, the input and the property that failed.
    """
    name = _name(model)
    start = _poses_copy(poses)
    n = start.shape[0]
    try:
        model.check(u)
    except REFUSALS as error:
        if strict:
            _assert_predict_refuses(model, start, u, seed, error)
        return False
    except Exception as error:
        raise AssertionError(f"{name}.check({u!r}) raised {type(error).__name__}: {error}; a refused input must "
                             "raise ValueError or TypeError") from error
    results = []
    for _ in range(2):
        moved = start.copy()
        state = _fresh_state(model, n)
        state_shape = None if state is None else state.shape
        try:
            rng = _predict(model, moved, u, seed, state)
        except Exception as error:
            raise AssertionError(f"{name}.check accepted {u!r} but predict raised {type(error).__name__}: "
                                 f"{error}") from error
        assert moved.shape == (n, 3) and moved.dtype == np.float64, \
            f"{name}.predict changed the poses' shape or dtype to {moved.dtype} {moved.shape} (input {u!r})"
        try:
            assert_poses_finite_and_wrapped(moved)
        except AssertionError as error:
            raise AssertionError(f"{name}.predict with {u!r}: {error}") from None
        if state is not None:
            assert state.shape == state_shape, \
                f"{name}.predict changed the state's shape from {state_shape} to {state.shape} (input {u!r})"
            if state.dtype.kind in "fc":
                assert np.isfinite(state).all(), f"{name}.predict left a non-finite particle state (input {u!r})"
        results.append((moved, state, _frozen(rng.bit_generator.state)))
    (first, first_state, first_rng), (second, second_state, second_rng) = results
    for label, a, b in (("poses", first, second), ("state", first_state, second_state)):
        difference = _array_difference(label, a, b)
        if difference:
            raise AssertionError(f"{name}.predict from the same seed gave different results: {difference} "
                                 f"(input {u!r}); it must draw only from the generator it is given")
    assert first_rng == second_rng, \
        f"{name}.predict from the same seed left the generator in different states (input {u!r})"
    return True


def _assert_predict_refuses(model, start: np.ndarray, u: MotionInput, seed: int, refusal: BaseException) -> None:
    name = _name(model)
    moved = start.copy()
    state = _fresh_state(model, start.shape[0])
    state_before = None if state is None else state.copy()
    rng = np.random.default_rng(seed)
    rng_before = _frozen(rng.bit_generator.state)
    try:
        if state is None:
            model.predict(moved, u, rng)
        else:
            model.predict(moved, u, rng, state=state)
    except REFUSALS:
        pass
    except Exception as error:
        raise AssertionError(f"{name}.predict({u!r}) raised {type(error).__name__}: {error}; check refused it "
                             f"({type(refusal).__name__}), predict must refuse it with ValueError or "
                             "TypeError") from error
    else:
        raise AssertionError(f"{name}.check refused {u!r} ({type(refusal).__name__}: {refusal}) but predict "
                             "accepted it")
    difference = _array_difference("poses", start, moved) or _array_difference("state", state_before, state)
    if difference:
        raise AssertionError(f"{name}.predict refused {u!r} but changed {difference}")
    assert _frozen(rng.bit_generator.state) == rng_before, \
        f"{name}.predict refused {u!r} but drew random numbers first"


def _run(test: Callable, max_examples: int, strategies: dict, shrink: bool | None) -> None:
    """Run `test` on `max_examples` examples drawn from `strategies`: the same examples on every run, nothing
    stored; the phases of the loaded hypothesis profile unless `shrink` says whether to shrink a failure."""
    configured = settings(max_examples=max_examples, deadline=None, derandomize=True, database=None,
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                                 HealthCheck.filter_too_much])
    if shrink is not None:
        configured = settings(configured, phases=tuple(Phase) if shrink else (Phase.explicit, Phase.reuse,
                                                                                Phase.generate))
    configured(given(**strategies)(test))()


def check_motion_model(model: MotionModel, field: Field | None = None, *, n: int | tuple[int, int] = (1, 64),
                       inputs: st.SearchStrategy | None = None, hostile: st.SearchStrategy | None = None,
                       refused: Sequence[MotionInput] = (), strict: bool = False,
                       max_examples: int = 20, shrink: bool | None = None) -> ContractReport:
    """Check a motion model against the contract the filter relies on, on examples hypothesis draws.

    Each example runs `assert_motion_contract` on particles on the carpet, for an input from `inputs` and one
    from `hostile`. Runs its own hypothesis search: call it from a plain test, not inside ``@given``.

    Parameters
    ----------
    model : motion model
        Anything with `check(u)` and `predict(poses, u, rng)`, optionally `particle_state(n)` (then used as
        ``predict(poses, u, rng, state=state)``).
    field : field.Field, optional
        Particles lie on its carpet (default: `field.spl()`).
    n : int or (int, int), optional
        Particles per example (default 1 to 64).
    inputs : hypothesis strategy of MotionInput, optional
        Inputs the model should take (default ``motion_inputs("any", collision=True)``: commands, odometry and
        footstep events, each with a collision percept). The model may refuse some, not all.
    hostile : hypothesis strategy of MotionInput, optional
        Inputs to accept or refuse cleanly (default `hostile_motion_inputs()`).
    refused : sequence of MotionInput, optional
        Inputs the model must refuse with ValueError/TypeError (checked first, once each).
    strict : bool, optional
        `predict` must refuse what `check` refuses, changing nothing (see `assert_motion_contract`).
    max_examples : int, optional
        Examples to run (default 20).
    shrink : bool, optional
        Whether hypothesis shrinks a failing example to a small one (slower) or reports the first it finds;
        default None: as the loaded hypothesis profile's phases say (all of them, unless a profile leaves
        shrinking out).

    Returns
    -------
    ContractReport
        How many inputs were accepted and refused.

    Raises
    ------
    AssertionError
        On the first property that fails (after hypothesis has shrunk the example), or when the model
        refuses every input from `inputs`.
    """
    field = _preset(spl) if field is None else field
    report = ContractReport()
    start = np.zeros((3, 3))
    for u in refused:
        try:
            model.check(u)
        except REFUSALS:
            pass
        except Exception as error:
            raise AssertionError(f"{_name(model)}.check({u!r}) raised {type(error).__name__}: {error}; it must "
                                 "refuse with ValueError or TypeError") from error
        else:
            raise AssertionError(f"{_name(model)}.check accepted {u!r}, which it must refuse")
        assert not assert_motion_contract(model, start, u, strict=strict)

    def test(poses, u, bad, seed):
        report.examples += 1
        if assert_motion_contract(model, poses, u, seed, strict=strict):
            report.accepted += 1
        else:
            report.refused += 1
        if assert_motion_contract(model, poses, bad, seed, strict=strict):
            report.hostile_accepted += 1
        else:
            report.hostile_refused += 1

    _run(test, max_examples, dict(
        poses=pose_arrays(field, n), u=motion_inputs("any", collision=True) if inputs is None else inputs,
        bad=hostile_motion_inputs() if hostile is None else hostile, seed=st.integers(0, 2**63 - 1)), shrink)
    assert report.accepted > 0, (f"{_name(model)} refused all {report.refused} inputs drawn: give `inputs=` a "
                                 "strategy of the inputs it takes")
    return report


_OBSERVATION_ARRAYS = ("kinds", "ranges", "bearings", "range_sigmas", "bearing_sigmas", "line_points")


def _observation_image(observations) -> tuple:
    return tuple((name, _copy(getattr(observations, name, None))) for name in _OBSERVATION_ARRAYS) + (
        ("view", repr(getattr(observations, "view", None))),)


def _bound_of(bound, observations) -> float | None:
    if bound is None:
        return None
    return float(bound(observations)) if callable(bound) else float(bound)


def assert_fused_likelihood(model: SensorModel, poses: ArrayLike, observations: Observations,
                            since: Sequence[float] | np.ndarray | None = None) -> bool:
    """The sensor model's fused-likelihood kernels (`sensing.fused`), run as the filter's fused step runs them,
    give `log_likelihood` bit for bit; with `since` (camera latency), `log_likelihood` of the poses moved back.

    Parameters
    ----------
    model : sensor model
        Any sensor model; one without the capability (`fused_likelihood` absent or returning None) passes.
    poses : array_like, (N, 3)
        The particles.
    observations : Observations
        A frame the model accepts (no camera view: a frame with one is scored through `log_likelihood`).
    since : sequence of 3 floats, optional
        The robot's motion (dx, dy, dθ) since the frame was captured.

    Returns
    -------
    bool
        Whether the model offers the capability (and so was compared).

    Raises
    ------
    AssertionError
        Naming the first particle whose scores differ.
    """
    from mcl.contracts import fused_kernels
    from mcl.latency import move_back
    from mcl.step import NO_SINCE, STEP_BLOCK, fused_step

    kernels = fused_kernels(model)
    if kernels is None:
        return False
    poses = np.ascontiguousarray(poses, dtype=np.float64)
    n = poses.shape[0]
    displacement = NO_SINCE if since is None else np.asarray(since, dtype=np.float64)
    frame, missing = kernels.prepare(kernels.inputs(observations), kernels.params)
    assert missing < 0, f"the kernels refuse detection {missing}, which `check` accepted"
    fused = np.empty(n)
    work = kernels.workspace(frame, min(max(n, 1), STEP_BLOCK))
    copying = (False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False, np.empty((0, 3)))
    fused_step(kernels).predict_and_score(poses, np.empty_like(poses), np.empty((n, 2)), fused, copying, (0, 0),
                                          frame, work, 0, n, False, displacement)
    scored = poses
    if since is not None:
        scored = np.empty_like(poses)
        move_back(poses, displacement, scored)
    plain = np.asarray(model.log_likelihood(scored, observations), dtype=np.float64)
    differ = np.flatnonzero(fused.view(np.int64) != plain.view(np.int64))
    assert differ.size == 0, (f"{_name(model)}: the fused kernels score particle {differ[0]} "
                              f"{fused[differ[0]]!r}, log_likelihood {plain[differ[0]]!r}")
    return True


def assert_sensor_contract(model: SensorModel, poses: ArrayLike, observations: Observations, *,
                           bound: float | Callable[[Observations], float] | None = None,
                           allow_neg_inf: bool = False) -> bool:
    """Check one frame against a sensor model's contract.

    `model.check(observations)` either refuses with ValueError/TypeError (any other exception fails), or
    accepts; then `terms(observations)`, when the model has it, is an int >= 0, and
    `log_likelihood(poses, observations, out=buffer)`, called as the filter calls it, returns shape (N,) floats
    without NaN or +inf (-inf only with `allow_neg_inf`), at most `bound`; it leaves the poses and the
    observations as they were; and called again, with or without `out`, it returns the same values bit for bit.

    Parameters
    ----------
    model : sensor model
        Anything with `check(observations)` and `log_likelihood(poses, observations, out=None)`, optionally
        `terms(observations)`.
    poses : array_like
        The particles (N, 3); the model scores a copy.
    observations : sensing.Observations
        The frame.
    bound : float or callable, optional
        The largest log-likelihood accepted, or a function of the observations giving it (e.g. the number
        of terms times the largest log-likelihood of one); default None: any finite value.
    allow_neg_inf : bool, optional
        Accept -inf (a particle that cannot explain the frame; the filter handles it). Default False: the
        library's models give finite values for every frame they accept.

    Returns
    -------
    bool
        Whether `check` accepted the observations.

    Raises
    ------
    AssertionError
        Naming the model, the property and the first particle that breaks it.
    """
    name = _name(model)
    start = _poses_copy(poses)
    n = start.shape[0]
    try:
        model.check(observations)
    except REFUSALS:
        return False
    except Exception as error:
        raise AssertionError(f"{name}.check raised {type(error).__name__}: {error}; refused observations must "
                             "raise ValueError or TypeError") from error
    terms = getattr(model, "terms", None)
    if callable(terms):
        count = terms(observations)
        assert isinstance(count, (int, np.integer)) and not isinstance(count, (bool, np.bool_)), \
            f"{name}.terms returned {count!r} ({type(count).__name__}), not an int"
        assert count >= 0, f"{name}.terms returned {count!r}, not >= 0"
        assert terms(observations) == count, f"{name}.terms gave two answers for the same observations"
    image = _observation_image(observations)
    scored = start.copy()
    buffer = np.full(n, np.nan)
    try:
        first = model.log_likelihood(scored, observations, out=buffer)
    except TypeError as error:
        raise AssertionError(f"{name}.log_likelihood(poses, observations, out=buffer) raised TypeError: {error}; "
                             "the filter passes `out=` (it may be ignored, the returned array is used)") from error
    except Exception as error:
        raise AssertionError(f"{name}.check accepted the observations but log_likelihood raised "
                             f"{type(error).__name__}: {error}") from error
    first = np.array(first, copy=True)
    assert first.shape == (n,), f"{name}.log_likelihood returned shape {first.shape} for {n} poses; must be ({n},)"
    assert first.dtype.kind == "f", f"{name}.log_likelihood returned dtype {first.dtype}; must be floats"
    bad = np.isnan(first) | np.isposinf(first) | (np.isneginf(first) & (not allow_neg_inf))
    if bad.any():
        i = int(np.argmax(bad))
        raise AssertionError(f"{name}.log_likelihood gave {float(first[i])!r} for poses[{i}] = {start[i].tolist()!r} "
                             f"({int(bad.sum())} of {n}); must be finite"
                             + (" or -inf" if allow_neg_inf else ""))
    limit = _bound_of(bound, observations)
    if limit is not None:
        above = first > limit
        if above.any():
            i = int(np.argmax(above))
            raise AssertionError(f"{name}.log_likelihood gave {float(first[i])!r} for poses[{i}] = "
                                 f"{start[i].tolist()!r}, above the bound {limit!r}")
    difference = _array_difference("poses", start, scored)
    if difference:
        raise AssertionError(f"{name}.log_likelihood changed its input: {difference}")
    after = _observation_image(observations)
    for (label, a), (_, b) in zip(image, after):
        difference = _array_difference(label, a, b) if label != "view" else (None if a == b else f"view: {a} -> {b}")
        if difference:
            raise AssertionError(f"{name}.log_likelihood changed the observations: {difference}")
    try:
        again = np.array(model.log_likelihood(start.copy(), observations), copy=True)
        third = np.array(model.log_likelihood(start.copy(), observations, out=np.full(n, np.inf)), copy=True)
    except Exception as error:
        raise AssertionError(f"{name}.log_likelihood raised {type(error).__name__} on the same input the second "
                             f"time: {error}") from error
    for label, values in (("without out", again), ("with another out buffer", third)):
        difference = _array_difference("log_likelihood", first, values)
        if difference:
            raise AssertionError(f"{name}.log_likelihood gave different results for the same input ({label}): "
                                 f"{difference}")
    return True


def _far_rows(field: Field) -> st.SearchStrategy:
    """Poses a filter may hold far off the carpet (set_particles takes |x|, |y| up to 1000 m)."""
    corner = st.sampled_from([-LARGEST_COORDINATE, LARGEST_COORDINATE, 0.0])
    return st.lists(st.tuples(st.one_of(corner, st.floats(-LARGEST_COORDINATE, LARGEST_COORDINATE)),
                              st.one_of(corner, st.floats(-LARGEST_COORDINATE, LARGEST_COORDINATE)),
                              st.floats(-math.pi, math.pi, exclude_min=True)), max_size=3)


def check_sensor_model(model: SensorModel, field: Field, *, n: int | tuple[int, int] = (1, 64),
                       frames: st.SearchStrategy | None = None, hostile: st.SearchStrategy | None = None,
                       bound: float | Callable[[Observations], float] | None = None, allow_neg_inf: bool = False,
                       max_examples: int = 20, shrink: bool | None = None) -> ContractReport:
    """Check a sensor model against the contract the filter relies on, on examples hypothesis draws.

    Each example runs `assert_sensor_contract` on particles on the carpet (sometimes with a few far off it)
    for a frame from `observations` and one from `hostile`. Runs its own hypothesis search: call it from a
    plain test, not inside ``@given``.

    Parameters
    ----------
    model : sensor model
        Anything with `check(observations)` and `log_likelihood(poses, observations, out=None)`, optionally
        `terms(observations)`.
    field : field.Field
        The field the model scores on: particles lie on its carpet, detections are of its landmark types.
    n : int or (int, int), optional
        Particles per example (default 1 to 64).
    frames : hypothesis strategy of Observations, optional
        Frames the model should score (default: up to 8 detections with and without their own noise, up to 16
        line points, sometimes a camera view). The model may refuse some, not all.
    hostile : hypothesis strategy of Observations, optional
        Frames to score or refuse cleanly (default `edge_observations(field)`).
    bound : float or callable, optional
        The largest log-likelihood accepted, or a function of the observations giving it (default: any finite
        value).
    allow_neg_inf : bool, optional
        Accept -inf log-likelihoods (default False).
    max_examples : int, optional
        Examples to run (default 20).
    shrink : bool, optional
        Whether hypothesis shrinks a failing example to a small one (slower) or reports the first it finds;
        default None: as the loaded hypothesis profile's phases say (all of them, unless a profile leaves
        shrinking out).

    Returns
    -------
    ContractReport
        How many frames were accepted and refused.

    Raises
    ------
    AssertionError
        On the first property that fails (after hypothesis has shrunk the example), or when the model refuses
        every frame from `observations`.
    """
    report = ContractReport()
    good = frames if frames is not None else observations(field, max_detections=8, with_sigmas=True,
                                                           max_line_points=16, with_view=True)
    bad_frames = edge_observations(field) if hostile is None else hostile

    def test(poses, far, frame, bad):
        report.examples += 1
        rows = np.concatenate([poses, np.array(far, dtype=np.float64).reshape(-1, 3)]) if far else poses
        if assert_sensor_contract(model, rows, frame, bound=bound, allow_neg_inf=allow_neg_inf):
            report.accepted += 1
        else:
            report.refused += 1
        if assert_sensor_contract(model, rows, bad, bound=bound, allow_neg_inf=allow_neg_inf):
            report.hostile_accepted += 1
        else:
            report.hostile_refused += 1

    _run(test, max_examples, dict(poses=pose_arrays(field, n), far=_far_rows(field), frame=good, bad=bad_frames),
         shrink)
    assert report.accepted > 0, (f"{_name(model)} refused all {report.refused} frames drawn: give "
                                 "`frames=` a strategy of the frames it takes")
    return report


# -- registered models -----------------------------------------------------------------------------------------------
# A team's models join the contract checks the library's own models go through: registered in the process
# (`register_motion_model`, `register_sensor_model`, e.g. in a conftest.py) or declared by an installed package
# as an entry point, so that the library's own contract tests (tests/test_contracts.py, run from a clone in
# the team's environment) check them too:
#
#     [project.entry-points."robocup_mcl.motion_models"]
#     our-odometry = "our_robot.localization:OurOdometry"          # called with no arguments
#     [project.entry-points."robocup_mcl.sensor_models"]
#     our-goals = "our_robot.localization:OurGoalModel"            # called with the field
ENTRY_POINT_GROUPS = {"motion": "robocup_mcl.motion_models", "sensor": "robocup_mcl.sensor_models"}
MODEL_KINDS = tuple(ENTRY_POINT_GROUPS)


@dataclass(frozen=True)
class RegisteredModel:
    """A model that `check_registered` runs through the contract checks.

    Attributes
    ----------
    name : str
        Its name in reports and test ids.
    kind : str
        "motion" or "sensor".
    make : callable
        Builds the model: with no arguments for a motion model, with the `field.Field` for a sensor model.
    refused : tuple of MotionInput
        Inputs a motion model must refuse (passed to `check_motion_model`).
    source : str
        "registered" (in this process) or "entry point <value>" (declared by an installed package).
    """

    name: str
    kind: str
    make: Callable[..., Any]
    refused: tuple = ()
    source: str = "registered"

    def build(self, field: Field) -> Any:
        """The model, built for `field` (a sensor model) or without it (a motion model).

        Parameters
        ----------
        field : field.Field
            Passed to `make` for a sensor model; unused for a motion model.

        Returns
        -------
        MotionModel or SensorModel
            What `make` returns.
        """
        return self.make(field) if self.kind == "sensor" else self.make()


_REGISTERED: dict[tuple[str, str], RegisteredModel] = {}


def _register(kind: str, name, make, refused: Sequence[MotionInput] = ()) -> RegisteredModel:
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"a registered model needs a non-empty name, not {name!r}")
    if not callable(make):
        raise TypeError(f"register a callable that builds the {kind} model, not {type(make).__name__}")
    refused = tuple(refused)
    if not all(isinstance(u, MotionInput) for u in refused):
        raise TypeError("refused= takes MotionInput values")
    if (kind, name) in _REGISTERED:
        raise ValueError(f"a {kind} model named {name!r} is already registered; unregister it first")
    entry = RegisteredModel(name, kind, make, refused)
    _REGISTERED[(kind, name)] = entry
    return entry


def register_motion_model(name: str, make: Callable[[], Any], *,
                          refused: Sequence[MotionInput] = ()) -> RegisteredModel:
    """Register a motion model for `check_registered` (and the library's contract tests run in this process).

    Parameters
    ----------
    name : str
        A name unique among registered motion models.
    make : callable
        Called with no arguments, returns the model (a class works).
    refused : sequence of MotionInput, optional
        Inputs the model must refuse.

    Returns
    -------
    RegisteredModel

    Raises
    ------
    ValueError
        An empty name, or a name already registered (nothing is registered then).
    TypeError
        `make` is not callable, or `refused` holds something other than MotionInput values.
    """
    return _register("motion", name, make, refused)


def register_sensor_model(name: str, make: Callable[[Field], Any]) -> RegisteredModel:
    """Register a sensor model for `check_registered`: `make(field)` returns the model (a class works).

    Parameters
    ----------
    name : str
        A name unique among registered sensor models.
    make : callable
        Called with the `field.Field`, returns the model (a class works).

    Returns
    -------
    RegisteredModel

    Raises
    ------
    ValueError
        An empty name, or a name already registered (nothing is registered then).
    TypeError
        `make` is not callable.
    """
    return _register("sensor", name, make)


def unregister(kind: str, name: str) -> None:
    """Take a model registered in this process off the list (KeyError when there is none by that name).

    Parameters
    ----------
    kind : str
        "motion" or "sensor".
    name : str
        The name it was registered under.

    Raises
    ------
    ValueError
        If `kind` is neither "motion" nor "sensor".
    KeyError
        If no model of that kind is registered in this process under `name` (entry points cannot be
        unregistered).
    """
    if kind not in MODEL_KINDS:
        raise ValueError(f"kind must be one of {MODEL_KINDS}, not {kind!r}")
    del _REGISTERED[(kind, name)]


def _entry_points(kind: str) -> list[RegisteredModel]:
    from importlib.metadata import entry_points
    found = []
    for point in entry_points(group=ENTRY_POINT_GROUPS[kind]):
        def make(*args, _point=point):
            return _point.load()(*args)
        found.append(RegisteredModel(point.name, kind, make, (), f"entry point {point.value}"))
    return found


def registered_models(kind: str | None = None) -> list[RegisteredModel]:
    """The models registered in this process and declared as entry points by installed packages, in that
    order, motion models first; `kind` ("motion" or "sensor") keeps one kind. Entry points are loaded only when
    a model is built.

    Parameters
    ----------
    kind : str or None, optional
        "motion" or "sensor" to keep one kind; None (the default) for both.

    Returns
    -------
    list of RegisteredModel
        The models, motion models first; of each kind, those registered in this process, then the entry points.

    Raises
    ------
    ValueError
        If `kind` is neither None, "motion" nor "sensor".
    """
    if kind is not None and kind not in MODEL_KINDS:
        raise ValueError(f"kind must be one of {MODEL_KINDS} or None, not {kind!r}")
    kinds = MODEL_KINDS if kind is None else (kind,)
    return [entry for k in kinds for entry in
            [e for (ek, _), e in _REGISTERED.items() if ek == k] + _entry_points(k)]


@dataclass
class RegisteredReport:
    """What `check_registered` found for one model.

    Attributes
    ----------
    model : RegisteredModel
    contract : ContractReport
        The contract check's counts.
    fast_path : dict
        `mcl.contracts.fast_path` for the model beside the library's reference partner (a velocity-linear
        motion model for a sensor model, a landmark sensor model for a motion model): whether it moves, or is
        scored, inside the filter's fused compiled step.
    same_run : bool
        A filter with the model gave the same run twice from the same seed (checked; False is never returned,
        a difference raises).
    """

    model: RegisteredModel
    contract: ContractReport
    fast_path: dict
    same_run: bool = True


def check_registered(field: Field | None = None, *, kind: str | None = None, max_examples: int = 20,
                     strict: bool = True) -> list[RegisteredReport]:
    """Run every registered model (see `registered_models`) through the contract checks the library's own
    models pass: `check_motion_model` (shapes, finite and wrapped poses, refusals that change nothing, same
    seed same result) or `check_sensor_model`, a short filter run from the same seed twice, and which part of
    the fused fast path the model reaches.

    Parameters
    ----------
    field : field.Field, optional
        Default `field.spl()`.
    kind : str, optional
        Check only "motion" or only "sensor" models.
    max_examples : int, optional
        Examples per contract check (default 20).
    strict : bool, optional
        Passed to `check_motion_model` (default True: `predict` refuses what `check` refuses).

    Returns
    -------
    list of RegisteredReport
        One per model, in `registered_models` order (empty when none is registered).

    Raises
    ------
    AssertionError
        Naming the model that broke a contract, and how.
    """
    from mcl.contracts import fast_path
    from mcl.filter import ParticleFilter
    from motion_models import VelocityLinear
    from sensing import LandmarkSensorModel

    field = _preset(spl) if field is None else field
    reports = []
    for entry in registered_models(kind):
        try:
            model = entry.build(field)
        except Exception as error:
            raise AssertionError(f"registered {entry.kind} model {entry.name!r} ({entry.source}) could not be "
                                 f"built: {type(error).__name__}: {error}") from error
        try:
            if entry.kind == "motion":
                contract = check_motion_model(model, field, refused=entry.refused, strict=strict,
                                              max_examples=max_examples)
                motion, sensor = model, LandmarkSensorModel(field)
                u = _accepted_input(model)
            else:
                contract = check_sensor_model(model, field, max_examples=max_examples)
                motion, sensor = VelocityLinear(), model
                u = MotionInput(dt=0.01, command=(0.2, 0.0, 0.1), collision=NO_COLLISION)
            frame = Observations.from_arrays(["goalpost", "T"], [3.0, 2.0], [0.3, -0.4])
            steps = [(u, None), (u, frame), (u, frame)] if u is not None else []
            assert_same_seed_same_run(lambda: ParticleFilter(field, motion, sensor, n_particles=64, seed=3), steps)
        except Exception as error:
            failures = _assertions(error)
            if not failures:
                raise
            more = f" (and {len(failures) - 1} other failures)" if len(failures) > 1 else ""
            raise AssertionError(f"registered {entry.kind} model {entry.name!r} ({entry.source}): "
                                 f"{failures[0]}{more}") from error
        reports.append(RegisteredReport(entry, contract, fast_path(motion, sensor)))
    return reports


def _assertions(error: BaseException) -> list[AssertionError]:
    """The assertion failures in `error`: itself, or those of an exception group (hypothesis raises one when it
    finds several distinct failures); empty when any part is not an assertion failure."""
    if isinstance(error, AssertionError):
        return [error]
    parts = getattr(error, "exceptions", None)
    if not parts:
        return []
    found = [_assertions(part) for part in parts]
    return [] if not all(found) else [failure for group in found for failure in group]


_PROBES = (MotionInput(dt=0.01, command=(0.2, 0.0, 0.1), collision=NO_COLLISION),
           MotionInput(dt=0.01, odometry=(0.002, 0.0, 0.001), collision=NO_COLLISION),
           MotionInput(dt=0.01, footstep=FootstepEvent(support=1, commanded=(0.04, 0.0, 0.1),
                                                       sensor=(0.04, 0.0, 0.1), duration=0.3,
                                                       previous_sensor=(0.04, 0.0, 0.1), previous_duration=0.3),
                       collision=NO_COLLISION))


def _accepted_input(model) -> MotionInput | None:
    """A plain walking input the motion model accepts (a command, odometry or a footstep), or None."""
    for u in _PROBES:
        try:
            model.check(u)
        except REFUSALS:
            continue
        return u
    return None
