"""Seconds to trace, lower and compile a vmapped program: the step over arenas, or the generator's
measurement (``raidjax.pcg.play_outcomes``) over episodes. Run it in a fresh process for each figure
(JAX keeps traces per process). Prints one JSON object with the machine.

    python benchmarks/trace_time.py step --arenas 4096
    python benchmarks/trace_time.py pcg --episodes 8 --games 100
"""

from __future__ import annotations

import argparse
import json
import time

import jax
import jax.numpy as jnp

import raidjax
from raidjax import pcg
from raidjax.io import machine


def main() -> None:
    raidjax.use_recommended_xla_flags()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("program", choices=("step", "pcg"))
    ap.add_argument("--arenas", type=int, default=4096, help="step: arenas of the vmapped step")
    ap.add_argument("--episodes", type=int, default=8, help="pcg: generator episodes side by side")
    ap.add_argument("--games", type=int, default=100, help="pcg: PT-HR games per measurement")
    args = ap.parse_args()
    if args.program == "step":
        params = raidjax.make_params(skill_range=9.0)
        n = args.arenas
        batch = jax.tree.map(lambda x: jnp.broadcast_to(x, (n,) + x.shape), params)
        keys = jax.random.split(jax.random.key(0), n)
        _, state = jax.vmap(raidjax.reset)(keys, batch)
        actions = jnp.full((n, 3), raidjax.ACTION_HEURISTIC, jnp.int32)
        program, program_args = jax.jit(jax.vmap(raidjax.step)), (keys, state, actions, batch)
    else:
        p = pcg.make_pcg_params(n_games=args.games)
        keys = jax.random.split(jax.random.key(9), args.episodes)
        skills = jnp.broadcast_to(jnp.asarray((12.0, 1.0, 0.3, 1.0)), (args.episodes, 4))
        program = jax.jit(jax.vmap(lambda k, s: pcg.play_outcomes(k, p.game, s, args.games)))
        program_args = (keys, skills)
    out = {"benchmark": "trace_time", "machine": machine(load=True), "program": args.program,
           "arenas": args.arenas if args.program == "step" else None,
           "episodes": args.episodes if args.program == "pcg" else None}
    t = time.perf_counter()
    traced = program.trace(*program_args)
    out["trace_s"] = round(time.perf_counter() - t, 2)
    t = time.perf_counter()
    lowered = traced.lower()
    out["lower_s"] = round(time.perf_counter() - t, 2)
    t = time.perf_counter()
    lowered.compile()
    out["compile_s"] = round(time.perf_counter() - t, 2)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
