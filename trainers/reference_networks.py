"""The reference trainer's MA-POCA networks (ML-Agents 0.28 POCA, ``Config.network = "reference"``):
the same interfaces as ``trainers.networks.Actor`` and ``Critic``, built layer by layer as
ML-Agents builds them (PROTOCOLS.md §12; paths under ``mlagents/trainers/torch/``):

* Observation encoder (``networks.py`` ``ObservationEncoder``, 34-135): the fixed-size
  observations (the reference player's rays and stack, 186 floats, unnormalised) pass through
  unchanged as ``x_self``; ``x_self`` is encoded once (``utils.py`` ``create_residual_self_attention``:
  one 128-wide Swish layer, normal initial weights of standard deviation √(0.125/128)); each
  entity row (a teammate) is concatenated after that encoding and embedded the same way
  (``attention.py`` ``EntityEmbedding``); residual self-attention, 128 wide, 4 heads, pools the
  live entities; the encoding is ``[x_self, pooled]``.
* Residual self-attention (``attention.py`` 203-293): LayerNorm without learned scale or shift
  (``layers.py`` 119-130, ε 1e-5) → q, k, v; logits ÷ √(the full width), masked keys at a large
  negative; the output projection plus the *normalised* input; LayerNorm again; a masked mean
  (``sum / (count + 1e-7)``: 0 when no entity is live). q, k, v and out start normal with standard
  deviation √(0.125/width), zero bias.
* Actor (``networks.py`` ``NetworkBody`` 174-252, ``distributions.py`` 206-229): the encoding →
  ``layers`` × ``hidden`` Swish layers (Kaiming normal for a linear gain: standard deviation
  1/√fan-in, zero bias) → one Kaiming × 0.1 head.
* Critic (``networks.py`` ``MultiAgentNetworkBody`` 255-427): every agent's observation through its
  own pass of the critic's observation encoder (its own weights; ``separate_critic``); an
  observation-only and an observation-action embedding (one ``hidden``-wide Swish layer each,
  normal √(0.125/hidden)); residual self-attention ``hidden`` wide over the agents; ``layers`` ×
  ``hidden`` Swish layers (Kaiming × √(0.125/hidden)); then the agent count, scaled to
  ``2 n / max - 1`` (``max`` a running maximum that reaches ``P`` at a full team's first step; here
  ``P``), is appended *after* that body; a Xavier-uniform head (``decoders.py``).

On raidjax's senses ``x_self`` is the player's own, boss and wall features with the projectile
slots flattened (or, with ``proj_attention``, the projectiles are a second kind of entity with its
own embedding, as a second buffer sensor would be).
"""

from __future__ import annotations

from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp

from raidjax.reference_observation import ReferenceObservation
from raidjax.types import Observation
from trainers import draws
from trainers.networks import NEG, masked_logits

ATTENTION_WIDTH = 128  # ObservationEncoder.ATTENTION_EMBEDDING_SIZE: fixed in ML-Agents


def small_normal(width: int):
    """ML-Agents' ``Initialization.Normal`` with gain √(0.125 / width) (the T-Fixup scheme)."""
    return draws.normal_init((0.125 / width) ** 0.5)


def kaiming(gain: float = 1.0):
    """ML-Agents' ``KaimingHeNormal`` as ``linear_layer`` calls it (``nonlinearity="linear"``):
    normal with standard deviation ``gain / √fan_in``."""
    return draws.variance_scaling(gain ** 2, "fan_in", "normal")


def swish_dense(x: jax.Array, width: int, init, dtype, name: str | None = None) -> jax.Array:
    """One ML-Agents ``LinearEncoder`` layer: Dense (zero bias) then Swish."""
    return nn.swish(nn.Dense(width, kernel_init=init, dtype=dtype, name=name)(x))


def plain_norm(x: jax.Array) -> jax.Array:
    """ML-Agents' ``LayerNorm``: ``(x - mean) / sqrt(var + 1e-5)`` over the last axis, no parameters."""
    mean = jnp.mean(x, axis=-1, keepdims=True)
    var = jnp.mean(jnp.square(x - mean), axis=-1, keepdims=True)
    return (x - mean) / jnp.sqrt(var + 1e-5)


