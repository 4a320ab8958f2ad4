"""What ``EnvConfig(random_spawns=True)`` does to the game's balance: PT-HR's win rate on the
reference content with the fixed spawns and with random ones, per skill range, the same games
per cell and the same keys, chained as the calibration plays them (``auto_games_per_arena``: the
arenas play up to 10 measured games in a row after a warm-up game). Prints one JSON
object; the 95 % interval of each rate is the normal approximation.

    python benchmarks/random_spawns.py --ranges 5 13 --games 2000 [--games-per-arena 1]
"""

from __future__ import annotations

import argparse
import json
import math
import time

import jax
import numpy as np

import raidjax
from raidjax.io import machine, run_cli, whole_number_arg
from raidjax.playtest import auto_games_per_arena


def main() -> None:
    raidjax.use_recommended_xla_flags()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ranges", type=float, nargs="+", default=[5.0, 13.0])
    ap.add_argument("--games", type=whole_number_arg(1), default=2000, help="games per cell")
    ap.add_argument("--seed", type=whole_number_arg(0), default=0)
    ap.add_argument("--games-per-arena", type=whole_number_arg(1),
                    help="measured games in a row per arena (default: auto_games_per_arena(--games))")
    args = ap.parse_args()
    k = args.games_per_arena or auto_games_per_arena(args.games)
    if args.games % k:
        ap.error(f"--games-per-arena: value {k}; allowed: a divisor of --games ({args.games})")
    t0, cells = time.perf_counter(), []
    for r in args.ranges:
        for spawns in (False, True):
            params = raidjax.make_params(skill_range=r, config=raidjax.EnvConfig(random_spawns=spawns))
            res = raidjax.playtest(jax.random.key(args.seed), params, raidjax.policies.heuristic, args.games,
                                   games_per_arena=k)
            p = float(np.mean(np.asarray(res["outcome"]) == raidjax.types.WIN))
            half = 1.96 * math.sqrt(p * (1 - p) / args.games)
            cells.append({"range": r, "random_spawns": spawns, "win_rate": round(p, 4),
                          "ci95": [round(p - half, 4), round(p + half, 4)]})
    print(json.dumps({"benchmark": "random_spawns", "machine": machine(load=True), "policy": "PT-HR",
                      "games_per_cell": args.games, "games_per_arena": k,
                      "seed": args.seed, "cells": cells,
                      "seconds": round(time.perf_counter() - t0, 1)}))


if __name__ == "__main__":
    run_cli(main)
