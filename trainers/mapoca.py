"""MA-POCA (Cohen et al. 2021; PROTOCOLS.md §12) as one pure, jittable JAX program, PureJaxRL style.

``make_train(config)(key)`` runs a whole training run on device: ``n_arenas`` auto-resetting
raidjax arenas roll out ``n_steps`` decisions inside ``lax.scan``, λ-returns and counterfactual
advantages are computed, and ``update_epochs x n_minibatches`` Adam steps follow, all inside
one scan over updates. ``make_trainer`` exposes the pieces (``init``, ``update``, ``chunk``) that
the CLI (``trainers.mapoca_cli``) drives chunk by chunk for progress, logs and checkpoints.

Reward (GAME.md §8, PROTOCOLS.md §12). ``raidjax.step`` pays player ``i``: ``r_i = 0.01 d_i + 1.0 w`` (``d_i``
the damage its hits did to the boss this step, ``w`` = the boss died this step). MA-POCA
trains every agent on its own + its teammates' individual rewards + the group reward, i.e. on
the one team reward ``r = 0.01 sum_i d_i + 1.0 w = sum_i r_i - (P - 1) w`` (the win bonus is a
group reward, paid once, not once per player). Where no player dies mid-game every agent has the
same λ-return G_t (``episode_ends`` ``"terminal"`` and ``"win_bootstrapped"``: always).

Returns (``trainers.returns``). How a game's end reaches the λ-returns is ``Config.episode_ends``:
under ``"reference"`` (the default, as ML-Agents 0.28 POCA trains the reference build) a win and a
timeout bootstrap from the value of the final observation, a loss does not, and a player who dies
while its teammates fight on ends its own trajectory there with a bootstrap, so every agent has its
own return ``G_ti``. Agent i's advantage is ``A_ti = G_ti - b_ti`` (counterfactual baseline),
defined where agent i acted (was alive at t), normalised over those entries of the whole update.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import optax
from flax import struct

import raidjax
from raidjax import pcg, validate
from raidjax.env import team_reward
from raidjax.types import LOSS, WIN, Observation, Params, State
from trainers import checkpoint, windows
from trainers.config import Config
from trainers.curriculum import begin_episodes, draw_skills, next_draws, range_table, training_content, with_drawn
from trainers.gradients import clip_by_global_norm, global_norm
from trainers.networks import Actor, Critic, sample_actions
from trainers.poca_loss import Batch, loss_fn
from trainers.reference_networks import ReferenceActor, ReferenceCritic
from trainers.returns import advantages, explained_variance, game_returns, last_seen


@struct.dataclass
class Runner:
    """Training state of one seed (``N`` arenas, ``P`` players); a pytree, checkpointed whole."""

    params: dict  # {"actor": ..., "critic": ...} network weights
    opt_state: Any
    env_state: State  # [N]
    obs: Observation  # [N, P, ...]
    content: Params  # the run's base content (unbatched); each episode sets its players' skill slot 1
    range_set: jax.Array  # float32[RANGE_TABLE] skill ranges drawn from (see range_table)
    skills: jax.Array  # float32[N, K] drawn content of each arena's current episode (see with_drawn)
    episode: jax.Array  # int32[N] episodes each arena has finished (the redraw cadence)
    ep_return: jax.Array  # float32[N] team return of the running episodes
    ep_length: jax.Array  # int32[N]
    key: jax.Array  # PRNG key of the kind train was given: raw uint32[2] or typed
    update: jax.Array  # int32[] updates done


@struct.dataclass
class StaleRunner(Runner):
    """A ``Runner`` with ``Config.stale_phases = K > 1`` (``trainers.windows``): ``N = K * n_arenas``
    arenas and every group's window of acted steps."""

    window: Any = None  # Step arrays [n_steps, K, n_arenas, ...]


@struct.dataclass
class Step:
    """One decision of ``N`` arenas as acted, before the critic values it (a ``Transition``'s inputs)."""

    obs: Observation  # [N, P, ...] observation acted on
    action: jax.Array  # int32[N, P]
    logp: jax.Array  # float32[N, P] log-probability under the acting policy
    final: Observation  # [N, P, ...] the observation after the step, in the same episode
    reward: jax.Array  # float32[N] team reward
    done: jax.Array  # bool[N]
    won: jax.Array  # bool[N]
    lost: jax.Array  # bool[N]


