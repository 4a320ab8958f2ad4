"""Command line of ``trainers.ppo_pcgrl``: chunked training with progress, CSV/JSONL metrics, atomic
orbax checkpoints and ``--resume``, then the controllability evaluation of PPO, PCG-HR and PCG-RD.

    python -m trainers.ppo_pcgrl --preset cpu --total-steps 8192 --seeds 1 --out runs/ppo_cpu
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import time
from functools import cache
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp

from raidjax import pcg
from raidjax import pcg_context as context
from raidjax import pcg_metrics as pm
from trainers.ppo_pcgrl import PRESETS, env_params, get_config, make_policy, make_train


def parse_signs(text: str) -> tuple[int, ...]:
    """``"1,0,-1,1"`` -> ``(1, 0, -1, 1)`` (an argparse type for ``--goal-axis``); the signs are
    checked by ``pcg.make_params``'s own rule, so the command line and the API reject the same input."""
    try:
        signs = tuple(int(v) for v in text.split(","))
    except ValueError:
        signs = tuple(text.split(","))  # not integers: the check below names the rule
    try:
        return context.check(False, None, True, signs, pcg.PARAM_NAMES)[1]
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"goal axis: value {text!r}: {err}") from None


def _args(argv=None):
    ap = argparse.ArgumentParser(description="PPO-PCGRL on raidjax.pcg")
    ap.add_argument("--preset", choices=sorted(PRESETS), default="cpu")
    ap.add_argument("--total-steps", type=int, default=None)
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--out", default="runs/ppo_pcgrl")
    ap.add_argument("--resume", action="store_true")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--n-games", type=int, default=None, help="playtest games per training measurement")
    ap.add_argument("--n-envs", type=int, default=None)
    ap.add_argument("--lr", type=float, default=None)
    ap.add_argument("--edit-cost", type=float, default=None, help="learner penalty per tick moved")
    ap.add_argument("--anchor-cost", type=float, default=None,
                    help="learner penalty per squared tick of displacement from the start skill (diversity)")
    ap.add_argument("--edit-preferences", action="store_true", default=None,
                    help="random per-episode edit preferences weight the edit cost (observed; diversity)")
    ap.add_argument("--favourite-weight", type=float, default=None,
                    help="edit preferences as one favourite parameter per episode with this weight in [0, 1], "
                         "the others (4 - w) / 3 (implies --edit-preferences)")
    ap.add_argument("--goal-cost", type=float, default=None,
                    help="learner penalty per squared tick of distance to a random corner goal per episode (diversity)")
    ap.add_argument("--goal-axis", type=parse_signs, default=None,
                    help="with --goal-cost: goals at the two ends of this style axis, 4 comma-separated signs "
                         "in {-1,0,1} for range,cool_time,cast_time,coefficient (1,1,1,1 = heavy vs light)")
    ap.add_argument("--one-lever", action="store_true", default=None,
                    help="the policy edits only the parameter the env designates per step (drawn uniformly)")
    ap.add_argument("--ent-coef", type=float, default=None, help="entropy bonus coefficient")
    ap.add_argument("--pool-repeats", action="store_true", default=None,
                    help="re-measuring an unchanged skill pools its games (sharper win rate when holding)")
    ap.add_argument("--chunk", type=int, default=4, help="updates per jitted chunk (progress/checkpoint period)")
    ap.add_argument("--eval-episodes", type=int, default=8, help="episodes per target and method")
    ap.add_argument("--eval-gen-games", type=int, default=100, help="games per generator measurement in eval")
    ap.add_argument("--eval-games", type=int, default=300, help="games measuring each final skill")
    ap.add_argument("--greedy", action="store_true", help="argmax actions in evaluation")
    ap.add_argument("--temperature", type=float, default=1.0,
                    help="evaluation samples each branch from softmax(logits / T) (T > 0; 1 = as trained)")
    ap.add_argument("--no-baselines", action="store_true")
    return ap.parse_args(argv)


def _groups(config, seeds: int):
    """Target pairs ``float32[G, 2]`` and labels: one group per seed (target observed) or per
    (target, seed) (one model per fixed target, the paper's setting)."""
    if config.observe_target:
        return np.tile(np.asarray(config.target, np.float32), (seeds, 1)), [(None, s) for s in range(seeds)]
    pairs = [(t, s) for t in pm.TARGETS for s in range(seeds)]
    return np.asarray([[t, t] for t, _ in pairs], np.float32), pairs


def metric_rows(start_update: int, metrics: dict, steps_per_update: int) -> list[dict]:
    """One dict per update of a chunk: ``update``, ``env_steps`` and every metric averaged over the
    groups (NaN when no group has a finite value), plus ``final_error_per_group`` (list of G floats).

    Args:
        start_update: updates done before the chunk.
        metrics: chunk metrics, leaves ``[G, n]`` (groups x updates).
        steps_per_update: generator steps per update and group.
    """
    m = jax.device_get(metrics)
    n = next(iter(m.values())).shape[1]
    rows = []
    for i in range(n):
        u = start_update + i + 1
        row = {k: float(np.nanmean(m[k][:, i])) if np.isfinite(m[k][:, i]).any() else float("nan") for k in sorted(m)}
        rows.append({"update": u, "env_steps": u * steps_per_update, **row,
                     "final_error_per_group": [float(x) for x in m["final_error"][:, i]]})
    return rows


