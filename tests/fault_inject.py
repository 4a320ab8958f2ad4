"""Run one raidjax command line with a fault injected: ``kill -9`` of the process itself at a chosen
moment; and the helpers of the fault-injection tests (``test_faults_*.py``). As a script::

    python tests/fault_inject.py FAULT MODULE [ARGS...]

FAULT is ``none`` or ``WHEN=N`` (the N-th time, counted from 1, in this invocation):

- ``before_save``: before a checkpoint save starts;
- ``during_save``: inside a save, after every byte is written to orbax's temporary folder and
  before the rename that commits it;
- ``after_save``: right after a checkpoint save returns;
- ``mid_metrics``: in the middle of a metrics row (half of the JSON line written, then killed);
- ``mid_file``: in the middle of an ``atomic_write`` (half of the temporary file written);
  ``mid_file@TEXT`` counts only the writes whose path contains ``TEXT`` (``mid_file@part_001=1``:
  while Benchmark 2 saves its second generation part).
"""

from __future__ import annotations

import json
import os
import runpy
import signal
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TIMING = {"seconds", "steps_per_s", "train_seconds", "eval_seconds", "compile_seconds", "env_steps_per_s"}


def _kill() -> None:
    sys.stdout.flush()
    sys.stderr.flush()
    os.kill(os.getpid(), signal.SIGKILL)


def _countdown(n: int):
    calls = [0]

    def hit() -> bool:
        calls[0] += 1
        return calls[0] == n

    return hit


def install(fault: str) -> None:
    """Patch the moment named by ``fault`` (before the command's modules are imported)."""
    if fault == "none":
        return
    when, n = fault.rsplit("=", 1)
    when, _, only = when.partition("@")
    hit = _countdown(int(n))
    if when in ("before_save", "after_save"):
        from trainers import checkpoint

        real = checkpoint.save

        def save(*a, **k):
            due = hit()
            if due and when == "before_save":
                _kill()
            out = real(*a, **k)
            if due:
                _kill()
            return out

        checkpoint.save = save
    elif when == "during_save":
        from orbax.checkpoint._src.path import async_path

        real_rename = async_path.rename

        async def rename(src, dst, *a, **k):
            if str(dst).rstrip("/").split("/")[-1].isdigit() and hit():  # the step folder's commit
                _kill()
            return await real_rename(src, dst, *a, **k)

        async_path.rename = rename
    elif when == "mid_metrics":
        from trainers import metrics

        real_write = metrics.MetricsLog.write

        def write(self, row):
            if hit():
                line = metrics.finite_json(row) + "\n"
                with self.jsonl.open("a") as f:
                    f.write(line[: len(line) // 2])
                _kill()
            return real_write(self, row)

        metrics.MetricsLog.write = write
    elif when == "mid_file":
        import tempfile

        from raidjax import io as raidjax_io

        real_atomic = raidjax_io.atomic_write

        def atomic_write(path, data):
            if only in str(path) and hit():
                name = os.path.basename(path)  # the temporary name atomic_write itself would use
                fd, _ = tempfile.mkstemp(dir=os.path.dirname(os.path.abspath(path)), prefix=f".{name}.", suffix=".tmp")
                os.write(fd, (data.encode() if isinstance(data, str) else data)[: len(data) // 2])
                _kill()
            return real_atomic(path, data)

        raidjax_io.atomic_write = atomic_write
    else:
        raise SystemExit(f"unknown fault {fault!r}")


# --- helpers of the tests ---------------------------------------------------------------------------

def run(fault: str, module: str, args: list[str], killed: bool) -> subprocess.CompletedProcess:
    """Run ``python -m module args`` with ``fault`` injected; assert it was killed (or exited 0)
    and printed no traceback."""
    p = subprocess.run([sys.executable, __file__, fault, module, *args], cwd=ROOT, capture_output=True,
                       text=True, timeout=900)
    expected = -9 if killed else 0
    assert p.returncode == expected, f"{fault}: exit {p.returncode}, expected {expected}\n{p.stderr[-3000:]}"
    assert "Traceback" not in p.stderr, p.stderr[-3000:]
    return p


def steps(ckpt: Path) -> list[int]:
    """The committed checkpoint steps in ``ckpt``."""
    return sorted(int(p.name) for p in ckpt.iterdir() if p.name.isdigit())


def rows(out: Path) -> list:
    """Metrics rows without wall-clock fields; a torn line stays a string (so it shows in a diff)."""
    found = []
    for line in (out / "metrics.jsonl").read_text().splitlines():
        try:
            found.append({k: v for k, v in json.loads(line).items() if k not in TIMING})
        except json.JSONDecodeError:
            found.append(line)
    return found


def updates(out: Path) -> list:
    """The ``update`` of every metrics row, ``"torn"`` for a torn line."""
    return [r["update"] if isinstance(r, dict) else "torn" for r in rows(out)]


def largest_state_file(step_dir: Path) -> Path:
    return max((p for p in (step_dir / "state").rglob("*") if p.is_file()), key=lambda p: p.stat().st_size)


def flip(f: Path, start: int, n: int = 64) -> None:
    """Flip ``n`` bytes of ``f`` from ``start``."""
    data = bytearray(f.read_bytes())
    for i in range(start, min(start + n, len(data))):
        data[i] ^= 0xFF
    f.write_bytes(bytes(data))


def without_timing(result: dict) -> dict:
    return {k: v for k, v in result.items() if k not in TIMING}


def same_run(out: Path, ref: Path, result_fields: tuple[str, ...] | None = None) -> None:
    """``out`` equals ``ref``: metrics rows, final policy weights, the result (its ``result_fields``,
    default all but timings); no temporary file left."""
    import jax
    import numpy as np

    from trainers import checkpoint

    assert rows(out) == rows(ref)
    wa, _ = checkpoint.load_policy_weights(out / "checkpoints")
    wb, _ = checkpoint.load_policy_weights(ref / "checkpoints")
    for x, y in zip(jax.tree.leaves(wa), jax.tree.leaves(wb), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    res, res_ref = (json.loads((d / "result.json").read_text()) for d in (out, ref))
    if result_fields is not None:
        res, res_ref = ({k: r[k] for k in result_fields} for r in (res, res_ref))
    assert without_timing(res) == without_timing(res_ref)
    assert not [p for p in out.rglob(".*.tmp")], "temporary files left behind"


if __name__ == "__main__":
    sys.path.insert(0, os.getcwd())
    install(sys.argv[1])
    module = sys.argv[2]
    sys.argv = [module, *sys.argv[3:]]
    runpy.run_module(module, run_name="__main__", alter_sys=True)
