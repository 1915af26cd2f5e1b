"""The reference engine (`ParticleFilter(..., reference=True)`): every stage in numpy, the same draws, the
compiled filter's results to rounding; refused with options it cannot honour."""

import json
import math

import numpy as np
import pytest

from field import spl
from mcl import ParticleFilter
from mcl.engine import Engine, ReferenceEngine
from motion_models import AdaptiveMotion, MotionInput, VelocityLinear
from proprioception.collision import NO_COLLISION
from sensing import LandmarkSensorModel, Observations

FIELD = spl()
TRUE_POSE = np.array([1.5, -1.0, 0.7])
CARRIED = TRUE_POSE + np.array([0.5, 2.0, 0.0])  # carried 2 m with its heading


def detections(pose):
    """Two landmarks of each kind, seen exactly (kind, range, bearing) from `pose`."""
    rows = []
    for kind in ("goalpost", "penalty_mark", "t_crossing", "x_crossing"):
        for target in FIELD.landmarks_of(kind)[:2]:
            d = target - pose[:2]
            rows.append((kind, math.hypot(*d), math.atan2(d[1], d[0]) - pose[2]))
    return Observations.from_arrays(*zip(*rows))


def pair(scheme="systematic", motion=VelocityLinear, n=300, seed=2):
    made = [
        ParticleFilter(
            FIELD, motion(), LandmarkSensorModel(FIELD), n_particles=n, seed=seed, resampling=scheme, reference=ref
        )
        for ref in (False, True)
    ]
    for pf in made:
        pf.reset_around(TRUE_POSE, (0.05, 0.05, 0.05))
    return made


def assert_close(compiled, reference):
    np.testing.assert_allclose(reference.poses, compiled.poses, rtol=0, atol=1e-9)
    np.testing.assert_allclose(reference.weights, compiled.weights, rtol=1e-9, atol=1e-15)
    a, b = compiled.estimate(), reference.estimate()
    np.testing.assert_allclose(b.pose, a.pose, rtol=0, atol=1e-9)
    np.testing.assert_allclose(b.covariance, a.covariance, rtol=1e-7, atol=1e-12)
    assert b.weight == pytest.approx(a.weight, rel=1e-9)
    h, g = compiled.entropy(), reference.entropy()
    assert (g.position, g.orientation) == pytest.approx((h.position, h.orientation), rel=1e-9)
    assert (reference.resampled, reference.injected) == (compiled.resampled, compiled.injected)


@pytest.mark.parametrize("scheme", ["systematic", "stratified", "multinomial", "residual"])
def test_the_reference_engine_follows_the_compiled_filter_through_a_kidnapping(scheme):
    """Tracking, then carried 2 m unseen: the same resampling, the same injection, the same re-localization,
    equal to rounding at every step (the stages' sums differ in order only)."""
    compiled, reference = pair(scheme)
    assert isinstance(reference.engine, ReferenceEngine) and reference.reference
    assert type(compiled.engine) is Engine and not compiled.reference
    u = MotionInput(dt=0.033, command=(0.05, 0.0, 0.1))
    injected = 0
    for k in range(40):
        z = detections(TRUE_POSE if k < 10 else CARRIED)
        compiled.step(u, z)
        reference.step(u, z)
        assert_close(compiled, reference)
        injected += reference.injected
    assert injected > 0
    assert math.hypot(*(reference.estimate().pose[:2] - CARRIED[:2])) < 0.3


def test_the_reference_engine_carries_a_motion_models_particle_state():
    """The adaptive model keeps a mobility state per particle: resampled along with the poses, in numpy."""
    compiled, reference = pair(motion=AdaptiveMotion)
    u = MotionInput(dt=0.033, command=(0.1, 0.0, 0.2), collision=NO_COLLISION)
    for _ in range(8):
        for pf in (compiled, reference):
            pf.step(u, detections(TRUE_POSE))
        assert_close(compiled, reference)
        np.testing.assert_array_equal(reference.motion_state, compiled.motion_state)


def test_the_reference_engine_gives_the_same_run_for_the_same_seed():
    runs = []
    for _ in range(2):
        _, reference = pair(seed=7)
        for _step in range(12):
            reference.step(MotionInput(dt=0.033, command=(0.1, 0.0, 0.0)), detections(TRUE_POSE))
        runs.append((reference.poses.copy(), reference.log_weights.copy()))
    assert np.array_equal(runs[0][0], runs[1][0]) and np.array_equal(runs[0][1], runs[1][1])


@pytest.mark.parametrize(
    "options, error",
    [
        (dict(reference=True, threads=2), ValueError),
        (dict(reference=True, fast=True), ValueError),
        (dict(reference="yes"), TypeError),
        (dict(reference=1), TypeError),
    ],
)
def test_options_the_reference_engine_cannot_honour_are_refused(options, error):
    with pytest.raises(error, match="reference"):
        ParticleFilter(FIELD, VelocityLinear(), LandmarkSensorModel(FIELD), n_particles=50, **options)


def test_a_late_frame_is_scored_where_the_particles_were_at_capture():
    """`correct(..., since=)`: the particles moved back along the displacement since capture, in numpy."""
    compiled, reference = pair()
    since = np.array([0.12, -0.03, 0.2])
    for pf in (compiled, reference):
        pf.predict(MotionInput(dt=0.5, command=(0.24, -0.06, 0.4)))
        pf.correct(detections(TRUE_POSE), since=since)
    assert_close(compiled, reference)


def test_bench_engines_times_both_and_says_how_far_apart_they_ended(capsys, tmp_path):
    from benchmarks.engines import main

    path = tmp_path / "engines.json"
    assert main(["--sizes", "50,80", "--steps", "2", "--rounds", "1", "--json", "--save", str(path)]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed == json.loads(path.read_text())
    assert [row["particles"] for row in printed["rows"]] == [50, 80]
    for row in printed["rows"]:
        assert row["compiled_us"] > 0 and row["reference_us"] > 0
        assert row["ratio"] == pytest.approx(row["reference_us"] / row["compiled_us"])
        assert max(row["largest_difference"].values()) < 1e-9


@pytest.mark.parametrize("sizes", ["0", "ten", "100,", "2000000"])
def test_bench_engines_refuses_bad_sizes(sizes, capsys):
    from benchmarks.engines import main

    with pytest.raises(SystemExit) as exit_info:
        main(["--sizes", sizes])
    assert exit_info.value.code == 2
    assert "--sizes" in capsys.readouterr().err


def test_the_numpy_twin_of_log_mean_likelihood_equals_the_kernel():
    """`mcl.reference.log_mean_likelihood` (what the reference engine's weights take the frame's evidence by)
    against the kernel, with particles of zero weight or likelihood among them and counts from 0 to N."""
    from mcl import reference
    from mcl.weights import log_mean_likelihood

    rng = np.random.default_rng(3)
    for trial in range(50):
        n = int(rng.integers(1, 40))
        log_weights = rng.normal(0.0, 2.0, n)
        log_likelihood = rng.normal(-3.0, 2.0, n)
        log_weights[rng.random(n) < 0.2] = -np.inf
        log_likelihood[rng.random(n) < 0.2] = -np.inf
        for count in (0, n // 2, n):
            expected = log_mean_likelihood(log_weights, log_likelihood, count)
            got = reference.log_mean_likelihood(log_weights, log_likelihood, count)
            if expected == -np.inf:
                assert got == -np.inf, (trial, count)
            else:
                assert got == pytest.approx(expected, rel=1e-12, abs=1e-12), (trial, count)
