"""Sizes and spaces of an arena, for learners written elsewhere (gymnax-style ``Discrete``/``Box``).

    sp = raidjax.spaces(params)
    sp.n_players, sp.n_actions          # 3, 10 (8 under action_space="reference")
    sp.action.sample(key)               # int32[] one player's action
    sp.observation["boss"].shape        # (3, 11): every field with its leading player axis
    sp.flat_observation.shape           # (3, D): Observation.flat()
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from raidjax import validate
from raidjax.types import ACTION_HEURISTIC, Params


@dataclasses.dataclass(frozen=True)
class Discrete:
    """Integers ``0 .. n - 1`` (one player's action id)."""

    n: int
    dtype: type = jnp.int32

    def sample(self, key: jax.Array) -> jax.Array:
        """A uniform ``int32[]`` in ``[0, n)``."""
        return jax.random.randint(key, (), 0, self.n, self.dtype)

    def contains(self, x) -> jax.Array:
        """``bool[]``: ``x`` is a scalar integer in range."""
        x = jnp.asarray(x)
        return jnp.asarray(x.shape == () and jnp.issubdtype(x.dtype, jnp.integer)) & (x >= 0) & (x < self.n)


@dataclasses.dataclass(frozen=True)
class Box:
    """Arrays of ``shape`` and ``dtype`` with every element in ``[low, high]`` (infinite: unbounded)."""

    low: float
    high: float
    shape: tuple[int, ...]
    dtype: type

    def sample(self, key: jax.Array) -> jax.Array:
        """A uniform draw (bounded boxes; unbounded dimensions draw from [-1, 1]).

        Returns:
            ``dtype[shape]``: ``bool`` boxes draw each element true with probability 1/2; others
            draw ``float32`` and cast to ``dtype``.
        """
        if self.dtype == jnp.bool_:
            return jax.random.bernoulli(key, 0.5, self.shape)
        low, high = (-1.0 if np.isinf(self.low) else self.low), (1.0 if np.isinf(self.high) else self.high)
        return jax.random.uniform(key, self.shape, jnp.float32, low, high).astype(self.dtype)

    def contains(self, x) -> jax.Array:
        """``bool[]``: ``x`` has this shape and every element lies in the bounds."""
        x = jnp.asarray(x)
        return jnp.asarray(x.shape == self.shape) & jnp.all((x >= self.low) & (x <= self.high))


@dataclasses.dataclass(frozen=True)
class Spaces:
    """What a learner needs to size its networks for an arena of ``params``.

    Attributes:
        n_players: ``P``, players per arena (the agents).
        n_actions: learner actions per player, ``config.n_actions``: ``N_ACTIONS`` (10) or 8 under
            the reference action space; ``ACTION_HEURISTIC`` (10) is the extra id that hands a
            player to the PT-HR script.
        action: ``Discrete(n_actions)``, one player's action; ``step`` takes ``int32[P]``.
        observation: ``Box`` per field of the observation (``Observation`` or, under
            ``observation="reference"``, ``ReferenceObservation``), each with the leading player
            axis ``P`` (features unbounded, masks in {0, 1}).
        flat_observation: ``Box`` of the observation's ``flat()``, ``float32[P, D]`` (D = 9 (P - 1) +
            186 for the reference observation: 204 for 3 players).
        heuristic_action: ``ACTION_HEURISTIC`` (10), the action id that hands a player to the
            built-in PT-HR script for one decision (outside ``action``; ``step`` accepts it).
    """

    n_players: int
    n_actions: int
    action: Discrete
    observation: dict[str, Box]
    flat_observation: Box
    heuristic_action: int = ACTION_HEURISTIC


def spaces(params: Params) -> Spaces:
    """The sizes and spaces of one arena of ``params`` (unbatched; shapes only, nothing compiles).

    Args:
        params: one arena's ``Params`` (``team: [U]``).

    Returns:
        ``Spaces``.
    """
    from raidjax.env import reset

    validate.one_arena("spaces", params.team)
    obs, _ = jax.eval_shape(reset, jax.random.key(0), params)
    boxes = {}
    for f in dataclasses.fields(obs):
        leaf = getattr(obs, f.name)
        is_mask = leaf.dtype == jnp.bool_
        boxes[f.name] = Box(0.0 if is_mask else -np.inf, 1.0 if is_mask else np.inf, tuple(leaf.shape), leaf.dtype)
    flat = jax.eval_shape(lambda o: o.flat(), obs)
    n_actions = params.config.n_actions
    return Spaces(n_players=int(params.team.shape[0]) - 1, n_actions=n_actions, action=Discrete(n_actions),
                  observation=boxes, flat_observation=Box(-np.inf, np.inf, tuple(flat.shape), flat.dtype))
