"""The footstep simulator under model mismatch: drawn robots and runs, the fit of LWPR's meta-parameters and of
the linear baseline, the robustness table's statistics, and the separation of the simulator from the model."""

from __future__ import annotations

import ast
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

import demos.fit_odometry as fit_odometry
from demos import footstep_sim
from demos.footstep_sim import (
    CONDITION_RANGES,
    MAX_MOMENTUM,
    ROBOT_RANGES,
    Conditions,
    Robot,
    draw_conditions,
    draw_robot,
    simulate,
    truth_displacements,
)
from demos.odometry import BASELINE, LinearCorrection, reduction_interval, step_inputs
from demos.odometry import main as odometry_main
from motion_models.learned_odometry import LearnedFootstepOdometry, LWPRSettings, RawFootstepOdometry

ROOT = Path(__file__).resolve().parents[1]
FIT_FILE = ROOT / "results" / "odometry_fit.json"


# -- the drawn robots and runs ----------------------------------------------------------------------------------
def _scaled(centre: float, low: float, high: float, spread: float) -> tuple[float, float]:
    return centre - spread * (centre - low), centre + spread * (high - centre)


def test_nominal_values_lie_inside_their_ranges_and_spread_0_is_nominal():
    for nominal, ranges in ((Robot(), ROBOT_RANGES), (Conditions(), CONDITION_RANGES)):
        for name, (low, high) in ranges.items():
            assert low < high and low <= getattr(nominal, name) <= high, name
    assert draw_robot(7, 0.0) == Robot() and draw_conditions(7, 0.0) == Conditions()


@pytest.mark.parametrize("spread", [0.5, 1.0, 2.0])
def test_draws_stay_in_the_scaled_ranges(spread):
    robots = [draw_robot(i, spread) for i in range(40)]
    runs = [draw_conditions(i, spread) for i in range(40)]
    for drawn, nominal, ranges in ((robots, Robot(), ROBOT_RANGES), (runs, Conditions(), CONDITION_RANGES)):
        for name, (low, high) in ranges.items():
            lo, hi = _scaled(getattr(nominal, name), low, high, spread)
            values = np.array([getattr(d, name) for d in drawn])
            assert np.all(values >= min(lo, 0.0 if lo < 0 else lo) - 1e-12), name
            assert np.all(values <= hi + 1e-12), name
            assert values.std() > 0.1 * (hi - lo) / math.sqrt(12), name  # they do vary
    for r in robots:
        assert sum(r.momentum) <= MAX_MOMENTUM + 1e-12 and min(r.momentum) >= 0
    if spread == 2.0:  # the draws go beyond the documented ranges
        beyond = [
            name
            for name, (low, high) in ROBOT_RANGES.items()
            if any(not low <= getattr(r, name) <= high for r in robots)
        ]
        assert len(beyond) > len(ROBOT_RANGES) // 2


def test_training_and_test_robots_are_different_draws_and_a_draw_repeats():
    assert draw_robot(0) != draw_robot(100)
    assert draw_robot(3, 1.0) == draw_robot(3, 1.0)
    a, b = draw_robot(3, 0.5), draw_robot(3, 1.0)
    # the same robot at another spread: the same variate, scaled about the nominal value
    for name in ROBOT_RANGES:
        centre = getattr(Robot(), name)
        if name.startswith("momentum") or name in footstep_sim._NON_NEGATIVE:
            continue
        assert getattr(b, name) - centre == pytest.approx(2 * (getattr(a, name) - centre), abs=1e-12)


@pytest.mark.parametrize("bad", [-1, 1.5, True, "3"])
def test_bad_robot_ids_and_run_seeds_are_refused(bad):
    with pytest.raises(ValueError, match="robot_id"):
        draw_robot(bad)
    with pytest.raises(ValueError, match="run_seed"):
        draw_conditions(bad)


@pytest.mark.parametrize("spread", [-0.5, float("nan"), float("inf"), True])
def test_bad_spreads_are_refused(spread):
    with pytest.raises(ValueError, match="spread"):
        draw_robot(1, spread)
    with pytest.raises(ValueError, match="spread"):
        draw_conditions(1, spread)


