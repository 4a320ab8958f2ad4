"""Game logs (summaries, traces, occupancy heatmaps) and GIF replays."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from PIL import Image

import raidjax
from raidjax.logs import occupancy_heatmap, record_episode, trace_heatmap
from raidjax.render import render_gif

T = 60
RECORD = jax.jit(record_episode, static_argnames=("policy", "n_decisions"))


@pytest.fixture(scope="module")
def recorded():
    params = raidjax.make_params(skill_range=9.0)
    trace, summary = RECORD(jax.random.key(3), params, raidjax.policies.heuristic, T)
    return params, trace, summary


def test_occupancy_heatmap_counts_hand_placed_positions():
    # 24 bins over [-12.25, 12.25]: bin width 24.5 / 24; (0, 0) falls in bin 12, the corners in 0 / 23.
    pos = jnp.array([[0.1, 0.1], [0.1, 0.1], [-12.2, 12.2], [5.0, 5.0]])
    mask = jnp.array([True, True, True, False])
    hm = np.asarray(occupancy_heatmap(pos, mask))
    assert hm.shape == (24, 24)
    assert hm[12, 12] == pytest.approx(2 / 3)
    assert hm[0, 23] == pytest.approx(1 / 3)
    assert hm.sum() == pytest.approx(1.0)
    assert np.asarray(occupancy_heatmap(pos, jnp.zeros(4, bool))).sum() == 0.0
    for bad in (0, 2.5):  # bins 0 returned an empty map
        with pytest.raises(ValueError, match=rf"^bins: value {bad!r} .*allowed: a whole number >= 1"):
            occupancy_heatmap(pos, mask, bins=bad)
    with pytest.raises(ValueError, match=r"^n_decisions: value -1 is too small"):  # was an MLIR error
        record_episode(jax.random.key(0), raidjax.make_params(), raidjax.policies.heuristic, -1)


def test_record_episode_trace_matches_the_summary(recorded):
    params, trace, summary = recorded
    assert trace.pos.shape == (T + 1, 4, 2) and trace.actions.shape == (T + 1, 3)
    np.testing.assert_allclose(trace.pos[0, :3], [[-3, -10], [0, -10], [3, -10]])  # spawns
    # the boss's HP in the trace falls by exactly the damage the summary credits to the players
    assert float(trace.hp[0, 3] - trace.hp[-1, 3]) == pytest.approx(min(float(summary["damage"].sum()), 1000.0))
    assert int(summary["length"]) == int(trace.running[1:].sum())
    hm = trace_heatmap(trace)
    assert float(hm.sum()) == pytest.approx(1.0) and int((hm > 0).sum()) > 3  # the players moved around


def test_replay_gif_decodes_with_every_frame_and_moving_units(recorded, tmp_path):
    params, trace, summary = recorded
    path = tmp_path / "replay.gif"
    n = render_gif(trace, params, str(path), size=200, every=2)
    last = int(summary["length"]) if int(summary["outcome"]) else T
    assert n == len(range(0, last + 1, 2)) + (1 if last % 2 else 0)
    with Image.open(path) as im:
        assert im.n_frames == n
        frames = []
        for i in (0, n // 2, n - 1):
            im.seek(i)
            frames.append(np.asarray(im.convert("RGB"), dtype=np.int16))
    assert np.abs(frames[0] - frames[1]).sum() > 0  # units moved between the first and middle frame
    assert np.abs(frames[1] - frames[2]).sum() > 0
    assert not list(tmp_path.glob(".tmp-*"))  # atomic write leaves no temp file


def test_a_trained_run_is_rendered_with_the_team_it_was_trained_for(tmp_path, monkeypatch):
    """``--policy RUN`` without ``--players`` plays the run's own team (``players_of``; here a stand-in
    for a run trained as warrior, mage, priest), not the three mages of a scripted replay."""
    from raidjax import render

    class Built(Exception):
        pass

    made = []

    def make_params(**kw):
        made.append(kw["players"])
        raise Built  # what the replay would play is known: stop before anything compiles

    monkeypatch.setattr(raidjax, "make_params", make_params)
    hooks = dict(load_policy=lambda path: None, find_run=lambda path: None,
                 players_of=lambda path: ["warrior", "mage", "priest"])
    for argv in (["--policy", str(tmp_path)], ["--policy", "heuristic"]):
        with pytest.raises(Built):
            render.main([*argv, "--out", str(tmp_path / "r.gif")], **hooks)
    assert made == [["warrior", "mage", "priest"], ["mage", "mage", "mage"]]
