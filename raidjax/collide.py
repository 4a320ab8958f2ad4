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


def _slab(q, d, ext):
    """Entry and exit ``t`` of the ray ``q + t d`` through the box ``|x| <= ext[..., 0], |y| <= ext[..., 1]``."""
    safe = jnp.where(jnp.abs(d) < 1e-9, 1e-9, d)
    t1, t2 = (-ext - q) / safe, (ext - q) / safe
    lo, hi = jnp.minimum(t1, t2), jnp.maximum(t1, t2)
    still = jnp.abs(d) < 1e-9  # parallel to that axis: inside the slab forever, or never
    inside = jnp.abs(q) <= ext
    lo = jnp.where(still, jnp.where(inside, -INF, INF), lo)
    hi = jnp.where(still, jnp.where(inside, INF, -INF), hi)
    enter, leave = jnp.max(lo, axis=-1), jnp.min(hi, axis=-1)
    return jnp.where((enter <= leave) & (leave >= 0), jnp.maximum(enter, 0.0), INF)


def _circle(q, d, centre, r):
    """First ``t >= 0`` at which the ray ``q + t d`` (``|d| = 1``) is within ``r`` of ``centre``."""
    rel = centre - q
    along = jnp.sum(rel * d, axis=-1)
    c = jnp.sum(rel * rel, axis=-1) - r**2
    disc = along**2 - c
    t = along - jnp.sqrt(jnp.maximum(disc, 0.0))
    return jnp.where(c <= 0, 0.0, jnp.where((disc >= 0) & (t >= 0), t, INF))


def ray_entry(q: jnp.ndarray, d: jnp.ndarray, half: jnp.ndarray, r: jnp.ndarray) -> jnp.ndarray:
    """First ``t >= 0`` at which a disc of radius ``r[M]`` moving from ``q`` along unit vector ``d``
    (``float32[M, U, 2]``, body frame) touches the square of half side ``half[U]``; ``inf`` if never.

    The touching region is the square grown by ``r``: two slabs and four corner discs.
    """
    a = jnp.broadcast_to(half[None, :], q.shape[:-1])[..., None]
    rr = jnp.broadcast_to(r[:, None], q.shape[:-1])
    t = jnp.minimum(_slab(q, d, jnp.concatenate([a + rr[..., None], a], -1)),
                    _slab(q, d, jnp.concatenate([a, a + rr[..., None]], -1)))
    for sx in (-1.0, 1.0):
        for sy in (-1.0, 1.0):
            corner = jnp.concatenate([sx * a, sy * a], -1)
            t = jnp.minimum(t, _circle(q, d, corner, rr))
    return t
