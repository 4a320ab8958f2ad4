"""Game logs: per-episode summaries, per-step traces recorded from a scan, occupancy heatmaps.

Everything here is pure and jittable; traces have a leading time axis ``T`` (and any batch
axes in front when vmapped), so a batch of recorded episodes is one pytree of arrays.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import struct

from raidjax import validate
from raidjax.content import sensed_by
from raidjax.env import reset, step
from raidjax.types import HALF_ARENA, RUNNING, Params, State

HEATMAP_BINS = 24


@struct.dataclass
class Trace:
    """One decision of one arena, as recorded by ``record_episode`` (leading ``T`` when stacked).

    Shapes with ``U`` units, ``S`` skill slots, ``M`` projectile slots.
    """

    pos: jax.Array  # float32[U, 2]
    heading: jax.Array  # float32[U]
    hp: jax.Array  # float32[U]
    alive: jax.Array  # bool[U]
    casting: jax.Array  # bool[U, S]
    target: jax.Array  # int32[U]
    projectile_live: jax.Array  # bool[M]
    projectile_pos: jax.Array  # float32[M, 2]
    projectile_kind: jax.Array  # int32[M]
    projectile_owner: jax.Array  # int32[M]
    projectile_slot: jax.Array  # int32[M]
    actions: jax.Array  # int32[P] the actions taken to reach this decision
    reward: jax.Array  # float32[P]
    running: jax.Array  # bool[]: the episode had not ended before this decision


def snapshot(state: State, actions: jax.Array, reward: jax.Array, running: jax.Array) -> Trace:
    """The ``Trace`` of ``state`` (one arena) after ``actions: int32[P]`` paid ``reward: float32[P]``."""
    p = state.projectiles
    return Trace(
        pos=state.pos, heading=state.heading, hp=state.hp, alive=state.alive, casting=state.casting,
        target=state.target, projectile_live=p.live, projectile_pos=p.pos, projectile_kind=p.kind,
        projectile_owner=p.owner, projectile_slot=p.slot, actions=actions, reward=reward, running=running,
    )


def episode_summary(state: State) -> dict[str, jax.Array]:
    """Summary of a finished (or running) episode from its ``State`` (any leading batch axes).

    Returns:
        Dict with ``outcome`` int32 (0 running, 1 win, 2 loss, 3 draw), ``length`` int32
        (decisions), ``damage`` float32[P] (to the boss), ``back_attacks`` int32[P],
        ``deaths`` int32, ``alive`` bool[P], ``dropped`` int32 (projectiles dropped for a full
        pool), ``boss_hp`` float32; and what the episode hands on to its arena's next one under
        the reference rules (GAME.md, "Rule sets"): ``boss_recharging`` bool[S] (the boss's
        cooldowns still running: under ``carry_cooldowns`` each adds a charge in the next episode)
        and ``in_flight`` int32 (live projectiles: under ``reset_exception`` any keeps the boss
        where it stands).
    """
    n_players = state.hp.shape[-1] - 1
    alive = state.alive[..., :n_players]
    return {
        "outcome": state.result,
        "length": state.decision,
        "damage": state.damage_dealt[..., :n_players],
        "back_attacks": state.back_attacks[..., :n_players],
        "deaths": jnp.sum(~alive, axis=-1).astype(jnp.int32),
        "alive": alive,
        "dropped": state.dropped,
        "boss_hp": state.hp[..., -1],
        "boss_recharging": state.recharging[..., -1, :],
        "in_flight": jnp.sum(state.projectiles.live, axis=-1).astype(jnp.int32),
    }


def record_episode(key: jax.Array, params: Params, policy: Callable, n_decisions: int, weights=None):
    """Play one episode for ``n_decisions`` decisions (static) and record every decision.

    Args:
        key: PRNG key.
        params: one arena's ``Params`` (vmap this function for a batch).
        policy: ``policy(key, obs, state, params) -> int32[P]``, or with ``weights``
            ``policy(weights, key, obs, state, params)``; a policy with a ``senses`` attribute plays
            with those senses (``raidjax.content.sensed_by``).
        n_decisions: trace length ``T``, a whole number >= 1; decisions after the episode ended
            repeat the final state with ``running = False``.
        weights: ``None`` or the policy's weights (a pytree of arrays; under ``jit`` with
            ``policy`` static, new weights of the same shapes reuse the compiled program).

    Returns:
        ``(trace, summary)``: ``Trace`` with leading axis ``T + 1`` (the reset state first) and
        ``episode_summary`` of the final state.

    Raises:
        ValueError: ``n_decisions`` not a whole number >= 1 (one line).
    """
    n_decisions = validate.whole_number("n_decisions", n_decisions, 1)
    params = sensed_by(params, policy)  # a trained team plays with the senses it learned on
    k_reset, k_play = jax.random.split(key)
    obs, state = reset(k_reset, params)
    n_players = params.team.shape[-1] - 1
    first = snapshot(state, jnp.zeros(n_players, jnp.int32), jnp.zeros(n_players), jnp.bool_(True))

    def body(carry, k):
        obs, state = carry
        ka, ks = jax.random.split(k)
        actions = policy(ka, obs, state, params) if weights is None else policy(weights, ka, obs, state, params)
        running = state.result == RUNNING
        obs, state, reward, _, _ = step(ks, state, actions, params)
        return (obs, state), snapshot(state, actions, reward, running)

    (_, state), traces = jax.lax.scan(body, (obs, state), jax.random.split(k_play, n_decisions))
    trace = jax.tree.map(lambda a, b: jnp.concatenate([a[None], b]), first, traces)
    return trace, episode_summary(state)


def grid_cell(pos: jax.Array, bins: int = HEATMAP_BINS) -> jax.Array:
    """Cell ``int32[..., 2]`` (x bin, y bin) of positions ``float32[..., 2]`` on a ``bins x bins``
    grid over the arena; positions on or beyond a wall fall in the edge cells."""
    cell = jnp.floor((pos + HALF_ARENA) / (2 * HALF_ARENA) * bins).astype(jnp.int32)
    return jnp.clip(cell, 0, bins - 1)


def occupancy_heatmap(pos: jax.Array, mask: jax.Array, bins: int = HEATMAP_BINS) -> jax.Array:
    """Average position occupancy on a ``bins x bins`` grid over the arena (PROTOCOLS.md §11).

    Args:
        pos: ``float32[..., 2]`` positions (any leading axes: games, time, players).
        mask: ``bool[...]`` which positions count (e.g. alive players of running decisions).
        bins: grid size, a whole number >= 1 (24 in the paper).

    Returns:
        ``float32[bins, bins]`` indexed ``[x_bin, y_bin]``, summing to 1 (all zeros if nothing
        counted).

    Raises:
        ValueError: ``bins`` not a whole number >= 1 (one line).
    """
    bins = validate.whole_number("bins", bins, 1)
    cell = grid_cell(pos, bins).reshape(-1, 2)
    w = mask.reshape(-1).astype(jnp.float32)
    counts = jnp.zeros((bins, bins)).at[cell[:, 0], cell[:, 1]].add(w)
    return counts / jnp.maximum(counts.sum(), 1.0)


def trace_heatmap(trace: Trace, bins: int = HEATMAP_BINS) -> jax.Array:
    """Occupancy heatmap ``float32[bins, bins]`` of the alive players over a (batch of) trace(s)."""
    n_players = trace.actions.shape[-1]
    pos = trace.pos[..., :n_players, :]
    mask = trace.alive[..., :n_players] & trace.running[..., None]
    return occupancy_heatmap(pos, mask, bins)
