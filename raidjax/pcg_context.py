"""Per-episode context for the opt-in diversity terms of ``raidjax.pcg`` (beyond SPEC §10).

Each draw takes its own key (``pcg`` folds the episode key with a fixed number per draw), so
turning a term on leaves the skills, targets and playtests of every episode unchanged. The
sizes come from the bounds' shape ``[P]`` (P = 4 parameters).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def check(edit_preferences: bool, favourite_weight: float | None, observe_goal: bool,
          goal_axis: tuple[int, ...] | None, names: tuple[str, ...]) -> tuple[float | None, tuple | None]:
    """Validate the host-side options of these terms (``names``: the parameter names) and return
    ``(favourite_weight, goal_axis)`` normalised to ``float`` and a ``tuple`` of ``int``; raises
    ``ValueError`` naming the field, the value and what is allowed."""
    if favourite_weight is not None:
        if not edit_preferences:
            raise ValueError(f"favourite_weight: value {favourite_weight} needs edit_preferences=True")
        if not 0.0 <= favourite_weight <= 1.0:
            raise ValueError(f"favourite_weight: value {favourite_weight} must lie in [0, 1] (the favourite "
                             "parameter is the cheap one; the others weigh (4 - w) / 3)")
        favourite_weight = float(favourite_weight)
    if goal_axis is not None:
        if not observe_goal:
            raise ValueError(f"goal_axis: value {goal_axis} needs observe_goal=True")
        if len(goal_axis) != len(names) or any(v not in (-1, 0, 1) for v in goal_axis):
            raise ValueError(f"goal_axis: value {goal_axis} must be {len(names)} signs, each -1, 0 or +1 "
                             f"(for {names})")
        goal_axis = tuple(int(v) for v in goal_axis)
    return favourite_weight, goal_axis


def displacement(skill: jax.Array, start: jax.Array, tick: jax.Array) -> jax.Array:
    """Squared distance in ticks, ``sum(((skill - start) / tick)**2)``: ``float32[...]`` for
    ``float32[..., P]`` inputs and ``tick`` ``float32[P]``. Squared, so that moving several
    parameters a little costs less than moving one a lot."""
    return jnp.sum(((skill - start) / tick) ** 2, -1)


def draw_preferences(key: jax.Array, n_params: int, favourite_weight: float | None) -> jax.Array:
    """Per-parameter edit weights, mean 1: ``n * softmax(1.5 z)`` with ``z`` standard normal, or
    (``favourite_weight`` w) one uniform favourite weighing w and the others ``(n - w) / (n - 1)``.
    Returns ``float32[n_params]``."""
    if favourite_weight is None:
        prefs = n_params * jax.nn.softmax(1.5 * jax.random.normal(key, (n_params,)))
    else:
        favourite = jax.random.randint(key, (), 0, n_params)
        prefs = jnp.where(jnp.arange(n_params) == favourite, favourite_weight,
                          (n_params - favourite_weight) / (n_params - 1))
    return prefs.astype(jnp.float32)


def draw_goal(k_corner: jax.Array, k_end: jax.Array, low: jax.Array, high: jax.Array,
              axis: tuple[int, ...] | None) -> jax.Array:
    """A style goal at a corner of the box ``[low, high]`` (``float32[P]`` each): every parameter at
    either bound with probability 1/2, independently (coins from ``k_corner``); with ``axis`` (P
    signs in {-1, 0, 1}, static) one coin from ``k_end`` picks an end of the axis (+1 parameters
    high and -1 low, or the reverse) and only the 0-signed parameters keep their own coins.
    Returns ``float32[P]``."""
    upper = jax.random.bernoulli(k_corner, 0.5, low.shape)
    if axis is not None:
        signs = jnp.asarray(axis, jnp.int32)
        upper = jnp.where(signs == 0, upper, (signs > 0) == jax.random.bernoulli(k_end, 0.5))
    return jnp.where(upper, high, low)


def draw_lever(key: jax.Array, n_params: int) -> jax.Array:
    """The designated parameter for the next edit, uniform: ``int32[]``."""
    return jax.random.randint(key, (), 0, n_params, jnp.int32)
