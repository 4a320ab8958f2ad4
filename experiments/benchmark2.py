"""Benchmark 2 of the RaidEnv paper (GAME.md §10, PROTOCOLS.md §11): controllable skill generation, as one
resumable command::

    python -m experiments.benchmark2 --scale {smoke,cpu,gpu,paper} --out DIR [--seed N] [--protocol {paper,raidjax}]

Stages (each a ``RunFolder.stage``; rerunning the same command with ``--resume`` resumes after the
last finished one, and ``train`` also resumes mid-training from its latest orbax checkpoint):

1. ``train``: PPO-PCGRL (``trainers.ppo_pcgrl``) in jitted chunks, orbax checkpoints in
   ``DIR/checkpoints/ppo``, per-update metrics in ``train/metrics.csv``, progress in ``log.txt``.
2. ``generate``: the trained PPO, PCG-HR and PCG-RD generators run ``episodes`` episodes per target
   (0.1..0.7) under the protocol (``raidjax.pcg.quality.PROTOCOLS``). ``paper`` (default): strict
   40-decision episodes, every decision measured with ``eval_games`` (300) PT-HR games, greedy PPO,
   each episode's last measured skill kept with that measurement. ``raidjax``: episodes end at the
   band, ``gen_games`` per measurement, sampled PPO, the final skill re-measured with
   ``eval_games`` games. The episodes are generated in ``parts``, every method and target side by
   side in each; a finished part is saved (``gen_parts/``), so an interruption loses at most the part
   under way and a resumed run neither repeats nor loses a finished skill; the result is
   ``generated.npz`` and ``csv/generated.csv``.
3. ``report``: controllability / diversity / yield tables beside the paper's numbers, the t-SNE,
   controllability and error-vs-diversity figures (``experiments.b2_report``); under ``paper``
   every (method, target) group is cut to 300 (or the smallest group) before the metrics, with a
   fixed seed.

Variants beyond the paper's protocol (each recorded in ``config.json``): ``--pool-repeats`` (the
generation environment pools the games of an unchanged skill, for all three generators),
``--edit-cost``, ``--goal-cost`` with ``--goal-axis`` (a style goal), ``--ent-coef`` and
``--total-steps`` (PPO learner), ``--seeds``, ``--episodes``.

``stages/records.json`` holds each finished stage's and part's start, end, seconds, commit and
machine. The last stdout line is the JSON summary (also ``summary.json``), with ``compute_seconds``
(the finished work's time, resumes summed) and ``span_seconds`` (first start to last end).
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import time

import jax
import jax.numpy as jnp
import numpy as np

from raidjax import pcg
from raidjax.io import HelpFormatter, atomic_write, fmt_seconds, run_cli, utc_now, whole_number_arg
from raidjax.pcg import quality as pm
from trainers import checkpoint, loop
from trainers.config import PPOConfig, load_config
from trainers.generate import BASELINES, PPOGenerator, generate_episodes, target_groups
from trainers.runfolder import RunFolder, add_run_arguments
from trainers.runs import ppo_learner

PPO_PAPER, PPO_OBSERVED = "PPO", "PPO, target observed"  # one model per target (the paper's) / one for all
FIELDS = ("target", "skill", "win_rate", "gen_win_rate", "edits", "reached")


def ppo_method(config: PPOConfig) -> str:
    """The generation method a PPO config trains: the paper's way (one model per fixed target, the
    target not observed) or raidjax's (one model for every target, observed)."""
    return PPO_OBSERVED if config.observe_target else PPO_PAPER


