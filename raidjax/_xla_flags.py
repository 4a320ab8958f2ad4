"""CPU compiler settings applied when raidjax is imported (before JAX starts its backend).

1. XLA:CPU in jaxlib 0.10 routes small reductions through YNNPACK fusions that are several
   times slower than its own loops for the tiny per-arena shapes of this simulator (measured:
   71k vs 120k decisions/s at 4096 arenas): ``--xla_cpu_experimental_ynn_fusion_type=``.
2. XLA:CPU's concurrency-optimised scheduler deadlocks on programs that vmap a scan of
   playtests (``lax.while_loop``) over several PPO-PCGRL learners: every thread parks on a
   futex and the step never returns (reproduced with 2 vmapped learners of the ``paper``
   preset; ``tests/test_pcg.py`` guards it): ``--xla_cpu_enable_concurrency_optimized_scheduler=false``.

Each flag is added unless the user already set it, or sets ``RAIDJAX_KEEP_XLA_FLAGS=1``. Older
jaxlibs may lack the flags (and XLA aborts on unknown flags), so they are only added from jaxlib
0.10 on.
"""

from __future__ import annotations

import os

FLAGS = ("--xla_cpu_experimental_ynn_fusion_type=", "--xla_cpu_enable_concurrency_optimized_scheduler=false")


def apply() -> None:
    """Append the missing ``FLAGS`` to ``XLA_FLAGS`` when safe; a no-op otherwise."""
    if os.environ.get("RAIDJAX_KEEP_XLA_FLAGS") == "1":
        return
    try:
        from importlib.metadata import version

        major, minor = (int(x) for x in version("jaxlib").split(".")[:2])
    except Exception:  # noqa: BLE001 - no jaxlib metadata: leave the flags alone
        return
    if (major, minor) < (0, 10):
        return
    flags = os.environ.get("XLA_FLAGS", "")
    for flag in FLAGS:
        if flag.split("=")[0] not in flags:
            flags = (flags + " " + flag).strip()
    os.environ["XLA_FLAGS"] = flags
