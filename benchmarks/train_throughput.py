"""MA-POCA training throughput: environment decisions per second of whole updates (rollout,
λ-returns, epochs of minibatch Adam steps), for the reference network (``paper`` preset,
2 x 256) and the ``cpu`` preset.

Compiles one update ahead of time (``lower().compile()``), warms up, times ``--repeats`` calls
with ``block_until_ready`` and prints one JSON object with the machine, the load average (the
machine may be shared) and, per preset, compile seconds, seconds per update and decisions/s
(one decision = every player acts once; agent steps = 3 x decisions).

    python benchmarks/train_throughput.py --presets paper cpu --repeats 3
    python benchmarks/train_throughput.py --presets cpu --pieces   # where an update's time goes
    python benchmarks/train_throughput.py --presets cpu --runs 1 8 32   # Benchmark 1's runs side by side
    python benchmarks/train_throughput.py --presets paper --seeds 3   # also 3 seeds vmapped, as mapoca_cli --seeds 3

``--pieces`` also times, for the same arenas and decisions, (1) the environment alone
(``raidjax.step_autoreset`` in a ``lax.scan`` with random actions and per-arena content, no networks) and (2) whole
updates with one epoch instead of ``update_epochs``: the difference gives the cost of one epoch
of minibatch gradient steps (losses, gradients, Adam), and the rest of the update is the rollout
(environment and the networks' forward passes) with the λ-returns. Random actions play a
different game than the policy's, so the environment's share is an estimate. It also reports
XLA's floating-point operation count of one minibatch gradient and the rate the epochs reach
(``epoch_gflop_per_s``), to compare with what the device can do, and (3) one minibatch's
parts compiled and timed alone (``minibatch_parts``): the actor's forward and backward pass, the
critic's, and Adam's update, each with its flop count.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run as a script from anywhere
from raidjax.io import machine, whole_number_arg
from raidjax.xla_flags import use_recommended_xla_flags
from trainers.config import PRESETS as ALL_PRESETS  # noqa: E402

PRESETS = ALL_PRESETS["mapoca"]
from trainers.mapoca import make_trainer  # noqa: E402


def bench(preset: str, repeats: int, seeds: int = 1, **overrides) -> dict:
    """Time whole updates of ``preset`` (with ``overrides``), ``seeds`` runs vmapped together as
    ``trainers.mapoca_cli --seeds`` trains them (1: one run, unbatched). Returns a JSON-able dict."""
    cfg = PRESETS[preset].replace(**overrides)
    trainer = make_trainer(cfg)
    init, update = trainer.init, trainer.update
    keys = jax.random.PRNGKey(0)
    if seeds > 1:
        init, update, keys = jax.vmap(init), jax.vmap(update), jax.random.split(keys, seeds)
    runner = jax.jit(init)(keys)
    t0 = time.perf_counter()
    update = jax.jit(update, donate_argnums=0).lower(runner).compile()
    compile_s = time.perf_counter() - t0
    runner, m = update(runner)  # warm-up
    jax.block_until_ready(m)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        runner, m = update(runner)
        jax.block_until_ready(m)
        times.append(time.perf_counter() - t0)
    best = min(times)
    n_params = sum(x.size for x in jax.tree.leaves(runner.params)) // seeds
    return {
        "preset": preset, "seeds": seeds, "hidden": cfg.hidden, "layers": cfg.layers, "heads": cfg.heads,
        "proj_attention": cfg.proj_attention, "n_arenas": cfg.n_arenas, "n_steps": cfg.n_steps,
        "update_epochs": cfg.update_epochs, "n_minibatches": cfg.n_minibatches, "parameters": int(n_params),
        "decisions_per_update": cfg.decisions_per_update, "compile_s": round(compile_s, 2),
        "seconds_per_update": [round(t, 3) for t in times],
        "decisions_per_s": round(seeds * cfg.decisions_per_update / best),
        "agent_steps_per_s": round(3 * seeds * cfg.decisions_per_update / best),
    }


def bench_runs(n_runs: int, repeats: int, protocol: str = "paper") -> dict:
    """Time one chunk of the first ``n_runs`` runs of Benchmark 1's ``cpu`` scale trained side by
    side as the pipeline trains them (``experiments.benchmark1``: each run its own seed, content
    and range table, ``jax.vmap`` over the runs). Returns a JSON-able dict with the aggregate
    decisions/s of all runs."""
    from experiments import benchmark1 as b1

    scale = b1.SCALES["cpu"]
    cfg = b1.config_of(scale, protocol)
    trainer = make_trainer(cfg, redraw_ranges=True)
    args = b1._run_inputs(b1.runs_of(scale, protocol)[:n_runs], 0)
    state = jax.jit(jax.vmap(trainer.init))(*args)
    t0 = time.perf_counter()
    chunk = jax.jit(jax.vmap(trainer.chunk), donate_argnums=0).lower(state).compile()
    compile_s = time.perf_counter() - t0
    state, m = chunk(state)  # warm-up
    jax.block_until_ready(m)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        state, m = chunk(state)
        jax.block_until_ready(m)
        times.append(time.perf_counter() - t0)
    decisions = n_runs * cfg.decisions_per_update * cfg.updates_per_chunk
    return {"protocol": protocol, "runs": n_runs, "hidden": cfg.hidden, "senses": cfg.senses,
            "compile_s": round(compile_s, 2), "seconds_per_chunk": [round(t, 3) for t in times],
            "decisions_per_s_all_runs": round(decisions / min(times))}


def best_seconds(fn, arg, repeats: int) -> float:
    """Best of ``repeats`` timed calls of the compiled ``fn(arg)`` after one warm-up call."""
    jax.block_until_ready(fn(arg))
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(arg))
        times.append(time.perf_counter() - t0)
    return min(times)


def env_only(cfg, repeats: int) -> float:
    """Seconds of ``cfg.n_steps`` decisions of ``cfg.n_arenas`` arenas with random actions."""
    import raidjax

    n, n_players = cfg.n_arenas, len(cfg.players)
    one = raidjax.make_params(players=list(cfg.players), skill_range=cfg.skill_ranges[0])
    one = raidjax.with_senses(one, cfg.senses)
    params = jax.tree.map(lambda x: jax.numpy.broadcast_to(x, (n,) + x.shape), one)  # per arena, as in training
    step_all = jax.vmap(raidjax.step_autoreset)

    def rollout(key):
        _, state = jax.vmap(raidjax.reset)(jax.random.split(key, n), params)

        def body(carry, _):
            state, key = carry
            key, k_act, k_step = jax.random.split(key, 3)
            acts = jax.random.randint(k_act, (n, n_players), 0, one.config.n_actions)
            _, state, reward, _, _ = step_all(jax.random.split(k_step, n), state, acts, params)
            return (state, key), reward.sum()

        return jax.lax.scan(body, (state, key), None, cfg.n_steps)[1]

    compiled = jax.jit(rollout).lower(jax.random.PRNGKey(0)).compile()
    return best_seconds(compiled, jax.random.PRNGKey(1), repeats)


def minibatch_rows(cfg) -> tuple[int, object, object]:
    """``(b, obs [b, P, ...], agent int32[b] or None)``: the rows of one minibatch of ``cfg``
    (fresh observations of the reference content; ``agent``: each row's player when a minibatch is
    agent experiences, ``Config.minibatch_rows = "agents"``, else ``None``: whole decisions)."""
    import jax.numpy as jnp

    import raidjax

    p = len(cfg.players)
    by_rows = cfg.minibatch_rows == "agents"  # a minibatch of agent experiences: b rows, one player each
    b = cfg.decisions_per_update * (p if by_rows else 1) // cfg.n_minibatches
    one = raidjax.with_senses(raidjax.make_params(players=list(cfg.players), skill_range=cfg.skill_ranges[0]),
                              cfg.senses)
    obs, _ = jax.vmap(raidjax.reset, (0, None))(jax.random.split(jax.random.PRNGKey(0), b), one)
    return b, obs, (jnp.arange(b, dtype=jnp.int32) % p if by_rows else None)


def flops(compiled) -> float:
    """XLA's floating-point operation count of a compiled program."""
    cost = compiled.cost_analysis()
    return float((cost[0] if isinstance(cost, list) else cost)["flops"])