@dataclasses.dataclass(frozen=True)
class Scale:
    """Budgets of one scale.

    Attributes:
        preset: ``trainers.config.PRESETS["ppo_pcgrl"]`` key; ``ppo`` holds overrides of its fields.
        seeds: PPO training seeds (per fixed target when the preset does not observe the target).
        paper_ppo: also train the paper's PPO (``paper`` preset: one model per fixed target, 20 000
            steps, 100 games per measurement) with these overrides (``{}``: none) and generate with
            both PPOs side by side; ``None``: the scale's PPO only.
        paper_ppo_seeds: seeds per target of that paper PPO.
        chunk: PPO updates per jitted chunk (progress / checkpoint period).
        episodes: generation episodes per target and method (PPO: split evenly over seeds).
        parts: generation is done in this many saved parts (``episodes`` divisible by it).
        gen_games: PT-HR games per generator measurement (``raidjax`` protocol).
        eval_games: PT-HR games behind each kept win rate (300 in PROTOCOLS.md §11): every measurement
            of the ``paper`` protocol, the re-measurement of the ``raidjax`` protocol.
        decisions: overrides the ``paper`` protocol's 40 decisions per episode (``None``: 40).
        tsne_per_target: at most this many skills per (method, target) in the t-SNE figure.
        bootstrap: resamples behind the report's 95 % intervals (``b2_report.bootstrap``).
        min_kept: the diversity table leaves out (method, target) groups that kept fewer skills
            and cuts the others to the smallest one's size (``raidjax.pcg.quality.diversity``).
    """

    preset: str
    ppo: dict
    seeds: int
    chunk: int
    episodes: int
    parts: int
    gen_games: int
    eval_games: int
    decisions: int | None = None
    paper_ppo: dict | None = None
    paper_ppo_seeds: int = 1
    tsne_per_target: int = 300
    bootstrap: int = 1000
    min_kept: int = 20


SCALES = {
    # Seconds: tiny learners, a few games per measurement, 4-decision paper-protocol episodes (used
    # by the tests; its numbers mean nothing).
    "smoke": Scale(preset="cpu", ppo=dict(n_arenas=4, n_steps=4, total_steps=32, update_epochs=1, n_minibatches=2,
                                          hidden=16, layers=2, n_games=4, max_edits=6),
                   seeds=1, chunk=1, episodes=2, parts=1, gen_games=4, eval_games=4, decisions=4,
                   paper_ppo=dict(n_arenas=2, n_steps=2, total_steps=4, update_epochs=1, n_minibatches=2, hidden=16,
                                  layers=2, n_games=4, max_edits=6),
                   bootstrap=50, min_kept=2),
    # One resumable run on a 2-core CPU (it may span sessions), the paper protocol unchanged (40-decision
    # episodes, 300-game measurements, greedy PPO, the last measured skill): PPO both ways side by
    # side, the paper's (one model per fixed target, 20 000 steps, N = 100 games per measurement,
    # one seed) and raidjax's (the cpu preset: one model for all targets, target observed, N = 50,
    # 10 240 steps), then 30 episodes per target and method (paper: 5 000 skills per target, 300
    # kept) in 3 parts of 10, every method's episodes side by side (one part's measurement is
    # 4 x 7 x 10 x 300 = 84 000 games). Measured on 2 cores (docs/results/benchmark2.md): 7 h 37 min of
    # compute: the paper's PPO trains on 7 x 20 000 x 100 = 14 M games in about 4 h 55 min, generation
    # plays 4 x 7 x 30 x 40 x 300 = 10.1 M in about 2 h 35 min (three parts of 47-56 min), ours 0.5 M
    # in 9 min.
    # Part i's key does not depend on the number of parts: a run with --episodes 40 plays a
    # 30-episode run's parts first.
    "cpu": Scale(preset="cpu", ppo=dict(total_steps=10240), seeds=1, chunk=5, episodes=30, parts=3,
                 gen_games=100, eval_games=300, paper_ppo={}),
    # The paper's budgets: one model per fixed (unobserved) target, 5 seeds, 20 000 steps, N = 100
    # in training and 300 in evaluation, 5 models x 1 000 skills per target (paper §5.3; PCG-HR and
    # PCG-RD as many), cut to 300 per (method, target) by the paper protocol's metrics.
    "paper": Scale(preset="paper", ppo={}, seeds=5, chunk=2, episodes=5000, parts=50, gen_games=300,
                   eval_games=300),
    # For one accelerator: the paper's models and training, 1 000 skills per target and method
    # (the paper protocol's metrics keep 300 of them). Not run yet: at the 105 000 PT-HR games/s one
    # H100 measured (RESULTS, "On a GPU") its 70 M training and 252 M generation games take about
    # 50 min at best.
    "gpu": Scale(preset="paper", ppo={}, seeds=5, chunk=2, episodes=1000, parts=10, gen_games=300,
                 eval_games=300),
}


