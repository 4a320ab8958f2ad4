"""The lane layout: the sub-step's arrays carry the arena axis last, so work runs over wide vectors.

Under ``jax.vmap`` the batch axis becomes the *first* axis of every array: a pool of ``[arenas, 16,
4]`` has its small unit axis innermost, and XLA:CPU spends its time on 4-wide loops, reductions over
that axis and gathers. The sub-step (``raidjax.env``'s ``advance``) is instead written for arrays
whose leading axes are the game's own (units, slots, pool slots, components) and whose trailing
axes, the *lanes*, are any number of batch axes, including none. Every elementwise operation then
runs over the arenas, and reductions over units or slots are a few vector operations.

One arena's ``State`` and ``Params`` already are lane arrays with no lanes (a unit's position
``pos[u]`` is ``float32[2]``). ``batched`` gives a lane function a ``vmap`` rule that moves the arena
axis last instead of first, so ``jax.vmap(raidjax.step)`` runs the lane program over the arenas.
Under it, ``with_vmap_rule`` gives any function a ``vmap`` rule without tracing the function where
only the rule runs (``raidjax.pcg``'s measurements use it too).

Helpers (shapes: ``x[N, *R, *L]`` with ``L`` the lanes; indices are lane arrays): ``pick`` (gather
along the leading axis), ``one_hot``, ``argmin``, ``first_true`` and reductions over leading axes as
folds of elementwise operations (``total``, ``any_``, ``fold``, ``cumsum``).

On XLA:CPU two more shape the compiled sub-step: ``computed`` (and ``materialize``) write a value
into memory once instead of letting XLA recompute it inside every consumer, and ``if_any`` skips
work that no arena of the batch needs this sub-step (hit groups nobody lands, the scripted moves of a
learner's batch).
"""

from __future__ import annotations

import contextlib
import functools

import jax
import jax.extend.core as jex_core
import jax.numpy as jnp
from jax.custom_batching import custom_vmap
from jax.interpreters import ad, batching, mlir

# Every lane function of the game, by qualified name (``lane_function``); tests/test_lane_functions.py runs
# each with 0, 1 and 3 lanes against ``jax.vmap`` of its one-arena call.
REGISTRY: dict[str, object] = {}
# While ``recording``: the calls of registered functions, ``(name, args, kwargs)`` (concrete values).
_RECORDS: list = [None]


def lane_function(fn=None, *, lane_shape: str | None = None, lane_count: str | None = None,
                  shared: tuple[str, ...] = ()):
    """Mark ``fn`` as a lane function (the layout's rules in CONTRIBUTING, "Write game code in the
    lane layout"): its arrays carry the game's axes first and any number of lane axes last, and it
    gives, lane by lane, what it gives one arena. Registered in ``REGISTRY``; the function is returned
    unchanged but for recording its calls while ``recording`` is active (checked by the test suite).

    ``lane_shape`` / ``lane_count``: the name of an argument that holds the lanes' shape (a tuple)
    or their number (an ``int``), for a function that must be told them. ``shared``: arguments
    whose arrays carry no lanes (the same for every arena, such as a group's die numbers).
    """
    if fn is None:
        return functools.partial(lane_function, lane_shape=lane_shape, lane_count=lane_count, shared=shared)
    name = f"{fn.__module__}.{fn.__qualname__}"

    @functools.wraps(fn)
    def marked(*args, **kwargs):
        calls = _RECORDS[-1]
        if calls is not None and not any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves((args, kwargs))):
            calls.append((name, args, kwargs))
        return fn(*args, **kwargs)

    marked.lane_args = {"lane_shape": lane_shape, "lane_count": lane_count, "shared": tuple(shared)}
    REGISTRY[name] = marked
    return marked


@contextlib.contextmanager
def recording():
    """Collect the calls of every ``lane_function`` made with concrete arrays (run the game under
    ``jax.disable_jit()``): yields the list of ``(name, args, kwargs)``."""
    _RECORDS.append([])
    try:
        yield _RECORDS[-1]
    finally:
        _RECORDS.pop()


def on_cpu() -> bool:
    """Whether the lane program and its XLA:CPU scheduling (``materialize``, ``computed``, ``if_any``,
    the pool's blocks) apply: the one place that asks which backend runs. Measured: the lanes pay on
    XLA:CPU only; elsewhere the plain vmapped program runs (docs/DESIGN.md)."""
    return jax.default_backend() == "cpu"


