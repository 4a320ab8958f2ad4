"""Benchmark 1 under two observations side by side: the MA-POCA win table of each run folder (or
its copy under ``docs/results``) beside the paper's, and the win-table runs' learning curves of
both on one figure.

    python -m experiments.b1_compare runs/b1_raidjax runs/b1_paper \\
        --labels "raidjax observation" "reference observation" --out b1_observations.png

Each folder holds ``csv/win_rate_table.csv`` (the report's table) and ``train/metrics.csv`` (one row
per training chunk: ``env_steps`` and ``win/table/r<range>/<seed>`` training win rates).
"""

from __future__ import annotations

import argparse
import csv
import re
from pathlib import Path

from experiments.figures import save_png
from raidjax.io import check_output_file

RANGES = (5.0, 9.0, 13.0, 17.0)


def win_table(folder: Path) -> dict[str, dict[float, tuple[float, float, float]]]:
    """``{agent: {range: (mean, sd, paper)}}`` from a run's ``csv/win_rate_table.csv``."""
    out: dict[str, dict[float, tuple[float, float, float]]] = {}
    with open(folder / "csv" / "win_rate_table.csv") as f:
        for row in csv.DictReader(f):
            out.setdefault(row["agent"], {})[float(row["range"])] = (
                float(row["mean"]), float(row["sd"]), float(row["paper"]) if row["paper"] else float("nan"))
    return out


def curves(folder: Path) -> dict[float, tuple[list[float], list[float]]]:
    """``{range: (env_steps, training win rate averaged over seeds)}`` of the win-table runs."""
    with open(folder / "train" / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    out = {}
    for rng in RANGES:
        cols = [c for c in rows[0] if re.fullmatch(rf"win/table/r{rng:g}/\d+", c)] if rows else []
        if cols:
            out[rng] = ([float(r["env_steps"]) for r in rows],
                        [sum(float(r[c]) for c in cols) / len(cols) for r in rows])
    return out


def markdown(tables: list[dict], labels: list[str]) -> str:
    """The MA-POCA rows of every run beside the paper's, one line per run."""
    lines = ["| MA-POCA | range 5 | range 9 | range 13 | range 17 |", "|---|---|---|---|---|"]
    paper = tables[0]["MA-POCA"]
    lines.append("| paper (50 M agent steps) | " + " | ".join(f"{paper[r][2]:.3f}" for r in RANGES) + " |")
    for t, label in zip(tables, labels, strict=True):
        cells = t["MA-POCA"]
        lines.append(f"| {label} | " + " | ".join(f"{cells[r][0]:.3f} ± {cells[r][1]:.3f}" for r in RANGES) + " |")
    return "\n".join(lines)


def figure(all_curves: list[dict], labels: list[str]):
    """Training win rate against decisions, one panel per range, one line per run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(RANGES), figsize=(12, 3), sharey=True)
    for ax, rng in zip(axes, RANGES, strict=True):
        for c, label in zip(all_curves, labels, strict=True):
            if rng in c:
                ax.plot([s / 1e6 for s in c[rng][0]], c[rng][1], label=label)
        ax.set_title(f"range {rng:g}")
        ax.set_xlabel("decisions per run (M)")
    axes[0].set_ylabel("training win rate")
    axes[0].set_ylim(0, 1)
    axes[-1].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    return fig


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m experiments.b1_compare", description=__doc__.split("\n")[0])
    ap.add_argument("folders", nargs="+", help="Benchmark 1 run folders (or their docs/results copies)")
    ap.add_argument("--labels", nargs="+", required=True, help="one label per folder")
    ap.add_argument("--out", required=True, help="the PNG of the learning curves")
    args = ap.parse_args(argv)
    try:
        check_output_file("--out", args.out, (".png",))
    except ValueError as e:
        ap.error(str(e))
    if len(args.labels) != len(args.folders):
        ap.error(f"--labels: {len(args.labels)} labels for {len(args.folders)} folders; allowed: one per folder")
    folders = [Path(f) for f in args.folders]
    missing = [str(f / "train" / "metrics.csv") for f in folders if not (f / "train" / "metrics.csv").exists()]
    if missing:
        ap.error(f"folders: {missing[0]} does not exist; allowed: Benchmark 1 run folders or their copies")
    save_png(figure([curves(f) for f in folders], args.labels), args.out, dpi=120)
    if all((f / "csv" / "win_rate_table.csv").exists() for f in folders):
        print(markdown([win_table(f) for f in folders], args.labels))
    print(args.out)


if __name__ == "__main__":
    main()
