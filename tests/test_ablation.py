"""``experiments.ablation``: every variant is a valid trainer on the reference senses that differs
from the one before it by the rows it names, and the table reads the play rows it is given."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import pytest

from experiments.ablation import CPU_BUDGET, NOT_ROWS, VARIANTS, main, run_inputs, table, variant_config
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
    # paper_stale: the same run with the reference's asynchronous data approximated, 32 decisions per
    # arena and update in 8 groups of 11 arenas (the reference's rows train about 0-10 updates late)
    stale = variant_config("paper_stale")
    assert stale == cfg.replace(stale_phases=8) and stale.n_steps // stale.stale_phases == 32


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


def test_a_seed_trained_alone_is_the_same_run_as_in_the_whole_layout():
    teams, (keys, contents, tables) = run_inputs([9.0, 13.0], 3, 0)
    alone, (keys1, contents1, tables1) = run_inputs([9.0, 13.0], 3, 0, only=[1])
    assert [t["seed"] for t in alone] == [1, 1] and [t["ranges"] for t in alone] == [(9.0,), (13.0,)]
    # runs 1 and 4 of the layout (range r, seed s is run r * 3 + s): the same key, content and table
    assert (keys1 == keys[jnp.array([1, 4])]).all() and (tables1 == tables[jnp.array([1, 4])]).all()
    assert jax.tree.all(jax.tree.map(lambda a, b: (a == b[jnp.array([1, 4])]).all(), contents1, contents))


def test_only_seeds_outside_the_layout_is_refused(tmp_path):
    with pytest.raises(ValueError, match=r"--only-seeds: value 3; allowed: seed indices 0..2"):
        main(["--out", str(tmp_path), "--seeds", "3", "--only-seeds", "3"])



def test_bad_out_resume_and_seed_are_refused_before_anything_trains(tmp_path, capsys):
    afile = tmp_path / "afile"
    afile.write_text("")
    with pytest.raises(ValueError, match=rf"^--out: {afile} is a file; allowed: a folder"):
        main(["--out", str(afile)])
    with pytest.raises(ValueError, match=r"^--resume: .* holds no started variant to resume .*drop --resume"):
        main(["--out", str(tmp_path / "none"), "--resume"])
    assert not (tmp_path / "none").exists()
    for seed in ("-1", "2147483648"):
        with pytest.raises(SystemExit):
            main(["--out", str(tmp_path / "s"), "--seed", seed])
        assert "allowed: a whole number in [0, 2147483647]" in capsys.readouterr().err


def test_tables_of_seeds_trained_alone_join_into_one_table(tmp_path):
    def folder(seed, team):
        rows = []
        for switch in ("reference", "carry_cooldowns=False", "clean"):
            rows.append({"switch": switch, "range": 13.0, "agent": "PT-HR", "win_rate": 0.5,
                         "win_rate_first_game": 0.5, "win_rate_by_position": [0.5, 0.5]})
            rows.append({"switch": switch, "range": 13.0, "agent": "MA-POCA", "seed": seed, "win_rate": team,
                         "win_rate_first_game": team, "win_rate_by_position": [team, team]})
        (tmp_path / f"s{seed}" / "paper").mkdir(parents=True)
        (tmp_path / f"s{seed}" / "paper" / "play.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
        return tmp_path / f"s{seed}"

    dirs = [folder(0, 0.9), folder(1, 0.3)]
    text = main(["--out", str(tmp_path / "all"), "--tables-of", *map(str, dirs)])
    assert (tmp_path / "all" / "ablation.md").read_text() == text + "\n"
    assert "| range 13, seed 0 | 0.900 |" in text and "| range 13, seed 1 | 0.300 |" in text
    assert text.count("| PT-HR, range 13 |") == 1
    assert "| paper | 0.600 / 0.600 / 0.600 | 2 of 4 |" in text  # the mean of both seeds; seed 1 below at 2
    with pytest.raises(ValueError, match="--tables-of: .* holds no variant that has played"):
        main(["--out", str(tmp_path / "x"), "--tables-of", str(tmp_path / "nothing")])
