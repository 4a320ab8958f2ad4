"""Batched playtesting and the scripted policies (GAME.md §9).

Few compilations of ``playtest`` (each costs seconds): the reference games chained two per arena,
per-game params, per-group params chained four per arena. The per-game and per-group contents are
chosen so that every game's outcome is certain:
WIN: the boss has 1 HP and does no damage; LOSS: players have 1 HP and do no damage;
DRAW: nobody can hurt anybody (ends at ``max_decisions``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import ACTION_HEURISTIC, RESET

import raidjax
from raidjax import policies
from raidjax.types import HALF_ARENA, EnvConfig

N = 4
GPA = 2  # the reference games: two measured games per arena, after each arena's warm-up game
GAMES = {"n_games": N, "games_per_arena": GPA}
SHORT = EnvConfig(max_decisions=200)
HARMLESS_BOSS = {"skill1.coefficient": 0.0, "skill2.coefficient": 0.0}
WIN = raidjax.make_params(config=SHORT, boss_overrides={"max_hp": 1, **HARMLESS_BOSS})
LOSS = raidjax.make_params(config=SHORT, max_hp=1, **{"skill1.coefficient": 0.0})
DRAW = raidjax.make_params(config=SHORT, boss_overrides=HARMLESS_BOSS, **{"skill1.coefficient": 0.0})


def stack(*trees):
    return jax.tree.map(lambda *x: jnp.stack(x), *trees)


@pytest.fixture(scope="module")
def reference_results(ref_params):
    return jax.device_get(raidjax.playtest(jax.random.key(0), ref_params, policies.heuristic, **GAMES))


def test_reference_playtest_results_are_consistent(reference_results):
    """The reference content's games (range 5, PT-HR), chained as the reference's arenas play them."""
    r = reference_results
    assert set(r) == {"outcome", "length", "damage", "back_attacks", "deaths", "alive", "dropped", "boss_hp",
                      "boss_recharging", "in_flight", "position"}
    assert r["position"].tolist() == [0, 1, 0, 1]  # game a * k + j is arena a's j-th measured game
    assert r["outcome"].shape == (N,) and r["damage"].shape == (N, 3) and r["alive"].shape == (N, 3)
    assert set(r["outcome"].tolist()) <= {1, 2}  # every reference game ends by a win or a loss
    assert (r["length"] < 2000).all() and (r["length"] > 0).all()  # ended early
    assert (r["dropped"] == 0).all()  # the pool never overflows in the reference setting
    np.testing.assert_array_equal(r["deaths"], 3 - r["alive"].sum(-1))
    np.testing.assert_array_equal(r["outcome"] == 2, r["deaths"] == 3)
    np.testing.assert_array_equal(r["outcome"] == 1, r["boss_hp"] <= 0)
    lost = r["outcome"] != 1
    # Damage to the boss adds up to the HP it lost; hits are 50 (front) or 60 (back).
    np.testing.assert_allclose(r["damage"].sum(-1)[lost], (1000.0 - r["boss_hp"])[lost])
    back = r["back_attacks"].sum(-1)
    assert ((r["damage"].sum(-1) - 60 * back) % 50 == 0).all()


def test_win_rate_is_mean_of_outcomes(reference_results):
    r = reference_results
    assert float(raidjax.win_rate(r)) == pytest.approx(float(np.mean(r["outcome"] == 1)))
    fake = {"outcome": jnp.array([1, 2, 3, 1, 1])}
    assert float(raidjax.win_rate(fake)) == pytest.approx(0.6)  # draws count as losses


def test_playtest_is_deterministic_per_key(ref_params, reference_results):
    again = jax.device_get(raidjax.playtest(jax.random.key(0), ref_params, policies.heuristic, **GAMES))
    for k in again:
        np.testing.assert_array_equal(again[k], reference_results[k])


def test_per_game_params():
    r = jax.device_get(raidjax.playtest(jax.random.key(1), stack(WIN, LOSS, DRAW, WIN), policies.heuristic, N))
    assert r["outcome"].tolist() == [1, 2, 3, 1]
    assert r["length"][2] == 200  # the draw runs to max_decisions
    assert (r["length"][[0, 1, 3]] < 200).all()
    assert r["boss_hp"][2] == 1000.0 and r["deaths"][2] == 0


def test_per_group_params_chained_in_their_arenas():
    """Three contents of four games each, four games per arena (``games_per_arena=4``): game ``g``
    uses content ``g // 4`` and arena ``g // 4`` plays it four times in a row, every game recorded as
    it ended; a draw content makes each of its games run to ``max_decisions`` (a game is recorded
    only once it ended, and the next starts afresh)."""
    r = jax.device_get(raidjax.playtest(jax.random.key(2), stack(WIN, LOSS, DRAW), policies.heuristic, 12,
                                        games_per_arena=4))
    assert r["outcome"].tolist() == [1] * 4 + [2] * 4 + [3] * 4
    assert (r["length"][:8] > 0).all() and (r["length"][:8] < 200).all() and r["length"][8:].tolist() == [200] * 4
    np.testing.assert_array_equal(r["deaths"], 3 - r["alive"].sum(-1))


@pytest.mark.parametrize("k, why", [(0, "whole number >= 1"), (3, "does not divide the 4 games"),
                                    (2.5, "whole number"), (True, "whole number")])
def test_games_per_arena_is_checked_before_compiling(k, why):
    with pytest.raises(ValueError, match="games_per_arena") as err:
        raidjax.playtest(jax.random.key(0), stack(WIN, LOSS), policies.heuristic, 8, games_per_arena=k)
    assert why.split()[0] in str(err.value)


def test_win_rate_by_position_groups_games_by_their_place_in_the_chain():
    fake = {"outcome": jnp.array([1, 2, 1, 1, 3, 1]), "position": jnp.array([0, 1, 2, 0, 1, 2])}
    np.testing.assert_allclose(raidjax.win_rate_by_position(fake), [1.0, 0.0, 1.0])
    groups = {k: v.reshape(2, 3) for k, v in fake.items()}  # playtest_groups' [G, n_games]
    np.testing.assert_allclose(raidjax.win_rate_by_position(groups), [1.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="results: "):
        raidjax.win_rate_by_position({"outcome": fake["outcome"]})


def test_default_games_per_arena_is_the_one_protocol():
    """Without ``games_per_arena`` a playtest chains ``auto_games_per_arena`` games of each content per
    arena (checked on the host, before anything compiles)."""
    from raidjax.playtest import auto_games_per_arena, check_games_per_arena
    assert check_games_per_arena(WIN, 1000, None) == auto_games_per_arena(1000) == 10
    assert check_games_per_arena(stack(WIN, LOSS), 600, None) == auto_games_per_arena(300) == 10
    assert check_games_per_arena(stack(WIN, LOSS, DRAW, WIN), 4, None) == 1  # one game per content
    assert check_games_per_arena(WIN, 8, 2) == 2


def test_auto_games_per_arena_divides():
    from raidjax.playtest import auto_games_per_arena
    assert [auto_games_per_arena(n) for n in (1000, 300, 8, 7, 1, 4096)] == [10, 10, 8, 7, 1, 8]


# --- policies ------------------------------------------------------------------------------

RANDOM = jax.jit(jax.vmap(policies.random, in_axes=(0, None, None, None)))


def test_random_policy_is_uniform_over_moves_and_own_cast_slots(ref_params):
    obs, s = RESET(jax.random.key(0), ref_params)
    a = np.asarray(RANDOM(jax.random.split(jax.random.key(3), 4000), obs, s, ref_params))
    assert a.min() == 0 and a.max() == 7  # 0-7 for the reference mage (one skill slot)
    freq = np.bincount(a.ravel(), minlength=8) / a.size
    np.testing.assert_allclose(freq, 1 / 8, atol=0.02)
    # A unit with three active slots: 0-9.
    bm = raidjax.make_params(players="battle_mage")
    b = np.asarray(RANDOM(jax.random.split(jax.random.key(4), 4000), obs, s, bm))
    np.testing.assert_allclose(np.bincount(b.ravel(), minlength=10) / b.size, 1 / 10, atol=0.02)
    # Passive slots are not actions (priest: heal, holy bolt, passive renew -> 0-8).
    pr = raidjax.make_params(players="priest")
    c = np.asarray(RANDOM(jax.random.split(jax.random.key(5), 2000), obs, s, pr))
    assert c.max() == 8


def test_heuristic_and_noop_policies(ref_params):
    obs, s = RESET(jax.random.key(0), ref_params)
    assert policies.heuristic(jax.random.key(0), obs, s, ref_params).tolist() == [ACTION_HEURISTIC] * 3
    assert policies.noop(jax.random.key(0), obs, s, ref_params).tolist() == [0, 0, 0]


def test_script_and_or_heuristic_choose_their_team_by_data_in_one_program(ref_params, reference_results):
    """``policies.script`` (index 0: PT-HR, 1: PT-RD) and ``policies.OrHeuristic`` (a policy with
    weights, or PT-HR) choose by a traced argument: decision by decision they return the chosen
    team's actions, and ``OrHeuristic(script)`` plays the fixture's PT-HR games game for game when
    told to play PT-HR, and PT-RD's games otherwise, from one compiled program."""
    from raidjax.playtest import _playtest

    both = policies.OrHeuristic(policies.script)
    obs, s = RESET(jax.random.key(0), ref_params)
    for k in range(8):
        key = jax.random.key(k)
        rd, hr = policies.random(key, obs, s, ref_params), policies.heuristic(key, obs, s, ref_params)
        np.testing.assert_array_equal(policies.script(jnp.int32(1), key, obs, s, ref_params), rd)
        np.testing.assert_array_equal(policies.script(jnp.int32(0), key, obs, s, ref_params), hr)
        np.testing.assert_array_equal(both(both.weights(jnp.int32(1), False), key, obs, s, ref_params), rd)
        np.testing.assert_array_equal(both(both.weights(jnp.int32(1), True), key, obs, s, ref_params), hr)
    before = _playtest._cache_size()
    scripted = jax.device_get(raidjax.playtest(jax.random.key(0), ref_params, both, **GAMES,
                                               weights=both.weights(jnp.int32(1), True)))
    random_team = jax.device_get(raidjax.playtest(jax.random.key(0), ref_params, both, **GAMES,
                                                  weights=both.weights(jnp.int32(1), False)))
    assert _playtest._cache_size() == before + 1
    assert not np.array_equal(random_team["length"], scripted["length"])  # PT-RD's games are not PT-HR's
    for name in scripted:  # told to play PT-HR: the fixture's PT-HR games, bit for bit
        np.testing.assert_array_equal(scripted[name], reference_results[name], err_msg=name)


