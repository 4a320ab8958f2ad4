"""MA-POCA trainer: hand-computed λ-returns, baseline/value masking, losses, clipping, and a
tiny end-to-end run with a checkpoint round-trip (no timing assertions)."""

from __future__ import annotations

import json
import re

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

import raidjax
from raidjax import team_reward
from raidjax.types import WIN
from trainers import checkpoint
from trainers.config import PRESETS, Config, load_config
from trainers.mapoca import begin_episodes, load_policy, make_train, make_trainer, training_content
from trainers.networks import Actor, Critic, masked_logits
from trainers.poca_loss import Batch, loss_fn
from trainers.returns import advantages, explained_variance, lambda_returns

TINY = PRESETS["mapoca"]["cpu"].replace(n_arenas=4, n_steps=8, n_minibatches=2, update_epochs=1, hidden=8, layers=1,
                              heads=2, updates_per_chunk=2, total_steps=4 * 8 * 4, checkpoint_every=2,
                              eval_games=4, skill_ranges=(9.0, 13.0), deterministic_eval=True)


@pytest.fixture(scope="module")
def obs3():
    """A batch of 3 live observations (reference content) with a fixed PRNG."""
    params = raidjax.make_params(skill_range=13.0)
    obs, _ = jax.jit(jax.vmap(raidjax.reset, in_axes=(0, None)))(jax.random.split(jax.random.PRNGKey(0), 3), params)
    # Make the three decisions distinct so that networks see different inputs.
    noise = jax.random.normal(jax.random.PRNGKey(1), obs.self_features.shape) * 0.1
    return obs.replace(self_features=obs.self_features + noise)


def test_explained_variance_by_hand():
    target = jnp.array([1.0, 2.0, 3.0, 4.0])  # variance 1.25
    assert float(explained_variance(target, target)) == 1.0
    assert float(explained_variance(jnp.full(4, 2.5), target)) == 0.0  # the mean explains nothing
    # residuals (0, 0, 0, 2): variance 0.75, so 1 - 0.75 / 1.25 = 0.4
    np.testing.assert_allclose(float(explained_variance(jnp.array([1.0, 2.0, 3.0, 2.0]), target)), 0.4, rtol=1e-6)
    # masked: only the first two entries count (target 1, 2: variance 0.25; residuals 0, 0.5: 0.0625)
    where = jnp.array([True, True, False, False])
    np.testing.assert_allclose(float(explained_variance(jnp.array([1.0, 1.5, 9.0, 9.0]), target, where)), 0.75,
                               rtol=1e-6)
    assert float(explained_variance(jnp.zeros(3), jnp.ones(3))) == 0.0  # a constant target: 0, not NaN


def test_posthumous_credit_mid_episode_death():
    """Agent 2 dies during step 1; the team fights on. Its last action (t=1) is credited with
    the rewards earned after its death, through the group return; later steps are masked."""
    gamma, lam = 0.9, 0.8
    r = jnp.array([0.5, 0.0, 2.0, 1.0])[:, None]
    v_next = jnp.array([1.0, 2.0, 3.0, 4.0])[:, None]
    done = jnp.zeros((4, 1), bool)
    g3 = 1.0 + 0.9 * 4.0
    g2 = 2.0 + 0.9 * (0.2 * 3.0 + 0.8 * g3)
    g1 = 0.0 + 0.9 * (0.2 * 2.0 + 0.8 * g2)
    g0 = 0.5 + 0.9 * (0.2 * 1.0 + 0.8 * g1)
    g = lambda_returns(r, v_next, done, done, gamma, lam)
    np.testing.assert_allclose(np.asarray(g[:, 0]), [g0, g1, g2, g3], rtol=1e-6)
    alive = jnp.array([[1, 1, 1], [1, 1, 1], [1, 1, 0], [1, 1, 0]], bool)[:, None]  # [T, N, P]
    base = jnp.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 9.0], [1.0, 1.1, 9.0]])[:, None]
    adv = np.asarray(advantages(g, base, alive))[:, 0]
    raw = np.array([g0, g1, g2, g3])[:, None] - np.asarray(base[:, 0])
    m = np.asarray(alive[:, 0])
    expect = (raw - raw[m].mean()) / (raw[m].std() + 1e-8)
    np.testing.assert_allclose(adv[m], expect[m], atol=1e-5)
    assert (adv[~m] == 0).all()
    # Agent 2's last action (t=1) is credited with G_1 = 4.573..., which holds the rewards 2.0 and
    # 1.0 earned after its death; an agent-level termination at death would have given r_1 = 0.
    assert abs(g1 - 4.5730) < 1e-3 and float(g[1, 0]) > 4.5


