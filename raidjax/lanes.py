"""The lane layout: the sub-step's arrays carry the arena axis last, so work runs over wide vectors.

Under ``jax.vmap`` the batch axis becomes the *first* axis of every array: a pool of ``[arenas, 16,
4]`` has its small unit axis innermost, and XLA:CPU spends its time on 4-wide loops, reductions over
that axis and gathers. The sub-step (``raidjax.env``'s ``advance``) is instead written for arrays
whose leading axes are the game's own (units, slots, pool slots, components) and whose trailing
axes, the *lanes*, are any number of batch axes, including none. Every elementwise operation then
runs over the arenas, and reductions over units or slots are a few vector operations.

One arena's ``State`` and ``Params`` already are lane arrays with no lanes (a unit's position
``pos[u]`` is ``float32[2]``). ``batched`` gives a lane function a ``vmap`` rule that moves the arena
axis last instead of first (``jax.custom_batching.custom_vmap``), so ``jax.vmap(raidjax.step)`` runs
the lane program over the arenas; it is also where the backend is decided, when the program is
traced (once per process and shapes for ``raidjax.step``).

Helpers (shapes: ``x[N, *R, *L]`` with ``L`` the lanes; indices are lane arrays): ``pick`` (gather
along the leading axis), ``one_hot``, ``argmin``, ``first_true`` and reductions over leading axes as
folds of elementwise operations (``total``, ``any_``, ``fold``, ``cumsum``).

On XLA:CPU two more shape the compiled sub-step, both told how by a ``Schedule`` that the caller
passes down (no state outside the arguments): ``computed`` (and ``materialize``) write a value into
memory once instead of letting XLA recompute it inside every consumer, and ``if_any`` skips work
that no arena of the batch needs this sub-step (hit groups nobody lands, the scripted moves of a
learner's batch). Only JAX's public API is used (tests/test_public_api.py).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
from jax.custom_batching import custom_vmap

# Every lane function of the game, by qualified name (``lane_function``); tests/test_lane_functions.py runs
# each with 0, 1 and 3 lanes against ``jax.vmap`` of its one-arena call.
REGISTRY: dict[str, object] = {}


def lane_function(fn=None, *, lane_shape: str | None = None, lane_count: str | None = None,
                  shared: tuple[str, ...] = ()):
    """Mark ``fn`` as a lane function (the layout's rules in CONTRIBUTING, "Write game code in the
    lane layout"): its arrays carry the game's axes first and any number of lane axes last, and it
    gives, lane by lane, what it gives one arena. Registered in ``REGISTRY`` and returned unchanged
    (with the attribute ``lane_args``, what the tests need to call it on lanes).

    ``lane_shape`` / ``lane_count``: the name of an argument that holds the lanes' shape (a tuple)
    or their number (an ``int``), for a function that must be told them. ``shared``: arguments
    whose arrays carry no lanes (the same for every arena, such as a group's die numbers).
    """
    if fn is None:
        return functools.partial(lane_function, lane_shape=lane_shape, lane_count=lane_count, shared=shared)
    fn.lane_args = {"lane_shape": lane_shape, "lane_count": lane_count, "shared": tuple(shared)}
    REGISTRY[f"{fn.__module__}.{fn.__qualname__}"] = fn
    return fn


@dataclasses.dataclass(frozen=True)
class Schedule:
    """How a lane program runs its work on XLA:CPU, passed down explicitly from where it starts.

    Attributes:
        gate: ``None`` for the plain program: no conditionals, every piece of work runs (off the CPU
            backend, under derivatives, inside a ``shard_map`` whose arguments vary along its mesh
            axes). Otherwise a scalar ``bool`` that is always true but that the compiler cannot
            evaluate (the sub-step loop's counter compared with 0), and that no ``vmap`` batches (the
            functions ``batch_level`` and ``if_any`` run close over it): ``materialize`` and
            ``computed`` branch on it, and ``if_any``, ``batch_level`` and the pool's blocks skip work
            that no arena needs. Either way the values are the same to the bit.
    """

    gate: jax.Array | None = None

    @property
    def fast(self) -> bool:
        """Whether the XLA:CPU schedule applies (a gate is given)."""
        return self.gate is not None


PLAIN = Schedule()


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


def batched(fn, full: tuple[int, ...] = ()):
    """``fn`` (a lane function of pytrees with a static keyword ``fast: bool``) as a function of one
    arena's arguments whose ``vmap`` puts the arena axis last; here the backend is decided, each time
    it is traced.

    ``fn(*args, fast=...)`` must work on lane arrays with any trailing lanes and return lane arrays,
    each output carrying the lanes (depending on a batched argument or one at ``full``);
    ``fast`` says whether it may schedule its work for XLA:CPU (``Schedule``), with the same values.
    On the CPU backend, under ``jax.vmap`` (``jax.custom_batching.custom_vmap``) every batched
    argument's axis moves to the end; an unbatched argument gets a trailing lane of size 1 (it
    broadcasts against the arenas), or, at the positions ``full`` (arguments whose shape the outputs
    keep, such as a carried state), is broadcast to the batch. ``fn`` runs once on the lanes and every
    output's axis moves back to the front. The lane call has the same rule, so nested ``vmap``s (a
    learner's runs, each with its arenas) add one lane each: the arenas of every run are lanes of one
    lane program, which skips the work that no arena of any run needs (``if_any``) as a single batch
    of arenas does. Derivatives (``jax.custom_jvp``) are those of the plain program
    (``fast=False``: no conditionals, the same values). Off the CPU backend the plain program runs,
    and ``vmap`` batches it as any JAX function.

    ``custom_vmap`` traces ``fn`` for one arena at every call, also where only its rule runs: a
    process that plays only vmapped games traces the sub-step twice (docs/DESIGN.md, "The lane
    program on JAX's public API", has the cost).
    """

    # Traced through ``jax.jit``: JAX keeps the traced program per argument shapes, so every later
    # program of the process that runs ``fn`` on the same shapes reuses it instead of tracing the
    # whole sub-step again; XLA inlines the call, so the compiled program is the same.
    traced = jax.jit(fn, static_argnames="fast")

    def plain(*args):
        return traced(*args, fast=False)

    @custom_vmap
    def lane_call(*args):
        # Inside a shard_map a conditional's branches must agree on which values vary along the
        # mesh axes, which the schedule's (a constant branch) do not: the plain program runs there.
        return traced(*args, fast=not _varying(args))

    @lane_call.def_vmap
    def rule(axis_size, in_batched, *args):
        def to_lanes(x, is_batched, width):
            return jnp.moveaxis(x, 0, -1) if is_batched else jnp.broadcast_to(x[..., None], x.shape + (width,))

        lanes = tuple(jax.tree.map(functools.partial(to_lanes, width=axis_size if i in full else 1), a, b)
                      for i, (a, b) in enumerate(zip(args, in_batched, strict=True)))
        out = jax.tree.map(lambda x: jnp.moveaxis(x, -1, 0), lane_call(*lanes))
        return out, jax.tree.map(lambda _: True, out)

    @jax.custom_jvp
    def on_cpu(*args):
        return lane_call(*args)

    @on_cpu.defjvp
    def _derivatives(primals, tangents):
        return jax.jvp(plain, primals, tangents)

    @functools.wraps(fn)
    def call(*args):
        if jax.default_backend() != "cpu":  # the lanes pay on XLA:CPU only (docs/DESIGN.md)
            return plain(*args)
        if not _traced(args):
            return traced(*args, fast=True)  # concrete values: no transformation to give rules to
        return on_cpu(*args)

    return call


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


def _varying(tree) -> bool:
    """Whether a leaf of ``tree`` varies along a ``shard_map``'s manual mesh axes."""
    for x in jax.tree.leaves(tree):
        t = jax.typeof(x)
        if getattr(getattr(t, "manual_axis_type", None), "varying", None) or getattr(t, "vma", None):
            return True
    return False


def _traced(tree) -> bool:
    """Whether a leaf of ``tree`` is being traced (under ``jit`` or a transformation), rather than a
    concrete array that a conditional's predicate can be read from in Python."""
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves(tree))


def _branch_or_zeros(pred: jax.Array, fn, args: tuple):
    """``jax.lax.cond(pred, fn, skip, *args)``, where ``skip`` gives zeros shaped as ``fn``'s outputs,
    but for outputs that are ``fn``'s arguments themselves: both branches pass those by, so the
    conditional forwards them instead of copying them.

    ``fn`` is traced once: ``lax.cond`` traces the branch that runs it first, which records the
    outputs' shapes and which of them are arguments. Were the other branch traced first, it takes
    the shapes from a trace of its own (``jax.eval_shape``) and passes nothing by (the same values).
    """
    seen: dict = {}

    def taken(*ops):
        out = fn(*ops)
        leaves, tree = jax.tree.flatten(out)
        at = {id(x): k for k, x in enumerate(jax.tree.leaves(ops))}
        seen.update(tree=tree, fwd=[at.get(id(x)) for x in leaves], like=[jax.typeof(x) for x in leaves])
        return out

    def skipped(*ops):
        if not seen:
            like, tree = jax.tree.flatten(jax.eval_shape(fn, *ops))
            seen.update(tree=tree, fwd=[None] * len(like), like=like)
        flat = jax.tree.leaves(ops)
        return seen["tree"].unflatten([_zeros(s) if k is None else flat[k]
                                       for k, s in zip(seen["fwd"], seen["like"], strict=True)])

    return jax.lax.cond(pred, taken, skipped, *args)


def _zeros(like) -> jax.Array:
    """Zeros of ``like``'s shape and dtype, weakly typed where ``like`` is (a Python scalar's zero
    broadcast), so both branches of a conditional agree on the type."""
    if getattr(like, "weak_type", False):
        return jax.lax.full(like.shape, like.dtype.type(0).item())
    return jnp.zeros(like.shape, like.dtype)


def materialize(schedule: Schedule, tree, since=None):
    """``tree`` (a pytree of arrays) unchanged, computed once into memory before its consumers run.

    XLA:CPU fuses an elementwise chain into every consumer and recomputes it there (per element of
    a reduction, per consumer); ``jax.lax.optimization_barrier`` does not stop that on CPU, a
    conditional does. With ``schedule.fast`` the values go through a ``lax.cond`` on its gate, which
    is always true; in the plain schedule this changes nothing.

    ``since``: a pytree whose leaves are already in memory (the phase's input state); leaves of
    ``tree`` that are the very same arrays pass by the conditional, which would only copy them.
    """
    if not schedule.fast:
        return tree
    leaves, treedef = jax.tree.flatten(tree)
    kept = {id(x) for x in jax.tree.leaves(since)}
    new = [i for i, x in enumerate(leaves) if id(x) not in kept]
    # The other branch must differ, or XLA merges the two and drops the conditional.
    done = jax.lax.cond(schedule.gate, lambda t: t, lambda t: [jnp.zeros_like(x) for x in t], [leaves[i] for i in new])
    for i, x in zip(new, done, strict=True):
        leaves[i] = x
    return jax.tree.unflatten(treedef, leaves)


def computed(schedule: Schedule, fn, *args):
    """``fn(*args)`` (a pytree), computed once into memory before its consumers run, written there by
    the operations that compute it.

    ``materialize`` moves a value into memory through a conditional whose branch returns it, which
    XLA:CPU implements as a copy of every leaf. Here ``fn``'s operations run inside the branch (on
    the gate), so their results are the conditional's outputs and nothing is copied; outputs that
    are leaves of ``args`` themselves (the leaves a phase did not change) pass by the conditional.
    ``fn`` may also close over values. In the plain schedule this is ``fn(*args)``.
    """
    if not schedule.fast:
        return fn(*args)
    return _branch_or_zeros(schedule.gate, fn, args)


def batch_level(schedule: Schedule, fast, plain, *args):
    """``fast(*args)``, or ``plain(*args)`` where an outer ``vmap`` batches ``args`` (two functions that
    return the same values, a pytree of arrays; every value they read that an outer ``vmap`` may
    batch must come in ``args``: what they close over stays unbatched).

    ``fast`` holds conditionals on the whole batch (``if_any``, the pool's blocks); an outer ``vmap``
    (vmapped learners or generators, each with its arenas, where no lane rule moved their axis)
    would batch their predicates and run every branch and then select, so there ``plain``, the same
    work without them, runs instead (``jax.custom_batching.custom_vmap``; ``fast`` alone is traced
    where nothing batches it). The plain schedule runs ``plain``. With concrete ``args`` (``jax.disable_jit``)
    ``fast`` runs as Python: its conditionals, on concrete predicates, run one branch op by op.
    """
    if not schedule.fast:
        return plain(*args)
    if not _traced(args):
        return fast(*args)

    @custom_vmap
    def program(*a):
        return fast(*a)

    @program.def_vmap
    def rule(axis_size, in_batched, *a):
        axes = [jax.tree.map(lambda b: 0 if b else None, b) for b in in_batched]
        out = jax.vmap(plain, in_axes=axes, axis_size=axis_size)(*a)
        return out, jax.tree.map(lambda _: True, out)

    return program(*args)


def if_any(schedule: Schedule, pred: jax.Array, fn, *args):
    """``fn(*args)`` (a pytree of arrays), or zeros of its shapes without running it when ``pred`` (a
    ``bool`` lane array) is false everywhere, in every lane: work that no arena of the batch needs.
    Outputs that are leaves of ``args`` come out as those arguments either way.

    Use it only where ``fn`` gives exact zeros (or values nothing selects) whenever ``pred`` is all
    false; then the result is the same to the bit whether ``fn`` ran or not. On XLA:CPU's lane program
    the lanes are the arenas, so one test covers the whole batch and the conditional skips the
    work. In the plain schedule and under an outer ``vmap`` of ``args`` (``batch_level``) ``fn``
    always runs; what ``fn`` closes over must stay unbatched, as there.
    """
    return batch_level(schedule, lambda p, *a: _branch_or_zeros(jnp.any(p), fn, a), lambda p, *a: fn(*a), pred, *args)
