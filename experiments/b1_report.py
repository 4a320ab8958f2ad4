"""Tables and figures of Benchmark 1 from its evaluation cells (``experiments.benchmark1``).

Writes ``tables/win_rate.md``, ``tables/robustness.md``, ``csv/win_rate_table.csv``,
``csv/robustness.csv``, ``figures/adjusted_score.png``, ``figures/heatmaps.png`` and
``figures/training.png`` (training win rates, mean and range over seeds); each table
puts our numbers beside the paper's.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from trainers.runfolder import RunFolder, markdown_table  # noqa: E402

# GAME.md §9 (the paper's Table "Win rate between MARL and Heuristic agent", 500 games)
PAPER_WIN_RATE = {"PT-RD": (0.000, 0.002, 0.029, 0.058), "PT-HR": (0.089, 0.371, 0.698, 0.830),
                  "MA-POCA": (0.485, 0.857, 0.990, 0.990)}
# the paper's Appendix F table: AdjustedScore at unseen ranges 3, 4, 19, 20 and the test average
PAPER_ADJUSTED = {"MA-POCA1": (0.004, 0.553, 0.597, 0.597, 0.506), "MA-POCA2": (0.028, 0.553, 0.523, 0.525, 0.473),
                  "MA-POCA3": (0.013, 0.369, 0.826, 0.778, 0.511), "MA-POCA4": (0.000, 0.016, 0.980, 0.971, 0.443),
                  "PT-HR": (0.013, 0.115, 0.890, 0.868, 0.441)}
TABLE_RANGES = (5.0, 9.0, 13.0, 17.0)
TEST_RANGES = (3.0, 4.0, 19.0, 20.0)


def _rates(cells: list[dict], agent: str, content: str, rng: float) -> np.ndarray:
    """Win rates ``float[k]`` of ``agent`` on ``content`` at range ``rng`` (one per seed/run)."""
    return np.asarray([c["win_rate"] for c in cells
                       if c["agent"] == agent and c["content"] == content and c["range"] == rng
                       and c["group"] != "population"], float)


def _ms(x: np.ndarray) -> str:
    if x.size == 0 or not np.all(np.isfinite(x)):
        return "n/a"
    return f"{x.mean():.3f}" if x.size == 1 else f"{x.mean():.3f} ± {x.std():.3f}"


def win_rate_table(rf: RunFolder, cells: list[dict]) -> dict:
    """The win-rate table (agents x ranges 5/9/13/17, reference content) beside the paper's."""
    rows, csv_rows, means = [], [], {}
    for agent in ("PT-RD", "PT-HR", "MA-POCA"):
        row = [agent]
        for j, r in enumerate(TABLE_RANGES):
            x = _rates(cells, agent, "reference", r)
            row.append(f"{_ms(x)} ({PAPER_WIN_RATE[agent][j]:.3f})")
            csv_rows.append({"agent": agent, "range": r, "mean": float(x.mean()), "sd": float(x.std()), "n": x.size,
                             "paper": PAPER_WIN_RATE[agent][j]})
            means[f"{agent}@{r:g}"] = float(x.mean())
        rows.append(row)
    n_games = cells[0]["games"]
    md = ("## Win rate by skill range (reference content)\n\n"
          f"Mean ± SD over seeds of the win rate in {n_games} games per seed; the paper's value in brackets.\n\n"
          + markdown_table(["agent"] + [f"range {r:g}" for r in TABLE_RANGES], rows))
    rf.write_table("win_rate", md)
    rf.write_csv("win_rate_table", csv_rows)
    return means


