"""Bad input is refused on the host before anything compiles, in one line naming the field, the
value and what is allowed (issue 18, defects 6-8), and what raidjax promises about determinism
(defect 10, docs/GAME.md §1 "Determinism").

Every error test checks the type (``ValueError``), that the message is one line, and that it
starts with the field and the bad value. The playtest checks use a policy that fails the test if
it is ever traced, so they also show that nothing was traced or compiled.
"""

from __future__ import annotations

import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import CLEAN1, RESET, STEP

import raidjax
from raidjax import EnvConfig, make_params, policies
from raidjax.playtest import broadcast_params

REF = make_params()


def raises_line(fn, starts: str, *also: str) -> str:
    """Call ``fn``; it must raise a one-line ``ValueError`` starting with ``starts`` and containing ``also``."""
    with pytest.raises(ValueError) as err:
        fn()
    msg = str(err.value)
    assert "\n" not in msg, msg
    assert re.match(re.escape(starts), msg), f"{msg!r} does not start with {starts!r}"
    for part in also:
        assert part in msg, f"{part!r} not in {msg!r}"
    return msg


# ---- defect 6: EnvConfig is validated on construction ----------------------------------------

BAD_CONFIG = [
    ("n_substeps", 0, "allowed: 1 or 5"),
    ("n_substeps", 2, "allowed: 1 or 5"),
    ("n_substeps", 5.0, "is a float"),
    ("max_decisions", -1, "whole number >= 1"),
    ("max_decisions", 0, "whole number >= 1"),
    ("max_decisions", 2.5, "is a float"),
    ("max_decisions", "200", "is a str"),
    ("max_decisions", True, "is a bool"),
    ("max_projectiles", 0, "whole number >= 1"),
    ("obs_projectiles", 0, "whole number >= 1"),
    ("obs_projectiles", 17, "exceeds max_projectiles 16"),
    ("carry_cooldowns", 1, "allowed: True or False"),
    ("unity_timers", "yes", "is a str"),
]
BUILDERS = {
    "EnvConfig": lambda kw: EnvConfig(**kw),
    "replace": lambda kw: EnvConfig().replace(**kw),
    "from_rules": lambda kw: EnvConfig.from_rules("clean", **kw),
}


@pytest.mark.parametrize("build", list(BUILDERS))
@pytest.mark.parametrize("field,value,allowed", BAD_CONFIG)
def test_env_config_rejects_bad_fields_when_built(build, field, value, allowed):
    raises_line(lambda: BUILDERS[build]({field: value}), f"{field}: value {value!r}", allowed)


def test_removed_or_unknown_config_field_is_named():
    # hurtbox_scale no longer exists (bodies are the `radius` stat, GAME.md §2 "Geometry").
    for build in BUILDERS.values():
        raises_line(lambda b=build: b({"hurtbox_scale": float("nan")}), "EnvConfig: unknown field 'hurtbox_scale'",
                    "n_substeps")
    raises_line(lambda: make_params(hurtbox_scale=float("nan")), "make_params: unknown field 'hurtbox_scale'")
    raises_line(lambda: make_params(n_substeps=1), "make_params: unknown field 'n_substeps'", "EnvConfig field")


@pytest.mark.parametrize("config", ["fast", 0, False, {"n_substeps": 1}])
def test_make_params_config_must_be_an_env_config(config):
    raises_line(lambda: make_params(config=config), f"config: value {config!r} is a", "allowed: None or an EnvConfig")


@pytest.mark.parametrize("rules", [3, ["clean"], "dirty"])
def test_rules_must_name_a_rule_set(rules):
    raises_line(lambda: make_params(rules=rules), f"rules: value {rules!r} is", "['clean', 'reference']")


def test_params_built_by_hand_reject_a_non_config():
    raises_line(lambda: REF.replace(config="fast"), "config: value 'fast' is a str", "EnvConfig")
    raises_line(lambda: raidjax.Params(REF.stats, REF.skills, REF.team, config=None), "config: value None")


def test_env_config_stays_static_hashable_and_takes_numpy_scalars():
    cfg = EnvConfig(n_substeps=np.int64(1), max_decisions=np.int32(40), unity_timers=np.bool_(False))
    same = EnvConfig(n_substeps=1, max_decisions=40, unity_timers=False)
    assert cfg == same and hash(cfg) == hash(same)
    assert type(cfg.n_substeps) is int and type(cfg.unity_timers) is bool
    assert jax.tree.leaves(cfg) == []  # no leaves: tree maps never rebuild it from placeholders
    params = make_params(config=cfg)
    assert jax.tree.map(lambda x: x, params).config is cfg
    assert jax.vmap(lambda p: p.stats.armor.sum())(jax.tree.map(lambda x: x[None], params)).shape == (1,)


