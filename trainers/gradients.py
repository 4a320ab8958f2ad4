"""The gradient's global norm and its clip, as the trainers use them.

``optax.clip_by_global_norm`` and ``optax.tree.norm`` sum each leaf's squares with
``jnp.sum(jnp.square(g))``. Under raidjax's XLA:CPU flags (``raidjax.use_recommended_xla_flags``:
classic LLVM IR emitters, no YNNPACK reductions) XLA splits every such sum over 1 024 floats or
more into a reduce-window kernel whose 32 x 32 window LLVM unrolls: about 8 s of compiling for one
128 x 128 kernel (measured on the 2-core CPU), several per program for the reference networks'
128-wide attention. ``jnp.vdot(g, g)`` is a dot product: it compiles in under 0.1 s. The values
agree to float32 rounding (the two sum in different orders).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optax


def global_norm(tree) -> jax.Array:
    """The L2 norm of all of ``tree``'s leaves taken together: ``float32[]``."""
    return jnp.sqrt(sum(jnp.vdot(g, g) for g in jax.tree.leaves(tree)))


def clip_by_global_norm(max_norm: float) -> optax.GradientTransformation:
    """``optax.clip_by_global_norm(max_norm)`` with ``global_norm``'s norm: updates whose global norm
    is ``max_norm`` or more are scaled to norm ``max_norm``; smaller ones pass unchanged."""

    def update(updates, state, params=None):
        del params
        norm = global_norm(updates)
        small = norm < max_norm
        return jax.tree.map(lambda t: jax.lax.select(small, t, (t / norm.astype(t.dtype)) * max_norm), updates), state

    return optax.GradientTransformation(optax.init_empty_state, update)
