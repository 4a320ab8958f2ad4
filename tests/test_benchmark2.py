"""``experiments.benchmark2`` at the smoke scale: files, numbers recomputed from the raw
generated skills, resume (whole stages, the PPO checkpoint, and the command killed during training,
generation and the report) and the scale guard."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import shutil
import time

import jax
import numpy as np
import pytest
from fault_inject import run, steps
from PIL import Image

from experiments import b2_report
from experiments import benchmark2 as b2
from raidjax.pcg import quality as pm
from trainers import checkpoint

# Two generation parts of the smoke scale's 2 episodes per target and method.
SMOKE = ["--scale", "smoke", "--seed", "3", "--episodes", "4"]
E = 4


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    """One uninterrupted smoke run, shared by the tests below: ``(folder, summary, last stdout line)``
    (a test that changes the folder works on a copy)."""
    out = tmp_path_factory.mktemp("b2") / "uninterrupted"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        summary = b2.main([*SMOKE, "--out", str(out)])
    return out, summary, buf.getvalue().strip().splitlines()[-1]


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
    # gpu: the paper's models and measurements, 1000 skills per target and method (300 are kept).
    g = b2.SCALES["gpu"]
    assert b2.ppo_config(g) == cfg and (g.seeds, g.eval_games, g.gen_games, g.episodes) == (5, 300, 300, 1000)
    for sc in b2.SCALES.values():  # episodes split evenly into parts and over the PPO seeds
        assert sc.episodes % sc.parts == 0 and (sc.episodes // sc.parts) % sc.seeds == 0


def test_smoke_run_files_numbers_resume_and_scale_guard(tmp_path, smoke_run):
    out = tmp_path / "b2"
    shutil.copytree(smoke_run[0], out)
    summary, last = smoke_run[1:]
    assert json.loads(last)["mean_error"] == summary["mean_error"]

    for f in ["config.json", "log.txt", "summary.json", "generated.npz", "tables/controllability.md",
              "tables/diversity.md", "tables/yield.md", "tables/summary.md", "csv/controllability.csv",
              "csv/diversity.csv", "csv/yield.csv", "csv/generated.csv", "train/metrics.csv",
              "train/metrics_paper.csv", "stages/train.json", "stages/train_paper_ppo.json",
              "stages/generate.json", "stages/report.json", "stages/records.json"]:
        assert (out / f).is_file(), f
    assert json.loads((out / "config.json").read_text())["scale"] == "smoke"
    # a line after each of a part's measurements (the start's and 3 edits' of strict 4-decision
    # episodes), with an ETA from the second
    for part in ("1/2", "2/2"):
        lines = [s for s in (out / "log.txt").read_text().splitlines() if f"generate: part {part}: measurement" in s]
        assert [s.split("measurement ")[1].split(":")[0] for s in lines] == ["1/4", "2/4", "3/4", "4/4"]
        assert "ETA" not in lines[0] and all("ETA at most" in s for s in lines[1:]), lines
    methods = b2.methods_of(b2.SCALES["smoke"])  # both PPOs (the paper's and raidjax's), then the baselines
    assert methods == ("PPO, target observed", "PPO", "PCG-HR", "PCG-RD")
    assert set(summary["ci95"]) == set(methods) and all(len(v) == 2 for c in summary["ci95"].values()
                                                            for v in c.values())
    for fig in ["tsne", "controllability", "error_vs_diversity"]:
        with Image.open(out / "figures" / f"{fig}.png") as im:
            im.load()
            assert im.size[0] > 100 and im.size[1] > 100
        assert (out / "figures" / f"{fig}.png").stat().st_size < 500_000
    saved = json.loads((out / "summary.json").read_text())
    assert set(saved["mean_error"]) == set(methods)
    assert all(math.isfinite(v) for v in saved["mean_error"].values())
    assert saved["paper"]["mean_error"] == {"PCG-HR": 0.081, "PPO": 0.248, "PCG-RD": 0.373}

    # Training metrics: one row per update.
    cfg = b2.ppo_config(b2.SCALES["smoke"])
    train_rows = _csv(out / "train" / "metrics.csv")
    assert [int(r["update"]) for r in train_rows] == list(range(1, cfg.num_updates + 1))

    # Raw generations: E episodes per target and method, one CSV row each.
    gens = b2.load_generated(out / "generated.npz")
    assert list(gens) == list(methods)
    for g in gens.values():
        assert g["skill"].shape == (E * len(pm.TARGETS), 4)
    assert len(_csv(out / "csv" / "generated.csv")) == E * len(pm.TARGETS) * len(methods)

    # The paper protocol (default): strict 4-decision smoke episodes (3 measured edits), the kept win
    # rate is the generator's own eval_games-game measurement.
    pr = b2.protocol_of(b2.SCALES["smoke"], "paper")
    assert saved["protocol"] == "paper"
    for g in gens.values():
        assert (g["edits"] == 3).all()
        np.testing.assert_array_equal(g["win_rate"], g["gen_win_rate"])
        n = b2.SCALES["smoke"].eval_games
        assert np.allclose(g["win_rate"] * n, np.round(g["win_rate"] * n))

    # Controllability CSV == pcg.quality.controllability recomputed from generated.npz, every
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
        paper = {"PCG-HR": 0.044, "PPO": 0.156, "PCG-RD": 0.335}.get(m, float("nan"))  # nothing for raidjax's PPO
        assert float(mine["0.1"]["paper_err_mean"]) == pytest.approx(paper, nan_ok=True)

    # The error-vs-diversity scatter plots the CSVs' numbers: per (method, target) (err_mean, pc1).
    num = lambda r: {**r, "target": r["target"] if r["target"] == "mean" else float(r["target"]),
                     **{k: float(r[k]) for k in ("err_mean", "pc1") if k in r}}
    crow, drow = [num(r) for r in rows], [num(r) for r in _csv(out / "csv" / "diversity.csv")]
    _check_scatter(crow, drow)

    # The finished run resumed: a no-op that says so, fast.
    n_log = len((out / "log.txt").read_text().splitlines())
    t = time.perf_counter()
    again = b2.main([*SMOKE, "--out", str(out), "--resume"])
    assert time.perf_counter() - t < 20
    new_log = (out / "log.txt").read_text().splitlines()[n_log:]
    assert any("already finished: nothing to do" in line for line in new_log)
    assert again["mean_error"] == summary["mean_error"]

    # A report setting changed: only the report is done again, with it; then a no-op again.
    regen = (out / "generated.npz").stat().st_mtime_ns
    again = b2.main([*SMOKE, "--out", str(out), "--resume", "--min-kept", "3"])
    new_log = (out / "log.txt").read_text().splitlines()[n_log:]
    assert any("stage report: to be done again (min_kept 2 -> 3)" in line for line in new_log)
    assert any("stage generate: already done, skipped" in line for line in new_log)
    assert (out / "generated.npz").stat().st_mtime_ns == regen and again["mean_error"] == summary["mean_error"]
    assert json.loads((out / "config.json").read_text())["min_kept"] == 3
    div = [r for r in _csv(out / "csv" / "diversity.csv") if r["target"] != "mean"]
    measured = {int(r["n_kept"]) for r in div if int(r["kept"]) >= 3}
    assert all(int(r["n_kept"]) == 0 and r["pc1"] in ("", "nan") for r in div if int(r["kept"]) < 3)
    assert len(measured) <= 1 and all(n >= 3 for n in measured)  # one size, the smallest group left in
    n_log = len((out / "log.txt").read_text().splitlines())
    b2.main([*SMOKE, "--out", str(out), "--resume", "--min-kept", "3"])
    assert any("already finished: nothing to do" in line for line in (out / "log.txt").read_text().splitlines()[n_log:])

    # Other settings into the same folder: a clear error.
    with pytest.raises(ValueError, match="other settings"):
        b2.main(["--scale", "cpu", "--out", str(out), "--resume"])
    with pytest.raises(ValueError, match="seed: saved 3, now 4"):
        b2.main(["--scale", "smoke", "--out", str(out), "--seed", "4", "--episodes", "4", "--resume"])
    with pytest.raises(ValueError, match="already holds a run: pass --resume"):
        b2.main([*SMOKE, "--out", str(out)])
    # every variant is recorded in config.json
    for variant in (["--pool-repeats"], ["--ent-coef", "0.01"], ["--episodes", "6"],
                    ["--edit-cost", "2", "--goal-cost", "1", "--goal-axis", "1,1,1,1"]):
        with pytest.raises(ValueError, match="other settings"):
            b2.main([*SMOKE, "--out", str(out), "--resume", *variant])
    np.testing.assert_array_equal(b2.load_generated(out / "generated.npz")["PPO"]["win_rate"],
                                  gens["PPO"]["win_rate"])

    # Weights-only restore (what generation uses) equals the full restore's weights.
    learner = b2._Learner(b2.RunFolder(out, json.loads((out / "config.json").read_text()), resume=True),
                          b2.scale_of(b2._parse([*SMOKE, "--out", str(out)])), 3)
    final, _ = learner.restore()
    weights, _ = checkpoint.load_policy_weights(out / "checkpoints" / "ppo")
    for x, y in zip(jax.tree.leaves(final["params"]), jax.tree.leaves(weights), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


SUMMARY_FIELDS = ("mean_error", "pc1_sd", "pc1_own_sd", "yield", "edits", "n_controllability", "ci95", "episodes",
                  "train_steps", "paper_ppo_train_steps")


def test_killed_in_training_generation_and_report_it_resumes_to_the_same_tables(tmp_path, smoke_run):
    # kill -9 (fault_inject.py) during PPO training, while a generation part is saved and during the
    # report: --resume generates every part once, loses none, and ends where the uninterrupted run did.
    ref, out = smoke_run[0], tmp_path / "faulty"

    def faulty(fault: str, killed: bool = True, resume: bool = True):
        return run(fault, "experiments.benchmark2", [*SMOKE, "--out", str(out)] + ["--resume"] * resume, killed)

    faulty("after_save=1", resume=False)  # raidjax's PPO: update 1 of 2 checkpointed, then killed
    assert steps(out / "checkpoints" / "ppo") == [1] and not (out / "stages" / "train.json").exists()
    faulty("mid_file@part_001.npz=1")  # training finished from update 1; part 0 saved; killed saving part 1
    assert (out / "gen_parts" / "part_000.npz").is_file() and not (out / "gen_parts" / "part_001.npz").exists()
    assert "resumed from the checkpoint at update 1/2" in (out / "log.txt").read_text()
    faulty("mid_file@controllability.md=1")  # part 0 loaded, part 1 generated; killed writing the first table
    assert (out / "stages" / "generate.json").is_file() and not (out / "summary.json").exists()
    p = faulty("none", killed=False)
    assert "removed an unfinished temporary file" in p.stdout

    # Every part generated once: a killed part had not finished, and was generated again, whole.
    log = (out / "log.txt").read_text()
    assert log.count("generate: part 1/2 ") == 1 and log.count("generate: part 2/2 ") == 1
    records = json.loads((out / "stages" / "records.json").read_text())
    assert {"started", "train", "train_paper_ppo", "generate/part_000", "generate/part_001", "generate",
            "report"} <= set(records)
    assert all(r["start"] <= r["end"] and r["machine"]["commit"] for r in records.values())

    # The uninterrupted run's networks, tables, CSVs and skills, bit for bit.
    for name in ("ppo", "ppo_paper"):
        wa, _ = checkpoint.load_policy_weights(out / "checkpoints" / name)
        wb, _ = checkpoint.load_policy_weights(ref / "checkpoints" / name)
        for x, y in zip(jax.tree.leaves(wa), jax.tree.leaves(wb), strict=True):
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    for sub in ("tables", "csv"):
        files = sorted(p.name for p in (ref / sub).iterdir())
        assert files == sorted(p.name for p in (out / sub).iterdir()) and files
        for name in files:
            assert (out / sub / name).read_bytes() == (ref / sub / name).read_bytes(), f"{sub}/{name}"
    gens, gens_ref = b2.load_generated(out / "generated.npz"), b2.load_generated(ref / "generated.npz")
    assert list(gens) == list(gens_ref)
    for m in gens:
        for k in b2.FIELDS:
            np.testing.assert_array_equal(gens[m][k], gens_ref[m][k], err_msg=f"{m}/{k}")
    summary, summary_ref = (json.loads((d / "summary.json").read_text()) for d in (out, ref))
    assert {k: summary[k] for k in SUMMARY_FIELDS} == {k: summary_ref[k] for k in SUMMARY_FIELDS}
    assert summary["compute_seconds"] > 0 and summary["span_seconds"] >= 0
    assert not list(out.rglob(".*.tmp"))


def _check_scatter(crow, drow):
    """``error_vs_diversity_figure(crow, drow)`` holds, per method, exactly the finite (pc1, err_mean)
    pairs of its per-target rows, and its ``mean`` rows' pair; returns the figure's points."""
    import matplotlib.pyplot as plt

    from experiments import b2_report

    fig = b2_report.error_vs_diversity_figure(crow, drow)
    ax = fig.axes[0]
    drawn = {c.get_label(): np.asarray(c.get_offsets(), float) for c in ax.collections}
    for m in dict.fromkeys(r["method"] for r in crow):
        err = {r["target"]: r["err_mean"] for r in crow if r["method"] == m and r["target"] != "mean"}
        pc1 = {r["target"]: r["pc1"] for r in drow if r["method"] == m and r["target"] != "mean"}
        want = sorted((pc1[t], err[t]) for t in err if math.isfinite(err[t]) and math.isfinite(pc1.get(t, math.nan)))
        got = sorted(map(tuple, drawn[f"{m}: per target"].tolist()))
        np.testing.assert_allclose(np.asarray(got).reshape(-1, 2), np.asarray(want).reshape(-1, 2))
        mean = (next(r["pc1"] for r in drow if r["method"] == m and r["target"] == "mean"),
                next(r["err_mean"] for r in crow if r["method"] == m and r["target"] == "mean"))
        if all(map(math.isfinite, mean)):
            np.testing.assert_allclose(drawn[f"{m}: mean"], [mean])
    assert "diversity" in ax.get_xlabel() and "|W_t − W_c|" in ax.get_ylabel()
    plt.close(fig)
    return drawn


def test_error_vs_diversity_figure_points_legend_and_gaps():
    """Synthetic rows: one dot per target with both numbers (a NaN PC1 SD is left out and counted
    in the title), a diamond per method mean, the paper's mean as a hollow square, a legend."""
    crow = [{"method": m, "target": t, "err_mean": e} for m, es in (("PPO", (0.3, 0.2)), ("PCG-HR", (0.05, 0.1)))
            for t, e in zip((0.1, 0.2), es, strict=True)]
    crow += [{"method": "PPO", "target": "mean", "err_mean": 0.25}, {"method": "PCG-HR", "target": "mean",
                                                                     "err_mean": 0.075}]
    drow = [{"method": "PPO", "target": 0.1, "pc1": 0.5}, {"method": "PPO", "target": 0.2, "pc1": math.nan},
            {"method": "PPO", "target": "mean", "pc1": 0.5}, {"method": "PCG-HR", "target": 0.1, "pc1": 0.2},
            {"method": "PCG-HR", "target": 0.2, "pc1": 0.3}, {"method": "PCG-HR", "target": "mean", "pc1": 0.25}]
    drawn = _check_scatter(crow, drow)
    np.testing.assert_allclose(drawn["PPO: per target"], [[0.5, 0.3]])  # target 0.2 (no PC1 SD) left out
    np.testing.assert_allclose(drawn["PCG-HR: per target"], [[0.2, 0.05], [0.3, 0.1]])
    np.testing.assert_allclose(drawn["PPO: paper's mean"], [[0.513, 0.248]])
    import matplotlib.pyplot as plt

    from experiments import b2_report

    fig = b2_report.error_vs_diversity_figure(crow, drow)
    assert "; 1 (method, target) group lacking a number not shown" in fig.axes[0].get_title()
    assert len(fig.axes[0].get_legend().get_texts()) == 6  # 2 methods x (per target, mean, paper)
    plt.close(fig)


