"""Damage, statistics, back attacks, heals, basic attacks, regeneration and rewards (GAME.md §3, §6, §8).

Most cases use an *instant* MagicMissile with no cast time (projectile speed 0, cast time 0):
the hit lands on decision 1, so one jitted step measures one hit. Base damage is
int(0.5 x 100) = 50 (GAME.md §4).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import BOSS, CAST_1, NOOP, acts, make, run, scenario, series

import raidjax.utils
from raidjax import damage
from raidjax.hits import Hits

FAST = {"skill1.projectile_speed": 0.0, "skill1.cast_time": 0.0}
CAST = acts(CAST_1, NOOP, NOOP)


def one_hit(overrides=None, boss=None, player=None, players=((0.0, -4.0), (-11, -11), (11, -11)),
            alive=(True, False, False), target=None, actions=CAST):
    p = make(boss_overrides=boss, player_overrides=[{**FAST, **(player or {})}, FAST, FAST],
             **(overrides or {}))
    s = scenario(p, players=players, boss=(0.0, 0.0), alive=alive, target=target)
    out, hist = run(s, p, actions, 1)
    return 1000.0 - float(out.hp[BOSS]), hist[0]


@pytest.mark.parametrize(
    "player, boss, expected",
    [
        ({}, {}, 50),
        ({}, {"armor": 100}, 25),  # x (1 - 100/200)
        ({}, {"armor": 50}, 37),  # int(50 x 0.75)
        ({}, {"evasion": 100}, 0),  # every hit dodged
        ({}, {"evasion": 75, "agility": 100}, 0),  # agility adds (100 - 50) / 2 to evasion
        ({}, {"parry": 100}, 25),  # every hit parried: half damage
        ({"critical": 100}, {}, 75),  # x 1.5
        ({"critical": 100, "crit_multiplier": 2.0}, {}, 100),
        ({"versatility": 100}, {}, 100),  # dealt x (1 + 100/100)
        ({}, {"versatility": 100}, 25),  # taken x (1 - 100/200)
        ({}, {"armor": 50, "versatility": 100}, 18),  # int(50 x 0.75 x 0.5)
        ({"intelligence": 100}, {}, 75),  # spell x (1 + (100 - 50)/100)
        ({"intelligence": 1}, {}, 25),  # int(50 x 0.51)
        ({"strength": 100}, {}, 50),  # strength does not scale spells
        ({"spell_power": 40}, {}, 20),
        ({"skill1.coefficient": 1.0}, {}, 100),
        ({"skill1.coefficient": 0.0}, {}, 0),
        ({"skill1.hit_type": 0, "attack_power": 80}, {}, 40),  # attack: base is attack power
        ({"skill1.hit_type": 0, "attack_power": 80, "strength": 100}, {}, 60),
        ({"skill1.hit_type": 0, "attack_power": 80, "intelligence": 100}, {}, 40),
        ({"mastery": 100, "back_attack_multiplier": 2.0}, {}, 50),  # front hit: no back bonus
        ({"skill1.school": 7}, {}, 50),  # cosmetic
    ],
)
def test_damage_modifiers(player, boss, expected):
    dealt, h = one_hit(player=player, boss=boss)
    assert dealt == expected
    assert float(h["info"]["damage_dealt"][0]) == expected
    assert float(h["reward"][0]) == pytest.approx(0.01 * expected)
    assert int(h["info"]["back_attack"][0]) == 0


# --- percentages, measured over many hit events at once -------------------------------------

E = 800


@jax.jit
def mean_multiplier(key, state, params):
    """Average damage of E simultaneous hits of player 0's slot 1 on the boss / base 50."""
    feats = jax.tree.map(lambda x: jnp.broadcast_to(x[damage.source_index(0, 0, 3)], (E,)), damage.effect_table(params))
    hits = Hits(jnp.zeros((E, 4), bool).at[:, BOSS].set(True))
    from_pos = jnp.broadcast_to(state.pos[0], (E, 2))
    seeds = raidjax.utils.dice_seeds(key)
    u_n = hits.hit.shape[1]
    outcomes = damage.hit_outcomes(seeds, damage.unit_columns(state, params), feats, hits, from_pos, E, 0, u_n, ())
    sums = damage.group_sums(outcomes, feats, jnp.zeros(E, jnp.int32), hits, u_n)
    _, to_boss, _ = damage.apply_hits(state, params, sums)
    return to_boss[0] / (50.0 * E)


