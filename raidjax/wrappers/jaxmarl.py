"""raidjax as a JaxMARL ``MultiAgentEnv``: one agent per player, content per arena kept.

    import jax, raidjax
    from raidjax.wrappers.jaxmarl import RaidMultiAgentEnv

    env = RaidMultiAgentEnv(raidjax.make_params(skill_range=13.0))
    obs, state = env.reset(jax.random.key(0))                   # obs["player_0"]: float32[D]
    actions = {a: env.action_space(a).sample(k) for a, k in zip(env.agents, jax.random.split(key, 3))}
    obs, state, rewards, dones, infos = env.step(jax.random.key(1), state, actions)

Agents are ``player_0 .. player_{P-1}``. Each observes its row of the observation's ``flat()``
(``float32[D]``: raidjax's observation with its action mask, or the reference's 204 floats) and
takes one of ``A = config.n_actions`` discrete actions, as an ``int[]`` or, as JaxMARL's
baselines hand them, an ``int[1]``; ``get_avail_actions`` gives the masks. ``rewards[a]`` is
``raidjax.step``'s per-player reward.
``dones[a]`` is true once player ``a`` is dead or the episode ended; ``dones["__all__"]`` when
the episode ended. Every ``infos`` value has one entry per agent (``float32``/``bool``/``int32[P]``,
the layout JaxMARL's learners reshape to ``NUM_ACTORS``): ``terminated``, ``truncated``,
``result`` (0 running, 1 win, 2 loss, 3 draw) and ``returned_episode`` (the episode ended this
step), and per player ``alive``, ``damage_dealt``, ``back_attack``.

``step`` auto-resets to the arena's *next* episode (``raidjax.next_episode``), so the reference
rules' carried cooldowns survive, and the content in the state (``ArenaState.params``) stays:
``jax.vmap(env.reset)(keys, batch_of_params)`` gives every arena its own content for good.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
from jaxmarl.environments.multi_agent_env import MultiAgentEnv
from jaxmarl.environments.spaces import Box, Discrete

from raidjax.content import make_params
from raidjax.env import check_actions
from raidjax.observation import action_mask, observe
from raidjax.spaces import spaces
from raidjax.types import RUNNING, Params
from raidjax.wrappers.common import ArenaState, start, step_arena


class RaidMultiAgentEnv(MultiAgentEnv):
    """A JaxMARL environment over raidjax arenas.

    Args:
        params: the default content (one arena's ``Params``), used when ``reset`` is given none;
            default ``raidjax.make_params()``. Its player count and ``EnvConfig`` fix the shapes
            of every content this environment takes.
    """

    def __init__(self, params: Params | None = None):
        self.default_params = make_params() if params is None else params
        sp = spaces(self.default_params)
        super().__init__(num_agents=sp.n_players)
        self.agents = [f"player_{i}" for i in range(sp.n_players)]
        self.obs_dim = sp.flat_observation.shape[-1]
        self.observation_spaces = {a: Box(-jnp.inf, jnp.inf, (self.obs_dim,)) for a in self.agents}
        self.action_spaces = {a: Discrete(sp.n_actions) for a in self.agents}

    def _split(self, x) -> dict:
        return {a: x[i] for i, a in enumerate(self.agents)}

    @partial(jax.jit, static_argnums=(0,))
    def reset(self, key: jax.Array, params: Params | None = None) -> tuple[dict, ArenaState]:
        """``(obs, ArenaState)`` of a new arena, ``obs`` ``{agent: float32[D]}``; ``params`` (one arena's)
        defaults to the constructor's."""
        obs, state = start(key, self.default_params if params is None else params)
        return self._split(obs.flat()), state

    @partial(jax.jit, static_argnums=(0,))
    def step(self, key: jax.Array, state: ArenaState, actions: dict, reset_state: ArenaState | None = None):
        """One decision of every player; auto-resets (to ``reset_state`` if given, else to the
        arena's next episode with its own content). ``actions``: ``{agent: int[] or int[1]}``.
        Returns ``(obs, state, rewards, dones, infos)`` as ``step_env``'s (``obs`` after the reset)."""
        obs, state, rewards, dones, infos = self.step_env(key, state, actions)
        if reset_state is not None:
            ended = dones["__all__"]
            state = jax.tree.map(lambda r, s: jnp.where(ended, r, s), reset_state, state)
            fresh = self.get_obs(reset_state)
            obs = jax.tree.map(lambda r, o: jnp.where(ended, r, o), fresh, obs)
        return obs, state, rewards, dones, infos

    def step_env(self, key: jax.Array, state: ArenaState, actions: dict):
        """One decision with the auto-reset to the arena's next episode built in.

        Returns:
            ``(obs, state, rewards, dones, infos)``: ``obs`` ``{agent: float32[D]}`` (the new
            episode's when it ended), ``ArenaState``, ``rewards`` ``{agent: float32[]}``, ``dones``
            ``{agent: bool[], "__all__": bool[]}``, and ``infos`` a dict of ``[P]`` arrays (one entry
            per agent): ``terminated``, ``truncated``, ``returned_episode``, ``alive`` (``bool[P]``),
            ``result``, ``back_attack`` (``int32[P]``), ``damage_dealt`` (``float32[P]``).

        Raises:
            ValueError: an agent's action missing or not of shape ``[]`` or ``[1]``; as ``check_actions``.
        """
        acts = check_actions(jnp.stack([self._agent_action(actions, a) for a in self.agents]), state.params)
        obs, new, reward, terminated, truncated, info, _ = step_arena(key, state, acts)
        ended = terminated | truncated
        n = self.num_agents
        per_agent = lambda x: jnp.broadcast_to(x, (n,))
        infos = {
            "terminated": per_agent(terminated), "truncated": per_agent(truncated),
            "result": per_agent(info["result"]), "returned_episode": per_agent(ended),
            "alive": info["alive"], "damage_dealt": info["damage_dealt"], "back_attack": info["back_attack"],
        }
        dones = {a: ended | ~info["alive"][i] for i, a in enumerate(self.agents)}
        dones["__all__"] = ended
        return self._split(obs.flat()), new, self._split(reward), dones, infos

    @staticmethod
    def _agent_action(actions: dict, agent: str) -> jax.Array:
        """Agent ``agent``'s action as ``int[]``: JaxMARL's baselines hand ``[1]``, others ``[]``.

        Raises:
            ValueError: a missing agent, or a shape other than ``[]`` or ``[1]`` (one line).
        """
        if agent not in actions:
            raise ValueError(f"actions: no entry for agent {agent!r}; allowed: a dict with one action per agent")
        x = jnp.asarray(actions[agent])
        if x.shape == (1,):
            return x[0]
        if x.shape != ():
            raise ValueError(f"actions[{agent!r}]: shape {list(x.shape)}; allowed: [] or [1] (one action id)")
        return x

    def get_obs(self, state: ArenaState) -> dict:
        """Every agent's ``float32[D]`` observation of ``state``."""
        return self._split(observe(state.game, state.params).flat())

    def get_avail_actions(self, state: ArenaState) -> dict:
        """Every agent's ``bool[A]`` action mask (dead players: no-op only; all true under the
        reference action space)."""
        return self._split(action_mask(state.game, state.params))

    def episode_running(self, state: ArenaState) -> jax.Array:
        """``bool[]``: the arena's episode has not ended (always true right after ``step``)."""
        return state.game.result == RUNNING

    @property
    def name(self) -> str:
        """``"raidjax"``."""
        return "raidjax"

    @property
    def agent_classes(self) -> dict:
        """``{"player": ["player_0", ..., "player_{P-1}"]}``: one class, every agent (one shared policy)."""
        return {"player": self.agents}
