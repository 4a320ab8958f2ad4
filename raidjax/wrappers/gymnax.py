"""raidjax as gymnax ``Environment``s (gymnax >= 1.0), for single-agent learners such as PureJaxRL's.

Two views of one arena; the content is gymnax's ``params`` argument (a ``raidjax.Params``):

* ``RaidTeamEnv``: one learner plays the whole team. An action is one of ``A ** P`` joint ids
  (``A = config.n_actions``: 10, or 8 under the reference action space; player ``i``'s action is
  digit ``i`` in base ``A``, player 0 the lowest);
  the observation is every player's ``Observation.flat()`` row concatenated, ``float32[P * D]``;
  the reward is the team's, ``0.01 x`` its damage to the boss ``+ 1.0`` on a win.
* ``RaidPlayerEnv``: the learner plays player ``player``; its teammates follow ``teammates``, a
  ``policy(key, obs, state, params) -> int32[P]`` (default PT-HR, ``raidjax.policies.heuristic``).
  Observation ``float32[D]`` (its row), ``A`` actions, its own ``raidjax.step`` reward.

    import jax, raidjax
    from raidjax.wrappers.gymnax import RaidPlayerEnv

    env = RaidPlayerEnv()
    params = env.default_params                      # raidjax.make_params()
    obs, state = env.reset(jax.random.key(0), params)
    obs, state, reward, terminated, truncated, info = env.step(jax.random.key(1), state, 7, params)

``step`` returns gymnax 1.0's six values and auto-resets to the arena's next episode
(``raidjax.next_episode``: the reference rules' carried cooldowns survive); ``info`` holds
``terminated``, ``truncated``, ``final_observation`` (the observation the step reached),
``result`` (0 running, 1 win, 2 loss, 3 draw), ``returned_episode`` and, per player, ``alive``,
``damage_dealt`` and ``back_attack``. Time limits are the content's ``EnvConfig.max_decisions``
(a draw is a truncation).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
from gymnax.environments import spaces as gspaces
from gymnax.environments.environment import Environment

from raidjax import policies
from raidjax.content import make_params
from raidjax.env import check_actions, team_reward
from raidjax.observation import observe
from raidjax.spaces import spaces
from raidjax.types import DRAW, LOSS, WIN, Observation, Params
from raidjax.wrappers.common import ArenaState, start, step_arena


class _RaidView(Environment):
    """What both views share; subclasses say how actions, observations and rewards map. ``P``: players;
    ``D``: one player's ``Observation.flat()`` width (``obs_dim``); ``A``: ``config.n_actions``."""

    def __init__(self, params: Params | None = None):
        self._default = make_params() if params is None else params
        sp = spaces(self._default)
        self.n_players = sp.n_players
        self.obs_dim = sp.flat_observation.shape[-1]

    @property
    def default_params(self) -> Params:
        """The constructor's content (default ``raidjax.make_params()``)."""
        return self._default

    def _observation(self, obs: Observation) -> jax.Array:
        raise NotImplementedError

    def _actions(self, key, action, obs: Observation, state: ArenaState) -> jax.Array:
        raise NotImplementedError

    def _reward(self, reward: jax.Array, info: dict) -> jax.Array:
        raise NotImplementedError

    def reset_env(self, key: jax.Array, params: Params):
        """``reset`` without the default content: ``(obs, ArenaState)``, ``obs`` the learner's view
        (``float32[P * D]`` for the team, ``float32[D]`` for a player)."""
        obs, state = start(key, params)
        return self._observation(obs), state

    @partial(jax.jit, static_argnames=("self",))
    def reset(self, key: jax.Array, params: Params | None = None):
        """``(obs, ArenaState)`` of a new arena with content ``params`` (default: the constructor's);
        ``obs``: ``float32[P * D]`` (``RaidTeamEnv``) or ``float32[D]`` (``RaidPlayerEnv``)."""
        return self.reset_env(key, self.default_params if params is None else params)

    @partial(jax.jit, static_argnames=("self",))
    def step(self, key: jax.Array, state: ArenaState, action, params: Params | None = None):
        """One decision; auto-resets to the arena's next episode. ``action``: ``int[]`` (a joint id for
        the team, the player's action id for a player). Returns ``(obs, state, reward: float32[],
        terminated: bool[], truncated: bool[], info)`` (gymnax 1.0), ``obs`` as ``reset``'s and
        ``info`` as the module docstring says (``final_observation`` shaped as ``obs``, ``result``
        ``int32[]``, ``returned_episode`` ``bool[]``, per player ``alive`` ``bool[P]``,
        ``damage_dealt`` ``float32[P]``, ``back_attack`` ``int32[P]``)."""
        params = self.default_params if params is None else params
        state = state.replace(params=params)
        k_act, k_step = jax.random.split(key)
        now = observe(state.game, params)
        actions = check_actions(self._actions(k_act, jnp.asarray(action), now, state), params)
        obs, new, reward, terminated, truncated, info, final = step_arena(k_step, state, actions)
        info = {**info, "terminated": terminated, "truncated": truncated, "returned_episode": terminated | truncated,
                "final_observation": self._observation(final)}
        return self._observation(obs), new, self._reward(reward, info), terminated, truncated, info

    def step_env(self, key, state, action, params):
        """``step`` as gymnax's ``step_env`` tuple, auto-reset included: ``(obs, state, reward:
        float32[], terminated: bool[], info)`` (``truncated`` only in ``info``)."""
        obs, new, reward, terminated, _, info = self.step(key, state, action, params)
        return obs, new, reward, terminated, info

    def is_terminated(self, state: ArenaState, params: Params) -> jax.Array:
        """``bool[]``: ``state``'s episode ended in a win or a loss."""
        return (state.game.result == WIN) | (state.game.result == LOSS)

    def is_truncated(self, state: ArenaState, params: Params) -> jax.Array:
        """``bool[]``: ``state``'s episode ended in a draw (the ``max_decisions`` limit)."""
        return state.game.result == DRAW

    def get_obs(self, state: ArenaState, params=None, key=None) -> jax.Array:
        """The learner's observation of ``state`` (content: ``params``, default the state's own),
        shaped as ``reset``'s; ``key`` is unused."""
        return self._observation(observe(state.game, state.params if params is None else params))

    def observation_space(self, params: Params | None = None) -> gspaces.Box:
        """``Box`` of the learner's observation (unbounded ``float32``; the subclasses give its shape)."""
        raise NotImplementedError

    @property
    def name(self) -> str:
        """``"raidjax-RaidTeamEnv"`` or ``"raidjax-RaidPlayerEnv"``."""
        return "raidjax-" + type(self).__name__


