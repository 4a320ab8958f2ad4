"""Casting, cool times, charges, mana, haste and the cast-condition flags (GAME.md §3, §5).

One caster (player 0, 4 units in front of a passive boss, inside MagicMissile's range 5); the
other players are dead. A decision is 0.1 s, so a cast of c seconds started on decision 1 fires
on decision c / 0.1, and a cool time of k seconds after it lets the next cast start k / 0.1
decisions later: fires at c, c + k + c, ... (in decisions).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import BOSS, CAST_1, NOOP, acts, events, make, run, scenario, series

from raidjax.types import FORWARD

CAST = acts(CAST_1, NOOP, NOOP)


def solo(params, mana=None, pos=(0.0, -4.0)):
    return scenario(params, players=(pos, (-11, -11), (11, -11)), boss=(0.0, 0.0),
                    alive=(True, False, False), mana=mana)


def expected_fires(cast, cool, n, charges=1):
    """Fire decisions within n decisions for a skill held down from decision 1 (hand model of
    GAME.md §5: a cast of c decisions fires at its end; the recharge timer starts when a cast
    completes with full charges, one charge returns every k decisions while below the max;
    a returned charge can start a cast on the next decision)."""
    c, k = round(cast / 0.1), round(cool / 0.1)
    stock, timer, t, fires = charges, None, 0, []
    while True:
        if stock == 0:  # wait for the next charge
            t, stock = timer, stock + 1
            timer = t + k if stock < charges else None
        fire = t + c
        while timer is not None and timer <= fire:  # charges returning during the cast
            stock += 1
            timer = timer + k if stock < charges else None
        if fire > n:
            return fires
        fires.append(fire)
        if stock == charges:
            timer = fire + k
        stock -= 1
        t = fire


def fire_decisions(params, n, **kw):
    """Decisions on which player 0 paid mana (no mana regen) while holding CAST_1."""
    _, hist = run(solo(params, **kw), params, CAST, n)
    return events(series(hist, lambda s: s.mana[0]), float(params.stats.max_mana[0]))


def test_magic_missile_one_cast_per_second_cast_delays_fire():
    p = make(mana_regen=0.0)
    assert expected_fires(0.5, 0.5, 30) == [5, 15, 25]
    assert fire_decisions(p, 30) == [5, 15, 25]


@pytest.mark.parametrize("cast, cool, n", [(1.0, 0.5, 30), (0.5, 1.5, 30), (2.0, 0.0, 30), (0.3, 0.7, 30),
                                           (2.0, 6.0, 100), (1.9, 12.0, 300)])
def test_cast_and_cool_time_schedule(cast, cool, n):
    p = make(mana_regen=0.0, **{"skill1.cast_time": cast, "skill1.cool_time": cool})
    assert fire_decisions(p, n) == expected_fires(cast, cool, n)


def test_projectile_spawns_when_cast_completes_not_before():
    p = make()
    _, hist = run(solo(p), p, CAST, 5)
    for t in range(1, 5):
        assert hist[t - 1]["state"].casting[0, 0] and not hist[t - 1]["state"].projectiles.live.any()
    assert hist[4]["state"].projectiles.live.sum() == 1 and not hist[4]["state"].casting[0, 0]


def test_two_charges_allow_two_casts_back_to_back():
    p = make(mana_regen=0.0, **{"skill1.charge": 2, "skill1.cool_time": 5.0})
    assert expected_fires(0.5, 5.0, 30, charges=2) == [5, 10]
    out, hist = run(solo(p), p, CAST, 30)
    assert events(series(hist, lambda s: s.mana[0]), 100.0) == [5, 10]
    assert int(hist[9]["state"].charges[0, 0]) == 0
    # The recharge timer started when the first cast completed (decision 5): 5.0 - 0.5 left.
    assert abs(float(hist[9]["state"].recharge_left[0, 0]) - 4.5) < 1e-4
    # One charge: only one cast in the same 30 decisions.
    p1 = make(mana_regen=0.0, **{"skill1.charge": 1, "skill1.cool_time": 5.0})
    assert fire_decisions(p1, 30) == [5]
    p3 = make(mana_regen=0.0, **{"skill1.charge": 3, "skill1.cool_time": 5.0})
    assert fire_decisions(p3, 30) == [5, 10, 15]


def test_charge_returns_one_per_cool_time():
    p = make(mana_regen=0.0, **{"skill1.charge": 2, "skill1.cool_time": 2.0, "skill1.cast_time": 0.5})
    # fires 5, 10 (both charges); first charge back at 5 + 20 = 25 -> fires 30; the second
    # charge is back 20 decisions after the first returned (45) -> fires 50.
    assert expected_fires(0.5, 2.0, 52, charges=2) == [5, 10, 30, 50]
    assert fire_decisions(p, 52) == [5, 10, 30, 50]


def test_mana_cost_paid_on_completion_and_blocks_when_short():
    p = make(mana_regen=0.0, **{"skill1.cost": 40.0, "skill1.cool_time": 0.0})
    _, hist = run(solo(p), p, CAST, 20)
    mana = series(hist, lambda s: s.mana[0])
    np.testing.assert_allclose(mana[:4], 100.0)  # nothing paid while casting
    assert events(mana, 100.0) == [5, 10]  # 100 -> 60 -> 20; 20 < 40 blocks the third cast
    assert mana[-1] == pytest.approx(20.0)
    assert not hist[-1]["state"].casting[0, 0]
    assert not hist[-1]["obs"].action_mask[0, CAST_1]
    # Mana below the cost from the start: the cast never starts.
    _, hist = run(solo(p, mana=(39.0, None, None, None)), p, CAST, 3)
    assert not any(h["state"].casting[0, 0] for h in hist)
    assert not hist[0]["obs"].action_mask[0, CAST_1]


def test_mana_regenerates_at_its_rate():
    p = make(**{"skill1.cost": 40.0})
    _, hist = run(solo(p, mana=(50.0, None, None, None)), p, acts(NOOP), 10)
    assert float(hist[0]["state"].mana[0]) == pytest.approx(50.1, abs=1e-4)  # 1.0 / s
    assert float(hist[-1]["state"].mana[0]) == pytest.approx(51.0, abs=1e-4)
    _, hist = run(solo(p, mana=(99.95, None, None, None)), p, acts(NOOP), 2)
    assert float(hist[-1]["state"].mana[0]) == pytest.approx(100.0)  # capped at max


def test_haste_shortens_cast_and_cool_time():
    p = make(mana_regen=0.0, haste=25)  # divide by 1.25: cast 0.4 s, cool 0.4 s
    assert fire_decisions(p, 30) == expected_fires(0.4, 0.4, 30) == [4, 12, 20, 28]
    _, hist = run(solo(p), p, CAST, 4)
    assert abs(float(hist[3]["state"].recharge_left[0, 0]) - 0.4) < 1e-4


def test_haste_cadence_follows_completion_times_not_decision_boundaries():
    # haste 100: cast 0.25 s and cool 0.25 s, a cycle of 0.5 s. Casts complete at
    # 0.25 + 0.5 k s and fire at the end of the decision containing that moment.
    p = make(mana_regen=0.0, haste=100)
    assert fire_decisions(p, 30) == [3, 8, 13, 18, 23, 28]


def test_cast_on_moving_false_moving_cancels_without_cost_or_cooldown():
    p = make(mana_regen=0.0, **{"skill1.cast_on_moving": 0, "skill1.cast_time": 1.0})
    seq = lambda t: acts(CAST_1 if t == 1 else FORWARD if t == 2 else NOOP, NOOP, NOOP)  # noqa: E731
    _, hist = run(solo(p), p, seq, 20)
    assert hist[0]["state"].casting[0, 0]
    assert not hist[1]["state"].casting[0, 0]  # cancelled by moving
    assert all(float(h["state"].mana[0]) == 100.0 for h in hist)  # no cost
    assert int(hist[-1]["state"].charges[0, 0]) == 1  # no cooldown
    assert not any(h["state"].projectiles.live.any() for h in hist)
    # The same with cast_on_moving = true fires on decision 10 while moving.
    p2 = make(mana_regen=0.0, **{"skill1.cast_on_moving": 1, "skill1.cast_time": 1.0})
    _, hist = run(solo(p2), p2, seq, 12)
    assert events(series(hist, lambda s: s.mana[0]), 100.0) == [10]


def test_cast_on_moving_false_cannot_start_while_moving():
    for flag, starts in ((0, False), (1, True)):
        p = make(**{"skill1.cast_on_moving": flag})
        s = solo(p)
        s = s.replace(vel=s.vel.at[0].set(np.array([6.0, 0.0], np.float32)))
        _, hist = run(s, p, CAST, 1)
        assert bool(hist[0]["state"].casting[0, 0]) is starts


@pytest.mark.parametrize(
    "slot1_moving, on_casting, on_channeling, starts",
    [
        (1, 0, 0, False),  # plain cast in progress, may not cast while casting
        (1, 1, 0, True),
        (0, 1, 0, False),  # slot 1 is a channel (cast_on_moving = 0)
        (0, 0, 1, True),
    ],
)
def test_cast_on_casting_and_channeling(slot1_moving, on_casting, on_channeling, starts):
    p = make(**{
        "skill2": "magic_missile",
        "skill1.cast_time": 2.0, "skill1.cast_on_moving": slot1_moving,
        "skill2.cast_on_casting": on_casting, "skill2.cast_on_channeling": on_channeling,
    })
    seq = lambda t: acts(CAST_1 if t == 1 else CAST_1 + 1, NOOP, NOOP)  # noqa: E731
    _, hist = run(solo(p), p, seq, 2)
    assert hist[0]["state"].casting[0, 0]
    assert bool(hist[0]["obs"].action_mask[0, CAST_1 + 1]) is starts
    assert bool(hist[1]["state"].casting[0, 1]) is starts
    assert hist[1]["state"].casting[0, 0]  # slot 1 keeps casting either way


def test_out_of_range_cannot_cast():
    p = make(**{"skill1.range": 3.0})
    _, hist = run(solo(p), p, CAST, 2)  # distance 4 > range 3
    assert not hist[-1]["state"].casting[0, 0] and not hist[0]["obs"].action_mask[0, CAST_1]
    p = make(**{"skill1.range": 4.5})
    _, hist = run(solo(p), p, CAST, 1)
    assert hist[0]["state"].casting[0, 0]


def test_unused_slot_cannot_cast():
    p = make()
    _, hist = run(solo(p), p, acts(CAST_1 + 1, NOOP, NOOP), 2)
    assert not hist[-1]["state"].casting.any()
    assert not hist[0]["obs"].action_mask[0, CAST_1 + 1:].any()


def test_passive_skill_fires_by_itself_every_cool_time():
    # Player 0 gets the passive "renew" (heal 0.1 x 100 = 10, cast 0, cool 2.0 s) in slot 2.
    p = make(player_overrides=[{"skill2": "renew"}, {}, {}])
    s = scenario(p, players=((0, -4), (2, -4), (11, -11)), boss=(0, 0), alive=(True, True, False),
                 hp=(None, 50.0, None, None))
    _, hist = run(s, p, acts(NOOP), 25)
    hp1 = series(hist, lambda st: st.hp[1])
    assert hp1[0] == pytest.approx(60.0)  # fires on decision 1 without any action
    # cool time 2.0 s after the (instant) cast completed: next heal 20 decisions later.
    assert [i + 1 for i in np.nonzero(np.diff(np.concatenate([[50.0], hp1])) > 0)[0]] == [1, 21]
    assert not hist[0]["obs"].action_mask[0, CAST_1 + 1]  # passives are not actions
    # The same skill as an active one does nothing without the cast action.
    p2 = make(player_overrides=[{"skill2": "renew", "skill2.trigger": 0}, {}, {}])
    _, hist = run(s, p2, acts(NOOP), 3)
    assert float(hist[-1]["state"].hp[1]) == 50.0


def test_projectile_pool_full_drops_and_counts():
    p = make()
    for n_busy, dropped in ((16, 1), (15, 0)):
        s = solo(p)
        pr = s.projectiles
        busy = np.arange(pr.live.shape[0]) < n_busy
        # Parked areas of player 0, far from everyone, already spent (hit_mask full).
        s = s.replace(projectiles=pr.replace(
            live=np.asarray(busy), kind=np.full(busy.shape, 2, np.int32),
            pos=np.full((busy.size, 2), -11.0, np.float32), life=np.full(busy.shape, 100.0, np.float32),
            hit_mask=np.ones(pr.hit_mask.shape, bool)))
        out, hist = run(s, p, CAST, 8)
        assert int(out.dropped) == dropped
        boss_hp = float(out.hp[BOSS])
        assert boss_hp == (1000.0 if dropped else 950.0)


def test_concurrent_casts_never_overspend_mana():
    # Two 1 s casts of cost 60 may overlap (cast on casting); 100 mana pays for one. The second
    # completes when only 40 is left: it fizzles (no effect, no cost, no cooldown).
    p = make(mana_regen=0.0, skill2="magic_missile", **{
        "skill1.cost": 60.0, "skill1.cast_time": 1.0, "skill1.cast_on_casting": 1,
        "skill2.cost": 60.0, "skill2.cast_time": 1.0, "skill2.cast_on_casting": 1})
    _, hist = run(solo(p), p, lambda t: acts(CAST_1 + (t == 2), NOOP, NOOP), 20)
    mana = series(hist, lambda s: s.mana[0])
    assert mana.min() == pytest.approx(40.0)  # never below zero
    assert events(mana, 100.0) == [10]  # slot 1 fires at decision 10; slot 2 never pays
    boss_hp = series(hist, lambda s: s.hp[BOSS])
    assert boss_hp[-1] == pytest.approx(950.0)  # one missile landed
    assert int(hist[-1]["state"].charges[0, 1]) == 1  # the fizzled slot kept its charge
    assert not hist[-1]["state"].casting[0, 1]
