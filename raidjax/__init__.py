"""raidjax: a batched, jittable boss-raid simulator for automated game-content balancing.

Quick start::

    import jax, raidjax
    params = raidjax.make_params(skill_range=13.0)
    obs, state = raidjax.reset(jax.random.key(0), params)
    results = raidjax.playtest(jax.random.key(1), params, raidjax.policies.heuristic, 1000)
"""

from raidjax import _xla_flags

_xla_flags.apply()

from raidjax import catalogue, logs, policies, types  # noqa: E402
from raidjax.content import default_params, make_params, validate_params, with_player_skill  # noqa: E402
from raidjax.env import next_episode, reset, step, step_autoreset  # noqa: E402
from raidjax.observation import action_mask, observe  # noqa: E402
from raidjax.playtest import playtest, playtest_occupancy, win_rate  # noqa: E402
from raidjax.spaces import Spaces, spaces  # noqa: E402
from raidjax.types import ACTION_HEURISTIC, N_ACTIONS, RULE_SETS, EnvConfig, Observation, Params, State  # noqa: E402

__version__ = "0.1.0"
__all__ = [
    "catalogue", "logs", "policies", "types", "default_params", "make_params", "validate_params", "with_player_skill",
    "reset", "next_episode", "step", "step_autoreset", "observe", "action_mask", "playtest", "playtest_occupancy",
    "win_rate", "spaces", "Spaces", "N_ACTIONS", "ACTION_HEURISTIC", "EnvConfig", "RULE_SETS", "Observation",
    "Params", "State",
]
