"""Content balancing end to end (PROTOCOLS.md §13): user-chosen parameter spaces, the generator on a
mixed team, the MA-POCA tester over a content box, and ``experiments.balance`` at the smoke scale
with its skill-gap table recomputed from the raw outputs."""

from __future__ import annotations

import csv
import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from experiments import balance, balance_report
from raidjax import pcg
from raidjax.content import SKILL_SPECS, STAT_SPECS, with_player_skill
from raidjax.pcg.space import PAPER_SPACE, make_space, parse_space
from trainers.runfolder import RunFolder

MIXED = ("warrior", "mage", "priest")
EIGHT = ("mage.skill1.range=1:20", "mage.skill1.cool_time=0.5:0.6", "mage.skill1.cast_time=0.5:1.5",
         "mage.skill1.coefficient=0.5:1", "warrior.skill1.coefficient", "priest.skill1.coefficient",
         "boss.max_hp=500:3000", "warrior.armor")


def test_the_paper_space_writes_what_with_player_skill_writes():
    game = pcg.base_game()
    sk = jnp.asarray([7.0, 0.55, 1.2, 0.8])
    a = PAPER_SPACE.apply(game, sk)
    b = with_player_skill(game, **dict(zip(pcg.PAPER_SPACE.fields, sk, strict=True)))
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    # The paper's four (GAME.md §10): range 1-20, cool time 0.5-0.6, cast time 0.5-1.5, coefficient
    # 0.5-1; a longer range and a larger coefficient help the players, longer times hurt them.
    assert PAPER_SPACE.fields == ("range", "cool_time", "cast_time", "coefficient")
    np.testing.assert_array_equal(PAPER_SPACE.low, np.float32([1.0, 0.5, 0.5, 0.5]))
    np.testing.assert_array_equal(PAPER_SPACE.high, np.float32([20.0, 0.6, 1.5, 1.0]))
    assert PAPER_SPACE.easier.tolist() == [1.0, -1.0, -1.0, 1.0]


def test_a_chosen_parameter_list_edits_exactly_those_fields_within_bounds():
    params = pcg.make_pcg_params(n_games=2, players=MIXED, parameters=EIGHT)
    space, base = params.space, params.game
    assert space.size == 8 and space.names == EIGHT
    # the default bounds are the content ranges: the warrior's coefficient and armor, for players
    assert (space.low[4], space.high[4]) == tuple(map(float, SKILL_SPECS["coefficient"][1]))
    assert (space.low[7], space.high[7]) == tuple(map(float, STAT_SPECS["armor"][1]))
    assert space.easier.tolist() == [1, -1, -1, 1, 1, 1, -1, 1]  # a bigger boss is harder

    edit = jax.jit(lambda s, a: pcg.env.apply_action(s, a, space))
    skill = jnp.asarray(pcg.measurement.box_probes(space)[0])
    rng = np.random.default_rng(0)
    for _ in range(60):  # random walks hit every bound
        skill = edit(skill, jnp.asarray(rng.integers(0, 5, 8), jnp.int32))
        assert np.all(np.asarray(skill) >= space.low) and np.all(np.asarray(skill) <= space.high)
    game = space.apply(base, skill)
    written = {(k.field, k.slot, u): k for k in space.knobs for u in k.units}
    for part in ("stats", "skills"):
        for field in getattr(base, part).__dataclass_fields__:
            old, new = (np.asarray(getattr(getattr(g, part), field)) for g in (base, game))
            for idx in zip(*np.nonzero(old != new), strict=True):
                unit, slot = int(idx[0]), (int(idx[1]) if part == "skills" else None)
                assert (field, slot, unit) in written, (field, slot, unit)
    for (field, slot, unit), k in written.items():
        arr = np.asarray(getattr(game.stats if slot is None else game.skills, field))
        v = arr[unit] if slot is None else arr[unit, slot]
        assert k.low <= v <= k.high
        if k.whole:
            assert v == round(v)
    # the team: warrior 0, mage 1, priest 2, boss 3
    assert {k.units for k in space.knobs} == {(1,), (0,), (2,), (3,)}


