"""``experiments.benchmark2`` at the smoke scale: files, numbers recomputed from the raw
generated skills, resume (whole stages and the PPO checkpoint) and the scale guard."""

from __future__ import annotations

import csv
import json
import math
import time

import numpy as np
import pytest
from PIL import Image

from experiments import benchmark2 as b2
from raidjax import pcg_metrics as pm


def _csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_paper_scale_is_wired_to_the_paper_budgets():
    s = b2.SCALES["paper"]
    cfg = b2.ppo_config(s)
    assert (cfg.total_steps, cfg.n_games, cfg.observe_target, s.seeds, s.eval_games, s.gen_games) == (
        20_000, 100, False, 5, 300, 300)
    assert s.episodes == 5 * 1000 and s.decisions is None  # 5 models x 1000 skills per target, 40 decisions
    assert b2.SCALES["cpu"].eval_games == 300
    for sc in b2.SCALES.values():  # episodes split evenly into parts and over the PPO seeds
        assert sc.episodes % sc.parts == 0 and (sc.episodes // sc.parts) % sc.seeds == 0


def test_smoke_run_files_numbers_resume_and_scale_guard(tmp_path, capsys):
    out = tmp_path / "b2"
    summary = b2.main(["--scale", "smoke", "--out", str(out), "--seed", "3"])
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert json.loads(last)["mean_error"] == summary["mean_error"]

    for f in ["config.json", "log.txt", "summary.json", "generated.npz", "tables/controllability.md",
              "tables/diversity.md", "tables/yield.md", "csv/controllability.csv", "csv/diversity.csv",
              "csv/yield.csv", "csv/generated.csv", "csv/ppo_train.csv", "stages/train.json",
              "stages/generate.json", "stages/report.json"]:
        assert (out / f).is_file(), f
    assert json.loads((out / "config.json").read_text())["scale"] == "smoke"
    for fig in ["tsne", "controllability"]:
        with Image.open(out / "figures" / f"{fig}.png") as im:
            im.load()
            assert im.size[0] > 100 and im.size[1] > 100
        assert (out / "figures" / f"{fig}.png").stat().st_size < 500_000
    saved = json.loads((out / "summary.json").read_text())
    assert set(saved["mean_error"]) == set(b2.METHODS)
    assert all(math.isfinite(v) for v in saved["mean_error"].values())
    assert saved["paper"]["mean_error"] == {"PCG-HR": 0.081, "PPO": 0.248, "PCG-RD": 0.373}

    # Training metrics: one row per update.
    cfg = b2.ppo_config(b2.SCALES["smoke"])
    train_rows = _csv(out / "csv" / "ppo_train.csv")
    assert [int(r["update"]) for r in train_rows] == list(range(1, cfg.n_updates + 1))

    # Raw generations: E episodes per target and method, one CSV row each.
    gens = b2.load_generated(out / "generated.npz")
    E = b2.SCALES["smoke"].episodes
    assert list(gens) == list(b2.METHODS)
    for g in gens.values():
        assert g["skill"].shape == (E * len(pm.TARGETS), 4)
    assert len(_csv(out / "csv" / "generated.csv")) == E * len(pm.TARGETS) * len(b2.METHODS)

    # The paper protocol (default): strict 4-decision smoke episodes (3 measured edits), the kept win
    # rate is the generator's own 16-game measurement.
    pr = b2.protocol_of(b2.SCALES["smoke"], "paper")
    assert saved["protocol"] == "paper"
    for g in gens.values():
        assert (g["edits"] == 3).all()
        np.testing.assert_array_equal(g["win_rate"], g["gen_win_rate"])
        assert np.allclose(g["win_rate"] * 16, np.round(g["win_rate"] * 16))

    # Controllability CSV == pcg_metrics.controllability recomputed from generated.npz, every
    # (method, target) group cut to the smallest group's size (here: E).
    rows = _csv(out / "csv" / "controllability.csv")
    for m, g in gens.items():
        c = pm.controllability(g, pr.min_edits, E, pr.seed)
        mine = {r["target"]: r for r in rows if r["method"] == m}
        assert float(mine["mean"]["err_mean"]) == pytest.approx(c["err_mean"], abs=1e-9)
        assert int(mine["mean"]["n"]) == c["n"]
        assert saved["mean_error"][m] == pytest.approx(c["err_mean"], abs=1e-9)
        for t, v in c["per_target"].items():
            r = mine[str(round(t, 3))]
            assert int(r["n"]) == v["n"]
            for k in ("wc_mean", "wc_sd", "err_mean", "err_sd"):
                assert float(r[k]) == pytest.approx(v[k], abs=1e-9)
        assert float(mine["0.1"]["paper_err_mean"]) == pytest.approx(
            {"PCG-HR": 0.044, "PPO": 0.156, "PCG-RD": 0.335}[m])

    # A second invocation resumes: every stage skipped, fast.
    n_log = len((out / "log.txt").read_text().splitlines())
    t = time.perf_counter()
    again = b2.main(["--scale", "smoke", "--out", str(out), "--seed", "3"])
    assert time.perf_counter() - t < 20
    new_log = (out / "log.txt").read_text().splitlines()[n_log:]
    assert sum("already done" in line for line in new_log) == 3
    assert again["mean_error"] == summary["mean_error"]

    # An interruption mid-training (the last checkpoint and the stage record lost): training resumes
    # from the previous checkpoint, redoes only the last update, bit-identically.
    import shutil

    import jax

    ckpt = out / "checkpoints" / "ppo"
    learner = b2._Learner(b2.RunFolder(out, json.loads((out / "config.json").read_text())), b2.SCALES["smoke"], 3)
    final = learner.restore(cfg.n_updates)
    shutil.rmtree(ckpt / str(cfg.n_updates))
    (out / "stages" / "train.json").unlink()
    b2.main(["--scale", "smoke", "--out", str(out), "--seed", "3"])
    log = (out / "log.txt").read_text()
    assert f"resumed from checkpoint at update {cfg.n_updates - 1}/{cfg.n_updates}" in log
    assert [int(r["update"]) for r in _csv(out / "csv" / "ppo_train.csv")] == list(range(1, cfg.n_updates + 1))
    again = learner.restore(cfg.n_updates)
    for x, y in zip(jax.tree.leaves(final), jax.tree.leaves(again), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))

    # Other settings into the same folder: a clear error.
    with pytest.raises(ValueError, match="other settings"):
        b2.main(["--scale", "cpu", "--out", str(out)])
    with pytest.raises(ValueError, match="seed"):
        b2.main(["--scale", "smoke", "--out", str(out), "--seed", "4"])
    # every variant is recorded in config.json
    for variant in (["--pool-repeats"], ["--ent-coef", "0.01"], ["--episodes", "4"], ["--one-lever"]):
        with pytest.raises(ValueError, match="other settings"):
            b2.main(["--scale", "smoke", "--out", str(out), "--seed", "3", *variant])
    np.testing.assert_array_equal(b2.load_generated(out / "generated.npz")["PPO"]["win_rate"],
                                  gens["PPO"]["win_rate"])

    # Weights-only restore (what generation uses) equals the full restore's weights.
    for x, y in zip(jax.tree.leaves(again["params"]), jax.tree.leaves(learner.restore_params(cfg.n_updates)),
                    strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))

    # Temperature sweep: the run's own baselines, PPO regenerated per temperature and cached.
    from experiments import b2_temperature

    capsys.readouterr()
    sweep = b2_temperature.main([str(out), "--temperatures", "0", "1", "--resamples", "5"])
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["key"] == 99
    for row in sweep["temperatures"]:
        assert row["all"]["PCG-HR"]["error"] == pytest.approx(saved["mean_error"]["PCG-HR"], abs=1e-9)
        assert len(row["per_seed"]) == b2.SCALES["smoke"].seeds
    cached = out / "temperature" / "T0.npz"
    ppo0 = b2.load_generated(cached)["PPO"]
    assert list(b2.load_generated(cached)) == ["PPO"] and ppo0["skill"].shape == gens["PPO"]["skill"].shape
    stamp = cached.stat().st_mtime_ns
    again_sweep = b2_temperature.main([str(out), "--temperatures", "0", "--resamples", "5"])
    assert cached.stat().st_mtime_ns == stamp  # reused, not regenerated
    assert again_sweep["temperatures"][0]["all"]["PPO"]["error"] == sweep["temperatures"][0]["all"]["PPO"]["error"]
    fresh = b2_temperature.main([str(out), "--temperatures", "1", "--resamples", "5", "--key", "7",
                                 "--fresh-baselines"])
    assert list(b2.load_generated(out / "temperature" / "T1_key7_all.npz")) == list(b2.METHODS)
    assert fresh["temperatures"][0]["all"]["PCG-HR"]["error"] != row["all"]["PCG-HR"]["error"]
    with pytest.raises(SystemExit, match="temperatures"):
        b2_temperature.main([str(out), "--temperatures", "-1"])

    # Lever report: one entry per PPO seed and PCG-HR, moves within the span.
    from experiments import b2_levers

    levers = b2_levers.main([str(out), "--episodes", "1"])["generators"]
    assert list(levers) == [f"PPO seed {s}" for s in range(b2.SCALES["smoke"].seeds)] + ["PCG-HR"]
    assert all(0 <= m <= 1 for g in levers.values() for m in g["abs"])


