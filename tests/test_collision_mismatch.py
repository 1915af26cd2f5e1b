"""The collision simulator's mismatched physics, the adaptive model's fit from training logs, and the rule that
no model default is a simulator constant."""

import ast
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from demos import collision_sim
from demos.collision_sim import (
    FREE,
    LEFT,
    MISMATCH_RANGES,
    STOPPED,
    CollisionEvent,
    CollisionScenario,
    draw_physics,
    simulate,
)
from demos.fit_adaptive import (
    CONDITIONS,
    DIGITS,
    FITTED,
    FOOT_SEPARATION,
    ODOMETRY_SHAPE,
    episode_ends,
    episode_rates,
    fit,
    fit_betas,
    fit_end_rates,
    fit_odometry,
    free_walk_errors,
)
from motion_models import AdaptiveMotion
from motion_models.adaptive import MobilityTransitions

ROOT = Path(__file__).resolve().parents[1]
MISMATCH = CollisionScenario(physics="mismatch")


def _numbers(value) -> list[float]:
    """Every number in a value: a number, or nested tuples, lists and dicts of numbers."""
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return []
    if isinstance(value, (int, float)):
        return [float(value)]
    if isinstance(value, dict):
        return [x for v in value.values() for x in _numbers(v)]
    if isinstance(value, (tuple, list)):
        return [x for v in value for x in _numbers(v)]
    return []


def test_every_range_is_drawn_within_its_bounds_and_the_same_robot_seed_gives_the_same_robot():
    robots = [draw_physics(MISMATCH, seed) for seed in range(300)]
    for name, bounds in MISMATCH_RANGES.items():
        values = np.array([getattr(robot, name) for robot in robots], dtype=np.float64)
        ends = bounds if isinstance(bounds[0], tuple) else (bounds,) * (values.shape[1] if values.ndim > 1 else 1)
        columns = values if values.ndim > 1 else values[:, None]
        for column, (low, high) in zip(columns.T, ends):
            assert low <= column.min() and column.max() <= high, name
            # Spread over the range, not stuck at the nominal value.
            assert column.max() - column.min() > 0.8 * (high - low), name
    turns = np.array([robot.stop_turn for robot in robots])
    assert (turns[:, 0] == turns[:, 1]).all()
    assert turns.min() < 0.1 and turns.max() > 1.0  # the stop turn anywhere in 0.1-1.0 of v / w, and beyond
    subsets = {robot.held_joints for robot in robots}
    assert len(subsets) == 15 and all(subsets)  # every non-empty subset of the four joints
    one, other = draw_physics(MISMATCH, 7), draw_physics(dataclasses.replace(MISMATCH, duration=3.0), 7)
    assert all(getattr(one, name) == getattr(other, name) for name in (*MISMATCH_RANGES, "held_joints"))
    assert (
        draw_physics(dataclasses.replace(MISMATCH, robot_seed=5), 1).foot_separation
        == draw_physics(MISMATCH, 5).foot_separation
    )
    assert draw_physics(CollisionScenario(), 3) == CollisionScenario()


def test_mismatched_runs_are_reproducible_and_differ_between_robots():
    scenario = dataclasses.replace(MISMATCH, duration=2.0)
    a, b, c = simulate(scenario, 4), simulate(scenario, 4), simulate(scenario, 5)
    assert a.truth.tobytes() == b.truth.tobytes() and a.servo_readings.tobytes() == b.servo_readings.tobytes()
    assert a.scenario == b.scenario != c.scenario


def test_unknown_physics_is_refused():
    with pytest.raises(ValueError, match="physics"):
        simulate(CollisionScenario(physics="ideal", duration=1.0), 0)


