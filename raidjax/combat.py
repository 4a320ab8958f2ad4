"""Casting, cooldowns/charges/mana, the projectile pool and damage (SPEC §5–§6), one arena.

Shapes: ``U`` units (boss last), ``S`` skill slots, ``M`` projectile slots,
``E = M + U*S + U`` hit events per sub-step (projectiles, instant skills, basic attacks).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from raidjax.movement import HALF_ARENA, TICK, heading_vec, nearest_alive_player
from raidjax.types import (
    HIT_ATTACK, PROJ_AREA, PROJ_HOMING, PROJ_STRAIGHT, TARGET_REGION, TARGET_UNIT, TRIGGER_PASSIVE,
    Params, Projectiles, State,
)

AREA_LIFETIME = 5 * TICK  # an area lingers 5 ticks
MISSILE_LIFETIME = 10.0  # safety net: missiles expire after 10 s
BACK_ATTACK_COS = 0.5  # within +-60 degrees of the rear direction
NEUTRAL_PRIMARY = 50.0  # strength / agility / intelligence with no effect
PARRY_FACTOR = 0.5  # a parried hit does half damage
EPS = 1e-6


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
    enemy_d = jnp.take_along_axis(dist, enemy_t[:, None], axis=1)  # [U, 1]
    enemy_ok = state.alive[enemy_t][:, None] & (enemy_d <= sk.range)
    same = params.team[:, None] == params.team[None]
    frac = state.hp / jnp.maximum(params.stats.max_hp, 1.0)
    cand = (same & state.alive[None])[:, None, :] & (dist[:, None, :] <= sk.range[..., None])  # [U,S,U]
    ally_t = jnp.argmin(jnp.where(cand, frac[None, None], jnp.inf), axis=-1).astype(jnp.int32)
    ally_ok = jnp.any(cand, axis=-1)
    ally_only = (sk.affect_enemy == 0) & (sk.affect_ally > 0)
    target = jnp.where(ally_only, ally_t, enemy_t[:, None])
    return target, jnp.where(ally_only, ally_ok, enemy_ok)


def usable_slot(state: State, params: Params, valid: jnp.ndarray, s: int) -> jnp.ndarray:
    """``bool[U]``: can slot ``s`` start a cast now (SPEC §5, with the casting/channeling rules)?

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


def advance_casts(state: State, params: Params, dt: float) -> tuple[State, jnp.ndarray]:
    """Count casts down; the ones that complete fire. Returns the state and ``fired: bool[U, S]``.

    Firing pays mana, uses a charge and starts the recharge timer (cool time starts when the
    cast completes; one charge returns per cool time).
    """
    sk = params.skills
    cast_left = jnp.where(state.casting, state.cast_left - dt, state.cast_left)
    fired = state.casting & (cast_left <= EPS) & state.alive[:, None]
    cool = sk.cool_time / haste_factor(params)
    full = state.charges >= sk.charge
    started = fired & full
    charges = state.charges - fired.astype(jnp.int32)
    recharge = jnp.where(started, cool, state.recharge_left)
    recharge = jnp.where((charges < sk.charge) & ~started, recharge - dt, recharge)
    back = (charges < sk.charge) & (recharge <= EPS)
    charges = charges + back.astype(jnp.int32)
    recharge = jnp.where(back & (charges < sk.charge), recharge + cool, recharge)
    mana = state.mana - jnp.sum(jnp.where(fired, sk.cost, 0.0), axis=-1)
    casting = state.casting & ~fired & state.alive[:, None]
    return state.replace(cast_left=cast_left, casting=casting, charges=charges,
                         recharge_left=recharge, mana=mana), fired


