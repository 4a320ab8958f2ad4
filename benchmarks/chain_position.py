"""How a game's outcome depends on its place in the arena's chain (docs/GAME.md, "Episodes of one
arena"): win rate by position over arenas that each play ``--games-per-arena`` games in a row after
their warm-up game (``raidjax.playtest``, raidjax's one protocol; game ``a * k + j`` is arena ``a``'s
``j``-th measured game), for PT-HR and, with ``--team``, a trained MA-POCA team played sampled (as it
is evaluated) and greedily, under each rule switch given.

What a game hands on to the next explains the differences: ``after_boss_slash_timer`` splits the
games at positions 1.. by whether the game before ended with the boss's slash cooldown running
(under ``carry_cooldowns`` it then adds a second slash charge in this game), ``after_in_flight`` by
whether projectiles were in flight at its end (under ``reset_exception`` the boss then starts this
game where the last one ended). Prints one JSON object per (rules, range, policy).

    python benchmarks/chain_position.py --ranges 5 13 --arenas 256 --games-per-arena 64
    python benchmarks/chain_position.py --ranges 13 --arenas 100 --games-per-arena 10 --team runs/r13 \\
        --switches reference carry_cooldowns=False reset_exception=False clean
"""

from __future__ import annotations

import argparse
import json
import time

import jax
import numpy as np

import raidjax
from raidjax.io import machine, run_cli, whole_number_arg
from raidjax.types import RULE_SWITCHES

SLASH = 1  # the boss's skill slot 2 (dragon_slash): 4 s cast, 7 s cooldown (GAME.md §7)


def rules_params(switch: str, skill_range: float) -> raidjax.Params:
    """The reference content at ``skill_range`` under ``switch``: a rule set name (``reference``,
    ``clean``) or one switch of the reference rules set as ``NAME=True|False``."""
    if "=" not in switch:
        return raidjax.make_params(skill_range=skill_range, rules=switch)
    name, value = switch.split("=", 1)
    if name not in RULE_SWITCHES or value not in ("True", "False"):
        raise ValueError(f"--switches: value {switch!r}; allowed: reference, clean or NAME=True|False with NAME "
                         f"one of {list(RULE_SWITCHES)}")
    p = raidjax.make_params(skill_range=skill_range)
    return p.replace(config=p.config.replace(**{name: value == "True"}))


def split_rate(won: np.ndarray, cond: np.ndarray) -> dict:
    """Win rate of the games where ``cond`` holds and where it does not, with their counts."""
    rate = lambda m: round(float(won[m].mean()), 4) if m.any() else None
    return {"share": round(float(cond.mean()), 4), "win_rate_if": rate(cond), "win_rate_if_not": rate(~cond)}


def chain_row(res: dict, k: int, config: raidjax.EnvConfig) -> dict:
    """Per-position win rates of one playtest and, under the switches that chain games, the split
    by what the game before handed on."""
    won = np.asarray(res["outcome"] == raidjax.types.WIN).reshape(-1, k)
    slash = np.asarray(res["boss_recharging"][..., SLASH]).reshape(-1, k)
    flying = np.asarray(res["in_flight"] > 0).reshape(-1, k)
    later = won[:, 1:].reshape(-1)
    row = {"win_rate": round(float(won.mean()), 4),
           "win_rate_se": round(float(np.sqrt(won.mean() * (1 - won.mean()) / won.size)), 4),
           "win_rate_first_game": round(float(won[:, 0].mean()), 4),
           "win_rate_by_position": [round(float(x), 4) for x in raidjax.win_rate_by_position(res)]}
    if k > 1 and config.carry_cooldowns:
        row["after_boss_slash_timer"] = split_rate(later, slash[:, :-1].reshape(-1))
    if k > 1 and config.reset_exception:
        row["after_in_flight"] = split_rate(later, flying[:, :-1].reshape(-1))
    if k % 8 == 0:
        row["win_rate_by_block_of_8"] = [round(float(won[:, i:i + 8].mean()), 4) for i in range(0, k, 8)]
    return row


def main() -> None:
    raidjax.use_recommended_xla_flags()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ranges", type=float, nargs="+", default=[5.0, 13.0])
    ap.add_argument("--arenas", type=whole_number_arg(1), default=256)
    ap.add_argument("--games-per-arena", type=whole_number_arg(1), default=64)
    ap.add_argument("--switches", nargs="+", default=["reference"],
                    help="rule sets (reference, clean) or one reference switch each, NAME=True|False")
    ap.add_argument("--team", help="a MA-POCA run folder: its team plays too, sampled and greedy")
    ap.add_argument("--team-seed", type=whole_number_arg(0), default=0, help="which of the run's seeds")
    ap.add_argument("--seed", type=whole_number_arg(0), default=12)
    args = ap.parse_args()
    k = args.games_per_arena
    for sw in args.switches:
        rules_params(sw, 13.0)  # a bad switch is refused before anything compiles
    policies = [("PT-HR", raidjax.policies.heuristic, None)]
    if args.team:
        from trainers.mapoca import load_policy

        for label, greedy in (("team, sampled", False), ("team, greedy", True)):
            policy, weights = load_policy(args.team, seed=args.team_seed, deterministic=greedy)
            policies.append((label, policy, weights))
    for sw in args.switches:
        for r in args.ranges:
            params = rules_params(sw, r)
            for label, policy, weights in policies:
                t0 = time.perf_counter()
                res = jax.device_get(raidjax.playtest(jax.random.key(args.seed), params, policy, args.arenas * k,
                                                      weights=weights, games_per_arena=k))
                print(json.dumps({"benchmark": "chain_position", "machine": machine(load=True), "rules": sw,
                                  "range": r, "policy": label, "team": args.team, "arenas": args.arenas,
                                  "games_per_arena": k, **chain_row(res, k, params.config),
                                  "seconds": round(time.perf_counter() - t0, 1)}), flush=True)


if __name__ == "__main__":
    run_cli(main)
