import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mcl.resampling import (SCHEMES, multinomial, multinomial_reference, stratified, stratified_reference,
                            systematic, systematic_reference)

weight_lists = st.lists(st.floats(0.0, 1.0), min_size=1, max_size=40).filter(lambda w: sum(w) > 1e-6).map(
    lambda w: np.array(w) / np.sum(w))


@pytest.mark.parametrize("scheme,reference", [(systematic, systematic_reference),
                                              (stratified, stratified_reference),
                                              (multinomial, multinomial_reference)])
@given(weights=weight_lists, seed=st.integers(0, 2**32 - 1), m=st.integers(1, 60))
def test_matches_numpy_reference(scheme, reference, weights, seed, m):
    assert np.array_equal(scheme(weights, m, np.random.default_rng(seed)),
                          reference(weights, m, np.random.default_rng(seed)))


@pytest.mark.parametrize("name", sorted(SCHEMES))
@given(weights=weight_lists, seed=st.integers(0, 2**32 - 1), m=st.integers(0, 60))
def test_valid_indices_and_count(name, weights, seed, m):
    ancestors = SCHEMES[name](weights, m, np.random.default_rng(seed))
    assert ancestors.shape == (m,) and ancestors.dtype == np.int64
    assert ((ancestors >= 0) & (ancestors < weights.shape[0])).all()
    assert (weights[ancestors] > 0).all()   # a particle of zero weight is never drawn


@pytest.mark.parametrize("name", sorted(SCHEMES))
def test_unbiased_offspring_counts(name):
    """E[offspring of i] = M·wᵢ: checked over many draws against the binomial-scale standard error."""
    rng = np.random.default_rng(7)
    weights = rng.dirichlet(np.full(12, 0.7))
    m, draws = 12, 20000
    counts = np.zeros(12)
    for _ in range(draws):
        counts += np.bincount(SCHEMES[name](weights, m, rng), minlength=12)
    mean = counts / draws
    standard_error = np.sqrt(m * weights * (1 - weights) / draws) + 1e-12
    assert (np.abs(mean - m * weights) < 5 * standard_error + 1e-9).all()


@given(weights=weight_lists, seed=st.integers(0, 2**32 - 1))
def test_systematic_keeps_every_particle_with_n_w_at_least_one(weights, seed):
    n = weights.shape[0]
    counts = np.bincount(systematic(weights, n, np.random.default_rng(seed)), minlength=n)
    kept = n * weights >= 1.0 + 1e-9
    assert (counts[kept] >= 1).all()
    # systematic: ⌊N·wᵢ⌋ or ⌈N·wᵢ⌉ copies, never further from N·wᵢ than one
    assert (np.abs(counts - n * weights) < 1 + 1e-9).all()


def test_residual_keeps_the_integer_parts():
    weights = np.array([0.5, 0.3, 0.15, 0.05])
    counts = np.bincount(SCHEMES["residual"](weights, 10, np.random.default_rng(0)), minlength=4)
    assert (counts >= np.floor(10 * weights)).all() and counts.sum() == 10


@pytest.mark.parametrize("bad", [np.array([]), np.ones((2, 2)) / 4])
def test_bad_weights(bad):
    with pytest.raises(ValueError, match="weights"):
        systematic(bad, 3, np.random.default_rng(0))


def test_bad_count():
    with pytest.raises(ValueError, match="M"):
        systematic(np.ones(3) / 3, -1, np.random.default_rng(0))
