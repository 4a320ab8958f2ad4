"""PPO against PCG-HR in a finished Benchmark 2 run folder: per-seed numbers and a bootstrap.

    python -m experiments.b2_compare runs/benchmark2_cpu_pool_b --resamples 300

Per seed: the PPO episodes of one training seed, re-pooled with the run's PCG-HR and PCG-RD
episodes (the diversity normalisation and PCA are fitted on the pooled kept skills, as in the
report). Bootstrap: episodes resampled within method x target, PCA refitted on each resample;
the 95 % interval of PPO minus PCG-HR for the mean error and the mean PC1 SD, on the pooled axis
and on each (method, target) group's own first axis. Prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from experiments.benchmark2 import load_generated
from trainers.ppo_pcgrl_cli import summarize


def scores(gens: dict) -> dict:
    """``{method: {"error", "pc1_sd", "pc1_own_sd"}}`` from ``ppo_pcgrl_cli.summarize``: mean error
    (episodes with >= 2 edits), mean PC1 SD (normalisation and PCA over all methods' kept skills) and
    mean SD along each (method, target) group's own first axis."""
    return {m: {"error": v["controllability"]["err_mean"], "pc1_sd": v["pc1_sd_mean"],
                "pc1_own_sd": v["pc1_own_sd_mean"]}
            for m, v in summarize(gens).items()}


def per_seed(gens: dict, config: dict) -> list[dict]:
    """PPO episodes of each seed (``generated.npz`` holds, per saved part, seed 0's episodes first)."""
    seeds, parts = config["seeds"], config["parts"]
    per_part = len(gens["PPO"]["target"]) // parts
    out = []
    for s in range(seeds):
        idx = np.concatenate([np.arange(p * per_part, (p + 1) * per_part).reshape(seeds, -1)[s] for p in range(parts)])
        one = {**gens, "PPO": {k: v[idx] for k, v in gens["PPO"].items()}}
        out.append({"seed": s, **scores(one)["PPO"], "edits": float(one["PPO"]["edits"].mean())})
    return out


def bootstrap(gens: dict, resamples: int, seed: int = 0) -> dict:
    """95 % intervals of PPO minus PCG-HR (error, PC1 SD on the pooled axis and on each group's own)
    and the share of resamples where PPO is not better."""
    rng = np.random.default_rng(seed)
    d_err, d_pc1, d_own = [], [], []
    for _ in range(resamples):
        res = {}
        for m, g in gens.items():
            idx = np.concatenate([rng.choice(np.flatnonzero(g["target"] == t), (g["target"] == t).sum())
                                  for t in np.unique(g["target"])])
            res[m] = {k: v[idx] for k, v in g.items()}
        s = scores(res)
        d_err.append(s["PPO"]["error"] - s["PCG-HR"]["error"])
        d_pc1.append(s["PPO"]["pc1_sd"] - s["PCG-HR"]["pc1_sd"])
        d_own.append(s["PPO"]["pc1_own_sd"] - s["PCG-HR"]["pc1_own_sd"])
    d_err, d_pc1, d_own = np.asarray(d_err), np.asarray(d_pc1), np.asarray(d_own)
    return {"resamples": resamples, "error_diff_ci95": np.percentile(d_err, [2.5, 97.5]).tolist(),
            "share_error_not_lower": float((d_err >= 0).mean()),
            "pc1_diff_ci95": np.percentile(d_pc1, [2.5, 97.5]).tolist(),
            "share_pc1_not_higher": float((d_pc1 <= 0).mean()),
            "pc1_own_diff_ci95": np.percentile(d_own, [2.5, 97.5]).tolist(),
            "share_pc1_own_not_higher": float((d_own <= 0).mean())}


def main(argv=None) -> dict:
    """Print and return ``{"all", "per_seed", "bootstrap"}``."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", help="a Benchmark 2 run folder (with generated.npz and config.json)")
    ap.add_argument("--resamples", type=int, default=300)
    a = ap.parse_args(argv)
    run = Path(a.run)
    gens = load_generated(run / "generated.npz")
    config = json.loads((run / "config.json").read_text())
    out = {"all": scores(gens), "per_seed": per_seed(gens, config), "bootstrap": bootstrap(gens, a.resamples)}
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main()
