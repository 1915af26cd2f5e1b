import math

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.estimate import cluster_estimate, grid_entropy
from mcl.reference import cluster_estimate as cluster_estimate_reference
from mcl.reference import grid_entropy as grid_entropy_reference

GRID = dict(x_min=-5.2, y_min=-3.7, cell_size=0.1, nx=104, ny=74, n_theta=36)


def entropy(poses, weights, **grid):
    g = dict(GRID, **grid)
    return grid_entropy(
        poses,
        weights,
        g["x_min"],
        g["y_min"],
        g["cell_size"],
        g["nx"],
        g["ny"],
        g["n_theta"],
        np.empty(g["nx"] * g["ny"]),
        np.empty(g["n_theta"]),
    )


def estimate(poses, weights, previous=None):
    mean, cov = np.empty(3), np.empty((3, 3))
    weight = cluster_estimate(
        poses,
        weights,
        (-5.2, -3.7, 0.5, 21, 15, 8),
        (0.75, 0.8, 3),
        np.empty(21 * 15 * 8),
        np.zeros(3) if previous is None else np.asarray(previous, float),
        previous is not None,
        mean,
        cov,
    )
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
    ref_mean, ref_cov, ref_weight = cluster_estimate_reference(
        poses, weights, -5.2, -3.7, 0.5, 21, 15, 8, 0.75, 0.8, 3, previous
    )
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
    true = np.column_stack(
        [rng.uniform(-0.3, 0.3, 700) - 0.2, rng.uniform(-0.3, 0.3, 700) - 0.2, rng.normal(0.0, 0.02, 700)]
    )  # spread over the cells around (-0.2, -0.2)
    clump = np.column_stack([rng.normal(2.85, 0.02, 300), rng.normal(1.85, 0.02, 300), rng.normal(0.0, 0.02, 300)])
    poses = np.vstack([true, clump])
    weights = np.full(1000, 1 / 1000)
    without_history, _, w1 = estimate(poses, weights)
    with_history, _, w2 = estimate(poses, weights, previous=(-0.2, -0.2, 0.0))
    assert np.hypot(*(without_history[:2] - (2.85, 1.85))) < 0.05 and w1 == pytest.approx(0.3, abs=0.01)
    assert np.hypot(*(with_history[:2] - (-0.2, -0.2))) < 0.05 and w2 == pytest.approx(0.7, abs=0.01)


# -- the filter's summary: shared histograms, bitmaps of the cells in use -------------------------------------------
SUMMARY = dict(
    x_min=-5.2,
    y_min=-3.7,
    cluster_cell=0.5,
    cluster_nx=21,
    cluster_ny=15,
    cluster_orientation_bins=8,
    cluster_radius=0.75,
    cluster_angle_radius=0.8,
    iterations=3,
    position_cell=0.1,
    entropy_nx=104,
    entropy_ny=74,
    orientation_bins=36,
)


@given(clouds, st.booleans(), st.booleans())
def test_summary_equals_cluster_estimate_and_grid_entropy_bit_for_bit(rng, with_previous, equal_weights):
    from mcl.estimate import summary_buffers, summary_entropy, summary_estimate, summary_fill, summary_grid

    grid = summary_grid(**SUMMARY)
    coordinates, histograms, bitmaps = summary_buffers(grid, 300)
    for _ in range(2):  # the buffers are reused: the second fill must forget the first
        poses, weights = random_cloud(rng)
        if equal_weights:
            weights = np.full(300, 1 / 300)
        previous = poses[int(np.argmax(weights))] if with_previous else None
        summary_fill(grid, poses, weights, coordinates, histograms, bitmaps)
        mean, cov = np.empty(3), np.empty((3, 3))
        weight = summary_estimate(
            grid,
            coordinates,
            weights,
            histograms,
            bitmaps,
            np.zeros(3) if previous is None else previous,
            previous is not None,
            mean,
            cov,
        )
        expected = estimate(poses, weights, previous)
        assert np.array_equal(mean, expected[0]) and np.array_equal(cov, expected[1]) and weight == expected[2]
        assert summary_entropy(grid, histograms, bitmaps) == entropy(poses, weights)


