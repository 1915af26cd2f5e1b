"""The fuzz targets: every public entry point of the filter, the localizer, the models and the loaders, called
with generated (mostly hostile) arguments through `fuzzing.attempt`.

A target is a hypothesis test; `TARGETS` names them for `tests/fuzz_run.py`, which runs each in a child process
with the profile it is given ("ci" or "full") and counts the cases.
"""

from __future__ import annotations

import math
import os
import tempfile

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from field import LandmarkType, preset
from fuzzing import attempt, check_estimate, check_filter, junk, number_or_junk, numbers, record_case, sane, triples
from mcl import AugmentedMCL, Grid, ParticleFilter
from mcl.localizer import Localizer
from motion_models import AdaptiveMotion, ConstantNoise, MotionInput, VelocityLinear
from proprioception.collision import NO_COLLISION, CollisionPercept
from sensing import CombinedSensorModel, LandmarkObservation, LandmarkSensorModel, LineSensorModel, Observations
from sensing.team import BallDetection, TeamMessage
from sensing.view import CameraView

FIELDS = {name: preset(name) for name in ("spl", "kidsize", "adultsize")}
KIND_NAMES = [kind.name for kind in LandmarkType] + [
    "L",
    "T",
    "X",
    "goalpost",
    "penalty_mark",
    "center_mark",
    "post",
    "centre",
]
BAD_KINDS = ["nope", "", 99, -1, 1.5, None, True]
_LINE_MODELS: dict = {}


def _line_model(field_name: str) -> LineSensorModel:
    if field_name not in _LINE_MODELS:  # its likelihood field takes a while to build
        _LINE_MODELS[field_name] = LineSensorModel(FIELDS[field_name])
    return _LINE_MODELS[field_name]


# -- arguments -------------------------------------------------------------------------------------------------
def motion_args():
    """Keyword arguments of a MotionInput: often sane, often not."""
    sane_step = st.fixed_dictionaries(
        {
            "dt": st.sampled_from([0.0, 0.01, 0.033, 0.1]),
            "command": st.tuples(sane(-0.5, 0.5), sane(-0.3, 0.3), sane(-1, 1)),
        }
    )
    sane_odometry = st.fixed_dictionaries(
        {
            "dt": st.sampled_from([0.01, 0.02]),
            "odometry": st.tuples(sane(-0.05, 0.05), sane(-0.05, 0.05), sane(-0.2, 0.2)),
        }
    )
    hostile = st.fixed_dictionaries(
        {"dt": number_or_junk()},
        optional={
            "command": triples(5.0),
            "odometry": triples(5.0),
            "collision": st.one_of(
                st.just(NO_COLLISION), junk(), st.just(CollisionPercept(left=True, rate=0.5, recent_left=True))
            ),
        },
    )
    return st.one_of(sane_step, sane_step, sane_odometry, hostile)


def detection_args():
    """One detection as (kind, range, bearing, range_sigma, bearing_sigma)."""
    kind = st.one_of(st.sampled_from(KIND_NAMES), st.sampled_from(KIND_NAMES), st.sampled_from(BAD_KINDS))
    sigma = st.one_of(st.none(), st.none(), sane(0.01, 0.5), numbers(), junk())
    return st.one_of(
        st.tuples(kind, sane(0.1, 8.0), sane(-1.5, 1.5), st.none(), st.none()),
        st.tuples(kind, number_or_junk(), number_or_junk(), sigma, sigma),
    )


def observation_args():
    """A frame's detections: a list of detections, as `from_list` or `from_arrays` takes them, or junk."""
    detections = st.lists(detection_args(), max_size=5)
    line_points = st.one_of(
        st.none(),
        st.lists(st.tuples(sane(-4, 4), sane(-4, 4)), max_size=6),
        st.lists(st.tuples(numbers(), numbers()), max_size=3),
        junk(),
        st.just(np.zeros((2, 3))),
        st.just(np.ones((3,))),
    )
    return st.one_of(
        st.tuples(st.just("list"), detections, line_points),
        st.tuples(st.just("arrays"), detections, line_points),
        st.tuples(st.just("junk"), junk(), st.none()),
    )


def build_observations(args):
    how, detections, line_points = args
    if how == "junk":
        return detections
    if how == "list":
        if line_points is None:
            return [LandmarkObservation(*d) for d in detections]
        return Observations.from_list([LandmarkObservation(*d) for d in detections], line_points=line_points)
    columns = list(zip(*detections)) if detections else [[], [], [], [], []]
    kinds, ranges, bearings, range_sigmas, bearing_sigmas = columns
    range_sigmas = (
        None if all(v is None for v in range_sigmas) else [math.nan if v is None else v for v in range_sigmas]
    )
    bearing_sigmas = (
        None if all(v is None for v in bearing_sigmas) else [math.nan if v is None else v for v in bearing_sigmas]
    )
    return Observations.from_arrays(
        list(kinds), list(ranges), list(bearings), range_sigmas, bearing_sigmas, line_points
    )


def filter_config():
    return st.fixed_dictionaries(
        {
            "field": st.sampled_from(sorted(FIELDS)),
            "motion": st.sampled_from(["velocity_linear", "velocity_linear_gaussian", "constant", "adaptive"]),
            "sensor": st.sampled_from(["landmarks", "landmarks", "landmarks_sum", "lines", "combined"]),
            "n": st.sampled_from([1, 2, 7, 64]),
            "seed": st.integers(0, 3),
            "fast": st.booleans(),
            "augmented": st.booleans(),
            "resampling": st.sampled_from(["systematic", "stratified", "residual", "multinomial"]),
        }
    )


