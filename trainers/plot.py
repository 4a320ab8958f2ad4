"""Learning curves and the learner's diagnostics (entropy, approximate KL, clipped fraction, value and
baseline explained variance, gradient norm) of MA-POCA runs from their ``metrics.csv`` (one row per chunk).

    python -m trainers.plot runs/mapoca_cpu_r9 runs/mapoca_cpu_r13 --out docs/img/mapoca_curves.png
"""

from __future__ import annotations

import argparse
import csv
import io
import math
from pathlib import Path

from raidjax.io import HelpFormatter, atomic_write, check_output_file, run_cli

FORMATS = ("png", "pdf", "svg")  # of --out, by its suffix


def read_metrics(run: str | Path) -> dict[str, list[float]]:
    """Columns of ``run/metrics.csv`` as lists of floats (keyed by header). An empty cell (a metric
    without a value at that update, NaN in the log) is NaN; a last row without its line end (a run
    killed or still writing it) is left out."""
    text = (Path(run) / "metrics.csv").read_text()
    rows = list(csv.DictReader(io.StringIO(text[:text.rfind("\n") + 1])))
    return {k: [float(r[k]) if r[k] else math.nan for r in rows] for k in rows[0]}


COLUMNS = ("env_steps", "win_rate", "return")  # of a MA-POCA run's metrics.csv (trainers.mapoca_cli)
# The panels: a metrics.csv column (per chunk) and its axis label; the learner's diagnostics after the curves.
PANELS = (("win_rate", "training win rate"), ("return", "team return per episode"), ("entropy", "policy entropy"),
          ("approx_kl", "approximate KL per update"), ("clip_frac", "clipped fraction of ratios"),
          ("value_explained_variance", "value explained variance"),
          ("baseline_explained_variance", "baseline explained variance"), ("grad_norm", "gradient norm"))


def _check_run(run: str) -> None:
    """``run`` must be a MA-POCA run folder whose ``metrics.csv`` has rows with ``COLUMNS`` (``ValueError``)."""
    allowed = "a MA-POCA run folder (trainers.mapoca_cli --out) with at least one row in its metrics.csv"
    path = Path(run) / "metrics.csv"
    if not Path(run).is_dir():
        wrong = "does not exist" if not Path(run).exists() else "is a file, not a folder"
    elif not path.is_file():
        wrong = "holds no metrics.csv"
    else:
        try:
            m = read_metrics(run)
        except (IndexError, ValueError, KeyError, csv.Error):  # empty, torn, or not numbers
            m = None
        missing = [c for c in COLUMNS if c not in (m or {})]
        if m is None:
            wrong = "has a metrics.csv without rows, or not a table of numbers"
        elif missing:
            wrong = f"has a metrics.csv without the column {missing[0]!r} (not a MA-POCA run?)"
        else:
            return
    raise ValueError(f"runs: value {run!r} {wrong}; allowed: {allowed}")


def main(argv=None) -> None:
    """Plot win rate, return per episode and the learner's diagnostics (``PANELS``) against decisions
    for each run; every argument is checked before matplotlib is imported (``ValueError``, one line)."""
    ap = argparse.ArgumentParser(prog="python -m trainers.plot", formatter_class=HelpFormatter,
                                 description="Learning curves of MA-POCA runs from their metrics.csv.")
    ap.add_argument("runs", nargs="+", help="MA-POCA run folders (trainers.mapoca_cli --out)")
    ap.add_argument("--out", required=True, help="the figure to write, in an existing folder; its suffix picks the "
                    f"format: {', '.join(FORMATS)} (required)")
    args = ap.parse_args(argv)
    check_output_file("--out", args.out, tuple(f".{f}" for f in FORMATS))
    for run in args.runs:
        _check_run(run)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 4, figsize=(15, 6.4))
    for i, run in enumerate(args.runs):
        m = read_metrics(run)
        steps = [s / 1e6 for s in m["env_steps"]]
        for ax, (col, _) in zip(axes.flat, PANELS, strict=True):
            if col in m:  # runs saved before a diagnostic existed leave its panel empty
                ax.plot(steps, m[col], label=Path(run).name, color=f"C{i % 10}", lw=1)  # one colour per run
    for ax, (col, ylabel) in zip(axes.flat, PANELS, strict=True):
        ax.set(xlabel="environment decisions (M)", ylabel=ylabel)
        if col == "win_rate":
            ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=7)
        else:
            ax.text(0.5, 0.5, "not recorded by these runs", ha="center", va="center", transform=ax.transAxes)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format=Path(args.out).suffix.lstrip(".").lower(), dpi=80)
    plt.close(fig)
    atomic_write(args.out, buf.getvalue())  # a reader never sees half a figure


def cli(argv=None) -> None:
    """``main`` as a command line: one-line errors (exit 2), one line on Ctrl-C (exit 130)."""
    run_cli(lambda: main(argv))


if __name__ == "__main__":
    cli()
