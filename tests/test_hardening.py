"""The inputs a fuzz run of the public entry points found mishandled, each refused now with a clear error and
the filter left bit for bit as it was (`fuzzing.snapshot` compares everything it holds, the generator too)."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from field import spl  # noqa: E402
from field.checks import LARGEST_SIGMA, SMALLEST_SIGMA, ArgumentTypeError, integer, real, reals  # noqa: E402
from fuzzing import check_filter, snapshot  # noqa: E402
from mcl import Grid, ParticleFilter  # noqa: E402
from mcl.localizer import Localizer  # noqa: E402
from motion_models import MotionInput, VelocityLinear  # noqa: E402
from sensing import LandmarkObservation, LandmarkSensorModel, Observations  # noqa: E402

FIELD = spl()
STEP = MotionInput(dt=0.01, command=(0.1, 0.0, 0.0))


def make_filter(n=64):
    pf = ParticleFilter(FIELD, VelocityLinear(), LandmarkSensorModel(FIELD), n_particles=n, seed=4)
    pf.step(STEP, [LandmarkObservation("goalpost", 3.0, 0.2), LandmarkObservation("T", 1.5, -0.4)])
    return pf


def refused_unchanged(owner, call, error=ValueError, match=None):
    before = snapshot(owner)
    with pytest.raises(error, match=match):
        call()
    assert snapshot(owner) == before


@pytest.mark.parametrize(
    "sigmas",
    [
        dict(bearing_sigma=1e-160),
        dict(range_sigma=1e-200),
        dict(range_sigma=5e-324),
        dict(bearing_sigma=1e300),
        dict(range_sigma=SMALLEST_SIGMA / 2),
    ],
)
def test_a_noise_below_the_smallest_is_refused_before_anything_changes(sigmas):
    with pytest.raises(ValueError, match=r"sigma = .* must be finite and >= 1e-06 and <= 1000"):
        LandmarkObservation("goalpost", 2.0, 0.3, **sigmas)
    key = next(iter(sigmas))
    pf = make_filter()
    batch = dict(kinds=["goalpost"], ranges=[2.0], bearings=[0.3], **{key + "s": [sigmas[key]]})
    refused_unchanged(pf, lambda: pf.step(STEP, Observations.from_arrays(**batch)), match=key + "s")
    loc = Localizer(FIELD, n_particles=32)
    refused_unchanged(loc, lambda: loc.observe(Observations.from_arrays(**batch)), match=key + "s")


def test_the_smallest_and_largest_noise_are_accepted_and_stay_finite():
    pf = make_filter()
    for sigma in (SMALLEST_SIGMA, LARGEST_SIGMA):
        pf.step(
            STEP, Observations.from_arrays(["goalpost", "T"], [2.0, 7.0], [0.3, -2.0], [sigma, sigma], [sigma, sigma])
        )
        check_filter(pf)
        assert np.isfinite(pf.estimate().pose).all()


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda pf: pf.reset_uniform("field", heading=1e300, heading_sigma=1e300), "heading"),
        (lambda pf: pf.reset_uniform("field", heading=0.0, heading_sigma=1e300), "heading_sigma"),
        (lambda pf: pf.diffuse((0.0, 0.0, 1e308)), "sigma"),
        (lambda pf: pf.reset_around((1e6, 0.0, 0.0)), "pose"),
        (lambda pf: pf.reset_candidates([(0.0, 0.0, 0.0), (0.0, 0.0, 1e9)]), r"poses\[1\]"),
        (lambda pf: pf.set_particles(np.full((64, 3), 1e300)), r"poses\[0\]"),
        (lambda pf: pf.correct([LandmarkObservation("goalpost", 2.0, 0.3)], since=(1e6, 0.0, 0.0)), "since"),
        (lambda pf: pf.reset_uniform((0.0, 1e308, 0.0, 1.0)), "region"),
    ],
)
def test_values_beyond_the_bounds_are_refused_and_change_nothing(call, match):
    pf = make_filter()
    refused_unchanged(pf, lambda: call(pf), match=match)


def test_headings_come_back_wrapped():
    pf = make_filter()
    pf.reset_uniform("field", heading=99.0, heading_sigma=5.0)
    check_filter(pf)
    pf.reset_around((0.0, 0.0, -99.0), (0.1, 0.1, 50.0))
    check_filter(pf)
    pf.predict(MotionInput(dt=1e3, command=(0.0, 0.0, 0.09)))
    check_filter(pf)


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        (dict(n_particles=10**13), ValueError, "n_particles"),
        (dict(n_particles=2.5), TypeError, "n_particles"),
        (dict(threads=10**9), ValueError, "threads"),
        (dict(seed="x"), TypeError, "seed"),
        (dict(grid=Grid(position_cell=0.01, orientation_bins=3600)), ValueError, "grid"),
    ],
)
def test_constructions_that_would_exhaust_memory_are_refused(kwargs, error, match):
    with pytest.raises(error, match=match):
        ParticleFilter(FIELD, VelocityLinear(), LandmarkSensorModel(FIELD), **kwargs)


def test_placement_spacings_are_bounded():
    loc = Localizer(FIELD, n_particles=32)
    for spacing in (0.0, 1e-9, -1.0, math.inf, 100.0):
        refused_unchanged(loc, lambda: loc.initial_placement(spacing), match="spacing")
    refused_unchanged(loc, lambda: loc.initial_placement("wide"), ArgumentTypeError, "spacing")
    loc.initial_placement(0.05)
    check_filter(loc.filter)


def test_observation_arrays_are_never_reshaped():
    with pytest.raises(ValueError, match="ranges must be one-dimensional"):
        Observations.from_arrays(["T", "L", "X", "goalpost"], np.ones((2, 2)), [0.0] * 4)
    with pytest.raises(ValueError, match=r"line_points must have shape \(P, 2\)"):
        Observations.from_arrays([], [], [], line_points=np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"ranges\[0\] = .* must be <= 1000 m"):
        Observations.from_arrays(["T"], [1e300], [0.0])
    with pytest.raises(ValueError, match=r"bearings\[0\] = .* must be within ±100 rad"):
        Observations.from_arrays(["T"], [1.0], [1e300])


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda pf: pf.correct(math.nan), "observations = nan must be an Observations"),
        (lambda pf: pf.step("u"), "u = 'u' must be a motion_models.MotionInput, not str"),
        (lambda pf: pf.diffuse("wide"), "sigma = 'wide' must be 3 numbers, not str"),
        (lambda pf: pf.reset_around(None), "pose = None must be 3 numbers"),
        (lambda pf: pf.correct([LandmarkObservation("T", 1.0, 0.0)], since="now"), "since = 'now'"),
        (lambda pf: setattr(pf, "resample_threshold", "half"), "resample_threshold = 'half' must be a number"),
    ],
)
def test_wrong_types_raise_a_type_error_naming_the_argument(call, match):
    pf = make_filter()
    before = snapshot(pf)
    with pytest.raises(TypeError, match=match) as error:
        call(pf)
    assert isinstance(error.value, ValueError)  # one family: a loop catching ValueError catches it too
    assert snapshot(pf) == before


def test_motion_inputs_name_the_wrong_type():
    with pytest.raises(TypeError, match="dt = 'fast' must be a number, not str"):
        MotionInput(dt="fast", command=(0.1, 0.0, 0.0))
    with pytest.raises(TypeError, match="command = 'ahead' must be 3 numbers"):
        MotionInput(dt=0.01, command="ahead")
    with pytest.raises(ValueError, match="dt = 7200.0 must be finite and >= 0 and <= 3600"):
        MotionInput(dt=7200.0)


def test_the_argument_checks():
    assert real("x", 3) == 3.0 and integer("n", np.int64(4), 1) == 4
    assert reals("v", (1, 2.5, np.float32(3)), 3).dtype == np.float64
    for bad in (True, "1", None, [1.0], np.array([1.0])):
        with pytest.raises(ArgumentTypeError, match="x = "):
            real("x", bad)
    with pytest.raises(ValueError, match=r"x = 1000000\d+\.\.\.\d+ must be finite$"):
        real("x", 10**400)
    with pytest.raises(ValueError, match="must be 3 numbers, got shape"):
        reals("v", [1.0, 2.0], 3)
    with pytest.raises(ArgumentTypeError):
        reals("v", [1.0, "2", 3.0], 3)
    with pytest.raises(ValueError, match="> 0"):
        real("x", 0.0, 0.0, low_open=True)


@pytest.mark.parametrize("make", [lambda: VelocityLinear(beta3=1e100), lambda: VelocityLinear(beta1=101.0)])
def test_noise_parameters_are_bounded(make):
    with pytest.raises(ValueError, match="must be finite and >= 0 and <= 100"):
        make()


def test_the_largest_noise_of_the_largest_step_stays_finite_and_wrapped():
    from motion_models import ConstantNoise
    from motion_models.base import MAX_NOISE_PARAMETER, MAX_STEP_DT

    for model in (ConstantNoise(*(3 * [MAX_NOISE_PARAMETER])), VelocityLinear(*(4 * [MAX_NOISE_PARAMETER]))):
        pf = ParticleFilter(FIELD, model, LandmarkSensorModel(FIELD), n_particles=64, seed=1)
        pf.step(MotionInput(dt=MAX_STEP_DT, command=(0.0, 0.0, 0.02)), [LandmarkObservation("goalpost", 2.0, 0.3)])
        check_filter(pf)
        assert np.isfinite(pf.estimate().pose).all()