@struct.dataclass
class Transition:
    """One rollout step of ``N`` arenas (a leading ``T`` axis once stacked)."""

    obs: Observation  # [N, P, ...] observation acted on
    action: jax.Array  # int32[N, P] (0 for dead players)
    logp: jax.Array  # float32[N, P] log-probability of the action
    alive: jax.Array  # bool[N, P] agent acted (alive at the observation)
    value: jax.Array  # float32[N] V(s_t)
    baseline: jax.Array  # float32[N, P] b_i(s_t, a_-i)
    next_value: jax.Array  # float32[N] V(s'_t) over the players alive in s'_t (the state after the step, same episode)
    death_value: jax.Array  # float32[N] V(s'_t) over the players that acted (a dying player's bootstrap)
    next_alive: jax.Array  # bool[N, P] alive in s'_t
    reward: jax.Array  # float32[N] team reward
    done: jax.Array  # bool[N] episode ended with this step
    won: jax.Array  # bool[N] ... in a win
    lost: jax.Array  # bool[N] ... in a loss


class Trainer(NamedTuple):
    """The pieces of one configured trainer (all pure; vmap them over seeds).

    init(key) -> Runner; update(runner) -> (runner, metrics); chunk(runner) -> (runner, metrics
    summed/averaged over ``updates_per_chunk`` updates); train(key) -> (runner, per-chunk
    metrics ``[num_chunks]``); collect(runner) -> (runner, Transition ``[n_steps, n_arenas]``, episode
    sums ``[n_steps / stale_phases]``): the rollout an update trains on.
    """

    config: Config
    actor: Actor
    critic: Critic
    init: Any
    update: Any
    chunk: Any
    train: Any
    collect: Any


EPISODE_KEYS = ("episodes", "return_sum", "wins", "draws", "length_sum")


def make_networks(cfg: Config):
    """``(actor, critic)`` flax modules of ``cfg.network``'s layout (``trainers.networks`` or
    ``trainers.reference_networks``; same methods)."""
    dtype = jnp.bfloat16 if cfg.bf16 else jnp.float32
    if cfg.network == "reference":
        return (ReferenceActor(cfg.hidden, cfg.layers, cfg.heads, cfg.proj_attention, dtype),
                ReferenceCritic(cfg.hidden, cfg.layers, cfg.heads, cfg.proj_attention, dtype))
    return Actor(cfg.hidden, cfg.layers, cfg.heads, cfg.proj_attention, dtype), Critic(cfg.hidden, cfg.layers,
                                                                                         cfg.heads, dtype)


