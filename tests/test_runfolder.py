"""Run folders (``trainers.runfolder.RunFolder``) without a trainer: what ``config.json`` says after a
resume with other values of the settings a run may change, the stage records a kill leaves, and the
lock that keeps a second process out of a folder in use."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from trainers import runfolder
from trainers.runfolder import RunFolder, RunFolderError, locked

ROOT = Path(__file__).resolve().parent.parent


def saved(out) -> dict:
    return json.loads((out / "config.json").read_text())


def test_an_unfinished_run_resumed_records_the_new_value_of_an_ignored_setting(tmp_path):
    out = tmp_path / "run"
    RunFolder(out, {"steps": 8, "eval_games": 100}, ignore=("eval_games",))
    RunFolder(out, {"steps": 8, "eval_games": 5}, resume=True, ignore=("eval_games",))
    assert saved(out) == {"steps": 8, "eval_games": 5}  # the evaluation still to come uses it


def test_a_finished_run_keeps_the_settings_its_results_were_made_with_until_a_stage_is_redone(tmp_path, capsys):
    out = tmp_path / "run"
    RunFolder(out, {"steps": 8, "eval_games": 100}, ignore=("eval_games",))
    (out / "result.json").write_text("{}")
    rf = RunFolder(out, {"steps": 8, "eval_games": 5}, resume=True, ignore=("eval_games",))
    assert rf.finished and saved(out)["eval_games"] == 100  # config.json still describes result.json
    rf.already_finished()
    assert "it finished with eval_games 100; the value given now (5) applies to a new run only" in (
        capsys.readouterr().out)
    rf.redo("report", "eval_games changed")  # a stage done again is done with the new value
    assert not rf.finished and saved(out)["eval_games"] == 5


@pytest.mark.parametrize("killed_at", ["records.json", "train.json"])
def test_a_stage_killed_while_it_is_stored_is_done_again_and_counted_once(tmp_path, monkeypatch, killed_at):
    # A stage is stored in two files: its record (stages/records.json: start, seconds, machine) and
    # its result (stages/train.json: the stage is done). Killed at either, the stage is not done
    # and runs again on resume; a done stage always has its record, so the run's seconds count it.
    out = tmp_path / "run"
    rf = RunFolder(out, {"steps": 8})
    real = runfolder.atomic_write

    def killed(path, data):
        if path.name == killed_at:
            raise KeyboardInterrupt
        return real(path, data)

    monkeypatch.setattr(runfolder, "atomic_write", killed)
    with pytest.raises(KeyboardInterrupt):
        rf.stage("train", lambda: {"loss": 1.0})
    monkeypatch.setattr(runfolder, "atomic_write", real)
    rf = RunFolder(out, {"steps": 8}, resume=True)
    assert not rf.done("train") and rf.stage_seconds() == {}
    assert rf.stage("train", lambda: {"loss": 2.0}) == {"loss": 2.0}  # run again, not skipped
    assert rf.done("train") and list(rf.records()) == ["train"] and set(rf.stage_seconds()) == {"train"}


# A second process opening the run folder: it holds the folder until it is killed or its stdin closes.
HOLDER = """
import sys
from trainers.runfolder import RunFolder, RunFolderError
try:
    rf = RunFolder(sys.argv[1], {"steps": 8}, resume=True)
except RunFolderError as e:
    print("refused:", e, flush=True)
    sys.exit(3)
