"""Small array helpers that stay fast under ``vmap`` on CPU: ``pick`` and ``contract`` (gathers as
contractions) and ``uniform_dice`` (cheap per-element game dice). Pure JAX; host-side helpers
(files, command lines, reports) live in ``raidjax.io``."""

from __future__ import annotations

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
