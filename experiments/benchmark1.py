"""Benchmark 1 of the RaidEnv paper (PROTOCOLS.md §11): playtesting agents, end to end.

    python -m experiments.benchmark1 --scale {smoke,cpu,paper} --out DIR [--protocol {paper,raidjax}]

The MA-POCA runs train side by side in vmapped, jitted programs of ``Scale.runs_per_program`` runs
(8), one group after another: each run is a row with its own seed, content and set of skill ranges
(``trainers.curriculum.range_table``), so groups of one size share one compiled program. The runs
(``R`` = seeds, ``Q`` = population size):

- ``table/r{5,9,13,17}`` x R: the win-rate table's MA-POCA, reference content at one range;
- ``robust/MA-POCA{1..4}`` x R: ranges drawn (see the protocols) from {5}, {5,9}, {5,9,13}, {5,9,13,17};
- ``population/r{3,4,19,20}`` x Q: trained directly on each unseen test range.

Protocols (``PROTOCOLS``; PROTOCOLS.md §11):

- ``paper`` (default), the reference configs: MA-POCA1..4 and the populations train on the
  reference content (players' cool time 0.5: ``RL_GENERALIZATION/JSON/train/*.json``,
  ``population/*.json``) and are tested on the test content (cool time 1.0:
  ``test/skill_{easy,hard}.json``); an arena redraws its range every second episode
  (``trainers.curriculum.next_draws``, one draw per arena shared by its players).
- ``raidjax``: train on the test content too (seen and unseen content differ only in the skill
  range) and redraw the range at every episode; raidjax's observation and 10 masked actions.
- ``paper-raidjax-senses``: ``paper`` with raidjax's observation and actions (the observation
  comparison: everything else as ``paper``).

Stages (``trainers.runfolder``; rerunning the command with ``--resume`` resumes): ``train`` (orbax checkpoints
every few chunks, progress lines with decisions/s and ETA), ``evaluate`` (every run's team and
PT-HR/PT-RD, ``games`` games per cell, all cells in one vmapped playtest), ``heatmaps``
(MA-POCA1 vs MA-POCA3 occupancy over ranges), ``report`` (``experiments.b1_report``).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import io
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import raidjax
from raidjax.io import HelpFormatter, atomic_write, run_cli, whole_number_arg
from raidjax.playtest import auto_games_per_arena
from trainers import checkpoint, loop
from trainers.config import PRESETS, Config
from trainers.curriculum import RANGE_TABLE, range_table
from trainers.mapoca import make_trainer
from trainers.networks import sample_actions
from trainers.runfolder import RunFolder, add_run_arguments
from trainers.runs import mapoca_learner, per_run_columns

TABLE_RANGES = (5.0, 9.0, 13.0, 17.0)
ROBUST_SETS = {"MA-POCA1": (5.0,), "MA-POCA2": (5.0, 9.0), "MA-POCA3": (5.0, 9.0, 13.0),
               "MA-POCA4": (5.0, 9.0, 13.0, 17.0)}
TEST_RANGES = (3.0, 4.0, 19.0, 20.0)
TEST_COOL_TIME = 1.0  # test/skill_easy.json, skill_hard.json
TRAIN_COOL_TIME = 0.5  # train/skill*_config.json, population/*.json (= the reference content)
MIXED_TEAM = ("warrior", "mage", "priest")  # raidjax's mixed-team row (not in the paper)


@dataclasses.dataclass(frozen=True)
class Protocol:
    """How the runs play and the robustness runs train. ``train_content``: content kind of
    MA-POCA1..4 and the populations (``"reference"``: cool time 0.5; ``"test"``: 1.0);
    ``redraw_every``: episodes of an arena per range draw (``trainers.config.Config.redraw_every``);
    ``senses``: every team's observation and action space (``Config.senses``), trained and tested."""

    train_content: str
    redraw_every: int
    senses: str


PROTOCOLS = {"paper": Protocol("reference", 2, "reference"), "raidjax": Protocol("test", 1, "raidjax"),
             # The paper's protocol played with raidjax's senses: the one difference from "paper" is
             # what the teams observe and how they act (the observation comparison of RESULTS).
             "paper-raidjax-senses": Protocol("reference", 2, "raidjax")}