def test_b2_compare_splits_seeds_and_bootstraps():
    from experiments import b2_compare

    rng = np.random.default_rng(0)
    # 2 saved parts, each: seed 0's episodes (targets 0.1, 0.5), then seed 1's; seed 1 misses by 0.3.
    per_part_targets = np.array([0.1, 0.5, 0.1, 0.5])
    targets = np.concatenate([per_part_targets, per_part_targets])
    miss = np.tile([0.0, 0.0, 0.3, 0.3], 2)

    def method(err):
        n = len(targets)
        return {"target": targets, "skill": rng.uniform(size=(n, 4)), "win_rate": targets + err,
                "gen_win_rate": targets, "edits": np.full(n, 5), "reached": np.ones(n, bool)}

    n = len(targets)
    gens = {"PPO": method(miss), "PCG-HR": method(np.full(n, 0.05)), "PCG-RD": method(np.zeros(n))}
    seeds = b2_compare.per_seed(gens, {"seeds": 2, "parts": 2})
    assert [round(s["error"], 6) for s in seeds] == [0.0, 0.3]
    boot = b2_compare.bootstrap(gens, resamples=20)
    lo, hi = boot["error_diff_ci95"]
    assert lo <= 0.15 - 0.05 <= hi  # PPO 0.15 on average against PCG-HR 0.05