def pick(x: jax.Array, idx: jax.Array) -> jax.Array:
    """``x[idx]`` along the leading axis, lane by lane, as ``N - 1`` selects (no gather).

    Args:
        x: ``[N, *R]``; idx: integer array broadcastable against ``x[0]`` (values past ``N - 1``
            read the last row, as ``mode="clip"`` does).

    Returns:
        ``broadcast(idx, x[0])``-shaped array of ``x``'s dtype.
    """
    n = x.shape[0]
    out = jnp.broadcast_to(x[n - 1], jnp.broadcast_shapes(idx.shape, x.shape[1:]))
    for i in range(n - 1):
        out = jnp.where(idx == i, x[i], out)
    return out


def one_hot(idx: jax.Array, n: int, axis: int) -> jax.Array:
    """``bool``: ``idx`` with a new axis of size ``n`` inserted at ``axis`` (counted from the front),
    true where the new index equals ``idx``."""
    ar = jnp.arange(n, dtype=idx.dtype).reshape((n,) + (1,) * (idx.ndim - axis))
    return jnp.expand_dims(idx, axis) == ar


def argmin(x: jax.Array, axis: int = 0) -> jax.Array:
    """``int32``: the first index of the smallest value along ``axis`` (``jnp.argmin``'s ties)."""
    best = jax.lax.index_in_dim(x, 0, axis, keepdims=False)
    idx = jnp.zeros(best.shape, jnp.int32)
    for i in range(1, x.shape[axis]):
        xi = jax.lax.index_in_dim(x, i, axis, keepdims=False)
        better = xi < best
        best, idx = jnp.where(better, xi, best), jnp.where(better, i, idx)
    return idx


def first_true(x: jax.Array) -> jax.Array:
    """``int32``: the first index along the leading axis where ``x`` is true, 0 where none is."""
    idx = jnp.zeros(x.shape[1:], jnp.int32)
    for i in reversed(range(x.shape[0])):
        idx = jnp.where(x[i], i, idx)
    return idx


def batched(fn, full: tuple[int, ...] = (), out_like=None):
    """``fn`` (a lane function of pytrees) with a ``vmap`` rule that puts the arena axis last.

    ``fn(*args)`` must work on lane arrays with any trailing lanes and return lane arrays.
    Under ``jax.vmap`` the rule moves every batched argument's axis to the end; an unbatched
    argument gets a trailing lane of size 1 (it broadcasts against the arenas), or, at the
    positions ``full`` (arguments whose shape the outputs keep, such as a carried state), is
    broadcast to the batch. ``fn`` runs once on the lanes and every output's axis moves back to the
    front. The lane call has the same rule, so nested ``vmap``s (a learner's runs, each with its
    arenas) add one lane each: the arenas of every run are lanes of one lane program, which skips
    the work that no arena of any run needs (``if_any``) as a single batch of arenas does.
    ``out_like`` as in ``with_vmap_rule``: given, one arena's ``fn`` is traced only where it runs.
    """

    # Traced through ``jax.jit``: JAX keeps the traced program per argument shapes, so every later
    # program of the process that runs ``fn`` on the same shapes reuses it instead of tracing the
    # whole sub-step again; XLA inlines the call, so the compiled program is the same.
    traced = jax.jit(fn)

    def rule(axis_size, in_batched, *args):
        if not on_cpu():
            return jax.vmap(traced, in_axes=jax.tree.map(lambda b: 0 if b else None, tuple(in_batched)))(*args)

        def to_lanes(x, is_batched, width):
            return jnp.moveaxis(x, 0, -1) if is_batched else jnp.broadcast_to(x[..., None], x.shape + (width,))

        lanes = tuple(jax.tree.map(functools.partial(to_lanes, width=axis_size if i in full else 1), a, b)
                      for i, (a, b) in enumerate(zip(args, in_batched, strict=True)))
        return jax.tree.map(lambda x: jnp.moveaxis(x, -1, 0), lane_call(*lanes))

    lane_call = with_vmap_rule(traced, rule, out_like)
    return functools.wraps(fn)(lane_call)


