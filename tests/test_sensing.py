import math

import numba
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from field import LandmarkType, spl
from field.angles import wrap_angles
from field.checks import LARGEST_SIGMA, SMALLEST_SIGMA
from sensing import LandmarkObservation, LandmarkSensorModel, Observations
from sensing.landmarks import range_noise_sigma
from sensing.observations import MAX_RANGE

FIELD = spl()


def observe(pose, kind, field=FIELD, index=0):
    """The exact range and bearing of landmark `index` of `kind` from `pose`."""
    target = field.landmarks_of(kind)[index]
    d = target - np.asarray(pose[:2])
    return math.hypot(*d), math.atan2(d[1], d[0]) - pose[2]


# -- observations ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(kind="goalpost", range=float("nan"), bearing=0.0), "range"),
        (dict(kind="goalpost", range=1.0, bearing=float("inf")), "bearing"),
        (dict(kind="goalpost", range=-0.5, bearing=0.0), "range"),
        (dict(kind="corner_flag", range=1.0, bearing=0.0), "corner_flag"),
        (dict(kind=17, range=1.0, bearing=0.0), "17"),
        (dict(kind="goalpost", range=1.0, bearing=0.0, range_sigma=0.0), "range_sigma"),
        (dict(kind="goalpost", range=1.0, bearing=0.0, bearing_sigma=float("nan")), "bearing_sigma"),
    ],
)
def test_bad_observation_is_rejected_with_its_field(kwargs, match):
    with pytest.raises(ValueError, match=match):
        LandmarkObservation(**kwargs)