def test_simulator_refuses_bad_robots_and_conditions():
    with pytest.raises(ValueError, match="friction"):
        simulate(10.0, "carpet", robot=Robot(), conditions=Conditions(friction=0.0))
    with pytest.raises(ValueError, match="Robot"):
        simulate(10.0, "carpet", robot="nominal")


def test_same_seed_robot_and_conditions_same_log_bit_for_bit():
    robot, run = draw_robot(5), draw_conditions(11)
    a = simulate(20.0, "grass", 11, robot=robot, conditions=run)
    b = simulate(20.0, "grass", 11, robot=robot, conditions=run)
    for name in ("swap_times", "swap_poses", "commanded", "sensor", "mocap"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_run_conditions_change_what_the_inputs_do_not_see():
    nominal = simulate(60.0, "carpet", 4)
    forward = nominal.commanded[:, 0] > 0.02
    # A per-run encoder scale changes the sensor steps, not the truth.
    scaled = simulate(60.0, "carpet", 4, conditions=Conditions(encoder_scale=0.04))
    np.testing.assert_array_equal(scaled.swap_poses, nominal.swap_poses)
    ratio = np.mean(scaled.sensor[forward, 0]) / np.mean(nominal.sensor[forward, 0])
    assert ratio == pytest.approx(1.04, abs=0.005)
    # A slippery ground shortens the real steps for the same commands; the encoders miss the slide.
    slippery = simulate(60.0, "carpet", 1, conditions=Conditions(friction=0.6))
    nominal = simulate(60.0, "carpet", 1)
    same = int(np.argmax(np.any(slippery.commanded != nominal.commanded, axis=1))) or nominal.n_steps
    assert same > 50  # the same commands until the operator steers the two robots differently
    true_n, true_s = truth_displacements(nominal)[:same], truth_displacements(slippery)[:same]
    walking = nominal.commanded[:same, 0] > 0.02
    assert walking.sum() > 10
    assert np.mean(true_s[walking, 0]) < 0.95 * np.mean(true_n[walking, 0])
    # A per-log bias turns the robot whatever it is commanded.
    biased = simulate(60.0, "carpet", 1, conditions=Conditions(bias_turn=0.006))
    same = int(np.argmax(np.any(biased.commanded != nominal.commanded, axis=1))) or nominal.n_steps
    assert same > 20
    assert np.mean(truth_displacements(biased)[:same, 2] - truth_displacements(nominal)[:same, 2]) > 0.003


def test_momentum_spans_more_than_the_previous_step():
    # The real step of step k depends on steps k-2 and k-3, which the LWPR inputs (t, t-1) do not hold.
    assert Robot().momentum_2 > 0 and Robot().momentum_3 > 0
    one_step = dataclasses.replace(Robot(), momentum_2=0.0, momentum_3=0.0)
    a, b = simulate(30.0, "carpet", 2), simulate(30.0, "carpet", 2, robot=one_step)
    assert not np.allclose(truth_displacements(a)[5:], truth_displacements(b)[5:], atol=1e-4)


# -- the simulator shares nothing with the model ----------------------------------------------------------------
# Structural values a simulator constant may share with a model default: 0 and 1 (no effect, unit gain), the
# walk engine's rhythm and the motion capture rate (properties of the setup the logs record, not of the model).
STRUCTURAL = {0.0, 1.0, 1.7, 100.0}


def _numbers(value) -> list[float]:
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return []
    if isinstance(value, (int, float)):
        return [float(value)]
    if isinstance(value, (tuple, list)):
        return [x for v in value for x in _numbers(v)]
    if dataclasses.is_dataclass(value):
        return [x for f in dataclasses.fields(value) for x in _numbers(getattr(value, f.name))]
    if isinstance(value, dict):
        return [x for v in value.values() for x in _numbers(v)]
    return []


def _simulator_constants() -> set[float]:
    values = _numbers(
        [Robot(), Conditions(), footstep_sim.Driver(), *footstep_sim.SURFACES.values(), ROBOT_RANGES, CONDITION_RANGES]
    )
    values += [
        v
        for name, v in vars(footstep_sim).items()
        if name.isupper() or name.startswith("_")
        for v in _numbers(v)
        if not isinstance(v, bool)
    ]
    return set(values) - STRUCTURAL


def _model_defaults() -> dict[str, float]:
    out = {}
    for name, obj in (("LWPRSettings", LWPRSettings()), ("RawFootstepOdometry", RawFootstepOdometry())):
        for f in dataclasses.fields(obj):
            for i, v in enumerate(_numbers(getattr(obj, f.name))):
                out[f"{name}.{f.name}[{i}]"] = v
    for f in dataclasses.fields(LearnedFootstepOdometry):
        if f.default is not dataclasses.MISSING:
            for i, v in enumerate(_numbers(f.default)):
                out[f"LearnedFootstepOdometry.{f.name}[{i}]"] = v
    return out


def test_no_model_default_equals_a_simulator_constant():
    constants = _simulator_constants()
    assert len(constants) > 60  # Robot, Conditions, Driver, surfaces, every range end
    shared = {name: v for name, v in _model_defaults().items() if v not in STRUCTURAL and v in constants}
    assert not shared, f"model defaults equal to simulator constants: {shared}"


def test_the_simulator_does_not_import_the_model():
    tree = ast.parse((ROOT / "demos" / "footstep_sim.py").read_text(encoding="utf-8"))
    forbidden_modules = {"motion_models.learned_odometry", "demos.odometry", "demos.fit_odometry"}
    forbidden_names = {"LWPR", "LWPRSettings", "LearnedFootstepOdometry", "RawFootstepOdometry"}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            assert not {a.name for a in node.names} & forbidden_modules
        elif isinstance(node, ast.ImportFrom):
            assert (node.module or "") not in forbidden_modules, node.module
            assert not {a.name for a in node.names} & forbidden_names, [a.name for a in node.names]
        elif isinstance(node, ast.Name):
            assert node.id not in forbidden_names, node.id


# -- the fits -----------------------------------------------------------------------------------------------------
def test_linear_baseline_recovers_a_known_affine_map():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(400, 9))
    W = rng.normal(size=(9, 3))
    Y = X @ W + np.array([0.01, -0.02, 0.03])
    model = LinearCorrection.fit(X, Y, "online", features="inputs", ridge=0.0)
    np.testing.assert_allclose(model.predict_steps(X)[0], Y, atol=1e-9)
    # "axis" uses each raw axis alone: it recovers a per-axis scale and offset exactly.
    Y_axis = X[:, :3] * np.array([1.2, 0.9, 1.05]) + np.array([0.002, 0.0, -0.01])
    axis = LinearCorrection.fit(X, Y_axis, "online", features="axis")
    np.testing.assert_allclose(axis.predict_steps(X)[0], Y_axis, atol=1e-9)
    for bad in ({"features": "all"}, {"ridge": -1.0}, {"ridge": float("nan")}):
        with pytest.raises(ValueError):
            LinearCorrection.fit(X, Y, "online", **bad)