@settings(max_examples=12)
@given(clouds)
def test_fast_and_chunked_estimates_match_to_rounding(rng):
    from mcl.estimate import (
        summary_buffers,
        summary_estimate,
        summary_estimate_chunked,
        summary_estimate_fast,
        summary_fill,
        summary_fill_chunked,
        summary_grid,
    )

    grid = summary_grid(**SUMMARY)
    poses, weights = random_cloud(rng, n=700)
    coordinates, histograms, bitmaps = summary_buffers(grid, 700)
    summary_fill(grid, poses, weights, coordinates, histograms, bitmaps)
    expected = np.empty(3), np.empty((3, 3))
    weight = summary_estimate(grid, coordinates, weights, histograms, bitmaps, poses[0], True, *expected)
    mean, cov = np.empty(3), np.empty((3, 3))
    assert summary_estimate_fast(
        grid, coordinates, weights, histograms, bitmaps, poses[0], True, mean, cov
    ) == pytest.approx(weight, abs=1e-12)
    np.testing.assert_allclose(mean, expected[0], atol=1e-12)
    np.testing.assert_allclose(cov, expected[1], atol=1e-12)
    chunked_histograms, chunked_bitmaps = histograms.copy(), bitmaps.copy()
    local = np.zeros((numba.config.NUMBA_NUM_THREADS, histograms.shape[0]), dtype=np.int64)
    summary_fill_chunked(grid, poses, weights, coordinates, chunked_histograms, chunked_bitmaps, local, 64)
    np.testing.assert_allclose(chunked_histograms, histograms, rtol=1e-12, atol=1e-17)
    assert np.array_equal(chunked_bitmaps, bitmaps) and not local.any()
    for chunk in (1 << 20, 64):
        c_weight = summary_estimate_chunked(
            grid, coordinates, weights, histograms, bitmaps, poses[0], True, mean, cov, chunk
        )
        if chunk > 700:
            assert c_weight == weight and np.array_equal(mean, expected[0]) and np.array_equal(cov, expected[1])
        np.testing.assert_allclose(mean, expected[0], atol=1e-12)
        assert c_weight == pytest.approx(weight, abs=1e-12)


# -- the belief's density at a pose: the 95 % region and the log score ---------------------------------------
def _kde_log_density_reference(poses, weights, pose):
    """The normalised kernel density at a pose written out as a sum of Gaussians (Scott's bandwidths)."""
    weights = weights / weights.sum()
    n_effective = 1.0 / np.sum(weights**2)
    centre = np.array(
        [
            weights @ poses[:, 0],
            weights @ poses[:, 1],
            math.atan2(weights @ np.sin(poses[:, 2]), weights @ np.cos(poses[:, 2])),
        ]
    )
    residual = poses - centre
    residual[:, 2] = (residual[:, 2] + math.pi) % (2 * math.pi) - math.pi
    bandwidth = np.maximum(np.sqrt(weights @ residual**2) * n_effective ** (-1 / 7), 0.005)
    terms = []  # log of each particle's term, summed in log space (a far pose underflows exp)
    for p, w in zip(poses, weights):
        d = pose - p
        d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
        terms.append(
            math.log(w)
            - 0.5 * float(np.sum((d / bandwidth) ** 2))
            - math.log((2 * math.pi) ** 1.5 * float(np.prod(bandwidth)))
        )
    top = max(terms)
    return top + math.log(sum(math.exp(term - top) for term in terms))


@given(clouds)
@settings(max_examples=30, deadline=None)
def test_belief_log_density_is_the_normalised_kernel_density(rng):
    from mcl.estimate import belief_log_density

    n = int(rng.integers(1, 60))
    poses = np.column_stack(
        [
            rng.normal(0, rng.uniform(0.01, 1), n),
            rng.normal(0, rng.uniform(0.01, 1), n),
            rng.uniform(-math.pi, math.pi, n),
        ]
    )
    weights = rng.uniform(0.01, 1, n)
    pose = np.array([rng.normal(0, 0.5), rng.normal(0, 0.5), rng.uniform(-math.pi, math.pi)])
    expected = _kde_log_density_reference(poses, weights, pose)
    assert belief_log_density(poses, weights, pose) == pytest.approx(expected, rel=1e-9, abs=1e-9)


