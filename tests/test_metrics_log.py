"""The trainers' shared metrics writer (``trainers.metrics``): resume trimming, torn lines, valid JSON."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from trainers.metrics import MetricsLog, update_rows


def _rows(path):
    return [json.loads(s) for s in path.read_text().splitlines()]


def test_resume_keeps_rows_up_to_the_checkpoint_and_drops_a_torn_line(tmp_path):
    log = MetricsLog(tmp_path, tensorboard=False)
    for u in (1, 2, 3):
        log.write({"update": u, "loss": 0.5 * u, "per_group": [u, u]})
    with (tmp_path / "metrics.jsonl").open("a") as f:
        f.write('{"update": 4, "lo')  # a run killed mid-write
    log = MetricsLog(tmp_path, resume_update=2, tensorboard=False)
    assert [r["update"] for r in _rows(tmp_path / "metrics.jsonl")] == [1, 2]
    log.write({"update": 3, "loss": 9.0, "per_group": [3, 3]})
    assert [r["loss"] for r in _rows(tmp_path / "metrics.jsonl")] == [0.5, 1.0, 9.0]
    with open(tmp_path / "metrics.csv", newline="") as f:
        table = list(csv.DictReader(f))
    assert [float(r["loss"]) for r in table] == [0.5, 1.0, 9.0] and "per_group" not in table[0]
    MetricsLog(tmp_path, tensorboard=False)  # a fresh run (no resume) starts both files empty
    assert (tmp_path / "metrics.jsonl").read_text() == "" and (tmp_path / "metrics.csv").read_text() == ""



def test_a_resumed_run_hides_tensorboard_points_it_logs_again(tmp_path, monkeypatch):
    """tensorboardX (an optional extra) stood in for by a writer that records how it was opened: a
    resume from update 2 purges TensorBoard's points from the step after update 2's (env_steps
    200), so the updates logged again after the checkpoint do not show twice; a first start marks
    step 0 (TensorBoard ignores a folder's first marker). Logs of other names (Benchmark 1's groups)
    have folders of their own, so one's purge never hides another's curves."""
    import sys
    import types

    opened, points = [], []

    class Writer:
        def __init__(self, logdir, purge_step=None):
            opened.append((Path(logdir).name, purge_step))

        def add_scalar(self, tag, value, step):
            points.append((tag, step))

        def flush(self):
            pass

    monkeypatch.setitem(sys.modules, "tensorboardX", types.SimpleNamespace(SummaryWriter=Writer))
    log = MetricsLog(tmp_path)
    for u in (1, 2, 3):
        log.write({"update": u, "env_steps": 100 * u, "loss": 0.5})
    MetricsLog(tmp_path, resume_update=2)
    MetricsLog(tmp_path, resume_update=0)  # no row kept: every earlier point is hidden
    MetricsLog(tmp_path, name="metrics_group1")
    assert opened == [("tensorboard", 0), ("tensorboard", 201), ("tensorboard", 0),
                      ("tensorboard_metrics_group1", 0)] and ("loss", 300) in points

def test_nan_is_written_as_json_null(tmp_path):
    log = MetricsLog(tmp_path, tensorboard=False)
    log.write({"update": 1, "final_error": float("nan"), "x": [float("inf"), 1.0]})
    assert _rows(tmp_path / "metrics.jsonl") == [{"update": 1, "final_error": None, "x": [None, 1.0]}]


def test_update_rows_average_groups_and_keep_nan_when_no_group_has_a_value():
    m = {"final_error": np.array([[0.1, np.nan], [0.3, np.nan]]), "reward": np.array([[1.0, 2.0], [3.0, 4.0]])}
    rows = update_rows(4, m, steps_per_update=10)
    assert [r["update"] for r in rows] == [5, 6] and [r["env_steps"] for r in rows] == [50, 60]
    assert abs(rows[0]["final_error"] - 0.2) < 1e-12
    assert np.isnan(rows[1]["final_error"]) and rows[1]["reward"] == 3.0
    assert rows[0]["final_error_per_group"] == [0.1, 0.3]


def test_plot_writes_its_figure_atomically(tmp_path, monkeypatch):
    from trainers import plot

    run = tmp_path / "run"
    log = MetricsLog(run, tensorboard=False)
    for u in (1, 2):
        log.write({"update": u, "env_steps": 100 * u, "win_rate": 0.1 * u, "return": float(u)})
    written = []
    monkeypatch.setattr(plot, "atomic_write", lambda path, data: written.append((str(path), data[:8])))
    plot.main([str(run), "--out", str(tmp_path / "curves.png")])
    assert written == [(str(tmp_path / "curves.png"), b"\x89PNG\r\n\x1a\n")]


def test_plot_reads_a_live_run_a_torn_last_row_and_a_missing_value(tmp_path):
    """``trainers.plot`` is for live and killed runs too: a last row without its line end is left out,
    and a metric without a value (NaN, an empty csv cell) is NaN, not a refused table."""
    from trainers import plot

    run = tmp_path / "run"
    log = MetricsLog(run, tensorboard=False)
    for u, ev in ((1, float("nan")), (2, 0.5)):
        log.write({"update": u, "env_steps": 100 * u, "win_rate": 0.1 * u, "return": float(u),
                   "value_explained_variance": ev})
    with (run / "metrics.csv").open("a") as f:
        f.write("3,300,0.")  # the row of update 3, cut in the middle of a number
    m = plot.read_metrics(run)
    assert m["env_steps"] == [100.0, 200.0] and m["win_rate"] == [0.1, 0.2]
    assert np.isnan(m["value_explained_variance"][0]) and m["value_explained_variance"][1] == 0.5
    plot.main([str(run), "--out", str(tmp_path / "curves.png")])
    assert (tmp_path / "curves.png").read_bytes()[:4] == b"\x89PNG"
