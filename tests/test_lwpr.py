"""Tests of motion_models.lwpr (LWPR as LWPR.md specifies it)."""

from __future__ import annotations

import copy
import pickle
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from motion_models.lwpr import FORMAT_VERSION, LWPR
from motion_models.lwpr_reference import ReferenceLWPR


def cross(x: np.ndarray) -> np.ndarray:
    """The "cross" function of LWPR.md "The benchmark users know"."""
    x1, x2 = x[..., 0], x[..., 1]
    return np.maximum.reduce([np.exp(-10 * x1**2), np.exp(-50 * x2**2), 1.25 * np.exp(-5 * (x1**2 + x2**2))])


def cross_model(cls=LWPR):
    model = cls(2, 1)
    model.init_D = 50.0 * np.eye(2)
    model.init_alpha = 250.0 * np.ones((2, 2))
    model.w_gen = 0.2
    return model


def cross_data(seed: int, n: int = 300):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1.0, 1.0, (n, 2))
    Y = cross(X) + rng.normal(0.0, 0.1, n)
    return X, Y[:, None]


@pytest.fixture(scope="module")
def trained():
    model = cross_model()
    X, Y = cross_data(1)
    for _ in range(3):
        for x, y in zip(X, Y):
            model.update(x, y)
    return model


def assert_same_rfs(model: LWPR, ref: ReferenceLWPR, rtol: float = 1e-9, atol: float = 1e-12) -> None:
    assert list(model.num_rfs) == ref.num_rfs
    for dim in range(model.n_out):
        for k, rf_ref in enumerate(ref.rfs[dim]):
            rf = model.receptive_field(dim, k)
            for key, value in rf_ref.items():
                np.testing.assert_allclose(
                    np.asarray(rf[key], float),
                    np.asarray(value, float),
                    rtol=rtol,
                    atol=atol,
                    err_msg=f"output {dim}, RF {k}, field {key}",
                )


# ------------------------------------------------------------------------------------------ the library
def test_defaults_match_the_library():
    model = LWPR(3, 2)
    np.testing.assert_array_equal(model.init_D, 25.0 * np.eye(3))
    np.testing.assert_array_equal(model.init_M, 5.0 * np.eye(3))
    np.testing.assert_array_equal(model.init_alpha, 50.0 * np.ones((3, 3)))
    assert (model.diag_only, model.update_D, model.meta) == (True, True, False)
    assert (model.meta_rate, model.penalty, model.w_gen, model.w_prune) == (250.0, 1e-6, 0.1, 1.0)
    assert (model.init_lambda, model.final_lambda, model.tau_lambda) == (0.999, 0.99999, 0.9999)
    assert (model.init_S2, model.add_threshold, model.kernel) == (1e-10, 0.5, "Gaussian")
    np.testing.assert_array_equal(model.norm_in, np.ones(3))
    np.testing.assert_array_equal(model.norm_out, np.ones(2))
    assert (model.n_in, model.n_out, model.nIn, model.nOut, model.n_data) == (3, 2, 3, 2, 0)
    np.testing.assert_array_equal(model.num_rfs, [0, 0])


def test_linear_function_is_learned_with_one_receptive_field():
    # The library's incremental PLS carries statistics gathered with earlier projection directions, so the
    # fit of an exactly linear function is close (nMSE ~ 1e-4 here), not exact to rounding.
    model = LWPR(2, 1)
    model.init_D = 0.05 * np.eye(2)  # one wide RF covers the whole domain
    rng = np.random.default_rng(3)
    for _ in range(2000):
        x = rng.uniform(-1.0, 1.0, 2)
        model.update(x, [2.0 * x[0] - 0.5 * x[1] + 0.3])
    assert list(model.num_rfs) == [1]
    X = rng.uniform(-1.0, 1.0, (200, 2))
    truth = 2.0 * X[:, 0] - 0.5 * X[:, 1] + 0.3
    error = model.predict(X)[:, 0] - truth
    assert np.mean(error**2) / np.var(truth) < 1e-3
    assert np.max(np.abs(error)) < 0.1


