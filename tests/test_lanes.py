"""The lane layout (``raidjax.lanes``): its helpers equal the jnp operations they replace, and the
step's ``vmap`` rule (arena axis last) gives the state one arena's step gives, whether the content
is shared or per arena, for one arena alone, and under a second ``vmap``: every integer and flag
bit for bit, every float within an ulp or two (XLA:CPU vectorises the arenas' loop by their count,
so on some CPUs a float rounds apart: GAME.md, "Determinism"). This is the
check of the step's whole lane program (``raidjax.phases.advance_lanes``, in the schedule the
backend runs); test_lane_functions.py checks each of its parts in the plain schedule."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import ACTION_HEURISTIC, CAST_1, NOOP, acts, run, scenario

import raidjax
from raidjax import lanes
from raidjax.types import FORWARD


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(0)
    # Values on a coarse grid so that ties occur (argmin must keep jnp's first index).
    x = jnp.asarray(rng.integers(0, 4, (5, 3, 7)).astype(np.float32))
    idx = jnp.asarray(rng.integers(0, 5, (3, 7)), jnp.int32)
    mask = jnp.asarray(rng.random((5, 3, 7)) < 0.3)
    return x, idx, mask


def test_pick_is_a_gather_along_the_leading_axis(data):
    x, idx, _ = data
    want = jnp.take_along_axis(x, idx[None], axis=0)[0]
    np.testing.assert_array_equal(lanes.pick(x, idx), want)
    # Rows past the end read the last one, as jnp.take(mode="clip").
    np.testing.assert_array_equal(lanes.pick(x, jnp.full((3, 7), 9)), x[-1])


def test_argmin_first_true_and_folds_equal_jnp(data):
    x, _, mask = data
    for axis in (0, 1):
        np.testing.assert_array_equal(lanes.argmin(x, axis), jnp.argmin(x, axis))
        np.testing.assert_array_equal(lanes.total(x, axis), jnp.sum(x, axis))
        np.testing.assert_array_equal(lanes.any_(mask, axis), jnp.any(mask, axis))
        np.testing.assert_array_equal(lanes.fold(jnp.maximum, x, axis), jnp.max(x, axis))
    np.testing.assert_array_equal(lanes.first_true(mask), jnp.argmax(mask, 0))
    np.testing.assert_array_equal(lanes.cumsum(mask), jnp.cumsum(mask, 0))
    np.testing.assert_array_equal(lanes.total(mask), jnp.sum(mask, 0))
    np.testing.assert_array_equal(lanes.one_hot(jnp.array([[2, 0]]), 3, axis=1),
                                  jax.nn.one_hot(jnp.array([[2, 0]]), 3, dtype=bool).transpose(0, 2, 1))


def test_materialize_returns_its_input_in_either_schedule():
    tree = {"a": jnp.arange(3.0), "b": jnp.array([True, False])}

    @jax.jit
    def gated(t, flag):
        return lanes.materialize(lanes.Schedule(flag > 0), t)

    for out in (lanes.materialize(lanes.PLAIN, tree), gated(tree, jnp.int32(1))):
        np.testing.assert_array_equal(out["a"], tree["a"])
        np.testing.assert_array_equal(out["b"], tree["b"])


def test_materialize_passes_the_leaves_of_since_by_the_conditional():
    """Leaves that are the very arrays of ``since`` come back as they are (no copy); the others go
    through the conditional, values unchanged."""
    seen = {}

    @jax.jit
    def gated(x, flag):
        y = x * 2.0
        out = lanes.materialize(lanes.Schedule(flag > 0), {"x": x, "y": y}, since=(x,))
        seen["kept"], seen["new"] = out["x"] is x, out["y"] is y
        return out

    out = gated(jnp.arange(3.0), jnp.int32(1))
    assert seen == {"kept": True, "new": False}
    np.testing.assert_array_equal(out["y"], [0.0, 2.0, 4.0])
    assert "conditional" in gated.lower(jnp.arange(3.0), jnp.int32(1)).as_text("hlo")


def test_computed_returns_fn_and_passes_its_arguments_by():
    """Values computed inside the conditional come back unchanged; an output that is one of ``fn``'s
    arguments is the very same array (forwarded by the conditional, no copy), and ``fn`` runs once."""
    seen = {"calls": 0}

    def fn(x):
        seen["calls"] += 1
        return {"x": x, "y": x * 2.0, "n": jnp.sum(x > 0)}

    @jax.jit
    def gated(x, flag):
        out = lanes.computed(lanes.Schedule(flag > 0), fn, x)
        seen["kept"] = out["x"] is x
        return out

    out = gated(jnp.arange(3.0), jnp.int32(1))
    assert seen == {"calls": 1, "kept": True}
    np.testing.assert_array_equal(out["y"], [0.0, 2.0, 4.0])
    assert int(out["n"]) == 2
    hlo = gated.lower(jnp.arange(3.0), jnp.int32(1)).as_text("hlo")
    assert "conditional" in hlo
    # The plain schedule is a plain call.
    np.testing.assert_array_equal(lanes.computed(lanes.PLAIN, lambda: jnp.arange(2.0) + 1.0), [1.0, 2.0])


def test_if_any_runs_fn_only_when_some_lane_needs_it():
    """``fn`` here gives non-zero values even where ``pred`` is false, so zeros show it was skipped."""
    fast = lanes.Schedule(jnp.bool_(True))
    f = jax.jit(lambda pred, x: lanes.if_any(fast, pred, lambda x: (x + 1.0, x > 0), x))
    x = jnp.array([1.0, 2.0])
    out = f(jnp.array([False, True]), x)
    np.testing.assert_array_equal(out[0], [2.0, 3.0])
    np.testing.assert_array_equal(out[1], [True, True])
    skipped = f(jnp.array([False, False]), x)
    np.testing.assert_array_equal(skipped[0], [0.0, 0.0])
    np.testing.assert_array_equal(skipped[1], [False, False])
    # In the plain schedule fn always runs.
    np.testing.assert_array_equal(lanes.if_any(lanes.PLAIN, jnp.array([False]), lambda: x + 1.0), [2.0, 3.0])
    # Under a vmap that batches the program (lanes.batch_level) fn runs, with no conditional.
    batched = jax.jit(jax.vmap(lambda p, v: lanes.if_any(fast, p, lambda v: v + 1.0, v)))
    np.testing.assert_array_equal(batched(jnp.array([False, False]), x), [2.0, 3.0])
    assert "conditional" not in batched.lower(jnp.array([False, False]), x).as_text("hlo")


def test_batch_level_runs_fast_as_python_under_disable_jit():
    """Eagerly, ``fast`` runs on the concrete values it is given (its conditionals take one branch
    in Python); under ``jit`` it is traced into the program."""
    seen = []
    fast_schedule = lanes.Schedule(jnp.bool_(True))

    def fast(x):
        seen.append(isinstance(x, jax.core.Tracer))
        return x * 2.0

    x = jnp.arange(3.0)
    with jax.disable_jit():
        np.testing.assert_array_equal(lanes.batch_level(fast_schedule, fast, lambda x: x * 2.0, x), [0.0, 2.0, 4.0])
    assert seen == [False]
    program = jax.jit(lambda x: lanes.batch_level(fast_schedule, fast, lambda x: x * 2.0, x))
    np.testing.assert_array_equal(program(x), [0.0, 2.0, 4.0])
    assert seen == [False, True]  # jitted: traced into the program


def _fights():
    """Four arenas in mid-fight (live projectiles, casts), different content and actions (PT-HR in
    the first, learners in the others). In the tested decision the second arena's players land
    instant skills and the fourth's basic attacks: hit groups a batch of the other arenas alone
    would skip (``lanes.if_any``)."""
    fights = (  # skill range, content overrides, decisions played before the tested one
        (5.0, {}, 6),
        (13.0, {"armor": 30, "skill1.projectile_speed": 0.0}, 14),
        (9.0, {"skill1.cool_time": 1.0}, 6),
        (13.0, {"attack_power": 40, "attack_range": 10, "spell_power": 0}, 10),
    )
    contents, states = [], []
    for r, extra, n in fights:
        c = raidjax.make_params(skill_range=r, **extra)
        s = scenario(c, players=((-3, -4), (0, -4.5), (3, -4)), boss=(0.0, 0.0))
        contents.append(c)
        states.append(run(s, c, acts(ACTION_HEURISTIC), n)[0])
    actions = jnp.stack([acts(ACTION_HEURISTIC), acts(CAST_1, NOOP, FORWARD), acts(NOOP), acts(FORWARD)])
    return contents, states, actions


def stacked(trees):
    return jax.tree.map(lambda *x: jnp.stack(x), *trees)


def assert_same_step(a, b):
    """Integers and flags (alive, casting, charges, the projectile pool's slots, outcomes) bit for bit;
    floats within 1e-6 (positions of a few units: a few ulps), since XLA:CPU may vectorise the
    arenas' loop differently for another lane count (GAME.md, "Determinism"; on an AVX2 CPU a
    player's position in the second fight differs by one ulp). A wrong lane, a lost or broadcast
    lane axis or a broken rule changes a game by far more."""
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        x, y = np.asarray(x), np.asarray(y)
        assert x.dtype == y.dtype and x.shape == y.shape, (x.dtype, x.shape, y.dtype, y.shape)
        if np.issubdtype(x.dtype, np.floating):
            np.testing.assert_allclose(x, y, rtol=1e-6, atol=1e-6)
        else:
            np.testing.assert_array_equal(x, y)


def test_batched_runs_the_lane_function_once_on_the_lanes():
    """``lanes.batched``: under ``vmap`` the lane function runs once on the lanes (arena axis last,
    batched at any axis, unbatched arguments as one lane), told the XLA:CPU schedule on the CPU
    backend. ``custom_vmap`` first traces one arena's call (the cost DESIGN.md measures); JAX keeps
    that trace, so a later one-arena program of the same shapes does not trace again."""
    shapes = []

    def f(a, b, fast=False):  # a lane function: leading axis of size 3, then any lanes
        shapes.append((a.shape, b.shape, fast))
        return a + b, a * b

    on_cpu = jax.default_backend() == "cpu"
    g = lanes.batched(f)
    a, b = jnp.arange(12.0).reshape(4, 3), jnp.arange(3.0) + 10  # four arenas; b unbatched
    s, m = jax.jit(jax.vmap(g, in_axes=(1, None), out_axes=1))(a.T, b)
    np.testing.assert_array_equal(s.T, a + b)
    np.testing.assert_array_equal(m.T, a * b)
    if not on_cpu:  # elsewhere vmap batches the plain program
        return
    assert shapes == [((3,), (3,), True), ((3, 4), (3, 1), True)]  # then lanes last, b a single lane
    np.testing.assert_array_equal(jax.jit(g)(a[0], b)[0], a[0] + b)  # one arena: the trace is kept
    assert len(shapes) == 2
    with jax.disable_jit():
        np.testing.assert_array_equal(g(a[1], b)[1], a[1] * b)
    assert shapes[2:] == [((3,), (3,), True)]
    # Nested vmaps (a learner's runs, each with its arenas) add one lane each, innermost first: the
    # lane function runs on every arena of every group (after the inner vmap's lanes are traced).
    shapes.clear()
    groups = a.reshape(2, 2, 3)  # two groups of two arenas
    s, m = jax.jit(jax.vmap(jax.vmap(g, in_axes=(0, None)), in_axes=(0, None)))(groups, b)
    np.testing.assert_array_equal(s, groups + b)
    np.testing.assert_array_equal(m, groups * b)
    assert shapes == [((3, 2), (3, 1), True), ((3, 2, 2), (3, 1, 1), True)]
    # Derivatives are those of the plain program.
    shapes.clear()
    grad = jax.grad(lambda a: jnp.sum(jax.vmap(g, in_axes=(0, None))(a, b)[1]))(a)
    np.testing.assert_array_equal(grad, jnp.broadcast_to(b, a.shape))
    assert all(not fast for *_, fast in shapes)


def test_vmapped_step_equals_single_steps():
    contents, states, actions = _fights()
    keys = jax.random.split(jax.random.key(4), 4)
    single = [raidjax.step(keys[i], states[i], actions[i], contents[i]) for i in range(4)]
    # The step exercises what it should: the players' only damage is their instant missiles in the
    # second arena and their basic attacks in the fourth (their missiles do none: spell power 0).
    assert float(single[1][4]["damage_dealt"].sum()) > 0
    assert float(single[3][4]["damage_dealt"].sum()) > 0
    # On the host: indexing device arrays would compile a slice program per leaf and arena.
    out = jax.device_get(jax.jit(jax.vmap(raidjax.step))(keys, stacked(states), actions, stacked(contents)))
    for i in range(4):
        mine = jax.tree.map(lambda x, i=i: x[i], out)
        assert_same_step(mine, single[i])  # observation, state, reward, done, info
    # One arena as one lane (a batch of 1): the lane program must not drop or broadcast its lane axis.
    alone = jax.device_get(jax.jit(jax.vmap(raidjax.step))(keys[:1], stacked(states[:1]), actions[:1],
                                                           stacked(contents[:1])))
    assert_same_step(jax.tree.map(lambda x: x[0], alone)[1:], single[0][1:])
    # One content shared by every arena (params unbatched: it broadcasts along the lanes).
    shared = jax.jit(jax.vmap(raidjax.step, (0, 0, 0, None)))(keys, stacked(states), actions, contents[0])
    per_arena = jax.jit(jax.vmap(raidjax.step))(keys, stacked(states), actions, stacked([contents[0]] * 4))
    assert_same_step(shared[1:], per_arena[1:])


def test_nested_vmap_equals_the_flat_one():
    """Two groups of two arenas under ``vmap(vmap(step))`` play as the four arenas of one ``vmap``
    (the flat program is ``test_vmapped_step_equals_single_steps``'s, read from the
    compilation cache)."""
    contents, states, actions = _fights()
    keys = jax.random.split(jax.random.key(5), 4)
    flat = jax.jit(jax.vmap(raidjax.step))(keys, stacked(states), actions, stacked(contents))
    nest = lambda t: jax.tree.map(lambda x: x.reshape((2, 2) + x.shape[1:]), t)  # noqa: E731
    nested = jax.jit(jax.vmap(jax.vmap(raidjax.step)))(nest(keys), nest(stacked(states)), nest(actions),
                                                        nest(stacked(contents)))
    assert_same_step(jax.tree.map(lambda x: x.reshape((4,) + x.shape[2:]), nested)[1:], flat[1:])
    # The groups' arenas are lanes of one lane program, which keeps the conditionals that skip work
    # no arena needs (lanes.if_any; on XLA:CPU): as many as the flat program's.
    args = (keys, stacked(states), actions, stacked(contents))
    count = lambda f, *a: jax.jit(f).lower(*a).as_text().count("stablehlo.case")  # noqa: E731
    n_flat = count(jax.vmap(raidjax.step), *args)
    assert count(jax.vmap(jax.vmap(raidjax.step)), *map(nest, args)) == n_flat
    assert (n_flat > 0) == (jax.default_backend() == "cpu")
