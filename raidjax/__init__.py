"""raidjax: a batched, jittable boss-raid simulator for automated game-content balancing.

Quick start::

    import jax, raidjax
    params = raidjax.make_params(skill_range=13.0)
    obs, state = raidjax.reset(jax.random.key(0), params)
    results = raidjax.playtest(jax.random.key(1), params, raidjax.policies.heuristic, 1000)

``import raidjax`` leaves the process's XLA settings alone; on CPU, call
``raidjax.use_recommended_xla_flags()`` before the first JAX computation for raidjax's
commands' speed (``raidjax.xla_flags``).
"""

from raidjax import catalogue, logs, policies, types
from raidjax.content import default_params, make_params, validate_params, with_player_skill, with_senses
from raidjax.env import next_episode, reset, step, step_autoreset, team_reward
from raidjax.observation import action_mask, observe
from raidjax.playtest import (
    auto_games_per_arena,
    playtest,
    playtest_groups,
    playtest_occupancy,
    win_rate,
    win_rate_by_position,
)
from raidjax.spaces import Spaces, spaces
from raidjax.types import ACTION_HEURISTIC, N_ACTIONS, RULE_SETS, EnvConfig, Observation, Params, State
from raidjax.xla_flags import use_recommended_xla_flags

__version__ = "0.1.0"
__all__ = [
    "catalogue", "logs", "policies", "types", "default_params", "make_params", "validate_params", "with_player_skill",
    "with_senses", "reset", "next_episode", "step", "step_autoreset", "team_reward", "observe", "action_mask",
    "playtest", "playtest_groups", "playtest_occupancy", "auto_games_per_arena", "win_rate", "win_rate_by_position",
    "spaces", "Spaces", "N_ACTIONS", "ACTION_HEURISTIC", "EnvConfig", "RULE_SETS", "Observation",
    "Params", "State", "use_recommended_xla_flags",
]