@pytest.mark.parametrize(
    "player, boss, expected",
    [
        ({}, {}, 1.0),
        ({}, {"evasion": 30}, 0.7),
        ({}, {"agility": 90}, 0.8),  # evasion 0 + (90 - 50) / 2 = 20 %
        ({"agility": 90}, {"evasion": 30}, 0.9),  # 30 - 20 = 10 %
        ({"critical": 40}, {}, 1.2),  # 40 % of hits x 1.5
        ({}, {"parry": 40}, 0.8),  # 40 % of hits halved
    ],
)
def test_percentage_stats(player, boss, expected):
    p = make(boss_overrides=boss, player_overrides=[player, {}, {}])
    s = scenario(p, players=((0.0, -4.0), (-11, -11), (11, -11)), boss=(0.0, 0.0))
    got = float(mean_multiplier(jax.random.key(3), s, p))
    assert abs(got - expected) < 0.06


# --- back attacks (GAME.md §6) ----------------------------------------------------------------

def behind(theta_deg, dist=4.0):
    """Player 0 at ``theta`` degrees from the boss's rear (+y: the boss faces player 1 at -y)."""
    t = math.radians(theta_deg)
    return (dist * math.sin(t), dist * math.cos(t))


@pytest.mark.parametrize("theta, expected, is_back",
                         [(0, 60, 1), (50, 60, 1), (-55, 60, 1), (70, 50, 0), (-70, 50, 0), (120, 50, 0)])
def test_back_attack_cone_of_60_degrees(theta, expected, is_back):
    dealt, h = one_hit(players=(behind(theta), (0.0, -3.0), (11, -11)), alive=(True, True, False), target=1)
    assert dealt == expected  # int(50 x 1.2) = 60 from behind
    assert int(h["info"]["back_attack"][0]) == is_back
    assert int(h["state"].back_attacks[0]) == is_back
    assert float(h["reward"][0]) == pytest.approx(0.01 * expected)  # 0.012 x base on a back attack


@pytest.mark.parametrize("player, expected",
                         [({"mastery": 100}, 120), ({"back_attack_multiplier": 1.5}, 75), ({"critical": 100}, 90)])
def test_back_attack_multiplier_mastery_and_crit(player, expected):
    dealt, _ = one_hit(player=player, players=(behind(0), (0.0, -3.0), (11, -11)), alive=(True, True, False),
                       target=1)
    assert dealt == expected


def test_reference_homing_missile_back_attack_pays_60():
    p = make()
    s = scenario(p, players=((0.0, 4.0), (0.0, -3.0), (11, -11)), boss=(0.0, 0.0), alive=(True, True, False),
                 target=1)
    _, hist = run(s, p, CAST, 8)
    boss_hp = series(hist, lambda st: st.hp[BOSS])
    assert sorted(set(boss_hp.tolist())) == [940.0, 1000.0]
    t = int(np.argmax(boss_hp < 1000.0))
    assert int(hist[t]["info"]["back_attack"][0]) == 1
    assert float(hist[t]["reward"][0]) == pytest.approx(0.6)


# --- affect on ally / enemy, heals ----------------------------------------------------------

@pytest.mark.parametrize("target_type, speed", [(1, 15.0), (1, 0.0), (0, 15.0)])
def test_skill_without_affect_enemy_does_not_damage(target_type, speed):
    p = make(**{"skill1.affect_enemy": 0, "skill1.target_type": target_type, "skill1.projectile_speed": speed})
    s = scenario(p, players=((0.0, -4.0), (-11, -11), (11, -11)), boss=(0.0, 0.0), alive=(True, False, False),
                 headings=(math.pi / 2, 0.0, 0.0))
    out, _ = run(s, p, CAST, 12)
    assert float(out.hp[BOSS]) == 1000.0


def heal_team(healer, hp1, hp2=100.0):
    p = make(player_overrides=[healer, {}, {}])
    s = scenario(p, players=((0.0, -4.0), (2.0, -4.0), (-2.0, -4.0)), boss=(0.0, 0.0),
                 hp=(None, hp1, hp2, None))
    return p, s


