import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mcl.reference import multinomial as multinomial_reference
from mcl.reference import stratified as stratified_reference
from mcl.reference import systematic as systematic_reference
from mcl.resampling import SCHEMES, multinomial, stratified, systematic
from numerics.reference import sincos as sincos_reference

weight_lists = (
    st.lists(st.floats(0.0, 1.0), min_size=1, max_size=40)
    .filter(lambda w: sum(w) > 1e-6)
    .map(lambda w: np.array(w) / np.sum(w))
)


@pytest.mark.parametrize(
    "scheme,reference",
    [(systematic, systematic_reference), (stratified, stratified_reference), (multinomial, multinomial_reference)],
)
@given(weights=weight_lists, seed=st.integers(0, 2**32 - 1), m=st.integers(1, 60))
def test_matches_numpy_reference(scheme, reference, weights, seed, m):
    assert np.array_equal(
        scheme(weights, m, np.random.default_rng(seed)), reference(weights, m, np.random.default_rng(seed))
    )


@pytest.mark.parametrize("name", sorted(SCHEMES))
@given(weights=weight_lists, seed=st.integers(0, 2**32 - 1), m=st.integers(0, 60))
def test_valid_indices_and_count(name, weights, seed, m):
    ancestors = SCHEMES[name](weights, m, np.random.default_rng(seed))
    assert ancestors.shape == (m,) and ancestors.dtype == np.int64
    assert ((ancestors >= 0) & (ancestors < weights.shape[0])).all()
    assert (weights[ancestors] > 0).all()  # a particle of zero weight is never drawn


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


# -- the filter's resampler: counting instead of merging, one pass with the copy and the roughening -------------
uniform_starts = st.one_of(st.just(0.0), st.floats(0.0, 1.0, exclude_max=True))


@given(weight_lists, uniform_starts, st.integers(0, 90), st.booleans())
def test_counting_equals_the_merge_bit_for_bit(weights, u0, m, equal):
    """The ancestors by counting (`systematic_counted`, what the filter's resampler runs, and
    `_systematic_in_place`, what `systematic` runs) against the merge loop (`_systematic`), including equal
    weights at u0 = 0, where points fall exactly on running totals."""
    from mcl.resampling import _systematic, _systematic_in_place, systematic_counted

    if equal:
        weights = np.full(weights.shape[0], 1.0 / weights.shape[0])
    counts = np.zeros(m + 1, dtype=np.int64)
    merged = _systematic(weights, m, u0, np.empty(m, dtype=np.int64))
    assert np.array_equal(systematic_counted(weights, m, u0, np.empty(m, dtype=np.int64), counts), merged)
    assert not counts.any()
    assert np.array_equal(_systematic_in_place(weights, m, u0, np.zeros(m, dtype=np.int64)), merged)


@given(weight_lists, st.integers(0, 2**32 - 1), st.integers(0, 60), st.booleans())
def test_resampling_with_jitter_equals_systematic_then_gather(weights, seed, m, known_trig):
    from mcl.resampling import gather_with_jitter, resample_with_jitter, systematic_with_jitter
    from numerics.random import bit_generator_handle

    n = weights.shape[0]
    rng = np.random.default_rng(seed)
    source = np.column_stack([rng.uniform(-5, 5, n), rng.uniform(-3, 3, n), rng.uniform(-np.pi, np.pi, n)])
    bounds = np.array([0.03, 0.02, 0.05])
    plain, drawn = np.random.default_rng(seed + 1), np.random.default_rng(seed + 1)
    expected = gather_with_jitter(source, systematic(weights, m, plain), bounds, plain.random((m, 3)), np.empty((m, 3)))
    trig = np.column_stack(sincos_reference(source[:, 2])) if known_trig else np.empty((0, 2))
    out, coordinates, counts = np.empty((m, 3)), np.empty((3, m)), np.zeros(m + 1, dtype=np.int64)
    resample_with_jitter(weights, m, source, bounds, out, trig, *bit_generator_handle(drawn), counts, coordinates)
    assert np.array_equal(out, expected) and np.array_equal(coordinates, expected.T) and not counts.any()
    assert plain.bit_generator.state == drawn.bit_generator.state
    again, generator = np.empty((m, 3)), np.random.default_rng(seed + 1)  # (a handle does not keep it)
    systematic_with_jitter(weights, m, source, bounds, again, trig, *bit_generator_handle(generator))
    assert np.array_equal(again, expected)


