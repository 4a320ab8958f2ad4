"""The ``raidjax`` console command: one entry point for every command line of the project.

    raidjax calibrate --games 2000
    raidjax render --policy heuristic --skill-range 13 --out replay.gif
    raidjax train mapoca --preset cpu --out runs/r9
    raidjax benchmark 1 --scale cpu --out runs/b1

Each subcommand forwards the rest of the command line to one module's ``cli(argv)`` (the same
as ``python -m <module>``), imported only when that subcommand runs: ``raidjax --help`` and the
simulator's commands work with the core install, and a subcommand whose extra is missing says
which ``pip install`` brings it, in one line (exit 2). It lives in ``experiments/``, the top
layer, because it reaches every layer.
"""

from __future__ import annotations

import importlib
import os
import sys

# (words, module, extra it needs or None, one line of help); in the order --help lists them.
COMMANDS = (
    ("calibrate", "raidjax.calibrate", None, "PT-HR / PT-RD win rates beside the paper's table"),
    ("render", "trainers.render_cli", None, "a replay GIF of one episode (a trained MA-POCA team needs [train])"),
    ("train mapoca", "trainers.mapoca_cli", "train", "train a MA-POCA team in a resumable run folder"),
    ("train ppo-pcgrl", "trainers.ppo_pcgrl_cli", "train", "train the PPO-PCGRL content generator"),
    ("benchmark 1", "experiments.benchmark1", "experiments", "Benchmark 1 (playtesting agents), end to end"),
    ("benchmark 2", "experiments.benchmark2", "experiments", "Benchmark 2 (content generation), end to end"),
    ("balance", "experiments.balance", "experiments", "the balancing loop: a learned playtester inside the generator"),
    ("plot", "trainers.plot", "experiments", "learning curves of MA-POCA runs from their metrics.csv"),
)
GROUPS = {"train": "trainer", "benchmark": "benchmark"}  # two-word commands: what their second word names
EXTRA_OF = {"optax": "train", "orbax": "train", "matplotlib": "experiments", "sklearn": "experiments",
            "tensorboardX": "tensorboard"}  # a third-party module -> the extra of pyproject.toml that installs it


def usage(group: str | None = None) -> str:
    """``raidjax --help`` (or ``raidjax train --help`` for ``group="train"``)."""
    rows = [c for c in COMMANDS if group is None or c[0].split()[0] == group]
    width = max(len(c[0]) for c in rows) + 2
    lines = [f"usage: raidjax {group + ' ' if group else ''}{'COMMAND' if group is None else GROUPS[group].upper()}"
             " [FLAGS ...]", "",
             "raidjax, a JAX boss-raid simulator: every command line. A command's flags: raidjax COMMAND --help.",
             "", "commands:"]
    for words, _, extra, text in rows:
        lines.append(f"  {words:<{width}}{text}{f' [{extra}]' if extra else ''}")
    lines += ["", "[NAME]: the command needs that extra, pip install -e \".[NAME]\" from a checkout. Each command",
              "is the same as python -m MODULE, which its --help names."]
    return "\n".join(lines)


def _fail(message: str) -> None:
    print(f"error: {message}", file=sys.stderr, flush=True)
    sys.exit(2)


def _missing_extra(e: ModuleNotFoundError, words: str) -> None:
    """Exit with one line naming the extra that installs the missing module, or re-raise (a module
    of the project itself, or another one: a real bug; also under ``RAIDJAX_DEBUG=1``)."""
    top = (e.name or "").split(".")[0]
    if top not in EXTRA_OF or os.environ.get("RAIDJAX_DEBUG"):
        raise e
    extra = EXTRA_OF[top]
    _fail(f"raidjax {words} needs {top}, which is not installed: pip install -e \".[{extra}]\" "
          "in your raidjax checkout")


def _load(words: str, module: str):
    """The module's ``cli``, imported now; ``render`` falls back to the simulator's own command
    (built-in policies only) without the ``[train]`` extra."""
    try:
        return importlib.import_module(module).cli
    except ModuleNotFoundError as e:
        if words == "render" and (e.name or "").split(".")[0] in ("optax", "orbax"):
            return importlib.import_module("raidjax.render").cli
        _missing_extra(e, words)


def main(argv: list[str] | None = None) -> None:
    """``raidjax COMMAND [FLAGS ...]``: run the command's ``cli(FLAGS)``; ``--help`` lists the commands."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv:
        print(usage(), file=sys.stderr)
        sys.exit(2)
    if argv[0] in ("-h", "--help"):
        print(usage())
        return
    if argv[0] == "--version":
        from importlib.metadata import PackageNotFoundError, version

        try:
            print(f"raidjax {version('raidjax')}")
        except PackageNotFoundError:
            print("raidjax (not installed: run from a checkout)")
        return
    allowed = f"a command ({', '.join(c[0] for c in COMMANDS)}), --help or --version"
    head = argv[0]
    if head in GROUPS:
        names = [c[0].split()[1] for c in COMMANDS if c[0].split()[0] == head]
        if len(argv) < 2 or argv[1] in ("-h", "--help"):
            if len(argv) < 2:
                print(usage(head), file=sys.stderr)
                sys.exit(2)
            print(usage(head))
            return
        words, rest = f"{head} {argv[1]}", argv[2:]
        if argv[1] not in names:
            _fail(f"raidjax {head}: value {argv[1]!r} is not a {GROUPS[head]}; allowed: {', '.join(names)}")
    else:
        words, rest = head, argv[1:]
    found = [c for c in COMMANDS if c[0] == words]
    if not found:
        _fail(f"raidjax: value {head!r} is not a command; allowed: {allowed}")
    _, module, _, _ = found[0]
    cli = _load(words, module)
    try:
        cli(rest)
    except ModuleNotFoundError as e:  # an extra imported only when drawing or reporting (matplotlib, sklearn)
        _missing_extra(e, words)


if __name__ == "__main__":
    main()
