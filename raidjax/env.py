"""The public functional API of one arena: ``reset``, ``next_episode``, ``step``, ``step_autoreset``.

Every function is pure and works under ``jax.jit``, ``jax.vmap`` (over keys, states and
params) and ``lax.scan``. ``step`` never resets: once an episode is done, further steps
leave the state unchanged and pay nothing, so a fixed-length scan plays each episode once.

``reset`` starts a fresh arena's first episode. ``next_episode`` starts the same arena's next
one: under the ``"reference"`` rules it carries what the reference build carries across its
resets (running cooldowns; the boss's place and the projectiles in flight after the 2023 reset
exception); under ``"clean"`` it equals ``reset``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from raidjax import combat, heuristic, lanes, movement, projectiles
from raidjax.observation import observe
from raidjax.reference_observation import remember, start_memory
from raidjax.types import (
    ACTION_HEURISTIC,
    DAMAGE_REWARD,
    DRAW,
    HALF_ARENA,
    LOSS,
    NOOP,
    REFERENCE_ACTIONS,
    RUNNING,
    TICK,
    TICKS_PER_DECISION,
    WIN,
    WIN_REWARD,
    Observation,
    Params,
    Projectiles,
    State,
)
from raidjax.utils import dice_seeds, traced_once

PLAYER_SPAWN_Y, PLAYER_SPACING = -10.0, 3.0
BOSS_SPAWN = (0.0, 8.0)


@traced_once
def reset(key: jax.Array, params: Params) -> tuple[Observation, State]:
    """Start an episode.

    Args:
        key: PRNG key (draws PT-HR's per-episode circling directions and, with
            ``EnvConfig.random_spawns``, the spawn positions and headings).
        params: ``Params`` of one arena (``U`` units).

    Returns:
        ``(obs, state)``: ``Observation`` with player axis ``P = U - 1`` and the initial ``State``.
    """
    st, sk = params.stats, params.skills
    u_n, s_n = sk.in_use.shape
    n_players = u_n - 1
    m = params.config.max_projectiles
    k_sign, k_clock = jax.random.split(key)
    if params.config.random_spawns:
        pos, heading = random_spawns(jax.random.fold_in(key, 1), params)  # fold_in: the other draws stay put
    else:
        xs = (jnp.arange(n_players) - (n_players - 1) / 2) * PLAYER_SPACING
        pos = jnp.concatenate([jnp.stack([xs, jnp.full(n_players, PLAYER_SPAWN_Y)], -1), jnp.array([BOSS_SPAWN])])
        heading = jnp.concatenate([jnp.full(n_players, jnp.pi / 2), jnp.array([-jnp.pi / 2])])
    alive = st.max_hp > 0
    state = State(
        pos=pos.astype(jnp.float32),
        heading=heading.astype(jnp.float32),
        vel=jnp.zeros((u_n, 2)),
        hp=st.max_hp,
        mana=st.max_mana,
        alive=alive,
        moving=jnp.zeros(u_n, bool),
        cast_left=jnp.zeros((u_n, s_n)),
        casting=jnp.zeros((u_n, s_n), bool),
        charges=sk.charge,
        recharging=jnp.zeros((u_n, s_n), bool),
        recharge_left=jnp.zeros((u_n, s_n)),
        basic_cooldown=jnp.zeros(u_n),
        target=jnp.full(u_n, n_players, jnp.int32),
        orbit_sign=jnp.where(jax.random.bernoulli(k_sign, 0.5, (u_n,)), jnp.float32(1.0), jnp.float32(-1.0)),
        clock=jax.random.uniform(k_clock, (), minval=0.0, maxval=2 * jnp.pi),
        projectiles=Projectiles(
            live=jnp.zeros(m, bool), kind=jnp.zeros(m, jnp.int32), pos=jnp.zeros((m, 2)),
            direction=jnp.zeros((m, 2)), owner=jnp.zeros(m, jnp.int32), slot=jnp.zeros(m, jnp.int32),
            target=jnp.zeros(m, jnp.int32), life=jnp.zeros(m), hit_mask=jnp.zeros((m, u_n), bool),
        ),
        decision=jnp.int32(0),
        result=jnp.int32(RUNNING),
        damage_dealt=jnp.zeros(u_n),
        back_attacks=jnp.zeros(u_n, jnp.int32),
        dropped=jnp.int32(0),
    )
    state = state.replace(target=state.target.at[n_players].set(movement.nearest_alive_player(state)))
    if params.config.observation == "reference":
        state = start_memory(state, params)
    return observe(state, params), state


def random_spawns(key: jax.Array, params: Params) -> tuple[jax.Array, jax.Array]:
    """Spawn positions ``float32[U, 2]`` and headings ``float32[U]`` drawn uniformly: players in the
    arena's lower half (y <= 0), the boss in its upper half (y >= 0), every disc inside the walls,
    headings in [-pi, pi). Used by ``reset`` when ``EnvConfig.random_spawns`` is on."""
    u_n = params.team.shape[-1]
    k_pos, k_heading = jax.random.split(key)
    lim = HALF_ARENA - params.stats.radius  # [U]
    unit = jax.random.uniform(k_pos, (u_n, 2))
    x = (2 * unit[:, 0] - 1) * lim
    is_boss = jnp.arange(u_n) == u_n - 1
    y = jnp.where(is_boss, unit[:, 1], -unit[:, 1]) * lim
    heading = jax.random.uniform(k_heading, (u_n,), minval=-jnp.pi, maxval=jnp.pi)
    return jnp.stack([x, y], -1), heading


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
def substep(seeds, state: State, actions, params: Params, sources, n_ticks: int, running=True):
    """Advance by ``n_ticks`` 0.02 s ticks; a lane function (``raidjax.lanes``: one arena's shapes, then
    any lane axes ``...``).

    Args:
        seeds: ``uint32[2, ...]`` dice seeds of this sub-step (``utils.dice_seeds``).
        state: ``State`` lane arrays; actions: ``int32[P, ...]`` (checked); params: ``Params`` lane arrays.
        sources: ``combat.effect_sources``' ``(skills, basic)`` ``Effects``.
        n_ticks: ticks in the sub-step (static).
        running: ``bool[...]``; where false the projectile pool comes out unchanged to the bit (nothing
            spawns, nothing flies), so the caller freezes an ended game's other fields only.

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
        learner = lanes.if_any(~scripted, lambda: _learner_moves(state, actions, params, dt))
        script = lanes.if_any(scripted, lambda: heuristic.scripted_moves(state, params, actions.shape[0], dt))
        state = movement.place_players(state, actions, learner, script)
        still = _boss_still_ticks(state, params, n_ticks)
        state = movement.move_boss(state, params, dt, (n_ticks - still) * TICK)
        state = movement.clamp_to_walls(state, params)
        state = lanes.materialize(movement.update_moving(state, old_pos, dt), since=start)
    with jax.named_scope("casting"):
        before = state
        state = combat.start_casts(state, params, heuristic.cast_requests(actions, state.casting.shape[1]))
        state = _pause_boss_for_new_cast(state, before, old_pos, params, n_ticks)
        state, fired_tick = lanes.materialize(combat.advance_casts(state, params, n_ticks), since=before)
    with jax.named_scope("fire"):
        state, inst_hits, inst_from, spawns = lanes.computed(
            lambda state=state: combat.fire(state, params, fired_tick, n_ticks))
    skills, basic = combat.event_sources(sources, state.hp.ndim - 1)
    unit_cols = combat.unit_columns(state, params, spawns.facing)  # the pool moves nobody: they serve every hit
    m = state.projectiles.live.shape[0]
    with jax.named_scope("projectiles"):
        state, pool_sums = projectiles.fly(seeds, state, params, sources[0], spawns, n_ticks=n_ticks,
                                           unit_cols=unit_cols, running=running,
                                           n_events=m + skills[0].base.shape[0] + basic[0].base.shape[0])
    with jax.named_scope("hits"):
        state, basic_hits = combat.basic_attacks(state, params, dt)
        groups = ((*skills, inst_hits, inst_from), (*basic, basic_hits, state.pos))
        state, to_boss, back = lanes.materialize(
            combat.resolve_hits(seeds, state, params, groups, unit_cols, resolved=(m, pool_sums)), since=state)
    state = combat.regenerate(state, params, dt)
    state = state.replace(clock=state.clock + dt)
    players_dead = ~lanes.any_(state.alive[:-1])
    # The reference checks the players before the boss: a tick that kills both is a loss.
    boss_dead_result = jnp.where(players_dead & params.config.ties_are_losses, LOSS, WIN)
    result = jnp.where(~state.alive[-1], boss_dead_result, jnp.where(players_dead, LOSS, RUNNING))
    return state.replace(result=result.astype(jnp.int32)), to_boss, back


