import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from field import spl
from mcl import ParticleFilter
from motion_models import MotionInput, VelocityLinear
from sensing import CombinedSensorModel, LandmarkSensorModel, LineSensorModel, Observations

FIELD = spl()
LINES = LineSensorModel(FIELD)


def seen_from(pose, world_points):
    """World points expressed in the robot frame of `pose`."""
    d = world_points - pose[:2]
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


def test_distance_map_is_zero_on_lines_and_grows_away():
    dist = LINES.distance_map
    x0, y0 = -FIELD.half_length - FIELD.dims.border_strip_width, -FIELD.half_width - FIELD.dims.border_strip_width

    def at(x, y):
        return dist[int((y - y0) / LINES.resolution), int((x - x0) / LINES.resolution)]

    assert at(0.0, 1.5) <= LINES.resolution  # on the centre line
    assert at(1.0, 0.0) == pytest.approx(0.25, abs=0.03)  # centre circle r = 0.75, at 1 m from the centre
    assert at(-1.5, 1.5) == pytest.approx(math.hypot(1.5, 1.5) - 0.75, abs=0.03)  # nearest: the centre circle
    assert not dist.flags.writeable


@given(st.integers(0, 2**32 - 1), st.integers(0, 30))
def test_kernel_matches_numpy_reference(seed, n_points):
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(-6, 6, 80), rng.uniform(-4, 4, 80), rng.uniform(-math.pi, math.pi, 80)])
    obs = Observations.from_arrays([], [], [], line_points=rng.uniform(-4, 4, (n_points, 2)))
    np.testing.assert_allclose(
        LINES.log_likelihood(poses, obs), LINES.numpy_twin().log_likelihood(poses, obs), atol=1e-9
    )
    assert LINES.terms(obs) == min(n_points, LINES.max_points)


@pytest.mark.parametrize("sigma,outlier_weight", [(0.05, 0.2), (0.3, 0.01)])
def test_likelihood_field_follows_the_model_parameters(sigma, outlier_weight):
    """The per-cell factors the kernel looks up are exp(-½(d/σ)²) + outlier_weight of the distance map, and
    scoring with them matches the numpy reference for other σ and outlier weights too."""
    model = LineSensorModel(FIELD, sigma=sigma, outlier_weight=outlier_weight)
    np.testing.assert_allclose(
        model._factors, np.exp(-0.5 * (model.distance_map / sigma) ** 2) + outlier_weight, rtol=1e-14
    )
    assert not model._factors.flags.writeable
    rng = np.random.default_rng(1)
    poses = np.column_stack([rng.uniform(-6, 6, 50), rng.uniform(-4, 4, 50), rng.uniform(-math.pi, math.pi, 50)])
    obs = Observations.from_arrays([], [], [], line_points=rng.uniform(-4, 4, (20, 2)))
    np.testing.assert_allclose(
        model.log_likelihood(poses, obs), model.numpy_twin().log_likelihood(poses, obs), atol=1e-9
    )


def test_true_pose_explains_the_line_points_best():
    pose = np.array([-2.0, 1.0, 0.4])
    on_lines = FIELD.line_points(spacing=0.2)
    visible = on_lines[np.hypot(*(on_lines - pose[:2]).T) < 3.0]
    obs = Observations.from_arrays([], [], [], line_points=seen_from(pose, visible))
    rng = np.random.default_rng(0)
    others = pose + np.column_stack([rng.normal(0, 0.3, 300), rng.normal(0, 0.3, 300), rng.normal(0, 0.2, 300)])
    scores = LINES.log_likelihood(np.vstack([pose, others]), obs)
    assert scores[0] >= scores[1:].max() - 1e-9


def test_combined_model_adds_and_delegates():
    landmarks = LandmarkSensorModel(FIELD)
    combined = CombinedSensorModel((landmarks, LINES))
    pose = np.array([[1.0, 0.5, 0.2], [-1.0, 2.0, 2.0]])
    obs = Observations.from_arrays(["penalty_mark"], [2.3], [0.1], line_points=[[1.0, 0.0], [1.5, 0.2]])
    np.testing.assert_allclose(
        combined.log_likelihood(pose, obs), landmarks.log_likelihood(pose, obs) + LINES.log_likelihood(pose, obs)
    )
    assert combined.terms(obs) == 3
    assert combined.sample_poses(obs, 4, np.random.default_rng(0)).shape == (4, 3)
    with pytest.raises(ValueError, match="models"):
        CombinedSensorModel(())


def test_filter_corrects_with_line_points_only():
    model = CombinedSensorModel((LandmarkSensorModel(FIELD), LINES))
    pf = ParticleFilter(FIELD, VelocityLinear(), model, n_particles=300, seed=0)
    pose = np.array([0.5, -1.5, 1.0])
    pf.reset_around(pose, (0.2, 0.2, 0.1))
    on_lines = FIELD.line_points(spacing=0.2)
    visible = on_lines[np.hypot(*(on_lines - pose[:2]).T) < 3.0]
    obs = Observations.from_arrays([], [], [], line_points=seen_from(pose, visible))
    for _ in range(20):
        pf.step(MotionInput(dt=0.033, command=(0, 0, 0)), obs)
    assert np.hypot(*(pf.estimate().pose[:2] - pose[:2])) < 0.1


@pytest.mark.parametrize("name,value", [("sigma", 0.0), ("resolution", -1.0), ("max_points", 0)])
def test_bad_parameters(name, value):
    with pytest.raises(ValueError, match=name):
        LineSensorModel(FIELD, **{name: value})


def test_bad_line_points():
    with pytest.raises(ValueError, match="line_points"):
        Observations.from_arrays([], [], [], line_points=[[0.0, float("inf")]])