@pytest.mark.parametrize("names, players, fragment", [
    (["skill1.in_use"], ("mage",) * 3, "'skill1.in_use': skill field 'in_use' is a bool"),
    (["rogue.armor"], ("mage",) * 3, "is not a parameter"),
    (["warrior.armor"], ("mage",) * 3, "no warrior in the team"),
    (["player3.armor"], ("mage",) * 3, "player 3 not in 0..2"),
    (["boss.max_hp=0:20000"], ("mage",) * 3, "bounds 0:20000 must satisfy 0 <= low < high <= 10000"),
    (["armor", "player1.armor"], ("mage",) * 3, "edit one field of one unit twice"),
    ([], MIXED, "name the parameters for another team"),
])
def test_bad_parameter_names_fail_naming_them(names, players, fragment):
    with pytest.raises(ValueError, match="parameters") as err:
        make_space(names, players)
    assert fragment in str(err.value)


def test_the_box_grid_spans_the_bounds_and_refuses_a_bad_size():
    grid = pcg.measurement.box_grid(np.int64(3))  # a numpy integer is a whole number too
    assert grid.shape == (81, 4) and grid.dtype == np.float32
    np.testing.assert_allclose(grid.min(0), PAPER_SPACE.low)
    np.testing.assert_allclose(grid.max(0), PAPER_SPACE.high)
    np.testing.assert_allclose(pcg.measurement.box_grid(1)[0], (PAPER_SPACE.low + PAPER_SPACE.high) / 2)
    for bad in (0, 2.0, "3"):
        with pytest.raises(ValueError, match=rf"^points: value {bad!r} .*allowed: a whole number >= 1"):
            pcg.measurement.box_grid(bad)


def test_pcg_heuristic_moves_the_picked_parameter_toward_easier_in_any_space():
    params = pcg.make_pcg_params(n_games=2, players=MIXED, parameters=EIGHT)
    _, state = pcg.reset(jax.random.PRNGKey(0), params)
    for w, sign in ((0.0, 1), (1.0, -1)):  # below the target: easier; above it: harder
        st = state.replace(win_rate=jnp.float32(w), target=jnp.float32(0.5))
        for s in range(12):
            act = np.asarray(pcg.pcg_hr(None, jax.random.PRNGKey(s), None, st, params))
            (j,) = np.flatnonzero(act != pcg.env.NOOP_ACTION)
            assert act[j] - pcg.env.NOOP_ACTION == sign * params.space.easier[j]
    assert pcg.pcg_rd(None, jax.random.PRNGKey(1), None, state, params).shape == (8,)


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_a_run_saved_with_fast_compile_still_resumes(tmp_path):
    """The scales no longer carry ``fast_compile`` (how a smoke run's programs compiled, not what they
    compute): a run folder saved with it, either value, resumes; any other difference still refuses."""
    from trainers.runfolder import RunFolderError

    settings = {"experiment": "balance", "budgets": dataclasses.asdict(balance.SCALES["cpu"])}
    assert "fast_compile" not in settings["budgets"]
    for i, saved in enumerate((False, True)):
        RunFolder(tmp_path / f"run{i}", {**settings, "budgets": {**settings["budgets"], "fast_compile": saved}})
        RunFolder(tmp_path / f"run{i}", settings, resume=True)
    with pytest.raises(RunFolderError, match="budgets.episodes: saved"):
        RunFolder(tmp_path / "run0", {**settings, "budgets": {**settings["budgets"], "episodes": 99}}, resume=True)


