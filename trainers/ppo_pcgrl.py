"""PPO-PCGRL (controllable PCGRL, GAME.md §10) on ``raidjax.pcg``: a PureJaxRL-style, scan-based learner.

``make_train(config) -> train(key, target=None)``: the whole run as one jittable function
(vmappable over seeds and, in the per-target mode, over targets). Its config is
``trainers.config.PPOConfig``; ``trainers.runs.run_ppo_pcgrl`` runs the same update in chunks
with progress, metrics and checkpoints (``raidjax train ppo-pcgrl`` on the command line)::

    python -m trainers.ppo_pcgrl_cli --preset cpu --total-steps 8192 --seeds 1 --out runs/ppo_cpu
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from functools import cache
from typing import Any, NamedTuple

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import optax

from raidjax import pcg, policies, xla_flags
from trainers import draws
from trainers.config import PPOConfig
from trainers.gradients import clip_by_global_norm
from trainers.networks import orthogonal


class ActorCritic(nn.Module):
    """MLP actor (``n_params`` branches x 5 logits) and MLP critic on a ``float32[D]`` observation."""

    hidden: tuple = (64, 64)
    n_params: int = pcg.env.N_PARAMS

    @nn.compact
    def __call__(self, x):
        """Returns ``(logits float32[..., n_params, 5], value float32[...])``."""
        def mlp(h, name):
            for i, n in enumerate(self.hidden):
                h = nn.tanh(nn.Dense(n, kernel_init=orthogonal(np.sqrt(2)), name=f"{name}{i}")(h))
            return h

        logits = nn.Dense(self.n_params * pcg.env.N_CHOICES, kernel_init=orthogonal(0.01),
                          name="pi")(mlp(x, "a"))
        value = nn.Dense(1, kernel_init=orthogonal(1.0), name="v")(mlp(x, "c"))
        return logits.reshape(x.shape[:-1] + (self.n_params, pcg.env.N_CHOICES)), value[..., 0]


class Transition(NamedTuple):
    """One rollout step of ``N = n_arenas`` generator episodes (``[T, N, ...]`` once stacked by the
    rollout scan, ``[T * N, ...]`` in the minibatches; ``K = config.space.size``).

    Attributes:
        obs: ``float32[N, obs_size]`` observation acted on.
        action: ``int32[N, K]`` choices in 0..4.
        logp: ``float32[N]`` joint log-probability of ``action``.
        value: ``float32[N]`` critic value of ``obs``.
        reward: ``float32[N]`` shaped reward: ``(env reward - edit_penalty * valid) * reward_scale``.
        done: ``bool[N]`` the episode ended with this step.
        valid: ``bool[N]`` an edit, not a reset call (``info["valid"]``); the loss masks the rest.
    """

    obs: jax.Array
    action: jax.Array
    logp: jax.Array
    value: jax.Array
    reward: jax.Array
    done: jax.Array
    valid: jax.Array


def env_params(config: PPOConfig, target=None, tester: Callable = policies.heuristic,
               tester_weights: Any = None) -> pcg.PCGParams:
    """``PCGParams`` for training; ``target`` (``float32[2]`` low/high, traced ok) overrides the
    config; ``tester`` / ``tester_weights``: the playtesting team (``pcg.PCGParams.tester``; PT-HR
    by default, or e.g. ``trainers.mapoca.load_policy``'s trained team and its weights)."""
    p = pcg.make_pcg_params(target=tuple(config.target), n_games=config.n_games, max_edits=config.max_edits,
                            strict_length=config.strict_length, observe_target=config.observe_target,
                            pool_repeats=config.pool_repeats, goal_axis=config.goal_axis, tester=tester,
                            tester_weights=tester_weights, parameters=config.parameters or None,
                            players=config.players)
    if target is not None:
        target = jnp.asarray(target, jnp.float32)
        p = p.replace(target_low=target[0], target_high=target[1])
    return p


def edit_penalty(config: PPOConfig, action: jax.Array, old: pcg.PCGState, new: pcg.PCGState) -> jax.Array:
    """Learner-side cost of one edit in env reward units: ``edit_cost`` per tick of ``action``
    (``int32[..., K]``, ``K = config.space.size``), plus ``goal_cost`` times the change of the
    squared distance to the goal from ``old`` to ``new`` (``PCGState`` with matching batch shape);
    over an episode the goal part sums to ``goal_cost`` times the final minus the start squared
    distance to the goal.
    Returns ``float32[...]`` (meaningless on reset transitions, which the learner masks)."""
    ticks = jnp.abs(jnp.asarray(pcg.env.TICK_FRACTIONS)[action]).sum(-1)
    space = config.space
    to_goal = pcg.goals.squared_ticks(new.skill, new.goal, space) - pcg.goals.squared_ticks(old.skill, old.goal, space)
    return config.edit_cost * ticks + config.goal_cost * to_goal


def _logp_entropy(logits, action):
    """Joint log-probability and entropy of the K independent branches (``logits float32[..., K, 5]``,
    ``action int32[..., K]``): ``float32[...]`` each."""
    lp = jax.nn.log_softmax(logits)
    logp = jnp.take_along_axis(lp, action[..., None], -1)[..., 0].sum(-1)
    ent = (-(jnp.exp(lp) * lp).sum(-1)).sum(-1)
    return logp, ent


def make_train(config: PPOConfig, tester: Callable = policies.heuristic, tester_weights: Any = None):
    """Build the learner.

    Args:
        config: ``PPOConfig``.
        tester, tester_weights: the playtesting team the generator is trained against (see
            ``env_params``; default PT-HR, the paper's).

    Returns:
        ``train(key, target=None) -> (runner, metrics)`` (jittable, vmappable; ``key`` a typed PRNG
        key or a raw ``uint32[2]``; ``target`` ``None``, the config's, or ``float32[2]`` ``(low, high)``
        as in ``env_params``), with helpers as attributes: ``train.init(key, target) -> runner``
        (every arena on an ended placeholder, ``raidjax.pcg.env.awaiting_reset``: its first rollout
        step is its reset) and ``train.update(runner, target, weights=tester_weights) -> (runner,
        metrics)`` (one PPO update; ``weights``: the tester's, an argument so that a program given
        them as one plays other weights of the same shapes without compiling again). ``runner`` is a dict pytree
        (``params``, ``opt_state``, ``env_state`` ``PCGState [N]``, ``obs`` ``float32[N, obs_size]``,
        ``key`` ``uint32[2]`` key data, ``update`` ``int32[]``); ``metrics`` holds per-update scalars,
        ``float32[]`` (``episodes``: ``int32[]``; ``final_error``, ``edits``, ``yield``: NaN when no
        episode ended), ``[num_updates]`` in ``train``.

    Warns (``RuntimeWarning``) on CPU when ``XLA_FLAGS`` lacks
    ``--xla_cpu_enable_concurrency_optimized_scheduler=false``: several learners vmapped together
    can deadlock XLA:CPU without it (``raidjax.use_recommended_xla_flags``).
    """
    if any("concurrency_optimized" in f for f in xla_flags.missing()) and jax.default_backend() == "cpu":
        warnings.warn("vmapping several PPO-PCGRL learners can deadlock XLA:CPU's concurrency-optimised "
                      "scheduler; call raidjax.use_recommended_xla_flags() before the first JAX computation "
                      "(raidjax.xla_flags)", RuntimeWarning, stacklevel=2)
    net = ActorCritic(config.widths, config.space.size)
    batch = config.n_arenas * config.n_steps
    mb = batch // config.n_minibatches

    def schedule(count):
        frac = 1.0 - count // (config.n_minibatches * config.update_epochs) / config.num_updates
        return config.lr * (frac if config.anneal_lr else 1.0)

    tx = optax.chain(clip_by_global_norm(config.max_grad_norm), optax.adam(schedule, eps=1e-5))

    def init(key, target=None):
        p = env_params(config, target, tester, tester_weights)
        k_net, k_env, k_run = jax.random.split(key, 3)
        params = net.init(k_net, jnp.zeros((pcg.env.obs_size(p),)))
        # Every arena starts on an ended placeholder, so the first rollout step is its reset
        # (measured, not trained on): this program plays no game and compiles in seconds.
        del k_env  # kept so that the other keys are as they were
        obs, env_state = jax.tree.map(lambda x: jnp.broadcast_to(x, (config.n_arenas,) + x.shape),
                                      pcg.env.awaiting_reset(p))
        return {"params": params, "opt_state": tx.init(params), "env_state": env_state, "obs": obs,
                "key": jax.random.key_data(k_run), "update": jnp.int32(0)}

    def update(runner, target=None, weights=tester_weights):
        p = env_params(config, target, tester, weights)
        key = jax.random.wrap_key_data(runner["key"])
        key, k_roll, k_perm = jax.random.split(key, 3)
        params = runner["params"]

        def env_step(carry, k):
            obs, st = carry
            ka, ke = jax.random.split(k)
            logits, value = net.apply(params, obs)
            action = draws.categorical(ka, logits).astype(jnp.int32)
            logp, _ = _logp_entropy(logits, action)
            obs2, st2, r, done, info = jax.vmap(lambda kk, s, a: pcg.step_autoreset(kk, s, a, p))(
                jax.random.split(ke, config.n_arenas), st, action)
            shaped = (r - edit_penalty(config, action, st, st2) * info["valid"]) * config.reward_scale
            tr = Transition(obs, action, logp, value, shaped, done, info["valid"])
            ended = done & info["valid"]
            return (obs2, st2), (tr, ended, info["final_error"], info["edits"], info["reached"], r)

        (obs, env_state), (trs, ended, ferr, edits, reached, raw_r) = jax.lax.scan(
            env_step, (runner["obs"], runner["env_state"]), jax.random.split(k_roll, config.n_steps))
        _, last_v = net.apply(params, obs)

        def gae(carry, tr):
            adv, v_next = carry
            nonterm = 1.0 - tr.done
            delta = tr.reward + config.gamma * v_next * nonterm - tr.value
            adv = delta + config.gamma * config.lam * nonterm * adv
            return (adv, tr.value), adv

        _, advs = jax.lax.scan(gae, (jnp.zeros_like(last_v), last_v), trs, reverse=True)
        targets = advs + trs.value
        flat = jax.tree.map(lambda x: x.reshape((batch,) + x.shape[2:]), (trs, advs, targets))

        def loss_fn(params, tr, adv, ret):
            logits, v = net.apply(params, tr.obs)
            logp, ent = _logp_entropy(logits, tr.action)
            w = tr.valid.astype(jnp.float32)
            wsum = jnp.maximum(w.sum(), 1.0)
            mean = lambda x: (x * w).sum() / wsum
            a_mu = mean(adv)
            adv = (adv - a_mu) / (jnp.sqrt(mean((adv - a_mu) ** 2)) + 1e-8)
            ratio = jnp.exp(logp - tr.logp)
            pg = -mean(jnp.minimum(ratio * adv, jnp.clip(ratio, 1 - config.clip_eps, 1 + config.clip_eps) * adv))
            v_clip = tr.value + jnp.clip(v - tr.value, -config.clip_eps, config.clip_eps)
            vl = 0.5 * mean(jnp.maximum((v - ret) ** 2, (v_clip - ret) ** 2))
            entropy = mean(ent)
            return pg + config.vf_coef * vl - config.ent_coef * entropy, (pg, vl, entropy)

        def epoch(carry, k):
            params, opt_state = carry
            perm = jax.random.permutation(k, batch)
            shuf = jax.tree.map(lambda x: x[perm].reshape((config.n_minibatches, mb) + x.shape[1:]), flat)

            def minibatch(carry, b):
                params, opt_state = carry
                (_, aux), grads = jax.value_and_grad(loss_fn, has_aux=True)(params, *b)
                upd, opt_state = tx.update(grads, opt_state, params)
                return (optax.apply_updates(params, upd), opt_state), aux

            return jax.lax.scan(minibatch, (params, opt_state), shuf)

        (params, opt_state), aux = jax.lax.scan(epoch, (params, runner["opt_state"]),
                                                jax.random.split(k_perm, config.update_epochs))
        n_end = ended.sum()
        avg = lambda x: jnp.where(n_end > 0, (x * ended).sum() / jnp.maximum(n_end, 1), jnp.nan)
        metrics = {"reward": (raw_r * trs.valid).sum() / jnp.maximum(trs.valid.sum(), 1), "episodes": n_end,
                   "final_error": avg(ferr), "edits": avg(edits), "yield": avg(reached),
                   "pg_loss": aux[0].mean(), "v_loss": aux[1].mean(), "entropy": aux[2].mean()}
        runner = {"params": params, "opt_state": opt_state, "env_state": env_state, "obs": obs,
                  "key": jax.random.key_data(key), "update": runner["update"] + 1}
        return runner, metrics

    def train(key, target=None):
        runner = init(key, target)
        return jax.lax.scan(lambda r, _: update(r, target), runner, None, config.num_updates)

    train.init, train.update, train.net = init, update, net
    return train


@cache
def make_generator_policy(hidden: tuple, greedy: bool = False, n_params: int = pcg.env.N_PARAMS):
    """Generator policy ``policy(net_params, key, obs, state, params) -> int32[n_params]`` for
    ``raidjax.pcg.quality.generate`` (cached, so the same hashable function is reused and jit does
    not recompile). ``greedy`` takes the argmax of each branch (the paper's generation);
    otherwise each branch is sampled."""
    net = ActorCritic(tuple(hidden), n_params)

    def policy(net_params, key, obs, state, params):
        logits, _ = net.apply(net_params, obs)
        action = jnp.argmax(logits, -1) if greedy else draws.categorical(key, logits)
        return action.astype(jnp.int32)

    return policy
