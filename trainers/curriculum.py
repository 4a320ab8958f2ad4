"""The content curriculum of MA-POCA training: which skill each arena plays and when it draws a
new one. An arena draws a skill range from its run's set (``range_table``), or under
``Config.content_box`` a point of the content generator's box, at its start and after every
``redraw_every``-th finished episode (the reference's ``MMORPGEnvController.ResetScene``); the
trainer begins the new episode under the new skill (``begin_episodes``).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

import raidjax
from raidjax import pcg
from raidjax.content import with_player_skill
from raidjax.types import Observation, Params, State
from trainers.config import Config

RANGE_TABLE = 12  # lcm(1, 2, 3, 4): sets of 1-4 ranges share one table shape, so draws stay uniform


def range_table(ranges, size: int | None = None) -> jax.Array:
    """The set of skill ranges a run draws from, tiled to ``float32[size]``.

    A uniform draw over the table is a uniform draw over the set. Runs whose tables share a size
    are one vmapped program (``experiments.benchmark1``: sets of 1-4 ranges, size 12).

    Args:
        ranges: the set (k values).
        size: table length, a multiple of k (default ``lcm(k, RANGE_TABLE)``).

    Raises:
        ValueError: an empty set, or ``size`` not a multiple of k.
    """
    ranges = tuple(float(r) for r in ranges)
    size = math.lcm(len(ranges), RANGE_TABLE) if size is None and ranges else size
    if not ranges or size % len(ranges):
        raise ValueError(f"skill_ranges: {len(ranges)} values cannot tile a table of {size} entries "
                         "(allowed: 1 or more values, a divisor of the table size)")
    return jnp.asarray(ranges * (size // len(ranges)), jnp.float32)


def next_draws(episode: jax.Array, done: jax.Array, every: int) -> tuple[jax.Array, jax.Array]:
    """The reference's per-arena redraw cadence (``MMORPGEnvController.ResetScene``:
    ``if (n_episode++ % 2 == 0) RequestMAConfig``, ``every = 2``) for any drawn content.

    An arena that ends an episode counts it; when its count of finished episodes is a multiple of
    ``every`` it draws its next content (one draw per arena, shared by its players: ``draw_skills``).
    The start of the run is a draw, so an arena's episodes 1..every share one.

    Args:
        episode: ``int32[N]`` finished episodes before this step; done: ``bool[N]`` an episode
            ended this step; every: static.

    Returns:
        ``(episode int32[N], redrawn bool[N])``.
    """
    episode = episode + done.astype(jnp.int32)
    return episode, done & (episode % every == 0)


def with_drawn(config: Config, content: Params, skill: jax.Array) -> Params:
    """``content`` with one arena's drawn values ``float32[K]`` (``draw_skills``) written in: the
    players' skill slot 1 range (``K = 1``), or under ``config.content_box`` the generator's
    parameters (``config.parameters``, ``raidjax.pcg.make_space``)."""
    if config.content_box:
        return pcg.make_space(config.parameters, config.players).apply(content, skill)
    return with_player_skill(content, range=skill[0])


def draw_skills(key: jax.Array, config: Config, range_set: jax.Array, n: int) -> jax.Array:
    """``n`` fresh draws ``float32[n, K]`` (``with_drawn``): a range from ``range_set``, or under
    ``config.content_box`` a point uniform in the generator's box."""
    if config.content_box:
        space = pcg.make_space(config.parameters, config.players)
        return jax.random.uniform(key, (n, space.size), minval=space.low, maxval=space.high)
    return jax.random.choice(key, range_set, (n,))[:, None]


def where_arenas(mask: jax.Array, new, old):
    """``new`` in the arenas where ``mask: bool[N]`` holds, ``old`` elsewhere (pytrees of ``[N, ...]``
    arrays of the same structure)."""
    return jax.tree.map(lambda a, b: jnp.where(mask.reshape((-1,) + (1,) * (a.ndim - 1)), a, b), new, old)


def training_content(cfg: Config, params: Params) -> Params:
    """``params`` as the learner trains on it: with ``cfg.senses`` and, under ``cfg.random_spawns``,
    every episode's spawns drawn (``EnvConfig.random_spawns``). Evaluation plays the content as given."""
    params = raidjax.with_senses(params, cfg.senses)
    if cfg.random_spawns:
        params = params.replace(config=params.config.replace(random_spawns=True))
    return params


def begin_episodes(next_keys: jax.Array, fresh_key: jax.Array, p: float, done: jax.Array, state: State,
                   params: Params) -> tuple[State, Observation]:
    """The arenas whose episode just ended begin their next one, built and observed once under the
    content it plays: ``raidjax.next_episode`` (what the arena carries over), or with probability
    ``p`` (``Config.fresh_starts``) ``raidjax.reset``. With ``p = 0`` and unchanged ``params`` this
    is the second half of ``raidjax.step_autoreset``.

    Args:
        next_keys: ``[N]`` per-arena PRNG keys of ``next_episode`` (raw ``uint32[N, 2]`` or typed, as the
            runner's; ``step_autoreset``'s second split of its key); fresh_key: PRNG key of the
            fresh-start draws; p: static.
        done: ``bool[N]``; state: ``State [N]`` as the decision left it; params: ``Params [N]``,
            the content of the episodes that begin (a redrawn skill already written in).

    Returns:
        ``(state [N], obs [N])``: the arenas not ``done`` keep ``state`` (observed again).
    """
    _, begun = jax.vmap(raidjax.next_episode)(next_keys, state, params)
    if p > 0:
        n = done.shape[0]
        k_coin, k_reset = jax.random.split(fresh_key)
        fresh = jax.random.uniform(k_coin, (n,)) < p
        _, reset = jax.vmap(raidjax.reset)(jax.random.split(k_reset, n), params)
        begun = where_arenas(fresh, reset, begun)
    state = where_arenas(done, begun, state)
    return state, jax.vmap(raidjax.observe)(state, params)
