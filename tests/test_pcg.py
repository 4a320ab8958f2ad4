"""Tests of the content-generation environment, baselines, metrics and PPO-PCGRL (GAME.md §10, PROTOCOLS.md §11)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import pcg_state as _state

import raidjax
from raidjax import pcg, policies
from raidjax.pcg import quality as pm

LOW, HIGH = np.array(pcg.PAPER_SPACE.low), np.array(pcg.PAPER_SPACE.high)
TICK = (HIGH - LOW) / 6


def test_ticks_and_clipping():
    np.testing.assert_allclose(np.asarray(pcg.space.tick()), [19 / 6, 0.1 / 6, 1 / 6, 0.5 / 6], rtol=1e-6)
    mid = jnp.asarray((10.0, 0.55, 1.0, 0.75))
    for c, frac in enumerate((-1.0, -0.5, 0.0, 0.5, 1.0)):
        out = np.asarray(pcg.env.apply_action(mid, jnp.full(4, c, jnp.int32)))
        np.testing.assert_allclose(out, np.asarray(mid) + frac * TICK, rtol=1e-6)
    # Mixed branches.
    out = np.asarray(pcg.env.apply_action(mid, jnp.array([0, 1, 3, 4])))
    np.testing.assert_allclose(out, np.asarray(mid) + np.array([-1, -0.5, 0.5, 1]) * TICK, rtol=1e-6)
    # Clipped to bounds.
    np.testing.assert_allclose(np.asarray(pcg.env.apply_action(jnp.asarray(HIGH - 0.1 * TICK), jnp.full(4, 4))), HIGH)
    np.testing.assert_allclose(np.asarray(pcg.env.apply_action(jnp.asarray(LOW + 0.1 * TICK), jnp.full(4, 0))), LOW)


@pytest.mark.parametrize("w, target, easier", [(0.2, 0.6, True), (0.8, 0.3, False)])
def test_heuristic_moves_each_parameter_the_right_way(w, target, easier):
    p = pcg.make_pcg_params(n_games=4)
    st = _state(target=target, w=w)
    seen = set()
    for i in range(64):
        a = np.asarray(pcg.pcg_hr(None, jax.random.key(i), None, st, p))
        moved = np.flatnonzero(a != pcg.env.NOOP_ACTION)
        assert moved.size == 1  # one parameter, half a tick
        j = int(moved[0])
        seen.add(j)
        sign = pcg.PAPER_SPACE.easier[j] * (1 if easier else -1)
        assert a[j] == pcg.env.NOOP_ACTION + sign and abs(a[j] - 2) == 1
        new = np.asarray(pcg.env.apply_action(st.skill, jnp.asarray(a)))
        np.testing.assert_allclose(new[j] - np.asarray(st.skill)[j], 0.5 * TICK[j] * sign, rtol=1e-5)
    assert seen == {0, 1, 2, 3}
    # Easier = range up, cool down, cast down, coefficient up.
    assert pcg.PAPER_SPACE.easier.tolist() == [1.0, -1.0, -1.0, 1.0]


def test_heuristic_idle_in_band_and_random_policy_range():
    p = pcg.make_pcg_params(n_games=4)
    a = pcg.pcg_hr(None, jax.random.key(0), None, _state(target=0.5, w=0.51), p)
    assert (np.asarray(a) == pcg.env.NOOP_ACTION).all()
    acts = np.stack([np.asarray(pcg.pcg_rd(None, jax.random.key(i), None, None, p)) for i in range(50)])
    assert acts.min() == 0 and acts.max() == 4 and acts.shape == (50, 4)


def test_reward_sign_and_scale_on_win_rate_sequences():
    p = pcg.make_pcg_params(n_games=4, band=0.02, strict_length=True)
    st = _state(target=0.5, w=0.1)  # w_0 measured at reset: no reward for it
    rewards = []
    for w in (0.3, 0.45, 0.7, 0.5, 0.5):
        st, r = pcg.env.advance(st, st.skill, jnp.float32(w), p)
        rewards.append(float(r))
    np.testing.assert_allclose(rewards, [20.0, 15.0, -15.0, 20.0, 0.0], atol=1e-4)
    assert float(pcg.env.reward_fn(0.5, 0.1, 0.5)) == pytest.approx(40.0, abs=1e-4)
    # The rewards telescope: sum = (|t - w_0| - |t - w_last|) * 100.
    assert sum(rewards) == pytest.approx(40.0, abs=1e-3)


def test_early_termination_and_strict_length():
    loose = pcg.make_pcg_params(n_games=4, max_edits=5)
    strict = pcg.make_pcg_params(n_games=4, max_edits=5, strict_length=True)
    st = _state(target=0.5, w=0.1)
    s1, _ = pcg.env.advance(st, st.skill, jnp.float32(0.3), loose)
    assert not bool(s1.done)
    s2, _ = pcg.env.advance(s1, st.skill, jnp.float32(0.52), loose)  # |w - t| = 0.02 <= band
    assert bool(s2.done) and bool(s2.reached) and int(s2.edits) == 2
    s = st
    for i in range(5):
        s, _ = pcg.env.advance(s, st.skill, jnp.float32(0.5), strict)
        assert bool(s.done) == (i == 4) and bool(s.reached)
    s = st
    for _ in range(5):
        s, _ = pcg.env.advance(s, st.skill, jnp.float32(0.9), loose)
    assert bool(s.done) and not bool(s.reached)


def test_observation_modes():
    st = _state(skill=pcg.PAPER_SPACE.low, target=0.4, w=0.2)
    o = pcg.env.observe_pcg(st, pcg.make_pcg_params(n_games=4))
    np.testing.assert_allclose(np.asarray(o), [0, 0, 0, 0, 0.4, 0.2], atol=1e-6)
    assert pcg.env.observe_pcg(st, pcg.make_pcg_params(n_games=4, observe_target=False)).shape == (4,)



@pytest.mark.parametrize("field,value,what", [
    ("max_edits", 2.5, "is a float"), ("band", -1.0, "is out of range"), ("strict_length", "no", "is a str"),
    ("band", "x", "is a str"), ("target", "ab", "is a str"), ("n_games", "5", "is a str"),
    ("target", (0.7, 0.1), "is out of range"), ("target", (0.1, 0.2, 0.3), "is a tuple of length 3"),
    ("n_games", 0, "is too small"), ("pool_repeats", 1, "is an int")])
def test_make_pcg_params_refuses_bad_values_in_one_line_naming_the_field(field, value, what):
    with pytest.raises(ValueError) as e:
        pcg.make_pcg_params(**{field: value})
    assert str(e.value).startswith(f"{field}: value {value!r} {what}; allowed: ") and "\n" not in str(e.value)
    assert pcg.make_pcg_params(target=np.float32(0.5), n_games=np.int64(4)).n_games == 4  # numpy scalars are fine


@pytest.mark.parametrize("field,value", [("edit_cost", -0.5), ("goal_cost", -0.1), ("n_minibatches", 3),
                                         ("n_games", 0), ("gamma", 1.5), ("lr", "1e-3"), ("pool_repeats", 1),
                                         ("total_steps", True), ("lr", float("nan"))])
def test_ppo_config_rejects_bad_values_naming_the_field(field, value):
    from trainers.config import load_config

    with pytest.raises(ValueError, match=f"^{field}: value {value!r}"):
        load_config("cpu", learner="ppo_pcgrl", **{field: value})


def test_pool_repeats_pools_only_an_unchanged_skill():
    p = pcg.make_pcg_params(n_games=4, pool_repeats=True, strict_length=True)
    st = _state(target=0.5, w=0.25, games=4)
    same, _ = pcg.env.advance(st, st.skill, jnp.float32(0.75), p)  # 1 + 3 wins of 8 games
    assert float(same.games) == 8 and float(same.win_rate) == pytest.approx(0.5)
    again, r = pcg.env.advance(same, st.skill, jnp.float32(1.0), p)  # 4 + 4 wins of 12 games
    assert float(again.games) == 12 and float(again.win_rate) == pytest.approx(8 / 12)
    assert float(r) == pytest.approx((0.0 - (8 / 12 - 0.5)) * 100, abs=1e-3)  # paid on the pooled rate
    moved, _ = pcg.env.advance(again, st.skill + 1.0, jnp.float32(0.0), p)
    assert float(moved.games) == 4 and float(moved.win_rate) == 0.0
    off, _ = pcg.env.advance(st, st.skill, jnp.float32(0.75), pcg.make_pcg_params(n_games=4, strict_length=True))
    assert float(off.games) == 4 and float(off.win_rate) == pytest.approx(0.75)  # the paper's environment: no pooling
    o = pcg.env.observe_pcg(again, p)
    assert o.shape == (pcg.env.obs_size(p),) == (7,) and float(o[-1]) == pytest.approx(np.sqrt(100 / 12))


def test_pooled_win_rate_is_mean_of_all_games_of_the_held_skill():
    p = pcg.make_pcg_params(n_games=8, pool_repeats=True, strict_length=True, max_edits=3)
    key = jax.random.key(7)
    _, st = pcg.reset(key, p)
    keys = jax.random.split(jax.random.key(8), 2)
    hold = jnp.full(4, pcg.env.NOOP_ACTION, jnp.int32)
    for k in keys:
        _, st, _, _, _ = pcg.step(k, st, hold, p)
    outcomes = [pcg.play_outcomes(k, p.game, st.skill, 8) for k in (jax.random.split(key)[1], *keys)]
    assert float(st.games) == 24
    assert float(st.win_rate) == pytest.approx(float(np.mean(np.concatenate(outcomes))), abs=1e-6)


def test_side_by_side_measurements_are_one_playtest_of_each_episode_s_own_games(monkeypatch):
    """Generator episodes vmapped over keys and skills measure in one playtest
    (``raidjax.playtest_groups``, no vmapped game loop; a single playtest is traced for its shapes
    by ``custom_vmap``, but the program does not hold it): each episode's games bit for bit as its
    own measurement plays them. With the game batched too (a content per
    episode) the vmap runs as it is, with the same games again."""
    p = pcg.make_pcg_params(n_games=8)
    keys = jax.random.split(jax.random.key(9), 3)
    skills = jnp.asarray([(20.0, 0.5, 0.5, 0.6), (5.0, 2.0, 1.0, 1.5), (12.0, 1.0, 0.3, 1.0)])
    # Each measured alone, as a user measures (the jitted playtest the test above compiled).
    alone = np.stack([np.asarray(pcg.play_outcomes(k, p.game, s, 8)) for k, s in zip(keys, skills, strict=True)])
    assert 0 < alone.mean() < 1  # wins and losses: the comparison can fail
    singles = []
    monkeypatch.setattr(pcg.measurement, "playtest", lambda *a, **k: singles.append(1) or raidjax.playtest(*a, **k))
    traced = jax.jit(jax.vmap(lambda k, s: pcg.play_outcomes(k, p.game, s, 8))).trace(keys, skills)
    lowered = traced.lower()
    text = lowered.as_text()
    assert "_playtest_groups" in text and "@_playtest(" not in text and singles == [1]
    np.testing.assert_array_equal(lowered.compile()(keys, skills), alone)
    # Nested (several learners, each with its episodes): the outer axis joins the groups of the one
    # playtest, the same games again.
    nested = jax.jit(jax.vmap(jax.vmap(lambda k, s: pcg.play_outcomes(k, p.game, s, 8))))(keys.reshape(3, 1),
                                                                                   skills.reshape(3, 1, 4))
    np.testing.assert_array_equal(np.asarray(nested).reshape(3, 8), alone)
    assert singles == [1, 1]
    games = jax.tree.map(lambda x: jnp.stack([x] * 3), p.game)
    per_game = jax.jit(jax.vmap(lambda k, g, s: pcg.play_outcomes(k, g, s, 8)))(keys, games, skills)
    np.testing.assert_array_equal(per_game, alone)
    contents = jax.vmap(lambda s: pcg.PAPER_SPACE.apply(p.game, s))(skills)
    with pytest.raises(ValueError, match=r"keys: shape \[2\]; allowed: one key per group, \[3\]"):
        raidjax.playtest_groups(keys[:2], contents, raidjax.policies.heuristic, 8)
    with pytest.raises(ValueError, match="games_per_arena: value 3 does not divide the 8 games"):
        raidjax.playtest_groups(keys, contents, raidjax.policies.heuristic, 8, games_per_arena=3)


def test_win_rate_is_mean_of_game_outcomes():
    p = pcg.make_pcg_params(n_games=8)
    skill = jnp.asarray((20.0, 0.5, 0.5, 0.6))
    key = jax.random.key(3)
    wins = np.asarray(pcg.play_outcomes(key, p.game, skill, 8))
    assert wins.shape == (8,) and wins.dtype == bool
    assert float(pcg.measure(key, p, skill)) == pytest.approx(wins.mean())
    # The skill really is in every player's slot 1, speed 10 and cost 1.
    g = pcg.PAPER_SPACE.apply(p.game, skill)
    np.testing.assert_allclose(np.asarray(g.skills.range[:3, 0]), 20.0)
    np.testing.assert_allclose(np.asarray(g.skills.projectile_speed[:3, 0]), 10.0)
    np.testing.assert_allclose(np.asarray(g.skills.cost[:3, 0]), 1.0)
    assert float(g.skills.range[3, 0]) == float(p.game.skills.range[3, 0])  # boss untouched


def test_controllability_on_hand_set():
    gen = {"target": np.array([0.1, 0.1, 0.5, 0.5, 0.5]), "win_rate": np.array([0.2, 0.1, 0.3, 0.6, 0.0]),
           "edits": np.array([3, 5, 2, 10, 1])}
    c = pm.controllability(gen)  # the last episode (1 edit) is left out
    assert c["n"] == 4
    assert c["per_target"][0.1]["wc_mean"] == pytest.approx(0.15)
    assert c["per_target"][0.1]["err_mean"] == pytest.approx(0.05)
    assert c["per_target"][0.1]["err_sd"] == pytest.approx(0.05)
    assert c["per_target"][0.5]["err_mean"] == pytest.approx(0.15)
    assert c["per_target"][0.5]["wc_sd"] == pytest.approx(0.15)
    assert c["err_mean"] == pytest.approx(0.1)


def test_diversity_on_hand_set():
    skills = np.array([[1.0, 0.5, 0.5, 0.5], [20.0, 0.5, 0.5, 0.5], [10.5, 0.5, 0.5, 0.5], [5.0, 0.6, 1.5, 1.0]])
    errors = np.array([0.0, 0.05, 0.09, 0.5])  # the last one is dropped (error >= 0.1)
    d = pm.diversity(skills, errors, np.array(["a", "a", "b", "a"]))
    # b kept one skill: left out of the scaling and PCA (min_kept 2), its count reported.
    assert set(d) == {"a", "b"} and d["a"]["n"] == 2 and (d["b"]["n"], d["b"]["kept"]) == (0, 1)
    # Kept set varies only in range: normalised ranges 0 and 1 in group a -> SD 0.5; PC1 = range.
    np.testing.assert_allclose(d["a"]["param_sd"], [0.5, 0, 0, 0], atol=1e-9)
    assert d["a"]["pc1_sd"] == pytest.approx(0.5)
    assert np.isnan(d["b"]["pc1_sd"]) and np.isnan(d["b"]["pc1_own_sd"])
    y = pm.yield_stats({"reached": np.array([True, False]), "edits": np.array([4, 40])})
    assert y == {"yield": 0.5, "edits_mean": 22.0, "edits_sd": 18.0}


def test_diversity_leaves_out_groups_that_kept_too_few_and_cuts_the_rest_to_one_size():
    # Group a keeps 3 skills, b 2 (its third misses the threshold), c 1: with min_kept 2 and a cut
    # to at most 300, c is left out and a is cut to b's 2; with min_kept 3 only a is measured, whole.
    skills = np.array([[1.0, 0.5, 0.5, 0.5], [20.0, 0.5, 0.5, 0.5], [10.5, 0.5, 0.5, 0.5],
                       [5.0, 0.6, 1.5, 1.0], [6.0, 0.6, 1.5, 1.0], [7.0, 0.6, 1.5, 1.0], [8.0, 0.6, 1.5, 1.0]])
    errors = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0])
    groups = np.array(["a", "a", "a", "b", "b", "b", "c"])
    d = pm.diversity(skills, errors, groups, group_size=300)
    assert {g: (v["n"], v["kept"]) for g, v in d.items()} == {"a": (2, 3), "b": (2, 2), "c": (0, 1)}
    assert np.isnan(d["c"]["pc1_sd"]) and np.isfinite(d["a"]["pc1_sd"])
    d = pm.diversity(skills, errors, groups, group_size=300, min_kept=3)
    assert {g: (v["n"], v["kept"]) for g, v in d.items()} == {"a": (3, 3), "b": (0, 2), "c": (0, 1)}
    # Only a is scaled: its ranges 1, 20, 10.5 -> 0, 1, 0.5, the sole spread, so PC1 is the range.
    assert d["a"]["pc1_sd"] == pytest.approx(np.std([0.0, 1.0, 0.5]))
    with pytest.raises(ValueError, match="min_kept: 1"):
        pm.diversity(skills, errors, groups, min_kept=1)


def test_summarize_keeps_targets_closer_than_a_tenth_apart_in_their_own_groups():
    # 0.15 and 0.2 were both labelled "0.2" (one decimal) in diversity, while controllability, which
    # rounds to 6 decimals, kept them apart.
    rng = np.random.default_rng(0)
    t = np.repeat(np.float32([0.15, 0.2, 0.5]), 3)
    gen = {"target": t, "skill": rng.uniform(0, 1, (9, 4)).astype(np.float32), "win_rate": t, "gen_win_rate": t,
           "edits": np.full(9, 5), "reached": np.ones(9, bool)}
    out = pm.summarize({"PPO": gen}, pm.PROTOCOLS["paper"])["PPO"]
    assert sorted(out["diversity"]) == ["0.15", "0.2", "0.5"] and all(v["kept"] == 3 for v in out["diversity"].values())
    assert len(out["controllability"]["per_target"]) == 3
    assert [pm.target_label(x) for x in pm.TARGETS] == [f"{x:.1f}" for x in pm.TARGETS]  # the tables' labels


def test_pc1_on_the_pooled_axis_and_on_each_groups_own_axis():
    # normalised (range, cool time): group a at (0, 0) and (1, 0), group b at (0.5, 0) and (0.5, 1).
    # Pooled: var(range) = 0.125 < var(cool) = 0.1875, covariance 0, so the pooled axis is cool time:
    # a has no spread along it, b has SD 0.5. Along its own axis each group has SD 0.5.
    skills = np.array([[1.0, 0.5, 1.0, 0.7], [20.0, 0.5, 1.0, 0.7], [10.5, 0.5, 1.0, 0.7], [10.5, 0.6, 1.0, 0.7]])
    d = pm.diversity(skills, np.zeros(4), np.array(["a", "a", "b", "b"]))
    assert d["a"]["pc1_sd"] == pytest.approx(0.0, abs=1e-9) and d["b"]["pc1_sd"] == pytest.approx(0.5)
    assert d["a"]["pc1_own_sd"] == pytest.approx(0.5) and d["b"]["pc1_own_sd"] == pytest.approx(0.5)


def test_a_step_from_the_placeholder_is_the_reset():
    """``pcg.env.awaiting_reset``: ``step_autoreset`` on it plays exactly ``reset``'s episode start
    (same keys, same measurement), pays nothing and is marked invalid."""
    p = pcg.make_pcg_params(n_games=4)
    key = jax.random.key(3)
    _, waiting = pcg.env.awaiting_reset(p)
    assert bool(waiting.done)
    obs, state, reward, done, info = jax.jit(pcg.step_autoreset)(key, waiting, jnp.full(4, 4, jnp.int32), p)
    obs0, state0 = jax.jit(pcg.reset)(key, p)
    np.testing.assert_array_equal(np.asarray(obs), np.asarray(obs0))
    for a, b in zip(jax.tree.leaves(state), jax.tree.leaves(state0), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert float(reward) == 0.0 and not bool(done) and not bool(info["valid"])


def test_ppo_init_plays_no_game(monkeypatch):
    """PPO-PCGRL's initial program holds no playtest (its arenas wait on the placeholder)."""
    from trainers.config import PPOConfig
    from trainers.ppo_pcgrl import make_train

    def no_game(*_):
        raise AssertionError("init measured a skill")

    monkeypatch.setattr(pcg.env, "measure", no_game)
    train = make_train(PPOConfig(n_arenas=2, n_steps=3, total_steps=12, n_minibatches=2, hidden=8, layers=1,
                                 n_games=2))
    runner = jax.eval_shape(train.init, jax.random.key(0))
    assert runner["env_state"].done.shape == (2,)


