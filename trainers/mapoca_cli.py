"""Command line of the MA-POCA trainer (``python -m trainers.mapoca_cli``).

The outer Python loop only runs jitted chunks of ``updates_per_chunk`` updates (all seeds
vmapped together), prints progress, appends one metrics row per chunk to
``DIR/metrics.jsonl`` and ``DIR/metrics.csv``, checkpoints every ``checkpoint_every`` updates,
and at the end evaluates the team over ``eval_games`` games next to PT-HR on the same content.
The last stdout line is one JSON object (``win_rate``, ``heuristic_win_rate``,
``env_steps_per_s``, ``seconds``, ...), also written to ``DIR/result.json``. The run folder
follows ``trainers.runfolder``: ``--resume`` continues from the newest intact checkpoint with the
same settings; anything else on an existing run is refused.

    python -m trainers.mapoca_cli --preset cpu --skill-range 13 --total-steps 2000000 --seeds 1 --out runs/r13
"""

from __future__ import annotations

import argparse

from raidjax.io import HelpFormatter, run_cli, whole_number_arg
from trainers import checkpoint
from trainers.config import load_config
from trainers.runfolder import add_run_arguments
from trainers.runs import run_mapoca


def parse_args(argv=None) -> argparse.Namespace:
    """CLI arguments (see the module docstring); numbers are checked here, before compiling."""
    ap = argparse.ArgumentParser(prog="python -m trainers.mapoca_cli", description="Train MA-POCA on raidjax.",
                                 formatter_class=HelpFormatter)
    ap.add_argument("--preset", default="cpu", choices=["paper", "cpu"],
                    help="paper: the paper's budget and network; cpu: a smaller one that trains on a CPU")
    ap.add_argument("--config", help="JSON file of Config fields, applied after the preset (default: none)")
    ap.add_argument("--skill-range", type=float, nargs="+", help="range(s) of the players' skill; "
                    "several values = drawn per episode (default: the preset's)")
    ap.add_argument("--content-box", action="store_true", default=None,
                    help="train over the content generator's whole skill box (range, cool time, cast time, "
                    "coefficient drawn per episode; Config.content_box) instead of --skill-range")
    ap.add_argument("--players", nargs="+", help="the team's class presets, e.g. warrior mage priest "
                    "(default: the preset's, three mages)")
    ap.add_argument("--parameters", nargs="+", help="the box of --content-box: generator parameter names "
                    "(raidjax.pcg.space, e.g. skill1.range boss.max_hp=500:3000; default: the paper's four)")
    ap.add_argument("--total-steps", type=whole_number_arg(1),
                    help="environment decisions per seed (default: the preset's)")
    ap.add_argument("--seeds", type=whole_number_arg(1), default=1, help="seeds trained together (vmapped)")
    add_run_arguments(ap)
    ap.add_argument("--checkpoint-every", type=whole_number_arg(1),
                    help="updates between checkpoints (default: the preset's)")
    ap.add_argument("--updates-per-chunk", type=whole_number_arg(1),
                    help="updates per jitted chunk, one log row each (default: the preset's)")
    ap.add_argument("--eval-games", type=whole_number_arg(0), help="games of the final evaluation, 0 skips it; "
                    "may change on --resume (default: the preset's)")
    ap.add_argument("--max-chunks", type=whole_number_arg(1), help="stop (after a checkpoint) once this many chunks "
                    "ran in this invocation (default: no limit)")
    return ap.parse_args(argv)


def main(argv=None) -> dict:
    """Train (or resume), log, checkpoint, evaluate (``trainers.runs.run_mapoca``); print and
    return the final JSON object."""
    args = parse_args(argv)
    cfg = load_config(args.preset, args.config, skill_ranges=args.skill_range, content_box=args.content_box,
                      players=args.players and tuple(args.players),
                      parameters=args.parameters and tuple(args.parameters),
                      total_steps=args.total_steps,
                      checkpoint_every=args.checkpoint_every, updates_per_chunk=args.updates_per_chunk,
                      eval_games=args.eval_games)
    if args.skill_range and cfg.content_box:
        raise ValueError(f"--skill-range: value {' '.join(f'{r:g}' for r in args.skill_range)}; allowed: none with "
                         "--content-box (the box draws every arena's skill)")
    if args.parameters and not cfg.content_box:
        raise ValueError(f"--parameters: value {' '.join(args.parameters)}; allowed: with --content-box (or "
                         "content_box in --config) only: they name the box it draws from")
    return run_mapoca(cfg, args.out, preset=args.preset, seeds=args.seeds, seed=args.seed, resume=args.resume,
                      max_chunks=args.max_chunks)


def cli(argv=None) -> None:
    """``main`` as a command line: one-line errors (exit 2), one line on Ctrl-C (exit 130)."""
    run_cli(lambda: main(argv), (ValueError, checkpoint.CheckpointError),
            "the newest checkpoint is kept: rerun the same command with --resume to continue")


if __name__ == "__main__":
    cli()