class RaidTeamEnv(_RaidView):
    """One learner plays every player through a joint discrete action (see the module docstring).

    Args:
        params: default content (one arena's ``Params``); fixes the player count and shapes.
    """

    @property
    def num_actions(self) -> int:
        """Joint actions, ``A ** P`` (1000 for three players under raidjax's action space)."""
        return self.default_params.config.n_actions**self.n_players

    def action_space(self, params: Params | None = None) -> gspaces.Discrete:
        """``Discrete(A ** P)``: one joint id, ``int[]``."""
        return gspaces.Discrete(self.num_actions)

    def observation_space(self, params: Params | None = None) -> gspaces.Box:
        """Unbounded ``Box`` of ``float32[P * D]``, every player's ``flat()`` row, player 0 first."""
        return gspaces.Box(-jnp.inf, jnp.inf, (self.n_players * self.obs_dim,), jnp.float32)

    def decode(self, action: jax.Array, params: Params | None = None) -> jax.Array:
        """Joint id ``int[]`` -> ``int32[P]`` per-player actions (player 0 the lowest digit), in the
        action space of ``params`` (default: the constructor's)."""
        a = (self.default_params if params is None else params).config.n_actions
        return (action // a ** jnp.arange(self.n_players)) % a

    def _observation(self, obs: Observation) -> jax.Array:
        return obs.flat().reshape(-1)

    def _actions(self, key, action, obs, state):
        if action.shape != ():
            raise ValueError(f"action: shape {list(action.shape)}; allowed: one joint id (shape [])")
        return self.decode(action.astype(jnp.int32), state.params)

    def _reward(self, reward, info):
        return team_reward(info, info["terminated"])


class RaidPlayerEnv(_RaidView):
    """One learner plays player ``player``; ``teammates`` plays the others (module docstring).

    Args:
        params: default content (one arena's ``Params``).
        player: which player the learner controls, ``0 <= player < P``.
        teammates: a hashable ``policy(key, obs, state, params) -> int32[P]`` for the others.
    """

    def __init__(self, params: Params | None = None, player: int = 0, teammates=policies.heuristic):
        super().__init__(params)
        if isinstance(player, bool) or not isinstance(player, int) or not 0 <= player < self.n_players:
            raise ValueError(f"player: value {player!r}; allowed: a whole number in [0, {self.n_players - 1}]")
        self.player = player
        self.teammates = teammates

    @property
    def num_actions(self) -> int:
        """The player's actions, ``A = config.n_actions`` (10, or 8 under the reference action space)."""
        return self.default_params.config.n_actions

    def action_space(self, params: Params | None = None) -> gspaces.Discrete:
        """``Discrete(A)``: one action id, ``int[]``."""
        return gspaces.Discrete(self.num_actions)

    def observation_space(self, params: Params | None = None) -> gspaces.Box:
        """Unbounded ``Box`` of ``float32[D]``, the player's ``flat()`` row."""
        return gspaces.Box(-jnp.inf, jnp.inf, (self.obs_dim,), jnp.float32)

    def _observation(self, obs: Observation) -> jax.Array:
        return obs.flat()[self.player]

    def _actions(self, key, action, obs, state):
        if action.shape != ():
            raise ValueError(f"action: shape {list(action.shape)}; allowed: one action id (shape [])")
        others = self.teammates(key, obs, state.game, state.params)
        return others.at[self.player].set(action.astype(jnp.int32))

    def _reward(self, reward, info):
        return reward[self.player]
