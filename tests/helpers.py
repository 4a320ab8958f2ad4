"""Shared, compile-once helpers for the raidjax test suite.

Every scenario uses the reference team size (3 players + the boss, 3 skill slots) and one
``EnvConfig``, ``CLEAN1`` (the ``"clean"`` rules at one sub-step: exact timers, so expected
decisions follow from the rulebook's times by hand), so the module-level jitted ``STEP`` / ``RESET``
compile once for the whole suite; only content *values* change between tests (no retracing).
The ``"reference"`` rule switches are tested in ``test_rules.py``.

Expected numbers in the tests are derived by hand from docs/GAME.md, never copied from a run.
"""

from __future__ import annotations

import math

import chex
import jax
import jax.numpy as jnp
import numpy as np

import raidjax
from raidjax.types import ACTION_HEURISTIC, CAST_1, NOOP

P = 3  # players
BOSS = 3  # unit index of the boss
DT = 0.1  # one decision
TICK = 0.02
DRAG = 0.92
KEY = jax.random.key(0)

CLEAN1 = raidjax.EnvConfig.from_rules("clean", n_substeps=1)

RESET = jax.jit(raidjax.reset)
STEP = jax.jit(raidjax.step)

# A boss that neither moves nor attacks (its skills' range 1 is shorter than any test distance),
# so that player mechanics can be measured in isolation. Its HP and defences stay the reference.
PASSIVE_BOSS = {"move_speed": 0.0, "skill1.range": 1.0, "skill2.range": 1.0}

# A tiny ``raidjax train mapoca`` run: its config file's fields and the command's arguments. The
# fault-injection chain (test_faults_mapoca), b1_switches' trained-run test (test_benchmark1) and
# test_sharding's one-device half train the same programs, so only the first to run compiles them
# (the others read them from the compilation cache). Its 4 seeds play as Benchmark 1's smoke table
# teams do (4 teams of the same network, sampled): b1_switches compiles one program per rule switch
# for both.
TINY_MAPOCA = {"n_arenas": 4, "n_steps": 8, "n_minibatches": 2, "update_epochs": 1, "hidden": 8, "layers": 1,
               "heads": 1, "updates_per_chunk": 1, "checkpoint_every": 1, "senses": "reference"}
TINY_MAPOCA_ARGS = ["--total-steps", "128", "--skill-range", "9", "--seeds", "4"]

__all__ = [
    "ACTION_HEURISTIC", "BOSS", "CAST_1", "CLEAN1", "DT", "DRAG", "KEY", "NOOP", "P", "PASSIVE_BOSS", "RESET",
    "STEP", "TICK", "TINY_MAPOCA", "TINY_MAPOCA_ARGS", "T_ROLL", "acts", "events", "make", "rollout", "run",
    "scenario", "series",
]


def make(passive_boss: bool = True, boss_overrides: dict | None = None, **kw) -> raidjax.Params:
    """``make_params`` with (by default) a passive boss; extra boss overrides on top."""
    bo = dict(PASSIVE_BOSS) if passive_boss else {}
    bo.update(boss_overrides or {})
    kw.setdefault("config", CLEAN1)
    return raidjax.make_params(boss_overrides=bo, **kw)


def acts(*a) -> jnp.ndarray:
    """Actions ``int32[3]``; a single value is given to every player."""
    if len(a) == 1:
        a = a * P
    return jnp.asarray(a, jnp.int32)