@pytest.mark.parametrize(
    "settings_",
    [
        {},
        {"meta": True},
        {"diag_only": False},
        {"diag_only": False, "meta": True},
        {"kernel": "BiSquare"},
        {"update_D": False, "norm_in": np.array([2.0, 0.5]), "norm_out": np.array([3.0])},
    ],
    ids=["default", "meta", "full", "full-meta", "bisquare", "norms"],
)
def test_numba_matches_reference(settings_):
    model, ref = cross_model(), cross_model(ReferenceLWPR)
    for key, value in settings_.items():
        setattr(model, key, value)
        setattr(ref, key, value)
    X, Y = cross_data(7, 200)
    for i in range(400):
        x, y = X[i % 200], Y[i % 200]
        np.testing.assert_allclose(model.update(x, y), ref.update(x, y), rtol=1e-9, atol=1e-12)
    assert_same_rfs(model, ref)
    G = np.random.default_rng(8).uniform(-1.2, 1.2, (50, 2))
    y, conf = model.predict_conf(G)
    for g, yy, cc in zip(G, y, conf):
        y_ref, conf_ref = ref.predict_conf(g)
        np.testing.assert_allclose(yy, y_ref, rtol=1e-9, atol=1e-12)
        # the bound is the root of a difference that cancels: compare it on an absolute scale
        np.testing.assert_allclose(cc, conf_ref, rtol=1e-7, atol=1e-7)
        np.testing.assert_allclose(model.predict(g), y_ref, rtol=1e-9, atol=1e-12)


def test_numba_matches_reference_three_inputs_two_outputs():
    # Full metric with meta-learning, and a third PLS direction added (LWPR.md "Add a projection").
    model, ref = LWPR(3, 2), ReferenceLWPR(3, 2)
    for m in (model, ref):
        m.init_D = 1.0 * np.eye(3)
        m.init_alpha = 100.0 * np.ones((3, 3))
        m.init_lambda = 0.99
        m.diag_only = False
        m.meta = True
    rng = np.random.default_rng(11)
    for _ in range(300):
        x = rng.uniform(-1.0, 1.0, 3)
        y = np.array([x[0] + 2.0 * x[1] - 3.0 * x[2], np.cos(x[0] + x[1])]) + rng.normal(0, 0.05, 2)
        # Meta-learning feeds each update's rounding into the next step sizes: the relative difference grows
        # from 5e-16 after 10 updates to 1e-9 after 300 (numpy 2.4, numba 0.68), so the bounds leave room.
        np.testing.assert_allclose(model.update(x, y), ref.update(x, y), rtol=1e-7, atol=1e-12)
    assert_same_rfs(model, ref, rtol=1e-7, atol=1e-8)  # the meta trace h holds small differences: 5e-9
    assert max(model.receptive_field(0, k)["n_reg"] for k in range(model.num_rfs[0])) == 3


def test_one_input_one_output_and_scalars():
    model, ref = LWPR(1, 1), ReferenceLWPR(1, 1)
    rng = np.random.default_rng(5)
    for _ in range(300):
        x = rng.uniform(-2, 2)
        y = np.sin(3 * x)
        np.testing.assert_allclose(model.update(x, y), ref.update(x, y), rtol=1e-9, atol=1e-12)
    assert_same_rfs(model, ref)
    assert abs(model.predict(0.3)[0] - np.sin(0.9)) < 0.1


def test_pruning_follows_the_library():
    model, ref = LWPR(1, 1), ReferenceLWPR(1, 1)
    for m in (model, ref):
        m.kernel = "BiSquare"
        m.w_prune = 0.5
        m.w_gen = 0.4
    rng = np.random.default_rng(2)
    for _ in range(300):
        x = rng.uniform(-1, 1)
        model.update(x, x * x)
        ref.update(x, x * x)
    assert model.n_pruned[0] == ref.n_pruned[0] > 0
    assert_same_rfs(model, ref)


def test_cross_benchmark_short(trained):
    g = np.linspace(-1.0, 1.0, 41)
    G = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    truth = cross(G)
    nmse = np.mean((trained.predict(G)[:, 0] - truth) ** 2) / np.var(truth)
    assert nmse < 0.1
    assert 20 <= trained.num_rfs[0] <= 80


def test_confidence_is_large_far_away(trained):
    _, conf_near = trained.predict_conf(np.array([0.0, 0.0]))
    y_far, conf_far = trained.predict_conf(np.array([50.0, 50.0]))
    assert 0.0 < conf_near[0] < 1.0
    assert y_far[0] == 0.0 and conf_far[0] == 1e20


