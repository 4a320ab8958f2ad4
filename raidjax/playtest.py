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
import numpy as np

from raidjax import validate
from raidjax.content import sensed_by
from raidjax.env import next_episode, reset, step
from raidjax.logs import HEATMAP_BINS, episode_summary, grid_cell
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


def _typed_key(key) -> jax.Array:
    """``key`` as a typed PRNG key array: a legacy ``uint32[..., 2]`` key becomes the typed key it
    stands for (``jax.random.wrap_key_data``: the same draws), a typed key is returned as it is. The
    playtests take both kinds and compile one program for the two."""
    key = jnp.asarray(key)
    return key if jnp.issubdtype(key.dtype, jax.dtypes.prng_key) else jax.random.wrap_key_data(key)


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


def _where_arenas(mask: jax.Array, a, b):
    """``a`` where ``mask`` (``bool[A, ...]``, the leading axes of every leaf) else ``b``, leaf by leaf."""
    return jax.tree.map(lambda x, y: jnp.where(mask.reshape(mask.shape + (1,) * (x.ndim - mask.ndim)), x, y), a, b)


def _flat(keys: jax.Array) -> jax.Array:
    """Typed keys ``[G, n]`` as ``[G * n]``, group after group."""
    return keys.reshape(-1)


def _play_games(key: jax.Array, batch: Params, policy: Policy, n_arenas: int, games_per_arena: int,
                fold=None, acc=None, grouped: bool = False):
    """Play ``games_per_arena`` measured games in a row in each of ``n_arenas`` arenas (``batch``:
    params with a leading ``n_arenas`` axis) and return ``(summaries, acc)``: ``episode_summary``
    of every measured game, each leaf ``[n_arenas, games_per_arena, ...]``, in the order played.

    An arena that ends a game starts its ``next_episode`` in the same decision's iteration, so no
    arena waits for the batch's longest game until it has played all of its own. Under rules
    whose episodes depend on the one before (``EnvConfig.chains_episodes``: the reference rules)
    each arena first plays one warm-up game, discarded, and its measured games follow it, as the
    reference build's arenas chain their games. ``fold(acc, state, counted: bool[n_arenas])`` sees
    the state at the start of every decision; ``counted`` marks the arenas playing a measured game.
    Keys are typed (the public functions wrap legacy ones, ``_typed_key``).

    With ``grouped``, ``key`` holds one key per group (``[G]``) and the arenas are ``G`` consecutive
    groups of ``n_arenas // G``: every group draws the keys its own call with its key would draw, so
    the games are those of ``G`` separate calls (a vmap over groups), in one loop. A single key is
    one group.
    """
    k = games_per_arena
    warm = 1 if batch.config.chains_episodes else 0
    max_t = (warm + k) * batch.config.max_decisions
    keys = key if grouped else key[None]  # [G]
    per = n_arenas // keys.shape[0]  # arenas of a group
    k_reset, k_play = jax.vmap(jax.random.split, out_axes=1)(keys)
    batch = shard_batch(batch, n_arenas)  # arenas are independent: spread them over every device
    obs, state = jax.vmap(reset)(_flat(jax.vmap(lambda k: jax.random.split(k, per))(k_reset)), batch)
    state = shard_batch(state, n_arenas)
    template = episode_summary(state)
    summaries = jax.tree.map(lambda x: jnp.zeros((n_arenas, k) + x.shape[1:], x.dtype), template)
    played = jnp.zeros(n_arenas, jnp.int32)  # games ended so far, warm-up included
    fold = fold or (lambda a, _s, _c: a)

    def play(carry):
        t, obs, state, played, summaries, acc = carry
        active = played < warm + k
        acc = fold(acc, state, active & (played >= warm))
        ks = jax.vmap(lambda k: jax.random.split(jax.random.fold_in(k, t), 3 * per))(k_play)
        keys = [_flat(ks[:, i * per:(i + 1) * per]) for i in range(3)]  # policy, step, next episode
        actions = jax.vmap(policy)(keys[0], obs, state, batch)
        obs, state, _, _, _ = jax.vmap(step)(keys[1], state, actions, batch)
        ended = active & (state.result != RUNNING)
        measured = ended & (played >= warm)
        slot = jax.nn.one_hot(played - warm, k, dtype=bool) & measured[:, None]  # [A, k]
        summary = jax.tree.map(lambda x: x[:, None], episode_summary(state))  # [A, 1, ...]
        summaries = _where_arenas(slot, summary, summaries)
        played = played + ended
        again = ended & (played < warm + k)
        obs_next, state_next = jax.vmap(next_episode)(keys[2], state, batch)
        obs, state = _where_arenas(again, (obs_next, state_next), (obs, state))
        return t + 1, obs, state, played, summaries, acc

    def running(carry):
        t, _, _, played, _, _ = carry
        return (t < max_t) & jnp.any(played < warm + k)

    carry = jax.lax.while_loop(running, play, (jnp.int32(0), obs, state, played, summaries, acc))
    return carry[4], carry[5]


