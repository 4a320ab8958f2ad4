"""Casting, cooldowns/charges/mana, spawning into the projectile pool, and damage (GAME.md §5–§6);
the pool's flight and collision are ``raidjax.projectiles``'.

Lane functions (``raidjax.lanes``): shapes are one arena's, followed by any number of lane (batch)
axes. ``U`` units (boss last), ``S`` skill slots, ``M`` projectile slots, ``E = M + U*S + U`` hit
events per sub-step (projectiles, instant skills, basic attacks).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from raidjax.lanes import any_, argmin, cumsum, first_true, lane_function, one_hot, pick, total
from raidjax.movement import nearest_alive_player, norm, set_boss
from raidjax.types import (
    HIT_ATTACK,
    PROJ_AREA,
    PROJ_HOMING,
    PROJ_STRAIGHT,
    TARGET_REGION,
    TARGET_UNIT,
    TICK,
    TRIGGER_PASSIVE,
    Effects,
    Params,
    Projectiles,
    Spawns,
    State,
)
from raidjax.utils import hash_dice

AREA_LIFETIME = 5 * TICK  # an area lingers 5 ticks
MISSILE_LIFETIME = 10.0  # safety net: missiles expire after 10 s
BACK_ATTACK_COS = 0.5  # within +-60 degrees of the rear direction
NEUTRAL_PRIMARY = 50.0  # strength / agility / intelligence with no effect
PARRY_FACTOR = 0.5  # a parried hit does half damage
EPS = 1e-6
# Timers run down by float32 subtraction of the sub-step; the rounding error reaches ~1e-3 s
# over a 60 s cool time at 0.02 s steps (and a 4.0 s cast took 41 decisions with 1e-6).
TIME_EPS = 2e-3


@lane_function
def haste_factor(params: Params) -> jnp.ndarray:
    """``float32[U, 1, ...]``: cast and cool times are divided by this (1 + haste/100)."""
    return (1.0 + params.stats.haste / 100.0)[:, None]


@lane_function
def skill_targets(state: State, params: Params) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Target and validity of every skill slot: ``(int32[U, S, ...], bool[U, S, ...])``.

    Enemy-affecting skills aim at the unit's enemy target (players: the boss; the boss: its
    current target). Ally-only skills aim at the alive ally (self included) with the lowest HP
    fraction within range. Valid means alive and within range (centre distance).
    """
    sk = params.skills
    dist = norm(state.pos[:, None] - state.pos[None], axis=2)  # [U, U, ...], symmetric
    enemy_t = state.target  # [U, ...]
    enemy_d = pick(dist, enemy_t)  # dist[target[u], u] = dist[u, target[u]]
    # keep_dead_target: the reference boss casts at its target even after it died.
    t_alive = pick(state.alive, enemy_t) | params.config.keep_dead_target
    enemy_ok = t_alive[:, None] & (enemy_d[:, None] <= sk.range)
    same = params.team[:, None] == params.team[None]
    frac = state.hp / jnp.maximum(params.stats.max_hp, 1.0)
    cand = (same & state.alive[None])[:, None] & (dist[:, None] <= sk.range[:, :, None])  # [U, S, U, ...]
    ally_t = argmin(jnp.where(cand, frac[None, None], jnp.inf), axis=2)
    ally_ok = any_(cand, axis=2)
    ally_only = (sk.affect_enemy == 0) & (sk.affect_ally > 0)
    target = jnp.where(ally_only, ally_t, enemy_t[:, None])
    return target, jnp.where(ally_only, ally_ok, enemy_ok)