def test_team_reward_is_shared_once():
    info = {"damage_dealt": jnp.array([[50.0, 0.0, 60.0], [0.0, 0.0, 0.0]]), "result": jnp.array([WIN, 0])}
    done = jnp.array([True, False])
    np.testing.assert_allclose(np.asarray(team_reward(info, done)), [0.01 * 110 + 1.0, 0.0])
    # Against the env's per-player rewards: r_team = sum_i r_i - (P - 1) * won.
    env_r = 0.01 * info["damage_dealt"] + 1.0 * (done & (info["result"] == WIN))[:, None]
    np.testing.assert_allclose(np.asarray(team_reward(info, done)), np.asarray(env_r.sum(-1) - 2.0 * done), rtol=1e-6)


@pytest.fixture(scope="module")
def critic(obs3):
    """``(Critic, weights)`` of a small critic."""
    net = Critic(hidden=16, layers=1, heads=2)
    return net, jax.jit(net.init)(jax.random.PRNGKey(2), obs3, jnp.zeros((3, 3), jnp.int32))


def test_baseline_ignores_own_action_and_sees_teammates(obs3, critic):
    net, params = critic
    base = jax.jit(lambda a, o: net.apply(params, o, a, method=Critic.baseline))
    dead = obs3.replace(alive=obs3.alive.at[:, 2].set(False))
    a = jnp.array([[1, 2, 7]] * 3, jnp.int32)
    b0, b_own = base(a, obs3), base(a.at[:, 0].set(4), obs3)  # agent 0 changes its own action
    np.testing.assert_allclose(np.asarray(b_own[:, 0]), np.asarray(b0[:, 0]), rtol=1e-6)
    assert np.abs(np.asarray(b_own[:, 1:] - b0[:, 1:])).min() > 1e-6  # teammates' baselines see it
    # A dead teammate's action is masked out as well.
    np.testing.assert_allclose(np.asarray(base(a.at[:, 2].set(3), dead)[:, :2]), np.asarray(base(a, dead)[:, :2]),
                               rtol=1e-6)


def test_value_masks_dead_agents(obs3, critic):
    net, params = critic
    value = jax.jit(lambda o: net.apply(params, o, method=Critic.value))
    dead = obs3.replace(alive=obs3.alive.at[:, 1].set(False))
    garbage = dead.replace(self_features=dead.self_features.at[:, 1].set(123.0),
                           action_mask=dead.action_mask.at[:, 1].set(True))
    np.testing.assert_allclose(np.asarray(value(garbage)), np.asarray(value(dead)), rtol=1e-6)
    assert np.abs(np.asarray(value(dead) - value(obs3))).min() > 1e-6
    all_dead = obs3.replace(alive=jnp.zeros_like(obs3.alive))
    assert np.isfinite(np.asarray(value(all_dead))).all()


def _batch(obs3, actor, a_params, critic, c_params, ratio_factor=1.0) -> Batch:
    """A fixed batch of 3 decisions (agent 2 dead in the second) whose stored log-probabilities
    are the current ones minus log(ratio_factor), values 0.3 below and baselines 0.3 above."""
    actions = jnp.array([[7, 1, 0], [2, 7, 3], [0, 0, 1]], jnp.int32)
    alive = jnp.array([[1, 1, 1], [1, 1, 0], [1, 1, 1]], bool)
    obs = obs3.replace(alive=alive, action_mask=obs3.action_mask | (jnp.arange(10)[None, None] < 8))
    logp = jnp.take_along_axis(jax.nn.log_softmax(actor.apply(a_params, obs)), actions[..., None], -1)[..., 0]
    v, b = critic.apply(c_params, obs, actions)
    return Batch(obs, actions, logp - jnp.log(ratio_factor), alive, v - 0.3, b + 0.3,
                 jnp.array([1.0, -2.0, 0.5])[:, None].repeat(3, 1),
                 jnp.array([[1.0, -1.0, 0.5], [2.0, 0.3, 0.0], [-0.7, 0.2, 1.1]]))