def test_the_search_picks_its_best_candidate_on_training_logs_only(monkeypatch):
    monkeypatch.setattr(fit_odometry, "STAGE_1", {"init_D": (0.006, 0.6), "init_alpha": (2.0,)})
    monkeypatch.setattr(fit_odometry, "STAGE_2", {"w_gen": (0.1,), "penalty": (1e-6, 1e-2)})
    monkeypatch.setattr(
        fit_odometry, "BASELINE_GRID", ({"features": "axis", "ridge": 0.0}, {"features": "inputs", "ridge": 0.0})
    )
    result = fit_odometry.fit(surfaces=("carpet",), robots=(0, 1), duration=60.0)
    assert len(result["candidates"]) == 4
    best = min(c["score"]["mean"] for c in result["candidates"])
    assert result["score"]["mean"] == best
    assert result["settings"]["init_D"] in (0.006, 0.6) and result["protocol"]["train_robots"] == [0, 1]
    assert set(result["baseline"]) == {"apriori", "online"}
    again = fit_odometry.fit(surfaces=("carpet",), robots=(0, 1), duration=60.0)
    assert json.dumps(again) == json.dumps(result)  # same logs, same seed: same fit, bit for bit


def test_the_defaults_are_the_fit_files_values():
    fitted = json.loads(FIT_FILE.read_text(encoding="utf-8"))
    settings = LWPRSettings()
    for name, value in fitted["settings"].items():
        assert getattr(settings, name) == pytest.approx(value, rel=1e-9), name
    for name, value in fitted["fixed"].items():
        assert getattr(settings, name) == value, name
    for kind, chosen in fitted["baseline"].items():
        assert BASELINE[kind] == {"features": chosen["features"], "ridge": chosen["ridge"]}