@lane_function
def usable_slot(state: State, params: Params, valid: jnp.ndarray, s: int) -> jnp.ndarray:
    """``bool[U, ...]``: can slot ``s`` start a cast now (GAME.md §5, with the casting/channeling rules)?

    A cast of a skill with ``cast_on_moving = 0`` is a *channel*; other casts are plain casts.
    """
    sk = params.skills
    on_moving = sk.cast_on_moving > 0
    busy_cast = any_(state.casting & on_moving, axis=1)
    busy_channel = any_(state.casting & ~on_moving, axis=1)
    return (
        state.alive
        & (sk.in_use[:, s] > 0)
        & ~state.casting[:, s]
        & (state.charges[:, s] > 0)
        & (state.mana >= sk.cost[:, s])
        & valid[:, s]
        & (on_moving[:, s] | ~state.moving)
        & (~busy_cast | (sk.cast_on_casting[:, s] > 0))
        & (~busy_channel | (sk.cast_on_channeling[:, s] > 0))
    )


@lane_function
def start_casts(state: State, params: Params, requested: jnp.ndarray) -> State:
    """Start the requested casts (``bool[U, S, ...]``) that are usable, slot by slot in order.

    Slot order makes "try attack 1, then attack 2" (the boss) and "cast every usable skill"
    (PT-HR) respect the cast-on-casting rule. Moving casters cancel their channels first.
    """
    channel = params.skills.cast_on_moving == 0
    state = state.replace(casting=state.casting & ~(channel & state.moving[:, None]))
    _, valid = skill_targets(state, params)
    requested = requested | (params.skills.trigger == TRIGGER_PASSIVE)
    cast_time = params.skills.cast_time / haste_factor(params)
    # Columns, stacked where read: an in-place update per slot costs XLA:CPU a copy of the array.
    casting = [state.casting[:, s] for s in range(state.casting.shape[1])]
    left = [state.cast_left[:, s] for s in range(state.casting.shape[1])]
    for s in range(len(casting)):
        start = requested[:, s] & usable_slot(state.replace(casting=jnp.stack(casting, axis=1)), params, valid, s)
        casting[s] = casting[s] | start
        left[s] = jnp.where(start, cast_time[:, s], left[s])
    return state.replace(casting=jnp.stack(casting, axis=1), cast_left=jnp.stack(left, axis=1))


@lane_function
def expired(left: jnp.ndarray, params: Params) -> jnp.ndarray:
    """Whether timers ``left`` (seconds, already counted down this tick) have run out.

    ``unity_timers``: the reference's ``for (r = T; r >= 0; r -= 0.02f)`` loop, so a timer ends on
    the first tick it is below 0 (float32 rounding makes 0.1 s last 6 ticks, 0.5 s 25, 1.0 s 51).
    Otherwise a timer of T seconds ends after T (within ``TIME_EPS`` of float32 rounding).
    """
    return left < 0.0 if params.config.unity_timers else left <= TIME_EPS


