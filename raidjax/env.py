"""The public functional API of one arena: ``reset``, ``step`` and ``step_autoreset``.

Every function is pure and works under ``jax.jit``, ``jax.vmap`` (over keys, states and
params) and ``lax.scan``. ``step`` never resets: once an episode is done, further steps
leave the state unchanged and pay nothing, so a fixed-length scan plays each episode once.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from raidjax import combat, movement
from raidjax.observation import observe
from raidjax.types import (
    ACTION_HEURISTIC,
    CAST_1,
    DRAW,
    LOSS,
    RUNNING,
    WIN,
    Observation,
    Params,
    Projectiles,
    State,
)

PLAYER_SPAWN_Y, PLAYER_SPACING = -10.0, 3.0
BOSS_SPAWN = (0.0, 8.0)
DAMAGE_REWARD = 0.01
WIN_REWARD = 1.0


def reset(key: jax.Array, params: Params) -> tuple[Observation, State]:
    """Start an episode.

    Args:
        key: PRNG key (draws PT-HR's per-episode circling directions).
        params: ``Params`` of one arena (``U`` units).

    Returns:
        ``(obs, state)``: ``Observation`` with player axis ``P = U - 1`` and the initial ``State``.
    """
    st, sk = params.stats, params.skills
    u_n, s_n = sk.in_use.shape
    n_players = u_n - 1
    m = params.config.max_projectiles
    k_sign, k_clock = jax.random.split(key)
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
        recharge_left=jnp.zeros((u_n, s_n)),
        basic_cooldown=jnp.zeros(u_n),
        target=jnp.full(u_n, n_players, jnp.int32),
        orbit_sign=jnp.where(jax.random.bernoulli(k_sign, 0.5, (u_n,)), 1.0, -1.0),
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
    return observe(state, params), state


def _cast_requests(actions: jnp.ndarray, s_n: int) -> jnp.ndarray:
    """``bool[U, S]`` requested casts: a learner's cast action, PT-HR all slots, the boss all slots."""
    slot = jnp.arange(s_n)
    req = (actions[:, None] == CAST_1 + slot[None]) | (actions[:, None] == ACTION_HEURISTIC)
    return jnp.concatenate([req, jnp.ones((1, s_n), bool)])


def _substep(key, state: State, actions, params: Params, table, dt: float):
    """Advance one arena by ``dt`` seconds. Returns ``(state, to_boss: f32[U], back: i32[U])``."""
    old_pos = state.pos
    state = movement.move_players(state, actions, params, dt)
    state = movement.move_boss(state, params, dt)
    state = movement.clamp_to_walls(state, params)
    state = movement.update_moving(state, old_pos, dt)
    state = combat.start_casts(state, params, _cast_requests(actions, state.casting.shape[1]))
    state, fired = combat.advance_casts(state, params, dt)
    state, inst_hits, inst_from = combat.fire(state, params, fired)
    proj = state.projectiles
    state, proj_hits, proj_from = combat.move_projectiles(state, params, table, dt)
    state, basic_hits = combat.basic_attacks(state, params, dt)
    u_n, s_n = fired.shape
    units = jnp.arange(u_n, dtype=jnp.int32)
    source = jnp.concatenate([
        combat.source_index(proj.owner, proj.slot, s_n),
        combat.source_index(jnp.repeat(units, s_n), jnp.tile(jnp.arange(s_n, dtype=jnp.int32), u_n), s_n),
        combat.source_index(units, jnp.full(u_n, s_n, jnp.int32), s_n),
    ])
    hits = jnp.concatenate([proj_hits, inst_hits, basic_hits])
    from_pos = jnp.concatenate([proj_from, inst_from, state.pos])
    state, to_boss, back = combat.resolve_hits(key, state, params, table, hits, source, from_pos)
    state = combat.regenerate(state, params, dt)
    state = state.replace(clock=state.clock + dt)
    result = jnp.where(~state.alive[-1], WIN, jnp.where(~jnp.any(state.alive[:-1]), LOSS, RUNNING))
    return state.replace(result=jnp.int32(result)), to_boss, back


def _select(pred, a, b):
    return jax.tree.map(lambda x, y: jnp.where(pred, x, y), a, b)


def step(key: jax.Array, state: State, actions: jax.Array, params: Params):
    """Play one decision (0.1 s) of one arena; no reset.

    Args:
        key: PRNG key (crits, dodges, parries).
        state: the arena's ``State``.
        actions: ``int32[P]`` one action per player (``types`` action ids; ``ACTION_HEURISTIC``
            hands the player to the built-in PT-HR script). Dead players' actions are ignored.
        params: the arena's ``Params``.

    Returns:
        ``(obs, state, reward: float32[P], done: bool[], info)`` where ``info`` holds
        ``terminated``, ``truncated`` (bool[]), ``result`` (int32[]: 0 running, 1 win, 2 loss,
        3 draw), and per player ``alive`` (bool[P]), ``damage_dealt`` (float32[P], to the boss
        this step, all multipliers applied) and ``back_attack`` (int32[P]).
    """
    n_players = actions.shape[0]
    n_sub = params.config.n_substeps
    dt = movement.DECISION / n_sub
    was_done = state.result != RUNNING
    new = state
    to_boss = jnp.zeros(n_players + 1)
    back = jnp.zeros(n_players + 1, jnp.int32)
    table = combat.effect_table(params)
    for i, k in enumerate(jax.random.split(key, n_sub)):
        nxt, tb, bk = _substep(k, new, actions.astype(jnp.int32), params, table, dt)
        running = new.result == RUNNING
        new = _select(running, nxt, new) if i else nxt
        to_boss = to_boss + jnp.where(running, tb, 0.0)
        back = back + jnp.where(running, bk, 0)
    decision = new.decision + 1
    result = jnp.where((new.result == RUNNING) & (decision >= params.config.max_decisions), DRAW, new.result)
    new = new.replace(decision=decision, result=jnp.int32(result))
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
    return observe(new, params, table), new, reward, done, info


def step_autoreset(key: jax.Array, state: State, actions: jax.Array, params: Params):
    """``step``, then reset the arena if the episode ended (for training loops).

    Returns the same tuple as ``step``; when ``done``, ``obs`` and ``state`` are those of the
    new episode and ``info`` also carries ``final_observation`` (the ``Observation`` the
    episode ended on) and ``final_result``. ``info["final_observation"]`` equals ``obs`` when
    not done.
    """
    k_step, k_reset = jax.random.split(key)
    obs, new, reward, done, info = step(k_step, state, actions, params)
    obs_reset, state_reset = reset(k_reset, params)
    info = {**info, "final_observation": obs, "final_result": new.result}
    return _select(done, obs_reset, obs), _select(done, state_reset, new), reward, done, info