def with_vmap_rule(fn, rule, out_like=None):
    """``fn`` with ``rule`` as its ``vmap`` rule, as ``jax.custom_batching.custom_vmap`` gives, except
    that ``fn`` is traced only where it runs unbatched: ``custom_vmap`` traces it at every call,
    although under ``vmap`` only the rule runs (for the sub-step, a second whole trace of the game in
    a process that plays only vmapped games, about 1 s on 2 cores).

    Args:
        fn: a function of pytrees of arrays returning a pytree of arrays (hashable: its identity).
        rule: ``rule(axis_size, in_batched, *args)``, the arguments' batched leaves on axis 0 and
            ``in_batched`` the arguments' pytrees of ``bool``; returns ``fn``'s outputs with a leading
            axis of ``axis_size`` on every leaf.
        out_like: ``out_like(*args)`` returns arrays or ``jax.ShapeDtypeStruct``s with the shapes and
            dtypes (weak types included) of ``fn(*args)`` without running it; default
            ``jax.eval_shape(fn, *args)``, which traces ``fn``.

    Returns:
        A function of the same arguments and outputs as ``fn``.
    """
    out_like = out_like or functools.partial(jax.eval_shape, fn)

    def wrapped(*args):
        flat, in_tree = jax.tree.flatten(args)
        out_flat, out_tree = jax.tree.flatten(out_like(*args))
        avals = tuple(map(jax.typeof, out_flat))  # arrays and ShapeDtypeStructs alike, weak types kept
        return jax.tree.unflatten(out_tree, _vmap_rule_p.bind(*flat, call=(fn, rule, in_tree, out_tree, avals)))

    return wrapped


def _unbatched(*flat, call):
    fn, _, in_tree, _, _ = call
    return jax.tree.leaves(fn(*jax.tree.unflatten(in_tree, flat)))


def _batched(flat, dims, *, call):
    _, rule, in_tree, out_tree, _ = call
    size = next(x.shape[d] for x, d in zip(flat, dims, strict=True) if d is not None)  # None: not batched
    flat = [x if d is None else jnp.moveaxis(x, d, 0) for x, d in zip(flat, dims, strict=True)]
    in_batched = jax.tree.unflatten(in_tree, [d is not None for d in dims])
    out = jax.tree.leaves(rule(size, tuple(in_batched), *jax.tree.unflatten(in_tree, flat)))
    return out, [0] * out_tree.num_leaves


# ``with_vmap_rule``'s primitive: its output avals are ``call[4]``; run or lowered unbatched it calls
# ``fn``; under ``vmap`` its batching rule calls ``rule`` instead.
_vmap_rule_p = jex_core.Primitive("with_vmap_rule")
_vmap_rule_p.multiple_results = True
_vmap_rule_p.def_impl(_unbatched)
_vmap_rule_p.def_abstract_eval(lambda *_, call: call[4])
def _jvp(primals, tangents, *, call):
    """Forward-mode derivatives of ``fn`` itself (the rule only reorders the arenas' axes), so
    ``jax.jvp`` and ``jax.grad`` go through a function with a vmap rule; integer inputs get zero
    (``float0``) tangents."""
    tangents = [ad.instantiate_zeros(t) for t in tangents]
    _DIFFERENTIATED.append(True)  # batch_level: the plain program (custom_vmap has no reverse mode)
    # ``fn`` itself, not its ``jax.jit`` (``batched``'s ``traced``): jit keeps one trace per argument
    # shapes, and a forward trace made earlier in the process holds the scheduling conditionals,
    # which have no reverse mode.
    fn, *rest = call
    call = (getattr(fn, "__wrapped__", fn), *rest)
    try:
        return jax.jvp(lambda *flat: _unbatched(*flat, call=call), list(primals), tangents)
    finally:
        _DIFFERENTIATED.pop()


mlir.register_lowering(_vmap_rule_p, mlir.lower_fun(_unbatched, multiple_results=True))
batching.primitive_batchers[_vmap_rule_p] = _batched
ad.primitive_jvps[_vmap_rule_p] = _jvp


def select(pred: jax.Array, a, b):
    """``a`` where ``pred`` holds, ``b`` elsewhere, leaf by leaf (pytrees of the same structure;
    ``pred``, e.g. ``bool[...]`` per arena, broadcasts against every leaf as NumPy does)."""
    return jax.tree.map(lambda x, y: jnp.where(pred, x, y), a, b)


