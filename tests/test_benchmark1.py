"""Benchmark 1 pipeline at smoke scale: files, numbers recomputed from the raw cells, resume."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from PIL import Image

from experiments import benchmark1


def _rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("b1") / "run"
    first = benchmark1.main(["--scale", "smoke", "--out", str(out), "--max-chunks", "1"])  # interrupted
    state_after_interrupt = {"train_done": (out / "stages" / "train.json").exists(),
                             "groups": sorted(p.name for p in (out / "checkpoints" / "mapoca").iterdir()),
                             "checkpoints": sorted(p.name for p in (out / "checkpoints" / "mapoca" / "group0").iterdir()
                                                   if p.name.isdigit())}
    summary = benchmark1.main(["--scale", "smoke", "--out", str(out), "--resume"])  # resumes and finishes
    return out, first, state_after_interrupt, summary


def test_interrupted_run_resumes_mid_training(run):
    out, first, after, summary = run
    assert first == {"interrupted": True}
    # The 16 smoke runs train in two groups of 8 (Scale.runs_per_program), one after the other; the
    # interruption came after chunk 1 of 2 of the first group, checkpointed.
    assert not after["train_done"] and after["groups"] == ["group0"] and after["checkpoints"] == ["1"]
    log = (out / "log.txt").read_text()
    assert "train group 0 (1 of 2): resumed from the checkpoint at update 1/2" in log
    for g in (0, 1):
        rows = (out / "train" / f"metrics_group{g}.jsonl").read_text().splitlines()
        assert [json.loads(s)["chunk"] for s in rows] == [0, 1]  # one row per chunk, none lost or repeated
    merged = _rows(out / "train" / "metrics.csv")  # the groups side by side, every run's column
    runs = benchmark1.runs_of(benchmark1.SCALES["smoke"])
    assert len(merged) == 2 and {f"{m}/{r['name']}/{r['seed']}" for r in runs for m in ("win", "entropy", "kl")} <= set(
        merged[0])
    # a policy of 8 actions: entropy in (0, ln 8]; the updates moved it (KL not 0)
    entropy = [float(merged[0][f"entropy/{r['name']}/{r['seed']}"]) for r in runs]
    assert all(0 < e <= np.log(8) + 1e-5 for e in entropy)
    assert any(float(merged[1][f"kl/{r['name']}/{r['seed']}"]) != 0 for r in runs)
    assert summary["train"]["decisions_per_run"] == 256 and summary["train"]["groups"] == 2
    assert [list(g) for g in benchmark1.groups_of(10, 4)] == [[0, 1, 2, 3], [4, 5, 6, 7], [8, 9]]


def test_run_folder_contents(run):
    out, *_ = run
    for name in ["config.json", "summary.json", "log.txt", "heatmaps.npz", "tables/win_rate.md",
                 "tables/robustness.md", "csv/win_rates.csv", "csv/win_rate_table.csv", "csv/robustness.csv"]:
        assert (out / name).is_file(), name
    for fig in ["adjusted_score", "heatmaps"]:
        with Image.open(out / "figures" / f"{fig}.png") as im:
            assert im.size[0] > 100 and im.size[1] > 100
    maps = np.load(out / "heatmaps.npz")["maps"]
    assert maps.shape == (2, 2, 3, 24, 24)  # agents x heatmap ranges x players x grid
    sums = maps.sum((-1, -2))
    assert np.all(np.isclose(sums, 1.0, atol=1e-4) | (sums == 0))
    table = (out / "tables" / "win_rate.md").read_text()
    assert "(0.371)" in table and "(0.857)" in table  # the paper's numbers beside ours


def test_tables_recompute_from_raw_cells(run):
    out, *_ = run
    cells = _rows(out / "csv" / "win_rates.csv")
    n_runs = len(benchmark1.runs_of(benchmark1.SCALES["smoke"]))
    assert len([c for c in cells if c["group"] != "scripted"]) == n_runs + 3 * 4  # robust runs: 4 test ranges
    table = _rows(out / "csv" / "win_rate_table.csv")
    assert {r["agent"] for r in table} == {"PT-RD", "PT-HR", "MA-POCA", "PT-RD, mixed team", "PT-HR, mixed team",
                                           "MA-POCA, mixed team"}
    for row in table:
        agent, _, team = row["agent"].partition(", ")
        content = "mixed" if team else "reference"
        own = [float(c["win_rate"]) for c in cells if c["agent"] == agent and c["content"] == content
               and float(c["range"]) == float(row["range"]) and c["group"] != "population"]
        assert len(own) >= 1 and float(row["mean"]) == pytest.approx(np.mean(own))
    for row in _rows(out / "csv" / "robustness.csv"):
        pop = np.mean([float(c["win_rate"]) for c in cells
                       if c["group"] == "population" and float(c["range"]) == float(row["range"])])
        assert float(row["population_win"]) == pytest.approx(pop)
        if pop > 0:
            assert float(row["adjusted_mean"]) == pytest.approx(float(row["win_mean"]) / pop)


def test_finished_run_resumed_is_a_no_op_and_other_settings_are_refused(run):
    out, *_ = run
    summary_bytes = (out / "summary.json").read_bytes()
    again = benchmark1.main(["--scale", "smoke", "--out", str(out), "--resume"])
    assert "this run has already finished: nothing to do" in (out / "log.txt").read_text()
    assert again["win_rate"] == run[3]["win_rate"] and (out / "summary.json").read_bytes() == summary_bytes
    with pytest.raises(ValueError, match="already holds a run: pass --resume"):
        benchmark1.main(["--scale", "smoke", "--out", str(out)])
    with pytest.raises(ValueError, match="other settings .*scale: saved \"smoke\", now \"cpu\""):
        benchmark1.main(["--scale", "cpu", "--out", str(out), "--resume"])


def test_heatmap_figure_orientation_shared_scale_and_redraw(tmp_path):
    """All of one map's occupancy in the south-east corner (x, y = +11.5, -11.5, binned by
    ``raidjax.logs.occupancy_heatmap``) comes out in that corner of the drawn panel: in the image
    data (origin lower, world-unit extent) and in the rendered pixels; every panel shares one
    colour scale; ``redraw_heatmaps`` writes the PNG from a run folder's npz and config alone."""
    import json

    import jax.numpy as jnp
    import matplotlib.pyplot as plt

    from experiments import b1_report
    from raidjax.logs import occupancy_heatmap
    from raidjax.types import HALF_ARENA

    corner = np.asarray(occupancy_heatmap(jnp.array([[11.5, -11.5]]), jnp.array([True])))  # [x_bin, y_bin]
    spread = np.full((24, 24), 1 / 24**2)
    maps = np.stack([np.stack([corner] * 3), np.stack([spread] * 3)])[:, None]  # [2 agents, 1 range, 3, 24, 24]
    fig, axes = b1_report.heatmap_figure(maps, ["A", "B"], [5.0], games=7)
    images = [ax.images[0] for ax in axes.ravel()]
    assert {im.get_clim() for im in images} == {(0.0, 100.0)}  # one scale, in percent
    assert len(fig.axes) == 3  # two panels and one colour bar
    im = images[0]
    a = np.asarray(im.get_array())
    assert im.origin == "lower" and tuple(im.get_extent()) == (-HALF_ARENA, HALF_ARENA, -HALF_ARENA, HALF_ARENA)
    row, col = np.unravel_index(np.argmax(a), a.shape)
    assert (row, col) == (0, 23) and a[row, col] == 100.0 and a.sum() == 100.0  # bottom row, last column
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    bright = (np.asarray(im.cmap(1.0)[:3]) * 255).round()

    def pixel(x, y):
        px, py = axes[0, 0].transData.transform((x, y))
        return rgba[int(round(rgba.shape[0] - py)), int(round(px)), :3].astype(float)

    assert np.abs(pixel(11.7, -11.7) - bright).max() <= 2  # the corner cell is drawn at the top of the scale
    for x, y in [(-11.7, -11.7), (11.7, 11.7), (-11.7, 11.7)]:  # the other three corners are not
        assert np.abs(pixel(x, y) - bright).max() > 50
    plt.close(fig)

    np.savez(tmp_path / "heatmaps.npz", maps=maps, agents=np.asarray(["A", "B"]), ranges=np.asarray([5.0]))
    (tmp_path / "config.json").write_text(json.dumps({"budgets": {"heatmap_games": 7}}))
    png = b1_report.redraw_heatmaps(tmp_path)
    with Image.open(png) as im:
        assert png == tmp_path / "figures" / "heatmaps.png" and im.size[0] > 300 and im.size[1] > 300