def make_filter(config) -> ParticleFilter:
    field = FIELDS[config["field"]]
    motion = {
        "velocity_linear": VelocityLinear(),
        "velocity_linear_gaussian": VelocityLinear(gaussian=True),
        "constant": ConstantNoise(),
        "adaptive": AdaptiveMotion(),
    }[config["motion"]]
    sensor = config["sensor"]
    if sensor == "lines":
        sensor_model = _line_model(config["field"])
    elif sensor == "combined":
        sensor_model = CombinedSensorModel((LandmarkSensorModel(field), _line_model(config["field"])))
    else:
        sensor_model = LandmarkSensorModel(field, mixture="sum" if sensor == "landmarks_sum" else "max")
    return ParticleFilter(
        field,
        motion,
        sensor_model,
        n_particles=config["n"],
        seed=config["seed"],
        fast=config["fast"],
        resampling=config["resampling"],
        augmented=AugmentedMCL() if config["augmented"] else None,
    )


def motion_input(kwargs, adaptive: bool) -> MotionInput:
    kwargs = dict(kwargs)
    if adaptive:
        kwargs.setdefault("collision", NO_COLLISION)
    return MotionInput(**kwargs)


REGIONS = st.one_of(
    st.sampled_from(["field", "own_half", "opponent_half", "nowhere"]),
    st.tuples(sane(-5, 0), sane(0.1, 5), sane(-3, 0), sane(0.1, 3)),
    st.tuples(numbers(), numbers(), numbers(), numbers()),
    junk(),
)
SIGMAS = st.one_of(st.tuples(sane(0, 0.5), sane(0, 0.5), sane(0, 0.5)), triples(1.0))
POSES = st.one_of(st.tuples(sane(-4, 4), sane(-3, 3), sane(-3.2, 3.2)), triples(5.0))


def filter_operations():
    return st.lists(
        st.one_of(
            st.tuples(st.just("predict"), motion_args()),
            st.tuples(st.just("step"), motion_args(), observation_args()),
            st.tuples(st.just("step"), motion_args(), observation_args()),
            st.tuples(st.just("correct"), observation_args(), st.one_of(st.none(), triples(0.2))),
            st.tuples(st.just("reset_uniform"), REGIONS, st.one_of(st.none(), number_or_junk()), number_or_junk()),
            st.tuples(st.just("reset_around"), POSES, SIGMAS),
            st.tuples(st.just("reset_candidates"), st.one_of(st.lists(POSES, max_size=3), junk()), SIGMAS, REGIONS),
            st.tuples(st.just("diffuse"), SIGMAS),
            st.tuples(st.just("reset_mirrored")),
            st.tuples(
                st.just("set_particles"), st.sampled_from(["valid", "huge", "nan", "shape", "weights", "bad_weights"])
            ),
            st.tuples(
                st.just("setting"),
                st.sampled_from(["resampling", "resample_threshold", "roughening", "augmented"]),
                number_or_junk(),
            ),
            st.tuples(st.just("estimate")),
        ),
        min_size=1,
        max_size=8,
    )


def apply_filter_operation(pf: ParticleFilter, op, adaptive: bool) -> None:
    name = op[0]
    n = pf.n
    if name == "predict":
        attempt("filter", pf, lambda: pf.predict(motion_input(op[1], adaptive)), check_filter)
    elif name == "step":
        attempt("filter", pf, lambda: pf.step(motion_input(op[1], adaptive), build_observations(op[2])), check_filter)
    elif name == "correct":
        attempt("filter", pf, lambda: pf.correct(build_observations(op[1]), since=op[2]), check_filter)
    elif name == "reset_uniform":
        attempt("filter", pf, lambda: pf.reset_uniform(op[1], op[2], op[3]), check_filter)
    elif name == "reset_around":
        attempt("filter", pf, lambda: pf.reset_around(op[1], op[2]), check_filter)
    elif name == "reset_candidates":
        attempt("filter", pf, lambda: pf.reset_candidates(op[1], op[2], op[3]), check_filter)
    elif name == "diffuse":
        attempt("filter", pf, lambda: pf.diffuse(op[1]), check_filter)
    elif name == "reset_mirrored":
        attempt("filter", pf, pf.reset_mirrored, check_filter)
    elif name == "set_particles":
        kind = op[1]
        poses = np.zeros((n, 3))
        poses[:, 0] = np.linspace(-1, 1, n)
        weights = None
        if kind == "huge":
            poses[:, 0] = 1e300
        elif kind == "nan":
            poses[-1, 1] = math.nan
        elif kind == "shape":
            poses = np.zeros((n + 1, 3))
        elif kind == "weights":
            weights = np.linspace(-3, 0, n)
        elif kind == "bad_weights":
            weights = np.full(n, -math.inf)
        attempt("filter", pf, lambda: pf.set_particles(poses, weights), check_filter)
    elif name == "setting":
        attempt("filter", pf, lambda: setattr(pf, op[1], op[2]), check_filter)
    elif name == "estimate":
        attempt("filter", pf, lambda: check_estimate(pf))


@given(config=filter_config(), operations=filter_operations())
def fuzz_filter(config, operations):
    """ParticleFilter: predict, step, correct, the resets, set_particles, the settings, the estimate."""
    record_case("filter", (config, operations))
    pf = make_filter(config)
    for op in operations:
        apply_filter_operation(pf, op, config["motion"] == "adaptive")
    check_filter(pf)
    check_estimate(pf)


