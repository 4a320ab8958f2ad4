"""Measure the PT-HR / PT-RD win-rate table and print it beside the paper's (GAME.md §9).

    python -m raidjax.calibrate --games 2000 [--seed S] [--rules reference|clean] [--substeps 5|1] [--json F]

Every cell is ``--games`` games with the reference content at that skill range, played in
parallel arenas of up to 10 games in a row each (``raidjax.playtest``'s ``games_per_arena``;
under the default ``"reference"`` rules each arena plays one discarded warm-up game first);
the tolerance check is the project's calibration contract (PT-HR within ±0.10, PT-RD within
±0.05 of the paper), made for the default rules at the reference tick (5 sub-steps), and judged with
each cell's sampling error (``outside_band``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import raidjax
from raidjax.io import HelpFormatter, atomic_write, check_output_file, machine, run_cli, whole_number_arg
from raidjax.playtest import auto_games_per_arena

RANGES = (5.0, 9.0, 13.0, 17.0)
PAPER = {"heuristic": (0.089, 0.371, 0.698, 0.830), "random": (0.000, 0.002, 0.029, 0.058)}
TOLERANCE = {"heuristic": 0.10, "random": 0.05}
LABEL = {"heuristic": "PT-HR", "random": "PT-RD"}


def calibration_table(n_games: int, seed: int = 0, ranges=RANGES, config: raidjax.EnvConfig | None = None,
                      games_per_arena: int | None = None, log=None) -> dict:
    """Win rates of PT-HR and PT-RD at each range.

    Args:
        n_games: games per cell.
        seed: PRNG seed.
        ranges: skill ranges (columns).
        config: ``EnvConfig`` (rules, sub-steps); default ``EnvConfig()``, the reference rules.
        games_per_arena: games each arena plays in a row (``raidjax.playtest``); default
            ``auto_games_per_arena(n_games)``.
        log: called with a progress line after each policy's games (``None``: silent).

    Returns:
        ``{policy: {"win_rate": [..], "stderr": [..], "mean_length": [..]}}`` for
        ``policy`` in ``("heuristic", "random")``, one entry per range.
    """
    contents = [raidjax.make_params(skill_range=r, config=config) for r in ranges]
    batch = jax.tree.map(lambda *x: jnp.stack(x), *contents)  # one content per group of games
    out = {}
    for i, name in enumerate(raidjax.policies.SCRIPTS):  # one compiled program plays both
        t0 = time.perf_counter()
        res = raidjax.playtest(jax.random.key(seed * 1000 + i), batch, raidjax.policies.script, n_games * len(ranges),
                               weights=jnp.int32(i), games_per_arena=games_per_arena or auto_games_per_arena(n_games))
        wins = np.asarray(res["outcome"] == raidjax.types.WIN).reshape(len(ranges), n_games).mean(axis=1)
        length = np.asarray(res["length"]).reshape(len(ranges), n_games).mean(axis=1)
        if log is not None:
            s = time.perf_counter() - t0
            log(f"{LABEL[name]}: {n_games * len(ranges)} games in {s:.1f} s "
                f"({n_games * len(ranges) / s:,.0f} games/s{', compile included' if i == 0 else ''})")
        out[name] = {
            "win_rate": [round(float(w), 4) for w in wins],
            "stderr": [round(math.sqrt(max(w * (1 - w), 1e-12) / n_games), 4) for w in wins],
            "mean_length": [round(float(x), 1) for x in length],
        }
    return out


Z95 = 1.96  # a two-sided 95 % interval


def outside_band(win_rate: float, stderr: float, paper: float, tolerance: float) -> bool:
    """Whether a cell is outside the contract's band ``paper ± tolerance`` beyond its sampling
    error: its whole 95 % interval ``win_rate ± 1.96 stderr`` lies outside the band. A cell whose
    interval overlaps the band is consistent with it, so the verdict does not flip with the seed
    for a cell that sits near the band's edge (PT-HR at range 9: about 0.45 against an edge of
    0.471), while a real deviation of a few standard errors is still reported."""
    low, high = win_rate - Z95 * stderr, win_rate + Z95 * stderr
    return high < paper - tolerance or low > paper + tolerance


def markdown(table: dict, n_games: int, ranges=RANGES) -> str:
    """The measured table beside the paper's as Markdown, with a verdict column (``outside_band``)."""
    head = "| agent | " + " | ".join(f"range {r:g}" for r in ranges) + " | within tolerance |"
    lines = [head, "|" + "---|" * (len(ranges) + 2)]
    for name, rows in table.items():
        cells, ok = [], True
        for w, se, paper in zip(rows["win_rate"], rows["stderr"], PAPER[name], strict=False):
            ok &= not outside_band(w, se, paper, TOLERANCE[name])
            cells.append(f"{w:.3f} ± {se:.3f} (paper {paper:.3f})")
        lines.append(f"| {LABEL[name]} | " + " | ".join(cells) + f" | {'yes' if ok else 'NO'} (±{TOLERANCE[name]}) |")
    lines.append(f"\n{n_games} games per cell; ± is the binomial standard error. A cell is within tolerance when "
                 "its 95 % interval (± 1.96 standard errors) overlaps the paper's value ± the tolerance.")
    return "\n".join(lines)