def robustness(rf: RunFolder, cells: list[dict]) -> dict:
    """AdjustedScore = test win rate / mean population win rate at each unseen range."""
    pop = {r: np.mean([c["win_rate"] for c in cells if c["group"] == "population" and c["range"] == r])
           for r in TEST_RANGES}
    rows, csv_rows, scores = [], [], {}
    for agent in ("MA-POCA1", "MA-POCA2", "MA-POCA3", "MA-POCA4", "PT-HR"):
        row, adj_all = [agent], []
        for j, r in enumerate(TEST_RANGES):
            x = _rates(cells, agent, "test", r)
            adj = x / pop[r] if pop[r] > 0 else np.full_like(x, np.nan)
            adj_all.append(adj)
            row.append(f"{_ms(adj)} ({PAPER_ADJUSTED[agent][j]:.3f}); win {_ms(x)}")
            csv_rows.append({"agent": agent, "range": r, "win_mean": float(x.mean()), "win_sd": float(x.std()),
                             "population_win": float(pop[r]), "adjusted_mean": float(np.mean(adj)),
                             "adjusted_sd": float(np.std(adj)), "paper_adjusted": PAPER_ADJUSTED[agent][j]})
        per_seed = np.nanmean(np.stack(adj_all), 0) if np.isfinite(np.stack(adj_all)).any() else np.array([np.nan])
        row.append(f"{_ms(per_seed)} ({PAPER_ADJUSTED[agent][4]:.3f})")
        scores[agent] = float(np.mean(per_seed))
        rows.append(row)
    rows.append(["population (win rate)"] + [f"{pop[r]:.3f}" for r in TEST_RANGES] + [""])
    md = ("## Robustness: AdjustedScore on unseen skill ranges (test content: cool time 1.0)\n\n"
          "AdjustedScore = win rate ÷ the mean win rate of the population trained on that range; "
          "mean ± SD over seeds, the paper's value in brackets, then the raw win rate. "
          "Test avg. = mean over the ranges whose population wins at all (n/a: population win rate 0).\n\n"
          + markdown_table(["agent"] + [f"range {r:g}" for r in TEST_RANGES] + ["test avg."], rows))
    rf.write_table("robustness", md)
    rf.write_csv("robustness", csv_rows)

    fig, ax = plt.subplots(figsize=(7, 3.2))
    agents = list(PAPER_ADJUSTED)
    width = 0.8 / len(agents)
    for k, agent in enumerate(agents):
        vals = [next(c["adjusted_mean"] for c in csv_rows if c["agent"] == agent and c["range"] == r)
                for r in TEST_RANGES]
        sds = [next(c["adjusted_sd"] for c in csv_rows if c["agent"] == agent and c["range"] == r)
               for r in TEST_RANGES]
        ax.bar(np.arange(4) + (k - 2) * width, np.nan_to_num(vals), width, yerr=np.nan_to_num(sds), label=agent,
               color="0.6" if agent == "PT-HR" else None)
    ax.axhline(1.0, color="red", lw=1, label="population")
    ax.set_xticks(np.arange(4), [f"range {r:g}" for r in TEST_RANGES])
    ax.set_ylabel("AdjustedScore")
    ax.legend(fontsize=7, ncol=3)
    ax.set_title("Unseen skill ranges (bars missing: population never wins)", fontsize=9)
    rf.save_figure("adjusted_score", fig)
    return {"adjusted_score_test_avg": scores, "population_win_rate": {f"{r:g}": float(v) for r, v in pop.items()}}


def heatmap_figure(rf: RunFolder) -> None:
    """MA-POCA1 vs MA-POCA3 team occupancy maps across ranges (from ``heatmaps.npz``)."""
    d = np.load(rf.path("heatmaps.npz"))
    maps, agents, ranges = d["maps"].mean(2), d["agents"], d["ranges"]  # team average over players
    fig, axes = plt.subplots(len(agents), len(ranges), figsize=(2.0 * len(ranges), 2.1 * len(agents)), squeeze=False)
    for a, agent in enumerate(agents):
        for j, r in enumerate(ranges):
            ax = axes[a, j]
            ax.imshow(maps[a, j].T, origin="lower", cmap="magma", extent=(-1, 1, -1, 1))
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{agent}, range {r:g}", fontsize=8)
    rf.save_figure("heatmaps", fig)


def training_figure(rf: RunFolder) -> None:
    """Training win rate (share of episodes won per chunk) of every run, one panel per group,
    from ``train/metrics.csv``."""
    import csv

    with open(rf.path("train", "metrics.csv")) as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return
    x = np.asarray([float(r["env_steps"]) for r in rows]) / 1e6
    runs = sorted({k.split("/", 1)[1].rsplit("/", 1)[0] for k in rows[0] if k.startswith("win/")})
    groups = ("table", "robust", "population")
    fig, axes = plt.subplots(1, 3, figsize=(10, 2.8), sharey=True)
    for ax, g in zip(axes, groups, strict=True):
        for run in (r for r in runs if r.startswith(g + "/")):
            cols = [k for k in rows[0] if k.startswith(f"win/{run}/")]
            y = np.asarray([[float(r[c]) for c in cols] for r in rows])
            line, = ax.plot(x, y.mean(1), label=run.split("/")[1])
            ax.fill_between(x, y.min(1), y.max(1), color=line.get_color(), alpha=0.2)
        ax.set_title(g, fontsize=9)
        ax.set_xlabel("decisions per run (M)")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("training win rate")
    rf.save_figure("training", fig)


def report(rf: RunFolder, cells: list[dict], timing: dict) -> dict:
    """Write every table and figure; returns the summary numbers."""
    means = win_rate_table(rf, cells)
    rob = robustness(rf, cells)
    heatmap_figure(rf)
    training_figure(rf)
    return {"win_rate": means, **rob}