# -------------------------------------------------------------------------------------------- properties
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=2, max_size=2),
    st.floats(min_value=0.0, max_value=1.0),
)
def test_predictions_finite_for_any_finite_input(trained, x, cutoff):
    y, conf = trained.predict_conf(np.array(x), cutoff=cutoff)
    assert np.all(np.isfinite(y)) and np.all(np.isfinite(conf))
    assert np.all(np.isfinite(trained.predict(np.array(x), cutoff=cutoff)))


def test_update_is_deterministic():
    X, Y = cross_data(4, 200)
    runs = []
    for _ in range(2):
        model = cross_model()
        model.meta = True
        out = np.array([model.update(x, y) for x, y in zip(X, Y)])
        runs.append((out, model.predict(X)))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])


def test_one_point_predictions_equal_the_batched_rows(trained):
    G = np.random.default_rng(5).uniform(-1.2, 1.2, (60, 2))
    batch, batch_conf = trained.predict_conf(G)
    np.testing.assert_array_equal(trained.predict(G), batch)
    for i, x in enumerate(G):
        for form in (x, x.tolist(), np.repeat(x, 2)[::2], tuple(x)):
            np.testing.assert_array_equal(trained.predict(form), batch[i])
        y, conf = trained.predict_conf(x)
        np.testing.assert_array_equal(y, batch[i])
        np.testing.assert_array_equal(conf, batch_conf[i])
        assert y.shape == (1,) and conf.shape == (1,)
    assert trained.predict(G[0]) is not trained.predict(G[0])  # a fresh array each call


def test_copy_is_independent_and_learns_the_same(trained):
    twin = trained.copy()
    X, Y = cross_data(11, 300)  # enough new RFs to grow the copy's storage
    G = np.random.default_rng(6).uniform(-1.0, 1.0, (100, 2))
    before = trained.predict(G)
    again = trained.copy()
    for x, y in zip(X, Y):
        np.testing.assert_array_equal(twin.update(x, y), again.update(x, y))
    np.testing.assert_array_equal(trained.predict(G), before)
    assert trained.n_data + len(X) == twin.n_data == again.n_data
    np.testing.assert_array_equal(twin.predict_conf(G)[1], again.predict_conf(G)[1])
    twin.w_gen = 0.5
    assert trained.w_gen == again.w_gen == 0.2


def test_pickled_and_deep_copied_models_learn_like_the_original(trained):
    X, Y = cross_data(12, 100)
    original = trained.copy()
    for clone in (pickle.loads(pickle.dumps(trained)), copy.deepcopy(trained)):
        twin = original.copy()
        for x, y in zip(X, Y):
            np.testing.assert_array_equal(clone.update(x, y), twin.update(x, y))
        np.testing.assert_array_equal(clone.num_rfs, twin.num_rfs)
        np.testing.assert_array_equal(clone.receptive_field(0, 0)["D"], twin.receptive_field(0, 0)["D"])
        assert clone.n_data == twin.n_data


def test_save_then_load_gives_identical_predictions(tmp_path, trained):
    path = tmp_path / "cross.npz"
    trained.save(path)
    for loaded in (LWPR.load(path), LWPR(str(path))):
        G = np.random.default_rng(0).uniform(-1.0, 1.0, (200, 2))
        np.testing.assert_array_equal(loaded.predict(G), trained.predict(G))
        np.testing.assert_array_equal(loaded.predict_conf(G)[1], trained.predict_conf(G)[1])
        np.testing.assert_array_equal(loaded.num_rfs, trained.num_rfs)
        assert (loaded.w_gen, loaded.n_data) == (trained.w_gen, trained.n_data)
        np.testing.assert_array_equal(loaded.init_D, trained.init_D)


def test_loaded_model_keeps_learning_like_the_original(tmp_path):
    X, Y = cross_data(9, 200)
    model = cross_model()
    for x, y in zip(X[:100], Y[:100]):
        model.update(x, y)
    model.save(tmp_path / "m.npz")
    loaded = LWPR.load(tmp_path / "m.npz")
    for x, y in zip(X[100:], Y[100:]):
        np.testing.assert_array_equal(model.update(x, y), loaded.update(x, y))