@dataclasses.dataclass(frozen=True)
class Scale:
    """Budgets of one scale. ``trainer`` holds ``trainers.config.Config`` overrides on ``preset``."""

    preset: str
    total_steps: int  # environment decisions per run
    seeds: int  # R: runs per table cell and per MA-POCA-k
    population: int  # Q: population runs per unseen test range
    games: int  # games per evaluation cell
    heatmap_games: int
    heatmap_ranges: tuple[float, ...]
    checkpoint_chunks: int  # checkpoint every this many chunks
    trainer: tuple[tuple[str, object], ...] = ()
    # Runs trained side by side in one vmapped program; the groups train one after another. On the
    # 2-core CPU 8 runs of the cpu preset train at 1.06x one run's decisions/s in aggregate, 32 runs
    # at 0.97x (benchmarks/train_throughput.py --runs 1 8 32; the 32 runs' rollouts fill memory).
    runs_per_program: int = 8


SCALES = {
    # seconds: a tiny network and two updates; checks the plumbing, not the learning (the game
    # keeps its defaults: the smoke scale is about wiring, its numbers mean nothing)
    "smoke": Scale("cpu", total_steps=256, seeds=1, population=1, games=2, heatmap_games=2,
                   heatmap_ranges=(5.0, 13.0), checkpoint_chunks=1,
                   trainer=(("n_arenas", 16), ("n_steps", 8), ("n_minibatches", 2), ("update_epochs", 1),
                            ("hidden", 8), ("layers", 1), ("heads", 1), ("updates_per_chunk", 1))),
    # about 2 h 15 min on 2 CPU cores (docs/results/benchmark1.md): the cpu preset, 2 seeds, populations of 2,
    # 1.5 M decisions per run
    "cpu": Scale("cpu", total_steps=1_500_000, seeds=2, population=2, games=500, heatmap_games=500,
                 heatmap_ranges=(5.0, 9.0, 13.0, 17.0), checkpoint_chunks=5),
    # the paper's budgets: 50 M agent steps (the paper preset's 16.7 M decisions) per run, 5 seeds,
    # populations of 5
    "paper": Scale("paper", total_steps=PRESETS["mapoca"]["paper"].total_steps, seeds=5, population=5, games=500,
                   heatmap_games=500,
                   heatmap_ranges=(5.0, 9.0, 13.0, 17.0), checkpoint_chunks=5),
}


def config_of(scale: Scale, protocol: str = "paper") -> Config:
    """The trainer ``Config`` of a scale under a protocol (``PROTOCOLS`` key)."""
    pr = PROTOCOLS[protocol]
    return PRESETS["mapoca"][scale.preset].replace(total_steps=scale.total_steps, eval_games=0,
                                                   redraw_every=pr.redraw_every, senses=pr.senses,
                                                   **dict(scale.trainer))


def content_of(kind: str, skill_range: float = 5.0) -> raidjax.Params:
    """``"reference"`` (players' cool time 0.5, the training content of the reference configs),
    ``"test"`` (cool time 1.0) or ``"mixed"`` (``MIXED_TEAM`` with the catalogue's skills) content
    with every player's skill slot 1 at the given range."""
    if kind == "mixed":  # same shapes as the mages' content, so its runs join the one vmapped program
        return raidjax.make_params(players=list(MIXED_TEAM), skill_range=skill_range)
    cool = {"reference": TRAIN_COOL_TIME, "test": TEST_COOL_TIME}[kind]
    return raidjax.with_player_skill(raidjax.make_params(skill_range=skill_range), cool_time=cool)


def test_content(skill_range: float = 5.0) -> raidjax.Params:
    """The robustness study's test content: reference content, cool time 1.0, the given range."""
    return content_of("test", skill_range)


