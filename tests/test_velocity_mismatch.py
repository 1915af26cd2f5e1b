"""The velocity experiment under model mismatch: the simulated robots drawn per run, the noise fit, the
separation between the simulator and the estimators' settings, and the robustness table."""

from __future__ import annotations

import ast
import dataclasses
import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import demos.biped as biped
from demos.biped import (
    DisturbanceParams,
    GaitParams,
    RobotVariation,
    SensorParams,
    _backlash,
    draw_robot,
    simulate_walk,
)
from proprioception.kinematics import NaoLegDimensions, nao_leg
from proprioception.velocity import VelocityEKFParams

ROOT = Path(__file__).resolve().parents[1]
CALM = DisturbanceParams(twist_probability=0.0, slip_probability=0.0)


# --- the robot of each run --------------------------------------------------------------------------------
def test_nominal_robot_is_the_drawings_and_the_datasheet():
    sensors = SensorParams()
    robot = draw_robot(3, sensors, RobotVariation.nominal())
    for leg in range(2):
        assert robot.dimensions[leg] == NaoLegDimensions()
    assert not robot.joint_offsets.any() and not robot.backlash.any()
    assert robot.accel_noise == sensors.accel_noise and robot.gyro_noise == sensors.gyro_noise
    assert robot.accel_bias_scale == 1.0 and robot.gyro_bias_scale == 1.0 and robot.gyro_bias_drift == 0.0
    np.testing.assert_array_equal(robot.accel_scale, 1.0)
    np.testing.assert_array_equal(robot.gyro_scale, 1.0)
    run = simulate_walk(2.0, 3, disturbances=CALM)  # the default is the nominal robot
    for leg, side in enumerate(("left", "right")):
        np.testing.assert_array_equal(run.true_chains[leg].a, nao_leg(side).a)


def test_draws_stay_in_their_ranges_and_use_them():
    variation = RobotVariation()
    published = np.array(NaoLegDimensions().as_tuple())
    factors, zeros, plays, noise = [], [], [], []
    for seed in range(40):
        robot = draw_robot(seed, SensorParams(), variation)
        factors.append([np.array(d.as_tuple()) / published for d in robot.dimensions])
        zeros.append(robot.joint_offsets)
        plays.append(robot.backlash)
        noise.append(robot.gyro_noise / SensorParams().gyro_noise)
        assert np.all(np.abs(robot.accel_scale - 1.0) <= variation.accel_scale_error)
        assert variation.gyro_bias_drift[0] <= robot.gyro_bias_drift <= variation.gyro_bias_drift[1]
    factors, zeros, plays = np.array(factors), np.array(zeros), np.array(plays)
    assert np.all(np.abs(factors - 1.0) <= variation.link_length_error + 1e-12)
    assert np.abs(factors - 1.0).max() > 0.9 * variation.link_length_error  # the range is used
    assert (
        np.all(np.abs(zeros) <= variation.joint_zero_error) and np.abs(zeros).max() > 0.9 * variation.joint_zero_error
    )
    assert np.all((plays >= variation.backlash[0]) & (plays <= variation.backlash[1]))
    assert min(noise) >= variation.gyro_noise_factor[0] and max(noise) <= variation.gyro_noise_factor[1]
    assert min(noise) < 0.8 and max(noise) > 1.5


def test_wider_chain_error_moves_the_same_robot_further():
    five, eight = RobotVariation().with_chain_error(0.05), RobotVariation().with_chain_error(0.08)
    assert eight.joint_zero_error == pytest.approx(math.radians(1.6))
    a, b = draw_robot(7, SensorParams(), five), draw_robot(7, SensorParams(), eight)
    published = np.array(NaoLegDimensions().as_tuple())
    np.testing.assert_allclose(
        (np.array(b.dimensions[0].as_tuple()) / published - 1.0),
        (np.array(a.dimensions[0].as_tuple()) / published - 1.0) * 0.08 / 0.05,
        rtol=1e-9,
    )
    np.testing.assert_allclose(b.joint_offsets, a.joint_offsets * 0.08 / 0.05, rtol=1e-9)
    assert a.gyro_noise == b.gyro_noise  # the rest of the draw is the same


def test_the_walk_and_its_noise_do_not_depend_on_the_variation_and_repeat_bit_for_bit():
    a = simulate_walk(3.0, 11, variation=RobotVariation())
    b = simulate_walk(3.0, 11, variation=RobotVariation())
    np.testing.assert_array_equal(a.gyro, b.gyro)
    np.testing.assert_array_equal(a.joint_angles, b.joint_angles)
    nominal = simulate_walk(3.0, 11)
    np.testing.assert_array_equal(a.trunk_position, nominal.trunk_position)
    assert not np.array_equal(a.joint_angles, nominal.joint_angles)  # other legs, other readings
    # The run's own legs put its trunk where the truth says; the estimators' legs (the drawings) do not.
    k, foot = 40, 0
    pose = a.true_chains[foot].forward(a.true_joint_angles[k, foot])
    assert not np.allclose(pose, nao_leg("left").forward(a.true_joint_angles[k, foot]), atol=1e-4)