@pytest.mark.parametrize(
    "healer, hp1, expected",
    [
        ({"skill1": "heal"}, 30.0, 70.0),  # int(0.4 x 100) = 40
        ({"skill1": "heal"}, 90.0, 100.0),  # capped at max HP
        ({"skill1": "heal", "intelligence": 100}, 30.0, 90.0),  # x 1.5
        ({"skill1": "heal", "spell_power": 50}, 30.0, 50.0),
    ],
)
def test_heal_restores_coefficient_times_spell_power_capped(healer, hp1, expected):
    p, s = heal_team(healer, hp1, hp2=95.0)
    _, hist = run(s, p, CAST, 10)  # heal: cast 1.0 s
    assert float(hist[8]["state"].hp[1]) == hp1  # not before the cast completes
    assert float(hist[9]["state"].hp[1]) == expected  # lowest HP fraction ally healed
    assert float(hist[9]["state"].hp[2]) == 95.0
    assert float(hist[9]["state"].hp[BOSS]) == 1000.0  # a heal does not hurt the boss


def test_homing_heal_missile_reaches_its_ally():
    healer = {"skill1.affect_enemy": 0, "skill1.affect_ally": 1, "skill1.range": 10.0}
    p, s = heal_team(healer, 30.0)
    out, _ = run(s, p, CAST, 10)
    assert float(out.hp[1]) == 80.0  # int(0.5 x 100) = 50 delivered by a homing missile
    assert float(out.hp[BOSS]) == 1000.0



@pytest.mark.parametrize("hit_count, expected", [(8, [90.0, 60.0, 100.0]), (3, [90.0, 60.0, 100.0]),
                                                 (2, [90.0, 60.0, 85.0]), (1, [90.0, 30.0, 85.0])])
def test_area_heal_heals_allies_in_its_circle_nearest_first_each_once(hit_count, expected):
    # healing_circle: an area of radius 4 centred on its caster (area_offset 0) that touches allies
    # only (the caster is one), int(0.3 x 100) = 30 HP each, capped at max HP 100, up to hit_count
    # units nearest its centre first (GAME.md §5-6). The healer is 0 from the centre, ally 1 is
    # 1.5 and ally 2 is 3.0; the boss's body reaches inside the circle but it is an enemy. At 5
    # sub-steps per decision the area lingers 5 ticks over the three: each is healed once, also
    # when hit_count (8) leaves room for more hits.
    healer = {"skill1": "healing_circle", "skill1.hit_count": hit_count}
    p = make(player_overrides=[healer, {}, {}], config=raidjax.EnvConfig.from_rules("clean"))
    s = scenario(p, players=((0.0, -4.0), (1.5, -4.0), (-3.0, -4.0)), boss=(0.0, 0.0),
                 hp=(60.0, 30.0, 85.0, None))
    _, hist = run(s, p, CAST, 40)  # cast 1.5 s; cooldown 6 s from the firing: one cast only
    hp = series(hist, lambda st: st.hp)
    changed = np.nonzero(np.any(np.diff(hp, axis=0) != 0, axis=1))[0]
    assert changed.tolist() == [14]  # fired in decision 15's last tick, lands in decision 16, once
    np.testing.assert_allclose(hp[-1, :3], expected)
    assert hp[-1, BOSS] == 1000.0


# --- basic attack, regeneration --------------------------------------------------------------

@pytest.mark.parametrize(
    "stats, hits, per_hit",
    [
        ({"attack_power": 20, "attack_range": 2}, [1, 11, 21], 20),  # 1 attack per second
        ({"attack_power": 20, "attack_range": 2, "attack_speed": 2.0}, [1, 6, 11, 16, 21], 20),
        ({"attack_power": 20, "attack_range": 2, "strength": 100}, [1, 11, 21], 30),
        ({"attack_power": 20, "attack_range": 1}, [], 20),  # surface gap 1.5 > range 1
        ({"attack_power": 0, "attack_range": 2}, [], 0),  # off in the reference setting
    ],
)
def test_basic_attack(stats, hits, per_hit):
    p = make(**stats)
    # Centre distance 3.5: gap between the discs 3.5 - 0.5 - 1.5 = 1.5.
    s = scenario(p, players=((0.0, -3.5), (-11, -11), (11, -11)), boss=(0.0, 0.0), alive=(True, False, False))
    _, hist = run(s, p, acts(NOOP), 21)
    boss_hp = series(hist, lambda st: st.hp[BOSS])
    got = [i + 1 for i in np.nonzero(np.diff(np.concatenate([[1000.0], boss_hp])) < 0)[0]]
    assert got == hits
    assert boss_hp[-1] == 1000.0 - per_hit * len(hits)


