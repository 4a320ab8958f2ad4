"""The content-generation baselines of the paper (GAME.md §10): PCG-RD and PCG-HR.

A generator policy is ``policy(policy_params, key, obs, state, params) -> int32[K]`` (one choice
in 0..4 per edited parameter, ``K = params.space.size``); the baselines ignore ``policy_params``
and ``obs``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from raidjax.pcg.env import N_CHOICES, NOOP_ACTION, PCGParams, PCGState


def pcg_rd(policy_params, key: jax.Array, obs: jax.Array, state: PCGState, params: PCGParams) -> jax.Array:
    """PCG-RD: a uniformly random choice on each of the K branches. Returns ``int32[K]``."""
    return jax.random.randint(key, (params.space.size,), 0, N_CHOICES, jnp.int32)


def pcg_hr(policy_params, key: jax.Array, obs: jax.Array, state: PCGState, params: PCGParams) -> jax.Array:
    """PCG-HR (the paper's Algorithm 2): nothing if ``|w - t| < band``; else one random parameter
    moved half a tick toward easier (range up, cool down, cast down, coefficient up; for another
    space its ``easier`` signs, ``raidjax.pcg.space.EASIER_FIELDS``) when ``w < t``, toward harder
    otherwise. Returns ``int32[K]``."""
    k = params.space.size
    j = jax.random.randint(key, (), 0, k)
    sign = jnp.where(state.win_rate < state.target, 1.0, -1.0) * jnp.asarray(params.space.easier)[j]
    act = jnp.full((k,), NOOP_ACTION, jnp.int32).at[j].set(NOOP_ACTION + sign.astype(jnp.int32))
    close = jnp.abs(state.win_rate - state.target) < params.band
    return jnp.where(close, NOOP_ACTION, act)
