"""The functional API (env.reset / step / step_autoreset): shapes, dtypes, info, outcomes,
done-freezing, autoreset, jit vs eager, vmap, params batching, determinism and lax.scan."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from helpers import ACTION_HEURISTIC, BOSS, CAST_1, KEY, NOOP, RESET, STEP, T_ROLL, acts, make, rollout, run, scenario

import raidjax
from raidjax.types import FORWARD, N_ACTIONS, PROJ_STRAIGHT

INFO_KEYS = {"terminated", "truncated", "result", "alive", "damage_dealt", "back_attack"}
VSTEP = jax.jit(jax.vmap(raidjax.step))
AUTORESET = jax.jit(raidjax.step_autoreset)
VRESET = jax.jit(jax.vmap(raidjax.reset))
HR = acts(ACTION_HEURISTIC)


def assert_trees_equal(a, b, atol=0.0):
    la, ta = jax.tree.flatten(a)
    lb, tb = jax.tree.flatten(b)
    assert ta == tb
    for x, y in zip(la, lb, strict=True):
        x, y = np.asarray(x), np.asarray(y)
        assert x.shape == y.shape and x.dtype == y.dtype
        if atol and np.issubdtype(x.dtype, np.floating):
            np.testing.assert_allclose(x, y, atol=atol, rtol=1e-5)
        else:
            np.testing.assert_array_equal(x, y)


def mid_fight(params=None):
    """Reference content, players close to the boss, a few decisions of PT-HR: casts, live missiles."""
    p = params if params is not None else raidjax.make_params()
    s = scenario(p, players=((-3, -4), (0, -4.5), (3, -4)), boss=(0.0, 0.0))
    s, _ = run(s, p, HR, 6)
    return p, s


def test_reset_and_step_shapes_dtypes_and_info(ref_params):
    obs, s = RESET(KEY, ref_params)
    expected = {
        "self_features": ((3, 10 + 5 * 3), jnp.float32), "boss": ((3, 11), jnp.float32),
        "teammates": ((3, 2, 7 + 3 * 3), jnp.float32), "teammate_mask": ((3, 2), jnp.bool_),
        "projectiles": ((3, 4, 6), jnp.float32), "projectile_mask": ((3, 4), jnp.bool_),
        "walls": ((3, 4), jnp.float32), "action_mask": ((3, N_ACTIONS), jnp.bool_), "alive": ((3,), jnp.bool_),
    }
    for name, (shape, dtype) in expected.items():
        x = getattr(obs, name)
        assert x.shape == shape and x.dtype == dtype, name
    d = 25 + 11 + 2 * 16 + 2 + 4 * 6 + 4 + 4 + N_ACTIONS
    assert obs.flat().shape == (3, d) and obs.flat().dtype == jnp.float32
    assert s.pos.shape == (4, 2) and s.hp.dtype == jnp.float32 and s.charges.dtype == jnp.int32
    assert s.projectiles.live.shape == (ref_params.config.max_projectiles,)
    obs2, s2, reward, done, info = STEP(KEY, s, acts(NOOP), ref_params)
    assert_trees_equal(jax.tree.map(lambda x: x.shape, obs2), jax.tree.map(lambda x: x.shape, obs))
    assert jax.tree.structure(s2) == jax.tree.structure(s)
    assert reward.shape == (3,) and reward.dtype == jnp.float32
    assert done.shape == () and done.dtype == jnp.bool_
    assert set(info) == INFO_KEYS
    assert info["terminated"].dtype == jnp.bool_ and info["truncated"].dtype == jnp.bool_
    assert info["result"].dtype == jnp.int32 and info["alive"].shape == (3,)
    assert info["damage_dealt"].shape == (3,) and info["back_attack"].shape == (3,)
    assert info["back_attack"].dtype == jnp.int32
    assert int(s2.decision) == 1 and int(info["result"]) == 0 and not bool(done)


def test_reset_spawns(ref_params):
    _, s = RESET(KEY, ref_params)
    np.testing.assert_allclose(np.asarray(s.pos), [[-3, -10], [0, -10], [3, -10], [0, 8]])
    np.testing.assert_allclose(np.cos(np.asarray(s.heading)), 0.0, atol=1e-6)
    np.testing.assert_allclose(np.sin(np.asarray(s.heading)), [1, 1, 1, -1], atol=1e-6)
    np.testing.assert_allclose(np.asarray(s.hp), [100, 100, 100, 1000])
    assert bool(s.alive.all()) and int(s.result) == 0


def win_next_decision():
    """One instant hit (decision 1) kills the boss at 50 HP; player 2 is dead."""
    p = make(**{"skill1.projectile_speed": 0.0, "skill1.cast_time": 0.0})
    s = scenario(p, players=((0, -4), (1, -4), (11, -11)), boss=(0, 0), alive=(True, True, False),
                 hp=(None, None, None, 50.0))
    return p, s


def test_win_terminates_and_pays_group_reward_to_every_player():
    p, s = win_next_decision()
    _, s2, reward, done, info = STEP(KEY, s, acts(CAST_1, NOOP, NOOP), p)
    assert bool(done) and int(info["result"]) == 1
    assert bool(info["terminated"]) and not bool(info["truncated"])
    np.testing.assert_allclose(np.asarray(reward), [0.5 + 1.0, 1.0, 1.0], atol=1e-6)  # dead player too
    np.testing.assert_array_equal(np.asarray(info["alive"]), [True, True, False])


def test_done_freezes_state_and_pays_nothing():
    p, s = win_next_decision()
    _, s2, _, _, _ = STEP(KEY, s, acts(CAST_1, NOOP, NOOP), p)
    for a in (acts(FORWARD), acts(CAST_1), HR):
        _, s3, reward, done, info = STEP(jax.random.key(9), s2, a, p)
        assert_trees_equal(s3, s2)
        assert bool(done) and int(info["result"]) == 1
        np.testing.assert_array_equal(np.asarray(reward), 0.0)
        np.testing.assert_array_equal(np.asarray(info["damage_dealt"]), 0.0)


def test_a_game_that_ends_inside_a_decision_stops_its_projectiles_there():
    """Five sub-steps; the boss dies in the first (an instant hit fired at once). A straight missile
    in flight, far from everyone, flies that sub-step (0.02 s at 20 units/s) and no further: an ended
    game's pool stands still for the rest of the decision, as the rest of its state does."""
    cfg = raidjax.EnvConfig.from_rules("clean", n_substeps=5)
    p = make(config=cfg, **{"skill1.projectile_speed": 0.0, "skill1.cast_time": 0.0})
    s = scenario(p, players=((0, -4), (1, -4), (11, -11)), boss=(0, 0), alive=(True, True, False),
                 hp=(None, None, None, 50.0))
    pr = s.projectiles
    s = s.replace(projectiles=pr.replace(
        live=pr.live.at[0].set(True), kind=pr.kind.at[0].set(PROJ_STRAIGHT), owner=pr.owner.at[0].set(BOSS),
        slot=pr.slot.at[0].set(0), pos=pr.pos.at[0].set(jnp.array([-5.0, 12.0])),
        direction=pr.direction.at[0].set(jnp.array([-1.0, 0.0])), life=pr.life.at[0].set(5.0)))
    assert float(p.skills.projectile_speed[BOSS, 0]) == 20.0
    _, s2, _, done, info = STEP(KEY, s, acts(CAST_1, NOOP, NOOP), p)
    assert bool(done) and int(info["result"]) == 1
    assert bool(s2.projectiles.live[0])
    np.testing.assert_allclose(np.asarray(s2.projectiles.pos[0]), [-5.0 - 20.0 * 0.02, 12.0], rtol=1e-6)
    np.testing.assert_allclose(float(s2.projectiles.life[0]), 5.0 - 0.02, rtol=1e-6)
    _, s3, _, _, _ = STEP(jax.random.key(9), s2, acts(CAST_1), p)  # and through a whole ended decision
    assert_trees_equal(s3, s2)


