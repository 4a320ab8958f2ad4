"""What both wrappers share: content carried in the state, and one decision with auto-reset."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from raidjax.env import next_episode, reset, step
from raidjax.types import Observation, Params, State


@struct.dataclass
class ArenaState:
    """One arena as the wrappers carry it: its game ``State`` and its content ``Params``.

    Carrying the content keeps it per arena through auto-resets: ``vmap`` a wrapper's ``reset``
    over a batch of ``Params`` and every arena keeps its own content for good.

    Attributes:
        game: ``raidjax.State`` of the running episode.
        params: ``raidjax.Params`` of the arena (``team: [U]``).
        time: ``int32[]`` decisions played in the running episode.
    """

    game: State
    params: Params
    time: jax.Array


def start(key: jax.Array, params: Params) -> tuple[Observation, ArenaState]:
    """``raidjax.reset`` wrapped: ``(obs, ArenaState)``."""
    obs, game = reset(key, params)
    return obs, ArenaState(game=game, params=params, time=jnp.int32(0))


def step_arena(key: jax.Array, state: ArenaState, actions: jax.Array):
    """One decision, then the arena's next episode (``raidjax.next_episode``, which keeps what the
    reference rules carry) if this one ended.

    Args:
        key: PRNG key.
        state: ``ArenaState``.
        actions: ``int32[P]``.

    Returns:
        ``(obs, state, reward: float32[P], terminated: bool[], truncated: bool[], info, final_obs)``:
        ``obs``/``state`` of the new episode when it ended; ``final_obs`` the ``Observation`` the
        step reached (the ended episode's last one); ``info`` as ``raidjax.step``'s.
    """
    k_step, k_next = jax.random.split(key)
    obs, game, reward, done, info = step(k_step, state.game, actions, state.params)
    obs_next, game_next = next_episode(k_next, game, state.params)
    pick = lambda a, b: jax.tree.map(lambda x, y: jnp.where(done, x, y), a, b)
    new = ArenaState(game=pick(game_next, game), params=state.params, time=jnp.where(done, 0, state.time + 1))
    return pick(obs_next, obs), new, reward, info["terminated"], info["truncated"], info, obs
