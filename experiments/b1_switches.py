"""Benchmark 1's table teams under every rule switch, by chain position, beside PT-HR.

A Benchmark 1 run's table teams (MA-POCA trained at one skill range on the reference content) are
played by raidjax's one protocol (chained arenas after a warm-up, sampled actions) under the rules
they trained on, without the carried cooldowns (``carry_cooldowns=False``: a team that wins only
by the boss's carried slash charge loses there) and under the clean rules; PT-HR plays the same
contents with the same key. Writes one JSON line per (switch, range, team) with the win rate, its
standard error, the first game after the warm-up against the later ones, and the win rate by
chain position (``raidjax.win_rate_by_position``):

    python -m experiments.b1_switches runs/b1 --games 1000 --out runs/b1/switches.jsonl

It needs only the table runs' final checkpoint (their group, ``checkpoints/mapoca/group0``), so it
runs as soon as that group has trained.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from raidjax.io import HelpFormatter, atomic_write, machine, run_cli, whole_number_arg

SWITCHES = ("reference", "carry_cooldowns=False", "clean")


def _content(skill_range: float, switch: str):
    from experiments.benchmark1 import content_of

    p = content_of("reference", skill_range)
    if switch == "clean":
        return p.replace(config=p.config.with_rules("clean"))
    if switch == "carry_cooldowns=False":
        return p.replace(config=p.config.replace(carry_cooldowns=False))
    return p


def _rates(outcome, k: int) -> dict:
    won = np.asarray(outcome).reshape(-1, k) == 1  # raidjax.playtest's order: arena a's game j at a * k + j
    rate = float(won.mean())
    return {"win_rate": round(rate, 4), "win_rate_se": round(float(np.sqrt(rate * (1 - rate) / won.size)), 4),
            "win_rate_first_game": round(float(won[:, 0].mean()), 4),
            "win_rate_later_games": round(float(won[:, 1:].mean()), 4) if k > 1 else None,
            "win_rate_by_position": [round(float(x), 3) for x in won.mean(0)]}


def table_teams(run_dir: Path):
    """``(actor, weights [T, ...], table runs, senses)`` of a Benchmark 1 run folder's table group."""
    from experiments import benchmark1 as b1
    from trainers import checkpoint
    from trainers.mapoca import make_trainer

    settings = json.loads((run_dir / "config.json").read_text())
    scale, protocol = b1.SCALES[settings["scale"]], settings["protocol"]
    runs = b1.runs_of(scale, protocol)
    cfg = b1.config_of(scale, protocol)
    trainer = make_trainer(cfg, redraw_ranges=True)
    idx = b1.groups_of(len(runs), scale.runs_per_program)[0]
    members = [runs[i] for i in idx]
    abstract = jax.eval_shape(jax.vmap(trainer.init), *b1._run_inputs(members, settings["seed"], idx[0]))
    final = run_dir / "checkpoints" / "mapoca" / "group0" / str(cfg.num_chunks * cfg.updates_per_chunk)
    if not final.exists():
        raise ValueError(f"run folder {str(run_dir)!r}: no final checkpoint of the table group ({final}); "
                         "train it first (python -m experiments.benchmark1 ... --resume)")
    runner, _, _ = checkpoint.restore(final, abstract)
    table = [j for j, m in enumerate(members) if m["group"] == "table"]
    weights = jax.tree.map(lambda x: x[jnp.asarray(table)], runner.params["actor"])
    return trainer.actor, weights, [members[j] for j in table], cfg.senses


def evaluate(run_dir: Path, games: int, seed: int = 4242) -> list[dict]:
    """One dict per (switch, range, team): the table teams' and PT-HR's rates (``_rates``)."""
    import raidjax
    from experiments.benchmark1 import _stack, per_team
    from raidjax.playtest import auto_games_per_arena

    actor, weights, teams, senses = table_teams(run_dir)
    k = auto_games_per_arena(games)
    key = jax.random.PRNGKey(seed)
    rows = []
    for switch in SWITCHES:
        contents = _stack([_content(t["ranges"][0], switch) for t in teams])
        out = per_team(key, actor, weights, contents,
                       lambda kk, c, p: raidjax.playtest(kk, c, p, games, games_per_arena=k)["outcome"], senses)
        rows += [{"switch": switch, "range": t["ranges"][0], "agent": "MA-POCA", "seed": t["seed"], "senses": senses,
                  **_rates(o, k)} for t, o in zip(teams, out, strict=True)]
        for rg in sorted({t["ranges"][0] for t in teams}):
            res = raidjax.playtest(key, _content(rg, switch), raidjax.policies.heuristic, games, games_per_arena=k)
            rows.append({"switch": switch, "range": rg, "agent": "PT-HR", **_rates(res["outcome"], k)})
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m experiments.b1_switches", description=__doc__.split("\n")[0],
                                 formatter_class=HelpFormatter)
    ap.add_argument("run", type=Path, help="a Benchmark 1 run folder whose table group has trained")
    ap.add_argument("--games", type=whole_number_arg(1), default=1000, help="games per team and switch")
    ap.add_argument("--out", type=Path, required=True, help="JSON lines file to write")
    args = ap.parse_args(argv)
    if not (args.run / "config.json").exists():
        raise ValueError(f"run: {str(args.run)!r} is not a Benchmark 1 run folder (no config.json)")
    rows = evaluate(args.run, args.games)
    stamp = machine()
    atomic_write(args.out, "".join(json.dumps({**r, "games": args.games, "machine": stamp}) + "\n" for r in rows))
    print(f"wrote {len(rows)} rows to {args.out}")


if __name__ == "__main__":
    run_cli(main)
