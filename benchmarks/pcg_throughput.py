"""Content-generation throughput: generator steps (edit + PT-HR playtest of N games) per second.

Compiles ahead of time, times with ``block_until_ready`` and prints one JSON object with the
machine, the batch of parallel generator episodes, N, compile seconds, generator steps/s and the
implied games/s. Uses ``raidjax.pcg.step_autoreset`` (exactly one playtest per step) under vmap.

    python benchmarks/pcg_throughput.py --envs 8 --n-games 100 --steps 2
"""

from __future__ import annotations

import argparse
import json
import time

import jax

from raidjax import pcg
from raidjax.io import machine
from raidjax.xla_flags import use_recommended_xla_flags


def make_rollout(params: pcg.PCGParams, n_steps: int):
    """``rollout(key, states) -> (states, reward_sum)``: ``n_steps`` random edits of a batch of episodes."""

    def rollout(key, states):
        def body(st, k):
            ka, ks = jax.random.split(k)
            n = st.target.shape[0]
            act = jax.random.randint(ka, (n, pcg.env.N_PARAMS), 0, pcg.env.N_CHOICES)
            _, st, r, _, _ = jax.vmap(lambda kk, s, a: pcg.step_autoreset(kk, s, a, params))(
                jax.random.split(ks, n), st, act)
            return st, r.sum()

        st, rs = jax.lax.scan(body, states, jax.random.split(key, n_steps))
        return st, rs.sum()

    return rollout


def main() -> None:
    """Run the benchmark and print one JSON line."""
    use_recommended_xla_flags()  # raidjax's commands measure with these (raidjax.xla_flags)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", type=int, default=8, help="generator episodes stepped in parallel")
    ap.add_argument("--n-games", type=int, default=100)
    ap.add_argument("--steps", type=int, default=2, help="generator steps per timed call")
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()

    params = pcg.make_pcg_params(n_games=args.n_games)
    _, states = jax.jit(jax.vmap(lambda k: pcg.reset(k, params)))(jax.random.split(jax.random.key(0), args.envs))
    rollout = make_rollout(params, args.steps)
    key = jax.random.key(1)
    t0 = time.perf_counter()
    compiled = jax.jit(rollout).lower(key, states).compile()
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(key, states))  # warm-up
    times = []
    for i in range(args.repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(jax.random.fold_in(key, i), states))
        times.append(time.perf_counter() - t0)
    best = min(times)
    steps = args.envs * args.steps
    print(json.dumps({
        "benchmark": "pcg_throughput", "machine": machine(load=True), "envs": args.envs, "n_games": args.n_games,
        "steps_per_call": steps, "compile_s": round(compile_s, 2), "best_s": round(best, 3),
        "generator_steps_per_s": round(steps / best, 2), "games_per_s": round(steps * args.n_games / best, 1),
        "times_s": [round(t, 3) for t in times],
    }))


if __name__ == "__main__":
    main()
