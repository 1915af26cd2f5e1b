import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mcl.estimate import cluster_estimate, cluster_estimate_reference, grid_entropy, grid_entropy_reference

GRID = dict(x_min=-5.2, y_min=-3.7, cell_size=0.1, nx=104, ny=74, n_theta=36)


def entropy(poses, weights, **grid):
    g = dict(GRID, **grid)
    return grid_entropy(poses, weights, g["x_min"], g["y_min"], g["cell_size"], g["nx"], g["ny"], g["n_theta"],
                        np.empty(g["nx"] * g["ny"]), np.empty(g["n_theta"]))


def estimate(poses, weights, previous=None):
    mean, cov = np.empty(3), np.empty((3, 3))
    weight = cluster_estimate(poses, weights, -5.2, -3.7, 0.5, 21, 15, 8, 0.75, 0.8, 3, np.empty(21 * 15 * 8),
                              np.zeros(3) if previous is None else np.asarray(previous, float), previous is not None,
                              mean, cov)
    return mean, cov, weight


clouds = st.integers(0, 2**32 - 1).map(lambda seed: np.random.default_rng(seed))


def random_cloud(rng, n=300):
    poses = np.column_stack([rng.uniform(-6, 6, n), rng.uniform(-4, 4, n), rng.uniform(-math.pi, math.pi, n)])
    weights = rng.random(n) ** 3
    return poses, weights / weights.sum()


@given(clouds)
def test_entropy_matches_reference_and_lies_within_bounds(rng):
    poses, weights = random_cloud(rng)
    position, orientation = entropy(poses, weights)
    ref = grid_entropy_reference(poses, weights, **GRID)
    assert position == pytest.approx(ref[0], abs=1e-9) and orientation == pytest.approx(ref[1], abs=1e-9)
    assert 0.0 <= position <= math.log2(104 * 74) and 0.0 <= orientation <= math.log2(36)


def test_entropy_extremes():
    one_cell = np.tile([[0.01, 0.01, 0.01]], (50, 1))
    assert entropy(one_cell, np.full(50, 1 / 50)) == (0.0, 0.0)
    # one particle per orientation bin, all equal weight: the maximum, log2(36)
    spread = np.column_stack([np.zeros(36), np.zeros(36), -math.pi + (np.arange(36) + 0.5) * 2 * math.pi / 36])
    assert entropy(spread, np.full(36, 1 / 36))[1] == pytest.approx(math.log2(36))
    # two cells of equal weight: one bit
    two = np.array([[0.05, 0.05, 0.0], [1.05, 0.05, 0.0]])
    assert entropy(two, np.array([0.5, 0.5]))[0] == pytest.approx(1.0)


@given(clouds, st.booleans())
def test_cluster_estimate_matches_reference(rng, with_previous):
    poses, weights = random_cloud(rng)
    previous = poses[int(np.argmax(weights))] if with_previous else None
    mean, cov, weight = estimate(poses, weights, previous)
    ref_mean, ref_cov, ref_weight = cluster_estimate_reference(poses, weights, -5.2, -3.7, 0.5, 21, 15, 8, 0.75,
                                                               0.8, 3, previous)
    np.testing.assert_allclose(mean, ref_mean, atol=1e-9)
    np.testing.assert_allclose(cov, ref_cov, atol=1e-9)
    assert weight == pytest.approx(ref_weight, abs=1e-9)


def test_two_mirror_modes_give_one_of_them_not_their_mean():
    rng = np.random.default_rng(0)
    mode = np.column_stack([rng.normal(2.0, 0.1, 300), rng.normal(1.0, 0.1, 300), rng.normal(3.0, 0.05, 300)])
    mirror = np.column_stack([-mode[:, 0], -mode[:, 1], np.angle(np.exp(1j * (mode[:, 2] + math.pi)))])
    poses = np.vstack([mode, mirror])
    weights = np.concatenate([np.full(300, 0.55 / 300), np.full(300, 0.45 / 300)])
    mean, cov, weight = estimate(poses, weights)
    assert np.hypot(mean[0] - 2.0, mean[1] - 1.0) < 0.05
    assert abs(math.remainder(mean[2] - 3.0, 2 * math.pi)) < 0.05
    assert weight == pytest.approx(0.55, abs=0.01)
    assert 0.005 < cov[0, 0] < 0.02 and np.allclose(cov, cov.T)


def test_heading_mean_across_the_wrap():
    """A cluster straddling ±π has its mean near π, not near 0."""
    rng = np.random.default_rng(1)
    theta = np.angle(np.exp(1j * (math.pi + rng.normal(0, 0.1, 400))))
    poses = np.column_stack([rng.normal(0, 0.05, 400), rng.normal(0, 0.05, 400), theta])
    mean, cov, _ = estimate(poses, np.full(400, 1 / 400))
    assert abs(math.remainder(mean[2] - math.pi, 2 * math.pi)) < 0.02
    assert cov[2, 2] == pytest.approx(0.01, rel=0.25)


def test_a_split_cluster_is_not_lost_to_a_clump_in_one_cell():
    """A wide true cluster straddling cell boundaries holds more weight than a clump filling one cell, but
    each of its cells holds less: seeded from the previous estimate, the estimate stays on the true one."""
    rng = np.random.default_rng(3)
    true = np.column_stack([rng.uniform(-0.3, 0.3, 700) - 0.2, rng.uniform(-0.3, 0.3, 700) - 0.2,
                            rng.normal(0.0, 0.02, 700)])              # spread over the cells around (-0.2, -0.2)
    clump = np.column_stack([rng.normal(2.85, 0.02, 300), rng.normal(1.85, 0.02, 300), rng.normal(0.0, 0.02, 300)])
    poses = np.vstack([true, clump])
    weights = np.full(1000, 1 / 1000)
    without_history, _, w1 = estimate(poses, weights)
    with_history, _, w2 = estimate(poses, weights, previous=(-0.2, -0.2, 0.0))
    assert np.hypot(*(without_history[:2] - (2.85, 1.85))) < 0.05 and w1 == pytest.approx(0.3, abs=0.01)
    assert np.hypot(*(with_history[:2] - (-0.2, -0.2))) < 0.05 and w2 == pytest.approx(0.7, abs=0.01)
