"""The reference players' observation and action space (GAME.md §8, ``EnvConfig(observation=
"reference", action_space="reference")``).

Expected values come from the sensor geometry by hand: a sphere of radius 0.5 cast along a ray
touches a wall at distance (gap to the wall - 0.5) and a projectile of radius r at (centre
distance - r - 0.5); ML-Agents orders the rays forward, 7 degrees right, 7 degrees left, ...
"""

from __future__ import annotations

import math

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import BOSS, CLEAN1, KEY, make, scenario

import raidjax
from raidjax import reference_observation as ro
from raidjax.types import CAST_1, ROTATE_LEFT, ROTATE_RIGHT

REF = CLEAN1.replace(observation="reference", action_space="reference")
OBSERVE = jax.jit(raidjax.observe)
STEP = jax.jit(raidjax.step)
UP = math.pi / 2


def ref_params(**kw):
    return make(config=REF, **kw)


def rays(flat_rays, player=0):
    return np.asarray(flat_rays[player]).reshape(ro.N_RAYS, 3)


def with_projectile(state, xy, radius_owner=BOSS):
    pr = state.projectiles
    pr = pr.replace(live=pr.live.at[0].set(True), kind=pr.kind.at[0].set(1), owner=pr.owner.at[0].set(radius_owner),
                    pos=pr.pos.at[0].set(jnp.asarray(xy, jnp.float32)), life=pr.life.at[0].set(5.0))
    return state.replace(projectiles=pr)


def test_shapes_flat_and_spaces():
    p = ref_params()
    obs, state = raidjax.reset(KEY, p)
    assert isinstance(obs, ro.ReferenceObservation)
    chex.assert_shape([obs.teammates, obs.teammate_mask, obs.projectile_rays, obs.wall_rays, obs.stack],
                      [(3, 2, 9), (3, 2), (3, 63), (3, 63), (3, 60)])
    assert obs.flat().shape == (3, 204)  # 18 + 63 + 63 + 60, the reference's total
    sp = raidjax.spaces(p)
    assert sp.n_actions == 8 and sp.flat_observation.shape == (3, 204)
    assert bool(obs.action_mask.all()) and obs.action_mask.shape == (3, 8)
    for name, box in sp.observation.items():
        assert bool(box.contains(getattr(obs, name))), name
    # The default observation keeps no memory in the state.
    assert raidjax.reset(KEY, make())[1].memory is None


def test_ray_order_follows_ml_agents():
    assert ro.RAY_ANGLES_DEG[:5] == (90.0, 83.0, 97.0, 76.0, 104.0)
    assert ro.RAY_ANGLES_DEG[-1] == 160.0 and len(ro.RAY_ANGLES_DEG) == 21


@pytest.mark.parametrize("gap", [3.0, 8.0, 15.0])
def test_wall_dead_ahead(gap):
    p = ref_params()
    s = scenario(p, players=((0.0, 12.25 - gap), (-5.0, -5.0), (5.0, -5.0)), boss=(0.0, -11.0), headings=(UP, UP, UP))
    r = rays(OBSERVE(s, p).wall_rays)
    np.testing.assert_allclose(r[0], [1.0, 0.0, (gap - 0.5) / 20], rtol=1e-5)


def test_wall_off_axis_ray():
    p = ref_params()
    gap = 3.0
    s = scenario(p, players=((0.0, 12.25 - gap), (-5.0, -5.0), (5.0, -5.0)), boss=(0.0, -11.0), headings=(UP, UP, UP))
    # Ray 1 is 7 degrees off the wall's normal: the sphere travels (gap - 0.5) / cos 7.
    expect = (gap - 0.5) / math.cos(math.radians(7.0)) / 20
    np.testing.assert_allclose(rays(OBSERVE(s, p).wall_rays)[1], [1.0, 0.0, expect], rtol=1e-5)


def test_wall_beyond_ray_length_is_a_miss():
    p = ref_params()
    s = scenario(p, players=((0.0, -10.0), (-5.0, -5.0), (5.0, -5.0)), boss=(0.0, 8.0), headings=(UP, UP, UP))
    # 22.25 to the far wall: the sphere would travel 21.75 > 20.
    np.testing.assert_allclose(rays(OBSERVE(s, p).wall_rays)[0], [0.0, 1.0, 1.0])


def test_projectile_seven_degrees_right_is_ray_1_only():
    p = ref_params()
    s = scenario(p, players=((0.0, -5.0), (-8.0, -8.0), (8.0, -8.0)), boss=(0.0, 8.0), headings=(UP, UP, UP))
    ang = UP - math.radians(7.0)  # 7 degrees clockwise of facing +y
    s = with_projectile(s, (10.0 * math.cos(ang), -5.0 + 10.0 * math.sin(ang)))
    r = rays(OBSERVE(s, p).projectile_rays)
    radius = float(p.skills.projectile_radius[BOSS, 0])
    np.testing.assert_allclose(r[1], [1.0, 0.0, (10.0 - radius - 0.5) / 20], rtol=1e-5)
    # Ray 0 passes 10 sin 7 = 1.22 from its centre and ray 2 10 sin 14 = 2.42: both beyond r + 0.5.
    np.testing.assert_allclose(r[0], [0.0, 1.0, 1.0])
    np.testing.assert_allclose(r[2], [0.0, 1.0, 1.0])


