"""Whole training runs of both learners as functions, in a run folder (``trainers.runfolder``):
settings recorded, ``trainers.loop.train`` driving the chunks, then the final evaluation and
``result.json``. The command lines (``trainers.mapoca_cli``, ``trainers.ppo_pcgrl_cli``) parse
their flags into these calls; ``experiments.balance`` calls them directly.

    result = run_mapoca(load_config("cpu", skill_ranges=(13.0,)), "runs/r13", preset="cpu")
    result = run_ppo_pcgrl(load_config("cpu", learner="ppo_pcgrl", total_steps=8192), "runs/ppo", preset="cpu")

The adapters ``mapoca_learner`` and ``ppo_learner`` turn each algorithm into a
``trainers.loop.Learner``; Benchmark 1 and Benchmark 2 train through them too.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import raidjax
from raidjax import pcg
from raidjax.io import atomic_write, finite_json, machine
from raidjax.playtest import auto_games_per_arena
from trainers import checkpoint
from trainers.config import Config, PPOConfig
from trainers.generate import PPOGenerator, generate_episodes, target_groups
from trainers.loop import Learner, train
from trainers.mapoca import load_policy, make_trainer, summarize
from trainers.metrics import update_rows
from trainers.ppo_pcgrl import make_train
from trainers.runfolder import RunFolder


def _say(line: str) -> None:
    """Progress of the trainers' runs: printed (their run folders keep no ``log.txt``)."""
    print(line, flush=True)


def _describe_mapoca(row: dict) -> str:
    return (f"return {row['return']:.2f}  win {row['win_rate']:.3f}  len {row['length']:.0f}  "
            f"ent {row['entropy']:.2f}")


def per_run_columns(m: dict, names: list[str]) -> dict:
    """One chunk's metrics of vmapped MA-POCA runs (values ``[R]``, ``names``: ``R`` column suffixes)
    as host columns per run: ``win/<name>`` (the share of its episodes won), ``entropy/<name>`` and
    ``kl/<name>`` (its updates' mean approximate KL; a team can lose its play in one update). Floats."""
    win = np.asarray(m["wins"]) / np.maximum(np.asarray(m["episodes"]), 1)
    columns = {"win": win, "entropy": np.asarray(m["entropy"]), "kl": np.asarray(m["approx_kl"])}
    return {f"{c}/{n}": float(v) for c, values in columns.items() for n, v in zip(names, values, strict=True)}


def mapoca_learner(trainer, init_args: tuple, n_runs: int, row: Callable[[dict], dict] = summarize,
                   describe: Callable[[dict], str] = _describe_mapoca) -> Learner:
    """MA-POCA (``trainers.mapoca.make_trainer``) as a ``Learner`` over ``n_runs`` runs.

    Args:
        trainer: the ``Trainer``; one chunk is its ``updates_per_chunk`` updates.
        init_args: arguments of ``trainer.init`` over the runs (keys ``[n_runs]``, and contents and range
            tables where the runs differ).
        row: host metrics of a chunk -> the row's learner fields (default: ``summarize``).
        describe: last row -> progress text.

    Returns:
        The learner: one row per chunk (``chunk``, ``update``, ``env_steps``, ``seconds``,
        ``steps_per_s`` and ``row``'s fields); the policy saved is the actor's weights.
    """
    cfg = trainer.config

    def chunk(n: int):
        assert n == cfg.updates_per_chunk, "MA-POCA chunks are whole (num_updates is a multiple)"
        return jax.vmap(trainer.chunk)

    def rows(u: int, n: int, m: dict, clock: dict) -> list[dict]:
        return [{"chunk": u // cfg.updates_per_chunk, "update": u + n, "env_steps": (u + n) * cfg.decisions_per_update,
                 **clock, **row(m)}]

    return Learner(init=jax.vmap(trainer.init), init_args=init_args, chunk=chunk,
                   policy=lambda s: s.params["actor"], rows=rows, describe=describe, config=cfg.to_dict(),
                   n_runs=n_runs, num_updates=cfg.num_updates, updates_per_chunk=cfg.updates_per_chunk,
                   steps_per_update=cfg.decisions_per_update, donate=True)


