"""Content generation on top of the game rules (GAME.md §10, PROTOCOLS.md §11): the generator environment
(``raidjax.pcg.env``), its playtests (``raidjax.pcg.measurement``), the edited parameters
(``raidjax.pcg.space``) and style goals (``raidjax.pcg.goals``), the paper's PCG-RD / PCG-HR baselines
(``raidjax.pcg.baselines``), and generation runs with the controllability / diversity metrics
(``raidjax.pcg.quality``).

    from raidjax import pcg
    params = pcg.make_pcg_params(target=0.5)
    obs, state = pcg.reset(key, params)
    obs, state, reward, done, info = pcg.step(key, state, action, params)
"""

from raidjax.pcg import env, goals, measurement, quality, space
from raidjax.pcg.baselines import pcg_hr, pcg_rd
from raidjax.pcg.env import (
    PCGParams,
    PCGState,
    base_game,
    in_band,
    make_pcg_params,
    measure,
    reset,
    step,
    step_autoreset,
)
from raidjax.pcg.measurement import play_outcomes
from raidjax.pcg.space import PAPER_SPACE, Space, make_space, parse_space

# What users call; the environment's building blocks stay in ``raidjax.pcg.env``.
__all__ = [
    "PAPER_SPACE", "Space", "PCGParams", "PCGState", "base_game", "pcg_hr", "pcg_rd", "in_band",
    "make_pcg_params", "make_space", "measure", "parse_space", "play_outcomes", "reset", "step", "step_autoreset",
    "env", "goals", "measurement", "quality", "space",
]
