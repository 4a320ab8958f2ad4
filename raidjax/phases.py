"""One sub-step of the game, phase by phase in the order of GAME.md's per-tick pseudo-code (move,
cast, fire, fly and collide, resolve hits, regenerate), and how XLA:CPU runs those phases.

The game files (``movement``, ``combat``, ``projectiles``, ``heuristic``) hold the rules only. The
scheduling lives here, at the phases' boundaries, with ``raidjax.lanes``' three tools:

* ``lanes.materialize`` / ``lanes.computed``: a phase's result goes into memory once, before its
  consumers run (XLA:CPU would otherwise recompute an elementwise chain inside every consumer).
* ``lanes.if_any``: work that no arena of the batch needs is skipped (a group of hit events that
  nobody lands, the learners' movement in a batch of scripted players, and the reverse).
* the pool in blocks (``_fly_pool``): a block of pool slots that no arena of the batch uses is
  skipped; slots fill lowest first, and the reference content keeps at most 8 projectiles alive
  (4 096 arenas x 600 decisions at ranges 9 / 13 / 17), so most of a 16-slot pool is empty.

Each of them leaves the values the same to the bit, and does nothing in the plain schedule
(``lanes.PLAIN``: off the CPU backend, under derivatives) or where an outer ``vmap`` batches the lane
program (``lanes.batch_level``). The schedule comes in as an argument (``advance_lanes``' ``fast``,
decided by ``lanes.batched``). Lane functions: one arena's shapes, then any lane axes ``...``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from raidjax import combat, damage, heuristic, lanes, movement, projectiles
from raidjax.types import ACTION_HEURISTIC, LOSS, RUNNING, TICK, TICKS_PER_DECISION, WIN, Effects, Params, Spawns, State

POOL_BLOCK = 4  # pool slots per block of work


@lanes.lane_function
def _boss_still_ticks(state: State, params: Params, n_ticks: int) -> jnp.ndarray:
    """``int32[...]``: ticks of this sub-step at whose start the boss is still casting a cast in progress."""
    b = state.pos.shape[0] - 1
    fire_tick = combat.ticks_until_expired(state.cast_left[b], params, n_ticks)
    return lanes.fold(jnp.maximum, jnp.where(state.casting[b], jnp.minimum(fire_tick, n_ticks), 0))


@lanes.lane_function
def _pause_boss_for_new_cast(state: State, before: State, start_pos, params: Params, n_ticks: int) -> State:
    """Cut the boss's chase in a sub-step where it started a cast to the ticks it was not casting.

    The reference boss chases, then tries its skills, every 0.02 s tick, and stands still from
    the tick after a cast starts until it fires. With one tick per sub-step that is the order
    of ``substep``; with several, the boss moved for the whole sub-step before the cast
    started, so its displacement is scaled to the start tick plus the ticks after the cast fired.
    """
    if n_ticks == 1:
        return state
    b = state.pos.shape[0] - 1
    new = state.casting[b] & ~before.casting[b]
    fire_tick = lanes.fold(jnp.minimum, jnp.where(new, combat.ticks_until_expired(state.cast_left[b], params, n_ticks),
                                                  n_ticks + 1))
    moved = jnp.minimum(1 + jnp.maximum(n_ticks - fire_tick, 0), n_ticks)
    started = lanes.any_(new) & ~lanes.any_(before.casting[b])
    frac = jnp.where(started, moved / n_ticks, 1.0)
    pos_b = start_pos[b] + frac * (state.pos[b] - start_pos[b])
    return state.replace(pos=movement.set_boss(state.pos, pos_b))


@lanes.lane_function
def substep(seeds, state: State, actions, params: Params, sources, n_ticks: int, running=True,
            schedule: lanes.Schedule = lanes.PLAIN):
    """Advance by ``n_ticks`` 0.02 s ticks; a lane function (``raidjax.lanes``: one arena's shapes, then
    any lane axes ``...``).

    Args:
        seeds: ``uint32[2, ...]`` dice seeds of this sub-step (``utils.dice_seeds``).
        state: ``State`` lane arrays; actions: ``int32[P, ...]`` (checked); params: ``Params`` lane arrays.
        sources: ``damage.effect_sources``' ``(skills, basic)`` ``Effects``.
        n_ticks: ticks in the sub-step (static).
        running: ``bool[...]``; where false the projectile pool comes out unchanged to the bit (nothing
            spawns, nothing flies), so the caller freezes an ended game's other fields only.
        schedule: ``lanes.Schedule``, how XLA:CPU runs the work (the same values either way).

    Returns:
        ``(state, to_boss: float32[U, ...], back: int32[U, ...])``: damage each unit dealt to the boss
        and back attacks it landed in the sub-step.
    """
    dt = n_ticks * TICK
    start, old_pos = state, state.pos
    # Named scopes label each phase's operations in compiled programs and profiles
    # (benchmarks/step_profile.py); they change nothing else.
    # Each phase's new state is materialised (``lanes.materialize``; the leaves it did not change
    # are already in memory) so that XLA:CPU does not recompute a phase inside every consumer.
    with jax.named_scope("movement"):
        # A batch that no learner (or no PT-HR script) moves in skips the other's work: its values
        # are then never selected, so the state is the same to the bit.
        scripted = actions == ACTION_HEURISTIC
        learner = lanes.if_any(schedule, ~scripted, lambda s, a, p: _learner_moves(s, a, p, dt, schedule),
                               state, actions, params)
        script = lanes.if_any(schedule, scripted, lambda s, p: heuristic.scripted_moves(s, p, actions.shape[0], dt),
                              state, params)
        state = movement.place_players(state, actions, learner, script)
        still = _boss_still_ticks(state, params, n_ticks)
        state = movement.move_boss(state, params, dt, (n_ticks - still) * TICK)
        state = movement.clamp_to_walls(state, params)
        state = lanes.materialize(schedule, movement.update_moving(state, old_pos, dt), since=start)
    with jax.named_scope("casting"):
        before = state
        # What every slot's parameters allow, read once into memory; the slots then start in order.
        ready = lanes.computed(schedule, combat.cast_ready, state, params,
                               heuristic.cast_requests(actions, state.casting.shape[1]))
        state = combat.start_casts(state, params, ready)
        state = _pause_boss_for_new_cast(state, before, old_pos, params, n_ticks)
        state, fired_tick = lanes.materialize(schedule, combat.advance_casts(state, params, n_ticks), since=before)
    with jax.named_scope("fire"):
        state, inst_hits, inst_from, spawns = lanes.computed(
            schedule, lambda s: combat.fire(s, params, fired_tick, n_ticks), state)
        # Spawn: the requests take the pool's free slots.
        match = lanes.computed(schedule, combat.slot_match, spawns.requested, state.projectiles.live)
        state, spawns = combat.take_slots(state, spawns, match)
    skills, basic = damage.event_sources(sources, state.hp.ndim - 1)
    # The pool moves nobody: the units' columns serve every hit of the sub-step.
    unit_cols = lanes.computed(schedule, damage.unit_columns, state, params)
    m = state.projectiles.live.shape[0]
    n_events = m + skills[0].base.shape[0] + basic[0].base.shape[0]
    with jax.named_scope("projectiles"):
        pool, sums = _fly_pool(seeds, state, params, sources[0], spawns, n_ticks, unit_cols, n_events, running,
                               schedule)
        state = state.replace(projectiles=pool)
    with jax.named_scope("hits"):
        state, basic_hits = damage.basic_attacks(state, params, dt)
        first = m
        for group in ((*skills, inst_hits, inst_from), (*basic, basic_hits, state.pos)):
            sums = sums.plus(_group_sums(seeds, unit_cols, group, n_events, first, schedule))
            first += group[0].base.shape[0]
        state, to_boss, back = lanes.materialize(schedule, damage.apply_hits(state, params, sums), since=state)
    state = damage.regenerate(state, params, dt)
    state = state.replace(clock=state.clock + dt)
    players_dead = ~lanes.any_(state.alive[:-1])
    # The reference checks the players before the boss: a tick that kills both is a loss.
    boss_dead_result = jnp.where(players_dead & params.config.ties_are_losses, LOSS, WIN)
    result = jnp.where(~state.alive[-1], boss_dead_result, jnp.where(players_dead, LOSS, RUNNING))
    return state.replace(result=result.astype(jnp.int32)), to_boss, back


@lanes.lane_function
def advance_lanes(seeds, state: State, actions, params: Params, fast: bool = False):
    """Play the decision's sub-steps (one per row of ``seeds: uint32[n_sub, 2, ...]``) on lane arrays;
    a finished arena stays as it ended. ``fast``: schedule the work for XLA:CPU (``lanes.Schedule``;
    the same values). Returns ``(state, to_boss: float32[U, ...], back: int32[U, ...])``."""
    n_ticks = TICKS_PER_DECISION // seeds.shape[0]
    sources = damage.effect_sources(params)  # once per decision, not per sub-step

    def one_substep(carry, xs):
        sub_seeds, i = xs
        cur, to_boss, back = carry
        # The gate is always true but must be a value XLA cannot fold (lanes.Schedule): the loop
        # counter, or, with one sub-step (its loop unrolled, the counter a constant), the counter behind
        # an optimisation barrier (the barrier on five sub-steps' counter cost them ~4 %).
        running = cur.result == RUNNING
        schedule = lanes.PLAIN
        if fast:
            schedule = lanes.Schedule(i >= 0 if seeds.shape[0] > 1 else jax.lax.optimization_barrier(i) >= 0)
        nxt, tb, bk = substep(sub_seeds, cur, actions, params, sources, n_ticks, running, schedule)
        # The pool of an ended game stands still in the sub-step already: freezing the rest is enough.
        frozen = lanes.select(running, nxt.replace(projectiles=None), cur.replace(projectiles=None))
        return (frozen.replace(projectiles=nxt.projectiles), to_boss + jnp.where(running, tb, 0.0),
                back + jnp.where(running, bk, 0)), None

    zeros = (jnp.zeros_like(state.hp), jnp.zeros_like(state.hp, jnp.int32))  # shaped (and varying) as hp
    # A scan compiles the sub-step once, whatever n_substeps is.
    (new, to_boss, back), _ = jax.lax.scan(one_substep, (state, *zeros), (seeds, jnp.arange(seeds.shape[0])))
    return new, to_boss, back


def _learner_moves(state: State, actions, params: Params, dt: float, schedule: lanes.Schedule):
    """``movement.learner_moves`` with the turned headings' unit vectors computed once into memory
    (``lanes.computed``): both the position and the velocity read them."""
    heading = movement.turned(state, actions, dt)
    fwd = lanes.computed(schedule, movement.heading_vec, heading)
    return (*movement.learner_moves(state, actions, params, dt, fwd), heading)


def pool_blocks(m: int, schedule: lanes.Schedule) -> int:
    """How many blocks the pool's ``m`` slots run in: ``m / POOL_BLOCK`` in XLA:CPU's schedule when
    ``POOL_BLOCK`` divides ``m`` (in the plain one every block would run anyway: one block)."""
    if schedule.fast and m % POOL_BLOCK == 0 and m > POOL_BLOCK:
        return m // POOL_BLOCK
    return 1


def _group_sums(seeds, unit_cols, group, n_events: int, first, schedule: lanes.Schedule) -> damage.HitSums:
    """``damage.group_sums`` of one group ``(effects, owner, hits, from_pos)`` starting at event
    ``first``; zeros without the work where no arena of the batch lands one of its events (the
    reference content has no instant skills and no basic attacks). Every sum is of whole points,
    so adding zeros or the group's sums of no hits gives the same bits."""
    f, owner, hits, from_pos = group
    u_n, lane_shape = unit_cols.x.shape[0], unit_cols.x.shape[1:]

    def sums(seeds, unit_cols, f, owner, hits, from_pos):
        # The dice and modifiers once into memory: every sum reads them. ``first`` is a static
        # ``int`` or the pool's block counter, which no outer vmap batches.
        outcomes = lanes.computed(schedule, lambda: damage.hit_outcomes(seeds, unit_cols, f, hits, from_pos, n_events,
                                                                        first, u_n, lane_shape))
        return damage.group_sums(outcomes, f, owner, hits, u_n)

    return lanes.if_any(schedule, hits.hit, sums, seeds, unit_cols, f, owner, hits, from_pos)


