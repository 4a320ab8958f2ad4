"""How a game's outcome depends on its place in the arena's chain (reference rules): PT-HR win
rate by position, in blocks of 8, over arenas that each play ``--games-per-arena`` games in a row
after their warm-up game (``raidjax.playtest(..., games_per_arena=k)``; game ``a * k + j`` is
arena ``a``'s ``j``-th measured game). Prints one JSON object per range.

    python benchmarks/chain_position.py --ranges 5 13 --arenas 256 --games-per-arena 64
"""

from __future__ import annotations

import argparse
import json
import time

import jax
import numpy as np

import raidjax
from raidjax.io import machine, run_cli, whole_number_arg


def main() -> None:
    raidjax.use_recommended_xla_flags()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ranges", type=float, nargs="+", default=[5.0, 13.0])
    ap.add_argument("--arenas", type=whole_number_arg(1), default=256)
    ap.add_argument("--games-per-arena", type=whole_number_arg(8), default=64, help="a multiple of 8 (blocks of 8)")
    ap.add_argument("--seed", type=whole_number_arg(0), default=12)
    args = ap.parse_args()
    k = args.games_per_arena
    if k % 8:
        ap.error(f"--games-per-arena: value {k}; allowed: a multiple of 8 (positions are reported in blocks of 8)")
    for r in args.ranges:
        t0 = time.perf_counter()
        res = raidjax.playtest(jax.random.key(args.seed), raidjax.make_params(skill_range=r),
                               raidjax.policies.heuristic, args.arenas * k, games_per_arena=k)
        won = np.asarray(res["outcome"] == raidjax.types.WIN).reshape(args.arenas, k)
        print(json.dumps({"benchmark": "chain_position", "machine": machine(load=True), "range": r,
                          "arenas": args.arenas,
                          "games_per_arena": k, "win_rate_position_0": round(float(won[:, 0].mean()), 4),
                          "win_rate_by_block_of_8": [round(float(won[:, i:i + 8].mean()), 4) for i in range(0, k, 8)],
                          "win_rate_all": round(float(won.mean()), 4), "seconds": round(time.perf_counter() - t0, 1)}))


if __name__ == "__main__":
    run_cli(main)
