"""Which parameters do a finished Benchmark 2 run's generators move? Start-to-final moves.

    python -m experiments.b2_levers runs/b2_fav0.3 --episodes 8

Generates ``--episodes`` episodes per target (0.1-0.7) with each trained PPO seed and with
PCG-HR, on the run's training environment (so PPO sees the preferences it was trained with), and
reports per generator the mean absolute and the mean signed move of each parameter from the
episode's random start to its final skill, in fractions of the parameter's span, overall and
grouped by the episode's cheapest parameter when the run drew edit preferences. The last stdout
line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from experiments.b2_temperature import learner
from raidjax import pcg
from raidjax import pcg_metrics as pm
from trainers.ppo_pcgrl import env_params
from trainers.ppo_pcgrl_cli import method_policy


def moves(gen: dict) -> dict:
    """Per-parameter ``abs`` and ``signed`` mean move (fractions of the span) of ``generate`` output
    ``gen``, the mean error and edits, and ``by_cheapest`` (``{parameter: {"n", "abs"}}``) when the
    preferences vary."""
    span = np.asarray(pcg.HIGH) - np.asarray(pcg.LOW)
    move = (gen["skill"] - gen["start"]) / span
    out = {"error": float(np.abs(gen["win_rate"] - gen["target"]).mean()), "edits": float(gen["edits"].mean()),
           "abs": np.abs(move).mean(0).round(3).tolist(), "signed": move.mean(0).round(3).tolist()}
    if np.ptp(gen["preferences"]) > 0:
        cheapest = gen["preferences"].argmin(1)
        out["by_cheapest"] = {name: {"n": int((cheapest == i).sum()),
                                     "abs": np.abs(move[cheapest == i]).mean(0).round(3).tolist()}
                              for i, name in enumerate(pcg.PARAM_NAMES) if (cheapest == i).any()}
    return out


def main(argv=None) -> dict:
    """Print and return ``{"params": [...], "generators": {name: moves(...)}}``."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", help="a finished Benchmark 2 run folder")
    ap.add_argument("--episodes", type=int, default=8, help="episodes per target and generator")
    ap.add_argument("--key", type=int, default=100)
    a = ap.parse_args(argv)
    lr, cfg = learner(Path(a.run))
    weights = lr.restore_params(lr.config.n_updates)
    params = env_params(lr.config).replace(n_games=cfg["gen_games"])
    policy = method_policy(tuple(lr.config.hidden))
    out = {}
    groups = [(f"PPO group {g} (target {t}, seed {s})" if t is not None else f"PPO seed {s}", g, 0, t)
              for g, (t, s) in enumerate(lr.labels)]
    for name, g, method, t in [*groups, ("PCG-HR", 0, 1, None)]:
        pp = {"net": jax.tree.map(lambda x, g=g: x[g], weights), "method": jnp.int32(method)}
        gen = pm.generate(jax.random.fold_in(jax.random.key(a.key), g), policy, params, policy_params=pp,
                          targets=pm.TARGETS if t is None else (t,), episodes=a.episodes,
                          eval_games=cfg["eval_games"])
        out[name] = moves(gen)
    result = {"run": a.run, "params": list(pcg.PARAM_NAMES), "generators": out}
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