def test_the_t_sne_draws_only_the_kept_skills():
    gens = {"A": {"target": np.array([0.1, 0.5, 0.7]), "win_rate": np.array([0.15, 0.2, 0.61]),
                  "skill": np.arange(12.0).reshape(3, 4)},
            "B": {"target": np.array([0.3]), "win_rate": np.array([0.9]), "skill": np.zeros((1, 4))}}
    kept = b2_report.kept_skills(gens)  # |W_t - W_c| < 0.1: A's first and third; B has none
    assert list(kept) == ["A"]
    np.testing.assert_array_equal(kept["A"]["skill"], gens["A"]["skill"][[0, 2]])
    np.testing.assert_array_equal(kept["A"]["target"], [0.1, 0.7])


def test_the_plan_counts_the_games_a_run_plays():
    # smoke: raidjax's PPO, 2 updates x 4 arenas x 4 steps x 4 games, and the paper's, 7 models x
    # 1 update x 2 x 2 steps x 4 games; paper protocol at 4 decisions: a start measurement and 3
    # measured edits of 4 games, for 4 methods x 7 targets x 2 episodes.
    s = b2.SCALES["smoke"]
    assert b2.planned_games(s, b2.protocol_of(s, "paper")) == (2 * 4 * 4 * 4 + 7 * 2 * 2 * 4, 4 * 7 * 2 * 4 * 4)
    # cpu: 40 updates x 32 x 8 steps x 50 games, and 7 models x 166 updates x 4 x 30 steps x 100 games
    # (20 000 steps: 166 whole updates of 120); 40 measurements of 300 games per episode, 30 episodes.
    c = b2.SCALES["cpu"]
    assert b2.planned_games(c, b2.protocol_of(c, "paper")) == (40 * 256 * 50 + 7 * 166 * 120 * 100,
                                                               4 * 7 * 30 * 40 * 300)


