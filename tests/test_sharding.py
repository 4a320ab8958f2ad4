"""Sharding over devices (``raidjax.sharding``): 4 forced CPU devices give the outputs of one.

The script runs in a fresh subprocess with ``--xla_force_host_platform_device_count=4`` (the device
count is fixed when JAX starts) and in the test's own process (one device, the same XLA flags), and
their saved outputs are compared.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from helpers import TINY_MAPOCA, TINY_MAPOCA_ARGS

ROOT = Path(__file__).resolve().parent.parent

# One script per device count (a JAX process fixes its device count when it starts): a playtest
# and its occupancy, then MA-POCA as the command line trains it, the tiny run of tests/helpers.py
# (its 4 seeds one per device; on one device its programs are those of test_faults_mapoca's runs).
SCRIPT = """
import json, sys, numpy as np, jax, raidjax
raidjax.use_recommended_xla_flags()
from raidjax.sharding import batch_sharding
from trainers import checkpoint, loop, mapoca_cli
out, tiny, args = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3])
placed, put_batch = [], loop.put_batch


def recorded(state, n):  # the devices trainers.loop puts the runs on
    state = put_batch(state, n)
    placed.append(len(jax.tree.leaves(state)[0].sharding.device_set))
    return state
cfg = raidjax.EnvConfig.from_rules("reference", max_decisions=300)
p = raidjax.make_params(skill_range=13.0, config=cfg)
key = jax.random.key(0)
r = raidjax.playtest(key, p, raidjax.policies.heuristic, 64)
occ = raidjax.playtest_occupancy(key, p, raidjax.policies.heuristic, 64)
with open(out + "_tiny.json", "w") as f:
    json.dump(tiny, f)
loop.put_batch = recorded
try:
    mapoca_cli.main(["--config", out + "_tiny.json", *args, "--eval-games", "0", "--out", out + "_run"])
finally:
    loop.put_batch = put_batch
weights, _ = checkpoint.load_policy_weights(out + "_run/checkpoints")
with open(out + "_run/metrics.jsonl") as f:
    rows = [json.loads(s) for s in f]
timing = ("seconds", "steps_per_s")
np.savez(out + "_playtest.npz", occ=np.asarray(occ), **{k: np.asarray(v) for k, v in r.items()})
np.savez(out + "_mapoca.npz", *[np.asarray(x) for x in jax.tree.leaves(weights)],
         **{k: np.asarray([row[k] for row in rows]) for k in rows[0] if k not in timing})
print("devices", len(r["outcome"].sharding.device_set), len(occ.sharding.device_set), *placed,
      batch_sharding(6) is None)
"""


ARGS = [json.dumps(TINY_MAPOCA), json.dumps(TINY_MAPOCA_ARGS)]


def run(code: str, out: Path, devices: int) -> list[str]:
    """The script in a new process with ``devices`` CPU devices: its last line, split into words."""
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    # The child adds raidjax's flags itself.
    env["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={devices}" if devices > 1 else ""
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    done = subprocess.run([sys.executable, "-c", code, str(out), *ARGS], env=env, capture_output=True, text=True,
                          timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout.splitlines()[-1].split()


def run_here(code: str, out: Path) -> list[str]:
    """The script in this process (its one device): its last line, split into words."""
    argv, sys.argv = sys.argv, ["-c", str(out), *ARGS]
    try:
        with contextlib.redirect_stdout(io.StringIO()) as printed:
            exec(code, {"__name__": "__main__"})
    finally:
        sys.argv = argv
    return printed.getvalue().splitlines()[-1].split()


def same(a: Path, b: Path, float_rtol: float = 0.0):
    """Every saved array equal; with ``float_rtol``, float arrays equal to that relative tolerance."""
    a, b = np.load(a), np.load(b)
    assert sorted(a) == sorted(b)
    for k in a:
        if float_rtol and np.issubdtype(a[k].dtype, np.floating):
            np.testing.assert_allclose(a[k], b[k], rtol=float_rtol, atol=1e-5, err_msg=k)
        else:
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_4_devices_give_the_single_device_outputs(tmp_path):
    """Playtest (the reference game, 5 sub-steps per decision): every output bit for bit (with one
    sub-step per decision the batched step may round differently with the batch, GAME.md). MA-POCA
    (4 updates of ``raidjax train mapoca``, its final weights and every metrics row): one seed per
    device is a batch of 1 where one device has a batch of 4, which XLA vectorises differently, so
    float sums round differently (about 1e-8 in the weights); integers must be equal and floats
    agree to rtol 1e-4, atol 1e-5 (the policy loss is a mean of O(1) terms that cancels to about
    1e-4, so its float32 rounding shows at about 1e-6 absolute)."""
    # the 4 seeds split over 4 devices; 6 games on 4 devices: unsplit
    assert run(SCRIPT, tmp_path / "four", 4) == ["devices", "4", "4", "4", "True"]
    assert run_here(SCRIPT, tmp_path / "one") == ["devices", "1", "1", "1", "True"]
    same(tmp_path / "four_playtest.npz", tmp_path / "one_playtest.npz")
    same(tmp_path / "four_mapoca.npz", tmp_path / "one_mapoca.npz", float_rtol=1e-4)