def test_bad_batches_are_rejected():
    with pytest.raises(ValueError, match="ranges"):
        Observations.from_arrays(["goalpost"], [float("nan")], [0.0])
    with pytest.raises(ValueError, match="ranges"):
        Observations.from_arrays(["goalpost", "goalpost"], [1.0, -1.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="entries"):
        Observations.from_arrays(["goalpost", "goalpost"], [1.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="not a landmark type"):
        Observations(np.array([9]), [1.0], [0.0], [np.nan], [np.nan])
    with pytest.raises(ValueError, match="LandmarkObservation"):
        Observations.from_list([("goalpost", 1.0, 0.0)])


@pytest.mark.parametrize(
    "kinds",
    [np.array([0.0, 2.0]), np.array([0.0, 1.7]), [0, 1.5], np.array([True, False])],
    ids=["integral floats", "float array", "list with a float", "booleans"],
)
def test_kinds_that_are_not_integers_are_refused(kinds):
    # a cast to int64 would truncate 1.7 to 1 (another landmark type): the constructor refuses instead
    given = np.array(kinds, copy=True) if isinstance(kinds, np.ndarray) else list(kinds)
    with pytest.raises(
        TypeError, match=r"^kinds has dtype (float64|bool): it must hold integer landmark type"
    ) as error:
        Observations(kinds, [1.0, 2.0], [0.0, 0.1], [np.nan, np.nan], [np.nan, np.nan])
    assert "\n" not in str(error.value)
    # the refused call changed nothing it was given
    if isinstance(kinds, np.ndarray):
        assert kinds.dtype == given.dtype and kinds.flags.writeable
        np.testing.assert_array_equal(kinds, given)
    else:
        assert kinds == given


def test_kinds_as_integers_members_or_an_empty_array_are_taken():
    members = Observations(
        [LandmarkType.GOALPOST, LandmarkType.T_CROSSING], [1.0, 2.0], [0.0, 0.1], [np.nan, np.nan], [np.nan, np.nan]
    )
    values = Observations(np.array([0, 2], dtype=np.int32), [1.0, 2.0], [0.0, 0.1], [np.nan, np.nan], [np.nan, np.nan])
    assert members.kinds.tolist() == values.kinds.tolist() == [0, 2] and values.kinds.dtype == np.int64
    assert len(Observations(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0))) == 0


ENTRIES = st.sampled_from([0.0, 1.5, -0.0, -2.0, 1e-300, float("nan"), float("inf"), -float("inf")])


@given(
    st.integers(0, 6).flatmap(
        lambda m: st.tuples(
            st.lists(st.integers(-2, 8), min_size=m, max_size=m), *(st.lists(ENTRIES, min_size=m, max_size=m),) * 4
        )
    )
)
def test_batch_checks_match_their_numpy_twin(columns):
    """`first_invalid` (compiled, one pass per check) names the check and the detection its numpy twin
    names, and `Observations` raises for that detection, or accepts the batch when both find nothing."""
    from sensing.observations import IS_KIND, first_invalid
    from sensing.reference import first_invalid as first_invalid_reference

    kinds, ranges, bearings, range_sigmas, bearing_sigmas = (
        np.array(columns[0], dtype=np.int64),
        *(np.array(c, dtype=np.float64) for c in columns[1:]),
    )
    found = first_invalid(kinds, ranges, bearings, range_sigmas, bearing_sigmas, IS_KIND)
    assert found == first_invalid_reference(kinds, ranges, bearings, range_sigmas, bearing_sigmas, IS_KIND)
    if found[0] < 0:
        batch = Observations(kinds, ranges, bearings, range_sigmas, bearing_sigmas)
        assert np.array_equal(batch.ranges, ranges) and np.array_equal(batch.kinds, kinds)
    else:
        name = ("kinds", "ranges", "bearings", "ranges", "range_sigmas", "bearing_sigmas")[found[0]]
        with pytest.raises(ValueError, match=rf"^{name}\[{found[1]}\] = "):
            Observations(kinds, ranges, bearings, range_sigmas, bearing_sigmas)


def test_kinds_given_as_values_names_or_members_make_the_same_batch():
    names = ["goalpost", "T_crossing", "center_mark"]
    members = [LandmarkType.GOALPOST, LandmarkType.T_CROSSING, LandmarkType.CENTER_MARK]
    values = np.array([0, 2, 5])
    for kinds in (names, members, values, values.astype(np.int32), values.astype(np.uint8), [0, 2, 5]):
        assert np.array_equal(Observations.from_arrays(kinds, [1.0] * 3, [0.0] * 3).kinds, values)
    with pytest.raises(ValueError, match="landmark type 9 is unknown"):
        Observations.from_arrays(np.array([0, 9]), [1.0, 1.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="must be a LandmarkType"):
        Observations.from_arrays(np.array([True]), [1.0], [0.0])


def test_every_path_taking_a_kind_string_accepts_the_aliases():
    aliases = ["post", "L", "t", "X-crossing", "penalty", "centre"]
    values = np.arange(6)
    assert np.array_equal(Observations.from_arrays(aliases, [1.0] * 6, [0.0] * 6).kinds, values)
    assert np.array_equal(Observations.from_arrays(np.array(aliases), [1.0] * 6, [0.0] * 6).kinds, values)
    batch = Observations.from_list([LandmarkObservation(alias, 1.0, 0.0) for alias in aliases])
    assert np.array_equal(batch.kinds, values)
    assert LandmarkObservation("centre mark", 1.0, 0.0).kind is LandmarkType.CENTER_MARK
    with pytest.raises(ValueError, match=r"kind = 'corner'.*aliases: L \(L_CROSSING\)"):
        LandmarkObservation("corner", 1.0, 0.0)
    with pytest.raises(ValueError, match=r"aliases: .*post \(GOALPOST\)"):
        Observations.from_arrays(["post", "corner"], [1.0, 1.0], [0.0, 0.0])


def test_batches_are_read_only_and_convert_to_points():
    obs = Observations.from_list([LandmarkObservation(LandmarkType.T_CROSSING, 2.0, math.pi / 2)])
    assert not obs.ranges.flags.writeable
    np.testing.assert_allclose(obs.points(), [[0.0, 2.0]], atol=1e-12)
    assert len(Observations.coerce(None)) == 0


def test_the_empty_batch_is_made_once_and_cannot_change():
    empty = Observations.empty()
    assert Observations.coerce(None) is empty and len(Observations.coerce([])) == 0 and empty.is_empty
    assert Observations.empty() is empty
    for name in ("kinds", "ranges", "bearings", "range_sigmas", "bearing_sigmas", "line_points"):
        array = getattr(empty, name)
        assert array.size == 0 and not array.flags.writeable
        with pytest.raises(ValueError):
            array.resize(4)
    with pytest.raises(AttributeError):
        empty.ranges = np.ones(2)

    class Tagged(Observations):
        pass

    assert type(Tagged.empty()) is Tagged and Tagged.empty() is Tagged.empty() and Tagged.empty() is not empty


SIGMAS = st.one_of(st.none(), st.floats(0.01, 2.0))


@given(
    st.lists(
        st.tuples(st.sampled_from(list(LandmarkType)), st.floats(0.0, 12.0), st.floats(-3.2, 3.2), SIGMAS, SIGMAS),
        max_size=12,
    ),
    st.one_of(st.none(), st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5)), max_size=4)),
)
def test_a_list_makes_the_batch_its_arrays_make(detections, line_points):
    """`from_list` (which adopts the two arrays it builds) gives the batch `from_arrays` gives: the same
    values, dtypes, contiguous read-only arrays, and nothing writable behind them."""
    batch = Observations.from_list([LandmarkObservation(*d) for d in detections], line_points=line_points)
    columns = list(zip(*detections)) or [[]] * 5
    expected = Observations.from_arrays(
        list(columns[0]),
        list(columns[1]),
        list(columns[2]),
        [np.nan if v is None else v for v in columns[3]],
        [np.nan if v is None else v for v in columns[4]],
        line_points=line_points,
    )
    for name in ("kinds", "ranges", "bearings", "range_sigmas", "bearing_sigmas", "line_points"):
        got, want = getattr(batch, name), getattr(expected, name)
        assert got.dtype == want.dtype and got.shape == want.shape
        assert np.array_equal(got, want, equal_nan=True)
        for array in (got, want):
            assert array.flags.c_contiguous and not array.flags.writeable
            assert array.base is None or not array.base.flags.writeable
    assert len(batch) == len(detections)