def test_hp_regeneration_capped_and_reference_zero():
    p = make(hp_regen=10.0)
    s = scenario(p, players=((0.0, -4.0), (2.0, -4.0), (-11, -11)), boss=(0.0, 0.0), alive=(True, True, False),
                 hp=(50.0, 99.5, None, None))
    _, hist = run(s, p, acts(NOOP), 2)
    assert float(hist[0]["state"].hp[0]) == pytest.approx(51.0)
    assert float(hist[1]["state"].hp[0]) == pytest.approx(52.0)
    assert float(hist[0]["state"].hp[1]) == 100.0
    assert float(hist[1]["state"].hp[2]) == 0.0  # the dead do not regenerate
    p = make()
    s = scenario(p, players=((0.0, -4.0), (2.0, -4.0), (-11, -11)), boss=(0.0, 0.0), hp=(50.0, None, None, None))
    out, _ = run(s, p, acts(NOOP), 3)
    assert float(out.hp[0]) == 50.0


def test_individual_rewards_follow_each_players_damage():
    p = make(player_overrides=[FAST, {**FAST, "skill1.coefficient": 1.0}, FAST])
    s = scenario(p, players=((0.0, -4.0), (1.0, -4.0), (-1.0, -4.0)), boss=(0.0, 0.0))
    _, hist = run(s, p, acts(CAST_1, CAST_1, NOOP), 1)
    np.testing.assert_allclose(hist[0]["reward"], [0.5, 1.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(hist[0]["info"]["damage_dealt"], [50.0, 100.0, 0.0])
    np.testing.assert_allclose(hist[0]["state"].damage_dealt[:3], [50.0, 100.0, 0.0])


def test_random_stats_use_the_step_key():
    # Same key -> same dice; the dice come from the key (a 50 % crit differs between keys).
    p = make(player_overrides=[{**FAST, "critical": 50}, FAST, FAST])
    s = scenario(p, players=((0.0, -4.0), (-11, -11), (11, -11)), boss=(0.0, 0.0), alive=(True, False, False))
    outs = {k: float(run(s, p, CAST, 1, key=jax.random.key(k))[0].hp[BOSS]) for k in range(12)}
    assert set(outs.values()) == {950.0, 925.0}
    assert outs[5] == float(run(s, p, CAST, 1, key=jax.random.key(5))[0].hp[BOSS])



def test_boss_back_attacks_pay_no_bonus():
    # GAME.md §6: the back-attack multiplier is for players only; a boss missile from behind a
    # player deals its base 55 even with the boss's multiplier and mastery maxed.
    p = make(passive_boss=False, boss_overrides={"back_attack_multiplier": 3.0, "mastery": 100})
    s = scenario(p, players=((0.0, -4.0), (11, -11), (-11, -11)), boss=(0.0, 0.0),
                 alive=(True, False, False), headings=(-math.pi / 2, 0.0, 0.0))
    _, hist = run(s, p, acts(NOOP), 6)
    hp = series(hist, lambda st: st.hp[0])
    assert sorted(set(hp.tolist()))[:1] == [45.0]  # 100 - 55
    assert int(hist[-1]["state"].back_attacks[BOSS]) == 0


def test_the_dice_are_the_hash_the_rulebook_writes_down():
    # GAME.md §1, "Dice and keys": element n of uniform_dice(k, shape) is a uint32 hash of n seeded by
    # the two words jax.random.bits(k, (2,), uint32), then (x >> 8) / 2^24. Here in plain Python.
    def die(n, s0, s1):
        m = 0xFFFFFFFF
        x = (n * 0x9E3779B1 + s0) & m
        x ^= x >> 16
        x = ((x * 0x85EBCA6B) & m) ^ s1
        x ^= x >> 13
        x = (x * 0xC2B2AE35) & m
        x ^= x >> 16
        return (x >> 8) / 2**24

    key = jax.random.fold_in(jax.random.key(7), 3)
    s0, s1 = (int(w) for w in np.asarray(jax.random.bits(key, (2,), jnp.uint32)))
    got = np.asarray(raidjax.utils.uniform_dice(key, (3, 32, 4)))
    want = np.asarray([die(n, s0, s1) for n in range(3 * 32 * 4)], np.float32).reshape(3, 32, 4)
    np.testing.assert_array_equal(got, want)