@lane_function
def advance_casts(state: State, params: Params, n_ticks: int) -> tuple[State, jnp.ndarray]:
    """Count casts and cooldowns down tick by tick; the casts that complete fire.

    Returns the state and ``fired: int32[U, S, ...]``, the tick (1..n_ticks) of this sub-step in which
    each slot's cast completed, 0 where none did.

    Firing pays mana and uses a charge; it starts a cooldown only if none is running for the
    slot and the slot is below its charge (the reference's ``Cast`` / ``Cooldown`` coroutines).
    A running cooldown adds one charge when it ends and starts over while the slot is still
    below its charge. ``recharging`` is explicit state: under ``carry_cooldowns`` a cooldown
    carried into the next episode adds its charge on top of the refilled ones (no cap).
    A cast that completes when its caster can no longer pay (other casts spent the mana
    meanwhile) fizzles like a cancelled cast; slots pay in order, so mana never goes negative.
    """
    sk = params.skills
    unity = params.config.unity_timers
    tick = jnp.float32(TICK)
    cool = sk.cool_time / haste_factor(params)
    alive = state.alive[:, None]
    cast_left, casting, mana = state.cast_left, state.casting & alive, state.mana
    charges, recharging, recharge = state.charges, state.recharging, state.recharge_left
    fired = jnp.zeros(casting.shape, jnp.int32)
    for tick_no in range(1, n_ticks + 1):
        cast_left = jnp.where(casting, cast_left - tick, cast_left)
        done = casting & expired(cast_left, params)
        paid = []
        for s in range(done.shape[1]):
            ok = done[:, s] & (mana >= sk.cost[:, s])
            mana = mana - jnp.where(ok, sk.cost[:, s], 0.0)
            paid.append(ok)
        now = jnp.stack(paid, axis=1)
        casting = casting & ~done
        # Running cooldowns tick; one that ends adds its charge and starts over if still short.
        recharge = jnp.where(recharging, recharge - tick, recharge)
        back = recharging & expired(recharge, params)
        charges = charges + back.astype(jnp.int32)
        again = back & (charges < sk.charge)
        # The reference restarts its loop at the full cool time; the clean game keeps the
        # overshoot so that cool times that are not whole ticks keep their exact cadence.
        recharge = jnp.where(again, cool + (0.0 if unity else recharge), recharge)
        recharging = recharging & (~back | again)
        # A skill with no cool time uses no charge (the reference's Activate: `if (cooltime > 0) nowCharged -= 1`).
        used = now & (cool > 0)
        charges = charges - used.astype(jnp.int32)
        start = used & ~recharging & (charges < sk.charge)
        overshoot = 0.0 if unity else jnp.minimum(cast_left, 0.0)
        recharge = jnp.where(start, cool + overshoot, recharge)
        recharging = recharging | start
        fired = jnp.where(now, tick_no, fired)
    return state.replace(cast_left=cast_left, casting=casting, charges=charges, recharging=recharging,
                         recharge_left=recharge, mana=mana), fired


@lane_function
def ticks_until_expired(left: jnp.ndarray, params: Params, n_ticks: int) -> jnp.ndarray:
    """``int32[...]``: the tick (1..n_ticks) in which timers at ``left`` run out, ``n_ticks + 1`` if later."""
    tick = jnp.float32(TICK)
    when = jnp.full(left.shape, n_ticks + 1, jnp.int32)
    for j in range(1, n_ticks + 1):
        left = left - tick  # the same float32 countdown as advance_casts
        when = jnp.where(expired(left, params) & (when > n_ticks), j, when)
    return when


@lane_function
def fire(state: State, params: Params, fired_tick: jnp.ndarray, n_ticks: int):
    """Deliver fired skills: spawn missiles/areas into the pool, return instant hits.

    Args:
        fired_tick: ``int32[U, S, ...]`` from ``advance_casts`` (tick of the sub-step a cast completed, or 0).
        n_ticks: ticks in this sub-step.

    Returns ``(state, instant_hits, instant_from: float32[U*S, 2, ...], spawns)`` where ``instant_hits =
    (hit: bool[U*S, ...], unit: int32[U*S, ...])`` (an instant skill hits its target) and ``spawns``
    (``Spawns``) holds the projectiles and areas requested, their slots not yet taken
    (``slot_match`` and ``take_slots`` assign them, ``spawn`` writes them).
    The boss re-picks its target (nearest alive player) as its skills fire; straight missiles keep
    the facing the caster had.
    """
    fired = fired_tick > 0
    u_n, s_n = fired.shape[:2]
    lanes = fired.shape[2:]
    b = u_n - 1
    # Straight missiles fly along the facing the caster had while casting (the boss faced its
    # old target); the re-picked target matters for homing, instant and area delivery.
    facing = jnp.stack([jnp.cos(state.heading), jnp.sin(state.heading)], axis=1)
    boss_fired = any_(fired[b])
    new_t = jnp.where(boss_fired, nearest_alive_player(state), state.target[b])
    to_t = pick(state.pos, new_t[None]) - state.pos[b]
    face = jnp.where(boss_fired & state.alive[b], jnp.arctan2(to_t[1], to_t[0]), state.heading[b])
    state = state.replace(target=set_boss(state.target, new_t), heading=set_boss(state.heading, face))

    sk = params.skills
    target, _ = skill_targets(state, params)
    region = sk.target_type == TARGET_REGION
    instant = ~region & (sk.projectile_speed <= 0)
    kind = jnp.where(region, PROJ_AREA, jnp.where(sk.target_type == TARGET_UNIT, PROJ_HOMING, PROJ_STRAIGHT))
    caster = jnp.broadcast_to(state.pos[:, None], (u_n, s_n, 2) + lanes)
    tpos = pick(state.pos, target[:, :, None])
    spawn_pos = jnp.where(region[:, :, None], caster + sk.area_offset[:, :, None] * (tpos - caster), caster)

    r = u_n * s_n
    req = (fired & ~instant).reshape((r,) + lanes)
    area_life = TICK if params.config.one_step_area else AREA_LIFETIME
    life = jnp.where(region, area_life, MISSILE_LIFETIME)
    per_request = lambda x: jnp.broadcast_to(x, fired.shape).reshape((r,) + lanes)  # noqa: E731
    spawns = Spawns(requested=req, got=None, src=None, pos=spawn_pos.reshape((r, 2) + lanes), kind=per_request(kind),
                    target=per_request(target), tick=per_request(fired_tick), life=per_request(life), facing=facing)
    inst = (fired & instant).reshape((r,) + lanes)
    inst_target = target.reshape((r,) + lanes)
    instant_hits = (inst & pick(state.alive, inst_target), inst_target)
    return state, instant_hits, caster.reshape((r, 2) + lanes), spawns


