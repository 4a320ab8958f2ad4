"""Generation with a trained PPO generator beside the paper's baselines (PCG-HR, PCG-RD), on one
protocol: the library behind ``trainers.ppo_pcgrl_cli`` and ``experiments.benchmark2``.

    gens = generate_episodes(key, config, weights, labels, gen_games=300, greedy=True, episodes=20,
                    eval_games=0, strict_length=True, max_edits=39)
    summary = raidjax.pcg.quality.summarize(gens, protocol)
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from raidjax import pcg, policies
from trainers.config import PPOConfig
from trainers.ppo_pcgrl import env_params, make_generator_policy


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


@cache
def method_policy(hidden: tuple, greedy: bool = False, n_params: int = pcg.env.N_PARAMS):
    """One generator policy for PPO, PCG-HR and PCG-RD, so that ``pcg.quality.generate`` compiles
    once per episode count rather than once per method: ``policy({"net": weights, "method":
    int32[]}, key, obs, state, params) -> int32[n_params]`` with method 0 = PPO (``make_generator_policy(hidden,
    greedy, n_params)``), 1 = PCG-HR, 2 = PCG-RD. ``method`` is not batched, so the ``lax.switch`` stays a
    conditional and only the chosen branch runs."""
    ppo = make_generator_policy(tuple(hidden), greedy, n_params)

    def policy(pp, key, obs, state, params):
        return jax.lax.switch(pp["method"], [
            lambda: ppo(pp["net"], key, obs, state, params),
            lambda: pcg.pcg_hr(None, key, obs, state, params),
            lambda: pcg.pcg_rd(None, key, obs, state, params)])

    return policy


def generate_episodes(key: jax.Array, config: PPOConfig, weights, labels: list, *, gen_games: int, greedy: bool,
             episodes: int, eval_games: int, baselines: bool = True, strict_length: bool | None = None,
             max_edits: int | None = None, tester: Callable = policies.heuristic,
             tester_weights: Any = None) -> dict[str, dict[str, np.ndarray]]:
    """Generate with PPO (every trained group), PCG-HR and PCG-RD in the training environment.

    Args:
        key: PRNG key.
        config: the PPO config the weights were trained with.
        weights: network weights with a leading group axis ``[G, ...]``.
        labels: ``target_groups``' labels, ``G`` of them.
        gen_games: playtest games per generator measurement.
        greedy: PPO takes the argmax of each branch (else samples).
        episodes: episodes per target and method (PPO's are split over the seeds).
        eval_games: games re-measuring each kept skill (0: keep the generator's own last measurement).
        baselines: also run PCG-HR and PCG-RD.
        strict_length, max_edits: override the training environment's (``None``: keep).
        tester, tester_weights: the playtesting team of every measurement (``env_params``; PT-HR
            by default).

    Returns:
        ``{method: pcg.quality.generate output}`` (numpy arrays, PPO's pooled over groups).
    """
    # the training env (generate sets the targets)
    p = env_params(config, tester=tester, tester_weights=tester_weights).replace(n_games=gen_games)
    p = p.replace(strict_length=p.strict_length if strict_length is None else np.bool_(strict_length),
                  max_edits=p.max_edits if max_edits is None else max_edits)
    policy = method_policy(config.widths, greedy, config.space.size)
    n_seeds = max(s for _, s in labels) + 1
    eps = max(1, episodes // n_seeds)
    parts = []
    for g, (t, _) in enumerate(labels):
        params_g = {"net": jax.tree.map(lambda x, g=g: x[g], weights), "method": jnp.int32(0)}
        targets = pcg.quality.TARGETS if t is None else (t,)
        parts.append(pcg.quality.generate(jax.random.fold_in(key, g), policy, p, policy_params=params_g,
                                          targets=targets, episodes=eps, eval_games=eval_games))
    gens = {"PPO": {k: np.concatenate([d[k] for d in parts]) for k in parts[0]}}
    if baselines:
        net0 = jax.tree.map(lambda x: x[0], weights)
        for i, name in enumerate(("PCG-HR", "PCG-RD")):
            gens[name] = pcg.quality.generate(jax.random.fold_in(key, 10_000 + i), policy, p,
                                              policy_params={"net": net0, "method": jnp.int32(i + 1)},
                                              episodes=episodes, eval_games=eval_games)
    return gens
