"""Fault injection, MA-POCA trainer and the checkpoint module: runs killed with ``kill -9`` at
chosen moments (``fault_inject.py``), checkpoints corrupted on disk, torn metrics lines, refusals.
A resumed run must equal the uninterrupted one bit-for-bit (metrics rows, final weights,
evaluation) or refuse in one line; nothing lost, duplicated or left half-written. One chain of
faults shares the compiled programs (the persistent compilation cache of ``conftest.py``)."""

from __future__ import annotations

import json
from pathlib import Path

import jax
import numpy as np
import pytest
from fault_inject import flip, largest_state_file, run, same_run, steps, updates
from helpers import TINY_MAPOCA, TINY_MAPOCA_ARGS

from trainers import checkpoint, mapoca_cli
from trainers.runfolder import LOCK_NAME


@pytest.fixture(scope="module")
def tiny_config(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("cfg") / "tiny.json"
    path.write_text(json.dumps(TINY_MAPOCA))
    return path


def test_mapoca_survives_a_chain_of_kills_and_a_corrupted_checkpoint(tmp_path, tiny_config, capsys):
    # No evaluation (a function of the final weights, compared below); test_refusals... runs one.
    args = ["--config", str(tiny_config), *TINY_MAPOCA_ARGS, "--eval-games", "0"]
    ref, out = tmp_path / "uninterrupted", tmp_path / "faulty"
    mapoca_cli.main([*args, "--out", str(ref)])  # in-process: the same programs, shared by the cache
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert last == json.loads((ref / "result.json").read_text()) and last["env_steps"] == 128
    ckpt = out / "checkpoints"

    def faulty(fault: str, killed: bool = True, resume: bool = True):
        return run(fault, "trainers.mapoca_cli", [*args, "--out", str(out)] + ["--resume"] * resume, killed)

    faulty("before_save=2", resume=False)  # chunk 2's row written, its checkpoint not
    assert steps(ckpt) == [1] and updates(out) == [1, 2]
    faulty("during_save=2")  # resumed at 1, row 2 trimmed and rewritten (not duplicated), checkpoint 2
    # saved; chunk 3's checkpoint fully written to a temporary folder, never committed
    assert steps(ckpt) == [1, 2] and any(not p.name.isdigit() for p in ckpt.iterdir())
    assert updates(out) == [1, 2, 3]
    faulty("mid_metrics=2")  # resumed at 2; row 3 and checkpoint 3 done, row 4 torn
    assert steps(ckpt) == [1, 2, 3] and updates(out) == [1, 2, 3, "torn"]
    f = largest_state_file(ckpt / "3")
    flip(f, f.stat().st_size // 2)
    p = faulty("mid_file=1")  # checkpoint 3 rejected (back to 2); killed while trimming the metrics
    assert f"warning: checkpoint {ckpt / '3'} is corrupted" in p.stderr and "trying the previous one" in p.stderr
    assert f"warning: {out / 'metrics.jsonl'} line 4 is not a whole JSON row" in p.stderr
    assert (out / "checkpoints_rejected" / "3").is_dir() and steps(ckpt) == [1, 2]  # moved aside, not deleted
    assert updates(out) == [1, 2, 3, "torn"]  # the old file is whole: the rewrite was cut in its temporary
    p = faulty("none", killed=False)
    assert "removed an unfinished temporary file" in p.stdout
    same_run(out, ref)


def _two_checkpoints(ckpt: Path):
    state = {"w": np.arange(5000, dtype=np.float32).reshape(50, 100), "key": jax.random.key(0)}
    for u in (1, 2):
        checkpoint.save(ckpt, {**state, "w": state["w"] * u}, {"w": state["w"] * u}, {}, {"update": u})
    return state, largest_state_file(ckpt / "2")


def test_a_changed_file_is_caught_before_orbax_reads_it(tmp_path, capsys):
    ckpt = tmp_path / "checkpoints"
    state, f = _two_checkpoints(ckpt)
    flip(f, 2000)
    got, _, meta = checkpoint.restore(ckpt, jax.eval_shape(lambda: state))
    assert meta["update"] == 1 and np.array_equal(np.asarray(got["w"]), state["w"])
    name = f.relative_to(ckpt / "2")
    assert f"warning: checkpoint {ckpt / '2'} is corrupted ({name} does not match its saved digest)" in (
        capsys.readouterr().err)
    f.write_bytes(f.read_bytes()[:100])
    weights, _ = checkpoint.load_policy_weights(ckpt)
    assert np.array_equal(np.asarray(weights["w"]), state["w"])
    assert f"({name}: 100 bytes, " in capsys.readouterr().err


def test_loading_the_policy_logs_nothing(tmp_path, caplog):
    """The policy restores as it was saved, without orbax's warning that the item folder has no
    step metadata (reading the item's metadata through a whole-step checkpointer logged one)."""
    ckpt = tmp_path / "checkpoints"
    state, _ = _two_checkpoints(ckpt)
    with caplog.at_level("DEBUG"):
        weights, _ = checkpoint.load_policy_weights(ckpt)
    assert np.array_equal(np.asarray(weights["w"]), 2 * state["w"])
    assert not [r for r in caplog.records if r.levelno >= 30], [r.getMessage() for r in caplog.records]


def test_flipped_bytes_orbax_reads_without_error_fail_the_pytree_digest(tmp_path, capsys):
    """Without its file list (a save killed just before writing it), 64 bytes flipped inside raw
    float data load without an error (the issue's silent garbage); the pytree digest catches them."""
    ckpt = tmp_path / "checkpoints"
    state, f = _two_checkpoints(ckpt)
    (ckpt / "2" / checkpoint.FILES).unlink()
    flip(f, 2000)
    got, _, meta = checkpoint.restore(ckpt, jax.eval_shape(lambda: state))
    assert meta["update"] == 1 and np.array_equal(np.asarray(got["w"]), state["w"])
    assert f"warning: checkpoint {ckpt / '2'} is corrupted (state does not match its saved digest)" in (
        capsys.readouterr().err)


def test_rejected_checkpoints_are_set_aside_without_overwriting_one_another(tmp_path, capsys):
    """Two groups of one run (Benchmark 1's ``checkpoints/mapoca/group<g>``) each reject their update
    2, then one of them saves update 2 again and rejects it again: three folders set aside, none
    overwritten (each holds the flipped file it was rejected with)."""
    parent = tmp_path / "checkpoints" / "mapoca"
    state, f0 = _two_checkpoints(parent / "group0")
    _, f1 = _two_checkpoints(parent / "group1")
    abstract = jax.eval_shape(lambda: state)

    def reject(ckpt: Path, f: Path, at: int) -> bytes:
        flip(f, at)  # a different place each time: each rejected copy differs from the others
        broken = f.read_bytes()
        _, _, meta = checkpoint.restore(ckpt, abstract, quarantine=True)
        assert meta["update"] == 1 and not (ckpt / "2").exists()
        return broken

    rejected = [reject(parent / "group0", f0, 2000), reject(parent / "group1", f1, 2064)]
    checkpoint.save(parent / "group0", {**state, "w": state["w"] * 2}, {"w": state["w"] * 2}, {}, {"update": 2})
    rejected.append(reject(parent / "group0", largest_state_file(parent / "group0" / "2"), 2128))
    capsys.readouterr()
    aside = [parent / "group0_rejected" / "2", parent / "group1_rejected" / "2", parent / "group0_rejected" / "2.1"]
    for folder, broken in zip(aside, rejected, strict=True):
        assert any(g.read_bytes() == broken for g in folder.rglob("*") if g.is_file()), folder


def cli(module, argv, capsys) -> tuple[int, str]:
    """Run ``module.cli(argv)`` in-process: ``(exit code, stderr)``."""
    with pytest.raises(SystemExit) as e:
        module.cli(argv)
    return e.value.code, capsys.readouterr().err


def test_refusals_are_one_line_and_touch_nothing(tmp_path, tiny_config, capsys):
    # The chain's training (128 steps): its programs are read from the compilation cache.
    args = ["--config", str(tiny_config), *TINY_MAPOCA_ARGS, "--eval-games", "4"]
    out = tmp_path / "run"
    first = mapoca_cli.main([*args, "--out", str(out)])
    assert 0.0 <= first["win_rate"] <= 1.0 and len(str(first["win_rate"])) <= 8  # 0.75, not 0.75000001
    assert len(str(first["heuristic_win_rate"])) <= 8
    files = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}

    cases = [
        ([*args, "--out", str(out)], f"{out} already holds a run: pass --resume"),
        ([*args, "--out", str(out), "--resume", "--total-steps", "256"],
         "other settings (config.total_steps: saved 128, now 256)"),
        ([*args, "--out", str(tmp_path / "empty"), "--resume"], "holds no run to resume"),
        ([*args, "--out", str(out / "config.json")], "is a file; allowed: a folder"),
    ]
    for argv, message in cases:
        code, err = cli(mapoca_cli, argv, capsys)
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    code, err = cli(mapoca_cli, [*args, "--out", str(out), "--resume", "--total-steps", "0"], capsys)  # argparse
    assert code == 2 and "--total-steps: value '0'; allowed: a whole number >= 1" in err and "Traceback" not in err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == files

    result = mapoca_cli.main([*args, "--out", str(out), "--resume"])  # finished: a no-op that says so
    assert "already finished: nothing to do" in capsys.readouterr().out
    assert result == json.loads((out / "result.json").read_text())
    # what it may write: its log line, and the lock file's holder (this process, now)
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name not in ("log.txt", LOCK_NAME)} == {
        p: b for p, b in files.items() if p.name != LOCK_NAME}

    for step in steps(out / "checkpoints"):  # every checkpoint bad: a one-line error, no fallback left
        f = largest_state_file(out / "checkpoints" / str(step))
        flip(f, f.stat().st_size // 2)
    (out / "result.json").unlink()
    code, err = cli(mapoca_cli, [*args, "--out", str(out), "--resume"], capsys)
    assert code == 2 and err.strip().splitlines()[-1].startswith("error: no intact checkpoint in")
    assert all(line.startswith(("warning:", "error:")) for line in err.strip().splitlines())
