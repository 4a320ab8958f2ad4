"""XLA:CPU settings that raidjax's own commands use, and that your scripts can opt into.

``import raidjax`` changes nothing in the process. raidjax's command lines (``raidjax ...``,
``python -m raidjax.calibrate``, the trainers, the benchmark pipelines, ``benchmarks/``) and its
test suite call ``use_recommended_xla_flags()`` before JAX starts; call it yourself first thing
in a script or notebook to get the same speed:

    import raidjax
    raidjax.use_recommended_xla_flags()   # before the first JAX computation

The flags (each added only if the installed jaxlib's XLA accepts it: XLA aborts on unknown flags;
``known_flags`` asks XLA once per jaxlib):

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
   decisions/s; docs/results/speed.md). The golden games replay bit for bit with either.

A cost of 1 and 3 together: XLA:CPU splits some 2-D reductions into a reduce-window kernel
whose 32 x 32 window LLVM unrolls. Compiling ``jnp.sum(jnp.square(x))`` takes 1.6 s CPU for a
64 x 64 ``x`` and 9.6 s for 128 x 128 (32 x 32: 0.4 s; 256 x 256: 0.2 s; either flag alone: under
0.1 s). The trainers take their gradients' norms as dot products for that reason
(``trainers/gradients.py``): ``jnp.vdot(x, x)``, which flattens ``x`` so that XLA sums one
vector, compiles in under 0.1 s (as does ``jnp.sum(jnp.square(x.ravel()))``).

GPU and TPU backends ignore them.
"""

from __future__ import annotations

import functools
import json
import os
from pathlib import Path

from raidjax.files import atomic_write, cache_folder

RECOMMENDED = ("--xla_cpu_experimental_ynn_fusion_type=", "--xla_cpu_enable_concurrency_optimized_scheduler=false",
               "--xla_cpu_use_fusion_emitters=false")


def _jaxlib_id() -> str | None:
    """Which jaxlib is installed (version and folder), read without importing it; None if none."""
    import importlib.metadata
    import importlib.util

    try:
        spec = importlib.util.find_spec("jaxlib")
        return f"{importlib.metadata.version('jaxlib')} {list(spec.submodule_search_locations or [])}" if spec else None
    except (ImportError, ValueError):
        return None


def _probe(flags: tuple[str, ...]) -> tuple[str, ...]:
    """The ``flags`` that XLA:CPU accepts, asked of XLA itself: a child Python starts JAX's CPU
    backend with them; XLA aborts naming the flags it does not know, those are dropped and the
    rest asked again. A child that fails for any other reason gives none."""
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAX_PLATFORMS")}
    candidates = list(flags)
    while candidates:
        try:
            child = subprocess.run([sys.executable, "-c", "import jax; jax.devices('cpu')"], capture_output=True,
                                   text=True, timeout=300, env={**env, "JAX_PLATFORMS": "cpu",
                                                                "XLA_FLAGS": " ".join(candidates)})
        except (OSError, subprocess.SubprocessError):
            return ()
        if child.returncode == 0:
            return tuple(candidates)
        unknown = set(child.stderr.rpartition("in XLA_FLAGS:")[2].split())
        if not unknown & set(candidates):  # failed for another reason: add nothing
            return ()
        candidates = [f for f in candidates if f not in unknown]
    return ()


def _cache_file() -> Path:
    return cache_folder() / "xla_flags.json"


@functools.cache
def known_flags(flags: tuple[str, ...] = RECOMMENDED) -> tuple[str, ...]:
    """The ``flags`` (default ``RECOMMENDED``) that the installed jaxlib's XLA accepts, in order;
    none when no jaxlib is found.

    XLA aborts the whole process on a flag it does not know, and flags come and go between jaxlib
    releases (``--xla_cpu_use_fusion_emitters`` is gone in 0.11 although its name is still in the
    library), so the answer comes from XLA: a child process is started with them once per jaxlib
    (about 2 s) and the answer is kept in ``$XDG_CACHE_HOME/raidjax/xla_flags.json`` (default
    ``~/.cache``), then once per process in memory."""
    jaxlib = _jaxlib_id()
    if jaxlib is None:
        return ()
    key = f"{jaxlib} {' '.join(flags)}"
    cache = _cache_file()
    try:
        stored = json.loads(cache.read_text())
    except (OSError, ValueError):
        stored = {}
    if isinstance(stored, dict) and isinstance(stored.get(key), list):
        return tuple(f for f in flags if f in stored[key])
    known = _probe(flags)
    try:  # atomically: another process may be writing the same file
        atomic_write(cache, json.dumps({**(stored if isinstance(stored, dict) else {}), key: list(known)}))
    except OSError:  # an unwritable cache only costs the probe next time
        pass
    return known


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
        ``False`` if nothing was changed: opted out, or a jaxlib that knows none of them. Called after
        the backend started, the flags are set but unread (JAX's public API cannot tell that moment:
        raidjax uses no private module, and ``jax.live_arrays()`` would start the backend itself).
    """
    if os.environ.get("RAIDJAX_KEEP_XLA_FLAGS") == "1":
        return False
    current = os.environ.get("XLA_FLAGS", "")
    if with_recommended(current) == current:  # all set already (a child of a process that opted in)
        return True
    known = known_flags()
    if not known:
        return False
    wanted = with_recommended(current, known)
    if wanted == current:
        return True
    os.environ["XLA_FLAGS"] = wanted
    return True
