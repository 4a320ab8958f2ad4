"""Tests of the content generator's style goal (``raidjax.pcg.PCGParams.goal_axis``, GAME.md §10):
goals at the two ends of a design axis, observed, kept through an episode and renewed with it,
and the learner's goal cost (``trainers.ppo_pcgrl.PPOConfig.goal_cost``)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import pcg_state as _state

import raidjax
from raidjax import pcg


def test_goal_observed_kept_through_edits_and_renewed_with_the_episode():
    on, off = pcg.make_pcg_params(n_games=2, goal_axis=(1, 0, -1, 1)), pcg.make_pcg_params(n_games=2)
    keys = jax.random.split(jax.random.key(0), 9)
    o, st = pcg.reset(keys[0], on)
    o_off, st_off = pcg.reset(keys[0], off)
    np.testing.assert_array_equal(np.asarray(st.skill), np.asarray(st_off.skill))  # same skills and targets
    np.testing.assert_array_equal(np.asarray(st_off.goal), np.asarray(st_off.skill))  # off: the start
    assert o.shape == (pcg.env.obs_size(on),) == (10,) and o_off.shape == (6,)
    span = np.asarray(pcg.PAPER_SPACE.high) - np.asarray(pcg.PAPER_SPACE.low)
    np.testing.assert_allclose(np.asarray(o[-4:]), (np.asarray(st.goal) - np.asarray(st.skill)) / span, atol=1e-6)
    _, st1, _, _, _ = pcg.step(jax.random.key(1), st, jnp.full(4, 4, jnp.int32), on)
    np.testing.assert_array_equal(np.asarray(st1.goal), np.asarray(st.goal))  # kept through edits
    fresh = [pcg.step_autoreset(k, st1.replace(done=jnp.bool_(True)), jnp.full(4, 2, jnp.int32), on)[1].goal
             for k in keys[1:]]
    assert any(not np.array_equal(np.asarray(g), np.asarray(st.goal)) for g in fresh)  # a new episode draws anew


def test_goal_penalty_telescopes_to_the_change_of_distance_to_the_goal():
    from trainers.config import PPOConfig
    from trainers.ppo_pcgrl import edit_penalty

    cfg = PPOConfig(goal_cost=0.5, goal_axis=(1, 1, 1, 1))
    # range, cast, coefficient high; cool low
    goal = jnp.asarray(pcg.PAPER_SPACE.high, jnp.float32).at[1].set(pcg.PAPER_SPACE.low[1])
    st = _state(skill=(10.5, 0.55, 1.0, 0.75)).replace(goal=goal)
    start_d2 = float(pcg.goals.squared_ticks(st.skill, goal))
    total = 0.0
    for a in ([4, 0, 4, 4], [3, 2, 2, 0], [0, 4, 2, 2]):  # toward, partly back, away
        a = jnp.asarray(a, jnp.int32)
        new = st.replace(skill=pcg.env.apply_action(st.skill, a))
        step_cost = float(edit_penalty(cfg, a, st, new))
        if a[0] == 4:  # every parameter moved a tick toward its goal: the step pays (a reward)
            assert step_cost < 0
        total += step_cost
        st = new
    assert total == pytest.approx(0.5 * (float(pcg.goals.squared_ticks(st.skill, goal)) - start_d2), rel=1e-4)
    # by hand: the goal is 3 ticks from the start in every parameter (range 9.5 / (19/6), cool 0.05 /
    # (0.1/6), cast 0.5 / (1/6), coefficient 0.25 / (0.5/6)), so d^2 = 4 * 9 = 36 at the start.
    assert start_d2 == pytest.approx(36.0, rel=1e-4)


def test_goal_axis_draws_the_two_ends_and_leaves_unsigned_parameters_free():
    keys = jax.random.split(jax.random.key(3), 400)

    def short(p):  # the goal has its own key stream (below): the 400 first measurements may be 8-decision draws
        return p.replace(game=p.game.replace(config=raidjax.EnvConfig.from_rules("clean", max_decisions=8)))

    def goals(axis):
        p = short(pcg.make_pcg_params(n_games=2, goal_axis=axis))
        high = np.asarray(pcg.PAPER_SPACE.high, np.float32)
        return np.asarray(jax.vmap(lambda k: pcg.reset(k, p)[1].goal)(keys)) == high

    heavy = goals((1, 1, 1, 1))
    assert (heavy.all(1) | (~heavy).all(1)).all()  # all high ("heavy") or all low ("light")
    assert abs(heavy[:, 0].mean() - 0.5) < 0.08
    mixed = goals((1, 0, -1, 1))
    assert (mixed[:, 0] == mixed[:, 3]).all() and (mixed[:, 0] != mixed[:, 2]).all()  # tied ends, -1 reversed
    for end in (True, False):  # cool time (sign 0) keeps its own coin at either end
        assert 0.35 < mixed[mixed[:, 0] == end, 1].mean() < 0.65
    on = pcg.make_pcg_params(n_games=2, goal_axis=(1, 1, 1, 1))
    st, st_off = pcg.reset(keys[0], on)[1], pcg.reset(keys[0], pcg.make_pcg_params(n_games=2))[1]
    np.testing.assert_array_equal(np.asarray(st.skill), np.asarray(st_off.skill))  # own key stream
    np.testing.assert_array_equal(np.asarray(st.win_rate), np.asarray(st_off.win_rate))


@pytest.mark.parametrize("axis", [(1, 2, 1, 1), (1, 1, 1), ("a", 1, 1, 1)])
def test_goal_axis_rejects_bad_values_naming_the_field(axis):
    with pytest.raises(ValueError, match=r"goal_axis: value .* must be 4 signs"):
        pcg.make_pcg_params(goal_axis=axis)


def test_goal_axis_in_the_learner_config_and_on_the_command_line():
    from trainers.config import PPOConfig
    from trainers.ppo_pcgrl import env_params
    from trainers.ppo_pcgrl_cli import _args

    cfg = PPOConfig(goal_cost=0.5, goal_axis=[1, 0, -1, 1])  # as read back from JSON
    assert cfg.goal_axis == (1, 0, -1, 1)
    p = env_params(cfg)
    assert p.goal_axis == (1, 0, -1, 1)
    goal = jax.jit(lambda k: pcg.reset(k, p)[1].goal)(jax.random.key(0))  # hashable static field
    assert goal.shape == (4,)
    for bad in ({"goal_axis": (1, 1, 1, 1)}, {"goal_cost": 0.5}):  # a style goal needs both
        with pytest.raises(ValueError, match="a style goal needs both"):
            PPOConfig(**bad)
    assert pcg.goals.parse_axis("1,1,-1,0") == (1, 1, -1, 0)
    assert _args(["--goal-cost", "1", "--goal-axis", "1,1,-1,0"]).goal_axis == (1, 1, -1, 0)
    for bad in ("2,0,0,0", "a,b,c,d"):
        with pytest.raises(SystemExit):
            _args(["--goal-axis", bad])
    # how many signs is the edited space's: two for a two-parameter space, four for the paper's
    assert _args(["--goal-axis", "1,-1"]).goal_axis == (1, -1)
    two = ["skill1.range", "skill1.cool_time"]
    assert PPOConfig(goal_cost=0.5, goal_axis=(1, -1), parameters=two).goal_axis == (1, -1)
    with pytest.raises(ValueError, match=r"goal_axis: value \(1, 1, 1\) must be 4 signs"):
        PPOConfig(goal_cost=0.5, goal_axis=(1, 1, 1))
