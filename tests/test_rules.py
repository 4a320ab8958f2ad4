"""The rule sets (docs/GAME.md "Rule sets"): every switch of the ``"reference"`` rules does what
it says, and nothing where its mechanic is not triggered; ``next_episode``; the boss's cast
pause at 1 and 5 sub-steps; chained playtests.

Expected values follow from the reference source by hand (tick counts of the float32 timer
loop, one-tick slash, players-first death check), never from a run.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import BOSS, CAST_1, NOOP, PASSIVE_BOSS, acts

import raidjax
from raidjax.types import LOSS, PROJ_HOMING, PROJ_STRAIGHT, RULE_SWITCHES, RUNNING, WIN

# Own jitted functions: the shared ones in ``helpers`` compile for ``CLEAN1`` only.
STEP = jax.jit(raidjax.step)
RESET = jax.jit(raidjax.reset)
NEXT = jax.jit(raidjax.next_episode)
KEY = jax.random.key(3)
CLEAN5 = raidjax.EnvConfig.from_rules("clean")
REF5 = raidjax.EnvConfig()


def only(switch: str, n_substeps: int = 5) -> raidjax.EnvConfig:
    """The clean rules with one reference switch on."""
    return raidjax.EnvConfig.from_rules("clean", n_substeps=n_substeps, **{switch: True})


def params(config, passive=True, boss=None, **kw):
    bo = dict(PASSIVE_BOSS) if passive else {}
    bo.update(boss or {})
    return raidjax.make_params(config=config, boss_overrides=bo, **kw)


def placed(p, players, boss, alive=(True, True, True), target=None, hp=None):
    """A reset state with units placed by hand (everyone faces +y; the boss faces its target)."""
    _, s = RESET(KEY, p)
    pos = jnp.asarray([*players, boss], jnp.float32)
    alive_u = jnp.asarray([*alive, True])
    d = jnp.linalg.norm(pos[:3] - pos[BOSS], axis=-1)
    t = int(jnp.argmin(jnp.where(alive_u[:3], d, jnp.inf))) if target is None else target
    to_t = pos[t] - pos[BOSS]
    s = s.replace(pos=pos, alive=alive_u, hp=jnp.where(alive_u, s.hp, 0.0) if hp is None else jnp.asarray(hp),
                  target=s.target.at[BOSS].set(t),
                  heading=s.heading.at[BOSS].set(jnp.arctan2(to_t[1], to_t[0])))
    return s


def play(s, p, actions, n):
    states = []
    for t in range(n):
        a = actions(t + 1) if callable(actions) else actions
        _, s, _, _, _ = STEP(jax.random.fold_in(KEY, t), s, a, p)
        states.append(jax.device_get(s))
    return s, states


def put(s, index, **fields):
    """Place a live projectile in pool slot ``index``."""
    pr = s.projectiles
    new = {k: getattr(pr, k).at[index].set(v) for k, v in fields.items()}
    return s.replace(projectiles=pr.replace(live=pr.live.at[index].set(True), **new))


# ---------------------------------------------------------------------------------- timers


@pytest.mark.parametrize("unity, decision", [(True, 2), (False, 1)])
def test_unity_timers_make_a_0_1_s_cast_last_6_ticks(unity, decision):
    # 0.1 - 5 x 0.02f is exactly 0 in float32 and the reference loop runs while r >= 0: the cast
    # started in tick 1 fires in tick 6 (decision 2); an exact 0.1 s timer fires in tick 5.
    cfg = dataclasses.replace(CLEAN5, unity_timers=unity)
    p = params(cfg, **{"skill1.cast_time": 0.1, "skill1.range": 20.0})
    s = placed(p, [(-3, -10), (0, -10), (3, -10)], (0, 8))
    _, states = play(s, p, lambda t: acts(CAST_1, NOOP, NOOP) if t == 1 else acts(NOOP), 3)
    paid = [i + 1 for i, st in enumerate(states) if st.mana[0] < 100]
    assert paid[0] == decision


@pytest.mark.parametrize("unity, back_by", [(True, 12), (False, 11)])
def test_unity_timers_make_a_1_s_cooldown_last_51_ticks(unity, back_by):
    # The 0.1 s cast fires in tick 6 (reference loop) or 5 (exact); a 1.0 s cool time then runs
    # 51 ticks (the float32 loop) or 50: the charge is back in tick 57 (decision 12) or 55 (11).
    cfg = dataclasses.replace(CLEAN5, unity_timers=unity)
    p = params(cfg, **{"skill1.cast_time": 0.1, "skill1.cool_time": 1.0, "skill1.range": 20.0})
    s = placed(p, [(-3, -10), (0, -10), (3, -10)], (0, 8))
    _, states = play(s, p, lambda t: acts(CAST_1, NOOP, NOOP) if t == 1 else acts(NOOP), 13)
    charges = [int(st.charges[0, 0]) for st in states]
    assert charges[1] == 0
    assert next(d for d in range(2, 14) if charges[d - 1] == 1) == back_by


# ------------------------------------------------------------------------------- the slash


@pytest.mark.parametrize("one_step", [True, False])
def test_one_step_area_hits_only_the_nearest_unit_once(one_step):
    # The boss's slash (attack 2, radius 2.4, up to 3 hits, 60 damage) at the boss-target
    # midpoint (0, -1); all three players are within 2.4 + 0.5 of it, player 0 nearest.
    cfg = dataclasses.replace(CLEAN5, one_step_area=one_step)
    p = params(cfg, passive=False, boss={"move_speed": 0.0, "skill1.range": 1.0, "skill2.cast_time": 0.1})
    s = placed(p, [(0, -2), (1.5, -2.5), (-1.5, -2.5)], (0, 0))
    _, states = play(s, p, acts(NOOP), 6)
    lost = 100 - states[-1].hp[:3]
    assert lost.tolist() == ([60, 0, 0] if one_step else [60, 60, 60])


# -------------------------------------------------------------------------- ties and targets


@pytest.mark.parametrize("ties_are_losses, result", [(True, LOSS), (False, WIN)])
def test_boss_and_last_player_dying_in_one_tick(ties_are_losses, result):
    cfg = dataclasses.replace(CLEAN5, ties_are_losses=ties_are_losses)
    p = params(cfg)
    s = placed(p, [(0, -5), (3, -10), (-3, -10)], (0, 5), alive=(True, False, False), hp=[1.0, 0, 0, 1.0])
    # A boss missile touching player 0 and a player missile touching the boss: both land next tick.
    s = put(s, 0, kind=PROJ_STRAIGHT, pos=jnp.array([0.0, -4.6]), direction=jnp.array([0.0, -1.0]),
            owner=BOSS, slot=0, life=5.0)
    s = put(s, 1, kind=PROJ_HOMING, pos=jnp.array([0.0, 3.7]), owner=0, slot=0, target=BOSS, life=5.0)
    _, states = play(s, p, acts(NOOP), 1)
    assert not states[0].alive.any()
    assert int(states[0].result) == result


@pytest.mark.parametrize("keep", [True, False])
def test_boss_keeps_chasing_a_dead_target(keep):
    cfg = dataclasses.replace(CLEAN5, keep_dead_target=keep)
    p = params(cfg, boss={"move_speed": 6.0})
    s = placed(p, [(0, 0), (8, 8), (-8, 8)], (0, 8), alive=(False, True, True), target=0)
    _, states = play(s, p, acts(NOOP), 1)
    boss = states[0].pos[BOSS]
    if keep:  # 0.6 units towards the body at (0, 0)
        assert int(states[0].target[BOSS]) == 0
        np.testing.assert_allclose(boss, [0.0, 7.4], atol=1e-4)
    else:  # re-targeted to player 1 (nearest alive; ties go to the lower index)
        assert int(states[0].target[BOSS]) == 1
        np.testing.assert_allclose(boss, [0.6, 8.0], atol=1e-4)


@pytest.mark.parametrize("keep", [True, False])
def test_keep_dead_target_casts_at_the_dead_target_until_a_skill_fires(keep):
    # GAME.md rule table: the reference boss casts at its target after it died, until one of its
    # skills fires (then it re-targets). A still boss at (0, 0) facing its dead target at (0, -5);
    # player 1, alive, at (6, 0). The breath (0.1 s) fires in decision 1: along (0, -1) at the dead
    # player under keep_dead_target, along (1, 0) at player 1 otherwise; both end targeting player 1.
    cfg = dataclasses.replace(CLEAN5, keep_dead_target=keep)
    p = params(cfg, passive=False, boss={"move_speed": 0.0, "skill2.range": 1.0})
    s = placed(p, [(0, -5), (6, 0), (-11, -11)], (0, 0), alive=(False, True, False), target=0)
    _, states = play(s, p, acts(NOOP), 1)
    (slot,) = np.flatnonzero(states[0].projectiles.live)
    np.testing.assert_allclose(states[0].projectiles.direction[slot], [0.0, -1.0] if keep else [1.0, 0.0], atol=1e-5)
    assert int(states[0].target[BOSS]) == 1


# ------------------------------------------------------------------------- next_episode


def ended_state(p):
    """A state at an episode's end: the boss away from its spawn with cooldowns running, two
    projectiles in flight (pool slots 2 and 5), player 0 alive and recharging, player 1 dead and
    recharging."""
    s = placed(p, [(-3, -10), (0, -10), (3, -10)], (4, -6), alive=(True, False, True))
    s = s.replace(
        charges=s.charges.at[BOSS, 1].set(0).at[0, 0].set(0).at[1, 0].set(0),
        recharging=s.recharging.at[BOSS, 1].set(True).at[0, 0].set(True).at[1, 0].set(True),
        recharge_left=s.recharge_left.at[BOSS, 1].set(0.3).at[0, 0].set(0.2).at[1, 0].set(0.2),
        result=jnp.int32(LOSS),
    )
    s = put(s, 2, kind=PROJ_STRAIGHT, pos=jnp.array([5.0, 5.0]), direction=jnp.array([1.0, 0.0]), owner=BOSS, life=5.0)
    return put(s, 5, kind=PROJ_STRAIGHT, pos=jnp.array([-5.0, 5.0]), direction=jnp.array([1.0, 0.0]), owner=BOSS,
               life=5.0)


def test_next_episode_equals_reset_under_clean_rules():
    p = params(CLEAN5)
    got = NEXT(KEY, ended_state(p), p)
    want = RESET(KEY, p)
    for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(want), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_next_episode_carries_running_cooldowns_of_units_not_deactivated():
    p = params(REF5)
    _, s = NEXT(KEY, ended_state(p), p)
    # Charges refilled; the boss's and living player 0's timers run on; dead player 1's are gone.
    assert s.charges[BOSS, 1] == 1 and s.charges[0, 0] == 1 and s.charges[1, 0] == 1
    assert s.recharging[BOSS, 1] and s.recharging[0, 0] and not s.recharging[1, 0]
    assert float(s.recharge_left[BOSS, 1]) == pytest.approx(0.3)
    # The carried timers end (0.3 s: 16 ticks, 0.2 s: 11) and add a charge above the cap.
    _, states = play(s, p, acts(NOOP), 4)
    assert [int(st.charges[BOSS, 1]) for st in states] == [1, 1, 1, 2]
    assert [int(st.charges[0, 0]) for st in states] == [1, 1, 2, 2]
    assert int(states[-1].charges[1, 0]) == 1 and not states[-1].recharging.any()
    # The boss is never deactivated: after a win, its dead self's timers carry all the same.
    won = ended_state(p)
    won = won.replace(alive=won.alive.at[BOSS].set(False), hp=won.hp.at[BOSS].set(0.0), result=jnp.int32(WIN))
    _, s = NEXT(KEY, won, p)
    assert s.alive[BOSS] and s.recharging[BOSS, 1] and float(s.recharge_left[BOSS, 1]) == pytest.approx(0.3)


def test_an_ended_game_reports_what_it_hands_on():
    # The state set by hand: the boss's slot 2 (index 1) recharging, two projectiles in flight.
    summary = raidjax.logs.episode_summary(ended_state(params(REF5)))
    assert np.asarray(summary["boss_recharging"]).tolist() == [False, True, False]
    assert int(summary["in_flight"]) == 2


def test_without_carry_next_episode_starts_with_no_timers():
    p = params(only("reset_exception"))
    _, s = NEXT(KEY, ended_state(p), p)
    assert not s.recharging.any() and (np.asarray(s.charges[:, 0]) == 1).all()


def test_reset_exception_keeps_the_boss_and_all_projectiles_but_the_first():
    p = params(only("reset_exception"))
    end = ended_state(p)
    _, s = NEXT(KEY, end, p)
    np.testing.assert_allclose(s.pos[BOSS], [4.0, -6.0])
    np.testing.assert_allclose(s.pos[:3], [[-3, -10], [0, -10], [3, -10]])
    assert np.flatnonzero(np.asarray(s.projectiles.live)).tolist() == [5]
    np.testing.assert_allclose(s.projectiles.pos[5], [-5.0, 5.0])
    # The boss that stays keeps its facing and picks its target from where it stands: player 2 at
    # (3, -10) is 4.12 from (4, -6), player 1 at (0, -10) 5.66 (from its spawn it would pick player 1).
    turned = end.replace(heading=end.heading.at[BOSS].set(1.25))
    _, s = NEXT(KEY, turned, p)
    assert float(s.heading[BOSS]) == 1.25 and int(s.target[BOSS]) == 2
    assert int(RESET(KEY, p)[1].target[BOSS]) == 1
    # Nothing in flight: the boss goes back to its spawn.
    empty = end.replace(projectiles=end.projectiles.replace(live=jnp.zeros_like(end.projectiles.live)))
    _, s = NEXT(KEY, empty, p)
    np.testing.assert_allclose(s.pos[BOSS], [0.0, 8.0])


def test_next_episode_clears_the_episode_and_refills_units():
    p = params(REF5)
    end = ended_state(p).replace(hp=jnp.array([5.0, 0.0, 7.0, 3.0]), decision=jnp.int32(99))
    _, s = NEXT(KEY, end, p)
    assert s.alive.all() and (np.asarray(s.hp) == [100, 100, 100, 1000]).all()
    assert int(s.decision) == 0 and int(s.result) == RUNNING and not s.casting.any()


# -------------------------------------------------------------------- switches when idle


def test_switches_change_nothing_where_their_mechanic_is_not_triggered():
    # 12 decisions of a fight with no death, no episode end and no area: every switch but the
    # timers (which shift casts by a tick) must leave the rollout bit-identical to the clean game.
    def rollout(cfg):
        p = params(cfg, passive=False, **{"skill1.range": 13.0})
        _, s = RESET(KEY, p)
        rng = np.random.default_rng(0)
        for t in range(12):
            a = jnp.asarray(rng.integers(0, 8, 3), jnp.int32)
            _, s, _, _, _ = STEP(jax.random.fold_in(KEY, t), s, a, p)
        return jax.device_get(s)

    base = rollout(CLEAN5)
    assert base.alive.all() and int(base.result) == RUNNING
    for switch in ("carry_cooldowns", "keep_dead_target", "reset_exception", "ties_are_losses"):
        got = rollout(only(switch))
        for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(base), strict=True):
            np.testing.assert_array_equal(a, b, err_msg=switch)


# --------------------------------------------------------------------- sub-step independence


@pytest.mark.parametrize("n_substeps", [1, 5])
def test_boss_stands_still_while_casting_at_any_substep_count(n_substeps):
    # Breath (cast 0.1 s = 6 ticks, range 12) ready, target 10 away: in decision 1 the boss chases
    # in tick 1, starts the cast, stands ticks 2-6 (the cast fires at the end of tick 6), chases
    # ticks 7-10. At 6 units/s a tick is 0.12: 0.12 in decision 1, 0.48 in decision 2.
    cfg = raidjax.EnvConfig(n_substeps=n_substeps)
    p = params(cfg, passive=False, boss={"skill2.range": 1.0})
    s = placed(p, [(0, -2), (-8, -10), (8, -10)], (0, 8))
    _, states = play(s, p, acts(NOOP), 2)
    moved = np.diff(np.array([8.0] + [st.pos[BOSS, 1] for st in states]))
    np.testing.assert_allclose(-moved, [0.12, 0.48], atol=1e-4)
    assert states[0].casting[BOSS, 0] and not states[1].casting[BOSS, 0]


def test_hp_floors_at_zero_on_death():
    p = params(CLEAN5)
    s = placed(p, [(0, -5), (3, -10), (-3, -10)], (0, 5), hp=[2.0, 100, 100, 1000])
    s = put(s, 0, kind=PROJ_STRAIGHT, pos=jnp.array([0.0, -4.6]), direction=jnp.array([0.0, -1.0]),
            owner=BOSS, slot=0, life=5.0)  # 55 damage on 2 HP
    _, states = play(s, p, acts(NOOP), 1)
    assert not states[0].alive[0] and float(states[0].hp[0]) == 0.0


# ------------------------------------------------------------------------ chained playtests


def test_playtest_discards_each_arenas_first_game_under_reference_rules():
    # Players who do nothing lose, and with no crits nothing is random: every arena's first game
    # has one length, and its next episode (carried cooldowns, the boss where it ended) another.
    # playtest must report the second under the reference rules, the first under the clean ones.
    cfg = raidjax.EnvConfig(max_decisions=400)
    p = raidjax.make_params(config=cfg)

    def length_of(s, p=p):
        for t in range(400):
            _, s, _, done, _ = STEP(jax.random.fold_in(KEY, t), s, acts(NOOP), p)
            if bool(done):
                return t + 1, s
        raise AssertionError("no end")

    first, end = length_of(RESET(KEY, p)[1])
    second, _ = length_of(NEXT(KEY, end, p)[1])
    assert second != first
    res = raidjax.playtest(jax.random.key(0), p, raidjax.policies.noop, 4)
    assert (np.asarray(res["outcome"]) == LOSS).all()
    assert (np.asarray(res["length"]) == second).all()
    # Under the clean rules every game starts as a reset one: each is the clean game's first.
    clean = p.replace(config=cfg.with_rules("clean"))
    first_clean, _ = length_of(RESET(KEY, clean)[1], clean)
    res_clean = raidjax.playtest(jax.random.key(0), clean, raidjax.policies.noop, 4)
    assert (np.asarray(res_clean["length"]) == first_clean).all()


def test_rule_presets_and_validation():
    assert raidjax.EnvConfig().rules == "reference"
    assert raidjax.make_params(rules="clean").config.rules == "clean"
    assert raidjax.make_params(rules="reference", config=CLEAN5).config.rules == "reference"
    assert only("carry_cooldowns").rules == "custom"
    assert set(raidjax.RULE_SETS["reference"]) == set(RULE_SWITCHES)
    with pytest.raises(ValueError, match="rules: value 'dirty'"):
        raidjax.make_params(rules="dirty")
    with pytest.raises(ValueError, match="n_substeps: value 2"):
        raidjax.make_params(config=raidjax.EnvConfig(n_substeps=2))
    with pytest.raises(ValueError, match="carry_cooldowns: value 1"):
        raidjax.make_params(config=raidjax.EnvConfig(carry_cooldowns=1))



def test_a_unit_with_no_max_hp_starts_dead():
    # GAME.md §2: a unit whose max_hp is 0 starts dead; a dead player sees zeros and may only no-op.
    p = raidjax.make_params(player_overrides=[{"max_hp": 0}, {}, {}])
    obs, s = RESET(KEY, p)
    assert np.asarray(s.alive).tolist() == [False, True, True, True]
    assert not np.asarray(obs.self_features[0]).any()
    assert np.asarray(obs.action_mask[0]).tolist() == [True] + [False] * 9


def test_a_homing_missile_vanishes_when_its_target_dies():
    # GAME.md: homing missiles chase their target and vanish if it dies. A boss missile 10 units from
    # its target, which is dead, is gone after one decision; the same missile aimed at a live player
    # is still flying (the breath's speed 20: 2 units per decision).
    p = params(CLEAN5)
    for alive0, live_after in ((False, False), (True, True)):
        s = placed(p, [(-8, -10), (0, -10), (8, -10)], (0, 8), alive=(alive0, True, True), target=1)
        s = put(s, 0, kind=PROJ_HOMING, pos=jnp.array([-8.0, 0.0]), direction=jnp.array([0.0, -1.0]), owner=BOSS,
                slot=0, target=0, life=5.0)
        _, states = play(s, p, acts(NOOP), 1)
        assert bool(states[0].projectiles.live[0]) is live_after


def test_death_cancels_a_cast():
    # GAME.md §5-6: a unit that dies stops its casts. Player 0 (1 HP, 4 units from the boss) starts
    # MagicMissile (0.5 s) on decision 1; a boss missile flying at it kills it on decision 2, before
    # the cast fires on decision 5: no missile of its ever flies and the boss keeps its HP. Without the
    # boss missile the same cast hits the boss (950 by decision 8).
    p = params(CLEAN5)
    for killed in (True, False):
        s = placed(p, [(0, -4), (-8, -10), (8, -10)], (0, 0), alive=(True, False, False), target=0,
                   hp=[1.0, 0.0, 0.0, 1000.0])
        if killed:
            s = put(s, 0, kind=PROJ_STRAIGHT, pos=jnp.array([0.0, -1.0]), direction=jnp.array([0.0, -1.0]),
                    owner=BOSS, slot=0, life=5.0)
        _, states = play(s, p, lambda t: acts(CAST_1 if t == 1 else NOOP, NOOP, NOOP), 8)
        if killed:
            assert not states[1].alive[0] and not states[1].casting[0].any()
            assert not any((st.projectiles.live & (st.projectiles.owner == 0)).any() for st in states)
            assert float(states[-1].hp[BOSS]) == 1000.0
        else:
            assert states[0].casting[0, 0] and float(states[-1].hp[BOSS]) == 950.0