@lane_function
def slot_match(requested: jnp.ndarray, live: jnp.ndarray) -> jnp.ndarray:
    """``bool[R, M, ...]``: request r takes pool slot m. The k-th request (in unit, then slot order)
    takes the k-th free slot (lowest first); requests beyond the free slots take none.
    ``requested``: ``Spawns.requested``, ``bool[R, ...]``; ``live``: the pool's ``bool[M, ...]``."""
    free = ~live
    req_rank = jnp.where(requested, cumsum(requested) - 1, -1)
    free_rank = jnp.where(free, cumsum(free) - 1, -2)
    return req_rank[:, None] == free_rank[None]


@lane_function
def take_slots(state: State, spawns: Spawns, match: jnp.ndarray) -> tuple[State, Spawns]:
    """``spawns`` with the slots its requests take (``got``, ``src``, from ``slot_match``'s ``match``),
    and the state with the requests that found no free slot counted in ``dropped``."""
    got = any_(match)
    src = first_true(match)  # [M, ...] request feeding each slot
    state = state.replace(dropped=state.dropped + (total(spawns.requested) - total(got)))
    return state, spawns.replace(got=got, src=src)


@lane_function
def spawn(p: Projectiles, spawns: Spawns, n_ticks: int) -> tuple[Projectiles, jnp.ndarray]:
    """Write ``fire``'s ``spawns`` into pool slots ``p`` (all ``M`` or a block of them, with ``got`` and
    ``src`` cut alike). Returns the slots and ``flight: float32[n, ...]``, how long each flies in this
    sub-step: the whole sub-step, or, for a projectile spawned now, the ticks after the one it was
    fired in (the reference spawns in the end-of-tick coroutine phase; a projectile first moves and
    collides in the next tick)."""
    got, src = spawns.got, spawns.src
    s_n = spawns.kind.shape[0] // spawns.facing.shape[0]
    owner, slot = jax.lax.div(src, s_n), jax.lax.rem(src, s_n)  # request r is unit r // S's slot r % S
    # Each slot's request, by selects over the R requests (and the caster's facing over U units).
    pos, kind, target, tick, life, direction = (
        pick(spawns.pos, src[:, None]), pick(spawns.kind, src), pick(spawns.target, src), pick(spawns.tick, src),
        pick(spawns.life, src), pick(spawns.facing, owner[:, None]))
    g = got[:, None]
    p = Projectiles(
        live=p.live | got,
        kind=jnp.where(got, kind, p.kind),
        pos=jnp.where(g, pos, p.pos),
        direction=jnp.where(g, direction, p.direction),
        owner=jnp.where(got, owner, p.owner),
        slot=jnp.where(got, slot, p.slot),
        target=jnp.where(got, target, p.target),
        life=jnp.where(got, life, p.life),
        hit_mask=p.hit_mask & ~g,
    )
    return p, jnp.where(got, n_ticks - tick, n_ticks) * TICK


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
def unit_columns(state: State, params: Params, facing: jnp.ndarray | None = None) -> dict[str, jnp.ndarray]:
    """Per-unit columns ``float32[U, ...]`` a hit reads from the unit it touches (position, rear
    direction, evasion, agility, parry, armour factor, team): read by every hit event of a sub-step.

    ``facing``: ``fire``'s ``float32[U, 2, ...]`` (cos and sin of the headings before the boss turned
    to fire), if at hand: only the boss's are then computed again, the players' being the same.
    """
    st = params.stats
    if facing is None:
        cos_h, sin_h = jnp.cos(state.heading), jnp.sin(state.heading)
    else:
        boss = state.heading[-1:]
        cos_h = jnp.concatenate([facing[:-1, 0], jnp.cos(boss)])
        sin_h = jnp.concatenate([facing[:-1, 1], jnp.sin(boss)])
    return {
        "x": state.pos[:, 0], "y": state.pos[:, 1], "back_x": -cos_h, "back_y": -sin_h,
        "evasion": st.evasion, "agility": st.agility, "parry": st.parry,
        "armor": (1.0 - st.armor / 200.0) * (1.0 - st.versatility / 200.0),
        "team": params.team.astype(jnp.float32),
    }


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
def hit_outcomes(seeds, unit_cols, f, hits, from_pos, n_events: int, first, u_n: int, lanes: tuple) -> HitOutcomes:
    """The dice and modifiers of one group of a sub-step's hit events (``group_sums`` adds them up).

    A sub-step's ``E`` hit events come in groups (the pool's projectiles, block by block, then every
    unit's ``S`` instant skill slots, then every unit's basic attack). Die ``d`` of event ``e`` on
    unit ``u`` is die number ``(d * E + e) * U + u`` of the sub-step.

    Args:
        seeds: ``uint32[2, ...]`` dice seeds (``utils.dice_seeds``) for crits, dodges and parries.
        unit_cols: ``unit_columns``' dict of ``float32[U, ...]``.
        f: ``Effects`` of the group's ``n`` events (each event's source, ``event_sources``).
        hits: the units each event touches: ``bool[n, U, ...]``, or ``(hit: bool[n, ...], unit:
            int32[n, ...])`` for events that touch at most one unit (only that unit's dice and
            damage are computed).
        from_pos: ``float32[n, 2, ...]`` where each event comes from (back attacks).
        n_events: ``E``; first: the group's first event (an ``int``, or a traced ``int32[]`` for
            the pool's blocks).
        u_n: ``U``; lanes: the lane axes' shape.

    Returns:
        ``HitOutcomes``.
    """
    xp = np if isinstance(first, int) else jnp
    base = (xp.arange(3)[:, None] * n_events + first + xp.arange(f.base.shape[0])[None]) * u_n  # [3, n]
    single = isinstance(hits, tuple)
    if single:  # one unit per event: [n, ...]
        hit, unit = hits
        from_x, from_y = from_pos[:, 0], from_pos[:, 1]
        index = jnp.asarray(base.reshape(base.shape + (1,) * len(lanes)), jnp.uint32) + unit.astype(jnp.uint32)
        col = {k: pick(v, unit) for k, v in unit_cols.items()}
    else:  # every unit: [n, U, ...]
        hit = hits
        from_x, from_y = from_pos[:, 0, None], from_pos[:, 1, None]
        index = base[:, :, None] + np.arange(u_n)
        # numpy: the same indices in every lane; traced (the pool's blocks): give it the lane axes.
        index = (index.astype(np.uint32) if isinstance(index, np.ndarray)
                 else index.reshape(index.shape + (1,) * len(lanes)).astype(jnp.uint32))
        col = {k: v[None] for k, v in unit_cols.items()}
    fc = lambda c: _per_event(f, c, single)  # noqa: E731
    dice = hash_dice(seeds, index)
    crit = dice[0] < fc("crit")
    relx, rely = from_x - col["x"], from_y - col["y"]
    length = jnp.maximum(jnp.sqrt(relx * relx + rely * rely), EPS)
    back = (relx / length) * col["back_x"] + (rely / length) * col["back_y"] >= BACK_ATTACK_COS
    evasion = col["evasion"] + 0.5 * (col["agility"] - fc("agility"))
    dodge = dice[1] * 100.0 < evasion
    parry = dice[2] * 100.0 < col["parry"]
    mult = (
        jnp.where(crit, fc("crit_mult"), 1.0)
        * jnp.where(back, fc("back_mult"), 1.0)
        * fc("vers")
        * col["armor"]
        * jnp.where(parry, PARRY_FACTOR, 1.0)
    )
    enemy = fc("team") != col["team"]
    # Homing and instant hits land on their target whatever the flags: gate them here.
    harm = hit & enemy & (fc("enemy") > 0) & ~dodge
    healed = hit & ~enemy & (fc("ally") > 0)
    return HitOutcomes(harm, healed, back, mult)


