"""The two trainers' command lines at tiny sizes: files written, resume, the final JSON line."""

from __future__ import annotations

import json

from trainers import mapoca_cli, ppo_pcgrl_cli

TINY_MAPOCA = {"n_arenas": 4, "n_steps": 8, "n_minibatches": 2, "update_epochs": 1, "hidden": 8, "layers": 1,
               "heads": 1, "updates_per_chunk": 1, "checkpoint_every": 1}


def test_mapoca_cli_interrupted_then_resumed(tmp_path, capsys):
    cfg = tmp_path / "tiny.json"
    cfg.write_text(json.dumps(TINY_MAPOCA))
    out = tmp_path / "run"
    args = ["--config", str(cfg), "--total-steps", "96", "--skill-range", "9", "--eval-games", "4", "--out", str(out)]
    mapoca_cli.main(args + ["--max-chunks", "1"])  # 3 chunks of 32 decisions; stop after the first
    assert [json.loads(s)["update"] for s in (out / "metrics.jsonl").read_text().splitlines()] == [1]
    result = mapoca_cli.main(args + ["--resume"])
    assert [json.loads(s)["update"] for s in (out / "metrics.jsonl").read_text().splitlines()] == [1, 2, 3]
    assert result["env_steps"] == 96 and 0.0 <= result["win_rate"] <= 1.0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["win_rate"] == result["win_rate"]
    assert json.loads((out / "result.json").read_text())["env_steps"] == 96


def test_ppo_pcgrl_cli_trains_checkpoints_and_evaluates(tmp_path, capsys):
    out = tmp_path / "ppo"
    argv = ["--total-steps", "16", "--n-arenas", "2", "--n-games", "2", "--chunk", "1", "--eval-episodes", "1",
            "--eval-gen-games", "2", "--eval-games", "2", "--out", str(out)]
    ppo_pcgrl_cli.main(argv)
    res = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert res["total_steps"] == 16 and set(res["yield"]) == {"PPO", "PCG-HR", "PCG-RD"}
    rows = [json.loads(s) for s in (out / "metrics.jsonl").read_text().splitlines()]
    assert [r["update"] for r in rows] == [1] and len(rows[0]["final_error_per_group"]) == 1
    assert (out / "checkpoints" / "1").is_dir() and json.loads((out / "eval.json").read_text())["PPO"]
