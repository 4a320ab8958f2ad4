"""What the figure commands share: PNGs written atomically (a reader, or a docs page, never sees
half a file, and an interrupted redraw leaves the old figure) and the command line of a figure
drawn from stored result files (``experiments.calibration_figure``, ``experiments.speed_figure``)."""

from __future__ import annotations

import argparse
import io
import json
from collections.abc import Callable
from pathlib import Path

from raidjax.io import atomic_write, check_output_file


def save_png(fig, path: str | Path, dpi: int = 100) -> Path:
    """Save the matplotlib ``fig`` as a PNG at ``path`` atomically. Returns ``path``."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return atomic_write(path, buf.getvalue())


def figure_command(argv: list[str] | None, *, prog: str, doc: str, inputs: str, read: Callable[[list[str]], object],
                   draw: Callable[[object], object]) -> Path:
    """``prog INPUT... --out PNG``: ``draw(read(INPUTS))`` saved with ``save_png``; prints and returns
    the PNG's path. ``inputs`` says what the files are (their help, and the error naming them); a file
    that cannot be read, or a ``ValueError`` from ``read``, ends the command with one line, exit 2."""
    ap = argparse.ArgumentParser(prog=prog, description=doc.split("\n")[0])
    ap.add_argument("inputs", nargs="+", help=inputs)
    ap.add_argument("--out", required=True, help="the PNG to write")
    args = ap.parse_args(argv)
    try:
        check_output_file("--out", args.out, (".png",))
    except ValueError as e:
        ap.error(str(e))
    try:
        data = read(args.inputs)
    except (OSError, json.JSONDecodeError) as e:
        ap.error(f"inputs: cannot read {inputs} ({e})")
    except ValueError as e:
        ap.error(f"inputs: {e}")
    out = save_png(draw(data), args.out, dpi=120)
    print(out)
    return out
