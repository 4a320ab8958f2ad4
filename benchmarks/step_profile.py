"""Where a decision's time goes: the random-policy rollout of ``env_throughput.py``, profiled.

Runs the AOT-compiled rollout once under ``jax.profiler``, reads the per-operation times of the
trace and attributes every compiled operation to the phase of the step it belongs to, from the
named scopes of ``raidjax.env`` (``movement``, ``casting``, ``fire``, ``projectiles``, ``hits``,
``observation``, ``next_episode``); operations outside them (loop control, copies of the carried
state, the policy, regeneration and results) are ``other``. Prints one JSON object with the machine,
the device count, the batch size and each phase's seconds and share of the profiled operation
time. Operation times overlap across threads, so shares, not sums, compare with the wall clock.
XLA fuses neighbouring operations; a fused operation counts for the phase of its root.

    python benchmarks/step_profile.py --arenas 4096 --steps 64 [--substeps 1]
"""

from __future__ import annotations

import argparse
import collections
import glob
import gzip
import json
import re
import tempfile
import time

import jax
from env_throughput import arenas, make_rollout

import raidjax
from raidjax.io import machine

PHASES = ("movement", "casting", "fire", "projectiles", "hits", "observation", "next_episode")


def phase_of_ops(hlo_text: str) -> dict[str, str]:
    """Compiled operation name -> phase, from the ``op_name`` metadata of the optimised HLO text.

    Loops and calls are left out: their time in a trace spans the operations they run.
    """
    out = {}
    for line in hlo_text.splitlines():
        m = re.match(r"\s*(?:ROOT )?%(\S+) = .*? (\w[\w-]*)\(", line)
        if not m or m.group(2) in ("while", "conditional", "call"):
            continue
        meta = re.search(r'op_name="([^"]*)"', line)
        parts = meta.group(1).split("/") if meta else []
        out[m.group(1)] = next((p for p in reversed(parts) if p in PHASES), "other")
    return out


def profile(compiled, args, trace_dir: str) -> dict[str, float]:
    """Seconds of profiled operation time per phase for one call of ``compiled(*args)``."""
    phase = phase_of_ops(compiled.as_text())
    jax.profiler.start_trace(trace_dir, create_perfetto_trace=True)
    jax.block_until_ready(compiled(*args))
    jax.profiler.stop_trace()
    trace = json.load(gzip.open(glob.glob(f"{trace_dir}/**/perfetto_trace.json.gz", recursive=True)[0]))
    events = trace["traceEvents"] if isinstance(trace, dict) else trace
    seconds = collections.Counter()
    for e in events:
        if e.get("ph") == "X" and e["name"] in phase:
            seconds[phase[e["name"]]] += e.get("dur", 0) / 1e6
    return seconds


def main() -> None:
    raidjax.use_recommended_xla_flags()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arenas", type=int, default=4096)
    ap.add_argument("--steps", type=int, default=64)
    ap.add_argument("--rules", default="reference", choices=sorted(raidjax.RULE_SETS))
    ap.add_argument("--substeps", type=int, default=5, choices=(1, 5))
    args = ap.parse_args()

    keys, state, batch = arenas(args.arenas, args.rules, args.substeps)
    compiled = jax.jit(make_rollout(args.arenas, args.steps)).lower(keys, state, batch).compile()
    jax.block_until_ready(compiled(keys, state, batch))  # warm
    t0 = time.perf_counter()
    jax.block_until_ready(compiled(keys, state, batch))
    wall = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as trace_dir:
        seconds = profile(compiled, (keys, state, batch), trace_dir)
    total = sum(seconds.values())
    print(json.dumps({
        "benchmark": "step_profile", "machine": machine(load=True),
        "arenas": args.arenas, "steps": args.steps, "rules": args.rules, "n_substeps": args.substeps,
        "wall_s": round(wall, 3), "decisions_per_s": round(args.arenas * args.steps / wall),
        "profiled_op_s": round(total, 3),
        "phases": {k: {"seconds": round(v, 3), "share": round(v / total, 3)} for k, v in seconds.most_common()},
    }))


if __name__ == "__main__":
    main()