def test_episodes_flag_adds_parts_of_the_scales_size():
    # A larger --episodes keeps the episodes per part, so a finished run's parts (keyed by their
    # index alone) are the first parts of the longer run; a count that does not split is refused.
    cpu = b2.scale_of(b2._parse(["--scale", "cpu", "--out", "x", "--episodes", "40"]))
    assert (cpu.episodes, cpu.parts) == (40, 4) and b2.SCALES["cpu"].episodes // b2.SCALES["cpu"].parts == 10
    paper = b2.scale_of(b2._parse(["--scale", "paper", "--out", "x", "--episodes", "200"]))
    assert (paper.episodes, paper.parts) == (200, 2)
    with pytest.raises(ValueError, match="--episodes: 150 must be a multiple of the paper scale's 100"):
        b2.scale_of(b2._parse(["--scale", "paper", "--out", "x", "--episodes", "150"]))
    with pytest.raises(ValueError, match="--seeds: 3 PPO seeds must split the 2 episodes"):
        b2.scale_of(b2._parse(["--scale", "smoke", "--out", "x", "--seeds", "3"]))


def test_bootstrap_intervals_bracket_the_estimate_and_collapse_on_identical_episodes():
    from experiments import b2_report

    rng = np.random.default_rng(0)
    t = np.repeat(np.asarray(pm.TARGETS, np.float32), 4)

    def gen(noise: float) -> dict:
        skill = rng.uniform(0, 1, (len(pm.TARGETS), 4)).astype(np.float32).repeat(4, 0)
        return {"target": t, "skill": skill, "win_rate": np.clip(t + noise, 0, 1).astype(np.float32),
                "gen_win_rate": t, "edits": np.full(len(t), 39), "reached": np.ones(len(t), bool)}

    # Every episode of a (method, target) group alike: every resample is the data itself.
    same = {"PPO": gen(0.05), "PCG-HR": gen(0.1)}
    ci = b2_report.bootstrap(same, pm.PROTOCOLS["paper"], n_boot=20)
    est = pm.summarize(same, pm.PROTOCOLS["paper"])
    for m in same:
        assert ci[m]["mean_error"] == pytest.approx((est[m]["controllability"]["err_mean"],) * 2)
    noisy = {"PPO": {**gen(0.0), "win_rate": np.clip(t + rng.normal(0, 0.1, len(t)), 0, 1).astype(np.float32)}}
    lo, hi = b2_report.bootstrap(noisy, pm.PROTOCOLS["paper"], n_boot=200)["PPO"]["mean_error"]
    assert lo < pm.summarize(noisy, pm.PROTOCOLS["paper"])["PPO"]["controllability"]["err_mean"] < hi