def test_playtest_accepts_raw_and_typed_keys(ref_params, reference_results):
    """A legacy ``PRNGKey`` (uint32[2]) and a typed key give the same games (same stream), and
    share one compiled program (the raw key is wrapped before the program)."""
    from raidjax.playtest import _playtest

    compiled = _playtest._cache_size()
    raw = jax.device_get(raidjax.playtest(jax.random.PRNGKey(0), ref_params, policies.heuristic, **GAMES))
    for k in reference_results:
        np.testing.assert_array_equal(raw[k], reference_results[k], err_msg=k)
    assert _playtest._cache_size() == compiled


def test_playtest_occupancy_counts_spawn_cells_of_a_standing_team():
    """Players that never move occupy only their spawn cells: each player's map is the
    histogram of its spawn cells over the games, as computed directly from ``reset``."""
    n, bins = 8, 24
    key = jax.random.key(5)
    occ = np.asarray(raidjax.playtest_occupancy(key, DRAW, policies.noop, n, bins=bins))
    assert occ.shape == (3, bins, bins)
    np.testing.assert_allclose(occ.sum((1, 2)), 1.0, rtol=1e-5)
    # playtest's reset stream: the first half of split(key)
    _, state = jax.vmap(raidjax.reset, in_axes=(0, None))(jax.random.split(jax.random.split(key)[0], n), DRAW)
    half = HALF_ARENA
    cells = np.clip(np.floor((np.asarray(state.pos[:, :3]) + half) / (2 * half) * bins).astype(int), 0, bins - 1)
    for p in range(3):
        expect = np.zeros((bins, bins))
        np.add.at(expect, (cells[:, p, 0], cells[:, p, 1]), 1.0 / n)
        np.testing.assert_allclose(occ[p], expect, atol=1e-6)


