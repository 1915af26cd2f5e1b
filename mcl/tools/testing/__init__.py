"""Property-based testing for teams: hypothesis strategies, filter invariants and model contract checks.

This module imports hypothesis, which the library itself does not need: install the `test` extra first, from
the clone::

    pip install -e '.[test]'

What it offers, all public:

- Strategies (hypothesis) for the library's inputs: `fields`, `poses`, `pose_arrays`, `particle_sets`,
  `observations`, `edge_observations`, `camera_views`, `motion_inputs`, `hostile_motion_inputs`,
  `collision_percepts`, `footstep_events`, and `hostile_values` (what a refused call must reject).
- Invariants of a `mcl.ParticleFilter`, plain functions that raise AssertionError with a message naming what
  broke: `assert_weights_normalized`, `assert_poses_finite_and_wrapped`, `snapshot` and `assert_unchanged`,
  `assert_refused_leaves_state`, `assert_same_seed_same_run`.
- Contract checks of any motion or sensor model, the library's or a team's own: `check_motion_model` and
  `check_sensor_model` draw examples with hypothesis and run `assert_motion_contract` and
  `assert_sensor_contract` on each. They use a model only through the interface the filter uses (`check`,
  `predict`, `particle_state`; `check`, `log_likelihood`, `terms`), never its private attributes.

A team's tests, parametrized over its own models (each check runs its own hypothesis search, so call it from
a plain test function, not from inside another ``@given`` test)::

    import pytest
    from field import spl
    from mcl.tools import testing as mt
    from sensing import CombinedSensorModel, LandmarkSensorModel, LineSensorModel

    from our_robot.localization import OurOdometry, OurGoalModel

    FIELD = spl()
    MOTION_MODELS = [OurOdometry(), OurOdometry(noise=0.0)]
    SENSOR_MODELS = [OurGoalModel(FIELD), CombinedSensorModel((OurGoalModel(FIELD), LineSensorModel(FIELD)))]

    @pytest.mark.parametrize("model", MOTION_MODELS, ids=repr)
    def test_motion_model_contract(model):
        mt.check_motion_model(model, FIELD, strict=True)

    @pytest.mark.parametrize("model", SENSOR_MODELS, ids=repr)
    def test_sensor_model_contract(model):
        mt.check_sensor_model(model, FIELD)

`docs/testing.md` walks through a complete test file that also checks a configured filter.

Ranges. The strategies draw what a walking robot produces (commands up to 0.5 m/s, steps of a few
centimetres, detections within the carpet's diagonal); `hostile_motion_inputs` and `edge_observations` add
the extremes the library still accepts (a step of 99 m and 99 rad, ranges of 1000 m, bearings of 100 rad,
noises of 1e-6 and 1e3), and `hostile_values` what it refuses.
"""

from __future__ import annotations

from mcl.tools.testing.contracts import (
    ContractReport,
    assert_fused_likelihood,
    assert_motion_contract,
    assert_sensor_contract,
    check_motion_model,
    check_sensor_model,
)
from mcl.tools.testing.invariants import (
    FilterSnapshot,
    assert_poses_finite_and_wrapped,
    assert_refused_leaves_state,
    assert_same_seed_same_run,
    assert_unchanged,
    assert_weights_normalized,
    snapshot,
)
from mcl.tools.testing.registry import (
    ENTRY_POINT_GROUPS,
    RegisteredModel,
    RegisteredReport,
    check_registered,
    register_motion_model,
    register_sensor_model,
    registered_models,
    unregister,
)
from mcl.tools.testing.strategies import (
    REFUSALS,
    camera_views,
    collision_percepts,
    edge_observations,
    fields,
    footstep_events,
    hostile_motion_inputs,
    hostile_values,
    motion_inputs,
    observations,
    particle_sets,
    pose_arrays,
    poses,
)

__all__ = [
    "REFUSALS",
    # strategies
    "fields",
    "poses",
    "pose_arrays",
    "particle_sets",
    "observations",
    "edge_observations",
    "camera_views",
    "motion_inputs",
    "hostile_motion_inputs",
    "collision_percepts",
    "footstep_events",
    "hostile_values",
    # filter invariants
    "assert_weights_normalized",
    "assert_poses_finite_and_wrapped",
    "FilterSnapshot",
    "snapshot",
    "assert_unchanged",
    "assert_refused_leaves_state",
    "assert_same_seed_same_run",
    # model contracts
    "ContractReport",
    "assert_motion_contract",
    "assert_sensor_contract",
    "check_motion_model",
    "check_sensor_model",
    "assert_fused_likelihood",
    # registered models
    "ENTRY_POINT_GROUPS",
    "RegisteredModel",
    "RegisteredReport",
    "register_motion_model",
    "register_sensor_model",
    "unregister",
    "registered_models",
    "check_registered",
]
