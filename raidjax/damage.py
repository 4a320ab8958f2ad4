"""What hits do (GAME.md §6): every hit's source (``Effects``), the dice and modifiers of a
sub-step's hit events, what they add up to and how it lands on the units; basic attacks and
regeneration.

Lane functions (``raidjax.lanes``): shapes are one arena's, followed by any number of lane (batch)
axes. ``U`` units (boss last), ``S`` skill slots, ``E`` hit events per sub-step (the pool's
projectiles, instant skills, basic attacks).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from raidjax.combat import EPS, TIME_EPS
from raidjax.hits import Hits, UnitColumns
from raidjax.lanes import lane_function, one_hot, pick, total
from raidjax.movement import norm
from raidjax.types import HIT_ATTACK, Effects, Params, State
from raidjax.utils import hash_dice

BACK_ATTACK_COS = 0.5  # within +-60 degrees of the rear direction
NEUTRAL_PRIMARY = 50.0  # strength / agility / intelligence with no effect
PARRY_FACTOR = 0.5  # a parried hit does half damage


@lane_function
def effect_sources(params: Params) -> tuple[Effects, Effects]:
    """Everything a hit needs to know about its source (``Effects``): the skill slots'
    (``n = U * S``, entry ``u * S + s``) and the basic attacks' (``n = U``). ``raidjax.env`` builds
    them once per decision, in the lanes."""
    sk, st = params.skills, params.stats
    u_n, s_n = sk.coefficient.shape[:2]
    str_scale = 1.0 + (st.strength - NEUTRAL_PRIMARY) / 100.0
    int_scale = 1.0 + (st.intelligence - NEUTRAL_PRIMARY) / 100.0
    back = jnp.where(params.team == 0, st.back_attack_multiplier * (1.0 + st.mastery / 100.0), 1.0)
    per_unit = dict(crit=st.critical / 100.0, crit_mult=st.crit_multiplier, back_mult=back,
                    vers=1.0 + st.versatility / 100.0, agility=st.agility, team=params.team.astype(jnp.float32))

    def effects(attack, coef, **per_source):  # [U, n, ...] each -> Effects of [U * n, ...]
        power = jnp.where(attack, st.attack_power[:, None], st.spell_power[:, None])
        scale = jnp.where(attack, str_scale[:, None], int_scale[:, None])
        base = jnp.floor(coef * power + 1e-3) * scale  # GAME.md §6: int(coefficient x power)
        heal = jnp.floor(coef * (st.spell_power * int_scale)[:, None] + 1e-3)
        cols = dict(base=base, heal=heal, **{k: v[:, None] for k, v in per_unit.items()}, **per_source)
        shape = jnp.broadcast_shapes(*(c.shape for c in cols.values()))
        return Effects(**{k: jnp.broadcast_to(c, shape).reshape((-1,) + shape[2:]) for k, c in cols.items()})

    as_f32 = lambda x: x.astype(jnp.float32)  # noqa: E731
    skills = effects(sk.hit_type == HIT_ATTACK, sk.coefficient, enemy=as_f32(sk.affect_enemy),
                     ally=as_f32(sk.affect_ally), speed=sk.projectile_speed, radius=sk.projectile_radius,
                     hits=as_f32(sk.hit_count))
    one = jnp.ones_like(st.attack_power)[:, None]  # [U, 1, ...]: one basic attack per unit
    zero = jnp.zeros_like(one)
    basic = effects(one > 0, one, enemy=one, ally=zero, speed=zero, radius=zero, hits=one)  # one unit, no flight
    return skills, basic


def effect_table(params: Params) -> Effects:
    """``effect_sources`` as one ``Effects`` of ``n = U * (S + 1)`` (one arena's ``params``, no lanes):
    entry ``u * (S + 1) + s`` is unit u's skill slot s, entry ``u * (S + 1) + S`` its basic attack."""
    skills, basic = effect_sources(params)
    u_n = basic.base.shape[0]
    return jax.tree.map(lambda sk, b: jnp.concatenate([sk.reshape(u_n, -1), b[:, None]], axis=1).reshape(-1),
                        skills, basic)


@lane_function
def source_index(owner: jnp.ndarray, slot: jnp.ndarray, n_slots: int) -> jnp.ndarray:
    """Entry of ``effect_table`` for ``(owner, slot)`` (``slot = n_slots`` is the basic attack)."""
    return owner * (n_slots + 1) + slot


@lane_function
def pick_effects(effects: Effects, idx: jnp.ndarray) -> Effects:
    """``effects`` at entries ``idx`` (an integer lane array), field by field (``lanes.pick``)."""
    return jax.tree.map(lambda x: pick(x, idx), effects)


@lane_function(lane_count="n_lanes")
def event_sources(sources: tuple[Effects, Effects], n_lanes: int):
    """Source effects and owners ``int32[n, ...]`` of two groups of a sub-step's hit events: every
    unit's ``S`` skill slots (instant skills) and every unit's basic attack (the pool's are
    ``raidjax.projectiles``'). ``sources``: ``effect_sources``' ``(skills, basic)``; ``n_lanes``: how
    many lane axes the arrays carry.

    Returns ``((skill_effects, skill_owner), (basic_effects, basic_owner))``.
    """
    skills, basic = sources
    u_n = basic.base.shape[0]
    units = jnp.arange(u_n, dtype=jnp.int32).reshape((u_n,) + (1,) * n_lanes)
    return (skills, jnp.repeat(units, skills.base.shape[0] // u_n, axis=0)), (basic, units)


@lane_function
def touchable(effects: Effects, params: Params, alive: jnp.ndarray) -> jnp.ndarray:
    """``bool[E, U, ...]``: alive units that ``E`` sources' ``effects`` can touch."""
    same = effects.team[:, None] == params.team[None].astype(jnp.float32)
    return ((effects.enemy[:, None] > 0) & ~same | (effects.ally[:, None] > 0) & same) & alive[None]


@lane_function
def unit_columns(state: State, params: Params) -> UnitColumns:
    """``UnitColumns``: what a hit reads from the unit it touches (position, heading, evasion, agility,
    parry, armour factor, team), read by every hit event of a sub-step (after the casts fired: the
    boss's heading is the one it turned to)."""
    st = params.stats
    cos_h, sin_h = jnp.cos(state.heading), jnp.sin(state.heading)
    return UnitColumns(
        x=state.pos[:, 0], y=state.pos[:, 1], cos_h=cos_h, sin_h=sin_h,
        evasion=st.evasion, agility=st.agility, parry=st.parry,
        armor=(1.0 - st.armor / 200.0) * (1.0 - st.versatility / 200.0),
        team=params.team.astype(jnp.float32),
    )


class HitSums(NamedTuple):
    """What a group of hit events adds up to, each ``float32[U, ...]`` (whole points): by the unit
    hit (``damage_in``, ``heal_in``) and by the unit that hit (``dealt``, ``dealt_to_boss``,
    ``back_count``)."""

    damage_in: jax.Array
    heal_in: jax.Array
    dealt: jax.Array
    dealt_to_boss: jax.Array
    back_count: jax.Array

    def plus(self, other: HitSums) -> HitSums:
        """Field by field sum (exact: whole points)."""
        return HitSums(*(a + b for a, b in zip(self, other, strict=True)))


@lane_function
def apply_hits(state: State, params: Params, sums: HitSums):
    """Apply what a sub-step's hit events add up to (``HitSums``, every group's ``group_sums`` added)
    to the units: damage, then heals of the survivors (capped at max HP); a unit at 0 HP dies.

    Returns:
        ``(state, dealt_to_boss: float32[U, ...], back: int32[U, ...])`` by owner.
    """
    damage_in, heal_in, dealt, dealt_to_boss, back_count = sums
    hp = state.hp - damage_in
    alive = state.alive & (hp > 0)
    hp = jnp.where(alive, jnp.minimum(hp + heal_in, params.stats.max_hp), 0.0)  # HP floors at 0
    back_count = back_count.astype(jnp.int32)
    died = state.alive & ~alive
    state = state.replace(
        hp=hp, alive=alive,
        casting=state.casting & alive[:, None],
        vel=jnp.where(died[:, None], 0.0, state.vel),
        damage_dealt=state.damage_dealt + dealt,
        back_attacks=state.back_attacks + back_count,
    )
    return state, dealt_to_boss, back_count


class HitOutcomes(NamedTuple):
    """What each of a group's hit events does to the units it touches, ``[n, ...]`` for events that
    touch at most one unit or ``[n, U, ...]``: ``harm`` (bool: it damages), ``healed`` (bool: it
    heals), ``back`` (bool: it comes from behind), ``mult`` (float32: crit, back, versatility, armour
    and parry factors together)."""

    harm: jax.Array
    healed: jax.Array
    back: jax.Array
    mult: jax.Array


@lane_function(lane_shape="lanes", shared=("first",))
def hit_outcomes(seeds, unit_cols: UnitColumns, f: Effects, hits: Hits, from_pos, n_events: int, first, u_n: int,
                 lanes: tuple) -> HitOutcomes:
    """The dice and modifiers of one group of a sub-step's hit events (``group_sums`` adds them up).

    A sub-step's ``E`` hit events come in groups (the pool's projectiles, block by block, then every
    unit's ``S`` instant skill slots, then every unit's basic attack). Die ``d`` of event ``e`` on
    unit ``u`` is die number ``(d * E + e) * U + u`` of the sub-step.

    Args:
        seeds: ``uint32[2, ...]`` dice seeds (``utils.dice_seeds``) for crits, dodges and parries.
        unit_cols: ``unit_columns``' ``UnitColumns``.
        f: ``Effects`` of the group's ``n`` events (each event's source, ``event_sources``).
        hits: ``Hits``, the units each event touches (with ``unit``: at most one each, whose dice
            and damage alone are computed).
        from_pos: ``float32[n, 2, ...]`` where each event comes from (back attacks).
        n_events: ``E``; first: the group's first event (an ``int``, or a traced ``int32[]`` for
            the pool's blocks).
        u_n: ``U``; lanes: the lane axes' shape.

    Returns:
        ``HitOutcomes``.
    """
    xp = np if isinstance(first, int) else jnp
    base = (xp.arange(3)[:, None] * n_events + first + xp.arange(f.base.shape[0])[None]) * u_n  # [3, n]
    single, hit = hits.single, hits.hit
    if single:  # one unit per event: [n, ...]
        from_x, from_y = from_pos[:, 0], from_pos[:, 1]
        index = jnp.asarray(base.reshape(base.shape + (1,) * len(lanes)), jnp.uint32) + hits.unit.astype(jnp.uint32)
        col = jax.tree.map(lambda v: pick(v, hits.unit), unit_cols)
    else:  # every unit: [n, U, ...]
        from_x, from_y = from_pos[:, 0, None], from_pos[:, 1, None]
        index = base[:, :, None] + np.arange(u_n)
        # numpy: the same indices in every lane; traced (the pool's blocks): give it the lane axes.
        index = (index.astype(np.uint32) if isinstance(index, np.ndarray)
                 else index.reshape(index.shape + (1,) * len(lanes)).astype(jnp.uint32))
        col = jax.tree.map(lambda v: v[None], unit_cols)
    fc = lambda c: _per_event(f, c, single)  # noqa: E731
    dice = hash_dice(seeds, index)
    crit = dice[0] < fc("crit")
    relx, rely = from_x - col.x, from_y - col.y
    length = jnp.maximum(jnp.sqrt(relx * relx + rely * rely), EPS)
    # From behind: the direction it comes from against the unit's rear, (-cos, -sin) of its heading.
    back = (relx / length) * -col.cos_h + (rely / length) * -col.sin_h >= BACK_ATTACK_COS
    evasion = col.evasion + 0.5 * (col.agility - fc("agility"))
    dodge = dice[1] * 100.0 < evasion
    parry = dice[2] * 100.0 < col.parry
    mult = (
        jnp.where(crit, fc("crit_mult"), 1.0)
        * jnp.where(back, fc("back_mult"), 1.0)
        * fc("vers")
        * col.armor
        * jnp.where(parry, PARRY_FACTOR, 1.0)
    )
    enemy = fc("team") != col.team
    # Homing and instant hits land on their target whatever the flags: gate them here.
    harm = hit & enemy & (fc("enemy") > 0) & ~dodge
    healed = hit & ~enemy & (fc("ally") > 0)
    return HitOutcomes(harm, healed, back, mult)


def _per_event(f: Effects, column: str, single: bool) -> jax.Array:
    """Column ``column`` of ``f``, shaped to broadcast over a group's ``[n, ...]`` or ``[n, U, ...]``."""
    x = getattr(f, column)
    return x if single else x[:, None]


@lane_function
def group_sums(outcomes: HitOutcomes, f: Effects, owner, hits: Hits, u_n: int) -> HitSums:
    """What one group of hit events adds up to (``hit_outcomes``' ``outcomes``; ``f``, ``owner`` and
    ``hits`` as there; ``u_n``: ``U``). Damage is whole points, so every sum is exact in any order, and the groups'
    sums add up exactly."""
    single = hits.single
    harm, healed, back, mult = outcomes
    fc = lambda c: _per_event(f, c, single)  # noqa: E731
    damage = jnp.where(harm, jnp.floor(fc("base") * mult + 1e-3), 0.0)
    heal = jnp.where(healed, fc("heal"), 0.0)
    back_landed = harm & back & (fc("team") == 0)
    if single:  # spread each event's one target over the unit axis
        on = one_hot(hits.unit, u_n, axis=1)
        damage_u, heal_u = jnp.where(on, damage[:, None], 0.0), jnp.where(on, heal[:, None], 0.0)
        per_event, to_boss, backs = damage, damage_u[:, -1], back_landed
    else:
        damage_u, heal_u = damage, heal
        per_event, to_boss, backs = total(damage, axis=1), damage[:, -1], total(back_landed, axis=1)
    by_owner = one_hot(owner, u_n, axis=1).astype(jnp.float32)  # [n, U, ...]
    return HitSums(total(damage_u), total(heal_u), total(by_owner * per_event[:, None]),
                   total(by_owner * to_boss[:, None]), total(by_owner * backs.astype(jnp.float32)[:, None]))


@lane_function
def basic_attacks(state: State, params: Params, dt: float):
    """Automatic melee hits on the enemy target within ``attack_range`` every ``1/attack_speed`` s.

    Off when ``attack_power = 0`` (the reference setting). Returns ``(state, Hits(hit: bool[U, ...],
    unit: int32[U, ...]))``: whether each unit's attack hits its target this sub-step, and the target.
    """
    st = params.stats
    t = state.target
    d = norm(pick(state.pos, t[:, None]) - state.pos, axis=1) - st.radius - pick(st.radius, t)
    # Time passes first, so that the next attack comes 1 / attack_speed after this one.
    left = jnp.maximum(state.basic_cooldown - dt, 0.0)
    ready = left <= TIME_EPS
    go = state.alive & pick(state.alive, t) & (st.attack_power > 0) & (d <= st.attack_range) & ready
    cooldown = jnp.where(go, 1.0 / st.attack_speed, left)
    return state.replace(basic_cooldown=cooldown), Hits(go, t)


@lane_function
def regenerate(state: State, params: Params, dt: float) -> State:
    """HP and mana regeneration of alive units, capped at their maxima."""
    st = params.stats
    hp = jnp.where(state.alive, jnp.minimum(state.hp + st.hp_regen * dt, st.max_hp), state.hp)
    mana = jnp.where(state.alive, jnp.minimum(state.mana + st.mana_regen * dt, st.max_mana), state.mana)
    return state.replace(hp=hp, mana=mana)