def ppo_config(scale: Scale) -> PPOConfig:
    """The ``PPOConfig`` of a scale (its preset with the scale's overrides)."""
    return load_config(scale.preset, learner="ppo_pcgrl", **scale.ppo)


def paper_ppo_config(scale: Scale) -> PPOConfig:
    """The ``PPOConfig`` of the paper's PPO trained beside the scale's (``Scale.paper_ppo``; the
    ``paper`` preset with those overrides)."""
    return load_config("paper", learner="ppo_pcgrl", **(scale.paper_ppo or {}))


def _parse(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m experiments.benchmark2",
                                 description="Benchmark 2 (content generation) of the RaidEnv paper",
                                 formatter_class=HelpFormatter)
    add_run_arguments(ap, SCALES, "budgets: smoke (minutes), cpu (about 7 h 40 min on 2 cores, resumable), "
                      "gpu (one accelerator), paper")
    ap.add_argument("--protocol", choices=sorted(pm.PROTOCOLS), default="paper",
                    help="paper: strict 40-decision episodes measured with eval_games games at every edit, greedy "
                    "PPO, last measured skill, groups cut to 300; raidjax: early stop at the band, sampled PPO, "
                    "final skill re-measured, unequal groups")
    ap.add_argument("--edit-cost", type=float, help="PPO learner penalty per tick moved (env reward units; "
                    "default: the scale's, 0 = the paper's reward)")
    ap.add_argument("--goal-cost", type=float, help="with --goal-axis: PPO learner penalty per squared tick of "
                    "distance to the episode's style goal (default 0 = off)")
    ap.add_argument("--goal-axis", type=pcg.goals.axis_arg, help="a style goal per episode at one end of this axis, 4 "
                    "comma-separated signs in {-1,0,1} for range,cool_time,cast_time,coefficient (1,1,1,1 = heavy "
                    "vs light skills) (default: none)")
    ap.add_argument("--ent-coef", type=float, help="PPO entropy coefficient (default: the preset's)")
    ap.add_argument("--total-steps", type=whole_number_arg(1),
                    help="PPO generator steps per group (default: the scale's)")
    ap.add_argument("--seeds", type=whole_number_arg(1), help="PPO seeds trained together (default: the scale's)")
    ap.add_argument("--episodes", type=whole_number_arg(1),
                    help="generation episodes per target and method, in parts of the scale's size (cpu: "
                    f"{SCALES['cpu'].episodes // SCALES['cpu'].parts} episodes per part; part i is the same "
                    "whatever the count) (default: the scale's)")
    ap.add_argument("--min-kept", type=whole_number_arg(2),
                    help="diversity: (method, target) groups that kept fewer skills are left out, the others cut to "
                    "the smallest one's size; a finished run resumed with another value is reported again "
                    f"(default: the scale's, cpu {SCALES['cpu'].min_kept})")
    ap.add_argument("--pool-repeats", action="store_true",
                    help="generation env: re-measuring an unchanged skill pools its games (all three "
                    "generators, training and generation)")
    return ap.parse_args(argv)


