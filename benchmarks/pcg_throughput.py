"""Content-generation throughput: generator steps (edit + PT-HR playtest of N games) per second.

Compiles ahead of time, times with ``block_until_ready`` and prints one JSON object with the
machine, the batch of parallel generator episodes, N, compile seconds, generator steps/s and the
implied games/s. Uses ``raidjax.pcg.step_autoreset`` (exactly one playtest per step) under vmap.

    python benchmarks/pcg_throughput.py --envs 8 --n-games 100 --steps 2
    python benchmarks/pcg_throughput.py --generation 10 --decisions 4 --n-games 300   # Benchmark 2's generation
    python benchmarks/pcg_throughput.py --train paper --steps 2                      # its paper PPO's training

``--beside-playtest`` also times two PT-HR playtests (chained arenas) of as many games as one of the
generator's measurements plays side by side, in the same process: the reference content at range
13 (``playtest_games_per_s``, ``ratio_to_playtest``), and one content per episode with a skill drawn
uniformly from the generator's box (``box_playtest_games_per_s``, ``ratio_to_box_playtest``), the
kind of games generation plays (longer: both report their mean decisions per game).
"""

from __future__ import annotations

import argparse
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


def generation(episodes: int, decisions: int, n_games: int) -> dict:
    """Benchmark 2's generation as its ``cpu`` scale runs it (``trainers.generate.generate_episodes``):
    raidjax's PPO, the paper's PPO (7 models; untrained networks: their edits, not their weights,
    set the games) and PCG-HR and PCG-RD, ``episodes`` per target and method side by side, strict
    episodes of ``decisions`` measurements of ``n_games`` PT-HR games. Times one call after a warm-up
    (compile excluded)."""
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
    generate_episodes(jax.random.key(1), gens, **kw)  # compiles, then plays
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    out = generate_episodes(jax.random.key(2), gens, **kw)
    seconds = time.perf_counter() - t0
    n_episodes = sum(len(g["target"]) for g in out.values())
    games = n_episodes * decisions * n_games
    return {"benchmark": "pcg_generation", "machine": machine(load=True), "methods": list(out),
            "episodes_per_target_and_method": episodes, "episodes": n_episodes, "decisions": decisions,
            "n_games": n_games, "games_per_measurement": n_episodes * n_games, "first_call_s": round(first, 2),
            "seconds": round(seconds, 2), "games_per_s": round(games / seconds, 1)}


def training(preset: str, updates: int) -> dict:
    """One PPO-PCGRL learner of Benchmark 2 (``preset``: ``cpu``, one model, or ``paper``, 7 models
    vmapped, one per target), ``updates`` updates timed after a warm-up update (compile excluded):
    the games/s of its training measurements (the networks' updates included)."""
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
    state, _ = jax.block_until_ready(compiled(state, targets))  # warm-up (its first steps reset the episodes)
    t0 = time.perf_counter()
    jax.block_until_ready(compiled(state, targets))
    seconds = time.perf_counter() - t0
    games = len(labels) * updates * cfg.n_arenas * cfg.n_steps * cfg.n_games
    return {"benchmark": "pcg_training", "machine": machine(load=True), "preset": preset, "models": len(labels),
            "episodes_side_by_side": len(labels) * cfg.n_arenas, "n_games": cfg.n_games,
            "games_per_measurement": len(labels) * cfg.n_arenas * cfg.n_games, "updates": updates,
            "compile_s": round(compile_s, 2), "seconds": round(seconds, 2), "games_per_s": round(games / seconds, 1)}


def playtest_beside(games: int, repeats: int, groups: int | None = None) -> tuple[float, float]:
    """``(games/s, mean decisions per game)`` of a PT-HR playtest of ``games`` games (raidjax's one
    protocol: chained arenas after a warm-up), compiled first, best of ``repeats``. ``groups=None``:
    the reference content at range 13; else ``groups`` contents of ``games // groups`` games each
    (``raidjax.playtest_groups``), each with a skill drawn uniformly from the generator's box, as
    generator episodes play: the same kind of games, which are longer than the reference's."""
    import numpy as np

    import raidjax

    if groups is None:
        params = raidjax.make_params(skill_range=13.0)
        play = lambda k: raidjax.playtest(k, params, raidjax.policies.heuristic, games)  # noqa: E731
    else:
        lo, hi = np.asarray(pcg.env.low()), np.asarray(pcg.env.high())
        skills = lo + np.random.default_rng(0).random((groups, lo.size)) * (hi - lo)
        contents = jax.vmap(lambda s: pcg.env.skill_params(pcg.env.base_game(), s))(jax.numpy.asarray(skills))
        n = games // groups
        play = jax.jit(lambda k: raidjax.playtest_groups(jax.random.split(k, groups), contents,
                                                         raidjax.policies.heuristic, n))
    length = float(np.mean(np.asarray(jax.block_until_ready(play(jax.random.key(0)))["length"])))  # compiles
    times = []
    for i in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(play(jax.random.key(1 + i)))
        times.append(time.perf_counter() - t0)
    return games / min(times), length


def _beside(row: dict, games: int, repeats: int, groups: int) -> dict:
    rate, length = playtest_beside(games, repeats)
    box_rate, box_length = playtest_beside(games, repeats, groups)
    return {**row, "playtest_games": games, "playtest_games_per_s": round(rate, 1),
            "playtest_decisions_per_game": round(length, 1), "ratio_to_playtest": round(row["games_per_s"] / rate, 3),
            "box_playtest_groups": groups, "box_playtest_games_per_s": round(box_rate, 1),
            "box_playtest_decisions_per_game": round(box_length, 1),
            "ratio_to_box_playtest": round(row["games_per_s"] / box_rate, 3)}


def main() -> None:
    """Run the benchmark and print one JSON line."""
    use_recommended_xla_flags()  # raidjax's commands measure with these (raidjax.xla_flags)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", type=int, default=8, help="generator episodes stepped in parallel")
    ap.add_argument("--n-games", type=int, default=100)
    ap.add_argument("--steps", type=int, default=2, help="generator steps per timed call")
    ap.add_argument("--repeats", type=int, default=2)
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
        groups = row.get("episodes", row.get("episodes_side_by_side"))
        print(json.dumps(_beside(row, row["games_per_measurement"], args.repeats, groups) if args.beside_playtest
                         else row))
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
    print(json.dumps(_beside(row, args.envs * args.n_games, args.repeats, args.envs) if args.beside_playtest
                     else row))


if __name__ == "__main__":
    main()
