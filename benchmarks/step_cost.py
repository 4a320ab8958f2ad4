"""What one sub-step and one decision cost, as XLA counts them: bytes and flops per arena per
sub-step, and the fusions, copies and loops of the compiled decision.

The sub-step figures come from XLA's cost analysis of a program that runs exactly one sub-step
(``raidjax.phases.substep`` in the lane layout, ``raidjax.lanes``, as ``env.advance`` runs it, vmapped
over ``--arenas`` arenas; the state's moves into and out of the layout included); they are divided by the arena count,
never derived from the decision's program (XLA counts a loop body once, so a 5-sub-step decision
"as counted" looks like one sub-step). On an accelerator the bytes bound the speed, so this
CPU-only figure shows what a GPU will do. The decision's program is ``vmap(raidjax.step)``;
its operation counts are read from the optimised HLO text. The observation is built once per
decision, outside the sub-steps: its own program (``vmap(raidjax.observe)``) is counted apart.

A decision moves its state into and out of the lane layout once, whatever its sub-step count, so a
second program runs two sub-steps in a row: what the second adds is a sub-step's own work
(``substep_own_*``), the rest of the one-sub-step program is the decision's once-only work
(``decision_once_*``), and ``substep_in_decision_*`` shares it among ``--substeps`` sub-steps. In
those two programs XLA fuses the moves into the layout into their readers, as copies inside the
sub-step's conditionals; ``substep_on_lanes_*`` is a sub-step on inputs already in the lane layout,
its state updated in place, as the decision's loop runs it.

    python benchmarks/step_cost.py --arenas 4096 [--substeps 5|1] [--rules reference|clean]
        [--observation raidjax|reference]
"""

from __future__ import annotations

import argparse
import functools
import json
import re

import jax
import jax.numpy as jnp
from env_throughput import arenas

import raidjax
from raidjax import damage, lanes
from raidjax.io import machine
from raidjax.phases import substep
from raidjax.types import TICKS_PER_DECISION
from raidjax.utils import dice_seeds


def cost(compiled) -> dict:
    """XLA's ``{"bytes": ..., "flops": ...}`` for one call of a compiled program."""
    c = compiled.cost_analysis()
    c = c[0] if isinstance(c, list) else c
    return {"bytes": float(c.get("bytes accessed", 0.0)), "flops": float(c.get("flops", 0.0))}


def op_counts(hlo: str) -> dict:
    """Fusions, copies, while loops and total instructions in optimised HLO text."""
    ops = re.findall(r"^\s*(?:ROOT )?%\S+ = .*? ([\w-]+)\(", hlo, flags=re.M)
    return {"instructions": len(ops), "fusions": ops.count("fusion"), "copies": ops.count("copy"),
            "while_loops": ops.count("while"), "gathers": ops.count("gather"), "scatters": ops.count("scatter")}


