"""Speed against arenas as a figure: decisions per second of raidjax (5 sub-steps, per-arena
content) and JaxMARL's SMAX-3m, one line per environment and machine, from ``benchmarks/vs_smax.py``
output.

    python -m experiments.speed_figure docs/results/speed/vs_smax_cpu.json \\
        docs/results/speed/gpu_h100.jsonl --out docs/img/speed.png

Each input holds JSON objects, one per line or one per file; the ``vs_smax`` summaries among them
(``"benchmark": "vs_smax"``, with ``machine`` and ``rows``) are plotted, everything else is skipped.
"""

from __future__ import annotations

import json
from pathlib import Path

from experiments.figures import figure_command

LABELS = {"smax-3m": "SMAX-3m", "raidjax-per-arena": "raidjax (per-arena content)",
          "raidjax-shared": "raidjax (one content)", "raidjax-jaxmarl": "raidjax (JaxMARL wrapper)"}


def summaries(paths: list[str]) -> list[dict]:
    """The ``vs_smax`` summary objects in ``paths`` (JSON files or JSON-lines files)."""
    found = []
    for p in paths:
        text = Path(p).read_text()
        try:
            objs = [json.loads(text)]
        except json.JSONDecodeError:
            objs = [json.loads(line) for line in text.splitlines() if line.strip().startswith("{")]
        found += [o for o in objs if isinstance(o, dict) and o.get("benchmark") == "vs_smax"]
    return found


def figure(runs: list[dict]):
    """A log-log matplotlib figure: decisions/s against arenas, one line per (machine, environment)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for run in runs:
        m = run["machine"]
        where = m["device"] if m["platform"] != "cpu" else f"{m['cpu_count']}-core CPU"
        for env in dict.fromkeys(r["env"] for r in run["rows"]):
            rows = sorted((r for r in run["rows"] if r["env"] == env), key=lambda r: r["arenas"])
            ax.plot([r["arenas"] for r in rows], [r["decisions_per_s"] for r in rows],
                    "--" if env == "smax-3m" else "-", marker="o", label=f"{LABELS.get(env, env)}, {where}")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("arenas (vmapped)")
    ax.set_ylabel("decisions per second")
    ax.set_title(f"random actions, {runs[0]['raidjax_substeps']} sub-steps per raidjax decision")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def _vs_smax_runs(paths: list[str]) -> list[dict]:
    runs = summaries(paths)
    if not runs:
        raise ValueError('no vs_smax summary (an object with "benchmark": "vs_smax") in them')
    return runs


def main(argv=None) -> None:
    figure_command(argv, prog="python -m experiments.speed_figure", doc=__doc__,
                   inputs="benchmarks/vs_smax.py output files (JSON or JSON lines)", read=_vs_smax_runs,
                   draw=figure)


if __name__ == "__main__":
    main()
