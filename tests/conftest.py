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
# The suite compiles with LLVM at optimisation level 0 instead of XLA:CPU's default 2: most of its
# time is compiling programs it then runs for a few decisions, and a level-0 compile takes about 40 %
# less CPU time (the 64-game PT-HR playtest: 3.95 -> 2.46 s) while the program runs about 5x slower.
# Level 0 rounds floats differently from program to program, so the tests that compare the bits of
# two programs (the golden games, vmapped vs single arenas, sharded vs one device, a policy with
# weights vs the bound one) compile those at ``helpers.OPTIMIZED`` (level 1: the bits of the default
# level 2 that users run).
if "--xla_backend_optimization_level" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} --xla_backend_optimization_level=0".strip()

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
