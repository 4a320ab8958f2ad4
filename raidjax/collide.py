"""Projectile–body geometry: every unit's body is a square that turns with its heading.

The reference build's colliders are boxes: a player's is 1 x 1 (``Prefabs/Agent/RaidPlayer.prefab``),
the dragon's 2.25 x 2.25 (``Prefabs/Agent/Enemy.prefab``), and both turn with the unit. A unit's
``radius`` stat is half its side. A projectile of radius ``r`` touches a body when its centre is
within ``r`` of the square: 0.7 from a player's centre in front, up to 0.91 towards a corner.

Shapes: ``M`` projectiles, ``U`` units; vectors are ``float32[..., 2]``.
"""

from __future__ import annotations

import jax.numpy as jnp

INF = jnp.inf


def to_body_frame(vec: jnp.ndarray, heading: jnp.ndarray) -> jnp.ndarray:
    """``vec[..., 2]`` (world axes) in the frames whose x axis is along ``heading[...]`` (broadcast
    against ``vec[..., 0]``; e.g. ``vec[M, U, 2]`` with every unit's ``heading[U]``)."""
    c, s = jnp.cos(heading), jnp.sin(heading)
    return jnp.stack([c * vec[..., 0] + s * vec[..., 1], -s * vec[..., 0] + c * vec[..., 1]], axis=-1)


def box_distance(q: jnp.ndarray, half: jnp.ndarray) -> jnp.ndarray:
    """Distance ``float32[...]`` from points ``q[..., 2]`` (body frame) to squares of half side ``half``
    (broadcast against ``q[..., 0]``; e.g. ``q[M, U, 2]`` and ``half[U]``)."""
    return jnp.linalg.norm(jnp.maximum(jnp.abs(q) - half[..., None], 0.0), axis=-1)


def _slab_axis(q, d, ext):
    """Entry and exit ``t`` of the ray ``q + t d`` through the slab ``|x| <= ext`` (one axis)."""
    still = jnp.abs(d) < 1e-9  # parallel to the slab: inside it forever, or never
    inv = 1.0 / jnp.where(still, 1e-9, d)
    t1, t2 = (-ext - q) * inv, (ext - q) * inv
    inside = jnp.abs(q) <= ext
    lo = jnp.where(still, jnp.where(inside, -INF, INF), jnp.minimum(t1, t2))
    hi = jnp.where(still, jnp.where(inside, INF, -INF), jnp.maximum(t1, t2))
    return lo, hi


def _circle(q, d, centre, r):
    """First ``t >= 0`` at which the ray ``q + t d`` (``|d| = 1``) is within ``r`` of ``centre``
    (``[..., 2]`` points and directions, ``r`` and the result ``[...]``)."""
    rel = centre - q
    along = rel[..., 0] * d[..., 0] + rel[..., 1] * d[..., 1]
    c = rel[..., 0] ** 2 + rel[..., 1] ** 2 - r**2
    disc = along**2 - c
    t = along - jnp.sqrt(jnp.maximum(disc, 0.0))
    return jnp.where(c <= 0, 0.0, jnp.where((disc >= 0) & (t >= 0), t, INF))


def ray_entry(q: jnp.ndarray, d: jnp.ndarray, half: jnp.ndarray, r: jnp.ndarray) -> jnp.ndarray:
    """First ``t >= 0`` at which a disc of radius ``r[M]`` moving from ``q`` along unit vector ``d``
    (``float32[M, U, 2]``, body frame) touches the square of half side ``half[U]``; ``inf`` if never.

    The touching region is the square grown by ``r`` (a rounded square). The ray first enters the
    square grown by ``r`` on both axes; an entry point beside a flat face is the answer, and one in
    a corner cell (both coordinates beyond ``half``) can only reach the rounded square through that
    corner's disc, so one slab test and one disc test replace two slabs and four discs.
    """
    a = half[None, :]  # [1, U]
    ext = a + r[:, None]  # [M, U]
    lo_x, hi_x = _slab_axis(q[..., 0], d[..., 0], ext)
    lo_y, hi_y = _slab_axis(q[..., 1], d[..., 1], ext)
    enter, leave = jnp.maximum(lo_x, lo_y), jnp.minimum(hi_x, hi_y)
    meets = (enter <= leave) & (leave >= 0)
    t_box = jnp.where(meets, jnp.maximum(enter, 0.0), 0.0)
    at = q + t_box[..., None] * d  # where the ray enters the grown square
    corner_cell = (jnp.abs(at[..., 0]) > a) & (jnp.abs(at[..., 1]) > a)
    centre = jnp.sign(at) * a[..., None]
    t_corner = _circle(q, d, centre, jnp.broadcast_to(r[:, None], ext.shape))
    return jnp.where(meets, jnp.where(corner_cell, t_corner, t_box), INF)
