"""Casting, cooldowns/charges/mana, the projectile pool and damage (GAME.md §5–§6), one arena.

Shapes: ``U`` units (boss last), ``S`` skill slots, ``M`` projectile slots,
``E = M + U*S + U`` hit events per sub-step (projectiles, instant skills, basic attacks).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from raidjax import collide
from raidjax.movement import heading_vec, nearest_alive_player
from raidjax.types import (
    HALF_ARENA,
    HIT_ATTACK,
    PROJ_AREA,
    PROJ_HOMING,
    PROJ_STRAIGHT,
    TARGET_REGION,
    TARGET_UNIT,
    TICK,
    TRIGGER_PASSIVE,
    Params,
    Projectiles,
    State,
)
from raidjax.utils import contract, pick, uniform_dice

AREA_LIFETIME = 5 * TICK  # an area lingers 5 ticks
MISSILE_LIFETIME = 10.0  # safety net: missiles expire after 10 s
BACK_ATTACK_COS = 0.5  # within +-60 degrees of the rear direction
NEUTRAL_PRIMARY = 50.0  # strength / agility / intelligence with no effect
PARRY_FACTOR = 0.5  # a parried hit does half damage
EPS = 1e-6
# Timers run down by float32 subtraction of the sub-step; the rounding error reaches ~1e-3 s
# over a 60 s cool time at 0.02 s steps (and a 4.0 s cast took 41 decisions with 1e-6).
TIME_EPS = 2e-3


def haste_factor(params: Params) -> jnp.ndarray:
    """``float32[U, 1]``: cast and cool times are divided by this (1 + haste/100)."""
    return (1.0 + params.stats.haste / 100.0)[:, None]


def skill_targets(state: State, params: Params) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Target and validity of every skill slot: ``(int32[U, S], bool[U, S])``.

    Enemy-affecting skills aim at the unit's enemy target (players: the boss; the boss: its
    current target). Ally-only skills aim at the alive ally (self included) with the lowest HP
    fraction within range. Valid means alive and within range (centre distance).
    """
    sk = params.skills
    dist = jnp.linalg.norm(state.pos[:, None] - state.pos[None], axis=-1)  # [U, U]
    enemy_t = state.target  # [U]
    t_oh = jax.nn.one_hot(enemy_t, dist.shape[0], dtype=bool)
    enemy_d = jnp.sum(jnp.where(t_oh, dist, 0.0), axis=1, keepdims=True)  # [U, 1]
    # keep_dead_target: the reference boss casts at its target even after it died.
    t_alive = jnp.any(t_oh & state.alive[None], axis=1) | params.config.keep_dead_target
    enemy_ok = t_alive[:, None] & (enemy_d <= sk.range)
    same = params.team[:, None] == params.team[None]
    frac = state.hp / jnp.maximum(params.stats.max_hp, 1.0)
    cand = (same & state.alive[None])[:, None, :] & (dist[:, None, :] <= sk.range[..., None])  # [U,S,U]
    ally_t = jnp.argmin(jnp.where(cand, frac[None, None], jnp.inf), axis=-1).astype(jnp.int32)
    ally_ok = jnp.any(cand, axis=-1)
    ally_only = (sk.affect_enemy == 0) & (sk.affect_ally > 0)
    target = jnp.where(ally_only, ally_t, enemy_t[:, None])
    return target, jnp.where(ally_only, ally_ok, enemy_ok)


def usable_slot(state: State, params: Params, valid: jnp.ndarray, s: int) -> jnp.ndarray:
    """``bool[U]``: can slot ``s`` start a cast now (GAME.md §5, with the casting/channeling rules)?

    A cast of a skill with ``cast_on_moving = 0`` is a *channel*; other casts are plain casts.
    """
    sk = params.skills
    on_moving = sk.cast_on_moving > 0
    busy_cast = jnp.any(state.casting & on_moving, axis=-1)
    busy_channel = jnp.any(state.casting & ~on_moving, axis=-1)
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


