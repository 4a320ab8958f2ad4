"""Benchmark 2 report: controllability, diversity and yield tables beside the paper's numbers,
and the t-SNE / controllability / error-vs-diversity figures, from the generated skills of
``experiments.benchmark2``.

Metrics are numpy (``raidjax.pcg.quality``); the
paper's numbers are transcribed from its Tables "controllability" and "diversity" (RaidEnv §5.3).
"""

from __future__ import annotations

import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from raidjax import pcg  # noqa: E402
from raidjax.pcg import quality as pm  # noqa: E402
from trainers.runfolder import RunFolder, markdown_table  # noqa: E402

# Paper, controllability table: target -> (W_c mean, W_c SD, |W_t - W_c| mean, SD).
PAPER_CONTROL = {
    "PCG-HR": {0.1: (0.107, 0.065, 0.044, 0.049), 0.2: (0.206, 0.098, 0.074, 0.065),
               0.3: (0.297, 0.108, 0.079, 0.073), 0.4: (0.416, 0.122, 0.089, 0.085),
               0.5: (0.489, 0.133, 0.099, 0.089), 0.6: (0.592, 0.132, 0.097, 0.090),
               0.7: (0.684, 0.113, 0.088, 0.073)},
    "PPO": {0.1: (0.149, 0.242, 0.156, 0.191), 0.2: (0.266, 0.343, 0.268, 0.225),
            0.3: (0.217, 0.189, 0.169, 0.119), 0.4: (0.377, 0.315, 0.276, 0.153),
            0.5: (0.435, 0.334, 0.296, 0.167), 0.6: (0.606, 0.309, 0.276, 0.138),
            0.7: (0.652, 0.354, 0.292, 0.205)},
    "PCG-RD": {0.1: (0.354, 0.389, 0.335, 0.321), 0.2: (0.366, 0.381, 0.333, 0.249),
               0.3: (0.418, 0.382, 0.348, 0.196), 0.4: (0.381, 0.394, 0.362, 0.154),
               0.5: (0.390, 0.391, 0.379, 0.144), 0.6: (0.409, 0.395, 0.405, 0.168),
               0.7: (0.387, 0.397, 0.445, 0.239)},
}
PAPER_MEAN_ERROR = {"PCG-HR": (0.081, 0.078), "PPO": (0.248, 0.183), "PCG-RD": (0.373, 0.221)}
# Paper, diversity table: target -> SDs of (range, cool time, cast time, damage = coefficient, PC1).
PAPER_DIVERSITY = {
    "PCG-HR": {0.1: (0.258, 0.300, 0.269, 0.265, 0.302), 0.2: (0.262, 0.324, 0.249, 0.288, 0.298),
               0.3: (0.271, 0.312, 0.265, 0.292, 0.312), 0.4: (0.252, 0.312, 0.233, 0.278, 0.304),
               0.5: (0.257, 0.316, 0.236, 0.269, 0.310), 0.6: (0.247, 0.313, 0.236, 0.269, 0.303),
               0.7: (0.257, 0.293, 0.227, 0.263, 0.293), "mean": (0.258, 0.310, 0.246, 0.275, 0.303)},
    "PPO": {0.1: (0.315, 0.482, 0.258, 0.472, 0.625), 0.2: (0.351, 0.381, 0.292, 0.428, 0.421),
            0.3: (0.218, 0.398, 0.261, 0.349, 0.488), 0.4: (0.180, 0.377, 0.364, 0.476, 0.559),
            0.5: (0.204, 0.393, 0.391, 0.405, 0.519), 0.6: (0.105, 0.284, 0.214, 0.212, 0.258),
            0.7: (0.194, 0.271, 0.447, 0.406, 0.625), "mean": (0.237, 0.375, 0.328, 0.402, 0.513)},
    "PCG-RD": {0.1: (0.266, 0.325, 0.294, 0.283, 0.336), 0.2: (0.284, 0.329, 0.279, 0.316, 0.359),
               0.3: (0.268, 0.331, 0.264, 0.308, 0.329), 0.4: (0.277, 0.333, 0.287, 0.292, 0.358),
               0.5: (0.278, 0.328, 0.280, 0.269, 0.326), 0.6: (0.261, 0.317, 0.302, 0.306, 0.385),
               0.7: (0.262, 0.322, 0.258, 0.305, 0.358), "mean": (0.271, 0.326, 0.281, 0.297, 0.351)},
}
DIV_COLS = ("range", "cool_time", "cast_time", "coefficient", "pc1")


