"""The reference trainer's networks (``trainers.reference_networks``, ``Config.network="reference"``):
the residual self-attention equals a numpy transcription of ML-Agents 0.28's ``ResidualSelfAttention``
and ``MultiHeadAttention`` forward passes (``torch/attention.py``) on the same weights; the initial
weights have ML-Agents' scales; dead agents and a player's own action cannot move what they must not."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import raidjax
from trainers.reference_networks import ReferenceActor, ReferenceCritic, ReferenceSelfAttention


def ml_agents_rsa(x, mask, w, heads):
    """ML-Agents' forward, numpy: ``x [b, n, e]``, ``mask [b, n]`` (1 = padded, as ML-Agents' masks)."""
    def norm(a):
        mean = a.mean(-1, keepdims=True)
        return (a - mean) / np.sqrt(((a - mean) ** 2).mean(-1, keepdims=True) + 1e-5)

    b, n, e = x.shape
    inp = norm(x)
    dense = lambda a, name: a @ w[name]["kernel"] + w[name]["bias"]
    q, k, v = (dense(inp, name).reshape(b, n, heads, e // heads).transpose(0, 2, 1, 3) for name in ("q", "k", "v"))
    qk = q @ k.transpose(0, 1, 3, 2)  # (b, h, n_q, n_k)
    km = mask.reshape(b, 1, 1, n)
    qk = (1 - km) * qk / e ** 0.5 + km * -1e6
    att = np.exp(qk - qk.max(-1, keepdims=True))
    att /= att.sum(-1, keepdims=True)
    out = (att @ v).transpose(0, 2, 1, 3).reshape(b, n, e)
    out = norm(dense(out, "out") + inp)
    return (out * (1 - mask)[..., None]).sum(1) / ((1 - mask).sum(1, keepdims=True) + 1e-7)


def test_attention_is_ml_agents_forward():
    x = jax.random.normal(jax.random.key(0), (4, 3, 16)) * 2.0 + 0.5
    mask = jnp.array([[1, 1, 1], [1, 0, 1], [0, 0, 1], [1, 1, 0]], bool)  # True = live
    net = ReferenceSelfAttention(16, 4)
    w = net.init(jax.random.key(1), x, mask)
    # Biases start at zero (ML-Agents too); set them so that they are checked.
    w = jax.tree.map(lambda a: a + 0.1 if a.ndim == 1 else a, w)
    got = np.asarray(net.apply(w, x, mask))
    weights = jax.tree.map(np.asarray, w["params"])
    expect = ml_agents_rsa(np.asarray(x), 1.0 - np.asarray(mask, np.float64), weights, 4)
    np.testing.assert_allclose(got[:3], expect[:3], rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(got[3], expect[3], rtol=1e-4, atol=1e-5)


def test_initial_weights_have_ml_agents_scales():
    params = raidjax.make_params(observation="reference", action_space="reference")
    obs, _ = jax.jit(jax.vmap(raidjax.reset, in_axes=(0, None)))(jax.random.split(jax.random.key(0), 2), params)
    w = jax.jit(ReferenceActor(256, 2, 4).init)(jax.random.key(1), obs)["params"]
    std = lambda a: float(np.asarray(a).std())
    assert std(w["encoder"]["rsa"]["q"]["kernel"]) == pytest.approx((0.125 / 128) ** 0.5, rel=0.05)
    assert std(w["encoder"]["self_enc"]["kernel"]) == pytest.approx((0.125 / 128) ** 0.5, rel=0.05)
    assert std(w["body_0"]["kernel"]) == pytest.approx(1 / (186 + 128) ** 0.5, rel=0.05)  # Kaiming, linear gain
    assert std(w["pi"]["kernel"]) == pytest.approx(0.1 / 256 ** 0.5, rel=0.15)  # 8 x 256 weights
    assert all(not np.asarray(a).any() for a in jax.tree.leaves(w) if a.ndim == 1)  # zero biases


@pytest.mark.parametrize("senses", ["reference", "raidjax"])
def test_critic_masks_dead_agents_and_baseline_ignores_own_action(senses):
    params = raidjax.make_params(observation=senses, action_space=senses)
    obs, _ = jax.jit(jax.vmap(raidjax.reset, in_axes=(0, None)))(jax.random.split(jax.random.key(0), 2), params)
    critic = ReferenceCritic(16, 2, 2, proj_attention=senses == "raidjax")
    acts = jnp.zeros((2, 3), jnp.int32)
    w = jax.jit(critic.init)(jax.random.key(2), obs, acts)
    apply = jax.jit(critic.apply)
    value, base = apply(w, obs, acts)
    assert value.shape == (2,) and base.shape == (2, 3) and np.isfinite(np.asarray(base)).all()
    # Player 2 dead: its observation and action cannot move V or the others' baselines.
    dead = obs.replace(alive=obs.alive.at[:, 2].set(False))
    moved = jax.tree.map(lambda a: a.at[:, 2].multiply(3.0) if a.dtype == jnp.float32 else a, dead)
    v0, b0 = apply(w, dead, acts)
    v1, b1 = apply(w, moved, acts.at[:, 2].set(5))
    np.testing.assert_allclose(v0, v1, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(b0[:, :2], b1[:, :2], rtol=1e-5, atol=1e-6)
    # b_i ignores a_i and sees its teammates' actions.
    _, b_own = apply(w, obs, acts.at[:, 0].set(3))
    np.testing.assert_allclose(b_own[:, 0], base[:, 0], rtol=1e-5, atol=1e-6)
    assert np.abs(np.asarray(b_own[:, 1] - base[:, 1])).max() > 1e-6
