"""Command line of the PPO-PCGRL generator (``trainers.ppo_pcgrl``): chunked training with
progress lines, metrics (``trainers.metrics``), checkpoints (``trainers.checkpoint``) and
``--resume``, then the controllability evaluation of PPO, PCG-HR and PCG-RD.

    python -m trainers.ppo_pcgrl_cli --preset cpu --total-steps 8192 --seeds 1 --out runs/ppo_cpu

The last stdout line is one JSON object, also written to ``DIR/result.json``: ``mean_error``
(PPO), ``heuristic_mean_error`` (PCG-HR), ``random_mean_error`` (PCG-RD), all on the same
protocol (targets 0.1..0.7, final skills re-measured with ``--eval-games`` games), and
``seconds``. The run folder follows ``trainers.runfolder``: ``--resume`` continues from the newest
intact checkpoint with the same settings; anything else on an existing run is refused.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from raidjax import pcg
from raidjax.io import HelpFormatter, atomic_write, finite_json, fmt_seconds, run_cli, whole_number_arg
from raidjax.sharding import put_batch
from trainers import checkpoint
from trainers.config import read_fields
from trainers.generate import evaluate, target_groups
from trainers.mapoca import load_policy
from trainers.metrics import MetricsLog, update_rows
from trainers.ppo_pcgrl import PRESETS, PPOConfig, get_config, make_train
from trainers.runfolder import RunFolder


def _args(argv=None):
    ap = argparse.ArgumentParser(prog="python -m trainers.ppo_pcgrl_cli", description="PPO-PCGRL on raidjax.pcg",
                                 formatter_class=HelpFormatter)
    ap.add_argument("--preset", choices=sorted(PRESETS), default="cpu", help="budget and network preset")
    ap.add_argument("--config", help="JSON file of PPOConfig fields, applied after the preset and before the "
                    "flags below (default: none)")
    ap.add_argument("--players", nargs="+", help="the team's class presets, e.g. warrior mage priest "
                    "(default: three mages)")
    ap.add_argument("--parameters", nargs="+", help="the edited parameters (raidjax.pcg.space names, e.g. "
                    "mage.skill1.range=1:20 boss.max_hp=500:3000; default: the paper's four)")
    ap.add_argument("--total-steps", type=whole_number_arg(1), help="generator steps per group (default: the preset's)")
    ap.add_argument("--seeds", type=whole_number_arg(1), default=1, help="seeds per target group (vmapped)")
    ap.add_argument("--out", default="runs/ppo_pcgrl", help="run folder (new, or holding this run with --resume)")
    ap.add_argument("--resume", action="store_true", help="continue the run in --out from its newest intact "
                    "checkpoint (same settings; a finished run is left as it is)")
    ap.add_argument("--seed", type=int, default=0, help="base PRNG seed")
    ap.add_argument("--tester", help="playtest with a trained MA-POCA team: its run folder (trainers.mapoca_cli "
                    "--out; seed 0, sampled actions) instead of PT-HR, in training and evaluation (default: PT-HR)")
    ap.add_argument("--n-games", type=whole_number_arg(1),
                    help="playtest games per training measurement (default: the preset's)")
    ap.add_argument("--n-arenas", type=whole_number_arg(1),
                    help="generator episodes stepped in parallel (default: the preset's)")
    ap.add_argument("--lr", type=float, help="learning rate (default: the preset's)")
    ap.add_argument("--edit-cost", type=float, help="learner penalty per tick moved (default: the preset's)")
    ap.add_argument("--goal-cost", type=float,
                    help="with --goal-axis: learner penalty per squared tick of distance to the episode's style goal "
                         "(default: the preset's)")
    ap.add_argument("--goal-axis", type=pcg.env.axis_arg,
                    help="style goals at the two ends of this axis, 4 comma-separated signs in {-1,0,1} for "
                         "range,cool_time,cast_time,coefficient (1,1,1,1 = heavy vs light) (default: none)")
    ap.add_argument("--ent-coef", type=float, help="entropy bonus coefficient (default: the preset's)")
    ap.add_argument("--pool-repeats", action="store_true", default=None,
                    help="re-measuring an unchanged skill pools its games (sharper win rate when holding; "
                         "default: the preset's)")
    ap.add_argument("--chunk", type=whole_number_arg(1), default=4,
                    help="updates per jitted chunk (progress/checkpoint period)")
    ap.add_argument("--max-chunks", type=whole_number_arg(1), help="stop (after a checkpoint) once this many chunks "
                    "ran in this invocation (default: no limit)")
    ap.add_argument("--eval-episodes", type=whole_number_arg(0), default=8,
                    help="episodes per target and method (0 skips the evaluation)")
    ap.add_argument("--eval-gen-games", type=whole_number_arg(1), default=100,
                    help="games per generator measurement in eval")
    ap.add_argument("--eval-games", type=whole_number_arg(1), default=300, help="games measuring each final skill")
    ap.add_argument("--greedy", action="store_true", help="argmax actions in evaluation")
    ap.add_argument("--no-baselines", action="store_true", help="evaluate PPO alone, without PCG-HR and PCG-RD")
    return ap.parse_args(argv)


def load_fields(path: str | None) -> dict:
    """The ``PPOConfig`` fields in the JSON file ``path`` (``{}`` without one); raises ``ValueError``
    naming the file and what is wrong, or the unknown keys."""
    if path is None:
        return {}
    data = read_fields(path, "PPOConfig")
    PPOConfig.from_dict(data)  # unknown keys and bad values fail here, naming the field
    return {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}


def _rounded(x, key: str = ""):
    """The result's floats for its printed line: seconds to 0.01 s, the rest to 6 decimals (0.132, not
    0.13200000524520874)."""
    if isinstance(x, dict):
        return {k: _rounded(v, k) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_rounded(v, key) for v in x]
    if isinstance(x, float) and math.isfinite(x):
        return round(x, 2 if key.endswith("seconds") else 6)
    return x


def main(argv=None) -> dict | None:
    """Train, checkpoint, evaluate; the last stdout line is one JSON object (also returned)."""
    args = _args(argv)
    t_start = time.perf_counter()
    flags = dict(total_steps=args.total_steps, n_games=args.n_games, n_arenas=args.n_arenas, lr=args.lr,
                 edit_cost=args.edit_cost, pool_repeats=args.pool_repeats, ent_coef=args.ent_coef,
                 goal_cost=args.goal_cost, goal_axis=args.goal_axis,
                 players=args.players and tuple(args.players), parameters=args.parameters and tuple(args.parameters))
    flags = {k: v for k, v in flags.items() if v is not None}
    config = get_config(args.preset, **{**load_fields(args.config), **flags})  # preset, then file, then flags
    evaluation = {k: getattr(args, k) for k in ("eval_episodes", "eval_gen_games", "eval_games", "greedy",
                                                "no_baselines")}
    settings = {"trainer": "ppo_pcgrl", "preset": args.preset, "seeds": args.seeds, "seed": args.seed,
                "chunk": args.chunk, "config": config.to_dict(), "evaluation": evaluation}
    tester = {}
    if args.tester is not None:  # loaded (and checked) before the run folder is touched
        policy, weights = load_policy(args.tester, seed=0, deterministic=False)
        tester = {"tester": policy, "tester_weights": weights}
        # the weights' digest decides whether --resume continues the same run; the folder may move
        settings.update(tester=checkpoint.digest(weights), tester_run=str(Path(args.tester).resolve()))
    rf = RunFolder(args.out, settings, resume=args.resume, ignore=("evaluation", "tester_run"))
    if rf.finished:
        return rf.already_finished()
    out = rf.out
    train = make_train(config, **tester)
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
    if checkpoint.latest_step(ckpt) is not None:  # else a new run, or one stopped before its first checkpoint
        runner, _, meta = checkpoint.restore(ckpt, jax.eval_shape(init_v, keys, tg), quarantine=True)
        start = int(meta["update"])
        print(f"resumed from the checkpoint at update {start}", flush=True)
    runner = put_batch(runner, G)  # the groups split over every visible device (raidjax.sharding)
    log = MetricsLog(out, resume_update=start)
    steps_per_update = config.n_arenas * config.n_steps
    total_updates = config.num_updates
    print(f"preset={args.preset} groups={G} updates={total_updates} steps/update={steps_per_update} "
          f"n_games={config.n_games}", flush=True)
    t_train = time.perf_counter()
    u, done_steps, chunks_here = start, 0, 0
    while u < total_updates and (args.max_chunks is None or chunks_here < args.max_chunks):
        chunks_here += 1
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
    if u < total_updates:
        print(f"stopped at update {u}/{total_updates} (--max-chunks); rerun with --resume to continue", flush=True)
        return {"stopped_at_update": u}
    t_eval = time.perf_counter()
    res = {"train_seconds": train_s, "preset": args.preset, "seeds": args.seeds,
           "total_steps": total_updates * steps_per_update, "groups": G, "n_games": config.n_games,
           "cpu_count": os.cpu_count()}
    if args.eval_episodes > 0:
        gens = evaluate(jax.random.key(args.seed + 1), config, runner["params"], labels,
                        gen_games=args.eval_gen_games, greedy=args.greedy, episodes=args.eval_episodes,
                        eval_games=args.eval_games, baselines=not args.no_baselines, **tester)
        summ = pcg.metrics.summarize(gens)
        atomic_write(out / "eval.json", finite_json(summ, indent=1))
        for name, s in summ.items():
            c = s["controllability"]
            print(f"{name}: mean error {c['err_mean']:.3f} ± {c['err_sd']:.3f} (n={c['n']}) yield {s['yield']:.2f} "
                  f"edits {s['edits_mean']:.1f} PC1 SD {s['pc1_sd_mean']:.3f}", flush=True)
        res.update({"mean_error": summ["PPO"]["controllability"]["err_mean"],
                    "heuristic_mean_error": summ.get("PCG-HR", {}).get("controllability", {}).get("err_mean"),
                    "random_mean_error": summ.get("PCG-RD", {}).get("controllability", {}).get("err_mean"),
                    "pc1_sd": {n: s["pc1_sd_mean"] for n, s in summ.items()},
                    "yield": {n: s["yield"] for n, s in summ.items()},
                    "eval_seconds": time.perf_counter() - t_eval})
    res["seconds"] = time.perf_counter() - t_start
    res = json.loads(finite_json(_rounded(res)))  # NaN as null: valid JSON
    atomic_write(out / "result.json", json.dumps(res, indent=1))
    print(json.dumps(res), flush=True)
    return res


def cli(argv=None) -> None:
    """``main`` as a command line: one-line errors (exit 2), one line on Ctrl-C (exit 130)."""
    run_cli(lambda: main(argv), (ValueError, checkpoint.CheckpointError),
            "the newest checkpoint is kept: rerun the same command with --resume to continue")


if __name__ == "__main__":
    cli()