def test_draw_is_a_truncation_at_the_decision_limit(ref_params):
    p = make()
    s = scenario(p, players=((0, -4), (1, -4), (-1, -4)), boss=(0, 0))
    limit = p.config.max_decisions
    s = s.replace(decision=jnp.int32(limit - 2))
    _, s1, _, done1, info1 = STEP(KEY, s, acts(NOOP), p)
    assert not bool(done1) and int(info1["result"]) == 0
    _, s2, reward, done2, info2 = STEP(KEY, s1, acts(NOOP), p)
    assert int(s2.decision) == limit == 2000
    assert bool(done2) and int(info2["result"]) == 3
    assert bool(info2["truncated"]) and not bool(info2["terminated"])
    np.testing.assert_array_equal(np.asarray(reward), 0.0)  # no time penalty


def test_dead_players_stay_dead_and_their_actions_are_ignored():
    p = make(hp_regen=50.0)
    s = scenario(p, players=((0, -4), (1, -4), (-1, -4)), boss=(0, 0), alive=(True, False, True))
    out, hist = run(s, p, acts(FORWARD, CAST_1, CAST_1), 12)
    assert not bool(out.alive[1]) and float(out.hp[1]) == 0.0  # no regeneration, no respawn
    np.testing.assert_allclose(np.asarray(out.pos[1]), [1, -4])
    assert not any(h["state"].casting[1].any() for h in hist)
    assert int(np.asarray(out.projectiles.owner)[np.asarray(out.projectiles.live)].tolist().count(1)) == 0
    assert hist[-1]["obs"].action_mask[1].tolist() == [True] + [False] * (N_ACTIONS - 1)
    assert float(out.damage_dealt[1]) == 0.0 and float(out.damage_dealt[2]) > 0.0