def fire(state: State, params: Params, fired: jnp.ndarray):
    """Deliver fired skills: spawn missiles/areas into the pool, return instant hits.

    Returns ``(state, instant_hits: bool[U*S, U], instant_from: float32[U*S, 2])``.
    The boss re-picks its target (nearest alive player) as its skills fire; straight missiles
    keep the facing the caster had.
    """
    u_n, s_n = fired.shape
    b = u_n - 1
    # Straight missiles fly along the facing the caster had while casting (the boss faced its
    # old target); the re-picked target matters for homing, instant and area delivery.
    direction = jnp.broadcast_to(heading_vec(state.heading)[:, None], (u_n, s_n, 2))
    new_t = jnp.where(jnp.any(fired[b]), nearest_alive_player(state), state.target[b])
    to_t = state.pos[new_t] - state.pos[b]
    face = jnp.where(jnp.any(fired[b]) & state.alive[b], jnp.arctan2(to_t[1], to_t[0]), state.heading[b])
    state = state.replace(target=state.target.at[b].set(new_t), heading=state.heading.at[b].set(face))

    sk = params.skills
    target, _ = skill_targets(state, params)
    region = sk.target_type == TARGET_REGION
    instant = ~region & (sk.projectile_speed <= 0)
    kind = jnp.where(region, PROJ_AREA, jnp.where(sk.target_type == TARGET_UNIT, PROJ_HOMING, PROJ_STRAIGHT))
    caster = jnp.broadcast_to(state.pos[:, None], (u_n, s_n, 2))
    tpos = state.pos[target]
    spawn_pos = jnp.where(region[..., None], caster + sk.area_offset[..., None] * (tpos - caster), caster)

    r = u_n * s_n
    req = (fired & ~instant).reshape(r)
    p = state.projectiles
    free = ~p.live
    req_rank = jnp.cumsum(req) - 1
    free_rank = jnp.cumsum(free) - 1
    assign = req[:, None] & free[None] & (req_rank[:, None] == free_rank[None])  # [R, M]
    got = jnp.any(assign, axis=0)
    af = assign.astype(jnp.float32)

    def put(old, new):
        new = new.reshape((r,) + new.shape[2:])
        val = jnp.einsum("rm,r...->m...", af, new.astype(jnp.float32)).astype(old.dtype)
        return jnp.where(got.reshape(got.shape + (1,) * (old.ndim - 1)), val, old)

    owner = jnp.broadcast_to(jnp.arange(u_n)[:, None], (u_n, s_n))
    slot = jnp.broadcast_to(jnp.arange(s_n)[None], (u_n, s_n))
    life = jnp.where(region, AREA_LIFETIME, MISSILE_LIFETIME)
    proj = Projectiles(
        live=p.live | got,
        kind=put(p.kind, kind),
        pos=put(p.pos, spawn_pos),
        direction=put(p.direction, direction),
        owner=put(p.owner, owner),
        slot=put(p.slot, slot),
        target=put(p.target, target),
        life=put(p.life, life),
        hit_mask=p.hit_mask & ~got[:, None],
    )
    dropped = jnp.sum(req) - jnp.sum(got)
    inst = (fired & instant).reshape(r)
    instant_hits = inst[:, None] & jax.nn.one_hot(target.reshape(r), u_n, dtype=bool)
    instant_hits = instant_hits & state.alive[None]
    return state.replace(projectiles=proj, dropped=state.dropped + dropped), instant_hits, caster.reshape(r, 2)


def affected(params: Params, owner: jnp.ndarray, slot: jnp.ndarray) -> jnp.ndarray:
    """``bool[E, U]``: which units an effect of ``(owner, slot)`` (``int32[E]`` each) can touch."""
    sk = params.skills
    same = params.team[owner][:, None] == params.team[None]
    return ((sk.affect_enemy[owner, slot] > 0)[:, None] & ~same) | ((sk.affect_ally[owner, slot] > 0)[:, None] & same)


