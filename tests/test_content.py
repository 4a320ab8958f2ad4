"""Content: reference values (GAME.md §3, §4, §7), presets (catalogue), make_params overrides and
validation of bad input (out of range, NaN, non-integer, unknown, wrong shapes)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import ACTION_HEURISTIC, RESET, T_ROLL, rollout

import raidjax
from raidjax import catalogue
from raidjax.content import SKILL_SPECS, STAT_SPECS
from raidjax.playtest import broadcast_params
from raidjax.types import TARGET_NONE, TARGET_REGION, TARGET_UNIT


def test_reference_content_matches_the_spec(ref_params):
    st, sk = ref_params.stats, ref_params.skills
    assert ref_params.team.tolist() == [0, 0, 0, 1]
    np.testing.assert_array_equal(np.asarray(st.max_hp), [100, 100, 100, 1000])
    np.testing.assert_array_equal(np.asarray(st.max_mana), [100, 100, 100, 100])
    np.testing.assert_array_equal(np.asarray(st.spell_power), [100, 100, 100, 50])
    np.testing.assert_array_equal(np.asarray(st.move_speed), [1, 1, 1, 6])
    np.testing.assert_array_equal(np.asarray(st.mana_regen), 1.0)
    np.testing.assert_array_equal(np.asarray(st.hp_regen), 0.0)
    np.testing.assert_allclose(np.asarray(st.back_attack_multiplier[:3]), 1.2)
    np.testing.assert_allclose(np.asarray(st.radius[:3]), 0.5)
    for neutral, value in (("armor", 0), ("evasion", 0), ("parry", 0), ("critical", 0), ("haste", 0),
                           ("versatility", 0), ("mastery", 0), ("attack_power", 0), ("strength", 50),
                           ("agility", 50), ("intelligence", 50)):
        np.testing.assert_array_equal(np.asarray(getattr(st, neutral)), value, err_msg=neutral)
    mm = {k: np.asarray(getattr(sk, k))[:3, 0] for k in SKILL_SPECS}
    want = dict(in_use=1, trigger=0, target_type=TARGET_UNIT, projectile_speed=15, projectile_radius=0.2,
                hit_count=1, cast_time=0.5, cool_time=0.5, cost=1, coefficient=0.5, range=5, cast_on_moving=1,
                charge=1, affect_enemy=1, affect_ally=0, hit_type=1)
    for k, v in want.items():
        np.testing.assert_allclose(mm[k], v, err_msg=k)
    assert np.asarray(sk.in_use)[:3, 1:].sum() == 0  # one skill slot
    boss = {k: np.asarray(getattr(sk, k))[3, :2] for k in SKILL_SPECS}
    for k, v in dict(range=(12, 6), cool_time=(0.5, 7.0), cast_time=(0.1, 4.0), coefficient=(1.1, 1.2),
                     target_type=(TARGET_NONE, TARGET_REGION), projectile_speed=(20, 0),
                     projectile_radius=(0.2, 2.4), hit_count=(1, 3), area_offset=(None, 0.5)).items():
        for i in (0, 1):
            if v[i] is not None:
                assert boss[k][i] == pytest.approx(v[i]), (k, i)


def test_default_params_and_skill_range():
    d = raidjax.default_params()
    assert np.asarray(d.skills.range)[:3, 0].tolist() == [5, 5, 5]
    p = raidjax.make_params(skill_range=13.0)
    assert np.asarray(p.skills.range)[:3, 0].tolist() == [13, 13, 13]
    assert float(p.skills.range[3, 0]) == 12.0  # the boss is untouched


def test_override_syntax():
    p = raidjax.make_params(armor=40, boss_overrides={"armor": 10, "skill2.hit_count": 2},
                            player_overrides=[{"skill1.cool_time": 1.0}, {"skill2": "heal"}, {}],
                            **{"skill1.coefficient": 0.8})
    assert np.asarray(p.stats.armor).tolist() == [40, 40, 40, 10]
    assert np.asarray(p.skills.cool_time)[:, 0].tolist() == [1.0, 0.5, 0.5, 0.5]
    np.testing.assert_allclose(np.asarray(p.skills.coefficient)[:3, 0], 0.8)
    assert np.asarray(p.skills.in_use)[:, 1].tolist() == [0, 1, 0, 1]
    assert float(p.skills.affect_ally[1, 1]) == 1 and int(p.skills.hit_count[3, 1]) == 2
    assert np.asarray(p.stats.armor).dtype == np.float32 and np.asarray(p.skills.charge).dtype == np.int32


def test_team_sizes():
    for names in (["mage"], ["mage"] * 5, ("mage", "warrior", "priest")):
        p = raidjax.make_params(players=names)
        u = len(names) + 1
        assert p.team.shape == (u,) and p.stats.max_hp.shape == (u,) and p.skills.range.shape == (u, 3)
    assert raidjax.make_params(players="warrior").team.shape == (4,)


# --- presets ---------------------------------------------------------------------------------

BOSS_SKILLS = {name for b in catalogue.BOSSES.values() for name in b["skills"]}


@pytest.mark.parametrize("name", sorted(catalogue.SKILLS))
def test_every_skill_preset_builds(name):
    if name in BOSS_SKILLS:  # boss skills may exceed player ranges (attack 2: cast 4 s)
        p, unit = raidjax.make_params(boss_overrides={"skill1": name, "skill3": name}), 3
    else:
        p, unit = raidjax.make_params(skill1=name, skill3=name), 0
    fields = catalogue.skill_fields(name)
    for slot in (0, 2):
        for k in ("range", "cast_time", "cool_time", "coefficient", "target_type", "projectile_speed"):
            assert float(getattr(p.skills, k)[unit, slot]) == pytest.approx(fields[k])


def test_every_class_and_boss_preset_builds():
    for cls in catalogue.CLASSES:
        for boss in catalogue.BOSSES:
            raidjax.make_params(players=cls, boss=boss)


def test_skills_cover_every_delivery():
    kinds = set()
    for f in map(catalogue.skill_fields, catalogue.SKILLS):
        ally_only = f["affect_ally"] and not f["affect_enemy"]
        if ally_only:
            kinds.add("heal")
        if f["target_type"] == TARGET_REGION:
            kinds.add("area")
        elif f["projectile_speed"] == 0:
            kinds.add("instant")
        elif f["target_type"] == TARGET_UNIT:
            kinds.add("homing")
        elif f["target_type"] == TARGET_NONE:
            kinds.add("straight")
        kinds.add("passive" if f["trigger"] else "active")
        kinds.add("attack" if f["hit_type"] == 0 else "spell")
    assert kinds == {"heal", "area", "instant", "homing", "straight", "passive", "active", "attack", "spell"}


@pytest.mark.parametrize("team", [("mage", "warrior", "priest"), ("ranger", "druid", "battle_mage")])
def test_mixed_team_runs_with_heuristic_and_random_actions(team):
    p = raidjax.make_params(players=team, boss="enraged_dragon")
    _, s = RESET(jax.random.key(1), p)
    rng = np.random.default_rng(1)
    actions = jnp.asarray(rng.integers(0, 10, (T_ROLL, 3)), jnp.int32).at[:, 0].set(ACTION_HEURISTIC)
    final, (rewards, _, results, finite) = rollout(jax.random.key(2), s, p, actions)
    assert bool(finite.all())
    # The scripted player left its spawn and keeps within its preferred distance of the boss (its
    # longest charged range, 10 while recharging), give or take the boss's chase of one decision.
    assert float(jnp.linalg.norm(final.pos[0] - jnp.array([-3.0, -10.0]))) > 1.0
    preferred = max(float(jnp.max(p.skills.range[0])), 10.0)
    assert float(jnp.linalg.norm(final.pos[0] - final.pos[3])) <= preferred + 1.0
    assert np.asarray(final.hp <= p.stats.max_hp).all()


def test_school_is_cosmetic():
    runs = []
    for school in (0, 9):
        p = raidjax.make_params(players=("mage", "battle_mage", "priest"),
                                **{f"skill{k}.school": school for k in (1, 2, 3)},
                                boss_overrides={"skill1.school": school, "skill2.school": school})
        _, s = RESET(jax.random.key(3), p)
        rng = np.random.default_rng(3)
        actions = jnp.asarray(rng.integers(0, 10, (T_ROLL, 3)), jnp.int32).at[:, 1].set(ACTION_HEURISTIC)
        runs.append(jax.device_get(rollout(jax.random.key(4), s, p, actions)))
    for a, b in zip(jax.tree.leaves(runs[0]), jax.tree.leaves(runs[1]), strict=True):
        np.testing.assert_array_equal(a, b)
    assert float(runs[0][0].hp[3]) < 1000.0  # something happened


# --- bad input -----------------------------------------------------------------------------

@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(armor=101), ["armor", "101", "[0, 100]"]),
        (dict(armor=-1), ["armor", "-1", "[0, 100]"]),
        ({"skill1.range": 25.0}, ["range", "25", "[1, 20]"]),
        ({"skill1.cast_time": 2.5}, ["cast_time", "2.5", "[0, 2]"]),
        (dict(move_speed=float("nan")), ["move_speed", "nan", "[1, 2]"]),
        (dict(spell_power=float("inf")), ["spell_power", "inf", "[0, 100]"]),
        (dict(max_hp=50.5), ["max_hp", "50.5", "whole number"]),
        ({"skill1.charge": 1.5}, ["charge", "1.5", "whole number"]),
        ({"skill1.target_type": 3}, ["target_type", "3", "[0, 2]"]),
        (dict(boss_overrides={"max_hp": 20000}), ["max_hp", "20000", "[0, 10000]", "boss"]),
        (dict(player_overrides=[{}, {"haste": 150}, {}]), ["haste", "150", "[0, 100]"]),
        (dict(bogus=1), ["bogus", "unknown field"]),
        ({"skill1.bogus": 1}, ["skill1.bogus", "unknown field"]),
        ({"skill4.range": 5.0}, ["skill slot 4"]),
        (dict(players="paladin"), ["paladin", "unknown"]),
        (dict(boss="hydra"), ["hydra", "unknown"]),
        (dict(skill2="nope"), ["nope", "unknown"]),
        (dict(players=["mage"] * 9), ["players", "9"]),
        (dict(player_overrides=[{}]), ["player_overrides", "1"]),
        ({"skill1.in_use": 0}, ["in_use", "slot 1"]),
    ],
)
def test_make_params_rejects_bad_content(kwargs, words):
    with pytest.raises(ValueError) as err:
        raidjax.make_params(**kwargs)
    for w in words:
        assert w in str(err.value), (w, str(err.value))


def test_validate_params_rejects_hand_built_params(ref_params):
    p = ref_params
    cases = [
        (p.replace(stats=p.stats.replace(armor=jnp.zeros(3))), ["armor", "shape", "(4,)"]),
        (p.replace(skills=p.skills.replace(range=jnp.full((4, 2), 5.0))), ["range", "shape", "(4, 3)"]),
        (p.replace(stats=p.stats.replace(spell_power=p.stats.spell_power.at[1].set(jnp.nan))),
         ["spell_power", "nan"]),
        (p.replace(skills=p.skills.replace(cost=p.skills.cost.at[0, 0].set(101.0))), ["cost", "101", "[0, 100]"]),
        (p.replace(team=jnp.array([0, 1, 0, 1], jnp.int32)), ["team"]),
        (p.replace(team=jnp.array([1], jnp.int32)), ["team", "shape"]),
    ]
    for bad, words in cases:
        with pytest.raises(ValueError) as err:
            raidjax.validate_params(bad)
        for w in words:
            assert w in str(err.value), (w, str(err.value))
    # Batched params are checked element-wise too.
    batch = jax.tree.map(lambda *x: jnp.stack(x), p, cases[3][0])
    with pytest.raises(ValueError, match="cost"):
        raidjax.validate_params(batch)
    assert raidjax.validate_params(jax.tree.map(lambda *x: jnp.stack(x), p, p)) is not None


def test_ranges_are_the_spec_tables():
    # A few ranges from GAME.md §3 ("controllable parameters"), player side.
    want = {"max_hp": (0, 1000), "max_mana": (0, 100), "spell_power": (0, 100), "move_speed": (1, 2),
            "attack_power": (0, 100), "attack_range": (1, 10), "attack_speed": (1, 2), "armor": (0, 100),
            "evasion": (0, 100), "parry": (0, 100), "strength": (1, 100), "critical": (0, 100),
            "haste": (0, 100), "versatility": (0, 100), "mastery": (0, 100)}
    for k, r in want.items():
        assert tuple(STAT_SPECS[k][1]) == r, k
    want = {"school": (0, 9), "projectile_speed": (0, 50), "cool_time": (0, 60), "cast_time": (0, 2),
            "cost": (0, 100), "range": (1, 20), "charge": (1, 3), "coefficient": (0, 2)}
    for k, r in want.items():
        assert tuple(SKILL_SPECS[k][1]) == r, k


def test_broadcast_params_layouts_and_errors(ref_params):
    one = broadcast_params(ref_params, 6)
    assert one.team.shape == (6, 4)
    groups = jax.tree.map(lambda *x: jnp.stack(x), ref_params, raidjax.make_params(armor=7))
    b = broadcast_params(groups, 6)  # games 0-2 content 0, games 3-5 content 1
    assert np.asarray(b.stats.armor[:, 0]).tolist() == [0, 0, 0, 7, 7, 7]
    with pytest.raises(ValueError, match="multiple"):
        broadcast_params(groups, 5)
    with pytest.raises(ValueError, match="batch axes"):
        broadcast_params(jax.tree.map(lambda x: x[None], groups), 4)


def test_with_player_skill_edits_players_only_and_traces():
    base = raidjax.make_params()
    ranges = jnp.array([3.0, 11.0])
    batch = jax.jit(jax.vmap(lambda r: raidjax.with_player_skill(base, range=r, cast_time=1.0)))(ranges)
    assert batch.skills.range.shape == (2, 4, 3)
    assert batch.skills.range[:, :3, 0].tolist() == [[3.0] * 3, [11.0] * 3]
    assert batch.skills.cast_time[:, :3, 0].tolist() == [[1.0] * 3] * 2
    assert float(batch.skills.range[0, 3, 0]) == float(base.skills.range[3, 0])  # boss untouched
    assert batch.skills.range[:, :3, 1].tolist() == [base.skills.range[:3, 1].tolist()] * 2  # slot 2 untouched
    raidjax.validate_params(batch)  # the edited contents are valid
    with pytest.raises(ValueError, match="unknown skill field"):
        raidjax.with_player_skill(base, rnage=3.0)
    for slot in (3, -1, 1.0):  # slot 3 used to change nothing, silently
        with pytest.raises(ValueError, match=rf"^slot: value {slot!r} .*allowed: a whole number in \[0, 3\)"):
            raidjax.with_player_skill(base, slot, range=3.0)
    with pytest.raises(ValueError, match=r"^range: value of shape \[2\]; allowed: a scalar or one value per player"):
        raidjax.with_player_skill(base, range=jnp.ones(2))
    per_player = raidjax.with_player_skill(base, 2, range=jnp.array([4.0, 5.0, 6.0]))
    assert per_player.skills.range[:3, 2].tolist() == [4.0, 5.0, 6.0]