def test_skill_gap_table_is_recomputed_from_the_raw_outputs(tmp_path):
    rng = np.random.default_rng(5)
    n = 56
    data = {"generator": np.repeat([0, 1], n // 2), "target": np.tile(np.repeat(pcg.quality.TARGETS, 4), 2),
            "skill": rng.uniform(pcg.PAPER_SPACE.low, pcg.PAPER_SPACE.high, (n, 4)),
            "learned": rng.integers(0, 101, n) / 100,
            "scripted": rng.integers(0, 101, n) / 100}
    np.savez(tmp_path / "generated.npz", generators=np.asarray(balance.GENERATORS), **data)
    rf = RunFolder(tmp_path, {"experiment": "test"})
    summary = balance_report.report(rf)
    rows = _rows(tmp_path / "csv" / "skill_gap.csv")
    assert len(rows) == 2 * len(pcg.quality.TARGETS)
    for r in rows:  # an independent loop over the raw rows
        g = balance.GENERATORS.index(r["generator"])
        idx = [i for i in range(n) if data["generator"][i] == g and abs(data["target"][i] - float(r["target"])) < 1e-9]
        gaps = [data["learned"][i] - data["scripted"][i] for i in idx]
        assert int(r["n"]) == len(idx) == 4
        assert float(r["gap"]) == pytest.approx(sum(gaps) / len(gaps))
        assert float(r["error_learned"]) == pytest.approx(
            sum(abs(data["learned"][i] - data["target"][i]) for i in idx) / len(idx))
    err = {g: np.mean([abs(data["learned"][i] - data["target"][i]) for i in range(n) if data["generator"][i] == k])
           for k, g in enumerate(balance.GENERATORS)}
    assert summary["learned_error_learned"] == pytest.approx(err["learned"])
    assert summary["closer_under_learned"] == bool(err["learned"] < err["scripted"])
    assert "closer to" in (tmp_path / "tables" / "balance.md").read_text()
    assert (tmp_path / "figures" / "skill_gap.png").stat().st_size > 1000


def test_smoke_loop_on_a_mixed_team_with_eight_parameters(tmp_path, capsys):
    """The whole loop at the smoke scale: a mixed-team MA-POCA tester trained over an
    eight-parameter box, generators trained against it and against PT-HR, generation, both
    testers on every generated content; then the report is recomputed from generated.npz."""
    out = tmp_path / "bal"
    summary = balance.main(["--scale", "smoke", "--out", str(out), "--players", *MIXED, "--parameters", *EIGHT])
    printed = capsys.readouterr().out
    assert json.loads(printed.strip().splitlines()[-1])["scale"] == "smoke"
    for g in balance.GENERATORS:  # each generation's progress, measurement by measurement
        assert f"generate: generator {g}: measurement 1/4: " in printed
    tester = json.loads((out / "tester" / "result.json").read_text())
    assert tester["content_box"] and tester["env_steps"] == balance.SCALES["smoke"].tester["total_steps"]
    cfg = json.loads((out / "tester" / "config.json").read_text())["config"]
    assert cfg["players"] == list(MIXED) and cfg["parameters"] == list(EIGHT)
    # both generators' runs record their team's weights (the flag of policies.OrHeuristic included)
    teams = [json.loads((out / f"generator_{g}" / "config.json").read_text())["tester"] for g in balance.GENERATORS]
    assert teams[0] != teams[1]
    data = balance_report.load(out / "generated.npz")
    space = make_space(EIGHT, MIXED)
    assert data["skill"].shape[1] == 8 and list(data["parameters"]) == list(EIGHT)
    assert np.all(data["skill"] >= space.low) and np.all(data["skill"] <= space.high)
    assert set(np.unique(data["generator"])) == {0, 1}
    for k in ("learned", "scripted"):
        assert np.all((data[k] >= 0) & (data[k] <= 1))
    # the stored table is what the raw outputs give
    stored, fresh = _rows(out / "csv" / "skill_gap.csv"), balance_report.skill_gap_rows(data)
    assert len(stored) == len(fresh) == 2 * len(pcg.quality.TARGETS)
    for s, f in zip(stored, fresh, strict=True):
        assert s["generator"] == f["generator"] and int(s["n"]) == f["n"]
        for k in ("target", "learned", "scripted", "gap", "error_learned", "error_scripted"):
            assert float(s[k]) == pytest.approx(f[k])
    # the verdict is what the raw outputs give: under the learned team, whose skills land closer
    names = list(data["generators"])
    err = {n: float(np.abs(data["learned"] - data["target"])[data["generator"] == names.index(n)].mean())
           for n in ("learned", "scripted")}
    assert summary["learned_error_learned"] == pytest.approx(err["learned"])
    assert summary["scripted_error_learned"] == pytest.approx(err["scripted"])
    assert summary["closer_under_learned"] == (err["learned"] < err["scripted"])
    assert balance.main(["--scale", "smoke", "--out", str(out), "--players", *MIXED, "--parameters", *EIGHT,
                         "--resume"])["seconds"] == summary["seconds"]  # a finished run is not redone
    # the mixed team's tester is refused for three mages' content, before a run folder is made
    from trainers.config import PPOConfig
    from trainers.runs import run_ppo_pcgrl

    with pytest.raises(ValueError, match=r"was trained for players \['warrior', 'mage', 'priest'\]; the generator "
                                         r"edits content for \['mage', 'mage', 'mage'\]"):
        run_ppo_pcgrl(PPOConfig(), tmp_path / "mismatch", tester=out / "tester")
    assert not (tmp_path / "mismatch").exists()


def test_parse_space_names_the_bad_value_type():
    with pytest.raises(ValueError, match="parameters: 3 is a int"):
        parse_space([3])


def test_generator_cli_refuses_a_bad_config_file_and_a_missing_tester(tmp_path):
    from trainers import checkpoint, ppo_pcgrl_cli

    bad = tmp_path / "c.json"
    bad.write_text(json.dumps({"n_games": 4, "n_gmaes": 4}))
    with pytest.raises(ValueError, match="n_gmaes"):
        ppo_pcgrl_cli.main(["--config", str(bad), "--out", str(tmp_path / "a")])
    bad.write_text(json.dumps({"parameters": ["boss.armour"]}))
    with pytest.raises(ValueError, match="'boss.armour' is not a parameter"):
        ppo_pcgrl_cli.main(["--config", str(bad), "--out", str(tmp_path / "a")])
    with pytest.raises(ValueError, match=r"^--tester: value '.*none' does not exist; allowed: a trained MA-POCA"):
        ppo_pcgrl_cli.main(["--tester", str(tmp_path / "none"), "--out", str(tmp_path / "b")])
    (tmp_path / "empty").mkdir()
    with pytest.raises(checkpoint.CheckpointError, match="no finished checkpoint"):
        ppo_pcgrl_cli.main(["--tester", str(tmp_path / "empty"), "--out", str(tmp_path / "b")])
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_the_paper_scale_uses_both_trainers_paper_presets():
    from trainers.config import PRESETS

    PRESETS = PRESETS["mapoca"]

    s = balance.SCALES["paper"]
    cfg = balance.tester_config(s, balance.Team())
    assert cfg.content_box
    assert cfg.replace(content_box=False, eval_games=PRESETS["paper"].eval_games) == PRESETS["paper"]
    assert s.preset == "paper" and s.ppo == {} and s.eval_games == 300
    assert [balance.SCALES[k].preset for k in ("smoke", "cpu")] == ["cpu", "cpu"]


def test_win_rates_pad_to_a_shared_program_without_changing_any_content_s_key(monkeypatch):
    """Padding the contents to ``PAD`` rows (one compiled program for the tester check and the
    cross-play) hands each content the key an unpadded call gives it, and returns its own result.
    The games themselves are replaced by a record of (key, content) to test only the padding."""
    seen = []

    def record(keys, skills, weights, n_games, tester, team):
        seen.append(keys.shape[0])
        return keys[:, 1].astype(jnp.float32) * 1e-9 + skills[:, 0]  # depends on both, row by row

    monkeypatch.setattr(balance, "_win_rates", record)
    key = jax.random.PRNGKey(3)
    for k in (3, balance.PAD, balance.PAD + 5):
        skills = np.arange(4 * k, dtype=np.float32).reshape(k, 4)
        out = balance.win_rates(key, skills, 6, balance.Team())
        expect = np.asarray(jax.random.split(key, k)[:, 1].astype(jnp.float32) * 1e-9 + skills[:, 0], float)
        assert out.shape == (k,) and seen[-1] % balance.PAD == 0 and seen[-1] - k < balance.PAD
        np.testing.assert_array_equal(out, expect)
