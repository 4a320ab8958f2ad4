"""MA-POCA on the reference player's senses, the reference trainer's rows added one at a time
(docs/results/ablation.md; PROTOCOLS.md §12, "The reference trainer, row by row").

    python -m experiments.ablation --out runs/ablation [--variants today reference_ends ...] [--resume]
    python -m experiments.ablation --out runs/paper_budget --variants paper   # the paper preset
    python -m experiments.ablation --out runs/paper_r13_s0 --variants paper --ranges 13 --only-seeds 0
    python -m experiments.ablation --out runs/paper_r13 --tables-of runs/paper_r13_s0 runs/paper_r13_s1 ...

Every variant is the `cpu` preset on the reference senses with ``VARIANTS``' overrides, but ``paper``,
the `paper` preset at the paper's budget (the same protocol, the same games), and ``paper_stale``, the
same with the reference's asynchronous data approximated (``Config.stale_phases``). It trains
``len(ranges) x seeds`` runs (default ranges 9 and 13, 3 seeds, 1.5 M decisions each) as one
vmapped program, run ``i`` from ``fold_in(PRNGKey(seed), i)`` in every variant, each on the
reference content at its range (as Benchmark 1's table runs), then plays every team by the one
protocol, chained arenas after a warm-up (``experiments.b1_switches``: ``--games`` games per team
under the reference rules, without the carried cooldowns and under the clean rules, PT-HR on the
same games). Each variant is a run folder ``OUT/<variant>`` (stages ``train``, ``play``; killed at
any point, ``--resume`` continues from the last checkpoint); ``OUT/ablation.md`` tabulates the
variants played so far.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import raidjax
from experiments.b1_switches import SWITCHES, play_switches
from raidjax.io import HelpFormatter, atomic_write, run_cli, whole_number_arg
from trainers import checkpoint, loop
from trainers.config import PRESETS, Config
from trainers.curriculum import RANGE_TABLE, range_table
from trainers.mapoca import make_trainer
from trainers.runfolder import SEED_MAX, RunFolder, check_out, markdown_table
from trainers.runs import mapoca_learner, per_run_columns

_REFERENCE_ENDS = {"episode_ends": "reference"}
_OPTIMISER = {**_REFERENCE_ENDS, "ent_coef": 0.01, "adam_eps": 1e-8, "max_grad_norm": 0.0}
_AGENT_ROWS = {**_OPTIMISER, "minibatch_rows": "agents", "n_minibatches": 96}  # 8192 x 3 / 96 = 256 rows
# name: (what it changes, overrides of the cpu preset on the reference senses); the order of the table.
VARIANTS = {
    "today": ("the learner before 2026-11-29: a win is terminal, a death does not end a trajectory",
              {"episode_ends": "terminal"}),
    "win_bootstrapped": ("a win bootstraps from the final observation's value (row 1 alone)",
                         {"episode_ends": "win_bootstrapped"}),
    "reference_ends": ("the reference trainer's game ends: a win bootstraps, a death ends that player's "
                       "trajectory with a bootstrap, value loss over agent experiences (rows 1-2, 7)", _REFERENCE_ENDS),
    "optimiser": ("+ entropy 0.01, Adam eps 1e-8, no gradient clipping (rows 8-9)", _OPTIMISER),
    "agent_rows": ("+ minibatches of 256 agent experiences, 96 per epoch (row 10)", _AGENT_ROWS),
    "network": ("+ ML-Agents' networks, hidden 64, 4 heads (rows 11-15)",
                {**_AGENT_ROWS, "network": "reference", "heads": 4}),
    # Not a reference row (the reference's yaml keeps the rate constant): the preset's choice with a
    # learning rate that decays to 0 over the run, against a team undone by one late update
    # (docs/results/benchmark1.md, "ten and thirty-five updates before the end").
    "lr_annealed": ("today's ends with the learning rate decayed linearly to 0 over the run (not a reference row)",
                    {"episode_ends": "terminal", "anneal_lr": True}),
    # Not a row added: the reference trainer whole, at the paper's budget unless --total-steps says
    # otherwise (about 10 h per run on a 2-core CPU; docs/results/speed.md, "The learner").
    "paper": ("the `paper` preset: every row, the reference buffer (11 arenas x 256 decisions), batch and "
              "2 x 256 networks, 16.7 M decisions per run", None),
    # The same with the reference's asynchronous data approximated (row 17, trainers.windows): each of
    # its 280 arenas advances about 10 decisions per update (2 816 / 280), and a trajectory arrives at
    # its episode's end (games last about 100 decisions: docs/results/speed.md) or at 256 steps, so a
    # row trains about 0-10 updates after it was acted, 5 on average (an estimate from the configs).
    # 8 phases (32 decisions per arena and update; rows 0-7 updates old, 3.5 on average) is the
    # divisor of 256 nearest it (16: 0-15, 7.5). A run's windows are about 110 MB (memory, checkpoints).
    "paper_stale": ("the `paper` preset with the reference's asynchronous data approximated: 8 groups of 11 "
                    "arenas, each update training on the 256-decision window the last 8 updates' policies "
                    "acted (row 17)", None),
}
# Variants that are not the reference trainer's rows added in turn (the rows before them add up).
NOT_ROWS = ("lr_annealed", "paper", "paper_stale")
STALE_PHASES = 8  # paper_stale's Config.stale_phases
CPU_BUDGET = 1_500_000  # decisions per run of the variants on the cpu preset


def variant_config(name: str, total_steps: int | None = None) -> Config:
    """The `cpu` preset on the reference senses with variant ``name``'s overrides (every variant sets
    ``episode_ends``, so the preset's own choice, made from this ablation, does not enter), or for
    ``"paper"`` the `paper` preset (``"paper_stale"``: with ``STALE_PHASES``). ``total_steps``: decisions
    per run (default: 1.5 M on the cpu preset, the paper's 16.7 M for ``"paper"`` and ``"paper_stale"``)."""
    if name in ("paper", "paper_stale"):
        paper = PRESETS["mapoca"]["paper"]
        # 2 updates per chunk: a checkpoint every 20 updates (loop.train's 10 chunks), about 13 min
        # of 6 runs on 2 cores, instead of 100 updates at the preset's 10 per chunk.
        return paper.replace(total_steps=total_steps or paper.total_steps, eval_games=0, updates_per_chunk=2,
                             stale_phases=STALE_PHASES if name == "paper_stale" else 1)
    return PRESETS["mapoca"]["cpu"].replace(senses="reference", total_steps=total_steps or CPU_BUDGET, eval_games=0,
                                            **VARIANTS[name][1])


def run_inputs(ranges, seeds: int, seed: int, only=None):
    """``(teams, (keys, contents, range tables))``: run ``i = r * seeds + s`` plays ``ranges[r]`` with
    key ``fold_in(PRNGKey(seed), i)``. ``only``: the seed indices ``s`` to keep (default all), each
    with the key it has among all ``seeds``, so that a seed trained alone is the same run as in the
    whole layout (a 10 h `paper` run gives its cell before the next starts)."""
    teams, index = [], []
    for r_i, r in enumerate(ranges):
        for s in range(seeds):
            if only is None or s in only:
                teams.append({"ranges": (float(r),), "seed": s})
                index.append(r_i * seeds + s)
    keys = jnp.stack([jax.random.fold_in(jax.random.PRNGKey(seed), i) for i in index])
    contents = jax.tree.map(lambda *x: jnp.stack(x), *[raidjax.make_params(skill_range=t["ranges"][0]) for t in teams])
    tables = jnp.stack([range_table(t["ranges"], size=RANGE_TABLE) for t in teams])
    return teams, (keys, contents, tables)


def train_variant(rf: RunFolder, cfg: Config, inputs, n_runs: int) -> dict:
    """Train the variant's runs in one vmapped program (checkpoints in ``rf``); timing figures."""
    trainer = make_trainer(cfg, redraw_ranges=True)

    row = lambda m: per_run_columns(m, [str(i) for i in range(n_runs)])  # noqa: E731
    describe = lambda r: "training win " + " ".join(f"{r[k]:.2f}" for k in r if k.startswith("win/"))
    learner = mapoca_learner(trainer, inputs, n_runs, row=row, describe=describe)
    done = loop.train(learner, rf.path("checkpoints"), rf.out / "train", log=rf.log, checkpoint_every=10)
    decisions = cfg.num_updates * cfg.decisions_per_update
    return {"runs": n_runs, "decisions_per_run": decisions, "train_seconds": done.seconds,
            "compile_seconds": done.compile_seconds, "decisions_per_s": decisions * n_runs / max(done.seconds, 1e-9)}


def final_actors(rf: RunFolder, cfg: Config, inputs):
    """``(actor, weights [n_runs, ...])`` from the variant's final checkpoint."""
    trainer = make_trainer(cfg, redraw_ranges=True)
    abstract = jax.eval_shape(jax.vmap(trainer.init), *inputs)
    final = rf.out / "checkpoints" / str(cfg.num_updates)
    runner, _, _ = checkpoint.restore(final, abstract)
    return trainer.actor, runner.params["actor"]


def overview(plays: dict[str, list[dict]]) -> str:
    """One row per variant: per range, the seeds' mean win rate under the reference rules / without
    the carry / under the clean rules, and the chain positions (all seeds) below PT-HR's."""
    ranges = sorted({r["range"] for rows in plays.values() for r in rows})
    body = []
    for name, rows in plays.items():
        by = {(r["switch"], r["range"], r["agent"], r.get("seed")): r for r in rows}
        cells = [name]
        for rg in ranges:
            hr = by.get(("reference", rg, "PT-HR", None))
            seeds = sorted({r["seed"] for r in rows if r["agent"] == "MA-POCA" and r["range"] == rg})
            if hr is None or not seeds:
                cells += ["", ""]
                continue
            team = {(sw, s): by[(sw, rg, "MA-POCA", s)] for sw in SWITCHES for s in seeds}
            means = [np.mean([team[(sw, s)]["win_rate"] for s in seeds]) for sw in SWITCHES]
            below = sum(a < b for s in seeds for a, b in zip(team[("reference", s)]["win_rate_by_position"],
                                                              hr["win_rate_by_position"], strict=True))
            n_pos = len(seeds) * len(hr["win_rate_by_position"])
            cells += [" / ".join(f"{m:.3f}" for m in means), f"{below} of {n_pos}"]
        body.append(cells)
    header = ["variant"] + [h for rg in ranges for h in (f"range {rg:g}: reference / no carry / clean",
                                                           f"range {rg:g}: positions below PT-HR")]
    return markdown_table(header, body)


def table(*outs: Path) -> str:
    """``ablation.md``: the overview, then per variant, range and seed, all games / first game / lowest
    position / positions below PT-HR's / without the carry / clean rules, and PT-HR's row per range.
    Several ``outs`` (seeds trained alone, ``--only-seeds``) are read as one: their play rows join
    (PT-HR's, the same games in every folder, once)."""
    plays = {}
    for out in outs:
        for name in VARIANTS:
            path = out / name / "play.jsonl"
            if path.exists():
                plays.setdefault(name, []).extend(json.loads(x) for x in path.read_text().splitlines())
    plays = {name: plays[name] for name in VARIANTS if name in plays}
    lines = [overview(plays), ""] if plays else []
    for name, rows in plays.items():
        what = VARIANTS[name][0]
        by = {(r["switch"], r["range"], r["agent"], r.get("seed")): r for r in rows}
        body = []
        for rg in sorted({r["range"] for r in rows}):
            hr = by[("reference", rg, "PT-HR", None)]
            body.append([f"PT-HR, range {rg:g}", hr["win_rate"], hr["win_rate_first_game"],
                         min(hr["win_rate_by_position"]), "",
                         by[("carry_cooldowns=False", rg, "PT-HR", None)]["win_rate"],
                         by[("clean", rg, "PT-HR", None)]["win_rate"]])
            for s in sorted({r["seed"] for r in rows if r["agent"] == "MA-POCA" and r["range"] == rg}):
                t = by[("reference", rg, "MA-POCA", s)]
                below = sum(a < b for a, b in zip(t["win_rate_by_position"], hr["win_rate_by_position"], strict=True))
                body.append([f"range {rg:g}, seed {s}", t["win_rate"], t["win_rate_first_game"],
                             min(t["win_rate_by_position"]), below,
                             by[("carry_cooldowns=False", rg, "MA-POCA", s)]["win_rate"],
                             by[("clean", rg, "MA-POCA", s)]["win_rate"]])
        lines += [f"### {name}: {what}", "", markdown_table(
            ["team", "reference rules", "first game", "lowest position", "positions below PT-HR",
             "carry_cooldowns=False", "clean rules"], body), ""]
    return "\n".join(lines)


def main(argv=None) -> str:
    ap = argparse.ArgumentParser(prog="python -m experiments.ablation", description=__doc__.split("\n")[0],
                                 formatter_class=HelpFormatter)
    ap.add_argument("--out", type=Path, required=True, help="folder of the variants' run folders")
    ap.add_argument("--variants", nargs="+", choices=list(VARIANTS), default=list(VARIANTS)[:3],
                    help="variants to train and play, in this order")
    ap.add_argument("--ranges", nargs="+", type=float, default=[9.0, 13.0], help="skill ranges (reference content)")
    ap.add_argument("--seeds", type=whole_number_arg(1), default=3, help="training seeds per range")
    ap.add_argument("--seed", type=whole_number_arg(0, SEED_MAX), default=0,
                    help="base PRNG seed of the runs (the same in every variant)")
    ap.add_argument("--only-seeds", nargs="+", type=int, metavar="S",
                    help="train and play only these of the --seeds seed indices (0-based), as they are in the "
                         "whole layout: one paper-budget seed at a time")
    ap.add_argument("--total-steps", type=whole_number_arg(1),
                    help=f"decisions per run (default: {CPU_BUDGET:,} on the cpu preset, the paper's for 'paper')")
    ap.add_argument("--games", type=whole_number_arg(1), default=1000, help="chained games per team and rule switch")
    ap.add_argument("--resume", action="store_true", help="continue the variants already started in --out")
    ap.add_argument("--tables-of", nargs="+", type=Path, metavar="DIR",
                    help="train nothing: write OUT/ablation.md from the play rows of these --out folders "
                         "(seeds trained alone with --only-seeds), as one table")
    args = ap.parse_args(argv)
    check_out(args.out)
    if args.tables_of:
        for d in args.tables_of:
            if not any((d / n / "play.jsonl").exists() for n in VARIANTS):
                raise ValueError(f"--tables-of: {d} holds no variant that has played (no <variant>/play.jsonl)")
        text = table(*args.tables_of)
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write(args.out / "ablation.md", text + "\n")
        print(text)
        return text
    for r in args.ranges:
        if not 1 <= r <= 20:
            raise ValueError(f"--ranges: value {r:g}; allowed: numbers in [1, 20]")
    for s in args.only_seeds or ():
        if not 0 <= s < args.seeds:
            raise ValueError(f"--only-seeds: value {s}; allowed: seed indices 0..{args.seeds - 1} "
                             f"(--seeds {args.seeds})")
    if args.resume and not any((args.out / n / "config.json").exists() for n in args.variants):
        raise ValueError(f"--resume: {args.out} holds no started variant to resume (no <variant>/config.json for "
                         f"{', '.join(args.variants)}); drop --resume to start them")
    teams, inputs = run_inputs(args.ranges, args.seeds, args.seed, args.only_seeds)
    for name in args.variants:
        cfg = variant_config(name, args.total_steps)
        with RunFolder(args.out / name, {"ablation": name, "config": cfg.to_dict(), "ranges": args.ranges,
                                         "seeds": args.seeds, "seed": args.seed, "games": args.games,
                                         # only when given: folders started before the flag still resume
                                         **({"only_seeds": args.only_seeds} if args.only_seeds else {})},
                       resume=args.resume and (args.out / name / "config.json").exists()) as rf:
            timing = rf.stage("train", lambda cfg=cfg, rf=rf: train_variant(rf, cfg, inputs, len(teams)))

            def play(cfg=cfg, rf=rf):
                actor, weights = final_actors(rf, cfg, inputs)
                rows = play_switches(actor, weights, teams, cfg.senses, cfg.deterministic_eval, args.games, log=rf.log)
                stamp = raidjax.io.machine()
                atomic_write(rf.path("play.jsonl"),
                             "".join(json.dumps({**r, "games": args.games, "machine": stamp}) + "\n" for r in rows))
                return {"rows": len(rows)}

            rf.stage("play", play)
            if not (rf.out / "summary.json").exists():
                rf.finish({"ablation": name, "train": timing, "switches": list(SWITCHES)})
    text = table(args.out)
    atomic_write(args.out / "ablation.md", text + "\n")
    print(text)
    return text


if __name__ == "__main__":
    run_cli(main, (ValueError, checkpoint.CheckpointError),
            "finished stages and the newest checkpoint are kept: rerun the same command with --resume "
            "(without it if no variant had started)")

