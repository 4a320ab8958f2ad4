"""Benchmark 2 (PROTOCOLS.md §11): generation runs and the controllability / diversity / yield metrics,
plus the playtest-noise measurement.

``generate`` runs any generator policy ``policy(policy_params, key, obs, state, params) ->
int32[K]`` (one choice per edited parameter, ``K = params.space.size``; ``raidjax.pcg.pcg_rd``,
``pcg_hr`` or a trained PPO policy) for E episodes per target, all episodes in parallel, and
keeps each episode's last skill: either with the generator's own last measurement
(``eval_games=0``, the paper's protocol) or re-measured with ``eval_games`` games (raidjax's
protocol). The metric functions are plain numpy on the returned arrays; ``group_size`` cuts every
(method, target) group to one size before a metric (``equal_groups``), as the reference
notebook's ``groupby(...).sample(n=300, random_state=1)``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from raidjax.pcg import env, measurement

TARGETS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7)
# Diversity keeps the skills whose |W_t - W_c| is below this (the paper §5.3, SPEC §11).
KEEP_ERROR = 0.1


@dataclasses.dataclass(frozen=True)
class Protocol:
    """How Benchmark 2 generates, keeps and compares skills (PROTOCOLS.md §11).

    Attributes:
        name: ``PROTOCOLS`` key.
        strict_length: generation episodes never end early at the band (``PCGParams.strict_length``).
        decisions: generation episode length in the reference's decisions (``PCGAgent`` MaxStep
            40); every decision measures the current skill, then edits it, so an episode is the
            start measurement plus ``decisions - 1`` measured edits, and the last edit is never
            measured (not played here). ``None``: the PPO config's ``max_edits`` measured edits.
        greedy: PPO generates with the argmax of each branch (else samples).
        remeasure: the kept skill is re-measured with ``eval_games`` games (else the generator's
            own last measurement, with ``eval_games`` games per edit, is the result).
        min_edits: controllability keeps episodes with at least this many measured edits (the
            notebook's ``StepCount >= 2`` = one measured edit; raidjax: 2).
        diversity_min_edits: the same filter for diversity (raidjax: none).
        group_size: cut every (method, target) group to this size before the metrics
            (``equal_groups``; ``None``: unequal groups).
        seed: the cut's seed.
    """

    name: str
    strict_length: bool
    decisions: int | None
    greedy: bool
    remeasure: bool
    min_edits: int
    diversity_min_edits: int
    group_size: int | None
    seed: int = 1

    def max_edits(self, config_max_edits: int) -> int:
        """Measured edits per generation episode (``config_max_edits`` when ``decisions`` is None)."""
        return config_max_edits if self.decisions is None else self.decisions - 1


PROTOCOLS = {
    # The reference (PCG/SkillSampling configs, SkillParameterVisualization3.ipynb): strict 40-decision
    # episodes measured with 300 games at every decision, greedy PPO, last measured skill of episodes
    # with StepCount >= 2, 300 per (method, target) before scaling and PCA.
    "paper": Protocol("paper", strict_length=True, decisions=40, greedy=True, remeasure=False, min_edits=1,
                      diversity_min_edits=1, group_size=300),
    # raidjax's earlier protocol: early stop at the band, sampled PPO, a fresh 300-game
    # re-measurement of the final skill, episodes with >= 2 measured edits, unequal groups.
    "raidjax": Protocol("raidjax", strict_length=False, decisions=None, greedy=False, remeasure=True, min_edits=2,
                        diversity_min_edits=0, group_size=None),
}


# A generation is three compiled programs driven from the host: the episodes' start, one measurement
# of every episode (the loop's body: the start's measurement, then each edit's; it holds the game
# once, called until every episode is done or has made its edits) and the re-measurement. The host
# loop says how far it has come between measurements (``generate``'s ``progress``) and keeps every
# program free of host callbacks, which JAX's persistent compilation cache will not store.
# Measurement 0 measures the start skills with reset's keys (``env.unmeasured_reset``); measurement
# i > 0 is ``env.step`` with the keys of edit i - 1: the episodes are those of ``env.reset`` followed
# by ``env.step``.


@partial(jax.jit, static_argnames=("episodes",))
def _start(key, params: env.PCGParams, targets, episodes: int):
    """Every episode's target ``t`` (``float32[n]``), the keys of its start measurement, of the
    loop and of the re-measurement, and its unmeasured start (observation and state)."""
    t = jnp.repeat(targets, episodes)
    n = t.shape[0]
    k_reset, k_loop, k_eval = jax.random.split(key, 3)
    k_start, state = jax.vmap(lambda k, tt: env.unmeasured_reset(k, params, tt))(jax.random.split(k_reset, n), t)
    obs = jax.vmap(lambda s: env.observe_pcg(s, params))(state)
    return t, (k_start, k_loop, k_eval), obs, state


@partial(jax.jit, static_argnames=("policy",))
def _measure(i, obs, state, k_start, k_loop, policy, policy_params, params: env.PCGParams, episode_params):
    """Measurement ``i`` (``int32[]``) of every episode not yet done; returns the new observation and
    state and whether another measurement follows."""
    n = k_start.shape[0]
    first = i == 0
    ks = jax.random.split(jax.random.fold_in(k_loop, i - 1), 2 * n)  # raw or typed keys
    ks = (ks[:n], ks[n:])
    if episode_params is None:
        act = jax.vmap(lambda k, o, s: policy(policy_params, k, o, s, params))(ks[0], obs, state)
    else:
        act = jax.vmap(lambda k, o, s, e: policy((policy_params, e), k, o, s, params))(ks[0], obs, state,
                                                                                    episode_params)
    edited = jax.vmap(lambda s, a: env.apply_action(s.skill, a, params.space))(state, act)
    skill = jnp.where(first, state.skill, edited)
    w = jax.vmap(lambda k, sk: env.measure(k, params, sk))(jnp.where(first, k_start, ks[1]), skill)
    stepped, _ = jax.vmap(lambda s, sk, ww: env.advance(s, sk, ww, params))(state, skill, w)
    state2 = jax.tree.map(lambda a, b: jnp.where(first, a, b), state.replace(win_rate=w), stepped)
    obs2 = jax.vmap(lambda s: env.observe_pcg(s, params))(state2)
    keep = lambda old, new: jnp.where(state.done.reshape((-1,) + (1,) * (new.ndim - 1)), old, new)
    state2 = jax.tree.map(keep, state, state2)
    return keep(obs, obs2), state2, (i + 1 <= params.max_edits) & ~jnp.all(state2.done)


def _placed_like(carried, inputs):
    """``carried`` committed to the one device an array of ``inputs`` is committed to, if any.

    A jitted call returns arrays committed to a device when one of its inputs is (weights restored
    from a checkpoint are), and JAX compiles a program again for arguments placed differently. The
    measurements carry ``_start``'s outputs from call to call: placed as ``_measure`` will return
    them, every measurement runs the first one's compiled program (else the second compiled again).
    """
    for x in jax.tree.leaves(inputs):
        if isinstance(x, jax.Array) and x.committed and len(x.devices()) == 1:
            return jax.device_put(carried, next(iter(x.devices())))
    return carried


@partial(jax.jit, static_argnames=("eval_games",))
def _remeasure(k_eval, state, params: env.PCGParams, eval_games: int):
    """Each episode's final skill played ``eval_games`` times: ``float32[n]``."""
    keys = jax.random.split(k_eval, state.skill.shape[0])
    return jax.vmap(lambda k, s: env.measure(k, params, s, eval_games))(keys, state.skill)


def generate(key: jax.Array, policy, params: env.PCGParams, *, policy_params=None, targets=TARGETS,
             episodes: int = 10, eval_games: int = 300, episode_params=None,
             progress: Callable[[int, int, int, int], None] | None = None) -> dict[str, np.ndarray]:
    """Run a generator for ``episodes`` episodes per target, all episodes side by side: every
    measurement of the ``n = T * E`` episodes is one playtest of ``n * params.n_games`` games.

    Args:
        key: PRNG key.
        policy: ``policy(policy_params, key, obs, state, params) -> int32[K]`` (hashable); with
            ``episode_params``, ``policy((policy_params, episode_params[i]), key, obs, state, params)``
            for episode ``i``.
        params: ``PCGParams`` (its ``n_games`` is the generator's per-edit measurement).
        policy_params: pytree passed to ``policy`` (network weights; ``None`` for baselines).
        targets: target win rates (T of them; repeats allowed, so several generators' episodes can
            run in one call).
        episodes: E, episodes per target.
        episode_params: ``None``, or a pytree whose leaves lead with ``n`` (episode ``i``'s values,
            episodes ordered target by target): which generator and network each episode runs.
        eval_games: games re-measuring each final skill (300); 0 keeps the generator's own last
            measurement (``params.n_games`` games), so ``win_rate == gen_win_rate``.
        progress: ``None``, or ``progress(measured, most, done, n)``, called after each
            measurement of the episodes: ``measured`` of at most ``most`` measurements (the
            start's and ``params.max_edits`` edits'; the loop stops early once every episode is
            done), ``done`` of the ``n`` episodes finished; the re-measurement follows the last.
            A long generation's progress line; the numbers are the same with or without it.

    Returns:
        numpy dict over ``n = T * E`` episodes (``K = params.space.size``): ``target`` ``float32[n]``,
        ``skill`` ``float32[n, K]`` (the last measured skill), ``win_rate`` ``float32[n]`` (its result,
        see ``eval_games``), ``gen_win_rate`` ``float32[n]`` (the generator's last measurement),
        ``edits`` ``int32[n]``, ``reached`` ``bool[n]`` (the band was reached) and ``goal``
        ``float32[n, K]`` (its style goal; the start skill unless ``params.goal_axis``).
    """
    t, (k_start, k_loop, k_eval), obs, state = _start(key, params, jnp.asarray(targets, jnp.float32), episodes)
    obs, state = _placed_like((obs, state), (policy_params, params, episode_params))
    measured, go = 0, True  # every episode measures its start (max_edits >= 0)
    while go:
        obs, state, go = _measure(jnp.int32(measured), obs, state, k_start, k_loop, policy, policy_params, params,
                                  episode_params)
        measured += 1
        if progress is not None:
            progress(measured, int(params.max_edits) + 1, int(jnp.sum(state.done)), int(t.shape[0]))
        go = bool(go)
    # without a re-measurement the generator's own last measurement is the result
    final = _remeasure(k_eval, state, params, eval_games) if eval_games else state.win_rate
    out = {"target": t, "skill": state.skill, "win_rate": final, "gen_win_rate": state.win_rate,
           "edits": state.edits, "reached": state.reached, "goal": state.goal}
    return {k: np.asarray(v) for k, v in jax.device_get(out).items()}


def equal_groups(groups: np.ndarray, size: int, seed: int = 1, min_size: int = 1) -> np.ndarray:
    """Indices of an equal-size sample of every group (without replacement, fixed seed).

    Groups with fewer than ``min_size`` members are left out; every other group is cut to
    ``m = min(size, smallest such group)`` members (the reference notebook samples exactly 300
    per (method, target); smaller runs take what the smallest group has).

    Args:
        groups: ``[n]`` hashable labels.
        size: the cap on members per group.
        seed: ``numpy.random.default_rng`` seed (groups are drawn in sorted label order).
        min_size: smallest group kept.

    Returns:
        ``int[k * m]`` sorted indices into ``groups`` (k groups kept).
    """
    groups = np.asarray(groups)
    labels, counts = np.unique(groups, return_counts=True)
    kept = labels[counts >= min_size]
    if kept.size == 0:
        return np.zeros(0, int)
    m = int(min(size, counts[counts >= min_size].min()))
    rng = np.random.default_rng(seed)
    return np.sort(np.concatenate([rng.choice(np.flatnonzero(groups == g), m, replace=False) for g in kept]))


def controllability(gen: dict, min_edits: int = 2, group_size: int | None = None, seed: int = 1) -> dict:
    """Controllability (PROTOCOLS.md §11) over episodes with at least ``min_edits`` edits.

    Args:
        gen: ``generate`` output (``target``, ``win_rate``, ``edits`` [n]).
        min_edits: episodes with fewer edits are left out (the paper's ">= 2 edits").
        group_size: cut every target's kept episodes to one size (``equal_groups``; ``None``: all).
        seed: the cut's seed.

    Returns:
        ``{"per_target": {t: {"n", "wc_mean", "wc_sd", "err_mean", "err_sd"}}, "n", "wc_mean",
        "err_mean", "err_sd", "mean_of_target_means"}`` (floats; SD with ddof 0).
    """
    keep = np.flatnonzero(np.asarray(gen["edits"]) >= min_edits)
    if group_size is not None:
        keep = keep[equal_groups(np.round(np.asarray(gen["target"])[keep], 6), group_size, seed)]
    t, w = np.asarray(gen["target"])[keep], np.asarray(gen["win_rate"])[keep]
    err = np.abs(t - w)
    per = {}
    for tv in np.unique(np.round(t, 6)):
        m = np.isclose(t, tv)
        per[float(tv)] = {"n": int(m.sum()), "wc_mean": float(w[m].mean()), "wc_sd": float(w[m].std()),
                          "err_mean": float(err[m].mean()), "err_sd": float(err[m].std())}
    return {"per_target": per, "n": int(keep.size), "wc_mean": float(w.mean()) if w.size else float("nan"),
            "err_mean": float(err.mean()) if err.size else float("nan"),
            "err_sd": float(err.std()) if err.size else float("nan"),
            "mean_of_target_means": float(np.mean([p["err_mean"] for p in per.values()])) if per else float("nan")}


def first_pc(x: np.ndarray) -> np.ndarray:
    """First principal axis ``float[d]`` of the rows of ``x`` ``[n, d]`` (centred SVD)."""
    xc = x - x.mean(0)
    _, _, vt = np.linalg.svd(xc, full_matrices=False)
    return vt[0]


def diversity(skills: np.ndarray, errors: np.ndarray, groups: np.ndarray, threshold: float = KEEP_ERROR,
              group_size: int | None = None, seed: int = 1, min_kept: int = 2) -> dict:
    """Diversity (PROTOCOLS.md §11): keep skills with error < ``threshold``, leave out groups that
    kept fewer than ``min_kept``, optionally cut every other group to one size, min-max normalise
    the K parameters over the pooled (cut) set, fit PCA on it, then per group the SD of each
    parameter and of PC1.

    Args:
        skills: ``[n, K]`` generated skills (any groups pooled, e.g. all methods and targets).
        errors: ``[n]`` ``|W_t - W_c|``.
        groups: ``[n]`` hashable labels, e.g. ``"PPO|0.3"``.
        threshold: error cut-off.
        group_size: cut the kept skills of every group left in to one size before the scaling and
            PCA (``equal_groups``; the reference notebook: 300); ``None``: all kept.
        seed: the cut's seed.
        min_kept: groups that kept fewer skills are left out of the cut, the scaling and the PCA
            (at least 2: an SD needs two). The reference notebook's groups all kept its 300; a
            smaller run sets how few skills an SD may rest on instead of cutting every group down
            to its smallest one.

    Returns:
        ``{group: {"n", "kept", "param_sd": [K], "pc1_sd", "pc1_own_sd"}}`` for every group with a
        kept skill (``param_sd``: a list of K floats): ``kept`` skills under the threshold, ``n`` of
        them measured (0 for a group left out; SD ddof 0; NaN where ``n`` < 2). ``pc1_own_sd`` is the
        SD along the group's own first principal axis (same normalisation): the pooled axis follows
        whichever method spreads most, so it is reported beside ``pc1_sd`` as a check that a lead
        does not come from the choice of axis.
    """
    if min_kept < 2:
        raise ValueError(f"min_kept: {min_kept} skills cannot have an SD; use 2 or more")
    skills, errors, groups = np.asarray(skills, float), np.asarray(errors), np.asarray(groups)
    kept = np.flatnonzero(errors < threshold)
    count = dict(zip(*(a.tolist() for a in np.unique(groups[kept], return_counts=True)), strict=True))
    out = {g: {"n": 0, "kept": c, "param_sd": [float("nan")] * skills.shape[1], "pc1_sd": float("nan"),
               "pc1_own_sd": float("nan")} for g, c in count.items() if c < min_kept}
    keep = kept[~np.isin(groups[kept], list(out))] if out else kept
    if group_size is not None:
        keep = keep[equal_groups(groups[keep], group_size, seed)]
    x = skills[keep]
    if x.shape[0] == 0:
        return out
    lo, hi = x.min(0), x.max(0)
    xn = (x - lo) / np.where(hi > lo, hi - lo, 1.0)
    pc = first_pc(xn) if x.shape[0] > 1 else np.zeros(x.shape[1])
    proj = (xn - xn.mean(0)) @ pc
    for g in np.unique(groups[keep]):
        m = groups[keep] == g
        n = int(m.sum())
        out[g] = {"n": n, "kept": count[g],
                  "param_sd": (xn[m].std(0) if n > 1 else np.full(x.shape[1], np.nan)).tolist(),
                  "pc1_sd": float(proj[m].std()) if n > 1 else float("nan"),
                  "pc1_own_sd": float(((xn[m] - xn[m].mean(0)) @ first_pc(xn[m])).std()) if n > 1 else float("nan")}
    return out


def yield_stats(gen: dict) -> dict:
    """Yield rate (share of episodes whose generator measurement reached the band) and edits per
    episode (mean, SD). Returns floats."""
    e = np.asarray(gen["edits"], float)
    return {"yield": float(np.mean(gen["reached"])), "edits_mean": float(e.mean()), "edits_sd": float(e.std())}


@partial(jax.jit, static_argnames=("n_games", "repeats"))
def _rates(key, game, skill, n_games: int, repeats: int):
    keys = jax.random.split(key, repeats)
    return jax.vmap(lambda k: jnp.mean(measurement.play_outcomes(k, game, skill, n_games).astype(jnp.float32)))(keys)


def win_rate_noise(key: jax.Array, skill, n_games_list=(25, 50, 100, 300), repeats: int = 20) -> list[dict]:
    """How the standard error of a measured win rate shrinks with the number of playtest games.

    Args:
        key: PRNG key.
        skill: ``float32[4]`` skill to measure.
        n_games_list: playtest sizes N.
        repeats: independent measurements per N.

    Returns:
        One dict per N: ``n_games``, ``mean`` win rate, ``se_measured`` (SD over repeats) and
        ``se_binomial`` (``sqrt(p (1 - p) / N)`` at the pooled ``p``).
    """
    game, skill = env.base_game(), jnp.asarray(skill, jnp.float32)
    out = []
    for i, n in enumerate(n_games_list):
        r = np.asarray(_rates(jax.random.fold_in(key, i), game, skill, int(n), repeats))
        p = float(r.mean())
        out.append({"n_games": int(n), "mean": p, "se_measured": float(r.std(ddof=1)),
                    "se_binomial": float(np.sqrt(p * (1 - p) / n))})
    return out


def target_label(t) -> str:
    """A target win rate's key in ``summarize``'s ``diversity``: rounded to 6 decimals as
    ``controllability`` groups targets (``"0.1"`` ... ``"0.7"`` for ``TARGETS``; 0.15 and 0.2 stay
    two groups)."""
    return f"{round(float(t), 6):g}"


def summarize(gens: dict, protocol: Protocol | None = None, min_kept: int = 2) -> dict:
    """Controllability, yield and diversity (pooled normalisation and PCA over all methods) per
    method, episodes kept and groups cut as ``protocol`` says.

    Args:
        gens: ``{method: generate output}``.
        protocol: a ``Protocol`` (default ``PROTOCOLS["raidjax"]``).
        min_kept: diversity leaves out (method, target) groups that kept fewer skills (``diversity``).

    Returns:
        ``{method: {"controllability": controllability(...), "yield", "edits_mean", "edits_sd",
        "pc1_sd_mean", "pc1_own_sd_mean", "param_sd_mean": [K] | None, "diversity": {target: ...}}}``
        (means over the targets whose group is measured, ``diversity``; NaN where none is; ``[K]``: a
        list, one float per edited parameter).
    """
    pr = PROTOCOLS["raidjax"] if protocol is None else protocol
    skills, errs, groups = [], [], []
    for name, g in gens.items():
        k = np.asarray(g["edits"]) >= pr.diversity_min_edits
        skills.append(g["skill"][k])
        errs.append(np.abs(g["target"] - g["win_rate"])[k])
        groups += [f"{name}|{target_label(t)}" for t in g["target"][k]]
    div = diversity(np.concatenate(skills), np.concatenate(errs), np.asarray(groups), group_size=pr.group_size,
                    seed=pr.seed, min_kept=min_kept)
    size = pr.group_size
    if size is not None:  # one size for every (method, target) group: the smallest, at most group_size
        counts = [np.unique(np.round(g["target"][np.asarray(g["edits"]) >= pr.min_edits], 6), return_counts=True)[1]
                  for g in gens.values()]
        size = int(min([size] + [c.min() for c in counts if c.size]))
    out = {}
    for name, g in gens.items():
        d = [v for k, v in div.items() if k.startswith(name + "|") and np.isfinite(v["pc1_sd"])]
        out[name] = {"controllability": controllability(g, pr.min_edits, size, pr.seed), **yield_stats(g),
                     "pc1_sd_mean": float(np.mean([v["pc1_sd"] for v in d])) if d else float("nan"),
                     "pc1_own_sd_mean": float(np.mean([v["pc1_own_sd"] for v in d])) if d else float("nan"),
                     "param_sd_mean": np.nanmean([v["param_sd"] for v in d], 0).tolist() if d else None,
                     "diversity": {k.split("|")[1]: v for k, v in div.items() if k.startswith(name + "|")}}
    return out