def test_step_autoreset_keeps_final_observation():
    p, s = win_next_decision()
    key = jax.random.key(4)
    k_step, k_reset = jax.random.split(key)
    obs, s2, reward, done, info = AUTORESET(key, s, acts(CAST_1, NOOP, NOOP), p)
    want_obs, want_state, want_reward, _, _ = STEP(k_step, s, acts(CAST_1, NOOP, NOOP), p)
    reset_obs, reset_state = RESET(k_reset, p)
    assert bool(done) and int(info["final_result"]) == 1
    assert_trees_equal(info["final_observation"], want_obs, atol=1e-6)
    assert_trees_equal(obs, reset_obs, atol=1e-6)
    assert_trees_equal(s2, reset_state, atol=1e-6)
    np.testing.assert_allclose(np.asarray(reward), np.asarray(want_reward))
    assert int(s2.decision) == 0 and float(s2.hp[BOSS]) == 1000.0
    # Not done: the step's own observation and state.
    obs, s3, _, done, info = AUTORESET(key, s, acts(NOOP), p)
    want_obs, want_state, _, _, _ = STEP(k_step, s, acts(NOOP), p)
    assert not bool(done)
    assert_trees_equal(info["final_observation"], obs)
    assert_trees_equal(s3, want_state, atol=1e-6)


def test_jit_and_eager_agree():
    """A decision of a fight in progress (the boss casting, three missiles in flight that hit it, a
    cast request, a move, PT-HR): every output of the eager step equals the jitted one's. An eager
    step takes about 25 s here (every operation dispatched and compiled on its own), hence one."""
    p, s = mid_fight()
    assert int(s.projectiles.live.sum()) == 3 and bool(s.casting[-1].any())
    a = acts(ACTION_HEURISTIC, CAST_1, FORWARD)
    key = jax.random.key(11)
    jitted = STEP(key, s, a, p)
    with jax.disable_jit():
        eager = raidjax.step(key, s, a, p)
    assert_trees_equal(jitted, eager, atol=1e-5)
    assert float(jitted[4]["damage_dealt"].sum()) > 0  # missiles hit the boss


def test_same_key_same_result_and_reset_key_matters(ref_params):
    p, s = mid_fight()
    a1 = STEP(jax.random.key(5), s, HR, p)
    a2 = STEP(jax.random.key(5), s, HR, p)
    assert_trees_equal(a1, a2)
    signs = {tuple(np.asarray(RESET(jax.random.key(k), ref_params)[1].orbit_sign[:3]).tolist()) for k in range(8)}
    assert len(signs) > 1  # PT-HR's coin flips come from the reset key


def stacked(trees):
    return jax.tree.map(lambda *x: jnp.stack(x), *trees)


def test_vmap_over_arenas_with_different_params_matches_single_steps():
    contents = [raidjax.make_params(skill_range=r, **extra)
                for r, extra in ((5.0, {}), (13.0, {"armor": 30}), (9.0, {"skill1.cool_time": 1.0}))]
    batch_p = raidjax.validate_params(stacked(contents))
    assert batch_p.team.shape == (3, 4) and batch_p.skills.range.shape == (3, 4, 3)
    states = [mid_fight(c)[1] for c in contents]
    keys = jax.random.split(jax.random.key(2), 3)
    actions = jnp.stack([HR, acts(CAST_1, NOOP, FORWARD), acts(NOOP)])
    out = jax.device_get(VSTEP(keys, stacked(states), actions, batch_p))  # host-side indexing below
    for i in range(3):
        single = STEP(keys[i], states[i], actions[i], contents[i])
        assert_trees_equal(jax.tree.map(lambda x, i=i: x[i], out), single, atol=1e-5)
    # Batched reset with the stacked params.
    obs, s0 = VRESET(keys, batch_p)
    assert s0.pos.shape == (3, 4, 2) and obs.self_features.shape[:2] == (3, 3)
    np.testing.assert_allclose(np.asarray(obs.self_features[:, 0, 16]), [5 / 20, 13 / 20, 9 / 20], atol=1e-6)