def test_a_list_is_checked_again_when_batched():
    """A detection changed behind its frozen dataclass's back is still rejected by `from_list`."""
    detection = LandmarkObservation(LandmarkType.GOALPOST, 2.0, 0.1)
    object.__setattr__(detection, "range", -1.0)
    with pytest.raises(ValueError, match=r"^ranges\[1\] = .*-1\.0\)? must be >= 0$"):
        Observations.from_list([LandmarkObservation(LandmarkType.GOALPOST, 1.0, 0.0), detection])


def test_type_absent_from_the_field_is_an_error(spl_field):
    model = LandmarkSensorModel(spl_field)
    model.check(Observations.from_arrays(["x_crossing"], [1.0], [0.0]))
    # A sensor model over a field whose table lacks a type must say so (simulate with an offsets hole).
    offsets = model._offsets.copy()
    offsets[LandmarkType.X_CROSSING + 1 :] -= 2
    object.__setattr__(model, "_offsets", offsets)
    with pytest.raises(ValueError, match="X_CROSSING"):
        model.check(Observations.from_arrays(["x_crossing"], [1.0], [0.0]))


@pytest.mark.parametrize(
    "name,value",
    [
        ("range_noise_floor", 0.0),
        ("bearing_sigma", -1.0),
        ("outlier_weight", float("nan")),
        ("bearing_model", "cosine"),
        ("mixture", "product"),
    ],
)
def test_bad_sensor_parameters(name, value):
    with pytest.raises(ValueError, match=name):
        LandmarkSensorModel(FIELD, **{name: value})


# -- likelihood -----------------------------------------------------------------------------------------------
kinds = st.sampled_from([t.name for t in LandmarkType])
detection = st.tuples(
    kinds, st.floats(0.0, 8.0), st.floats(-math.pi, math.pi), st.one_of(st.none(), st.floats(0.01, 1.0))
)


@given(st.lists(detection, min_size=1, max_size=12), st.sampled_from(["von_mises", "exact"]), st.integers(0, 2**32 - 1))
def test_kernel_matches_numpy_reference(detections, bearing_model, seed):
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(-5, 5, 50), rng.uniform(-3.5, 3.5, 50), rng.uniform(-math.pi, math.pi, 50)])
    obs = Observations.from_arrays(
        [d[0] for d in detections],
        [d[1] for d in detections],
        [d[2] for d in detections],
        [np.nan if d[3] is None else d[3] for d in detections],
    )
    model = LandmarkSensorModel(FIELD, bearing_model=bearing_model)
    fast = model.log_likelihood(poses, obs)
    slow = model.numpy_twin().log_likelihood(poses, obs)
    assert np.isfinite(fast).all()
    np.testing.assert_allclose(fast, slow, rtol=1e-9, atol=1e-9)


def test_true_pose_scores_best_and_perfect_match_scores_near_zero():
    pose = np.array([1.0, -0.5, 0.4])
    detections = [
        observe(pose, kind, index=i)
        for kind, i in (("goalpost", 3), ("penalty_mark", 1), ("x_crossing", 0), ("l_crossing", 7))
    ]
    obs = Observations.from_arrays(
        ["goalpost", "penalty_mark", "x_crossing", "l_crossing"], [d[0] for d in detections], [d[1] for d in detections]
    )
    model = LandmarkSensorModel(FIELD)
    rng = np.random.default_rng(0)
    others = pose + np.column_stack([rng.normal(0, 0.5, 200), rng.normal(0, 0.5, 200), rng.normal(0, 0.3, 200)])
    scores = model.log_likelihood(np.vstack([pose, others]), obs)
    assert scores[0] == pytest.approx(0.0, abs=1e-9)  # max-mixture: a perfect match scores 0
    assert scores[0] >= scores[1:].max()
    summed = LandmarkSensorModel(FIELD, mixture="sum").log_likelihood(pose[None], obs)
    assert summed[0] == pytest.approx(4 * math.log1p(model.outlier_weight), abs=1e-9)


