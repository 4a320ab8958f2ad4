"""Which parameters do a finished Benchmark 2 run's generators move? Start-to-final moves.

    python -m experiments.b2_levers runs/b2_fav0.3 --episodes 8

Generates ``--episodes`` episodes per target (0.1-0.7) with each trained PPO seed and with
PCG-HR (``ppo_pcgrl_cli.evaluate``), on the run's training environment (so PPO sees the
preferences it was trained with). Reports per generator the mean absolute and the mean signed
move of each parameter from the episode's random start to its final skill, in fractions of the
parameter's span, overall and grouped by the episode's cheapest parameter when the run drew edit
preferences; with style goals (``--goal-cost``), also each parameter's mean final value (scaled to
[0, 1]) in the episodes whose goal has it high and in those that have it low. The last stdout
line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import numpy as np

from experiments.b2_temperature import _args, learner
from raidjax import pcg
from trainers.ppo_pcgrl_cli import evaluate


def moves(gen: dict) -> dict:
    """Per-parameter ``abs`` and ``signed`` mean move (fractions of the span) of ``generate`` output
    ``gen``, the mean error and edits, ``by_cheapest`` (``{parameter: {"n", "abs"}}``) when the
    preferences vary, and ``final_by_goal`` (``{"high": [4], "low": [4]}``, the mean scaled final
    value per parameter over the episodes whose goal corner has that parameter high / low) when the
    goals are corners rather than the starts."""
    span = np.asarray(pcg.HIGH) - np.asarray(pcg.LOW)
    move = (gen["skill"] - gen["start"]) / span
    out = {"error": float(np.abs(gen["win_rate"] - gen["target"]).mean()), "edits": float(gen["edits"].mean()),
           "abs": np.abs(move).mean(0).round(3).tolist(), "signed": move.mean(0).round(3).tolist()}
    if np.ptp(gen["preferences"]) > 0:
        cheapest = gen["preferences"].argmin(1)
        out["by_cheapest"] = {name: {"n": int((cheapest == i).sum()),
                                     "abs": np.abs(move[cheapest == i]).mean(0).round(3).tolist()}
                              for i, name in enumerate(pcg.PARAM_NAMES) if (cheapest == i).any()}
    if "goal" in gen and not np.array_equal(gen["goal"], gen["start"]):
        high = gen["goal"] > (np.asarray(pcg.LOW) + np.asarray(pcg.HIGH)) / 2  # corners: no float32-vs-bound test
        final = (gen["skill"] - np.asarray(pcg.LOW)) / span
        side = lambda m: [round(float(final[m[:, j], j].mean()), 3) if m[:, j].any() else None for j in range(4)]
        out["final_by_goal"] = {"high": side(high), "low": side(~high)}
    return out


def _split(gen: dict, n: int) -> list[dict]:
    """``n`` equal consecutive blocks of every field of a ``generate`` output."""
    m = len(gen["target"]) // n
    return [{k: v[i * m:(i + 1) * m] for k, v in gen.items()} for i in range(n)]


def main(argv=None) -> dict:
    """Print and return ``{"params": [...], "generators": {name: moves(...)}}``."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", help="a finished Benchmark 2 run folder")
    ap.add_argument("--episodes", type=int, default=8, help="episodes per target and generator")
    ap.add_argument("--key", type=int, default=100)
    a = ap.parse_args(argv)
    lr, cfg = learner(Path(a.run))
    n_groups = len(lr.labels)
    args = _args(cfg, 1.0, baselines=True)
    args.eval_episodes = a.episodes * n_groups  # evaluate splits PPO's episodes over the groups
    gens = evaluate(jax.random.key(a.key), lr.config, lr.restore_params(lr.config.n_updates), lr.labels, args)
    # evaluate concatenates the groups' equal-sized blocks in label order
    out = {(f"PPO group {g} (target {t}, seed {s})" if t is not None else f"PPO seed {s}"): moves(block)
           for g, ((t, s), block) in enumerate(zip(lr.labels, _split(gens["PPO"], n_groups), strict=True))}
    out["PCG-HR"] = moves(gens["PCG-HR"])
    result = {"run": a.run, "params": list(pcg.PARAM_NAMES), "generators": out}
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