def minibatch_flops(trainer, runner) -> float:
    """XLA's count of floating-point operations of one minibatch gradient (losses and their
    gradients, no Adam), compiled alone: the networks hold no loops, so the count is complete."""
    import jax.numpy as jnp

    from trainers.poca_loss import Batch, loss_fn

    cfg = trainer.config
    p = len(cfg.players)
    b, obs, agent = minibatch_rows(cfg)
    batch = Batch(obs, jnp.zeros((b, p), jnp.int32), jnp.zeros((b, p)), jnp.ones((b, p), bool), jnp.zeros(b),
                  jnp.zeros((b, p)), jnp.zeros((b, p)), jnp.zeros((b, p)))
    rows = "agents" if agent is not None or cfg.episode_ends == "reference" else "decisions"
    grad = jax.grad(loss_fn, has_aux=True)
    return flops(jax.jit(lambda prm, bt: grad(prm, bt, trainer.actor, trainer.critic, cfg.clip_eps, cfg.ent_coef,
                                              rows, agent)).lower(runner.params, batch).compile())


def network_parts(trainer, runner, repeats: int) -> dict:
    """The three parts of one minibatch step timed alone, compiled alone (best of ``repeats``): the
    actor's forward and backward pass (its logits on the minibatch's rows), the critic's (value and
    baselines), and Adam's update of all parameters. Each with XLA's flop count; their sum beside
    an epoch's measured time per minibatch says what the loss algebra and the shuffling add."""
    import jax.numpy as jnp
    import optax

    cfg = trainer.config
    b, obs, agent = minibatch_rows(cfg)
    actions = jnp.zeros((b, len(cfg.players)), jnp.int32)
    pick = (lambda x: x) if agent is None else (lambda x: x[jnp.arange(b), agent])

    def actor_loss(prm):
        return jnp.sum(jax.nn.log_softmax(trainer.actor.apply(prm, jax.tree.map(pick, obs)))[..., 0])

    def critic_loss(prm):
        value, baseline = trainer.critic.apply(prm, obs, actions, agent)
        return jnp.sum(value) + jnp.sum(baseline)

    tx = optax.adam(cfg.lr, eps=cfg.adam_eps)
    params = runner.params

    def adam(state):
        prm, opt = state
        updates, opt = tx.update(jax.tree.map(jnp.ones_like, prm), opt, prm)
        return optax.apply_updates(prm, updates), opt

    out = {}
    for name, fn, arg in (("actor", jax.grad(actor_loss), params["actor"]),
                          ("critic", jax.grad(critic_loss), params["critic"]),
                          ("adam", adam, (params, tx.init(params)))):
        compiled = jax.jit(fn).lower(arg).compile()
        seconds, count = best_seconds(compiled, arg, repeats), flops(compiled)
        out[name] = {"gflop": round(count / 1e9, 3), "ms": round(1e3 * seconds, 2),
                     "gflop_per_s": round(count / seconds / 1e9, 1)}
    out["rows_per_minibatch"] = b
    return out