def paper_summary() -> dict:
    """The paper's headline numbers: ``mean_error`` and ``pc1_sd`` per method (floats)."""
    return {"mean_error": {m: v[0] for m, v in PAPER_MEAN_ERROR.items()},
            "pc1_sd": {m: PAPER_DIVERSITY[m]["mean"][4] for m in PAPER_DIVERSITY}}


def _pm(mean: float, sd: float) -> str:
    return "–" if not np.isfinite(mean) else f"{mean:.3f} ± {sd:.3f}"


def _t(t) -> str:
    return t if isinstance(t, str) else f"{t:.1f}"


def _f(x) -> str:
    return "–" if x is None or not np.isfinite(x) else f"{x:.3f}"


def controllability_rows(summ: dict) -> list[dict]:
    """Rows (method x target, then a ``"mean"`` row per method) of ``pm.controllability`` numbers
    (episodes with >= 2 edits) beside the paper's. ``summ``: ``summarize`` output."""
    rows = []
    for m, s in summ.items():
        c, paper = s["controllability"], PAPER_CONTROL.get(m, {})
        for t, v in sorted(c["per_target"].items()):
            p = paper.get(round(t, 3), (np.nan,) * 4)
            rows.append({"method": m, "target": round(t, 3), "n": v["n"], "wc_mean": v["wc_mean"], "wc_sd": v["wc_sd"],
                         "err_mean": v["err_mean"], "err_sd": v["err_sd"], "paper_wc_mean": p[0],
                         "paper_wc_sd": p[1], "paper_err_mean": p[2], "paper_err_sd": p[3]})
        p = PAPER_MEAN_ERROR.get(m, (np.nan, np.nan))
        rows.append({"method": m, "target": "mean", "n": c["n"], "wc_mean": np.nan, "wc_sd": np.nan,
                     "err_mean": c["err_mean"], "err_sd": c["err_sd"], "paper_wc_mean": np.nan, "paper_wc_sd": np.nan,
                     "paper_err_mean": p[0], "paper_err_sd": p[1]})
    return rows


def diversity_rows(summ: dict) -> list[dict]:
    """Rows (method x target, then ``"mean"`` over targets) of the SDs of the min-max-normalised
    parameters and of PC1 (skills with error < 0.1, normalisation/PCA pooled over all methods),
    beside the paper's. ``summ``: ``summarize`` output."""
    rows = []
    for m, s in summ.items():
        paper = PAPER_DIVERSITY.get(m, {})
        per = []
        for t in pm.TARGETS:
            d = s["diversity"].get(pm.target_label(t), {"n": 0, "kept": 0, "param_sd": [np.nan] * 4, "pc1_sd": np.nan,
                                                "pc1_own_sd": np.nan})
            vals = list(d["param_sd"]) + [d["pc1_sd"]]
            per.append(vals + [d["pc1_own_sd"]])
            p = paper.get(t, (np.nan,) * 5)
            rows.append({"method": m, "target": t, "n_kept": d["n"], "kept": d["kept"],
                         **dict(zip(DIV_COLS, vals, strict=True)), "pc1_own": d["pc1_own_sd"],
                         **{f"paper_{k}": v for k, v in zip(DIV_COLS, p, strict=True)}})
        a = np.asarray(per, float)
        means = [float(np.nanmean(a[:, j])) if np.isfinite(a[:, j]).any() else np.nan for j in range(6)]
        p = paper.get("mean", (np.nan,) * 5)
        rows.append({"method": m, "target": "mean", "n_kept": sum(r["n_kept"] for r in rows if r["method"] == m),
                     "kept": sum(r["kept"] for r in rows if r["method"] == m),
                     **dict(zip(DIV_COLS, means[:5], strict=True)), "pc1_own": means[5],
                     **{f"paper_{k}": v for k, v in zip(DIV_COLS, p, strict=True)}})
    return rows