class _Learner:
    """A PPO learner of a run: its config, groups, ``trainers.loop.Learner``, checkpoints folder and
    generation method. ``paper``: the paper's PPO trained beside the scale's (``Scale.paper_ppo``)."""

    def __init__(self, run: RunFolder, scale: Scale, seed: int, paper: bool = False):
        self.config = paper_ppo_config(scale) if paper else ppo_config(scale)
        pairs, self.labels = target_groups(self.config, scale.paper_ppo_seeds if paper else scale.seeds)
        self.G = len(self.labels)
        self.steps_per_update = self.config.n_arenas * self.config.n_steps
        keys = jax.random.split(jax.random.key(seed + (7919 if paper else 0)), self.G)
        self.learner = ppo_learner(self.config, keys, jnp.asarray(pairs), scale.chunk)
        self.name = "ppo_paper" if paper else "ppo"
        self.ckpt = run.out / "checkpoints" / self.name
        self.method = ppo_method(self.config)

    def restore(self):
        """``(runner, update)`` of the latest checkpoint, or ``(None, 0)`` without checkpoints."""
        if checkpoint.latest_step(self.ckpt) is None:
            return None, 0
        runner, _, meta = checkpoint.restore(self.ckpt, self.learner.abstract_state(), quarantine=True)
        return runner, int(meta["update"])

    def final_weights(self):
        """The networks of the final checkpoint (an older one would be a less trained generator)."""
        total = self.config.num_updates
        if checkpoint.latest_step(self.ckpt) != total:
            raise RuntimeError(f"no final PPO checkpoint (update {total}) in {self.ckpt}")
        return checkpoint.load_policy_weights(self.ckpt / str(total))[0]


def learners_of(run: RunFolder, scale: Scale, seed: int) -> list[_Learner]:
    """The run's PPO learners: the scale's, and the paper's beside it when ``scale.paper_ppo`` is set."""
    return [_Learner(run, scale, seed)] + ([_Learner(run, scale, seed, paper=True)] if scale.paper_ppo is not None
                                           else [])


def methods_of(scale: Scale) -> tuple[str, ...]:
    """The generation methods of a scale's run, in the order of ``generated.npz``."""
    methods = [ppo_method(ppo_config(scale))] + ([ppo_method(paper_ppo_config(scale))] if scale.paper_ppo is not None
                                                 else [])
    return (*methods, *BASELINES)


def stage_train(run: RunFolder, scale: Scale, seed: int, paper: bool = False) -> dict:
    """Train one PPO learner (``paper``: the paper's beside the scale's) with checkpoints
    (``trainers.loop``); resume from the latest one. Returns ``train_seconds`` (cumulative over
    resumes, compiles excluded), ``steps`` (generator steps per group), ``groups``, ``updates``,
    ``seconds``."""
    lr = _Learner(run, scale, seed, paper)
    total = lr.config.num_updates
    run.log(f"{lr.name}: {lr.method}, {lr.G} group(s), {total} updates x {lr.steps_per_update} steps, "
            f"N = {lr.config.n_games} games per measurement")
    done = loop.train(lr.learner, lr.ckpt, run.out / "train", metrics_name="metrics_paper" if paper else "metrics",
                      log=lambda s: run.log(f"{lr.name}: {s}"), max_to_keep=2)
    return {"train_seconds": done.seconds, "steps": total * lr.steps_per_update, "groups": lr.G, "updates": total,
            "n_games": lr.config.n_games, "seconds": done.seconds}


def save_generated(path, gens: dict) -> None:
    """Write ``{method: generate output}`` atomically as an ``.npz`` with keys ``"<method>/<field>"``."""
    buf = io.BytesIO()
    np.savez(buf, **{f"{m}/{k}": v for m, g in gens.items() for k, v in g.items()})
    atomic_write(path, buf.getvalue())


def load_generated(path) -> dict[str, dict[str, np.ndarray]]:
    """Read ``save_generated``'s file: ``{method: {"target" [n], "skill" [n, 4], "win_rate" [n],
    "gen_win_rate" [n], "edits" [n], "reached" [n]}}`` (methods in file order)."""
    out: dict[str, dict[str, np.ndarray]] = {}
    with np.load(path) as z:
        for key in z.files:
            m, k = key.split("/", 1)
            out.setdefault(m, {})[k] = z[key]
    return out


