"""The gradient's global norm and its clip, as the trainers use them.

``optax.clip_by_global_norm`` and ``optax.tree.norm`` sum each leaf's squares with
``jnp.sum(jnp.square(g))``. Under raidjax's XLA:CPU flags (``raidjax.use_recommended_xla_flags``:
classic LLVM IR emitters, no YNNPACK reductions) XLA turns that sum over some 2-D shapes into a
reduce-window kernel whose 32 x 32 window LLVM unrolls: compiling it takes 1.6 s CPU for one
64 x 64 kernel and 9.6 s for 128 x 128 (measured on the 2-core CPU), once per such kernel of the
networks. ``jnp.vdot(g, g)`` flattens the leaf first, and XLA sums one vector (as it does for
``jnp.sum(jnp.square(g.ravel()))``): under 0.1 s. The values agree to float32 rounding (the two
sum in different orders).
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
    is ``max_norm`` or more are scaled to norm ``max_norm``; smaller ones pass unchanged.

    Returns an ``optax.GradientTransformation`` with an empty state whose ``update(updates, state)``
    takes a pytree of float arrays and returns ``(the same pytree's shapes and dtypes, state)``.
    (The trainers compute ``global_norm`` of the same gradients for their metric too; XLA merges
    the two: the compiled update has the same reductions with the metric as without it.)"""

    def update(updates, state, params=None):
        del params
        norm = global_norm(updates)
        small = norm < max_norm
        return jax.tree.map(lambda t: jax.lax.select(small, t, (t / norm.astype(t.dtype)) * max_norm), updates), state

    return optax.GradientTransformation(optax.init_empty_state, update)
