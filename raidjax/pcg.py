"""Controllable skill generation (SPEC §10): a gymnax-style pure environment and the
PCG-RD / PCG-HR baselines.

A generator edits the players' shared skill slot 1 (range, cool time, cast time, coefficient;
projectile speed 10, cost 1, the rest as the reference mage) and is paid for moving the win
rate that PT-HR reaches with it, measured over ``n_games`` games *inside* the jitted step,
toward a target win rate.

Episode start (our choice for "no reward on the first measurement"): ``reset`` draws the skill
uniformly within the bounds and the target (fixed, or uniform in ``[target_low, target_high]``),
and *measures* the initial win rate ``w_0`` (one playtest, no reward). Every edit then pays
``(|t - w_prev| - |t - w_new|) * 100``. An episode ends after ``max_edits`` edits, or earlier
when ``|w - t| <= band`` after an edit (not checked at reset; off with ``strict_length``).

``step_autoreset`` is the training variant that keeps exactly one playtest per call: a call
on an ended episode performs the reset (new skill, new target, its measurement) instead of an
edit and reports ``info["valid"] = False`` (the learner masks that transition out).

Opt-in switches beyond SPEC §10, all off by default (``PCGParams`` documents each):
``pool_repeats`` pools the games of a re-measured unchanged skill (the 100-game SE, ≈ 0.05, is
wider than the ±0.02 band). The others draw per-episode context for Benchmark 2's diversity terms
(``raidjax.pcg_context``; a learner, ``trainers.ppo_pcgrl``, is charged by it): the start skill,
edit preferences, a designated parameter per edit and a style goal, each on its own key stream.

Shapes are for one episode; ``jax.vmap`` runs many generator episodes in parallel, each with
its own batch of ``n_games`` playtests.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

import raidjax
from raidjax import pcg_context as context
from raidjax.content import with_player_skill
from raidjax.types import Params

PARAM_NAMES = ("range", "cool_time", "cast_time", "coefficient")
LOW = (1.0, 0.5, 0.5, 0.5)
HIGH = (20.0, 0.6, 1.5, 1.0)
# +1 where a larger value makes the skill stronger ("easier" for the players).
EASIER = (1.0, -1.0, -1.0, 1.0)
N_PARAMS, N_CHOICES = 4, 5
NOOP_ACTION = 2  # choice 2 = 0 ticks on a branch
TICK_FRACTIONS = (-1.0, -0.5, 0.0, 0.5, 1.0)


def low() -> jax.Array:
    """Lower bounds ``float32[4]``."""
    return jnp.asarray(LOW, jnp.float32)


def high() -> jax.Array:
    """Upper bounds ``float32[4]``."""
    return jnp.asarray(HIGH, jnp.float32)


def tick() -> jax.Array:
    """One tick per parameter, ``(max - min) / 6``: ``float32[4]``."""
    return (high() - low()) / 6.0


@struct.dataclass
class PCGParams:
    """Environment parameters.

    Attributes:
        game: base ``raidjax.Params`` (three mages, skill slot 1 with projectile speed 10, cost 1).
        target_low, target_high: ``float32[]``; the target is fixed when they are equal, else
            drawn uniformly per episode.
        band: ``float32[]`` early-termination half-width (0.02).
        n_games: playtest games per measurement (static).
        max_edits: edits per episode at most (static).
        strict_length: never end early (static).
        observe_target: append target and last win rate to the observation (static).
        pool_repeats: an edit that leaves the skill unchanged (all-zero action, or a move
            clipped away) re-measures it and pools the new games with the earlier measurements of
            the same skill, so holding a skill sharpens its win rate; the observation then also
            carries ``sqrt(100 / games)``, proportional to the win rate's standard error (static;
            off = SPEC §10).
        observe_start: append the displacement from the episode's start skill, min-max scaled
            (``(skill - start) / (high - low)``, 4 values in [-1, 1]), to the observation (static;
            off = SPEC §10).
        edit_preferences: draw per-episode edit weights (``pcg_context.draw_preferences``) and
            append them / 4 to the observation (static; off = all ones, not observed).
        favourite_weight: with ``edit_preferences``, one favourite parameter of this weight
            instead of the softmax draw (static; ``None`` = softmax).
        observe_lever: draw a designated parameter uniformly at reset and after every edit and
            append it one-hot to the observation (static; off = lever 0, not observed).
        observe_goal: draw a style goal per episode at a random corner of the box
            (``pcg_context.draw_goal``) and append the scaled offset ``(goal - skill) / (high -
            low)`` to the observation (static; off = the goal is the start skill, not observed).
        goal_axis: with ``observe_goal``, 4 signs in {-1, 0, 1}: the goal is one end of this axis
            (``(1, 1, 1, 1)``: "heavy" all high or "light" all low; two strengthening and two
            weakening parameters, ``EASIER``, so both ends suit any target) (static; ``None`` =
            independent corners).
    """

    game: Params
    target_low: jax.Array
    target_high: jax.Array
    band: jax.Array
    n_games: int = struct.field(pytree_node=False, default=100)
    max_edits: int = struct.field(pytree_node=False, default=40)
    strict_length: bool = struct.field(pytree_node=False, default=False)
    observe_target: bool = struct.field(pytree_node=False, default=True)
    pool_repeats: bool = struct.field(pytree_node=False, default=False)
    observe_start: bool = struct.field(pytree_node=False, default=False)
    edit_preferences: bool = struct.field(pytree_node=False, default=False)
    favourite_weight: float | None = struct.field(pytree_node=False, default=None)
    observe_lever: bool = struct.field(pytree_node=False, default=False)
    observe_goal: bool = struct.field(pytree_node=False, default=False)
    goal_axis: tuple[int, ...] | None = struct.field(pytree_node=False, default=None)


@struct.dataclass
class PCGState:
    """One generator episode.

    Attributes:
        skill: ``float32[4]`` range, cool time, cast time, coefficient.
        target: ``float32[]`` target win rate.
        win_rate: ``float32[]`` last measured win rate.
        edits: ``int32[]`` edits made this episode.
        done: ``bool[]`` the episode has ended (``step_autoreset`` resets on the next call).
        reached: ``bool[]`` some measurement after an edit fell within the band.
        games: ``float32[]`` games behind ``win_rate`` (``n_games``, more when pooled).
        start: ``float32[4]`` the skill the episode started from.
        preferences: ``float32[4]`` per-parameter edit weights of the episode (ones unless
            ``edit_preferences``); the environment only observes them, a learner may be charged by them.
        lever: ``int32[]`` the parameter designated for the next edit (0 unless ``observe_lever``);
            observed, not enforced.
        goal: ``float32[4]`` the episode's style goal (a corner of the box with ``observe_goal``,
            else the start skill); observed, a learner may be charged by the distance to it.
    """

    skill: jax.Array
    target: jax.Array
    win_rate: jax.Array
    edits: jax.Array
    done: jax.Array
    reached: jax.Array
    games: jax.Array
    start: jax.Array
    preferences: jax.Array
    lever: jax.Array
    goal: jax.Array


_BASE: list[Params] = []


def base_game() -> Params:
    """The base content (built once with ``raidjax.make_params``): ``Params`` with ``U = 4``."""
    if not _BASE:
        with jax.ensure_compile_time_eval():  # concrete arrays even when first called under jit
            _BASE.append(raidjax.make_params(**{"skill1.projectile_speed": 10.0, "skill1.cost": 1.0}))
    return _BASE[0]


def make_params(
    *, target: float | tuple[float, float] = (0.1, 0.7), n_games: int = 100, max_edits: int = 40,
    band: float = 0.02, strict_length: bool = False, observe_target: bool = True, pool_repeats: bool = False,
    observe_start: bool = False, edit_preferences: bool = False, favourite_weight: float | None = None,
    observe_lever: bool = False, observe_goal: bool = False, goal_axis: tuple[int, ...] | None = None,
) -> PCGParams:
    """Build ``PCGParams`` on the host.

    Args:
        target: a fixed target win rate, or ``(low, high)`` to draw one uniformly per episode.
        n_games, max_edits, band, strict_length, observe_target, pool_repeats, observe_start,
            edit_preferences, favourite_weight, observe_lever, observe_goal, goal_axis: see ``PCGParams``.

    Returns:
        ``PCGParams``.
    """
    lo, hi = (target, target) if isinstance(target, int | float) else target
    if not 0.0 <= lo <= hi <= 1.0:
        raise ValueError(f"target: value {target} must lie in [0, 1] with low <= high")
    if n_games < 1 or max_edits < 1:
        raise ValueError(f"n_games={n_games}, max_edits={max_edits}: both must be >= 1")
    favourite_weight, goal_axis = context.check(edit_preferences, favourite_weight, observe_goal, goal_axis,
                                               PARAM_NAMES)
    f = lambda x: np.float32(x)
    return PCGParams(game=base_game(), target_low=f(lo), target_high=f(hi), band=f(band), n_games=n_games,
                     max_edits=max_edits, strict_length=strict_length, observe_target=observe_target,
                     pool_repeats=pool_repeats, observe_start=observe_start, edit_preferences=edit_preferences,
                     favourite_weight=favourite_weight, observe_lever=observe_lever, observe_goal=observe_goal,
                     goal_axis=goal_axis)


def skill_params(game: Params, skill: jax.Array) -> Params:
    """Put ``skill`` (``float32[4]``) into every player's skill slot 1 of ``game``; returns ``Params``."""
    return with_player_skill(game, **dict(zip(PARAM_NAMES, skill, strict=True)))


