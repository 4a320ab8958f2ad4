"""How MA-POCA turns a rollout into training targets: λ-returns, counterfactual advantages, and how
a game's end reaches them (``Config.episode_ends``; PROTOCOLS.md §12).

The λ-return, time-major, for one trajectory (an arena's team, or one agent)::

    G_t = r_t + γ (1 - term_t) [(1 - λ_t) V'_t + λ_t G_{t+1}],   λ_t = λ (1 - end_t),  λ_{T-1} = 0

``V'_t`` is the critic's value of the state after step ``t`` in the same episode; ``end_t`` cuts
the trajectory there (the next step belongs to another episode, or the agent died); ``term_t``
zeroes the bootstrap (nothing follows). This is ML-Agents' ``lambda_return``
(``poca/trainer.py`` 308-317, ``r[t] + γλ G[t+1] + (1 - λ) γ V[t+1]``, the last step
``r + γ value_next``) applied to every trajectory the reference trainer cuts.

What ends where (``episode_ends``):

* ``"reference"`` (the reference trainer; ML-Agents 0.28 POCA on RaidEnv): the game calls
  ``GroupEpisodeInterrupted`` on every result (``MMORPGEnvController.cs`` ``EndGame``), so a **win**
  and a **timeout** bootstrap from the final observation's value; a **loss** does not (each player
  was deactivated at its death, which ends its episode as done, not interrupted, and the last death
  leaves no group member to bootstrap: ``poca/trainer.py`` passes ``all_group_dones_reached and
  done_reached and not interrupted`` as ``done``). A **player who dies while its teammates fight
  on** ends its own trajectory there and bootstraps from the critic's value of the state after the
  step, itself included with its live teammates (``agent_processor.py``: its last step carries its
  teammates' observations; a dead player's own observation is blank in raidjax, so it enters with
  its last live one); one who dies in a game's last step does not bootstrap. So returns are per
  agent, ``float32[T, N, P]``, and the value loss is
  averaged over agent experiences, as ML-Agents' buffer rows are.
* ``"win_bootstrapped"``: a win bootstraps as above, but the group's return runs through a
  player's death (posthumous credit) and the value loss averages over decisions.
* ``"terminal"`` (raidjax's learner before 2026-11-29): a win and a loss are both terminal, a
  timeout bootstraps; posthumous credit; value loss over decisions. Here a win is worth 1.0,
  about a tenth of a game's damage reward, while under ``"reference"`` it is worth 1.0 plus the
  value of playing on, which a loss forfeits.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from raidjax.types import Observation

EPISODE_ENDS = ("reference", "win_bootstrapped", "terminal")


def lambda_returns(reward, next_value, end, terminal, gamma: float, lam: float) -> jax.Array:
    """λ-returns of trajectories, time-major (formula in the module docstring).

    Args:
        reward, next_value: ``float32[T, ...]``; end, terminal: ``bool[T, ...]``; all four
            broadcast to one shape ``[T, ...]``.

    Returns:
        ``float32[T, ...]`` G_t (the last step bootstraps from ``next_value[-1]`` unless terminal).
    """
    shape = jnp.broadcast_shapes(*(jnp.shape(x) for x in (reward, next_value, end, terminal)))
    reward, next_value, end, terminal = (jnp.broadcast_to(x, shape) for x in (reward, next_value, end, terminal))

    def body(g_next, x):
        r, v, e, term = x
        lam_t = lam * (1.0 - e)
        g = r + gamma * (1.0 - term) * ((1.0 - lam_t) * v + lam_t * g_next)
        return g, g

    xs = (reward, next_value, end.astype(jnp.float32), terminal.astype(jnp.float32))
    _, g = jax.lax.scan(body, next_value[-1], xs, reverse=True)
    return g


def game_returns(ends: str, reward, next_value, death_value, done, won, lost, alive, next_alive,
                 gamma: float, lam: float) -> jax.Array:
    """Every agent's λ-return under ``ends`` (one of ``EPISODE_ENDS``; static).

    Args:
        reward, next_value: ``float32[T, N]``: the team reward and V of the state after the step
            over the players alive after it (``info["final_observation"]`` at an episode's end).
        death_value: ``float32[T, N]``: V of the same state over the players that acted at ``t``,
            a player who died in the step entering with its observation before it (read under
            ``"reference"`` only: a dying player's bootstrap).
        done, won, lost: ``bool[T, N]``: the episode ended with the step, in a win, in a loss.
        alive, next_alive: ``bool[T, N, P]``: who acted at ``t``; who is alive after the step.

    Returns:
        ``float32[T, N, P]`` (meaningful where ``alive``; under ``"terminal"`` and
        ``"win_bootstrapped"`` every player of an arena has the group's return).
    """
    if ends == "reference":
        died = alive & ~next_alive
        end = done[..., None] | died
        v = jnp.where(died, death_value[..., None], next_value[..., None])
        # A player who dies in a game's last step is done, not interrupted, and its group is all done
        # with it (ML-Agents marks every agent of that step done before it processes any): no bootstrap.
        terminal = lost[..., None] | (died & done[..., None])
        return lambda_returns(reward[..., None], v, end, terminal, gamma, lam)
    terminal = lost if ends == "win_bootstrapped" else won | lost
    g = lambda_returns(reward, next_value, done, terminal, gamma, lam)
    return jnp.broadcast_to(g[..., None], alive.shape)


def advantages(returns: jax.Array, baseline: jax.Array, alive: jax.Array) -> jax.Array:
    """Counterfactual advantages ``G_i - b_i``, normalised over the alive entries, 0 elsewhere.

    Args:
        returns: ``float32[..., P]`` (or ``float32[...]``, one return per decision);
            baseline: ``float32[..., P]``; alive: ``bool[..., P]``.

    Returns:
        ``float32[..., P]``.
    """
    returns = returns if returns.shape == baseline.shape else returns[..., None]
    m = alive.astype(jnp.float32)
    n = jnp.maximum(m.sum(), 1.0)
    a = returns - baseline
    mean = jnp.sum(a * m) / n
    std = jnp.sqrt(jnp.sum(jnp.square(a - mean) * m) / n)
    return jnp.where(alive, (a - mean) / (std + 1e-8), 0.0)


def explained_variance(pred: jax.Array, target: jax.Array, where: jax.Array | None = None) -> jax.Array:
    """``1 - Var(target - pred) / Var(target)`` over the entries ``where`` (all by default): 1 for a
    perfect critic, 0 for one that predicts the mean, negative for a worse one; 0 when the target
    does not vary. ``pred``, ``target`` and ``where`` broadcast together. Returns ``float32[]``."""
    pred, target = jnp.broadcast_arrays(pred, target)
    m = jnp.ones(pred.shape, jnp.float32) if where is None else jnp.broadcast_to(where, pred.shape).astype(jnp.float32)
    n = jnp.maximum(m.sum(), 1.0)

    def var(x):
        mean = jnp.sum(x * m) / n
        return jnp.sum(jnp.square(x - mean) * m) / n

    v = var(target)
    return jnp.where(v > 0, 1.0 - var(target - pred) / jnp.where(v > 0, v, 1.0), 0.0)


def last_seen(obs: Observation, final: Observation) -> Observation:
    """``final`` (``[N, P, ...]``, the observation after a step) with every player who died in the
    step (alive in ``obs``, not in ``final``) seen as in ``obs``: raidjax blanks a dead player's
    observation, while ML-Agents collects a real one at its death (``Agent.NotifyAgentDone``), which
    its bootstrap reads (``trainers.returns``)."""
    died = obs.alive & ~final.alive

    def pick(before, after):
        return jnp.where(died.reshape(died.shape + (1,) * (after.ndim - 2)), before, after)

    return jax.tree.map(pick, obs, final).replace(alive=final.alive)
