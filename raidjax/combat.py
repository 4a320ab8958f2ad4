"""Casting, cooldowns/charges/mana and firing: the casts that complete become instant hits or
requests for pool slots, which they take and are written into (GAME.md §5). The pool's flight and
collision are ``raidjax.projectiles``'; what hits do, ``raidjax.damage``'.

Lane functions (``raidjax.lanes``): shapes are one arena's, followed by any number of lane (batch)
axes. ``U`` units (boss last), ``S`` skill slots, ``M`` projectile slots, ``E = M + U*S + U`` hit
events per sub-step (projectiles, instant skills, basic attacks).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from raidjax.hits import Hits
from raidjax.lanes import any_, argmin, cumsum, first_true, lane_function, pick, total
from raidjax.movement import nearest_alive_player, norm, set_boss
from raidjax.types import (
    PROJ_AREA,
    PROJ_HOMING,
    PROJ_STRAIGHT,
    TARGET_REGION,
    TARGET_UNIT,
    TICK,
    TRIGGER_PASSIVE,
    Params,
    Projectiles,
    Spawns,
    State,
)

AREA_LIFETIME = 5 * TICK  # an area lingers 5 ticks
MISSILE_LIFETIME = 10.0  # safety net: missiles expire after 10 s
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
def slot_ready(state: State, params: Params, valid: jnp.ndarray) -> jnp.ndarray:
    """``bool[U, S, ...]``: could each slot start a cast now, casts in progress aside (``free_slot``
    applies those): a live caster, a slot in use and charged, the mana, a valid target, and standing
    still for a channel (a cast with ``cast_on_moving = 0``)."""
    sk = params.skills
    return (
        state.alive[:, None]
        & (sk.in_use > 0)
        & (state.charges > 0)
        & (state.mana[:, None] >= sk.cost)
        & valid
        & ((sk.cast_on_moving > 0) | ~state.moving[:, None])
    )


@lane_function
def free_slot(casting: jnp.ndarray, params: Params, s: int) -> jnp.ndarray:
    """``bool[U, ...]``: do the casts in progress (``casting: bool[U, S, ...]``) let slot ``s`` start one:
    the slot is not casting, and a cast (a channel) in progress allows it (``cast_on_casting``,
    ``cast_on_channeling``)."""
    sk = params.skills
    on_moving = sk.cast_on_moving > 0
    busy_cast = any_(casting & on_moving, axis=1)
    busy_channel = any_(casting & ~on_moving, axis=1)
    return (~casting[:, s] & (~busy_cast | (sk.cast_on_casting[:, s] > 0))
            & (~busy_channel | (sk.cast_on_channeling[:, s] > 0)))


@lane_function
def usable_slots(state: State, params: Params, valid: jnp.ndarray) -> jnp.ndarray:
    """``bool[U, S, ...]``: can each slot start a cast now (GAME.md §5, with the casting/channeling
    rules)? ``valid``: ``bool[U, S, ...]`` from ``skill_targets``.

    A cast of a skill with ``cast_on_moving = 0`` is a *channel*; other casts are plain casts.
    """
    free = jnp.stack([free_slot(state.casting, params, s) for s in range(state.casting.shape[1])], axis=1)
    return slot_ready(state, params, valid) & free


@lane_function
def cast_ready(state: State, params: Params, requested: jnp.ndarray) -> jnp.ndarray:
    """``bool[U, S, ...]``: the requested casts (and every passive slot) that ``slot_ready`` allows;
    ``start_casts`` takes them. What a cast in progress changes is left to ``start_casts``, so this
    reads every slot's parameters once (the caller may put it into memory)."""
    _, valid = skill_targets(state, params)
    requested = requested | (params.skills.trigger == TRIGGER_PASSIVE)
    return requested & slot_ready(state, params, valid)


@lane_function
def start_casts(state: State, params: Params, ready: jnp.ndarray) -> State:
    """Start the casts ``ready`` (``bool[U, S, ...]``, ``cast_ready``) that the casts in progress allow,
    slot by slot in order.

    Slot order makes "try attack 1, then attack 2" (the boss) and "cast every usable skill"
    (PT-HR) respect the cast-on-casting rule. Moving casters cancel their channels first;
    ``cast_ready`` does not read the casts in progress, so it may run before.
    """
    channel = params.skills.cast_on_moving == 0
    state = state.replace(casting=state.casting & ~(channel & state.moving[:, None]))
    cast_time = params.skills.cast_time / haste_factor(params)
    # Columns, stacked where read: an in-place update per slot costs XLA:CPU a copy of the array.
    casting = [state.casting[:, s] for s in range(state.casting.shape[1])]
    left = [state.cast_left[:, s] for s in range(state.casting.shape[1])]
    for s in range(len(casting)):
        start = ready[:, s] & free_slot(jnp.stack(casting, axis=1), params, s)
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

    Returns ``(state, instant_hits, instant_from: float32[U*S, 2, ...], spawns)`` where ``instant_hits``
    is ``Hits(hit: bool[U*S, ...], unit: int32[U*S, ...])`` (an instant skill hits its target) and ``spawns``
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
    instant_hits = Hits(inst & pick(state.alive, inst_target), inst_target)
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