def runs_of(scale: Scale, protocol: str = "paper") -> list[dict]:
    """Every training run: ``name``, ``group``, ``ranges``, ``content`` (training content kind,
    ``content_of``), ``seed``. The win-rate table trains and is tested on the reference content;
    MA-POCA1..4 and the populations train on ``PROTOCOLS[protocol].train_content`` and are tested
    on the test content."""
    kind = PROTOCOLS[protocol].train_content
    runs = [dict(name=f"table/r{r:g}", group="table", ranges=(r,), content="reference", seed=s)
            for r in TABLE_RANGES for s in range(scale.seeds)]
    runs += [dict(name=f"robust/{k}", group="robust", ranges=v, content=kind, seed=s)
             for k, v in ROBUST_SETS.items() for s in range(scale.seeds)]
    runs += [dict(name=f"population/r{r:g}", group="population", ranges=(r,), content=kind, seed=s)
             for r in TEST_RANGES for s in range(scale.population)]
    runs += [dict(name=f"mixed/r{r:g}", group="mixed", ranges=(r,), content="mixed", seed=s)
             for r in TABLE_RANGES for s in range(scale.seeds)]
    return runs


def _stack(trees):
    return jax.tree.map(lambda *x: jnp.stack(x), *trees)


def _run_inputs(runs: list[dict], base_seed: int, first: int = 0):
    """Keys, contents and range tables of ``runs``, the runs ``first``, ``first + 1``, ... of the
    benchmark (a run's key depends on its place in the whole benchmark, not in its group)."""
    keys = jnp.stack([jax.random.fold_in(jax.random.PRNGKey(base_seed), first + i) for i in range(len(runs))])
    contents = _stack([content_of(r["content"]) for r in runs])
    tables = jnp.stack([range_table(r["ranges"], size=RANGE_TABLE) for r in runs])  # one shape for all runs
    return keys, contents, tables


class Interrupted(Exception):
    """Training stopped early on purpose (``--max-chunks``); rerunning the command resumes."""


def _training_wins(row: dict) -> str:
    """Progress text: the mean training win rate of each group of runs (``win/<group>/...`` fields)."""
    groups: dict[str, list[float]] = {}
    for k, v in row.items():
        if k.startswith("win/"):
            groups.setdefault(k.split("/")[1], []).append(v)
    return "training win " + "  ".join(f"{g} {np.mean(w):.2f}" for g, w in groups.items() if g != "mixed")


def groups_of(n_runs: int, per_program: int) -> list[range]:
    """The runs' indices cut into consecutive groups of at most ``per_program`` runs, each trained
    as one vmapped program (``Scale.runs_per_program``)."""
    return [range(i, min(i + per_program, n_runs)) for i in range(0, n_runs, per_program)]