print("holding", flush=True)
sys.stdin.read()
"""


def other_process(out) -> subprocess.Popen:
    """``HOLDER`` on ``out`` in a new process, once it has said whether it holds the folder."""
    child = subprocess.Popen([sys.executable, "-c", HOLDER, str(out)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    child.said = ""
    while not child.said.startswith(("holding", "refused")):  # past the run folder's own log lines
        line = child.stdout.readline()
        assert line, "the other process ended without a word"
        child.said = line.strip()
    return child


def test_a_folder_in_use_by_another_process_is_refused_until_that_process_ends(tmp_path):
    out = tmp_path / "run"
    RunFolder(out, {"steps": 8}).close()
    child = other_process(out)
    assert child.said == "holding"
    files = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    with pytest.raises(RunFolderError, match=rf"{out} is in use by process {child.pid} on .*: wait for it to end"):
        RunFolder(out, {"steps": 8}, resume=True)
    with pytest.raises(RunFolderError, match="already holds a run"):  # the settings' refusals come first
        RunFolder(out, {"steps": 8})
    child.kill()  # however it ends, the system releases its lock: no stale lock to remove by hand
    child.wait()
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == files  # the refusals touched nothing
    with RunFolder(out, {"steps": 8}, resume=True) as rf:
        assert rf.resumed
        assert other_process(out).said.startswith(f"refused: {out} is in use by process {os.getpid()} on ")
    child = other_process(out)  # the with block released it
    assert child.said == "holding"
    child.communicate("")


def test_a_redraw_is_refused_while_another_process_works_in_the_folder(tmp_path):
    """``locked``: a job that writes into a run folder without a RunFolder (``b1_report``'s heatmap
    redraw) is refused in one line while another process holds the folder, and runs once it ends."""
    from experiments import b1_report

    out = tmp_path / "run"
    RunFolder(out, {"steps": 8}).close()
    np.savez(out / "heatmaps.npz", maps=np.full((1, 1, 3, 24, 24), 1 / 24**2), agents=np.asarray(["A"]),
             ranges=np.asarray([5.0]))
    child = other_process(out)
    assert child.said == "holding"
    with pytest.raises(RunFolderError, match=rf"{out} is in use by process {child.pid} on "):
        b1_report.redraw_heatmaps(out)
    assert not (out / "figures").exists()
    child.kill()
    child.wait()
    with RunFolder(out, {"steps": 8}, resume=True):  # this process's own folder: shared
        with locked(out):
            pass
        assert other_process(out).said.startswith("refused")  # leaving locked kept the RunFolder's lock
        assert b1_report.redraw_heatmaps(out).is_file()
    child = other_process(out)  # and the last use released it
    assert child.said == "holding"
    child.communicate("")


def test_a_refusal_before_the_lock_makes_no_lock_file(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.json").write_text(json.dumps({"steps": 8}))  # a run saved before the lock existed
    for kwargs in ({}, {"resume": True, "config": {"steps": 9}}):
        with pytest.raises(RunFolderError):
            RunFolder(out, **{"config": {"steps": 8}, **kwargs})
    assert sorted(p.name for p in out.iterdir()) == ["config.json"]


def test_a_renamed_folder_is_the_same_lock(tmp_path):
    first = RunFolder(tmp_path / "run", {"steps": 8})
    (tmp_path / "run").rename(tmp_path / "moved")
    with RunFolder(tmp_path / "moved", {"steps": 8}, resume=True):  # this process holds it: not refused
        pass
    assert other_process(tmp_path / "moved").said.startswith("refused:")  # still held by ``first``
    first.close()


def test_this_process_may_open_its_own_folder_again_and_holds_it_until_the_last_close(tmp_path):
    out = tmp_path / "run"
    first = RunFolder(out, {"steps": 8})
    second = RunFolder(out, {"steps": 8}, resume=True)  # e.g. a notebook resuming its own run
    first.close()
    first.close()  # idempotent: one release per object
    assert other_process(out).said.startswith("refused:")
    del second  # collected: released as by close()
    child = other_process(out)
    assert child.said == "holding"
    child.communicate("")


def test_a_refusal_under_the_lock_releases_it(tmp_path, monkeypatch):
    out = tmp_path / "run"
    RunFolder(out, {"steps": 8}).close()
    monkeypatch.setattr(runfolder, "atomic_write", lambda *a: (_ for _ in ()).throw(OSError("disk full")))
    with pytest.raises(OSError, match="disk full") as caught:
        RunFolder(out, {"steps": 8, "eval_games": 5}, resume=True, ignore=("eval_games",))  # writes config.json
    # the traceback kept (as a notebook keeps the last one) holds the half-made RunFolder: not its lock
    assert caught.tb is not None and other_process(out).said == "holding"


def test_a_folder_deleted_and_made_again_is_locked_anew(tmp_path):
    import shutil

    out = tmp_path / "run"
    kept = RunFolder(out, {"steps": 8})  # still alive (a notebook's variable) when the folder goes
    shutil.rmtree(out)
    again = RunFolder(out, {"steps": 8})  # a new run in the same place: its own lock, really taken
    assert other_process(out).said.startswith(f"refused: {out} is in use by process {os.getpid()}")
    kept.close()
    assert other_process(out).said.startswith("refused:")
    again.close()
    child = other_process(out)
    assert child.said == "holding"
    child.communicate("")
