"""Every lane function (``raidjax.lanes.lane_function``) gives, lane by lane, what it gives one arena.

The calls are recorded from real decisions (``recording`` around eager steps of three arenas with
different content, policies and moments of a fight, in the plain schedule, which runs every piece of
work), so every marked function is checked on the inputs the game gives it (the whole step, which
test_lanes.py checks, aside). Each one then runs with 0, 1 and 3 trailing lanes (the three arenas'
inputs stacked last) and is compared with ``jax.vmap`` of its one-arena call over the last axis. A
function that reduces over ``axis=-1``, indexes with ``.at[]`` on a lane, or gathers along the wrong
axis fails here and names itself; ``test_a_planted_break_is_caught`` shows that it would.
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raidjax
from raidjax import env, lanes, phases

# Called only where the game's state asks for it; the recorded decisions below reach every one.
_SITUATIONS = (  # (players, skill range, policy, decisions played before the recorded one)
    ("mage", 13.0, raidjax.policies.heuristic, 40),
    (("warrior", "mage", "priest"), 9.0, raidjax.policies.random, 25),
    (("priest", "warrior", "mage"), 17.0, raidjax.policies.random, 60),
)


@contextlib.contextmanager
def recording():
    """Collect the calls of every registered lane function made with concrete arrays (run the game
    under ``jax.disable_jit()``): yields the list of ``(name, args, kwargs)``. Each function is
    replaced while recording in every module of the package that holds it (its own, and those that
    imported it by name), where the calls look it up."""
    calls, patched = [], []

    def recorder(name, fn):
        @functools.wraps(fn)
        def recorded(*args, **kwargs):
            if not any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves((args, kwargs))):
                calls.append((name, args, kwargs))
            return fn(*args, **kwargs)
        return recorded

    by_function = {id(fn): name for name, fn in lanes.REGISTRY.items()}
    for module in [m for n, m in sys.modules.items() if n == "raidjax" or n.startswith("raidjax.")]:
        for attr, fn in list(vars(module).items()):  # also where a module imported the function by name
            if id(fn) in by_function and callable(fn):
                patched.append((module, attr, fn))
                setattr(module, attr, recorder(by_function[id(fn)], fn))
    try:
        yield calls
    finally:
        for module, attr, fn in patched:
            setattr(module, attr, fn)


def _record_three_arenas() -> dict[str, list[tuple]]:
    """``{function name: [(args, kwargs) of its first call in arena 0, 1, 2]}`` for the functions
    every arena called."""
    raidjax.use_recommended_xla_flags()
    step = jax.jit(raidjax.step)
    per_arena = []
    for i, (players, rng, policy, n) in enumerate(_SITUATIONS):
        params = raidjax.make_params(players=players, skill_range=rng)
        obs, state = raidjax.reset(jax.random.key(i), params)
        for t in range(n):
            act = policy(jax.random.key(1000 * i + t), obs, state, params)
            obs, state, *_ = step(jax.random.key(2000 * i + t), state, act, params)
        act = policy(jax.random.key(7 + i), obs, state, params)
        # The plain schedule (lanes.PLAIN) runs all of the work, on the values given.
        plain = lambda *a: phases.advance_lanes(*a)  # noqa: E731 (looked up while recording)
        with jax.disable_jit(), recording() as calls, pytest.MonkeyPatch.context() as mp:
            mp.setattr(env, "advance", plain)
            raidjax.step(jax.random.key(9 + i), state, act, params)
        first = {}
        for name, args, kwargs in calls:
            first.setdefault(name, (args, kwargs))
        per_arena.append(first)
    return {name: [a[name] for a in per_arena] for name in per_arena[0] if all(name in a for a in per_arena)}


@pytest.fixture(scope="module")
def recorded():
    return _record_three_arenas()


def _is_array(x) -> bool:
    return isinstance(x, jax.Array | np.ndarray)


def _arguments(fn, call: tuple) -> dict:
    """``call = (args, kwargs)`` as ``{parameter name: value}``."""
    bound = inspect.signature(fn).bind(*call[0], **call[1])
    return dict(bound.arguments)


def check_lanes(fn, calls: list[tuple]) -> str | None:
    """``None`` if ``fn`` on 0, 1 and 3 trailing lanes equals ``jax.vmap`` of its one-arena call over
    the last axis (``calls``: three one-arena ``(args, kwargs)``; their arrays are stacked into 3
    lanes, but for ``lane_function``'s ``shared`` arguments), else what differed."""
    meta = getattr(fn, "lane_args", {})
    told = {k: v for k, v in ((meta.get("lane_shape"), tuple), (meta.get("lane_count"), len)) if k}
    shared = set(meta.get("shared", ()))
    per_call = [_arguments(fn, c) for c in calls]
    names = list(per_call[0])

    def run(arguments: dict, lane_shape: tuple):
        return fn(**{**arguments, **{k: how(lane_shape) for k, how in told.items()}})

    def lanes_of(name, make):  # ``make(*values of the three calls)`` for a lane argument's arrays
        if name in shared or name in told:
            return per_call[0][name]
        return jax.tree.map(lambda *xs: make(*xs) if _is_array(xs[0]) else xs[0], *(a[name] for a in per_call))

    three = {n: lanes_of(n, lambda *xs: jnp.stack(xs, -1)) for n in names}
    one = {n: lanes_of(n, lambda x, *_: x[..., None]) for n in names}
    leaves, treedef = jax.tree.flatten(three)
    lane_leaves = set()
    for n in names:  # which leaves of ``three`` carry the lanes
        if n not in shared and n not in told:
            lane_leaves |= {id(x) for x in jax.tree.leaves(three[n]) if _is_array(x)}
    at = [i for i, x in enumerate(leaves) if id(x) in lane_leaves]

    def from_lanes(*xs):
        full = list(leaves)
        for i, x in zip(at, xs, strict=True):
            full[i] = x
        return jax.tree.unflatten(treedef, full)

    want3 = jax.vmap(lambda *xs: run(from_lanes(*xs), ()), in_axes=-1, out_axes=-1)(*[leaves[i] for i in at])
    for n_lanes, arguments, want in ((3, three, want3), (1, one, jax.tree.map(lambda x: x[..., :1], want3)),
                                     (0, per_call[0], jax.tree.map(lambda x: x[..., 0], want3))):
        got = run(arguments, (n_lanes,) if n_lanes else ())
        got_leaves, want_leaves = jax.tree.leaves(got), jax.tree.leaves(want)
        if len(got_leaves) != len(want_leaves):
            return f"{n_lanes} lanes: {len(got_leaves)} outputs, vmap gives {len(want_leaves)}"
        for i, (g, w) in enumerate(zip(got_leaves, want_leaves, strict=True)):
            try:
                g = jnp.broadcast_to(g, w.shape)  # a lane-free output broadcasts over the lanes
            except ValueError:
                return f"{n_lanes} lanes: output {i} has shape {list(jnp.shape(g))}, vmap gives {list(w.shape)}"
            if not np.array_equal(np.asarray(g), np.asarray(w), equal_nan=True):
                return f"{n_lanes} lanes: output {i} differs from vmap's (shape {list(w.shape)})"
    return None


def test_every_lane_function_is_recorded(recorded):
    """The recorded decisions reach every marked function, so the next test checks them all."""
    assert set(lanes.REGISTRY) - set(recorded) == set()


# The step's whole lane program, the decision's loop of sub-steps: test_lanes.py checks it against
# one arena's step (integers bit for bit, floats within 1e-6) at 4 lanes, 2 x 2 and 1, in the
# schedule the backend runs (on the CPU the fast one); in the plain schedule test_transforms'
# shard_map test checks it at 2 lanes.
# Its sub-step and every part of that are checked here in the plain schedule at 0, 1 and 3 lanes.
# Compiled once per lane count here, it cost 39 s of the suite.
WHOLE_STEP = f"{phases.advance_lanes.__module__}.{phases.advance_lanes.__qualname__}"
assert WHOLE_STEP in lanes.REGISTRY, WHOLE_STEP


@pytest.mark.parametrize("name", sorted(set(lanes.REGISTRY) - {WHOLE_STEP}))
def test_lane_function_equals_vmap_of_one_arena(recorded, name):
    if name not in recorded:
        pytest.fail(f"{name} was not called in every recorded arena")
    with jax.disable_jit():  # op by op, as a newcomer's function runs in a notebook
        problem = check_lanes(lanes.REGISTRY[name], recorded[name])
    assert problem is None, f"{name}: {problem}"


def test_a_planted_break_is_caught():
    """A lane function that reduces over its last axis (the lanes, once there are any) is told apart."""

    @lanes.lane_function
    def strongest(hp):  # hp: float32[U, ...]; meant: the strongest unit's hp, lane by lane
        return jnp.max(hp, axis=-1)

    @lanes.lane_function
    def strongest_right(hp):
        return lanes.fold(jnp.maximum, hp)

    try:
        calls = [((jnp.asarray([3.0, 1.0, 2.0]) * k,), {}) for k in (1, 2, 3)]
        problem = check_lanes(strongest, calls)
        assert problem is not None and ("differs" in problem or "shape" in problem)
        assert check_lanes(strongest_right, calls) is None
    finally:
        for f in ("strongest", "strongest_right"):
            lanes.REGISTRY.pop(f"{__name__}.test_a_planted_break_is_caught.<locals>.{f}", None)


def test_recording_sees_only_concrete_calls():
    """Traced calls (inside ``jit``) are not recorded: only values a test can replay are."""
    with recording() as calls:
        jax.jit(lambda x: lanes.REGISTRY["raidjax.movement.norm"](x, 0))(jnp.ones((2, 3)))
    assert calls == []