def start_casts(state: State, params: Params, requested: jnp.ndarray) -> State:
    """Start the requested casts (``bool[U, S]``) that are usable, slot by slot in order.

    Slot order makes "try attack 1, then attack 2" (the boss) and "cast every usable skill"
    (PT-HR) respect the cast-on-casting rule. Moving casters cancel their channels first.
    """
    channel = params.skills.cast_on_moving == 0
    state = state.replace(casting=state.casting & ~(channel & state.moving[:, None]))
    _, valid = skill_targets(state, params)
    requested = requested | (params.skills.trigger == TRIGGER_PASSIVE)
    cast_time = params.skills.cast_time / haste_factor(params)
    for s in range(state.casting.shape[1]):
        start = requested[:, s] & usable_slot(state, params, valid, s)
        state = state.replace(
            casting=state.casting.at[:, s].set(state.casting[:, s] | start),
            cast_left=state.cast_left.at[:, s].set(jnp.where(start, cast_time[:, s], state.cast_left[:, s])),
        )
    return state


def expired(left: jnp.ndarray, params: Params) -> jnp.ndarray:
    """Whether timers ``left`` (seconds, already counted down this tick) have run out.

    ``unity_timers``: the reference's ``for (r = T; r >= 0; r -= 0.02f)`` loop, so a timer ends on
    the first tick it is below 0 (float32 rounding makes 0.1 s last 6 ticks, 0.5 s 25, 1.0 s 51).
    Otherwise a timer of T seconds ends after T (within ``TIME_EPS`` of float32 rounding).
    """
    return left < 0.0 if params.config.unity_timers else left <= TIME_EPS


