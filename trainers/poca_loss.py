"""MA-POCA's loss, as ML-Agents' POCA computes it: PPO's clipped policy loss, the clipped regressions of
the centralised value and of each agent's counterfactual baseline, and the entropy bonus
(docs/PROTOCOLS.md §12, rows 5-8). ``trainers.mapoca`` trains on it; ``Batch`` holds its samples."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from raidjax.types import Observation
from trainers.networks import Actor, Critic


class Batch(NamedTuple):
    """Flattened training samples (leading axis = decisions) for ``loss_fn``."""

    obs: Observation  # [B, P, ...]
    action: jax.Array  # int32[B, P]
    logp: jax.Array  # float32[B, P]
    alive: jax.Array  # bool[B, P]
    value: jax.Array  # float32[B] old V
    baseline: jax.Array  # float32[B, P] old b
    returns: jax.Array  # float32[B, P] λ-returns G_i (every column the group's unless episode_ends="reference")
    advantage: jax.Array  # float32[B, P] normalised G - b (0 where not alive)


def loss_fn(params: dict, batch: Batch, actor: Actor, critic: Critic, clip_eps: float, ent_coef,
            value_rows: str = "decisions", agent: jax.Array | None = None):
    """MA-POCA loss ``L = L_pi + 0.5 (L_V + 0.5 L_b) - β H`` on one minibatch.

    L_pi: PPO clipped surrogate; L_V / L_b: clipped squared regression of V / b_i onto G_i (max of
    the clipped and unclipped errors); H: entropy of the masked categorical. Policy, baseline
    and entropy terms average over the agents that acted; L_V over decisions (``value_rows``
    ``"decisions"``, onto the group's return) or over the agents that acted (``"agents"``, onto each
    agent's return, as ML-Agents' buffer rows are agent experiences; ``episode_ends="reference"``).

    Args:
        params: ``{"actor": ..., "critic": ...}`` network weights (the differentiated argument).
        batch: ``[M, P, ...]`` decisions (fields as ``Batch``).
        actor, critic: the flax modules of ``params`` (``make_networks``).
        clip_eps: PPO ratio clip ε, also the half-width of the value and baseline clips.
        ent_coef: entropy coefficient β (a float or ``float32[]``; traced when annealed).
        value_rows: ``"decisions"`` or ``"agents"`` (above; forced to ``"agents"`` when ``agent`` is given).
        agent: ``None`` (every player of each decision is a sample) or ``int32[M]``: row ``r`` is
            the experience of player ``agent[r]`` in decision ``r`` only (``Config.minibatch_rows
            = "agents"``, ML-Agents' rows); the value loss is then over rows.

    Returns:
        ``(loss: float32[], aux: dict of float32[])``.
    """
    if agent is None:
        logits = actor.apply(params["actor"], batch.obs)
        value, baseline = critic.apply(params["critic"], batch.obs, batch.action)
        action, old_logp, adv, alive, returns = batch.action, batch.logp, batch.advantage, batch.alive, batch.returns
        old_baseline = batch.baseline
    else:
        rows = jnp.arange(agent.shape[0])
        pick = lambda x: x[rows, agent]
        logits = actor.apply(params["actor"], jax.tree.map(pick, batch.obs))
        value, baseline = critic.apply(params["critic"], batch.obs, batch.action, agent)
        action, old_logp, adv, alive, returns, old_baseline = map(
            pick, (batch.action, batch.logp, batch.advantage, batch.alive, batch.returns, batch.baseline))
        value_rows = "agents"
    logp_all = jax.nn.log_softmax(logits)
    logp = jnp.take_along_axis(logp_all, action[..., None], axis=-1)[..., 0]
    m = alive.astype(jnp.float32)
    n = jnp.maximum(m.sum(), 1.0)
    ratio = jnp.exp(logp - old_logp)
    surrogate = jnp.minimum(ratio * adv, jnp.clip(ratio, 1 - clip_eps, 1 + clip_eps) * adv)
    l_pi = -jnp.sum(surrogate * m) / n
    probs = jnp.exp(logp_all)
    mask = batch.obs.action_mask if agent is None else pick(batch.obs.action_mask)
    ent = -jnp.sum(jnp.where(mask, probs * logp_all, 0.0), axis=-1)
    entropy = jnp.sum(ent * m) / n

    def clipped_sq(new, old, target):
        clipped = old + jnp.clip(new - old, -clip_eps, clip_eps)
        return jnp.maximum(jnp.square(new - target), jnp.square(clipped - target))

    if value_rows == "agents":
        per_row = lambda x: x if agent is not None else x[..., None]
        l_v = jnp.sum(clipped_sq(per_row(value), per_row(batch.value), returns) * m) / n
    else:  # every column holds the group's return
        l_v = jnp.mean(clipped_sq(value, batch.value, returns[..., 0]))
    l_b = jnp.sum(clipped_sq(baseline, old_baseline, returns) * m) / n
    loss = l_pi + 0.5 * (l_v + 0.5 * l_b) - ent_coef * entropy
    aux = {
        "loss": loss, "policy_loss": l_pi, "value_loss": l_v, "baseline_loss": l_b, "entropy": entropy,
        "approx_kl": jnp.sum(((ratio - 1) - (logp - old_logp)) * m) / n,
        "clip_frac": jnp.sum((jnp.abs(ratio - 1) > clip_eps) * m) / n,
    }
    return loss, aux