def fold(op, x: jax.Array, axis: int = 0) -> jax.Array:
    """``op`` applied left to right over the slices of ``x`` along ``axis`` (counted from the front).

    XLA:CPU loops element by element over a reduction of a leading axis; a fold is a few
    elementwise operations over the lanes instead (sums come out in index order).
    """
    out = jax.lax.index_in_dim(x, 0, axis, keepdims=False)
    for i in range(1, x.shape[axis]):
        out = op(out, jax.lax.index_in_dim(x, i, axis, keepdims=False))
    return out


def total(x: jax.Array, axis: int = 0) -> jax.Array:
    """Sum along a leading ``axis`` (a ``fold``; booleans count as ``int32``)."""
    return fold(jnp.add, x.astype(jnp.int32) if x.dtype == jnp.bool_ else x, axis)


def any_(x: jax.Array, axis: int = 0) -> jax.Array:
    """``jnp.any`` along a leading ``axis`` (a ``fold``)."""
    return fold(jnp.logical_or, x, axis)


def cumsum(x: jax.Array) -> jax.Array:
    """``int32`` running count or sum along the leading axis, in index order."""
    x = x.astype(jnp.int32) if x.dtype == jnp.bool_ else x
    out = [x[0]]
    for i in range(1, x.shape[0]):
        out.append(out[-1] + x[i])
    return jnp.stack(out)


# Whether a function with a vmap rule is being traced for its derivatives (``_jvp``).
_DIFFERENTIATED: list = [False]

# The gate of the sub-step being traced (see ``materialize``); None outside one.
_GATE: list = [None]


@contextlib.contextmanager
def gate(pred: jax.Array):
    """While tracing a sub-step: ``materialize`` branches on ``pred``, a scalar ``bool`` the compiler
    cannot evaluate (the sub-step loop's counter compared with 0), which is always true."""
    _GATE.append(pred)
    try:
        yield
    finally:
        _GATE.pop()


def _varying(tree) -> bool:
    """Whether a leaf of ``tree`` varies along a ``shard_map``'s manual mesh axes: there a
    conditional's branches must agree on it, which the scheduling conditionals below (a constant
    branch) do not; they are skipped, leaving the same values."""
    for x in jax.tree.leaves(tree):
        t = jax.typeof(x)
        if getattr(getattr(t, "manual_axis_type", None), "varying", None) or getattr(t, "vma", None):
            return True
    return False


def materialize(tree, since=None):
    """``tree`` (a pytree of arrays) unchanged, computed once into memory before its consumers run.

    XLA:CPU fuses an elementwise chain into every consumer and recomputes it there (per element of
    a reduction, per consumer); ``jax.lax.optimization_barrier`` does not stop that on CPU, a
    conditional does. Inside ``gate`` the values go through a ``lax.cond`` on the gate, which is
    always true; elsewhere, off the CPU backend (a GPU conditional would wait on the host) and when an
    outer ``vmap`` batches the gate, this changes nothing.

    ``since``: a pytree whose leaves are already in memory (the phase's input state); leaves of
    ``tree`` that are the very same arrays pass by the conditional, which would only copy them.
    """
    if _GATE[-1] is None or not on_cpu() or _varying(tree):
        return tree
    leaves, treedef = jax.tree.flatten(tree)
    kept = {id(x) for x in jax.tree.leaves(since)}
    new = [i for i, x in enumerate(leaves) if id(x) not in kept]
    # The other branch must differ, or XLA merges the two and drops the conditional.
    done = jax.lax.cond(_GATE[-1], lambda t: t, lambda t: [jnp.zeros_like(x) for x in t], [leaves[i] for i in new])
    for i, x in zip(new, done, strict=True):
        leaves[i] = x
    return jax.tree.unflatten(treedef, leaves)


