"""Projectile–body geometry: every unit's body is a square that turns with its heading.

The reference build's colliders are boxes: a player's is 1 x 1 (``Prefabs/Agent/RaidPlayer.prefab``),
the dragon's 2.25 x 2.25 (``Prefabs/Agent/Enemy.prefab``), and both turn with the unit. A unit's
``radius`` stat is half its side. A projectile of radius ``r`` touches a body when its centre is
within ``r`` of the square: 0.7 from a player's centre in front, up to 0.91 towards a corner.

Vectors are pairs of lane arrays ``(x, y)`` (``raidjax.lanes``): every function is elementwise, so
shapes are any that broadcast (e.g. ``[M, U, ...]`` projectile-unit pairs with ``half[U, ...]``).
"""

from __future__ import annotations

import jax.numpy as jnp

from raidjax.lanes import lane_function

INF = jnp.inf


@lane_function
def to_body_frame(x: jnp.ndarray, y: jnp.ndarray, c: jnp.ndarray, s: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """The world vector ``(x, y)`` in the frame whose x axis is along a heading of cosine ``c`` and
    sine ``s`` (all broadcast; the caller computes them once per unit)."""
    return c * x + s * y, -s * x + c * y


@lane_function
def box_distance(qx: jnp.ndarray, qy: jnp.ndarray, half: jnp.ndarray) -> jnp.ndarray:
    """Distance from the point ``(qx, qy)`` (body frame) to the square of half side ``half``."""
    ex, ey = jnp.maximum(jnp.abs(qx) - half, 0.0), jnp.maximum(jnp.abs(qy) - half, 0.0)
    return jnp.sqrt(ex * ex + ey * ey)


@lane_function
def _slab_axis(q, d, ext):
    """Entry and exit ``t`` of the line ``q + t d`` through the slab ``|x| <= ext`` (one axis)."""
    safe = jnp.where(jnp.abs(d) < 1e-9, 1e-9, d)
    # min / max of (-ext - q) / safe and (ext - q) / safe, picked by the sign of ``safe`` (division is
    # monotone, so the values are the same): each division then has one use, and XLA fuses the test.
    ahead = safe > 0
    lo, hi = (jnp.where(ahead, -ext, ext) - q) / safe, (jnp.where(ahead, ext, -ext) - q) / safe
    still = jnp.abs(d) < 1e-9  # parallel to that axis: inside the slab forever, or never
    inside = jnp.abs(q) <= ext
    return jnp.where(still, jnp.where(inside, -INF, INF), lo), jnp.where(still, jnp.where(inside, INF, -INF), hi)


@lane_function
def _slab(qx, qy, dx, dy, ex, ey):
    """Entry ``t >= 0`` of the ray ``q + t d`` into the box ``|x| <= ex, |y| <= ey``, ``inf`` if never."""
    lo_x, hi_x = _slab_axis(qx, dx, ex)
    lo_y, hi_y = _slab_axis(qy, dy, ey)
    enter, leave = jnp.maximum(lo_x, lo_y), jnp.minimum(hi_x, hi_y)
    return jnp.where((enter <= leave) & (leave >= 0), jnp.maximum(enter, 0.0), INF)


@lane_function
def _circle(qx, qy, dx, dy, cx, cy, r):
    """First ``t >= 0`` at which the ray ``q + t d`` (``|d| = 1``) is within ``r`` of ``(cx, cy)``."""
    rx, ry = cx - qx, cy - qy
    along = rx * dx + ry * dy
    c = (rx * rx + ry * ry) - r**2
    disc = along**2 - c
    t = along - jnp.sqrt(jnp.maximum(disc, 0.0))
    return jnp.where(c <= 0, 0.0, jnp.where((disc >= 0) & (t >= 0), t, INF))


@lane_function
def ray_entry(qx, qy, dx, dy, half, r) -> jnp.ndarray:
    """First ``t >= 0`` at which a disc of radius ``r`` moving from ``(qx, qy)`` along the unit vector
    ``(dx, dy)`` (body frame) touches the square of half side ``half``; ``inf`` if never.

    The touching region is the square grown by ``r``: two slabs and four corner discs.
    """
    t = jnp.minimum(_slab(qx, qy, dx, dy, half + r, half), _slab(qx, qy, dx, dy, half, half + r))
    for sx in (-1.0, 1.0):
        for sy in (-1.0, 1.0):
            t = jnp.minimum(t, _circle(qx, qy, dx, dy, sx * half, sy * half, r))
    return t
