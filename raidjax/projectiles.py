"""The projectile pool in flight: swept collision, and the pool's hits resolved block by block.

Lane functions (``raidjax.lanes``): shapes are one arena's, followed by any number of lane (batch)
axes. ``U`` units (boss last), ``S`` skill slots, ``M`` pool slots.

The pool's per-slot work (writing the sub-step's new projectiles, their source features, the
flight and collision of ``move_projectiles``, the damage of their hits) runs in blocks of
``POOL_BLOCK`` slots. On XLA:CPU's lane program a block in which no arena of the batch has a live
or new projectile is skipped: slots fill lowest first, and the reference content keeps at most 8
projectiles alive (4 096 arenas x 600 decisions at ranges 9 / 13 / 17), so most of a 16-slot pool
is empty in every arena. An empty slot's state does not change in flight, so a skipped block
leaves the same state to the bit as a processed one.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from raidjax import collide
from raidjax.combat import EPS, HitSums, group_sums, pick_effects, spawn, touchable
from raidjax.lanes import any_, argmin, batch_level, computed, lane_function, materialize, on_cpu, one_hot, pick, total
from raidjax.types import HALF_ARENA, PROJ_AREA, PROJ_HOMING, PROJ_STRAIGHT, Effects, Params, Projectiles, Spawns, State

POOL_BLOCK = 4  # pool slots per block of work


def pool_blocks(m: int) -> int:
    """How many blocks the pool's ``m`` slots run in: ``m / POOL_BLOCK`` on the CPU backend when
    ``POOL_BLOCK`` divides ``m`` (elsewhere every block would run anyway: one block)."""
    if on_cpu() and m % POOL_BLOCK == 0 and m > POOL_BLOCK:
        return m // POOL_BLOCK
    return 1


@lane_function
def move_projectiles(state: State, params: Params, feats: Effects, flight: jnp.ndarray, unit_cols):
    """Advance the pool one sub-step with swept collision; slot m flies ``flight[m]`` seconds
    (``combat.spawn``'s ``flight``: 0 for a projectile spawned in the last tick, which neither moves nor
    hits before the next). ``feats``: the pool's sources' ``Effects`` (``n = M``);
    ``unit_cols``: ``combat.unit_columns(state, params)`` (its rear directions give the units'
    headings' cosines and sines, exactly).

    Returns ``(state, hits, from_pos: float32[M, 2, ...])`` where ``from_pos`` is the projectile's
    position before the move (the direction a hit comes from) and ``hits`` is ``bool[M, U, ...]``, or
    under ``one_step_area``, when no slot can hit two units, ``(hit: bool[M, ...], unit: int32[M, ...])``.
    """
    p = state.projectiles
    u_n = state.pos.shape[0]
    step = feats.speed * flight
    flying = p.live & (flight > 0)
    touch = computed(lambda: touchable(feats, params, state.alive))  # [M, U, ...]
    # Reference geometry (collide.py): bodies are squares of half side ``radius`` turning with
    # their heading; a projectile touches one within its own radius of the square.
    r_proj = feats.radius
    half = params.stats.radius
    px, py = p.pos[:, 0], p.pos[:, 1]
    ux, uy = state.pos[:, 0], state.pos[:, 1]
    t_oh = one_hot(p.target, u_n, axis=1)
    cos_h, sin_h = -unit_cols["back_x"], -unit_cols["back_y"]  # [U, ...]; negation is exact

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

    def geometry():  # [M, U, ...] each
        relx, rely = ux[None] - px[:, None], uy[None] - py[:, None]
        dist = jnp.sqrt(relx * relx + rely * rely)
        q0x, q0y = collide.to_body_frame(-relx, -rely, cos_h[None], sin_h[None])
        d0x, d0y = collide.to_body_frame(dx[:, None], dy[:, None], cos_h[None], sin_h[None])
        return collide.ray_entry(q0x, q0y, d0x, d0y, half[None], r_proj[:, None]), dist, q0x, q0y

    # Computed once into memory: XLA would otherwise recompute the geometry inside every consumer.
    t_in, dist, q0x, q0y = computed(geometry)
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
        unit = lambda: jnp.where(homing, p.target, jnp.where(straight, first, area_first))  # noqa: E731
        hits = computed(lambda: (hit_h | hit_s | hit_a, unit()))
    else:
        hits = computed(lambda: hits_h | hits_s | hits_a)
    new_x = jnp.where(homing, hx, jnp.where(straight, sx, px))
    new_y = jnp.where(homing, hy, jnp.where(straight, sy, py))
    life = jnp.where(p.live, p.life - flight, p.life)  # an empty slot's clock stands still
    gone = (homing & (hit_h | ~t_alive)) | (straight & (hit_s | out)) | (life <= EPS)
    new = p.replace(live=p.live & ~gone, pos=jnp.stack([new_x, new_y], axis=1), life=life,
                    hit_mask=p.hit_mask | hits_a)
    return state.replace(projectiles=new), hits, p.pos


@lane_function
def fly(seeds, state: State, params: Params, skills: Effects, spawns: Spawns, *, n_ticks: int, unit_cols,
        n_events: int, running=True):
    """Spawn this sub-step's projectiles, move the pool and resolve its hits, block by block (see
    the module docstring).

    Args:
        seeds: ``uint32[2, ...]`` the sub-step's dice seeds.
        state: the state after ``combat.fire``.
        skills: the skill slots' ``Effects`` (``n = U * S``, ``combat.effect_sources``).
        spawns: ``combat.fire``'s spawns (``combat.spawn`` writes them).
        n_ticks: ticks in the sub-step (static).
        unit_cols: ``combat.unit_columns(state, params)``.
        n_events: ``E``, the sub-step's hit events (the pool's are events ``0..M-1``).
        running: ``bool[...]``; where false nothing spawns and nothing flies: the pool comes out
            unchanged to the bit (an ended game's).

    Returns:
        ``(state, sums)``: the state with the pool moved, and what the pool's hits add up to
        (``combat.HitSums``).
    """
    p = state.projectiles
    u_n, s_n = state.casting.shape[:2]
    lanes = state.hp.shape[1:]
    m = p.live.shape[0]
    n_blocks = pool_blocks(m)
    size = m // n_blocks
    got, src = spawns.got & running, spawns.src

    def block(pb: Projectiles, got_b, src_b, start):
        pb, flight = spawn(pb, spawns.replace(got=got_b, src=src_b), n_ticks)
        flight = jnp.where(running, flight, 0.0)
        feats = computed(lambda: pick_effects(skills, pb.owner * s_n + pb.slot))
        moved, hits, from_pos = move_projectiles(state.replace(projectiles=pb), params, feats, flight, unit_cols)
        sums = group_sums(seeds, unit_cols, feats, pb.owner, hits, from_pos, n_events, start, u_n, lanes)
        return moved.projectiles, sums

    def one_block_only():
        return block(p, got, src, 0)

    if n_blocks == 1:
        new, sums = one_block_only()
        return state.replace(projectiles=new), sums
    zeros = HitSums(*(jnp.zeros(state.hp.shape) for _ in range(5)))

    def one_block(i, carry):
        start = i * size
        cut = lambda x: jax.lax.dynamic_slice_in_dim(x, start, size)  # noqa: E731

        def run(carry):
            pool, total_sums = carry
            # The block's slots into memory of their own: the pool's buffers are then written in
            # place with nothing left to read them, and need no copy.
            new, sums = block(materialize(jax.tree.map(cut, pool)), cut(got), cut(src), start)
            pool = jax.tree.map(lambda x, y: jax.lax.dynamic_update_slice_in_dim(x, y, start, 0), pool, new)
            # Whole points: the sums are exact in any order.
            return pool, total_sums.plus(sums)

        # A block where no arena of the batch has a live projectile or a new one is skipped.
        return jax.lax.cond(jnp.any(cut(carry[0].live) | cut(got)), run, lambda c: c, carry)

    def in_blocks():
        return jax.lax.fori_loop(0, n_blocks, one_block, (p, zeros))

    # Under an outer vmap the blocks' conditionals would run every block: one block there.
    new, sums = batch_level(in_blocks, one_block_only)
    return state.replace(projectiles=new), sums
