"""Flax networks of MA-POCA (PROTOCOLS.md §12): a shared entity-attention actor and a centralised critic
that gives both the group value V(s) and the counterfactual baselines Q(s, a_-i).

Shapes: ``P`` players, ``A`` actions (``config.n_actions``, the width of ``obs.action_mask``),
``H`` hidden width, ``...`` any leading batch axes. Every module takes a ``raidjax.Observation``
or a ``ReferenceObservation`` (``observation="reference"``) whose fields carry the player axis
``P`` right after the batch axes (as ``raidjax.step`` returns them).

Mixed precision: with ``dtype=jnp.bfloat16`` every Dense and LayerNorm computes in bfloat16
(XLA accumulates matmuls in float32 on GPUs and TPUs) while the parameters stay float32; attention
logits, softmaxes and the outputs (logits, values) are float32, so the losses and the optimizer
never see bfloat16.

Dead players are handled by masks, never by zero inputs alone: a dead teammate (actor) and a
dead agent (critic) are removed from attention keys and from the mean-pools, so the network
cannot tell a dead player from "no player" and can never mistake zeros for a live state.
"""

from __future__ import annotations

import functools
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from raidjax.reference_observation import ReferenceObservation
from raidjax.types import Observation
from trainers import draws

NEG = -1e9  # additive mask for logits/attention (finite: an all-masked row stays NaN-free)
# flax's Dense with its default kernel initialiser drawn flat (trainers.draws: the same numbers, a
# faster compile); every layer here that does not choose its own initialiser is one of these.
Dense = functools.partial(nn.Dense, kernel_init=draws.lecun_normal())


def orthogonal(scale: float = 1.0):
    """Flax kernel initialiser: a random orthogonal matrix times ``scale``, distributed as
    ``flax.linen.initializers.orthogonal``'s (QR of a Gaussian matrix, signs fixed so that R has a
    positive diagonal), computed by Gram-Schmidt with re-orthogonalisation instead of LAPACK's QR.

    Why: XLA:CPU runs a vmapped QR (several runs initialised together) as a batched LAPACK call
    that splits its batch over the 2-thread pool; two of them running at once each waited on the
    thread the other held and the process hung (seen in 2 of 3 tries of Benchmark 2's 7 vmapped
    paper-PPO models on 2 cores). Gram-Schmidt is plain matrix arithmetic.

    Returns ``init(key, shape, dtype) -> dtype[shape]`` for a 2-D or larger ``shape`` (the last axis
    is the output width, the others are flattened into rows).
    """
    def init(key, shape, dtype=jnp.float32):
        rows, cols = int(np.prod(shape[:-1])), shape[-1]
        tall = (max(rows, cols), min(rows, cols))
        a = draws.normal(key, tall, jnp.float32)

        def column(j, q):
            v = a[:, j]
            for _ in range(2):  # twice is enough in float32 (Giraud et al. 2005, "twice is enough")
                v = v - q @ (q.T @ v)
            return q.at[:, j].set(v / jnp.linalg.norm(v))

        q = jax.lax.fori_loop(0, tall[1], column, jnp.zeros(tall, jnp.float32))
        q = q.T if rows < cols else q
        return (scale * q.reshape(shape)).astype(dtype)

    return init


def masked_mean(x: jax.Array, mask: jax.Array) -> jax.Array:
    """Mean of ``x: [..., N, H]`` over the entities where ``mask: bool[..., N]``; zeros if none.

    Returns:
        ``[..., H]``.
    """
    m = mask.astype(x.dtype)[..., None]
    return jnp.sum(x * m, axis=-2) / jnp.maximum(jnp.sum(m, axis=-2), 1.0)


