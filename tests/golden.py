"""Golden games: fixed-seed games whose per-game results are stored in ``tests/data/golden.npz``.

They pin the simulator's behaviour bit for bit so that an optimisation of the step can be checked
against the step before it (``test_golden.py``). The games use only the public per-arena API
(``reset``, ``step``, ``next_episode``, ``policies``), vmapped over arenas in one ``while_loop``,
so a change to ``playtest`` does not move them.

Per rule set (``"reference"``, ``"clean"``), one compiled program plays every arena:

* the reference content at skill ranges 5 / 9 / 13 / 17, ``GAMES_PER_CELL`` games each with
  PT-HR and as many with PT-RD;
* ``N_FUZZ`` random contents (``fuzz_contents``: every stat and most skill parameters drawn
  uniformly inside their allowed ranges), one game each, PT-HR on the even ones and PT-RD on
  the odd ones.

Episodes last at most ``MAX_DECISIONS`` decisions. Under chaining rules
(``EnvConfig.chains_episodes``) each arena plays a warm-up game and the recorded game is its
``next_episode``, as ``playtest`` measures. Recorded per game: ``outcome``,
``length``, final ``hp`` and ``damage_dealt`` per unit, ``dropped``.

Regenerate (only for a change that is meant to change the game, with the reason in the commit):
``python tests/golden.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import raidjax
from raidjax.content import SKILL_SPECS, STAT_SPECS
from raidjax.types import ACTION_HEURISTIC, RUNNING

PATH = Path(__file__).resolve().parent / "data" / "golden.npz"
RANGES = (5.0, 9.0, 13.0, 17.0)
GAMES_PER_CELL = 8
N_FUZZ = 200
SEED = 20261125
RULES = ("reference", "clean")
# Episodes end by 400 decisions (40 s): every reference-content game ends well before (the longest
# of the calibration's 8 000 is under 170), so only random contents that would run longer are
# draws; the test costs a fifth of full 2000-decision episodes.
MAX_DECISIONS = 400
FIELDS = ("outcome", "length", "hp", "damage_dealt", "dropped")


def _draw(rng: np.random.Generator, kind: str, lo: float, hi: float):
    if kind in ("int", "bool"):
        return int(rng.integers(int(np.ceil(lo)), int(np.floor(hi)) + 1))
    return float(rng.uniform(lo, hi))


def fuzz_overrides(rng: np.random.Generator) -> tuple[list[dict], dict]:
    """One random content as ``make_params`` overrides: ``(player_overrides, boss_overrides)``.

    Every stat of every unit uniform in its allowed range; every parameter of a player's skill
    slots 2 and 3 (``in_use`` included; slot 1 keeps the mage's missile) and of the boss's two
    skills (both stay in use), uniform in its allowed range.
    """
    def unit(side: int, slots: tuple[int, ...]) -> dict:
        out = {k: _draw(rng, s[0], *s[side]) for k, s in STAT_SPECS.items()}
        for slot in slots:
            for k, s in SKILL_SPECS.items():
                if k != "in_use" or side == 1:
                    out[f"skill{slot}.{k}"] = _draw(rng, s[0], *s[side])
        return out

    return [unit(1, (2, 3)) for _ in range(3)], unit(2, (1, 2))


def fuzz_contents(n: int, config: raidjax.EnvConfig, seed: int = SEED) -> list[raidjax.Params]:
    """``n`` random valid contents (see ``fuzz_overrides``), the same for every ``config``."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        players, boss = fuzz_overrides(rng)
        out.append(raidjax.make_params(player_overrides=players, boss_overrides=boss, config=config))
    return out


def arenas(rules: str) -> tuple[raidjax.Params, np.ndarray]:
    """``(params batched [N], heuristic bool[N])``: every golden arena of a rule set and whether
    PT-HR (else PT-RD) plays it."""
    config = raidjax.EnvConfig.from_rules(rules, max_decisions=MAX_DECISIONS)
    ref = [raidjax.make_params(skill_range=r, config=config) for r in RANGES]
    contents, hr = [], []
    for p in ref:
        for use_hr in (True, False):
            contents += [p] * GAMES_PER_CELL
            hr += [use_hr] * GAMES_PER_CELL
    fuzz = fuzz_contents(N_FUZZ, config)
    contents += fuzz
    hr += [i % 2 == 0 for i in range(N_FUZZ)]
    return jax.tree.map(lambda *x: jnp.stack(x), *contents), np.array(hr)


def _play(key, state, params, hr):
    """Step every arena (vmapped) until all episodes ended; returns the final ``State``."""
    n = hr.shape[0]
    max_t = params.config.max_decisions

    def body(carry):
        t, obs, state = carry
        keys = jax.random.split(jax.random.fold_in(key, t), 2 * n)
        rd = jax.vmap(raidjax.policies.random)(keys[:n], obs, state, params)
        actions = jnp.where(hr[:, None], ACTION_HEURISTIC, rd)
        obs, state, _, _, _ = jax.vmap(raidjax.step)(keys[n:], state, actions, params)
        return t + 1, obs, state

    def running(carry):
        t, _, state = carry
        return (t <= max_t) & jnp.any(state.result == RUNNING)

    obs = jax.vmap(raidjax.observe)(state, params)
    return jax.lax.while_loop(running, body, (jnp.int32(0), obs, state))[2]


@jax.jit
def play(key: jax.Array, params: raidjax.Params, hr: jax.Array) -> dict[str, jax.Array]:
    """The recorded game of every arena: dict of ``FIELDS`` with leading axis ``N``."""
    n = hr.shape[0]
    k_reset, k_warm, k_next, k_play = jax.random.split(key, 4)
    _, state = jax.vmap(raidjax.reset)(jax.random.split(k_reset, n), params)
    if params.config.chains_episodes:
        state = _play(k_warm, state, params, hr)
        _, state = jax.vmap(raidjax.next_episode)(jax.random.split(k_next, n), state, params)
    s = _play(k_play, state, params, hr)
    return {"outcome": s.result, "length": s.decision, "hp": s.hp, "damage_dealt": s.damage_dealt,
            "dropped": s.dropped}


def golden_results() -> dict[str, np.ndarray]:
    """Play every golden game now: ``{f"{rules}/{field}": array}``."""
    out = {}
    for i, rules in enumerate(RULES):
        params, hr = arenas(rules)
        res = jax.device_get(play(jax.random.key(SEED + i), params, jnp.asarray(hr)))
        out.update({f"{rules}/{k}": np.asarray(v) for k, v in res.items()})
        out[f"{rules}/heuristic"] = hr
    return out


def main() -> None:
    raidjax.use_recommended_xla_flags()  # as the test suite runs (tests/conftest.py)
    res = golden_results()
    PATH.parent.mkdir(exist_ok=True)
    np.savez_compressed(PATH, **res)
    for rules in RULES:
        o = res[f"{rules}/outcome"]
        print(rules, "games", o.size, "wins", int((o == 1).sum()), "losses", int((o == 2).sum()),
              "draws", int((o == 3).sum()), "max length", int(res[f"{rules}/length"].max()),
              "dropped", int(res[f"{rules}/dropped"].sum()))
    print("wrote", PATH, file=sys.stderr)


if __name__ == "__main__":
    main()
