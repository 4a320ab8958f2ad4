"""The projectile pool in flight: new projectiles written into their slots, swept collision, and
the hit events the flight makes (GAME.md §5).

Lane functions (``raidjax.lanes``): shapes are one arena's, followed by any number of lane (batch)
axes. ``U`` units (boss last), ``S`` skill slots, ``M`` pool slots (or a block of them:
``raidjax.phases`` runs the pool in blocks on XLA:CPU).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from raidjax import collide
from raidjax.combat import EPS
from raidjax.hits import Hits, UnitColumns
from raidjax.lanes import any_, argmin, lane_function, one_hot, pick, total
from raidjax.types import HALF_ARENA, PROJ_AREA, PROJ_HOMING, PROJ_STRAIGHT, Effects, Params, State


class Contacts(NamedTuple):
    """Where the pool's ``M`` slots stand against the ``U`` units before they move, each
    ``float32[M, U, ...]``: ``t_in`` (how far along its direction a straight missile enters the
    unit's reach, ``inf`` if never), ``dist`` (centre distance), ``q0x``, ``q0y`` (the slot's
    position in the unit's body frame)."""

    t_in: jax.Array
    dist: jax.Array
    q0x: jax.Array
    q0y: jax.Array


@lane_function
def contacts(state: State, params: Params, feats: Effects, unit_cols: UnitColumns) -> Contacts:
    """The pool's (``state.projectiles``) ``Contacts`` with the units. ``feats``: the slots' sources'
    ``Effects`` (``n = M``); ``unit_cols``: ``damage.unit_columns(state, params)``.

    Reference geometry (collide.py): bodies are squares of half side ``radius`` turning with their
    heading; a projectile touches one within its own radius of the square."""
    p = state.projectiles
    half = params.stats.radius
    px, py = p.pos[:, 0], p.pos[:, 1]
    ux, uy = state.pos[:, 0], state.pos[:, 1]
    dx, dy = p.direction[:, 0], p.direction[:, 1]
    cos_h, sin_h = unit_cols.cos_h, unit_cols.sin_h  # [U, ...]
    relx, rely = ux[None] - px[:, None], uy[None] - py[:, None]
    dist = jnp.sqrt(relx * relx + rely * rely)
    q0x, q0y = collide.to_body_frame(-relx, -rely, cos_h[None], sin_h[None])
    d0x, d0y = collide.to_body_frame(dx[:, None], dy[:, None], cos_h[None], sin_h[None])
    t_in = collide.ray_entry(q0x, q0y, d0x, d0y, half[None], feats.radius[:, None])
    return Contacts(t_in, dist, q0x, q0y)


@lane_function
def move_projectiles(state: State, params: Params, feats: Effects, flight: jnp.ndarray, unit_cols: UnitColumns,
                     touch: jnp.ndarray, near: Contacts):
    """Advance the pool one sub-step with swept collision; slot m flies ``flight[m]`` seconds
    (``combat.spawn``'s ``flight``: 0 for a projectile spawned in the last tick, which neither moves nor
    hits before the next). ``feats``: the pool's sources' ``Effects`` (``n = M``);
    ``unit_cols``: ``damage.unit_columns(state, params)`` (the units' headings' cosines and sines);
    ``touch``: ``damage.touchable``'s ``bool[M, U, ...]`` for the
    slots' sources; ``near``: the pool's ``contacts`` before the move.

    Returns ``(state, hits, from_pos: float32[M, 2, ...])`` where ``from_pos`` is the projectile's
    position before the move (the direction a hit comes from) and ``hits`` the ``Hits`` of the pool's
    slots: every unit (``bool[M, U, ...]``), or under ``one_step_area``, when no slot can hit two
    units, one unit each (``unit: int32[M, ...]``).
    """
    p = state.projectiles
    u_n = state.pos.shape[0]
    step = feats.speed * flight
    flying = p.live & (flight > 0)
    t_in, dist, q0x, q0y = near
    r_proj = feats.radius
    half = params.stats.radius
    px, py = p.pos[:, 0], p.pos[:, 1]
    ux, uy = state.pos[:, 0], state.pos[:, 1]
    t_oh = one_hot(p.target, u_n, axis=1)
    cos_h, sin_h = unit_cols.cos_h, unit_cols.sin_h  # [U, ...]

    # Homing: straight at the target's current position; hits only its target, once within reach
    # at the end of its move (it flies at the body's centre, so it cannot pass through it).
    # Only the target matters, so this is [M] work, not [M, U].
    tx, ty = pick(ux, p.target), pick(uy, p.target)
    trelx, trely = tx - px, ty - py
    tdist = jnp.sqrt(trelx * trelx + trely * trely)
    t_alive = pick(state.alive, p.target)
    homing = flying & (p.kind == PROJ_HOMING)
    inv, reach = jnp.maximum(tdist, EPS), jnp.minimum(step, tdist)
    hx, hy = px + trelx / inv * reach, py + trely / inv * reach
    qx, qy = collide.to_body_frame(hx - tx, hy - ty, pick(cos_h, p.target), pick(sin_h, p.target))
    end_gap = collide.box_distance(qx, qy, pick(half, p.target))
    hit_h = homing & t_alive & (end_gap <= r_proj)
    hits_h = hit_h[:, None] & t_oh

    # Straight: first touched unit along the segment; walls destroy it.
    dx, dy = p.direction[:, 0], p.direction[:, 1]
    cross = touch & (t_in <= step[:, None])
    straight = flying & (p.kind == PROJ_STRAIGHT)
    first = argmin(jnp.where(cross, t_in, jnp.inf), axis=1)
    hit_s = straight & any_(cross, axis=1)
    hits_s = hit_s[:, None] & one_hot(first, u_n, axis=1)
    sx, sy = px + dx * step, py + dy * step
    out = (jnp.abs(sx) > HALF_ARENA) | (jnp.abs(sy) > HALF_ARENA)

    # Area: every touchable unit inside, nearest first, at most hit_count units in all.
    area = flying & (p.kind == PROJ_AREA)
    gap = collide.box_distance(q0x, q0y, half[None])
    inside = area[:, None] & touch & (gap <= r_proj[:, None]) & ~p.hit_mask
    rank = []
    for u in range(u_n):  # how many inside units are nearer than u (ties: the lower index first)
        nearer = [((dist[:, v] < dist[:, u]) | ((dist[:, v] == dist[:, u]) & (v < u))) & inside[:, v]
                  for v in range(u_n)]
        rank.append(sum(x.astype(jnp.int32) for x in nearer))
    rank = jnp.stack(rank, axis=1)
    # one_step_area: the reference's slash is switched off by its first hit.
    cap = 1.0 if params.config.one_step_area else feats.hits
    left = cap - total(p.hit_mask, axis=1)
    hits_a = inside & (rank < left[:, None])
    if params.config.one_step_area:
        # Every kind hits at most one unit (an area its nearest inside): one target per slot.
        area_first = argmin(jnp.where(inside, dist, jnp.inf), axis=1)
        hit_a = area & any_(inside, axis=1)
        hits_a = hit_a[:, None] & one_hot(area_first, u_n, axis=1)
        hits = Hits(hit_h | hit_s | hit_a, jnp.where(homing, p.target, jnp.where(straight, first, area_first)))
    else:
        hits = Hits(hits_h | hits_s | hits_a)
    new_x = jnp.where(homing, hx, jnp.where(straight, sx, px))
    new_y = jnp.where(homing, hy, jnp.where(straight, sy, py))
    life = jnp.where(p.live, p.life - flight, p.life)  # an empty slot's clock stands still
    gone = (homing & (hit_h | ~t_alive)) | (straight & (hit_s | out)) | (life <= EPS)
    new = p.replace(live=p.live & ~gone, pos=jnp.stack([new_x, new_y], axis=1), life=life,
                    hit_mask=p.hit_mask | hits_a)
    return state.replace(projectiles=new), hits, p.pos