def _per_event(f: Effects, column: str, single: bool) -> jax.Array:
    """Column ``column`` of ``f``, shaped to broadcast over a group's ``[n, ...]`` or ``[n, U, ...]``."""
    x = getattr(f, column)
    return x if single else x[:, None]


@lane_function
def group_sums(outcomes: HitOutcomes, f: Effects, owner, hits, u_n: int) -> HitSums:
    """What one group of hit events adds up to (``hit_outcomes``' ``outcomes``; ``f``, ``owner`` and
    ``hits`` as there; ``u_n``: ``U``). Damage is whole points, so every sum is exact in any order, and the groups'
    sums add up exactly."""
    single = isinstance(hits, tuple)
    harm, healed, back, mult = outcomes
    fc = lambda c: _per_event(f, c, single)  # noqa: E731
    damage = jnp.where(harm, jnp.floor(fc("base") * mult + 1e-3), 0.0)
    heal = jnp.where(healed, fc("heal"), 0.0)
    back_landed = harm & back & (fc("team") == 0)
    if single:  # spread each event's one target over the unit axis
        on = one_hot(hits[1], u_n, axis=1)
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

    Off when ``attack_power = 0`` (the reference setting). Returns ``(state, (hit: bool[U, ...], unit:
    int32[U, ...]))``: whether each unit's attack hits its target this sub-step, and the target.
    """
    st = params.stats
    t = state.target
    d = norm(pick(state.pos, t[:, None]) - state.pos, axis=1) - st.radius - pick(st.radius, t)
    # Time passes first, so that the next attack comes 1 / attack_speed after this one.
    left = jnp.maximum(state.basic_cooldown - dt, 0.0)
    ready = left <= TIME_EPS
    go = state.alive & pick(state.alive, t) & (st.attack_power > 0) & (d <= st.attack_range) & ready
    cooldown = jnp.where(go, 1.0 / st.attack_speed, left)
    return state.replace(basic_cooldown=cooldown), (go, t)


@lane_function
def regenerate(state: State, params: Params, dt: float) -> State:
    """HP and mana regeneration of alive units, capped at their maxima."""
    st = params.stats
    hp = jnp.where(state.alive, jnp.minimum(state.hp + st.hp_regen * dt, st.max_hp), state.hp)
    mana = jnp.where(state.alive, jnp.minimum(state.mana + st.mana_regen * dt, st.max_mana), state.mana)
    return state.replace(hp=hp, mana=mana)