@lanes.lane_function
def _advance(seeds, state: State, actions, params: Params):
    """Play the decision's sub-steps (one per row of ``seeds: uint32[n_sub, 2, ...]``) on lane arrays;
    a finished arena stays as it ended. Returns ``(state, to_boss: float32[U, ...], back: int32[U, ...])``."""
    n_ticks = TICKS_PER_DECISION // seeds.shape[0]
    sources = combat.effect_sources(params)  # once per decision, not per sub-step

    def one_substep(carry, xs):
        sub_seeds, i = xs
        cur, to_boss, back = carry
        # The gate is always true but must be a value XLA cannot fold (lanes.gate): the loop counter,
        # or, with one sub-step (its loop unrolled, the counter a constant), the counter behind an
        # optimisation barrier (the barrier on five sub-steps' counter cost them ~4 %).
        running = cur.result == RUNNING
        with lanes.gate(i >= 0 if seeds.shape[0] > 1 else jax.lax.optimization_barrier(i) >= 0):
            nxt, tb, bk = substep(sub_seeds, cur, actions, params, sources, n_ticks, running)
        # The pool of an ended game stands still in the sub-step already: freezing the rest is enough.
        frozen = _select(running, nxt.replace(projectiles=None), cur.replace(projectiles=None))
        return (frozen.replace(projectiles=nxt.projectiles), to_boss + jnp.where(running, tb, 0.0),
                back + jnp.where(running, bk, 0)), None

    zeros = (jnp.zeros_like(state.hp), jnp.zeros_like(state.hp, jnp.int32))  # shaped (and varying) as hp
    # A scan compiles the sub-step once, whatever n_substeps is.
    (new, to_boss, back), _ = jax.lax.scan(one_substep, (state, *zeros), (seeds, jnp.arange(seeds.shape[0])))
    return new, to_boss, back