def _fly_pool(seeds, state: State, params: Params, skills: Effects, spawns: Spawns, n_ticks: int, unit_cols,
              n_events: int, running, schedule: lanes.Schedule):
    """The pool's sub-step (spawn the new projectiles, their sources' ``Effects``, ``contacts``,
    ``move_projectiles``) and the sums of its hits (events ``0..M-1``), in ``pool_blocks`` blocks; a
    block in which no arena of the batch has a live or a new projectile is skipped (an empty slot's
    state does not change in flight, so the state is the same to the bit).
    Returns ``(pool, damage.HitSums)``."""
    p = state.projectiles
    m = p.live.shape[0]
    s_n = state.casting.shape[1]
    n_blocks = pool_blocks(m, schedule)
    size = m // n_blocks
    got = spawns.got & running

    def block(ctx, pb, got_b, src_b, start):
        # Spawn: the block's slots take their requests; then the slots' sources, where each slot
        # stands against each unit (collide), and the flight with its hits.
        seeds, state, params, skills, spawns, unit_cols, running = ctx
        requests = spawns.replace(got=got_b, src=src_b)
        def spawned(pb):  # with each slot's source entry, which every field of the sources' picks reads
            pb, flight = combat.spawn(pb, requests, n_ticks)
            return pb, flight, pb.owner * s_n + pb.slot

        pb, flight, source = lanes.computed(schedule, spawned, pb)
        flight = jnp.where(running, flight, 0.0)
        feats = lanes.computed(schedule, lambda: damage.pick_effects(skills, source))
        at = state.replace(projectiles=pb)
        touch = lanes.computed(schedule, damage.touchable, feats, params, state.alive)
        near = lanes.computed(schedule, projectiles.contacts, at, params, feats, unit_cols)
        moved, hits, from_pos = projectiles.move_projectiles(at, params, feats, flight, unit_cols, touch, near)
        sums = _group_sums(seeds, unit_cols, (feats, pb.owner, hits, from_pos), n_events, start, schedule)
        return moved.projectiles, sums

    def whole_pool(ctx, got):
        return block(ctx, ctx[1].projectiles, got, ctx[4].src, 0)

    def in_blocks(ctx, got):
        def one_block(i, carry):
            start = i * size
            cut = lambda x: jax.lax.dynamic_slice_in_dim(x, start, size)  # noqa: E731

            def run(carry):
                pool, total_sums = carry
                # The block's slots go into memory of their own as operands of spawn's conditional
                # (lanes.computed in ``block``): the pool's buffers are then written in place with
                # nothing left to read them (a lanes.materialize of the cut would only copy it again).
                new, sums = block(ctx, jax.tree.map(cut, pool), cut(got), cut(ctx[4].src), start)
                pool = jax.tree.map(lambda x, y: jax.lax.dynamic_update_slice_in_dim(x, y, start, 0), pool, new)
                return pool, total_sums.plus(sums)  # whole points: exact in any order

            return jax.lax.cond(jnp.any(cut(carry[0].live) | cut(got)), run, lambda c: c, carry)

        zeros = damage.HitSums(*(jnp.zeros(ctx[1].hp.shape) for _ in range(5)))
        return jax.lax.fori_loop(0, n_blocks, one_block, (ctx[1].projectiles, zeros))

    ctx = (seeds, state, params, skills, spawns, unit_cols, running)
    if n_blocks == 1:
        return whole_pool(ctx, got)
    # Under an outer vmap the blocks' conditionals would run every block: one block there.
    return lanes.batch_level(schedule, in_blocks, whole_pool, ctx, got)
