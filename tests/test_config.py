"""One config module for both learners (``trainers.config``): shared names, one presets table, one
loader with one-line errors, and configs saved by older code read back."""

from __future__ import annotations

import dataclasses
import json

import pytest

from trainers.config import PRESETS, Config, PPOConfig, load_config
from trainers.runfolder import RunFolder

SHARED = ("n_arenas", "n_steps", "total_steps", "update_epochs", "n_minibatches", "lr", "anneal_lr", "gamma", "lam",
          "clip_eps", "ent_coef", "max_grad_norm", "hidden", "layers", "players", "parameters")


def test_the_same_hyper_parameter_has_the_same_name_and_type_in_both_learners():
    ma, ppo = ({f.name: f.type for f in dataclasses.fields(c)} for c in (Config, PPOConfig))
    for name in SHARED:
        assert ma[name] == ppo[name], name
    assert set(PRESETS) == {"mapoca", "ppo_pcgrl"} and all(set(p) == {"paper", "cpu"} for p in PRESETS.values())
    assert PRESETS["ppo_pcgrl"]["paper"].widths == (256, 256, 256, 256)  # GAME.md: 4 x 256 tanh layers
    assert PRESETS["mapoca"]["paper"].hidden == 256 and PRESETS["mapoca"]["paper"].layers == 2  # 2 x 256


@pytest.mark.parametrize("learner", ["mapoca", "ppo_pcgrl"])
@pytest.mark.parametrize("fields,message", [({"hidden": "wide"}, "hidden: value 'wide'"),
                                            ({"lr": -1.0}, "lr: value -1.0"),
                                            ({"n_arenaz": 4}, "config: unknown keys ['n_arenaz']")])
def test_a_wrong_field_in_a_saved_config_is_one_line_naming_it(tmp_path, learner, fields, message):
    path = tmp_path / "c.json"
    path.write_text(json.dumps(fields))
    with pytest.raises(ValueError) as e:
        load_config("cpu", path, learner=learner)
    assert str(e.value).startswith(message) and "\n" not in str(e.value)
    with pytest.raises(ValueError) as e:  # the same fields given as overrides
        load_config("cpu", learner=learner, **fields)
    assert str(e.value).startswith(message) and "\n" not in str(e.value)


def test_a_ppo_config_saved_with_hidden_as_a_list_reads_back_and_its_run_resumes(tmp_path):
    # Before `layers` existed PPOConfig saved hidden as a list of widths (checkpoints, config.json).
    old = {**PPOConfig().to_dict(), "hidden": [32, 32]}
    del old["layers"]
    assert PPOConfig.from_dict(old) == PPOConfig(hidden=32, layers=2)
    with pytest.raises(ValueError, match=r"^hidden: value \[32, 16\]"):
        PPOConfig.from_dict({"hidden": [32, 16]})
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.json").write_text(json.dumps({"benchmark": 2, "ppo_config": old}))
    now = {"benchmark": 2, "ppo_config": PPOConfig(hidden=32, layers=2).to_dict()}
    assert RunFolder(out, now, resume=True).resumed
    with pytest.raises(ValueError, match="ppo_config.hidden: saved 32, now 64"):
        RunFolder(out, {"benchmark": 2, "ppo_config": PPOConfig().to_dict()}, resume=True)


def test_a_mapoca_run_saved_before_fresh_starts_and_random_spawns_existed_resumes(tmp_path):
    # Benchmark 1 folders saved before these two fields existed played chained arenas and fixed
    # spawns (their values 0.0 and False); another value is another run and is refused.
    old = Config().to_dict()
    del old["fresh_starts"], old["random_spawns"]
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.json").write_text(json.dumps({"benchmark": 1, "trainer": old}))
    assert RunFolder(out, {"benchmark": 1, "trainer": Config().to_dict()}, resume=True).resumed
    with pytest.raises(ValueError, match="trainer.fresh_starts: saved null, now 0.5"):
        RunFolder(out, {"benchmark": 1, "trainer": Config(fresh_starts=0.5).to_dict()}, resume=True)


