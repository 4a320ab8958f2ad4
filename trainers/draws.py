"""Random draws for the learners: ``jax.random``'s numbers, drawn as one flat vector.

Why: under raidjax's recommended XLA flags (``raidjax.xla_flags``: XLA:CPU's classic LLVM IR
emitters, which compile the game step in about 60 % of the time) a draw of a multi-dimensional
shape compiles many times slower than a draw of the same number of values as a vector
(``jax.random.bits`` of shape ``(2, 16, 16)``: 1.2 s; of shape ``(512,)``: 0.09 s; 2-core CPU,
jax 0.10.2): the counter behind each value is built from one index per axis, and the classic
emitters unroll that. A learner draws its initial weights (a matrix per layer, vmapped over
seeds) and its sampled actions (``[arenas, players, actions]``) in every program it compiles:
drawing them flat took a 2-seed MA-POCA trainer's ``init`` from 5.2 s to 3.4 s of compiling.

The numbers are the same bit for bit: JAX's threefry gives the value at index ``(i, j)`` of a
``(H, W)`` draw the counter ``i * W + j``, the flat draw's counter at ``i * W + j`` (both with
``jax_threefry_partitionable``, the default, and without it). ``tests/test_draws.py`` compares
every function here with ``jax.random`` and ``jax.nn.initializers``.

Initialisers follow ``jax.nn.initializers``' signature ``init(key, shape, dtype) -> dtype[shape]``
and formulas (``variance_scaling``'s fans: the last axis is the output, the one before it the
input, the others receptive field).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

# The standard deviation of a standard normal truncated to (-2, 2) (jax.nn.initializers).
TRUNCATED_STD = 0.87962566103423978


def _flat(shape) -> tuple[int]:
    return (math.prod(shape),)


def normal(key: jax.Array, shape, dtype=jnp.float32) -> jax.Array:
    """``jax.random.normal(key, shape, dtype)``: ``dtype[shape]``."""
    return jax.random.normal(key, _flat(shape), dtype).reshape(shape)


def uniform(key: jax.Array, shape, dtype=jnp.float32, minval=0.0, maxval=1.0) -> jax.Array:
    """``jax.random.uniform(key, shape, dtype, minval, maxval)`` (scalar bounds): ``dtype[shape]``."""
    return jax.random.uniform(key, _flat(shape), dtype, minval, maxval).reshape(shape)


def truncated_normal(key: jax.Array, lower, upper, shape, dtype=jnp.float32) -> jax.Array:
    """``jax.random.truncated_normal(key, lower, upper, shape, dtype)`` (scalar bounds): ``dtype[shape]``."""
    return jax.random.truncated_normal(key, lower, upper, _flat(shape), dtype).reshape(shape)


def categorical(key: jax.Array, logits: jax.Array) -> jax.Array:
    """``jax.random.categorical(key, logits)`` over the last axis: ``[..., A] -> int32[...]``."""
    gumbel = jax.random.gumbel(key, _flat(logits.shape), logits.dtype).reshape(logits.shape)
    return jnp.argmax(gumbel + logits, axis=-1)


def _fans(shape) -> tuple[float, float]:
    receptive = math.prod(shape[:-2])
    return shape[-2] * receptive, shape[-1] * receptive


def variance_scaling(scale: float, mode: str, distribution: str):
    """``jax.nn.initializers.variance_scaling(scale, mode, distribution)`` for a kernel of 2 or
    more axes; ``mode``: ``"fan_in"``, ``"fan_out"`` or ``"fan_avg"``; ``distribution``:
    ``"truncated_normal"``, ``"normal"`` or ``"uniform"``."""
    if mode not in ("fan_in", "fan_out", "fan_avg"):
        raise ValueError(f"mode: value {mode!r}; allowed: 'fan_in', 'fan_out', 'fan_avg'")
    if distribution not in ("truncated_normal", "normal", "uniform"):
        raise ValueError(f"distribution: value {distribution!r}; allowed: 'truncated_normal', 'normal', 'uniform'")

    def init(key, shape, dtype=jnp.float32):
        fan_in, fan_out = _fans(shape)
        denominator = {"fan_in": fan_in, "fan_out": fan_out, "fan_avg": (fan_in + fan_out) / 2}[mode]
        variance = jnp.array(scale / denominator, dtype=dtype)
        if distribution == "truncated_normal":
            stddev = jnp.sqrt(variance) / jnp.array(TRUNCATED_STD, dtype)
            return truncated_normal(key, -2, 2, shape, dtype) * stddev
        if distribution == "normal":
            return normal(key, shape, dtype) * jnp.sqrt(variance)
        return uniform(key, shape, dtype, -1) * jnp.sqrt(3 * variance)

    return init


def lecun_normal():
    """``jax.nn.initializers.lecun_normal()``: flax ``Dense``'s default kernel initialiser."""
    return variance_scaling(1.0, "fan_in", "truncated_normal")


def xavier_uniform():
    """``jax.nn.initializers.xavier_uniform()``."""
    return variance_scaling(1.0, "fan_avg", "uniform")


def normal_init(stddev: float):
    """``jax.nn.initializers.normal(stddev)``."""

    def init(key, shape, dtype=jnp.float32):
        return normal(key, shape, dtype) * jnp.array(stddev, dtype)

    return init