def yield_rows(gens: dict) -> list[dict]:
    """Per method: episodes, yield rate (generator's measurement reached the ±0.02 band), edits per
    episode (mean, SD) and episodes with >= 2 edits."""
    rows = []
    for m, g in gens.items():
        y = pm.yield_stats(g)
        rows.append({"method": m, "episodes": len(g["target"]), "yield": y["yield"], "edits_mean": y["edits_mean"],
                     "edits_sd": y["edits_sd"], "n_ge2_edits": int((np.asarray(g["edits"]) >= 2).sum())})
    return rows


def _control_md(rows: list[dict]) -> str:
    body = [[_t(r["target"]), r["method"], r["n"], _pm(r["wc_mean"], r["wc_sd"]),
             _pm(r["paper_wc_mean"], r["paper_wc_sd"]), _pm(r["err_mean"], r["err_sd"]),
             _pm(r["paper_err_mean"], r["paper_err_sd"])]
            for r in sorted(rows, key=lambda r: (r["target"] == "mean", str(r["target"])))]
    return ("## Controllability (episodes with ≥ 2 edits; final skill measured with the run's eval games)\n\n"
            + markdown_table(["target", "method", "n", "W_c (ours)", "W_c (paper)", "|W_t − W_c| (ours)",
                              "|W_t − W_c| (paper)"], body)
            + "\n\nMean ± SD (ddof 0). The `mean` rows pool all targets; paper means: PCG-HR 0.081, "
              "PPO 0.248, PCG-RD 0.373.")


def _diversity_md(rows: list[dict], min_kept: int) -> str:
    body = [[_t(r["target"]), r["method"], f"{r['n_kept']} ({r['kept']})"]
            + [f"{_f(r[k])} ({_f(r['paper_' + k])})" for k in DIV_COLS] + [_f(r["pc1_own"])]
            for r in sorted(rows, key=lambda r: (r["target"] == "mean", str(r["target"])))]
    return ("## Diversity: SD of min-max-normalised parameters and of PC1, ours (paper)\n\n"
            + markdown_table(["target", "method", "n (kept)", "range", "cool time", "cast time", "coefficient",
                              "PC1", "PC1 own axis"], body)
            + "\n\nKept: skills with |W_t − W_c| < 0.1; n: those measured, every group that kept at least "
              f"{min_kept} cut to one size (the smallest such group's, at most the protocol's); `–`: a group that "
              f"kept fewer than {min_kept}, left out. Normalisation and PCA over the pooled measured skills of all "
              "methods (PROTOCOLS.md §11); `PC1 own axis`: SD along the (method, target) group's own first axis, "
              "a check that a lead does not come from the pooled axis. `mean` rows: mean over the measured "
              "targets.")


def _yield_md(rows: list[dict]) -> str:
    body = [[r["method"], r["episodes"], r["n_ge2_edits"], r["yield"], _pm(r["edits_mean"], r["edits_sd"])]
            for r in rows]
    return ("## Yield and edits per episode\n\n"
            + markdown_table(["method", "episodes", "≥ 2 edits", "yield", "edits / episode"], body)
            + "\n\nYield: share of episodes whose generator measurement reached |W_t − W| ≤ 0.02 "
              "(the paper reports no yield numbers).")


def bootstrap(gens: dict, protocol: pm.Protocol | None = None, n_boot: int = 1000, seed: int = 0,
              min_kept: int = 2) -> dict:
    """95 % percentile bootstrap intervals of each method's headline numbers: episodes resampled
    with replacement within each (method, target) group, ``pm.summarize`` recomputed on every
    resample (the pooled normalisation and PCA included).

    Returns:
        ``{method: {"mean_error" | "pc1_sd" | "yield": (low, high)}}`` (NaN where a resample has
        no number).
    """
    rng = np.random.default_rng(seed)
    keys = {"mean_error": lambda s: s["controllability"]["err_mean"], "pc1_sd": lambda s: s["pc1_sd_mean"],
            "yield": lambda s: s["yield"]}
    draws = {m: {k: [] for k in keys} for m in gens}
    groups = {m: [np.flatnonzero(np.round(g["target"], 6) == t) for t in np.unique(np.round(g["target"], 6))]
              for m, g in gens.items()}
    for _ in range(n_boot):
        sample = {}
        for m, g in gens.items():
            idx = np.concatenate([rng.choice(ix, ix.size) for ix in groups[m]])
            sample[m] = {k: np.asarray(v)[idx] for k, v in g.items()}
        for m, s in pm.summarize(sample, protocol, min_kept).items():
            for k, get in keys.items():
                draws[m][k].append(get(s))
    ci = lambda x: tuple(float(v) for v in np.nanpercentile(x, [2.5, 97.5])) if np.isfinite(x).any() else (
        float("nan"), float("nan"))
    return {m: {k: ci(np.asarray(v, float)) for k, v in d.items()} for m, d in draws.items()}


