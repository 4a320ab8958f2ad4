"""The boss (GAME.md §7), projectile deliveries (§5) and the reference kill counts.

Distances: a decision is 0.1 s; the boss chases at 6 u/s (0.6 per decision); attack 1 is a
straight missile at 20 u/s, radius 0.2; MagicMissile flies at 15 u/s.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import BOSS, CAST_1, NOOP, RESET, acts, events, make, run, scenario, series

from raidjax import damage, projectiles

CAST = acts(CAST_1, NOOP, NOOP)
CHASER = {"move_speed": 6.0}  # passive boss that chases (its attacks out of range)
SOLO = dict(alive=(True, False, False))


def solo(params, pos, boss=(0.0, 0.0), **kw):
    return scenario(params, players=(pos, (-11, -11), (11, -11)), boss=boss, **{**SOLO, **kw})


def test_boss_chases_at_6_units_per_second_and_stops_at_1_6():
    p = make(boss_overrides=CHASER)
    s = solo(p, (0.0, -10.0), boss=(0.0, 8.0))
    _, hist = run(s, p, acts(NOOP), 35)
    y = series(hist, lambda st: st.pos[BOSS, 1])
    assert y[0] == pytest.approx(7.4, abs=1e-5) and y[4] == pytest.approx(5.0, abs=1e-4)
    # 18 - 1.6 = 16.4 units to cover: 27 full steps then 0.2; stays at distance 1.6 afterwards.
    np.testing.assert_allclose(y[27:], -10.0 + 1.6, atol=1e-4)
    assert np.all(np.diff(y) <= 1e-6)
    np.testing.assert_allclose(series(hist, lambda st: st.pos[BOSS, 0]), 0.0, atol=1e-6)


def test_boss_chase_speed_is_its_move_speed():
    p = make(boss_overrides={"move_speed": 3.0})
    out, _ = run(solo(p, (0.0, -10.0), boss=(0.0, 8.0)), p, acts(NOOP), 2)
    assert float(out.pos[BOSS, 1]) == pytest.approx(8.0 - 0.6, abs=1e-5)


def test_boss_faces_its_target_also_while_casting():
    # Attack 2 only (attack 1 out of range), cast time 4 s: the boss is frozen while casting.
    p = make(passive_boss=False, boss_overrides={"skill1.range": 1.0})
    s = solo(p, (0.0, -4.0))
    out, hist = run(s, p, acts(NOOP), 2)
    assert out.casting[BOSS, 1]
    moved = np.asarray(out.pos[BOSS])
    s2 = out.replace(pos=out.pos.at[0].set(jnp.array([3.0, -3.0])))  # the target steps aside
    out2, _ = run(s2, p, acts(NOOP), 1)
    assert out2.casting[BOSS, 1]
    np.testing.assert_allclose(np.asarray(out2.pos[BOSS]), moved, atol=1e-6)
    want = math.atan2(-3.0 - moved[1], 3.0 - moved[0])
    assert math.cos(float(out2.heading[BOSS]) - want) > 1 - 1e-6


def test_boss_frozen_while_casting_attack_2_which_fires_after_4_seconds():
    p = make(passive_boss=False, boss_overrides={"skill1.range": 1.0})
    s = solo(p, (0.0, -4.0))
    _, hist = run(s, p, acts(NOOP), 42)
    pos = series(hist, lambda st: st.pos[BOSS])
    # Decision 1: chases in tick 1 (0.12 at 6 units/s), then starts the 4.0 s cast (200 ticks: it
    # fires at the end of tick 200, decision 40): frozen for 2..40. The slash lands in the next
    # tick (a projectile first acts in the tick after it is fired): decision 41.
    assert pos[0][1] == pytest.approx(-0.12, abs=1e-5)
    np.testing.assert_allclose(pos[1:40], np.broadcast_to(pos[0], (39, 2)), atol=1e-6)
    hp0 = series(hist, lambda st: st.hp[0])
    assert events(hp0, 100.0) == [41]
    assert hp0[40] == 100.0 - 60.0  # int(1.2 x 50) = 60
    assert pos[40][1] < pos[39][1] - 0.1  # moves again once the cast is over


def test_boss_attack_2_cadence_cast_4_s_then_cool_7_s():
    p = make(passive_boss=False, boss_overrides={"skill1.range": 1.0}, max_hp=1000)
    _, hist = run(solo(p, (0.0, -4.0)), p, acts(NOOP), 152)
    # Fires at 4.0 s (tick 200); the cool time (7.0 s) starts then: the charge is back at the end
    # of tick 550, the next cast starts in decision 111 and fires in tick 750. Each slash lands a
    # tick after it is fired: decisions 41 and 151.
    assert events(series(hist, lambda st: st.hp[0]), 1000.0) == [41, 151]


def test_boss_tries_attack_1_then_attack_2():
    p = make(passive_boss=False, boss_overrides={"move_speed": 0.0})
    _, hist = run(solo(p, (0.0, -4.0)), p, acts(NOOP), 2)  # both attacks in range
    first = hist[0]["state"]
    assert not first.casting[BOSS].any()  # attack 1 (cast 0.1 s) started and fired
    live = np.asarray(first.projectiles.live)
    assert live.sum() == 1 and first.projectiles.owner[live][0] == BOSS and first.projectiles.slot[live][0] == 0
    assert hist[1]["state"].casting[BOSS, 1]  # attack 1 cooling down: attack 2 starts
    # Out of attack 2's range (8 > 6): only attack 1.
    _, hist = run(solo(p, (0.0, -8.0)), p, acts(NOOP), 12)
    assert not any(h["state"].casting[BOSS, 1] for h in hist)


def test_boss_retargets_nearest_alive_player_when_target_dies():
    p = make(boss_overrides=CHASER)
    s = scenario(p, players=((0.0, -3.0), (4.0, 0.0), (0.0, 6.0)), boss=(0.0, 0.0))
    assert int(s.target[BOSS]) == 0
    s = s.replace(alive=s.alive.at[0].set(False), hp=s.hp.at[0].set(0.0))
    out, _ = run(s, p, acts(NOOP), 1)
    assert int(out.target[BOSS]) == 1


def test_reset_targets_nearest_player(ref_params):
    _, s = RESET(jax.random.key(0), ref_params)
    assert int(s.target[BOSS]) == 1  # (0, -10) is the nearest spawn to the boss at (0, 8)


# --- attack 1: straight missile; attack 2: area ------------------------------------------------

def test_the_boss_re_targets_as_it_fires_and_its_missile_keeps_the_old_facing():
    # GAME.md §5, §7: as a skill fires the boss re-picks its target (the nearest alive player), but a
    # straight missile flies along the facing the boss had while casting. The boss faces player 0 at
    # (0, -5) (its target, 5 away) while player 1 at (3, 0) is nearer (3): the breath (0.1 s) fires on
    # decision 1 along (0, -1), the target becomes player 1, and the missile (2 units per decision from
    # decision 2) reaches player 0's front at y = -4.3 in decision 4: 55 damage to player 0, none to 1.
    p = make(passive_boss=False, boss_overrides={"skill2.range": 1.0, "move_speed": 0.0})
    s = scenario(p, players=((0.0, -5.0), (3.0, 0.0), (11.0, -11.0)), boss=(0.0, 0.0),
                 alive=(True, True, False), target=0)
    out, hist = run(s, p, acts(NOOP), 4)
    first = hist[0]["state"]
    assert int(first.target[BOSS]) == 1
    (slot,) = np.flatnonzero(first.projectiles.live)
    np.testing.assert_allclose(first.projectiles.direction[slot], [0.0, -1.0], atol=1e-6)
    assert [float(h["state"].hp[0]) for h in hist] == [100.0, 100.0, 100.0, 45.0]
    assert float(out.hp[1]) == 100.0


def test_attack_1_straight_missile_hits_first_player_on_its_path():
    p = make(passive_boss=False, boss_overrides={"skill2.range": 1.0, "move_speed": 0.0})
    # A (target, distance 3) and B right behind it on the same line, C far aside.
    s = scenario(p, players=((0.0, -3.0), (0.0, -3.5), (5.0, -5.0)), boss=(0.0, 0.0))
    _, hist = run(s, p, acts(NOOP), 4)
    hp = hist[-1]["state"].hp
    assert float(hp[0]) == 100.0 - 55.0  # int(1.1 x 50)
    assert float(hp[1]) == 100.0 and float(hp[2]) == 100.0


def test_two_attack_1_hits_kill_a_reference_player_loss():
    p = make(passive_boss=False, boss_overrides={"skill2.range": 1.0, "move_speed": 0.0})
    _, hist = run(solo(p, (0.0, -5.0)), p, acts(NOOP), 12)
    hp = series(hist, lambda st: st.hp[0])
    hits = events(hp, 100.0)
    assert len(hits) == 2
    assert hp[hits[0] - 1] == 45.0 and hist[hits[0] - 1]["state"].alive[0]
    assert not hist[hits[1] - 1]["state"].alive[0] and hp[hits[1] - 1] <= 0.0
    last = hist[hits[1] - 1]
    assert last["done"] and int(last["info"]["result"]) == 2 and bool(last["info"]["terminated"])
    assert not bool(last["info"]["truncated"])


def test_straight_missile_flies_along_facing_and_is_destroyed_by_walls():
    p = make(**{"skill1.target_type": 0})
    s = solo(p, (0.0, -4.0), headings=(0.0, 0.0, 0.0))  # faces +x; the boss is at +y
    _, hist = run(s, p, CAST, 14)
    live = [bool(h["state"].projectiles.live.any()) for h in hist]
    # Fired at the end of decision 5 (tick 25) at x = 0; it first moves in decision 6, 1.5 per
    # decision: x = 12.0 on decision 13, 13.5 > 12.25 on 14.
    assert live == [False] * 4 + [True] * 9 + [False] * 1
    assert float(hist[-1]["state"].hp[BOSS]) == 1000.0
    # Facing the boss, the same missile hits it.
    s = solo(p, (0.0, -4.0))
    out, _ = run(s, p, CAST, 8)
    assert float(out.hp[BOSS]) == 950.0


def test_a_straight_missile_flies_through_an_ally_in_its_path():
    # GAME.md §5: a projectile touches only the units its skill may hit (a damage skill: enemies).
    # Player 0 at (0, -4.5) faces the boss at (0, 0) with player 1 standing at (0, -2.5) between them;
    # the straight missile passes player 1 and hits the boss once (the facing test above: 950).
    p = make(**{"skill1.target_type": 0})
    s = scenario(p, players=((0.0, -4.5), (0.0, -2.5), (11.0, -11.0)), boss=(0.0, 0.0),
                 alive=(True, True, False), headings=(math.pi / 2, math.pi / 2, 0.0))
    out, _ = run(s, p, CAST, 10)
    assert float(out.hp[BOSS]) == 950.0 and float(out.hp[1]) == 100.0 and not out.projectiles.live.any()


@pytest.mark.parametrize("target_type", [0, 1])
def test_fast_missile_does_not_tunnel_through_a_small_unit(target_type):
    # Speed 50 = 5 units per decision; boss hurtbox ~0.27: the missile's positions at decision
    # ends (y = -1 and 4) are both 2.5 away from the boss at y = 1.5.
    p = make(boss_overrides={"radius": 0.1},
             **{"skill1.projectile_speed": 50.0, "skill1.cast_time": 0.0, "skill1.range": 20.0,
                "skill1.target_type": target_type})
    out, hist = run(solo(p, (0.0, -6.0), boss=(0.0, 1.5)), p, CAST, 3)
    assert float(out.hp[BOSS]) == 950.0
    assert [float(h["state"].hp[BOSS]) for h in hist][:2] == [1000.0, 950.0]


def test_homing_missile_follows_and_hits_its_target():
    p = make(boss_overrides={"move_speed": 3.0, "skill1.range": 1.0, "skill2.range": 1.0})
    # Player faces away from the boss; the homing missile still hits it (the boss moves).
    s = solo(p, (0.0, -4.5), headings=(-math.pi / 2, 0.0, 0.0))
    out, hist = run(s, p, CAST, 12)
    assert float(out.hp[BOSS]) == 950.0
    assert not out.projectiles.live.any()


def test_instant_effect_lands_at_cast_completion():
    p = make(**{"skill1.projectile_speed": 0.0})
    _, hist = run(solo(p, (0.0, -4.0)), p, CAST, 6)
    boss_hp = series(hist, lambda st: st.hp[BOSS])
    assert events(boss_hp, 1000.0) == [5]  # cast 0.5 s
    assert not any(h["state"].projectiles.live.any() for h in hist)


def slash_params(hit_count=3):
    return make(passive_boss=False, boss_overrides={
        "move_speed": 0.0, "skill1.range": 1.0, "skill2.cast_time": 0.1, "skill2.hit_count": hit_count})


@pytest.mark.parametrize("offset, expected", [(0.5, [40.0, 40.0, 100.0]), (1.0, [40.0, 40.0, 40.0]),
                                              (0.0, [100.0, 100.0, 100.0])])
def test_attack_2_area_is_centred_at_the_boss_target_midpoint(offset, expected):
    # Target A at distance 4: midpoint (0, -2), reach 2.4 + 0.5. B is 2.5 from the midpoint (hit);
    # C is 2.6 from A but 4.6 from the midpoint.
    # area_offset 1.0 centres it on A (all within 2.6); 0.0 on the boss (A, B, C >= 4 away).
    p = make(passive_boss=False, boss_overrides={"move_speed": 0.0, "skill1.range": 1.0, "skill2.cast_time": 0.1,
                                                 "skill2.area_offset": offset})
    s = scenario(p, players=((0.0, -4.0), (1.5, -4.0), (0.0, -6.6)), boss=(0.0, 0.0))
    out, _ = run(s, p, acts(NOOP), 2)  # fired in tick 5, lands in tick 6
    np.testing.assert_allclose(np.asarray(out.hp[:3]), expected)


@pytest.mark.parametrize("radius, hit", [(0.2, False), (1.5, True)])
def test_missile_radius_widens_its_path(radius, hit):
    # A straight missile flying +y, 2.0 to the side of the boss's centre (boss radius 1.5).
    p = make(**{"skill1.target_type": 0, "skill1.projectile_radius": radius})
    out, _ = run(solo(p, (2.0, -4.0), headings=(math.pi / 2, 0.0, 0.0)), p, CAST, 12)
    assert (float(out.hp[BOSS]) == 950.0) is hit


@pytest.mark.parametrize("hit_count, expected", [(3, [40, 40, 40]), (2, [40, 40, 100]), (1, [40, 100, 100])])
def test_area_hits_at_most_hit_count_units_nearest_first(hit_count, expected):
    p = slash_params(hit_count)
    # Midpoint (0, -1.5): A 1.5 away, B and C 2.16 away (tie -> lower index first).
    s = scenario(p, players=((0.0, -3.0), (1.2, -3.3), (-1.2, -3.3)), boss=(0.0, 0.0))
    out, _ = run(s, p, acts(NOOP), 2)  # fired in tick 5, lands in tick 6
    np.testing.assert_allclose(np.asarray(out.hp[:3]), expected)


@jax.jit
def _move(state, params):
    skills, _ = damage.effect_sources(params)
    feats = jax.tree.map(lambda x: x[state.projectiles.owner * 3 + state.projectiles.slot], skills)
    cols = damage.unit_columns(state, params)
    touch = damage.touchable(feats, params, state.alive)
    near = projectiles.contacts(state, params, feats, cols)
    return projectiles.move_projectiles(state, params, feats, 0.1, cols, touch, near)


def test_area_hits_each_unit_only_once_while_it_lingers():
    p = make(**{"skill1.target_type": 2, "skill1.projectile_radius": 3.0})
    s = solo(p, (0.0, -4.0))
    pr = s.projectiles
    s = s.replace(projectiles=pr.replace(live=pr.live.at[0].set(True), kind=pr.kind.at[0].set(2),
                                         pos=pr.pos.at[0].set(jnp.array([0.0, 0.5])), life=pr.life.at[0].set(1.0)))
    s1, hits1, _ = _move(s, p)
    _, hits2, _ = _move(s1, p)
    assert not hits1.single  # an area may hit several units (clean rules)
    hits1, hits2 = hits1.hit, hits2.hit
    assert bool(hits1[0, BOSS]) and not bool(hits1[0, :BOSS].any())  # enemies only
    assert not bool(hits2.any())
    assert bool(s1.projectiles.live[0])  # still lingering


def test_empty_pool_slots_do_not_change_in_flight():
    """What lets the CPU program skip pool blocks no arena uses: a slot with no projectile keeps
    every field, whatever an earlier projectile left there (here a homing missile that expired)."""
    p = make()
    s = solo(p, (0.0, -4.0))
    pr = s.projectiles
    leftover = pr.replace(kind=pr.kind.at[1].set(1), pos=pr.pos.at[1].set(jnp.array([2.0, 3.0])),
                          direction=pr.direction.at[1].set(jnp.array([0.0, 1.0])), target=pr.target.at[1].set(BOSS),
                          life=pr.life.at[1].set(0.5), hit_mask=pr.hit_mask.at[1, BOSS].set(True))
    live = leftover.replace(live=leftover.live.at[0].set(True), kind=leftover.kind.at[0].set(1),
                            target=leftover.target.at[0].set(BOSS), life=leftover.life.at[0].set(5.0))
    s1, _, _ = _move(s.replace(projectiles=live), p)
    for before, after in zip(jax.tree.leaves(live), jax.tree.leaves(s1.projectiles), strict=True):
        np.testing.assert_array_equal(np.asarray(after)[1:], np.asarray(before)[1:])
    assert float(s1.projectiles.life[0]) < 5.0  # the live slot's clock runs


# --- reference kill counts (GAME.md §4, §7) ----------------------------------------------------

def test_reference_boss_dies_after_20_front_hits():
    p = make()
    s = solo(p, (0.0, -4.0))
    _, hist = run(s, p, CAST, 205)
    hp = series(hist, lambda st: st.hp[BOSS])
    drops = np.diff(np.concatenate([[1000.0], hp]))
    assert set(drops[drops < 0].tolist()) == {-50.0}
    assert (drops < 0).sum() == 20 and hp.min() == 0.0
    t = int(np.argmax(hp <= 0))
    assert hist[t - 1]["state"].alive[BOSS] and not hist[t]["state"].alive[BOSS]
    assert int(hist[t]["info"]["result"]) == 1 and hist[t]["done"]


def test_reference_boss_dies_after_17_back_attacks():
    p = make()
    # Player 1 (noop) is the boss's target in front; player 0 shoots from behind.
    s = scenario(p, players=((0.0, 4.0), (0.0, -3.0), (11, -11)), boss=(0.0, 0.0), alive=(True, True, False))
    _, hist = run(s, p, CAST, 175)
    hp = series(hist, lambda st: st.hp[BOSS])
    drops = np.diff(np.concatenate([[1000.0], hp]))
    # 16 x 60 = 960 < 1000 <= 17 x 60: the 17th hit takes the last 40 (HP floors at 0).
    assert drops[drops < 0].tolist() == [-60.0] * 16 + [-40.0]
    assert int(hist[-1]["state"].back_attacks[0]) == 17
    assert int(hist[-1]["info"]["result"]) == 1