# ---- defect 7: no silent coercion of Python types --------------------------------------------

BAD_CONTENT = [
    (dict(skill_range="13"), "skill_range: value '13' is a str; allowed: a number in [1, 20]"),
    (dict(skill_range=[13]), "skill_range: value [13] is a list of length 1"),
    (dict(skill_range=np.array([13.0])), "skill_range: value array([13.]) is an array of shape (1,)"),
    (dict(skill_range=None, armor="50"), "armor: value '50' is a str; allowed: a whole number in [0, 100]"),
    (dict(armor=True), "armor: value True is a bool; allowed: a whole number in [0, 100]"),
    (dict(armor=None), "armor: value None; allowed: a whole number in [0, 100]"),
    (dict(armor=1 + 2j), "armor: value (1+2j) is a complex"),
    (dict(armor=np.ones(3)), "armor: value array([1., 1., 1.]) is an array of shape (3,)"),
    ({"skill1.cool_time": "1"}, "skill1.cool_time: value '1' is a str; allowed: a number in [0, 60]"),
    (dict(skill2=3), "skill2: value 3 is an int; allowed: a skill preset"),
    (dict(skill2="lazer"), "skill2: value 'lazer' is an unknown skill preset"),
    (dict(players=5), "players: value 5 is an int; allowed: a class preset name or a list"),
    (dict(players=["mage", 3]), "players[1]: value 3 is an int"),
    (dict(players=[]), "players: value [] is 0 players; allowed"),
    (dict(players="wizard"), "players: value 'wizard' is an unknown class preset"),
    (dict(boss=3), "boss: value 3 is an int; allowed: a boss preset"),
    (dict(boss="hydra"), "boss: value 'hydra' is an unknown boss preset; allowed: a boss preset, one of"),
    (dict(boss_overrides="armor"), "boss_overrides: value 'armor' is a str; allowed: None or a mapping"),
    (dict(boss_overrides={"armor": "5"}), "armor: value '5' is a str in boss_overrides"),
    (dict(boss_overrides={1: 5}), "boss_overrides: key: value 1 is an int"),
    (dict(player_overrides={"armor": 1}), "player_overrides: value {'armor': 1} is a dict"),
    (dict(player_overrides=[{}, {}]), "player_overrides: value [{}, {}] is 2 mappings; allowed: None or a list of 3"),
    (dict(player_overrides=[1, 2, 3]), "player_overrides[0]: value 1 is an int; allowed: a mapping"),
    (dict(player_overrides=[{}, {}, {"armor": "x"}]), "armor: value 'x' is a str in player_overrides[2]"),
]


@pytest.mark.parametrize("kwargs,starts", BAD_CONTENT, ids=[s.split(":")[0] for _, s in BAD_CONTENT])
def test_make_params_refuses_wrong_python_types(kwargs, starts):
    raises_line(lambda: make_params(**kwargs), starts)


def test_make_params_accepts_real_numbers_of_any_kind():
    for armor in (50, 50.0, np.int64(50), np.float32(50), np.array(50.0), jnp.int32(50)):
        assert np.asarray(make_params(armor=armor).stats.armor).tolist() == [50, 50, 50, 0], repr(armor)
    flags = make_params(**{"skill1.cast_on_moving": False}).skills.cast_on_moving  # 0/1 fields take bools
    assert np.asarray(flags)[:3, 0].tolist() == [0, 0, 0]
    assert float(make_params(skill_range=np.float64(13)).skills.range[0, 0]) == 13.0
    raises_line(lambda: make_params(armor=float("nan")), "armor: value nan at a player is not finite")
    raises_line(lambda: make_params(max_hp=-(10**400)), "max_hp: value -inf at a player is not finite")


# ---- defect 8: n_games (and the other playtest arguments) checked before tracing ------------

def never_traced(key, obs, state, params):
    raise AssertionError("the policy was traced: validation must come first")


BAD_N_GAMES = [0, -1, 2.5, "3", True, None, np.float64(2.0), [2]]


@pytest.mark.parametrize("n_games", BAD_N_GAMES, ids=repr)
def test_playtest_functions_refuse_bad_n_games(n_games):
    key = jax.random.key(0)
    calls = {
        "playtest": lambda: raidjax.playtest(key, REF, never_traced, n_games),
        "playtest_occupancy": lambda: raidjax.playtest_occupancy(key, REF, never_traced, n_games),
        "broadcast_params": lambda: broadcast_params(REF, n_games),
    }
    start = "n_games: value None" if n_games is None else f"n_games: value {n_games!r}"
    for call in calls.values():
        raises_line(call, start, "allowed: a whole number >= 1")