def _summary_md(summ: dict, ci: dict, n_boot: int) -> str:
    paper = paper_summary()
    f = lambda x: "–" if x is None or not np.isfinite(x) else f"{x:.3f}"
    body = [[m, f(s["controllability"]["err_mean"]) + f" [{f(ci[m]['mean_error'][0])}, {f(ci[m]['mean_error'][1])}]",
             f(paper["mean_error"].get(m)),
             f(s["pc1_sd_mean"]) + f" [{f(ci[m]['pc1_sd'][0])}, {f(ci[m]['pc1_sd'][1])}]", f(paper["pc1_sd"].get(m)),
             f(s["yield"]) + f" [{f(ci[m]['yield'][0])}, {f(ci[m]['yield'][1])}]"]
            for m, s in summ.items()]
    return ("## Headline numbers with 95 % bootstrap intervals\n\n"
            + markdown_table(["method", "mean error [95 % CI]", "paper", "PC1 SD [95 % CI]", "paper",
                              "yield [95 % CI]"], body)
            + f"\n\n{n_boot} resamples of the episodes within each (method, target) group, every number "
              "recomputed on each (experiments.b2_report.bootstrap).")


def kept_skills(gens: dict, threshold: float = pm.KEEP_ERROR) -> dict:
    """``gens`` cut to the skills the diversity metric keeps (``|W_t - W_c| < threshold``), the
    paper's t-SNE figure's points; a method with none is left out."""
    out = {}
    for m, g in gens.items():
        k = np.abs(np.asarray(g["target"]) - np.asarray(g["win_rate"])) < threshold
        if k.any():
            out[m] = {f: np.asarray(v)[k] for f, v in g.items()}
    return out


def tsne_figure(gens: dict, seed: int = 0, per_target: int = 300):
    """t-SNE (scikit-learn) of the generated skills (4 parameters min-max scaled by their bounds),
    one joint embedding, one panel per method coloured by target. At most ``per_target`` skills
    per (method, target). Returns ``(figure, n_points)``."""
    from sklearn.manifold import TSNE
    from threadpoolctl import threadpool_limits

    rng = np.random.default_rng(seed)
    xs, ts, ms = [], [], []
    for m, g in gens.items():
        for t in np.unique(g["target"]):
            idx = np.flatnonzero(g["target"] == t)
            idx = rng.choice(idx, min(per_target, idx.size), replace=False)
            xs.append(g["skill"][idx])
            ts += [float(t)] * idx.size
            ms += [m] * idx.size
    lo, hi = pcg.PAPER_SPACE.low, pcg.PAPER_SPACE.high
    x = (np.concatenate(xs) - lo) / (hi - lo)
    ts, ms = np.asarray(ts), np.asarray(ms)
    perplexity = float(min(30.0, max(1.0, (len(x) - 1) / 3)))
    with threadpool_limits(1):  # OpenMP threads beside XLA's pool were 20-50x slower on 2 busy cores
        emb = TSNE(2, perplexity=perplexity, init="pca", random_state=seed).fit_transform(x)
    fig, axes = plt.subplots(1, len(gens), figsize=(4 * len(gens), 3.8), sharex=True, sharey=True)
    for ax, m in zip(np.atleast_1d(axes), gens, strict=True):
        ax.scatter(emb[:, 0], emb[:, 1], s=4, c="0.85")
        k = ms == m
        sc = ax.scatter(emb[k, 0], emb[k, 1], s=8, c=ts[k], cmap="viridis", vmin=0.1, vmax=0.7)
        ax.set_title(m)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.colorbar(sc, ax=axes, label="target win rate", shrink=0.85)
    fig.suptitle(f"t-SNE of generated skills (perplexity {perplexity:.0f}; grey: all methods)")
    return fig, len(x)