def test_loss_terms_on_fixed_batch(obs3, critic):
    net, c_params = critic
    actor = Actor(16, 1, 2, False)

    @jax.jit
    def run(key):
        params = {"actor": actor.init(key, obs3), "critic": c_params}
        batch = _batch(obs3, actor, params["actor"], net, c_params, ratio_factor=1.5)  # every ratio = 1.5
        loss, aux = loss_fn(params, batch, actor, net, 0.2, 0.01)
        v, b = net.apply(c_params, batch.obs, batch.action)
        return batch, loss, aux, v, b, jax.nn.softmax(actor.apply(params["actor"], batch.obs))

    batch, loss, aux, v, b, p = jax.tree.map(np.asarray, run(jax.random.PRNGKey(3)))
    m = batch.alive.astype(float)
    adv = batch.advantage
    # ratio 1.5: min(1.5 A, 1.2 A) = 1.2 A for A > 0 and 1.5 A for A < 0.
    surr = np.where(adv > 0, 1.2 * adv, 1.5 * adv)
    np.testing.assert_allclose(aux["policy_loss"], -(surr * m).sum() / m.sum(), rtol=1e-5)
    # Values sit 0.3 above their stored old values and baselines 0.3 below theirs: outside the clip,
    # so clipped to old + 0.2 = v - 0.1 and old - 0.2 = b + 0.1; each term takes the larger of the
    # two squared errors.
    g = batch.returns[:, 0]  # the group's return (every column)
    lv = np.maximum((v - g) ** 2, (v - 0.1 - g) ** 2).mean()
    lb = (np.maximum((b - g[:, None]) ** 2, (b + 0.3 - 0.2 - g[:, None]) ** 2) * m).sum() / m.sum()
    np.testing.assert_allclose(aux["value_loss"], lv, rtol=1e-5)
    np.testing.assert_allclose(aux["baseline_loss"], lb, rtol=1e-5)
    ent = -np.where(p > 0, p * np.log(np.maximum(p, 1e-30)), 0).sum(-1)
    np.testing.assert_allclose(aux["entropy"], (ent * m).sum() / m.sum(), rtol=1e-4)
    np.testing.assert_allclose(loss, aux["policy_loss"] + 0.5 * (lv + 0.5 * lb) - 0.01 * aux["entropy"], rtol=1e-5)


def test_bf16_networks_track_float32_and_their_loss_descends(obs3):
    """Mixed precision (``Config.bf16``): the same float32 weights give float32 outputs close to the
    float32 networks', and Adam on the MA-POCA loss of a fixed batch lowers it, finitely."""
    nets = {dt: (Actor(16, 1, 2, True, dt), Critic(16, 1, 2, dt)) for dt in (jnp.float32, jnp.bfloat16)}
    actions = jnp.zeros((3, 3), jnp.int32)

    @jax.jit
    def run(key):
        a32, c32 = nets[jnp.float32]
        a16, c16 = nets[jnp.bfloat16]
        params = {"actor": a32.init(key, obs3), "critic": c32.init(key, obs3, actions)}
        out32 = (a32.apply(params["actor"], obs3), *c32.apply(params["critic"], obs3, actions))
        out16 = (a16.apply(params["actor"], obs3), *c16.apply(params["critic"], obs3, actions))
        batch = _batch(obs3, a16, params["actor"], c16, params["critic"], ratio_factor=1.5)
        tx = optax.adam(1e-2)

        def descend(carry, _):
            p, opt = carry
            (loss, _), g = jax.value_and_grad(loss_fn, has_aux=True)(p, batch, a16, c16, 0.2, 0.01)
            upd, opt = tx.update(g, opt)
            return (optax.apply_updates(p, upd), opt), loss

        _, losses = jax.lax.scan(descend, (params, tx.init(params)), None, 30)
        return out32, out16, losses

    out32, out16, losses = jax.tree.map(np.asarray, run(jax.random.PRNGKey(5)))
    for x32, x16 in zip(out32, out16, strict=True):
        assert x16.dtype == np.float32
        live = x32 > -1e8  # masked logits sit at NEG in both
        np.testing.assert_allclose(x16[live], x32[live], atol=0.05, rtol=0.05)
    assert np.isfinite(losses).all() and losses[-1] < losses[0] - 0.1, losses[[0, -1]]


