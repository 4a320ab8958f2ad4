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

from raidjax import damage, lanes, movement, validate
from raidjax.observation import observe
from raidjax.phases import advance_lanes, substep  # noqa: F401 (substep: public, raidjax.env.substep)
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
    validate.one_arena("reset", params.team)
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


# Under vmap the sub-steps run on the lane layout: the arena axis last (raidjax.lanes).
advance = lanes.batched(advance_lanes, full=(1,))


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
    validate.one_arena("step", params.team)
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
    new, reward, done, info = _play(key, state, actions, params)
    with jax.named_scope("observation"):
        obs = observe(new, params)
    return obs, new, reward, done, info


def _play(key: jax.Array, state: State, actions: jax.Array, params: Params):
    """``step`` without the observation: ``(state, reward, done, info)`` as ``step`` returns them
    (``step_autoreset`` observes only the state it hands back)."""
    actions = check_actions(actions, params)
    n_players = actions.shape[0]
    n_sub = params.config.n_substeps
    was_done = state.result != RUNNING
    seeds = jax.vmap(dice_seeds)(jax.random.split(key, n_sub))
    new, to_boss, back = advance(seeds, state.replace(memory=None), actions, params)
    new = new.replace(memory=state.memory)
    decision = new.decision + 1
    result = jnp.where((new.result == RUNNING) & (decision >= params.config.max_decisions), DRAW, new.result)
    new = new.replace(decision=decision, result=jnp.int32(result))
    if params.config.observation == "reference":
        new = remember(new, params)
    new = lanes.select(was_done, state, new)
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
    return new, reward, done, info


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

    Args:
        key: PRNG key (split into ``step``'s and ``next_episode``'s).
        state: the arena's ``State``.
        actions: ``int32[P]`` one action per player, as in ``step``.
        params: the arena's ``Params``.

    Returns:
        ``(obs, state, reward: float32[P], done: bool[], info)`` as ``step``; when ``done``, ``obs`` and
        ``state`` are those of the new episode. ``info`` also carries ``final_observation`` (the
        ``Observation``, leading axis ``P``, the ended episode last saw; equals ``obs`` when not done)
        and ``final_result`` (``int32[]``, the step's ``result`` before any reset).
    """
    k_step, k_reset = jax.random.split(key)
    new, reward, done, info = _play(k_step, state, actions, params)
    with jax.named_scope("next_episode"):
        _, state_next = next_episode(k_reset, new, params)
    state = lanes.select(done, state_next, new)
    # One observation of the state handed back, not one per candidate: the episode's last one is
    # computed only where a caller reads info["final_observation"] (XLA drops it otherwise).
    table = damage.effect_table(params)
    with jax.named_scope("observation"):
        obs, final = observe(state, params, table), observe(new, params, table)
    info = {**info, "final_observation": final, "final_result": new.result}
    return obs, state, reward, done, info
