"""raidjax beside JaxMARL's SMAX-3m in the same process shape: decisions per second.

Both environments run the loop of JaxMARL's own SMAX speed script (jaxmarl/environments/smax/
speed.py, ``ACTION_SELECTION="random"``): ``vmap`` of the JaxMARL ``step`` (auto-reset included)
over ``--arenas`` arenas, inside one ``lax.scan`` of ``--steps`` decisions, uniform random
actions, compiled ahead of time, the best of ``--repeats`` timed with ``block_until_ready``, in
this one process with the same XLA flags (raidjax's recommended ones unless
``RAIDJAX_KEEP_XLA_FLAGS=1``). One decision = every agent of one arena acts once.

Rows: ``smax-3m`` (``HeuristicEnemySMAX``, map 3m); ``raidjax-jaxmarl`` (``RaidMultiAgentEnv``:
content carried per arena in the state, as the wrapper always does); ``raidjax-shared`` and
``raidjax-per-arena`` (``raidjax.step_autoreset`` directly, one content for all arenas or one per
arena). raidjax rows use ``--substeps`` (5: the reference's 0.02 s tick; 1: one 0.1 s sub-step).

``--learner`` runs the loop as a learner's rollout sees it instead: every decision's observations
are kept (their sum is carried through the loop, so neither environment can skip computing them)
and each agent's action is drawn uniformly among the actions its environment says are available
(SMAX's ``get_avail_actions``, raidjax's ``Observation.action_mask``).

    pip install -e ".[jaxmarl]"
    python benchmarks/vs_smax.py --arenas 4096 --steps 128
"""

from __future__ import annotations

import argparse
import json
import time

import jax
import jax.numpy as jnp

import raidjax
from raidjax.io import machine
from raidjax.xla_flags import use_recommended_xla_flags


def obs_sum(obs) -> jax.Array:
    """The sum of every float in ``obs`` (a pytree): a value that needs all of it."""
    return sum(jnp.sum(x, dtype=jnp.float32) for x in jax.tree.leaves(obs))


def draw_available(key: jax.Array, available: jax.Array) -> jax.Array:
    """``int32[...]``: one action per row of ``available bool[..., A]``, uniform among its true entries."""
    return jax.random.categorical(key, jnp.where(available, 0.0, -jnp.inf)).astype(jnp.int32)


def jaxmarl_rollout(env, n_arenas: int, n_steps: int, learner: bool = False):
    """JaxMARL speed-script loop: ``rollout(key) -> (final state, observation sum)`` (the sum is 0
    unless ``learner``)."""
    n_actions = env.action_space(env.agents[0]).n

    def rollout(key):
        k_reset, k_run = jax.random.split(key)
        obs, state = jax.vmap(env.reset)(jax.random.split(k_reset, n_arenas))

        def body(carry, _):
            state, key, total = carry
            key, k_act, k_step = jax.random.split(key, 3)
            if learner:
                avail = jax.vmap(env.get_avail_actions)(state)
                acts = draw_available(k_act, jnp.stack([avail[a] for a in env.agents]).astype(bool))
            else:
                acts = jax.random.randint(k_act, (env.num_agents, n_arenas), 0, n_actions)
            obs, state, _, _, _ = jax.vmap(env.step)(jax.random.split(k_step, n_arenas), state,
                                                     {a: acts[i] for i, a in enumerate(env.agents)})
            # The agents' observations, as a decentralised learner (IPPO) reads them; SMAX's extra
            # "world_state" (a centralised critic's input) is left out, so XLA may skip it.
            agents_obs = [obs[a] for a in env.agents]
            return (state, key, total + obs_sum(agents_obs) if learner else total), None

        (state, _, total), _ = jax.lax.scan(body, (state, k_run, jnp.float32(0)), None, n_steps)
        return state, total

    return rollout


