"""Command line of the MA-POCA trainer (``python -m trainers.mapoca_cli``).

The outer Python loop only runs jitted chunks of ``updates_per_chunk`` updates (all seeds
vmapped together), prints progress, appends one metrics row per chunk to
``DIR/metrics.jsonl`` and ``DIR/metrics.csv``, checkpoints every ``checkpoint_every`` updates,
and at the end evaluates the team over ``eval_games`` games next to PT-HR on the same content.
The last stdout line is one JSON object (``win_rate``, ``heuristic_win_rate``,
``env_steps_per_s``, ``seconds``, ...), also written to ``DIR/result.json``. The run folder
follows ``trainers.runfolder``: ``--resume`` continues from the newest intact checkpoint with the
same settings; anything else on an existing run is refused.

    python -m trainers.mapoca_cli --preset cpu --skill-range 13 --total-steps 2000000 --seeds 1 --out runs/r13
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import raidjax
from raidjax import pcg
from raidjax.io import HelpFormatter, atomic_write, fmt_seconds, machine, run_cli, whole_number_arg
from raidjax.sharding import put_batch
from trainers import checkpoint
from trainers.config import Config, load_config
from trainers.mapoca import load_policy, make_trainer, summarize
from trainers.metrics import MetricsLog
from trainers.runfolder import RunFolder


def parse_args(argv=None) -> argparse.Namespace:
    """CLI arguments (see the module docstring); numbers are checked here, before compiling."""
    ap = argparse.ArgumentParser(prog="python -m trainers.mapoca_cli", description="Train MA-POCA on raidjax.",
                                 formatter_class=HelpFormatter)
    ap.add_argument("--preset", default="cpu", choices=["paper", "cpu"],
                    help="paper: the paper's budget and network; cpu: a smaller one that trains on a CPU")
    ap.add_argument("--config", help="JSON file of Config fields, applied after the preset (default: none)")
    ap.add_argument("--skill-range", type=float, nargs="+", help="range(s) of the players' skill; "
                    "several values = drawn per episode (default: the preset's)")
    ap.add_argument("--content-box", action="store_true", default=None,
                    help="train over the content generator's whole skill box (range, cool time, cast time, "
                    "coefficient drawn per episode; Config.content_box) instead of --skill-range")
    ap.add_argument("--players", nargs="+", help="the team's class presets, e.g. warrior mage priest "
                    "(default: the preset's, three mages)")
    ap.add_argument("--parameters", nargs="+", help="the box of --content-box: generator parameter names "
                    "(raidjax.pcg.space, e.g. skill1.range boss.max_hp=500:3000; default: the paper's four)")
    ap.add_argument("--total-steps", type=whole_number_arg(1),
                    help="environment decisions per seed (default: the preset's)")
    ap.add_argument("--seeds", type=whole_number_arg(1), default=1, help="seeds trained together (vmapped)")
    ap.add_argument("--seed", type=int, default=0, help="base PRNG seed")
    ap.add_argument("--out", required=True, help="run folder, new or holding this run with --resume (required)")
    ap.add_argument("--resume", action="store_true", help="continue the run in --out from its newest intact "
                    "checkpoint (same settings; a finished run is left as it is)")
    ap.add_argument("--checkpoint-every", type=whole_number_arg(1),
                    help="updates between checkpoints (default: the preset's)")
    ap.add_argument("--updates-per-chunk", type=whole_number_arg(1),
                    help="updates per jitted chunk, one log row each (default: the preset's)")
    ap.add_argument("--eval-games", type=whole_number_arg(0), help="games of the final evaluation, 0 skips it; "
                    "may change on --resume (default: the preset's)")
    ap.add_argument("--max-chunks", type=whole_number_arg(1), help="stop (after a checkpoint) once this many chunks "
                    "ran in this invocation (default: no limit)")
    return ap.parse_args(argv)


def eval_contents(cfg: Config) -> dict[str, raidjax.Params]:
    """The contents of the final evaluation, by label: one per skill range in ``cfg.skill_ranges``,
    or under ``cfg.content_box`` the box's centre and each parameter at its bounds
    (``raidjax.pcg.box_probes``; label: the values joined by ``/``)."""
    if not cfg.content_box:
        return {f"{r:g}": raidjax.make_params(players=list(cfg.players), skill_range=r) for r in cfg.skill_ranges}
    space = pcg.make_space(cfg.parameters, cfg.players)
    base = pcg.base_game(cfg.players)
    return {"/".join(f"{v:g}" for v in sk): space.apply(base, jnp.asarray(sk)) for sk in pcg.env.box_probes(space)}


def evaluate(out: Path, cfg: Config, n_seeds: int, key: jax.Array) -> dict:
    """Win rates of every seed's trained team and of PT-HR over ``cfg.eval_games`` games per
    content of ``eval_contents`` (same content, same typed PRNG ``key``). Returns a JSON-able
    dict (``per_range`` keyed by ``eval_contents``' labels)."""
    per_range = {}
    teams = [load_policy(out, seed=s) for s in range(n_seeds)]  # one policy, n_seeds weights: one compile
    rate = lambda x: round(float(x), 6)  # float32 win rates without their float32 noise (0.726, not 0.72600001)
    for label, content in eval_contents(cfg).items():
        hr = rate(raidjax.win_rate(raidjax.playtest(key, content, raidjax.policies.heuristic, cfg.eval_games)))
        wins = [rate(raidjax.win_rate(raidjax.playtest(key, content, p, cfg.eval_games, weights=w))) for p, w in teams]
        per_range[label] = {"win_rate": rate(np.mean(wins)), "win_rate_per_seed": wins,
                               "heuristic_win_rate": hr}
    return {
        "win_rate": rate(np.mean([v["win_rate"] for v in per_range.values()])),
        "heuristic_win_rate": rate(np.mean([v["heuristic_win_rate"] for v in per_range.values()])),
        "per_range": per_range,
    }


def main(argv=None) -> dict:
    """Train (or resume), log, checkpoint, evaluate; print and return the final JSON object."""
    t_start = time.perf_counter()
    args = parse_args(argv)
    cfg = load_config(args.preset, args.config, skill_ranges=args.skill_range, content_box=args.content_box,
                      players=args.players and tuple(args.players),
                      parameters=args.parameters and tuple(args.parameters),
                      total_steps=args.total_steps,
                      checkpoint_every=args.checkpoint_every, updates_per_chunk=args.updates_per_chunk,
                      eval_games=args.eval_games)
    settings = {"trainer": "mapoca", "preset": args.preset, "seeds": args.seeds, "seed": args.seed,
                "config": {k: v for k, v in cfg.to_dict().items() if k != "eval_games"}, "eval_games": cfg.eval_games}
    rf = RunFolder(args.out, settings, resume=args.resume, ignore=("eval_games",))
    if rf.finished:
        return rf.already_finished()
    out, ckpt_dir = rf.out, rf.out / "checkpoints"
    trainer = make_trainer(cfg)
    keys = jax.random.split(jax.random.PRNGKey(args.seed), args.seeds)
    init = jax.jit(jax.vmap(trainer.init))
    t0 = time.perf_counter()
    if checkpoint.latest_step(ckpt_dir) is not None:
        runner, _, meta = checkpoint.restore(ckpt_dir, jax.eval_shape(init, keys), quarantine=True)
        start_chunk, seconds_before = meta["chunk"], meta["seconds"]
        print(f"resumed from the checkpoint at update {meta['update']}", flush=True)
    else:  # a new run, or one stopped before its first checkpoint
        runner, start_chunk, seconds_before = init(keys), 0, 0.0
    runner = put_batch(runner, args.seeds)  # the seeds split over every visible device (raidjax.sharding)
    chunk = jax.jit(jax.vmap(trainer.chunk), donate_argnums=0).lower(runner).compile()
    compile_s = time.perf_counter() - t0
    print(f"compiled in {compile_s:.1f}s; {cfg.num_updates} updates x {cfg.decisions_per_update} decisions "
          f"x {args.seeds} seeds; {machine()}", flush=True)
    log = MetricsLog(out, resume_update=start_chunk * cfg.updates_per_chunk)
    per_chunk = cfg.updates_per_chunk * cfg.decisions_per_update
    every = max(1, -(-cfg.checkpoint_every // cfg.updates_per_chunk))
    t_loop, done_here = time.perf_counter(), 0
    end_chunk = cfg.num_chunks if args.max_chunks is None else min(cfg.num_chunks, start_chunk + args.max_chunks)
    for c in range(start_chunk, end_chunk):
        runner, m = chunk(runner)
        row = summarize(jax.device_get(m))
        done_here += 1
        el = time.perf_counter() - t_loop
        sps = done_here * per_chunk * args.seeds / el
        steps = (c + 1) * per_chunk
        row = {"chunk": c, "update": (c + 1) * cfg.updates_per_chunk, "env_steps": steps,
               "seconds": seconds_before + el, "steps_per_s": sps, **row}
        log.write(row)
        eta = (end_chunk - c - 1) * el / done_here
        total = cfg.num_updates * cfg.decisions_per_update
        print(f"[{c + 1}/{cfg.num_chunks}] steps {steps / 1e6:.2f}M/{total / 1e6:.2f}M"
              f"  {sps:,.0f} steps/s  ETA {fmt_seconds(eta)}  return {row['return']:.2f}  win {row['win_rate']:.3f}"
              f"  len {row['length']:.0f}  ent {row['entropy']:.2f}", flush=True)
        if (c + 1) % every == 0 or c + 1 == end_chunk:  # always before stopping, so --resume can continue
            meta = {"chunk": c + 1, "update": (c + 1) * cfg.updates_per_chunk, "env_steps": steps,
                    "seconds": seconds_before + el}
            checkpoint.save(ckpt_dir, runner, runner.params["actor"], cfg.to_dict(), meta)
    train_s = time.perf_counter() - t_loop
    if end_chunk < cfg.num_chunks:
        print(f"stopped after chunk {end_chunk}/{cfg.num_chunks} (--max-chunks); rerun with --resume to continue",
              flush=True)
        return {"stopped_at_chunk": end_chunk}
    result = {"preset": args.preset, "skill_ranges": list(cfg.skill_ranges),
              "content_box": cfg.content_box, "seeds": args.seeds,
              "env_steps": end_chunk * per_chunk,
              "env_steps_per_s": round(done_here * per_chunk * args.seeds / max(train_s, 1e-9), 1),
              "compile_seconds": round(compile_s, 2), "train_seconds": round(seconds_before + train_s, 2)}
    if cfg.eval_games > 0:
        t_eval = time.perf_counter()
        result.update(evaluate(out, cfg, args.seeds, jax.random.key(args.seed + 12345)))
        result["eval_seconds"] = round(time.perf_counter() - t_eval, 2)
    result["seconds"] = round(time.perf_counter() - t_start, 2)
    atomic_write(out / "result.json", json.dumps(result, indent=1))
    print(json.dumps(result), flush=True)
    return result


def cli(argv=None) -> None:
    """``main`` as a command line: one-line errors (exit 2), one line on Ctrl-C (exit 130)."""
    run_cli(lambda: main(argv), (ValueError, checkpoint.CheckpointError),
            "the newest checkpoint is kept: rerun the same command with --resume to continue")


if __name__ == "__main__":
    cli()
