"""Benchmark 1's table teams under every rule switch, by chain position, beside PT-HR.

A Benchmark 1 run's table teams (MA-POCA trained at one skill range on the reference content) are
played by raidjax's one protocol (chained arenas after a warm-up, sampled actions) under the rules
they trained on, without the carried cooldowns (``carry_cooldowns=False``: a team that wins only
by the boss's carried slash charge loses there) and under the clean rules; PT-HR plays the same
contents with the same key. Writes one JSON line per (switch, range, team) with the win rate, its
standard error, the first game after the warm-up against the later ones, and the win rate by
chain position (``trainers.runs.chained_win_rates``):

    python -m experiments.b1_switches runs/b1 --games 1000 --out runs/b1/switches.jsonl

A finished ``raidjax train mapoca`` run folder (one skill range, three mages) works too: its seeds
are the teams, played greedily if the run's ``deterministic_eval`` says so (rows: ``greedy``).

It needs only the table runs' final checkpoint (their group, ``checkpoints/mapoca/group0``), so it
runs as soon as that group has trained.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp

from raidjax.io import HelpFormatter, atomic_write, check_output_file, fmt_seconds, machine, run_cli, whole_number_arg

SWITCHES = ("reference", "carry_cooldowns=False", "clean")


def _content(skill_range: float, switch: str):
    from experiments.benchmark1 import content_of

    p = content_of("reference", skill_range)
    if switch == "clean":
        return p.replace(config=p.config.with_rules("clean"))
    if switch == "carry_cooldowns=False":
        return p.replace(config=p.config.replace(carry_cooldowns=False))
    return p


def table_teams(run_dir: Path):
    """``(actor, weights with a leading axis T, the T table runs, senses, greedy)`` of a Benchmark 1 run
    folder's table runs, all in its first training group (``benchmark1.load_group_actors``)."""
    from experiments import benchmark1 as b1

    settings = json.loads((run_dir / "config.json").read_text())
    scale, protocol = b1.SCALES[settings["scale"]], settings["protocol"]
    runs = b1.runs_of(scale, protocol)
    actor, weights, senses = b1.load_group_actors(run_dir, scale, runs, settings["seed"], protocol, 0)
    members = [runs[i] for i in b1.groups_of(len(runs), scale.runs_per_program)[0]]
    table = [j for j, m in enumerate(members) if m["group"] == "table"]
    return (actor, jax.tree.map(lambda x: x[jnp.asarray(table)], weights), [members[j] for j in table], senses,
            False)  # Benchmark 1's teams sample


def trained_teams(run_dir: Path):
    """``table_teams``' tuple for a ``raidjax train mapoca`` run folder (its seeds, trained at its
    one skill range on the reference content; the run must have finished: it has ``result.json``)."""
    from trainers.config import Config
    from trainers.mapoca import load_policy

    settings = json.loads((run_dir / "config.json").read_text())
    cfg = Config.from_dict(settings["config"])
    if len(cfg.skill_ranges) != 1 or cfg.content_box or tuple(cfg.players) != ("mage",) * 3:
        raise ValueError(f"run: {str(run_dir)!r} trained on {list(cfg.skill_ranges)} / content_box "
                         f"{cfg.content_box} / {list(cfg.players)}; allowed: one skill range, three mages")
    if not (run_dir / "result.json").exists():
        raise ValueError(f"run: {str(run_dir)!r} has not finished (no result.json); finish it with --resume")
    loaded = [load_policy(run_dir, seed=i) for i in range(settings["seeds"])]  # one policy, a weights tree per seed
    weights = jax.tree.map(lambda *w: jnp.stack(w), *[w for _, w in loaded])
    teams = [{"ranges": tuple(cfg.skill_ranges), "seed": i} for i in range(settings["seeds"])]
    return loaded[0][0].actor, weights, teams, loaded[0][0].senses, loaded[0][0].deterministic


def evaluate(run_dir: Path, games: int, seed: int = 4242) -> list[dict]:
    """One dict per (switch, range, team): ``switch``, ``range``, ``agent`` (``MA-POCA`` with its
    ``seed`` and ``senses``, or ``PT-HR``) and ``trainers.runs.chained_win_rates`` of its ``games``."""
    trainer = json.loads((run_dir / "config.json").read_text()).get("trainer")
    actor, weights, teams, senses, greedy = trained_teams(run_dir) if trainer == "mapoca" else table_teams(run_dir)
    return play_switches(actor, weights, teams, senses, greedy, games, seed, log=print)


def play_switches(actor, weights, teams: list[dict], senses: str, greedy: bool, games: int,
                  seed: int = 4242, log=None) -> list[dict]:
    """``evaluate``'s rows for trained teams: ``actor`` with ``weights`` (a leading axis over
    ``teams``, dicts with ``ranges`` (one range: the reference content's) and ``seed``); ``log``, when
    given, is called with a progress line after each rule switch."""
    import raidjax
    from experiments.benchmark1 import _stack, per_team
    from raidjax.playtest import auto_games_per_arena
    from trainers.runs import chained_win_rates

    k = auto_games_per_arena(games)
    key = jax.random.PRNGKey(seed)

    def play(kk, content, policy):
        res = raidjax.playtest(kk, content, policy, games, games_per_arena=k)
        return {"outcome": res["outcome"], "position": res["position"]}

    rows, t0 = [], time.perf_counter()
    for j, switch in enumerate(SWITCHES):
        out = per_team(key, actor, weights, _stack([_content(t["ranges"][0], switch) for t in teams]), play, senses,
                       greedy)
        rows += [{"switch": switch, "range": t["ranges"][0], "agent": "MA-POCA", "seed": t["seed"], "senses": senses,
                  "greedy": greedy,
                  **chained_win_rates(jax.tree.map(lambda x, i=i: x[i], out))} for i, t in enumerate(teams)]
        for rg in sorted({t["ranges"][0] for t in teams}):
            rows.append({"switch": switch, "range": rg, "agent": "PT-HR",
                         **chained_win_rates(play(key, _content(rg, switch), raidjax.policies.heuristic))})
        if log is not None:
            s = time.perf_counter() - t0
            log(f"played {switch} ({j + 1}/{len(SWITCHES)}): {len(teams)} teams and PT-HR, {games} games each, "
                f"{fmt_seconds(s)} so far, ETA {fmt_seconds(s / (j + 1) * (len(SWITCHES) - j - 1))}")
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m experiments.b1_switches", description=__doc__.split("\n")[0],
                                 formatter_class=HelpFormatter)
    ap.add_argument("run", type=Path, help="a Benchmark 1 run folder whose table group has trained, or a "
                    "finished `raidjax train mapoca` run folder (one skill range, three mages)")
    ap.add_argument("--games", type=whole_number_arg(1), default=1000, help="games per team and switch")
    ap.add_argument("--out", type=Path, required=True, help="JSON lines file to write")
    args = ap.parse_args(argv)
    check_output_file("--out", args.out, (".jsonl",))  # before the games, not at their last write
    if not (args.run / "config.json").exists():
        raise ValueError(f"run: {str(args.run)!r} is not a run folder (no config.json)")
    rows = evaluate(args.run, args.games)
    stamp = machine()
    atomic_write(args.out, "".join(json.dumps({**r, "games": args.games, "machine": stamp}) + "\n" for r in rows))
    print(f"wrote {len(rows)} rows to {args.out}")


if __name__ == "__main__":
    run_cli(main)