def scenario(
    params,
    players=((-3.0, -10.0), (0.0, -10.0), (3.0, -10.0)),
    boss=(0.0, 8.0),
    alive=(True, True, True),
    headings=None,
    boss_heading=None,
    target=None,
    hp=None,
    mana=None,
    key=KEY,
):
    """A reset state with units placed by hand.

    Players face the boss unless ``headings`` is given (radians, 0 = +x). The boss targets the
    nearest alive player (or ``target``) and faces it (or ``boss_heading``). Dead players get
    HP 0. ``hp`` / ``mana`` are ``[4]`` overrides (``None`` entries keep the default).
    """
    _, s = RESET(key, params)
    pos = np.array([*players, boss], np.float32)
    alive_u = np.array([*alive, True])
    if target is None:
        d = np.linalg.norm(pos[:P] - pos[BOSS], axis=-1)
        target = int(np.argmin(np.where(alive_u[:P], d, np.inf)))
    if headings is None:
        headings = [math.atan2(pos[BOSS, 1] - y, pos[BOSS, 0] - x) for x, y in pos[:P]]
    if boss_heading is None:
        tx, ty = pos[target]
        boss_heading = math.atan2(ty - pos[BOSS, 1], tx - pos[BOSS, 0])
    hp_u = np.array(s.hp)
    mana_u = np.array(s.mana)
    for arr, new in ((hp_u, hp), (mana_u, mana)):
        if new is not None:
            for i, v in enumerate(new):
                if v is not None:
                    arr[i] = v
    hp_u[~alive_u] = 0.0
    return s.replace(
        pos=jnp.asarray(pos),
        heading=jnp.asarray([*headings, boss_heading], jnp.float32),
        alive=jnp.asarray(alive_u),
        hp=jnp.asarray(hp_u, jnp.float32),
        mana=jnp.asarray(mana_u, jnp.float32),
        target=s.target.at[BOSS].set(target),
    )


def run(state, params, actions, n: int, key=KEY):
    """Play ``n`` decisions with jitted ``step``.

    ``actions`` is ``int32[3]`` (repeated) or a callable ``t -> int32[3]`` (t = 1..n).
    Returns ``(final_state, history)`` where history is a list of per-decision dicts with
    numpy copies of ``state``, ``reward``, ``done`` and ``info`` (index 0 = decision 1).
    """
    hist = []
    for t in range(1, n + 1):
        a = actions(t) if callable(actions) else actions
        obs, state, reward, done, info = STEP(jax.random.fold_in(key, t), state, a, params)
        hist.append(dict(state=jax.device_get(state), obs=obs, reward=np.asarray(reward),
                         done=bool(done), info=jax.device_get(info)))
    return state, hist


def series(hist, fn):
    """``np.array([fn(h["state"]) for h in hist])``."""
    return np.array([fn(h["state"]) for h in hist])


def events(values, initial) -> list[int]:
    """1-based decisions at which a per-decision series fell below its previous value
    (``initial`` before decision 1), e.g. mana paid or HP lost."""
    v = np.asarray(values, np.float64)
    prev = np.concatenate([[initial], v[:-1]])
    return [i + 1 for i in np.nonzero(v < prev - 1e-4)[0]]


T_ROLL = 40  # decisions per ``rollout`` (one shape: one compilation)


def _finite_tree(tree) -> jnp.ndarray:
    leaves = [jnp.all(jnp.isfinite(x)) for x in jax.tree.leaves(tree) if jnp.issubdtype(x.dtype, jnp.floating)]
    return jnp.all(jnp.stack(leaves))


@jax.jit
@chex.assert_max_traces(n=1)
def rollout(key, state, params, actions):
    """``lax.scan`` of ``T_ROLL`` decisions with ``actions: int32[T_ROLL, 3]``.

    Returns ``(final_state, (reward[T, 3], done[T], result[T], finite[T]))`` where ``finite``
    says every float in that decision's observation, state and reward is finite. Traced once
    for the whole suite (``chex.assert_max_traces``): shapes never change between calls.
    """

    def body(s, xs):
        t, a = xs
        obs, s, r, done, info = raidjax.step(jax.random.fold_in(key, t), s, a, params)
        finite = _finite_tree(obs) & _finite_tree(s) & _finite_tree(r)
        return s, (r, done, info["result"], finite)

    return jax.lax.scan(body, state, (jnp.arange(1, T_ROLL + 1), actions))


def pcg_state(skill=(10.0, 0.55, 1.0, 0.75), target=0.5, w=0.3, edits=0, games=4):
    """A hand-made ``raidjax.pcg.PCGState``: ``skill`` float32[4], target, last win rate ``w``,
    ``edits`` made, ``games`` behind ``w``; the skill as goal."""
    from raidjax import pcg

    return pcg.PCGState(skill=jnp.asarray(skill, jnp.float32), target=jnp.float32(target), win_rate=jnp.float32(w),
                        edits=jnp.int32(edits), done=jnp.bool_(False), reached=jnp.bool_(False),
                        games=jnp.float32(games), goal=jnp.asarray(skill, jnp.float32))