def generated_rows(gens: dict) -> list[dict]:
    """One CSV row per episode: method, target, the 4 skill parameters, win_rate, gen_win_rate,
    edits, reached."""
    rows = []
    for m, g in gens.items():
        for i in range(len(g["target"])):
            rows.append({"method": m, "target": round(float(g["target"][i]), 6),
                         **{p: float(g["skill"][i, j]) for j, p in enumerate(pcg.PAPER_SPACE.fields)},
                         "win_rate": float(g["win_rate"][i]), "gen_win_rate": float(g["gen_win_rate"][i]),
                         "edits": int(g["edits"][i]), "reached": int(bool(g["reached"][i]))})
    return rows


def protocol_of(scale: Scale, name: str) -> pm.Protocol:
    """``pm.PROTOCOLS[name]`` with the scale's ``decisions`` override (paper protocol only)."""
    pr = pm.PROTOCOLS[name]
    if scale.decisions is not None and pr.decisions is not None:
        pr = dataclasses.replace(pr, decisions=scale.decisions)
    return pr


def generation_kwargs(scale: Scale, pr: pm.Protocol, max_edits: int, episodes: int) -> dict:
    """``trainers.generate.generate_episodes``'s keyword arguments under a protocol: per-edit games, greedy,
    strict length, measured edits per episode (``pr.max_edits(max_edits)``), re-measurement games
    (0: none)."""
    return dict(gen_games=scale.gen_games if pr.remeasure else scale.eval_games, greedy=pr.greedy,
                episodes=episodes, eval_games=scale.eval_games if pr.remeasure else 0,
                strict_length=pr.strict_length, max_edits=pr.max_edits(max_edits))


# Wall-clock of a whole run per scale, as measured (docs/results/benchmark2.md); printed before a run starts.
MEASURED_WALL = {"smoke": "a few minutes", "cpu": "7 h 37 min of compute (2026-11-29)"}


def planned_games(scale: Scale, pr: pm.Protocol) -> tuple[int, int]:
    """``(training games, generation games)`` a run plays at most: every training step measured with
    ``n_games`` games; every generation episode of 3 methods x 7 targets playing its start
    measurement and each measured edit (``pr.max_edits``) with its per-measurement games, plus the
    re-measurement of its kept skill (``raidjax`` protocol). Early stops (``raidjax``) play fewer."""
    cfg = ppo_config(scale)
    runs = [(cfg, scale.seeds)] + ([(paper_ppo_config(scale), scale.paper_ppo_seeds)]
                                   if scale.paper_ppo is not None else [])
    train = sum(c.num_updates * c.n_arenas * c.n_steps * len(target_groups(c, s)[1]) * c.n_games for c, s in runs)
    kw = generation_kwargs(scale, pr, cfg.max_edits, scale.episodes)
    per_episode = (1 + kw["max_edits"]) * kw["gen_games"] + kw["eval_games"]
    return train, len(methods_of(scale)) * len(pm.TARGETS) * scale.episodes * per_episode