@given(kwargs=motion_args())
def fuzz_motion_input(kwargs):
    """MotionInput: an accepted input has a finite displacement within the documented bounds."""
    record_case("motion_input", kwargs)
    from motion_models.base import MAX_STEP_DISTANCE, MAX_STEP_TURN

    holder = []
    if attempt("motion_input", None, lambda: holder.append(MotionInput(**kwargs))):
        u = holder[0]
        if u.command is not None or u.odometry is not None:
            dx, dy, dtheta = u.displacement()
            assert math.hypot(dx, dy) <= MAX_STEP_DISTANCE and abs(dtheta) <= MAX_STEP_TURN


@given(
    detections=st.lists(detection_args(), max_size=4),
    how=st.sampled_from(["list", "arrays"]),
    line_points=st.one_of(
        st.none(),
        st.lists(st.tuples(numbers(), numbers()), max_size=3),
        junk(),
        st.just(np.zeros((2, 3))),
        st.just(np.zeros((2, 2, 2))),
    ),
    shape=st.sampled_from([None, (2, 2), (1, 4), (4, 1)]),
)
def fuzz_observations(detections, how, line_points, shape):
    """Observations and LandmarkObservation: accepted batches hold finite, in-bound, 1-D arrays."""
    record_case("observations", (detections, how, line_points, shape))
    holder = []

    def build():
        if shape is not None and how == "arrays" and len(detections) == 4:
            holder.append(
                Observations.from_arrays(
                    [d[0] for d in detections],
                    np.reshape([d[1] for d in detections], shape),
                    [d[2] for d in detections],
                )
            )
        else:
            holder.append(Observations.coerce(build_observations((how, detections, line_points))))

    if attempt("observations", None, build):
        batch = holder[0]
        for name in ("ranges", "bearings", "range_sigmas", "bearing_sigmas"):
            assert getattr(batch, name).ndim == 1
        assert np.isfinite(batch.ranges).all() and np.isfinite(batch.bearings).all()
        assert batch.line_points.ndim == 2 and batch.line_points.shape[1] == 2
        assert np.isfinite(batch.line_points).all()


@given(
    kwargs=st.fixed_dictionaries(
        {},
        optional={
            "n_particles": st.one_of(st.sampled_from([0, -1, 10**13, 2**63, 1.5, True, 10**7 + 1]), junk()),
            "seed": st.one_of(st.integers(-5, 10**30), junk()),
            "resampling": st.one_of(st.sampled_from(["systematic", "bogus"]), junk()),
            "resample_threshold": number_or_junk(),
            "roughening": triples(1.0),
            "threads": st.one_of(st.sampled_from([0, -1, 10**9, 1.0]), junk()),
            "fast": st.one_of(st.booleans(), junk()),
            "augmented": st.one_of(st.just(AugmentedMCL()), junk()),
            "grid": st.one_of(st.just("grid"), junk()),
            "relocalization": junk(),
        },
    ),
    grid=st.fixed_dictionaries(
        {},
        optional={
            "position_cell": number_or_junk(),
            "orientation_bins": number_or_junk(),
            "cluster_cell": number_or_junk(),
        },
    ),
    augmented=st.fixed_dictionaries(
        {},
        optional={
            "alpha_slow": number_or_junk(),
            "alpha_fast": number_or_junk(),
            "max_fraction": number_or_junk(),
            "fit_threshold": number_or_junk(),
        },
    ),
)
def fuzz_filter_construction(kwargs, grid, augmented):
    """ParticleFilter, Grid and AugmentedMCL constructors: refused with ValueError/TypeError, or a filter
    that steps."""
    record_case("filter_construction", (kwargs, grid, augmented))
    field = FIELDS["spl"]
    holder = []

    def build():
        options = dict(kwargs)
        if options.get("grid") == "grid":
            options["grid"] = Grid(**grid)
        if augmented:
            options["augmented"] = AugmentedMCL(**augmented)
        holder.append(ParticleFilter(field, VelocityLinear(), LandmarkSensorModel(field), **options))

    if attempt("filter_construction", None, build):
        pf = holder[0]
        if pf.n <= 5000:
            pf.step(
                MotionInput(dt=0.01, command=(0.2, 0.0, 0.1)),
                [LandmarkObservation("goalpost", 2.0, 0.3), LandmarkObservation("T", 1.0, -0.5)],
            )
            check_filter(pf)
            check_estimate(pf)


@given(
    kwargs=st.fixed_dictionaries(
        {},
        optional={
            "range_noise_floor": number_or_junk(),
            "range_noise_growth": number_or_junk(),
            "range_noise_linear": number_or_junk(),
            "bearing_sigma": number_or_junk(),
            "outlier_weight": number_or_junk(),
            "mixture": st.one_of(st.sampled_from(["max", "sum", "x"]), junk()),
            "bearing_model": st.one_of(st.sampled_from(["von_mises", "gaussian", "x"]), junk()),
        },
    ),
    line_kwargs=st.fixed_dictionaries(
        {},
        optional={
            "sigma": number_or_junk(),
            "resolution": st.one_of(st.sampled_from([1e-9, 0.0, -1.0, 1e-300]), junk()),
            "max_points": number_or_junk(),
            "outlier_weight": number_or_junk(),
        },
    ),
    motion_kwargs=st.fixed_dictionaries(
        {},
        optional={"beta1": number_or_junk(), "beta4": number_or_junk(), "gaussian": st.one_of(st.booleans(), junk())},
    ),
    constant_kwargs=st.fixed_dictionaries({}, optional={"rate_x": number_or_junk(), "rate_theta": number_or_junk()}),
    observations=observation_args(),
)
def fuzz_models(kwargs, line_kwargs, motion_kwargs, constant_kwargs, observations):
    """The models' constructors: refused cleanly, or models a filter steps with."""
    record_case("models", (kwargs, line_kwargs, motion_kwargs, constant_kwargs, observations))
    field = FIELDS["kidsize"]
    models = []
    attempt("models", None, lambda: models.append(("sensor", LandmarkSensorModel(field, **kwargs))))
    if line_kwargs:
        attempt("models", None, lambda: models.append(("sensor", LineSensorModel(field, **line_kwargs))))
    attempt("models", None, lambda: models.append(("motion", VelocityLinear(**motion_kwargs))))
    attempt("models", None, lambda: models.append(("motion", ConstantNoise(**constant_kwargs))))
    sensors = [m for kind, m in models if kind == "sensor"] or [LandmarkSensorModel(field)]
    motions = [m for kind, m in models if kind == "motion"] or [VelocityLinear()]
    for sensor in sensors:
        for motion in motions:
            pf = ParticleFilter(field, motion, sensor, n_particles=32, seed=1)
            attempt(
                "models",
                pf,
                lambda: pf.step(MotionInput(dt=0.05, command=(0.3, 0.1, 0.5)), build_observations(observations)),
                check_filter,
            )
            check_estimate(pf)


