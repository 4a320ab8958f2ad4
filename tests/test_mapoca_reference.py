"""MA-POCA on the reference player's senses (``Config.senses = "reference"``, the ``paper`` preset):
the network takes the 204-float observation (teammate buffer through masked attention, rays and
stack beside it) and 8 actions, trains, checkpoints, and its ``TeamPolicy`` playtests any content
with the senses it was trained on."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raidjax
from raidjax.reference_observation import ReferenceObservation
from trainers import checkpoint
from trainers.config import PRESETS, Config
from trainers.mapoca import load_policy, make_trainer
from trainers.networks import Actor, Critic

TINY = PRESETS["mapoca"]["cpu"].replace(n_arenas=4, n_steps=8, n_minibatches=2, update_epochs=1, hidden=8, layers=1,
                              heads=2, updates_per_chunk=2, total_steps=4 * 8 * 2, eval_games=4, senses="reference",
                              skill_ranges=(5.0, 17.0), redraw_every=1)  # the redraw path restarts the stack


def test_paper_preset_uses_the_reference_senses():
    assert PRESETS["mapoca"]["paper"].senses == "reference" and PRESETS["mapoca"]["cpu"].senses == "raidjax"
    with pytest.raises(ValueError, match=r"^senses: value 'rays'"):
        Config(senses="rays")
    assert Config.from_dict({k: v for k, v in Config().to_dict().items() if k != "senses"}).senses == "raidjax"


def test_networks_on_reference_observations():
    params = raidjax.make_params(observation="reference", action_space="reference")
    reset = jax.jit(jax.vmap(raidjax.reset, in_axes=(0, None)))
    obs, _ = reset(jax.random.split(jax.random.key(0), 2), params)
    assert isinstance(obs, ReferenceObservation)
    # Jitted: run op by op, the networks would compile every operation on its own.
    actor, critic = Actor(16, 2, 2), Critic(16, 2, 2)
    wa = jax.jit(actor.init)(jax.random.key(1), obs)
    apply = jax.jit(actor.apply)
    logits = apply(wa, obs)
    assert logits.shape == (2, 3, 8) and np.isfinite(np.asarray(logits)).all()
    # A dead teammate's buffer row is masked out of the attention: its contents cannot matter.
    dead = obs.replace(teammate_mask=obs.teammate_mask.at[:, 0, 0].set(False))
    changed = dead.replace(teammates=dead.teammates.at[:, 0, 0].add(5.0))
    np.testing.assert_allclose(apply(wa, dead)[:, 0], apply(wa, changed)[:, 0], rtol=1e-5, atol=1e-6)
    wc = jax.jit(critic.init)(jax.random.key(2), obs, jnp.zeros((2, 3), jnp.int32))
    value, baseline = jax.jit(critic.apply)(wc, obs, jnp.full((2, 3), 7, jnp.int32))
    assert value.shape == (2,) and baseline.shape == (2, 3)


def test_train_checkpoint_and_playtest_with_reference_senses(tmp_path):
    # ML-Agents' networks (the paper preset's); raidjax's networks on these senses train, checkpoint
    # and play in Benchmark 1's smoke run (protocol paper) and b1_switches' trained-run test.
    cfg = TINY.replace(network="reference", heads=4)
    keys = jax.random.split(jax.random.PRNGKey(0), 1)
    trainer = make_trainer(cfg)
    init = jax.jit(jax.vmap(trainer.init))  # one run, vmapped as the command line trains it
    r0 = init(keys)
    assert isinstance(r0.obs, ReferenceObservation) and r0.obs.flat().shape == (1, cfg.n_arenas, 3, 204)
    r1, m1 = jax.jit(jax.vmap(trainer.chunk))(r0)
    assert all(np.isfinite(np.asarray(x)).all() for x in jax.tree.leaves((m1, r1.params)))
    assert r1.params["actor"]["params"]["pi"]["kernel"].shape[-1] == 8
    checkpoint.save(tmp_path / "checkpoints", r1, r1.params["actor"], cfg.to_dict(),
                    {"chunk": 1, "update": 2, "env_steps": 64, "seconds": 1.0})
    policy, w = load_policy(tmp_path, seed=0)
    assert policy.senses == "reference"
    # The content is made with raidjax's senses; the policy plays it with its own.
    out = raidjax.playtest(jax.random.key(3), raidjax.make_params(skill_range=13.0), policy, 2, weights=w)
    assert out["outcome"].shape == (2,) and set(np.asarray(out["outcome"]).tolist()) <= {1, 2, 3}
    # A replay (raidjax render --policy RUN) records it with its senses too.
    trace, _ = raidjax.logs.record_episode(jax.random.key(4), raidjax.make_params(), policy, 3, w)
    assert trace.actions.shape == (4, 3) and int(np.asarray(trace.actions).max()) < 8


def test_a_run_saved_before_senses_existed_still_resumes(tmp_path):
    from trainers.runfolder import RunFolder, RunFolderError

    old = Config().to_dict()
    del old["senses"]  # as every run folder saved before the field existed
    RunFolder(tmp_path / "run", {"config": old})
    RunFolder(tmp_path / "run", {"config": Config().to_dict()}, resume=True)  # raidjax senses: the same run
    with pytest.raises(RunFolderError, match=r'config.senses: saved null, now "reference"'):
        RunFolder(tmp_path / "run", {"config": Config(senses="reference").to_dict()}, resume=True)
