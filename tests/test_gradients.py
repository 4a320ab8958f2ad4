"""The trainers' gradient norm and clip (trainers/gradients.py) against optax's, on a tree shaped as a
reference network's gradients (a 128 x 128 kernel, a vector, a scalar)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from trainers.gradients import clip_by_global_norm, global_norm


def _tree(key, scale):
    k1, k2, k3 = jax.random.split(key, 3)
    return {"kernel": scale * jax.random.normal(k1, (128, 128)), "bias": scale * jax.random.normal(k2, (128,)),
            "head": {"w": scale * jax.random.normal(k3, (1,))}}


@pytest.mark.parametrize("scale", [1e-4, 1.0, 30.0])
def test_global_norm_is_optax_norm_to_rounding(scale):
    tree = _tree(jax.random.key(0), scale)
    ours, theirs = jax.jit(global_norm)(tree), jax.jit(optax.tree.norm)(tree)
    assert ours.dtype == jnp.float32 and ours.shape == ()
    np.testing.assert_allclose(ours, theirs, rtol=1e-6)
    exact = np.sqrt(sum(np.sum(np.square(np.asarray(x, np.float64))) for x in jax.tree.leaves(tree)))
    np.testing.assert_allclose(ours, exact, rtol=1e-6)


@pytest.mark.parametrize("max_norm", [0.5, 1e6])
def test_clip_is_optax_clip_to_rounding(max_norm):
    tree = _tree(jax.random.key(1), 1.0)  # global norm about 128
    ours, state = jax.jit(clip_by_global_norm(max_norm).update)(tree, clip_by_global_norm(max_norm).init(tree))
    theirs, _ = jax.jit(optax.clip_by_global_norm(max_norm).update)(tree, optax.EmptyState())
    assert state == optax.EmptyState()
    for a, b, g in zip(jax.tree.leaves(ours), jax.tree.leaves(theirs), jax.tree.leaves(tree), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-12)
        if max_norm > 1e3:  # below the limit the updates pass untouched
            np.testing.assert_array_equal(a, g)
    np.testing.assert_allclose(global_norm(ours), min(max_norm, float(global_norm(tree))), rtol=1e-5)
