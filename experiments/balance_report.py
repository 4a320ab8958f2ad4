"""Tables and figures of the balancing loop (``experiments.balance``), from its raw outputs alone.

    python -m experiments.balance_report DIR

Reads ``DIR/generated.npz`` (one row per generated skill: ``generator`` index into
``generators``, ``target``, ``skill [4]``, ``learned`` and ``scripted``: the win rates the two
testers reached on it) and writes ``tables/skill_gap.md``, ``tables/balance.md``,
``csv/skill_gap.csv``, ``figures/skill_gap.png`` and ``figures/controllability.png``.

Definitions (PROTOCOLS.md §13). A skill's *gap* is ``learned - scripted``: how much more the
learned team wins with it than PT-HR. A generator's *error under a tester* is ``|w - target|``
with that tester's win rate ``w``; diversity is Benchmark 2's PC1 SD over the skills within 0.1 of
their target under that tester (``raidjax.pcg.quality.diversity``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from raidjax.io import HelpFormatter, run_cli
from raidjax.pcg import quality as pm
from trainers.runfolder import RunFolder, markdown_table

TESTERS = ("learned", "scripted")


def load(path) -> dict[str, np.ndarray]:
    """``generated.npz`` as a dict of numpy arrays (``generators`` as a list of str)."""
    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    data["generators"] = [str(g) for g in data["generators"]]
    return data


def skill_gap_rows(data: dict) -> list[dict]:
    """One row per (generator, target): ``n``, mean win rate under each tester, the gap's mean and
    SD (ddof 0), and the mean error under each tester."""
    rows = []
    for g, name in enumerate(data["generators"]):
        for t in np.unique(data["target"]):
            m = (data["generator"] == g) & np.isclose(data["target"], t)
            if not m.any():
                continue
            gap = data["learned"][m] - data["scripted"][m]
            rows.append({"generator": name, "target": float(t), "n": int(m.sum()),
                         "learned": float(data["learned"][m].mean()), "scripted": float(data["scripted"][m].mean()),
                         "gap": float(gap.mean()), "gap_sd": float(gap.std()),
                         **{f"error_{k}": float(np.abs(data[k][m] - t).mean()) for k in TESTERS}})
    return rows


def generator_rows(data: dict) -> list[dict]:
    """One row per generator: mean error (and SD) under each tester, mean gap, diversity under
    each tester (PC1 SD of its skills within 0.1 of their target, pooled over targets)."""
    rows = []
    for g, name in enumerate(data["generators"]):
        m = data["generator"] == g
        row = {"generator": name, "n": int(m.sum()), "gap": float((data["learned"][m] - data["scripted"][m]).mean())}
        for k in TESTERS:
            err = np.abs(data[k][m] - data["target"][m])
            div = pm.diversity(data["skill"][m], err, np.zeros(int(m.sum()), int))
            row.update({f"error_{k}": float(err.mean()), f"error_{k}_sd": float(err.std()),
                        f"diversity_{k}": div.get(0, {}).get("pc1_sd", float("nan"))})
        rows.append(row)
    return rows


def report(rf: RunFolder) -> dict:
    """Write the tables and figures of the run in ``rf``; returns the summary numbers."""
    data = load(rf.out / "generated.npz")
    gap_rows, gen_rows = skill_gap_rows(data), generator_rows(data)
    rf.write_csv("skill_gap", gap_rows)
    rf.write_table("skill_gap", "## Skill gap: the same generated skill under the learned team and under PT-HR\n\n"
                   + markdown_table(["generator", "target", "n", "win (learned)", "win (PT-HR)", "gap", "gap SD",
                                     "error (learned)", "error (PT-HR)"],
                                    [[r["generator"], r["target"], r["n"], r["learned"], r["scripted"], r["gap"],
                                      r["gap_sd"], r["error_learned"], r["error_scripted"]] for r in gap_rows]))
    by = {r["generator"]: r for r in gen_rows}
    closer = by["learned"]["error_learned"] < by["scripted"]["error_learned"]
    rf.write_table("balance", "## Controllability and diversity under both testers\n\n"
                   + markdown_table(["generator (trained against)", "n", "error (learned)", "error (PT-HR)",
                                     "mean gap", "PC1 SD (learned)", "PC1 SD (PT-HR)"],
                                    [[r["generator"], r["n"], f"{r['error_learned']:.3f} ± {r['error_learned_sd']:.3f}",
                                      f"{r['error_scripted']:.3f} ± {r['error_scripted_sd']:.3f}", r["gap"],
                                      r["diversity_learned"], r["diversity_scripted"]] for r in gen_rows])
                   + f"\n\nPlayed by the learned team, the learned-tester generator's skills are "
                   f"{'closer to' if closer else 'not closer to'} their targets than the PT-HR generator's "
                   f"({by['learned']['error_learned']:.3f} vs {by['scripted']['error_learned']:.3f}).\n")
    figures(rf, gap_rows)
    return {"closer_under_learned": bool(closer),
            **{f"{r['generator']}_{k}": r[k] for r in gen_rows for k in ("error_learned", "error_scripted", "gap")}}


def figures(rf: RunFolder, gap_rows: list[dict]) -> None:
    """``figures/skill_gap.png`` (gap vs target) and ``figures/controllability.png`` (mean win
    rate vs target under each tester), one line per generator."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = sorted({r["generator"] for r in gap_rows}, key=lambda n: n != "learned")
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for name in names:
        rs = [r for r in gap_rows if r["generator"] == name]
        ax.errorbar([r["target"] for r in rs], [r["gap"] for r in rs], [r["gap_sd"] for r in rs], marker="o",
                    capsize=3, label=f"generator trained against {'MA-POCA' if name == 'learned' else 'PT-HR'}")
    ax.axhline(0, color="grey", lw=0.8)
    ax.set_xlabel("target win rate")
    ax.set_ylabel("win rate: learned team − PT-HR")
    ax.legend(fontsize=8)
    rf.save_figure("skill_gap", fig)
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5), sharey=True)
    for ax, tester in zip(axes, TESTERS, strict=True):
        for name in names:
            rs = [r for r in gap_rows if r["generator"] == name]
            ax.plot([r["target"] for r in rs], [r[tester] for r in rs], marker="o", label=f"{name} generator")
        ax.plot([0.1, 0.7], [0.1, 0.7], color="grey", ls="--", lw=0.8)
        ax.set_title(f"played by {'the learned team' if tester == 'learned' else 'PT-HR'}")
        ax.set_xlabel("target win rate")
    axes[0].set_ylabel("mean win rate of generated skills")
    axes[0].legend(fontsize=8)
    rf.save_figure("controllability", fig)


def main(argv=None) -> dict:
    """Rewrite the tables and figures of an existing balance run folder from its raw outputs."""
    ap = argparse.ArgumentParser(prog="python -m experiments.balance_report", formatter_class=HelpFormatter,
                                 description="Redraw a balance run's tables and figures from its generated.npz.")
    ap.add_argument("run", help="a balance run folder holding config.json and generated.npz (required)")
    args = ap.parse_args(argv)
    run = Path(args.run)
    if not (run / "generated.npz").is_file() or not (run / "config.json").is_file():
        raise ValueError(f"run: value {str(run)!r} holds no config.json and generated.npz; allowed: a balance run "
                         "folder past its generate stage")
    with RunFolder(run, json.loads((run / "config.json").read_text()), resume=True) as rf:
        summary = report(rf)
    print(json.dumps(summary))
    return summary


if __name__ == "__main__":
    run_cli(main, (ValueError,), "")
