"""Replay GIFs of trained MA-POCA teams: ``raidjax.render``'s command with the MA-POCA loader.

    python -m trainers.render --policy runs/mapoca_cpu_r9 --skill-range 9 --out team.gif
"""

from __future__ import annotations

from raidjax import render
from trainers.mapoca import load_policy


def main(argv=None) -> None:
    """``python -m raidjax.render``'s flags; ``--policy`` may also name a MA-POCA run folder."""
    render.main(argv, load_policy=load_policy)


if __name__ == "__main__":
    main()