def test_ambiguous_type_associates_with_the_best_candidate():
    """Seen from the mirror pose, a goalpost detection matches a different post equally well."""
    pose = np.array([2.0, 1.0, 0.3])
    r, b = observe(pose, "goalpost", index=2)
    obs = Observations.from_arrays(["goalpost"], [r], [b])
    mirrored = FIELD.mirror_poses(pose[None, :])
    model = LandmarkSensorModel(FIELD)
    scores = model.log_likelihood(np.vstack([pose, mirrored]), obs)
    assert scores[0] == pytest.approx(scores[1], abs=1e-9)


@given(st.floats(-0.2, 0.2), st.floats(0.02, 0.2))
def test_von_mises_matches_exact_for_small_bearing_errors(error, sigma):
    pose = np.array([[0.5, 0.5, 0.0]])
    r, b = observe(pose[0], "penalty_mark", index=1)
    obs = Observations.from_arrays(["penalty_mark"], [r], [b + error], bearing_sigmas=[sigma])
    exact = LandmarkSensorModel(FIELD, bearing_model="exact", outlier_weight=1e-300).log_likelihood(pose, obs)
    von_mises = LandmarkSensorModel(FIELD, outlier_weight=1e-300).log_likelihood(pose, obs)
    # κ(cos e − 1) = −e²/(2σ²) + e⁴/(24σ²) − ...
    assert von_mises[0] == pytest.approx(exact[0], abs=error**4 / (24 * sigma**2) + 1e-9)


def test_outlier_floor_bounds_the_cost_of_a_false_positive():
    model = LandmarkSensorModel(FIELD)
    poses = np.array([[0.0, 0.0, 0.0], [3.0, 2.0, 1.0]])
    far_off = Observations.from_arrays(["goalpost"], [0.1], [math.pi])  # nothing explains this
    scores = model.log_likelihood(poses, far_off)
    assert (scores >= math.log(model.outlier_weight) - 1e-12).all()


@given(st.integers(0, 2**32 - 1), st.sampled_from(["von_mises", "exact"]))
def test_max_and_sum_mixtures_differ_by_at_most_log2(seed, bearing_model):
    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(-5, 5, 40), rng.uniform(-3, 3, 40), rng.uniform(-3, 3, 40)])
    obs = Observations.from_arrays(
        ["goalpost", "t_crossing", "l_crossing"], rng.uniform(0, 6, 3), rng.uniform(-3, 3, 3)
    )
    by_max = LandmarkSensorModel(FIELD, bearing_model=bearing_model).log_likelihood(poses, obs)
    by_sum = LandmarkSensorModel(FIELD, bearing_model=bearing_model, mixture="sum").log_likelihood(poses, obs)
    np.testing.assert_allclose(
        by_sum,
        LandmarkSensorModel(FIELD, bearing_model=bearing_model, mixture="sum").numpy_twin().log_likelihood(poses, obs),
        atol=1e-9,
    )
    assert (by_sum >= by_max - 1e-12).all() and (by_sum - by_max <= 3 * math.log(2) + 1e-12).all()


def test_range_noise_grows_with_range():
    model = LandmarkSensorModel(FIELD)
    sigmas = model.range_sigma(np.array([0.5, 2.0, 5.0]))
    assert np.all(np.diff(sigmas) > 0)


# -- the range noise law σ_r = floor + linear·r + growth·r² -------------------------------------------------------
@pytest.mark.parametrize(
    "floor,linear,growth", [(0.05, 0.0, 0.02), (0.05, 0.03, 0.0), (0.1, 0.0, 0.0), (0.02, 0.01, 0.005)]
)
def test_range_sigma_is_floor_plus_linear_plus_quadratic_term(floor, linear, growth):
    model = LandmarkSensorModel(FIELD, range_noise_floor=floor, range_noise_linear=linear, range_noise_growth=growth)
    for r in (0.0, 0.5, 2.0, 7.5):
        assert model.range_sigma(np.array([r]))[0] == pytest.approx(floor + linear * r + growth * r * r, rel=1e-15)
    assert np.array_equal(model.range_sigma(np.array([0.0, 3.0])) > floor, [False, linear + growth > 0])


def test_the_default_law_is_the_quadratic_one_and_passes_the_kernels_the_pair():
    """Without a linear term the kernels get the pair (0, growth), which scores as floor + growth·r², bit for bit
    (see the next test): models with and without a linear term share one compiled specialization."""
    model = LandmarkSensorModel(FIELD)
    assert model.range_noise_linear == 0.0
    assert model.fused_likelihood().params[3] == (0.0, 0.02)
    r = np.array([0.5, 2.0, 5.0])
    assert np.array_equal(model.range_sigma(r), 0.05 + 0.02 * r * r)
    linear = LandmarkSensorModel(FIELD, range_noise_linear=0.04)
    assert linear.fused_likelihood().params[3] == (0.04, 0.02)


@numba.njit
def _compiled_sigma(r, floor, growth):
    return range_noise_sigma(r, floor, growth)


