"""Generation-time temperature sweep of a finished Benchmark 2 run's PPO generators.

    python -m experiments.b2_temperature runs/benchmark2_cpu_pool_b --temperatures 0 1 1.5 2

Re-generates the PPO episodes of every trained seed on the run's own protocol (episodes per
target, games per measurement and per evaluation, pooled repeats), each branch sampled from
``softmax(logits / T)`` (``T = 0``: argmax), and scores them against the run's saved PCG-HR and
PCG-RD episodes, which a temperature does not change: mean error, mean PC1 SD (normalisation and
PCA refitted on the pooled kept skills), per seed, and a bootstrap of PPO minus PCG-HR. Every
temperature uses the same key, so the temperatures differ only by the sampling.

``--key K`` draws the episodes from another key (default 99). With ``--fresh-baselines`` the
PCG-HR and PCG-RD episodes are regenerated from that key too, so a temperature chosen on one
sweep can be confirmed on episodes it was not chosen on:

    python -m experiments.b2_temperature RUN --temperatures 2 --key 7 --fresh-baselines

Each temperature's episodes are written atomically to ``RUN/temperature/`` and reused when the
command is rerun. The last stdout line is one JSON object.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
import types
from pathlib import Path

import jax

from experiments import b2_compare
from experiments.benchmark2 import FIELDS, SCALES, _Learner, load_generated, save_generated
from raidjax.utils import fmt_seconds
from trainers.ppo_pcgrl_cli import evaluate


def learner(run: Path) -> tuple[_Learner, dict]:
    """The run's PPO learner (its config rebuilt from ``config.json``) and that config dict."""
    cfg = json.loads((run / "config.json").read_text())
    scale = dataclasses.replace(SCALES[cfg["scale"]], ppo=cfg["ppo"], seeds=cfg["seeds"], episodes=cfg["episodes"])
    return _Learner(types.SimpleNamespace(out=run), scale, cfg["seed"]), cfg


def _args(cfg: dict, temperature: float, baselines: bool) -> types.SimpleNamespace:
    return types.SimpleNamespace(eval_gen_games=cfg["gen_games"], greedy=temperature == 0,
                                 temperature=temperature or 1.0, eval_episodes=cfg["episodes"],
                                 eval_games=cfg["eval_games"], no_baselines=not baselines)


def episodes(run: Path, lr: _Learner, cfg: dict, temperature: float, key: int, baselines: bool) -> dict:
    """``{method: generate output (FIELDS only)}`` at ``temperature`` from key ``key``: PPO only,
    or with PCG-HR and PCG-RD when ``baselines``; cached in ``RUN/temperature/``."""
    name = f"T{temperature:g}" + ("" if key == 99 else f"_key{key}") + ("_all" if baselines else "")
    path = run / "temperature" / f"{name}.npz"
    if not path.exists():
        total = lr.config.n_updates
        if lr.mgr.latest_step() != total:
            raise RuntimeError(f"no final PPO checkpoint (update {total}) in {run / 'checkpoints' / 'ppo'}")
        k = jax.random.fold_in(jax.random.key(cfg["seed"] + 1), key)
        gens = evaluate(k, lr.config, lr.restore_params(total), lr.labels, _args(cfg, temperature, baselines))
        path.parent.mkdir(exist_ok=True)
        save_generated(path, {m: {f: g[f] for f in FIELDS} for m, g in gens.items()})
    return load_generated(path)


def main(argv=None) -> dict:
    """Print one progress line per temperature and return (and print) ``{"temperatures": [...]}``,
    one entry per temperature with ``all`` (every method's error and PC1 SD), ``per_seed`` and
    ``bootstrap`` (``experiments.b2_compare``'s)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", help="a finished Benchmark 2 run folder (config.json, checkpoints, generated.npz)")
    ap.add_argument("--temperatures", type=float, nargs="+", default=[0.0, 1.0, 1.5, 2.0])
    ap.add_argument("--resamples", type=int, default=300)
    ap.add_argument("--key", type=int, default=99, help="fold-in of the run's generation key (99 = the sweep's)")
    ap.add_argument("--fresh-baselines", action="store_true",
                    help="regenerate PCG-HR and PCG-RD from --key too, instead of the run's saved episodes")
    a = ap.parse_args(argv)
    bad = [t for t in a.temperatures if t < 0]
    if bad:
        raise SystemExit(f"error: temperatures: values {bad} must be >= 0 (0 = argmax)")
    run = Path(a.run)
    lr, cfg = learner(run)
    base = None if a.fresh_baselines else load_generated(run / "generated.npz")
    rows, t0 = [], time.perf_counter()
    for i, temp in enumerate(a.temperatures):
        new = episodes(run, lr, cfg, temp, a.key, a.fresh_baselines)
        gens = new if base is None else {**base, "PPO": new["PPO"]}
        row = {"temperature": temp, "all": b2_compare.scores(gens),
               "per_seed": b2_compare.per_seed(gens, {"seeds": cfg["seeds"], "parts": 1}),
               "bootstrap": b2_compare.bootstrap(gens, a.resamples)}
        rows.append(row)
        eta = (time.perf_counter() - t0) / (i + 1) * (len(a.temperatures) - i - 1)
        ppo, hr = row["all"]["PPO"], row["all"]["PCG-HR"]
        print(f"T={temp:g}: PPO error {ppo['error']:.3f} PC1 SD {ppo['pc1_sd']:.3f} | PCG-HR error "
              f"{hr['error']:.3f} PC1 SD {hr['pc1_sd']:.3f} | ETA {fmt_seconds(eta)}", flush=True)
    out = {"run": str(run), "key": a.key, "fresh_baselines": a.fresh_baselines, "temperatures": rows}
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