def controllability_figure(rows: list[dict]):
    """Generated win rate W_c (mean ± SD) against the target per method, the paper's means as hollow
    markers, and the identity line. ``rows``: ``controllability_rows``. Returns the figure."""
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot([0, 0.8], [0, 0.8], "k:", lw=1, label="W_c = W_t")
    methods = list(dict.fromkeys(r["method"] for r in rows))
    for i, m in enumerate(methods):
        rs = [r for r in rows if r["method"] == m and r["target"] != "mean"]
        t = np.asarray([r["target"] for r in rs], float) + (i - 1) * 0.008
        line = ax.errorbar(t, [r["wc_mean"] for r in rs], [r["wc_sd"] for r in rs], fmt="o-", ms=4, capsize=2,
                           label=m)
        ax.plot(t, [r["paper_wc_mean"] for r in rs], "s--", mfc="none", ms=5, lw=0.8,
                color=line[0].get_color(), label=f"{m} (paper)")
    ax.set(xlabel="target W_t", ylabel="generated W_c", xlim=(0, 0.8), ylim=(-0.05, 1.05),
           title="Controllability")
    ax.legend(fontsize=7, ncol=2)
    return fig


def error_vs_diversity_points(crow: list[dict], drow: list[dict]) -> dict:
    """The points of ``error_vs_diversity_figure``.

    Args:
        crow: ``controllability_rows`` (``err_mean`` per method x target, and a ``"mean"`` row).
        drow: ``diversity_rows`` (``pc1`` per method x target, and a ``"mean"`` row).

    Returns:
        ``{method: {"target": float[k], "pc1": float[k], "err": float[k], "missing": int,
        "mean": (pc1, err), "paper": (pc1, err) | None}}``: the ``k`` targets where both numbers
        are finite, ``missing`` targets left out (no controllability episode, or fewer than 2 kept
        skills), the ``"mean"`` rows' pair and the paper's (mean PC1 SD, mean error).
    """
    out = {}
    for m in dict.fromkeys(r["method"] for r in crow):
        err = {round(r["target"], 3): r["err_mean"] for r in crow if r["method"] == m and r["target"] != "mean"}
        pc1 = {round(r["target"], 3): r["pc1"] for r in drow if r["method"] == m and r["target"] != "mean"}
        ts = [t for t in sorted(err) if np.isfinite(err[t]) and np.isfinite(pc1.get(t, np.nan))]
        mean_err = next(r["err_mean"] for r in crow if r["method"] == m and r["target"] == "mean")
        mean_pc1 = next((r["pc1"] for r in drow if r["method"] == m and r["target"] == "mean"), np.nan)
        paper = (PAPER_DIVERSITY[m]["mean"][4], PAPER_MEAN_ERROR[m][0]) if m in PAPER_MEAN_ERROR else None
        out[m] = {"target": np.asarray(ts, float), "pc1": np.asarray([pc1[t] for t in ts], float),
                  "err": np.asarray([err[t] for t in ts], float), "missing": len(set(err) | set(pc1)) - len(ts),
                  "mean": (float(mean_pc1), float(mean_err)), "paper": paper}
    return out


def error_vs_diversity_figure(crow: list[dict], drow: list[dict]):
    """One scatter of controllability error (y) against diversity (x): per method, one small dot
    per target (labelled with the target), a large diamond for the method's mean (mean PC1 SD over
    targets, error pooled over targets) and a hollow square for the paper's mean. Lower right is
    better. ``crow``, ``drow``: ``controllability_rows``, ``diversity_rows``. Returns the figure."""
    pts = error_vs_diversity_points(crow, drow)
    fig, ax = plt.subplots(figsize=(6, 4.6))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    missing = 0
    for i, (m, p) in enumerate(pts.items()):
        c = colours[i % len(colours)]
        ax.scatter(p["pc1"], p["err"], s=22, color=c, alpha=0.75, label=f"{m}: per target")
        for t, x, y in zip(p["target"], p["pc1"], p["err"], strict=True):
            ax.annotate(f"{t:g}", (x, y), xytext=(3, 2), textcoords="offset points", fontsize=6, color=c)
        if np.all(np.isfinite(p["mean"])):
            ax.scatter(*p["mean"], s=110, marker="D", color=c, edgecolor="black", zorder=3, label=f"{m}: mean")
        if p["paper"] is not None:
            ax.scatter(*p["paper"], s=80, marker="s", facecolor="none", edgecolor=c, lw=1.5, zorder=3,
                       label=f"{m}: paper's mean")
        missing += p["missing"]
    ax.set_xlabel("diversity: SD of the kept skills along PC1\n(skills with |W_t − W_c| < 0.1, "
                  "min-max-normalised parameters)", fontsize=8)
    ax.set_ylabel("controllability error |W_t − W_c|\n(mean over episodes with ≥ 2 edits)", fontsize=8)
    note = f"; {missing} (method, target) group{'s' * (missing > 1)} lacking a number not shown" if missing else ""
    ax.set_title(f"Error vs diversity per generator (lower right is better)\n"
                 f"dots: one per target W_t (labelled){note}", fontsize=9)
    ax.margins(0.12)
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7, ncol=len(pts), loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False)
    return fig