def make_trainer(config: Config, base_params: Params | None = None, redraw_ranges: bool | None = None,
                 fixed_content: bool = False) -> Trainer:
    """Build the pure training functions for ``config``.

    Args:
        config: hyper-parameters.
        base_params: default content of ``init`` (default: the reference content; under
            ``config.content_box`` the content generator's, ``raidjax.pcg.base_game()``).
        redraw_ranges: draw new skill ranges (every ``config.redraw_every`` episodes of an
            arena, ``next_draws``; static; default: when ``config.skill_ranges`` has several
            values). ``init(key, content, range_set)`` may give each vmapped run its own content
            and range set; set this ``True`` when any run's set has several values.
        fixed_content: play ``init``'s content exactly as given, with no range or box draw
            (static; e.g. a specialist trained on one generated content).
    """
    cfg = config
    if base_params is not None:
        base = base_params
    else:
        base = (pcg.base_game(cfg.players) if cfg.content_box
                else raidjax.make_params(players=list(cfg.players), skill_range=cfg.skill_ranges[0]))
    base = training_content(cfg, base)
    default_set = range_table(cfg.skill_ranges)
    multi_range = len(cfg.skill_ranges) > 1 if redraw_ranges is None else redraw_ranges
    multi_range = (multi_range or cfg.content_box) and not fixed_content
    actor, critic = make_networks(cfg)
    n, t_len = cfg.n_arenas, cfg.n_steps
    phases = cfg.stale_phases
    n_env, seg = n * phases, t_len // phases  # arenas stepped; decisions per arena and update
    grad_steps = cfg.num_updates * cfg.update_epochs * cfg.n_minibatches
    lr = optax.linear_schedule(cfg.lr, 0.0, grad_steps) if cfg.anneal_lr else cfg.lr
    clip = [clip_by_global_norm(cfg.max_grad_norm)] if cfg.max_grad_norm > 0 else []
    tx = optax.chain(*clip, optax.adam(lr, eps=cfg.adam_eps))
    env_params_of = jax.vmap(lambda content, sk: content if fixed_content else with_drawn(cfg, content, sk),
                             in_axes=(None, 0))
    step_all = jax.vmap(raidjax.step)
    value_rows = "agents" if cfg.episode_ends == "reference" else "decisions"
    by_rows = cfg.minibatch_rows == "agents"
    n_players = len(cfg.players)

    def init(key: jax.Array, content: Params | None = None, range_set: jax.Array | None = None) -> Runner:
        """A fresh runner; ``content`` (unbatched Params) and ``range_set`` (``float32[RANGE_TABLE]``,
        see ``range_table``) default to ``base_params`` and ``config.skill_ranges``."""
        content = base if content is None else training_content(cfg, content)
        range_set = default_set if range_set is None else range_set
        k_a, k_c, k_env, k_rng, k_run = jax.random.split(key, 5)
        skills = draw_skills(k_rng, cfg, range_set, n_env)
        obs, state = jax.vmap(raidjax.reset)(jax.random.split(k_env, n_env), env_params_of(content, skills))
        obs0 = jax.tree.map(lambda x: x[0], obs)
        params = {"actor": actor.init(k_a, obs0),
                  "critic": critic.init(k_c, obs0, jnp.zeros(obs0.alive.shape, jnp.int32))}
        zf = jnp.zeros(n_env, jnp.float32)
        zi = jnp.zeros(n_env, jnp.int32)
        fields = (params, tx.init(params), state, obs, content, range_set, skills, zi, zf, zi, k_run, jnp.int32(0))
        if phases == 1:
            return Runner(*fields)
        runner = StaleRunner(*fields, window=windows.empty(jax.eval_shape(acted_segment, Runner(*fields))[1], phases))
        # The windows start staggered: the K - 1 segments before update 0, with the initial policy.
        return jax.lax.fori_loop(1 - phases, 0, lambda u, r: stale_segment(r, u)[0], runner)

    def act(runner: Runner):
        """``(runner, Step, episode sums)`` of one decision of every arena, acted by ``runner.params``."""
        key, k_act, k_env, k_rng = jax.random.split(runner.key, 4)
        obs = runner.obs
        action, logp = sample_actions(k_act, actor.apply(runner.params["actor"], obs), obs.alive)
        # step_autoreset's keys: each arena's key splits into the step's and the next episode's.
        keys = jax.vmap(jax.random.split)(jax.random.split(k_env, n_env))
        content = env_params_of(runner.content, runner.skills)
        final, state, _, done, info = step_all(keys[:, 0], runner.env_state, action, content)
        # The auto-reset, once: every redraw_every-th finished episode of an arena draws its next
        # skill, then the new episodes begin and are observed under the content they play.
        episode, redrawn = next_draws(runner.episode, done, cfg.redraw_every)
        skills = runner.skills
        if multi_range:
            skills = jnp.where(redrawn[:, None], draw_skills(k_rng, cfg, runner.range_set, n_env), skills)
            content = env_params_of(runner.content, skills)
        state, nxt = begin_episodes(keys[:, 1], jax.random.fold_in(k_rng, 1), cfg.fresh_starts, done, state, content)
        reward = team_reward(info, done)
        ep_ret, ep_len = runner.ep_return + reward, runner.ep_length + 1
        won = done & (info["result"] == WIN)
        ep = {"episodes": done.sum(), "return_sum": jnp.sum(ep_ret * done), "wins": won.sum(),
              "draws": jnp.sum(done & info["truncated"]), "length_sum": jnp.sum(ep_len * done)}
        step = Step(obs, action, logp, final, reward, done, won, done & (info["result"] == LOSS))
        runner = runner.replace(env_state=state, obs=nxt, skills=skills, episode=episode, key=key,
                                ep_return=jnp.where(done, 0.0, ep_ret), ep_length=jnp.where(done, 0, ep_len))
        return runner, step, ep

    def valued(p: dict, step: Step) -> Transition:
        """``step`` valued by the critic ``p["critic"]``."""
        obs, final = step.obs, step.final
        value, baseline = critic.apply(p["critic"], obs, step.action)
        next_value = critic.apply(p["critic"], final, method="value")
        death_value = (critic.apply(p["critic"], last_seen(obs, final), obs.alive, method="value")
                       if cfg.episode_ends == "reference" else next_value)
        return Transition(obs, step.action, step.logp, obs.alive, value, baseline, next_value, death_value,
                          final.alive, step.reward, step.done, step.won, step.lost)

    def rollout_step(runner: Runner, _):
        p = runner.params
        runner, step, ep = act(runner)
        return runner, (valued(p, step), ep)

    def acted_segment(runner: Runner):
        """``(runner, Step [seg, N], episode sums [seg])``: every arena's next ``seg`` decisions."""
        def one(r, _):
            r, step, ep = act(r)
            return r, (step, ep)

        runner, (steps, ep) = jax.lax.scan(one, runner, None, seg)
        return runner, steps, ep

    def stale_segment(runner: StaleRunner, u):
        """Every arena's segment of update ``u`` written into its group's window (``trainers.windows``)."""
        runner, steps, ep = acted_segment(runner)
        return runner.replace(window=windows.write(runner.window, steps, u)), ep

    def collect(runner: Runner):
        if phases == 1:
            runner, (traj, ep) = jax.lax.scan(rollout_step, runner, None, t_len)
            return runner, traj, ep
        runner, ep = stale_segment(runner, runner.update)
        # Valued when it completes, as ML-Agents values a trajectory when it arrives.
        window = windows.completed(runner.window, runner.update, phases)
        return runner, jax.vmap(lambda s: valued(runner.params, s))(window), ep

    def update(runner: Runner):
        runner, traj, ep = collect(runner)
        returns = game_returns(cfg.episode_ends, traj.reward, traj.next_value, traj.death_value, traj.done, traj.won,
                               traj.lost, traj.alive, traj.next_alive, cfg.gamma, cfg.lam)
        adv = advantages(returns, traj.baseline, traj.alive)
        flat = lambda x: x.reshape((t_len * n,) + x.shape[2:])
        batch = jax.tree.map(flat, Batch(traj.obs, traj.action, traj.logp, traj.alive, traj.value,
                                         traj.baseline, returns, adv))
        frac = 1.0 - runner.update / cfg.num_updates
        beta = cfg.ent_coef * frac if cfg.anneal_ent else cfg.ent_coef

        def minibatch(carry, mb):
            params, opt_state = carry
            grads, aux = jax.grad(loss_fn, has_aux=True)(params, mb, actor, critic, cfg.clip_eps, beta, value_rows)
            aux["grad_norm"] = global_norm(grads)  # unclipped
            upd, opt_state = tx.update(grads, opt_state, params)
            return (optax.apply_updates(params, upd), opt_state), aux

        def epoch(carry, k):
            perm = jax.random.permutation(k, t_len * n)
            mbs = jax.tree.map(lambda x: x[perm].reshape((cfg.n_minibatches, -1) + x.shape[1:]), batch)
            return jax.lax.scan(minibatch, carry, mbs)

        def minibatch_of_rows(carry, ids):
            """One minibatch of agent experiences ``ids int32[M]`` (row = decision * P + player);
            skipped unless all ``M`` are live, as ML-Agents drops a buffer's leftover rows."""
            params, opt_state = carry
            mb = jax.tree.map(lambda x: x[ids // n_players], batch)
            agent = ids % n_players
            grads, aux = jax.grad(loss_fn, has_aux=True)(params, mb, actor, critic, cfg.clip_eps, beta, "agents",
                                                         agent)
            aux["grad_norm"] = global_norm(grads)
            upd, new_opt = tx.update(grads, opt_state, params)
            full = jnp.all(mb.alive[jnp.arange(ids.shape[0]), agent])
            keep = lambda new, old: jax.tree.map(lambda a, b: jnp.where(full, a, b), new, old)
            aux["taken"] = full.astype(jnp.float32)
            return (keep(optax.apply_updates(params, upd), params), keep(new_opt, opt_state)), aux

        def epoch_of_rows(carry, k):
            # The live rows in a random order, then the dead ones: minibatches of live rows first.
            live = batch.alive.reshape(-1)
            u = jax.random.uniform(k, live.shape)
            ids = jnp.argsort(jnp.where(live, u, u + 2.0)).astype(jnp.int32)
            return jax.lax.scan(minibatch_of_rows, carry, ids.reshape(cfg.n_minibatches, -1))

        key, k_perm = jax.random.split(runner.key)
        (params, opt_state), aux = jax.lax.scan(epoch_of_rows if by_rows else epoch, (runner.params, runner.opt_state),
                                                jax.random.split(k_perm, cfg.update_epochs))
        if by_rows:  # averages over the minibatches taken; "taken": their share
            taken = aux["taken"]
            metrics = {k: jnp.sum(v * taken) / jnp.maximum(taken.sum(), 1.0) for k, v in aux.items()}
            metrics["taken"] = taken.mean()
        else:
            metrics = {k: v.mean() for k, v in aux.items()}
        metrics.update({k: v.sum().astype(jnp.float32) for k, v in ep.items()})
        metrics["value_mean"] = traj.value.mean()
        metrics["value_explained_variance"] = (explained_variance(traj.value[..., None], returns, traj.alive)
                                               if value_rows == "agents" else explained_variance(traj.value,
                                                                                                  returns[..., 0]))
        metrics["baseline_explained_variance"] = explained_variance(traj.baseline, returns, traj.alive)
        runner = runner.replace(params=params, opt_state=opt_state, key=key, update=runner.update + 1)
        return runner, metrics

    def chunk(runner: Runner):
        runner, m = jax.lax.scan(lambda r, _: update(r), runner, None, cfg.updates_per_chunk)
        return runner, {k: (v.sum() if k in EPISODE_KEYS else v.mean()) for k, v in m.items()}

    def train(key: jax.Array):
        runner = init(key)
        return jax.lax.scan(lambda r, _: chunk(r), runner, None, cfg.num_chunks)

    return Trainer(cfg, actor, critic, init, update, chunk, train, collect)


def make_train(config: Config, base_params: Params | None = None):
    """``train(key) -> (Runner, metrics)``: a whole run, pure and jittable; vmap it over keys to
    train seeds together. ``key``: a typed PRNG key or a raw ``uint32[2]`` one (``Runner.key`` takes
    its kind). ``metrics``: a dict of ``float32[num_chunks]`` (``[S, num_chunks]`` vmapped over ``S``
    seeds), one row per chunk: losses and statistics averaged over the chunk's updates, the episode
    counts and sums (``EPISODE_KEYS``) summed; its size never depends on the chunk length."""
    return make_trainer(config, base_params).train


def summarize(m: dict) -> dict:
    """Host-side per-chunk row from chunk metrics (seed axes averaged / summed): return per
    episode, win rate, episode length, losses. Returns a dict of Python floats."""
    m = {k: float(jnp.mean(v)) if k not in EPISODE_KEYS else float(jnp.sum(v)) for k, v in m.items()}
    eps = max(m["episodes"], 1.0)
    out = {"episodes": m["episodes"], "return": m["return_sum"] / eps, "win_rate": m["wins"] / eps,
           "draw_rate": m["draws"] / eps, "length": m["length_sum"] / eps}
    out.update({k: v for k, v in m.items() if k not in EPISODE_KEYS})
    return out


@dataclasses.dataclass(frozen=True)
class TeamPolicy:
    """A trained team as ``policy(weights, key, obs, state, params) -> int32[P]`` for one arena.

    Hashable by value (the architecture and ``deterministic``), with the weights an argument:
    ``raidjax.playtest(key, params, policy, n, weights=w)`` compiles once for every checkpoint
    of one architecture. ``weights`` is the actor's flax parameter tree, unbatched.
    """

    actor: Actor
    deterministic: bool = False
    senses: str = "raidjax"  # raidjax.playtest plays every content with these senses (sensed_by)

    def __call__(self, weights, key, obs, state, params):
        return sample_actions(key, self.actor.apply(weights, obs), obs.alive, self.deterministic)[0]


def load_policy(path: str | Path, seed: int = 0, deterministic: bool | None = None):
    """Load a trained team as ``(policy, weights)`` for ``raidjax.playtest(..., policy, n, weights=weights)``.

    Args:
        path: the run folder (``--out``), its ``checkpoints`` folder, or one checkpoint.
        seed: which of the run's seeds (index into the seed axis).
        deterministic: greedy actions instead of sampling (default: the run's ``deterministic_eval``).

    Returns:
        ``(policy, weights)``: a ``TeamPolicy`` (equal for every run of one architecture) and that
        seed's actor weights (a pytree of arrays).

    Raises:
        ValueError: ``seed`` not a whole number >= 0.
        checkpoint.CheckpointError: missing, incomplete or corrupted checkpoint, or ``seed`` out of range.
    """
    seed = validate.whole_number("seed", seed, 0, "a whole number >= 0 (which of the run's seeds)")
    weights, config = checkpoint.load_policy_weights(path)
    cfg = Config.from_dict(config)
    n_seeds = jax.tree.leaves(weights)[0].shape[0]
    if not 0 <= seed < n_seeds:
        raise checkpoint.CheckpointError(f"seed: {seed} not in the checkpoint's {n_seeds} seeds")
    weights = jax.tree.map(lambda x: jnp.asarray(x[seed]), weights)
    actor, _ = make_networks(cfg)
    greedy = cfg.deterministic_eval if deterministic is None else bool(deterministic)
    return TeamPolicy(actor, greedy, cfg.senses), weights
