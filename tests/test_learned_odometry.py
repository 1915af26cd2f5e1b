"""LearnedFootstepOdometry: training, prediction, the motion-model interface, files, and the odometry demo."""

import json
import math

import numpy as np
import pytest

from demos.footstep_sim import GRASS, simulate, truth_displacements
from demos.odometry import main as odometry_main
from demos.odometry import step_inputs
from field.angles import wrap_angles
from motion_models import MotionInput
from motion_models.footsteps import LEFT, FootstepEvent, integrate
from motion_models.learned_odometry import (
    MODEL_FORMAT_VERSION,
    LearnedFootstepOdometry,
    LWPRSettings,
    RawFootstepOdometry,
)
from motion_models.lwpr import LWPR


@pytest.fixture(scope="module")
def data():
    """A 90 s learning walk and a 60 s test walk on grass (inputs, true displacements)."""
    learn, test = simulate(90.0, GRASS, seed=11), simulate(60.0, GRASS, seed=12)
    return {
        kind: (step_inputs(learn, kind), truth_displacements(learn), step_inputs(test, kind), truth_displacements(test))
        for kind in ("apriori", "online")
    }


@pytest.fixture(scope="module")
def models(data):
    return {kind: LearnedFootstepOdometry.train(X, Y, kind, seed=0) for kind, (X, Y, _, _) in data.items()}


def event(kind="online"):
    return FootstepEvent(
        support=LEFT,
        commanded=(0.03, 0.005, 0.1),
        previous_commanded=(0.03, 0.0, 0.08),
        sensor=(0.035, 0.004, 0.12),
        previous_sensor=(0.03, 0.001, 0.09),
        duration=0.3,
        previous_duration=0.29,
    )


# -- learning ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["apriori", "online"])
def test_learning_beats_the_raw_displacement_on_a_new_walk(data, models, kind):
    _, _, X, Y = data[kind]
    mean, sigma = models[kind].predict_steps(X)
    learned = np.mean(np.abs(mean - Y), axis=0)
    raw = np.mean(np.abs(X[:, :3] - Y), axis=0)
    assert learned[0] < 0.7 * raw[0]  # the forward step, where inertia and backlash bite
    assert learned[1] < raw[1] and learned[2] < 1.05 * raw[2]
    # The confidence bounds are of the size of the errors (a 2σ band holds most of them).
    assert 0.75 < np.mean(np.abs(mean - Y) < 2 * sigma) <= 1.0


def test_same_data_and_seed_same_model_bit_for_bit(data, models):
    X, Y, Xt, _ = data["online"]
    again = LearnedFootstepOdometry.train(X, Y, "online", seed=0)
    np.testing.assert_array_equal(again.predict_steps(Xt)[0], models["online"].predict_steps(Xt)[0])
    other = LearnedFootstepOdometry.train(X, Y, "online", seed=1)
    assert not np.array_equal(other.predict_steps(Xt)[0], models["online"].predict_steps(Xt)[0])


def test_receptive_fields_stay_bounded(models):
    # The paper finds 1 to 5 RFs, the functions being "quite simple and almost linear". The settings fitted by
    # `robocup-mcl fit odometry` (init_D = 1: fields about one standard deviation wide) grow tens of fields on
    # this 90 s log (docs/papers/rouxel.md); they stay far from one per sample.
    for m in models.values():
        assert all(1 <= int(lwpr.num_rfs[0]) <= 150 for lwpr in m.models)


# -- bad input ---------------------------------------------------------------------------------------------------
def test_training_rejects_bad_data(data):
    X, Y, _, _ = data["online"]
    with pytest.raises(ValueError, match=r"shape \(n, 9\)"):
        LearnedFootstepOdometry.train(X[:, :7], Y, "online")
    with pytest.raises(ValueError, match=r"shape \(n, 7\)"):
        LearnedFootstepOdometry.train(X, Y, "apriori")
    bad = X.copy()
    bad[17, 4] = np.nan
    with pytest.raises(ValueError, match="inputs must be finite: row 17"):
        LearnedFootstepOdometry.train(bad, Y, "online")
    bad_y = Y.copy()
    bad_y[3, 2] = np.inf
    with pytest.raises(ValueError, match="targets must be finite: row 3"):
        LearnedFootstepOdometry.train(X, bad_y, "online")
    with pytest.raises(ValueError, match="targets must have shape"):
        LearnedFootstepOdometry.train(X, Y[:-1], "online")
    with pytest.raises(ValueError, match="at least 10"):
        LearnedFootstepOdometry.train(X[:5], Y[:5], "online")
    with pytest.raises(ValueError, match="inputs = 'both'"):
        LearnedFootstepOdometry.train(X, Y, "both")
    with pytest.raises(ValueError, match="epochs"):
        LWPRSettings(epochs=0)


