"""Learning curves of MA-POCA runs from their ``metrics.csv`` (one row per chunk).

    python -m trainers.plot runs/mapoca_cpu_r9 runs/mapoca_cpu_r13 --out docs/img/mapoca_curves.png
"""

from __future__ import annotations

import argparse
import csv
import io
from pathlib import Path

from raidjax.utils import atomic_write


def read_metrics(run: str | Path) -> dict[str, list[float]]:
    """Columns of ``run/metrics.csv`` as lists of floats (keyed by header)."""
    with (Path(run) / "metrics.csv").open() as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) for r in rows] for k in rows[0]}


def main(argv=None) -> None:
    """Plot win rate and return per episode against decisions (and wall-clock) for each run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    fig, (ax_w, ax_r) = plt.subplots(1, 2, figsize=(10, 3.6))
    for run in args.runs:
        m = read_metrics(run)
        steps = [s / 1e6 for s in m["env_steps"]]
        label = Path(run).name
        ax_w.plot(steps, m["win_rate"], label=label)
        ax_r.plot(steps, m["return"], label=label)
    ax_w.set(xlabel="environment decisions (M)", ylabel="training win rate (per chunk)", ylim=(0, 1.02))
    ax_r.set(xlabel="environment decisions (M)", ylabel="team return per episode")
    for ax in (ax_w, ax_r):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format=Path(args.out).suffix.lstrip(".") or "png", dpi=110)
    plt.close(fig)
    atomic_write(args.out, buf.getvalue())  # a reader never sees half a figure


if __name__ == "__main__":
    main()