def test_a_live_teammate_row_is_its_position_velocity_hp_and_first_skill():
    # GAME.md §8, the reference observation: position (absolute) and velocity / 20, HP / 100, then
    # slot 1's cooldown left (before its first use the reference shows the whole cool time, 0.5 s),
    # range 5, coefficient 0.5 x spell power 100 and cast time 0.5, divided by 5, 20, 100 and 5.
    p = ref_params()
    s = scenario(p, players=((0.0, -5.0), (-8.0, -8.0), (8.0, -8.0)), boss=(0.0, 8.0), headings=(UP, UP, UP),
                 hp=(None, 40.0, None, None))
    s = s.replace(vel=s.vel.at[1].set(jnp.array([3.0, 4.0])))
    obs = OBSERVE(s, p)
    np.testing.assert_allclose(obs.teammates[0, 0], [-8 / 20, -8 / 20, 3 / 20, 4 / 20, 0.4, 0.5 / 5, 5 / 20, 0.5,
                                                     0.5 / 5], rtol=1e-6)
    np.testing.assert_allclose(obs.teammates[1, 0, :2], [0.0, -5 / 20])  # player 0, seen by player 1


@pytest.mark.parametrize("radius, seen", [(0.05, 0.2), (1.0, 1.0)])
def test_a_ray_meets_the_larger_of_the_skill_radius_and_the_prefab_sphere(radius, seen):
    # Every pooled projectile also carries the prefab's 0.2 trigger sphere (GAME.md §8): a ray meets
    # whichever of the two co-centred spheres is larger. A projectile 10 straight ahead on ray 0.
    p = ref_params(boss_overrides={"skill1.projectile_radius": radius})
    s = scenario(p, players=((0.0, -5.0), (-8.0, -8.0), (8.0, -8.0)), boss=(0.0, 8.0), headings=(UP, UP, UP))
    s = with_projectile(s, (0.0, 5.0))
    np.testing.assert_allclose(rays(OBSERVE(s, p).projectile_rays)[0], [1.0, 0.0, (10.0 - seen - 0.5) / 20],
                               rtol=1e-5)


def test_overlapping_projectile_is_not_reported():
    p = ref_params()
    s = scenario(p, players=((0.0, -5.0), (-8.0, -8.0), (8.0, -8.0)), boss=(0.0, 8.0), headings=(UP, UP, UP))
    s = with_projectile(s, (0.0, -4.6))  # 0.4 ahead: inside r + 0.5 where the cast starts
    assert not np.asarray(OBSERVE(s, p).projectile_rays[0]).reshape(21, 3)[:, 0].any()
    s = with_projectile(s, (0.0, -3.0))  # the same projectile 2 ahead is seen
    assert rays(OBSERVE(s, p).projectile_rays)[0, 0] == 1.0


def test_own_missiles_are_seen_too():
    p = ref_params()
    s = scenario(p, players=((0.0, -5.0), (-8.0, -8.0), (8.0, -8.0)), boss=(0.0, 8.0), headings=(UP, UP, UP))
    s = with_projectile(s, (0.0, 0.0), radius_owner=0)  # player 0's own missile, 5 ahead
    assert rays(OBSERVE(s, p).projectile_rays)[0, 0] == 1.0


def test_stack_shifts_once_per_decision_and_starts_zeroed():
    p = ref_params(passive_boss=False)
    obs, s = raidjax.reset(KEY, p)
    stack = np.asarray(obs.stack).reshape(3, 4, 15)
    assert not stack[:, :3].any()  # zeroed at the episode's start, then its first vector
    np.testing.assert_allclose(stack[:, 3], ro.vector(s, p), rtol=1e-6, atol=1e-9)
    for i in range(3):
        obs2, s2, *_ = STEP(jax.random.key(i), s, jnp.array([1, 5, 0]), p)
        new = np.asarray(obs2.stack).reshape(3, 4, 15)
        np.testing.assert_array_equal(new[:, :3], stack[:, 1:])
        np.testing.assert_allclose(new[:, 3], ro.vector(s2, p), rtol=1e-6, atol=1e-9)
        s, stack = s2, new


def test_next_episode_restarts_the_stack():
    p = ref_params(passive_boss=False)
    _, s = raidjax.reset(KEY, p)
    for i in range(5):
        _, s, *_ = STEP(jax.random.key(i), s, jnp.array([1, 5, 3]), p)
    assert np.asarray(s.memory.stack)[:, 0].any()  # full after 5 decisions
    _, fresh = raidjax.next_episode(jax.random.key(9), s, p)
    stack = np.asarray(fresh.memory.stack)
    assert not stack[:, :3].any()
    np.testing.assert_allclose(stack[:, 3], ro.vector(fresh, p), rtol=1e-6, atol=1e-9)


