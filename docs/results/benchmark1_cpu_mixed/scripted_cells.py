"""PT-HR and PT-RD on Benchmark 1's mixed-team content (warrior, mage, priest; catalogue skills):
the cells ``experiments.benchmark1.stage_evaluate`` plays for its scripted rows, 2 batches x 500 games
per range. Writes ``scripted_cells.json`` (win rate per range and batch)."""

import json
import time

import jax
import jax.numpy as jnp
import numpy as np

import raidjax
from experiments.benchmark1 import TABLE_RANGES, content_of

raidjax.use_recommended_xla_flags()
cells = [(r, s) for r in TABLE_RANGES for s in range(2)]
contents = jax.tree.map(lambda *x: jnp.stack(x), *[content_of("mixed", r) for r, _ in cells])
out = {}
for name, pol, seed in (("PT-HR", raidjax.policies.heuristic, 999), ("PT-RD", raidjax.policies.random, 998)):
    t = time.perf_counter()
    games = raidjax.playtest(jax.random.PRNGKey(seed), contents, pol, len(cells) * 500)["outcome"]
    wins = (np.asarray(games).reshape(len(cells), 500) == 1).mean(1)
    out[name] = {f"{r:g}": [float(w) for w, (rr, _) in zip(wins, cells, strict=True) if rr == r] for r in TABLE_RANGES}
    print(name, out[name], f"{time.perf_counter() - t:.0f}s", flush=True)
with open("scripted_cells.json", "w") as f:
    json.dump(out, f, indent=1)
