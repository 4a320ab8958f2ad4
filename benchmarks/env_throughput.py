"""Environment throughput: random-policy rollouts of the full step (observations included).

Compiles ahead of time, times with ``block_until_ready`` and prints one JSON object with the
machine, the batch size, compile seconds and environment decisions per second (one decision =
every player acts once). Also times ``raidjax.playtest`` (PT-HR, reference content, range 9,
games played to completion, ``--games-per-arena`` games in a row per arena; the best of
``--playtest-repeats`` calls, each on other games).

    python benchmarks/env_throughput.py --arenas 4096 --steps 200
"""

from __future__ import annotations

import argparse
import json
import time

import jax
import jax.numpy as jnp

import raidjax
from raidjax.io import machine, whole_number_arg
from raidjax.playtest import auto_games_per_arena


def make_rollout(n_arenas: int, n_steps: int):
    """A jittable ``rollout(key, state, params) -> (state, checksum)`` of ``n_steps`` decisions.

    The checksum adds up the rewards and every observation: a policy that ignores observations
    (PT-RD) would otherwise let XLA drop their computation from the program.
    """

    def one(key, state, params):
        obs = raidjax.observe(state, params)

        def body(carry, k):
            obs, state = carry
            ka, ks = jax.random.split(k)
            actions = raidjax.policies.random(ka, obs, state, params)
            obs, state, reward, _, _ = raidjax.step_autoreset(ks, state, actions, params)
            seen = sum(jnp.sum(x.astype(jnp.float32)) for x in jax.tree.leaves(obs))
            return (obs, state), reward.sum() + seen

        (_, state), rewards = jax.lax.scan(body, (obs, state), jax.random.split(key, n_steps))
        return state, rewards.sum()

    return jax.vmap(one)


def arenas(n_arenas: int, rules: str, n_substeps: int, observation: str = "raidjax"):
    """``(keys, state, params)`` of ``n_arenas`` fresh arenas, each with its own copy of the range-9
    reference content: keys ``[N]``, ``State`` and ``Params`` batched ``[N, ...]``."""
    config = raidjax.EnvConfig.from_rules(rules, n_substeps=n_substeps, observation=observation)
    params = raidjax.make_params(skill_range=9.0, config=config)
    batch = jax.tree.map(lambda x: jnp.broadcast_to(x, (n_arenas,) + x.shape), params)
    keys = jax.random.split(jax.random.key(0), n_arenas)
    _, state = jax.vmap(raidjax.reset)(keys, batch)
    return keys, state, batch


def main() -> None:
    raidjax.use_recommended_xla_flags()  # raidjax's commands measure with these (raidjax.xla_flags)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arenas", type=int, default=4096)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--playtest-games", type=int, default=4096)
    ap.add_argument("--rules", default="reference", choices=sorted(raidjax.RULE_SETS))
    ap.add_argument("--substeps", type=int, default=5, choices=(1, 5))
    ap.add_argument("--playtest-repeats", type=whole_number_arg(1), default=3,
                    help="timed playtest calls (the best counts)")
    ap.add_argument("--games-per-arena", type=whole_number_arg(1), default=None,
                    help="playtest games each arena plays in a row (default: auto_games_per_arena, up to 10)")
    args = ap.parse_args()

    keys, state, batch = arenas(args.arenas, args.rules, args.substeps)
    params = jax.tree.map(lambda x: x[0], batch)
    rollout = make_rollout(args.arenas, args.steps)

    t0 = time.perf_counter()
    no_op = jnp.zeros((args.arenas, 3), jnp.int32)
    step_compiled = jax.jit(jax.vmap(raidjax.step)).lower(keys, state, no_op, batch).compile()
    step_compile_s = time.perf_counter() - t0
    del step_compiled
    t0 = time.perf_counter()
    compiled = jax.jit(rollout).lower(keys, state, batch).compile()
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(keys, state, batch))  # warm-up
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(keys, state, batch))
        times.append(time.perf_counter() - t0)
    best = min(times)

    k = args.games_per_arena or auto_games_per_arena(args.playtest_games)
    pt = jax.jit(raidjax.playtest, static_argnames=("policy", "n_games", "games_per_arena"))
    t0 = time.perf_counter()
    pt_compiled = pt.lower(jax.random.key(1), params, raidjax.policies.heuristic, args.playtest_games,
                           games_per_arena=k).compile()
    pt_compile_s = time.perf_counter() - t0
    jax.block_until_ready(pt_compiled(jax.random.key(1), params))
    # Each call plays other games (its own key); one call's time moves by up to 30 % on a shared
    # machine, so the best of several counts, as for the rollouts.
    pt_times, results = [], []
    for i in range(args.playtest_repeats):
        t0 = time.perf_counter()
        results.append(jax.block_until_ready(pt_compiled(jax.random.key(2 + i), params)))
        pt_times.append(time.perf_counter() - t0)
    best_call = min(range(len(pt_times)), key=pt_times.__getitem__)
    pt_s, res = pt_times[best_call], results[best_call]

    print(json.dumps({
        "benchmark": "env_throughput",
        "machine": machine(load=True),
        "arenas": args.arenas,
        "rules": args.rules,
        "n_substeps": args.substeps,
        "steps_per_rollout": args.steps,
        "step_compile_s": round(step_compile_s, 2),
        "rollout_compile_s": round(compile_s, 2),
        "decisions_per_s": round(args.arenas * args.steps / best),
        "seconds_per_rollout": [round(t, 3) for t in times],
        "playtest": {"policy": "heuristic", "skill_range": 9.0, "games": args.playtest_games, "games_per_arena": k,
                     "compile_s": round(pt_compile_s, 2), "seconds": round(pt_s, 3),
                     "seconds_each": [round(t, 3) for t in pt_times],
                     # Measured games; under chained rules each arena's one warm-up game is in the time.
                     "games_per_s": round(args.playtest_games / pt_s),
                     "warm_up_game": params.config.chains_episodes,
                     "measured_decisions_per_s": round(float(res["length"].sum()) / pt_s),
                     "win_rate": round(float(raidjax.win_rate(results[0])), 3)},  # key 2's games
    }))


if __name__ == "__main__":
    main()
