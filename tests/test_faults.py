"""Fault injection: runs killed with ``kill -9`` at chosen moments (``fault_inject.py``), checkpoints
corrupted on disk, torn metrics lines. Every resumed run must equal the uninterrupted one
bit-for-bit (same metrics rows, same final weights, same evaluation) or refuse in one line, and
nothing may be lost or duplicated. Each trainer is taken through one chain of faults, so the
compiled programs are shared (the persistent compilation cache of ``conftest.py``)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

from trainers import checkpoint, mapoca_cli, ppo_pcgrl_cli

ROOT = Path(__file__).resolve().parent.parent
TIMING = {"seconds", "steps_per_s", "train_seconds", "eval_seconds", "compile_seconds", "env_steps_per_s"}
TINY_MAPOCA = {"n_arenas": 4, "n_steps": 8, "n_minibatches": 2, "update_epochs": 1, "hidden": 8, "layers": 1,
               "heads": 1, "updates_per_chunk": 1, "checkpoint_every": 1}


def _run(fault: str, module: str, args: list[str], killed: bool) -> subprocess.CompletedProcess:
    p = subprocess.run([sys.executable, str(ROOT / "tests" / "fault_inject.py"), fault, module, *args],
                       cwd=ROOT, capture_output=True, text=True, timeout=900)
    expected = -9 if killed else 0
    assert p.returncode == expected, f"{fault}: exit {p.returncode}, expected {expected}\n{p.stderr[-3000:]}"
    assert "Traceback" not in p.stderr, p.stderr[-3000:]
    return p


def _steps(ckpt: Path) -> list[int]:
    return sorted(int(p.name) for p in ckpt.iterdir() if p.name.isdigit())


def _rows(out: Path) -> list[dict]:
    """Metrics rows without wall-clock fields; a torn line stays a string (so it shows in a diff)."""
    rows = []
    for line in (out / "metrics.jsonl").read_text().splitlines():
        try:
            rows.append({k: v for k, v in json.loads(line).items() if k not in TIMING})
        except json.JSONDecodeError:
            rows.append(line)
    return rows


def _updates(out: Path) -> list:
    return [r["update"] if isinstance(r, dict) else "torn" for r in _rows(out)]


def _assert_same_weights(a: Path, b: Path) -> None:
    wa, _ = checkpoint.load_policy_weights(a / "checkpoints")
    wb, _ = checkpoint.load_policy_weights(b / "checkpoints")
    for x, y in zip(jax.tree.leaves(wa), jax.tree.leaves(wb), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def _flip_bytes(step_dir: Path, n: int = 64) -> Path:
    """Flip ``n`` bytes in the middle of the largest file of the checkpoint's ``state`` item."""
    f = max((p for p in (step_dir / "state").rglob("*") if p.is_file()), key=lambda p: p.stat().st_size)
    _flip_at(f, f.stat().st_size // 2, min(n, f.stat().st_size // 2))
    return f


def _truncate(step_dir: Path) -> Path:
    f = max((p for p in (step_dir / "state").rglob("*") if p.is_file()), key=lambda p: p.stat().st_size)
    f.write_bytes(f.read_bytes()[: f.stat().st_size // 3])
    return f


def _without_timing(result: dict) -> dict:
    return {k: v for k, v in result.items() if k not in TIMING}


@pytest.fixture(scope="module")
def tiny_config(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("cfg") / "tiny.json"
    path.write_text(json.dumps(TINY_MAPOCA))
    return path


def test_mapoca_survives_a_chain_of_kills_and_a_corrupted_checkpoint(tmp_path, tiny_config):
    mod = "trainers.mapoca_cli"
    args = ["--config", str(tiny_config), "--total-steps", "128", "--skill-range", "9", "--eval-games", "8"]
    ref, out = tmp_path / "uninterrupted", tmp_path / "faulty"
    _run("none", mod, [*args, "--out", str(ref)], killed=False)
    ckpt = out / "checkpoints"
    run = lambda fault, killed=True, resume=True: _run(fault, mod, [*args, "--out", str(out)]  # noqa: E731
                                                       + ["--resume"] * resume, killed)

    run("before_save=2", resume=False)  # chunk 2's row written, its checkpoint not
    assert _steps(ckpt) == [1] and _updates(out) == [1, 2]
    run("during_save=1")  # resumed at 1; chunk 2's checkpoint fully written, never committed
    assert _steps(ckpt) == [1] and any(not p.name.isdigit() for p in ckpt.iterdir())
    assert _updates(out) == [1, 2]  # row 2 trimmed on resume and written again: not duplicated
    run("mid_metrics=2")  # resumed at 1; row 2 and checkpoint 2 done, row 3 torn
    assert _steps(ckpt) == [1, 2] and _updates(out) == [1, 2, "torn"]
    p = run("after_save=1")  # resumed at 2 (the torn line dropped, with a warning), checkpoint 3 done
    assert f"warning: {out / 'metrics.jsonl'} line 3 is not a whole JSON row" in p.stderr
    assert _steps(ckpt) == [1, 2, 3] and _updates(out) == [1, 2, 3]
    _flip_bytes(ckpt / "3")
    p = run("none", killed=False)  # checkpoint 3 fails to load or to match its digest: back to 2, and finished
    assert f"warning: checkpoint {ckpt / '3'} is " in p.stderr and "trying the previous one" in p.stderr
    assert (out / "checkpoints_rejected" / "3").is_dir()  # moved aside, not deleted

    assert _rows(out) == _rows(ref)
    _assert_same_weights(out, ref)
    res, res_ref = (json.loads((d / "result.json").read_text()) for d in (out, ref))
    assert _without_timing(res) == _without_timing(res_ref)


def test_ppo_pcgrl_survives_a_chain_of_kills_and_a_truncated_checkpoint(tmp_path):
    mod = "trainers.ppo_pcgrl_cli"
    args = ["--total-steps", "64", "--n-arenas", "2", "--n-games", "2", "--chunk", "1", "--eval-episodes", "1",
            "--eval-gen-games", "2", "--eval-games", "2", "--no-baselines"]
    ref, out = tmp_path / "uninterrupted", tmp_path / "faulty"
    _run("none", mod, [*args, "--out", str(ref)], killed=False)
    ckpt = out / "checkpoints"
    run = lambda fault, killed=True, resume=True: _run(fault, mod, [*args, "--out", str(out)]  # noqa: E731
                                                       + ["--resume"] * resume, killed)

    run("before_save=2", resume=False)
    assert _steps(ckpt) == [1] and _updates(out) == [1, 2]
    run("mid_metrics=2")
    assert _steps(ckpt) == [1, 2] and _updates(out) == [1, 2, "torn"]
    run("after_save=1")
    assert _steps(ckpt) == [2, 3] and _updates(out) == [1, 2, 3]  # two checkpoints kept
    _truncate(ckpt / "3")
    p = run("mid_file=1")  # checkpoint 3 truncated: back to 2; killed writing eval.json
    assert f"warning: checkpoint {ckpt / '3'} is corrupted (state/" in p.stderr and " bytes, " in p.stderr
    assert not (out / "eval.json").exists() and not (out / "result.json").exists()
    run("none", killed=False)

    assert _rows(out) == _rows(ref)
    _assert_same_weights(out, ref)
    res, res_ref = (json.loads((d / "result.json").read_text()) for d in (out, ref))
    assert _without_timing(res) == _without_timing(res_ref)
    assert (out / "eval.json").read_text() == (ref / "eval.json").read_text()


def _two_checkpoints(ckpt: Path):
    state = {"w": np.arange(5000, dtype=np.float32).reshape(50, 100), "key": jax.random.key(0)}
    for u in (1, 2):
        checkpoint.save(ckpt, {**state, "w": state["w"] * u}, {"w": state["w"] * u}, {}, {"update": u})
    f = max((p for p in (ckpt / "2" / "state").rglob("*") if p.is_file()), key=lambda p: p.stat().st_size)
    return state, f


def _flip_at(f: Path, start: int = 2000, n: int = 64) -> None:
    data = bytearray(f.read_bytes())
    for i in range(start, start + n):
        data[i] ^= 0xFF
    f.write_bytes(bytes(data))


def test_a_changed_file_is_caught_before_orbax_reads_it(tmp_path, capsys):
    ckpt = tmp_path / "checkpoints"
    state, f = _two_checkpoints(ckpt)
    _flip_at(f)
    got, _, meta = checkpoint.restore(ckpt, jax.eval_shape(lambda: state))
    assert meta["update"] == 1 and np.array_equal(np.asarray(got["w"]), state["w"])
    name = f.relative_to(ckpt / "2")
    assert f"warning: checkpoint {ckpt / '2'} is corrupted ({name} does not match its saved digest)" in (
        capsys.readouterr().err)
    f.write_bytes(f.read_bytes()[:100])
    weights, _ = checkpoint.load_policy_weights(ckpt)
    assert np.array_equal(np.asarray(weights["w"]), state["w"])
    assert f"({name}: 100 bytes, " in capsys.readouterr().err


def test_flipped_bytes_orbax_reads_without_error_fail_the_pytree_digest(tmp_path, capsys):
    """Without its file list (a save killed just before writing it), 64 bytes flipped inside raw
    float data load without an error (the issue's silent garbage); the pytree digest catches them."""
    ckpt = tmp_path / "checkpoints"
    state, f = _two_checkpoints(ckpt)
    (ckpt / "2" / checkpoint.FILES).unlink()
    _flip_at(f)
    got, _, meta = checkpoint.restore(ckpt, jax.eval_shape(lambda: state))
    assert meta["update"] == 1 and np.array_equal(np.asarray(got["w"]), state["w"])
    assert f"warning: checkpoint {ckpt / '2'} is corrupted (state does not match its saved digest)" in (
        capsys.readouterr().err)


def _cli(module, argv, capsys) -> tuple[int, str]:
    """Run ``module.cli(argv)`` in-process: ``(exit code, stderr)``."""
    with pytest.raises(SystemExit) as e:
        module.cli(argv)
    return e.value.code, capsys.readouterr().err


def test_refusals_are_one_line_and_touch_nothing(tmp_path, tiny_config, capsys):
    args = ["--config", str(tiny_config), "--total-steps", "32", "--skill-range", "9", "--eval-games", "0"]
    out = tmp_path / "run"
    mapoca_cli.main([*args, "--out", str(out)])
    files = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}

    cases = [
        ([*args, "--out", str(out)], f"{out} already holds a run: pass --resume"),
        ([*args, "--out", str(out), "--resume", "--total-steps", "64"],
         "other settings (config.total_steps: saved 32, now 64)"),
        ([*args, "--out", str(tmp_path / "empty"), "--resume"], "holds no run to resume"),
        ([*args, "--out", str(out / "config.json")], "is a file; allowed: a folder"),
    ]
    for argv, message in cases:
        code, err = _cli(mapoca_cli, argv, capsys)
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == files

    result = mapoca_cli.main([*args, "--out", str(out), "--resume"])  # finished: a no-op that says so
    assert "already finished: nothing to do" in capsys.readouterr().out
    assert result == json.loads((out / "result.json").read_text())
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != "log.txt"} == files

    for step in _steps(out / "checkpoints"):  # every checkpoint bad: a one-line error, no fallback left
        _flip_bytes(out / "checkpoints" / str(step))
    (out / "result.json").unlink()
    code, err = _cli(mapoca_cli, [*args, "--out", str(out), "--resume"], capsys)
    assert code == 2 and err.strip().splitlines()[-1].startswith("error: no intact checkpoint in")
    assert all(line.startswith(("warning:", "error:")) for line in err.strip().splitlines())


def test_ppo_pcgrl_refuses_a_rerun_without_resume(tmp_path, capsys):
    out = tmp_path / "ppo"
    (out).mkdir()
    (out / "config.json").write_text(json.dumps({"trainer": "ppo_pcgrl"}))
    code, err = _cli(ppo_pcgrl_cli, ["--total-steps", "16", "--out", str(out)], capsys)
    assert code == 2 and "already holds a run: pass --resume" in err
    code, err = _cli(ppo_pcgrl_cli, ["--total-steps", "16", "--out", str(out), "--resume"], capsys)
    assert code == 2 and "other settings (chunk: saved null, now 4; config: saved null" in err