def play_outcomes(key: jax.Array, game: Params, skill: jax.Array, n_games: int) -> jax.Array:
    """PT-HR plays ``n_games`` games with ``skill`` (``float32[4]``); returns ``bool[n_games]`` wins
    (draws and losses are ``False``)."""
    res = raidjax.playtest(key, skill_params(game, skill), raidjax.policies.heuristic, n_games)
    return res["outcome"] == raidjax.types.WIN


def measure(key: jax.Array, params: PCGParams, skill: jax.Array, n_games: int | None = None) -> jax.Array:
    """Win rate ``float32[]`` of ``skill`` over ``n_games`` (default ``params.n_games``) PT-HR games."""
    return jnp.mean(play_outcomes(key, params.game, skill, n_games or params.n_games).astype(jnp.float32))


def apply_action(skill: jax.Array, action: jax.Array) -> jax.Array:
    """Edit a skill: ``action`` int32[4] in 0..4 -> {-1, -1/2, 0, +1/2, +1} ticks, clipped to bounds.

    Returns:
        ``float32[4]``.
    """
    frac = jnp.asarray(TICK_FRACTIONS, jnp.float32)[action]
    return jnp.clip(skill + frac * tick(), low(), high())


def reward_fn(target: jax.Array, w_prev: jax.Array, w_new: jax.Array) -> jax.Array:
    """``(|t - w_prev| - |t - w_new|) * 100`` (any broadcastable shapes)."""
    return (jnp.abs(target - w_prev) - jnp.abs(target - w_new)) * 100.0