class TableActor(nn.Module):
    """A policy with one free logit vector per (decision, player): samples do not share weights."""

    @nn.compact
    def __call__(self, obs):
        logits = self.param("logits", nn.initializers.zeros, obs.action_mask.shape)
        return masked_logits(logits, obs.action_mask)


def test_clipped_update_keeps_ratio_in_bounds(obs3, critic):
    net, c_params = critic
    actor = TableActor()

    @jax.jit
    def run(key):
        a0 = actor.init(key, obs3)
        batch = _batch(obs3, actor, a0, net, c_params)

        def pi_loss(a, batch, clip):
            return loss_fn({"actor": a, "critic": c_params}, batch, actor, net, clip, 0.0)[1]["policy_loss"]

        def ratios(a):
            logp_all = jax.nn.log_softmax(actor.apply(a, batch.obs))
            return jnp.exp(jnp.take_along_axis(logp_all, batch.action[..., None], -1)[..., 0] - batch.logp)

        def descend(clip):  # plain gradient descent on the policy loss
            step = lambda _, a: jax.tree.map(lambda p, g: p - 0.1 * g, a, jax.grad(pi_loss)(a, batch, clip))
            return jax.lax.fori_loop(0, 400, step, a0)

        # Every stored ratio at 2 and every advantage positive: already past the bound.
        far = _batch(obs3, actor, a0, net, c_params, 2.0)._replace(advantage=jnp.abs(batch.advantage) + 0.1)
        return batch, ratios(descend(0.2)), ratios(descend(1e6)), jax.grad(pi_loss)(a0, far, 0.2)

    batch, clipped, unclipped, g_far = run(jax.random.PRNGKey(4))
    alive = np.asarray(batch.alive)
    adv, clipped, unclipped = (np.asarray(x)[alive] for x in (batch.advantage, clipped, unclipped))
    assert np.abs(unclipped - 1).max() > 1.0  # the unclipped surrogate runs far away
    # Each ratio moved in its advantage's direction and stopped at the bound (within one step).
    pos, neg = adv > 0, adv < 0
    assert (clipped[pos] > 1.195).all() and (clipped[pos] < 1.23).all()
    assert (clipped[neg] < 0.805).all() and (clipped[neg] > 0.77).all()
    # Past the bound in the advantage's direction the policy gradient vanishes.
    assert max(float(jnp.abs(x).max()) for x in jax.tree.leaves(g_far)) == 0.0


def test_config_presets_and_json(tmp_path):
    paper = PRESETS["mapoca"]["paper"]
    assert (paper.hidden, paper.layers, paper.lr, paper.ent_coef, paper.clip_eps, paper.lam, paper.update_epochs,
            paper.gamma, paper.decisions_per_update) == (256, 2, 3e-4, 0.01, 0.2, 0.95, 3, 0.99, 11 * 256)
    f = tmp_path / "c.json"
    f.write_text(json.dumps({"hidden": 24, "skill_ranges": [5, 9]}))
    cfg = load_config("cpu", f, total_steps=123)
    assert cfg.hidden == 24 and cfg.skill_ranges == (5.0, 9.0) and cfg.total_steps == 123
    assert Config.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(ValueError, match="unknown keys"):
        Config.from_dict({"hiden": 3})




