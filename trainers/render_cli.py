"""Replay GIFs of trained MA-POCA teams: ``raidjax.render``'s command with the MA-POCA loader.

    python -m trainers.render_cli --policy runs/mapoca_cpu_r9 --skill-range 9 --out team.gif
"""

from __future__ import annotations

from pathlib import Path

from raidjax import render
from raidjax.io import run_cli
from trainers import checkpoint
from trainers.config import Config
from trainers.mapoca import load_policy


def find_run(path: str) -> str | None:
    """``None`` if ``path`` (a run folder, its ``checkpoints`` folder or one checkpoint) holds a
    finished checkpoint, else why not, in a few words (checked before anything loads or compiles)."""
    p = Path(path)
    if not p.exists():
        return "no such folder"
    if not p.is_dir():
        return "a file, not a folder"
    if checkpoint.latest_step(p) is None:
        return "no finished checkpoint in it"
    return None


def players_of(path: str) -> list[str]:
    """The team the MA-POCA run at ``path`` was trained for (its newest checkpoint's config)."""
    return list(Config.from_dict(checkpoint.load_config(path)).players)


def main(argv=None) -> None:
    """``python -m raidjax.render``'s flags; ``--policy`` may also name a MA-POCA run folder, played
    by the team it was trained for."""
    render.main(argv, load_policy=load_policy, find_run=find_run, prog="python -m trainers.render_cli",
                players_of=players_of)


def cli(argv=None) -> None:
    """``main`` as a command line: one-line errors (exit 2, a damaged checkpoint included), one line
    on Ctrl-C (exit 130)."""
    run_cli(lambda: main(argv), (ValueError, checkpoint.CheckpointError))


if __name__ == "__main__":
    cli()
