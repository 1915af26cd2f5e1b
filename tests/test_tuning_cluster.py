"""The tuning study on a two-node Ray cluster on this machine (`ray.cluster_utils.Cluster`), and with a worker
that dies mid-task: the same study as on one local instance, every time."""

from __future__ import annotations

import os

import pytest

pytest.importorskip("ray")
pytestmark = pytest.mark.ray  # every test here starts Ray
pytest.importorskip("optuna")

from demos.battery import BatteryCase  # noqa: E402
from mcl.tools.tuning import SearchSpace, TuneSettings, run_study  # noqa: E402
from mcl.tools.tuning.search import CRASH_VARIABLE, start_ray  # noqa: E402

SETTINGS = TuneSettings(
    cases=(BatteryCase("tracking", 1, 12.0), BatteryCase("fall", 1, 12.0)),
    space=SearchSpace.from_toml(
        "[sensor]\noutlier_weight = { low = 0.002, high = 0.1, log = true }\n"
        "[motion]\nbeta1 = { low = 0.5, high = 4.0 }\n"
    ),
    objective="truth",
    trials=3,
    particles=100,
)


def history(outcome):
    return [(t["value"], tuple(sorted(t["values"].items()))) for t in outcome.trials]


@pytest.fixture(scope="module")
def reference():
    """The study on an embedded local instance with two workers."""
    import ray

    start_ray(None, workers=2)
    try:
        return history(run_study(SETTINGS))
    finally:
        ray.shutdown()


def test_a_two_node_cluster_gives_the_same_study(reference):
    import ray
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    cluster.add_node(num_cpus=1)
    try:
        info = start_ray(cluster.address)
        assert info["nodes"] == 2 and info["cpus"] == 2
        outcome = run_study(SETTINGS)
        assert history(outcome) == reference
        assert outcome.tasks.costs()["tasks"] == 3 * 2
    finally:
        ray.shutdown()
        cluster.shutdown()


def test_a_worker_that_dies_mid_task_is_retried_and_the_study_does_not_change(reference, tmp_path):
    import ray

    marker = tmp_path / "crashed"
    os.environ[CRASH_VARIABLE] = str(marker)  # the workers start with it and the first task kills its worker
    try:
        start_ray(None, workers=2)
        outcome = run_study(SETTINGS)
    finally:
        ray.shutdown()
        del os.environ[CRASH_VARIABLE]
    assert marker.exists()  # a worker did die
    assert history(outcome) == reference
