"""Content generation on top of the game rules (GAME.md §10–11): the generator environment
(``raidjax.pcg.env``), the paper's PCG-RD / PCG-HR baselines (``raidjax.pcg.baselines``), and
generation runs with the controllability / diversity metrics (``raidjax.pcg.metrics``).

    from raidjax import pcg
    params = pcg.make_pcg_params(target=0.5)
    obs, state = pcg.reset(key, params)
    obs, state, reward, done, info = pcg.step(key, state, action, params)
"""

from raidjax.pcg import metrics, space
from raidjax.pcg.baselines import heuristic_policy, random_policy
from raidjax.pcg.env import (
    EASIER,
    HEAVY_VS_LIGHT,
    HIGH,
    LOW,
    N_CHOICES,
    N_PARAMS,
    NOOP_ACTION,
    PARAM_NAMES,
    TICK_FRACTIONS,
    PCGParams,
    PCGState,
    advance,
    apply_action,
    axis_arg,
    base_game,
    box_grid,
    box_probes,
    check_axis,
    draw_goal,
    high,
    in_band,
    low,
    make_pcg_params,
    measure,
    obs_size,
    observe_pcg,
    parse_axis,
    play_outcomes,
    reset,
    reward_fn,
    skill_params,
    squared_ticks,
    step,
    step_autoreset,
    tick,
)
from raidjax.pcg.space import PAPER_SPACE, Space, make_space, parse_space

__all__ = [
    "EASIER", "HEAVY_VS_LIGHT", "HIGH", "LOW", "N_CHOICES", "N_PARAMS", "NOOP_ACTION", "PARAM_NAMES", "PAPER_SPACE",
    "Space", "TICK_FRACTIONS", "PCGParams", "PCGState", "advance", "apply_action", "axis_arg", "base_game",
    "box_grid", "box_probes", "check_axis", "draw_goal",
    "heuristic_policy", "high", "in_band", "low", "make_pcg_params", "make_space", "measure", "metrics", "obs_size",
    "observe_pcg", "parse_axis", "parse_space", "play_outcomes", "random_policy", "reset", "reward_fn", "skill_params",
    "space", "squared_ticks", "step", "step_autoreset", "tick",
]
