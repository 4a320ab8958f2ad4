"""What holding a skill is worth: PCG-HR against PCG-HR that holds near the target.

PCG-HR (Algorithm 2) edits whenever its last measurement is outside the ±0.02 band, so it also
walks away from skills that were on target but measured unluckily (100-game SE ≈ 0.05). The
holding variant makes no edit while ``|w - t| < band + k * SE`` (SE from the measured rate and the
games behind it), so the environment re-measures the same skill. Every row uses the Benchmark 2
protocol (targets 0.1..0.7, 100-game measurements, 300-game final measurement) and the same key::

    python -m experiments.pcg_hold --episodes 10

Prints one JSON line per row: environment (``pooled``: ``pcg.make_params(pool_repeats=True)``),
generator, mean error (episodes with >= 2 edits), episodes kept, edits per episode, seconds.
"""

from __future__ import annotations

import argparse
import json
import time

import jax
import jax.numpy as jnp

from raidjax import pcg
from raidjax import pcg_metrics as pm


def holding_heuristic(k, key, obs, state, params):
    """PCG-HR that makes no edit while ``|w - t| < band + k * SE``. Returns ``int32[4]``."""
    se = jnp.sqrt(jnp.maximum(state.win_rate * (1 - state.win_rate), 0.01) / state.games)
    hold = jnp.abs(state.win_rate - state.target) < params.band + k * se
    return jnp.where(hold, pcg.NOOP_ACTION, pcg.heuristic_policy(None, key, obs, state, params))


def main(argv=None) -> list[dict]:
    """Run the rows; returns them (also printed as JSON lines)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=10, help="episodes per target and row")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--gen-games", type=int, default=100)
    a = ap.parse_args(argv)
    rows = []
    variants = ((False, "PCG-HR", pcg.heuristic_policy, 0.0),  # ignores its policy_params
                (False, "PCG-HR + hold k=1", holding_heuristic, 1.0),
                (False, "PCG-HR + hold k=2", holding_heuristic, 2.0),
                (True, "PCG-HR + hold k=1", holding_heuristic, 1.0))
    for pooled, name, policy, k in variants:
        t0 = time.perf_counter()
        p = pcg.make_params(n_games=a.gen_games, pool_repeats=pooled)
        g = pm.generate(jax.random.key(a.seed), policy, p, policy_params=jnp.float32(k), episodes=a.episodes)
        c = pm.controllability(g)
        rows.append({"environment": "pooled" if pooled else "SPEC", "generator": name, "mean_error": c["err_mean"],
                     "n": c["n"], "edits": float(g["edits"].mean()), "seconds": time.perf_counter() - t0})
        print(json.dumps(rows[-1]), flush=True)
    return rows


if __name__ == "__main__":
    main()
