"""Spreading independent games, arenas or runs over every visible device, with JAX's own sharding.

A batch axis whose entries never interact (the games of a playtest, the arenas of a rollout,
the seeds of a training run) is split evenly over all devices ``jax.devices()`` returns: the
GPUs of this machine, or of every host after ``jax.distributed.initialize()``. Nothing else
changes: the same program, keys and inputs give the same numbers on one device or many (random
draws use JAX's partitionable threefry, the default since JAX 0.5). A batch that does not
divide evenly, or a single device, stays where it is.

    XLA_FLAGS=--xla_force_host_platform_device_count=4 python ...   # try it on CPU
"""

from __future__ import annotations

import jax
from jax.sharding import NamedSharding, PartitionSpec

AXIS = "batch"


def batch_sharding(n: int) -> NamedSharding | None:
    """The sharding that splits a leading axis of size ``n`` over every device, or ``None`` when
    there is one device or ``n`` is not a multiple of the device count."""
    devices = jax.devices()
    if len(devices) == 1 or n % len(devices):
        return None
    return NamedSharding(jax.sharding.Mesh(devices, (AXIS,)), PartitionSpec(AXIS))


def shard_batch(tree, n: int):
    """Inside ``jit``: constrain every leaf of ``tree`` with leading axis ``n`` to be split over the
    devices along it (``batch_sharding``); leaves without that axis and single-device runs are
    returned unchanged.

    Args:
        tree: a pytree of arrays, most with leading axis ``n``.
        n: the batch size.

    Returns:
        ``tree``, with sharding constraints where they apply.
    """
    sharding = batch_sharding(n)
    if sharding is None:
        return tree

    def one(x):
        if getattr(x, "ndim", 0) >= 1 and x.shape[0] == n and not jax.dtypes.issubdtype(x.dtype, jax.dtypes.prng_key):
            return jax.lax.with_sharding_constraint(x, sharding)
        return x

    return jax.tree.map(one, tree)


def put_batch(tree, n: int):
    """Outside ``jit``: place every leaf of ``tree`` with leading axis ``n`` split over the devices
    (``batch_sharding``), so that a program jitted on it (seeds or runs of a trainer, vmapped)
    runs spread over all of them; single-device runs and uneven counts are returned unchanged.

    Args:
        tree: a pytree of arrays (e.g. a trainer's vmapped state, leading axis ``n``).
        n: the batch size.

    Returns:
        ``tree`` on the devices.
    """
    sharding = batch_sharding(n)
    if sharding is None:
        return tree
    replicated = NamedSharding(sharding.mesh, PartitionSpec())
    return jax.tree.map(lambda x: jax.device_put(x, sharding if getattr(x, "ndim", 0) >= 1 and x.shape[0] == n
                                                 else replicated), tree)