def in_band(params: PCGParams, target: jax.Array, w: jax.Array) -> jax.Array:
    """``|w - t| <= band`` (with a 1e-6 tolerance for float rounding): ``bool``."""
    return jnp.abs(w - target) <= params.band + 1e-6


def observe(state: PCGState, params: PCGParams) -> jax.Array:
    """Observation: the 4 parameters min-max scaled to [0, 1], then target and last win rate when
    ``params.observe_target``, then ``sqrt(100 / games)`` when ``params.pool_repeats``, then the
    displacement from the start skill (scaled like the parameters, in [-1, 1]) when
    ``params.observe_start``, then the edit preferences / 4 when ``params.edit_preferences``, then
    the lever one-hot when ``params.observe_lever``, then the offset to the goal when
    ``params.observe_goal``: ``float32[obs_size(params)]`` (4 to 23)."""
    x = (state.skill - low()) / (high() - low())
    if params.observe_target:
        x = jnp.concatenate([x, jnp.stack([state.target, state.win_rate])])
    if params.pool_repeats:
        x = jnp.concatenate([x, jnp.sqrt(100.0 / state.games)[None]])
    if params.observe_start:
        # scaled like the parameters: in ticks (up to ±6) PPO stalled, likely on saturated tanh layers
        x = jnp.concatenate([x, (state.skill - state.start) / (high() - low())])
    if params.edit_preferences:
        x = jnp.concatenate([x, state.preferences / N_PARAMS])
    if params.observe_lever:
        x = jnp.concatenate([x, jax.nn.one_hot(state.lever, N_PARAMS)])
    if params.observe_goal:
        x = jnp.concatenate([x, (state.goal - state.skill) / (high() - low())])
    return x.astype(jnp.float32)