def test_end_to_end_train_resume_and_checkpoint(tmp_path, capsys):
    cfg = TINY
    keys = jax.random.split(jax.random.PRNGKey(0), 2)
    # make_train: a whole run, two seeds vmapped in one call (traced abstractly: shapes only).
    runner, metrics = jax.eval_shape(jax.vmap(make_train(cfg)), keys)
    assert metrics["loss"].shape == (2, cfg.num_chunks)
    assert runner.obs.self_features.shape == (2, cfg.n_arenas, 3, 25)

    # Chunks as the CLI runs them (compiled once, from the runner's shapes: a restored runner is
    # committed to its device and a fresh one is not, trainers.loop); interrupt after one chunk,
    # checkpoint, restore, go on: the resumed run matches the uninterrupted one exactly.
    trainer = make_trainer(cfg)
    init = jax.jit(jax.vmap(trainer.init))
    r0 = init(keys)
    chunk = jax.jit(jax.vmap(trainer.chunk)).lower(jax.eval_shape(init, keys)).compile()
    r1, m1 = chunk(r0)
    straight, m_straight = chunk(r1)
    assert m1["loss"].shape == (2,) and int(straight.update[0]) == cfg.num_updates
    diagnostics = ("entropy", "approx_kl", "clip_frac", "value_explained_variance", "baseline_explained_variance",
                   "grad_norm")
    assert all(m1[k].shape == (2,) for k in diagnostics)  # the learner's diagnostics, per chunk and seed
    assert (np.asarray(m1["grad_norm"]) > 0).all() and (np.asarray(m1["value_explained_variance"]) <= 1).all()
    assert all(np.isfinite(np.asarray(x)).all() for x in jax.tree.leaves((m1, m_straight, straight.params)))
    assert set(np.unique(np.asarray(straight.skills))) <= {9.0, 13.0}
    # every finished episode is counted in its arena (the range redraw cadence, next_draws)
    assert np.array_equal(np.asarray(straight.episode.sum(1)), np.asarray(m1["episodes"] + m_straight["episodes"]))
    assert not np.array_equal(np.asarray(straight.params["actor"]["params"]["pi"]["kernel"]),
                              np.asarray(r0.params["actor"]["params"]["pi"]["kernel"]))
    ckpt = tmp_path / "checkpoints"
    checkpoint.save(ckpt, r1, r1.params["actor"], cfg.to_dict(), {"chunk": 1, "update": 2, "env_steps": 64,
                                                              "seconds": 1.0})
    restored, cfg2, meta = checkpoint.restore(tmp_path, jax.eval_shape(init, keys))
    assert Config.from_dict(cfg2) == cfg and meta["update"] == 2 and checkpoint.latest_step(ckpt) == 2
    for a, b in zip(jax.tree.leaves(r1), jax.tree.leaves(restored), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    resumed, m_resumed = chunk(restored)
    for a, b in zip(jax.tree.leaves((straight, m_straight)), jax.tree.leaves((resumed, m_resumed)), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))

    # The trained team loads as a hashable policy that takes its weights as an argument: every
    # seed's weights share one policy, so playtesting them compiles once.
    policy, w1 = load_policy(tmp_path, seed=1, deterministic=True)
    policy0, w0 = load_policy(tmp_path, seed=0, deterministic=True)
    assert load_policy(tmp_path, seed=0)[0] == policy0  # by default, the run's deterministic_eval (True here)
    assert policy == policy0 and hash(policy) == hash(policy0)
    first = lambda tree: jax.tree.map(lambda x: x[0, 0], tree)  # seed 0, arena 0
    obs, state = first(r0.obs), first(r0.env_state)
    actions = np.asarray(jax.jit(policy)(w1, jax.random.PRNGKey(6), obs, state, raidjax.make_params(skill_range=9.0)))
    assert actions.shape == (3,) and actions.dtype == np.int32
    assert np.asarray(obs.action_mask)[np.arange(3), actions].all()
    content = raidjax.make_params(skill_range=9.0)
    from raidjax.playtest import _playtest

    before = _playtest._cache_size()
    for w in (w0, w1, w0):
        raidjax.playtest(jax.random.key(0), content, policy, 4, weights=w)
    assert _playtest._cache_size() == before + 1

    # The replay command renders the trained team (its weights go to record_episode as an argument).
    from trainers import render_cli as render

    gif = tmp_path / "team.gif"
    render.main(["--policy", str(tmp_path), "--skill-range", "9", "--decisions", "3", "--out", str(gif)])
    assert gif.read_bytes()[:6] == b"GIF89a" and "frames" in capsys.readouterr().out
    with pytest.raises(ValueError, match=r"^--players: value 'warrior mage priest'; allowed: the team .* was trained "
                                         r"for, mage mage mage \(leave --players out to use it\)$"):
        render.main(["--policy", str(tmp_path), "--players", "warrior", "mage", "priest", "--out", str(gif)])

    with pytest.raises(checkpoint.CheckpointError, match="does not exist"):
        load_policy(tmp_path / "nope")
    for bad in (True, 1.5, -1):  # True indexed a new axis in
        with pytest.raises(ValueError, match=rf"^seed: value {bad!r} "):
            load_policy(tmp_path, seed=bad)
    with pytest.raises(checkpoint.CheckpointError, match="seed: 2 not in the checkpoint's 2 seeds"):
        load_policy(tmp_path, seed=2)
    (tmp_path / "empty").mkdir()
    with pytest.raises(checkpoint.CheckpointError, match="no finished checkpoint"):
        load_policy(tmp_path / "empty")
    checkpoint.save(ckpt, straight, straight.params["actor"], cfg.to_dict(), {"chunk": 2, "update": 4})
    for step in (4, 2):
        for f in (ckpt / str(step) / "policy").rglob("*"):  # corrupt every file of the policy item
            if f.is_file():
                f.write_bytes(b"garbage")
        if step == 4:  # the older intact checkpoint is used, with a warning naming the bad one
            load_policy(tmp_path)
            assert f"warning: checkpoint {ckpt / str(step)} is corrupted" in capsys.readouterr().err
    with pytest.raises(checkpoint.CheckpointError, match="no intact checkpoint"):
        load_policy(tmp_path)


