"""Run one raidjax command line with a fault injected: ``kill -9`` of the process itself at a chosen
moment. Used by ``test_faults.py`` (a script, not a test module)::

    python tests/fault_inject.py FAULT MODULE [ARGS...]

FAULT is ``none`` or ``WHEN=N`` (the N-th time, counted from 1, in this invocation):

- ``before_save``: before a checkpoint save starts;
- ``during_save``: inside a save, after every byte is written to orbax's temporary folder and
  before the rename that commits it;
- ``after_save``: right after a checkpoint save returns;
- ``mid_metrics``: in the middle of a metrics row (half of the JSON line written, then killed);
- ``mid_file``: in the middle of an ``atomic_write`` (half of the temporary file written).
"""

from __future__ import annotations

import os
import runpy
import signal
import sys


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
    when, n = fault.split("=")
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

        from raidjax import utils

        real_atomic = utils.atomic_write

        def atomic_write(path, data):
            if hit():
                fd, _ = tempfile.mkstemp(dir=os.path.dirname(os.path.abspath(path)), suffix=".tmp")
                os.write(fd, (data.encode() if isinstance(data, str) else data)[: len(data) // 2])
                _kill()
            return real_atomic(path, data)

        utils.atomic_write = atomic_write
    else:
        raise SystemExit(f"unknown fault {fault!r}")


if __name__ == "__main__":
    sys.path.insert(0, os.getcwd())
    install(sys.argv[1])
    module = sys.argv[2]
    sys.argv = [module, *sys.argv[3:]]
    runpy.run_module(module, run_name="__main__", alter_sys=True)