def obs_size(params: PCGParams) -> int:
    """Length of the observation vector (4 to 23)."""
    flags = params.observe_start, params.edit_preferences, params.observe_lever, params.observe_goal
    return (N_PARAMS * (1 + sum(map(int, flags)))
            + 2 * int(params.observe_target) + int(params.pool_repeats))


def displacement(skill: jax.Array, start: jax.Array) -> jax.Array:
    """Squared distance from ``start`` in ticks (``pcg_context.displacement``): ``float32[...]`` for
    ``float32[..., 4]`` inputs."""
    return context.displacement(skill, start, tick())


def _lever(key: jax.Array, params: PCGParams) -> jax.Array:
    """The next designated parameter ``int32[]``: uniform with ``observe_lever``, else 0."""
    return context.draw_lever(jax.random.fold_in(key, 11), N_PARAMS) if params.observe_lever else jnp.int32(0)


def _fresh(key: jax.Array, params: PCGParams, target: jax.Array | None):
    k_skill, k_target = jax.random.split(key)
    skill = jax.random.uniform(k_skill, (N_PARAMS,), minval=low(), maxval=high())
    if target is None:
        target = jax.random.uniform(k_target, (), minval=params.target_low, maxval=params.target_high)
    prefs = jnp.ones((N_PARAMS,), jnp.float32)
    if params.edit_preferences:
        prefs = context.draw_preferences(jax.random.fold_in(key, 7), N_PARAMS, params.favourite_weight)
    goal = skill
    if params.observe_goal:
        goal = context.draw_goal(jax.random.fold_in(key, 13), jax.random.fold_in(key, 17), low(), high(),
                                 params.goal_axis)
    return skill, jnp.asarray(target, jnp.float32), prefs, goal


def _started(skill, target, w, prefs, goal, lever, params: PCGParams) -> PCGState:
    """A new episode's state: ``skill`` (also its start) measured at ``w``, no edits yet."""
    return PCGState(skill=skill, target=target, win_rate=w, edits=jnp.int32(0), done=jnp.bool_(False),
                    reached=jnp.bool_(False), games=jnp.float32(params.n_games), start=skill, preferences=prefs,
                    lever=lever, goal=goal)


def reset(key: jax.Array, params: PCGParams, target: jax.Array | None = None) -> tuple[jax.Array, PCGState]:
    """Start an episode: a skill drawn uniformly within the bounds, its measured win rate.

    Args:
        key: PRNG key.
        params: ``PCGParams``.
        target: optional ``float32[]`` target overriding the one drawn from ``params``.

    Returns:
        ``(obs, state)``: ``float32[obs_size]`` and ``PCGState``.
    """
    k_new, k_play = jax.random.split(key)
    skill, target, prefs, goal = _fresh(k_new, params, target)
    w = measure(k_play, params, skill)
    state = _started(skill, target, w, prefs, goal, _lever(k_new, params), params)
    return observe(state, params), state


