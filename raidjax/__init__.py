"""raidjax: a batched, jittable boss-raid simulator for automated game-content balancing.

Quick start::

    import jax, raidjax
    params = raidjax.make_params(skill_range=13.0)
    obs, state = raidjax.reset(jax.random.key(0), params)
    results = raidjax.playtest(jax.random.key(1), params, raidjax.policies.heuristic, 1000)
"""

from raidjax import catalogue, policies, types
from raidjax.content import default_params, make_params, validate_params
from raidjax.env import reset, step, step_autoreset
from raidjax.observation import observe
from raidjax.playtest import playtest, win_rate
from raidjax.types import EnvConfig, Observation, Params, State

__version__ = "0.1.0"
__all__ = [
    "catalogue", "policies", "types", "default_params", "make_params", "validate_params",
    "reset", "step", "step_autoreset", "observe", "playtest", "win_rate",
    "EnvConfig", "Observation", "Params", "State",
]
