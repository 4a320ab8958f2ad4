"""The docs' figure scripts run on the stored results and on tiny synthetic run folders."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("matplotlib")

from experiments import b1_compare, calibration_figure, speed_figure  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def test_calibration_figure_from_the_stored_tables(tmp_path):
    tables = sorted((ROOT / "docs" / "results" / "calibration").glob("calibration_*_seed*.json"))
    assert tables
    out = tmp_path / "c.png"
    calibration_figure.main([*map(str, tables), "--out", str(out)])
    assert out.stat().st_size > 1000


def _run_folder(path: Path, win: float) -> Path:
    (path / "csv").mkdir(parents=True)
    (path / "train").mkdir()
    rows = ["agent,range,mean,sd,n,paper"] + [f"MA-POCA,{r},{win},0.01,2,0.5" for r in (5.0, 9.0, 13.0, 17.0)]
    (path / "csv" / "win_rate_table.csv").write_text("\n".join(rows) + "\n")
    cols = [f"win/table/r{r}/{s}" for r in (5, 9, 13, 17) for s in (0, 1)]
    lines = ["chunk,env_steps," + ",".join(cols), "0,100," + ",".join(["0.2"] * 8), "1,200," + ",".join(["0.6"] * 8)]
    (path / "train" / "metrics.csv").write_text("\n".join(lines) + "\n")
    return path


def test_b1_compare_table_and_curves(tmp_path, capsys):
    a, b = _run_folder(tmp_path / "a", 0.9), _run_folder(tmp_path / "b", 0.4)
    assert b1_compare.curves(a)[13.0] == ([100.0, 200.0], [0.2, 0.6])  # mean over the two seeds
    out = tmp_path / "curves.png"
    b1_compare.main([str(a), str(b), "--labels", "ours", "theirs", "--out", str(out)])
    text = capsys.readouterr().out
    assert "| ours | 0.900 ± 0.010 |" in text and "| theirs | 0.400 ± 0.010 |" in text and out.stat().st_size > 1000
    with pytest.raises(SystemExit):
        b1_compare.main([str(a), "--labels", "x", "y", "--out", str(out)])


def test_speed_figure_reads_the_stored_vs_smax_runs_and_skips_other_lines(tmp_path):
    stored = sorted((ROOT / "docs" / "results" / "speed").glob("*.json*"))
    runs = speed_figure.summaries([str(p) for p in stored])
    assert runs and all(r["benchmark"] == "vs_smax" for r in runs)
    assert any(r["machine"]["platform"] == "gpu" for r in runs)  # gpu_h100.jsonl: rows and summaries mixed
    out = tmp_path / "speed.png"
    speed_figure.main([*map(str, stored), "--out", str(out)])
    assert out.stat().st_size > 1000
    other = tmp_path / "step_cost.json"
    other.write_text('{"benchmark": "step_cost"}\n')
    before = out.read_bytes()
    with pytest.raises(SystemExit):  # a file without a vs_smax summary: one line, the figure untouched
        speed_figure.main([str(other), "--out", str(out)])
    assert out.read_bytes() == before
    with pytest.raises(SystemExit):  # an unreadable file
        speed_figure.main([str(tmp_path / "missing.json"), "--out", str(out)])


@pytest.mark.parametrize("main, inputs", [(calibration_figure.main, ["missing.json"]),
                                          (b1_compare.main, ["missing", "--labels", "x"])])
def test_a_bad_out_is_refused_before_reading_or_drawing(main, inputs, tmp_path, capsys):
    for out, why in ((tmp_path, "is a folder"), (tmp_path / "nowhere" / "f.png", "is in a folder that does not exist"),
                     (tmp_path / "f.pdf", "does not end in .png")):
        with pytest.raises(SystemExit) as e:
            main([*inputs, "--out", str(out)])
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert e.value.code == 2 and f"--out: value '{out}' {why}" in err, err


def test_calibration_figure_names_a_json_file_that_is_not_a_calibration_table(tmp_path, capsys):
    for i, text in enumerate(('[1, 2]', '{"foo": 1}', '{"table": {"heuristic": {}}, "seed": 0, "games_per_cell": 1}')):
        bad = tmp_path / f"bad{i}.json"
        bad.write_text(text)
        with pytest.raises(SystemExit):
            calibration_figure.main([str(bad), "--out", str(tmp_path / "c.png")])
        err = capsys.readouterr().err
        assert f"inputs: {bad} is not a raidjax.calibrate --json file" in err and "Traceback" not in err
    assert not (tmp_path / "c.png").exists()