class ResidualSelfAttention(nn.Module):
    """Residual multi-head self-attention over entities with a key mask, then a masked mean-pool.

    ``__call__(x, mask)``: ``x: [..., N, H]``, ``mask: bool[..., N]`` -> ``[..., H]`` (zeros when no
    entity is valid) equals ``masked_mean(x + Out(MHA(LN(x))), mask)``; the output projection is
    linear, so it is applied after pooling (same function, N times cheaper).
    ``project(x)`` and ``attend(x, qkv, mask)`` split the work so that callers can share the
    per-token projections between several entity sets (the counterfactual baselines).
    """

    features: int
    heads: int = 4
    dtype: Any = jnp.float32

    def setup(self):
        self.norm = nn.LayerNorm(dtype=self.dtype)
        self.qkv = Dense(3 * self.features, dtype=self.dtype)
        self.out = Dense(self.features, dtype=self.dtype)

    def project(self, x: jax.Array) -> jax.Array:
        """Per-token ``qkv: [..., N, 3, heads, H / heads]``."""
        h = self.features
        return self.qkv(self.norm(x)).reshape(*x.shape[:-1], 3, self.heads, h // self.heads)

    def attend(self, x: jax.Array, qkv: jax.Array, mask: jax.Array) -> jax.Array:
        """Masked attention from projected tokens, residual, masked mean-pool: ``[..., H]``."""
        q, k, v = qkv[..., 0, :, :], qkv[..., 1, :, :], qkv[..., 2, :, :]
        # Broadcast-multiply-and-sum instead of einsum: XLA:CPU fuses these, while tiny batched
        # matmuls ([N x N] per head) run far slower there.
        q, k = q.astype(jnp.float32), k.astype(jnp.float32)  # logits and softmax in float32
        logits = jnp.sum(q[..., :, None, :, :] * k[..., None, :, :, :], axis=-1) / jnp.sqrt(q.shape[-1])
        logits = logits + jnp.where(mask, 0.0, NEG)[..., None, :, None]  # [..., q, k, heads]
        w = jax.nn.softmax(logits, axis=-2).astype(v.dtype)
        att = jnp.sum(w[..., None] * v[..., None, :, :, :], axis=-3).reshape(x.shape)
        return masked_mean(x, mask) + self.out(masked_mean(att, mask))

    def __call__(self, x: jax.Array, mask: jax.Array) -> jax.Array:
        """Pooled ``[..., H]``: see the class docstring."""
        return self.attend(x, self.project(x), mask)


class MLP(nn.Module):
    """``layers`` ReLU Dense layers of width ``hidden``: ``[..., D] -> [..., hidden]``."""

    hidden: int
    layers: int
    dtype: Any = jnp.float32

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        for _ in range(self.layers):
            x = nn.relu(Dense(self.hidden, dtype=self.dtype)(x))
        return x


def masked_logits(logits: jax.Array, action_mask: jax.Array) -> jax.Array:
    """Logits with invalid actions pushed to ``NEG``: ``[..., A]`` -> ``[..., A]``."""
    return jnp.where(action_mask, logits, NEG)


class Actor(nn.Module):
    """Shared per-player policy: self (own + boss + wall features) and entities (teammates, and
    with ``proj_attention`` the nearest hostile projectiles) -> residual self-attention ->
    masked mean-pool -> MLP -> masked logits. Without ``proj_attention`` the K projectile slots
    (sorted nearest first, masked slots zero) join the self features instead (cheaper on CPU).

    On a ``ReferenceObservation`` it is the reference trainer's network (ML-Agents'
    ``ObservationEncoder``): the teammate buffer through an entity embedding that also sees the
    rank-1 observations (rays and stack, 186 floats, unnormalised), residual self-attention with
    dead teammates' rows masked, then the 186 floats and the pooled attention into the MLP.

    ``obs`` fields ``[..., P, ...]`` -> logits ``float32[..., P, A]`` (invalid actions at ``NEG``).
    """

    hidden: int = 64
    layers: int = 2
    heads: int = 4
    proj_attention: bool = True
    dtype: Any = jnp.float32

    @nn.compact
    def __call__(self, obs: Observation | ReferenceObservation) -> jax.Array:
        h, dt = self.hidden, self.dtype
        n_actions = obs.action_mask.shape[-1]
        if isinstance(obs, ReferenceObservation):
            flat = jnp.concatenate([obs.projectile_rays, obs.wall_rays, obs.stack], axis=-1)
            ctx = Dense(h, use_bias=False, dtype=dt, name="self_ctx")(flat)[..., None, :]
            ents = nn.relu(Dense(h, dtype=dt, name="mate_emb")(obs.teammates) + ctx)
            pooled = ResidualSelfAttention(h, self.heads, dt, name="rsa")(ents, obs.teammate_mask)
            x = MLP(h, self.layers, dt, name="body")(jnp.concatenate([flat.astype(pooled.dtype), pooled], axis=-1))
            logits = nn.Dense(n_actions, kernel_init=orthogonal(0.01), dtype=dt, name="pi")(x)
            return masked_logits(logits.astype(jnp.float32), obs.action_mask)
        self_parts = [obs.self_features, obs.boss, obs.walls]
        if not self.proj_attention:
            lead = obs.projectile_mask.shape
            self_parts += [obs.projectiles.reshape(*lead[:-1], -1), obs.projectile_mask.astype(jnp.float32)]
        s = nn.relu(Dense(h, dtype=dt, name="self_enc")(jnp.concatenate(self_parts, axis=-1)))
        # Entity embeddings see the self encoding (as ML-Agents' EntityEmbedding does).
        ctx = Dense(h, use_bias=False, dtype=dt, name="self_ctx")(s)[..., None, :]
        ents = nn.relu(Dense(h, dtype=dt, name="mate_emb")(obs.teammates) + ctx)
        mask = obs.teammate_mask
        if self.proj_attention:
            projs = nn.relu(Dense(h, dtype=dt, name="proj_emb")(obs.projectiles) + ctx)
            ents = jnp.concatenate([ents, projs], axis=-2)
            mask = jnp.concatenate([mask, obs.projectile_mask], axis=-1)
        pooled = ResidualSelfAttention(h, self.heads, dt, name="rsa")(ents, mask)
        x = MLP(h, self.layers, dt, name="body")(jnp.concatenate([s, pooled], axis=-1))
        logits = nn.Dense(n_actions, kernel_init=orthogonal(0.01), dtype=dt, name="pi")(x)
        return masked_logits(logits.astype(jnp.float32), obs.action_mask)


def critic_inputs(obs: Observation | ReferenceObservation) -> jax.Array:
    """Per-agent critic input ``float32[..., P, D]``: the flat observation view (the fields of
    ``Observation.flat``, masks as 0/1; a reference observation's 204 floats and its teammate
    mask), for any number of leading batch axes."""
    lead = obs.alive.shape
    if isinstance(obs, ReferenceObservation):
        parts = [obs.teammates, obs.teammate_mask, obs.projectile_rays, obs.wall_rays, obs.stack]
        return jnp.concatenate([x.astype(jnp.float32).reshape(*lead, -1) for x in parts], axis=-1)
    parts = [obs.self_features, obs.boss, obs.teammates, obs.teammate_mask, obs.projectiles,
             obs.projectile_mask, obs.walls, obs.action_mask]
    return jnp.concatenate([x.astype(jnp.float32).reshape(*lead, -1) for x in parts], axis=-1)


class Critic(nn.Module):
    """Centralised critic. Agents are entities: an observation embedding (value and agent i in
    its own baseline) or an observation-action embedding (teammates in a baseline), then shared
    residual self-attention, masked mean-pool, the normalised agent count, an MLP and a head.

    Methods: ``value(obs) -> [...]`` and ``baseline(obs, actions) -> [..., P]``;
    ``__call__`` returns both (used for ``init``).
    """

    hidden: int = 64
    layers: int = 2
    heads: int = 4
    dtype: Any = jnp.float32

    def setup(self):
        dt = self.dtype
        self.obs_emb = Dense(self.hidden, dtype=dt)
        self.obs_act_emb = Dense(self.hidden, dtype=dt)
        self.rsa = ResidualSelfAttention(self.hidden, self.heads, dt)
        self.body = MLP(self.hidden, self.layers, dt)
        self.value_head = Dense(1, dtype=dt)
        self.baseline_head = Dense(1, dtype=dt)

    def _head(self, pooled: jax.Array, mask: jax.Array, head) -> jax.Array:
        count = jnp.sum(mask, axis=-1, keepdims=True).astype(pooled.dtype) / mask.shape[-1]
        return head(self.body(jnp.concatenate([pooled, count], axis=-1)))[..., 0].astype(jnp.float32)

    def value(self, obs: Observation, agents: jax.Array | None = None) -> jax.Array:
        """V(s) over the agents ``agents: bool[..., P]`` (default: the alive ones, ``obs.alive``):
        ``obs [..., P, ...]`` -> ``float32[...]``."""
        agents = obs.alive if agents is None else agents
        e = nn.relu(self.obs_emb(critic_inputs(obs)))
        return self._head(self.rsa(e, agents), agents, self.value_head)

    def baseline(self, obs: Observation, actions: jax.Array, agent: jax.Array | None = None) -> jax.Array:
        """Counterfactual baselines b_i = Q(s, a_-i): agent i enters with its observation only,
        alive teammates with (observation, action); dead teammates are masked out.

        Args:
            obs: fields ``[..., P, ...]``.
            actions: ``int32[..., P]``.
            agent: ``None`` (every agent's baseline) or ``int32[...]`` (only that agent's).

        Returns:
            ``float32[..., P]`` (row i is agent i's baseline; meaningful where agent i is alive), or
            ``float32[...]`` with ``agent``.
        """
        x = critic_inputs(obs)
        p = x.shape[-2]
        e_o = nn.relu(self.obs_emb(x))
        one_hot = jax.nn.one_hot(actions, obs.action_mask.shape[-1])
        e_oa = nn.relu(self.obs_act_emb(jnp.concatenate([x, one_hot], axis=-1)))
        if agent is not None:
            me = jax.nn.one_hot(agent, p, dtype=bool)  # [..., j]: token j is observation-only
            tokens = jnp.where(me[..., None], e_o, e_oa)
            mask = obs.alive | me
            return self._head(self.rsa(tokens, mask), mask, self.baseline_head)
        qkv_o, qkv_oa = self.rsa.project(e_o), self.rsa.project(e_oa)  # per-token, shared by all i
        eye = jnp.eye(p, dtype=bool)  # [i, j]: token j of agent i's baseline is observation-only
        tokens = jnp.where(eye[..., None], e_o[..., None, :, :], e_oa[..., None, :, :])  # [..., i, j, H]
        qkv = jnp.where(eye[..., None, None, None], qkv_o[..., None, :, :, :, :], qkv_oa[..., None, :, :, :, :])
        mask = obs.alive[..., None, :] | eye  # agent i always present in its own baseline
        pooled = self.rsa.attend(tokens, qkv, mask)
        return self._head(pooled, mask, self.baseline_head)

    def __call__(self, obs: Observation, actions: jax.Array, agent: jax.Array | None = None):
        """``(value [...], baseline [..., P])`` (``[...]`` for one ``agent``, see ``baseline``)."""
        return self.value(obs), self.baseline(obs, actions, agent)


def sample_actions(key, logits: jax.Array, alive: jax.Array, deterministic: bool = False):
    """Sample from masked logits ``[..., P, A]``; dead players get action 0.

    Args:
        key: PRNG key (typed or raw ``uint32[2]``); unused when ``deterministic``.
        logits: ``float32[..., P, A]`` masked logits (``Actor``'s; invalid actions at ``NEG``).
        alive: ``bool[..., P]``, the players that act.
        deterministic: take each player's argmax instead of sampling (static Python bool).

    Returns:
        ``(actions int32[..., P], logp float32[..., P])``: ``logp`` is the log-probability of the
        returned action (of action 0 for dead players).
    """
    a = jnp.argmax(logits, -1) if deterministic else draws.categorical(key, logits)
    a = jnp.where(alive, a, 0).astype(jnp.int32)
    logp = jnp.take_along_axis(jax.nn.log_softmax(logits), a[..., None], axis=-1)[..., 0]
    return a, logp