def test_lax_scan_rollout_matches_python_loop_and_compiles_once():
    p, s = mid_fight()
    rng = np.random.default_rng(0)
    actions = jnp.asarray(rng.integers(0, 8, (T_ROLL, 3)), jnp.int32).at[:, 0].set(ACTION_HEURISTIC)
    key = jax.random.key(21)
    final, (rewards, dones, results, finite) = rollout(key, s, p, actions)
    loop = s
    total = np.zeros(3)
    for t in range(1, T_ROLL + 1):
        _, loop, r, _, _ = STEP(jax.random.fold_in(key, t), loop, actions[t - 1], p)
        total += np.asarray(r)
    assert_trees_equal(final, loop, atol=1e-4)
    np.testing.assert_allclose(np.asarray(rewards).sum(0), total, atol=1e-4)
    assert bool(finite.all())
    # Other content values and keys: no retrace (chex.assert_max_traces(n=1) would raise), and
    # no new compilation of ``step`` (one per EnvConfig the suite uses).
    compiled = STEP._cache_size()
    p2 = raidjax.make_params(skill_range=17.0, armor=20, **{"skill1.cast_time": 1.0})
    rollout(jax.random.key(22), s, p2, actions)
    rollout(key, loop, p, actions)
    STEP(key, loop, actions[0], p2)
    assert STEP._cache_size() == compiled



def test_random_spawns_draw_positions_and_headings_in_each_half_and_keep_other_draws():
    fixed = raidjax.make_params(skill_range=13.0)
    drawn = raidjax.make_params(skill_range=13.0, config=raidjax.EnvConfig(random_spawns=True))
    keys = jax.random.split(KEY, 64)
    _, s = jax.jit(jax.vmap(raidjax.reset, (0, None)))(keys, drawn)
    pos, heading = np.asarray(s.pos), np.asarray(s.heading)
    lim = raidjax.types.HALF_ARENA - np.asarray(drawn.stats.radius)
    assert (np.abs(pos) <= lim[None, :, None] + 1e-6).all()
    assert (pos[:, :-1, 1] <= 0).all() and (pos[:, -1, 1] >= 0).all()
    assert len(np.unique(pos.round(4).reshape(64, -1), axis=0)) == 64  # every episode opens elsewhere
    assert ((heading >= -np.pi) & (heading < np.pi)).all() and heading.std() > 1.0
    # Each key's spawn spreads over the half: players reach both sides of x = 0 and deep into y < -6.
    assert (pos[:, :-1, 0] < -6).any() and (pos[:, :-1, 0] > 6).any() and (pos[:, :-1, 1] < -6).any()
    # The option touches only positions and headings: the other draws of reset are the same.
    _, f = jax.vmap(raidjax.reset, (0, None))(keys, fixed)
    np.testing.assert_array_equal(np.asarray(f.orbit_sign), np.asarray(s.orbit_sign))
    np.testing.assert_array_equal(np.asarray(f.clock), np.asarray(s.clock))
    assert not np.allclose(np.asarray(f.pos), pos)
    # The target is the nearest player from the drawn spawns.
    d = np.linalg.norm(pos[:, :-1] - pos[:, -1:], axis=-1)
    np.testing.assert_array_equal(np.asarray(s.target)[:, -1], d.argmin(-1))


def test_programs_around_the_game_trace_its_sub_step_once(monkeypatch):
    """``raidjax.utils.traced_once``: a second program that plays the same arenas (here a scan of
    ``step_autoreset``, after a plain vmapped ``step``) reuses the traced sub-step."""
    from raidjax import phases

    traced = []
    real = phases.substep
    monkeypatch.setattr(phases, "substep", lambda *a: traced.append(1) or real(*a))
    n = 19  # an arena count no other test plays (grouped PCG measurements included): traced here first
    p = jax.tree.map(lambda x: jnp.broadcast_to(x, (n,) + x.shape), raidjax.make_params())
    keys = jax.random.split(KEY, n)
    _, s = jax.vmap(raidjax.reset)(keys, p)
    a = jnp.zeros((n, 3), jnp.int32)
    jax.jit(jax.vmap(raidjax.step)).lower(keys, s, a, p)
    first = len(traced)
    assert first == 1  # the lane program only: one arena's sub-step is traced where it runs unbatched

    def scan(s):
        return jax.lax.scan(lambda s, _: (jax.vmap(raidjax.step_autoreset)(keys, s, a, p)[1], None), s, None, 3)[0]

    jax.jit(scan).lower(s)
    assert len(traced) == first