def _learner_moves(state: State, actions, params: Params, dt: float):
    """``movement.learner_moves`` with the turned headings' unit vectors computed once into memory
    (``lanes.computed``): both the position and the velocity read them."""
    heading = movement.turned(state, actions, dt)
    fwd = lanes.computed(lambda: movement.heading_vec(heading))
    return (*movement.learner_moves(state, actions, params, dt, fwd), heading)


# Under vmap the sub-steps run on the lane layout: the arena axis last (raidjax.lanes).
advance = lanes.batched(_advance, full=(1,))


def _select(pred, a, b):
    return jax.tree.map(lambda x, y: jnp.where(pred, x, y), a, b)


def check_actions(actions, params: Params) -> jax.Array:
    """``actions`` as ``int32[P]``, checked when traced (shapes and dtypes are static).

    Ids outside ``[0, A)`` (``A = config.n_actions``) other than ``ACTION_HEURISTIC`` are no-ops
    (``NOOP``), as are actions the player cannot take now (a cast on cooldown, an empty slot, a
    dead player): values are data under ``jit`` and cannot raise. Under the reference action
    space, id k plays ``REFERENCE_ACTIONS[k]``.

    Raises:
        ValueError: ``actions`` not of shape ``[P]`` or not of an integer dtype (the message names
            the shape or dtype and what is allowed).
    """
    actions = jnp.asarray(actions)
    n_players = params.team.shape[-1] - 1
    if actions.shape != (n_players,):
        raise ValueError(f"actions: shape {list(actions.shape)}; allowed: [{n_players}], one action id per player "
                         "(vmap over arenas for a batch)")
    if not jnp.issubdtype(actions.dtype, jnp.integer):
        raise ValueError(f"actions: dtype {actions.dtype}; allowed: an integer dtype (action ids "
                         f"0..{params.config.n_actions - 1}, or ACTION_HEURISTIC = {ACTION_HEURISTIC})")
    actions = actions.astype(jnp.int32)
    if params.config.action_space == "reference":
        ours = jnp.asarray(REFERENCE_ACTIONS, jnp.int32)[jnp.clip(actions, 0, len(REFERENCE_ACTIONS) - 1)]
        known = (actions >= 0) & (actions < len(REFERENCE_ACTIONS))
        return jnp.where(known, ours, jnp.where(actions == ACTION_HEURISTIC, ACTION_HEURISTIC, NOOP))
    return jnp.where((actions < 0) | (actions > ACTION_HEURISTIC), NOOP, actions)


