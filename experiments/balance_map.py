"""The balance map of ``notebooks/balancing_sweep.ipynb``: PT-HR win rate over a grid of
MagicMissile skill ranges x cool times, with the win rate 0.5 ("balanced") contour in black.

The notebook plays the games; this module only draws and saves, so the figure can be remade
from the win-rate grid alone. ``DOCS_PNG`` is where the README's copy lives.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from experiments.figures import save_png  # noqa: F401 (the notebook's writer, re-exported)
from raidjax.io import atomic_write, finite_json, machine

DOCS_PNG = Path(__file__).resolve().parents[1] / "docs" / "img" / "balance_map.png"
DOCS_JSON = Path(__file__).resolve().parents[1] / "docs" / "results" / "balance_map" / "win_rate.json"
BALANCED = 0.5  # the win rate that separates "too easy" from "too hard"


def smooth(a: np.ndarray) -> np.ndarray:
    """Mean over each cell's 3 x 3 neighbourhood (edges padded by repetition).

    Args:
        a: ``float[R, C]``.

    Returns:
        ``float[R, C]``.
    """
    a = np.asarray(a, float)
    p = np.pad(a, 1, mode="edge")
    return sum(p[i:i + a.shape[0], j:j + a.shape[1]] for i in range(3) for j in range(3)) / 9.0


def _edges(v: np.ndarray) -> list[float]:
    """Outer pixel edges ``[first - step/2, last + step/2]`` of evenly spaced centres ``v``."""
    step = v[1] - v[0] if len(v) > 1 else 1.0
    return [float(v[0] - step / 2), float(v[-1] + step / 2)]


def balance_map_figure(win_rate: np.ndarray, ranges: np.ndarray, cools: np.ndarray, games_per_cell: int,
                       reference: tuple[float, float] | None = None, level: float = BALANCED):
    """Draw the balance map.

    Args:
        win_rate: ``float[R, C]`` PT-HR win rate per content, row = skill range, column = cool time.
        ranges: ``float[R]`` evenly spaced skill ranges (world units), ascending.
        cools: ``float[C]`` evenly spaced cool times (s), ascending.
        games_per_cell: games played per content (for the title).
        reference: ``(cool time, range)`` of the reference content, marked with a star; None: no star.
        level: the win rate of the contour, drawn on ``smooth(win_rate)`` when the grid crosses it.

    Returns:
        ``(figure, axes)``: a ``matplotlib.figure.Figure`` (show it with IPython's ``display``)
        holding one ``imshow`` image (``win_rate`` as given, origin lower left: range up, cool time
        right) on a fixed 0-1 colour scale with a labelled colour bar.
    """
    win_rate = np.asarray(win_rate, float)
    ranges, cools = np.asarray(ranges, float), np.asarray(cools, float)
    if win_rate.shape != (ranges.size, cools.size):
        raise ValueError(f"win_rate has shape {win_rate.shape}, expected (len(ranges), len(cools)) = "
                         f"({ranges.size}, {cools.size})")
    smoothed = smooth(win_rate)
    fig = Figure(figsize=(7, 5.5))  # not pyplot's: no backend is chosen or changed (PNGs render with Agg)
    ax = fig.subplots()
    im = ax.imshow(win_rate, origin="lower", aspect="auto", cmap="RdYlBu_r", vmin=0.0, vmax=1.0,
                   extent=_edges(cools) + _edges(ranges), interpolation="nearest")
    cbar = fig.colorbar(im, ax=ax, label="PT-HR win rate (share of games won)")
    cbar.ax.axhline(level, color="black", lw=2)
    if smoothed.min() < level < smoothed.max() and min(win_rate.shape) >= 2:
        cs = ax.contour(cools, ranges, smoothed, levels=[level], colors="black", linewidths=2)
        ax.clabel(cs, fmt={level: f"{level:g}"})
        ax.plot([], [], color="black", lw=2, label=f"balanced: win rate {level:g} (3 x 3 smoothed)")
    if reference is not None:
        ax.plot([reference[0]], [reference[1]], marker="*", color="black", mec="white", markersize=15, ls="none",
                label=f"reference content (cool time {reference[0]:g} s, range {reference[1]:g})")
    ax.set_xlabel("MagicMissile cool time (s)")
    ax.set_ylabel("MagicMissile skill range (world units)")
    ax.set_title(f"Balance map: PT-HR win rate per content\n({ranges.size} x {cools.size} contents, "
                 f"{games_per_cell} games each)", fontsize=10)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="lower right", fontsize=8, framealpha=0.85)
    return fig, ax


def save_grid(path: str | Path, win_rate: np.ndarray, ranges: np.ndarray, cools: np.ndarray,
              games_per_cell: int, seconds: float) -> Path:
    """Save the map's data as JSON at ``path`` atomically, with the machine, date and commit that
    measured it (``raidjax.io.machine``), so the figure can be redrawn and checked. Returns ``path``.

    Args:
        win_rate: ``float[R, C]``, row = range, column = cool time.
        ranges, cools: ``float[R]`` and ``float[C]``, the grid's axes.
    """
    return atomic_write(path, finite_json({
        "benchmark": "balance_map", "machine": machine(load=True), "policy": "PT-HR",
        "games_per_cell": games_per_cell, "seconds": round(seconds, 1),
        "ranges": [float(r) for r in ranges], "cool_times": [float(c) for c in cools],
        "win_rate": np.asarray(win_rate, float).round(4).tolist()}) + "\n")