def test_untrained_or_mismatched_models_are_rejected(models):
    with pytest.raises(ValueError, match="untrained"):
        LearnedFootstepOdometry(tuple(LWPR(9, 1) for _ in range(3)), "online")
    with pytest.raises(ValueError, match="R\\^9"):
        LearnedFootstepOdometry(models["apriori"].models, "online")
    with pytest.raises(ValueError, match="three LWPR"):
        LearnedFootstepOdometry(models["online"].models[:2], "online")
    with pytest.raises(ValueError, match="untrained"):
        LWPR(9, 1).predict(np.zeros(9))
    with pytest.raises(ValueError, match=r"shape \(m, 9\)"):
        models["online"].predict_steps(np.zeros((4, 7)))


def test_updating_never_touches_the_original(data, models):
    X, Y, Xt, _ = data["online"]
    before = models["online"].predict_steps(Xt)[0]
    counts = [int(m.n_data) for m in models["online"].models]
    newer = models["online"].updated(Xt, data["online"][3])
    assert [int(m.n_data) for m in newer.models] == [c + Xt.shape[0] for c in counts]
    np.testing.assert_array_equal(models["online"].predict_steps(Xt)[0], before)
    bad = Xt.copy()
    bad[-1, 0] = np.nan
    with pytest.raises(ValueError, match="row"):
        models["online"].updated(bad, data["online"][3])
    assert [int(m.n_data) for m in models["online"].models] == counts


# -- the motion model --------------------------------------------------------------------------------------------
def test_particles_move_only_at_support_swaps(models):
    model = models["online"]
    poses = np.random.default_rng(0).normal(size=(50, 3))
    before, rng = poses.copy(), np.random.default_rng(5)
    state = rng.bit_generator.state
    model.predict(poses, MotionInput(dt=0.01, odometry=(0.0, 0.0, 0.0)), rng)
    np.testing.assert_array_equal(poses, before)
    assert rng.bit_generator.state == state  # no variates drawn between swaps


def test_a_swap_moves_each_particle_by_the_predicted_step(models):
    exact = LearnedFootstepOdometry(models["online"].models, "online", noise_scale=0.0, min_sigma=(0, 0, 0))
    mean, sigma = exact.predict_event(event())
    assert np.all(sigma == 0)
    poses = np.random.default_rng(1).uniform(-3, 3, size=(20, 3))
    expected = np.array([integrate(mean[None, :], start=p)[1] for p in poses])
    exact.predict(poses, MotionInput(dt=0.01, footstep=event()), np.random.default_rng(2))
    np.testing.assert_allclose(poses[:, :2], expected[:, :2], atol=1e-12)
    np.testing.assert_allclose(wrap_angles(poses[:, 2] - expected[:, 2]), 0, atol=1e-12)


def test_swap_noise_follows_the_confidence_bounds(models):
    model = models["online"]
    mean, sigma = model.predict_event(event())
    poses = np.zeros((20000, 3))
    model.predict(poses, MotionInput(dt=0.01, footstep=event()), np.random.default_rng(3))
    np.testing.assert_allclose(poses.mean(axis=0), mean, atol=4 * sigma.max() / math.sqrt(20000))
    # From a zero heading the robot frame is the field frame: the spread is the bound (first order in θ).
    np.testing.assert_allclose(poses.std(axis=0), sigma, rtol=0.05)


def test_check_rejects_what_the_model_cannot_use(models):
    with pytest.raises(ValueError, match="FootstepEvent"):
        models["online"].check(MotionInput(dt=0.01, footstep=(0.1, 0.0, 0.0)))
    apriori_only = FootstepEvent(support=LEFT, commanded=(0.03, 0.0, 0.0))
    models["apriori"].check(MotionInput(dt=0.01, footstep=apriori_only))
    poses = np.zeros((5, 3))
    with pytest.raises(ValueError, match="sensor"):
        models["online"].predict(poses, MotionInput(dt=0.01, footstep=apriori_only), np.random.default_rng(0))
    assert not poses.any()


def test_particle_filter_rejects_a_bad_event_and_stays_as_it_was(models):
    from field import spl
    from mcl import ParticleFilter
    from sensing import LandmarkSensorModel

    pf = ParticleFilter(spl(), models["online"], LandmarkSensorModel(spl()), n_particles=100, seed=0)
    pf.reset_around((0.0, 0.0, 0.0))
    before = pf.poses.copy()
    pf.predict(MotionInput(dt=0.01, odometry=(0.0, 0.0, 0.0)))
    np.testing.assert_array_equal(pf.poses, before)
    with pytest.raises(ValueError):
        pf.predict(
            MotionInput(
                dt=0.01, odometry=(0.0, 0.0, 0.0), footstep=FootstepEvent(support=LEFT, commanded=(0.03, 0.0, 0.0))
            )
        )
    np.testing.assert_array_equal(pf.poses, before)
    pf.predict(MotionInput(dt=0.01, odometry=event().sensor, footstep=event()))
    assert np.mean(pf.poses[:, 0] - before[:, 0]) > 0.02


