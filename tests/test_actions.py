"""Actions checked when traced: shape ``[P]`` and an integer dtype, else a one-line error before
compiling; ids outside ``[0, ACTION_HEURISTIC]`` are no-ops."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import KEY, RESET, STEP

import raidjax
from raidjax.types import FORWARD, NOOP


@pytest.mark.parametrize("actions,message", [
    (jnp.zeros((3, 1), jnp.int32), r"actions: shape \[3, 1\]; allowed: \[3\], one action id per player"),
    (jnp.zeros((4,), jnp.int32), r"actions: shape \[4\]; allowed: \[3\]"),
    (jnp.zeros((3,), jnp.float32), r"actions: dtype float32; allowed: an integer dtype"),
])
def test_wrong_shape_or_dtype_is_refused_naming_it(ref_params, actions, message):
    _, state = RESET(KEY, ref_params)
    for fn in (raidjax.step, jax.jit(raidjax.step), raidjax.step_autoreset):
        with pytest.raises(ValueError, match=message):
            fn(KEY, state, actions, ref_params)


def test_out_of_range_ids_are_no_ops(ref_params):
    _, state = RESET(KEY, ref_params)
    out_noop = STEP(KEY, state, jnp.full((3,), NOOP, jnp.int32), ref_params)
    out_odd = STEP(KEY, state, jnp.array([11, 12, -1], jnp.int32), ref_params)
    for a, b in zip(jax.tree.leaves(out_noop), jax.tree.leaves(out_odd), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    moved = STEP(KEY, state, jnp.full((3,), FORWARD, jnp.int32), ref_params)  # the comparison can fail
    assert not np.array_equal(np.asarray(moved[1].pos), np.asarray(out_noop[1].pos))


def test_spaces_match_what_reset_and_step_return(ref_params):
    sp = raidjax.spaces(ref_params)
    assert (sp.n_players, sp.n_actions, sp.action.n, sp.heuristic_action) == (3, 10, 10, 10)
    obs, state = RESET(KEY, ref_params)
    for name, box in sp.observation.items():
        leaf = getattr(obs, name)
        assert box.shape == leaf.shape and box.dtype == leaf.dtype and bool(box.contains(leaf)), name
    assert sp.flat_observation.shape == obs.flat().shape
    assert bool(sp.action.contains(sp.action.sample(KEY))) and not bool(sp.action.contains(jnp.int32(10)))
    mask = raidjax.action_mask(state, ref_params)
    assert mask.shape == (3, sp.n_actions) and np.array_equal(np.asarray(mask), np.asarray(obs.action_mask))
    two = raidjax.make_params(players=["mage", "mage"])
    assert raidjax.spaces(two).n_players == 2 and raidjax.spaces(two).observation["teammates"].shape[:2] == (2, 1)
    with pytest.raises(ValueError, match="one arena's params"):
        raidjax.spaces(jax.tree.map(lambda x: x[None], ref_params))