# The plain learner (no pooling, no goal) trains and round-trips its checkpoints bit-for-bit in
# tests/test_faults_ppo.py; this covers the two options.
@pytest.mark.parametrize("pool,goal", [(True, 0.5)])
def test_tiny_ppo_run_and_checkpoint_roundtrip(tmp_path, pool, goal):
    from trainers import checkpoint
    from trainers.config import PPOConfig
    from trainers.ppo_pcgrl import make_generator_policy, make_train

    cfg = PPOConfig(n_arenas=2, n_steps=3, total_steps=12, update_epochs=1, n_minibatches=2, hidden=8, layers=1,
                    n_games=2,
                    max_edits=2, pool_repeats=pool, edit_cost=1.0, goal_cost=goal,
                    goal_axis=(1, 1, 1, 1) if goal else None)
    train = make_train(cfg)
    key = jax.random.key(0)
    runner, metrics = jax.jit(train)(key)  # its numbers are not compared
    assert metrics["reward"].shape == (2,) and np.isfinite(np.asarray(metrics["pg_loss"])).all()
    assert int(runner["update"]) == 2
    assert int(np.asarray(metrics["episodes"]).sum()) >= 1  # max_edits=2 forces episode ends
    checkpoint.save(tmp_path, runner, runner["params"], cfg.to_dict(), {"update": 2})
    back, config, meta = checkpoint.restore(tmp_path, jax.eval_shape(lambda: runner))
    assert meta["update"] == 2 and PPOConfig.from_dict(config) == cfg
    for a, b in zip(jax.tree.leaves(runner), jax.tree.leaves(back), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    weights, _ = checkpoint.load_policy_weights(tmp_path)
    policy = make_generator_policy((8,), True)
    obs = pcg.env.observe_pcg(_state(), pcg.make_pcg_params(n_games=2, pool_repeats=pool,
                                                        goal_axis=cfg.goal_axis))
    assert obs.shape == (6 + pool + 4 * (goal > 0),)
    a = policy(weights, jax.random.key(1), obs, _state(), None)
    assert a.shape == (4,) and a.dtype == jnp.int32


_VMAPPED_LEARNERS = """
import jax, jax.numpy as jnp
from trainers.config import load_config
from trainers.ppo_pcgrl import make_train
cfg = load_config("paper", learner="ppo_pcgrl", n_games=4, hidden=64, layers=2)  # smaller configs did not deadlock
train = make_train(cfg)
t = jnp.asarray([[0.3, 0.3], [0.5, 0.5]])
r = jax.jit(jax.vmap(train.init))(jax.random.split(jax.random.key(0), 2), t)
one = lambda r, t: jax.lax.scan(lambda rr, _: train.update(rr, t), r, None, 1)
r, m = jax.jit(jax.vmap(one))(r, t)
jax.block_until_ready(r)
print("finished")
"""


def test_vmapped_learners_do_not_deadlock_xla_cpu():
    """Two vmapped PPO-PCGRL learners (a scan of playtest while-loops) used to deadlock in
    XLA:CPU's concurrency-optimised scheduler (in about half the runs); the recommended flags
    switch it off, and make_train warns when they are missing. Run in a fresh subprocess that
    opts in itself, so that a regression fails on the timeout instead of hanging the suite."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("RAIDJAX_KEEP_XLA_FLAGS", "XLA_FLAGS")}
    env["PYTHONPATH"] = os.pathsep.join([os.getcwd(), env.get("PYTHONPATH", "")])
    code = "import raidjax\nassert raidjax.use_recommended_xla_flags()\n" + _VMAPPED_LEARNERS
    out = subprocess.run([sys.executable, "-W", "error::RuntimeWarning", "-c", code], env=env,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and "finished" in out.stdout, out.stderr[-2000:]


def test_make_train_warns_on_cpu_without_the_scheduler_flag(monkeypatch):
    import warnings

    from raidjax import xla_flags
    from trainers.config import load_config
    from trainers.ppo_pcgrl import make_train

    monkeypatch.setenv("XLA_FLAGS", "")
    if not any("concurrency_optimized" in f for f in xla_flags.missing()):
        pytest.skip("this jaxlib has no such flag")
    with pytest.warns(RuntimeWarning, match="use_recommended_xla_flags"):
        make_train(load_config("cpu", learner="ppo_pcgrl"))
    monkeypatch.setenv("XLA_FLAGS", " ".join(xla_flags.RECOMMENDED))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        make_train(load_config("cpu", learner="ppo_pcgrl"))


def heuristic_with_weights(weights, key, obs, state, params):
    """PT-HR through the policy-with-weights interface (the weights only scale nothing)."""
    return policies.heuristic(key, obs, state, params) * weights["one"]


def test_generator_with_a_tester_given_through_the_weights_interface():
    """PT-HR passed as a policy with weights plays exactly as the default tester; a trained-team
    policy (MA-POCA's, here with fresh weights) plays inside the jitted generator step, and other
    weights of the same shapes reuse the compiled step."""
    from trainers.config import load_config
    from trainers.mapoca import TeamPolicy
    from trainers.networks import Actor

    key = jax.random.key(4)
    skill = jnp.asarray([12.0, 0.5, 0.8, 0.9])
    # The clean rules play no warm-up game: half the program to compile.
    clean = lambda p: p.replace(game=p.game.replace(config=raidjax.EnvConfig.from_rules("clean")))
    default = clean(pcg.make_pcg_params(n_games=16))
    same = clean(pcg.make_pcg_params(n_games=16, tester=heuristic_with_weights, tester_weights={"one": jnp.int32(1)}))

    @jax.jit
    def play(params, key):  # what every generator step measures
        return pcg.play_outcomes(key, params.game, skill, params.n_games, params.tester, params.tester_weights)

    np.testing.assert_array_equal(np.asarray(play(default, key)), np.asarray(play(same, key)))

    cfg = load_config("cpu")
    team = TeamPolicy(Actor(cfg.hidden, cfg.layers, cfg.heads, cfg.proj_attention), deterministic=True)
    init = jax.jit(lambda k: team.actor.init(k, raidjax.reset(k, default.game)[0]))
    weights = [init(jax.random.key(s)) for s in (0, 1)]
    learned = [clean(pcg.make_pcg_params(n_games=16, tester=team, tester_weights=w)) for w in weights]
    before = play._cache_size()
    wins = [np.asarray(play(p, key)) for p in learned]
    assert play._cache_size() == before + 1
    assert all(w.shape == (16,) and w.dtype == bool for w in wins)
    with pytest.raises(ValueError, match="policy"):
        pcg.make_pcg_params(tester=[1])