class ReferenceSelfAttention(nn.Module):
    """ML-Agents' ``ResidualSelfAttention``: ``x [..., N, E]``, ``mask bool[..., N]`` -> ``[..., E]``."""

    features: int
    heads: int = 4
    dtype: Any = jnp.float32

    @nn.compact
    def __call__(self, x: jax.Array, mask: jax.Array) -> jax.Array:
        e, dt = self.features, self.dtype
        x = plain_norm(x.astype(jnp.float32)).astype(dt)
        proj = lambda name: nn.Dense(e, kernel_init=small_normal(e), dtype=dt, name=name)(x)
        q, k, v = (proj(n).reshape(*x.shape[:-1], self.heads, e // self.heads) for n in ("q", "k", "v"))
        q, k = q.astype(jnp.float32), k.astype(jnp.float32)
        # Broadcast-multiply-and-sum (not einsum): XLA:CPU fuses it, tiny batched matmuls are slow there.
        logits = jnp.sum(q[..., :, None, :, :] * k[..., None, :, :, :], axis=-1) / jnp.sqrt(e)  # [.., q, k, heads]
        logits = jnp.where(mask[..., None, :, None], logits, NEG)
        w = jax.nn.softmax(logits, axis=-2).astype(v.dtype)
        att = jnp.sum(w[..., None] * v[..., None, :, :, :], axis=-3).reshape(x.shape)
        out = nn.Dense(e, kernel_init=small_normal(e), dtype=dt, name="out")(att) + x
        out = plain_norm(out.astype(jnp.float32))
        m = mask.astype(jnp.float32)[..., None]
        return jnp.sum(out * m, axis=-2) / (jnp.sum(m, axis=-2) + 1e-7)


def self_and_entities(obs: Observation | ReferenceObservation, proj_attention: bool):
    """``(x_self float32[..., D], groups)`` of one observation: ``groups`` is a list of ``(entities
    float32[..., N, F], mask bool[..., N])``, one per kind of entity (ML-Agents: one buffer sensor each)."""
    if isinstance(obs, ReferenceObservation):
        x_self = jnp.concatenate([obs.projectile_rays, obs.wall_rays, obs.stack], axis=-1)
        return x_self, [(obs.teammates, obs.teammate_mask)]
    parts = [obs.self_features, obs.boss, obs.walls]
    groups = [(obs.teammates, obs.teammate_mask)]
    if proj_attention:
        groups.append((obs.projectiles, obs.projectile_mask))
    else:
        lead = obs.projectile_mask.shape[:-1]
        parts += [obs.projectiles.reshape(*lead, -1), obs.projectile_mask.astype(jnp.float32)]
    return jnp.concatenate(parts, axis=-1), groups


class ObservationEncoder(nn.Module):
    """ML-Agents' ``ObservationEncoder`` on one observation: fields ``[..., ...]`` -> ``[..., D + 128]``."""

    heads: int = 4
    proj_attention: bool = False
    dtype: Any = jnp.float32

    @nn.compact
    def __call__(self, obs) -> jax.Array:
        x_self, groups = self_and_entities(obs, self.proj_attention)
        w, dt = ATTENTION_WIDTH, self.dtype
        s = swish_dense(x_self, w, small_normal(w), dt, "self_enc")
        embedded = []
        for g, (ents, _) in enumerate(groups):  # EntityEmbedding: [self encoding, entity row] -> Swish
            tiled = jnp.broadcast_to(s[..., None, :], ents.shape[:-1] + (w,))
            embedded.append(swish_dense(jnp.concatenate([tiled, ents.astype(s.dtype)], axis=-1), w, small_normal(w),
                                        dt, f"entity_emb_{g}"))
        mask = jnp.concatenate([m for _, m in groups], axis=-1)
        pooled = ReferenceSelfAttention(w, self.heads, dt, name="rsa")(jnp.concatenate(embedded, axis=-2), mask)
        return jnp.concatenate([x_self.astype(jnp.float32), pooled], axis=-1)


class ReferenceActor(nn.Module):
    """The reference trainer's policy: ``obs`` fields ``[..., P, ...]`` -> logits ``float32[..., P, A]``."""

    hidden: int = 256
    layers: int = 2
    heads: int = 4
    proj_attention: bool = False
    dtype: Any = jnp.float32

    @nn.compact
    def __call__(self, obs) -> jax.Array:
        x = ObservationEncoder(self.heads, self.proj_attention, self.dtype, name="encoder")(obs)
        for i in range(self.layers):
            x = swish_dense(x, self.hidden, kaiming(), self.dtype, f"body_{i}")
        logits = nn.Dense(obs.action_mask.shape[-1], kernel_init=kaiming(0.1), dtype=self.dtype, name="pi")(x)
        return masked_logits(logits.astype(jnp.float32), obs.action_mask)


class ReferenceCritic(nn.Module):
    """The reference trainer's centralised critic; methods as ``trainers.networks.Critic``:
    ``value(obs, agents=None) -> float32[...]``, ``baseline(obs, actions) -> float32[..., P]``."""

    hidden: int = 256
    layers: int = 2
    heads: int = 4
    proj_attention: bool = False
    dtype: Any = jnp.float32

    def setup(self):
        h, dt = self.hidden, self.dtype
        self.encoder = ObservationEncoder(self.heads, self.proj_attention, dt)
        self.obs_emb = nn.Dense(h, kernel_init=small_normal(h), dtype=dt)
        self.obs_act_emb = nn.Dense(h, kernel_init=small_normal(h), dtype=dt)
        self.rsa = ReferenceSelfAttention(h, self.heads, dt)
        self.body = [nn.Dense(h, kernel_init=kaiming((0.125 / h) ** 0.5), dtype=dt) for _ in range(self.layers)]
        # One head for the value and the baselines, as ML-Agents' POCAValueNetwork.value_heads (poca/
        # optimizer_torch.py 61-62): they differ only in their inputs.
        self.head = nn.Dense(1, kernel_init=draws.xavier_uniform(), dtype=dt)

    def _head(self, pooled: jax.Array, mask: jax.Array, head) -> jax.Array:
        x = pooled
        for layer in self.body:
            x = nn.swish(layer(x))
        count = 2.0 * jnp.sum(mask, axis=-1, keepdims=True) / mask.shape[-1] - 1.0
        return head(jnp.concatenate([x, count.astype(x.dtype)], axis=-1))[..., 0].astype(jnp.float32)

    def value(self, obs, agents: jax.Array | None = None) -> jax.Array:
        """V(s) over ``agents: bool[..., P]`` (default ``obs.alive``): ``obs [..., P, ...]`` -> ``float32[...]``."""
        agents = obs.alive if agents is None else agents
        return self._value(nn.swish(self.obs_emb(self.encoder(obs))), agents)

    def _value(self, e_o, agents):
        return self._head(self.rsa(e_o, agents), agents, self.head)

    def baseline(self, obs, actions: jax.Array, agent: jax.Array | None = None) -> jax.Array:
        """b_i = Q(s, a_-i): agent i observation-only, its alive teammates with their actions;
        ``obs [..., P, ...]``, ``actions int32[..., P]`` -> ``float32[..., P]``, or ``float32[...]``
        for the one agent ``agent int32[...]``."""
        enc = self.encoder(obs)
        return self._baseline(obs, enc, nn.swish(self.obs_emb(enc)), actions, agent)

    def _baseline(self, obs, enc, e_o, actions, agent):
        p = enc.shape[-2]
        one_hot = jax.nn.one_hot(actions, obs.action_mask.shape[-1], dtype=enc.dtype)
        e_oa = nn.swish(self.obs_act_emb(jnp.concatenate([enc, one_hot], axis=-1)))
        if agent is not None:
            me = jax.nn.one_hot(agent, p, dtype=bool)
            mask = obs.alive | me
            return self._head(self.rsa(jnp.where(me[..., None], e_o, e_oa), mask), mask, self.head)
        eye = jnp.eye(p, dtype=bool)
        tokens = jnp.where(eye[..., None], e_o[..., None, :, :], e_oa[..., None, :, :])  # [..., i, j, H]
        mask = obs.alive[..., None, :] | eye
        return self._head(self.rsa(tokens, mask), mask, self.head)

    def __call__(self, obs, actions: jax.Array, agent: jax.Array | None = None):
        """``(value [...], baseline [..., P] or [...] with agent)``, the agents' encoding computed once."""
        enc = self.encoder(obs)
        e_o = nn.swish(self.obs_emb(enc))
        return self._value(e_o, obs.alive), self._baseline(obs, enc, e_o, actions, agent)
