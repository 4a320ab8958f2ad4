"""Command lines that fail politely: every mistake in a flag is refused before anything compiles,
in one line naming the flag, the value and what is allowed (exit 2, no traceback), and leaves no
file behind; the ``raidjax`` console command (``experiments.cli``) dispatches to each of them;
every ``--help`` shows the defaults. The trainers' run-folder refusals (``--resume``, a finished
run, ``--total-steps 0``) are tested in ``test_faults_mapoca.py`` / ``test_faults_ppo.py``.

The mistakes run as ``python -m MODULE`` would, all in one fresh process (``in_one_process.py``);
the refusals that must not share a process (a missing dependency, Ctrl-C) get their own."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from in_one_process import run_all

ROOT = Path(__file__).resolve().parent.parent
KNOWN_CLASSES = "['battle_mage', 'druid', 'mage', 'priest', 'ranger', 'warrior']"
POLICIES = "['heuristic', 'noop', 'random']"
OUT_GIF = "allowed: a file path ending in .gif, in an existing folder"

# (id, module, argv, the message's text): "{tmp}" is the test's folder, which holds "run_without_checkpoint/"
# (a folder with no checkpoint) and "ppo_run/metrics.csv" (a run of the other trainer); the command runs in
# "{tmp}/cwd". A message starting with "argument" is argparse's (usage, then "PROG: error: argument ...").
MISTAKES = [
    ("render-out-folder", "raidjax.render", ["--out", "{tmp}"],
     f"error: --out: value '{{tmp}}' is a folder; {OUT_GIF}"),
    ("render-out-missing-folder", "raidjax.render", ["--out", "{tmp}/nowhere/replay.gif"],
     f"error: --out: value '{{tmp}}/nowhere/replay.gif' is in a folder that does not exist ({{tmp}}/nowhere); "
     f"{OUT_GIF}"),
    ("render-out-not-gif", "raidjax.render", ["--out", "{tmp}/replay.png"],
     f"error: --out: value '{{tmp}}/replay.png' does not end in .gif; {OUT_GIF}"),
    ("render-policy-mistyped", "raidjax.render", ["--policy", "heurstic"],
     f"error: --policy: value 'heurstic' is not a built-in policy; allowed: one of {POLICIES}"),
    ("trainers-render-policy-mistyped", "trainers.render_cli", ["--policy", "heurstic"],
     "error: --policy: value 'heurstic' is neither a built-in policy nor a run folder holding a checkpoint "
     f"(no such folder); allowed: one of {POLICIES}, or a trained MA-POCA run folder"),
    ("trainers-render-policy-no-checkpoint", "trainers.render_cli", ["--policy", "{tmp}/run_without_checkpoint"],
     "error: --policy: value '{tmp}/run_without_checkpoint' is neither a built-in policy nor a run folder "
     "holding a checkpoint (no finished checkpoint in it)"),
    ("render-decisions-0", "raidjax.render", ["--decisions", "0"],
     "argument --decisions: value '0'; allowed: a whole number in [1, 2000]"),
    ("render-skill-range-out-of-range", "raidjax.render", ["--skill-range", "50"],
     "argument --skill-range: value '50'; allowed: a number in [1, 20]"),
    ("render-unknown-class", "trainers.render_cli", ["--players", "mage", "wizard"],
     f"error: --players: value 'mage wizard' names an unknown class 'wizard'; allowed: 1 to 8 class presets "
     f"(space-separated) from {KNOWN_CLASSES}"),
    ("calibrate-games-0", "raidjax.calibrate", ["--games", "0"],
     "argument --games: value '0'; allowed: a whole number >= 1"),
    ("calibrate-games-negative", "raidjax.calibrate", ["--games", "-5"],
     "argument --games: value '-5'; allowed: a whole number >= 1"),
    ("calibrate-json-folder", "raidjax.calibrate", ["--games", "1", "--json", "{tmp}"],
     "error: --json: value '{tmp}' is a folder; allowed: a file path ending in .json, in an existing folder"),
    ("plot-not-a-mapoca-run", "trainers.plot", ["{tmp}/ppo_run", "--out", "{tmp}/curves.png"],
     "error: runs: value '{tmp}/ppo_run' has a metrics.csv without the column 'env_steps' (not a MA-POCA run?)"),
    ("raidjax-unknown-command", "experiments.cli", ["trian", "mapoca"],
     "error: raidjax: value 'trian' is not a command; allowed: a command (calibrate, render, train mapoca, "
     "train ppo-pcgrl, benchmark 1, benchmark 2, balance, plot), --help or --version"),
    ("raidjax-unknown-trainer", "experiments.cli", ["train", "ppo"],
     "error: raidjax train: value 'ppo' is not a trainer; allowed: mapoca, ppo-pcgrl"),
    ("raidjax-forwards-mistakes", "experiments.cli", ["render", "--out", "{tmp}"],
     f"error: --out: value '{{tmp}}' is a folder; {OUT_GIF}"),
    ("train-seed-negative", "trainers.mapoca_cli", ["--seed", "-1", "--out", "{tmp}/run"],
     "argument --seed: value '-1'; allowed: a whole number in [0, 2147483647]"),
    ("train-seed-too-large", "experiments.benchmark1", ["--seed", "100000000000000000000", "--out", "{tmp}/run"],
     "argument --seed: value '100000000000000000000'; allowed: a whole number in [0, 2147483647]"),
    ("train-skill-range-with-content-box", "trainers.mapoca_cli",
     ["--content-box", "--skill-range", "9", "--out", "{tmp}/run"],
     "error: --skill-range: value 9; allowed: none with --content-box"),
    ("train-parameters-without-content-box", "trainers.mapoca_cli",
     ["--parameters", "skill1.range", "--out", "{tmp}/run"],
     "error: --parameters: value skill1.range; allowed: with --content-box"),
    ("train-nine-players", "trainers.mapoca_cli", ["--players", *["mage"] * 9, "--out", "{tmp}/run"],
     "error: players: value ('mage', 'mage', 'mage', 'mage', 'mage', 'mage', 'mage', ... is 9 players; allowed: "
     "a class preset name or a list of 1 to 8 of them"),
    ("ablation-resume-nothing", "experiments.ablation", ["--out", "{tmp}/none", "--resume"],
     "error: --resume: {tmp}/none holds no started variant to resume"),
    ("ablation-out-file", "experiments.ablation", ["--out", "{tmp}/ppo_run/metrics.csv"],
     "error: --out: {tmp}/ppo_run/metrics.csv is a file; allowed: a folder"),
    ("ppo-tester-missing", "trainers.ppo_pcgrl_cli", ["--tester", "{tmp}/nowhere", "--out", "{tmp}/run"],
     "error: --tester: value '{tmp}/nowhere' does not exist; allowed: a trained MA-POCA run folder"),
    ("switches-out-folder", "experiments.b1_switches", ["{tmp}/run_without_checkpoint", "--out", "{tmp}"],
     "error: --out: value '{tmp}' is a folder; allowed: a file path ending in .jsonl, in an existing folder"),
]


def _files(folder: Path) -> set[str]:
    """Every file and folder under ``folder``, hidden ones (``.replay.gif.XXXX.tmp``) included."""
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _run(argv: list[str], cwd: Path, code: str | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    env.pop("RAIDJAX_DEBUG", None)
    cmd = [sys.executable, "-c", code] if code else [sys.executable, "-m", *argv]
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=120)


CONSOLE = [(["--help"], "help"), ([], "no-command"), (["train", "mapoca", "--help"], "forwarded")]


@pytest.fixture(scope="module")
def ran(tmp_path_factory) -> dict:
    """Every case of ``MISTAKES`` and ``CONSOLE`` run in one fresh process (``in_one_process``:
    about 2 s for all instead of 2 s each), each mistake in its own folder prepared as above:
    ``{id: (folder, its files before, result)}``."""
    cases, folders = [], {}
    for case_id, module, argv, _ in MISTAKES:
        tmp = tmp_path_factory.mktemp(case_id)
        (tmp / "run_without_checkpoint").mkdir()
        (tmp / "ppo_run").mkdir()
        (tmp / "ppo_run" / "metrics.csv").write_text("update,env_steps_x,reward\n1,10,0.5\n")
        (tmp / "cwd").mkdir()
        folders[case_id] = (tmp, _files(tmp))
        cases.append({"target": f"-m {module}", "argv": [a.replace("{tmp}", str(tmp)) for a in argv],
                      "cwd": str(tmp / "cwd")})
    console = tmp_path_factory.mktemp("console")
    for argv, case_id in CONSOLE:
        folders[case_id] = (console, set())
        cases.append({"target": "-m experiments.cli", "argv": argv, "cwd": str(console)})
    env = dict(os.environ)
    env.pop("RAIDJAX_DEBUG", None)
    results = run_all(cases, env, timeout=120)
    return {case_id: (*folders[case_id], r) for case_id, r in zip(folders, results, strict=True)}


@pytest.mark.parametrize("module, message", [(m[1], m[3]) for m in MISTAKES], ids=[m[0] for m in MISTAKES])
def test_a_mistake_is_one_line_before_anything_compiles_and_leaves_no_file(request, ran, module, message):
    tmp_path, before, p = ran[request.node.callspec.id]
    fill = lambda s: s.replace("{tmp}", str(tmp_path))
    err = p["stderr"].strip().splitlines()
    assert p["code"] == 2 and "Traceback" not in p["stderr"] and p["stdout"] == "", p["stderr"][-3000:]
    assert not p["backend"], "a JAX backend started before the mistake was refused"
    if message.startswith("argument"):  # argparse: its usage, then "PROG: error: argument FLAG: ..."
        assert err[0].startswith("usage: ") and err[-1].startswith(f"python -m {module}: error: "), p["stderr"]
        assert fill(message) in err[-1], p["stderr"]
    else:  # run_cli: exactly one line
        assert len(err) == 1 and err[0].startswith(fill(message)), p["stderr"]
    assert _files(tmp_path) == before  # no output, no hidden temporary file, no replay.gif in the cwd


def test_raidjax_console_command_lists_and_dispatches(ran):
    p = ran["help"][2]
    assert p["code"] == 0 and p["stderr"] == ""
    listed = re.findall(r"^  (\S+(?: [\w-]+)?)  +\S", p["stdout"], re.M)
    assert listed == ["calibrate", "render", "train mapoca", "train ppo-pcgrl", "benchmark 1", "benchmark 2", "balance",
                      "plot"]
    p = ran["no-command"][2]  # no command: the help on stderr, exit 2
    assert p["code"] == 2 and p["stdout"] == "" and p["stderr"].startswith("usage: raidjax COMMAND")
    p = ran["forwarded"][2]  # forwarded to trainers.mapoca_cli
    assert p["code"] == 0 and p["stdout"].startswith("usage: python -m trainers.mapoca_cli"), p["stderr"][-3000:]
    assert "--total-steps" in p["stdout"] and "(default: 1)" in p["stdout"]
    assert not list(ran["help"][0].iterdir())


def test_a_missing_extra_is_named_in_one_line(tmp_path):
    block = "import sys; sys.modules['optax'] = None; from experiments.cli import main; main({})"  # as if uninstalled
    p = _run([], tmp_path, block.format("['train', 'mapoca', '--out', 'run']"))
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr[-3000:]
    assert p.stderr.strip() == ('error: raidjax train mapoca needs optax, which is not installed: pip install -e '
                                '".[train]" in your raidjax checkout')
    p = _run([], tmp_path, block.format("['render', '--policy', 'runs/x']"))  # render: the simulator's own command
    assert p.returncode == 2 and p.stderr.strip().startswith(
        f"error: --policy: value 'runs/x' is not a built-in policy; allowed: one of {POLICIES} (a trained MA-POCA "
        "run folder renders with python -m trainers.render_cli, which needs pip install -e '.[train]')"), p.stderr
    assert not list(tmp_path.iterdir())


def _options(help_text: str) -> dict[str, str]:
    """``{option: its help block}`` of an argparse ``--help``."""
    blocks = re.split(r"^  (?=-)", help_text.split("options:", 1)[1], flags=re.M)[1:]
    return {b.split()[0].rstrip(","): " ".join(b.split()) for b in blocks}


@pytest.mark.parametrize("command", ["calibrate", "render", "train mapoca", "train ppo-pcgrl", "benchmark 1",
                                     "benchmark 2", "balance", "plot"])
def test_every_help_shows_the_defaults(command, capsys):
    """In-process (the same parsers as ``python -m``): every option that takes a value says its
    default, or that it is required; flags (``--resume``) have none."""
    from experiments import cli

    with pytest.raises(SystemExit) as e:
        cli.main([*command.split(), "--help"])
    text = capsys.readouterr().out
    assert e.value.code == 0 and text.startswith("usage: python -m "), text
    options = _options(text)
    assert len(options) >= 2, text
    for name, block in options.items():
        takes_value = re.match(rf"{re.escape(name)} [A-Z{{]", block)
        if name != "-h" and takes_value:
            assert "default" in block or "(required)" in block, f"{command}: {block}"
    expected = {"calibrate": "(default: 2000)", "render": "(default: 600)", "train mapoca": "(default: cpu)",
                "train ppo-pcgrl": "(default: 300)", "benchmark 1": "(default: smoke)",
                "benchmark 2": "(default: smoke)", "balance": "(default: smoke)", "plot": "(required)"}
    assert expected[command] in text


def _documented() -> dict[str, set[str]]:
    """``{command: flags}`` of every ``raidjax COMMAND ...`` line in the README, CONTRIBUTING.md and
    docs/*.md, docs/results/*.md (``test_house.py`` checks their ``python -m`` lines the same way)."""
    docs = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").glob("*.md")),
        *sorted((ROOT / "docs" / "results").glob("*.md"))]
    text = "".join(p.read_text() for p in docs)
    out: dict[str, set[str]] = {}
    pattern = r"\braidjax (calibrate|render|plot|balance|train [\w-]+|benchmark \w+)\b([^`\n|]*)"
    for command, rest in re.findall(pattern, text):
        out.setdefault(command, set()).update(re.findall(r"--[a-z][\w-]*", rest))
    return out


DOCUMENTED = _documented()


@pytest.mark.parametrize("command", sorted(DOCUMENTED))
def test_documented_raidjax_commands_exist_with_their_flags(command, capsys):
    from experiments import cli

    with pytest.raises(SystemExit) as e:
        cli.main([*command.split(), "--help"])
    text = capsys.readouterr().out
    assert e.value.code == 0, f"raidjax {command} is not a command"
    missing = sorted(f for f in DOCUMENTED[command] if f not in text)
    assert not missing, f"raidjax {command} has no flag {missing}"


def test_ctrl_c_is_one_line_saying_how_to_resume(tmp_path):
    """SIGINT while a trainer compiles: no traceback, exit 130 within seconds (not after the compile,
    and not lost: raised as KeyboardInterrupt inside jax's gc callback it used to be ignored), one
    line naming --resume."""
    import signal
    import time

    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    env.pop("RAIDJAX_DEBUG", None)
    proc = subprocess.Popen([sys.executable, "-m", "trainers.mapoca_cli", "--out", str(tmp_path / "run")], cwd=tmp_path,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    started = time.monotonic()
    while not (tmp_path / "run" / "config.json").exists():  # written when the run starts, before compiling
        assert proc.poll() is None and time.monotonic() - started < 120, proc.communicate()[1][-2000:]
        time.sleep(0.05)
    time.sleep(0.5)  # into the trainer's set-up and compile (about 30 s here)
    proc.send_signal(signal.SIGINT)
    sent = time.monotonic()
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err[-2000:]
    assert time.monotonic() - sent < 15, "the interrupt waited for the compile"
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith("interrupted") and "--resume" in err


def test_json_is_finite_and_rounded():
    """No bare NaN (invalid JSON for most parsers) and no float32 noise in what users read."""
    import json

    import numpy as np

    from raidjax.io import finite_json

    text = finite_json({"w": np.float32(0.726), "nan": float("nan"), "x": [np.float64(0.6759999999999999)]}, 6)
    assert json.loads(text) == {"w": 0.726, "nan": None, "x": [0.676]} and "NaN" not in text
    assert json.loads(finite_json({"w": np.float32(0.726)}))["w"] == float(np.float32(0.726))  # no digits: exact