def test_stopped_robot_pivots_about_the_held_foot():
    # A left contact: the body turns left at the stop share times |v| / w over a gait cycle, and its centre
    # walks on at half the foot separation times the turn rate.
    share = 0.8
    scenario = CollisionScenario(
        duration=4.0,
        stop_turn=(share, share),
        step_noise=0.0,
        scale_sigma=0.0,
        turn_bias_sigma=0.0,
        events=(CollisionEvent(1.0, 2.5, STOPPED, LEFT, 0.5),),
    )
    log = simulate(scenario, 3)
    stopped = np.flatnonzero(log.mode == STOPPED)
    cycles = int(len(stopped) * log.dt / scenario.cycle)
    stopped = stopped[: int(round(cycles * scenario.cycle / log.dt))]
    first, last = stopped[0] - 1, stopped[-1]
    turned = log.truth[last, 2] - log.truth[first, 2]
    duration = len(stopped) * log.dt
    expected = share * 0.2 / scenario.foot_separation
    assert turned / duration == pytest.approx(expected, rel=0.05)
    walked = np.hypot(*(log.truth[last, :2] - log.truth[first, :2]))
    arc = 0.5 * scenario.foot_separation * abs(turned)
    assert walked == pytest.approx(arc * math.sin(turned / 2) / (turned / 2), rel=0.1)


def test_the_fit_recovers_known_ranges():
    rng = np.random.default_rng(0)
    n = 4000
    truth = {
        "beta1": 0.3,
        "beta2": 0.5,
        "beta3": 0.2,
        "beta4": 0.6,
        "beta5": 0.45,
        "beta6": 0.8,
        "beta7": 0.25,
        "beta_turn": 0.9,
        "stop_creep": 0.4,
    }
    rates = {
        "slip_speed": rng.uniform(truth["beta1"], 1.0, n),
        "slip_turn": rng.uniform(0, truth["beta2"], n),
        "hinder_speed": rng.uniform(truth["beta3"], 1.0, n),
        "hinder_turn": rng.uniform(truth["beta4"], 1.0, n),
        "push_speed": rng.uniform(0, truth["beta5"], n),
        "push_turn": rng.uniform(0, truth["beta6"], n),
        "stop_turn_unknown": rng.uniform(0, truth["beta7"], n),
        "stop_turn": rng.uniform(0, truth["beta_turn"], n),
        "stop_creep": rng.uniform(0, truth["stop_creep"], n),
    }
    # With every episode covered (coverage close to 1) the quantiles are the bounds themselves.
    fitted = fit_betas({k: list(v) for k, v in rates.items()}, coverage=0.999)
    for name in FITTED:
        assert fitted[name] == pytest.approx(truth[name], abs=0.01), name
    # At 95 % coverage each bound moves in by 5 % of its range.
    fitted = fit_betas({k: list(v) for k, v in rates.items()}, coverage=0.95)
    assert fitted["beta1"] == pytest.approx(0.3 + 0.05 * 0.7, abs=0.02)
    assert fitted["beta_turn"] == pytest.approx(0.95 * 0.9, abs=0.03)


def test_episode_rates_measure_the_simulated_stop_from_poses():
    share = 0.5
    scenario = CollisionScenario(
        duration=5.0,
        stop_turn=(share, share),
        step_noise=0.0,
        scale_sigma=0.0,
        turn_bias_sigma=0.0,
        events=(CollisionEvent(1.0, 3.0, STOPPED, LEFT, 0.5),),
    )
    log = simulate(scenario, 1)
    rates = episode_rates(log, np.ones(log.times.shape[0]))
    # c·ω / (|v| / w) for the model's w: the simulated share scaled by w_model / w_sim (a cycle's mean turn).
    assert rates["stop_turn"][0] == pytest.approx(share * FOOT_SEPARATION / scenario.foot_separation, rel=0.1)
    assert rates["stop_creep"][0] == pytest.approx(share / 2, rel=0.15)


def test_refused_fits_change_nothing():
    rates = {"slip_speed": [0.5]}
    before = json.dumps(rates)
    for coverage in (0.5, 1.0, 1.2, math.nan):
        with pytest.raises(ValueError, match="coverage"):
            fit_betas(rates, coverage)
    with pytest.raises(ValueError, match="no training episode"):
        fit_betas(rates, 0.95)
    assert json.dumps(rates) == before
    with pytest.raises(ValueError, match="stop_creep"):
        AdaptiveMotion(stop_creep=-0.1)