def ppo_learner(config: PPOConfig, keys: jax.Array, targets: jax.Array, updates_per_chunk: int, **tester) -> Learner:
    """PPO-PCGRL (``trainers.ppo_pcgrl.make_train``) as a ``Learner``: one group per key.

    Args:
        config: the generator's config.
        keys: typed PRNG keys ``[G]``; targets: each group's (low, high) target ``float32[G, 2]``
            (``trainers.generate.target_groups``).
        updates_per_chunk: updates per jitted chunk (the last one may be shorter).
        tester: ``tester=`` and ``tester_weights=`` of ``make_train`` (a learned playtester).

    Returns:
        The learner: one row per update (``trainers.metrics.update_rows`` with ``seconds`` and
        ``steps_per_s``); the policy saved is the network's parameters.
    """
    trained = make_train(config, **tester)
    steps = config.n_arenas * config.n_steps
    # The tester's weights are an argument of the chunk, not constants in it: the balancing loop's
    # two generators (policies.OrHeuristic, two weights) then share one compiled program.
    tester_weights = tester.get("tester_weights")

    def chunk(n: int):
        def run(state, tg, tw):
            one = lambda r, t: jax.lax.scan(lambda rr, _: trained.update(rr, t, tw), r, None, n)
            return jax.vmap(one)(state, tg)
        return run

    def rows(u: int, n: int, m: dict, clock: dict) -> list[dict]:
        return [{**r, **clock} for r in update_rows(u, m, steps)]

    def describe(r: dict) -> str:
        return (f"reward {r['reward']:.2f}  final_err {r['final_error']:.3f}  edits {r['edits']:.1f}  "
                f"entropy {r['entropy']:.2f}")

    return Learner(init=jax.vmap(trained.init), init_args=(keys, targets), chunk=chunk,
                   chunk_args=(targets, tester_weights),
                   policy=lambda s: s["params"], rows=rows, describe=describe, config=config.to_dict(),
                   n_runs=len(keys), num_updates=config.num_updates, updates_per_chunk=updates_per_chunk,
                   steps_per_update=steps)


def eval_contents(cfg: Config) -> dict[str, raidjax.Params]:
    """The contents of MA-POCA's final evaluation, by label: one per skill range in
    ``cfg.skill_ranges``, or under ``cfg.content_box`` the box's centre and each parameter at its
    bounds (``raidjax.pcg.measurement.box_probes``; label: the values joined by ``/``)."""
    if not cfg.content_box:
        return {f"{r:g}": raidjax.make_params(players=list(cfg.players), skill_range=r) for r in cfg.skill_ranges}
    space = pcg.make_space(cfg.parameters, cfg.players)
    base = pcg.base_game(cfg.players)
    probes = pcg.measurement.box_probes(space)
    return {"/".join(f"{v:g}" for v in sk): space.apply(base, jnp.asarray(sk)) for sk in probes}


def chained_win_rates(results: dict) -> dict:
    """A team's win rates from a ``raidjax.playtest`` under the one protocol (chained arenas after a
    warm-up): ``win_rate`` over every game with its binomial standard error ``win_rate_se``, and the
    chain diagnostic: ``win_rate_first_game`` (each arena's first game after its warm-up),
    ``win_rate_later_games`` and ``win_rate_by_position``. JSON-able (floats rounded to 6 places)."""
    won = np.asarray(results["outcome"]).reshape(-1) == 1
    pos = np.asarray(results["position"]).reshape(-1)
    rate = lambda x: round(float(x), 6)
    later = won[pos > 0]
    return {"win_rate": rate(won.mean()), "win_rate_se": rate(np.sqrt(won.mean() * (1 - won.mean()) / won.size)),
            "win_rate_first_game": rate(won[pos == 0].mean()),
            "win_rate_later_games": rate(later.mean()) if later.size else None,
            "win_rate_by_position": [rate(x) for x in raidjax.win_rate_by_position(results)]}


def evaluate_teams(out: Path, cfg: Config, n_seeds: int, key: jax.Array) -> dict:
    """Every seed's trained team and PT-HR over ``cfg.eval_games`` games per content of
    ``eval_contents`` (same content, same typed PRNG ``key``), by raidjax's one protocol: chained
    arenas after a warm-up game, ``auto_games_per_arena`` games each (``raidjax.playtest``'s
    default). Returns a JSON-able dict: ``win_rate`` and ``heuristic_win_rate`` (means over the
    contents), and ``per_range`` keyed by ``eval_contents``' labels, each with the seeds' mean,
    ``per_seed`` (``chained_win_rates`` of each seed) and ``heuristic`` (PT-HR's)."""
    per_range = {}
    teams = [load_policy(out, seed=s) for s in range(n_seeds)]  # one policy, n_seeds weights: one compile
    for label, content in eval_contents(cfg).items():
        hr = chained_win_rates(raidjax.playtest(key, content, raidjax.policies.heuristic, cfg.eval_games))
        seeds = [chained_win_rates(raidjax.playtest(key, content, p, cfg.eval_games, weights=w)) for p, w in teams]
        per_range[label] = {k: round(float(np.mean([x[k] for x in seeds])), 6)
                            for k in ("win_rate", "win_rate_first_game")}
        per_range[label].update(per_seed=seeds, heuristic=hr)
    mean = lambda f: round(float(np.mean([f(v) for v in per_range.values()])), 6)
    return {
        "win_rate": mean(lambda v: v["win_rate"]),
        "heuristic_win_rate": mean(lambda v: v["heuristic"]["win_rate"]),
        "games_per_arena": auto_games_per_arena(cfg.eval_games),
        "per_range": per_range,
    }


