"""Playtest noise: the standard error of a measured win rate vs the number of PT-HR games N.

Prints one JSON object: for each N, the mean win rate, the SD over independent repeats (the
measured standard error) and the binomial ``sqrt(p (1 - p) / N)``.

    python benchmarks/pcg_noise.py --repeats 20
"""

from __future__ import annotations

import argparse
import json

import jax

from raidjax.pcg import quality as pm
from raidjax.xla_flags import use_recommended_xla_flags


def main() -> None:
    """Measure and print one JSON line."""
    use_recommended_xla_flags()  # raidjax's commands measure with these (raidjax.xla_flags)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skill", type=float, nargs=4, default=(20.0, 0.5, 1.0, 0.75),
                    help="range, cool time, cast time, coefficient (default: a skill near 50 %% wins)")
    ap.add_argument("--n-games", type=int, nargs="+", default=(25, 50, 100, 300))
    ap.add_argument("--repeats", type=int, default=20)
    args = ap.parse_args()
    rows = pm.win_rate_noise(jax.random.key(0), args.skill, tuple(args.n_games), args.repeats)
    print(json.dumps({"skill": list(args.skill), "repeats": args.repeats, "rows": rows}))


if __name__ == "__main__":
    main()
