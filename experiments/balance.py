"""Automated content balancing end to end (PROTOCOLS.md §13): a skill generator whose playtests are
played by a robust learned team, compared with one trained against the paper's scripted PT-HR.

    python -m experiments.balance --scale {smoke,cpu,paper} --out DIR [--seed N] [--resume]

The question it answers: does content balanced with a scripted tester stay balanced for skilled
play? Stages (``trainers.runfolder``; rerun with ``--resume`` to continue; the three trainers
resume mid-training from their own checkpoints, the other stages rerun whole):

1. ``tester``: MA-POCA trained over the generator's whole content box (``trainers.runs.run_mapoca``
   with ``content_box``: range, cool time, cast time and coefficient drawn per episode), in ``DIR/tester``.
2. ``tester_check``: the tester's and PT-HR's win rates over a grid of the box (``grid`` values
   per parameter, ``grid_games`` games per skill), and Benchmark 1's AdjustedScore on ``heldout``
   skills drawn from the box with a fixed seed: the tester's win rate ÷ that of a specialist
   trained on that one skill (all specialists in one vmapped program, checkpointed in
   ``DIR/specialists``).
3. ``generator_learned`` / ``generator_scripted``: PPO-PCGRL (``trainers.runs.run_ppo_pcgrl``) trained
   against the tester / against PT-HR, in ``DIR/generator_{learned,scripted}``.
4. ``generate``: each generator, measuring with its own tester, runs ``episodes`` episodes per
   target 0.1..0.7 (``gen_games`` games per measurement, sampled actions, episodes end at the
   ±0.02 band or after ``max_edits``); every final skill is then played by *both* testers with
   ``eval_games`` games each. Raw outputs: ``generated.npz``, ``csv/generated.csv``.
5. ``report``: the skill-gap, controllability and diversity tables and figures
   (``experiments.balance_report``), all recomputable from ``generated.npz``.

The last stdout line is the JSON summary (also ``summary.json``).
"""

from __future__ import annotations

import argparse
import dataclasses
import io
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

import raidjax
from raidjax import pcg
from raidjax.io import HelpFormatter, atomic_write, fmt_seconds, run_cli
from trainers import checkpoint, loop
from trainers.config import PRESETS, Config, PPOConfig
from trainers.curriculum import range_table
from trainers.generate import PPOGenerator, generate_episodes, target_groups
from trainers.mapoca import load_policy, make_trainer
from trainers.runfolder import RunFolder, add_run_arguments
from trainers.runs import mapoca_learner, run_mapoca, run_ppo_pcgrl

GENERATORS = ("learned", "scripted")  # trained against the MA-POCA tester / against PT-HR


@dataclasses.dataclass(frozen=True)
class Scale:
    """Budgets of one scale.

    Attributes:
        tester: ``trainers.config.Config`` overrides on the MA-POCA ``preset`` (``content_box`` is
            always on); the specialists of the AdjustedScore train with the same settings.
        heldout: held-out skills of the AdjustedScore (one specialist each).
        grid, grid_games: box grid values per parameter (``pcg.measurement.box_grid``) and games per skill.
        ppo: ``trainers.ppo_pcgrl.PPOConfig`` overrides on its ``preset`` (both generators).
        chunk: PPO updates per jitted chunk.
        episodes: generation episodes per target and generator.
        gen_games: games per generator measurement during generation.
        max_edits: edits per generation episode at most.
        eval_games: games of each tester on every final skill.
        preset: the trainers' preset (``cpu`` or ``paper``, in ``trainers.config.PRESETS`` of both
            learners).
    """

    tester: dict
    heldout: int
    grid: int
    grid_games: int
    ppo: dict
    chunk: int
    episodes: int
    gen_games: int
    max_edits: int
    eval_games: int
    preset: str = "cpu"


SCALES = {
    # A few minutes of compiling: tiny learners and a few games (used by the tests; its numbers mean nothing).
    "smoke": Scale(tester=dict(n_arenas=8, n_steps=8, n_minibatches=2, update_epochs=1, hidden=8, layers=1, heads=1,
                               updates_per_chunk=1, checkpoint_every=1, total_steps=128),
                   heldout=1, grid=2, grid_games=4,
                   ppo=dict(n_arenas=4, n_steps=4, total_steps=32, update_epochs=1, n_minibatches=2, hidden=8, layers=1,
                            n_games=4, max_edits=4),
                   chunk=1, episodes=1, gen_games=4, max_edits=3, eval_games=4),
    # About 1 h on 2 CPU cores (40 min 33 s on 2026-11-24 with that day's lighter MA-POCA preset,
    # docs/results/balancing.md; today's trains about half as many decisions/s): a 2 M-decision tester and 3 specialists
    # with the same budget, generators of 2 048 edits at 20 games per measurement, 6 episodes per target.
    "cpu": Scale(tester=dict(total_steps=2_000_000), heldout=3, grid=3, grid_games=40,
                 ppo=dict(n_arenas=16, n_steps=8, total_steps=2048, n_games=20), chunk=2,
                 episodes=6, gen_games=20, max_edits=20, eval_games=100),
    # The paper's budgets, for an accelerator (not run here): the MA-POCA paper preset (16.7 M
    # decisions) for the tester and 5 specialists, the PPO paper preset (one model per target,
    # 20 000 edits, 100 games per measurement), 100 episodes per target, 300-game cross-play.
    "paper": Scale(tester={}, heldout=5, grid=5, grid_games=100, ppo={}, chunk=2, episodes=100, gen_games=100,
                   max_edits=40, eval_games=300, preset="paper"),
}