def localizer_operations():
    return st.lists(
        st.one_of(
            st.tuples(st.just("motion"), st.one_of(sane(0, 0.05), number_or_junk()), motion_args()),
            st.tuples(st.just("motion"), sane(0, 0.05), motion_args()),
            st.tuples(st.just("observe"), observation_args(), st.one_of(st.none(), sane(-0.2, 0.0), number_or_junk())),
            st.tuples(st.just("observe"), observation_args(), st.none(), view_args()),
            st.tuples(st.just("initial_placement"), st.one_of(sane(0.05, 1.0), number_or_junk())),
            st.tuples(st.just("penalty_return")),
            st.tuples(
                st.just("kickoff_placement"),
                st.one_of(st.none(), st.lists(POSES, max_size=3), junk()),
                st.one_of(st.booleans(), junk()),
            ),
            st.tuples(st.just("manual_placement"), st.one_of(st.none(), st.lists(POSES, max_size=3), junk())),
            st.tuples(st.just("anywhere_in_own_half")),
            st.tuples(st.just("place"), POSES, st.one_of(st.none(), SIGMAS)),
            st.tuples(st.just("fallen")),
            st.tuples(st.just("got_up")),
            st.tuples(st.just("quality")),
            st.tuples(st.just("penalized")),
            st.tuples(st.just("team_message"), team_message_args()),
            st.tuples(st.just("observe_ball"), ball_args(), st.one_of(st.none(), sane(-0.2, 0.0), number_or_junk())),
            st.tuples(st.just("hypotheses")),
        ),
        min_size=1,
        max_size=10,
    )


def team_message_args():
    """A teammate's message as `TeamMessage` takes it: sane, with bad numbers (NaN, inf, huge), a covariance
    that is not positive definite, a time far away, an unknown sender; or junk."""
    covariances = st.one_of(
        st.none(),
        st.just(np.diag([0.01, 0.01, 0.01])),
        st.just(np.ones((3, 3))),
        st.just(-np.eye(3)),
        st.just(np.full((3, 3), np.nan)),
        st.just(np.eye(2)),
        junk(),
    )
    return st.one_of(
        st.fixed_dictionaries(
            {
                "sender": st.one_of(st.integers(-1, 22), junk()),
                "time": st.one_of(sane(-2.0, 0.5), st.just(1e12), number_or_junk()),
                "pose": POSES,
            },
            optional={
                "pose_covariance": covariances,
                "confidence": st.one_of(sane(-0.5, 1.5), number_or_junk()),
                "is_goalkeeper": st.one_of(st.booleans(), junk()),
                "ball": st.one_of(
                    st.none(), st.tuples(sane(-5, 5), sane(-4, 4)), st.tuples(number_or_junk(), number_or_junk())
                ),
                "ball_velocity": st.one_of(
                    st.none(), st.tuples(sane(-3, 3), sane(-3, 3)), st.tuples(number_or_junk(), number_or_junk())
                ),
                "ball_age": st.one_of(sane(0, 3), number_or_junk()),
                "clock_offset": st.one_of(sane(-1, 1), number_or_junk()),
            },
        ),
        junk(),
    )


def ball_args():
    """A ball detection as `BallDetection` takes it (range, bearing, sigmas), sane or not; or junk."""
    return st.one_of(
        st.tuples(
            sane(0, 6), sane(-3.2, 3.2), st.one_of(st.none(), sane(0.01, 0.5)), st.one_of(st.none(), sane(0.01, 0.5))
        ),
        st.tuples(
            number_or_junk(),
            number_or_junk(),
            st.one_of(st.none(), number_or_junk()),
            st.one_of(st.none(), number_or_junk()),
        ),
        junk(),
    )


def build_team_message(args, clock: float):
    """The message of `team_message_args` (its time relative to the localizer's clock), or the junk itself."""
    if not isinstance(args, dict):
        return args
    args = dict(args)
    if isinstance(args.get("time"), float) and math.isfinite(args["time"]):
        args["time"] = clock + args["time"]
    return TeamMessage(**args)


def build_ball(args):
    return BallDetection(*args) if isinstance(args, tuple) else args


def view_args():
    """A camera view as `CameraView` takes it (sane or not), or something that is not one."""
    return st.one_of(
        st.tuples(sane(-3.5, 3.5), sane(0.1, 1.6), sane(1.0, 9.0), sane(0.0, 0.5)),
        st.tuples(number_or_junk(), number_or_junk(), number_or_junk(), number_or_junk()),
        junk(),
    )