def pieces(preset: str, repeats: int, whole: dict, **overrides) -> dict:
    """Split one update of ``preset`` into rollout and epochs (see the module docstring)."""
    cfg = PRESETS[preset].replace(**overrides)
    one = cfg.replace(update_epochs=1)
    trainer = make_trainer(one)
    runner = jax.jit(trainer.init)(jax.random.PRNGKey(0))
    update = jax.jit(trainer.update).lower(runner).compile()
    one_s = best_seconds(update, runner, repeats)
    update_s = min(whole["seconds_per_update"])
    epoch_s = (update_s - one_s) / (cfg.update_epochs - 1) if cfg.update_epochs > 1 else float("nan")
    rollout_s = one_s - epoch_s
    env_s = env_only(cfg, repeats)
    grad_flops = minibatch_flops(trainer, runner)
    parts = network_parts(trainer, runner, repeats)
    return {"preset": preset, "seconds_per_update": round(update_s, 4), "one_epoch_update_s": round(one_s, 4),
            "minibatch_ms": round(1e3 * epoch_s / cfg.n_minibatches, 2), "minibatch_parts": parts,
            "epoch_s": round(epoch_s, 4), "rollout_and_returns_s": round(rollout_s, 4),
            "env_only_s": round(env_s, 4), "networks_in_rollout_s": round(rollout_s - env_s, 4),
            "minibatch_gradient_gflop": round(grad_flops / 1e9, 3),
            "epoch_gflop_per_s": round(grad_flops * cfg.n_minibatches / epoch_s / 1e9, 1),
            "shares": {"epochs": round(cfg.update_epochs * epoch_s / update_s, 3),
                       "environment": round(env_s / update_s, 3),
                       "rollout_networks_and_returns": round((rollout_s - env_s) / update_s, 3)}}


def main() -> None:
    """Parse flags, run the benchmarks, print one JSON object."""
    use_recommended_xla_flags()  # raidjax's commands measure with these (raidjax.xla_flags)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="+", default=["paper", "cpu"], choices=sorted(PRESETS))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--arenas", type=int, help="override n_arenas of every preset")
    ap.add_argument("--pieces", action="store_true", help="also split an update into rollout and epochs")
    ap.add_argument("--runs", type=int, nargs="+", default=[],
                    help="also time the first N runs of Benchmark 1's cpu scale trained side by side, for each N")
    ap.add_argument("--protocol", default="paper", help="Benchmark 1's protocol for --runs")
    ap.add_argument("--seeds", type=whole_number_arg(2), nargs="+", default=[],
                    help="also time each preset with N seeds vmapped together (mapoca_cli --seeds N), for each N; "
                    "decisions/s then counts all seeds")
    args = ap.parse_args()
    overrides = {} if args.arenas is None else {"n_arenas": args.arenas}
    results = [bench(p, args.repeats, **overrides) for p in args.presets]
    results += [bench(p, args.repeats, seeds=n, **overrides) for n in args.seeds for p in args.presets]
    out = {"benchmark": "train_throughput", "machine": machine(load=True),
           "results": results}
    if args.runs:
        out["side_by_side"] = [bench_runs(n, args.repeats, args.protocol) for n in args.runs]
    if args.pieces:
        alone = results[:len(args.presets)]  # one run each
        out["pieces"] = [pieces(p, args.repeats, r, **overrides) for p, r in zip(args.presets, alone, strict=True)]
    print(json.dumps(out))


if __name__ == "__main__":
    main()