def advance_casts(state: State, params: Params, n_ticks: int) -> tuple[State, jnp.ndarray]:
    """Count casts and cooldowns down tick by tick; the casts that complete fire.

    Returns the state and ``fired: int32[U, S]``, the tick (1..n_ticks) of this sub-step in which
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
        now = jnp.stack(paid, axis=-1)
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


def ticks_until_expired(left: jnp.ndarray, params: Params, n_ticks: int) -> jnp.ndarray:
    """``int32[...]``: the tick (1..n_ticks) in which timers at ``left`` run out, ``n_ticks + 1`` if later."""
    tick = jnp.float32(TICK)
    when = jnp.full(left.shape, n_ticks + 1, jnp.int32)
    for j in range(1, n_ticks + 1):
        left = left - tick  # the same float32 countdown as advance_casts
        when = jnp.where(expired(left, params) & (when > n_ticks), j, when)
    return when


def fire(state: State, params: Params, fired_tick: jnp.ndarray, n_ticks: int):
    """Deliver fired skills: spawn missiles/areas into the pool, return instant hits.

    Args:
        fired_tick: ``int32[U, S]`` from ``advance_casts`` (tick of the sub-step a cast completed, or 0).
        n_ticks: ticks in this sub-step.

    Returns ``(state, instant_hits: bool[U*S, U], instant_from: float32[U*S, 2], flight: float32[M])``
    where ``flight`` is how long each pool slot flies in this sub-step: the whole sub-step, or, for
    a projectile spawned now, the ticks after the one it was fired in (the reference spawns in the
    end-of-tick coroutine phase; a projectile first moves and collides in the next tick).
    The boss re-picks its target (nearest alive player) as its skills fire; straight missiles
    keep the facing the caster had.
    """
    fired = fired_tick > 0
    u_n, s_n = fired.shape
    b = u_n - 1
    # Straight missiles fly along the facing the caster had while casting (the boss faced its
    # old target); the re-picked target matters for homing, instant and area delivery.
    direction = jnp.broadcast_to(heading_vec(state.heading)[:, None], (u_n, s_n, 2))
    new_t = jnp.where(jnp.any(fired[b]), nearest_alive_player(state), state.target[b])
    to_t = pick(state.pos, new_t) - state.pos[b]
    face = jnp.where(jnp.any(fired[b]) & state.alive[b], jnp.arctan2(to_t[1], to_t[0]), state.heading[b])
    state = state.replace(target=state.target.at[b].set(new_t), heading=state.heading.at[b].set(face))

    sk = params.skills
    target, _ = skill_targets(state, params)
    region = sk.target_type == TARGET_REGION
    instant = ~region & (sk.projectile_speed <= 0)
    kind = jnp.where(region, PROJ_AREA, jnp.where(sk.target_type == TARGET_UNIT, PROJ_HOMING, PROJ_STRAIGHT))
    caster = jnp.broadcast_to(state.pos[:, None], (u_n, s_n, 2))
    tpos = pick(state.pos, target)
    spawn_pos = jnp.where(region[..., None], caster + sk.area_offset[..., None] * (tpos - caster), caster)

    r = u_n * s_n
    req = (fired & ~instant).reshape(r)
    p = state.projectiles
    free = ~p.live
    req_rank = jnp.where(req, jnp.cumsum(req) - 1, -1)
    free_rank = jnp.where(free, jnp.cumsum(free) - 1, -2)
    assign = req_rank[:, None] == free_rank[None]  # [R, M]: request r goes to pool slot m
    got = jnp.any(assign, axis=0)
    src = jnp.argmax(assign, axis=0)  # [M] request feeding each slot
    owner = jnp.broadcast_to(jnp.arange(u_n)[:, None], (u_n, s_n))
    slot = jnp.broadcast_to(jnp.arange(s_n)[None], (u_n, s_n))
    area_life = TICK if params.config.one_step_area else AREA_LIFETIME
    life = jnp.where(region, area_life, MISSILE_LIFETIME)
    # One packed gather instead of one scatter per field: [R, 10] -> [M, 10].
    cols = jnp.stack([kind, owner, slot, target, fired_tick], -1).astype(jnp.float32)
    packed = jnp.concatenate([spawn_pos, direction, cols, life[..., None]], axis=-1).reshape(r, 10)
    new = jnp.take(packed, src, axis=0)
    g = got[:, None]
    as_int = lambda x: jnp.round(x).astype(jnp.int32)  # noqa: E731
    proj = Projectiles(
        live=p.live | got,
        kind=jnp.where(got, as_int(new[:, 4]), p.kind),
        pos=jnp.where(g, new[:, 0:2], p.pos),
        direction=jnp.where(g, new[:, 2:4], p.direction),
        owner=jnp.where(got, as_int(new[:, 5]), p.owner),
        slot=jnp.where(got, as_int(new[:, 6]), p.slot),
        target=jnp.where(got, as_int(new[:, 7]), p.target),
        life=jnp.where(got, new[:, 9], p.life),
        hit_mask=p.hit_mask & ~g,
    )
    dropped = jnp.sum(req) - jnp.sum(got)
    inst = (fired & instant).reshape(r)
    instant_hits = inst[:, None] & jax.nn.one_hot(target.reshape(r), u_n, dtype=bool)
    instant_hits = instant_hits & state.alive[None]
    flight = jnp.where(got, n_ticks - new[:, 8], n_ticks) * TICK
    state = state.replace(projectiles=proj, dropped=state.dropped + dropped)
    return state, instant_hits, caster.reshape(r, 2), flight


# Columns of the per-source effect table (``effect_table``).
(F_BASE, F_HEAL, F_CRIT, F_CRIT_MULT, F_BACK_MULT, F_VERS, F_AGI, F_TEAM, F_ENEMY, F_ALLY, F_SPEED, F_RADIUS,
 F_HITS) = range(13)


def effect_table(params: Params) -> jnp.ndarray:
    """Everything a hit needs to know about its source, ``float32[U * (S + 1), 13]``.

    Row ``u * (S + 1) + s`` is unit u's skill slot s; row ``u * (S + 1) + S`` its basic attack.
    Events look their source up with one contraction (``utils.pick``) instead of many gathers.
    """
    sk, st = params.skills, params.stats
    u_n, s_n = sk.coefficient.shape
    attack = jnp.concatenate([sk.hit_type == HIT_ATTACK, jnp.ones((u_n, 1), bool)], axis=1)
    coef = jnp.concatenate([sk.coefficient, jnp.ones((u_n, 1))], axis=1)
    str_scale = 1.0 + (st.strength - NEUTRAL_PRIMARY) / 100.0
    int_scale = 1.0 + (st.intelligence - NEUTRAL_PRIMARY) / 100.0
    power = jnp.where(attack, st.attack_power[:, None], st.spell_power[:, None])
    scale = jnp.where(attack, str_scale[:, None], int_scale[:, None])
    base = jnp.floor(coef * power + 1e-3) * scale  # GAME.md §6: int(coefficient x power)
    heal = jnp.floor(coef * (st.spell_power * int_scale)[:, None] + 1e-3)

    def per_unit(x):
        return jnp.broadcast_to(x[:, None], (u_n, s_n + 1))

    def per_slot(x, basic_value):
        return jnp.concatenate([x.astype(jnp.float32), jnp.full((u_n, 1), basic_value)], axis=1)

    cols = [
        base, heal, per_unit(st.critical / 100.0), per_unit(st.crit_multiplier),
        per_unit(jnp.where(params.team == 0, st.back_attack_multiplier * (1.0 + st.mastery / 100.0), 1.0)),
        per_unit(1.0 + st.versatility / 100.0), per_unit(st.agility), per_unit(params.team.astype(jnp.float32)),
        per_slot(sk.affect_enemy, 1.0), per_slot(sk.affect_ally, 0.0), per_slot(sk.projectile_speed, 0.0),
        per_slot(sk.projectile_radius, 0.0), per_slot(sk.hit_count, 1.0),
    ]
    return jnp.stack(cols, axis=-1).reshape(u_n * (s_n + 1), len(cols))


def source_index(owner: jnp.ndarray, slot: jnp.ndarray, n_slots: int) -> jnp.ndarray:
    """Row of ``effect_table`` for ``(owner, slot)`` (``slot = n_slots`` is the basic attack)."""
    return owner * (n_slots + 1) + slot


def touchable(feats: jnp.ndarray, params: Params, alive: jnp.ndarray) -> jnp.ndarray:
    """``bool[E, U]``: alive units an effect with source features ``feats[E, 13]`` can touch."""
    same = feats[:, F_TEAM, None] == params.team[None].astype(jnp.float32)
    return ((feats[:, F_ENEMY, None] > 0) & ~same | (feats[:, F_ALLY, None] > 0) & same) & alive[None]


def move_projectiles(state: State, params: Params, table: jnp.ndarray, flight: jnp.ndarray):
    """Advance the pool one sub-step with swept collision; slot m flies ``flight[m]`` seconds
    (``fire``'s ``flight``: 0 for a projectile spawned in the last tick, which neither moves nor
    hits before the next).

    Returns ``(state, hits: bool[M, U], from_pos: float32[M, 2])`` where ``from_pos`` is the
    projectile's position before the move (the direction a hit comes from).
    """
    p = state.projectiles
    s_n = state.casting.shape[1]
    u_n = state.pos.shape[0]
    feats = pick(table, source_index(p.owner, p.slot, s_n))  # [M, F]
    step = feats[:, F_SPEED] * flight
    flying = p.live & (flight > 0)
    touch = touchable(feats, params, state.alive)  # [M, U]
    # Reference geometry (collide.py): bodies are squares of half side ``radius`` turning with
    # their heading; a projectile touches one within its own radius of the square.
    r_proj = feats[:, F_RADIUS]
    half = params.stats.radius
    rel = state.pos[None] - p.pos[:, None]  # [M, U, 2]
    dist = jnp.linalg.norm(rel, axis=-1)
    t_oh = jax.nn.one_hot(p.target, u_n, dtype=bool)

    def of_target(x):  # x[U, ...] -> x[target of each slot]: [M, ...] (a masked sum: no gather)
        oh = t_oh.reshape(t_oh.shape + (1,) * (x.ndim - 1))
        if x.dtype == jnp.bool_:
            return jnp.any(oh & x[None], axis=1)
        return jnp.sum(jnp.where(oh, x[None], 0), axis=1)

    # Homing: straight at the target's current position; hits only its target, once within reach
    # at the end of its move (it flies at the body's centre, so it cannot pass through it).
    # Only the target matters, so this is [M] work, not [M, U].
    trel = of_target(state.pos) - p.pos
    tdist = jnp.linalg.norm(trel, axis=-1)
    t_alive = of_target(state.alive)
    homing = flying & (p.kind == PROJ_HOMING)
    pos_h = p.pos + trel / jnp.maximum(tdist, EPS)[:, None] * jnp.minimum(step, tdist)[:, None]
    t_heading = of_target(state.heading)
    end_gap = collide.box_distance(collide.to_body_frame(pos_h - of_target(state.pos), t_heading), of_target(half))
    hit_h = homing & t_alive & (end_gap <= r_proj)
    hits_h = hit_h[:, None] & t_oh

    # Straight: first touched unit along the segment; walls destroy it.
    q0 = collide.to_body_frame(-rel, state.heading)
    d0 = collide.to_body_frame(jnp.broadcast_to(p.direction[:, None], rel.shape), state.heading)
    t_in = collide.ray_entry(q0, d0, half, r_proj)
    cross = touch & (t_in <= step[:, None])
    straight = flying & (p.kind == PROJ_STRAIGHT)
    first = jnp.argmin(jnp.where(cross, t_in, jnp.inf), axis=1)
    hit_s = straight & jnp.any(cross, axis=1)
    hits_s = hit_s[:, None] & jax.nn.one_hot(first, u_n, dtype=bool)
    pos_s = p.pos + p.direction * step[:, None]
    out = jnp.any(jnp.abs(pos_s) > HALF_ARENA, axis=-1)

    # Area: every touchable unit inside, nearest first, at most hit_count units in all.
    area = flying & (p.kind == PROJ_AREA)
    gap = collide.box_distance(q0, half)
    inside = area[:, None] & touch & (gap <= r_proj[:, None]) & ~p.hit_mask
    order = jnp.arange(u_n)
    closer = (dist[:, None, :] < dist[:, :, None]) | (
        (dist[:, None, :] == dist[:, :, None]) & (order[None, None] < order[None, :, None])
    )
    rank = jnp.sum(closer & inside[:, None, :], axis=-1)
    # one_step_area: the reference's slash is switched off by its first hit.
    cap = 1.0 if params.config.one_step_area else feats[:, F_HITS]
    left = cap - jnp.sum(p.hit_mask, axis=1)
    hits_a = inside & (rank < left[:, None])

    hits = hits_h | hits_s | hits_a
    pos = jnp.where(homing[:, None], pos_h, jnp.where(straight[:, None], pos_s, p.pos))
    life = p.life - flight
    gone = (homing & (hit_h | ~t_alive)) | (straight & (hit_s | out)) | (life <= EPS)
    new = p.replace(live=p.live & ~gone, pos=pos, life=life, hit_mask=p.hit_mask | hits_a)
    return state.replace(projectiles=new), hits, p.pos


def resolve_hits(key, state: State, params: Params, table: jnp.ndarray, hits, source, from_pos):
    """Apply damage and heals of ``E`` hit events to the units.

    Args:
        key: PRNG key for crits, dodges and parries.
        table: ``effect_table(params)``.
        hits: ``bool[E, U]`` event e touches unit u.
        source: ``int32[E]`` row of ``table`` (owner and slot, or the owner's basic attack).
        from_pos: ``float32[E, 2]`` where the hit comes from (back-attack test).

    Returns:
        ``(state, dealt_to_boss: float32[U], back: int32[U])`` by owner.
    """
    st = params.stats
    e_n, u_n = hits.shape
    oh_src = jax.nn.one_hot(source, table.shape[0], dtype=jnp.float32)  # [E, R]
    f = jnp.take(table, source, axis=0)  # [E, F]
    by_owner = oh_src.reshape(e_n, u_n, -1).sum(-1)  # [E, U]

    dice = uniform_dice(key, (3, e_n, u_n))
    crit = dice[0] < f[:, F_CRIT, None]
    rel = from_pos[:, None] - state.pos[None]  # [E, U, 2]
    rel = rel / jnp.maximum(jnp.linalg.norm(rel, axis=-1, keepdims=True), EPS)
    back = jnp.sum(rel * -heading_vec(state.heading)[None], axis=-1) >= BACK_ATTACK_COS
    evasion = st.evasion[None] + 0.5 * (st.agility[None] - f[:, F_AGI, None])
    dodge = dice[1] * 100.0 < evasion
    parry = dice[2] * 100.0 < st.parry[None]
    mult = (
        jnp.where(crit, f[:, F_CRIT_MULT, None], 1.0)
        * jnp.where(back, f[:, F_BACK_MULT, None], 1.0)
        * f[:, F_VERS, None]
        * ((1.0 - st.armor / 200.0) * (1.0 - st.versatility / 200.0))[None]
        * jnp.where(parry, PARRY_FACTOR, 1.0)
    )
    enemy = f[:, F_TEAM, None] != params.team[None].astype(jnp.float32)
    # Homing and instant hits land on their target whatever the flags: gate them here.
    harm = hits & enemy & (f[:, F_ENEMY, None] > 0) & ~dodge
    damage = jnp.where(harm, jnp.floor(f[:, F_BASE, None] * mult + 1e-3), 0.0)  # [E, U]
    heal = jnp.where(hits & ~enemy & (f[:, F_ALLY, None] > 0), f[:, F_HEAL, None], 0.0)
    # Materialise once: otherwise XLA:CPU recomputes the whole chain inside every reduction below.
    damage, heal, back = jax.lax.optimization_barrier((damage, heal, back))

    hp = state.hp - jnp.sum(damage, axis=0)
    alive = state.alive & (hp > 0)
    hp = jnp.where(alive, jnp.minimum(hp + jnp.sum(heal, axis=0), st.max_hp), 0.0)  # HP floors at 0
    dealt = contract(by_owner.T, jnp.sum(damage, axis=1))
    dealt_to_boss = contract(by_owner.T, damage[:, -1])
    back_landed = harm & back & (f[:, F_TEAM, None] == 0)
    back_count = contract(by_owner.T, jnp.sum(back_landed, axis=1).astype(jnp.float32)).astype(jnp.int32)
    died = state.alive & ~alive
    state = state.replace(
        hp=hp, alive=alive,
        casting=state.casting & alive[:, None],
        vel=jnp.where(died[:, None], 0.0, state.vel),
        damage_dealt=state.damage_dealt + dealt,
        back_attacks=state.back_attacks + back_count,
    )
    return state, dealt_to_boss, back_count


def basic_attacks(state: State, params: Params, dt: float):
    """Automatic melee hits on the enemy target within ``attack_range`` every ``1/attack_speed`` s.

    Off when ``attack_power = 0`` (the reference setting). Returns ``(state, hits: bool[U, U])``.
    """
    st = params.stats
    t = state.target
    d = jnp.linalg.norm(pick(state.pos, t) - state.pos, axis=-1) - st.radius - pick(st.radius, t)
    # Time passes first, so that the next attack comes 1 / attack_speed after this one.
    left = jnp.maximum(state.basic_cooldown - dt, 0.0)
    ready = left <= TIME_EPS
    go = state.alive & pick(state.alive, t) & (st.attack_power > 0) & (d <= st.attack_range) & ready
    cooldown = jnp.where(go, 1.0 / st.attack_speed, left)
    hits = go[:, None] & jax.nn.one_hot(t, t.shape[0], dtype=bool)
    return state.replace(basic_cooldown=cooldown), hits


def regenerate(state: State, params: Params, dt: float) -> State:
    """HP and mana regeneration of alive units, capped at their maxima."""
    st = params.stats
    hp = jnp.where(state.alive, jnp.minimum(state.hp + st.hp_regen * dt, st.max_hp), state.hp)
    mana = jnp.where(state.alive, jnp.minimum(state.mana + st.mana_regen * dt, st.max_mana), state.mana)
    return state.replace(hp=hp, mana=mana)