@given(
    st.floats(0.0, MAX_RANGE),
    st.floats(SMALLEST_SIGMA, LARGEST_SIGMA),
    st.floats(0.0, LARGEST_SIGMA),
)
def test_a_zero_linear_term_leaves_the_quadratic_law_bit_for_bit(r, floor, growth):
    """floor + 0·r + c·r² is floor + c·r² to the last bit for every accepted range and noise (b·r is +0 for a
    finite range, and floor + 0 is floor), in Python, numpy and compiled code."""
    quadratic = range_noise_sigma(r, floor, growth)
    assert range_noise_sigma(r, floor, (0.0, growth)) == quadratic
    assert _compiled_sigma(r, floor, (0.0, growth)) == _compiled_sigma(r, floor, growth) == quadratic
    ranges = np.array([r, 0.0, MAX_RANGE])
    assert np.array_equal(range_noise_sigma(ranges, floor, (0.0, growth)), range_noise_sigma(ranges, floor, growth))


@pytest.mark.parametrize("value", [-0.01, float("nan"), float("inf"), True, "0.1", None])
def test_a_bad_linear_range_noise_is_rejected(value):
    with pytest.raises(ValueError, match=r"range_noise_linear = "):
        LandmarkSensorModel(FIELD, range_noise_linear=value)


@pytest.mark.parametrize("bearing_model", ["von_mises", "exact"])
@pytest.mark.parametrize("mixture", ["max", "sum"])
def test_a_linear_law_scores_the_hand_computed_gaussian(bearing_model, mixture):
    """One goalpost seen at its bearing and 0.3 m too far: every path scores -½((r - d)/σ_r)² with
    σ_r = floor + linear·r + growth·r² at the measured range r."""
    from sensing.landmarks import prepare_detections, von_mises_log_likelihood

    floor, linear, growth = 0.05, 0.08, 0.01
    outlier = 1e-30  # a floor far below the score
    model = LandmarkSensorModel(
        FIELD,
        range_noise_floor=floor,
        range_noise_linear=linear,
        range_noise_growth=growth,
        bearing_model=bearing_model,
        mixture=mixture,
        outlier_weight=outlier,
    )
    post = FIELD.landmarks_of("goalpost")[0]
    poses = np.array([[post[0] + 2.0, post[1], math.pi], [post[0] + 1.5, post[1] + 0.2, math.pi - 0.3]])
    d, b = observe(poses[0], "goalpost", index=0)
    r = d + 0.3
    sigma = floor + linear * r + growth * r * r
    expected = -0.5 * ((r - d) / sigma) ** 2
    if mixture == "sum":
        expected = math.log(math.exp(expected) + outlier)
    obs = Observations.from_arrays(["goalpost"], [r], [b])
    scores = model.log_likelihood(poses, obs)
    assert scores[0] == pytest.approx(expected, rel=1e-9, abs=1e-12)
    assert model.numpy_twin().log_likelihood(poses, obs)[0] == pytest.approx(expected, rel=1e-9, abs=1e-12)
    np.testing.assert_allclose(scores, model.numpy_twin().log_likelihood(poses, obs), rtol=1e-9, atol=1e-12)
    # The same law with only the quadratic term would score otherwise: the linear term is used.
    quadratic = LandmarkSensorModel(
        FIELD,
        range_noise_floor=floor,
        range_noise_growth=growth,
        bearing_model=bearing_model,
        mixture=mixture,
        outlier_weight=outlier,
    )
    assert abs(quadratic.log_likelihood(poses, obs)[0] - expected) > 1.0
    if mixture == "max" and bearing_model == "von_mises":
        table, offsets, range_floor, range_growth, bearing_sigma, log_outlier, _ = model.fused_likelihood().params
        prepared, groups, _ = prepare_detections(
            obs.kinds,
            obs.ranges,
            obs.bearings,
            obs.range_sigmas,
            obs.bearing_sigmas,
            offsets,
            range_floor,
            range_growth,
            bearing_sigma,
        )
        assert prepared[0, 1] == -0.5 / (sigma * sigma)
        out = von_mises_log_likelihood(
            poses, table, offsets, prepared, groups, log_outlier, np.empty(2), np.empty((0, 2))
        )
        assert np.array_equal(out, scores)