def test_switches_play_the_table_teams_and_pt_hr_by_chain_position(run, tmp_path, capsys):
    from experiments import b1_switches

    out = tmp_path / "switches.jsonl"
    b1_switches.main([str(run[0]), "--games", "20", "--out", str(out)])
    progress = [s for s in capsys.readouterr().out.splitlines() if s.startswith("played ")]
    assert [s.split(" (")[1][:3] for s in progress] == ["1/3", "2/3", "3/3"] and "ETA" in progress[0]
    rows = [json.loads(s) for s in out.read_text().splitlines()]
    table = [r for r in benchmark1.runs_of(benchmark1.SCALES["smoke"]) if r["group"] == "table"]
    for switch in b1_switches.SWITCHES:
        mine = [r for r in rows if r["switch"] == switch]
        assert sorted((r["range"], r["seed"]) for r in mine if r["agent"] == "MA-POCA") == sorted(
            (t["ranges"][0], t["seed"]) for t in table)
        assert sorted(r["range"] for r in mine if r["agent"] == "PT-HR") == [5.0, 9.0, 13.0, 17.0]
    for r in rows:  # 2 arenas x 10 games: every position holds 2 games, so the rates agree exactly
        by_pos = r["win_rate_by_position"]
        assert len(by_pos) == 10 and r["win_rate_first_game"] == by_pos[0]
        assert r["win_rate"] == pytest.approx(np.mean(by_pos), abs=1e-3)
        assert r["win_rate_later_games"] == pytest.approx(np.mean(by_pos[1:]), abs=1e-3)
    # a run folder whose table group has not trained is refused in one line, naming it
    bare = tmp_path / "bare"
    bare.mkdir()
    (bare / "config.json").write_text((run[0] / "config.json").read_text())
    with pytest.raises(ValueError, match="training group 0 has no final checkpoint"):
        b1_switches.evaluate(bare, 20)


