"""XLA:CPU settings that raidjax's own commands use, and that your scripts can opt into.

``import raidjax`` changes nothing in the process. raidjax's command lines (``raidjax ...``,
``python -m raidjax.calibrate``, the trainers, the benchmark pipelines, ``benchmarks/``) and its
test suite call ``use_recommended_xla_flags()`` before JAX starts; call it yourself first thing
in a script or notebook to get the same speed:

    import raidjax
    raidjax.use_recommended_xla_flags()   # before the first JAX computation

The flags (jaxlib >= 0.10; older jaxlibs lack them and XLA aborts on unknown flags):

1. ``--xla_cpu_experimental_ynn_fusion_type=``: XLA:CPU routes small reductions through YNNPACK
   fusions that are several times slower than its own loops for the tiny per-arena shapes of
   this simulator (measured: 71 k vs 120 k decisions/s at 4 096 arenas on 2 cores).
2. ``--xla_cpu_enable_concurrency_optimized_scheduler=false``: XLA:CPU's concurrency-optimised
   scheduler deadlocked on programs that vmap a scan of playtests (``lax.while_loop``) over
   several PPO-PCGRL learners: every thread parked on a futex and the step never returned
   (reproduced with 2 vmapped learners of the ``paper`` preset, in about half the runs; passing
   the option to that one compile instead, ``jax.jit(..., compiler_options=...)``, did not
   prevent it). ``trainers.ppo_pcgrl.make_train`` warns on CPU when it is missing.

GPU and TPU backends ignore both.
"""

from __future__ import annotations

import os
import warnings

RECOMMENDED = ("--xla_cpu_experimental_ynn_fusion_type=", "--xla_cpu_enable_concurrency_optimized_scheduler=false")


def _jaxlib_knows_them() -> bool:
    try:
        from importlib.metadata import version

        major, minor = (int(x) for x in version("jaxlib").split(".")[:2])
    except Exception:  # noqa: BLE001 - no jaxlib metadata: leave the flags alone
        return False
    return (major, minor) >= (0, 10)


def with_recommended(flags: str) -> str:
    """``flags`` (an ``XLA_FLAGS`` string) with every flag of ``RECOMMENDED`` that it does not set
    appended; a flag it already sets, to any value, is left as the user set it."""
    for flag in RECOMMENDED:
        if flag.split("=")[0] not in flags:
            flags = (flags + " " + flag).strip()
    return flags


def missing() -> list[str]:
    """The flags of ``RECOMMENDED`` that ``XLA_FLAGS`` does not set (empty on jaxlib < 0.10)."""
    if not _jaxlib_knows_them():
        return []
    current = os.environ.get("XLA_FLAGS", "")
    return [f for f in RECOMMENDED if f.split("=")[0] not in current]


def use_recommended_xla_flags() -> bool:
    """Add ``RECOMMENDED`` to ``os.environ["XLA_FLAGS"]`` for this process (flags you set win).

    Call it before the first JAX computation: XLA reads ``XLA_FLAGS`` once, when JAX starts its
    backend. ``RAIDJAX_KEEP_XLA_FLAGS=1`` turns it into a no-op (for raidjax's commands too).

    Returns:
        ``True`` if ``XLA_FLAGS`` now holds every recommended flag (or a value you set for it);
        ``False`` if nothing was changed: opted out, a jaxlib older than 0.10, or the backend had
        already started (then with a ``RuntimeWarning`` saying so).
    """
    if os.environ.get("RAIDJAX_KEEP_XLA_FLAGS") == "1" or not _jaxlib_knows_them():
        return False
    current = os.environ.get("XLA_FLAGS", "")
    wanted = with_recommended(current)
    if wanted == current:
        return True
    from jax._src import xla_bridge  # no public query for "has the backend started" in jax 0.4-0.10

    started = getattr(xla_bridge, "backends_are_initialized", lambda: False)()
    if started:
        warnings.warn("raidjax.use_recommended_xla_flags(): JAX's backend has already started, so XLA_FLAGS "
                      "can no longer change; call it before the first JAX computation", RuntimeWarning,
                      stacklevel=2)
        return False
    os.environ["XLA_FLAGS"] = wanted
    return True
