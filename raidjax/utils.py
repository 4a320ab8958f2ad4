"""Small array helpers that stay fast under ``vmap`` on CPU, and host-side helpers shared by the
simulator, trainers and experiments: ``atomic_write`` (every file a user keeps), ``machine`` and
``fmt_seconds`` (reports and progress lines)."""

from __future__ import annotations

import os
import platform
import tempfile
from pathlib import Path

import jax
import jax.numpy as jnp


def pick(x: jax.Array, idx: jax.Array) -> jax.Array:
    """``x[idx]`` along axis 0.

    Args:
        x: ``[N, ...]`` array (bool arrays come back as bool).
        idx: integer array of any shape ``I`` with values in ``[0, N)``.

    Returns:
        ``[*I, ...]`` array.
    """
    return jnp.take(x, idx, axis=0, mode="clip")


def contract(weights: jax.Array, x: jax.Array) -> jax.Array:
    """``weights @ x`` over ``x``'s first axis as multiply-and-sum, which XLA CPU fuses; tiny
    batched matmuls are slow there.

    Args:
        weights: ``[*I, N]``; x: ``[N, ...]``.

    Returns:
        ``[*I, ...]`` (bool if ``x`` is bool).
    """
    xf = x.astype(jnp.float32)
    w = weights.reshape(weights.shape + (1,) * (x.ndim - 1))
    out = jnp.sum(w * xf, axis=weights.ndim - 1)
    return out > 0.5 if x.dtype == jnp.bool_ else out.astype(x.dtype)


def uniform_dice(key: jax.Array, shape: tuple[int, ...]) -> jax.Array:
    """Uniform ``float32[shape]`` in [0, 1) from a counter hash seeded by ``key``.

    Two words come from the key; every element is then a murmur3-finalised hash of its
    index, which is far cheaper than threefry per element and good enough for game dice.
    """
    seed = jax.random.bits(key, (2,), jnp.uint32)
    n = 1
    for d in shape:
        n *= d
    x = jnp.arange(n, dtype=jnp.uint32) * jnp.uint32(0x9E3779B1) + seed[0]
    x = x ^ (x >> 16)
    x = x * jnp.uint32(0x85EBCA6B) ^ seed[1]
    x = x ^ (x >> 13)
    x = x * jnp.uint32(0xC2B2AE35)
    x = x ^ (x >> 16)
    return ((x >> 8).astype(jnp.float32) * (1.0 / (1 << 24))).reshape(shape)


def machine(load: bool = False) -> dict:
    """A JSON-able description of the JAX device and the host: ``platform``, ``device``,
    ``cpu_count``, ``processor``, ``jax`` version, and with ``load`` the 1-minute load average
    (``load_average_1m``; timings on a shared machine depend on it)."""
    dev = jax.devices()[0]
    out = {"platform": dev.platform, "device": str(dev.device_kind), "cpu_count": os.cpu_count(),
           "processor": platform.processor() or platform.machine(), "jax": jax.__version__}
    if load:
        out["load_average_1m"] = round(os.getloadavg()[0], 2)
    return out


def fmt_seconds(s: float) -> str:
    """A duration for progress lines: ``"1h02m"``, ``"3m07s"`` or ``"12s"``."""
    if s >= 3600:
        return f"{int(s // 3600)}h{int(s % 3600 // 60):02d}m"
    return f"{int(s // 60)}m{int(s % 60):02d}s" if s >= 60 else f"{s:.0f}s"


def atomic_write(path: str | Path, data: str | bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and ``os.replace``, so
    a reader sees the old file or the new one, never half of one. Returns ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data.encode() if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; give the file the usual mode
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
