"""CPU compiler setting applied when raidjax is imported (before JAX starts its backend).

XLA:CPU in jaxlib 0.10 routes small reductions through YNNPACK fusions that are several times
slower than its own loops for the tiny per-arena shapes of this simulator (measured: 71k vs
120k decisions/s at 4096 arenas). We switch them off unless the user set the flag, or sets
``RAIDJAX_KEEP_XLA_FLAGS=1``. Older jaxlibs lack the flag (and XLA aborts on unknown flags),
so it is only added from jaxlib 0.10 on.
"""

from __future__ import annotations

import os

FLAG = "--xla_cpu_experimental_ynn_fusion_type="


def apply() -> None:
    """Append ``FLAG`` to ``XLA_FLAGS`` when safe; a no-op otherwise."""
    if os.environ.get("RAIDJAX_KEEP_XLA_FLAGS") == "1":
        return
    flags = os.environ.get("XLA_FLAGS", "")
    if "ynn_fusion_type" in flags:
        return
    try:
        from importlib.metadata import version

        major, minor = (int(x) for x in version("jaxlib").split(".")[:2])
    except Exception:  # noqa: BLE001 - no jaxlib metadata: leave the flags alone
        return
    if (major, minor) >= (0, 10):
        os.environ["XLA_FLAGS"] = (flags + " " + FLAG).strip()