def test_defaults_are_the_fitted_values():
    fit = json.loads((ROOT / "results" / "adaptive_fit.json").read_text())
    model = AdaptiveMotion()
    for name in FITTED:
        expected = round(fit["fitted"][name], DIGITS)
        assert fit["defaults"][name] == expected
        if name == "stop_creep":  # the pivot variant's parameter; the paper's model keeps 0
            from demos.collision import PIVOT_CREEP

            assert PIVOT_CREEP == expected and model.stop_creep == 0.0
        else:
            assert getattr(model, name) == expected, name
    assert model.foot_separation == fit["foot_separation"]
    assert model.odometry == tuple(round(b, DIGITS) for b in fit["odometry"]) == tuple(fit["odometry_default"])
    # The episode ends of the "frequent" condition are the fitted ones; the other rates stay settings.
    assert fit["transitions"]["condition"] == "frequent"
    frequent = {f"{a}->{b}": rate for a, b, rate in MobilityTransitions().frequent}
    for name, rate in fit["transitions"]["rates"].items():
        assert frequent[name] == rate == round(fit["end_rates"]["frequent"][name.split("->")[0]], DIGITS), name


def test_episode_end_rates_are_the_maximum_likelihood_rates_of_the_chain():
    rng = np.random.default_rng(4)
    dt, rate = 0.01, 0.8  # 1/s: how fast a stop ends
    mode, total_stopped, ends = [], 0.0, 0
    for _ in range(300):
        free = int(rng.integers(50, 200))
        stopped = max(1, int(round(rng.exponential(1 / rate) / dt)))
        mode += [FREE] * free + [STOPPED] * stopped
        total_stopped += stopped * dt
        ends += 1
    mode += [FREE]
    log = dataclasses.replace(simulate(CollisionScenario(duration=0.05), 0), mode=np.array(mode, dtype=np.int8), dt=dt)
    percept = np.full(len(mode), 0.5)  # "frequent" throughout
    counted, exposure = episode_ends(log, percept)
    assert counted[CONDITIONS.index("frequent"), STOPPED] == ends
    # The time in the state is counted frame by frame before each change: every stopped frame once.
    assert exposure[CONDITIONS.index("frequent"), STOPPED] == pytest.approx(total_stopped)
    fitted = fit_end_rates(counted, exposure)
    assert fitted["frequent"]["stopped"] == pytest.approx(rate, rel=0.15)
    assert fitted["quiet"]["stopped"] is None  # no time there: no rate
    # Another condition sees none of it.
    counted, exposure = episode_ends(log, np.zeros(len(mode)))
    assert counted[CONDITIONS.index("frequent")].sum() == 0 and counted[CONDITIONS.index("quiet"), STOPPED] == ends


def test_fit_odometry_recovers_the_noise_of_eq_10_from_its_own_errors():
    rng = np.random.default_rng(6)
    dt, horizon, beta = 0.01, 5.0, (0.9, 0.5, 0.4, 0.4)
    n = 20000
    speed = rng.uniform(0.05, 0.3, n)
    mix = ODOMETRY_SHAPE[2] * speed
    gain = math.sqrt(dt * horizon / 3.0)
    factor_theta = beta[2] / ODOMETRY_SHAPE[2]
    errors = np.column_stack(
        [
            rng.normal(0, beta[0] * speed * gain),
            rng.normal(0, beta[1] * speed * gain),
            rng.normal(0, factor_theta * mix * gain),
            speed,
            mix,
        ]
    )
    fitted = fit_odometry(errors, dt, horizon, coverage=0.95)
    assert fitted[0] == pytest.approx(beta[0], rel=0.05) and fitted[1] == pytest.approx(beta[1], rel=0.05)
    assert fitted[2] == pytest.approx(beta[2], rel=0.05) and fitted[3] == pytest.approx(beta[2], rel=0.05)
    with pytest.raises(ValueError, match="no stretch"):
        fit_odometry(np.empty((0, 5)), dt, horizon)
    standing = errors.copy()
    standing[:, 3:] = 0.0
    with pytest.raises(ValueError, match="walks at all"):
        fit_odometry(standing, dt, horizon)


