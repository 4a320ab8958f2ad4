"""The reference geometry (``raidjax.collide``): bodies are squares turning with their heading, and a
projectile of radius r touches one within r of the square. Checked against closed forms and a
brute-force march along each ray, independent of the slab-and-corner-disc construction."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from raidjax import collide


def test_box_distance_front_and_corner_of_a_player_body():
    """A player's body is a 1 x 1 square (half side 0.5): a projectile of radius 0.2 touches it from
    0.7 in front of its centre and from 0.5 * sqrt(2) + 0.2 = 0.907 towards a corner."""
    q = jnp.array([[0.7, 0.0], [0.0, -0.7], [0.6413, 0.6413], [0.66, 0.66]])  # 4 points
    d = np.asarray(collide.box_distance(q[:, 0], q[:, 1], jnp.float32(0.5)))
    np.testing.assert_allclose(d[:2], 0.2, atol=1e-6)
    assert d[2] <= 0.2 < d[3]


def test_to_body_frame_turns_with_the_heading():
    """A point straight ahead of a unit facing +y lies on its body x axis; behind it, on -x."""
    heading = jnp.float32(jnp.pi / 2)
    x, y = collide.to_body_frame(jnp.array([0.0, 0.0]), jnp.array([2.0, -3.0]), jnp.cos(heading), jnp.sin(heading))
    np.testing.assert_allclose(np.stack([x, y], -1), [[2.0, 0.0], [-3.0, 0.0]], atol=1e-6)


def _marched_entry(q, d, half, r, t_max=12.0, n=24001):
    """First t on a grid of step t_max / (n - 1) at which the disc is within r of the square."""
    t = np.linspace(0.0, t_max, n)
    pts = q[..., None, :] + t[:, None] * d[..., None, :]  # [M, U, n, 2]
    gap = np.linalg.norm(np.maximum(np.abs(pts) - half[None, :, None, None], 0.0), axis=-1)
    inside = gap <= r[:, None, None]
    return np.where(inside.any(-1), t[np.argmax(inside, -1)], np.inf)


@pytest.mark.parametrize("seed", [0, 1])
def test_ray_entry_matches_a_brute_force_march(seed):
    """Random rays (a quarter of them along an axis, some starting inside a body) against squares of
    random half sides: the entry time equals the first marched contact within one grid step, and
    rays that never touch return inf."""
    rng = np.random.default_rng(seed)
    m, u = 64, 4
    q = rng.uniform(-4, 4, (m, u, 2)).astype(np.float32)
    ang = rng.uniform(-np.pi, np.pi, (m, u))
    ang[: m // 4] = rng.choice([0.0, np.pi / 2, np.pi, -np.pi / 2], (m // 4, u))
    d = np.stack([np.cos(ang), np.sin(ang)], -1).astype(np.float32)
    half = rng.uniform(0.3, 1.5, u).astype(np.float32)
    r = rng.uniform(0.05, 0.8, m).astype(np.float32)
    got = np.asarray(jax.jit(collide.ray_entry)(q[..., 0], q[..., 1], d[..., 0], d[..., 1], half[None], r[:, None]))
    want = _marched_entry(q.astype(np.float64), d.astype(np.float64), half, r)
    assert ((got == 0) & (want == 0)).sum() > 0 and np.isinf(want).sum() > 0 and np.isfinite(want).sum() > 50
    np.testing.assert_array_equal(np.isinf(got), np.isinf(want))
    hit = np.isfinite(want)
    np.testing.assert_allclose(got[hit], want[hit], atol=12.0 / 24000 + 1e-5)
