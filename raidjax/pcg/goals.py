"""Style goals of the content-generation environment (``PCGParams.goal_axis``, GAME.md §10): an
axis of signs over the edited parameters, its parsing for command lines, a goal drawn at one of its
ends per episode, and the distance in ticks a learner may be charged for."""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp

from raidjax.pcg.space import PAPER_SPACE, Space, high, low, tick

N_PARAMS = PAPER_SPACE.size
HEAVY_VS_LIGHT = (1, 1, 1, 1)  # a style axis: all four parameters high, or all four low


def check_axis(goal_axis, size: int = N_PARAMS) -> tuple[int, ...] | None:
    """``goal_axis`` as a tuple of ints (``None`` stays ``None``); raises ``ValueError`` naming the
    field, the value and what is allowed unless it is ``size`` signs in {-1, 0, 1}."""
    if goal_axis is None:
        return None
    axis = tuple(goal_axis)
    if len(axis) != size or any(v not in (-1, 0, 1) for v in axis):
        raise ValueError(f"goal_axis: value {goal_axis} must be {size} signs, each -1, 0 or +1 "
                         f"(one per edited parameter{', ' + str(PAPER_SPACE.fields) if size == N_PARAMS else ''})")
    return tuple(int(v) for v in axis)


def parse_axis(text: str) -> tuple[int, ...]:
    """``"1,0,-1,1"`` -> ``(1, 0, -1, 1)`` for command lines: comma-separated signs, each -1, 0 or 1;
    how many the edited space needs is ``check_axis``'s (the space is known later). Raises
    ``ValueError`` naming the value and what is allowed."""
    allowed = "comma-separated signs, each -1, 0 or 1, one per edited parameter (the paper's four: " \
              f"{','.join(PAPER_SPACE.fields)})"
    try:
        signs = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"goal_axis: value {text!r}; allowed: {allowed}") from None
    if any(v not in (-1, 0, 1) for v in signs):
        raise ValueError(f"goal_axis: value {text!r}; allowed: {allowed}")
    return signs


def axis_arg(text: str) -> tuple[int, ...]:
    """``parse_axis`` as an argparse ``type`` (``--goal-axis 1,1,1,1``): bad input becomes a usage
    error naming the flag, the value and what is allowed."""
    try:
        return parse_axis(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def squared_ticks(skill: jax.Array, other: jax.Array, space: Space = PAPER_SPACE) -> jax.Array:
    """Squared distance in ticks, ``sum(((skill - other) / tick)**2)``: ``float32[...]`` for
    ``float32[..., K]`` inputs. Squared, so that moving several parameters a little costs less
    than moving one a lot."""
    return jnp.sum(((skill - other) / tick(space)) ** 2, -1)


def draw_goal(key: jax.Array, axis: tuple[int, ...], space: Space = PAPER_SPACE) -> jax.Array:
    """A style goal at one end of ``axis`` (static, ``check_axis``): ``float32[K]`` (see
    ``PCGParams.goal_axis``). The keys are folded from ``key`` with their own numbers, so a goal
    never changes the episode's skill, target or playtests."""
    upper = jax.random.bernoulli(jax.random.fold_in(key, 13), 0.5, (space.size,))  # 0-signed parameters
    signs = jnp.asarray(axis, jnp.int32)
    upper = jnp.where(signs == 0, upper, (signs > 0) == jax.random.bernoulli(jax.random.fold_in(key, 17), 0.5))
    return jnp.where(upper, high(space), low(space))