def _write_metrics(out: Path, start_update: int, metrics: dict, steps_per_update: int) -> None:
    rows = metric_rows(start_update, metrics, steps_per_update)
    keys = sorted(k for k in rows[0] if k not in ("update", "env_steps", "final_error_per_group"))
    new = not (out / "metrics.csv").exists()
    with open(out / "metrics.csv", "a", newline="") as fc, open(out / "metrics.jsonl", "a") as fj:
        w = csv.writer(fc)
        if new:
            w.writerow(["update", "env_steps"] + keys)
        for r in rows:
            w.writerow([r["update"], r["env_steps"]] + [r[k] for k in keys])
            fj.write(json.dumps(r) + "\n")


@cache
def method_policy(hidden: tuple, greedy: bool = False, temperature: float = 1.0, one_lever: bool = False):
    """One generator policy for PPO, PCG-HR and PCG-RD, so that ``pm.generate`` compiles once per
    episode count rather than once per method: ``policy({"net": net_params, "method": int32[]}, key,
    obs, state, params) -> int32[4]`` with method 0 = PPO (``make_policy(hidden, greedy, temperature,
    one_lever)``),
    1 = ``pcg.heuristic_policy``, 2 = ``pcg.random_policy``. ``method`` is not batched, so the
    ``lax.switch`` stays a conditional and only the chosen branch runs."""
    ppo = make_policy(tuple(hidden), greedy, temperature, one_lever)

    def policy(pp, key, obs, state, params):
        return jax.lax.switch(pp["method"], [
            lambda: ppo(pp["net"], key, obs, state, params),
            lambda: pcg.heuristic_policy(None, key, obs, state, params),
            lambda: pcg.random_policy(None, key, obs, state, params)])

    return policy