def main() -> None:
    raidjax.use_recommended_xla_flags()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arenas", type=int, default=4096)
    ap.add_argument("--rules", default="reference", choices=sorted(raidjax.RULE_SETS))
    ap.add_argument("--substeps", type=int, default=5, choices=(1, 5))
    ap.add_argument("--observation", default="raidjax", choices=("raidjax", "reference"))
    args = ap.parse_args()

    keys, state, batch = arenas(args.arenas, args.rules, args.substeps, args.observation)
    actions = jnp.full((args.arenas, state.pos.shape[1] - 1), raidjax.ACTION_HEURISTIC, jnp.int32)
    n_ticks = TICKS_PER_DECISION // args.substeps

    def lane_substep(seeds, state, actions, params, sources, fast):  # one sub-step as ``env.advance`` runs it
        first = seeds.reshape(-1)[0]
        schedule = lanes.Schedule(first != first + 1) if fast else lanes.PLAIN
        return substep(seeds, state, actions, params, sources, n_ticks, schedule=schedule)

    def lane_two_substeps(seeds, state, actions, params, sources, fast):  # two in a row, as a decision's scan
        state, _, _ = lane_substep(seeds, state, actions, params, sources, fast)
        return lane_substep(seeds, state, actions, params, sources, fast)

    def program_of(lane_fn):
        program = lanes.batched(lane_fn, full=(1,))

        def run(key, state, actions, params):
            return program(dice_seeds(key), state.replace(memory=None), actions, params,
                           damage.effect_sources(params))

        return jax.jit(jax.vmap(run)).lower(keys, state, actions, batch).compile()

    sub, two = program_of(lane_substep), program_of(lane_two_substeps)
    # The sub-step as the decision's loop runs it: its inputs already in the lane layout (the loop
    # carries them so) and its state updated in place (donated, as the loop's carry is). No move into
    # the layout is then fused into the conditionals, nor the pool copied before its blocks are
    # written: the sub-step's work alone.
    to_lanes = jax.jit(lambda tree: jax.tree.map(lambda x: jnp.moveaxis(x, 0, -1), tree))
    lane_args = to_lanes((jax.vmap(dice_seeds)(keys), state.replace(memory=None), actions, batch,
                          jax.vmap(damage.effect_sources)(batch)))
    # The schedule ``lanes.batched`` picks: XLA:CPU's on the CPU, the plain program elsewhere.
    fast = jax.default_backend() == "cpu"
    on_lanes = jax.jit(functools.partial(lane_substep, fast=fast), donate_argnums=1).lower(*lane_args).compile()
    sources = jax.jit(jax.vmap(damage.effect_sources)).lower(batch).compile()
    table = jax.jit(jax.vmap(damage.effect_table)).lower(batch).compile()
    dec = jax.jit(jax.vmap(raidjax.step)).lower(keys, state, actions, batch).compile()
    obs = jax.jit(jax.vmap(lambda s, p: raidjax.observe(s, p, damage.effect_table(p)))).lower(state, batch).compile()
    sub_cost, two_cost, sources_cost, table_cost, obs_cost = cost(sub), cost(two), cost(sources), cost(table), cost(obs)
    lanes_cost = cost(on_lanes)
    n = args.arenas
    # A sub-step inside a decision: what a second sub-step in a row adds (its own work), plus the
    # decision's once-only work (the moves into and out of the lane layout, the sources' layout)
    # shared by its sub-steps.
    own = {k: two_cost[k] - sub_cost[k] for k in ("bytes", "flops")}
    once = {k: sub_cost[k] - sources_cost[k] - own[k] for k in ("bytes", "flops")}
    state_bytes = sum(x.dtype.itemsize * x.size for x in jax.tree.leaves(state)) / n
    print(json.dumps({
        "benchmark": "step_cost", "machine": machine(load=True), "arenas": n, "rules": args.rules,
        "n_substeps": args.substeps, "observation": args.observation, "state_bytes_per_arena": round(state_bytes),
        # The sub-step program also builds the per-decision source rows; they are taken out.
        "substep_bytes_per_arena": round((sub_cost["bytes"] - sources_cost["bytes"]) / n),
        "substep_flops_per_arena": round((sub_cost["flops"] - sources_cost["flops"]) / n),
        "substep_own_bytes_per_arena": round(own["bytes"] / n),
        "substep_on_lanes_bytes_per_arena": round(lanes_cost["bytes"] / n),
        "substep_on_lanes_flops_per_arena": round(lanes_cost["flops"] / n),
        "decision_once_bytes_per_arena": round(once["bytes"] / n),
        "substep_in_decision_bytes_per_arena": round((own["bytes"] + once["bytes"] / args.substeps) / n),
        "substep_in_decision_flops_per_arena": round((own["flops"] + once["flops"] / args.substeps) / n),
        # Once per decision: the observation of every player (its effect table taken out likewise).
        "observation_bytes_per_arena": round((obs_cost["bytes"] - table_cost["bytes"]) / n),
        "observation_flops_per_arena": round((obs_cost["flops"] - table_cost["flops"]) / n),
        "decision_program": op_counts(dec.as_text()),
        "substep_program": op_counts(sub.as_text()),
    }))


if __name__ == "__main__":
    main()
