"""Shared test settings: hypothesis profiles, and small fixtures.

"ci" (the default) draws the same 60 examples per property on every run, so a red CI always means a
change did it; "thorough" (HYPOTHESIS_PROFILE=thorough) draws 1 000 fresh ones to explore.
"""
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

settings.register_profile("ci", max_examples=60, deadline=None, derandomize=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("thorough", max_examples=1000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture(scope="session")
def spl_field():
    from field import spl
    return spl()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
