"""Command line of the PPO-PCGRL generator (``trainers.ppo_pcgrl``): chunked training with
progress lines, metrics (``trainers.metrics``), checkpoints (``trainers.checkpoint``) and
``--resume``, then the controllability evaluation of PPO, PCG-HR and PCG-RD.

    python -m trainers.ppo_pcgrl_cli --preset cpu --total-steps 8192 --seeds 1 --out runs/ppo_cpu

The last stdout line is one JSON object: ``mean_error`` (PPO), ``heuristic_mean_error`` (PCG-HR),
``random_mean_error`` (PCG-RD), all on the same protocol (targets 0.1..0.7, final skills
re-measured with ``--eval-games`` games), and ``seconds``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from raidjax import pcg
from raidjax.utils import atomic_write, fmt_seconds
from trainers import checkpoint
from trainers.generate import evaluate, target_groups
from trainers.metrics import MetricsLog, update_rows
from trainers.ppo_pcgrl import PRESETS, get_config, make_train


def _args(argv=None):
    ap = argparse.ArgumentParser(prog="python -m trainers.ppo_pcgrl_cli", description="PPO-PCGRL on raidjax.pcg",
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--preset", choices=sorted(PRESETS), default="cpu")
    ap.add_argument("--total-steps", type=int, help="generator steps per group (default: the preset's)")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--out", default="runs/ppo_pcgrl")
    ap.add_argument("--resume", action="store_true")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--n-games", type=int, help="playtest games per training measurement")
    ap.add_argument("--n-arenas", type=int, help="generator episodes stepped in parallel")
    ap.add_argument("--lr", type=float)
    ap.add_argument("--edit-cost", type=float, help="learner penalty per tick moved")
    ap.add_argument("--goal-cost", type=float,
                    help="with --goal-axis: learner penalty per squared tick of distance to the episode's style goal")
    ap.add_argument("--goal-axis", type=pcg.axis_arg,
                    help="style goals at the two ends of this axis, 4 comma-separated signs in {-1,0,1} for "
                         "range,cool_time,cast_time,coefficient (1,1,1,1 = heavy vs light)")
    ap.add_argument("--ent-coef", type=float, help="entropy bonus coefficient")
    ap.add_argument("--pool-repeats", action="store_true", default=None,
                    help="re-measuring an unchanged skill pools its games (sharper win rate when holding)")
    ap.add_argument("--chunk", type=int, default=4, help="updates per jitted chunk (progress/checkpoint period)")
    ap.add_argument("--eval-episodes", type=int, default=8, help="episodes per target and method")
    ap.add_argument("--eval-gen-games", type=int, default=100, help="games per generator measurement in eval")
    ap.add_argument("--eval-games", type=int, default=300, help="games measuring each final skill")
    ap.add_argument("--greedy", action="store_true", help="argmax actions in evaluation")
    ap.add_argument("--no-baselines", action="store_true")
    return ap.parse_args(argv)


def main(argv=None) -> None:
    """Train, checkpoint, evaluate; the last stdout line is one JSON object."""
    args = _args(argv)
    t_start = time.perf_counter()
    config = get_config(args.preset, total_steps=args.total_steps, n_games=args.n_games, n_arenas=args.n_arenas,
                        lr=args.lr, edit_cost=args.edit_cost, pool_repeats=args.pool_repeats,
                        ent_coef=args.ent_coef, goal_cost=args.goal_cost, goal_axis=args.goal_axis)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / "config.json", json.dumps({**vars(args), "config": config.to_dict()}, default=str, indent=1))
    train = make_train(config)
    pairs, labels = target_groups(config, args.seeds)
    G, chunk = len(labels), max(1, args.chunk)
    keys = jax.random.split(jax.random.key(args.seed), G)
    tg = jnp.asarray(pairs)
    init_v = jax.jit(jax.vmap(train.init))
    runner = init_v(keys, tg)

    @jax.jit
    def run_chunk(runner, tg):
        def one(r, t):
            return jax.lax.scan(lambda rr, _: train.update(rr, t), r, None, chunk)
        return jax.vmap(one)(runner, tg)

    ckpt = out / "checkpoints"
    start = 0
    if args.resume and checkpoint.latest_step(ckpt) is not None:
        runner, _, meta = checkpoint.restore(ckpt, jax.eval_shape(init_v, keys, tg))
        start = int(meta["update"])
        print(f"resumed from update {start}", flush=True)
    log = MetricsLog(out, resume_update=start)
    steps_per_update = config.n_arenas * config.n_steps
    total_updates = config.num_updates
    print(f"preset={args.preset} groups={G} updates={total_updates} steps/update={steps_per_update} "
          f"n_games={config.n_games}", flush=True)
    t_train = time.perf_counter()
    u, done_steps = start, 0
    while u < total_updates:
        t0 = time.perf_counter()
        runner, metrics = run_chunk(runner, tg)
        jax.block_until_ready(runner)
        dt = time.perf_counter() - t0
        m = jax.device_get(metrics)
        for row in update_rows(u, m, steps_per_update):
            log.write(row)
        u += chunk
        done_steps += chunk * steps_per_update
        checkpoint.save(ckpt, runner, runner["params"], config.to_dict(), {"update": u}, max_to_keep=2)
        rate = done_steps * G / max(time.perf_counter() - t_train, 1e-9)
        eta = (total_updates - u) * steps_per_update * G / max(rate, 1e-9)
        last = lambda k: np.nanmean(m[k][:, -1]) if np.isfinite(m[k][:, -1]).any() else float("nan")  # noqa: B023
        print(f"update {min(u, total_updates)}/{total_updates} steps {min(u, total_updates) * steps_per_update} "
              f"steps/s {rate:.1f} chunk {dt:.1f}s ETA {fmt_seconds(max(eta, 0))} "
              f"reward {np.mean(m['reward'][:, -1]):.2f} "
              f"final_err {last('final_error'):.3f} edits {last('edits'):.1f} "
              f"entropy {np.mean(m['entropy'][:, -1]):.2f}", flush=True)
    train_s = time.perf_counter() - t_train
    t_eval = time.perf_counter()
    gens = evaluate(jax.random.key(args.seed + 1), config, runner["params"], labels, gen_games=args.eval_gen_games,
                    greedy=args.greedy, episodes=args.eval_episodes, eval_games=args.eval_games,
                    baselines=not args.no_baselines)
    summ = pcg.metrics.summarize(gens)
    atomic_write(out / "eval.json", json.dumps(summ, indent=1))
    for name, s in summ.items():
        c = s["controllability"]
        print(f"{name}: mean error {c['err_mean']:.3f} ± {c['err_sd']:.3f} (n={c['n']}) yield {s['yield']:.2f} "
              f"edits {s['edits_mean']:.1f} PC1 SD {s['pc1_sd_mean']:.3f}", flush=True)
    res = {"mean_error": summ["PPO"]["controllability"]["err_mean"],
           "heuristic_mean_error": summ.get("PCG-HR", {}).get("controllability", {}).get("err_mean"),
           "random_mean_error": summ.get("PCG-RD", {}).get("controllability", {}).get("err_mean"),
           "pc1_sd": {n: s["pc1_sd_mean"] for n, s in summ.items()},
           "yield": {n: s["yield"] for n, s in summ.items()},
           "train_seconds": train_s, "eval_seconds": time.perf_counter() - t_eval,
           "seconds": time.perf_counter() - t_start, "preset": args.preset, "seeds": args.seeds,
           "total_steps": total_updates * steps_per_update, "groups": G, "n_games": config.n_games,
           "cpu_count": os.cpu_count()}
    print(json.dumps(res), flush=True)


if __name__ == "__main__":
    try:
        main()
    except ValueError as e:
        raise SystemExit(f"error: {e}") from e