def merge_group_metrics(rf: RunFolder, n_groups: int) -> None:
    """``train/metrics.csv``: the groups' rows side by side (row ``i`` of every group is its chunk
    ``i``; the ``win/<run>/<seed>`` columns of every run), the file the report reads."""
    tables = []
    for g in range(n_groups):
        with open(rf.path("train", f"metrics_group{g}.csv")) as f:
            tables.append(list(csv.DictReader(f)))
    n = min(len(t) for t in tables)
    rows = [{k: v for t in tables for k, v in t[i].items()} for i in range(n)]
    buf = io.StringIO()
    if rows:
        w = csv.DictWriter(buf, list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    atomic_write(rf.path("train", "metrics.csv"), buf.getvalue())


def stage_train(rf: RunFolder, scale: Scale, runs: list[dict], base_seed: int, max_chunks: int | None = None,
                protocol: str = "paper") -> dict:
    """Train every run, ``scale.runs_per_program`` at a time in one vmapped program (resuming each
    group from its last checkpoint, ``checkpoints/mapoca/group<g>``; ``trainers.loop``); returns
    timing figures. ``max_chunks`` stops after that many chunks of this invocation (raises
    ``Interrupted``, after a checkpoint)."""
    cfg = config_of(scale, protocol)
    trainer = make_trainer(cfg, redraw_ranges=True)
    groups = groups_of(len(runs), scale.runs_per_program)
    rf.log(f"train: {len(runs)} runs in {len(groups)} group(s) of up to {scale.runs_per_program} x {cfg.num_chunks} "
           f"chunks x {cfg.updates_per_chunk * cfg.decisions_per_update} decisions")
    seconds, compile_seconds, left = 0.0, 0.0, max_chunks
    for g, idx in enumerate(groups):
        members = [runs[i] for i in idx]

        def row(m: dict, members=members) -> dict:
            return per_run_columns(m, [f"{r['name']}/{r['seed']}" for r in members])

        learner = mapoca_learner(trainer, _run_inputs(members, base_seed, idx[0]), len(members), row=row,
                                 describe=_training_wins)
        done = loop.train(learner, rf.path("checkpoints", "mapoca", f"group{g}"), rf.out / "train",
                          metrics_name=f"metrics_group{g}",
                          log=lambda s, g=g: rf.log(f"train group {g} ({g + 1} of {len(groups)}): {s}"),
                          checkpoint_every=scale.checkpoint_chunks, max_chunks=left)
        seconds += done.seconds
        compile_seconds += done.compile_seconds
        if not done.finished:
            raise Interrupted(f"stopped in group {g} at update {done.update}/{cfg.num_updates} (--max-chunks); "
                              "rerun with --resume to continue")
        if left is not None:
            left -= (done.update - done.start_update) // cfg.updates_per_chunk
            if left <= 0 and g + 1 < len(groups):
                raise Interrupted(f"stopped after group {g} (--max-chunks); rerun with --resume to continue")
    merge_group_metrics(rf, len(groups))
    decisions = cfg.num_updates * cfg.decisions_per_update
    return {"runs": len(runs), "groups": len(groups), "decisions_per_run": decisions,
            "compile_seconds": compile_seconds, "train_seconds": seconds,
            "decisions_per_s": decisions * len(runs) / max(seconds, 1e-9)}


def load_group_actors(out, scale: Scale, runs: list[dict], base_seed: int, protocol: str, group: int):
    """``(actor module, actor weights with a leading axis over the group's runs, senses)`` from the
    final checkpoint of training group ``group`` in the run folder ``out`` (an older checkpoint would
    be a less trained team: no fallback here).

    Raises:
        ValueError: the group has no final checkpoint (one line naming the folder).
    """
    cfg = config_of(scale, protocol)  # the senses fix the network's shapes
    trainer = make_trainer(cfg, redraw_ranges=True)
    idx = groups_of(len(runs), scale.runs_per_program)[group]
    abstract = jax.eval_shape(jax.vmap(trainer.init), *_run_inputs([runs[i] for i in idx], base_seed, idx[0]))
    final = Path(out) / "checkpoints" / "mapoca" / f"group{group}" / str(cfg.num_chunks * cfg.updates_per_chunk)
    if not final.exists():
        raise ValueError(f"run folder {str(out)!r}: training group {group} has no final checkpoint ({final}); "
                         "train it first (rerun its benchmark command with --resume)")
    runner, _, _ = checkpoint.restore(final, abstract)
    return trainer.actor, runner.params["actor"], cfg.senses


def load_actors(rf: RunFolder, scale: Scale, runs: list[dict], base_seed: int, protocol: str):
    """``(actor module, actor weights with a leading run axis, senses)`` of every run, from each
    training group's final checkpoint (``load_group_actors``)."""
    loaded = [load_group_actors(rf.out, scale, runs, base_seed, protocol, g)
              for g in range(len(groups_of(len(runs), scale.runs_per_program)))]
    actor, senses = loaded[0][0], loaded[0][2]
    return actor, jax.tree.map(lambda *w: jnp.concatenate(w), *[w for _, w, _ in loaded]), senses


def per_team(key, actor, weights, contents, measure, senses: str = "raidjax", greedy: bool = False) -> jax.Array:
    """``measure(key, content, policy)`` of C (team, content) cells, vmapped in one program.

    Args:
        key: PRNG key (split into one key per cell).
        actor: the actor module; weights: its parameters with a leading axis C.
        contents: ``Params`` with a leading axis C, played with the teams' ``senses``.
        measure: e.g. ``lambda k, c, p: raidjax.playtest(k, c, p, n)["outcome"]``.
        greedy: the teams play their most likely actions instead of sampling (a run's
            ``deterministic_eval``; Benchmark 1's teams sample, as its runs' config says).

    Returns:
        ``measure``'s output with a leading axis C.
    """

    def one(k, w, content):
        def policy(kk, obs, state, params):
            return sample_actions(kk, actor.apply(w, obs), obs.alive, greedy)[0]

        return measure(k, raidjax.with_senses(content, senses), policy)

    keys = jax.random.split(key, jax.tree.leaves(contents)[0].shape[0])
    return jax.jit(jax.vmap(one))(keys, weights, contents)


def eval_cells(runs: list[dict]) -> list[tuple[int, str, float, int]]:
    """The team cells ``(run index, content kind, range, seed)`` of the evaluation: a table run on
    the reference content at its range, MA-POCA1..4 on the test content at every unseen range,
    a population run on the test content at its range (whatever content they trained on)."""
    cells = []
    for i, r in enumerate(runs):
        if r["group"] == "robust":
            cells += [(i, "test", t, r["seed"]) for t in TEST_RANGES]
        else:
            kind = {"table": "reference", "mixed": "mixed"}.get(r["group"], "test")
            cells.append((i, kind, r["ranges"][0], r["seed"]))
    return cells


def stage_evaluate(rf: RunFolder, scale: Scale, runs: list[dict], base_seed: int, protocol: str = "paper") -> dict:
    """Win rates of every cell; returns ``{"cells": [...]}`` (one dict per cell)."""
    actor, weights, senses = load_actors(rf, scale, runs, base_seed, protocol)
    cells = eval_cells(runs)
    chained = auto_games_per_arena(scale.games)  # each arena plays up to 10 games in a row
    contents = _stack([content_of(k, rg) for _, k, rg, _ in cells])
    w = jax.tree.map(lambda x: x[jnp.asarray([c[0] for c in cells])], weights)
    t = time.perf_counter()
    out = np.asarray(per_team(jax.random.PRNGKey(base_seed + 777), actor, w, contents,
                              lambda k, c, p: raidjax.playtest(k, c, p, scale.games,
                                                               games_per_arena=chained)["outcome"], senses))
    rf.log(f"evaluate: {len(cells)} team cells x {scale.games} games in {time.perf_counter() - t:.0f}s")
    position = np.tile(np.arange(chained), scale.games // chained)  # raidjax.playtest's game order

    def rates(o: np.ndarray) -> dict:
        """A cell's win and draw rates, and the chain diagnostic: its arenas' first games after
        their warm-ups against their later games."""
        later = o[position > 0]
        return {"win_rate": float(np.mean(o == 1)), "draw_rate": float(np.mean(o == 3)),
                "win_rate_first_game": float(np.mean(o[position == 0] == 1)),
                "win_rate_later_games": float(np.mean(later == 1)) if later.size else float("nan"),
                "games": scale.games}

    rows = [{"agent": runs[i]["name"].split("/")[1] if runs[i]["group"] == "robust" else "MA-POCA",
             "group": runs[i]["group"], "run": runs[i]["name"], "seed": s, "content": kind, "range": rg, **rates(o)}
            for (i, kind, rg, s), o in zip(cells, out, strict=True)]
    # scripted agents: every (content, range) cell x `seeds` independent batches of games, one
    # playtest per policy with one content per group of games
    contents_ranges = ([("reference", r) for r in TABLE_RANGES] + [("test", r) for r in TEST_RANGES]
                       + [("mixed", r) for r in TABLE_RANGES])
    pt_cells = [(kind, rg, sd) for kind, rg in contents_ranges for sd in range(scale.seeds)]
    pt_contents = _stack([content_of(kind, rg) for kind, rg, _ in pt_cells])
    for which, name in enumerate(("PT-HR", "PT-RD")):  # raidjax.policies.SCRIPTS: one program plays both
        key = jax.random.PRNGKey(base_seed + (999 if name == "PT-HR" else 998))
        out = raidjax.playtest(key, pt_contents, raidjax.policies.script, len(pt_cells) * scale.games,
                               weights=jnp.int32(which), games_per_arena=chained)["outcome"]
        for (kind, rg, sd), o in zip(pt_cells, np.asarray(out).reshape(len(pt_cells), scale.games), strict=True):
            rows.append({"agent": name, "group": "scripted", "run": name, "seed": sd, "content": kind, "range": rg,
                         **rates(o)})
    rf.write_csv("win_rates", rows)
    return {"cells": rows}


def stage_heatmaps(rf: RunFolder, scale: Scale, runs: list[dict], base_seed: int, protocol: str = "paper") -> dict:
    """Occupancy maps of MA-POCA1 and MA-POCA3 (seed 0) over ``heatmap_ranges`` (test content);
    saved as ``heatmaps.npz`` (``[agent, range, player, 24, 24]``)."""
    actor, weights, senses = load_actors(rf, scale, runs, base_seed, protocol)
    agents = ("MA-POCA1", "MA-POCA3")
    idx = [next(i for i, r in enumerate(runs) if r["name"] == f"robust/{a}" and r["seed"] == 0) for a in agents]
    grid = [(i, rg) for i in idx for rg in scale.heatmap_ranges]
    contents = _stack([test_content(rg) for _, rg in grid])
    w = jax.tree.map(lambda x: x[jnp.asarray([g[0] for g in grid])], weights)
    maps = np.asarray(per_team(jax.random.PRNGKey(base_seed + 555), actor, w, contents,
                               lambda k, c, p: raidjax.playtest_occupancy(
                                  k, c, p, scale.heatmap_games,
                                  games_per_arena=auto_games_per_arena(scale.heatmap_games)), senses))
    maps = maps.reshape(len(agents), len(scale.heatmap_ranges), *maps.shape[1:])
    buf = io.BytesIO()
    np.savez(buf, maps=maps, agents=np.asarray(agents), ranges=np.asarray(scale.heatmap_ranges))
    atomic_write(rf.path("heatmaps.npz"), buf.getvalue())
    return {"agents": list(agents), "ranges": list(scale.heatmap_ranges), "games": scale.heatmap_games}


def main(argv=None) -> dict:
    """Run (or resume) Benchmark 1; returns the summary (also the last stdout line)."""
    ap = argparse.ArgumentParser(prog="python -m experiments.benchmark1", description=__doc__.split("\n")[0],
                                 formatter_class=HelpFormatter)
    add_run_arguments(ap, SCALES, "budgets: smoke (a test), cpu, paper")
    ap.add_argument("--protocol", choices=sorted(PROTOCOLS), default="paper",
                    help="paper: the reference player's observation and 8 actions; MA-POCA1..4 and populations "
                    "train at cool time 0.5, range redrawn every second episode; raidjax: raidjax's observation "
                    "and 10 masked actions, training at the test content (cool time 1.0), range redrawn every episode; "
                    "paper-raidjax-senses: the paper protocol with raidjax's observation and actions")
    ap.add_argument("--max-chunks", type=whole_number_arg(1),
                    help="stop training after this many chunks, to resume later (default: no limit)")
    args = ap.parse_args(argv)
    scale = SCALES[args.scale]
    runs = runs_of(scale, args.protocol)
    with RunFolder(args.out, {"benchmark": 1, "scale": args.scale, "seed": args.seed, "protocol": args.protocol,
                              "budgets": dataclasses.asdict(scale),
                              "trainer": config_of(scale, args.protocol).to_dict(), "runs": runs},
                   resume=args.resume) as rf:
        if rf.finished:
            return rf.already_finished()
        from experiments import b1_report

        try:
            timing = rf.stage("train", lambda: stage_train(rf, scale, runs, args.seed, args.max_chunks, args.protocol))
        except Interrupted as e:
            rf.log(str(e))
            return {"interrupted": True}
        ev = rf.stage("evaluate", lambda: stage_evaluate(rf, scale, runs, args.seed, args.protocol))
        rf.stage("heatmaps", lambda: stage_heatmaps(rf, scale, runs, args.seed, args.protocol))
        summary = rf.stage("report", lambda: b1_report.report(rf, ev["cells"], timing))
        return rf.finish({"benchmark": 1, "scale": args.scale, "protocol": args.protocol, **summary, "train": timing})


def cli(argv=None) -> None:
    """``main`` as a command line: one-line errors (exit 2), one line on Ctrl-C (exit 130)."""
    run_cli(lambda: main(argv), (ValueError, checkpoint.CheckpointError),
            "finished stages and the newest checkpoint are kept: rerun the same command with --resume")


if __name__ == "__main__":
    cli()
