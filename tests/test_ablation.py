"""``experiments.ablation``: every variant is a valid trainer on the reference senses that differs
from the one before it by the rows it names, and the table reads the play rows it is given."""

from __future__ import annotations

import json

import pytest

from experiments.ablation import CPU_BUDGET, NOT_ROWS, VARIANTS, table, variant_config
from trainers.config import PRESETS
from trainers.mapoca import make_trainer


@pytest.mark.parametrize("name", list(VARIANTS))
def test_every_variant_is_a_trainer_on_the_reference_senses(name):
    cfg = variant_config(name, 1_500_000)
    assert cfg.senses == "reference" and cfg.total_steps == 1_500_000
    make_trainer(cfg)  # validates the minibatch split (no compile)


def test_the_paper_variant_is_the_paper_preset_at_the_papers_budget():
    paper = PRESETS["mapoca"]["paper"]
    cfg = variant_config("paper")
    assert cfg.total_steps == paper.total_steps == -(-50_000_000 // 3)  # 5e7 agent steps, three players
    # only the chunking (checkpoint cadence) and the evaluation, which the ablation plays itself, differ
    assert cfg.replace(updates_per_chunk=paper.updates_per_chunk, eval_games=paper.eval_games) == paper
    assert variant_config("today").total_steps == CPU_BUDGET


def test_the_rows_add_up_in_order():
    names = [n for n in VARIANTS if n not in NOT_ROWS]
    fields = [VARIANTS[n][1] for n in names]
    assert fields[0]["episode_ends"] == "terminal" and fields[1]["episode_ends"] == "win_bootstrapped"
    for before, after in zip(fields[2:], fields[3:], strict=False):  # from the reference ends on, cumulative
        assert before.items() <= after.items()


def test_table_from_play_rows(tmp_path):
    rows = []
    for switch, hr, team in (("reference", 0.5, 0.6), ("carry_cooldowns=False", 0.4, 0.1), ("clean", 0.3, 0.9)):
        rows.append({"switch": switch, "range": 9.0, "agent": "PT-HR", "win_rate": hr, "win_rate_first_game": hr,
                     "win_rate_by_position": [hr, hr]})
        rows.append({"switch": switch, "range": 9.0, "agent": "MA-POCA", "seed": 0, "win_rate": team,
                     "win_rate_first_game": 1.0, "win_rate_by_position": [1.0, 0.2]})
    (tmp_path / "today").mkdir()
    (tmp_path / "today" / "play.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    text = table(tmp_path)
    assert "### today" in text and "reference_ends" not in text
    # the team: 0.6 overall, first game 1.0, lowest position 0.2, one position below PT-HR's 0.5, 0.1, 0.9
    assert "| range 9, seed 0 | 0.600 | 1.000 | 0.200 | 1 | 0.100 | 0.900 |" in text
    assert "| PT-HR, range 9 | 0.500 | 0.500 | 0.500 |  | 0.400 | 0.300 |" in text
    assert "| today | 0.600 / 0.100 / 0.900 | 1 of 2 |" in text  # the overview: one seed, two positions