def evaluate(key, config, runner_params, labels, args) -> dict:
    """Controllability/diversity of PPO (every trained group), PCG-HR and PCG-RD on one protocol.

    Args:
        key: PRNG key.
        config: the PPO ``Config``.
        runner_params: network weights with a leading group axis ``[G, ...]``.
        labels: ``_groups``' labels ``[(target or None, seed)] * G``.
        args: namespace with ``eval_gen_games``, ``greedy``, ``temperature`` (PPO's sampling
            temperature), ``eval_episodes`` (per target and method; PPO's are split over the
            seeds), ``eval_games`` (0: keep the generator's own last measurement), ``no_baselines``
            and optionally ``strict_length`` and ``max_edits`` (default: the training env's).

    Returns a dict of per-method ``generate`` outputs (numpy arrays pooled over groups)."""
    p = env_params(config).replace(n_games=args.eval_gen_games)  # the training env; targets come from generate
    strict, max_edits = getattr(args, "strict_length", None), getattr(args, "max_edits", None)
    p = p.replace(strict_length=p.strict_length if strict is None else strict,
                  max_edits=p.max_edits if max_edits is None else max_edits)
    policy = method_policy(tuple(config.hidden), args.greedy, args.temperature, config.one_lever)
    n_seeds = max(s for _, s in labels) + 1
    eps = max(1, args.eval_episodes // n_seeds)
    parts = []
    for g, (t, _) in enumerate(labels):
        params_g = {"net": jax.tree.map(lambda x, g=g: x[g], runner_params), "method": jnp.int32(0)}
        targets = pm.TARGETS if t is None else (t,)
        parts.append(pm.generate(jax.random.fold_in(key, g), policy, p, policy_params=params_g, targets=targets,
                                 episodes=eps, eval_games=args.eval_games))
    gens = {"PPO": {k: np.concatenate([d[k] for d in parts]) for k in parts[0]}}
    if not args.no_baselines:
        net0 = jax.tree.map(lambda x: x[0], runner_params)
        for i, name in enumerate(("PCG-HR", "PCG-RD")):
            gens[name] = pm.generate(jax.random.fold_in(key, 10_000 + i), policy, p,
                                     policy_params={"net": net0, "method": jnp.int32(i + 1)},
                                     episodes=args.eval_episodes, eval_games=args.eval_games)
    return gens


def summarize(gens: dict, protocol: pm.Protocol | None = None) -> dict:
    """Controllability, yield and diversity (pooled normalisation/PCA over all methods) per method,
    episodes kept and groups cut as ``protocol`` says (default ``pm.PROTOCOLS["raidjax"]``)."""
    pr = pm.PROTOCOLS["raidjax"] if protocol is None else protocol
    skills, errs, groups = [], [], []
    for name, g in gens.items():
        k = np.asarray(g["edits"]) >= pr.diversity_min_edits
        skills.append(g["skill"][k])
        errs.append(np.abs(g["target"] - g["win_rate"])[k])
        groups += [f"{name}|{t:.1f}" for t in g["target"][k]]
    div = pm.diversity(np.concatenate(skills), np.concatenate(errs), np.asarray(groups), group_size=pr.group_size,
                       seed=pr.seed)
    size = pr.group_size
    if size is not None:  # one size for every (method, target) group: the smallest, at most group_size
        counts = [np.unique(np.round(g["target"][np.asarray(g["edits"]) >= pr.min_edits], 6), return_counts=True)[1]
                  for g in gens.values()]
        size = int(min([size] + [c.min() for c in counts if c.size]))
    out = {}
    for name, g in gens.items():
        c = pm.controllability(g, pr.min_edits, size, pr.seed)
        d = [v for k, v in div.items() if k.startswith(name + "|") and np.isfinite(v["pc1_sd"])]
        out[name] = {"controllability": c, **pm.yield_stats(g),
                     "pc1_sd_mean": float(np.mean([v["pc1_sd"] for v in d])) if d else float("nan"),
                     "pc1_own_sd_mean": float(np.mean([v["pc1_own_sd"] for v in d])) if d else float("nan"),
                     "param_sd_mean": np.nanmean([v["param_sd"] for v in d], 0).tolist() if d else None,
                     "diversity": {k.split("|")[1]: v for k, v in div.items() if k.startswith(name + "|")}}
    return out


def main(argv=None) -> None:
    """Train, checkpoint, evaluate; the last stdout line is one JSON object."""
    args = _args(argv)
    t_start = time.perf_counter()
    config = get_config(args.preset, total_steps=args.total_steps, n_games=args.n_games, n_envs=args.n_envs,
                        lr=args.lr, edit_cost=args.edit_cost, pool_repeats=args.pool_repeats,
                        ent_coef=args.ent_coef, anchor_cost=args.anchor_cost,
                        edit_preferences=(args.edit_preferences or args.favourite_weight is not None) or None,
                        favourite_weight=args.favourite_weight, one_lever=args.one_lever or None,
                        goal_cost=args.goal_cost, goal_axis=args.goal_axis)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "config.json").write_text(json.dumps({**vars(args), "config": config.__dict__}, default=str, indent=1))
    train = make_train(config)
    pairs, labels = _groups(config, args.seeds)
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

    mgr = ocp.CheckpointManager(
        (out / "ckpt").absolute(),
        options=ocp.CheckpointManagerOptions(max_to_keep=2, enable_async_checkpointing=False))
    start = 0
    if args.resume and mgr.latest_step() is not None:
        abstract = jax.tree.map(ocp.utils.to_shape_dtype_struct, runner)
        runner = mgr.restore(mgr.latest_step(), args=ocp.args.StandardRestore(abstract))
        start = int(np.asarray(runner["update"]).reshape(-1)[0])
        print(f"resumed from update {start}", flush=True)
    steps_per_update = config.n_envs * config.n_steps
    total_updates = config.n_updates
    print(f"preset={args.preset} groups={G} updates={total_updates} steps/update={steps_per_update} "
          f"n_games={config.n_games}", flush=True)
    t_train = time.perf_counter()
    u, done_steps = start, 0
    while u < total_updates:
        t0 = time.perf_counter()
        runner, metrics = run_chunk(runner, tg)
        jax.block_until_ready(runner)
        dt = time.perf_counter() - t0
        _write_metrics(out, u, metrics, steps_per_update)
        u += chunk
        done_steps += chunk * steps_per_update
        mgr.save(u, args=ocp.args.StandardSave(runner))
        rate = done_steps * G / max(time.perf_counter() - t_train, 1e-9)
        eta = (total_updates - u) * steps_per_update * G / max(rate, 1e-9)
        m = jax.device_get(metrics)
        fe = m["final_error"][:, -1]
        print(f"update {min(u, total_updates)}/{total_updates} steps {min(u, total_updates) * steps_per_update} "
              f"steps/s {rate:.1f} chunk {dt:.1f}s ETA {max(eta, 0):.0f}s reward {np.mean(m['reward'][:, -1]):.2f} "
              f"final_err {np.nanmean(fe) if np.isfinite(fe).any() else float('nan'):.3f} "
              f"edits {np.nanmean(m['edits'][:, -1]):.1f} entropy {np.mean(m['entropy'][:, -1]):.2f}", flush=True)
    mgr.wait_until_finished()
    train_s = time.perf_counter() - t_train
    t_eval = time.perf_counter()
    gens = evaluate(jax.random.key(args.seed + 1), config, runner["params"], labels, args)
    np.savez(out / "generated.npz", **{f"{n}/{k}": v for n, g in gens.items() for k, v in g.items()})
    summ = summarize(gens)
    (out / "eval.json").write_text(json.dumps(summ, indent=1))
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