def test_vector_layout():
    p = ref_params()
    s = scenario(p, players=((2.0, -4.0), (-8.0, -8.0), (8.0, -8.0)), boss=(1.0, 3.0), headings=(0.0, UP, UP),
                 boss_heading=math.pi, hp=(40.0, None, None, None))
    s = s.replace(vel=s.vel.at[0].set(jnp.array([3.0, 4.0])))
    v = np.asarray(ro.vector(s, p)[0])
    sk = p.skills
    # Facing +x: forward speed is vx, rightward speed is -vy.
    expect = [2 / 20, -4 / 20, 3 / 20, -4 / 20, 1 / 20, 3 / 20, -1.0, 0.0,
              float(sk.cool_time[BOSS, 0]) / 5, float(sk.cool_time[BOSS, 1]) / 5, 40 / 100,
              float(sk.cool_time[0, 0]) / 5, float(sk.range[0, 0]) / 20,
              float(sk.coefficient[0, 0] * p.stats.spell_power[0]) / 100, float(sk.cast_time[0, 0]) / 5]
    np.testing.assert_allclose(v, expect, atol=1e-6)  # cooldowns unstarted: the full cool time (quirk)


def test_cooldown_shows_full_until_one_runs_then_zero():
    p = ref_params()
    s = scenario(p, players=((0.0, 4.0), (-8.0, -8.0), (8.0, -8.0)), boss=(0.0, 8.0))  # player 0 in range
    cool = float(p.skills.cool_time[0, 0])
    assert float(ro.shown_cooldowns(s, p)[0, 0]) == pytest.approx(cool)
    ran = ended = False
    for i in range(int(cool / 0.1) + 20):  # cast once, then wait the cooldown out
        _, s, *_ = STEP(jax.random.key(i), s, jnp.array([CAST_1 if i == 0 else 0, 0, 0]), p)
        running = bool(s.recharging[0, 0])
        if running:
            ran = True
            assert not bool(s.memory.cooldown_unstarted[0, 0])
            assert float(ro.shown_cooldowns(s, p)[0, 0]) == pytest.approx(float(s.recharge_left[0, 0]))
        ended = ended or (ran and not running)
    assert ran and ended
    assert float(ro.shown_cooldowns(s, p)[0, 0]) == 0.0  # the ended cooldown left 0
    assert float(ro.shown_cooldowns(s, p)[1, 0]) == pytest.approx(cool)  # player 1 never cast


def test_dead_teammate_row_is_zero_and_masked():
    p = ref_params()
    s = scenario(p, players=((0.0, -5.0), (-8.0, -8.0), (8.0, -8.0)), alive=(True, False, True))
    obs = OBSERVE(s, p)
    np.testing.assert_array_equal(obs.teammates[0, 0], np.zeros(9))
    assert obs.teammate_mask[0].tolist() == [False, True]
    assert not np.asarray(obs.flat()[1]).any()  # a dead player observes zeros


def test_reference_turns_are_mirrored():
    p = ref_params()
    s = scenario(p, players=((0.0, -5.0), (-8.0, -8.0), (8.0, -8.0)), headings=(UP, UP, UP))
    _, turned, *_ = STEP(KEY, s, jnp.array([3, 4, 9]), p)
    # Reference id 3 turns clockwise (ROTATE_RIGHT), 4 anticlockwise; 9 is not an action: a no-op.
    _, ours, *_ = STEP(KEY, s.replace(memory=None), jnp.array([ROTATE_RIGHT, ROTATE_LEFT, 0]), make(config=CLEAN1))
    np.testing.assert_array_equal(turned.heading, ours.heading)
    assert float(turned.heading[0]) < UP < float(turned.heading[1])


def test_jit_eager_vmap_agree():
    p = ref_params(passive_boss=False)
    keys = jax.random.split(KEY, 2)
    acts = jnp.array([[1, 7, 3], [6, 2, 7]])

    def play(key, a):
        obs, s = raidjax.reset(key, p)
        for i in range(3):
            obs, s, *_ = raidjax.step(jax.random.fold_in(key, i), s, a, p)
        return obs.flat()

    batched = jax.jit(jax.vmap(play))(keys, acts)
    for i in range(2):
        np.testing.assert_allclose(batched[i], play(keys[i], acts[i]), rtol=1e-5, atol=1e-6)
    assert np.isfinite(np.asarray(batched)).all()


def test_bad_choice_is_one_line():
    with pytest.raises(ValueError, match=r"^observation: .*'rays'.*allowed"):
        raidjax.EnvConfig(observation="rays")
    with pytest.raises(ValueError, match=r"^action_space: "):
        raidjax.make_params(action_space=8)