def test_playtest_refuses_bad_params_policy_and_bins():
    key = jax.random.key(0)
    raises_line(lambda: raidjax.playtest(key, "p", never_traced, 2), "params: value 'p' is a str")
    raises_line(lambda: raidjax.playtest(key, REF, [never_traced], 2), "policy: value [", "unhashable")
    raises_line(lambda: raidjax.playtest(key, REF, "heuristic", 2), "policy: value 'heuristic' is a str")
    batch = jax.tree.map(lambda x: jnp.stack([x, x]), REF)
    raises_line(lambda: raidjax.playtest(key, batch, never_traced, 3), "n_games: value 3 is not a multiple of the 2")
    for bins in (0, 2.5):
        raises_line(lambda b=bins: raidjax.playtest_occupancy(key, REF, never_traced, 2, bins=b),
                    f"bins: value {bins!r}")


def test_the_game_calls_refuse_a_batch_of_params_naming_it():
    # One arena's calls given a batch (forgot the vmap): one line naming params, before compiling;
    # under jax.vmap the same calls see one arena and play.
    key = jax.random.key(0)
    obs, state = RESET(key, REF)
    batch = jax.tree.map(lambda x: jnp.stack([x, x]), REF)
    actions = jnp.zeros(3, jnp.int32)
    calls = [("reset", lambda: raidjax.reset(key, batch)),
             ("step", lambda: raidjax.step(key, state, actions, batch)),
             ("step", lambda: raidjax.step_autoreset(key, state, actions, batch)),
             ("reset", lambda: raidjax.next_episode(key, state, batch)),
             ("observe", lambda: raidjax.observe(state, batch)),
             ("action_mask", lambda: raidjax.action_mask(state, batch)),
             ("spaces", lambda: raidjax.spaces(batch))]
    for name, call in calls:
        raises_line(call, "params: team of shape [2, 4]", f"in {name}:", f"jax.vmap({name})")
    assert jax.eval_shape(jax.vmap(raidjax.reset), jax.random.split(key, 2), batch)[0].alive.shape == (2, 3)


def test_win_rate_refuses_empty_results():
    empty = {"outcome": jnp.zeros((0,), jnp.int32)}
    raises_line(lambda: raidjax.win_rate(empty), "results['outcome']: value of shape (0,)", "n_games >= 1")
    raises_line(lambda: raidjax.win_rate([1, 2]), "results: value [1, 2] is a list")


TRACES: list[int] = []


def counting_heuristic(key, obs, state, params):
    TRACES.append(1)
    return policies.heuristic(key, obs, state, params)


def test_validated_playtest_compiles_once_per_n_games():
    params = make_params(config=CLEAN1.replace(max_decisions=3))
    key = jax.random.key(5)
    first = raidjax.playtest(key, params, counting_heuristic, 2)
    traced = len(TRACES)
    assert traced > 0 and first["outcome"].shape == (2,)
    again = raidjax.playtest(key, params, counting_heuristic, 2)
    numpy_n = raidjax.playtest(key, params, counting_heuristic, np.int64(2))  # same program as 2
    assert len(TRACES) == traced  # no retrace
    for r in (again, numpy_n):
        jax.tree.map(np.testing.assert_array_equal, first, r)


# ---- defect 10: determinism (docs/GAME.md §1 "Determinism") --------------------------------

# Skill range 20: the players spawn in range and PT-HR only eases outwards, so no unit sits on a
# range threshold in these 20 decisions, where a rounding difference could flip a cast.
DET_PARAMS = make_params(config=CLEAN1, skill_range=20.0)
DET_STEPS = 20


def play(reset, step, params=DET_PARAMS, n=DET_STEPS):
    """``n`` decisions of PT-HR; a list of host copies of ``(state, reward)``, the reset first."""
    obs, state = reset(jax.random.key(0), params)
    out = [(jax.device_get(state), np.zeros(3, np.float32))]
    for t in range(n):
        actions = policies.heuristic(None, obs, state, params)
        obs, state, reward, _, _ = step(jax.random.fold_in(jax.random.key(1), t), state, actions, params)
        out.append(jax.device_get((state, reward)))
    return out


def test_same_program_same_key_is_bit_identical():
    first, again = play(RESET, STEP), play(RESET, STEP)
    for (s1, r1), (s2, r2) in zip(first, again, strict=True):
        jax.tree.map(np.testing.assert_array_equal, (s1, r1), (s2, r2))
    final = first[-1][0]
    assert float(final.hp[3]) < 1000 and float(final.hp[:3].min()) < 100  # both sides were hit