def test_free_walk_errors_are_zero_for_a_robot_that_walks_as_requested():
    scenario = CollisionScenario(
        duration=12.0, command=(0.2, 0.05, 0.3), scale_sigma=0.0, turn_bias_sigma=0.0, step_noise=0.0
    )
    log = simulate(scenario, 2)
    errors = free_walk_errors(log, np.zeros(log.times.shape[0]), horizon=5.0)
    assert errors.shape == (2, 5)
    np.testing.assert_allclose(errors[:, :3], 0.0, atol=1e-9)
    assert errors[0, 3] == pytest.approx(math.hypot(0.2, 0.05))
    # A collision percept anywhere in a stretch leaves it out.
    rate = np.zeros(log.times.shape[0])
    rate[700] = 0.1
    assert free_walk_errors(log, rate, horizon=5.0).shape == (1, 5)


def test_a_refused_fit_says_why():
    for horizon in (0.0, -1.0, math.nan, 1e6):
        with pytest.raises(ValueError, match="horizon"):
            fit([2000], minutes=0.5, horizon=horizon)


def test_the_baseline_widenings_are_the_tuned_ones():
    from demos.collision import BASELINE_WIDEN

    tuning = json.loads((ROOT / "results" / "collision_baseline_tuning.json").read_text())["baseline_tuning"]
    assert BASELINE_WIDEN == tuning["best"]


# Structural values a model may share with the simulator: nothing, a whole share, and the control rate.
STRUCTURAL = {0.0, 1.0, 100.0}


def test_no_model_default_is_a_simulator_constant():
    model_values = set()
    for obj in (AdaptiveMotion(), MobilityTransitions()):
        for f in dataclasses.fields(obj):
            model_values.update(_numbers(getattr(obj, f.name)))
    nominal = CollisionScenario()
    simulator_values = set()
    for f in dataclasses.fields(nominal):
        if f.name in ("field", "camera", "events", "held_joints"):  # objects, and joint indices (not physics)
            continue
        simulator_values.update(_numbers(getattr(nominal, f.name)))
    simulator_values.update(_numbers(MISMATCH_RANGES))
    assert len(simulator_values) > 40 and len(model_values) > 15
    shared = {v for v in model_values for s in simulator_values if math.isclose(v, s, rel_tol=1e-9, abs_tol=1e-12)}
    assert shared <= STRUCTURAL, f"model defaults equal to simulator constants: {sorted(shared - STRUCTURAL)}"


def test_the_simulator_does_not_import_the_models():
    for module in (collision_sim,):
        tree = ast.parse(Path(module.__file__).read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                assert not (node.module or "").startswith(("motion_models", "sensing")), node.module
                assert not {a.name for a in node.names} & {"AdaptiveMotion", "MobilityTransitions", "VelocityLinear"}
            elif isinstance(node, ast.Import):
                assert not any(a.name.startswith(("motion_models", "sensing")) for a in node.names)
    # walk_sim (the camera the simulator borrows) does not import them either.
    tree = ast.parse((ROOT / "demos" / "walk_sim.py").read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert not any((m or "").startswith("motion_models") for m in imported)


def test_detection_on_mismatched_robots_is_told_per_held_joint_subset():
    from demos.collision import detection_figures, robot_reference

    d = detection_figures(None, seeds=(4100, 4101), minutes=1.5, physics="mismatch")
    assert d["physics"] == "mismatch" and d["episodes"] > 0
    assert sum(row["episodes"] for row in d["by_held_joints"].values()) == d["episodes"]
    shares = [row["detected_share"] * row["episodes"] for row in d["by_held_joints"].values() if row["episodes"]]
    assert sum(shares) == pytest.approx(d["detected_share"] * d["episodes"])
    robots = {
        "+".join(collision_sim.JOINTS[j] for j in draw_physics(MISMATCH, seed).held_joints) for seed in (4100, 4101)
    }
    assert set(d["by_held_joints"]) == robots
    assert robot_reference.cache_info().currsize >= 2  # each robot's own reference