def switched(weights, key, obs, state, params):
    """A policy with weights: PT-HR where ``weights["on"]`` is true, standing still otherwise."""
    return jnp.where(weights["on"], policies.heuristic(key, obs, state, params), policies.noop(key, obs, state, params))


def test_policy_with_weights_plays_as_bound_and_compiles_once(ref_params, reference_results):
    from raidjax.playtest import _playtest

    before = _playtest._cache_size()
    on, off = (jax.device_get(raidjax.playtest(jax.random.key(0), ref_params, switched, weights={"on": jnp.bool_(b)},
                                               **GAMES)) for b in (True, False))
    assert (off["damage"] == 0).all() and (off["outcome"] != 1).all()  # a team standing still hurts nobody
    assert (on["damage"] > 0).any()
    assert _playtest._cache_size() == before + 1  # the second weights reused the program
    for name in on:  # the fixture's plain PT-HR games, game for game
        np.testing.assert_array_equal(on[name], reference_results[name], err_msg=name)
    # record_episode with weights equals the bound policy too.
    key = jax.random.key(3)
    trace_w, _ = raidjax.logs.record_episode(key, LOSS, switched, 12, weights={"on": jnp.bool_(True)})
    trace_p, _ = raidjax.logs.record_episode(key, LOSS, policies.heuristic, 12)
    np.testing.assert_array_equal(trace_w.pos, trace_p.pos)
    with pytest.raises(ValueError, match="weights"):
        raidjax.playtest(key, LOSS, switched, N, weights={"on": "yes"})