def test_raw_footstep_odometry(data):
    X, Y, _, _ = data["online"]
    raw = RawFootstepOdometry.calibrate(X, Y, "online")
    np.testing.assert_allclose(raw.sigma, np.sqrt(np.mean((X[:, :3] - Y) ** 2, axis=0)))
    poses = np.zeros((4000, 3))
    raw.predict(poses, MotionInput(dt=0.01, footstep=event()), np.random.default_rng(0))
    np.testing.assert_allclose(poses.mean(axis=0), event().sensor, atol=4 * max(raw.sigma) / math.sqrt(4000))
    with pytest.raises(ValueError, match="sigma"):
        RawFootstepOdometry("online", (0.01, -1.0, 0.0))


# -- files -------------------------------------------------------------------------------------------------------
def test_save_load_round_trip_and_bad_directories(tmp_path, data, models):
    _, _, Xt, _ = data["apriori"]
    models["apriori"].save(tmp_path / "m")
    back = LearnedFootstepOdometry.load(tmp_path / "m")
    assert back.inputs == "apriori" and back.fallback_sigma == models["apriori"].fallback_sigma
    np.testing.assert_array_equal(back.predict_steps(Xt)[0], models["apriori"].predict_steps(Xt)[0])
    with pytest.raises(ValueError, match="holds no"):
        LearnedFootstepOdometry.load(tmp_path / "nothing")
    # A truncated model file.
    dx = tmp_path / "m" / "dx.npz"
    good = dx.read_bytes()
    dx.write_bytes(good[: len(good) // 2])
    with pytest.raises(ValueError, match="truncated"):
        LearnedFootstepOdometry.load(tmp_path / "m")
    dx.write_bytes(good)
    # Another format version.
    meta_path = tmp_path / "m" / "footstep_odometry.json"
    meta = json.loads(meta_path.read_text())
    meta_path.write_text(json.dumps({**meta, "format_version": MODEL_FORMAT_VERSION + 1}))
    with pytest.raises(ValueError, match="format version"):
        LearnedFootstepOdometry.load(tmp_path / "m")
    meta_path.write_text(json.dumps({**meta, "models": {"dx": "dx.npz", "dy": "dy.npz"}}))
    with pytest.raises(ValueError, match="dtheta"):
        LearnedFootstepOdometry.load(tmp_path / "m")
    meta_path.write_text(json.dumps(meta)[:40])
    with pytest.raises(ValueError, match="truncated or not JSON"):
        LearnedFootstepOdometry.load(tmp_path / "m")


# -- the demo ----------------------------------------------------------------------------------------------------
def test_record_train_and_save_from_a_log(tmp_path, capsys):
    log = tmp_path / "walk.npz"
    assert odometry_main(["--record", str(log), "--surface", "carpet", "--duration", "40", "--seed", "4"]) == 0
    assert odometry_main(["--train", str(log), "--save", str(tmp_path / "models"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out.split("\n", 1)[1])
    assert out["surface"] == "carpet" and out["steps"] > 100
    for kind in ("apriori", "online"):
        assert LearnedFootstepOdometry.load(tmp_path / "models" / kind).inputs == kind
    (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04 not really")
    assert odometry_main(["--train", str(tmp_path / "bad.npz"), "--save", str(tmp_path / "x")]) == 1
    assert "truncated" in capsys.readouterr().err


def test_the_papers_protocol_learning_halves_the_drift(capsys):
    assert odometry_main(["--surface", "carpet", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)["surfaces"]["carpet"]["evaluation"]
    assert result["sequences"] >= 50 and result["learning_steps"] > 400
    for kind in ("apriori", "online"):
        assert result["drift_reduction_10s"][kind] >= 0.5
    drift = result["drift"]
    # The raw odometries underestimate: a priori far more than online (Rouxel sec. IV-B 3).
    assert drift["apriori_raw"]["10s"]["cartesian_m"]["mean"] > drift["online_raw"]["10s"]["cartesian_m"]["mean"]


# -- the linear stage (the variant lin+LWPR) ------------------------------------------------------------------
def _linear_data(seed=3, n=500, kind="apriori"):
    from motion_models.footsteps import N_INPUTS

    rng = np.random.default_rng(seed)
    X = rng.uniform(-0.05, 0.05, (n, N_INPUTS[kind]))
    Y = 0.8 * X[:, :3] + 0.3 * X[:, 3:6] + 0.01 + 0.0005 * rng.standard_normal((n, 3))
    return X, Y


def test_a_linear_stage_holds_an_affine_step_and_is_saved_with_the_models(tmp_path):
    from motion_models.learned_odometry import LearnedFootstepOdometry, LinearStage

    X, Y = _linear_data()
    model = LearnedFootstepOdometry.train(X, Y, "apriori", linear_stage=True)
    assert isinstance(model.linear, LinearStage) and model.residual
    stage = LinearStage.fit(X, Y)
    np.testing.assert_array_equal(model.linear.weights, stage.weights)
    assert np.abs(stage.predict(X) - Y).max() < 0.003  # the affine part is the linear stage's
    # Far outside every receptive field the prediction is the linear step, not the raw one.
    far = np.full((1, 7), 5.0)
    np.testing.assert_allclose(model.predict_steps(far)[0], stage.predict(far), rtol=1e-12, atol=1e-12)
    model.save(tmp_path / "m")
    loaded = LearnedFootstepOdometry.load(tmp_path / "m")
    for a, b in zip(model.predict_steps(X), loaded.predict_steps(X)):
        np.testing.assert_array_equal(a, b)
    # The same data and seed give the same model, bit for bit; updated keeps the stage.
    again = LearnedFootstepOdometry.train(X, Y, "apriori", linear_stage=True)
    np.testing.assert_array_equal(again.predict_steps(X)[0], model.predict_steps(X)[0])
    assert model.updated(X[:50], Y[:50]).linear is model.linear


def test_a_holder_without_a_linear_stage_saves_no_linear_key(tmp_path):
    import json

    from motion_models.learned_odometry import META_FILE, LearnedFootstepOdometry

    X, Y = _linear_data()
    LearnedFootstepOdometry.train(X, Y, "apriori").save(tmp_path / "m")
    assert "linear" not in json.loads((tmp_path / "m" / META_FILE).read_text())


@pytest.mark.parametrize(
    "change, match",
    [
        (lambda linear: linear.pop("weights"), "linear"),
        (lambda linear: linear.update(extra=1), "linear"),
        (lambda linear: linear["scale_in"].__setitem__(0, 0.0), "linear"),
        (lambda linear: linear["scale_in"].__setitem__(0, -1.0), "linear"),
        (lambda linear: linear["mean_out"].append(0.0), "linear"),
        (lambda linear: linear["weights"][0].__setitem__(1, "x"), "linear"),
        (lambda linear: linear["weights"].pop(), "linear"),
        (lambda linear: linear["mean_in"].__setitem__(2, True), "linear"),
    ],
)
def test_load_refuses_a_bad_linear_stage(tmp_path, change, match):
    import json

    from motion_models.learned_odometry import META_FILE, LearnedFootstepOdometry

    X, Y = _linear_data()
    LearnedFootstepOdometry.train(X, Y, "apriori", linear_stage=True).save(tmp_path / "m")
    path = tmp_path / "m" / META_FILE
    meta = json.loads(path.read_text())
    change(meta["linear"])
    path.write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=match):
        LearnedFootstepOdometry.load(tmp_path / "m")


def test_a_linear_stage_must_fit_the_holder():
    import dataclasses

    from motion_models.learned_odometry import LearnedFootstepOdometry, LinearStage

    X, Y = _linear_data()
    model = LearnedFootstepOdometry.train(X, Y, "apriori", linear_stage=True)
    with pytest.raises(ValueError, match="residual"):
        dataclasses.replace(model, residual=False)
    online = LinearStage.fit(np.hstack([X, X[:, :2]]), Y)  # nine inputs
    with pytest.raises(ValueError, match="inputs"):
        dataclasses.replace(model, linear=online)
    with pytest.raises(ValueError, match="LinearStage"):
        dataclasses.replace(model, linear="a stage")
    with pytest.raises(ValueError, match="linear_stage"):
        LearnedFootstepOdometry.train(X, Y, "apriori", linear_stage="yes")
    for bad in (dict(scale_in=np.zeros(7)), dict(mean_out=np.zeros(2)), dict(weights=np.full((7, 3), np.nan))):
        fields = dict(mean_in=np.zeros(7), scale_in=np.ones(7), mean_out=np.zeros(3), weights=np.zeros((7, 3)))
        with pytest.raises(ValueError):
            LinearStage(**{**fields, **bad})


def test_a_constant_input_leaves_the_linear_stage_finite():
    from motion_models.learned_odometry import LinearStage

    X, Y = _linear_data()
    X[:, 6] = 0.02  # an input that never changes: a singular normal matrix
    stage = LinearStage.fit(X, Y)
    assert np.isfinite(stage.weights).all() and np.abs(stage.predict(X) - Y).max() < 0.003