@traced_once
def step(key: jax.Array, state: State, actions: jax.Array, params: Params):
    """Play one decision (0.1 s) of one arena; no reset.

    Args:
        key: PRNG key (crits, dodges, parries).
        state: the arena's ``State``.
        actions: ``int32[P]`` one action per player (ids of ``config.action_space``; ``ACTION_HEURISTIC``
            hands the player to the built-in PT-HR script). Dead players' actions, masked actions
            and ids outside ``[0, ACTION_HEURISTIC]`` are no-ops (``check_actions``).
        params: the arena's ``Params``.

    Returns:
        ``(obs, state, reward: float32[P], done: bool[], info)`` where ``info`` holds
        ``terminated``, ``truncated`` (bool[]), ``result`` (int32[]: 0 running, 1 win, 2 loss,
        3 draw), and per player ``alive`` (bool[P]), ``damage_dealt`` (float32[P], to the boss
        this step, all multipliers applied) and ``back_attack`` (int32[P]).
    """
    actions = check_actions(actions, params)
    n_players = actions.shape[0]
    n_sub = params.config.n_substeps
    was_done = state.result != RUNNING
    table = combat.effect_table(params)
    seeds = jax.vmap(dice_seeds)(jax.random.split(key, n_sub))
    new, to_boss, back = advance(seeds, state.replace(memory=None), actions, params)
    new = new.replace(memory=state.memory)
    decision = new.decision + 1
    result = jnp.where((new.result == RUNNING) & (decision >= params.config.max_decisions), DRAW, new.result)
    new = new.replace(decision=decision, result=jnp.int32(result))
    if params.config.observation == "reference":
        new = remember(new, params)
    new = _select(was_done, state, new)
    won = (new.result == WIN) & ~was_done
    reward = DAMAGE_REWARD * to_boss[:n_players] + WIN_REWARD * won
    reward = jnp.where(was_done, 0.0, reward).astype(jnp.float32)
    done = new.result != RUNNING
    info = {
        "terminated": (new.result == WIN) | (new.result == LOSS),
        "truncated": new.result == DRAW,
        "result": new.result,
        "alive": new.alive[:n_players],
        "damage_dealt": jnp.where(was_done, 0.0, to_boss[:n_players]),
        "back_attack": jnp.where(was_done, 0, back[:n_players]),
    }
    with jax.named_scope("observation"):
        obs = observe(new, params, table)
    return obs, new, reward, done, info


