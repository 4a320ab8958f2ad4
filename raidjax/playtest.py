"""Batched playtesting: many games in parallel on-device, stopping once every game ended.

The public functions check their arguments in plain Python first (``n_games`` a whole number
>= 1, ``params`` a ``Params`` whose batch fits ``n_games``, ``policy`` a hashable function) and
raise a one-line ``ValueError`` before anything is traced or compiled; the jitted programs behind
them are cached by ``(policy, n_games)`` as before.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import partial

import jax
import jax.numpy as jnp

from raidjax import validate
from raidjax.env import next_episode, reset, step
from raidjax.logs import HEATMAP_BINS, episode_summary, grid_cell
from raidjax.observation import observe
from raidjax.sharding import shard_batch
from raidjax.types import RUNNING, Params

Policy = Callable  # policy(key, obs, state, params) -> int32[P], or policy(weights, key, obs, state, params)


def bind(policy: Policy, weights):
    """``policy`` as ``(key, obs, state, params) -> actions``: itself when ``weights`` is ``None``,
    else with ``weights`` (a pytree of arrays, traced, so new weights of the same shapes reuse
    the compiled program) as its first argument."""
    if weights is None:
        return policy
    return lambda key, obs, state, params: policy(weights, key, obs, state, params)


def check_args(params: Params, n_games, policy: Policy | None = None, weights=None) -> int:
    """Check the arguments of a playtest on the host, before anything is traced or compiled.

    Args:
        params: ``Params``, unbatched or with one batch axis (see ``broadcast_params``).
        n_games: a whole number >= 1 (a Python or numpy integer; not a ``bool``, ``float`` or ``str``).
        policy: if given, a hashable callable (it is a static argument of the jitted playtest).
        weights: ``None`` or a pytree of arrays (the policy's weights, a traced argument).

    Returns:
        ``n_games`` as a Python ``int`` (so ``5`` and ``np.int64(5)`` share one compilation).

    Raises:
        ValueError: one line naming the argument, the value and what is allowed.
    """
    n = validate.whole_number("n_games", n_games, 1)
    if not isinstance(params, Params):
        raise validate.fail("params", params, "a raidjax.Params (raidjax.make_params(...))")
    nb = params.team.ndim - 1
    if nb not in (0, 1):
        raise ValueError(f"params: {nb} batch axes; playtest takes at most one")
    if nb == 1 and n % params.team.shape[0]:
        raise ValueError(f"n_games: value {n} is not a multiple of the {params.team.shape[0]} contents in params")
    if policy is not None:
        allowed = "a hashable function policy(key, obs, state, params) -> int32[P], e.g. raidjax.policies.heuristic"
        try:
            hash(policy)
        except TypeError:
            raise validate.fail("policy", policy, allowed, "unhashable") from None
        if not callable(policy):
            raise validate.fail("policy", policy, allowed)
    if weights is not None:
        bad = [x for x in jax.tree.leaves(weights) if not hasattr(x, "dtype")]
        if bad:
            raise validate.fail("weights", bad[0], "a pytree of arrays (the policy's weights) or None")
    return n


def broadcast_params(params: Params, n_games: int) -> Params:
    """Give ``params`` a leading ``n_games`` axis.

    Args:
        params: unbatched (``team: [U]``), one content per game (``[n_games, U]``), or one content
            per group of games (``[G, U]`` with ``n_games % G == 0``: game ``g`` uses content
            ``g // (n_games // G)``).
        n_games: a whole number >= 1.

    Returns:
        ``Params`` with every leaf's leading axis ``n_games``.

    Raises:
        ValueError: as ``check_args`` (``n_games`` not a whole number >= 1 or not a multiple of the
            contents, more than one batch axis).
    """
    n_games = check_args(params, n_games)
    if params.team.ndim == 1:
        return jax.tree.map(lambda x: jnp.broadcast_to(x, (n_games,) + x.shape), params)
    return jax.tree.map(lambda x: jnp.repeat(x, n_games // params.team.shape[0], axis=0), params)


def _play_until_done(key: jax.Array, state, batch: Params, policy: Policy, n_games: int, fold, acc):
    """Step ``n_games`` arenas until every one's episode has ended; ``fold(acc, state)`` sees the
    start state and the state after every decision. Returns ``(final state, acc)``."""
    obs = jax.vmap(observe)(state, batch)
    max_t = batch.config.max_decisions

    def play(carry):
        t, obs, state, acc = carry
        keys = jax.random.split(jax.random.fold_in(key, t), 2 * n_games)  # raw or typed keys
        actions = jax.vmap(policy)(keys[:n_games], obs, state, batch)
        obs, state, _, _, _ = jax.vmap(step)(keys[n_games:], state, actions, batch)
        return t + 1, obs, state, fold(acc, state)

    def running(carry):
        t, _, state, _ = carry
        return (t < max_t) & jnp.any(state.result == RUNNING)

    _, _, state, acc = jax.lax.while_loop(running, play, (jnp.int32(0), obs, state, fold(acc, state)))
    return state, acc


def _play_games(key: jax.Array, batch: Params, policy: Policy, n_games: int, fold=None, acc=None):
    """Play ``n_games`` measured games, one per arena (``batch``: params with a leading
    ``n_games`` axis). Under rules whose episodes depend on the one before
    (``EnvConfig.chains_episodes``: the reference rules), every arena first plays a warm-up
    game that is discarded and the measured game is its ``next_episode``, as the reference
    build's arenas chain their games. ``fold(acc, state)`` sees only the measured games.
    Returns ``(final state, acc)``."""
    fold = fold or (lambda a, _: a)
    k_reset, k_play = jax.random.split(key)
    batch = shard_batch(batch, n_games)  # games are independent: spread them over every device
    _, state = jax.vmap(reset)(jax.random.split(k_reset, n_games), batch)
    state = shard_batch(state, n_games)
    if batch.config.chains_episodes:
        k_warm, k_next = jax.random.split(jax.random.fold_in(key, 1))
        state, _ = _play_until_done(k_warm, state, batch, policy, n_games, lambda a, _: a, None)
        _, state = jax.vmap(next_episode)(jax.random.split(k_next, n_games), state, batch)
    return _play_until_done(k_play, state, batch, policy, n_games, fold, acc)


@partial(jax.jit, static_argnames=("policy", "n_games"))
def _playtest(key: jax.Array, params: Params, policy: Policy, n_games: int, weights) -> dict[str, jax.Array]:
    state, _ = _play_games(key, broadcast_params(params, n_games), bind(policy, weights), n_games)
    return episode_summary(state)


def playtest(key: jax.Array, params: Params, policy: Policy, n_games: int, weights=None) -> dict[str, jax.Array]:
    """Play ``n_games`` games in parallel until every one has ended (win, loss or draw).

    Under the ``"reference"`` rules an arena's games depend on the one before (carried
    cooldowns, the 2023 reset exception), so every arena plays a discarded warm-up game first
    and the measured game is its next episode (about twice the cost; see docs/GAME.md). Under
    the ``"clean"`` rules every game is an arena's first.

    With several devices (GPUs, hosts after ``jax.distributed.initialize()``), the games are
    split evenly over all of them when ``n_games`` is a multiple of the device count
    (``raidjax.sharding``); the results are the same as on one device.

    Args:
        key: PRNG key (typed or a legacy ``uint32[2]`` key).
        params: content, unbatched or batched (see ``broadcast_params``).
        policy: ``policy(key, obs, state, params) -> int32[P]`` for one arena (e.g.
            ``raidjax.policies.heuristic``); it must be hashable (a function, not a lambda
            rebuilt every call, to avoid recompiling). With ``weights``, it is called
            ``policy(weights, key, obs, state, params)``.
        n_games: number of games, a whole number >= 1 (static: one compilation per value).
        weights: ``None``, or the policy's weights (a pytree of arrays). They are an argument of
            the compiled program, not constants in it, so evaluating many checkpoints of one
            network compiles once (``trainers.mapoca.load_policy`` returns ``(policy, weights)``).

    Returns:
        Dict of arrays with leading axis ``n_games``: ``outcome`` int32 (1 win, 2 loss, 3 draw),
        ``length`` int32 (decisions), ``damage`` float32[n, P] (to the boss), ``back_attacks``
        int32[n, P], ``deaths`` int32 (players dead at the end), ``alive`` bool[n, P],
        ``dropped`` int32 (projectiles dropped), ``boss_hp`` float32.

    Raises:
        ValueError: before anything compiles, as ``check_args``: ``n_games`` not a whole number
            >= 1 (``0``, ``-1``, ``2.5``, ``"3"``, ``True``), ``params`` not ``Params`` or batched
            wrongly, ``policy`` not a hashable callable, ``weights`` not a pytree of arrays.
    """
    return _playtest(key, params, policy, check_args(params, n_games, policy, weights), weights)


@partial(jax.jit, static_argnames=("policy", "n_games", "bins"))
def _playtest_occupancy(key: jax.Array, params: Params, policy: Policy, n_games: int, bins: int, weights) -> jax.Array:
    batch = broadcast_params(params, n_games)
    n_players = batch.team.shape[-1] - 1

    def count(counts, state):
        cell = grid_cell(state.pos[:, :n_players], bins)  # [n, P, 2]
        w = (state.alive[:, :n_players] & (state.result == RUNNING)[:, None]).astype(jnp.float32)
        player = jnp.broadcast_to(jnp.arange(n_players), w.shape)
        return counts.at[player, cell[..., 0], cell[..., 1]].add(w)

    _, counts = _play_games(key, batch, bind(policy, weights), n_games, count, jnp.zeros((n_players, bins, bins)))
    return counts / jnp.maximum(counts.sum((1, 2), keepdims=True), 1.0)


def playtest_occupancy(key: jax.Array, params: Params, policy: Policy, n_games: int,
                       bins: int = HEATMAP_BINS, weights=None) -> jax.Array:
    """Per-player position occupancy over the games ``playtest`` would play with the same key.

    Counts, at every decision (the reset state included) of every game still running, the cell
    of each alive player on a ``bins x bins`` grid over the arena (GAME.md §11), without storing
    traces, so 500 games x 2000 decisions cost no memory.

    Args:
        key, params, policy, n_games, weights: as ``playtest``.
        bins: grid size, a whole number >= 1 (24 in the paper; static).

    Returns:
        ``float32[P, bins, bins]`` indexed ``[player, x_bin, y_bin]``, each player's map summing
        to 1 (all zeros for a player never counted). Average over axis 0 for the team's map.

    Raises:
        ValueError: as ``playtest``, or ``bins`` not a whole number >= 1.
    """
    n_games = check_args(params, n_games, policy, weights)
    return _playtest_occupancy(key, params, policy, n_games, validate.whole_number("bins", bins, 1), weights)


def win_rate(results: dict[str, jax.Array]) -> jax.Array:
    """Share of wins (draws count as losses).

    Args:
        results: what ``playtest`` returns, at least ``outcome`` int32[n] with ``n >= 1``.

    Returns:
        ``float32[]`` in [0, 1].

    Raises:
        ValueError: ``results`` has no ``outcome`` array, or an empty one (its mean would be NaN).
    """
    outcome = results.get("outcome") if isinstance(results, Mapping) else None
    if outcome is None or not hasattr(outcome, "shape"):
        raise validate.fail("results", results, "the dict playtest returns, with an 'outcome' array")
    if outcome.size == 0:
        raise ValueError(f"results['outcome']: value of shape {tuple(outcome.shape)} is empty; "
                         "allowed: the outcomes of n_games >= 1 games")
    return jnp.mean(outcome == 1)


__all__ = ["playtest", "playtest_occupancy", "broadcast_params", "win_rate"]
