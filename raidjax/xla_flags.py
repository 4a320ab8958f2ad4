"""XLA:CPU settings that raidjax's own commands use, and that your scripts can opt into.

``import raidjax`` changes nothing in the process. raidjax's command lines (``raidjax ...``,
``python -m raidjax.calibrate``, the trainers, the benchmark pipelines, ``benchmarks/``) and its
test suite call ``use_recommended_xla_flags()`` before JAX starts; call it yourself first thing
in a script or notebook to get the same speed:

    import raidjax
    raidjax.use_recommended_xla_flags()   # before the first JAX computation

The flags (each added only if the installed jaxlib knows it: XLA aborts on unknown flags):

1. ``--xla_cpu_experimental_ynn_fusion_type=``: XLA:CPU routes small reductions through YNNPACK
   fusions that are several times slower than its own loops for the tiny per-arena shapes of
   this simulator (measured: 71 k vs 120 k decisions/s at 4 096 arenas on 2 cores).
2. ``--xla_cpu_enable_concurrency_optimized_scheduler=false``: XLA:CPU's concurrency-optimised
   scheduler deadlocked on programs that vmap a scan of playtests (``lax.while_loop``) over
   several PPO-PCGRL learners: every thread parked on a futex and the step never returned
   (reproduced with 2 vmapped learners of the ``paper`` preset, in about half the runs; passing
   the option to that one compile instead, ``jax.jit(..., compiler_options=...)``, did not
   prevent it). ``trainers.ppo_pcgrl.make_train`` warns on CPU when it is missing.
3. ``--xla_cpu_use_fusion_emitters=false``: XLA:CPU's MLIR fusion emitters compile each of the
   step's ~450 fused operations through its own MLIR pipeline; its classic LLVM IR emitters
   compile the step in about 60 % of the time (measured: 11.5 s -> 6.6 s) and run it at least as
   fast (per-arena rollouts at 4 096 arenas on 2 cores, medians of 3: 44 769 -> 51 371
   decisions/s; docs/RESULTS.md). The golden games replay bit for bit with either.

GPU and TPU backends ignore them.
"""

from __future__ import annotations

import functools
import mmap
import os
import warnings
from pathlib import Path

RECOMMENDED = ("--xla_cpu_experimental_ynn_fusion_type=", "--xla_cpu_enable_concurrency_optimized_scheduler=false",
               "--xla_cpu_use_fusion_emitters=false")


@functools.cache
def known_flags(flags: tuple[str, ...] = RECOMMENDED) -> tuple[str, ...]:
    """The ``flags`` (default ``RECOMMENDED``) that the installed jaxlib defines (its XLA library
    names them), in order; none when no jaxlib library is found. Reads the libraries' bytes without
    loading them (a few tens of ms, once per process)."""
    try:
        import importlib.util

        spec = importlib.util.find_spec("jaxlib")
        libs = [p for d in (spec.submodule_search_locations or []) for p in Path(d).glob("*.so")] if spec else []
    except Exception:  # noqa: BLE001 - no jaxlib to read: leave the flags alone
        return ()
    found = set()
    for lib in libs:
        try:
            with open(lib, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as m:
                found.update(flag for flag in flags if m.find(flag.split("=")[0][2:].encode()) >= 0)
        except (OSError, ValueError):  # unreadable or empty file
            continue
    return tuple(f for f in flags if f in found)


def with_recommended(flags: str, recommended: tuple[str, ...] = RECOMMENDED) -> str:
    """``flags`` (an ``XLA_FLAGS`` string) with every flag of ``recommended`` that it does not set
    appended; a flag it already sets, to any value, is left as the user set it."""
    for flag in recommended:
        if flag.split("=")[0] not in flags:
            flags = (flags + " " + flag).strip()
    return flags


def missing() -> list[str]:
    """The flags of ``RECOMMENDED`` known to the installed jaxlib that ``XLA_FLAGS`` does not set."""
    current = os.environ.get("XLA_FLAGS", "")
    return [f for f in known_flags() if f.split("=")[0] not in current]


def use_recommended_xla_flags() -> bool:
    """Add ``RECOMMENDED`` to ``os.environ["XLA_FLAGS"]`` for this process (flags you set win).

    Call it before the first JAX computation: XLA reads ``XLA_FLAGS`` once, when JAX starts its
    backend. ``RAIDJAX_KEEP_XLA_FLAGS=1`` turns it into a no-op (for raidjax's commands too).

    Returns:
        ``True`` if ``XLA_FLAGS`` now holds every recommended flag (or a value you set for it);
        ``False`` if nothing was changed: opted out, a jaxlib that knows none of them, or the backend had
        already started (then with a ``RuntimeWarning`` saying so).
    """
    if os.environ.get("RAIDJAX_KEEP_XLA_FLAGS") == "1" or not known_flags():
        return False
    current = os.environ.get("XLA_FLAGS", "")
    wanted = with_recommended(current, known_flags())
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