# The MA-POCA fields of a run folder saved on 2026-11-28 (Benchmark 1, code 94032da).
SAVED_MAPOCA_FIELDS = {
    "adam_eps", "anneal_ent", "anneal_lr", "bf16", "checkpoint_every", "clip_eps", "content_box",
    "deterministic_eval", "ent_coef", "eval_games", "gamma", "heads", "hidden", "lam", "layers", "lr",
    "max_grad_norm", "n_arenas", "n_minibatches", "n_steps", "parameters", "players", "proj_attention",
    "redraw_every", "senses", "skill_ranges", "total_steps", "update_epochs", "updates_per_chunk"}


def test_every_mapoca_field_added_since_says_what_older_runs_played_with():
    # Without an entry in ADDED_SETTINGS a saved run is refused on --resume ("saved null, now ...").
    from trainers.runfolder import ADDED_SETTINGS
    added = {f.name for f in dataclasses.fields(Config)} - SAVED_MAPOCA_FIELDS
    assert added <= set(ADDED_SETTINGS), sorted(added - set(ADDED_SETTINGS))
    # A field whose default changed when it was added says the old value, and such a run is then
    # refused unless the old value is set again (it would otherwise train differently on resume).
    changed = {"episode_ends": "reference"}
    assert all(ADDED_SETTINGS[k] == getattr(Config(), k) for k in added - set(changed))
    assert all(getattr(Config(), k) == v != ADDED_SETTINGS[k] for k, v in changed.items())



@pytest.mark.parametrize("learner, fields, message", [
    ("mapoca", {"players": ["mage"] * 9}, "players: value ('mage', 'mage', "),
    ("ppo_pcgrl", {"players": ["wizard", "mage", "mage"], "parameters": ["mage.skill1.range"]},
     "players[0]: value 'wizard' is an unknown class preset; allowed: a class preset, one of ["),
    ("mapoca", {"n_minibatches": 7}, "n_minibatches: value 7; allowed: a divisor of the "),
    ("ppo_pcgrl", {"target": [-5, 7]}, "target: value (-5, 7); allowed: (low, high) win rates with 0 <= low"),
    ("mapoca", {"total_steps": 2**31}, "total_steps: value 2147483648; allowed: a whole number in [1, 2147483647]"),
    ("ppo_pcgrl", {"total_steps": 10**20}, "total_steps: value 100000000000000000000; allowed: a whole number in"),
    ("ppo_pcgrl", {"lr": float("nan")}, "lr: value nan is not finite; allowed: a number"),
])
def test_what_a_trainer_would_refuse_later_the_config_refuses(tmp_path, learner, fields, message):
    """Refused by the config (``load_config``), so before a run folder records it: the corrected
    command then starts afresh instead of meeting 'already holds a run'."""
    path = tmp_path / "c.json"
    path.write_text(json.dumps(fields))
    with pytest.raises(ValueError) as e:
        load_config("cpu", path, learner=learner)
    assert str(e.value).startswith(message) and "\n" not in str(e.value), str(e.value)


def test_replace_and_run_settings_refuse_unknown_names_in_one_line(tmp_path):
    from trainers.runs import run_ppo_pcgrl

    for cfg in (Config(), PPOConfig()):
        with pytest.raises(ValueError, match=r"^config: unknown keys \['hiden'\]; known: "):
            cfg.replace(hiden=8)
    # a misspelt evaluation setting was ignored; refused before the run folder is made
    with pytest.raises(ValueError, match=r"^evaluation: unknown keys \['eval_episode'\]; known: "):
        run_ppo_pcgrl(PPOConfig(), tmp_path / "run", evaluation={"eval_episode": 0})
    assert not (tmp_path / "run").exists()
