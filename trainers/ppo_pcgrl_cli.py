"""Command line of the PPO-PCGRL generator (``trainers.ppo_pcgrl``): chunked training with
progress lines, metrics (``trainers.metrics``), checkpoints (``trainers.checkpoint``) and
``--resume``, then the controllability evaluation of PPO, PCG-HR and PCG-RD.

    python -m trainers.ppo_pcgrl_cli --preset cpu --total-steps 8192 --seeds 1 --out runs/ppo_cpu

The last stdout line is one JSON object, also written to ``DIR/result.json``: ``mean_error``
(PPO), ``heuristic_mean_error`` (PCG-HR), ``random_mean_error`` (PCG-RD), all on the same
protocol (targets 0.1..0.7, final skills re-measured with ``--eval-games`` games), and
``seconds``. The run folder follows ``trainers.runfolder``: ``--resume`` continues from the newest
intact checkpoint with the same settings; anything else on an existing run is refused.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from raidjax import pcg
from raidjax.io import HelpFormatter, run_cli, whole_number_arg
from trainers import checkpoint
from trainers.config import PRESETS, load_config
from trainers.runfolder import add_run_arguments
from trainers.runs import run_ppo_pcgrl


def _args(argv=None):
    ap = argparse.ArgumentParser(prog="python -m trainers.ppo_pcgrl_cli", description="PPO-PCGRL on raidjax.pcg",
                                 formatter_class=HelpFormatter)
    ap.add_argument("--preset", choices=sorted(PRESETS["ppo_pcgrl"]), default="cpu", help="budget and network preset")
    ap.add_argument("--config", help="JSON file of PPOConfig fields, applied after the preset and before the "
                    "flags below (default: none)")
    ap.add_argument("--players", nargs="+", help="the team's class presets, e.g. warrior mage priest "
                    "(default: three mages)")
    ap.add_argument("--parameters", nargs="+", help="the edited parameters (raidjax.pcg.space names, e.g. "
                    "mage.skill1.range=1:20 boss.max_hp=500:3000; default: the paper's four)")
    ap.add_argument("--total-steps", type=whole_number_arg(1), help="generator steps per group (default: the preset's)")
    ap.add_argument("--seeds", type=whole_number_arg(1), default=1, help="seeds per target group (vmapped)")
    add_run_arguments(ap, out_default="runs/ppo_pcgrl")
    ap.add_argument("--tester", help="playtest with a trained MA-POCA team: its run folder (trainers.mapoca_cli "
                    "--out; seed 0, sampled actions) instead of PT-HR, in training and evaluation (default: PT-HR)")
    ap.add_argument("--n-games", type=whole_number_arg(1),
                    help="playtest games per training measurement (default: the preset's)")
    ap.add_argument("--n-arenas", type=whole_number_arg(1),
                    help="generator episodes stepped in parallel (default: the preset's)")
    ap.add_argument("--lr", type=float, help="learning rate (default: the preset's)")
    ap.add_argument("--edit-cost", type=float, help="learner penalty per tick moved (default: the preset's)")
    ap.add_argument("--goal-cost", type=float,
                    help="with --goal-axis: learner penalty per squared tick of distance to the episode's style goal "
                         "(default: the preset's)")
    ap.add_argument("--goal-axis", type=pcg.goals.axis_arg,
                    help="style goals at the two ends of this axis, 4 comma-separated signs in {-1,0,1} for "
                         "range,cool_time,cast_time,coefficient (1,1,1,1 = heavy vs light) (default: none)")
    ap.add_argument("--ent-coef", type=float, help="entropy bonus coefficient (default: the preset's)")
    ap.add_argument("--pool-repeats", action="store_true", default=None,
                    help="re-measuring an unchanged skill pools its games (sharper win rate when holding; "
                         "default: the preset's)")
    ap.add_argument("--chunk", type=whole_number_arg(1), default=4,
                    help="updates per jitted chunk (progress/checkpoint period)")
    ap.add_argument("--max-chunks", type=whole_number_arg(1), help="stop (after a checkpoint) once this many chunks "
                    "ran in this invocation (default: no limit)")
    ap.add_argument("--eval-episodes", type=whole_number_arg(0), default=8,
                    help="episodes per target and method (0 skips the evaluation)")
    ap.add_argument("--eval-gen-games", type=whole_number_arg(1), default=100,
                    help="games per generator measurement in eval")
    ap.add_argument("--eval-games", type=whole_number_arg(1), default=300, help="games measuring each final skill")
    ap.add_argument("--greedy", action="store_true", help="argmax actions in evaluation")
    ap.add_argument("--no-baselines", action="store_true", help="evaluate PPO alone, without PCG-HR and PCG-RD")
    return ap.parse_args(argv)


def main(argv=None) -> dict | None:
    """Train, checkpoint, evaluate (``trainers.runs.run_ppo_pcgrl``); the last stdout line is one
    JSON object (also returned)."""
    args = _args(argv)
    if args.tester is not None and not Path(args.tester).is_dir():
        wrong = "is a file" if Path(args.tester).exists() else "does not exist"
        raise ValueError(f"--tester: value {args.tester!r} {wrong}; allowed: a trained MA-POCA run folder "
                         "(trainers.mapoca_cli --out)")
    flags = dict(total_steps=args.total_steps, n_games=args.n_games, n_arenas=args.n_arenas, lr=args.lr,
                 edit_cost=args.edit_cost, pool_repeats=args.pool_repeats, ent_coef=args.ent_coef,
                 goal_cost=args.goal_cost, goal_axis=args.goal_axis,
                 players=args.players and tuple(args.players), parameters=args.parameters and tuple(args.parameters))
    flags = {k: v for k, v in flags.items() if v is not None}
    config = load_config(args.preset, args.config, learner="ppo_pcgrl", **flags)  # preset, then file, then flags
    evaluation = {k: getattr(args, k) for k in ("eval_episodes", "eval_gen_games", "eval_games", "greedy",
                                                "no_baselines")}
    return run_ppo_pcgrl(config, args.out, preset=args.preset, seeds=args.seeds, seed=args.seed, chunk=args.chunk,
                         resume=args.resume, max_chunks=args.max_chunks, evaluation=evaluation, tester=args.tester)


def cli(argv=None) -> None:
    """``main`` as a command line: one-line errors (exit 2), one line on Ctrl-C (exit 130)."""
    run_cli(lambda: main(argv), (ValueError, checkpoint.CheckpointError),
            "the newest checkpoint is kept: rerun the same command with --resume to continue")


if __name__ == "__main__":
    cli()