def build_view(args):
    return CameraView(*args) if isinstance(args, tuple) else args


def check_localizer(loc) -> None:
    check_filter(loc.filter)
    assert not math.isnan(loc.side_log_odds), "side log odds NaN"


def check_hypotheses(hypotheses) -> None:
    total = sum(h.weight for h in hypotheses)
    assert total <= 1.0 + 1e-9, f"hypotheses' weights sum to {total}"
    for h in hypotheses:
        assert np.isfinite(h.pose).all() and np.isfinite(h.covariance).all() and 0.0 <= h.weight <= 1.0, h


@given(
    field_name=st.sampled_from(sorted(FIELDS)),
    n=st.sampled_from([1, 16, 64]),
    operations=localizer_operations(),
    options=st.fixed_dictionaries(
        {},
        optional={
            "history": number_or_junk(),
            "getup_sigma": SIGMAS,
            "placement_sigma": SIGMAS,
            "compensate_latency": st.booleans(),
        },
    ),
)
def fuzz_localizer(field_name, n, operations, options):
    """Localizer: the loop (motion, observe), the game events, the quality."""
    record_case("localizer", (field_name, n, operations, options))
    field = FIELDS[field_name]
    holder = []
    if not attempt("localizer", None, lambda: holder.append(Localizer(field, n_particles=n, seed=3, **options))):
        return
    loc = holder[0]
    clock = [0.0]
    for op in operations:
        name = op[0]
        if name == "motion":
            dt = op[1]

            def motion():
                t = clock[0] + float(dt)
                loc.motion(t, MotionInput(**op[2]))
                clock[0] = t

            attempt("localizer", loc, motion, check_localizer)
        elif name == "observe":
            offset = op[2]
            view = op[3] if len(op) > 3 else None
            attempt(
                "localizer",
                loc,
                lambda: loc.observe(
                    build_observations(op[1]),
                    None if offset is None else clock[0] + offset,
                    None if view is None else build_view(view),
                ),
                check_localizer,
            )
        elif name == "initial_placement":
            attempt("localizer", loc, lambda: loc.initial_placement(op[1]), check_localizer)
        elif name == "kickoff_placement":
            attempt("localizer", loc, lambda: loc.kickoff_placement(op[1], op[2]), check_localizer)
        elif name == "manual_placement":
            attempt("localizer", loc, lambda: loc.manual_placement(op[1]), check_localizer)
        elif name == "place":
            attempt("localizer", loc, lambda: loc.place(op[1], op[2]), check_localizer)
        elif name == "quality":
            attempt("localizer", loc, lambda: (loc.quality(), loc.is_lost, loc.fit, loc.seen_share))
        elif name == "team_message":
            attempt("localizer", loc, lambda: loc.team_message(build_team_message(op[1], clock[0])), check_localizer)
        elif name == "observe_ball":
            offset = op[2]
            attempt(
                "localizer",
                loc,
                lambda: loc.observe_ball(build_ball(op[1]), None if offset is None else clock[0] + offset),
                check_localizer,
            )
        elif name == "hypotheses":
            attempt("localizer", loc, lambda: check_hypotheses(loc.hypotheses()))
        else:
            attempt("localizer", loc, getattr(loc, name), check_localizer)
    check_estimate(loc.filter)


# -- loaders ---------------------------------------------------------------------------------------------------
_VALID_FILES: dict = {}


def _valid_files() -> dict:
    """One valid file of each kind the library reads, as bytes (made once): what the mutations start from."""
    if _VALID_FILES:
        return _VALID_FILES
    from field import save_field
    from motion_models.learned_odometry import LearnedFootstepOdometry
    from motion_models.lwpr import LWPR
    from proprioception.collision import CollisionReference

    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        for suffix in (".toml", ".json"):
            save_field(FIELDS["kidsize"], os.path.join(tmp, "field" + suffix))
        model = LWPR(2, 1)
        for x in rng.uniform(-1, 1, (60, 2)):
            model.update(x, [math.sin(3 * x[0]) + x[1]])
        model.save(os.path.join(tmp, "lwpr.npz"))
        CollisionReference(
            np.array([1, 2]), np.array([0, 1]), 5, np.array([0.0, 0.1]), rng.uniform(0.01, 0.1, (2, 2, 4)), 0.05
        ).save(os.path.join(tmp, "collision.npz"))
        inputs = rng.uniform(-0.05, 0.05, (80, 9))
        odometry = LearnedFootstepOdometry.train(inputs, inputs[:, :3] * 1.1, "online")
        odometry.save(os.path.join(tmp, "odometry"))
        LearnedFootstepOdometry.train(inputs, inputs[:, :3] * 1.1 + 0.01, "online", linear_stage=True).save(
            os.path.join(tmp, "odometry_linear")
        )
        from mcl.profile import Profile

        Profile.from_values(
            {
                "sensor.outlier_weight": 0.02,
                "odometry.scale_x": 1.1,
                "localizer.particles": 300,
                "motion.beta1": 2.0,
                "quality.superb_fit": 0.6,
            }
        ).save(os.path.join(tmp, "profile.toml"))
        with open(os.path.join(tmp, "space.toml"), "w", encoding="utf-8") as handle:
            handle.write(
                "[sensor]\noutlier_weight = { low = 0.001, high = 0.1, log = true }\n"
                'mixture = { choices = ["max", "sum"] }\n[localizer]\nparticles = { low = 100, high = 900 }\n'
            )
        from mcl.tools.logs import write_log

        log = _small_log()
        write_log(log, os.path.join(tmp, "log.mcap"))
        write_log(log, os.path.join(tmp, "log.npz"))
        write_log(log, os.path.join(tmp, "csv"))
        for name in sorted(os.listdir(tmp)):
            path = os.path.join(tmp, name)
            if os.path.isdir(path):
                for inner in sorted(os.listdir(path)):
                    _VALID_FILES[f"{name}/{inner}"] = open(os.path.join(path, inner), "rb").read()
            else:
                _VALID_FILES[name] = open(path, "rb").read()
    return _VALID_FILES