@given(weight_lists, st.integers(0, 2**32 - 1), st.integers(0, 60), st.integers(1, 5))
def test_motion_state_follows_the_resampled_particles(weights, seed, m, columns):
    """gather_offspring_rows moves the ancestors' rows (a stateful motion model's per-particle state) to the
    offspring `resample_with_jitter` placed with the same u0: those of `systematic`."""
    from mcl.resampling import gather_offspring_rows, resample_with_jitter
    from numerics.random import bit_generator_handle

    n = weights.shape[0]
    rows = np.random.default_rng(seed).standard_normal((max(n, m), columns))
    expected = rows.copy()
    expected[:m] = rows[systematic(weights, m, np.random.default_rng(seed))]
    counts, scratch = np.zeros(m + 1, dtype=np.int64), np.full((m, columns), np.nan)
    generator = np.random.default_rng(seed)  # (kept: a handle does not keep its generator alive)
    u0 = resample_with_jitter(
        weights,
        m,
        np.zeros((n, 3)),
        np.zeros(3),
        np.empty((m, 3)),
        np.empty((0, 2)),
        *bit_generator_handle(generator),
        counts,
        np.empty((3, 0)),
    )
    assert u0 == np.random.default_rng(seed).random()
    gather_offspring_rows(weights, m, u0, counts, rows, scratch)
    assert np.array_equal(rows, expected) and not counts.any()


@settings(max_examples=20)
@given(weight_lists, st.integers(0, 2**32 - 1))
def test_chunked_resampling(weights, seed):
    """On several threads: with one chunk, the serial resampler bit for bit; with small chunks the running
    totals are summed by chunk, and the offspring stay those of systematic resampling."""
    from mcl.resampling import resample_with_jitter, resample_with_jitter_chunked
    from numerics.random import bit_generator_handle

    n = m = weights.shape[0]
    rng = np.random.default_rng(seed)
    source = np.column_stack([rng.uniform(-5, 5, n), rng.uniform(-3, 3, n), rng.uniform(-np.pi, np.pi, n)])
    bounds = np.zeros(3)
    results = []
    for chunk in (0, 1 << 20, 4):
        out = np.empty((m, 3))
        generator = np.random.default_rng(seed)
        counts = np.zeros(m + 1, dtype=np.int64)
        if chunk:
            resample_with_jitter_chunked(
                weights,
                m,
                source,
                bounds,
                out,
                np.empty((0, 2)),
                *bit_generator_handle(generator),
                counts,
                np.empty((3, 0)),
                np.empty(3 * m),
                chunk,
            )
        else:
            resample_with_jitter(
                weights,
                m,
                source,
                bounds,
                out,
                np.empty((0, 2)),
                *bit_generator_handle(generator),
                counts,
                np.empty((3, 0)),
            )
        assert not counts.any()
        results.append(out)
    assert np.array_equal(results[0], results[1])
    # Zero roughening: each offspring is a copy; count them per source particle.
    offspring = (results[2][:, None, :] == source[None, :, :]).all(axis=2).sum(axis=0)
    assert offspring.sum() == m and (np.abs(offspring - m * weights) < 1 + 1e-9).all()


def test_systematic_into_a_kept_array():
    # out= gives the ancestors of a fresh call, in the caller's array, whatever it held; a wrong array is refused
    # before anything is drawn.
    rng = np.random.default_rng(4)
    weights = rng.random(300)
    weights /= weights.sum()
    kept = np.full(300, 77, dtype=np.int64)
    a, b = np.random.default_rng(9), np.random.default_rng(9)
    result = systematic(weights, 300, a, out=kept)
    assert result is kept and np.array_equal(kept, systematic(weights, 300, b))
    for wrong in (np.empty(299, dtype=np.int64), np.empty(300), np.empty((300, 1), dtype=np.int64)):
        state = a.bit_generator.state
        with pytest.raises(ValueError, match="out must be"):
            systematic(weights, 300, a, out=wrong)
        assert a.bit_generator.state == state