def run_mapoca(cfg: Config, out: str | Path, *, preset: str = "cpu", seeds: int = 1, seed: int = 0,
               resume: bool = False, max_chunks: int | None = None) -> dict:
    """Train MA-POCA in the run folder ``out`` (or resume it), then evaluate the teams.

    Args:
        cfg: the trainer's config (``trainers.config.load_config``); ``cfg.eval_games`` games per
            content in the final evaluation (0 skips it; it may change on resume).
        out: the run folder. preset: the preset's name, recorded. seeds: seeds trained together
            (vmapped). seed: base PRNG seed. resume: continue the run in ``out``.
        max_chunks: stop after this many chunks (checkpointed; rerun with ``resume``).

    Returns:
        The result (also ``out/result.json`` and the last stdout line): ``win_rate``,
        ``heuristic_win_rate``, ``per_range``, ``env_steps_per_s``, ``seconds``, ...; or
        ``{"stopped_at_chunk": c}`` when ``max_chunks`` stopped it.
    """
    t_start = time.perf_counter()
    settings = {"trainer": "mapoca", "preset": preset, "seeds": seeds, "seed": seed,
                "config": {k: v for k, v in cfg.to_dict().items() if k != "eval_games"}, "eval_games": cfg.eval_games}
    with RunFolder(out, settings, resume=resume, ignore=("eval_games",)) as rf:
        if rf.finished:
            return rf.already_finished()
        _say(f"{cfg.num_updates} updates x {cfg.decisions_per_update} decisions x {seeds} seeds; {machine()}")
        keys = jax.random.split(jax.random.PRNGKey(seed), seeds)
        learner = mapoca_learner(make_trainer(cfg), (keys,), seeds)
        every = max(1, -(-cfg.checkpoint_every // cfg.updates_per_chunk))
        done = train(learner, rf.out / "checkpoints", rf.out, log=_say, checkpoint_every=every, max_chunks=max_chunks)
        if not done.finished:
            return {"stopped_at_chunk": done.update // cfg.updates_per_chunk}
        result = {"preset": preset, "skill_ranges": list(cfg.skill_ranges), "content_box": cfg.content_box,
                  "seeds": seeds, "env_steps": cfg.num_updates * cfg.decisions_per_update,
                  "env_steps_per_s": round(done.steps_per_s, 1), "compile_seconds": round(done.compile_seconds, 2),
                  "train_seconds": round(done.seconds, 2)}
        if cfg.eval_games > 0:
            t_eval = time.perf_counter()
            result.update(evaluate_teams(rf.out, cfg, seeds, jax.random.key(seed + 12345)))
            result["eval_seconds"] = round(time.perf_counter() - t_eval, 2)
        result["seconds"] = round(time.perf_counter() - t_start, 2)
        atomic_write(rf.out / "result.json", json.dumps(result, indent=1))
        print(json.dumps(result), flush=True)
        return result


def _rounded(x, key: str = ""):
    """The result's floats for its printed line: seconds to 0.01 s, the rest to 6 decimals (0.132, not
    0.13200000524520874)."""
    if isinstance(x, dict):
        return {k: _rounded(v, k) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_rounded(v, key) for v in x]
    if isinstance(x, float) and math.isfinite(x):
        return round(x, 2 if key.endswith("seconds") else 6)
    return x


def run_ppo_pcgrl(config: PPOConfig, out: str | Path, *, preset: str = "cpu", seeds: int = 1, seed: int = 0,
                  chunk: int = 4, resume: bool = False, max_chunks: int | None = None,
                  evaluation: dict | None = None, tester: str | Path | tuple | None = None) -> dict:
    """Train PPO-PCGRL in the run folder ``out`` (or resume it), then measure it beside PCG-HR and
    PCG-RD.

    Args:
        config: the generator's config (``trainers.config.load_config(..., learner="ppo_pcgrl")``).
        out: the run folder. preset: the preset's name, recorded. seeds: seeds per target group.
        seed: base PRNG seed. chunk: updates per jitted chunk (progress and checkpoint period).
        resume, max_chunks: as ``run_mapoca``.
        evaluation: ``eval_episodes`` (0 skips it), ``eval_gen_games``, ``eval_games``,
            ``greedy``, ``no_baselines`` (defaults 8, 100, 300, False, False; another key raises
            ``ValueError`` naming it); may change on resume.
        tester: a trained MA-POCA run folder playing the playtests (seed 0, sampled actions)
            instead of PT-HR, in training and evaluation, trained for ``config.players`` (else
            ``ValueError``); or a loaded ``(policy, weights)`` pair (``trainers.mapoca.load_policy``,
            ``raidjax.policies.OrHeuristic``).

    Returns:
        The result (also ``out/result.json`` and the last stdout line): ``mean_error`` (PPO),
        ``heuristic_mean_error``, ``random_mean_error``, ``yield``, ``pc1_sd``, ``seconds``, ...;
        or ``{"stopped_at_update": u}`` when ``max_chunks`` stopped it.
    """
    t_start = time.perf_counter()
    ev = {"eval_episodes": 8, "eval_gen_games": 100, "eval_games": 300, "greedy": False, "no_baselines": False}
    unknown = sorted(set(evaluation or {}) - set(ev))
    if unknown:
        raise ValueError(f"evaluation: unknown keys {unknown}; known: {sorted(ev)}")
    ev.update(evaluation or {})
    settings = {"trainer": "ppo_pcgrl", "preset": preset, "seeds": seeds, "seed": seed, "chunk": chunk,
                "config": config.to_dict(), "evaluation": ev}
    team = {}
    if tester is not None:  # loaded (and checked) before the run folder is touched
        loaded = isinstance(tester, tuple)
        policy, weights = tester if loaded else load_policy(tester, seed=0, deterministic=False)
        if not loaded:  # a team trained for other players would play them without a word
            trained_for = tuple(Config.from_dict(checkpoint.load_config(tester)).players)
            if trained_for != tuple(config.players):
                raise ValueError(f"tester: {tester} was trained for players {list(trained_for)}; the generator "
                                 f"edits content for {list(config.players)} (train the tester with the same --players)")
        team = {"tester": policy, "tester_weights": weights}
        # the weights' digest decides whether a resume continues the same run; the folder may move
        settings.update(tester=checkpoint.digest(weights))
        if not loaded:
            settings.update(tester_run=str(Path(tester).resolve()))
    with RunFolder(out, settings, resume=resume, ignore=("evaluation", "tester_run")) as rf:
        if rf.finished:
            return rf.already_finished()
        pairs, labels = target_groups(config, seeds)
        keys = jax.random.split(jax.random.key(seed), len(labels))
        _say(f"preset={preset} groups={len(labels)} updates={config.num_updates} "
             f"steps/update={config.n_arenas * config.n_steps} n_games={config.n_games}")
        learner = ppo_learner(config, keys, jnp.asarray(pairs), max(1, chunk), **team)
        done = train(learner, rf.out / "checkpoints", rf.out, log=_say, max_chunks=max_chunks, max_to_keep=2)
        if not done.finished:
            return {"stopped_at_update": done.update}
        t_eval = time.perf_counter()
        res = {"train_seconds": done.seconds, "preset": preset, "seeds": seeds,
               "total_steps": config.num_updates * config.n_arenas * config.n_steps, "groups": len(labels),
               "n_games": config.n_games, "cpu_count": os.cpu_count()}
        if ev["eval_episodes"] > 0:
            ppo = PPOGenerator(config, done.state["params"], labels)
            gens = generate_episodes(jax.random.key(seed + 1), {"PPO": ppo},
                                     gen_games=ev["eval_gen_games"], greedy=ev["greedy"], episodes=ev["eval_episodes"],
                                     eval_games=ev["eval_games"], baselines=not ev["no_baselines"], **team,
                                     log=lambda s: _say(f"evaluation: {s}"))
            summ = pcg.quality.summarize(gens)
            atomic_write(rf.out / "eval.json", finite_json(summ, indent=1))
            for name, s in summ.items():
                c = s["controllability"]
                _say(f"{name}: mean error {c['err_mean']:.3f} ± {c['err_sd']:.3f} (n={c['n']}) yield {s['yield']:.2f} "
                     f"edits {s['edits_mean']:.1f} PC1 SD {s['pc1_sd_mean']:.3f}")
            res.update({"mean_error": summ["PPO"]["controllability"]["err_mean"],
                        "heuristic_mean_error": summ.get("PCG-HR", {}).get("controllability", {}).get("err_mean"),
                        "random_mean_error": summ.get("PCG-RD", {}).get("controllability", {}).get("err_mean"),
                        "pc1_sd": {n: s["pc1_sd_mean"] for n, s in summ.items()},
                        "yield": {n: s["yield"] for n, s in summ.items()},
                        "eval_seconds": time.perf_counter() - t_eval})
        res["seconds"] = time.perf_counter() - t_start
        res = json.loads(finite_json(_rounded(res)))  # NaN as null: valid JSON
        atomic_write(rf.out / "result.json", json.dumps(res, indent=1))
        print(json.dumps(res), flush=True)
        return res