def _small_log():
    """A log with every stream, a few rows each, and two camera frames."""
    from mcl.tools.logs import RobotLog, VisionFrame

    t = np.arange(5) * 0.1
    rng = np.random.default_rng(5)
    seen = Observations.from_arrays(
        ["goalpost", "T", "penalty_mark"], [1.0, 2.5, 3.0], [0.1, -0.2, 0.4], line_points=[[1.0, 2.0], [3.0, 4.0]]
    )
    return RobotLog(
        origin_ns=1_700_000_000 * 10**9,
        odometry_times=t,
        odometry=rng.uniform(-1, 1, (5, 3)),
        command_times=t,
        commands=rng.uniform(-1, 1, (5, 3)),
        imu_times=t,
        gyro=rng.uniform(-1, 1, (5, 3)),
        acceleration=rng.uniform(-1, 1, (5, 3)),
        joint_names=("HeadYaw", "HeadPitch"),
        joint_command_times=t,
        joint_commands=rng.uniform(-1, 1, (5, 2)),
        joint_reading_times=t,
        joint_readings=rng.uniform(-1, 1, (5, 2)),
        truth_times=t,
        truth=rng.uniform(-1, 1, (5, 3)),
        vision=(VisionFrame(0.0, 0.02, seen), VisionFrame(0.15, 0.17, Observations.empty())),
    )


def _load(name: str, path: str):
    from field import load_field
    from motion_models.learned_odometry import LearnedFootstepOdometry
    from motion_models.lwpr import LWPR
    from proprioception.collision import CollisionDetector, CollisionReference

    if name.startswith("field"):
        return load_field(path)
    if name == "profile.toml":
        from mcl.profile import Profile

        profile = Profile.load(path)
        profile.localizer_options(FIELDS["spl"])
        return profile
    if name == "space.toml":
        from mcl.tools.tuning.space import SearchSpace

        return SearchSpace.load(path)
    if name.startswith("log") or name.startswith("csv/"):
        from mcl.tools.logs import read_log
        from mcl.tools.logs.mcap_io import list_topics

        log, report = read_log(path if name.startswith("log") else os.path.dirname(path))
        assert math.isfinite(log.duration) and np.isfinite(log.odometry).all()
        if name == "log.mcap":
            list_topics(path)
        return log
    if name == "lwpr.npz":
        model = LWPR.load(path)
        model.predict(np.zeros(model.n_in) if hasattr(model, "n_in") else np.zeros(2))
        return model
    if name == "collision.npz":
        reference = CollisionReference.load(path)
        detector = CollisionDetector(reference)
        commands = np.zeros(reference.n_joints)
        for _ in range(reference.window + 2):
            detector.update(commands, commands + 0.01, 0.3, (0.1, 0.0, 0.0))
        return reference
    return LearnedFootstepOdometry.load(os.path.dirname(path))


@given(data=st.data())
def fuzz_loaders(data):
    """Field files, LWPR models, collision references, learned odometry, profiles and tuning spaces: valid files
    with bytes flipped, cut, inserted or replaced, read by their loaders: a loaded object that works, or a
    ValueError/TypeError."""
    _fuzz_files(data, "loaders", [name for name in _valid_files() if not _is_log(name)])


def _is_log(name: str) -> bool:
    return name.startswith("log") or name.startswith("csv/")


@given(data=st.data())
def fuzz_logs(data):
    """Robot logs (ROS 2 MCAP, .npz, a folder of CSV files) with bytes flipped, cut, inserted or replaced, read
    by `mcl.tools.logs.read_log` (and `list_topics`): a usable log, or a ValueError naming the file."""
    _fuzz_files(data, "logs", [name for name in _valid_files() if _is_log(name)])


def _fuzz_files(data, target: str, names: list[str]) -> None:
    files = _valid_files()
    name = data.draw(st.sampled_from(sorted(names)), label="file")
    content = bytearray(files[name])
    how = data.draw(st.sampled_from(["flip", "flips", "truncate", "insert", "replace"]), label="how")
    if how in ("flip", "flips"):
        for _ in range(1 if how == "flip" else data.draw(st.integers(2, 20), label="count")):
            offset = data.draw(st.integers(0, len(content) - 1), label="offset")
            content[offset] ^= data.draw(st.integers(1, 255), label="mask")
    elif how == "truncate":
        del content[data.draw(st.integers(0, len(content) - 1), label="length") :]
    elif how == "insert":
        offset = data.draw(st.integers(0, len(content)), label="offset")
        content[offset:offset] = data.draw(st.binary(min_size=1, max_size=64), label="bytes")
    else:
        offset = data.draw(st.integers(0, len(content) - 1), label="offset")
        chunk = data.draw(
            st.sampled_from(
                [
                    b"\xff" * 8,
                    b"\x00" * 8,
                    b"9" * 30,
                    b"[" * 200,
                    b"-1e400",
                    b"nan",
                    b"\x7f\xff\xff\xff\xff\xff\xff\xff",
                ]
            ),
            label="chunk",
        )
        content[offset : offset + len(chunk)] = chunk
    record_case(target, (name, how, bytes(content[:64])))
    with tempfile.TemporaryDirectory() as tmp:
        if "/" in name:  # a directory of files: the others stay valid
            directory, _ = name.split("/")
            os.makedirs(os.path.join(tmp, directory))
            for other, valid in files.items():
                if other.startswith(directory + "/"):
                    open(os.path.join(tmp, other), "wb").write(valid)
        path = os.path.join(tmp, name)
        open(path, "wb").write(bytes(content))
        attempt(target, None, lambda: _load(name, path))


