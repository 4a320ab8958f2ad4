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
