"""``raidjax.step`` under JAX's transforms: differentiation (``jax.grad``, ``jax.jvp``), ``lax.scan``,
``shard_map``, and ``Observation.flat`` on any batch shape (nested ``vmap``: ``test_lanes``; ``jit``
and eager: ``test_api``). Derivatives exist where the game is continuous (positions, velocities)
and are zero through its discrete parts (casts, dice, integer counters)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from helpers import NOOP, acts

import raidjax

P = raidjax.make_params(skill_range=13.0, config=raidjax.EnvConfig(n_substeps=1))  # one sub-step: cheap
_, STATE = raidjax.reset(jax.random.key(0), P)


def _players_x_after_a_step(pos):
    """Sum of the players' x after one decision of no-ops from positions ``pos`` (no velocity, far
    from the walls): each player stands still, so d/d pos is 1 on every player's x."""
    _, s, _, _, _ = raidjax.step(jax.random.key(1), STATE.replace(pos=pos), acts(NOOP), P)
    return s.pos[:-1, 0].sum()


def test_grad_and_jvp_through_step():
    # A forward step of the same shapes first: jit keeps its trace, scheduling conditionals included,
    # and the derivatives reuse it; its custom_jvp must send them to the plain program (this order
    # once failed in CI).
    jax.jit(raidjax.step)(jax.random.key(1), STATE, acts(NOOP), P)
    g = jax.jit(jax.grad(_players_x_after_a_step))(STATE.pos)
    assert np.isfinite(np.asarray(g)).all()
    expected = np.zeros(STATE.pos.shape, np.float32)
    expected[:-1, 0] = 1.0  # the players' x; the boss's position moves nothing of theirs
    np.testing.assert_allclose(np.asarray(g), expected, atol=1e-6)
    tangent = jnp.zeros_like(STATE.pos).at[:-1, 0].set(1.0)
    _, dx = jax.jvp(_players_x_after_a_step, (STATE.pos,), (tangent,))
    np.testing.assert_allclose(float(dx), 3.0, atol=1e-5)


def test_scan_of_steps_equals_a_loop_of_steps():
    keys = jax.random.split(jax.random.key(2), 6)
    a = acts(1, 7, raidjax.ACTION_HEURISTIC)

    def body(s, k):
        _, s, r, _, _ = raidjax.step(k, s, a, P)
        return s, r

    scanned, rewards = jax.jit(lambda s: jax.lax.scan(body, s, keys))(STATE)
    step = jax.jit(raidjax.step)
    s = STATE
    for i in range(len(keys)):
        _, s, r, _, _ = step(keys[i], s, a, P)
        np.testing.assert_allclose(np.asarray(r), np.asarray(rewards[i]), atol=1e-5)
    np.testing.assert_allclose(np.asarray(s.pos), np.asarray(scanned.pos), atol=1e-4)
    assert int(s.decision) == int(scanned.decision) == len(keys)


def test_shard_map_of_vmapped_step_equals_the_vmap():
    from jax.sharding import Mesh, PartitionSpec

    n = 2 * len(jax.devices())
    keys = jax.random.split(jax.random.key(3), n)
    obs, states = jax.vmap(raidjax.reset, (0, None))(keys, P)
    actions = jnp.tile(acts(1, 7, raidjax.ACTION_HEURISTIC), (n, 1))
    step = jax.vmap(raidjax.step, (0, 0, 0, None))
    mesh = Mesh(np.asarray(jax.devices()), ("arenas",))
    arenas = PartitionSpec("arenas")
    sharded = jax.shard_map(lambda k, s, a: step(k, s, a, P), mesh=mesh, in_specs=(arenas, arenas, arenas),
                            out_specs=arenas)
    out = jax.jit(sharded)(keys, states, actions)
    ref = jax.jit(lambda k, s, a: step(k, s, a, P))(keys, states, actions)
    for x, y in zip(jax.tree.leaves(out[1:]), jax.tree.leaves(ref[1:]), strict=True):
        np.testing.assert_allclose(np.asarray(x, np.float32), np.asarray(y, np.float32), atol=1e-5)


def test_observation_flat_takes_any_batch_shape():
    keys = jax.random.split(jax.random.key(4), 6)
    obs, _ = jax.vmap(raidjax.reset, (0, None))(keys, P)
    one = np.stack([np.asarray(jax.tree.map(lambda x, i=i: x[i], obs).flat()) for i in range(6)])
    assert one.shape == (6, 3, 112)
    np.testing.assert_array_equal(np.asarray(obs.flat()), one)  # a batch of arenas
    nested = jax.tree.map(lambda x: x.reshape((2, 3) + x.shape[1:]), obs)
    np.testing.assert_array_equal(np.asarray(nested.flat()).reshape(6, 3, 112), one)  # any leading axes
    np.testing.assert_array_equal(np.asarray(jax.vmap(lambda o: o.flat())(obs)), one)  # under vmap
