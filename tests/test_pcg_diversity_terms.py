"""Tests of the opt-in diversity terms of content generation (beyond SPEC §10): the start-skill
displacement, edit preferences, the favourite lever, the per-step designated lever, and the PPO
generator's sampling temperature and one-lever policy; the style goal and its axis."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import pcg_state as _state

from raidjax import pcg


def test_start_skill_displacement_and_its_observation():
    p = pcg.make_params(n_games=2, max_edits=2, observe_start=True)
    _, st = pcg.reset(jax.random.key(0), p)
    start = np.asarray(st.skill)
    np.testing.assert_array_equal(np.asarray(st.start), start)
    act = jnp.asarray([4, 0, 2, 3], jnp.int32)  # +1, -1, 0, +1/2 ticks
    o, st1, _, _, _ = pcg.step(jax.random.key(1), st, act, p)
    np.testing.assert_array_equal(np.asarray(st1.start), start)  # the start stays through edits
    moved = (np.asarray(st1.skill) - start) / np.asarray(pcg.tick())  # clipping may shorten a move
    assert o.shape == (pcg.obs_size(p),) == (10,)
    np.testing.assert_allclose(np.asarray(o[-4:]), moved / 6.0, atol=1e-5)  # a tick is 1/6 of the range
    assert float(pcg.displacement(st1.skill, st1.start)) == pytest.approx(float((moved ** 2).sum()), rel=1e-5)
    assert float(pcg.displacement(jnp.asarray(pcg.LOW) + pcg.tick() * jnp.asarray([2.0, 0, 0, 1]),
                                  jnp.asarray(pcg.LOW))) == pytest.approx(5.0, rel=1e-5)  # 2^2 + 1^2 ticks^2
    ended = st1.replace(done=jnp.bool_(True))
    _, fresh, _, _, info = pcg.step_autoreset(jax.random.key(2), ended, act, p)
    assert not bool(info["valid"])
    np.testing.assert_array_equal(np.asarray(fresh.start), np.asarray(fresh.skill))  # a reset starts anew


def test_edit_penalty_telescopes_to_final_displacement():
    from trainers.ppo_pcgrl import Config, edit_penalty

    cfg = Config(edit_cost=0.5, anchor_cost=2.0)
    st = _state(skill=(10.0, 0.55, 1.0, 0.75))
    total, ticks = 0.0, 0.0
    for a in ([4, 2, 2, 2], [4, 1, 2, 2], [0, 2, 3, 2], [2, 2, 2, 2]):  # out, out, back: oscillation is free
        a = jnp.asarray(a, jnp.int32)
        new = st.replace(skill=pcg.apply_action(st.skill, a))
        total += float(edit_penalty(cfg, a, st, new))
        ticks += float(np.abs(np.asarray(pcg.TICK_FRACTIONS)[np.asarray(a)]).sum())
        st = new
    final = float(pcg.displacement(st.skill, st.start))
    assert final == pytest.approx(1.0 + 0.25 + 0.25, rel=1e-4)  # range +1 tick, cool -1/2, cast +1/2
    assert total == pytest.approx(0.5 * ticks + 2.0 * final, rel=1e-4)


def test_edit_preferences_drawn_observed_and_renewed():
    on, off = pcg.make_params(n_games=2, edit_preferences=True), pcg.make_params(n_games=2)
    o, st = pcg.reset(jax.random.key(3), on)
    _, st_off = pcg.reset(jax.random.key(3), off)
    prefs = np.asarray(st.preferences)
    assert (prefs > 0).all() and prefs.sum() == pytest.approx(4.0, rel=1e-5) and prefs.std() > 0.05
    np.testing.assert_array_equal(np.asarray(st_off.preferences), np.ones(4))  # off: all ones
    np.testing.assert_array_equal(np.asarray(st.skill), np.asarray(st_off.skill))  # same skills and targets
    assert float(st.target) == float(st_off.target)
    assert o.shape == (pcg.obs_size(on),) == (10,) and pcg.obs_size(off) == 6
    np.testing.assert_allclose(np.asarray(o[-4:]), prefs / 4, rtol=1e-6)
    _, st1, _, _, _ = pcg.step(jax.random.key(4), st, jnp.full(4, 4, jnp.int32), on)
    np.testing.assert_array_equal(np.asarray(st1.preferences), prefs)  # kept through edits
    _, fresh, _, _, _ = pcg.step_autoreset(jax.random.key(5), st1.replace(done=jnp.bool_(True)),
                                           jnp.full(4, 4, jnp.int32), on)
    assert not np.allclose(np.asarray(fresh.preferences), prefs)  # a new episode draws new ones


def test_favourite_preferences_one_cheap_parameter_uniformly_drawn():
    on = pcg.make_params(n_games=2, edit_preferences=True, favourite_weight=0.25)
    soft = pcg.make_params(n_games=2, edit_preferences=True)
    keys = jax.random.split(jax.random.key(0), 400)
    prefs = np.asarray(jax.vmap(lambda k: pcg.reset(k, on)[1].preferences)(keys))
    cheap = prefs.argmin(1)
    np.testing.assert_allclose(np.sort(prefs, 1), np.broadcast_to([0.25, 1.25, 1.25, 1.25], prefs.shape), rtol=1e-6)
    counts = np.bincount(cheap, minlength=4)
    assert counts.min() > 70  # each parameter is the favourite about 100 times in 400
    o, st = pcg.reset(keys[0], on)
    _, st_soft = pcg.reset(keys[0], soft)  # the same skill and target as the softmax draw
    np.testing.assert_array_equal(np.asarray(st.skill), np.asarray(st_soft.skill))
    np.testing.assert_allclose(np.asarray(o[-4:]), prefs[0] / 4, rtol=1e-6)


@pytest.mark.parametrize("kwargs,match", [({"favourite_weight": 1.5, "edit_preferences": True}, r"\[0, 1\]"),
                                          ({"favourite_weight": 0.2}, "needs edit_preferences")])
def test_favourite_weight_rejected_when_out_of_range_or_alone(kwargs, match):
    with pytest.raises(ValueError, match=f"favourite_weight: value {kwargs['favourite_weight']}.*{match}"):
        pcg.make_params(**kwargs)


def test_edit_penalty_weights_ticks_by_preferences():
    from trainers.ppo_pcgrl import Config, edit_penalty

    st = _state().replace(preferences=jnp.asarray([2.0, 1.0, 0.5, 0.5]))
    a = jnp.asarray([4, 1, 2, 0], jnp.int32)  # +1, -1/2, 0, -1 ticks
    new = st.replace(skill=pcg.apply_action(st.skill, a))
    assert float(edit_penalty(Config(edit_cost=3.0), a, st, new)) == pytest.approx(3.0 * (2.0 + 0.5 + 0.5))


def test_policy_temperature_interpolates_between_argmax_and_uniform():
    from trainers.ppo_pcgrl import ActorCritic, make_policy

    params = pcg.make_params(n_games=2)
    obs = pcg.observe(_state(), params)
    net = ActorCritic((8,)).init(jax.random.key(0), obs)
    net = jax.tree.map(lambda x: 3.0 * x, net)  # sharper logits than at init
    logits, _ = ActorCritic((8,)).apply(net, obs)
    keys = jax.random.split(jax.random.key(1), 4000)

    def sample(**kw):
        pol = make_policy((8,), **kw)
        return np.asarray(jax.vmap(lambda k: pol(net, k, obs, None, params))(keys))

    greedy = np.asarray(jnp.argmax(logits, -1))
    np.testing.assert_array_equal(sample(greedy=True)[0], greedy)
    top2 = np.sort(np.asarray(logits), -1)[:, -2:]
    cold = float((top2[:, 1] - top2[:, 0]).min()) / 30  # the best choice is e^30 times likelier
    assert (sample(temperature=cold) == greedy).all()  # T -> 0: argmax
    hot = sample(temperature=1e3)  # T -> inf: uniform over the 5 choices of each branch
    freq = np.stack([np.bincount(hot[:, b], minlength=5) for b in range(4)]) / len(keys)
    np.testing.assert_allclose(freq, 0.2, atol=0.03)
    base = sample()  # T = 1 samples softmax(logits)
    freq1 = np.bincount(base[:, 0], minlength=5) / len(keys)
    np.testing.assert_allclose(freq1, np.asarray(jax.nn.softmax(logits[0])), atol=0.03)
    with pytest.raises(ValueError, match="temperature: value 0"):
        make_policy((8,), temperature=0.0)


def test_lever_drawn_uniformly_observed_and_leaves_the_game_unchanged():
    on, off = pcg.make_params(n_games=4, observe_lever=True), pcg.make_params(n_games=4)
    keys = jax.random.split(jax.random.key(0), 400)
    levers = np.asarray(jax.vmap(lambda k: pcg.reset(k, on)[1].lever)(keys))
    assert np.bincount(levers, minlength=4).min() > 70  # each parameter about 100 times in 400
    o, st = pcg.reset(keys[0], on)
    o_off, st_off = pcg.reset(keys[0], off)
    assert o.shape == (pcg.obs_size(on),) == (10,) and pcg.obs_size(off) == 6
    np.testing.assert_array_equal(np.asarray(o[-4:]), np.eye(4)[int(st.lever)])
    np.testing.assert_array_equal(np.asarray(o[:6]), np.asarray(o_off))  # same skill, target, measurement
    a = jnp.asarray([4, 0, 2, 3], jnp.int32)
    for fn in (pcg.step, pcg.step_autoreset):  # the environment does not enforce the lever
        _, s1, r1, _, _ = fn(jax.random.key(3), st, a, on)
        _, s0, r0, _, _ = fn(jax.random.key(3), st_off, a, off)
        np.testing.assert_array_equal(np.asarray(s1.skill), np.asarray(s0.skill))
        assert float(s1.win_rate) == float(s0.win_rate) and float(r1) == float(r0)
    # a new lever after every edit, drawn from the step's key
    nxt = np.asarray(jax.vmap(lambda k: pcg.step(k, st, a, on)[1].lever)(keys[:200]))
    assert len(set(nxt.tolist())) == 4


def test_one_lever_policy_decides_and_is_scored_on_the_lever_only():
    from trainers.ppo_pcgrl import ActorCritic, _logp_entropy, branch_mask, make_policy, masked_action

    params = pcg.make_params(n_games=2, observe_lever=True)
    st = _state().replace(lever=jnp.int32(2))
    obs = pcg.observe(st, params)
    net = ActorCritic((8,)).init(jax.random.key(0), obs)
    net = jax.tree.map(lambda x: 3.0 * x, net)
    pol = make_policy((8,), one_lever=True)
    acts = np.asarray(jax.vmap(lambda k: pol(net, k, obs, st, params))(jax.random.split(jax.random.key(1), 500)))
    assert (acts[:, [0, 1, 3]] == pcg.NOOP_ACTION).all() and len(set(acts[:, 2].tolist())) > 1
    mask = branch_mask(True, st)
    np.testing.assert_array_equal(np.asarray(mask), [0, 0, 1, 0])
    np.testing.assert_array_equal(np.asarray(masked_action(jnp.asarray([0, 4, 1, 3]), mask)), [2, 2, 1, 2])
    logits, _ = ActorCritic((8,)).apply(net, obs)
    lp = jax.nn.log_softmax(logits)
    logp, ent = _logp_entropy(logits, jnp.asarray([0, 4, 1, 3]), mask)
    assert float(logp) == pytest.approx(float(lp[2, 1]), rel=1e-6)  # other branches leave the ratio alone
    assert float(ent) == pytest.approx(float(-(jnp.exp(lp[2]) * lp[2]).sum()), rel=1e-6)
    full, _ = _logp_entropy(logits, jnp.asarray([0, 4, 1, 3]), branch_mask(False, st))
    assert float(full) == pytest.approx(float(lp[0, 0] + lp[1, 4] + lp[2, 1] + lp[3, 3]), rel=1e-6)


def test_goal_is_a_uniform_corner_observed_kept_and_renewed():
    on, off = pcg.make_params(n_games=2, observe_goal=True), pcg.make_params(n_games=2)
    keys = jax.random.split(jax.random.key(0), 400)
    goals = np.asarray(jax.vmap(lambda k: pcg.reset(k, on)[1].goal)(keys))
    high = goals == np.asarray(pcg.HIGH, np.float32)
    assert (high | (goals == np.asarray(pcg.LOW, np.float32))).all()  # corners of the box
    corner = high @ (2 ** np.arange(4))
    assert np.bincount(corner, minlength=16).min() > 10  # all 16 corners, about 25 times each
    assert abs(high.mean() - 0.5) < 0.05
    o, st = pcg.reset(keys[0], on)
    o_off, st_off = pcg.reset(keys[0], off)
    np.testing.assert_array_equal(np.asarray(st.skill), np.asarray(st_off.skill))  # same skills and targets
    np.testing.assert_array_equal(np.asarray(st_off.goal), np.asarray(st_off.skill))  # off: the start
    assert o.shape == (pcg.obs_size(on),) == (10,)
    span = np.asarray(pcg.HIGH) - np.asarray(pcg.LOW)
    np.testing.assert_allclose(np.asarray(o[-4:]), (goals[0] - np.asarray(st.skill)) / span, atol=1e-6)
    _, st1, _, _, _ = pcg.step(jax.random.key(1), st, jnp.full(4, 4, jnp.int32), on)
    np.testing.assert_array_equal(np.asarray(st1.goal), goals[0])  # kept through edits
    fresh = [pcg.step_autoreset(k, st1.replace(done=jnp.bool_(True)), jnp.full(4, 2, jnp.int32), on)[1].goal
             for k in keys[1:9]]
    assert any(not np.array_equal(np.asarray(g), goals[0]) for g in fresh)  # a new episode draws anew


def test_goal_penalty_telescopes_to_the_change_of_distance_to_the_goal():
    from trainers.ppo_pcgrl import Config, edit_penalty

    cfg = Config(goal_cost=0.5)
    goal = jnp.asarray(pcg.HIGH, jnp.float32).at[1].set(pcg.LOW[1])  # range, cast, coefficient high; cool low
    st = _state(skill=(10.5, 0.55, 1.0, 0.75)).replace(goal=goal)
    start_d2 = float(pcg.displacement(st.skill, goal))
    total = 0.0
    for a in ([4, 0, 4, 4], [3, 2, 2, 0], [0, 4, 2, 2]):  # toward, partly back, away
        a = jnp.asarray(a, jnp.int32)
        new = st.replace(skill=pcg.apply_action(st.skill, a))
        step_cost = float(edit_penalty(cfg, a, st, new))
        if a[0] == 4:  # every parameter moved a tick toward its goal: the step pays (a reward)
            assert step_cost < 0
        total += step_cost
        st = new
    assert total == pytest.approx(0.5 * (float(pcg.displacement(st.skill, goal)) - start_d2), rel=1e-4)
    # by hand: the goal is 3 ticks from the start in every parameter (range 9.5 / (19/6), cool 0.05 /
    # (0.1/6), cast 0.5 / (1/6), coefficient 0.25 / (0.5/6)), so d^2 = 4 * 9 = 36 at the start.
    assert start_d2 == pytest.approx(36.0, rel=1e-4)


def test_goal_axis_draws_the_two_ends_and_leaves_unsigned_parameters_free():
    keys = jax.random.split(jax.random.key(3), 400)

    def goals(axis):
        p = pcg.make_params(n_games=2, observe_goal=True, goal_axis=axis)
        return np.asarray(jax.vmap(lambda k: pcg.reset(k, p)[1].goal)(keys)) == np.asarray(pcg.HIGH, np.float32)

    heavy = goals((1, 1, 1, 1))
    assert (heavy.all(1) | (~heavy).all(1)).all()  # all high ("heavy") or all low ("light")
    assert abs(heavy[:, 0].mean() - 0.5) < 0.08
    mixed = goals((1, 0, -1, 1))
    assert (mixed[:, 0] == mixed[:, 3]).all() and (mixed[:, 0] != mixed[:, 2]).all()  # tied ends, -1 reversed
    for end in (True, False):  # cool time (sign 0) keeps its own coin at either end
        assert 0.35 < mixed[mixed[:, 0] == end, 1].mean() < 0.65
    on = pcg.make_params(n_games=2, observe_goal=True, goal_axis=(1, 1, 1, 1))
    st, st_off = pcg.reset(keys[0], on)[1], pcg.reset(keys[0], pcg.make_params(n_games=2))[1]
    np.testing.assert_array_equal(np.asarray(st.skill), np.asarray(st_off.skill))  # own key stream
    np.testing.assert_array_equal(np.asarray(st.win_rate), np.asarray(st_off.win_rate))


@pytest.mark.parametrize("kwargs,match", [
    ({"goal_axis": (1, 1, 1, 1)}, r"goal_axis: value \(1, 1, 1, 1\) needs observe_goal=True"),
    ({"observe_goal": True, "goal_axis": (1, 2, 1, 1)}, r"goal_axis: value \(1, 2, 1, 1\) must be 4 signs"),
    ({"observe_goal": True, "goal_axis": (1, 1, 1)}, r"goal_axis: value \(1, 1, 1\) must be 4 signs")])
def test_goal_axis_rejects_bad_values_naming_the_field(kwargs, match):
    with pytest.raises(ValueError, match=match):
        pcg.make_params(**kwargs)


def test_goal_axis_in_the_learner_config_and_on_the_command_line():
    import argparse

    from trainers.ppo_pcgrl import Config, env_params
    from trainers.ppo_pcgrl_cli import parse_signs

    cfg = Config(goal_cost=0.5, goal_axis=[1, 0, -1, 1])  # as read back from JSON
    assert cfg.goal_axis == (1, 0, -1, 1)
    p = env_params(cfg)
    assert p.observe_goal and p.goal_axis == (1, 0, -1, 1)
    goal = jax.jit(lambda k: pcg.reset(k, p)[1].goal)(jax.random.key(0))  # hashable static field
    assert goal.shape == (4,)
    with pytest.raises(ValueError, match=r"goal_axis: value \(1, 1, 1, 1\) needs goal_cost > 0"):
        Config(goal_axis=(1, 1, 1, 1))
    assert parse_signs("1,1,-1,0") == (1, 1, -1, 0)
    for bad in ("1,1,1", "2,0,0,0", "a,b,c,d"):
        with pytest.raises(argparse.ArgumentTypeError, match="goal axis: value"):
            parse_signs(bad)
