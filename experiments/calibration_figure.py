"""The calibration table as a figure: PT-HR and PT-RD win rates by skill range, each seed's bar
with its 95 % interval, against the paper's value and the calibration contract's band around it.

    python -m experiments.calibration_figure docs/results/calibration/calibration_2000_seed*.json \\
        --out docs/img/calibration.png

Each input is a ``raidjax.calibrate --json`` file (one seed, same ranges and games per cell).
"""

from __future__ import annotations

import json
from pathlib import Path

from experiments.figures import figure_command
from raidjax.calibrate import LABEL, PAPER, RANGES, TOLERANCE


def figure(tables: list[dict]):
    """A matplotlib figure of ``tables`` (``raidjax.calibrate`` JSON objects, one per seed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4), sharey=False)
    width = 0.8 / max(len(tables), 1)
    for ax, name in zip(axes, ("heuristic", "random"), strict=True):
        for i, paper in enumerate(PAPER[name]):
            ax.add_patch(plt.Rectangle((i - 0.45, max(paper - TOLERANCE[name], 0.0)), 0.9,
                                       min(paper + TOLERANCE[name], 1.0) - max(paper - TOLERANCE[name], 0.0),
                                       color="0.88", zorder=0, label="contract band" if i == 0 else None))
            ax.plot([i - 0.45, i + 0.45], [paper, paper], color="k", lw=1.5, zorder=3,
                    label="paper (500 games)" if i == 0 else None)
        for j, t in enumerate(tables):
            cell = t["table"][name]
            xs = [i - 0.4 + width * (j + 0.5) for i in range(len(RANGES))]
            ax.bar(xs, cell["win_rate"], width * 0.9, yerr=[1.96 * e for e in cell["stderr"]], capsize=2,
                   label=f"raidjax, seed {t['seed']} ({t['games_per_cell']} games)", zorder=2)
        ax.set_xticks(range(len(RANGES)), [f"{r:g}" for r in RANGES])
        ax.set_xlabel("skill range")
        ax.set_title(LABEL[name])
        ax.set_ylim(0, 1.0 if name == "heuristic" else 0.15)
    axes[0].set_ylabel("win rate")
    axes[1].legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    return fig


def read_tables(paths: list[str]) -> list[dict]:
    """The ``raidjax.calibrate --json`` objects in ``paths``; ``ValueError`` naming a file that is JSON
    but not one of them."""
    tables = [json.loads(Path(p).read_text()) for p in paths]
    for p, t in zip(paths, tables, strict=True):
        if not isinstance(t, dict) or not {"table", "seed", "games_per_cell"} <= set(t) or not all(
                name in t["table"] for name in LABEL):
            raise ValueError(f"{p} is not a raidjax.calibrate --json file (no 'table' of {', '.join(LABEL)}, "
                             "'seed' and 'games_per_cell')")
    return tables


def main(argv=None) -> None:
    figure_command(argv, prog="python -m experiments.calibration_figure", doc=__doc__,
                   inputs="raidjax.calibrate --json files, one per seed", read=read_tables, draw=figure)


if __name__ == "__main__":
    main()
