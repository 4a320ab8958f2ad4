"""How a game's end reaches MA-POCA's returns (``trainers.returns``, ``Config.episode_ends``): on
hand-made trajectories of a won, a lost and a timed-out game, each with a player dying mid-game,
``game_returns`` equals ML-Agents' own recipe, written out here independently: ``lambda_return``
(``returns[-1] = r[-1] + γ value_next``, ``returns[t] = γλ returns[t+1] + r[t] + (1-λ) γ V[t+1]``)
over every agent trajectory the reference trainer cuts, with ``value_next`` zeroed only when the
trajectory's agent and its whole group are done and it was not interrupted (a loss)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from trainers.networks import Actor, Critic
from trainers.poca_loss import Batch, loss_fn
from trainers.returns import game_returns, lambda_returns, last_seen

GAMMA, LAM = 0.9, 0.8
T, END, DEATH = 8, 5, 2  # the game ends with step 5; player 2 dies in step 2; steps 6-7 begin the next game
R = np.array([0.3, 0.0, 0.5, 0.2, 0.1, 0.4, 0.0, 0.6], np.float32)  # team rewards (a win's bonus included)
V = np.array([1.0, 1.2, 1.1, 0.9, 1.3, 0.8, 2.0, 2.1, 2.2], np.float32)  # V(s_0..s_8) over the live players
V_FINAL = 1.7  # V of the ended game's final observation (over its survivors)
V_DEATH = 0.7  # V(s_3) with the dying player 2 counted among the players


def ml_agents_lambda_return(r, value_estimates, value_next):
    """ML-Agents 0.28's ``lambda_return`` on one agent trajectory (numpy, as it is written there)."""
    returns = np.zeros_like(r)
    returns[-1] = r[-1] + GAMMA * value_next
    for t in reversed(range(r.size - 1)):
        returns[t] = GAMMA * LAM * returns[t + 1] + r[t] + (1 - LAM) * GAMMA * value_estimates[t + 1]
    return returns


def game(result: str):
    """One arena's rollout window: ``(reward, next_value, death_value, done, won, lost, alive,
    next_alive)`` with the ``[T, N=1]`` / ``[T, 1, P=3]`` shapes ``game_returns`` takes."""
    alive = np.ones((T, 3), bool)
    alive[DEATH + 1:END + 1, 2] = False  # dead from step 3 to the game's end
    next_alive = np.ones((T, 3), bool)
    next_alive[DEATH:END + 1, 2] = False
    if result == "loss":
        next_alive[END] = False  # the last two die in the game's last step
    next_value = V[1:].copy()
    next_value[END] = V_FINAL
    death_value = np.full(T, -99.0, np.float32)  # read only where a player died
    death_value[DEATH] = V_DEATH
    done = np.arange(T) == END
    won, lost = done & (result == "win"), done & (result == "loss")
    as_arena = lambda x: jnp.asarray(x)[:, None]
    return tuple(map(as_arena, (R, next_value, death_value, done, won, lost, alive, next_alive)))


def reference_returns(result: str) -> np.ndarray:
    """``float32[T, P]``: every agent trajectory of the window through ``ml_agents_lambda_return``."""
    out = np.full((T, 3), np.nan, np.float32)
    interrupted = result != "loss"  # GroupEpisodeInterrupted reaches the players still alive
    for i in (0, 1):  # alive to the end: one trajectory to the game's end, then the next game's
        out[:END + 1, i] = ml_agents_lambda_return(R[:END + 1], V[:END + 1], V_FINAL if interrupted else 0.0)
    # Player 2 died in step 2 while its teammates fought on: done, not interrupted, but its group is
    # not all done, so it bootstraps from its last observation with its teammates' (V_DEATH).
    out[:DEATH + 1, 2] = ml_agents_lambda_return(R[:DEATH + 1], V[:DEATH + 1], V_DEATH)
    for i in range(3):  # the next game, cut by the window (time horizon): bootstrap from V(s_8)
        out[END + 1:, i] = ml_agents_lambda_return(R[END + 1:], V[END + 1:], V[T])
    return out


@pytest.mark.parametrize("result", ["win", "loss", "timeout"])
def test_reference_ends_equal_ml_agents_on_a_hand_made_game(result):
    args = game(result)
    g = np.asarray(jax.jit(game_returns, static_argnums=0)("reference", *args, GAMMA, LAM))[:, 0]
    alive = np.asarray(args[6])[:, 0]
    expect = reference_returns(result)
    np.testing.assert_allclose(g[alive], expect[alive], rtol=1e-5)
    # The three endings differ only in the last step's bootstrap: a win as a timeout, a loss none.
    assert g[END, 0] == pytest.approx(R[END] + (GAMMA * V_FINAL if result != "loss" else 0.0))


def test_a_win_is_terminal_only_under_terminal_ends():
    args = game("win")
    run = jax.jit(game_returns, static_argnums=0)
    g_term = np.asarray(run("terminal", *args, GAMMA, LAM))[:, 0]
    g_win = np.asarray(run("win_bootstrapped", *args, GAMMA, LAM))[:, 0]
    assert g_term[END, 0] == pytest.approx(R[END])  # worth its reward, nothing after
    assert g_win[END, 0] == pytest.approx(R[END] + GAMMA * V_FINAL)
    # Both give every player the group's return: player 2's last action is credited with what the
    # team earns after its death (posthumous credit), not cut at its death as under "reference".
    np.testing.assert_array_equal(g_win[:, 2], g_win[:, 0])
    g_ref = np.asarray(run("reference", *args, GAMMA, LAM))[:, 0]
    assert g_ref[DEATH, 2] == pytest.approx(R[DEATH] + GAMMA * V_DEATH)
    assert g_win[DEATH, 2] != pytest.approx(g_ref[DEATH, 2])
    # A loss is terminal in all three.
    for ends in ("terminal", "win_bootstrapped", "reference"):
        g = np.asarray(run(ends, *game("loss"), GAMMA, LAM))[:, 0]
        assert g[END, 0] == pytest.approx(R[END])