def test_range_table_tiles_sets_uniformly():
    from trainers.curriculum import RANGE_TABLE, range_table

    for ranges in [(5.0,), (5.0, 9.0), (5.0, 9.0, 13.0), (5.0, 9.0, 13.0, 17.0)]:
        t = np.asarray(range_table(ranges))
        assert t.shape == (RANGE_TABLE,)
        values, counts = np.unique(t, return_counts=True)
        np.testing.assert_array_equal(values, sorted(ranges))
        assert np.all(counts == RANGE_TABLE // len(ranges))  # every value equally likely
    t = np.asarray(range_table((1.0, 2.0, 3.0, 4.0, 5.0)))  # any count: the table grows to lcm(5, 12)
    assert t.shape == (60,) and np.all(np.unique(t, return_counts=True)[1] == 12)
    with pytest.raises(ValueError, match="skill_ranges: 5 values"):
        range_table((1.0, 2.0, 3.0, 4.0, 5.0), size=RANGE_TABLE)


@pytest.mark.parametrize("field,value,allowed", [
    ("n_arenas", 0, "a whole number >= 1"), ("lr", "1e-3", "a number"), ("anneal_lr", 1, "true or false"),
    ("total_steps", True, "a whole number"), ("gamma", 1.5, "a number in [0, 1]"), ("lr", 0.0, "a number > 0"),
    ("skill_ranges", "13", "a non-empty list of numbers in [1, 20]"), ("skill_ranges", [], "a non-empty list"),
    ("eval_games", -1, "a whole number >= 0"), ("ent_coef", float("nan"), "a number"),
    ("fresh_starts", 1.5, "a number in [0, 1]")])
def test_config_rejects_wrong_types_and_values_naming_the_field(field, value, allowed):
    with pytest.raises(ValueError, match=f"^{field}: value {re.escape(repr(value))}.*allowed: {re.escape(allowed)}"):
        Config().replace(**{field: value})
    assert Config().replace(skill_ranges=[9, 13]).skill_ranges == (9.0, 13.0)  # JSON ints are fine


@pytest.mark.parametrize("shape", [(20, 64), (64, 64), (64, 20), (64, 1), (3, 4, 5)])
def test_orthogonal_init_is_flaxs_without_qr(shape):
    """``trainers.networks.orthogonal`` draws flax's orthogonal matrices (same key, same matrix up
    to float32 rounding), and the vmapped initialisation of several PPO-PCGRL learners (Benchmark
    2's paper models) holds no QR: XLA:CPU's batched LAPACK QR deadlocked on 2 cores."""
    from trainers.networks import orthogonal
    from trainers.ppo_pcgrl import ActorCritic

    key = jax.random.key(3)
    mine, flax_ = orthogonal(1.3)(key, shape), nn.initializers.orthogonal(1.3)(key, shape)
    np.testing.assert_allclose(mine, flax_, atol=1e-5)
    net = ActorCritic((32, 32))
    init = jax.vmap(lambda k: net.init(k, jnp.zeros((7,))))
    program = str(jax.make_jaxpr(init)(jax.random.split(key, 7)))
    assert not re.search(r"\b(qr|geqrf|householder_product|orgqr)\b", program)


def _ended_arenas(n: int = 3):
    """``(params [n], state [n], actions, keys)``: arenas 0 and 2 one decision from their time limit
    (a step ends them in a draw); ``keys`` as ``step_autoreset`` splits ``split(PRNGKey(5), n)``."""
    params = jax.vmap(lambda _: raidjax.make_params(skill_range=13.0))(jnp.arange(n))
    _, state = jax.vmap(raidjax.reset)(jax.random.split(jax.random.PRNGKey(0), n), params)
    last = params.config.max_decisions - 1
    state = state.replace(decision=jnp.where(jnp.array([True, False, True]), last, state.decision))
    keys = jax.vmap(jax.random.split)(jax.random.split(jax.random.PRNGKey(5), n))  # [n, 2 (step, next), 2]
    actions = jnp.zeros((n, 3), jnp.int32)
    return params, state, actions, keys


def test_begin_episodes_is_step_autoreset_second_half():
    """p = 0, the content unchanged: ``step`` then ``begin_episodes`` hand back what
    ``step_autoreset`` does, bit for bit (the trainer's auto-reset plays the same games)."""
    params, state, actions, keys = _ended_arenas()
    arena_keys = jax.random.split(jax.random.PRNGKey(5), 3)  # step_autoreset splits each as keys holds it
    obs_a, state_a, _, done_a, _ = jax.vmap(raidjax.step_autoreset)(arena_keys, state, actions, params)
    final, stepped, _, done, _ = jax.vmap(raidjax.step)(keys[:, 0], state, actions, params)
    state_b, obs_b = jax.jit(begin_episodes, static_argnums=2)(keys[:, 1], jax.random.PRNGKey(7), 0.0, done, stepped,
                                                                params)
    assert np.asarray(done).tolist() == [True, False, True] == np.asarray(done_a).tolist()
    for a, b in zip(jax.tree.leaves((obs_a, state_a)), jax.tree.leaves((obs_b, state_b)), strict=True):
        np.testing.assert_array_equal(a, b)


def test_begin_episodes_fresh_start_resets_only_drawn_arenas_that_ended():
    """p = 1: every arena whose episode ended starts as ``raidjax.reset`` with the drawn key would
    (no carried timer), the others keep the stepped state; the observation is the state's."""
    params, state, actions, keys = _ended_arenas()
    _, stepped, _, done, _ = jax.vmap(raidjax.step)(keys[:, 0], state, actions, params)
    carried = stepped.replace(recharging=jnp.ones_like(stepped.recharging),
                              recharge_left=jnp.full_like(stepped.recharge_left, 3.0))
    fresh_key = jax.random.PRNGKey(7)
    new_state, new_obs = jax.jit(begin_episodes, static_argnums=2)(keys[:, 1], fresh_key, 1.0, done, carried, params)
    _, k_reset = jax.random.split(fresh_key)
    _, state_f = jax.vmap(raidjax.reset)(jax.random.split(k_reset, 3), params)
    for i, want in ((0, state_f), (1, carried), (2, state_f)):
        for a, b in zip(jax.tree.leaves(jax.tree.map(lambda x, i=i: x[i], new_state)),
                        jax.tree.leaves(jax.tree.map(lambda x, i=i: x[i], want)), strict=True):
            np.testing.assert_array_equal(a, b)
    assert not bool(new_state.recharging[0].any()) and bool(new_state.recharging[1].all())
    for a, b in zip(jax.tree.leaves(new_obs), jax.tree.leaves(jax.vmap(raidjax.observe)(new_state, params)),
                    strict=True):
        np.testing.assert_array_equal(a, b)


def test_random_spawns_train_on_drawn_openings_and_leave_the_content_as_given():
    cfg = TINY.replace(senses="reference", random_spawns=True)
    given = raidjax.make_params(skill_range=9.0)
    trained = training_content(cfg, given)
    assert trained.config.random_spawns and trained.config.observation == "reference"
    assert not given.config.random_spawns  # what evaluation plays
    runner = jax.jit(make_trainer(cfg).init)(jax.random.PRNGKey(0))
    pos = np.asarray(runner.env_state.pos)  # [arenas, units, 2]: each arena drew its own opening
    assert len({tuple(np.round(p.ravel(), 4)) for p in pos}) == cfg.n_arenas
    assert not training_content(TINY, given).config.random_spawns
