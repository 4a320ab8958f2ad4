"""Sharding over devices (``raidjax.sharding``): 4 forced CPU devices give the outputs of one.

Each case runs in two fresh subprocesses (the device count is fixed when JAX starts): one with
``--xla_force_host_platform_device_count=4``, one without, and compares their saved outputs.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

PLAYTEST = """
import sys, numpy as np, jax, raidjax
raidjax.use_recommended_xla_flags()
cfg = raidjax.EnvConfig.from_rules("reference", n_substeps=1, max_decisions=300)
p = raidjax.make_params(skill_range=13.0, config=cfg)
r = raidjax.playtest(jax.random.key(0), p, raidjax.policies.heuristic, 64)
occ = raidjax.playtest_occupancy(jax.random.key(0), p, raidjax.policies.heuristic, 64)
odd = raidjax.playtest(jax.random.key(0), p, raidjax.policies.heuristic, 6)  # not a multiple of 4: one device
print(len(r["outcome"].sharding.device_set), len(occ.sharding.device_set), len(odd["outcome"].sharding.device_set))
np.savez(sys.argv[1], occ=np.asarray(occ), **{k: np.asarray(v) for k, v in r.items()})
"""


def run(code: str, out: Path, devices: int) -> str:
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    if devices > 1:
        env["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={devices}"
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    done = subprocess.run([sys.executable, "-c", code, str(out)], env=env, capture_output=True, text=True,
                          timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout.split()


def same(a: Path, b: Path, float_rtol: float = 0.0):
    """Every saved array equal; with ``float_rtol``, float arrays equal to that relative tolerance."""
    a, b = np.load(a), np.load(b)
    assert sorted(a) == sorted(b)
    for k in a:
        if float_rtol and np.issubdtype(a[k].dtype, np.floating):
            np.testing.assert_allclose(a[k], b[k], rtol=float_rtol, atol=1e-6, err_msg=k)
        else:
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_playtest_games_split_over_4_devices_give_the_single_device_results(tmp_path):
    assert run(PLAYTEST, tmp_path / "four.npz", 4) == ["4", "4", "1"]
    assert run(PLAYTEST, tmp_path / "one.npz", 1) == ["1", "1", "1"]
    same(tmp_path / "four.npz", tmp_path / "one.npz")


MAPOCA = """
import sys, numpy as np, jax, raidjax
raidjax.use_recommended_xla_flags()
from raidjax.sharding import put_batch
from trainers.config import load_config
from trainers.mapoca import make_trainer
cfg = load_config("cpu", n_arenas=8, n_steps=4, n_minibatches=2, update_epochs=1, hidden=16, updates_per_chunk=2,
                  total_steps=64)
trainer = make_trainer(cfg)
runner = put_batch(jax.jit(jax.vmap(trainer.init))(jax.random.split(jax.random.PRNGKey(0), 4)), 4)
runner, metrics = jax.jit(jax.vmap(trainer.chunk))(runner)
print(len(jax.tree.leaves(runner)[0].sharding.device_set))
np.savez(sys.argv[1], *[np.asarray(x) for x in jax.tree.leaves((runner.params, metrics))])
"""


def test_mapoca_seeds_split_over_4_devices_train_as_on_one(tmp_path):
    """One seed per device is a batch of 1 where one device has a batch of 4: XLA vectorises the
    two differently, so float sums round differently (1e-8 here); integers must be equal."""
    assert run(MAPOCA, tmp_path / "four.npz", 4) == ["4"]
    assert run(MAPOCA, tmp_path / "one.npz", 1) == ["1"]
    same(tmp_path / "four.npz", tmp_path / "one.npz", float_rtol=1e-4)
