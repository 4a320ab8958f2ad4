"""Generation with trained PPO generators beside the paper's baselines (PCG-HR, PCG-RD), on one
protocol: the library behind ``trainers.ppo_pcgrl_cli``, ``experiments.benchmark2`` and the balancing
loop.

Every episode of every generator runs side by side in one ``raidjax.pcg.quality.generate`` call, so
each measurement is one playtest of all of their games, sized to fill the CPU's vectors (a
generator alone at one episode per target played too few arenas to)::

    gens = generate_episodes(key, {"PPO": PPOGenerator(config, weights, labels)}, gen_games=300, greedy=True,
                             episodes=20, eval_games=0, strict_length=True, max_edits=39)
    summary = raidjax.pcg.quality.summarize(gens, protocol)
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from functools import cache
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from raidjax import pcg, policies
from raidjax.io import fmt_seconds
from trainers import draws
from trainers.config import PPOConfig
from trainers.ppo_pcgrl import ActorCritic, env_params

BASELINES = ("PCG-HR", "PCG-RD")


def _progress_line(log: Callable[[str], None], eval_games: int, gen_games: int) -> Callable:
    """``log`` one line per measurement of a generation (``pcg.quality.generate``'s ``progress``):
    how far it is, and an ETA from the measurements' pace, the re-measurement of ``eval_games``
    games counted as ``eval_games / gen_games`` measurements (at most: the loop ends early once every
    episode is done)."""
    t0, first = time.perf_counter(), {}

    def line(measured: int, most: int, done: int, n: int) -> None:
        now = time.perf_counter()
        # the pace is taken after the first measurement, which holds the compile
        m0, t_first = first.setdefault("measurement", (measured, now))
        pace = (now - t_first) / (measured - m0) if measured > m0 else None
        left = most - measured + eval_games / gen_games
        eta = f", ETA at most {fmt_seconds(pace * left)}" if pace is not None else ""
        log(f"measurement {measured}/{most}: {done} of {n} episodes done, {fmt_seconds(now - t0)} so far{eta}")
    return line


def target_groups(config: PPOConfig, seeds: int) -> tuple[np.ndarray, list[tuple[float | None, int]]]:
    """The groups a run trains: one per seed when the target is observed (one model for all
    targets), else one per (target, seed) (one model per fixed target, the paper's setting).

    Returns:
        ``(pairs float32[G, 2], labels)``: each group's (low, high) target range and its
        ``(target or None, seed)`` label.
    """
    if config.observe_target:
        return np.tile(np.asarray(config.target, np.float32), (seeds, 1)), [(None, s) for s in range(seeds)]
    pairs = [(t, s) for t in pcg.quality.TARGETS for s in range(seeds)]
    return np.asarray([[t, t] for t, _ in pairs], np.float32), pairs


@dataclasses.dataclass(frozen=True)
class PPOGenerator:
    """A trained PPO-PCGRL run: its ``config``, its networks' ``weights`` with a leading group axis
    ``[G, ...]`` and the groups' ``labels`` (``target_groups``)."""

    config: PPOConfig
    weights: Any
    labels: list


def _without_target(obs: jax.Array, k: int) -> jax.Array:
    """An observation of a target-observing environment (``raidjax.pcg.env.observe_pcg``: the ``k``
    parameters, target and last win rate, the rest) as a generator that does not observe the target
    sees it: the two target entries dropped."""
    return jnp.concatenate([obs[:k], obs[k + 2:]])


@cache
def method_policy(families: tuple[tuple[tuple[int, ...], bool], ...], greedy: bool = False,
                  n_params: int = pcg.env.N_PARAMS):
    """One generator policy for every method of a generation call:
    ``policy((nets, episode), key, obs, state, params) -> int32[n_params]``.

    Args:
        families: per PPO run, its networks' widths and whether it observes the target (the
            call's environment always does; a run that does not sees the observation without the
            target entries).
        greedy: PPO takes the argmax of each branch (else samples).
        n_params: the edited parameters (branches).

    ``nets`` is a tuple with each run's weights (leading group axis); ``episode`` holds
    ``method`` (``int32[]``: ``f < len(families)`` runs PPO run ``f``, then PCG-HR, then PCG-RD) and
    ``group`` (the run's network). Under the episodes' ``vmap`` every method's action is computed and
    the episode's is selected: the networks are small beside a measurement's games.
    """
    nets_of = [ActorCritic(tuple(hidden), n_params) for hidden, _ in families]

    def policy(pp, key, obs, state, params):
        nets, episode = pp
        actions = []
        for net, (_, observes), weights in zip(nets_of, families, nets, strict=True):
            o = obs if observes else _without_target(obs, n_params)
            logits = jax.vmap(lambda w, net=net, o=o: net.apply(w, o)[0])(weights)  # [G, n_params, 5]
            logits = jnp.take(logits, episode["group"], axis=0, mode="clip")
            a = jnp.argmax(logits, -1) if greedy else draws.categorical(key, logits)
            actions.append(a.astype(jnp.int32))
        actions.append(pcg.pcg_hr(None, key, obs, state, params))
        actions.append(pcg.pcg_rd(None, key, obs, state, params))
        return jax.lax.switch(episode["method"], [lambda a=a: a for a in actions])

    return policy


def _shared_env(configs: list[PPOConfig], strict_length, max_edits) -> PPOConfig:
    """The one environment config every PPO run's episodes share (observing the target); raises
    ``ValueError`` when the runs' environments differ in anything but that."""
    env_fields = ("parameters", "players", "pool_repeats", "goal_axis") + (
        () if strict_length is not None else ("strict_length",)) + (() if max_edits is not None else ("max_edits",))
    first = configs[0]
    for c in configs[1:]:
        for f in env_fields:
            if getattr(c, f) != getattr(first, f):
                raise ValueError(f"generators: {f} differs between the PPO runs ({getattr(first, f)!r} and "
                                 f"{getattr(c, f)!r}); allowed: runs of one environment, generated together")
    return first.replace(observe_target=True)


def generate_episodes(key: jax.Array, generators: dict[str, PPOGenerator], *, gen_games: int, greedy: bool,
                      episodes: int, eval_games: int, baselines: bool = True, strict_length: bool | None = None,
                      max_edits: int | None = None, tester: Callable = policies.heuristic,
                      tester_weights: Any = None,
                      log: Callable[[str], None] | None = None) -> dict[str, dict[str, np.ndarray]]:
    """Generate with trained PPO runs (every group of each), PCG-HR and PCG-RD in the training
    environment, every episode of every method side by side in one call.

    Args:
        key: PRNG key.
        generators: ``{method name: PPOGenerator}`` (at least one; their environments must agree
            but for observing the target, ``_shared_env``).
        gen_games: playtest games per generator measurement.
        greedy: PPO takes the argmax of each branch (else samples).
        episodes: episodes per target and method (a PPO run's are split over its seeds).
        eval_games: games re-measuring each kept skill (0: keep the generator's own last measurement).
        baselines: also run PCG-HR and PCG-RD (``BASELINES``).
        strict_length, max_edits: override the training environment's (``None``: keep).
        tester, tester_weights: the playtesting team of every measurement (``env_params``; PT-HR
            by default).
        log: ``None``, or where a progress line goes after each measurement of the episodes (the
            same numbers are generated with or without it).

    Returns:
        ``{method: pcg.quality.generate output}`` (numpy arrays; a PPO run's groups pooled), methods
        in the order of ``generators``, then the baselines.
    """
    if not generators:
        raise ValueError("generators: value {}; allowed: at least one trained PPO run")
    runs = list(generators.values())
    p = env_params(_shared_env([g.config for g in runs], strict_length, max_edits), tester=tester,
                   tester_weights=tester_weights).replace(n_games=gen_games)
    p = p.replace(strict_length=p.strict_length if strict_length is None else np.bool_(strict_length),
                  max_edits=p.max_edits if max_edits is None else max_edits)
    # Every episode's target, method (an index into generators, then the baselines) and network.
    targets, method, group = [], [], []
    for f, g in enumerate(runs):
        n_seeds = max(s for _, s in g.labels) + 1
        eps = max(1, episodes // n_seeds)
        for i, (t, _) in enumerate(g.labels):
            for tt in (pcg.quality.TARGETS if t is None else (t,)):
                targets += [tt] * eps
                method += [f] * eps
                group += [i] * eps
    for b in range(len(BASELINES) if baselines else 0):
        for tt in pcg.quality.TARGETS:
            targets += [tt] * episodes
            method += [len(runs) + b] * episodes
            group += [0] * episodes
    policy = method_policy(tuple((g.config.widths, bool(g.config.observe_target)) for g in runs), greedy,
                           runs[0].config.space.size)
    out = pcg.quality.generate(key, policy, p, policy_params=tuple(g.weights for g in runs),
                               targets=np.asarray(targets, np.float32), episodes=1, eval_games=eval_games,
                               episode_params={"method": jnp.asarray(method, jnp.int32),
                                               "group": jnp.asarray(group, jnp.int32)},
                               progress=None if log is None else _progress_line(log, eval_games, p.n_games))
    names = list(generators) + (list(BASELINES) if baselines else [])
    method = np.asarray(method)
    return {name: {k: v[method == m] for k, v in out.items()} for m, name in enumerate(names)}
