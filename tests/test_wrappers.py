"""The JaxMARL and gymnax wrappers against the real packages (``pip install -e ".[dev]"`` brings
them): shapes and spaces, content kept per arena through auto-resets, per-agent infos, and a few
PPO updates through each (PureJaxRL/JaxMARL-IPPO style) that must raise the probability of the
one action that wins."""

from __future__ import annotations

import flax.linen as flax_nn
import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

import raidjax
from raidjax.types import CAST_1, DRAW, N_ACTIONS, WIN
from raidjax.wrappers import gymnax as gymnax_env
from raidjax.wrappers import jaxmarl as jaxmarl_env

SHORT = raidjax.EnvConfig(max_decisions=8, n_substeps=1)
# Casting slot 1 wins at once: the boss has 1 HP and is in range of the spawn row (18 units away),
# the skill hits instantly and the boss does no damage. Anything else runs to an 8-decision draw.
ONE_CAST_WINS = raidjax.make_params(
    config=SHORT, skill_range=20.0, **{"skill1.projectile_speed": 0.0, "skill1.cast_time": 0.0},
    boss_overrides={"max_hp": 1, "skill1.coefficient": 0.0, "skill2.coefficient": 0.0})
NOBODY_HURTS = raidjax.make_params(config=SHORT, boss_overrides={"skill1.coefficient": 0.0, "skill2.coefficient": 0.0},
                                   **{"skill1.coefficient": 0.0})


def stack(*trees):
    return jax.tree.map(lambda *x: jnp.stack(x), *trees)


# ---------------------------------------------------------------- JaxMARL
def test_jaxmarl_env_shapes_spaces_and_per_agent_infos():
    from jaxmarl.environments.multi_agent_env import MultiAgentEnv

    env = jaxmarl_env.RaidMultiAgentEnv(ONE_CAST_WINS)
    assert isinstance(env, MultiAgentEnv) and env.num_agents == 3 and env.agents == ["player_0", "player_1", "player_2"]
    d = raidjax.spaces(ONE_CAST_WINS).flat_observation.shape[-1]
    obs, state = env.reset(jax.random.key(0))
    assert {a: o.shape for a, o in obs.items()} == dict.fromkeys(env.agents, (d,))
    assert env.observation_space("player_0").shape == (d,) and env.action_space("player_1").n == N_ACTIONS
    avail = env.get_avail_actions(state)
    assert avail["player_0"].shape == (N_ACTIONS,) and bool(avail["player_0"][CAST_1])
    cast = dict.fromkeys(env.agents, jnp.int32(CAST_1))
    obs2, state2, rewards, dones, infos = env.step(jax.random.key(1), state, cast)
    assert bool(dones["__all__"]) and all(bool(dones[a]) for a in env.agents)
    for name, v in infos.items():
        assert v.shape == (3,), name  # one value per agent
    assert (np.asarray(infos["result"]) == WIN).all() and np.asarray(infos["terminated"]).all()
    assert all(float(rewards[a]) >= 1.0 for a in env.agents)  # the win bonus to every player
    assert int(state2.game.result) == 0 and int(state2.time) == 0  # auto-reset to the next episode
    # The step is raidjax.step_autoreset's: same key, same observation (to rounding: GAME.md §1).
    ref_obs, *_ = raidjax.step_autoreset(jax.random.key(1), state.game, jnp.full(3, CAST_1), ONE_CAST_WINS)
    np.testing.assert_allclose(np.asarray(obs2["player_2"]), np.asarray(ref_obs.flat()[2]), atol=1e-6)  # jit vs eager
    with pytest.raises(ValueError, match="actions: dtype"):
        env.step(jax.random.key(1), state, dict.fromkeys(env.agents, jnp.float32(7)))