def move_projectiles(state: State, params: Params, dt: float):
    """Advance the pool one sub-step with swept collision.

    Returns ``(state, hits: bool[M, U], from_pos: float32[M, 2])`` where ``from_pos`` is the
    projectile's position before the move (the direction a hit comes from).
    """
    p = state.projectiles
    sk, st = params.skills, params.stats
    speed = sk.projectile_speed[p.owner, p.slot]
    prad = sk.projectile_radius[p.owner, p.slot]
    step = speed * dt
    touch = affected(params, p.owner, p.slot) & state.alive[None]  # [M, U]
    reach = prad[:, None] + params.config.hurtbox_scale * st.radius[None]  # [M, U]
    rel = state.pos[None] - p.pos[:, None]  # [M, U, 2]
    dist = jnp.linalg.norm(rel, axis=-1)

    # Homing: straight at the target's current position; hits only its target.
    tdist = jnp.take_along_axis(dist, p.target[:, None], axis=1)[:, 0]
    treach = jnp.take_along_axis(reach, p.target[:, None], axis=1)[:, 0]
    t_alive = state.alive[p.target]
    homing = p.live & (p.kind == PROJ_HOMING)
    hit_h = homing & t_alive & (tdist - step <= treach)
    tdir = (state.pos[p.target] - p.pos) / jnp.maximum(tdist, EPS)[:, None]
    pos_h = p.pos + tdir * jnp.minimum(step, tdist)[:, None]
    hits_h = hit_h[:, None] & jax.nn.one_hot(p.target, dist.shape[1], dtype=bool)

    # Straight: first touched unit along the segment; walls destroy it.
    proj_along = jnp.einsum("mud,md->mu", rel, p.direction)
    c = dist**2 - reach**2
    disc = proj_along**2 - c
    t_in = proj_along - jnp.sqrt(jnp.maximum(disc, 0.0))
    t_in = jnp.where(c <= 0, 0.0, t_in)
    cross = touch & (disc >= 0) & (t_in >= 0) & (t_in <= step[:, None])
    straight = p.live & (p.kind == PROJ_STRAIGHT)
    first = jnp.argmin(jnp.where(cross, t_in, jnp.inf), axis=1)
    hit_s = straight & jnp.any(cross, axis=1)
    hits_s = hit_s[:, None] & jax.nn.one_hot(first, dist.shape[1], dtype=bool)
    pos_s = p.pos + p.direction * step[:, None]
    out = jnp.any(jnp.abs(pos_s) > HALF_ARENA, axis=-1)

    # Area: every touchable unit inside, nearest first, at most hit_count units in all.
    area = p.live & (p.kind == PROJ_AREA)
    inside = area[:, None] & touch & (dist <= reach) & ~p.hit_mask
    closer = (dist[:, None, :] < dist[:, :, None]) | (
        (dist[:, None, :] == dist[:, :, None]) & (jnp.arange(dist.shape[1])[None, None] < jnp.arange(dist.shape[1])[None, :, None])
    )
    rank = jnp.sum(closer & inside[:, None, :], axis=-1)
    left = sk.hit_count[p.owner, p.slot] - jnp.sum(p.hit_mask, axis=1)
    hits_a = inside & (rank < left[:, None])

    hits = hits_h | hits_s | hits_a
    pos = jnp.where(homing[:, None], pos_h, jnp.where(straight[:, None], pos_s, p.pos))
    life = p.life - dt
    gone = (homing & (hit_h | ~t_alive)) | (straight & (hit_s | out)) | (life <= EPS)
    new = p.replace(live=p.live & ~gone, pos=pos, life=life, hit_mask=p.hit_mask | hits_a)
    return state.replace(projectiles=new), hits, p.pos


