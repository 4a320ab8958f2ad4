"""Per-player observations (GAME.md §8): entity-structured, fixed shapes, with a flat view.

Normalisation: positions and velocities / 20, cooldowns / 5, HP / max, range / 20,
damage / 100, cast time / 5. Dead entities are zeros *and* masked out.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from raidjax import validate
from raidjax.combat import haste_factor, skill_targets, usable_slots
from raidjax.damage import effect_table, pick_effects, source_index
from raidjax.reference_observation import ReferenceObservation, observe_reference
from raidjax.types import CAST_1, HALF_ARENA, HIT_ATTACK, TRIGGER_PASSIVE, Effects, Observation, Params, State
from raidjax.utils import traced_once

POS_SCALE, COOL_SCALE, RANGE_SCALE, DAMAGE_SCALE, CAST_SCALE = 20.0, 5.0, 20.0, 100.0, 5.0


def skill_damage(params: Params) -> jnp.ndarray:
    """Base damage (or heal) ``float32[U, S]`` of every skill slot: coefficient x power."""
    st, sk = params.stats, params.skills
    power = jnp.where(sk.hit_type == HIT_ATTACK, st.attack_power[:, None], st.spell_power[:, None])
    return sk.coefficient * power


def action_mask(state: State, params: Params) -> jnp.ndarray:
    """``bool[P, A]``, ``A = params.config.n_actions``: which actions do something now (dead players
    may only no-op); all true under the reference action space, which masks nothing."""
    validate.one_arena("action_mask", params.team)
    n_players = params.team.shape[0] - 1
    if params.config.action_space == "reference":
        return jnp.ones((n_players, params.config.n_actions), bool)
    alive = state.alive[:n_players]
    _, valid = skill_targets(state, params)
    casts = usable_slots(state, params, valid)
    casts = casts & (params.skills.trigger != TRIGGER_PASSIVE)
    move = jnp.broadcast_to(alive[:, None], (n_players, CAST_1))
    move = move.at[:, 0].set(True)  # no-op is always allowed
    return jnp.concatenate([move, casts[:n_players]], axis=-1)


def nearest(score: jnp.ndarray, k: int) -> jnp.ndarray:
    """``int32[..., k]``: the indices of the ``k`` smallest entries of each row of ``score`` (``[..., M]``,
    no NaN), smallest first, ties to the lower index (as ``lax.top_k(-score, k)``).

    Ranked by comparing every pair (M x M per row): ``lax.top_k`` runs on XLA:CPU as a sort per row
    in a runtime call outside the fused code, and ``k`` passes of a minimum run one after another;
    with the pool's 16 projectiles the pairs were the fastest of the three in a learner's rollout.
    """
    m = score.shape[-1]
    a, b = score[..., :, None], score[..., None, :]  # [..., j, i]
    earlier = jnp.arange(m)[None, :] < jnp.arange(m)[:, None]  # [j, i]: i < j
    rank = jnp.sum((b < a) | ((b == a) & earlier), axis=-1)  # [..., M]: a permutation of 0..M-1
    return jnp.argmax(rank[..., None, :] == jnp.arange(k)[:, None], axis=-1).astype(jnp.int32)


@traced_once
def observe(state: State, params: Params, table: Effects | None = None) -> Observation | ReferenceObservation:
    """Build every player's observation.

    Args:
        state: one arena's ``State`` (``U = P + 1`` units).
        params: its ``Params``.
        table: ``damage.effect_table(params)`` if already computed (saves work inside ``step``).

    Returns:
        ``Observation`` with a leading player axis ``P`` (shapes in ``types.Observation``), or under
        ``config.observation = "reference"`` a ``ReferenceObservation`` (``raidjax.reference_observation``).
    """
    validate.one_arena("observe", params.team)
    table = effect_table(params) if table is None else table
    if params.config.observation == "reference":
        return observe_reference(state, params, table, action_mask(state, params))
    st, sk = params.stats, params.skills
    n_players = params.team.shape[0] - 1
    b = n_players
    pos, vel = state.pos / POS_SCALE, state.vel / POS_SCALE
    hp = state.hp / jnp.maximum(st.max_hp, 1.0)
    mana = state.mana / jnp.maximum(st.max_mana, 1.0)
    cast_time = sk.cast_time / haste_factor(params)
    progress = jnp.where(state.casting, 1.0 - state.cast_left / jnp.maximum(cast_time, 1e-6), 0.0)
    skill_feats = jnp.concatenate(
        [
            state.recharge_left / COOL_SCALE,
            state.charges / jnp.maximum(sk.charge, 1),
            sk.range / RANGE_SCALE,
            skill_damage(params) / DAMAGE_SCALE,
            cast_time / CAST_SCALE,
        ],
        axis=-1,
    ) * jnp.tile(sk.in_use > 0, (1, 5))  # [U, 5S], feature-major: mask every feature of unused slots
    heading = jnp.stack([jnp.cos(state.heading), jnp.sin(state.heading)], axis=-1)
    unit_core = jnp.concatenate([pos, heading, vel, hp[:, None], mana[:, None]], axis=-1)  # [U, 8]
    casting_any = jnp.any(state.casting, axis=-1)
    self_features = jnp.concatenate(
        [unit_core, casting_any[:, None], jnp.max(progress, axis=-1, keepdims=True), skill_feats], axis=-1
    )[:n_players]
    alive_p = state.alive[:n_players]
    self_features = self_features * alive_p[:, None]

    boss_core = jnp.concatenate(
        [
            pos[b] - pos[:n_players],
            jnp.broadcast_to(heading[b], (n_players, 2)),
            jnp.broadcast_to(hp[b], (n_players, 1)),
            jnp.broadcast_to(state.recharge_left[b, :2] / COOL_SCALE, (n_players, 2)),
            jnp.broadcast_to(casting_any[b], (n_players, 1)).astype(jnp.float32),
            jnp.broadcast_to(jnp.max(progress[b]), (n_players, 1)),
            (state.target[b] == jnp.arange(n_players))[:, None].astype(jnp.float32),
            jnp.linalg.norm(pos[b] - pos[:n_players], axis=-1, keepdims=True),
        ],
        axis=-1,
    )  # [P, 11]

    # Teammates: every other player, in index order, relative position.
    others = jnp.array([[j for j in range(n_players) if j != i] for i in range(n_players)], jnp.int32).reshape(
        n_players, n_players - 1
    )
    used = sk.in_use > 0  # unused slots read as zeros, as in the self features
    mate_feats = jnp.concatenate(
        [pos[others] - pos[:n_players, None], vel[others], hp[others][..., None], state.alive[others][..., None],
         (used * sk.range)[others] / RANGE_SCALE, (used * skill_damage(params))[others] / DAMAGE_SCALE,
         (used * cast_time)[others] / CAST_SCALE, mana[others][..., None]],
        axis=-1,
    )
    mate_mask = state.alive[others] & alive_p[:, None]  # a dead viewer sees nothing
    mate_feats = mate_feats * mate_mask[..., None]

    # Hostile projectiles: the K nearest live ones owned by the boss's team.
    p = state.projectiles
    k = params.config.obs_projectiles
    feats = pick_effects(table, source_index(p.owner, p.slot, sk.in_use.shape[1]))  # n = M
    hostile = p.live & (feats.team != 0)
    rel = p.pos[None] - state.pos[:n_players, None]  # [P, M, 2]
    d = jnp.linalg.norm(rel, axis=-1)
    score = jnp.where(hostile[None], d, jnp.inf)
    idx = nearest(score, k)
    pmask = jnp.isfinite(jnp.take_along_axis(score, idx, axis=1)) & alive_p[:, None]
    speed = feats.speed
    pvel = jnp.where((p.kind == 1)[:, None], p.direction * speed[:, None], 0.0) / POS_SCALE
    pfeat = jnp.concatenate(
        [jnp.take_along_axis(rel, idx[..., None], axis=1) / POS_SCALE, pvel[idx],
         jax.nn.one_hot(p.kind[idx], 3)[..., 1:]],
        axis=-1,
    ) * pmask[..., None]

    own = state.pos[:n_players]
    walls = jnp.concatenate([HALF_ARENA - own, HALF_ARENA + own], axis=-1) / POS_SCALE
    return Observation(
        self_features=self_features,
        boss=boss_core * alive_p[:, None],
        teammates=mate_feats,
        teammate_mask=mate_mask,
        projectiles=pfeat,
        projectile_mask=pmask,
        walls=walls * alive_p[:, None],
        action_mask=action_mask(state, params),
        alive=alive_p,
    )

