"""Replays: turn a recorded episode (``logs.Trace``) into an animated GIF.

Drawn with Pillow (fast: no plotting library in the loop): the arena, the boss with its facing
and a line to its target, players coloured by slot, HP bars, casting rings, missiles and area
attacks.

    python -m raidjax.render --policy heuristic --skill-range 9 --out replay.gif
    python -m trainers.render_cli --policy runs/mapoca_cpu_r9 --skill-range 9 --out team.gif   # a trained team

(``raidjax render ...`` is the second: ``experiments.cli``.)
"""

from __future__ import annotations

import argparse
import io
from collections.abc import Callable

import jax
import numpy as np
from PIL import Image, ImageDraw

from raidjax.catalogue import CLASSES
from raidjax.content import SKILL_SPECS
from raidjax.io import HelpFormatter, atomic_write, check_output_file, number_arg, run_cli, whole_number_arg
from raidjax.policies import BY_NAME
from raidjax.types import HALF_ARENA, PROJ_AREA, EnvConfig, Params

PLAYER_COLOURS = [(66, 135, 245), (46, 204, 113), (241, 196, 15), (155, 89, 182), (230, 126, 34)]
BOSS_COLOUR = (200, 40, 40)
BG, WALL = (245, 243, 238), (60, 60, 60)


def _frames(trace, params: Params, size: int, every: int) -> list[Image.Image]:
    tr = jax.tree.map(np.asarray, trace)
    radius = np.asarray(params.stats.radius)
    max_hp = np.maximum(np.asarray(params.stats.max_hp), 1.0)
    proj_radius = np.asarray(params.skills.projectile_radius)
    n_players = tr.actions.shape[-1]
    margin = 12
    scale = (size - 2 * margin) / (2 * HALF_ARENA)

    def xy(p):  # world (x, y) -> pixel; +y is up
        return margin + (p[0] + HALF_ARENA) * scale, size - margin - (p[1] + HALF_ARENA) * scale

    last = int(np.argmin(tr.running)) if not tr.running.all() else tr.pos.shape[0] - 1
    frames = []
    for t in list(range(0, last + 1, every)) + ([last] if last % every else []):
        img = Image.new("RGB", (size, size), BG)
        d = ImageDraw.Draw(img)
        d.rectangle([margin, margin, size - margin, size - margin], outline=WALL, width=3)
        for m in np.flatnonzero(tr.projectile_live[t]):  # areas under units, missiles above
            if tr.projectile_kind[t, m] == PROJ_AREA:
                cx, cy = xy(tr.projectile_pos[t, m])
                r = proj_radius[tr.projectile_owner[t, m], tr.projectile_slot[t, m]] * scale
                d.ellipse([cx - r, cy - r, cx + r, cy + r], fill=(255, 180, 180), outline=BOSS_COLOUR)
        boss = tr.pos[t, -1]
        if tr.alive[t, -1]:
            tx, ty = xy(tr.pos[t, tr.target[t, -1]])
            d.line([xy(boss), (tx, ty)], fill=(230, 150, 150), width=1)
        for u in range(tr.pos.shape[1]):
            cx, cy = xy(tr.pos[t, u])
            r = radius[u] * scale
            colour = BOSS_COLOUR if u == n_players else PLAYER_COLOURS[u % len(PLAYER_COLOURS)]
            if not tr.alive[t, u]:
                d.line([cx - r, cy - r, cx + r, cy + r], fill=(120, 120, 120), width=2)
                d.line([cx - r, cy + r, cx + r, cy - r], fill=(120, 120, 120), width=2)
                continue
            if tr.casting[t, u].any():
                d.ellipse([cx - r - 3, cy - r - 3, cx + r + 3, cy + r + 3], outline=(0, 0, 0), width=2)
            d.ellipse([cx - r, cy - r, cx + r, cy + r], fill=colour)
            h = tr.heading[t, u]
            d.line([cx, cy, cx + np.cos(h) * r * 1.6, cy - np.sin(h) * r * 1.6], fill=(0, 0, 0), width=2)
            frac = float(np.clip(tr.hp[t, u] / max_hp[u], 0, 1))
            w = max(2 * r, 14)
            d.rectangle([cx - w / 2, cy - r - 8, cx + w / 2, cy - r - 4], fill=(90, 90, 90))
            d.rectangle([cx - w / 2, cy - r - 8, cx - w / 2 + w * frac, cy - r - 4], fill=(60, 200, 60))
        for m in np.flatnonzero(tr.projectile_live[t]):
            if tr.projectile_kind[t, m] != PROJ_AREA:
                cx, cy = xy(tr.projectile_pos[t, m])
                own = tr.projectile_owner[t, m]
                colour = BOSS_COLOUR if own == n_players else PLAYER_COLOURS[own % len(PLAYER_COLOURS)]
                d.ellipse([cx - 3, cy - 3, cx + 3, cy + 3], fill=colour, outline=(0, 0, 0))
        d.text((margin + 4, margin + 4), f"t = {t / 10:5.1f} s   boss HP {tr.hp[t, -1]:.0f}", fill=(0, 0, 0))
        frames.append(img)
    return frames


def render_gif(trace, params: Params, path: str, size: int = 360, every: int = 2, fps: int = 20) -> int:
    """Write an animated GIF of one recorded episode, atomically.

    Args:
        trace: ``logs.Trace`` of one arena with leading time axis ``T`` (from ``record_episode``).
        params: that arena's ``Params`` (radii, HP maxima, area radii).
        path: output ``.gif`` path.
        size: image side in pixels.
        every: draw every ``every``-th decision (2 = 0.2 s of game time per frame).
        fps: frames per second of the GIF.

    Returns:
        The number of frames written (the episode's end is always included).
    """
    frames = _frames(trace, params, size, every)
    buf = io.BytesIO()
    frames[0].save(buf, format="GIF", save_all=True, append_images=frames[1:], duration=int(1000 / fps), loop=0,
                   optimize=True)
    atomic_write(path, buf.getvalue())
    return len(frames)