def raidjax_rollout(params, n_arenas: int, n_steps: int, per_arena: bool, learner: bool = False):
    """The same loop on ``raidjax.step_autoreset``; ``per_arena``: ``params`` batched ``[n_arenas]``."""
    axis = 0 if per_arena else None
    n_players = params.team.shape[-1] - 1

    def rollout(key):
        k_reset, k_run = jax.random.split(key)
        obs, state = jax.vmap(raidjax.reset, (0, axis))(jax.random.split(k_reset, n_arenas), params)

        def body(carry, _):
            state, mask, key, total = carry  # mask: the last observation's action mask (learner only)
            key, k_act, k_step = jax.random.split(key, 3)
            if learner:
                acts = draw_available(k_act, mask)
            else:
                acts = jax.random.randint(k_act, (n_arenas, n_players), 0, raidjax.N_ACTIONS)
            obs, state, _, _, _ = jax.vmap(raidjax.step_autoreset, (0, 0, 0, axis))(
                jax.random.split(k_step, n_arenas), state, acts, params)
            if learner:
                return (state, obs.action_mask, key, total + obs_sum(obs)), None
            return (state, mask, key, total), None

        mask = obs.action_mask if learner else jnp.zeros((), bool)
        (state, _, _, total), _ = jax.lax.scan(body, (state, mask, k_run, jnp.float32(0)), None, n_steps)
        return state, total

    return rollout


def measure(rollout, n_arenas: int, n_steps: int, repeats: int) -> dict:
    """Compile ``rollout`` ahead of time and time it; returns compile seconds and decisions/s."""
    key = jax.random.key(0)
    t0 = time.perf_counter()
    compiled = jax.jit(rollout).lower(key).compile()
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(key))
    times = []
    for r in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(jax.random.key(r + 1)))
        times.append(time.perf_counter() - t0)
    return {"compile_s": round(compile_s, 2), "seconds": [round(t, 3) for t in times],
            "decisions_per_s": round(n_arenas * n_steps / min(times))}


def main() -> None:
    use_recommended_xla_flags()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--arenas", type=int, nargs="+", default=[4096], help="arena counts to measure")
    ap.add_argument("--steps", type=int, default=128, help="decisions per rollout")
    ap.add_argument("--repeats", type=int, default=3, help="timed rollouts (the best counts)")
    ap.add_argument("--substeps", type=int, default=5, choices=(1, 5), help="raidjax sub-steps per decision")
    ap.add_argument("--rows", nargs="+", default=["smax-3m", "raidjax-jaxmarl", "raidjax-shared", "raidjax-per-arena"])
    ap.add_argument("--learner", action="store_true",
                    help="keep every observation and draw actions among the available ones (a learner's rollout)")
    args = ap.parse_args()

    from jaxmarl import make
    from jaxmarl.environments.smax import map_name_to_scenario

    from raidjax.wrappers.jaxmarl import RaidMultiAgentEnv

    params = raidjax.make_params(skill_range=9.0, config=raidjax.EnvConfig(n_substeps=args.substeps))
    rows = []
    for n in args.arenas:
        batch = jax.tree.map(lambda x: jnp.broadcast_to(x, (n,) + x.shape), params)  # noqa: B023
        makers = {
            "smax-3m": lambda: jaxmarl_rollout(make("HeuristicEnemySMAX", scenario=map_name_to_scenario("3m")),
                                               n, args.steps, args.learner),  # noqa: B023
            "raidjax-jaxmarl": lambda: jaxmarl_rollout(RaidMultiAgentEnv(params), n, args.steps, args.learner),  # noqa: B023
            "raidjax-shared": lambda: raidjax_rollout(params, n, args.steps, False, args.learner),  # noqa: B023
            "raidjax-per-arena": lambda: raidjax_rollout(batch, n, args.steps, True, args.learner),  # noqa: B023
        }
        for name in args.rows:
            rows.append({"env": name, "arenas": n, **measure(makers[name](), n, args.steps, args.repeats)})
            print(json.dumps(rows[-1]), flush=True)
    print(json.dumps({"benchmark": "vs_smax", "machine": machine(load=True),
                      "steps": args.steps, "raidjax_substeps": args.substeps, "learner": args.learner,
                      "rows": rows}))


if __name__ == "__main__":
    main()
