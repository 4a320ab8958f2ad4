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
                             "checkpoints": sorted(p.name for p in (out / "checkpoints" / "mapoca").iterdir()
                                                   if p.name.isdigit())}
    summary = benchmark1.main(["--scale", "smoke", "--out", str(out), "--resume"])  # resumes and finishes
    return out, first, state_after_interrupt, summary


def test_interrupted_run_resumes_mid_training(run):
    out, first, after, summary = run
    assert first == {"interrupted": True}
    assert not after["train_done"] and after["checkpoints"] == ["1"]  # chunk 1 of 2 checkpointed
    log = (out / "log.txt").read_text()
    assert "resumed at chunk 1/2" in log
    chunks = [json.loads(s)["chunk"] for s in (out / "train" / "metrics.jsonl").read_text().splitlines()]
    assert chunks == [0, 1]  # one row per chunk, none lost or repeated across the interruption
    assert summary["train"]["decisions_per_run"] == 256


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
    for row in _rows(out / "csv" / "win_rate_table.csv"):
        own = [float(c["win_rate"]) for c in cells if c["agent"] == row["agent"] and c["content"] == "reference"
               and float(c["range"]) == float(row["range"]) and c["group"] != "population"]
        assert float(row["mean"]) == pytest.approx(np.mean(own))
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