def test_b2_levers_moves_in_span_fractions_and_by_cheapest_parameter():
    from experiments.b2_levers import _split, moves
    from raidjax import pcg

    low, span = np.asarray(pcg.LOW), np.asarray(pcg.HIGH) - np.asarray(pcg.LOW)
    start = np.tile(low + 0.5 * span, (2, 1))
    skill = start + np.array([[0.25, 0.0, 0.0, 0.0], [0.0, 0.0, -0.5, 0.0]]) * span  # range up, cast down
    prefs = np.array([[0.3, 1.2, 1.2, 1.2], [1.2, 1.2, 0.3, 1.2]])
    gen = {"skill": skill, "start": start, "preferences": prefs, "win_rate": np.array([0.3, 0.5]),
           "target": np.array([0.2, 0.5]), "edits": np.array([2, 4])}
    out = moves(gen)
    np.testing.assert_allclose(out["abs"], [0.125, 0, 0.25, 0], atol=1e-3)
    np.testing.assert_allclose(out["signed"], [0.125, 0, -0.25, 0], atol=1e-3)
    assert out["error"] == pytest.approx(0.05) and out["edits"] == 3.0
    assert out["by_cheapest"]["range"] == {"n": 1, "abs": [0.25, 0.0, 0.0, 0.0]}
    assert out["by_cheapest"]["cast_time"]["abs"] == [0.0, 0.0, 0.5, 0.0]
    assert "by_cheapest" not in moves({**gen, "preferences": np.ones((2, 4))})
    assert "final_by_goal" not in moves({**gen, "goal": start})  # no style goals: the goal is the start
    goal = np.array([pcg.HIGH, [pcg.LOW[0], pcg.HIGH[1], pcg.LOW[2], pcg.LOW[3]]])
    by_goal = moves({**gen, "goal": goal})["final_by_goal"]
    assert by_goal["high"] == [0.75, 0.5, 0.5, 0.5]  # episode 0 (range ends at 0.75) / both for cool time
    assert by_goal["low"] == [0.5, None, 0.0, 0.5]  # episode 1 (cast ends at 0); no goal has cool time low
    first, second = _split(gen, 2)
    np.testing.assert_array_equal(second["skill"], skill[1:])
    np.testing.assert_array_equal(first["edits"], [2])
