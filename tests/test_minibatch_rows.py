"""Minibatches of agent experiences (``Config.minibatch_rows="agents"``, ML-Agents' buffer rows):
the per-row loss over every live (decision, player) row equals the per-decision loss over the live
entries; a single agent's baseline is that agent's column of all baselines; training takes only
minibatches whose rows are all live."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raidjax
from trainers.config import PRESETS
from trainers.mapoca import make_trainer
from trainers.networks import Actor, Critic
from trainers.poca_loss import Batch, loss_fn
from trainers.reference_networks import ReferenceActor, ReferenceCritic


def decisions(senses: str):
    """4 decisions of 3 players (player 2 dead in decisions 1 and 3) with made-up old values."""
    params = raidjax.make_params(observation=senses, action_space=senses)
    obs, _ = jax.vmap(raidjax.reset, in_axes=(0, None))(jax.random.split(jax.random.key(0), 4), params)
    alive = jnp.array([[1, 1, 1], [1, 1, 0], [1, 1, 1], [1, 1, 0]], bool)
    obs = obs.replace(alive=alive)
    k = jax.random.split(jax.random.key(1), 6)
    n_act = obs.action_mask.shape[-1]
    return obs, Batch(obs, jax.random.randint(k[0], (4, 3), 0, n_act), -jax.random.uniform(k[1], (4, 3)), alive,
                      jax.random.normal(k[2], (4,)), jax.random.normal(k[3], (4, 3)),
                      jax.random.normal(k[4], (4, 3)), jax.random.normal(k[5], (4, 3)))


@pytest.mark.parametrize("network", ["raidjax", "reference"])
def test_rows_loss_equals_the_decisions_loss_over_live_players(network):
    senses = "reference"
    obs, batch = decisions(senses)
    actor, critic = ((Actor(8, 1, 2, False), Critic(8, 1, 2)) if network == "raidjax"
                     else (ReferenceActor(8, 1, 2), ReferenceCritic(8, 1, 2)))
    w = {"actor": actor.init(jax.random.key(2), obs), "critic": critic.init(jax.random.key(3), obs, batch.action)}
    _, by_decision = jax.jit(loss_fn, static_argnums=(2, 3, 6))(w, batch, actor, critic, 0.2, 0.01, "agents")
    # Every live (decision, player) as a row of its own.
    d, i = np.nonzero(np.asarray(batch.alive))
    rows = jax.tree.map(lambda x: x[d], batch)
    _, by_row = jax.jit(loss_fn, static_argnums=(2, 3, 6))(w, rows, actor, critic, 0.2, 0.01, "agents",
                                                           jnp.asarray(i, jnp.int32))
    for k in ("policy_loss", "value_loss", "baseline_loss", "entropy", "approx_kl"):
        np.testing.assert_allclose(float(by_row[k]), float(by_decision[k]), rtol=2e-5, atol=1e-6, err_msg=k)
    # One agent's baseline is that agent's column of all baselines.
    full = critic.apply(w["critic"], obs, batch.action, method="baseline")
    for j in range(3):
        one = critic.apply(w["critic"], obs, batch.action, jnp.full(4, j), method="baseline")
        np.testing.assert_allclose(np.asarray(one), np.asarray(full[:, j]), rtol=1e-5, atol=1e-6)


def test_training_takes_only_minibatches_of_live_rows():
    cfg = PRESETS["mapoca"]["cpu"].replace(n_arenas=4, n_steps=64, n_minibatches=8, update_epochs=1, hidden=8,
                                           layers=1, heads=2, updates_per_chunk=4, total_steps=4 * 64 * 4,
                                           minibatch_rows="agents", skill_ranges=(5.0,))
    trainer = make_trainer(cfg)
    r = jax.jit(trainer.init)(jax.random.key(0))
    r, m = jax.jit(trainer.chunk)(r)
    assert all(np.isfinite(np.asarray(v)).all() for v in jax.tree.leaves((r.params, m)))
    # 768 rows per update in 8 minibatches of 96, live rows first: a lost game leaves dead rows, so
    # the last minibatches of such an update hold some and are skipped.
    assert float(m["episodes"]) > float(m["wins"] + m["draws"])  # a game was lost
    assert 0.0 < float(m["taken"]) < 1.0
