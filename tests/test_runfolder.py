"""Run folders (``trainers.runfolder.RunFolder``) without a trainer: what ``config.json`` says after a
resume with other values of the settings a run may change, and the stage records a kill leaves."""

from __future__ import annotations

import json

import pytest

from trainers import runfolder
from trainers.runfolder import RunFolder


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
