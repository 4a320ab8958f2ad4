"""Is the calibration table statistically the same two ways? A two-sided two-proportion z-test
per cell (PT-HR and PT-RD at ranges 5 / 9 / 13 / 17) between two ways of playing the games.

One measured game per arena after its warm-up (``games_per_arena=1``) against the chained arenas
raidjax measures with (``auto_games_per_arena``: up to 10 games in a row after one warm-up).
Different keys (seeds ``--seed`` and ``--seed + 1``), so the games differ; what must agree is
each cell's win rate. Prints one JSON object with each cell's two win rates, z and p-value, and
the wall-clock of both ways.

    python benchmarks/calibration_equivalence.py --games 4096
"""

from __future__ import annotations

import argparse
import json
import math
import time

import raidjax
from raidjax import calibrate
from raidjax.io import machine, run_cli, whole_number_arg
from raidjax.playtest import auto_games_per_arena


def two_proportion(w1: float, w2: float, n1: int, n2: int) -> tuple[float, float]:
    """``(z, two-sided p)`` of the pooled two-proportion z-test of win rates ``w1``, ``w2``."""
    pooled = (w1 * n1 + w2 * n2) / (n1 + n2)
    se = math.sqrt(max(pooled * (1 - pooled) * (1 / n1 + 1 / n2), 1e-300))
    z = 0.0 if pooled in (0.0, 1.0) else (w1 - w2) / se
    return z, math.erfc(abs(z) / math.sqrt(2))


def main() -> None:
    raidjax.use_recommended_xla_flags()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--games", type=whole_number_arg(1), default=4096, help="games per cell, each way")
    ap.add_argument("--seed", type=whole_number_arg(0, 2**31 - 2), default=0)
    args = ap.parse_args()
    ways = {"one_game_per_arena": 1, "chained": None}
    tables, seconds = {}, {}
    for i, (name, k) in enumerate(ways.items()):
        t0 = time.perf_counter()
        tables[name] = calibrate.calibration_table(args.games, seed=args.seed + i, games_per_arena=k)
        seconds[name] = round(time.perf_counter() - t0, 1)
    a, b = (tables[n] for n in ways)
    cells = []
    for pol in a:
        for j, r in enumerate(calibrate.RANGES):
            z, p = two_proportion(a[pol]["win_rate"][j], b[pol]["win_rate"][j], args.games, args.games)
            cells.append({"policy": pol, "range": r, "one_game_per_arena": a[pol]["win_rate"][j],
                          "chained": b[pol]["win_rate"][j], "z": round(z, 3), "p": round(p, 4)})
    print(json.dumps({"benchmark": "calibration_equivalence", "machine": machine(load=True),
                      "games_per_cell": args.games,
                      "chained_games_per_arena": auto_games_per_arena(args.games),
                      "seconds": seconds, "cells": cells, "min_p": min(c["p"] for c in cells)}))


if __name__ == "__main__":
    run_cli(main)
