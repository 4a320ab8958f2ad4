"""Fault injection, PPO-PCGRL trainer (see ``test_faults_mapoca.py``): kills after a checkpoint and
mid metrics row, a truncated checkpoint; the resumed run equals the uninterrupted one bit-for-bit."""

from __future__ import annotations

import json

from fault_inject import largest_state_file, rows, run, same_run, steps, updates
from test_faults_mapoca import cli

from trainers import ppo_pcgrl_cli


def test_ppo_pcgrl_survives_a_chain_of_kills_and_a_truncated_checkpoint(tmp_path, capsys):
    short = tmp_path / "short.json"  # 4-edit generation episodes (40 by default): a short evaluation
    short.write_text(json.dumps({"max_edits": 4}))
    args = ["--config", str(short), "--total-steps", "64", "--n-arenas", "2", "--n-games", "2", "--chunk", "1",
            "--eval-gen-games", "2", "--eval-games", "2", "--no-baselines"]
    ref, out = tmp_path / "uninterrupted", tmp_path / "faulty"
    ppo_pcgrl_cli.main([*args, "--eval-episodes", "1", "--out", str(ref)])  # the evaluation, here only
    printed = capsys.readouterr().out
    last = json.loads(printed.strip().splitlines()[-1])
    assert last == json.loads((ref / "result.json").read_text())
    assert "evaluation: measurement 1/5: " in printed  # the evaluation's progress (a start and 4 edits at most)
    assert last["total_steps"] == 64 and set(last["yield"]) == {"PPO"} and last["heuristic_mean_error"] is None
    assert len(rows(ref)[0]["final_error_per_group"]) == 1 and json.loads((ref / "eval.json").read_text())["PPO"]
    ckpt = out / "checkpoints"

    def faulty(fault: str, killed: bool = True, resume: bool = True):
        return run(fault, "trainers.ppo_pcgrl_cli", [*args, "--eval-episodes", "0", "--out", str(out)]
                   + ["--resume"] * resume, killed)

    faulty("after_save=2", resume=False)
    assert steps(ckpt) == [1, 2] and updates(out) == [1, 2]
    f = largest_state_file(ckpt / "2")
    f.write_bytes(f.read_bytes()[: f.stat().st_size // 3])
    p = faulty("mid_metrics=2")  # checkpoint 2 truncated: back to 1; row 2 and checkpoint 2 again, row 3 torn
    assert f"warning: checkpoint {ckpt / '2'} is corrupted (state/" in p.stderr and " bytes, " in p.stderr
    assert steps(ckpt) == [1, 2] and updates(out) == [1, 2, "torn"]
    faulty("none", killed=False)
    same_run(out, ref, result_fields=("total_steps", "groups", "n_games", "preset", "seeds"))


def test_ppo_pcgrl_refuses_a_rerun_without_resume(tmp_path, capsys):
    out = tmp_path / "ppo"
    out.mkdir()
    (out / "config.json").write_text(json.dumps({"trainer": "ppo_pcgrl"}))
    code, err = cli(ppo_pcgrl_cli, ["--total-steps", "16", "--out", str(out)], capsys)
    assert code == 2 and "already holds a run: pass --resume" in err
    code, err = cli(ppo_pcgrl_cli, ["--total-steps", "16", "--out", str(out), "--resume"], capsys)
    assert code == 2 and "other settings (chunk: saved null, now 4; config: saved null" in err
