"""Shared fixtures and settings. Heavy compiled callables live in ``helpers`` (module level) so
that every test file shares one compilation of ``reset`` / ``step``."""

from __future__ import annotations

import os
from pathlib import Path

# One persistent XLA compilation cache for the test session, shared by both pytest-xdist workers
# and by the command lines the CLI and fault-injection tests start as subprocesses (they inherit
# these variables): most of the suite's time is compiling, often the same programs. Set before
# JAX is imported, which reads them once.
os.environ.setdefault("JAX_COMPILATION_CACHE_DIR",
                      str(Path(__file__).resolve().parent.parent / ".pytest_cache" / "jax_compilation_cache"))
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES", "0")

import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

import raidjax  # noqa: E402

# The suite runs with the flags raidjax's commands use (subprocesses inherit them); importing
# raidjax does not set them, and this runs before any test's first JAX computation.
raidjax.use_recommended_xla_flags()

settings.register_profile(
    "raidjax", max_examples=15, deadline=None, derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.load_profile("raidjax")


@pytest.fixture(scope="session")
def ref_params() -> raidjax.Params:
    """The reference content (three mages with MagicMissile at range 5 against the Dragon)."""
    return raidjax.make_params()