def advance(state: PCGState, skill: jax.Array, w: jax.Array, params: PCGParams) -> tuple[PCGState, jax.Array]:
    """Book one edit whose skill ``float32[4]`` measured win rate ``w`` (``float32[]``, over
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
    done = edits >= params.max_edits
    if not params.strict_length:
        done = done | close
    reward = reward_fn(state.target, state.win_rate, w)
    new = state.replace(skill=skill, win_rate=w, edits=edits, done=done, reached=state.reached | close, games=games)
    return new, reward


def step(key: jax.Array, state: PCGState, action: jax.Array, params: PCGParams):
    """Apply one edit and playtest it (no reset).

    Args:
        key: PRNG key for the playtest.
        state: ``PCGState`` of a running episode (stepping an ended one keeps editing; use
            ``step_autoreset`` for rollouts).
        action: ``int32[4]`` choices in 0..4.
        params: ``PCGParams``.

    Returns:
        ``(obs, state, reward, done, info)``: ``float32[obs_size]``, ``PCGState``, ``float32[]``,
        ``bool[]``, dict with ``win_rate``, ``edits``, ``reached``.
    """
    skill = apply_action(state.skill, action)
    w = measure(key, params, skill)
    new, reward = advance(state, skill, w, params)
    new = new.replace(lever=_lever(key, params))
    info = {"win_rate": new.win_rate, "edits": new.edits, "reached": new.reached, "valid": jnp.bool_(True)}
    return observe(new, params), new, reward, new.done, info


def step_autoreset(key: jax.Array, state: PCGState, action: jax.Array, params: PCGParams):
    """``step``, or, on an ended episode, a reset (new skill and target, measured) — one playtest
    either way.

    Args:
        key, state, action, params: as in ``step``.

    Returns:
        ``(obs, state, reward, done, info)`` as ``step``; a reset call pays 0, is not done and
        has ``info["valid"] = False``. ``info["final_error"]`` is ``|t - w|`` (meaningful where done).
    """
    k_new, k_play = jax.random.split(key)
    fresh_skill, fresh_target, fresh_prefs, fresh_goal = _fresh(k_new, params, None)
    skill = jnp.where(state.done, fresh_skill, apply_action(state.skill, action))
    w = measure(k_play, params, skill)
    edited, reward = advance(state, skill, w, params)
    started = _started(skill, fresh_target, w, fresh_prefs, fresh_goal, state.lever, params)
    new = jax.tree.map(lambda a, b: jnp.where(state.done, a, b), started, edited)
    new = new.replace(lever=_lever(key, params))
    reward = jnp.where(state.done, 0.0, reward)
    info = {"win_rate": new.win_rate, "edits": new.edits, "reached": new.reached, "valid": ~state.done,
            "final_error": jnp.abs(new.target - new.win_rate)}
    return observe(new, params), new, reward, new.done, info


# --- baselines (pure policies: policy(policy_params, key, obs, state, params) -> int32[4]) ---

def random_policy(policy_params, key: jax.Array, obs: jax.Array, state: PCGState, params: PCGParams) -> jax.Array:
    """PCG-RD: a uniformly random choice on each of the 4 branches. Returns ``int32[4]``."""
    return jax.random.randint(key, (N_PARAMS,), 0, N_CHOICES, jnp.int32)


def heuristic_policy(policy_params, key: jax.Array, obs: jax.Array, state: PCGState, params: PCGParams) -> jax.Array:
    """PCG-HR (Algorithm 2): nothing if ``|w - t| < band``; else one random parameter moved half a
    tick toward easier (range up, cool down, cast down, coefficient up) when ``w < t``, toward
    harder otherwise. Returns ``int32[4]``."""
    j = jax.random.randint(key, (), 0, N_PARAMS)
    sign = jnp.where(state.win_rate < state.target, 1.0, -1.0) * jnp.asarray(EASIER, jnp.float32)[j]
    act = jnp.full((N_PARAMS,), NOOP_ACTION, jnp.int32).at[j].set(NOOP_ACTION + sign.astype(jnp.int32))
    close = jnp.abs(state.win_rate - state.target) < params.band
    return jnp.where(close, NOOP_ACTION, act)


__all__ = [
    "PCGParams", "PCGState", "make_params", "reset", "step", "step_autoreset", "observe", "obs_size",
    "apply_action", "advance", "reward_fn", "measure", "play_outcomes", "skill_params", "random_policy",
    "heuristic_policy", "tick", "low", "high", "PARAM_NAMES", "EASIER", "displacement",
]