def test_switches_play_a_trained_mapoca_run_folder(tmp_path):
    """``b1_switches`` also takes a finished ``raidjax train mapoca`` folder: its seeds are the teams,
    played with the run's senses, sampled as its ``deterministic_eval`` (False) says (test_mapoca
    shows ``load_policy`` reading it). The run is test_faults_mapoca's (``TINY_MAPOCA``; the
    compilation cache shares its training, and its playing with the table teams' test above)."""
    from helpers import TINY_MAPOCA, TINY_MAPOCA_ARGS

    from experiments import b1_switches
    from trainers import mapoca_cli

    cfg = tmp_path / "tiny.json"
    cfg.write_text(json.dumps(TINY_MAPOCA))
    run_dir = tmp_path / "run"
    mapoca_cli.main(["--config", str(cfg), *TINY_MAPOCA_ARGS, "--eval-games", "0", "--out", str(run_dir)])
    out = tmp_path / "switches.jsonl"
    b1_switches.main([str(run_dir), "--games", "20", "--out", str(out)])
    rows = [json.loads(s) for s in out.read_text().splitlines()]
    assert sorted((r["switch"], r["agent"], r.get("seed"), r["range"]) for r in rows) == sorted(
        (s, a, i, 9.0) for s in b1_switches.SWITCHES for a, i in [*(("MA-POCA", i) for i in range(4)), ("PT-HR", None)])
    assert all(r["senses"] == "reference" and not r["greedy"] for r in rows if r["agent"] == "MA-POCA")
    (run_dir / "result.json").unlink()
    with pytest.raises(ValueError, match="has not finished"):
        b1_switches.evaluate(run_dir, 20)


def test_per_team_plays_greedily_only_when_asked():
    """``per_team(greedy=True)`` plays each team's most likely actions (a run's ``deterministic_eval``);
    by default it samples, so different keys give different actions."""
    import jax
    import jax.numpy as jnp

    import raidjax
    from trainers.networks import Actor

    actor = Actor(16, 1, 1, False)
    content = raidjax.make_params(skill_range=13.0)
    obs0, _ = raidjax.reset(jax.random.PRNGKey(0), content)
    w = actor.init(jax.random.PRNGKey(1), obs0)
    weights = jax.tree.map(lambda x: jnp.stack([x, x * 3.0]), w)  # two teams
    contents = jax.tree.map(lambda x: jnp.stack([x, x]), content)

    def first_actions(k, c, policy):
        obs, state = raidjax.reset(jax.random.PRNGKey(0), c)
        return policy(k, obs, state, c)

    want = jnp.stack([jnp.argmax(actor.apply(jax.tree.map(lambda x, i=i: x[i], weights), obs0), -1) for i in (0, 1)])
    for seed in range(3):
        got = benchmark1.per_team(jax.random.PRNGKey(seed), actor, weights, contents, first_actions, greedy=True)
        np.testing.assert_array_equal(got, want)
    sampled = {tuple(np.asarray(benchmark1.per_team(jax.random.PRNGKey(s), actor, weights, contents,
                                                    first_actions)).ravel()) for s in range(8)}
    assert len(sampled) > 1
