"""Shared fixtures and settings. Heavy compiled callables live in ``helpers`` (module level) so
that every test file shares one compilation of ``reset`` / ``step``."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, settings

import raidjax

settings.register_profile(
    "raidjax", max_examples=15, deadline=None, derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.load_profile("raidjax")


@pytest.fixture(scope="session")
def ref_params() -> raidjax.Params:
    """The reference content (three mages with MagicMissile at range 5 against the Dragon)."""
    return raidjax.make_params()
