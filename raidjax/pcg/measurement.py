"""The generator's playtests: a skill's wins over a batch of games (``play_outcomes``), run as one
playtest of every episode's games under ``jax.vmap``, and the points of a parameter box that a
balancing run measures (``box_grid``, ``box_probes``)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_batching import custom_vmap

from raidjax import policies, validate
from raidjax.pcg.space import PAPER_SPACE, Space
from raidjax.playtest import auto_games_per_arena, playtest, playtest_groups
from raidjax.types import WIN, Params


def play_outcomes(key: jax.Array, game: Params, skill: jax.Array, n_games: int, tester: Callable = policies.heuristic,
                  tester_weights: Any = None, space: Space = PAPER_SPACE) -> jax.Array:
    """``tester`` (default PT-HR; with ``tester_weights`` as in ``PCGParams``) plays ``n_games`` games
    with ``skill`` (``float32[K]`` in ``space``); returns ``bool[n_games]`` wins (draws and losses
    are ``False``).

    Under ``jax.vmap`` over keys and skills (generator episodes run side by side), the batch's
    playtests run as one (``raidjax.playtest_groups``): the same games bit for bit, but
    every arena stops with its own games instead of a vmapped loop running the whole batch's
    longest, and the program traces and compiles as a single playtest does."""
    return _outcomes(tester, n_games, space)(key, game, skill, tester_weights)


@functools.cache
def _outcomes(tester: Callable, n_games: int, space: Space):
    """``play_outcomes`` for one ``(tester, n_games, space)``: a function of ``(key, game, skill,
    weights)`` with a vmap rule (cached, so its programs are traced once per process)."""
    gpa = auto_games_per_arena(n_games)

    def one(key, game, skill, weights):
        results = playtest(key, space.apply(game, skill), tester, n_games, weights=weights, games_per_arena=gpa)
        return results["outcome"] == WIN

    outcomes = custom_vmap(one)

    @outcomes.def_vmap
    def rule(axis_size, in_batched, key, game, skill, weights):
        k_b, g_b, s_b, w_b = in_batched
        if any(jax.tree.leaves(g_b)) or any(jax.tree.leaves(w_b)):  # contents or testers per episode: vmap as is
            axes = [jax.tree.map(lambda b: 0 if b else None, b) for b in in_batched]
            return jax.vmap(one, in_axes=axes)(key, game, skill, weights), True
        keys = key if k_b else jnp.broadcast_to(key, (axis_size,) + key.shape)
        skills = skill if s_b else jnp.broadcast_to(skill, (axis_size,) + skill.shape)
        contents = jax.vmap(lambda sk: space.apply(game, sk))(skills)
        return _grouped_wins(tester, n_games, gpa)(keys, contents, weights), True

    # custom_vmap traces one playtest at every call, also where only the rule runs (a generator's
    # measurements always run vmapped): docs/DESIGN.md, "The lane program", has the cost.
    return outcomes


@functools.cache
def _grouped_wins(tester: Callable, n_games: int, games_per_arena: int):
    """``f(keys [G], contents [G, ...], weights) -> bool[G, n_games]``: the wins of ``G``
    measurements in one ``playtest_groups``. Under a further ``vmap`` (several learners, each with
    its generator episodes: PPO-PCGRL's runs or one model per target) the outer axis joins the
    groups, so every measurement of every learner is one playtest again, the same games bit for bit;
    with testers' weights per learner it is vmapped as it is."""

    def grouped(keys, contents, weights):
        return playtest_groups(keys, contents, tester, n_games, games_per_arena, weights)["outcome"] == WIN

    wins_of = custom_vmap(grouped)

    @wins_of.def_vmap
    def rule(axis_size, in_batched, keys, contents, weights):
        k_b, c_b, w_b = in_batched
        if any(jax.tree.leaves(w_b)):
            axes = [jax.tree.map(lambda b: 0 if b else None, b) for b in in_batched]
            return jax.vmap(grouped, in_axes=axes)(keys, contents, weights), True
        full = lambda x, b: x if b else jnp.broadcast_to(x, (axis_size,) + x.shape)  # noqa: E731
        keys = full(keys, k_b)
        contents = jax.tree.map(full, contents, c_b)
        g = keys.shape[1]
        flat = lambda x: x.reshape((axis_size * g,) + x.shape[2:])  # noqa: E731
        wins = wins_of(flat(keys), jax.tree.map(flat, contents), weights)
        return wins.reshape(axis_size, g, n_games), True

    return wins_of


def box_grid(points: int, space: Space = PAPER_SPACE) -> np.ndarray:
    """A grid over ``space``'s box (default the paper's four): ``points`` evenly spaced values per
    parameter, bounds included (1 = the box's centre), every combination: ``float32[points**K, K]``
    (first parameter slowest). Raises ``ValueError`` unless ``points >= 1``."""
    points = validate.whole_number("points", points, 1)
    axes = [np.linspace(lo, hi, points) if points > 1 else np.asarray([(lo + hi) / 2])
            for lo, hi in zip(space.low, space.high, strict=True)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, space.size).astype(np.float32)


def box_probes(space: Space = PAPER_SPACE) -> np.ndarray:
    """The box's centre, then for each parameter its lower and its upper bound with the others at
    the centre: ``float32[1 + 2K, K]`` (a check that grows linearly with ``K``)."""
    centre = (space.low + space.high) / 2
    rows = [centre]
    for j in range(space.size):
        for bound in (space.low[j], space.high[j]):
            rows.append(centre.copy())
            rows[-1][j] = bound
    return np.stack(rows).astype(np.float32)