@given(
    st.lists(
        st.tuples(kinds, st.floats(0.0, 8.0), st.floats(-3.2, 3.2), st.one_of(st.none(), st.floats(0.01, 1.0))),
        max_size=10,
    ),
    st.integers(0, 2**32 - 1),
    st.floats(0.01, 0.3),
    st.floats(0.0, 0.2),
    st.floats(0.0, 0.05),
)
def test_kernels_with_a_linear_law_equal_their_twins(detections, seed, floor, linear, growth):
    """With a linear term: the block kernel equals the particle-by-particle kernel bit for bit, both equal the
    numpy reference to rounding (exact bearing term too), and sensor resetting equals its numpy twin bit for
    bit."""
    from sensing.landmarks import detection_batch, landmark_log_likelihood

    rng = np.random.default_rng(seed)
    n = 150
    poses = np.column_stack([rng.uniform(-6, 6, n), rng.uniform(-4, 4, n), rng.uniform(-math.pi, math.pi, n)])
    obs = Observations.from_arrays(
        [d[0] for d in detections],
        [d[1] for d in detections],
        [d[2] for d in detections],
        [np.nan if d[3] is None else d[3] for d in detections],
    )
    for bearing_model in ("von_mises", "exact"):
        model = LandmarkSensorModel(
            FIELD,
            range_noise_floor=floor,
            range_noise_linear=linear,
            range_noise_growth=growth,
            bearing_model=bearing_model,
        )
        scores = model.log_likelihood(poses, obs)
        np.testing.assert_allclose(scores, model.numpy_twin().log_likelihood(poses, obs), rtol=1e-9, atol=1e-9)
        if bearing_model == "von_mises":
            general = np.empty(n)
            landmark_log_likelihood(
                poses,
                model.landmark_group,
                detection_batch(obs),
                (floor, model.fused_likelihood().params[3], model.bearing_sigma),
                False,
                False,
                math.log(model.outlier_weight),
                general,
            )
            assert np.array_equal(scores, general)
    if len(obs):
        compiled_rng, plain_rng = np.random.default_rng(seed), np.random.default_rng(seed)
        compiled = model.sample_poses(obs, 40, compiled_rng, heading=0.3)
        plain = model.numpy_twin().sample_poses(obs, 40, plain_rng, heading=0.3)
        assert np.array_equal(compiled, plain)


def test_no_observations_give_zero():
    model = LandmarkSensorModel(FIELD)
    assert np.array_equal(model.log_likelihood(np.zeros((3, 3)), Observations.empty()), np.zeros(3))


# -- sensor resetting -----------------------------------------------------------------------------------------
def test_sampled_poses_explain_the_detection():
    pose = np.array([-1.0, 1.5, 2.0])
    r, b = observe(pose, "penalty_mark", index=0)
    obs = Observations.from_arrays(["penalty_mark"], [r], [b], [1e-6], [1e-6])
    model = LandmarkSensorModel(FIELD)
    samples = model.sample_poses(obs, 200, np.random.default_rng(0), heading=pose[2], heading_sigma=1e-6)
    # Two penalty marks: every sample is at the true pose or at the pose that sees the other mark there.
    near_truth = np.hypot(*(samples[:, :2] - pose[:2]).T) < 1e-3
    assert near_truth.any() and (~near_truth).any()
    scored_with_model_noise = Observations.from_arrays(["penalty_mark"], [r], [b])
    assert np.allclose(model.log_likelihood(samples, scored_with_model_noise), 0.0, atol=1e-3)
    assert (np.abs(wrap_angles(samples[:, 2] - pose[2])) < 1e-3).all()
    assert model.sample_poses(Observations.empty(), 5, np.random.default_rng(0)).shape == (0, 3)


@given(
    n=st.integers(0, 300),
    heading=st.one_of(st.none(), st.floats(-10.0, 10.0)),
    heading_sigma=st.floats(0.0, 2.0),
    own_sigmas=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_sampled_poses_equal_their_numpy_twin_bit_for_bit(n, heading, heading_sigma, own_sigmas, seed):
    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 12))
    kinds = [("goalpost", "t_crossing", "l_crossing", "penalty_mark", "center_mark")[k] for k in rng.integers(0, 5, m)]
    sigmas = np.where(rng.random(m) < 0.5, np.nan, rng.uniform(0.01, 0.5, m)) if own_sigmas else None
    obs = Observations.from_arrays(kinds, rng.uniform(0.0, 8.0, m), rng.uniform(-3.2, 3.2, m), sigmas, sigmas)
    model = LandmarkSensorModel(FIELD)
    compiled_rng, plain_rng = np.random.default_rng(seed), np.random.default_rng(seed)
    compiled = model.sample_poses(obs, n, compiled_rng, heading=heading, heading_sigma=heading_sigma)
    plain = model.numpy_twin().sample_poses(obs, n, plain_rng, heading=heading, heading_sigma=heading_sigma)
    assert compiled.shape == (n, 3) and np.array_equal(compiled, plain)
    assert compiled_rng.bit_generator.state == plain_rng.bit_generator.state
    assert np.isfinite(compiled).all() and (np.abs(compiled[:, 2]) <= math.pi).all()