def stage_generate(run: RunFolder, scale: Scale, seed: int, protocol: str = "paper") -> dict:
    """Generate with every PPO learner of the run (weights from their final checkpoints), PCG-HR and
    PCG-RD, every method's episodes side by side, in saved parts, under ``protocol``
    (``pm.PROTOCOLS`` key). Returns ``episodes`` per method, ``parts`` and ``seconds``."""
    lrs = learners_of(run, scale, seed)
    generators = {lr.method: PPOGenerator(lr.config, lr.final_weights(), lr.labels) for lr in lrs}
    per_part = scale.episodes // scale.parts
    kwargs = generation_kwargs(scale, protocol_of(scale, protocol), lrs[0].config.max_edits, per_part)
    t0, done_here, parts = time.perf_counter(), 0, []
    for i in range(scale.parts):
        path = run.path("gen_parts", f"part_{i:03d}.npz")
        if not path.exists():
            t, start = time.perf_counter(), utc_now()
            key = jax.random.fold_in(jax.random.key(seed + 1), i)
            gens = generate_episodes(key, generators, **kwargs,
                                     log=lambda s, i=i: run.log(f"generate: part {i + 1}/{scale.parts}: {s}"))
            run.record(part_record(i), start, time.perf_counter() - t)  # first: a saved part has its record
            save_generated(path, gens)
            done_here += 1
            eta = (time.perf_counter() - t0) / done_here * (scale.parts - i - 1)
            run.log(f"generate: part {i + 1}/{scale.parts} ({per_part} episodes per target and method, "
                    f"{len(gens)} methods side by side) in {fmt_seconds(time.perf_counter() - t)}, "
                    f"ETA {fmt_seconds(eta)}")
        parts.append(load_generated(path))
    gens = {m: {k: np.concatenate([p[m][k] for p in parts]) for k in FIELDS} for m in parts[0]}
    save_generated(run.out / "generated.npz", gens)
    run.write_csv("generated", generated_rows(gens))
    errs = {m: float(np.mean(np.abs(g["target"] - g["win_rate"]))) for m, g in gens.items()}
    run.log("generate: mean |W_t - W_c| (all episodes) " + ", ".join(f"{m} {e:.3f}" for m, e in errs.items()))
    return {"episodes": {m: int(len(g["target"])) for m, g in gens.items()}, "parts": scale.parts,
            "seconds": time.perf_counter() - t0}


def part_record(i: int) -> str:
    """The ``RunFolder.record`` name of generation part ``i``."""
    return f"generate/part_{i:03d}"


def compute_time(run: RunFolder, tr: dict, tr_paper: dict | None) -> dict:
    """What the run's finished work cost: ``compute_seconds`` (both PPOs' training, cumulative over
    resumes with compiles excluded, every generation part and the report; work lost to an
    interruption is not counted), ``span_seconds`` (the wall-clock from the run's first start to
    the last piece's end, pauses between sessions included), ``first_start``, ``last_end`` and the
    ``commits`` the pieces ran at."""
    import datetime

    recs = run.records()
    parts = [r["seconds"] for n, r in recs.items() if n.startswith("generate/part_")]
    compute = tr["train_seconds"] + (tr_paper["train_seconds"] if tr_paper else 0.0) + sum(parts) + \
        recs.get("report", {}).get("seconds", 0.0)
    when = lambda s: datetime.datetime.fromisoformat(s)
    first, last = min(r["start"] for r in recs.values()), max(r["end"] for r in recs.values())
    return {"compute_seconds": compute, "span_seconds": (when(last) - when(first)).total_seconds(),
            "first_start": first, "last_end": last,
            "commits": sorted({r["machine"]["commit"] for r in recs.values()})}


# Settings only the report reads (its stage records them): a run resumed with other values is reported again.
REPORT_SETTINGS = ("bootstrap", "min_kept")