def test_backlash_is_a_play_operator():
    angles = np.concatenate([np.linspace(0.0, 0.1, 11), np.linspace(0.1, 0.0, 11)[1:]])[:, None, None]
    angles = np.broadcast_to(angles, (angles.shape[0], 2, 6)).copy()
    play = np.full((2, 6), 0.02)
    read = _backlash(angles, play)
    assert read[0, 0, 0] == 0.0
    assert read[10, 0, 0] == pytest.approx(0.09)  # lags by half the play going up
    assert read[11, 0, 0] == pytest.approx(0.09)  # and stays put at the reversal
    assert read[-1, 0, 0] == pytest.approx(0.01)  # then lags going down
    np.testing.assert_array_equal(_backlash(angles, np.zeros((2, 6))), angles)


def test_bad_variations_are_refused():
    with pytest.raises(ValueError, match="link_length_error"):
        RobotVariation(link_length_error=-0.01)
    with pytest.raises(ValueError, match="backlash"):
        RobotVariation(backlash=(0.01, 0.0))
    with pytest.raises(ValueError, match="gyro_noise_factor"):
        RobotVariation(gyro_noise_factor=(math.nan, 1.0))
    with pytest.raises(ValueError, match="variation"):
        simulate_walk(2.0, 0, variation="wide")
    with pytest.raises(ValueError, match="foot_height"):
        NaoLegDimensions(foot_height=0.0)
    with pytest.raises(ValueError, match="factors"):
        NaoLegDimensions().scaled([1.0, 1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="joint_offsets"):
        nao_leg("left", joint_offsets=[0.0] * 5)


# --- the simulator shares nothing with the estimators' settings -------------------------------------------
STRUCTURAL = {
    0.0,
    1.0,  # nothing, one
    biped.GRAVITY,  # gravity
    100.0,
    30.0,  # the IMU and kinematics rates, both the simulator's and the robot's
}
LIMITS = ("max_imu_gap", "max_prediction_time")
"""VelocityEKFParams fields that are input checks (the IMU gap refused, when a filter is stale), not a model of
the robot; they are not compared."""


def _numbers(value) -> list[float]:
    if isinstance(value, bool):
        return []
    if isinstance(value, (int, float)):
        return [float(value)]
    if isinstance(value, np.ndarray):
        return [float(v) for v in value.ravel()]
    if isinstance(value, (tuple, list)):
        return [x for v in value for x in _numbers(v)]
    if dataclasses.is_dataclass(value):
        return [x for f in dataclasses.fields(value) for x in _numbers(getattr(value, f.name))]
    return []


def simulator_constants() -> list[float]:
    """Every numeric constant, nominal parameter and range endpoint of the simulator."""
    numbers = []
    for obj in (
        SensorParams(),
        RobotVariation(),
        RobotVariation.nominal(),
        DisturbanceParams(),
        GaitParams(),
        NaoLegDimensions(),
    ):
        numbers += _numbers(obj)
    for name in dir(biped):
        if name.isupper():
            numbers += _numbers(getattr(biped, name))
    for error in (0.02, 0.05, 0.08):
        numbers += _numbers(RobotVariation().with_chain_error(error))
    return numbers


def model_settings() -> dict[str, float]:
    """The numeric settings of the EKF: the library's defaults and every fitted filter of the results file."""
    from demos.velocity import EKF_VARIANTS, ekf_params_for, load_fit

    settings = {}
    fit = load_fit()
    for label, params in [("default", VelocityEKFParams())] + [(v, ekf_params_for(fit, v)) for v in EKF_VARIANTS]:
        for f in dataclasses.fields(params):
            value = getattr(params, f.name)
            if f.name not in LIMITS and not isinstance(value, bool):
                settings[f"{label}.{f.name}"] = float(value)
    return settings


def test_no_model_setting_equals_a_simulator_constant():
    constants = [c for c in simulator_constants() if c not in STRUCTURAL]
    assert len(constants) > 50
    for name, value in model_settings().items():
        assert value not in STRUCTURAL, name
        clashes = [c for c in constants if math.isclose(abs(value), abs(c), rel_tol=1e-6)]
        assert not clashes, f"{name} = {value} equals a simulator constant"


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            names.add(node.module or "")
            names.update(f"{node.module}.{alias.name}" for alias in node.names)
    return names


def test_the_simulator_does_not_import_the_estimators_settings():
    path = ROOT / "demos" / "biped.py"
    imported = _imports(path)
    for forbidden in ("proprioception.velocity", "demos.velocity", "demos.fit_velocity"):
        assert not any(name == forbidden or name.startswith(forbidden + ".") for name in imported), forbidden
    assert not any(name.endswith(("VelocityEKFParams", "ekf_params_for", "load_fit")) for name in imported)
    assert "ekf_fit" not in path.read_text(encoding="utf-8")


def test_the_demo_takes_its_noise_settings_from_the_fit_file():
    from demos.velocity import EKF_VARIANTS, FIT_PATH, VARIANT_SETTINGS, default_variants

    fit = json.loads(FIT_PATH.read_text(encoding="utf-8"))
    for name, params in default_variants().items():
        assert dataclasses.asdict(params) == fit["variants"][name]
    paper = default_variants()["ekf"]
    assert paper.estimate_gyro_bias is False and paper.exact_jacobian is False
    assert VARIANT_SETTINGS["ekf"]["zero_gyro"] is False  # the raw gyro, as in the paper
    assert set(EKF_VARIANTS) == set(fit["variants"])
    assert not set(fit["training_seeds"]) & set(range(1000, 1012))


# --- the fit ----------------------------------------------------------------------------------------------
def fake_standing(n_walks, n_samples, accel_noise, gyro_noise, gyro_bias, rng):
    runs = []
    for _ in range(n_walks):
        bias = rng.normal(0.0, gyro_bias, 3)
        runs.append(
            SimpleNamespace(
                imu_time=np.arange(n_samples + 5) * 0.01,
                gait=SimpleNamespace(stand_time=n_samples * 0.01 - 1e-9),
                accel=np.array([0.3, -0.2, 9.7]) + rng.normal(0.0, accel_noise, (n_samples + 5, 3)),
                gyro=bias + rng.normal(0.0, gyro_noise, (n_samples + 5, 3)),
            )
        )
    return runs


def test_standing_statistics_recover_the_noise_they_were_made_with():
    from demos.fit_velocity import standing_statistics

    rng = np.random.default_rng(5)
    stats = standing_statistics(fake_standing(200, 100, 0.03, 0.004, 0.02, rng))
    assert stats["accel_noise"] == pytest.approx(0.03, rel=0.03)
    assert stats["gyro_noise"] == pytest.approx(0.004, rel=0.03)
    assert stats["gyro_bias_spread"] == pytest.approx(0.02, rel=0.1)
    assert stats["gyro_rms_raw"] == pytest.approx(math.hypot(0.02, 0.004), rel=0.1)
    with pytest.raises(ValueError, match="at least one"):
        standing_statistics([])
    with pytest.raises(ValueError, match="at least 10"):
        standing_statistics(fake_standing(1, 5, 0.03, 0.004, 0.02, rng))


def test_the_fit_picks_the_best_setting_of_its_grid_on_the_training_walks():
    from demos.fit_velocity import fit_noise

    runs = [simulate_walk(5.0, seed, variation=RobotVariation()) for seed in (100, 101)]
    fit = fit_noise(runs)
    assert fit_noise(runs) == fit  # same walks, same fit
    for name, grid in fit["grid"].items():
        assert len(grid) == 24
        best = min(grid, key=lambda g: g["mean_error_percent"])
        assert fit["variants"][name]["velocity_noise"] == best["velocity_noise"]
        assert np.mean(fit["training_error_percent"][name]) == pytest.approx(best["mean_error_percent"])
        VelocityEKFParams(**fit["variants"][name])  # a valid setting


# --- refusals ---------------------------------------------------------------------------------------------
def test_refused_calls_change_nothing(tmp_path, capsys):
    from demos.velocity import ekf_params_for, load_fit, main

    with pytest.raises(ValueError, match="robocup-mcl fit ekf"):
        load_fit(tmp_path / "missing.json")
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(ValueError, match="variants"):
        load_fit(tmp_path / "bad.json")
    with pytest.raises(ValueError, match="variant"):
        ekf_params_for(None, "ekf+scale")
    with pytest.raises(ValueError, match="fit must be"):
        ekf_params_for(SensorParams(), "ekf")
    save = tmp_path / "table.json"
    with pytest.raises(SystemExit):
        main(["--mismatch", "--seed", "105", "--save", str(save)])  # training seeds are refused
    assert "training seeds" in capsys.readouterr().err
    assert not save.exists()


def test_mismatch_table_is_deterministic_and_complete():
    from demos.velocity import EKF_VARIANTS, format_mismatch, mismatch_table

    levels = (("nominal", None), ("links +-8 %", 0.08))
    a = mismatch_table([1000], 5.0, levels=levels)
    assert a == mismatch_table([1000], 5.0, levels=levels)
    for level in ("nominal", "links +-8 %"):
        block = a["levels"][level]
        assert set(block["summary"]) == set(a["estimators"])
        assert set(block["ekf_below_kinematics_gyro"]) == set(EKF_VARIANTS)
    text = format_mismatch(a)
    assert "ekf (paper)" in text and "ekf variant: + gyro bias state" in text and "links +-8 %" in text


def test_library_defaults_are_the_fitted_bias_state_filter():
    from demos.fit_velocity import NOISE_FIELDS
    from demos.velocity import load_fit

    fitted = load_fit()["variants"]["ekf+bias"]
    defaults = VelocityEKFParams()
    for name in NOISE_FIELDS:
        assert getattr(defaults, name) == float(f"{fitted[name]:.3g}"), name