# -- estimators and helpers -------------------------------------------------------------------------------------
VECTOR3 = st.one_of(st.tuples(sane(-3, 3), sane(-3, 3), sane(-12, 12)), triples(10.0))


def estimator_operations():
    return st.lists(
        st.one_of(
            st.tuples(st.just("ekf_predict"), st.one_of(sane(0.001, 0.05), number_or_junk()), VECTOR3, VECTOR3),
            st.tuples(st.just("ekf_correct"), VECTOR3, st.one_of(st.none(), number_or_junk())),
            st.tuples(
                st.just("history_record"),
                st.one_of(sane(0.0, 0.05), number_or_junk()),
                st.one_of(sane(0.0, 0.05), number_or_junk()),
                triples(0.1),
            ),
            st.tuples(st.just("history_since"), st.one_of(sane(-1.0, 0.1), number_or_junk())),
            st.tuples(
                st.just("lwpr_update"),
                st.one_of(st.tuples(sane(-1, 1), sane(-1, 1)), triples(1.0)),
                st.one_of(sane(-1, 1), number_or_junk()),
            ),
            st.tuples(st.just("lwpr_predict"), st.one_of(st.tuples(sane(-1, 1), sane(-1, 1)), triples(1.0))),
            st.tuples(
                st.just("collision"),
                st.one_of(st.lists(sane(-1, 1), min_size=2, max_size=2), triples(1.0)),
                st.one_of(st.lists(sane(-1, 1), min_size=2, max_size=2), triples(1.0)),
                st.one_of(sane(0, 1), number_or_junk()),
                VECTOR3,
            ),
            st.tuples(st.just("leg_imu"), st.one_of(sane(0.001, 0.02), number_or_junk()), VECTOR3, VECTOR3),
            st.tuples(
                st.just("leg_kinematics"),
                st.one_of(sane(0.0, 0.02), number_or_junk()),
                st.one_of(
                    st.lists(st.lists(sane(-1, 1), min_size=6, max_size=6), min_size=2, max_size=2),
                    st.lists(st.lists(numbers(), min_size=6, max_size=6), min_size=2, max_size=2),
                    st.lists(numbers(), max_size=13),
                    junk(),
                ),
                st.one_of(
                    st.lists(st.lists(st.booleans(), min_size=4, max_size=4), min_size=2, max_size=2),
                    junk(),
                    st.lists(numbers(), max_size=3),
                ),
            ),
            st.tuples(st.just("leg_take")),
            st.tuples(
                st.just("footstep"),
                st.one_of(st.sampled_from([1, -1]), number_or_junk()),
                st.one_of(st.tuples(sane(-0.1, 0.1), sane(-0.1, 0.1), sane(-0.3, 0.3)), triples(1.0)),
                st.one_of(st.none(), triples(0.1)),
                st.one_of(st.none(), sane(0.2, 0.5), number_or_junk()),
            ),
        ),
        min_size=1,
        max_size=10,
    )


@given(operations=estimator_operations())
def fuzz_estimators(operations):
    """The velocity EKF, the motion history (latency), LWPR's update and predict, the collision detector, the
    footstep model through a filter: sequences of calls with hostile arguments."""
    record_case("estimators", operations)
    from mcl.latency import MotionHistory
    from motion_models import FootstepEvent, RawFootstepOdometry
    from motion_models.lwpr import LWPR
    from proprioception.collision import CollisionDetector, CollisionReference
    from proprioception.velocity import VelocityEKF

    ekf = VelocityEKF.from_standing(np.tile([0.0, 0.0, 9.81], (10, 1)), 0.0)
    history = MotionHistory(1.0)
    model = LWPR(2, 1)
    detector = CollisionDetector(
        CollisionReference(np.array([1, 2]), np.array([0, 1]), 5, np.array([0.0, 0.1]), np.full((2, 2, 4), 0.05), 0.05)
    )
    field = FIELDS["kidsize"]
    pf = ParticleFilter(field, RawFootstepOdometry(), LandmarkSensorModel(field), n_particles=16, seed=2)
    from proprioception.kinematics import nao_leg
    from proprioception.velocity import LegOdometry
    from proprioception.velocity_odometry import EKFOdometry

    legs = EKFOdometry(
        LegOdometry(
            (nao_leg("left"), nao_leg("right")), VelocityEKF.from_standing(np.tile([0.0, 0.0, 9.81], (10, 1)), 0.0)
        )
    )
    clock = {"ekf": 0.0, "history": 0.0, "legs": 0.0}

    def leg_imu(dt, gyro, accel):
        t = clock["legs"] + dt
        legs.imu(t, gyro, accel)
        clock["legs"] = t

    def check_legs(o):
        check_ekf(o.ekf)
        assert np.isfinite(o.sum.peek().odometry).all(), "non-finite odometry sum"

    def ekf_predict(dt, gyro, accel):
        t = clock["ekf"] + dt
        ekf.predict(t, gyro, accel)
        clock["ekf"] = t

    def history_record(dt_end, dt, displacement):
        t = clock["history"] + dt_end
        history.record(t, dt, displacement)
        clock["history"] = t

    def check_ekf(e):
        assert np.isfinite(e.state).all() and np.isfinite(e.covariance).all(), "non-finite EKF state"

    for op in operations:
        name = op[0]
        if name == "ekf_predict":
            attempt("estimators", ekf, lambda: ekf_predict(op[1], op[2], op[3]), check_ekf)
        elif name == "ekf_correct":
            attempt("estimators", ekf, lambda: ekf.correct(op[1], op[2]), check_ekf)
        elif name == "history_record":
            attempt("estimators", history, lambda: history_record(op[1], op[2], op[3]))
        elif name == "history_since":
            result = []
            if attempt("estimators", history, lambda: result.append(history.since(clock["history"] + op[1]))):
                assert np.isfinite(result[0]).all(), "non-finite displacement"
        elif name == "lwpr_update":
            attempt("estimators", model, lambda: model.update(op[1], [op[2]]))
        elif name == "lwpr_predict":
            result = []
            if attempt("estimators", model, lambda: result.append(model.predict(op[1]))):
                assert np.isfinite(result[0]).all(), "non-finite LWPR prediction"
        elif name == "collision":
            attempt("estimators", detector, lambda: detector.update(op[1], op[2], op[3], op[4]))
        elif name == "leg_imu":
            attempt("estimators", legs, lambda: leg_imu(op[1], op[2], op[3]), check_legs)
        elif name == "leg_kinematics":
            attempt("estimators", legs, lambda: legs.kinematics(clock["legs"] + op[1], op[2], op[3]), check_legs)
        elif name == "leg_take":
            result = []
            if attempt("estimators", legs, lambda: result.append(legs.take())):
                assert np.isfinite(result[0].odometry).all() and math.isfinite(result[0].dt)
        elif name == "footstep":
            attempt(
                "estimators",
                pf,
                lambda: pf.predict(
                    MotionInput(dt=0.3, footstep=FootstepEvent(op[1], op[2], sensor=op[3], duration=op[4]))
                ),
                check_filter,
            )