@dataclasses.dataclass(frozen=True)
class Team:
    """The team and the generator's parameters: ``players`` (class presets) and ``parameters``
    (``raidjax.pcg.space`` names; empty = the paper's four on three mages)."""

    players: tuple[str, ...] = ("mage", "mage", "mage")
    parameters: tuple[str, ...] = ()

    @property
    def space(self) -> pcg.Space:
        return pcg.make_space(self.parameters, self.players)


def tester_config(scale: Scale, team: Team) -> Config:
    """The tester's MA-POCA config (the scale's preset and overrides, ``content_box``)."""
    return PRESETS["mapoca"][scale.preset].replace(**scale.tester, content_box=True, eval_games=0, players=team.players,
                                  parameters=team.parameters)


def heldout_skills(n: int, space: pcg.Space, seed: int = 2024) -> np.ndarray:
    """``n`` points uniform in ``space``'s box from a fixed seed: ``float32[n, K]``."""
    rng = np.random.default_rng(seed)
    return rng.uniform(space.low, space.high, (n, space.size)).astype(np.float32)


PAD = 32


@partial(jax.jit, static_argnames=("n_games", "tester", "team"))
def _win_rates(keys, skills, weights, n_games: int, tester, team: Team):
    game, space = pcg.base_game(team.players), team.space

    def one(k, sk):
        return jnp.mean(pcg.play_outcomes(k, game, sk, n_games, tester, weights, space).astype(jnp.float32))

    return jax.vmap(one)(keys, skills)


def win_rates(key, skills: np.ndarray, n_games: int, team: Team, tester=raidjax.policies.heuristic,
              weights=None) -> np.ndarray:
    """Win rates ``float64[k]`` of ``tester`` (with ``weights``) on each generated content
    ``float32[k, K]`` (``team.space``), ``n_games`` games each, one vmapped program.

    The contents are padded to a multiple of ``PAD`` rows (copies of the first, played and
    dropped) so that the tester check and the cross-play, with their different numbers of
    contents, share one compiled program per tester; the keys are ``split(key, k)`` either way."""
    skills = np.asarray(skills, np.float32)
    k = len(skills)
    pad = -k % PAD
    keys = jax.random.split(key, k)
    keys = jnp.concatenate([keys, jnp.repeat(keys[:1], pad, axis=0)])
    skills = np.concatenate([skills, np.repeat(skills[:1], pad, axis=0)])
    return np.asarray(_win_rates(keys, jnp.asarray(skills), weights, n_games, tester, team), float)[:k]


def stage_tester(rf: RunFolder, scale: Scale, team: Team, seed: int) -> dict:
    out = rf.out / "tester"
    return run_mapoca(tester_config(scale, team), out, preset=scale.preset, seed=seed,
                      resume=(out / "config.json").exists())


