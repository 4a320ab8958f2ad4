"""Movement of units within one sub-step: player actions (PT-HR's scripted moves come from
``raidjax.heuristic``), the boss's chase.

Lane functions (``raidjax.lanes``): shapes are one arena's, ``U`` units with the boss last, followed by
any number of lane (batch) axes; positions are ``float32[U, 2, ...]``.
"""

from __future__ import annotations

import math

import jax.numpy as jnp

from raidjax.lanes import any_, argmin, lane_function, pick
from raidjax.types import (
    ACTION_HEURISTIC,
    BACKWARD,
    FORWARD,
    HALF_ARENA,
    ROTATE_LEFT,
    ROTATE_RIGHT,
    STRAFE_LEFT,
    STRAFE_RIGHT,
    TICK,
    Params,
    State,
)

DRAG = 0.92  # velocity factor per tick
TURN_RATE = math.radians(200.0)  # rad/s (a Python float: importing raidjax must not start a JAX backend)
STRAFE_FACTOR = 0.75
BOSS_STOP_DISTANCE = 1.6  # the boss stops chasing this close to its target
MOVING_SPEED = 0.5  # a unit displaced faster than this (units/s) counts as moving


@lane_function
def heading_vec(angle: jnp.ndarray) -> jnp.ndarray:
    """Unit vectors ``float32[U, 2, ...]`` of heading angles ``float32[U, ...]`` (0 = +x, CCW)."""
    return jnp.stack([jnp.cos(angle), jnp.sin(angle)], axis=1)


@lane_function
def norm(v: jnp.ndarray, axis: int) -> jnp.ndarray:
    """Length of vectors ``v`` whose 2 components lie along ``axis`` (counted from the front)."""
    x, y = jnp.take(v, 0, axis), jnp.take(v, 1, axis)
    return jnp.sqrt(x * x + y * y)


def impulse_integrals(n_ticks: int) -> tuple[float, float, float]:
    """Closed-form drag integration over ``n_ticks`` ticks of ``v <- DRAG (v + a); p <- p + v dt``.

    Returns:
        ``(dn, s, c0, ca)`` such that ``v_n = dn v0 + s a`` and ``p_n = p0 + c0 v0 + ca a``.
    """
    d = DRAG
    s = d * (1 - d**n_ticks) / (1 - d)  # sum_{k=1..n} d^k
    c0 = TICK * s
    ca = TICK * d / (1 - d) * (n_ticks - s)
    return d**n_ticks, s, c0, ca


@lane_function
def turned(state: State, actions: jnp.ndarray, dt: float) -> jnp.ndarray:
    """The players' headings ``float32[P, ...]`` after ``actions: int32[P, ...]`` rotate them for
    ``dt`` seconds (a learner's decision rotates or translates, rotation first)."""
    turn = jnp.where(actions == ROTATE_LEFT, 1.0, jnp.where(actions == ROTATE_RIGHT, -1.0, 0.0))
    return state.heading[:actions.shape[0]] + turn * TURN_RATE * dt


@lane_function
def learner_moves(state: State, actions: jnp.ndarray, params: Params, dt: float, fwd: jnp.ndarray):
    """Where ``actions: int32[P, ...]`` move the players in ``dt`` seconds under the velocity-impulse
    model (GAME.md §4), given the unit vectors ``fwd: float32[P, 2, ...]`` of their turned headings
    (``heading_vec(turned(...))``).

    Returns:
        ``(pos float32[P, 2, ...], vel float32[P, 2, ...])`` of every player as if it were a learner
        (``place_players`` keeps what applies).
    """
    n_players = actions.shape[0]
    dn, s, c0, ca = impulse_integrals(round(dt / TICK))
    pos, vel = state.pos[:n_players], state.vel[:n_players]
    speed = params.stats.move_speed[:n_players]
    left = jnp.stack([-fwd[:, 1], fwd[:, 0]], axis=1)
    thrust = (
        (actions == FORWARD)[:, None] * fwd
        - (actions == BACKWARD)[:, None] * fwd
        + STRAFE_FACTOR * (actions == STRAFE_LEFT)[:, None] * left
        - STRAFE_FACTOR * (actions == STRAFE_RIGHT)[:, None] * left
    ) * speed[:, None]
    return pos + c0 * vel + ca * thrust, dn * vel + s * thrust


