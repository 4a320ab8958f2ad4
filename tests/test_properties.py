"""Property-based tests (hypothesis): random *valid* content never produces non-finite state,
observations or rewards, keeps the invariants of the game, and random *invalid* content is
always rejected with the field named. Shapes never change, so the shared ``rollout`` is
compiled once."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import ACTION_HEURISTIC, RESET, T_ROLL, rollout
from hypothesis import given
from hypothesis import strategies as st

import raidjax
from raidjax.content import SKILL_SPECS, STAT_SPECS

PLAYER, BOSS_SIDE = 1, 2  # column of the range in the spec tables


def value(kind, lo, hi):
    if kind in ("int", "bool"):
        return st.integers(int(np.ceil(lo)), int(np.floor(hi)))
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


def stats(side):
    return st.fixed_dictionaries({k: value(s[0], *s[side]) for k, s in STAT_SPECS.items()})


def skill(side, slot):
    fields = {f"skill{slot}.{k}": value(s[0], *s[side]) for k, s in SKILL_SPECS.items() if k != "in_use"}
    return st.fixed_dictionaries(fields)


content = st.fixed_dictionaries({
    "player": stats(PLAYER), "boss": stats(BOSS_SIDE),
    "skill1": skill(PLAYER, 1), "skill2": skill(PLAYER, 2), "use2": st.integers(0, 1),
    "boss_skill1": skill(BOSS_SIDE, 1), "boss_skill2": skill(BOSS_SIDE, 2),
    "seed": st.integers(0, 2**31 - 1),
})


@given(content)
def test_random_valid_content_stays_finite_and_consistent(c):
    player = {**c["player"], **c["skill1"], **c["skill2"], "skill2.in_use": c["use2"]}
    boss = {**c["boss"], **c["boss_skill1"], **c["boss_skill2"]}
    p = raidjax.make_params(player_overrides=[player] * 3, boss_overrides=boss)
    _, s = RESET(jax.random.key(c["seed"] % 1000), p)
    rng = np.random.default_rng(c["seed"])
    actions = rng.integers(0, 10, (T_ROLL, 3))
    actions[:, 0] = ACTION_HEURISTIC
    final, (rewards, done, result, finite) = rollout(jax.random.key(c["seed"]), s, p, jnp.asarray(actions, jnp.int32))
    assert bool(finite.all())
    f = jax.device_get(final)
    assert (np.abs(f.pos) <= 12.25 + 1e-4).all()
    assert (f.hp <= np.asarray(p.stats.max_hp) + 1e-3).all()
    assert (f.hp >= 0).all()  # HP floors at 0 on death
    assert (f.mana <= np.asarray(p.stats.max_mana) + 1e-3).all()
    assert (f.charges >= 0).all() and (f.charges <= np.asarray(p.skills.charge)).all()
    assert (np.asarray(rewards) >= 0).all()
    res = np.asarray(result)
    assert set(res.tolist()) <= {0, 1, 2}
    # Once done, always done, with the same result.
    d = np.asarray(done)
    if d.any():
        first = int(np.argmax(d))
        assert d[first:].all() and (res[first:] == res[first]).all()
    assert (f.alive[:3] <= (f.hp[:3] > 0)).all()


def out_of_range(kind, lo, hi):
    below = st.floats(-1e6, lo, exclude_max=True, allow_nan=False) if lo > -1e6 else st.nothing()
    above = st.floats(hi, 1e6, exclude_min=True, allow_nan=False)
    bad = st.one_of(below, above, st.just(float("nan")))
    if kind in ("int", "bool"):
        bad = st.one_of(bad, st.floats(lo, hi).filter(lambda v: v != round(v)))
    return bad


@pytest.mark.filterwarnings("ignore:invalid value encountered in cast:RuntimeWarning")
@pytest.mark.parametrize("table", ["stat", "skill"])
@given(data=st.data())
def test_any_invalid_value_is_rejected_naming_the_field(table, data):
    specs = STAT_SPECS if table == "stat" else SKILL_SPECS
    name = data.draw(st.sampled_from(sorted(specs)))
    kind, prange = specs[name][0], specs[name][1]
    v = data.draw(out_of_range(kind, *prange))
    key = name if table == "stat" else f"skill1.{name}"
    with pytest.raises(ValueError) as err:
        raidjax.make_params(**{key: v})
    assert name in str(err.value) and str(prange[0]) in str(err.value)
