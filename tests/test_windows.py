"""``Config.stale_phases`` (``trainers.windows``): the reference trainer's asynchronous data,
approximated by staggered windows that the last ``K`` updates' policies acted."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from trainers import windows
from trainers.config import load_config
from trainers.mapoca import make_trainer


def test_each_update_completes_one_groups_window_in_time_order():
    k, seg, n = 4, 2, 3
    t = k * seg

    def segment(u):  # arena a's step s of update u holds its decision count * 100 + a
        return (u * seg + jnp.arange(seg)[:, None]) * 100 + jnp.arange(k * n)[None, :]

    window = windows.empty(jax.ShapeDtypeStruct((seg, k * n), jnp.int32), k)
    assert window.shape == (t, k, n)
    for u in range(1 - k, 9):  # the k - 1 segments before update 0 (init's), then updates 0..8
        window = windows.write(window, segment(u), jnp.int32(u))
        if u >= 0:
            g = (u + 1) % k  # one group a update, each in turn: its decisions of updates u - k + 1 .. u
            want = ((u - k + 1) * seg + np.arange(t)[:, None]) * 100 + g * n + np.arange(n)[None, :]
            np.testing.assert_array_equal(np.asarray(windows.completed(window, jnp.int32(u), k)), want)


def test_a_window_is_acted_by_the_policies_of_the_updates_that_filled_it():
    # lr 1e-2: one update moves the policy far enough to tell stale rows from fresh ones.
    cfg = load_config("cpu", n_arenas=2, n_steps=8, n_minibatches=2, update_epochs=1, hidden=8, layers=1, heads=1,
                      lr=1e-2, updates_per_chunk=1, total_steps=32, stale_phases=2)
    tr = make_trainer(cfg)
    runner = jax.jit(tr.init)(jax.random.key(0))
    assert runner.env_state.hp.shape[0] == 4 and runner.window.reward.shape == (8, 2, 2)  # K x n_arenas arenas
    runner, metrics = jax.jit(tr.update)(runner)
    assert all(np.isfinite(float(v)) for v in metrics.values())
    # Update 1 completes group 0's window: its first segment acted at update 0, its second now.
    runner, traj, _ = jax.jit(tr.collect)(runner)
    assert traj.reward.shape == (8, 2)
    logits = jax.vmap(lambda o: tr.actor.apply(runner.params["actor"], o))(traj.obs)
    logp = jnp.take_along_axis(jax.nn.log_softmax(logits), traj.action[..., None], axis=-1)[..., 0]
    gap = np.abs(np.asarray(logp - traj.logp)) * np.asarray(traj.alive)
    assert gap[4:].max() < 1e-5  # acted by the policy of this update
    assert gap[:4].max() > 1e-3  # acted by the policy of the update before, as stored then


@pytest.mark.parametrize("phases", [0, 3])
def test_stale_phases_must_divide_the_rollout(phases):
    with pytest.raises(ValueError, match="stale_phases: value"):
        load_config("cpu", n_steps=8, stale_phases=phases)
