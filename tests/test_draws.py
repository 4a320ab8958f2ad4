"""``trainers.draws`` gives ``jax.random``'s and ``jax.nn.initializers``' numbers bit for bit (it draws
them as one flat vector, which XLA:CPU compiles faster), eagerly, jitted and vmapped over keys."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from trainers import draws

INIT = jax.nn.initializers
KEYS = jax.random.split(jax.random.PRNGKey(1), 3)
PAIRS = {
    "lecun_normal": (draws.lecun_normal(), INIT.lecun_normal()),
    "xavier_uniform": (draws.xavier_uniform(), INIT.xavier_uniform()),
    "normal": (draws.normal_init(0.03), INIT.normal(0.03)),
    "variance_scaling fan_out normal": (draws.variance_scaling(0.01, "fan_out", "normal"),
                                        INIT.variance_scaling(0.01, "fan_out", "normal")),
}


@pytest.mark.parametrize("name", PAIRS)
@pytest.mark.parametrize("shape", [(5, 7), (3, 4, 6)])
def test_initialisers_are_jax_s(name, shape):
    mine, theirs = PAIRS[name]
    for wrap in (lambda f: f, jax.jit):
        a = jax.vmap(wrap(lambda k: mine(k, shape, jnp.float32)))(KEYS)
        b = jax.vmap(wrap(lambda k: theirs(k, shape, jnp.float32)))(KEYS)
        assert a.shape == (3, *shape) and float(jnp.std(a)) > 0
        np.testing.assert_array_equal(a, b)


def test_samplers_are_jax_random_s():
    logits = jax.random.normal(KEYS[0], (64, 3, 10))
    for wrap in (lambda f: f, jax.jit):
        np.testing.assert_array_equal(jax.vmap(wrap(draws.categorical), (0, None))(KEYS, logits),
                                      jax.vmap(wrap(jax.random.categorical), (0, None))(KEYS, logits))
        np.testing.assert_array_equal(wrap(lambda k: draws.uniform(k, (8, 5), jnp.float32, -1.0, 2.0))(KEYS[0]),
                                      wrap(lambda k: jax.random.uniform(k, (8, 5), jnp.float32, -1.0, 2.0))(KEYS[0]))
        np.testing.assert_array_equal(wrap(lambda k: draws.normal(k, (4, 2, 3)))(KEYS[1]),
                                      wrap(lambda k: jax.random.normal(k, (4, 2, 3)))(KEYS[1]))
        np.testing.assert_array_equal(wrap(lambda k: draws.truncated_normal(k, -2, 2, (6, 6)))(KEYS[2]),
                                      wrap(lambda k: jax.random.truncated_normal(k, -2, 2, (6, 6)))(KEYS[2]))


def test_bad_mode_or_distribution_is_named():
    with pytest.raises(ValueError, match="mode: value 'fan_geo'"):
        draws.variance_scaling(1.0, "fan_geo", "normal")
    with pytest.raises(ValueError, match="distribution: value 'cauchy'"):
        draws.variance_scaling(1.0, "fan_in", "cauchy")


def _draw_shapes(jaxpr) -> list[tuple]:
    """The shapes of every ``random_bits`` in ``jaxpr`` and its sub-jaxprs."""
    shapes = []
    for e in jaxpr.eqns:
        if e.primitive.name == "random_bits":
            shapes.append(e.outvars[0].aval.shape)
        for v in e.params.values():
            for sub in v if isinstance(v, (list, tuple)) else [v]:
                inner = getattr(sub, "jaxpr", sub)
                if hasattr(inner, "eqns"):
                    shapes += _draw_shapes(inner)
    return shapes


@pytest.mark.parametrize("network, senses", [("raidjax", "raidjax"), ("reference", "reference")])
def test_the_networks_draw_flat(network, senses):
    """Every draw of the networks' initial weights (2 seeds vmapped, as the trainers run them) and of
    a sampled action is one vector per seed: a layer left at flax's default initialiser, or a
    ``jax.random`` call on a matrix, draws a ``[seeds, rows, columns]`` block and fails here."""
    import raidjax
    from trainers.config import PRESETS
    from trainers.mapoca import make_networks
    from trainers.networks import sample_actions

    cfg = PRESETS["mapoca"]["cpu"].replace(network=network, senses=senses, hidden=8, layers=1,
                                           heads=4 if network == "reference" else 2)
    actor, critic = make_networks(cfg)
    params = raidjax.make_params(observation=senses, action_space=senses)
    shapes_only, _ = jax.eval_shape(raidjax.reset, jax.random.key(0), params)
    obs = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), shapes_only)  # traced below, never run
    init = lambda k: (actor.init(k, obs), critic.init(k, obs, jnp.zeros(obs.alive.shape, jnp.int32)))  # noqa: E731
    shapes = _draw_shapes(jax.make_jaxpr(jax.vmap(init))(KEYS[:2]).jaxpr)
    logits = jnp.zeros((2, 16, 3, obs.action_mask.shape[-1]))
    alive = jnp.ones((2, 16, 3), bool)
    shapes += _draw_shapes(jax.make_jaxpr(jax.vmap(lambda k, x, a: sample_actions(k, x, a)))(KEYS[:2], logits,
                                                                                           alive).jaxpr)
    assert len(shapes) > 5 and all(len(s) <= 2 for s in shapes), shapes