def team_reward(info: dict, done: jax.Array) -> jax.Array:
    """The team's reward for one decision, from ``step``'s ``info``: 0.01 x the damage all players
    dealt to the boss + 1.0 when the episode ended (``done``) in a win. It equals the sum of the
    players' rewards minus ``(P - 1)`` x the win bonus (every player gets the bonus; the team once).

    Args:
        info: ``step``'s info (``damage_dealt: float32[..., P]``, ``result: int32[...]``).
        done: ``bool[...]``, the episode ended in this decision.

    Returns:
        ``float32[...]``.
    """
    won = done & (info["result"] == WIN)
    return DAMAGE_REWARD * jnp.sum(info["damage_dealt"], axis=-1) + WIN_REWARD * won


@traced_once
def next_episode(key: jax.Array, state: State, params: Params) -> tuple[Observation, State]:
    """Start the arena's next episode after ``state`` (normally an ended one).

    Equals ``reset(key, params)`` except for what the rules carry across the reference build's
    resets (docs/GAME.md, "Rule sets"):

    * ``carry_cooldowns``: every cooldown still running keeps its time left and adds a charge
      (no cap) when it ends; units that died lose theirs (the reference deactivates dead players,
      which stops their coroutines; the boss is never deactivated).
    * ``reset_exception``: if any projectile is in flight, the boss stays where it ended (facing
      the same way) and every live projectile but the one in the lowest pool slot keeps flying.

    Args:
        key: PRNG key (the new episode's draws, as in ``reset``).
        state: the arena's ``State`` at the end of its previous episode.
        params: the arena's ``Params``.

    Returns:
        ``(obs, state)`` of the new episode, shaped as ``reset``'s.
    """
    obs, fresh = reset(key, params)
    cfg = params.config
    if not cfg.chains_episodes:
        return obs, fresh
    b = state.pos.shape[0] - 1
    if cfg.carry_cooldowns:
        kept = (state.alive | (jnp.arange(b + 1) == b))[:, None] & state.recharging
        fresh = fresh.replace(recharging=kept, recharge_left=jnp.where(kept, state.recharge_left, fresh.recharge_left))
    if cfg.reset_exception:
        p = state.projectiles
        in_flight = jnp.any(p.live)
        first = jnp.argmax(p.live)
        live = p.live & (jnp.arange(p.live.shape[0]) != first)
        fresh = fresh.replace(
            projectiles=p.replace(live=live),
            pos=fresh.pos.at[b].set(jnp.where(in_flight, state.pos[b], fresh.pos[b])),
            heading=fresh.heading.at[b].set(jnp.where(in_flight, state.heading[b], fresh.heading[b])),
        )
        # The boss's OnEpisodeBegin picks its target from where it stands.
        fresh = fresh.replace(target=fresh.target.at[b].set(movement.nearest_alive_player(fresh)))
    if cfg.observation == "reference":  # the memory starts from the carried state
        fresh = start_memory(fresh, params)
    return observe(fresh, params), fresh


@traced_once
def step_autoreset(key: jax.Array, state: State, actions: jax.Array, params: Params):
    """``step``, then start the arena's next episode (``next_episode``) if this one ended.

    Returns the same tuple as ``step``; when ``done``, ``obs`` and ``state`` are those of the
    new episode and ``info`` also carries ``final_observation`` (the ``Observation`` the
    episode ended on) and ``final_result``. ``info["final_observation"]`` equals ``obs`` when
    not done.
    """
    k_step, k_reset = jax.random.split(key)
    obs, new, reward, done, info = step(k_step, state, actions, params)
    with jax.named_scope("next_episode"):
        obs_next, state_next = next_episode(k_reset, new, params)
    info = {**info, "final_observation": obs, "final_result": new.result}
    return _select(done, obs_next, obs), _select(done, state_next, new), reward, done, info