def test_sampling_poses_for_a_type_the_field_lacks_raises_and_draws_nothing():
    model = LandmarkSensorModel(FIELD)
    offsets = model._offsets.copy()  # a table without X crossings, as above
    offsets[LandmarkType.X_CROSSING + 1 :] -= 2
    object.__setattr__(model, "_offsets", offsets)
    obs = Observations.from_arrays(["goalpost", "x_crossing"], [2.0, 3.0], [0.1, 0.2])
    rng = np.random.default_rng(0)
    before = rng.bit_generator.state
    with pytest.raises(ValueError, match="observation 1"):
        model.sample_poses(obs, 5, rng)
    assert rng.bit_generator.state == before


# -- the block kernel of the default model ------------------------------------------------------------------------
@given(
    st.lists(detection, min_size=0, max_size=14),
    st.integers(1, 300),
    st.integers(0, 2**32 - 1),
    st.floats(0.01, 0.3),
    st.floats(0.0, 0.1),
    st.floats(0.005, 0.5),
    st.floats(1e-4, 0.9),
)
def test_block_kernel_equals_the_particle_by_particle_kernel_bit_for_bit(
    detections, n, seed, floor, growth, bearing_sigma, outlier_weight
):
    """`von_mises_log_likelihood` (what `log_likelihood` runs for the default model) against the general kernel
    `landmark_log_likelihood`, which computes every variant particle by particle."""
    from sensing.landmarks import detection_batch, landmark_log_likelihood

    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(-6, 6, n), rng.uniform(-4, 4, n), rng.uniform(-math.pi, math.pi, n)])
    poses[: min(n, 4), :2] = FIELD.landmarks_of("goalpost")[: min(n, 4)]  # on a candidate: distance 0
    obs = Observations.from_arrays(
        [d[0] for d in detections],
        [d[1] for d in detections],
        [d[2] for d in detections],
        [np.nan if d[3] is None else d[3] for d in detections],
        rng.choice([np.nan, 0.1], len(detections)),
    )
    model = LandmarkSensorModel(
        FIELD,
        range_noise_floor=floor,
        range_noise_growth=growth,
        bearing_sigma=bearing_sigma,
        outlier_weight=outlier_weight,
    )
    general = np.empty(n)
    landmark_log_likelihood(
        poses,
        model.landmark_group,
        detection_batch(obs),
        (floor, growth, bearing_sigma),
        False,
        False,
        math.log(outlier_weight),
        general,
    )
    assert np.array_equal(model.log_likelihood(poses, obs), general)


@pytest.mark.parametrize("bearing_model, mixture", [("exact", "max"), ("von_mises", "sum"), ("exact", "sum")])
def test_general_kernel_scores_each_particle_alone(bearing_model, mixture):
    """`landmark_log_likelihood` takes the headings' cos and sin TRIG_CHUNK particles at a time (fixed scratch
    whatever N): across the chunks' edges every particle scores what it scores alone."""
    from sensing.landmarks import TRIG_CHUNK

    rng = np.random.default_rng(4)
    n = 2 * TRIG_CHUNK + 37
    poses = np.column_stack([rng.uniform(-6, 6, n), rng.uniform(-4, 4, n), rng.uniform(-math.pi, math.pi, n)])
    obs = Observations.from_arrays(["goalpost", "t_crossing", "goalpost"], [2.0, 3.0, 4.5], [0.1, -0.4, 1.2])
    model = LandmarkSensorModel(FIELD, bearing_model=bearing_model, mixture=mixture)
    together = model.log_likelihood(poses, obs)
    picked = np.r_[0, TRIG_CHUNK - 1, TRIG_CHUNK, TRIG_CHUNK + 1, 2 * TRIG_CHUNK, n - 1]
    alone = np.array([model.log_likelihood(poses[i : i + 1], obs)[0] for i in picked])
    assert np.array_equal(together[picked], alone)
    np.testing.assert_allclose(together, model.numpy_twin().log_likelihood(poses, obs), rtol=1e-9, atol=1e-9)