def batch_level(fast, plain):
    """``fast()``, or ``plain()`` where an outer ``vmap`` batches the lane program (both functions of no
    arguments, closing over lane arrays, returning the same values: a pytree of arrays).

    ``fast`` holds conditionals on the whole batch (``if_any``, the pool's blocks); an outer ``vmap``
    (vmapped learners or generators, each with its arenas) would batch their predicates and run
    every branch and then select, so there ``plain``, the same work without them, runs instead.

    Under ``jax.disable_jit`` ``fast()`` runs as Python: its conditionals, on concrete predicates,
    run one branch op by op. Bound as a program here, each would be compiled whole, with the
    values it closes over as constants (an eager decision: 20 such compiles, about 10 s on 2 cores).
    """
    if _RECORDS[-1] is not None:  # recording (tests): all of the work, on the values given
        return plain()
    if jax.config.jax_disable_jit:
        return fast()
    if _DIFFERENTIATED[-1]:  # derivatives of the same values, through the program without conditionals
        return plain()
    closed_plain = jax.make_jaxpr(plain)()
    if _varying(closed_plain.consts):  # inside a shard_map: fast's conditionals' branches would disagree
        return plain()
    closed_fast, shapes = jax.make_jaxpr(fast, return_shape=True)()
    leaves, treedef = jax.tree.flatten(shapes)
    n_fast = len(closed_fast.consts)

    def run(closed, consts):
        return jex_core.jaxpr_as_fun(jex_core.ClosedJaxpr(closed.jaxpr, list(consts)))()

    @custom_vmap
    def program(*consts):
        return run(closed_fast, consts[:n_fast])

    @program.def_vmap
    def rule(axis_size, in_batched, *consts):
        axes = [0 if b else None for b in in_batched[n_fast:]]
        out = jax.vmap(lambda *c: run(closed_plain, c), in_axes=axes, axis_size=axis_size)(*consts[n_fast:])
        return out, [True] * len(out)

    return jax.tree.unflatten(treedef, program(*closed_fast.consts, *closed_plain.consts))


def if_any(pred: jax.Array, fn):
    """``fn()`` (a pytree of arrays), or zeros of its shapes without running it when ``pred`` (a
    ``bool`` lane array) is false everywhere, in every lane: work that no arena of the batch needs.

    Use it only where ``fn`` gives exact zeros (or values nothing selects) whenever ``pred`` is all
    false; then the result is the same to the bit whether ``fn`` ran or not. On XLA:CPU's lane program
    the lanes are the arenas, so one test covers the whole batch and the conditional skips the
    work. Under an outer ``vmap`` (``batch_level``) and off the CPU backend ``fn`` always runs.
    """
    if not on_cpu() or _varying(pred) or _RECORDS[-1] is not None:
        return fn()  # recording (tests): every lane function runs on the values it is given
    closed, shapes = jax.make_jaxpr(fn, return_shape=True)()  # traced once: both programs run its jaxpr
    run = jex_core.jaxpr_as_fun(closed)
    zeros = [jnp.zeros(x.shape, x.dtype) for x in jax.tree.leaves(shapes)]
    out = batch_level(lambda: jax.lax.cond(jnp.any(pred), lambda: run(), lambda: zeros), run)
    return jax.tree.unflatten(jax.tree.structure(shapes), out)


def computed(fn):
    """``fn()`` (a function of no arguments that closes over lane arrays and returns a pytree), computed
    once into memory before its consumers run, written there by the operations that compute it.

    ``materialize`` moves a value into memory through a conditional whose branch returns it, which
    XLA:CPU implements as a copy of every leaf. Here ``fn``'s operations run inside the branch, so
    their results are the conditional's outputs and nothing is copied. Outputs that are values
    ``fn`` closed over (the leaves a phase did not change) pass by the conditional. Outside ``gate``
    and off the CPU backend this is ``fn()``.
    """
    if _GATE[-1] is None or not on_cpu() or _RECORDS[-1] is not None:
        return fn()
    closed, shapes = jax.make_jaxpr(fn, return_shape=True)()
    if _varying(closed.consts):
        return jax.tree.unflatten(jax.tree.structure(shapes), jex_core.jaxpr_as_fun(closed)())
    jaxpr = closed.jaxpr
    const_at = {v: i for i, v in enumerate(jaxpr.constvars)}
    out_shapes, treedef = jax.tree.flatten(shapes)
    outs: list = [None] * len(out_shapes)
    todo = []
    for j, v in enumerate(jaxpr.outvars):
        if isinstance(v, jex_core.Literal):
            outs[j] = jnp.asarray(v.val, out_shapes[j].dtype)
        elif v in const_at:
            outs[j] = closed.consts[const_at[v]]
        else:
            todo.append(j)
    run = jex_core.jaxpr_as_fun(closed)

    def branch():
        res = run()
        return [res[j] for j in todo]

    # The other branch must differ, or XLA merges the two and drops the conditional.
    done = jax.lax.cond(_GATE[-1], branch, lambda: [jnp.zeros(out_shapes[j].shape, out_shapes[j].dtype) for j in todo])
    for j, x in zip(todo, done, strict=True):
        outs[j] = x
    return jax.tree.unflatten(treedef, outs)