def test_belief_log_density_integrates_to_one_and_rewards_a_tight_cloud_that_holds_the_truth():
    from mcl.estimate import belief_log_density

    rng = np.random.default_rng(3)
    poses = np.column_stack([rng.normal(0, 0.2, 200), rng.normal(0, 0.1, 200), rng.normal(0, 0.1, 200)])
    weights = np.full(200, 1 / 200)
    xs, ys, ts = np.linspace(-1.2, 1.2, 49), np.linspace(-0.7, 0.7, 29), np.linspace(-0.7, 0.7, 29)
    cell = (xs[1] - xs[0]) * (ys[1] - ys[0]) * (ts[1] - ts[0])
    mass = sum(math.exp(belief_log_density(poses, weights, np.array([x, y, t]))) for x in xs for y in ys for t in ts)
    assert mass * cell == pytest.approx(1.0, abs=0.01)
    truth = np.zeros(3)
    tight, wide = belief_log_density(poses, weights, truth), belief_log_density(poses * 4, weights, truth)
    assert tight > wide + 3 * math.log(4) - 0.5  # four times as wide in x, y and θ: log 4 each, less
    missed = belief_log_density(poses + [1.0, 0.0, 0.0], weights, truth)  # tight, but a metre off
    assert missed < wide
    far = belief_log_density(poses, weights, np.array([1e3, -1e3, 3.0]))  # far: very low, never -inf or NaN
    assert math.isfinite(far) and far < -1e6


@pytest.mark.parametrize("n", [30, 100, 200])
def test_credible_region_holds_the_truth_about_as_often_as_its_mass(n):
    from mcl.estimate import credible_region_contains

    rng = np.random.default_rng(5)
    inside = []
    for _ in range(300):
        poses = np.column_stack([rng.normal(0, 0.3, n), rng.normal(0, 0.2, n), rng.normal(0, 0.2, n)])
        truth = np.array([rng.normal(0, 0.3), rng.normal(0, 0.2), rng.normal(0, 0.2)])
        inside.append(credible_region_contains(poses, np.ones(n), truth))
    assert 0.91 <= np.mean(inside) <= 0.98  # 95 %, to the sampling error of 300 draws


def test_credible_region_of_a_single_heavy_particle_is_its_kernel():
    from mcl.estimate import credible_region_contains

    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    weights = np.array([1.0, 0.0, 0.0])
    assert credible_region_contains(poses, weights, np.zeros(3))
    assert not credible_region_contains(poses, weights, np.array([0.5, 0.5, 0.0]))
    assert credible_region_contains(poses[:1], np.ones(1), np.zeros(3))


@pytest.mark.parametrize(
    "poses, weights, pose, match",
    [
        (np.zeros((3, 2)), np.ones(3), np.zeros(3), "expected"),
        (np.zeros((3, 3)), np.ones(2), np.zeros(3), "expected"),
        (np.zeros((3, 3)), np.ones(3), np.zeros(2), "expected"),
        (np.zeros((3, 3)), np.array([1.0, -1.0, 1.0]), np.zeros(3), "weights"),
        (np.zeros((3, 3)), np.zeros(3), np.zeros(3), "weights"),
        (np.zeros((3, 3)), np.ones(3), np.array([0.0, math.nan, 0.0]), "finite"),
        (np.array([[0.0, 0.0, 0.0], [math.inf, 0.0, 0.0], [0.0, 0.0, 0.0]]), np.ones(3), np.zeros(3), "finite"),
        (np.zeros((3, 3)), np.array([1.0, math.nan, 1.0]), np.zeros(3), "weights"),
    ],
)
def test_belief_log_density_refuses_bad_input_and_leaves_it_unchanged(poses, weights, pose, match):
    from mcl.estimate import belief_log_density, credible_region_contains

    before = (poses.copy(), weights.copy(), pose.copy())
    with pytest.raises(ValueError, match=match):
        belief_log_density(poses, weights, pose)
    with pytest.raises(ValueError, match=match):
        credible_region_contains(poses, weights, pose)
    with pytest.raises(ValueError, match="min_bandwidth"):
        belief_log_density(np.zeros((3, 3)), np.ones(3), np.zeros(3), min_bandwidth=(0.01, 0.0, 0.01))
    for a, b in zip(before, (poses, weights, pose)):
        np.testing.assert_array_equal(a, b)


def test_the_region_with_its_own_kernel_left_in_holds_less_than_its_mass():
    from mcl.estimate import credible_region_contains

    rng = np.random.default_rng(7)
    inside = {True: 0, False: 0}
    for _ in range(200):
        poses = rng.standard_normal((50, 3)) * [0.3, 0.2, 0.2]
        truth = rng.standard_normal(3) * [0.3, 0.2, 0.2]
        for loo in inside:
            inside[loo] += credible_region_contains(poses, np.ones(50), truth, leave_one_out=loo)
    assert inside[False] < 0.85 * 200 < inside[True]
