"""Command line of the MA-POCA trainer (``python -m trainers.mapoca_cli``).

The outer Python loop only runs jitted chunks of ``updates_per_chunk`` updates (all seeds
vmapped together), prints progress, appends one metrics row per chunk to
``DIR/metrics.jsonl`` and ``DIR/metrics.csv``, checkpoints every ``checkpoint_every`` updates,
and at the end evaluates the team over ``eval_games`` games next to PT-HR on the same content.
The last stdout line is one JSON object (``win_rate``, ``heuristic_win_rate``,
``env_steps_per_s``, ``seconds``, ...).

    python -m trainers.mapoca_cli --preset cpu --skill-range 13 --total-steps 2000000 --seeds 1 --out runs/r13
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax
import numpy as np

import raidjax
from raidjax.utils import atomic_write, fmt_seconds, machine
from trainers import checkpoint
from trainers.config import Config, load_config
from trainers.mapoca import load_policy, make_trainer, summarize
from trainers.metrics import MetricsLog


def parse_args(argv=None) -> argparse.Namespace:
    """CLI arguments (see the module docstring)."""
    ap = argparse.ArgumentParser(prog="python -m trainers.mapoca_cli", description="Train MA-POCA on raidjax.")
    ap.add_argument("--preset", default="cpu", choices=["paper", "cpu"])
    ap.add_argument("--config", help="JSON file of Config fields (applied after the preset)")
    ap.add_argument("--skill-range", type=float, nargs="+", help="range(s) of the players' skill; "
                    "several values = drawn per episode")
    ap.add_argument("--total-steps", type=int, help="environment decisions per seed")
    ap.add_argument("--seeds", type=int, default=1, help="seeds trained together (vmapped)")
    ap.add_argument("--seed", type=int, default=0, help="base PRNG seed")
    ap.add_argument("--out", required=True, help="run directory (checkpoints, metrics)")
    ap.add_argument("--resume", action="store_true", help="continue from the last checkpoint in --out")
    ap.add_argument("--checkpoint-every", type=int, help="updates between checkpoints")
    ap.add_argument("--updates-per-chunk", type=int, help="updates per jitted chunk (log row)")
    ap.add_argument("--eval-games", type=int, help="games of the final evaluation (0 skips it)")
    ap.add_argument("--max-chunks", type=int, help="stop after this many chunks of this invocation "
                    "(testing interruption/resume)")
    return ap.parse_args(argv)


def evaluate(out: Path, cfg: Config, n_seeds: int, key: jax.Array) -> dict:
    """Win rates of every seed's trained team and of PT-HR over ``cfg.eval_games`` games per
    skill range in ``cfg.skill_ranges`` (same content, same typed PRNG ``key``). Returns a
    JSON-able dict."""
    per_range = {}
    policies = [load_policy(out, seed=s) for s in range(n_seeds)]  # one compile per seed
    for r in cfg.skill_ranges:
        content = raidjax.make_params(skill_range=r)
        hr = float(raidjax.win_rate(raidjax.playtest(key, content, raidjax.policies.heuristic, cfg.eval_games)))
        wins = [float(raidjax.win_rate(raidjax.playtest(key, content, p, cfg.eval_games))) for p in policies]
        per_range[f"{r:g}"] = {"win_rate": float(np.mean(wins)), "win_rate_per_seed": wins,
                               "heuristic_win_rate": hr}
    return {
        "win_rate": float(np.mean([v["win_rate"] for v in per_range.values()])),
        "heuristic_win_rate": float(np.mean([v["heuristic_win_rate"] for v in per_range.values()])),
        "per_range": per_range,
    }


def main(argv=None) -> dict:
    """Train (or resume), log, checkpoint, evaluate; print and return the final JSON object."""
    t_start = time.perf_counter()
    args = parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    ckpt_dir = out / "checkpoints"
    cfg = load_config(args.preset, args.config, skill_ranges=args.skill_range, total_steps=args.total_steps,
                      checkpoint_every=args.checkpoint_every, updates_per_chunk=args.updates_per_chunk,
                      eval_games=args.eval_games)
    if not args.resume and checkpoint.latest_step(ckpt_dir) is not None:
        raise SystemExit(f"{ckpt_dir} already holds checkpoints: pass --resume to continue, or a new --out")
    if args.resume:
        if checkpoint.latest_step(ckpt_dir) is None:
            raise checkpoint.CheckpointError(f"--resume: no finished checkpoint in {ckpt_dir}")
        cfg = Config.from_dict(checkpoint.saved_config(ckpt_dir))  # the run's own config: the resumed run must match
        print("resuming with the checkpoint's config (flags other than --out/--eval-games ignored)", flush=True)
        if args.eval_games is not None:
            cfg = cfg.replace(eval_games=args.eval_games)
    trainer = make_trainer(cfg)
    keys = jax.random.split(jax.random.PRNGKey(args.seed), args.seeds)
    init = jax.jit(jax.vmap(trainer.init))
    t0 = time.perf_counter()
    if args.resume:
        runner, saved_cfg, meta = checkpoint.restore(ckpt_dir, jax.eval_shape(init, keys))
        start_chunk, seconds_before = meta["chunk"], meta["seconds"]
        n_seeds = jax.tree.leaves(runner.params)[0].shape[0]
        if n_seeds != args.seeds:
            raise ValueError(f"--seeds: {args.seeds} given, the checkpoint holds {n_seeds}")
    else:
        runner, start_chunk, seconds_before = init(keys), 0, 0.0
    atomic_write(out / "config.json", json.dumps(cfg.to_dict(), indent=1))
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
        if (c + 1) % every == 0 or c + 1 == cfg.num_chunks:
            meta = {"chunk": c + 1, "update": (c + 1) * cfg.updates_per_chunk, "env_steps": steps,
                    "seconds": seconds_before + el}
            checkpoint.save(ckpt_dir, runner, runner.params["actor"], cfg.to_dict(), meta)
    train_s = time.perf_counter() - t_loop
    result = {"preset": args.preset, "skill_ranges": list(cfg.skill_ranges), "seeds": args.seeds,
              "env_steps": end_chunk * per_chunk,
              "env_steps_per_s": done_here * per_chunk * args.seeds / max(train_s, 1e-9),
              "compile_seconds": compile_s, "train_seconds": seconds_before + train_s}
    if cfg.eval_games > 0 and end_chunk == cfg.num_chunks:
        t_eval = time.perf_counter()
        result.update(evaluate(out, cfg, args.seeds, jax.random.key(args.seed + 12345)))
        result["eval_seconds"] = time.perf_counter() - t_eval
    result["seconds"] = time.perf_counter() - t_start
    atomic_write(out / "result.json", json.dumps(result, indent=1))
    print(json.dumps(result), flush=True)
    return result


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