def train_specialists(rf: RunFolder, scale: Scale, team: Team, skills: np.ndarray, seed: int) -> dict:
    """One MA-POCA specialist per generated content (``float32[k, K]``), trained together through
    ``trainers.loop`` (checkpoints in ``DIR/specialists``, so the stage resumes mid-training):
    actor weights with a leading axis ``k``."""
    cfg = tester_config(scale, team).replace(content_box=False)
    base, space = pcg.base_game(team.players), team.space
    trainer = make_trainer(cfg, base_params=base, redraw_ranges=False, fixed_content=True)
    contents = jax.vmap(lambda sk: space.apply(base, sk))(jnp.asarray(skills))
    tables = jnp.stack([range_table(cfg.skill_ranges)] * len(skills))  # unused: the content is fixed
    keys = jax.random.split(jax.random.PRNGKey(seed + 31), len(skills))
    learner = mapoca_learner(trainer, (keys, contents, tables), len(skills),
                             describe=lambda r: f"training win rate {r['win_rate']:.3f}")
    every = max(1, -(-cfg.checkpoint_every // cfg.updates_per_chunk))
    done = loop.train(learner, rf.path("specialists", "checkpoints"), rf.out / "specialists",
                      log=lambda s: rf.log(f"specialists: {s}"), checkpoint_every=every)
    return done.state.params["actor"]


def testers(rf: RunFolder) -> dict[str, tuple]:
    """The two playtesting teams as ``{name: (policy, weights)}`` (``GENERATORS``' names): the
    MA-POCA tester (seed 0, sampled actions) and PT-HR, both as ``raidjax.policies.OrHeuristic``
    of the tester, so that every playtesting program (tester check, training, generation,
    cross-play) compiles once for the two teams instead of once per team."""
    policy, weights = load_policy(rf.out / "tester", deterministic=False)
    both = raidjax.policies.OrHeuristic(policy)
    return {"learned": (both, both.weights(weights, False)), "scripted": (both, both.weights(weights, True))}


def stage_tester_check(rf: RunFolder, scale: Scale, team: Team, seed: int) -> dict:
    teams = testers(rf)
    policy = teams["learned"][0].policy  # the tester's architecture, played with each specialist's weights
    key = jax.random.PRNGKey(seed + 101)
    space = team.space
    grid = pcg.measurement.box_grid(scale.grid, space) if space.size <= 4 else pcg.measurement.box_probes(space)
    held = heldout_skills(scale.heldout, space)
    both = np.concatenate([grid, held])  # one program per tester for the grid and the held-out skills
    learned, tester_win = np.split(win_rates(key, both, scale.grid_games, team, *teams["learned"]), [len(grid)])
    rf.log(f"tester_check: the tester played {len(both)} skills x {scale.grid_games} games; PT-HR next")
    scripted, scripted_win = np.split(win_rates(key, both, scale.grid_games, team, *teams["scripted"]), [len(grid)])
    rf.log(f"tester_check: PT-HR played them; {len(held)} specialists next")
    rf.write_csv("tester_grid", [{**dict(zip(space.names, map(float, sk), strict=True)),
                                  "learned": float(a), "scripted": float(b)}
                                 for sk, a, b in zip(grid, learned, scripted, strict=True)])
    spec = train_specialists(rf, scale, team, held, seed)
    game = pcg.base_game(team.players)
    spec_win = np.asarray(jax.jit(jax.vmap(lambda k, sk, w: jnp.mean(
        pcg.play_outcomes(k, game, sk, scale.grid_games, policy, w, space).astype(jnp.float32))))(
        jax.random.split(key, len(held)), jnp.asarray(held), spec), float)
    rows = [{**dict(zip(space.names, map(float, sk), strict=True)), "tester": float(a), "specialist": float(s),
             "scripted": float(b), "adjusted": float(a / s) if s > 0 else float("nan")}
            for sk, a, s, b in zip(held, tester_win, spec_win, scripted_win, strict=True)]
    rf.write_csv("tester_heldout", rows)
    adjusted = [r["adjusted"] for r in rows if np.isfinite(r["adjusted"])]
    return {"grid_learned": float(learned.mean()), "grid_scripted": float(scripted.mean()),
            "grid_learned_beats_scripted": float(np.mean(learned > scripted)),
            "adjusted_mean": float(np.mean(adjusted)) if adjusted else None, "adjusted_n": len(adjusted)}


def train_generator(rf: RunFolder, scale: Scale, team: Team, name: str, seed: int) -> dict:
    """Train generator ``name`` (``trainers.runs.run_ppo_pcgrl``, no evaluation) in
    ``DIR/generator_<name>``: the scale's PPO fields and the team; it playtests with ``testers``'
    team ``name`` (the MA-POCA tester or PT-HR, one compiled training program for the two)."""
    config = PRESETS["ppo_pcgrl"][scale.preset].replace(**scale.ppo, players=team.players, parameters=team.parameters)
    out = rf.out / f"generator_{name}"
    return run_ppo_pcgrl(config, out, preset=scale.preset, seed=seed, chunk=scale.chunk,
                         evaluation={"eval_episodes": 0}, tester=testers(rf)[name],
                         resume=(out / "config.json").exists())


def stage_generate(rf: RunFolder, scale: Scale, team: Team, seed: int) -> dict:
    teams = testers(rf)
    out = {k: [] for k in ("generator", "target", "skill", "gen_win_rate", "edits", "reached", "learned", "scripted")}
    for g, name in enumerate(GENERATORS):
        ckpt = rf.out / f"generator_{name}" / "checkpoints"
        w, config = checkpoint.load_policy_weights(ckpt / str(checkpoint.latest_step(ckpt)))  # the final one
        config = PPOConfig.from_dict(config)
        groups = jax.tree.leaves(w)[0].shape[0]  # seeds, or seeds x targets when the target is not observed
        _, labels = target_groups(config, groups if config.observe_target else groups // len(pcg.quality.TARGETS))
        gens = generate_episodes(jax.random.PRNGKey(seed + 200 + g), {"PPO": PPOGenerator(config, w, labels)},
                                 gen_games=scale.gen_games, greedy=False, episodes=scale.episodes, eval_games=0,
                                 baselines=False, max_edits=scale.max_edits, tester=teams[name][0],
                                 tester_weights=teams[name][1],
                                 log=lambda s, g=g: rf.log(f"generate: generator {GENERATORS[g]}: {s}"))["PPO"]
        n = len(gens["target"])
        rf.log(f"generate: generator {name} ({g + 1} of {len(GENERATORS)}) made {n} skills")
        out["generator"].append(np.full(n, g))
        for k in ("target", "skill", "gen_win_rate", "edits", "reached"):
            out[k].append(gens[k])
    data = {k: np.concatenate(v) for k, v in out.items() if v}
    for t, (policy, weights) in teams.items():  # both testers play every final skill, with the same keys
        data[t] = win_rates(jax.random.PRNGKey(seed + 300), data["skill"], scale.eval_games, team, policy, weights)
        rf.log(f"generate: the {t} tester played the {len(data['skill'])} skills, {scale.eval_games} games each")
    buf = io.BytesIO()
    np.savez(buf, generators=np.asarray(GENERATORS), parameters=np.asarray(team.space.names), **data)
    atomic_write(rf.out / "generated.npz", buf.getvalue())
    rf.write_csv("generated", [{"generator": GENERATORS[int(data["generator"][i])], "target": float(data["target"][i]),
                                **{p: float(v) for p, v in zip(team.space.names, data["skill"][i], strict=True)},
                                "gen_win_rate": float(data["gen_win_rate"][i]), "edits": int(data["edits"][i]),
                                "learned": float(data["learned"][i]), "scripted": float(data["scripted"][i])}
                               for i in range(len(data["target"]))])
    return {"skills": int(len(data["target"]))}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(prog="python -m experiments.balance", formatter_class=HelpFormatter,
                                 description="The integrated balancing loop: a learned playtester inside the "
                                 "skill generator, against the scripted PT-HR (PROTOCOLS.md §13).")
    add_run_arguments(ap, SCALES, "budgets (smoke: a few minutes, for the plumbing; cpu: about 1 h on 2 cores; "
                      "paper: the paper's budgets, for an accelerator)")
    ap.add_argument("--players", nargs="+", default=["mage"] * 3,
                    help="the team's class presets, e.g. warrior mage priest (default: three mages)")
    ap.add_argument("--parameters", nargs="+", default=[],
                    help="the generator's parameters (raidjax.pcg.space names, e.g. mage.skill1.range=1:20 "
                    "boss.max_hp=500:3000; default: the paper's four, which need three mages)")
    args = ap.parse_args(argv)
    scale = SCALES[args.scale]
    team = Team(tuple(args.players), tuple(args.parameters))
    tester_config(scale, team)  # a bad team or parameter fails here, before anything is written
    with RunFolder(args.out, {"experiment": "balance", "scale": args.scale, "seed": args.seed,
                              "players": list(team.players), "parameters": list(team.parameters),
                              "budgets": dataclasses.asdict(scale)}, resume=args.resume) as rf:
        if rf.finished:
            return rf.already_finished()
        from experiments import balance_report  # matplotlib only for the report

        tester = rf.stage("tester", lambda: stage_tester(rf, scale, team, args.seed))
        check = rf.stage("tester_check", lambda: stage_tester_check(rf, scale, team, args.seed))
        for name in GENERATORS:
            rf.stage(f"generator_{name}",
                     lambda name=name: train_generator(rf, scale, team, name, args.seed))
        rf.stage("generate", lambda: stage_generate(rf, scale, team, args.seed))
        report = rf.stage("report", lambda: balance_report.report(rf))
        rf.log(f"done in {fmt_seconds(sum(rf.stage_seconds().values()))}")
        return rf.finish({"scale": args.scale, "tester_decisions": tester["env_steps"], **check, **report})


def cli(argv=None) -> None:
    """``main`` as a command line: one-line errors (exit 2), one line on Ctrl-C (exit 130)."""
    run_cli(lambda: main(argv), (ValueError, checkpoint.CheckpointError),
            "finished stages and the newest checkpoints are kept: rerun the same command with --resume")


if __name__ == "__main__":
    raidjax.use_recommended_xla_flags()
    cli()
