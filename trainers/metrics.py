"""The metrics writer of both trainers: one row per logged step in ``DIR/metrics.jsonl`` (every
field) and ``DIR/metrics.csv`` (the scalar fields), optionally mirrored to TensorBoard.

On resume, rows past the checkpoint are dropped first, so a resumed run's log reads as if it had
never stopped; a torn line (a kill in the middle of a write) is dropped with a warning naming the
file. Both files are rewritten atomically when trimmed and appended one whole row at a time
(one ``write`` call) afterwards.
"""

from __future__ import annotations

import csv
import io
import json
import math
import sys
from pathlib import Path

import numpy as np

from raidjax.io import atomic_write, finite_json


def _scalar(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _tensorboard_writer(folder: Path, purge_step: int):
    """A ``tensorboardX.SummaryWriter`` on ``folder``, or ``None`` if it is not installed.
    ``purge_step``: TensorBoard hides the earlier event files' points from this step on (the ones a
    resumed run logs again); a first start gives 0, so that a resume's is not the folder's first
    (TensorBoard ignores a folder's first start marker)."""
    try:
        from tensorboardX import SummaryWriter
    except ImportError:
        return None
    return SummaryWriter(str(folder), purge_step=purge_step)


def _tensorboard_step(row: dict) -> int:
    """A row's step on TensorBoard's axis: its decisions so far, else its update."""
    return int(row.get("env_steps", row["update"]))


class MetricsLog:
    """Rows keyed by ``update`` (an int that grows with every row).

    Args:
        out: the run folder.
        resume_update: keep the rows with ``update <= resume_update`` from an earlier run (the
            update of the checkpoint resumed from); ``None`` starts both files empty.
        tensorboard: also write the scalar fields to ``DIR/tensorboard`` (``DIR/tensorboard_<name>``
            for another ``name``: a purge on resume hides every curve of its folder) when ``tensorboardX`` is
            installed.
        name: the files' name, ``DIR/<name>.jsonl`` and ``DIR/<name>.csv``.
    """

    def __init__(self, out: str | Path, resume_update: int | None = None, tensorboard: bool = True,
                 name: str = "metrics"):
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        self.jsonl, self.csv = out / f"{name}.jsonl", out / f"{name}.csv"
        rows = []
        if resume_update is not None and self.jsonl.exists():
            for i, line in enumerate(self.jsonl.read_text().splitlines(), 1):
                try:
                    row = json.loads(line)
                except json.JSONDecodeError:  # a torn last line from a killed run
                    print(f"warning: {self.jsonl} line {i} is not a whole JSON row (a write cut short); dropped",
                          file=sys.stderr, flush=True)
                    continue
                if isinstance(row, dict) and row.get("update", math.inf) <= resume_update:
                    rows.append(row)
        self.fields = [k for k, v in rows[0].items() if _scalar(v) or v is None] if rows else None
        atomic_write(self.jsonl, "".join(json.dumps(r) + "\n" for r in rows))
        atomic_write(self.csv, self._csv_text(rows, header=bool(rows)))
        folder = out / ("tensorboard" if name == "metrics" else f"tensorboard_{name}")
        purge = _tensorboard_step(rows[-1]) + 1 if rows else 0  # a resume hides what came after the kept rows
        self.tb = _tensorboard_writer(folder, purge) if tensorboard else None

    def _csv_text(self, rows: list[dict], header: bool) -> str:
        buf = io.StringIO()
        if self.fields:
            w = csv.DictWriter(buf, self.fields, extrasaction="ignore")
            if header:
                w.writeheader()
            w.writerows(rows)
        return buf.getvalue()

    def write(self, row: dict) -> None:
        """Append one row (a dict with an ``update`` key) to both files, and to TensorBoard."""
        row = json.loads(finite_json(row))  # NaN as null, numpy scalars as numbers
        if self.tb is not None:
            step = _tensorboard_step(row)
            for k, v in row.items():
                if _scalar(v):
                    self.tb.add_scalar(k, v, step)
            self.tb.flush()
        with self.jsonl.open("a") as f:
            f.write(json.dumps(row) + "\n")
        new = self.fields is None
        if new:
            self.fields = [k for k, v in row.items() if _scalar(v) or v is None]
        with self.csv.open("a", newline="") as f:
            f.write(self._csv_text([row], header=new))


def update_rows(start_update: int, metrics: dict, steps_per_update: int) -> list[dict]:
    """One row per update of a chunk of grouped metrics (PPO-PCGRL): ``update``, ``env_steps`` and
    every metric averaged over the groups (NaN when no group has a finite value), plus
    ``final_error_per_group`` (list of G floats).

    Args:
        start_update: updates done before the chunk.
        metrics: chunk metrics, host arrays ``[G, n]`` (groups x updates).
        steps_per_update: generator steps per update and group.
    """
    n = next(iter(metrics.values())).shape[1]
    rows = []
    for i in range(n):
        u = start_update + i + 1
        row = {k: float(np.nanmean(v[:, i])) if np.isfinite(v[:, i]).any() else float("nan")
               for k, v in sorted(metrics.items())}
        rows.append({"update": u, "env_steps": u * steps_per_update, **row,
                     "final_error_per_group": [float(x) for x in metrics["final_error"][:, i]]})
    return rows
