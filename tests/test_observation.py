"""Observations (GAME.md §8): layout, normalisation, masks of dead entities, projectiles, action mask.

Layouts (see ``types.Observation``): self = pos(2) heading(2) vel(2) hp mana casting progress,
then per skill slot recharge/5, charges/charge, range/20, damage/100, cast time/5 (feature-major:
all slots of one feature, then the next feature). Boss = relative pos(2)/20, facing(2), HP
fraction, its two cool-downs/5, casting, cast progress, targets-me, distance/20.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import BOSS, make, scenario

import raidjax
from raidjax import observation
from raidjax.types import N_ACTIONS

OBSERVE = jax.jit(raidjax.observe)
H = 12.25


def setup_state():
    p = make()
    s = scenario(p, players=((2.0, -4.0), (0.0, -5.0), (-11.0, -11.0)), boss=(0.0, 0.0),
                 alive=(True, True, False), hp=(50.0, None, None, 800.0), mana=(80.0, None, None, None))
    s = s.replace(
        vel=s.vel.at[0].set(jnp.array([2.0, -4.0])),
        charges=s.charges.at[0, 0].set(0),
        recharge_left=s.recharge_left.at[0, 0].set(2.5).at[BOSS].set(jnp.array([0.5, 3.5, 0.0])),
        casting=s.casting.at[BOSS, 1].set(True),
        cast_left=s.cast_left.at[BOSS, 1].set(1.0),
    )
    pr = s.projectiles
    # One hostile straight missile (boss attack 1) at (2, -2) flying -y, one of player 0's own.
    pr = pr.replace(
        live=pr.live.at[0].set(True).at[1].set(True),
        kind=pr.kind.at[0].set(1).at[1].set(0),
        pos=pr.pos.at[0].set(jnp.array([2.0, -2.0])).at[1].set(jnp.array([1.0, -1.0])),
        direction=pr.direction.at[0].set(jnp.array([0.0, -1.0])),
        owner=pr.owner.at[0].set(BOSS).at[1].set(0),
        target=pr.target.at[1].set(BOSS),
        life=pr.life.at[0].set(5.0).at[1].set(5.0),
    )
    return p, s.replace(projectiles=pr)


def test_self_features_normalised():
    p, s = setup_state()
    o = OBSERVE(s, p)
    d = math.hypot(2, 4)
    want = [2 / 20, -4 / 20, -2 / d, 4 / d, 2 / 20, -4 / 20, 0.5, 0.8, 0.0, 0.0,
            2.5 / 5, 0, 0,  # recharge / 5
            0, 0, 0,  # charges / charge (slot 1 spent; unused slots 0)
            5 / 20, 0, 0,  # range / 20
            50 / 100, 0, 0,  # damage / 100
            0.5 / 5, 0, 0]  # cast time / 5
    np.testing.assert_allclose(np.asarray(o.self_features[0]), want, atol=1e-6)
    np.testing.assert_allclose(np.asarray(o.self_features[1, 13:16]), [1, 0, 0], atol=1e-6)


def test_boss_features():
    p, s = setup_state()
    o = OBSERVE(s, p)
    d = math.hypot(2, 4)
    want0 = [-2 / 20, 4 / 20, 2 / d, -4 / d, 0.8, 0.5 / 5, 3.5 / 5, 1.0, 1 - 1.0 / 4.0, 1.0, d / 20]
    np.testing.assert_allclose(np.asarray(o.boss[0]), want0, atol=1e-6)
    np.testing.assert_allclose(np.asarray(o.boss[1, :2]), [0, 5 / 20], atol=1e-6)
    assert float(o.boss[1, 9]) == 0.0  # the boss targets player 0, not player 1
    np.testing.assert_allclose(np.asarray(o.boss[1, 10]), 5 / 20, atol=1e-6)


def test_teammates_and_dead_entities_are_zero_and_masked():
    p, s = setup_state()
    o = OBSERVE(s, p)
    # Player 0's teammates: player 1, player 2 (dead).
    mate = [-2 / 20, -1 / 20, 0, 0, 1.0, 1.0, 5 / 20, 0, 0, 0.5, 0, 0, 0.1, 0, 0, 1.0]
    np.testing.assert_allclose(np.asarray(o.teammates[0, 0]), mate, atol=1e-6)
    np.testing.assert_array_equal(np.asarray(o.teammates[0, 1]), 0.0)
    assert o.teammate_mask[0].tolist() == [True, False]
    assert o.teammate_mask[1].tolist() == [True, False]
    # The dead player's own view: all zeros and masks off, only no-op allowed.
    assert not bool(o.alive[2]) and o.alive[:2].tolist() == [True, True]
    for field in (o.self_features, o.boss, o.teammates, o.projectiles, o.walls):
        np.testing.assert_array_equal(np.asarray(field[2]), 0.0)
    assert not o.teammate_mask[2].any() and not o.projectile_mask[2].any()
    assert o.action_mask[2].tolist() == [True] + [False] * (N_ACTIONS - 1)


def test_hostile_projectiles_only_with_mask():
    p, s = setup_state()
    o = OBSERVE(s, p)
    assert o.projectile_mask[0].tolist() == [True, False, False, False]  # own missile not listed
    np.testing.assert_allclose(np.asarray(o.projectiles[0, 0]), [0, 2 / 20, 0, -20 / 20, 1, 0], atol=1e-6)
    np.testing.assert_allclose(np.asarray(o.projectiles[1, 0, :2]), [2 / 20, 3 / 20], atol=1e-6)
    np.testing.assert_array_equal(np.asarray(o.projectiles[0, 1:]), 0.0)


def test_nearest_k_hostile_projectiles():
    p, s = setup_state()
    pr = s.projectiles
    # Six hostile missiles at distances 6, 1, 5, 2, 4, 3 straight above player 0.
    dists = [6.0, 1.0, 5.0, 2.0, 4.0, 3.0]
    idx = jnp.arange(2, 8)
    pr = pr.replace(
        live=pr.live.at[0].set(False).at[idx].set(True), kind=pr.kind.at[idx].set(1),
        owner=pr.owner.at[idx].set(BOSS),
        pos=pr.pos.at[idx].set(jnp.array([[2.0, -4.0 + dd] for dd in dists])))
    o = OBSERVE(s.replace(projectiles=pr), p)
    assert o.projectile_mask[0].all()
    got = sorted(np.round(np.asarray(o.projectiles[0, :, 1]) * 20, 4).tolist())
    assert got == [1.0, 2.0, 3.0, 4.0]


@pytest.mark.parametrize("m", [4, 7, 16])
def test_nearest_lists_the_k_smallest_first_with_ties_to_the_lower_index_as_top_k(m):
    rng = np.random.default_rng(m)
    score = rng.integers(0, 4, size=(50, m)).astype(np.float32)  # many ties
    score[rng.random((50, m)) < 0.4] = np.inf  # no hostile projectile there
    got = jax.jit(lambda x: observation.nearest(x, 4))(jnp.asarray(score))
    np.testing.assert_array_equal(np.asarray(got), np.asarray(jax.lax.top_k(-jnp.asarray(score), 4)[1]))
    assert observation.nearest(jnp.asarray([[3.0, 1.0, jnp.inf, 1.0, 0.5]]), 4).tolist() == [[4, 1, 3, 0]]


def test_walls_and_action_mask():
    p, s = setup_state()
    o = OBSERVE(s, p)
    np.testing.assert_allclose(np.asarray(o.walls[0]), np.array([H - 2, H + 4, H + 2, H - 4]) / 20, atol=1e-6)
    # Player 0: no charge left -> cannot cast; player 1 at distance 5 = range: can.
    assert o.action_mask[0].tolist() == [True] * 7 + [False] * 3
    assert o.action_mask[1].tolist() == [True] * 7 + [True, False, False]


def test_flat_view_concatenates_every_part():
    p, s = setup_state()
    o = OBSERVE(s, p)
    flat = np.asarray(o.flat())
    parts = [o.self_features, o.boss, o.teammates.reshape(3, -1), o.teammate_mask, o.projectiles.reshape(3, -1),
             o.projectile_mask, o.walls, o.action_mask]
    np.testing.assert_array_equal(flat, np.concatenate([np.asarray(x, np.float32) for x in parts], axis=-1))


@pytest.mark.parametrize("field, value, index, expected", [
    ("skill1.range", 13.0, 16, 13.0 / 20),
    ("skill1.cast_time", 1.5, 22, 1.5 / 5),
    ("skill1.coefficient", 1.0, 19, 1.0 * 100 / 100),  # damage = coefficient x spell power, / 100
    ("haste", 25.0, 22, 0.5 / 1.25 / 5),  # the cast time after haste: 0.5 s / (1 + 25 / 100)
])
def test_skill_features_follow_content(field, value, index, expected):
    p = make(**{field: value})
    o = OBSERVE(scenario(p), p)
    np.testing.assert_allclose(np.asarray(o.self_features[:, index]), expected, atol=1e-6)
