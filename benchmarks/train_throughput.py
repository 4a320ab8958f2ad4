"""MA-POCA training throughput: environment decisions per second of whole updates (rollout,
λ-returns, epochs of minibatch Adam steps), for the reference network (``paper`` preset,
2 x 256) and the ``cpu`` preset.

Compiles one update ahead of time (``lower().compile()``), warms up, times ``--repeats`` calls
with ``block_until_ready`` and prints one JSON object with the machine, the load average (the
machine may be shared) and, per preset, compile seconds, seconds per update and decisions/s
(one decision = every player acts once; agent steps = 3 x decisions).

    python benchmarks/train_throughput.py --presets paper cpu --repeats 3
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run as a script from anywhere
from raidjax.utils import machine
from raidjax.xla_flags import use_recommended_xla_flags
from trainers.config import PRESETS  # noqa: E402
from trainers.mapoca import make_trainer  # noqa: E402


def bench(preset: str, repeats: int, **overrides) -> dict:
    """Time whole updates of ``preset`` (with ``overrides``). Returns a JSON-able dict."""
    cfg = PRESETS[preset].replace(**overrides)
    trainer = make_trainer(cfg)
    runner = jax.jit(trainer.init)(jax.random.PRNGKey(0))
    t0 = time.perf_counter()
    update = jax.jit(trainer.update, donate_argnums=0).lower(runner).compile()
    compile_s = time.perf_counter() - t0
    runner, m = update(runner)  # warm-up
    jax.block_until_ready(m)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        runner, m = update(runner)
        jax.block_until_ready(m)
        times.append(time.perf_counter() - t0)
    best = min(times)
    n_params = sum(x.size for x in jax.tree.leaves(runner.params))
    return {
        "preset": preset, "hidden": cfg.hidden, "layers": cfg.layers, "heads": cfg.heads,
        "proj_attention": cfg.proj_attention, "n_arenas": cfg.n_arenas, "n_steps": cfg.n_steps,
        "update_epochs": cfg.update_epochs, "n_minibatches": cfg.n_minibatches, "parameters": int(n_params),
        "decisions_per_update": cfg.decisions_per_update, "compile_s": round(compile_s, 2),
        "seconds_per_update": [round(t, 3) for t in times],
        "decisions_per_s": round(cfg.decisions_per_update / best),
        "agent_steps_per_s": round(3 * cfg.decisions_per_update / best),
    }


def main() -> None:
    """Parse flags, run the benchmarks, print one JSON object."""
    use_recommended_xla_flags()  # raidjax's commands measure with these (raidjax.xla_flags)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=["paper", "cpu"], choices=sorted(PRESETS))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--arenas", type=int, help="override n_arenas of every preset")
    args = ap.parse_args()
    overrides = {} if args.arenas is None else {"n_arenas": args.arenas}
    results = [bench(p, args.repeats, **overrides) for p in args.presets]
    print(json.dumps({"benchmark": "train_throughput", "machine": machine(load=True), "results": results}))


if __name__ == "__main__":
    main()