def _flatten_games(summaries: dict[str, jax.Array]) -> dict[str, jax.Array]:
    """``[A, k, ...]`` -> ``[A * k, ...]``: game ``a * k + j`` is arena ``a``'s ``j``-th measured game,
    its chain ``position`` ``j``."""
    n_arenas, k = summaries["outcome"].shape[:2]
    flat = jax.tree.map(lambda x: x.reshape((-1,) + x.shape[2:]), summaries)
    return {**flat, "position": jnp.tile(jnp.arange(k, dtype=jnp.int32), n_arenas)}


@partial(jax.jit, static_argnames=("policy", "n_games", "games_per_arena"))
def _playtest(key: jax.Array, params: Params, policy: Policy, n_games: int, games_per_arena: int,
              weights) -> dict[str, jax.Array]:
    n_arenas = n_games // games_per_arena
    params = sensed_by(params, policy)
    summaries, _ = _play_games(key, broadcast_params(params, n_games // games_per_arena), bind(policy, weights),
                               n_arenas, games_per_arena)
    return _flatten_games(summaries)


def playtest_groups(keys: jax.Array, params: Params, policy: Policy, n_games: int,
                    games_per_arena: int | None = None, weights=None) -> dict[str, jax.Array]:
    """``G`` playtests in one loop, each of one content with its own key: the results of
    ``jax.vmap(lambda k, c: playtest(k, c, policy, n_games, weights, games_per_arena))(keys, params)``
    bit for bit, without a vmapped loop (every arena runs until its own games end; the lanes
    program runs as in a single playtest).

    Args:
        keys: ``G`` PRNG keys (typed ``[G]`` or raw ``uint32[G, 2]``).
        params: ``Params`` with a leading ``G`` axis on every leaf, one content per group.
        policy, n_games, games_per_arena, weights: as ``playtest``, per group (``weights`` shared).

    Returns:
        ``playtest``'s dict with leading axes ``[G, n_games]``.

    Raises:
        ValueError: before anything compiles, as ``playtest``, or ``keys`` without one key per group.
    """
    n = validate.whole_number("n_games", n_games, 1)
    if not isinstance(params, Params) or params.team.ndim != 2:
        raise validate.fail("params", params, "a raidjax.Params with one leading group axis on every leaf")
    groups = params.team.shape[0]
    if getattr(keys, "shape", ())[:1] != (groups,):
        raise ValueError(f"keys: shape {list(getattr(keys, 'shape', ()))}; allowed: one key per group, [{groups}]")
    check_args(params, n * groups, policy, weights)
    k = check_games_per_arena(params, n * groups, games_per_arena)
    return _playtest_groups(_typed_key(keys), params, policy, n, k, weights)


@partial(jax.jit, static_argnames=("policy", "n_games", "games_per_arena"))
def _playtest_groups(keys, params: Params, policy: Policy, n_games: int, games_per_arena: int, weights):
    groups = keys.shape[0]
    per = n_games // games_per_arena
    batch = jax.tree.map(lambda x: jnp.repeat(x, per, axis=0), sensed_by(params, policy))
    summaries, _ = _play_games(keys, batch, bind(policy, weights), groups * per, games_per_arena, grouped=True)
    return jax.tree.map(lambda x: x.reshape((groups, n_games) + x.shape[1:]), _flatten_games(summaries))


def playtest(key: jax.Array, params: Params, policy: Policy, n_games: int, weights=None,
             games_per_arena: int | None = None) -> dict[str, jax.Array]:
    """Play ``n_games`` games in ``n_games // games_per_arena`` parallel arenas, each arena playing
    its ``games_per_arena`` games in a row (``next_episode``), until every arena has played its own.

    This is raidjax's one protocol for a win rate, the paper's chained arenas: under the
    ``"reference"`` rules an arena's games depend on the one before (carried cooldowns, the 2023
    reset exception), so every arena plays one discarded warm-up game first and its measured games
    follow it, as the reference build's arenas chain their games (docs/GAME.md, "Episodes of one
    arena"); by default each arena then plays ``auto_games_per_arena`` games (10 for 1 000 games).
    Under the ``"clean"`` rules every game starts fresh. An arena that ends a game starts its next
    one at once, so arenas do not wait for the batch's longest game, and the warm-up is paid once
    per arena. ``results["position"]`` and ``win_rate_by_position`` tell the chain positions apart.

    With several devices (GPUs, hosts after ``jax.distributed.initialize()``), the arenas are
    split evenly over all of them when their number is a multiple of the device count
    (``raidjax.sharding``); the results are the same as on one device.

    Args:
        key: PRNG key (typed or a legacy ``uint32[2]`` key).
        params: content, unbatched or batched (see ``broadcast_params``; with a batch of ``G``
            contents each content's games are ``n_games // G`` consecutive games, which must be
            a multiple of ``games_per_arena`` so that every arena plays one content).
        policy: ``policy(key, obs, state, params) -> int32[P]`` for one arena (e.g.
            ``raidjax.policies.heuristic``); it must be hashable (a function, not a lambda
            rebuilt every call, to avoid recompiling). With ``weights``, it is called
            ``policy(weights, key, obs, state, params)``. A policy with a ``senses`` attribute
            plays with those senses (``raidjax.content.sensed_by``).
        n_games: number of measured games, a whole number >= 1 (static: one compilation per value).
        weights: ``None``, or the policy's weights (a pytree of arrays). They are an argument of
            the compiled program, not constants in it, so evaluating many checkpoints of one
            network compiles once (``trainers.mapoca.load_policy`` returns ``(policy, weights)``).
        games_per_arena: measured games each arena plays in a row, a whole number >= 1 dividing
            each content's games (static); ``None`` (the default): ``auto_games_per_arena`` of each
            content's games. ``1`` measures only each arena's first game after its warm-up.

    Returns:
        Dict of arrays with leading axis ``n_games`` (game ``a * games_per_arena + j`` is arena
        ``a``'s ``j``-th measured game): ``outcome`` int32 (1 win, 2 loss, 3 draw), ``length``
        int32 (decisions), ``damage`` float32[n, P] (to the boss), ``back_attacks`` int32[n, P],
        ``deaths`` int32 (players dead at the end), ``alive`` bool[n, P], ``dropped`` int32
        (projectiles dropped), ``boss_hp`` float32, ``boss_recharging`` bool[n, S] and
        ``in_flight`` int32 (what the game hands on to the arena's next one:
        ``raidjax.logs.episode_summary``), ``position`` int32 (``j``: 0 is the arena's first game
        after its warm-up).

    Raises:
        ValueError: before anything compiles, as ``check_args``: ``n_games`` not a whole number
            >= 1 (``0``, ``-1``, ``2.5``, ``"3"``, ``True``), ``params`` not ``Params`` or batched
            wrongly, ``policy`` not a hashable callable, ``weights`` not a pytree of arrays,
            ``games_per_arena`` not a whole number >= 1 dividing every content's games.
    """
    n_games = check_args(params, n_games, policy, weights)
    k = check_games_per_arena(params, n_games, games_per_arena)
    return _playtest(_typed_key(key), params, policy, n_games, k, weights)


MOST_GAMES_PER_ARENA = 10


def auto_games_per_arena(n_games: int, most: int = MOST_GAMES_PER_ARENA) -> int:
    """The ``games_per_arena`` raidjax's own measurements use for ``n_games`` games of one content:
    the largest whole number ``<= most`` dividing ``n_games`` (10 for 1000 games, 8 for 8, 1 for 7).

    Ten games in a row already pay the warm-up once per ten measured games and keep the arenas
    busy; more would leave too few arenas to fill the machine."""
    n = validate.whole_number("n_games", n_games, 1)
    return max(d for d in range(1, min(most, n) + 1) if n % d == 0)


def check_games_per_arena(params: Params, n_games: int, games_per_arena) -> int:
    """``games_per_arena`` as a Python ``int`` after checking that it is a whole number >= 1 that
    divides each content's games (``n_games``, or ``n_games // G`` for ``G`` contents); ``None`` is
    ``auto_games_per_arena`` of each content's games (raidjax's one protocol).

    Raises:
        ValueError: one line naming ``games_per_arena``, the value and what is allowed.
    """
    per_content = n_games // (params.team.shape[0] if params.team.ndim == 2 else 1)
    if games_per_arena is None:
        return auto_games_per_arena(per_content)
    k = validate.whole_number("games_per_arena", games_per_arena, 1)
    if per_content % k:
        raise ValueError(f"games_per_arena: value {k} does not divide the {per_content} games of each content; "
                         f"allowed: a whole number >= 1 dividing {per_content}")
    return k


@partial(jax.jit, static_argnames=("policy", "n_games", "bins", "games_per_arena"))
def _playtest_occupancy(key: jax.Array, params: Params, policy: Policy, n_games: int, bins: int,
                        games_per_arena: int, weights) -> jax.Array:
    batch = broadcast_params(sensed_by(params, policy), n_games // games_per_arena)
    n_players = batch.team.shape[-1] - 1

    def count(counts, state, counted):
        cell = grid_cell(state.pos[:, :n_players], bins)  # [A, P, 2]
        running = counted & (state.result == RUNNING)
        w = (state.alive[:, :n_players] & running[:, None]).astype(jnp.float32)
        player = jnp.broadcast_to(jnp.arange(n_players), w.shape)
        return counts.at[player, cell[..., 0], cell[..., 1]].add(w)

    _, counts = _play_games(key, batch, bind(policy, weights), n_games // games_per_arena, games_per_arena,
                            count, jnp.zeros((n_players, bins, bins)))
    return counts / jnp.maximum(counts.sum((1, 2), keepdims=True), 1.0)


def playtest_occupancy(key: jax.Array, params: Params, policy: Policy, n_games: int,
                       bins: int = HEATMAP_BINS, weights=None, games_per_arena: int | None = None) -> jax.Array:
    """Per-player position occupancy over the games ``playtest`` would play with the same key.

    Counts, at every decision (the start state included) of every measured game still running,
    the cell of each alive player on a ``bins x bins`` grid over the arena (PROTOCOLS.md §11), without
    storing traces, so 500 games x 2000 decisions cost no memory.

    Args:
        key, params, policy, n_games, weights, games_per_arena: as ``playtest``.
        bins: grid size, a whole number >= 1 (24 in the paper; static).

    Returns:
        ``float32[P, bins, bins]`` indexed ``[player, x_bin, y_bin]``, each player's map summing
        to 1 (all zeros for a player never counted). Average over axis 0 for the team's map.

    Raises:
        ValueError: as ``playtest``, or ``bins`` not a whole number >= 1.
    """
    n_games = check_args(params, n_games, policy, weights)
    k = check_games_per_arena(params, n_games, games_per_arena)
    return _playtest_occupancy(_typed_key(key), params, policy, n_games, validate.whole_number("bins", bins, 1), k,
                               weights)


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


def win_rate_by_position(results: dict) -> np.ndarray:
    """Win rate at each chain position, on the host: a diagnostic of how a game's outcome depends
    on the games its arena played before (docs/GAME.md, "Episodes of one arena").

    Args:
        results: what ``playtest`` or ``playtest_groups`` returns (``outcome`` and ``position``,
            any leading axes).

    Returns:
        ``float64[k]``: the share of wins among the games at position ``j`` (0: each arena's first
        game after its warm-up), ``k = games_per_arena``.

    Raises:
        ValueError: ``results`` without ``outcome`` and ``position`` arrays of one shape.
    """
    outcome = results.get("outcome") if isinstance(results, Mapping) else None
    position = results.get("position") if isinstance(results, Mapping) else None
    if outcome is None or position is None or np.shape(outcome) != np.shape(position) or np.size(outcome) == 0:
        raise validate.fail("results", results, "the dict playtest returns, with 'outcome' and 'position' arrays")
    won, pos = np.asarray(outcome).reshape(-1) == 1, np.asarray(position).reshape(-1)
    return np.bincount(pos, weights=won) / np.bincount(pos)


__all__ = ["playtest", "playtest_groups", "playtest_occupancy", "broadcast_params", "win_rate", "win_rate_by_position",
           "auto_games_per_arena"]