def scale_of(a) -> Scale:
    """The run's ``Scale``: ``SCALES[a.scale]`` with the command line's overrides (``_parse``'s
    namespace). ``--episodes`` keeps the scale's episodes per part and sets the number of parts, so
    part i (keyed by i alone) is the same whatever the count. Raises ValueError naming the flag."""
    scale = SCALES[a.scale]
    ppo = {"edit_cost": a.edit_cost, "goal_cost": a.goal_cost, "goal_axis": a.goal_axis,
           "ent_coef": a.ent_coef, "total_steps": a.total_steps,
           "pool_repeats": a.pool_repeats or None}
    per_part = scale.episodes // scale.parts
    if a.episodes is not None and a.episodes % per_part:
        raise ValueError(f"--episodes: {a.episodes} must be a multiple of the {a.scale} scale's "
                         f"{per_part} episodes per part")
    episodes = {} if a.episodes is None else {"episodes": a.episodes, "parts": a.episodes // per_part}
    scale = dataclasses.replace(scale, ppo={**scale.ppo, **{k: v for k, v in ppo.items() if v is not None}},
                                **({"seeds": a.seeds} if a.seeds is not None else {}),
                                **({"min_kept": a.min_kept} if a.min_kept is not None else {}), **episodes)
    if per_part % scale.seeds:
        raise ValueError(f"--seeds: {scale.seeds} PPO seeds must split the {per_part} episodes per part "
                         f"per target evenly")
    return scale


def main(argv=None) -> dict:
    """Run (or resume) Benchmark 2 at one scale. Returns the summary dict (also the last stdout line)."""
    from experiments import b2_report

    a = _parse(argv)
    scale = scale_of(a)
    pr = protocol_of(scale, a.protocol)
    config = {"benchmark": 2, "scale": a.scale, "seed": a.seed, "protocol": dataclasses.asdict(pr),
              **dataclasses.asdict(scale),
              "ppo_config": dataclasses.asdict(ppo_config(scale)), "targets": list(pm.TARGETS),
              **({"paper_ppo_config": dataclasses.asdict(paper_ppo_config(scale))} if scale.paper_ppo is not None
                 else {})}
    with RunFolder(a.out, config, resume=a.resume, ignore=REPORT_SETTINGS) as run:
        settings = {k: config[k] for k in REPORT_SETTINGS}
        made_with = (run.result("report") or {}).get("settings", {})
        if run.done("report") and made_with != settings:  # checked on every resume: a kill cannot skip it
            run.redo("report", ", ".join(f"{k} {made_with.get(k, 'unrecorded')} -> {v}" for k, v in settings.items()
                                         if made_with.get(k) != v))
        if run.finished:
            return run.already_finished()
        if "started" not in run.records():  # the run's first start: where its wall-clock span begins
            run.record("started", utc_now(), 0.0)
        train_games, gen_games = planned_games(scale, pr)
        run.log(f"plan: scale {a.scale}, at most {train_games:,} PT-HR games in training and {gen_games:,} in "
                f"generation; a whole {a.scale} run took {MEASURED_WALL.get(a.scale, 'not yet measured')} "
                "on a 2-core CPU (docs/results/benchmark2.md); the training and generation lines give the ETA "
                "as they go")
        tr = run.stage("train", lambda: stage_train(run, scale, a.seed))
        tr_paper = (run.stage("train_paper_ppo", lambda: stage_train(run, scale, a.seed, paper=True))
                    if scale.paper_ppo is not None else None)
        ge = run.stage("generate", lambda: stage_generate(run, scale, a.seed, a.protocol))
        rep = run.stage("report", lambda: {**b2_report.report(run, load_generated(run.out / "generated.npz"),
                                                                 seed=a.seed, tsne_per_target=scale.tsne_per_target,
                                                                 protocol=pr, n_boot=scale.bootstrap,
                                                                 min_kept=scale.min_kept),
                                           "settings": settings})
        summary = {"benchmark": 2, "scale": a.scale, "seed": a.seed, "protocol": a.protocol,
                   **{k: rep.get(k) for k in ("mean_error", "pc1_sd", "pc1_own_sd", "yield", "edits",
                                              "n_controllability", "ci95")},
                   "paper": b2_report.paper_summary(),
                   "train_steps": tr["steps"], "train_groups": tr["groups"], "episodes": ge["episodes"],
                   "train_seconds": tr["seconds"], "generate_seconds": ge["seconds"],
                   **({"paper_ppo_train_steps": tr_paper["steps"], "paper_ppo_train_groups": tr_paper["groups"],
                       "paper_ppo_train_seconds": tr_paper["seconds"]} if tr_paper else {}),
                   "wall_seconds": sum(run.stage_seconds().values())}
        return run.finish({**summary, **compute_time(run, tr, tr_paper)})


def cli(argv=None) -> None:
    """``main`` as a command line: one-line errors (exit 2), one line on Ctrl-C (exit 130)."""
    run_cli(lambda: main(argv), (ValueError, checkpoint.CheckpointError),
            "finished stages and the newest checkpoint are kept: rerun the same command with --resume")


if __name__ == "__main__":
    cli()