def test_block_kernel_keeps_cos_and_sin_of_the_headings():
    from numerics.reference import sincos as sincos_reference
    from sensing.landmarks import prepare_detections, von_mises_log_likelihood

    rng = np.random.default_rng(1)
    poses = np.column_stack([rng.uniform(-4, 4, 300), rng.uniform(-3, 3, 300), rng.uniform(-3, 3, 300)])
    obs = Observations.from_arrays(["goalpost", "t_crossing"], [2.0, 3.0], [0.1, -0.4])
    model = LandmarkSensorModel(FIELD)
    table, offsets, floor, growth, bearing_sigma, log_outlier, exact = model.fused_likelihood().params
    assert not exact
    detections, groups, missing = prepare_detections(
        obs.kinds, obs.ranges, obs.bearings, obs.range_sigmas, obs.bearing_sigmas, offsets, floor, growth, bearing_sigma
    )
    assert missing == -1 and groups[:, 0].tolist() == [0, 2]
    trig = np.empty((300, 2))
    out = von_mises_log_likelihood(poses, table, offsets, detections, groups, log_outlier, np.empty(300), trig)
    assert np.array_equal(out, model.log_likelihood(poses, obs))
    cos, sin = sincos_reference(poses[:, 2])
    assert np.array_equal(trig[:, 0], cos) and np.array_equal(trig[:, 1], sin)
    assert LandmarkSensorModel(FIELD, bearing_model="exact").fused_likelihood().params[-1] is True
    assert LandmarkSensorModel(FIELD, mixture="sum").fused_likelihood() is None
    assert LandmarkSensorModel(FIELD, bearing_model="exact", mixture="sum").fused_likelihood() is None


@given(
    st.lists(
        st.tuples(kinds, st.floats(0.0, 8.0), st.floats(-10.0, 10.0), st.one_of(st.none(), st.floats(0.01, 1.0))),
        min_size=1,
        max_size=12,
    ),
    st.integers(0, 2**32 - 1),
)
def test_exact_block_kernel_matches_the_general_kernel(detections, seed):
    """The exact bearing term with the max-mixture runs a block of particles at a time (`score_block_exact`:
    `atan2_poly`, detections' bearings wrapped once); it equals the particle-by-particle kernel (libm's atan2)
    to rounding: bearings beyond ±π, particles on a landmark (distance 0, atan2(0, 0)) and headings beyond ±π
    included."""
    from sensing.landmarks import detection_batch, exact_log_likelihood, landmark_log_likelihood, prepare_detections

    rng = np.random.default_rng(seed)
    poses = np.column_stack([rng.uniform(-6, 6, 300), rng.uniform(-4, 4, 300), rng.uniform(-7, 7, 300)])
    model = LandmarkSensorModel(FIELD, bearing_model="exact")
    table, offsets = model._table, model._offsets
    poses[: len(table), :2] = table[:300]  # standing on a landmark
    obs = Observations.from_arrays(
        [d[0] for d in detections],
        [d[1] for d in detections],
        [d[2] for d in detections],
        [np.nan if d[3] is None else d[3] for d in detections],
    )
    log_outlier = math.log(model.outlier_weight)
    general = np.empty(300)
    landmark_log_likelihood(
        poses,
        model.landmark_group,
        detection_batch(obs),
        (model.range_noise_floor, model.range_noise_growth, model.bearing_sigma),
        True,
        False,
        log_outlier,
        general,
    )
    prepared, groups, missing = prepare_detections(
        obs.kinds,
        obs.ranges,
        obs.bearings,
        obs.range_sigmas,
        obs.bearing_sigmas,
        offsets,
        model.range_noise_floor,
        model.range_noise_growth,
        model.bearing_sigma,
        True,
    )
    assert missing == -1
    blocks = exact_log_likelihood(poses, table, offsets, prepared, groups, log_outlier, np.empty(300))
    assert np.isfinite(blocks).all()
    np.testing.assert_allclose(blocks, general, rtol=1e-12, atol=1e-12)
    assert np.array_equal(model.log_likelihood(poses, obs), blocks)


_SCORE_SCRIPT = """
import numpy as np
from field import spl
from sensing import LandmarkSensorModel, Observations
rng = np.random.default_rng(3)
poses = np.column_stack([rng.uniform(-5, 5, 700), rng.uniform(-3.5, 3.5, 700), rng.uniform(-4, 4, 700)])
obs = Observations.from_arrays(["goalpost", "t_crossing", "goalpost", "penalty_mark"], [2.0, 3.0, 4.5, 1.2],
                               [0.1, -0.4, 1.2, -2.0])
print(LandmarkSensorModel(spl()).log_likelihood(poses, obs).tobytes().hex())
"""


def test_default_scoring_gives_the_same_bits_on_a_robots_instruction_set(tmp_path):
    """The default likelihood (plain arithmetic, `sincos`: no fast-math, no fused multiply-add) compiled for the
    NAO's Atom (SSE4.2, no AVX, no FMA) in a fresh process gives the bits it gives compiled for this machine."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent

    def run(name, extra):
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / name), **extra}
        done = subprocess.run(
            [sys.executable, "-c", _SCORE_SCRIPT], cwd=root, env=env, capture_output=True, text=True, timeout=600
        )
        assert done.returncode == 0, done.stderr
        return done.stdout.strip()

    atom = run("atom", {"NUMBA_CPU_NAME": "silvermont", "NUMBA_CPU_FEATURES": "+sse4.2,+popcnt,-avx,-avx2,-fma"})
    assert len(atom) == 700 * 16 and atom == run("native", {})
