"""Execute the notebooks in ``notebooks/`` at smoke scale (``RAIDJAX_SMOKE=1``) with nbclient."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

nbclient = pytest.importorskip("nbclient")
nbformat = pytest.importorskip("nbformat")

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "notebooks"


def execute(name: str, monkeypatch: pytest.MonkeyPatch, **env: str):
    """Run ``notebooks/<name>`` in a fresh ``python3`` kernel from the repository root; return it."""
    monkeypatch.setenv("RAIDJAX_SMOKE", "1")
    for k, v in env.items():
        monkeypatch.setenv(k, v)
    nb = nbformat.read(NOTEBOOKS / name, as_version=4)
    client = nbclient.NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(ROOT)}}
    )
    client.execute()  # raises CellExecutionError on the first failing cell
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors, errors
    return nb


def output_text(nb) -> str:
    """Everything the notebook printed or displayed as text (stdout, text/plain, text/markdown)."""
    parts = []
    for cell in nb.cells:
        for out in cell.get("outputs", []):
            if out.output_type == "stream":
                parts.append(out.text)
            for mime in ("text/plain", "text/markdown"):
                if mime in out.get("data", {}):
                    parts.append(out.data[mime])
    return "\n".join(parts)


def has_image(nb, mime: str) -> bool:
    return any(mime in out.get("data", {}) for c in nb.cells for out in c.get("outputs", []))


def test_notebooks_committed_with_full_size_outputs():
    """The stored notebooks read on a code host: every code cell ran, in order, without an error,
    at full size (not the smoke sizes the tests below use)."""
    for path in sorted(NOTEBOOKS.glob("*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        nbformat.validate(nb)
        code = [c for c in nb.cells if c.cell_type == "code"]
        assert [c.execution_count for c in code] == list(range(1, len(code) + 1)), f"{path.name}: run all cells"
        assert not any(o.output_type == "error" for c in code for o in c.outputs), f"{path.name}: an error is stored"
        assert "smoke=True" not in output_text(nb), f"{path.name}: stored at smoke size"


def test_quickstart(monkeypatch):
    nb = execute("quickstart.ipynb", monkeypatch)
    text = output_text(nb)
    assert "PT-HR" in text and "PT-RD" in text
    assert "ValueError: range" in text
    assert has_image(nb, "image/gif") and has_image(nb, "image/png")


def test_balancing_sweep(monkeypatch):
    nb = execute("balancing_sweep.ipynb", monkeypatch)
    assert "4 ranges x 4 cool times = 16 contents" in output_text(nb)
    assert "saved balance_map.png and win_rate.json in a temporary folder" in output_text(nb)  # docs/ only at full size
    assert has_image(nb, "image/png")


def test_balance_map_figure_orientation_scale_and_contour(tmp_path):
    """``experiments.balance_map``: win_rate[range, cool] is drawn at (x = cool time, y = range) on a
    0-1 scale with a labelled colour bar; the 0.5 contour appears when the map crosses 0.5 and
    separates the cells below it from those above; the PNG is written."""
    import numpy as np
    from PIL import Image

    from experiments.balance_map import balance_map_figure, save_png

    ranges, cools = np.linspace(3.0, 18.0, 6), np.linspace(0.25, 4.0, 5)
    win = np.zeros((6, 5))
    win[3:, :] = 1.0  # won from the 4th range up, at every cool time
    win[5, 4] = 0.25  # one marked cell: top range, longest cool time
    fig, ax = balance_map_figure(win, ranges, cools, 7, reference=(0.5, 5.0))
    im = ax.images[0]
    assert im.get_clim() == (0.0, 1.0) and im.origin == "lower"
    x0, x1, y0, y1 = im.get_extent()
    assert x0 < cools[0] < cools[-1] < x1 and y0 < ranges[0] < ranges[-1] < y1
    assert np.asarray(im.get_array())[5, 4] == 0.25  # row = range (up), column = cool time (right)
    assert len(fig.axes) == 2 and "win rate" in fig.axes[1].get_ylabel()  # the colour bar
    assert "cool time (s)" in ax.get_xlabel() and "range" in ax.get_ylabel()
    (line,) = [p for c in ax.collections for p in c.get_paths()]  # the 0.5 contour
    assert np.all((line.vertices[:, 1] > ranges[1]) & (line.vertices[:, 1] < ranges[4]))
    png = save_png(fig, tmp_path / "map.png")
    with Image.open(png) as img:
        assert img.size[0] > 300
    flat, _ = balance_map_figure(np.zeros((6, 5)), ranges, cools, 7)
    assert not flat.axes[0].collections  # nothing crosses 0.5: no contour


def test_benchmark_results(monkeypatch, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from trainers.runfolder import RunFolder, markdown_table

    run = RunFolder(tmp_path / "run", {"scale": "smoke", "games": 16})
    table = markdown_table(["agent", "range 5", "range 9"], [["PT-HR synthetic", 0.125, 0.5]])
    run.write_table("win_rates", table)
    run.write_csv("win_rates", [{"agent": "PT-HR", "range": 5, "win_rate": 0.125},
                                {"agent": "PT-HR", "range": 9, "win_rate": 0.5}])
    fig, ax = plt.subplots(figsize=(2, 2))
    ax.plot([0, 1], [0, 1])
    run.save_figure("curve", fig, dpi=30)
    run.finish({"status": "synthetic"})

    nb = execute("benchmark_results.ipynb", monkeypatch, RAIDJAX_RUN_DIR=str(run.out))
    text = output_text(nb)
    assert "| PT-HR synthetic | 0.125 | 0.500 |" in text  # the table, rendered as Markdown
    assert "win_rates.csv" in text and "| PT-HR | 9 | 0.5 |" in text
    assert json.loads((run.out / "summary.json").read_text())["status"] == "synthetic"
    assert '"status": "synthetic"' in text
    assert has_image(nb, "image/png")


def test_benchmark_results_missing_folder(monkeypatch, tmp_path):
    with pytest.raises(nbclient.exceptions.CellExecutionError, match="does not exist"):
        execute("benchmark_results.ipynb", monkeypatch, RAIDJAX_RUN_DIR=str(tmp_path / "nowhere"))
