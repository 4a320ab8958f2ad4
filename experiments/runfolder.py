"""A resumable, atomically written run folder shared by the benchmark pipelines.

Layout of ``DIR``::

    config.json     the scale and every setting of the run (a rerun must match it)
    log.txt         timestamped progress lines (also printed)
    stages/*.json   one file per finished stage: its JSON result; a rerun skips finished stages
                    (stages/seconds.json: each finished stage's wall seconds)
    csv/*.csv       every number the run measured
    tables/*.md     the tables, our numbers beside the paper's
    figures/*.png   the figures
    checkpoints/    learner checkpoints (orbax)
    summary.json    the final summary (also the last stdout line)

Every file is written to a temporary name and renamed into place, so an interrupted run never
leaves a half-written file: rerunning the same command resumes after the last finished stage.
"""

from __future__ import annotations

import csv
import io
import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from raidjax.utils import atomic_write, fmt_seconds, machine


class RunFolder:
    """The run folder ``out`` of one pipeline at one scale.

    Args:
        out: the folder (created).
        config: JSON-able settings of the run. If ``out/config.json`` exists it must be equal
            (otherwise ``ValueError`` naming the differing keys): resuming with other settings
            would mix incompatible numbers.
    """

    def __init__(self, out: str | Path, config: dict):
        self.out = Path(out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.t0 = time.perf_counter()
        cfg_path = self.out / "config.json"
        config = json.loads(json.dumps(config))
        if cfg_path.exists():
            old = json.loads(cfg_path.read_text())
            diff = sorted(k for k in set(old) | set(config) if old.get(k) != config.get(k))
            if diff:
                raise ValueError(f"{self.out} holds a run with other settings ({', '.join(diff)}): "
                                 "use a new --out, or the same --scale and options to resume")
            self.log(f"resuming run in {self.out}")
        else:
            atomic_write(cfg_path, json.dumps(config, indent=1))
        self.config = config

    def path(self, *parts: str) -> Path:
        """``out/parts...`` with its parent folder created."""
        p = self.out.joinpath(*parts)
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def log(self, msg: str) -> None:
        """Print ``msg`` and append it with a timestamp to ``log.txt``."""
        line = f"[{time.strftime('%H:%M:%S')} +{fmt_seconds(time.perf_counter() - self.t0)}] {msg}"
        print(line, flush=True)
        with open(self.out / "log.txt", "a") as f:
            f.write(line + "\n")

    def done(self, name: str) -> bool:
        """Whether stage ``name`` has finished (its result is on disk)."""
        return (self.out / "stages" / f"{name}.json").exists()

    def stage(self, name: str, fn: Callable[[], Any]) -> Any:
        """Run ``fn()`` once: return its stored JSON result if stage ``name`` already finished,
        otherwise run it, store the (JSON-able) result atomically and return it."""
        p = self.out / "stages" / f"{name}.json"
        if p.exists():
            self.log(f"stage {name}: already done, skipped")
            return json.loads(p.read_text())
        t = time.perf_counter()
        self.log(f"stage {name}: start")
        result = fn()
        seconds = time.perf_counter() - t
        atomic_write(self.path("stages", f"{name}.json"), json.dumps(result, indent=1, default=float))
        timings = self.stage_seconds()
        timings[name] = seconds
        atomic_write(self.out / "stages" / "seconds.json", json.dumps(timings, indent=1))
        self.log(f"stage {name}: done in {fmt_seconds(seconds)}")
        return json.loads(json.dumps(result, default=float))

    def stage_seconds(self) -> dict:
        """Wall seconds of every finished stage (of the invocation that finished it)."""
        p = self.out / "stages" / "seconds.json"
        return json.loads(p.read_text()) if p.exists() else {}

    def write_csv(self, name: str, rows: Sequence[dict]) -> Path:
        """Write ``rows`` (dicts with the same keys) to ``csv/<name>.csv``."""
        buf = io.StringIO()
        if rows:
            w = csv.DictWriter(buf, list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        return atomic_write(self.path("csv", f"{name}.csv"), buf.getvalue())

    def write_table(self, name: str, markdown: str) -> Path:
        """Write a Markdown table (or section) to ``tables/<name>.md``."""
        return atomic_write(self.path("tables", f"{name}.md"), markdown.rstrip() + "\n")

    def save_figure(self, name: str, fig, dpi: int = 90) -> Path:
        """Save a matplotlib figure as ``figures/<name>.png`` (atomically) and close it."""
        import matplotlib.pyplot as plt

        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
        plt.close(fig)
        return atomic_write(self.path("figures", f"{name}.png"), buf.getvalue())

    def finish(self, summary: dict) -> dict:
        """Write ``summary.json`` (with the machine, the wall seconds of each stage and their sum)
        and print it as the last line."""
        stages = self.stage_seconds()
        summary = {**summary, "machine": machine(), "stage_seconds": stages, "seconds": sum(stages.values()),
                   "seconds_this_invocation": time.perf_counter() - self.t0}
        atomic_write(self.out / "summary.json", json.dumps(summary, indent=1, default=float))
        self.log("finished")
        print(json.dumps(summary, default=float), flush=True)
        return summary


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A Markdown table; floats are printed with 3 decimals."""
    fmt = lambda v: f"{v:.3f}" if isinstance(v, float) else str(v)
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(v) for v in r) + " |" for r in rows]
    return "\n".join(lines)