def test_group_lambda_returns_by_hand():
    # Two arenas: arena 0 is cut (bootstraps) at t=1, arena 1 ends terminally there.
    r = jnp.array([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0], [4.0, 4.0]])
    v_next = jnp.array([[10.0, 10.0], [20.0, 20.0], [30.0, 30.0], [40.0, 40.0]])
    end = jnp.array([[0, 0], [1, 1], [0, 0], [0, 0]], bool)
    term = jnp.array([[0, 0], [0, 1], [0, 0], [0, 0]], bool)
    g = np.asarray(lambda_returns(r, v_next, end, term, 0.5, 0.5))
    # t=3 (window end): 4 + .5*40 = 24; t=2: 3 + .5*(.5*30 + .5*24) = 16.5; arena 0, t=1: 2 + .5*20 = 12;
    # t=0: 1 + .5*(.5*10 + .5*12) = 6.5; arena 1, t=1: 2; t=0: 1 + .5*(.5*10 + .5*2) = 4
    np.testing.assert_allclose(g[:, 0], [6.5, 12.0, 16.5, 24.0])
    np.testing.assert_allclose(g[:, 1], [4.0, 2.0, 16.5, 24.0])


def test_value_loss_rows():
    """``value_rows="agents"`` regresses V onto each live agent's return, averaged over agent
    experiences (ML-Agents' buffer rows); ``"decisions"`` onto the group's, averaged over decisions."""
    import raidjax

    params = raidjax.make_params(skill_range=13.0)
    obs, _ = jax.vmap(raidjax.reset, in_axes=(0, None))(jax.random.split(jax.random.PRNGKey(0), 2), params)
    alive = jnp.array([[True, True, True], [True, False, False]])
    obs = obs.replace(alive=alive)
    actor, critic = Actor(8, 1, 2, False), Critic(8, 1, 2)
    actions = jnp.zeros((2, 3), jnp.int32)
    w = {"actor": actor.init(jax.random.PRNGKey(1), obs), "critic": critic.init(jax.random.PRNGKey(2), obs, actions)}
    logp = jnp.zeros((2, 3))
    v, b = critic.apply(w["critic"], obs, actions)
    returns = jnp.array([[1.0, 2.0, 3.0], [4.0, 9.0, 9.0]])  # dead players' columns are never read
    batch = Batch(obs, actions, logp, alive, v, b, returns, jnp.zeros((2, 3)))
    _, aux = loss_fn(w, batch, actor, critic, 0.2, 0.0, "agents")
    v = np.asarray(v)
    expect = ((v[0] - 1) ** 2 + (v[0] - 2) ** 2 + (v[0] - 3) ** 2 + (v[1] - 4) ** 2) / 4
    np.testing.assert_allclose(float(aux["value_loss"]), expect, rtol=1e-5)
    _, aux = loss_fn(w, batch, actor, critic, 0.2, 0.0, "decisions")
    np.testing.assert_allclose(float(aux["value_loss"]), ((v[0] - 1) ** 2 + (v[1] - 4) ** 2) / 2, rtol=1e-5)


def test_a_player_dying_in_the_winning_step_does_not_bootstrap():
    # ML-Agents marks every agent of a game's last step done before it processes any, so a player
    # who died in it (done, not interrupted) has its whole group done: its bootstrap is zeroed,
    # while its teammates (interrupted) bootstrap.
    reward, next_value, death_value, done, won, lost, alive, next_alive = game("win")
    next_alive = next_alive.at[END, 0, 0].set(False)  # [T, N, P]: player 0 of the one arena
    g = np.asarray(game_returns("reference", reward, next_value, death_value.at[END].set(5.0), done, won, lost,
                                alive, next_alive, GAMMA, LAM))[:, 0]
    assert g[END, 0] == pytest.approx(R[END])
    assert g[END, 1] == pytest.approx(R[END] + GAMMA * V_FINAL)


def test_a_dying_player_is_seen_as_before_its_death():
    import raidjax

    params = raidjax.make_params(observation="reference", action_space="reference")
    obs, _ = jax.vmap(raidjax.reset, in_axes=(0, None))(jax.random.split(jax.random.key(0), 2), params)
    final = jax.tree.map(lambda x: x * 0 if x.dtype == jnp.float32 else x, obs)
    final = final.replace(alive=final.alive.at[0, 1].set(False))
    seen = last_seen(obs, final)
    np.testing.assert_array_equal(np.asarray(seen.alive), np.asarray(final.alive))
    earlier = obs.replace(alive=final.alive)  # the alive mask is the one after the step
    for before, after, got in zip(jax.tree.leaves(earlier), jax.tree.leaves(final), jax.tree.leaves(seen),
                                  strict=True):
        np.testing.assert_array_equal(np.asarray(got[0, 1]), np.asarray(before[0, 1]))  # died: as before
        np.testing.assert_array_equal(np.asarray(got[1]), np.asarray(after[1]))  # the rest: as after
        np.testing.assert_array_equal(np.asarray(got[0, 0]), np.asarray(after[0, 0]))
