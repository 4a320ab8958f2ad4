"""The content-generation environment (GAME.md §10), gymnax style: ``PCGParams`` / ``PCGState``
pytrees and pure ``reset`` / ``step`` / ``step_autoreset``.

A generator edits the players' shared skill slot 1 (range, cool time, cast time, coefficient;
projectile speed 10, cost 1, the rest as the reference mage) and is paid for moving the win
rate that the playtesting team reaches with it, measured over ``n_games`` games *inside* the
jitted step, toward a target win rate. The team is PT-HR (the paper's) unless
``PCGParams.tester`` names another policy, e.g. a trained MA-POCA team with its weights.

Episode start (our choice for "no reward on the first measurement"): ``reset`` draws the skill
uniformly within the bounds and the target (fixed, or uniform in ``[target_low, target_high]``),
and *measures* the initial win rate ``w_0`` (one playtest, no reward). Every edit then pays
``(|t - w_prev| - |t - w_new|) * 100``. An episode ends after ``max_edits`` edits, or earlier
when ``|w - t| <= band`` after an edit (not checked at reset; off with ``strict_length``).

``step_autoreset`` is the training variant that keeps exactly one playtest per call: a call
on an ended episode performs the reset (new skill, new target, its measurement) instead of an
edit and reports ``info["valid"] = False`` (the learner masks that transition out).

Two documented options, off by default (``PCGParams`` describes each): ``pool_repeats`` pools
the games of a re-measured unchanged skill (the 100-game standard error, about 0.05, is wider than
the ±0.02 band), and ``goal_axis`` draws a per-episode *style goal* at one end of a design axis
(e.g. heavy vs light skills), observed, that a learner may be charged the distance to
(``trainers.ppo_pcgrl.Config.goal_cost``).

Shapes are for one episode; ``jax.vmap`` runs many generator episodes in parallel, each with
its own batch of ``n_games`` playtests.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from raidjax import policies, validate
from raidjax.content import REFERENCE_PLAYERS, make_params
from raidjax.pcg.goals import check_axis, draw_goal
from raidjax.pcg.measurement import play_outcomes
from raidjax.pcg.space import PAPER_SPACE, Space, high, low, make_space, tick
from raidjax.playtest import check_args
from raidjax.types import Params

N_PARAMS, N_CHOICES = PAPER_SPACE.size, 5
NOOP_ACTION = 2  # choice 2 = 0 ticks on a branch
TICK_FRACTIONS = (-1.0, -0.5, 0.0, 0.5, 1.0)


@struct.dataclass
class PCGParams:
    """Environment parameters.

    Attributes:
        game: base ``raidjax.Params`` (``base_game``: three mages, skill slot 1 with projectile
            speed 10, cost 1, unless another team was chosen).
        target_low, target_high: ``float32[]``; the target is fixed when they are equal, else
            drawn uniformly per episode.
        band: ``float32[]`` early-termination half-width (0.02).
        n_games: playtest games per measurement (static).
        max_edits: edits per episode at most (static).
        strict_length: ``bool[]``, never end early (data: the paper's strict episodes and early-ending
            ones share a compiled program).
        observe_target: append target and last win rate to the observation (static).
        pool_repeats: an edit that leaves the skill unchanged (all-zero action, or a move
            clipped away) re-measures it and pools the new games with the earlier measurements of
            the same skill, so holding a skill sharpens its win rate; the observation then also
            carries ``sqrt(100 / games)``, proportional to the win rate's standard error (static;
            off = the paper's environment).
        goal_axis: a style axis, 4 signs in {-1, 0, 1} (static; ``None`` = no goal, the paper's
            environment). Each episode draws a goal at one end of the axis: the +1 parameters at
            their upper bound and the -1 ones at their lower bound, or the reverse (one coin); a
            0-signed parameter gets its own coin. The observation then ends with the scaled offset
            ``(goal - skill) / (high - low)``. ``raidjax.pcg.goals.HEAVY_VS_LIGHT`` has two strengthening and two
            weakening parameters (``Space.easier``), so both ends suit any target.
        tester: the playtesting team (static): a hashable ``policy(key, obs, state, params) ->
            int32[P]`` (default PT-HR, ``raidjax.policies.heuristic``, the paper's), or, with
            ``tester_weights``, ``policy(weights, key, obs, state, params)`` (e.g. a trained
            MA-POCA team from ``trainers.mapoca.load_policy``).
        tester_weights: ``None``, or the tester's weights (a pytree of arrays, traced: other
            weights of the same shapes reuse the compiled step).
        space: the edited parameters and their bounds (static; ``raidjax.pcg.space``; default the
            paper's four, ``PAPER_SPACE``). ``K = space.size`` below.
    """

    game: Params
    target_low: jax.Array
    target_high: jax.Array
    band: jax.Array
    n_games: int = struct.field(pytree_node=False, default=100)
    max_edits: int = struct.field(pytree_node=False, default=40)
    strict_length: jax.Array | bool = False
    observe_target: bool = struct.field(pytree_node=False, default=True)
    pool_repeats: bool = struct.field(pytree_node=False, default=False)
    goal_axis: tuple[int, ...] | None = struct.field(pytree_node=False, default=None)
    tester: Callable = struct.field(pytree_node=False, default=policies.heuristic)
    tester_weights: Any = None
    space: Space = struct.field(pytree_node=False, default=PAPER_SPACE)


@struct.dataclass
class PCGState:
    """One generator episode.

    Attributes:
        skill: ``float32[K]`` the edited parameters (the paper's: range, cool time, cast time,
            coefficient).
        target: ``float32[]`` target win rate.
        win_rate: ``float32[]`` last measured win rate.
        edits: ``int32[]`` edits made this episode.
        done: ``bool[]`` the episode has ended (``step_autoreset`` resets on the next call).
        reached: ``bool[]`` some measurement after an edit fell within the band.
        games: ``float32[]`` games behind ``win_rate`` (``n_games``, more when pooled).
        goal: ``float32[K]`` the episode's style goal (an end of ``goal_axis``; the start skill
            when there is no axis).
    """

    skill: jax.Array
    target: jax.Array
    win_rate: jax.Array
    edits: jax.Array
    done: jax.Array
    reached: jax.Array
    games: jax.Array
    goal: jax.Array


_BASE: dict[tuple[str, ...], Params] = {}
GENERATOR_MAGE = {"skill1.projectile_speed": 10.0, "skill1.cost": 1.0}  # the reference generator's mage skill


def base_game(players: tuple[str, ...] = REFERENCE_PLAYERS) -> Params:
    """The base content (built once per team with ``raidjax.make_params``): ``Params`` with
    ``U = len(players) + 1``. Every mage's skill slot 1 is the reference generator's (projectile
    speed 10, cost 1); other classes keep their catalogue presets."""
    players = tuple(players)
    if players not in _BASE:
        with jax.ensure_compile_time_eval():  # concrete arrays even when first called under jit
            _BASE[players] = make_params(players=list(players), player_overrides=[
                GENERATOR_MAGE if c == "mage" else {} for c in players])
    return _BASE[players]


def make_pcg_params(
    *, target: float | tuple[float, float] = (0.1, 0.7), n_games: int = 100, max_edits: int = 40,
    band: float = 0.02, strict_length: bool = False, observe_target: bool = True, pool_repeats: bool = False,
    goal_axis: tuple[int, ...] | None = None, tester: Callable = policies.heuristic, tester_weights: Any = None,
    parameters: Sequence[str] | None = None, players: Sequence[str] = REFERENCE_PLAYERS,
) -> PCGParams:
    """Build ``PCGParams`` on the host.

    Args:
        target: a fixed target win rate, or ``(low, high)`` to draw one uniformly per episode.
        n_games, max_edits, band, strict_length, observe_target, pool_repeats, goal_axis, tester,
            tester_weights: see ``PCGParams``.
        parameters: the edited parameters (``raidjax.pcg.space`` names; ``None``: the paper's four).
        players: the team's class presets (``base_game``); the default is the paper's three mages.

    Returns:
        ``PCGParams``.

    Raises:
        ValueError: naming the field, the value and what is allowed.
    """
    allowed = "a win rate in [0, 1], or (low, high) with 0 <= low <= high <= 1"
    pair = isinstance(target, list | tuple)
    if pair and len(target) != 2:
        raise validate.fail("target", target, allowed)
    lo, hi = (validate.number("target", t, allowed) for t in (target if pair else (target, target)))
    if not 0.0 <= lo <= hi <= 1.0:
        raise validate.fail("target", target, allowed, "out of range")
    n_games = validate.whole_number("n_games", n_games, 1)
    max_edits = validate.whole_number("max_edits", max_edits, 1)
    band = validate.number("band", band, "a number in [0, 1)")
    if not 0.0 <= band < 1.0:
        raise validate.fail("band", band, "a number in [0, 1)", "out of range")
    strict_length, observe_target, pool_repeats = (validate.flag(k, v) for k, v in (
        ("strict_length", strict_length), ("observe_target", observe_target), ("pool_repeats", pool_repeats)))
    f = lambda x: np.float32(x)
    space = make_space(parameters, players)
    game = base_game(tuple(players))
    check_args(game, n_games, tester, tester_weights)  # a hashable callable; weights a pytree of arrays
    return PCGParams(game=game, target_low=f(lo), target_high=f(hi), band=f(band), n_games=n_games,
                     max_edits=max_edits, strict_length=np.bool_(strict_length), observe_target=observe_target,
                     pool_repeats=pool_repeats, goal_axis=check_axis(goal_axis, space.size), tester=tester,
                     tester_weights=tester_weights, space=space)


def measure(key: jax.Array, params: PCGParams, skill: jax.Array, n_games: int | None = None) -> jax.Array:
    """Win rate of ``skill`` over ``n_games`` games of ``params.tester``.

    Args:
        key: PRNG key of the playtest.
        params: ``PCGParams``.
        skill: ``float32[K]`` values of the edited parameters (``K = params.space.size``).
        n_games: games to play (static); ``None`` (or 0): ``params.n_games``.

    Returns:
        ``float32[]``, the share of games won (draws and losses count as not won).
    """
    wins = play_outcomes(key, params.game, skill, n_games or params.n_games, params.tester, params.tester_weights,
                         params.space)
    return jnp.mean(wins.astype(jnp.float32))


def apply_action(skill: jax.Array, action: jax.Array, space: Space = PAPER_SPACE) -> jax.Array:
    """Edit a skill: ``action`` int32[K] in 0..4 -> {-1, -1/2, 0, +1/2, +1} ticks, clipped to ``space``'s bounds.

    Returns:
        ``float32[K]``.
    """
    frac = jnp.asarray(TICK_FRACTIONS, jnp.float32)[action]
    return jnp.clip(skill + frac * tick(space), low(space), high(space))


def reward_fn(target: jax.Array, w_prev: jax.Array, w_new: jax.Array) -> jax.Array:
    """``(|t - w_prev| - |t - w_new|) * 100`` (any broadcastable shapes)."""
    return (jnp.abs(target - w_prev) - jnp.abs(target - w_new)) * 100.0


def in_band(params: PCGParams, target: jax.Array, w: jax.Array) -> jax.Array:
    """``|w - t| <= band`` (with a 1e-6 tolerance for float rounding).

    Args:
        params: ``PCGParams`` (its ``band``, ``float32[]``).
        target: ``float32[...]`` target win rates.
        w: ``float32[...]`` win rates, broadcastable with ``target``.

    Returns:
        ``bool[...]``, the broadcast shape of ``target`` and ``w``.
    """
    return jnp.abs(w - target) <= params.band + 1e-6


def observe_pcg(state: PCGState, params: PCGParams) -> jax.Array:
    """Observation: the K parameters min-max scaled to [0, 1], then target and last win rate when
    ``params.observe_target``, then ``sqrt(100 / games)`` when ``params.pool_repeats``, then the
    offset to the style goal (scaled like the parameters, in [-1, 1]) when ``params.goal_axis``:
    ``float32[obs_size(params)]`` (4 to 11 for the paper's four)."""
    lo, hi = low(params.space), high(params.space)
    x = (state.skill - lo) / (hi - lo)
    if params.observe_target:
        x = jnp.concatenate([x, jnp.stack([state.target, state.win_rate])])
    if params.pool_repeats:
        x = jnp.concatenate([x, jnp.sqrt(100.0 / state.games)[None]])
    if params.goal_axis is not None:
        x = jnp.concatenate([x, (state.goal - state.skill) / (hi - lo)])
    return x.astype(jnp.float32)


def obs_size(params: PCGParams) -> int:
    """Length of the observation vector (K to 2K + 3)."""
    return (params.space.size * (1 + int(params.goal_axis is not None))
            + 2 * int(params.observe_target) + int(params.pool_repeats))


def _fresh(key: jax.Array, params: PCGParams, target: jax.Array | None):
    k_skill, k_target = jax.random.split(key)
    space = params.space
    skill = jax.random.uniform(k_skill, (space.size,), minval=low(space), maxval=high(space))
    if target is None:
        target = jax.random.uniform(k_target, (), minval=params.target_low, maxval=params.target_high)
    goal = skill if params.goal_axis is None else draw_goal(key, params.goal_axis, space)
    return skill, jnp.asarray(target, jnp.float32), goal


def _started(skill, target, w, goal, params: PCGParams) -> PCGState:
    """A new episode's state: ``skill`` measured at ``w``, no edits yet."""
    return PCGState(skill=skill, target=target, win_rate=w, edits=jnp.int32(0), done=jnp.bool_(False),
                    reached=jnp.bool_(False), games=jnp.float32(params.n_games), goal=goal)


def reset(key: jax.Array, params: PCGParams, target: jax.Array | None = None) -> tuple[jax.Array, PCGState]:
    """Start an episode: a skill drawn uniformly within the bounds, its measured win rate.

    Args:
        key: PRNG key.
        params: ``PCGParams``.
        target: optional ``float32[]`` target overriding the one drawn from ``params``.

    Returns:
        ``(obs, state)``: ``float32[obs_size]`` and ``PCGState``.
    """
    k_play, state = unmeasured_reset(key, params, target)
    state = state.replace(win_rate=measure(k_play, params, state.skill))
    return observe_pcg(state, params), state


def unmeasured_reset(key: jax.Array, params: PCGParams, target: jax.Array | None = None) -> tuple[jax.Array, PCGState]:
    """``reset``'s draws without its playtest, for a program that plays every measurement in one
    place (``raidjax.pcg.quality.generate``): returns ``(k_play, state)``, the key ``reset``
    measures the skill with and the new episode's ``PCGState`` with ``win_rate`` 0 (unmeasured).
    ``reset(key, ...)``'s state is this state with ``win_rate = measure(k_play, params, state.skill)``."""
    k_new, k_play = jax.random.split(key)
    skill, target, goal = _fresh(k_new, params, target)
    return k_play, _started(skill, target, jnp.float32(0.0), goal, params)


def awaiting_reset(params: PCGParams) -> tuple[jax.Array, PCGState]:
    """An ended placeholder episode, unmeasured: ``step_autoreset`` on it starts (and measures) a
    real one, as ``reset`` would, in a call whose transition is marked invalid. A learner that
    starts its arenas here holds no playtest in its initial program, which then compiles in
    seconds instead of compiling the whole game. Returns ``(obs, state)``: ``float32[obs_size]`` and a
    ``PCGState`` with ``done`` true, as ``reset``'s."""
    skill = low(params.space)
    state = _started(skill, jnp.float32(params.target_low), jnp.float32(0.0), skill, params).replace(
        done=jnp.bool_(True))
    return observe_pcg(state, params), state


def advance(state: PCGState, skill: jax.Array, w: jax.Array, params: PCGParams) -> tuple[PCGState, jax.Array]:
    """Book one edit whose skill ``float32[K]`` measured win rate ``w`` (``float32[]``, over
    ``n_games`` games): count it, pool ``w`` with the earlier games when ``pool_repeats`` and the
    skill is unchanged, pay ``reward_fn(t, state.win_rate, w)`` with that (pooled) ``w``, end the
    episode at ``max_edits`` or, unless ``strict_length``, inside the band.
    Returns ``(PCGState, reward float32[])``."""
    n = jnp.float32(params.n_games)
    games = n
    if params.pool_repeats:
        same = jnp.all(skill == state.skill)
        games = jnp.where(same, state.games + n, n)
        w = jnp.where(same, (state.win_rate * state.games + w * n) / games, w)
    edits = state.edits + 1
    close = in_band(params, state.target, w)
    done = (edits >= params.max_edits) | (close & ~jnp.asarray(params.strict_length))
    reward = reward_fn(state.target, state.win_rate, w)
    new = state.replace(skill=skill, win_rate=w, edits=edits, done=done, reached=state.reached | close, games=games)
    return new, reward


def step(key: jax.Array, state: PCGState, action: jax.Array, params: PCGParams):
    """Apply one edit and playtest it (no reset).

    Args:
        key: PRNG key for the playtest.
        state: ``PCGState`` of a running episode (stepping an ended one keeps editing; use
            ``step_autoreset`` for rollouts).
        action: ``int32[K]`` choices in 0..4.
        params: ``PCGParams``.

    Returns:
        ``(obs, state, reward, done, info)``: ``float32[obs_size]``, ``PCGState``, ``float32[]``,
        ``bool[]``, and a dict of scalars: ``win_rate`` (``float32[]``, the new, possibly pooled,
        measurement), ``edits`` (``int32[]``), ``reached`` (``bool[]``, ``PCGState.reached``) and
        ``valid`` (``bool[]``, always true here).
    """
    skill = apply_action(state.skill, action, params.space)
    new, reward = advance(state, skill, measure(key, params, skill), params)
    info = {"win_rate": new.win_rate, "edits": new.edits, "reached": new.reached, "valid": jnp.bool_(True)}
    return observe_pcg(new, params), new, reward, new.done, info


def step_autoreset(key: jax.Array, state: PCGState, action: jax.Array, params: PCGParams):
    """``step``, or, on an ended episode, a reset (new skill and target, measured) — one playtest
    either way.

    Args:
        key, state, action, params: as in ``step``.

    Returns:
        ``(obs, state, reward, done, info)`` as ``step`` (``float32[obs_size]``, ``PCGState``,
        ``float32[]``, ``bool[]``); a reset call pays 0, is not done and has ``info["valid"] = False``.
        ``info`` holds ``step``'s ``win_rate`` (``float32[]``), ``edits`` (``int32[]``), ``reached``
        and ``valid`` (``bool[]``), and ``final_error`` (``float32[]``, ``|t - w|`` of the new state;
        meaningful where done).
    """
    k_play, fresh = unmeasured_reset(key, params)
    skill = jnp.where(state.done, fresh.skill, apply_action(state.skill, action, params.space))
    w = measure(k_play, params, skill)
    edited, reward = advance(state, skill, w, params)
    started = fresh.replace(win_rate=w)
    new = jax.tree.map(lambda a, b: jnp.where(state.done, a, b), started, edited)
    reward = jnp.where(state.done, 0.0, reward)
    info = {"win_rate": new.win_rate, "edits": new.edits, "reached": new.reached, "valid": ~state.done,
            "final_error": jnp.abs(new.target - new.win_rate)}
    return observe_pcg(new, params), new, reward, new.done, info
