"""Tables and figures of Benchmark 1 from its evaluation cells (``experiments.benchmark1``).

Writes ``tables/win_rate.md``, ``tables/robustness.md``, ``csv/win_rate_table.csv``,
``csv/robustness.csv``, ``figures/adjusted_score.png``, ``figures/heatmaps.png`` and
``figures/training.png`` (training win rates, mean and range over seeds); each table
puts our numbers beside the paper's. ``python -m experiments.b1_report RUN_DIR`` redraws a
finished run's ``figures/heatmaps.png`` from its ``heatmaps.npz`` alone.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from raidjax.env import BOSS_SPAWN, PLAYER_SPACING, PLAYER_SPAWN_Y  # noqa: E402
from raidjax.io import atomic_write  # noqa: E402
from raidjax.types import HALF_ARENA  # noqa: E402
from trainers.runfolder import RunFolder, locked, markdown_table  # noqa: E402

# GAME.md §9 (the paper's Table "Win rate between MARL and Heuristic agent", 500 games)
PAPER_WIN_RATE = {"PT-RD": (0.000, 0.002, 0.029, 0.058), "PT-HR": (0.089, 0.371, 0.698, 0.830),
                  "MA-POCA": (0.485, 0.857, 0.990, 0.990)}
# the paper's Appendix F table: AdjustedScore at unseen ranges 3, 4, 19, 20 and the test average
PAPER_ADJUSTED = {"MA-POCA1": (0.004, 0.553, 0.597, 0.597, 0.506), "MA-POCA2": (0.028, 0.553, 0.523, 0.525, 0.473),
                  "MA-POCA3": (0.013, 0.369, 0.826, 0.778, 0.511), "MA-POCA4": (0.000, 0.016, 0.980, 0.971, 0.443),
                  "PT-HR": (0.013, 0.115, 0.890, 0.868, 0.441)}
TABLE_RANGES = (5.0, 9.0, 13.0, 17.0)
TEST_RANGES = (3.0, 4.0, 19.0, 20.0)
HEATMAP_DPI = 110


def _rates(cells: list[dict], agent: str, content: str, rng: float, field: str = "win_rate") -> np.ndarray:
    """``field`` (a win rate) ``float[k]`` of ``agent`` on ``content`` at range ``rng`` (one per seed/run)."""
    return np.asarray([c.get(field, np.nan) for c in cells
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
    for agent in ("PT-RD", "PT-HR", "MA-POCA"):  # raidjax's mixed team (warrior, mage, priest); not in the paper
        x = [_rates(cells, agent, "mixed", r) for r in TABLE_RANGES]
        if not any(v.size for v in x):
            continue
        rows.append([f"{agent}, mixed team"] + [_ms(v) for v in x])
        for r, v in zip(TABLE_RANGES, x, strict=True):
            csv_rows.append({"agent": f"{agent}, mixed team", "range": r, "mean": float(v.mean()),
                             "sd": float(v.std()), "n": v.size, "paper": float("nan")})
            means[f"{agent}@{r:g}/mixed"] = float(v.mean())
    n_games = cells[0]["games"]
    chain_rows = []
    for agent in ("PT-HR", "MA-POCA"):  # the chain diagnostic: first games after the warm-up against later ones
        row = [agent]
        for r in TABLE_RANGES:
            first, later = (_rates(cells, agent, "reference", r, f) for f in ("win_rate_first_game",
                                                                                 "win_rate_later_games"))
            row.append(f"{_ms(first)} / {_ms(later)}")
            means[f"{agent}@{r:g}/first_game"], means[f"{agent}@{r:g}/later_games"] = (float(np.mean(first)),
                                                                                     float(np.mean(later)))
        chain_rows.append(row)
    md = ("## Win rate by skill range (reference content)\n\n"
          f"Mean ± SD over seeds of the win rate in {n_games} games per seed (arenas chaining their games after a "
          "warm-up, `raidjax.playtest`); the paper's value in brackets. "
          "The mixed-team rows (not in the paper) play a warrior, a mage and a priest from the catalogue, "
          "every player's skill slot 1 at the range.\n\n"
          + markdown_table(["agent"] + [f"range {r:g}" for r in TABLE_RANGES], rows)
          + "\n\n### By chain position\n\n"
          "The same games split by their place in the arena's chain: each arena's first game after its warm-up "
          "/ its later games (mean ± SD over seeds). Under the reference rules an arena's games depend on the "
          "ones before (docs/GAME.md, \"Episodes of one arena\").\n\n"
          + markdown_table(["agent"] + [f"range {r:g}: first / later" for r in TABLE_RANGES], chain_rows))
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


def heatmap_figure(maps: np.ndarray, agents, ranges, games: int | None = None):
    """Team occupancy maps, one panel per (agent, skill range), on one shared colour scale.

    Args:
        maps: ``float[A, R, P, B, B]`` per-player occupancy (``raidjax.playtest_occupancy``,
            indexed ``[agent, range, player, x_bin, y_bin]``, bins over the arena
            ``[-HALF_ARENA, HALF_ARENA]`` as ``raidjax.logs.grid_cell`` cuts it), or ``float[A, R, B, B]``
            maps already averaged over the players.
        agents: ``A`` agent names (row titles).
        ranges: ``R`` skill ranges (column titles).
        games: games per map, for the title (None: not stated).

    Returns:
        ``(figure, axes)`` with ``axes`` an ``Axes[A, R]`` array. Each panel holds one image, the
        team mean in percent, ``array[y_bin, x_bin]`` drawn with ``origin="lower"`` over the arena
        in world units (+x right, +y up); every image has vmin 0 and the same vmax; one colour bar.
    """
    maps = np.asarray(maps, float)
    team = maps.mean(2) if maps.ndim == 5 else maps  # [A, R, B, B]: mean over players
    n_players = maps.shape[2] if maps.ndim == 5 else None
    pct = 100.0 * team
    vmax = float(pct.max()) if pct.max() > 0 else 1.0
    h, cell = HALF_ARENA, 2 * HALF_ARENA / team.shape[-1]
    fig, axes = plt.subplots(len(agents), len(ranges), figsize=(2.3 * len(ranges) + 1.2, 2.55 * len(agents) + 1.0),
                             squeeze=False, sharex=True, sharey=True, layout="constrained")
    for a, agent in enumerate(agents):
        for j, r in enumerate(ranges):
            ax = axes[a, j]
            im = ax.imshow(pct[a, j].T, origin="lower", extent=(-h, h, -h, h), cmap="magma", vmin=0.0, vmax=vmax,
                           interpolation="nearest")
            ax.add_patch(plt.Rectangle((-h, -h), 2 * h, 2 * h, fill=False, ec="0.55", lw=2.5))
            ax.plot([-h, h], [PLAYER_SPAWN_Y] * 2, color="c", lw=0.8, ls="--", label="player spawn row")
            if n_players:
                xs = (np.arange(n_players) - (n_players - 1) / 2) * PLAYER_SPACING
                ax.plot(xs, np.full(n_players, PLAYER_SPAWN_Y), "^", ms=4, mfc="none", mec="c", label="player spawns")
            ax.plot(*BOSS_SPAWN, "o", ms=6, mfc="none", mec="lime", mew=1.2, label="boss spawn")
            ax.set(xlim=(-h - 0.6, h + 0.6), ylim=(-h - 0.6, h + 0.6), aspect="equal",
                   xticks=[-10, -5, 0, 5, 10], yticks=[-10, -5, 0, 5, 10])
            ax.tick_params(labelsize=7)
            ax.set_title(f"{agent}, range {float(r):g}", fontsize=8)
        axes[a, 0].set_ylabel("y (world units)", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("x (world units)", fontsize=8)
    fig.colorbar(im, ax=axes, shrink=0.8, label=f"share of alive-player time per {cell:.2f} x {cell:.2f} cell (%)")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    handles.append(plt.Rectangle((0, 0), 1, 1, fill=False, ec="0.55", lw=2.5))
    labels.append(f"walls (x, y = ±{h:g})")
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=7, frameon=False)
    games_txt = f"{games} games per map, " if games else ""
    fig.suptitle("Where the team stands: occupancy of the alive players (team mean)\n"
                 f"{games_txt}test content; +y up, the boss starts at the top", fontsize=9)
    return fig, axes


def load_heatmaps(path) -> dict:
    """``heatmaps.npz`` (``experiments.benchmark1.stage_heatmaps``) as ``{"maps": float[A, R, P, B, B],
    "agents": str[A], "ranges": float[R]}``."""
    with np.load(path) as d:
        return {"maps": d["maps"], "agents": [str(a) for a in d["agents"]], "ranges": [float(r) for r in d["ranges"]]}


def _heatmap_games(config: dict) -> int | None:
    """Games per occupancy map recorded in a Benchmark 1 ``config.json`` (None if absent)."""
    return config.get("budgets", {}).get("heatmap_games")


def save_heatmaps(rf: RunFolder) -> None:
    """Draw ``rf/heatmaps.npz`` (``heatmap_figure``) into ``rf/figures/heatmaps.png``."""
    fig, _ = heatmap_figure(**load_heatmaps(rf.path("heatmaps.npz")), games=_heatmap_games(rf.config))
    rf.save_figure("heatmaps", fig, dpi=HEATMAP_DPI)


def redraw_heatmaps(run_dir) -> Path:
    """Redraw ``run_dir/figures/heatmaps.png`` (atomically) from the run's ``heatmaps.npz`` and
    ``config.json`` alone, without a RunFolder (no training or playtest), under the folder's lock
    (``trainers.runfolder.locked``: refused while a Benchmark 1 job works there). Returns the PNG's path."""
    run_dir = Path(run_dir)
    if not (run_dir / "heatmaps.npz").is_file() or not (run_dir / "config.json").is_file():
        raise ValueError(f"run_dir: value {str(run_dir)!r} holds no heatmaps.npz and config.json; allowed: a "
                         "Benchmark 1 run folder whose heatmaps stage has finished")
    with locked(run_dir):
        games = _heatmap_games(json.loads((run_dir / "config.json").read_text()))
        fig, _ = heatmap_figure(**load_heatmaps(run_dir / "heatmaps.npz"), games=games)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=HEATMAP_DPI, bbox_inches="tight")
        plt.close(fig)
        return atomic_write(run_dir / "figures" / "heatmaps.png", buf.getvalue())


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
    groups = [g for g in ("table", "robust", "population", "mixed") if any(r.startswith(g + "/") for r in runs)]
    fig, axes = plt.subplots(1, len(groups), figsize=(3.4 * len(groups), 2.8), sharey=True)
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
    save_heatmaps(rf)
    training_figure(rf)
    return {"win_rate": means, **rob}


def cli(argv=None) -> None:
    """``python -m experiments.b1_report RUN_DIR``: redraw a Benchmark 1 run's ``figures/heatmaps.png``
    from its ``heatmaps.npz`` and ``config.json`` (no training, no playing)."""
    import argparse

    from raidjax.io import HelpFormatter, run_cli

    ap = argparse.ArgumentParser(prog="python -m experiments.b1_report", formatter_class=HelpFormatter,
                                 description="Redraw a Benchmark 1 run's occupancy heatmaps from its saved maps")
    ap.add_argument("run_dir", help="a Benchmark 1 run folder (experiments.benchmark1 --out) holding heatmaps.npz")
    args = ap.parse_args(argv)

    def main():
        print(redraw_heatmaps(args.run_dir))

    run_cli(main)


if __name__ == "__main__":
    cli()
