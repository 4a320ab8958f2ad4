"""Game dice: ``uniform_dice`` / ``hash_dice`` (cheap per-element hashes) and ``dice_seeds``. Pure
JAX; host-side helpers (files, command lines, reports) live in ``raidjax.io``; array helpers for the
lane layout in ``raidjax.lanes``."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np


def traced_once(fn):
    """``fn`` through ``jax.jit``: JAX keeps its traced program per argument shapes (and static
    content such as ``EnvConfig``), so each program of a process that calls it again, under ``vmap``,
    ``scan`` or another ``jit``, reuses that trace instead of running the Python again; tracing the
    game is a large part of compiling a program that plays it. XLA inlines the nested call, so the
    compiled program is the same; called eagerly, ``fn`` runs as one compiled program."""
    return jax.jit(fn)


def dice_seeds(key: jax.Array) -> jax.Array:
    """The two ``uint32`` words ``hash_dice`` hashes with: ``uint32[2]`` from ``key``."""
    return jax.random.bits(key, (2,), jnp.uint32)


def hash_dice(seeds: jax.Array, index) -> jax.Array:
    """Uniform ``float32[*I, ...]`` in [0, 1): a murmur3-finalised hash of every die's ``index``
    (numpy ``[*I]``, the same in every lane, or ``uint32[*I, ...]``), seeded by ``seeds: uint32[2, ...]``
    (trailing lanes, ``raidjax.lanes``, come out trailing). Far cheaper than threefry per element and
    good enough for game dice.
    """
    if isinstance(index, np.ndarray):  # the same indices in every lane
        index = jnp.asarray(index.astype(np.uint32).reshape(index.shape + (1,) * (seeds.ndim - 1)))
    x = index * jnp.uint32(0x9E3779B1) + seeds[0]
    x = x ^ (x >> 16)
    x = x * jnp.uint32(0x85EBCA6B) ^ seeds[1]
    x = x ^ (x >> 13)
    x = x * jnp.uint32(0xC2B2AE35)
    x = x ^ (x >> 16)
    return (x >> 8).astype(jnp.float32) * (1.0 / (1 << 24))


def uniform_dice(key: jax.Array, shape: tuple[int, ...]) -> jax.Array:
    """Uniform ``float32[shape]`` in [0, 1): ``hash_dice`` seeded from ``key``."""
    return hash_dice(dice_seeds(key), np.arange(math.prod(shape), dtype=np.uint32).reshape(shape))