def recorder_operations():
    return st.lists(
        st.one_of(
            st.tuples(
                st.just("log_step"),
                st.one_of(st.integers(0, 20), number_or_junk()),
                st.one_of(sane(0, 5), number_or_junk()),
                st.one_of(st.none(), POSES, triples(1.0)),
                st.one_of(st.none(), observation_args()),
            ),
            st.tuples(
                st.just("log_scalars"),
                st.one_of(st.dictionaries(st.sampled_from(["a/b", "c", ""]), number_or_junk(), max_size=3), junk()),
            ),
            st.tuples(st.just("set_time"), st.one_of(st.integers(0, 20), number_or_junk()), number_or_junk()),
            st.tuples(st.just("flush")),
        ),
        min_size=1,
        max_size=8,
    )


@given(operations=recorder_operations(), particles_every=st.one_of(st.sampled_from([1, 2, 5]), number_or_junk()))
def fuzz_recorder(operations, particles_every):
    """mcl.tools.recording.Recorder: its constructor and sequences of log_step, log_scalars, set_time, flush into an
    .rrd file, then close."""
    record_case("recorder", (operations, particles_every))
    from mcl.tools.recording import Recorder

    field = FIELDS["spl"]
    pf = _RECORDED.get("pf")
    if pf is None:
        pf = _RECORDED["pf"] = ParticleFilter(field, VelocityLinear(), LandmarkSensorModel(field), n_particles=32)
    with tempfile.TemporaryDirectory() as tmp:
        holder = []
        if not attempt(
            "recorder",
            None,
            lambda: holder.append(Recorder(os.path.join(tmp, "run.rrd"), field, particles_every=particles_every)),
        ):
            return
        recorder = holder[0]
        for op in operations:
            if op[0] == "log_step":

                def log_step(op=op):
                    observations = None if op[4] is None else Observations.coerce(build_observations(op[4]))
                    recorder.log_step(op[1], op[2], pf, truth=op[3], observations=observations)

                attempt("recorder", recorder, log_step)
            elif op[0] == "log_scalars":
                attempt("recorder", recorder, lambda: recorder.log_scalars(op[1]))
            elif op[0] == "set_time":
                attempt("recorder", recorder, lambda: recorder.set_time(op[1], op[2]))
            else:
                attempt("recorder", recorder, recorder.flush)
        recorder.close()
        assert os.path.getsize(os.path.join(tmp, "run.rrd")) > 0


_RECORDED: dict = {}


@given(value=st.integers(0, 10))
def fuzz_crash(value):
    """Not a target of the suite: dies of SIGSEGV, so the runner's crash report can be tested."""
    record_case("_crash", value)
    if value >= 0:
        import ctypes
        import faulthandler

        faulthandler.disable()
        ctypes.string_at(0)


TARGETS = {
    "motion_input": fuzz_motion_input,
    "observations": fuzz_observations,
    "filter": fuzz_filter,
    "filter_construction": fuzz_filter_construction,
    "models": fuzz_models,
    "localizer": fuzz_localizer,
    "loaders": fuzz_loaders,
    "logs": fuzz_logs,
    "estimators": fuzz_estimators,
    "recorder": fuzz_recorder,
}
HIDDEN = {"_crash": fuzz_crash}  # run by name only
# The share of a profile's examples each target gets (the filter and the localizer hold the most).
WEIGHTS = {
    "motion_input": 1,
    "observations": 1,
    "filter": 3,
    "filter_construction": 1,
    "models": 1,
    "localizer": 3,
    "loaders": 2,
    "logs": 2,
    "estimators": 2,
    "recorder": 1,
}