def test_jaxmarl_content_stays_per_arena_through_auto_resets():
    env = jaxmarl_env.RaidMultiAgentEnv(ONE_CAST_WINS)
    contents = stack(ONE_CAST_WINS, NOBODY_HURTS)
    _, state = jax.vmap(env.reset)(jax.random.split(jax.random.key(0), 2), contents)
    cast = dict.fromkeys(env.agents, jnp.full(2, CAST_1, jnp.int32))
    step = jax.jit(jax.vmap(env.step))
    results = []
    for t in range(20):  # arena 0 wins every decision; arena 1 draws every 8 decisions
        _, state, _, _, infos = step(jax.random.split(jax.random.key(t + 1), 2), state, cast)
        results.append(np.asarray(infos["result"])[:, 0])
    results = np.stack(results)
    assert (results[:, 0] == WIN).all()
    assert (results[7::8, 1] == DRAW).all() and (results[:, 1] == DRAW).sum() == 2
    for a, b in zip(jax.tree.leaves(state.params), jax.tree.leaves(contents), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


# ---------------------------------------------------------------- gymnax
def test_gymnax_views_shapes_spaces_and_rewards():
    from gymnax.environments.environment import Environment

    d = raidjax.spaces(ONE_CAST_WINS).flat_observation.shape[-1]
    team = gymnax_env.RaidTeamEnv(ONE_CAST_WINS)
    player = gymnax_env.RaidPlayerEnv(ONE_CAST_WINS, player=1, teammates=raidjax.policies.noop)
    assert isinstance(team, Environment) and isinstance(player, Environment)
    assert team.action_space().n == N_ACTIONS**3 and team.observation_space().shape == (3 * d,)
    assert player.action_space().n == N_ACTIONS and player.observation_space().shape == (d,)
    np.testing.assert_array_equal(np.asarray(team.decode(jnp.int32(7 + 10 * 3 + 100 * 9))), [7, 3, 9])
    params = team.default_params
    obs, state = team.reset(jax.random.key(0), params)
    assert obs.shape == (3 * d,)
    # Only player 1 casts (joint id 10 * CAST_1): the team wins, rewarded once for the team.
    obs, state, reward, terminated, truncated, info = team.step(jax.random.key(1), state, 10 * CAST_1, params)
    assert bool(terminated) and not bool(truncated) and int(info["result"]) == WIN
    dealt = float(np.asarray(info["damage_dealt"]).sum())
    assert dealt > 0 and float(reward) == pytest.approx(0.01 * dealt + 1.0)
    assert info["final_observation"].shape == (3 * d,)
    # The player view: the learner's no-op next to no-op teammates runs to the draw.
    obs, state = player.reset(jax.random.key(0), params)
    for t in range(8):
        obs, state, reward, terminated, truncated, info = player.step(jax.random.key(t), state, 0, params)
    assert bool(truncated) and not bool(terminated) and float(reward) == 0.0
    with pytest.raises(ValueError, match="player: value 3"):
        gymnax_env.RaidPlayerEnv(ONE_CAST_WINS, player=3)


def test_jaxmarl_actions_of_shape_one_and_the_reference_spaces():
    env = jaxmarl_env.RaidMultiAgentEnv(ONE_CAST_WINS)
    _, state = env.reset(jax.random.key(0))
    as_scalar = env.step(jax.random.key(1), state, dict.fromkeys(env.agents, jnp.int32(CAST_1)))
    as_one = env.step(jax.random.key(1), state, dict.fromkeys(env.agents, jnp.array([CAST_1])))
    for a, b in zip(jax.tree.leaves(as_scalar), jax.tree.leaves(as_one), strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match=r"^actions\['player_0'\]: shape \[2\]; allowed: \[\] or \[1\]"):
        env.step_env(jax.random.key(1), state, dict.fromkeys(env.agents, jnp.array([CAST_1, 0])))
    ref = jaxmarl_env.RaidMultiAgentEnv(raidjax.make_params(observation="reference", action_space="reference"))
    obs, state = ref.reset(jax.random.key(0))
    assert ref.action_space("player_0").n == 8 and obs["player_1"].shape == (204,) and ref.obs_dim == 204
    assert ref.get_avail_actions(state)["player_2"].shape == (8,)
    team = gymnax_env.RaidTeamEnv(raidjax.make_params(action_space="reference"))
    assert team.num_actions == 8**3 and team.decode(jnp.int32(7 + 8 * 3)).tolist() == [7, 3, 0]


# ---------------------------------------------------------------- a few PPO updates through each
class Net(flax_nn.Module):
    @flax_nn.compact
    def __call__(self, x):
        h = flax_nn.tanh(flax_nn.Dense(32)(x))
        return flax_nn.Dense(N_ACTIONS)(h), flax_nn.Dense(1)(h)[..., 0]


def ppo(env_reset, env_step, obs_dim: int, n_envs=16, n_steps=8, n_updates=6, lr=1e-2):
    """A minimal PPO (clipped objective, GAE, one shared MLP over ``N_ACTIONS``), PureJaxRL style:
    ``env_reset(keys) -> (obs [A, obs_dim], state)``, ``env_step(keys, state, actions [A]) ->
    (obs, state, reward [A], done [A])`` over ``A`` actors. Returns the policy's probability of
    ``CAST_1`` at the first observation, before and after training, and the loss per update."""
    net, tx = Net(), optax.adam(lr)
    key = jax.random.key(0)
    obs, state = env_reset(jax.random.split(key, n_envs))
    weights = net.init(key, obs)
    opt = tx.init(weights)
    first = obs

    def rollout(carry, k):
        weights, obs, state = carry
        logits, value = net.apply(weights, obs)
        ka, ks = jax.random.split(k)
        action = jax.random.categorical(ka, logits)
        logp = jax.nn.log_softmax(logits)[jnp.arange(obs.shape[0]), action]
        obs2, state, reward, done = env_step(jax.random.split(ks, n_envs), state, action)
        return (weights, obs2, state), (obs, action, logp, value, reward, done)

    def update(carry, k):
        weights, opt, obs, state = carry
        keys = jax.random.split(k, n_steps)
        (_, obs, state), (o, a, lp, v, r, d) = jax.lax.scan(rollout, (weights, obs, state), keys)
        _, last_v = net.apply(weights, obs)

        def gae(carry, x):
            adv, nxt = carry
            r, d, v = x
            delta = r + 0.99 * nxt * (1 - d) - v
            adv = delta + 0.99 * 0.95 * (1 - d) * adv
            return (adv, v), adv

        _, adv = jax.lax.scan(gae, (jnp.zeros_like(last_v), last_v), (r, d.astype(jnp.float32), v), reverse=True)
        target = adv + v

        def loss(w):
            logits, value = net.apply(w, o)
            new_lp = jnp.take_along_axis(jax.nn.log_softmax(logits), a[..., None], -1)[..., 0]
            ratio = jnp.exp(new_lp - lp)
            nadv = (adv - adv.mean()) / (adv.std() + 1e-8)
            pg = -jnp.minimum(ratio * nadv, jnp.clip(ratio, 0.8, 1.2) * nadv).mean()
            return pg + 0.5 * ((value - target) ** 2).mean()

        value, grads = jax.value_and_grad(loss)(weights)
        upd, opt = tx.update(grads, opt)
        return (optax.apply_updates(weights, upd), opt, obs, state), value

    p_cast = lambda w: jax.nn.softmax(net.apply(w, first)[0])[:, CAST_1].mean()
    before = p_cast(weights)
    (weights, *_), losses = jax.jit(lambda c: jax.lax.scan(update, c, jax.random.split(key, n_updates)))(
        (weights, opt, obs, state))
    return float(before), float(p_cast(weights)), np.asarray(losses)


def test_ippo_through_the_jaxmarl_wrapper_learns_to_cast():
    """JaxMARL IPPO's shape: JaxMARL's own ``LogWrapper``, agents batched into actors
    (``NUM_ACTORS = n_envs * P``), one shared net."""
    from jaxmarl.wrappers.baselines import LogWrapper

    env = LogWrapper(jaxmarl_env.RaidMultiAgentEnv(ONE_CAST_WINS))
    batchify = lambda x: jnp.stack([x[a] for a in env.agents]).reshape(-1, *x[env.agents[0]].shape[1:])

    def reset(keys):
        obs, state = jax.vmap(env.reset)(keys)
        return batchify(obs), state

    def step(keys, state, actions):
        # JaxMARL's unbatchify (baselines/IPPO/ippo_ff_mpe.py) hands every agent int[1] per env.
        acts = actions.reshape(env.num_agents, -1, 1)
        per_agent = {a: acts[i] for i, a in enumerate(env.agents)}
        obs, state, rewards, dones, infos = jax.vmap(env.step)(keys, state, per_agent)
        assert infos["returned_episode_returns"].shape == (keys.shape[0], env.num_agents)  # reshapes to NUM_ACTORS
        return batchify(obs), state, batchify(rewards), batchify(dones)

    before, after, losses = ppo(reset, step, env.obs_dim)
    assert np.isfinite(losses).all()
    assert before < 0.2 and after > before + 0.1, (before, after)


def test_ppo_through_the_gymnax_player_view_learns_to_cast():
    env = gymnax_env.RaidPlayerEnv(ONE_CAST_WINS, teammates=raidjax.policies.noop)
    params = env.default_params

    def reset(keys):
        return jax.vmap(env.reset, (0, None))(keys, params)

    def step(keys, state, actions):
        obs, state, reward, terminated, truncated, _ = jax.vmap(env.step, (0, 0, 0, None))(keys, state, actions, params)
        return obs, state, reward, terminated | truncated

    before, after, losses = ppo(reset, step, env.obs_dim)
    assert np.isfinite(losses).all()
    assert before < 0.2 and after > before + 0.1, (before, after)