# ----------------------------------------------------------------------------------------------- errors
def test_bad_input_is_rejected_and_leaves_the_model_untouched(tmp_path, trained):
    model = LWPR.load(_saved(trained, tmp_path))
    before = model.predict_conf(np.array([0.1, 0.2]))
    n_data = model.n_data
    with pytest.raises(ValueError, match="x must have shape"):
        model.update(np.zeros(3), [0.0])
    with pytest.raises(ValueError, match="y must have shape"):
        model.update(np.zeros(2), [0.0, 1.0])
    with pytest.raises(ValueError, match="x must be finite"):
        model.update(np.array([np.nan, 0.0]), [0.0])
    with pytest.raises(ValueError, match="y must be finite"):
        model.update(np.zeros(2), [np.inf])
    with pytest.raises(ValueError, match="x must have shape"):
        model.predict(np.zeros(3))
    with pytest.raises(ValueError, match="x must be finite"):
        model.predict(np.array([[0.0, 0.0], [np.nan, 1.0]]))
    with pytest.raises(ValueError, match="x must be finite"):
        model.predict_conf(np.array([0.0, np.inf]))
    with pytest.raises(ValueError, match="cutoff"):
        model.predict(np.zeros(2), cutoff=-1.0)
    assert model.n_data == n_data
    after = model.predict_conf(np.array([0.1, 0.2]))
    np.testing.assert_array_equal(before[0], after[0])
    np.testing.assert_array_equal(before[1], after[1])


def test_predicting_with_an_untrained_model_is_an_error():
    model = LWPR(2, 1)
    with pytest.raises(ValueError, match="untrained"):
        model.predict(np.zeros(2))
    with pytest.raises(ValueError, match="untrained"):
        model.predict_conf(np.zeros(2))


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("w_gen", 1.5),
        ("w_gen", float("nan")),
        ("init_lambda", 0.0),
        ("meta_rate", -1.0),
        ("penalty", "x"),
        ("diag_only", 1),
        ("kernel", "Epanechnikov"),
        ("init_D", -np.eye(2)),
        ("init_D", np.ones((3, 3))),
        ("init_D", np.array([[1.0, 2.0], [0.0, 1.0]])),
        ("init_alpha", 0.0),
        ("norm_in", [1.0, 0.0]),
        ("norm_out", [1.0, 1.0]),
    ],
)
def test_bad_parameters_are_rejected(name, value):
    model = LWPR(2, 1)
    before = getattr(model, name)
    with pytest.raises(ValueError, match=name):
        setattr(model, name, value)
    np.testing.assert_array_equal(getattr(model, name), before)


@pytest.mark.parametrize("args", [(0, 1), (2, 0), (2.5, 1), (True, 1)])
def test_bad_dimensions_are_rejected(args):
    with pytest.raises(ValueError, match="n_in|n_out"):
        LWPR(*args)


def _saved(model: LWPR, tmp_path) -> str:
    path = str(tmp_path / "model.npz")
    model.save(path)
    return path


def test_truncated_file_is_a_clear_error(tmp_path, trained):
    path = _saved(trained, tmp_path)
    data = open(path, "rb").read()
    for size in (0, 100, len(data) // 2, len(data) - 10):
        cut = tmp_path / f"cut{size}.npz"
        cut.write_bytes(data[:size])
        with pytest.raises(ValueError, match="cut"):
            LWPR.load(cut)


def _rewrite(path: str, out, **changes) -> None:
    with np.load(path) as npz:
        fields = {key: npz[key] for key in npz.files}
    fields.update(changes)
    for key in [k for k, v in changes.items() if v is None]:
        del fields[key]
    np.savez(out, **fields)


def test_other_version_or_missing_field_is_a_clear_error(tmp_path, trained):
    path = _saved(trained, tmp_path)
    _rewrite(path, tmp_path / "v2.npz", format_version=np.array(FORMAT_VERSION + 1))
    with pytest.raises(ValueError, match=r"v2\.npz.*version 2"):
        LWPR.load(tmp_path / "v2.npz")
    _rewrite(path, tmp_path / "missing.npz", rf_mat=None)
    with pytest.raises(ValueError, match=r"missing\.npz.*rf_mat"):
        LWPR.load(tmp_path / "missing.npz")
    _rewrite(path, tmp_path / "shape.npz", rf_reg=np.zeros((1, 2, 3)))
    with pytest.raises(ValueError, match=r"shape\.npz.*rf_reg"):
        LWPR.load(tmp_path / "shape.npz")
    with zipfile.ZipFile(tmp_path / "foreign.npz", "w") as z:
        z.writestr("hello.txt", "not a model")
    with pytest.raises(ValueError, match="foreign"):
        LWPR.load(tmp_path / "foreign.npz")
