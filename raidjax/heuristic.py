"""PT-HR, the paper's scripted playtester, as the reference build runs it (GAME.md §9).

A player whose action is ``types.ACTION_HEURISTIC`` (what ``raidjax.policies.heuristic`` returns)
is driven by this script for that decision: it moves by setting its position, which no learner
action can express, and requests every skill slot each tick (casts start whenever a skill is
usable and the boss is within its range).
"""

from __future__ import annotations

import jax.numpy as jnp

from raidjax.lanes import any_, fold, lane_function
from raidjax.types import ACTION_HEURISTIC, CAST_1, TICK, Params, State

SPEED = 5.0  # PT-HR moves at 5 x move speed units/s
EASE_PER_TICK = 0.02  # PT-HR closes 2 % of the gap to its circling spot per tick
DEFAULT_DISTANCE = 10.0  # preferred distance when no skill is charged


@lane_function
def preferred_distance(state: State, params: Params) -> jnp.ndarray:
    """PT-HR's preferred distance ``float32[U, ...]``: the largest range of a charged skill in use (10 if none)."""
    ready = (params.skills.in_use > 0) & (state.charges > 0)
    best = fold(jnp.maximum, jnp.where(ready, params.skills.range, -1.0), axis=1)
    return jnp.where(best > 0, best, DEFAULT_DISTANCE)


@lane_function
def scripted_moves(state: State, params: Params, n_players: int, dt: float) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Where PT-HR puts each player after ``dt`` seconds: ``(pos float32[P, 2, ...], heading float32[P, ...])``.

    Approach at 5 x move speed to the preferred distance R; inside R, ease towards a point on the
    circle of radius R around the boss that turns at move-speed rad/s (one phase shared by the
    team, so players circling the same way clump, as in the reference), while retreating at 5 x
    move speed. Stand still while casting; always face the boss. (Lane function: ``raidjax.lanes``.)
    """
    pos = state.pos[:n_players]
    speed = params.stats.move_speed[:n_players]
    n_ticks = round(dt / TICK)
    boss = state.pos[-1]
    to_boss = boss - pos
    dist = jnp.sqrt(to_boss[:, 0] * to_boss[:, 0] + to_boss[:, 1] * to_boss[:, 1])
    unit = to_boss / jnp.maximum(dist, 1e-6)[:, None]
    preferred = preferred_distance(state, params)[:n_players]
    step = SPEED * speed * dt
    theta = speed * state.clock
    cw = jnp.stack([jnp.cos(theta), jnp.sin(theta)], axis=1)
    ccw = jnp.stack([jnp.sin(theta), jnp.cos(theta)], axis=1)
    spot = boss - preferred[:, None] * jnp.where(state.orbit_sign[:n_players, None] > 0, cw, ccw)
    ease = 1.0 - (1.0 - EASE_PER_TICK) ** n_ticks
    orbit_pos = pos + ease * (spot - pos) - step[:, None] * unit
    approach_pos = pos + unit * jnp.minimum(step, dist - preferred)[:, None]
    new_pos = jnp.where((dist > preferred)[:, None], approach_pos, orbit_pos)
    new_pos = jnp.where(any_(state.casting[:n_players], axis=1)[:, None], pos, new_pos)
    return new_pos, jnp.arctan2(boss[1] - new_pos[:, 1], boss[0] - new_pos[:, 0])


@lane_function
def cast_requests(actions: jnp.ndarray, s_n: int) -> jnp.ndarray:
    """``bool[U, S, ...]`` requested casts: a learner's cast action, every slot for a PT-HR player, and
    every slot for the boss (last row), from ``actions int32[P, ...]``."""
    slot = jnp.arange(s_n).reshape((1, s_n) + (1,) * (actions.ndim - 1))
    req = (actions[:, None] == CAST_1 + slot) | (actions[:, None] == ACTION_HEURISTIC)
    return jnp.concatenate([req, jnp.ones((1,) + req.shape[1:], bool)])