def _parser(prog: str, trained: bool) -> argparse.ArgumentParser:
    low, high = SKILL_SPECS["range"][1]
    limit = EnvConfig().max_decisions
    ap = argparse.ArgumentParser(prog=prog, description="Render a replay GIF of one episode.",
                                 formatter_class=HelpFormatter)
    ap.add_argument("--policy", default="heuristic", help=" | ".join(sorted(BY_NAME))
                    + (" | a trained MA-POCA run folder (trainers.mapoca_cli --out)" if trained else ""))
    ap.add_argument("--skill-range", type=number_arg(low, high), default=9.0, metavar="RANGE",
                    help="range of every player's skill slot 1")
    ap.add_argument("--players", nargs="+",
                    help=f"1 to 8 class presets, e.g. warrior mage priest, from {', '.join(sorted(CLASSES))} "
                    "(default: " + ("a trained run's own team, else " if trained else "") + "three mages)")
    ap.add_argument("--seed", type=whole_number_arg(0, 2**31 - 1), default=0, help="PRNG seed of the episode")
    ap.add_argument("--decisions", type=whole_number_arg(1, limit), default=600,
                    help=f"decisions recorded (0.1 s each; the episode limit is {limit})")
    ap.add_argument("--out", default="replay.gif", help="the GIF to write, in an existing folder")
    return ap


def _players(words: list[str]) -> list[str]:
    """``--players`` (space-separated, as in every command) as class preset names, checked
    (``ValueError`` naming the flag)."""
    names = [n.strip() for w in words for n in w.split(",") if n.strip()]  # "mage,mage" still reads
    text = " ".join(words)
    allowed = f"1 to 8 class presets (space-separated) from {sorted(CLASSES)}"
    unknown = [n for n in names if n not in CLASSES]
    if unknown:
        raise ValueError(f"--players: value {text!r} names an unknown class {unknown[0]!r}; allowed: {allowed}")
    if not 1 <= len(names) <= 8:
        raise ValueError(f"--players: value {text!r} names {len(names)} players; allowed: {allowed}")
    return names


def _check_policy(name: str, load_policy: Callable | None, find_run: Callable[[str], str | None] | None) -> None:
    """A ``--policy`` that is not a built-in name needs a ``load_policy``, and ``find_run`` (when
    given) must accept it: else ``ValueError``, listing the built-in names."""
    import difflib

    if name in BY_NAME:
        return
    names = sorted(BY_NAME)
    close = difflib.get_close_matches(name, names, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    if load_policy is None:
        raise ValueError(f"--policy: value {name!r} is not a built-in policy; allowed: one of {names} (a trained "
                         "MA-POCA run folder renders with python -m trainers.render_cli, which needs pip install -e "
                         f"'.[train]'){hint}")
    why = find_run(name) if find_run is not None else None
    if why:
        raise ValueError(f"--policy: value {name!r} is neither a built-in policy nor a run folder holding a "
                         f"checkpoint ({why}); allowed: one of {names}, or a trained MA-POCA run folder "
                         f"(trainers.mapoca_cli --out){hint}")


def main(argv=None, load_policy: Callable | None = None, find_run: Callable[[str], str | None] | None = None,
         prog: str = "python -m raidjax.render", players_of: Callable[[str], list[str]] | None = None) -> None:
    """The replay command. ``load_policy(path) -> (policy, weights)`` turns a ``--policy`` that is not a
    built-in name into a policy (``trainers.render_cli`` passes the MA-POCA loader) once
    ``find_run(path)`` accepted it (``None``; otherwise it returns why not), and ``players_of(path)``
    says the team it was trained for (the default ``--players``; another team is refused); without
    them only the built-in policies are accepted. Every flag is checked before anything compiles
    (``ValueError``, one line naming the flag, the value and what is allowed)."""
    import raidjax

    args = _parser(prog, load_policy is not None).parse_args(argv)
    players = _players(args.players) if args.players else None
    check_output_file("--out", args.out, (".gif",))
    _check_policy(args.policy, load_policy, find_run)
    if args.policy not in BY_NAME and players_of is not None:
        trained = list(players_of(args.policy))
        if players is not None and players != trained:
            raise ValueError(f"--players: value {' '.join(args.players)!r}; allowed: the team {args.policy} was "
                             f"trained for, {' '.join(trained)} (leave --players out to use it)")
        players = trained
    players = players or ["mage"] * 3
    params = raidjax.make_params(players=players, skill_range=args.skill_range)
    if args.policy in raidjax.policies.BY_NAME:
        policy, weights = raidjax.policies.BY_NAME[args.policy], None
    else:
        policy, weights = load_policy(args.policy)  # (policy(weights, key, obs, state, params), weights)
    record = jax.jit(raidjax.logs.record_episode, static_argnames=("policy", "n_decisions"))
    trace, summary = record(jax.random.key(args.seed), params, policy, args.decisions, weights)
    n = render_gif(trace, params, args.out)
    outcome = {0: "running", 1: "win", 2: "loss", 3: "draw"}[int(summary["outcome"])]
    print(f"{args.out}: {n} frames, {outcome} after {int(summary['length']) / 10:.1f} s")


def cli(argv=None) -> None:
    """``main`` as a command line: one-line errors (exit 2), one line on Ctrl-C (exit 130)."""
    run_cli(lambda: main(argv))


if __name__ == "__main__":
    cli()