def resolve_hits(key, state: State, params: Params, hits, owner, slot, basic, from_pos):
    """Apply damage and heals of ``E`` hit events to the units.

    Args:
        key: PRNG key for crits, dodges and parries.
        hits: ``bool[E, U]`` event e touches unit u. ``owner``, ``slot``: ``int32[E]``.
        basic: ``bool[E]`` the event is a basic attack (coefficient 1, attack power).
        from_pos: ``float32[E, 2]`` where the hit comes from (back-attack test).

    Returns:
        ``(state, dealt: float32[U], dealt_to_boss: float32[U], back: int32[U])`` by owner.
    """
    sk, st = params.skills, params.stats
    e_n, u_n = hits.shape
    coef = jnp.where(basic, 1.0, sk.coefficient[owner, slot])
    attack = basic | (sk.hit_type[owner, slot] == HIT_ATTACK)
    str_scale = 1.0 + (st.strength - NEUTRAL_PRIMARY) / 100.0
    int_scale = 1.0 + (st.intelligence - NEUTRAL_PRIMARY) / 100.0
    power = jnp.where(attack, st.attack_power[owner], st.spell_power[owner])
    scale = jnp.where(attack, str_scale[owner], int_scale[owner])
    base = jnp.floor(coef * power + 1e-3) * scale  # SPEC §6: int(coefficient x power)

    u = jax.random.uniform(key, (3, e_n, u_n))
    crit = u[0] < st.critical[owner][:, None] / 100.0
    rel = from_pos[:, None] - state.pos[None]  # [E, U, 2]
    rel = rel / jnp.maximum(jnp.linalg.norm(rel, axis=-1, keepdims=True), EPS)
    rear = -heading_vec(state.heading)[None]
    back = jnp.sum(rel * rear, axis=-1) >= BACK_ATTACK_COS
    back_mult = (st.back_attack_multiplier * (1.0 + st.mastery / 100.0))[owner][:, None]
    evasion = st.evasion[None] + 0.5 * (st.agility[None] - NEUTRAL_PRIMARY) - 0.5 * (st.agility[owner][:, None] - NEUTRAL_PRIMARY)
    dodge = u[1] * 100.0 < evasion
    parry = u[2] * 100.0 < st.parry[None]
    mult = (
        jnp.where(crit, st.crit_multiplier[owner][:, None], 1.0)
        * jnp.where(back, back_mult, 1.0)
        * (1.0 + st.versatility[owner][:, None] / 100.0)
        * (1.0 - st.armor[None] / 200.0)
        * (1.0 - st.versatility[None] / 200.0)
        * jnp.where(parry, PARRY_FACTOR, 1.0)
    )
    enemy = params.team[owner][:, None] != params.team[None]
    harm = hits & enemy & ~dodge
    damage = jnp.where(harm, jnp.floor(base[:, None] * mult + 1e-3), 0.0)  # [E, U]
    heal_amt = jnp.floor(coef * st.spell_power[owner] * int_scale[owner] + 1e-3)
    heal = jnp.where(hits & ~enemy, heal_amt[:, None], 0.0)

    hp = state.hp - jnp.sum(damage, axis=0)
    alive = state.alive & (hp > 0)
    hp = jnp.where(alive, jnp.minimum(hp + jnp.sum(heal, axis=0), st.max_hp), jnp.minimum(hp, 0.0))
    by_owner = jax.nn.one_hot(owner, u_n, dtype=jnp.float32)  # [E, U]
    dealt = by_owner.T @ jnp.sum(damage, axis=1)
    dealt_to_boss = by_owner.T @ damage[:, -1]
    back_landed = harm & back & (params.team[owner] == 0)[:, None]
    back_count = (by_owner.T @ jnp.sum(back_landed, axis=1).astype(jnp.float32)).astype(jnp.int32)
    died = state.alive & ~alive
    state = state.replace(
        hp=hp, alive=alive,
        casting=state.casting & alive[:, None],
        vel=jnp.where(died[:, None], 0.0, state.vel),
        damage_dealt=state.damage_dealt + dealt,
        back_attacks=state.back_attacks + back_count,
    )
    return state, dealt, dealt_to_boss, back_count


def basic_attacks(state: State, params: Params, dt: float):
    """Automatic melee hits on the enemy target within ``attack_range`` every ``1/attack_speed`` s.

    Off when ``attack_power = 0`` (the reference setting). Returns ``(state, hits: bool[U, U])``.
    """
    st = params.stats
    t = state.target
    d = jnp.linalg.norm(state.pos[t] - state.pos, axis=-1) - st.radius - st.radius[t]
    ready = state.basic_cooldown <= EPS
    go = state.alive & state.alive[t] & (st.attack_power > 0) & (d <= st.attack_range) & ready
    cooldown = jnp.where(go, 1.0 / st.attack_speed, jnp.maximum(state.basic_cooldown - dt, 0.0))
    hits = go[:, None] & jax.nn.one_hot(t, t.shape[0], dtype=bool)
    return state.replace(basic_cooldown=cooldown), hits


def regenerate(state: State, params: Params, dt: float) -> State:
    """HP and mana regeneration of alive units, capped at their maxima."""
    st = params.stats
    hp = jnp.where(state.alive, jnp.minimum(state.hp + st.hp_regen * dt, st.max_hp), state.hp)
    mana = jnp.where(state.alive, jnp.minimum(state.mana + st.mana_regen * dt, st.max_mana), state.mana)
    return state.replace(hp=hp, mana=mana)
