"""Scripted playtesting policies (GAME.md §9), pure and jittable.

A policy is ``policy(key, obs, state, params) -> int32[P]`` for one arena.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp

from raidjax.types import ACTION_HEURISTIC, CAST_1, TRIGGER_PASSIVE, Observation, Params, State
from raidjax.utils import uniform_dice


def random(key: jax.Array, obs: Observation, state: State, params: Params) -> jax.Array:
    """PT-RD: a uniformly random action per player among the 7 movement actions and the cast
    actions of the active skill slots it has (0–7 for the reference mage), ignoring whether
    the cast is usable now. Under the reference action space: its 7 movement ids and its cast.

    Returns:
        ``int32[P]`` actions.
    """
    n_players = params.team.shape[0] - 1
    sk = params.skills
    has = (sk.in_use[:n_players] > 0) & (sk.trigger[:n_players] != TRIGGER_PASSIVE)  # [P, S]
    if params.config.action_space == "reference":
        has = has[:, :1]  # the reference's one cast action (slot 0)
    allowed = jnp.concatenate([jnp.ones((n_players, CAST_1), bool), has], axis=-1)
    # Inverse-CDF sampling with the cheap counter-hash dice (threefry costs more than a step).
    u = uniform_dice(key, (n_players,))
    count = jnp.sum(allowed, axis=-1)
    k = jnp.minimum(jnp.floor(u * count), count - 1).astype(jnp.int32)  # k-th allowed action
    rank = jnp.cumsum(allowed, axis=-1) - 1
    return jnp.argmax(allowed & (rank == k[:, None]), axis=-1).astype(jnp.int32)


def heuristic(key: jax.Array, obs: Observation, state: State, params: Params) -> jax.Array:
    """PT-HR (the paper's Algorithm 1 as the reference build runs it), carried out by the
    simulator's built-in script (``raidjax.heuristic``): approach to the preferred distance,
    circle the boss in the per-episode direction, face it, cast every usable skill.

    Returns:
        ``int32[P]`` filled with ``ACTION_HEURISTIC``.
    """
    n_players = params.team.shape[0] - 1
    return jnp.full((n_players,), ACTION_HEURISTIC, jnp.int32)


def noop(key: jax.Array, obs: Observation, state: State, params: Params) -> jax.Array:
    """Every player does nothing. Returns ``int32[P]`` zeros."""
    return jnp.zeros((params.team.shape[0] - 1,), jnp.int32)


SCRIPTS = ("heuristic", "random")


def script(which: jax.Array, key: jax.Array, obs: Observation, state: State, params: Params) -> jax.Array:
    """The scripted policy named ``SCRIPTS[which]`` (``which``: ``int32[]``, a traced argument).

    ``raidjax.playtest(key, params, script, n, weights=jnp.int32(i))`` plays PT-HR (``i = 0``) or
    PT-RD (``i = 1``) with one compiled program for both (``raidjax.calibrate`` compiles once).

    Returns:
        ``int32[P]`` actions: those of ``heuristic`` or of ``random`` with the same key.
    """
    return jnp.where(which == 0, heuristic(key, obs, state, params), random(key, obs, state, params))


@dataclasses.dataclass(frozen=True)
class OrHeuristic:
    """A policy with weights, ``policy(weights, key, obs, state, params) -> int32[P]``, or PT-HR,
    chosen by data: ``OrHeuristic(policy)`` is called with weights ``(scripted, policy_weights)``
    (``scripted``: ``bool[]``, traced; see ``weights``). One compiled program then plays both
    teams, e.g. a learned tester and PT-HR in the balancing loop (``experiments.balance``), which
    would otherwise compile every playtesting program twice.

    With ``scripted`` unbatched (the weights bound to a playtest, as usual) the choice is a
    ``lax.cond``: PT-HR does not run the network. The policy's ``senses`` (if any) are this
    wrapper's, so PT-HR plays under them too; a ``heuristic`` team acts the same under either.
    """

    policy: Callable

    @property
    def senses(self) -> str | None:
        """The wrapped policy's ``senses`` (``"raidjax"`` or ``"reference"``), ``None`` if it has none."""
        return getattr(self.policy, "senses", None)

    @staticmethod
    def weights(policy_weights, scripted: bool):
        """The weights that make ``OrHeuristic(policy)`` play ``policy`` with ``policy_weights``
        (``scripted=False``) or PT-HR (``True``; ``policy_weights`` only give the shapes).

        Returns:
            ``(bool[] scripted, policy_weights)``, the tuple ``__call__`` takes as ``weights``.
        """
        return jnp.bool_(scripted), policy_weights

    def __call__(self, weights, key: jax.Array, obs: Observation, state: State, params: Params) -> jax.Array:
        scripted, policy_weights = weights
        return jax.lax.cond(scripted, lambda: heuristic(key, obs, state, params),
                            lambda: self.policy(policy_weights, key, obs, state, params).astype(jnp.int32))


BY_NAME = {"random": random, "heuristic": heuristic, "noop": noop}