# -- the robustness table -----------------------------------------------------------------------------------------
def test_reduction_interval_is_deterministic_and_brackets_its_mean():
    rng = np.random.default_rng(1)
    raw = rng.uniform(0.1, 0.3, 60)
    drifts = {"raw": raw, "lwpr": raw * rng.uniform(0.3, 0.6, 60)}
    a, b = reduction_interval(drifts, "lwpr"), reduction_interval(drifts, "lwpr")
    assert a == b and a["ci95"][0] < a["mean"] < a["ci95"][1] and 0.4 < a["mean"] < 0.7


def test_mismatch_refuses_bad_spreads_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "table.json"
    for bad in (["--spreads", "-1"], ["--spreads", "nan"], ["--spreads", "1:2:3"], ["--curve"]):
        with pytest.raises(SystemExit) as done:
            odometry_main(["--mismatch", *bad, "--save", str(out)])
        assert done.value.code == 2
    assert not out.exists()


def test_mismatch_table_on_the_nominal_simulator(tmp_path, capsys, monkeypatch):
    import demos.odometry as odometry

    monkeypatch.setattr(odometry, "TRAIN_ROBOTS", (0, 1))
    monkeypatch.setattr(odometry, "TEST_ROBOTS", (100,))
    monkeypatch.setattr(odometry, "TEST_LOGS", 2)
    monkeypatch.setattr(odometry, "LOG_SECONDS", 120.0)
    out = tmp_path / "table.json"
    assert odometry_main(["--mismatch", "--surface", "carpet", "--spreads", "0:0", "--save", str(out)]) == 0
    text = capsys.readouterr().out
    assert "own:" in text and "fleet:" in text
    rows = json.loads(out.read_text())["rows"]
    assert {(r["regime"], r["kind"]) for r in rows} == {(g, k) for g in ("own", "fleet") for k in ("apriori", "online")}
    for r in rows:
        assert r["sequences"] >= 5 and r["drift10_cm"]["raw"] > 0
        assert r["reduction"]["lwpr"]["ci95"][0] <= r["reduction"]["lwpr"]["mean"] <= r["reduction"]["lwpr"]["ci95"][1]
    X = step_inputs(simulate(20.0, "carpet", 0), "apriori")
    assert X.shape[1] == 7


def test_training_and_held_out_seeds_and_robots_never_meet():
    from demos.odometry import TEST_LOGS, TEST_ROBOTS, TRAIN_ROBOTS, fleet_seed

    train = {fleet_seed("train", s, r, i) for s in ("carpet", "grass") for r in TRAIN_ROBOTS for i in range(TEST_LOGS)}
    test = {fleet_seed("test", s, r, i) for s in ("carpet", "grass") for r in TEST_ROBOTS for i in range(TEST_LOGS)}
    assert not train & test and len(test) == 2 * len(TEST_ROBOTS) * TEST_LOGS
    assert not set(TRAIN_ROBOTS) & set(TEST_ROBOTS)


def test_the_variant_learns_what_the_linear_map_leaves():
    from motion_models.learned_odometry import LearnedFootstepOdometry

    rng = np.random.default_rng(3)
    X = rng.uniform(-1, 1, (600, 7))
    Y = 0.5 * X[:, :3] + 0.05 * X[:, 3:4] ** 2 + 0.001 * rng.standard_normal((600, 3))  # a bend in one input
    linear = LinearCorrection.fit(X, Y, "apriori")
    variant = LearnedFootstepOdometry.train(X, Y, "apriori", settings=LWPRSettings(), linear_stage=True)
    # The variant's linear stage is the linear baseline with every input and no penalty, bit for bit.
    np.testing.assert_array_equal(variant.linear.weights, linear.weights)
    np.testing.assert_array_equal(variant.linear.predict(X), linear.predict_steps(X)[0])
    error = {name: np.mean(np.abs(m.predict_steps(X)[0] - Y)) for name, m in (("linear", linear), ("variant", variant))}
    assert error["variant"] < 0.7 * error["linear"]
    # Far outside the training data no receptive field is active: the variant falls back to the linear map.
    far = np.full((1, 7), 1e6)
    np.testing.assert_allclose(variant.predict_steps(far)[0], linear.predict_steps(far)[0], rtol=1e-9)