def _parse(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m raidjax.calibrate", description="PT-HR / PT-RD win rates beside "
                                 "the RaidEnv paper's table.", formatter_class=HelpFormatter)
    ap.add_argument("--games", type=whole_number_arg(1), default=2000, help="games per cell")
    ap.add_argument("--seed", type=whole_number_arg(0, 2**31 - 1), default=0, help="PRNG seed")
    ap.add_argument("--rules", default="reference", choices=sorted(raidjax.RULE_SETS),
                    help="reference: the game the paper measured; clean: the intended game")
    ap.add_argument("--substeps", type=int, default=5, choices=(1, 5),
                    help="sub-steps per decision: 5 (the 0.02 s tick) or 1")
    ap.add_argument("--json", help="also write the results to this JSON file, in an existing folder (default: none)")
    ap.add_argument("--check", action="store_true", help="exit 1 if a cell's 95 %% interval is outside the tolerance")
    args = ap.parse_args(argv)
    if args.json is not None:  # checked now: the games take minutes
        check_output_file("--json", args.json, (".json",))
    return args


def main(argv=None) -> int:
    """Play, print the table (and write ``--json``); returns the exit status (1: ``--check`` failed)."""
    args = _parse(argv)
    config = raidjax.EnvConfig.from_rules(args.rules, n_substeps=args.substeps)
    t0 = time.perf_counter()
    print(f"Playing {args.games} games per cell, {len(RANGES) * 2} cells, rules {args.rules!r}, "
          f"{args.substeps} sub-steps, seed {args.seed}, on {jax.devices()[0].platform} ...",
          file=sys.stderr, flush=True)
    table = calibration_table(args.games, args.seed, config=config, log=lambda s: print(s, file=sys.stderr, flush=True))
    seconds = time.perf_counter() - t0
    print(f"Rules {args.rules!r}, {args.substeps} sub-steps per decision, seed {args.seed}.\n")
    print(markdown(table, args.games))
    games = args.games * len(RANGES) * 2
    print(f"{games} games in {seconds:.1f} s (compile included).")
    if args.json:
        payload = {"games_per_cell": args.games, "seed": args.seed, "rules": args.rules,
                   "n_substeps": args.substeps, "seconds": round(seconds, 2), "table": table, "paper": PAPER,
                   "machine": machine(load=True)}
        atomic_write(args.json, json.dumps(payload, indent=2))
    ok = not any(
        outside_band(w, se, p, TOLERANCE[n])
        for n, rows in table.items()
        for w, se, p in zip(rows["win_rate"], rows["stderr"], PAPER[n], strict=False)
    )
    return 0 if ok or not args.check else 1


def cli(argv=None) -> None:
    """``main`` as a command line: one-line errors (exit 2), one line on Ctrl-C (exit 130), exit 1
    when ``--check`` fails."""
    run_cli(lambda: sys.exit(main(argv)))


if __name__ == "__main__":
    cli()