def report(run: RunFolder, gens: dict, seed: int = 0, tsne_per_target: int = 300,
           protocol: pm.Protocol | None = None, n_boot: int = 1000, min_kept: int = 2) -> dict:
    """Write the tables, CSVs and figures of Benchmark 2 into ``run``.

    Args:
        run: the run folder.
        gens: ``{method: generate output}`` (``target`` [n], ``skill`` [n, 4], ``win_rate`` [n], ...).
        seed: t-SNE / subsampling seed.
        tsne_per_target: at most this many skills per (method, target) in the t-SNE.
        protocol: which episodes count and how groups are cut (``summarize``; default raidjax's).
        n_boot: bootstrap resamples behind the intervals (``bootstrap``).
        min_kept: diversity leaves out (method, target) groups that kept fewer skills
            (``raidjax.pcg.quality.diversity``).

    Returns:
        JSON-able ``mean_error``, ``pc1_sd``, ``yield``, ``edits`` and ``n_controllability`` per
        method, and ``seconds``.
    """
    t0 = time.perf_counter()
    summ = pm.summarize(gens, protocol, min_kept)
    crow, drow, yrow = controllability_rows(summ), diversity_rows(summ), yield_rows(gens)
    run.write_csv("controllability", crow)
    run.write_csv("diversity", drow)
    run.write_csv("yield", yrow)
    run.write_table("controllability", _control_md(crow))
    run.write_table("diversity", _diversity_md(drow, min_kept))
    run.write_table("yield", _yield_md(yrow))
    ci = bootstrap(gens, protocol, n_boot, seed, min_kept)
    run.write_table("summary", _summary_md(summ, ci, n_boot))
    run.save_figure("controllability", controllability_figure(crow), dpi=85)
    run.save_figure("error_vs_diversity", error_vs_diversity_figure(crow, drow), dpi=90)
    kept = kept_skills(gens)  # the paper's figure; a tiny run that kept almost none shows every skill
    enough = sum(len(g["target"]) for g in kept.values()) >= 5
    fig, n = tsne_figure(kept if enough else gens, seed, tsne_per_target)
    run.save_figure("tsne", fig, dpi=80)
    run.log(f"report: t-SNE of {n} {'kept' if enough else 'generated (fewer than 5 kept)'} skills; mean errors "
            + ", ".join(
        f"{m} {s['controllability']['err_mean']:.3f}" for m, s in summ.items()))
    fin = lambda x: None if x is None or not np.isfinite(x) else float(x)
    return {"mean_error": {m: fin(s["controllability"]["err_mean"]) for m, s in summ.items()},
            "pc1_sd": {m: fin(s["pc1_sd_mean"]) for m, s in summ.items()},
            "pc1_own_sd": {m: fin(s["pc1_own_sd_mean"]) for m, s in summ.items()},
            "yield": {m: s["yield"] for m, s in summ.items()},
            "edits": {m: s["edits_mean"] for m, s in summ.items()},
            "n_controllability": {m: s["controllability"]["n"] for m, s in summ.items()},
            "ci95": {m: {k: [fin(v) for v in lohi] for k, lohi in c.items()} for m, c in ci.items()},
            "seconds": time.perf_counter() - t0}