@lane_function
def place_players(state: State, actions: jnp.ndarray, learner, scripted) -> State:
    """The players after their moves: ``learner`` (``(pos, vel, heading)``: ``learner_moves`` and
    ``turned``) where ``actions:
    int32[P, ...]`` are learner actions, ``scripted`` (``heuristic.scripted_moves``' ``(pos, heading)``)
    where they are ``ACTION_HEURISTIC`` (which sets the position: no velocity); dead players stay
    where they are. The boss is untouched."""
    n_players = actions.shape[0]
    pos, heading = state.pos[:n_players], state.heading[:n_players]
    learner_pos, learner_vel, learner_heading = learner
    h_pos, h_heading = scripted
    is_scripted = actions == ACTION_HEURISTIC
    new_pos = jnp.where(is_scripted[:, None], h_pos, learner_pos)
    new_vel = jnp.where(is_scripted[:, None], 0.0, learner_vel)
    new_heading = jnp.where(is_scripted, h_heading, learner_heading)
    keep = ~state.alive[:n_players]
    new_pos = jnp.where(keep[:, None], pos, new_pos)
    new_vel = jnp.where(keep[:, None], 0.0, new_vel)
    new_heading = jnp.where(keep, heading, new_heading)
    return state.replace(
        pos=jnp.concatenate([new_pos, state.pos[n_players:]]),
        vel=jnp.concatenate([new_vel, state.vel[n_players:]]),
        heading=jnp.concatenate([new_heading, state.heading[n_players:]]),
    )


@lane_function
def nearest_alive_player(state: State) -> jnp.ndarray:
    """Index ``int32[...]`` of the alive player nearest the boss (0 if none is alive)."""
    d = norm(state.pos[:-1] - state.pos[-1], axis=1)
    return argmin(jnp.where(state.alive[:-1], d, jnp.inf))


@lane_function
def set_boss(x: jnp.ndarray, value: jnp.ndarray) -> jnp.ndarray:
    """``x[U, ...]`` with its last (the boss's) row replaced by ``value``."""
    return jnp.concatenate([x[:-1], value[None].astype(x.dtype)])


@lane_function
def move_boss(state: State, params: Params, dt: float, moving_time: jnp.ndarray | float | None = None) -> State:
    """Re-target, chase at ``move_speed`` for ``moving_time`` seconds (default ``dt``) unless casting
    or close, face the target.

    The boss re-picks its target (the nearest alive player) when it has none; under
    ``keep_dead_target`` a dead target still counts as one (the reference's ``Chase`` re-targets
    only on ``null``; dead players are deactivated, not destroyed). A cast in progress pauses
    the chase; ``env`` passes the part of the sub-step the boss spends not casting.
    """
    b = state.pos.shape[0] - 1
    target = state.target[b]
    keep = params.config.keep_dead_target
    target = jnp.where(pick(state.alive, target) | keep, target, nearest_alive_player(state))
    to_t = pick(state.pos, target[None]) - state.pos[b]
    dist = norm(to_t, axis=0)
    unit = to_t / jnp.maximum(dist, 1e-6)
    moving_time = dt if moving_time is None else moving_time
    may_move = (dist >= BOSS_STOP_DISTANCE) & state.alive[b] & any_(state.alive[:b])
    step = jnp.minimum(params.stats.move_speed[b] * moving_time, jnp.maximum(dist - BOSS_STOP_DISTANCE, 0.0))
    new_pos = state.pos[b] + jnp.where(may_move, step, 0.0) * unit
    facing = jnp.where(dist > 1e-6, jnp.arctan2(to_t[1], to_t[0]), state.heading[b])
    facing = jnp.where(state.alive[b], facing, state.heading[b])
    return state.replace(
        pos=set_boss(state.pos, new_pos),
        heading=set_boss(state.heading, facing),
        target=set_boss(state.target, target),
    )


@lane_function
def clamp_to_walls(state: State, params: Params) -> State:
    """Keep every unit's disc inside the arena; zero the velocity component into a wall."""
    lim = (HALF_ARENA - params.stats.radius)[:, None]
    clamped = jnp.clip(state.pos, -lim, lim)
    hit = clamped != state.pos
    return state.replace(pos=clamped, vel=jnp.where(hit, 0.0, state.vel))


@lane_function
def update_moving(state: State, old_pos: jnp.ndarray, dt: float) -> State:
    """Set ``moving[U, ...]``: displaced faster than ``MOVING_SPEED`` during the sub-step."""
    speed = norm(state.pos - old_pos, axis=1) / dt
    return state.replace(moving=speed > MOVING_SPEED)
