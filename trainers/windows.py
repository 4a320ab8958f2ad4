"""Staggered rollout windows: the reference trainer's asynchronous data, approximated in static shapes.

The reference trainer (ML-Agents 0.28 POCA, docs/PROTOCOLS.md §12 row 17) steps 280 arenas that
hand in a 256-step trajectory each as it fills, and updates whenever its buffer holds more than
8 192 agent experiences: an update trains on about 33 trajectories, each collected over the many
policies of the updates before it, with the log-probabilities stored when it acted. raidjax's
learner otherwise steps ``n_arenas`` arenas for ``n_steps`` decisions with the current policy and
trains on all of them.

With ``Config.stale_phases = K > 1`` the run steps ``K`` groups of ``n_arenas`` arenas instead, each
``n_steps / K`` decisions per update. Every group fills a window of ``n_steps`` decisions in ``K``
segments, one per update; one group's window completes per update and is what the update trains
on: the same ``n_arenas x n_steps`` decisions per update as before, but each window was acted by the
policies of the last ``K`` updates (its log-probabilities as stored then), and its values are the
critic's at the update, as ML-Agents estimates them when a trajectory arrives. The windows start
staggered, each group one segment ahead of the next: ``init`` plays ``K - 1`` segments of every
arena with the initial policy, after which group 1 holds ``K - 1`` segments of its first window,
group 2 ``K - 2``, ..., group 0 none. About half of those ``(K - 1) x n_arenas x n_steps`` decisions
are trained on (the rest belong to no window) and none are counted in ``total_steps``.

A window holds the observations acted on and those after each step: for the ``paper`` preset about
13 MB per phase and run (``K = 8``: about 110 MB), in memory and in every checkpoint (the ``paper``
preset's runner: about 11 MB).

Window arrays are ``[n_steps, K, n_arenas, ...]``; a segment of every arena is ``[n_steps / K, K *
n_arenas, ...]`` (group ``g`` is arenas ``g * n_arenas`` to ``(g + 1) * n_arenas - 1``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def offsets(update: jax.Array, phases: int, seg: int) -> jax.Array:
    """``int32[K]``: where each group's segment of update ``update`` starts in its window. Group ``g``'s
    windows start at the updates ``u = g`` (mod ``K``), so its segment of ``update`` is number
    ``(update - g) mod K``; group ``(update + 1) mod K`` writes its last one."""
    return jnp.mod(update - jnp.arange(phases), phases) * seg


def write(window, segment, update: jax.Array):
    """``window`` (arrays ``[T, K, N, ...]``) with every group's segment (arrays ``[T / K, K * N, ...]``)
    written at its offset for ``update`` (``offsets``; ``K`` is the window's second axis)."""
    def one(w, s):
        t, k, n = w.shape[:3]
        groups = s.reshape((t // k, k, n) + s.shape[2:])
        put = jax.vmap(lambda wg, sg, o: jax.lax.dynamic_update_slice_in_dim(wg, sg, o, 0), in_axes=(1, 1, 0),
                       out_axes=1)
        return put(w, groups, offsets(update, k, t // k))

    return jax.tree.map(one, window, segment)


def completed(window, update: jax.Array, phases: int):
    """The window (arrays ``[T, N, ...]``) that update ``update`` completes: group ``(update + 1) mod K``'s."""
    g = jnp.mod(update + 1, phases)
    return jax.tree.map(lambda w: jax.lax.dynamic_index_in_dim(w, g, 1, keepdims=False), window)


def empty(segment_like, phases: int):
    """Zeros for a window of ``phases`` segments shaped as ``segment_like`` (``jax.ShapeDtypeStruct``s or
    arrays ``[T / K, K * N, ...]``): arrays ``[T, K, N, ...]``."""
    def one(s):
        seg, a = s.shape[:2]
        return jnp.zeros((seg * phases, phases, a // phases) + tuple(s.shape[2:]), s.dtype)

    return jax.tree.map(one, segment_like)
