"""The content-generation baselines of the paper (GAME.md §10): PCG-RD and PCG-HR.

A generator policy is ``policy(policy_params, key, obs, state, params) -> int32[4]`` (one choice
in 0..4 per parameter); the baselines ignore ``policy_params`` and ``obs``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from raidjax.pcg.env import EASIER, N_CHOICES, N_PARAMS, NOOP_ACTION, PCGParams, PCGState


def random_policy(policy_params, key: jax.Array, obs: jax.Array, state: PCGState, params: PCGParams) -> jax.Array:
    """PCG-RD: a uniformly random choice on each of the 4 branches. Returns ``int32[4]``."""
    return jax.random.randint(key, (N_PARAMS,), 0, N_CHOICES, jnp.int32)


def heuristic_policy(policy_params, key: jax.Array, obs: jax.Array, state: PCGState, params: PCGParams) -> jax.Array:
    """PCG-HR (the paper's Algorithm 2): nothing if ``|w - t| < band``; else one random parameter
    moved half a tick toward easier (range up, cool down, cast down, coefficient up) when
    ``w < t``, toward harder otherwise. Returns ``int32[4]``."""
    j = jax.random.randint(key, (), 0, N_PARAMS)
    sign = jnp.where(state.win_rate < state.target, 1.0, -1.0) * jnp.asarray(EASIER, jnp.float32)[j]
    act = jnp.full((N_PARAMS,), NOOP_ACTION, jnp.int32).at[j].set(NOOP_ACTION + sign.astype(jnp.int32))
    close = jnp.abs(state.win_rate - state.target) < params.band
    return jnp.where(close, NOOP_ACTION, act)
