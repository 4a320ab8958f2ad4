"""Content-generation throughput: generator steps (edit + PT-HR playtest of N games) per second.

Compiles ahead of time, times with ``block_until_ready`` and prints one JSON object with the
machine, the batch of parallel generator episodes, N, compile seconds, generator steps/s and the
implied games/s. Uses ``raidjax.pcg.step_autoreset`` (exactly one playtest per step) under vmap.

    python benchmarks/pcg_throughput.py --envs 8 --n-games 100 --steps 2
    python benchmarks/pcg_throughput.py --generation 10 --decisions 4 --n-games 300   # Benchmark 2's generation
    python benchmarks/pcg_throughput.py --train paper --steps 2                      # its paper PPO's training

``--beside-playtest`` also times two PT-HR playtests (chained arenas) of as many games as one of the
generator's measurements plays side by side, in the same process, call after call with the
generator's (medians of ``--repeats``): the reference content at range
13 (``playtest_games_per_s``, ``ratio_to_playtest``), and one content per episode with a skill drawn
uniformly from the generator's box (``box_playtest_games_per_s``, ``ratio_to_box_playtest``), the
kind of games generation plays (longer: both report their mean decisions per game). With
``--generation`` a third: the skills the generation's first call kept, one content per episode,
as many games each as a measurement plays (``generated_playtest_games_per_s``,
``ratio_to_generated_playtest``): a playtest of the very contents generation measures, so the ratio
is the generator's own cost, not the length of its games.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time

import jax

from raidjax import pcg
from raidjax.io import machine
from raidjax.xla_flags import use_recommended_xla_flags


def make_rollout(params: pcg.PCGParams, n_steps: int):
    """``rollout(key, states) -> (states, reward_sum)``: ``n_steps`` random edits of a batch of episodes."""

    def rollout(key, states):
        def body(st, k):
            ka, ks = jax.random.split(k)
            n = st.target.shape[0]
            act = jax.random.randint(ka, (n, pcg.env.N_PARAMS), 0, pcg.env.N_CHOICES)
            _, st, r, _, _ = jax.vmap(lambda kk, s, a: pcg.step_autoreset(kk, s, a, params))(
                jax.random.split(ks, n), st, act)
            return st, r.sum()

        st, rs = jax.lax.scan(body, states, jax.random.split(key, n_steps))
        return st, rs.sum()

    return rollout


def generation(episodes: int, decisions: int, n_games: int):
    """Benchmark 2's generation as its ``cpu`` scale runs it (``trainers.generate.generate_episodes``):
    raidjax's PPO, the paper's PPO (7 models; untrained networks: their edits, not their weights,
    set the games) and PCG-HR and PCG-RD, ``episodes`` per target and method side by side, strict
    episodes of ``decisions`` measurements of ``n_games`` PT-HR games. Returns ``(row, call, games, kept)``:
    the settings, a function that plays one call (compiled by the first, here), its games and the
    skills its first call kept (``[episodes, 4]``)."""
    from trainers.config import load_config
    from trainers.generate import PPOGenerator, generate_episodes, target_groups
    from trainers.ppo_pcgrl import make_train

    gens = {}
    for name, preset in (("PPO, target observed", "cpu"), ("PPO", "paper")):
        cfg = load_config(preset, learner="ppo_pcgrl")
        pairs, labels = target_groups(cfg, 1)
        train = make_train(cfg)
        weights = jax.vmap(lambda k, t, train=train: train.init(k, t)["params"])(
            jax.random.split(jax.random.key(0), len(labels)), jax.numpy.asarray(pairs))
        gens[name] = PPOGenerator(cfg, weights, labels)
    kw = dict(gen_games=n_games, greedy=True, episodes=episodes, eval_games=0, strict_length=True,
              max_edits=decisions - 1)
    t0 = time.perf_counter()
    out = generate_episodes(jax.random.key(1), gens, **kw)  # compiles, then plays
    first = time.perf_counter() - t0
    n_episodes = sum(len(g["target"]) for g in out.values())
    calls = itertools.count(2)  # a fresh key per call

    def call():
        generate_episodes(jax.random.key(next(calls)), gens, **kw)

    row = {"benchmark": "pcg_generation", "machine": machine(load=True), "methods": list(out),
           "episodes_per_target_and_method": episodes, "episodes": n_episodes, "decisions": decisions,
           "n_games": n_games, "games_per_measurement": n_episodes * n_games, "first_call_s": round(first, 2)}
    kept = jax.numpy.concatenate([jax.numpy.asarray(g["skill"]) for g in out.values()])
    return row, call, n_episodes * decisions * n_games, kept


def training(preset: str, updates: int):
    """One PPO-PCGRL learner of Benchmark 2 (``preset``: ``cpu``, one model, or ``paper``, 7 models
    vmapped, one per target). Returns ``(row, call, games, kept)``: the settings, a function that runs
    ``updates`` more updates (compiled and warmed up here), the games of its training
    measurements (the networks' updates are in its time) and ``None`` (no kept skills)."""
    from trainers.config import load_config
    from trainers.generate import target_groups
    from trainers.ppo_pcgrl import make_train

    cfg = load_config(preset, learner="ppo_pcgrl")
    pairs, labels = target_groups(cfg, 1)
    train = make_train(cfg)
    targets = jax.numpy.asarray(pairs)
    init = jax.jit(jax.vmap(train.init))
    state = init(jax.random.split(jax.random.key(0), len(labels)), targets)
    run = jax.jit(jax.vmap(lambda r, t: jax.lax.scan(lambda rr, _: train.update(rr, t), r, None, updates)))
    t0 = time.perf_counter()
    compiled = run.lower(state, targets).compile()
    compile_s = time.perf_counter() - t0
    held = [jax.block_until_ready(compiled(state, targets))[0]]  # warm-up (its first steps reset the episodes)

    def call():
        held[0] = jax.block_until_ready(compiled(held[0], targets))[0]

    games = len(labels) * updates * cfg.n_arenas * cfg.n_steps * cfg.n_games
    row = {"benchmark": "pcg_training", "machine": machine(load=True), "preset": preset, "models": len(labels),
           "episodes_side_by_side": len(labels) * cfg.n_arenas, "n_games": cfg.n_games,
           "games_per_measurement": len(labels) * cfg.n_arenas * cfg.n_games, "updates": updates,
           "compile_s": round(compile_s, 2)}
    return row, call, games, None


def playtest_beside(games: int, groups: int | None = None, skills=None):
    """``(call, mean decisions per game)`` of a PT-HR playtest of ``games`` games (raidjax's one
    protocol: chained arenas after a warm-up): ``call()`` plays it once (compiled here). ``groups=None``:
    the reference content at range 13; else ``groups`` contents of ``games // groups`` games each
    (``raidjax.playtest_groups``), each with a skill drawn uniformly from the generator's box, as
    generator episodes play: the same kind of games, which are longer than the reference's; or, given
    ``skills`` (``[groups, 4]``, the generator's parameters), those skills."""
    import numpy as np

    import raidjax

    if groups is None:
        params = raidjax.make_params(skill_range=13.0)
        play = lambda k: raidjax.playtest(k, params, raidjax.policies.heuristic, games)  # noqa: E731
    else:
        lo, hi = pcg.PAPER_SPACE.low, pcg.PAPER_SPACE.high
        if skills is None:
            skills = lo + np.random.default_rng(0).random((groups, lo.size)) * (hi - lo)
        contents = jax.vmap(lambda s: pcg.PAPER_SPACE.apply(pcg.base_game(), s))(jax.numpy.asarray(skills))
        n = games // groups
        play = jax.jit(lambda k: raidjax.playtest_groups(jax.random.split(k, groups), contents,
                                                         raidjax.policies.heuristic, n))
    length = float(np.mean(np.asarray(jax.block_until_ready(play(jax.random.key(0)))["length"])))  # compiles
    keys = itertools.count(1)
    return lambda: jax.block_until_ready(play(jax.random.key(next(keys)))), length


def _seconds(call) -> float:
    t0 = time.perf_counter()
    call()
    return time.perf_counter() - t0


def _timed(row: dict, call, games: int, repeats: int, beside: int | None = None, groups: int | None = None,
           kept=None) -> dict:
    """``row`` with ``call``'s games/s (``games`` per call): the median of ``repeats`` timed calls.
    With ``beside`` (a game count) the playtests of ``playtest_beside`` (the reference content,
    ``groups`` box-drawn contents and, given, the ``kept`` skills) are timed between them, call after
    call, so all share this CPU's slow and fast phases alike; each rate is its median and the ratios
    are of medians."""
    others = {}
    if beside:
        others = {"playtest": playtest_beside(beside), "box_playtest": playtest_beside(beside, groups)}
        if kept is not None:
            others["generated_playtest"] = playtest_beside(beside, len(kept), kept)
    times = {"": [], **{k: [] for k in others}}
    for _ in range(repeats):
        times[""].append(_seconds(call))
        for k, (other, _length) in others.items():
            times[k].append(_seconds(other))
    median = {k: sorted(v)[len(v) // 2] for k, v in times.items()}
    rate = games / median[""]
    out = {**row, "repeats": repeats, "seconds": [round(t, 2) for t in times[""]], "games_per_s": round(rate, 1)}
    for k, (_, length) in others.items():
        other_rate = beside / median[k]
        out.update({f"{k}_games": beside, f"{k}_seconds": [round(t, 3) for t in times[k]],
                    f"{k}_games_per_s": round(other_rate, 1), f"{k}_decisions_per_game": round(length, 1),
                    f"ratio_to_{k}": round(rate / other_rate, 3)})
    if groups:
        out["box_playtest_groups"] = groups
    return out


def main() -> None:
    """Run the benchmark and print one JSON line."""
    use_recommended_xla_flags()  # raidjax's commands measure with these (raidjax.xla_flags)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", type=int, default=8, help="generator episodes stepped in parallel")
    ap.add_argument("--n-games", type=int, default=100)
    ap.add_argument("--steps", type=int, default=2, help="generator steps per timed call")
    ap.add_argument("--repeats", type=int, default=3, help="timed calls")
    ap.add_argument("--generation", type=int, metavar="EPISODES",
                    help="instead: Benchmark 2's generation, EPISODES per target and method side by side, with "
                    "--decisions measurements of --n-games games each")
    ap.add_argument("--decisions", type=int, default=4, help="measurements per generation episode (--generation)")
    ap.add_argument("--train", choices=("cpu", "paper"), help="instead: one PPO-PCGRL learner of Benchmark 2, "
                    "--steps updates timed")
    ap.add_argument("--beside-playtest", action="store_true",
                    help="also time a PT-HR playtest of as many games as one measurement plays side by side")
    args = ap.parse_args()
    row = None
    if args.generation:
        row = generation(args.generation, args.decisions, args.n_games)
    elif args.train:
        row = training(args.train, args.steps)
    if row is not None:
        row, call, games, kept = row
        groups = row.get("episodes", row.get("episodes_side_by_side"))
        beside = row["games_per_measurement"] if args.beside_playtest else None
        print(json.dumps(_timed(row, call, games, args.repeats, beside, groups, kept)))
        return

    params = pcg.make_pcg_params(n_games=args.n_games)
    _, states = jax.jit(jax.vmap(lambda k: pcg.reset(k, params)))(jax.random.split(jax.random.key(0), args.envs))
    rollout = make_rollout(params, args.steps)
    key = jax.random.key(1)
    t0 = time.perf_counter()
    compiled = jax.jit(rollout).lower(key, states).compile()
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(key, states))  # warm-up
    times = []
    for i in range(args.repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(jax.random.fold_in(key, i), states))
        times.append(time.perf_counter() - t0)
    best = min(times)
    steps = args.envs * args.steps
    row = {
        "benchmark": "pcg_throughput", "machine": machine(load=True), "envs": args.envs, "n_games": args.n_games,
        "steps_per_call": steps, "compile_s": round(compile_s, 2), "best_s": round(best, 3),
        "generator_steps_per_s": round(steps / best, 2), "games_per_s": round(steps * args.n_games / best, 1),
        "times_s": [round(t, 3) for t in times],
    }
    if args.beside_playtest:
        row = _timed(row, lambda: jax.block_until_ready(compiled(key, states)), steps * args.n_games, args.repeats,
                     args.envs * args.n_games, args.envs)
    print(json.dumps(row))


if __name__ == "__main__":
    main()
