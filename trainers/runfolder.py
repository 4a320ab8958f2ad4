"""The run folder of every long job (both trainers, both benchmark pipelines): one contract.

- The settings are recorded in ``config.json`` on the first start. A rerun must pass ``--resume``
  (an existing run is never silently restarted) and must have the same settings (a mismatch is
  refused, naming every differing setting with both values); ``--resume`` on a folder that holds
  no run is refused too. A finished run (``summary.json``/``result.json`` present) resumed is a
  no-op that says so.
- Every file is written atomically (``raidjax.io.atomic_write``; a resumed run removes the
  temporaries of writes that were killed); metrics rows past the
  checkpoint resumed from are dropped (``trainers.metrics``); checkpoints are verified on restore
  (``trainers.checkpoint``).

Layout of ``DIR`` (the pipelines use all of it, the trainers the first lines)::

    config.json     every setting of the run (a rerun must match it)
    log.txt         timestamped progress lines (also printed)
    stages/*.json   one file per finished stage: its JSON result; a rerun skips finished stages
                    (stages/records.json: each finished stage's or part's start, end, wall seconds,
                    commit and machine)
    csv/*.csv       every number the run measured
    tables/*.md     the tables, our numbers beside the paper's
    figures/*.png   the figures
    checkpoints/    learner checkpoints (orbax)
    summary.json    the final summary (also the last stdout line)

Every file is written to a temporary name and renamed into place, so an interrupted run never
leaves a half-written file: rerunning the same command with ``--resume`` resumes after the last
finished stage.

One process at a time: a job holds an advisory lock on ``DIR/.runfolder.lock`` (``fcntl.flock``)
while it works in the folder, and a second process that opens the folder is refused, naming the
process that holds it. The operating system releases the lock when that process ends, however it
ends (a killed run leaves no stale lock). Within one process the folder may be opened again (a
notebook resuming its own run). Where nothing can lock (no ``fcntl``, as on Windows, or a file
system without locks) the run says so in its log and goes on unlocked. A job that writes into a
run folder without a ``RunFolder`` (a redraw of its figures) holds the same lock with ``locked``.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import socket
import time
import weakref
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from raidjax.io import atomic_write, finite_json, fmt_seconds, machine, utc_now, whole_number_arg
from trainers.config import upgrade_settings


class RunFolderError(ValueError):
    """A run folder refused: the message names the folder and what to do."""


# Settings added after run folders were first saved, with the value every older run played with:
# a saved run without the key resumes as long as the new value is that one.
# MA-POCA's fresh_starts and random_spawns: every earlier run continued its arenas' chains and played
# the fixed spawns; episode_ends: every earlier run made a win terminal (the cpu preset still does;
# the Config default is the reference trainer's "reference").
ADDED_SETTINGS = {"senses": "raidjax", "fresh_starts": 0.0, "random_spawns": False,
                  "episode_ends": "terminal", "network": "raidjax",
                  "minibatch_rows": "decisions", "stale_phases": 1}
# Settings no longer saved, ignored where an older run saved them: the scales' fast_compile was false
# but for smoke runs (XLA's optimisation level 0: other float rounding, in runs whose numbers are not
# read), so a real run resumes exactly as it would have.
REMOVED_SETTINGS = {"fast_compile"}


def _differences(old: dict, new: dict, prefix: str = "") -> list[str]:
    """``"key: saved X, now Y"`` for every (nested) setting that differs (``ADDED_SETTINGS``
    missing from the saved side count as their old value; ``REMOVED_SETTINGS`` saved are ignored)."""
    out = []
    for k in sorted(set(old) | set(new)):
        a, b = old.get(k), new.get(k)
        if k not in old and k in ADDED_SETTINGS and b == ADDED_SETTINGS[k]:
            continue
        if k not in new and k in REMOVED_SETTINGS:
            continue
        if isinstance(a, dict) and isinstance(b, dict):
            out += _differences(a, b, f"{prefix}{k}.")
        elif a != b:
            out.append(f"{prefix}{k}: saved {json.dumps(a)}, now {json.dumps(b)}")
    return out


try:  # POSIX; where it is missing (Windows) a run folder is not locked
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None

LOCK_NAME = ".runfolder.lock"
# The locks this process holds: the lock file's (device, inode) -> [its open descriptor, RunFolder
# objects using it]. A flock lock belongs to an open file, so a second open in this process would
# refuse the first; the file's identity, unlike its path, follows a renamed folder and tells a lock
# file deleted with its folder (and made again) from the one held.
_HELD: dict[tuple[int, int], list] = {}


def _lock(folder: Path) -> tuple[int, int] | None:
    """Take (or, held by this process already, share) the lock of ``folder`` (which exists); return
    its key for ``_unlock``, or ``None`` where the file system cannot lock. Raises
    ``RunFolderError`` naming the holder when another process holds it."""
    if fcntl is None:
        return None
    fd = os.open(folder / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)  # not truncated: it names the holder
    stat = os.fstat(fd)
    key = (stat.st_dev, stat.st_ino)
    if key in _HELD:
        os.close(fd)
        _HELD[key][1] += 1
        return key
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.read(fd, 200).decode(errors="replace").strip() or "another process"
        os.close(fd)
        raise RunFolderError(f"{folder} is in use by {holder}: wait for it to end (or stop it), then try "
                             "again") from None
    except OSError:  # a file system without locks (some network mounts): the folder is used unlocked
        os.close(fd)
        return None
    _HELD[key] = [fd, 1]
    try:  # who holds it, for another process's refusal; the lock holds without it
        os.ftruncate(fd, 0)
        os.write(fd, f"process {os.getpid()} on {socket.gethostname()} (since {utc_now()})".encode())
    except OSError:
        pass
    return key


def _unlock(key: tuple[int, int] | None) -> None:
    """Release one use of the lock ``_lock`` returned; the last use closes the file (unlocking it)."""
    if key is None or key not in _HELD:
        return
    _HELD[key][1] -= 1
    if _HELD[key][1] == 0:
        os.close(_HELD.pop(key)[0])


@contextlib.contextmanager
def locked(folder: str | Path) -> Iterator[None]:
    """Hold the run lock of ``folder`` (an existing run folder) for a job that writes into it without
    a ``RunFolder``, such as a redraw of its figures. Raises ``RunFolderError`` naming the holder
    while another process works in the folder; this process's own ``RunFolder`` shares it. Where
    nothing can lock (see above) it holds nothing and says nothing: the job goes on unlocked."""
    key = _lock(Path(folder))
    try:
        yield
    finally:
        _unlock(key)


SEED_MAX = 2**31 - 1  # a --seed's largest value, as raidjax.calibrate's and render's (offsets stay well in range)


def add_run_arguments(ap, scales=None, scale_help: str = "budgets", out_default: str | None = None) -> None:
    """The flags every long job shares: ``--scale`` (when ``scales`` is given; default ``smoke``),
    ``--out`` (required unless ``out_default``), ``--resume`` and ``--seed``, to an
    ``argparse.ArgumentParser`` ``ap``."""
    if scales is not None:
        ap.add_argument("--scale", choices=sorted(scales), default="smoke", help=scale_help)
    ap.add_argument("--out", required=out_default is None, default=out_default,
                    help="run folder, new or holding this run with --resume"
                    + (" (required)" if out_default is None else ""))
    ap.add_argument("--resume", action="store_true", help="continue the run in --out from its newest intact "
                    "checkpoint (same settings; a finished run is left as it is)")
    ap.add_argument("--seed", type=whole_number_arg(0, SEED_MAX), default=0, help="base PRNG seed")


def check_out(out: str | Path, flag: str = "--out") -> Path:
    """``out`` as a folder path, refusing an existing file (``RunFolderError`` naming ``flag``)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RunFolderError(f"{flag}: {out} is a file; allowed: a folder (new or holding a run)")
    return out


class RunFolder:
    """The run folder ``out`` of one job.

    Args:
        out: the folder (created).
        config: JSON-able settings of the run, recorded in ``out/config.json`` on the first start.
        resume: continue the run in ``out``. Without it an ``out`` holding a run is refused; with
            it an ``out`` holding none is refused, and so are other settings than the recorded ones.
        ignore: top-level settings a resumed run may change (e.g. the size of the final
            evaluation); the recorded value is replaced by the new one, unless the run has
            finished: its ``config.json`` keeps describing the results beside it (until ``redo``).

    The object holds the folder's lock (the module docstring) until ``close()`` (or the end of a
    ``with`` block, or its collection); another process opening the folder meanwhile is refused.

    Attributes:
        resumed: whether a run was found and is being continued.
        finished: whether that run had already finished (``summary.json`` or ``result.json``).

    Raises:
        RunFolderError: the cases above, and a folder in use by another process, each in one line
            naming the folder and what to do.
    """

    def __init__(self, out: str | Path, config: dict, resume: bool = False, ignore: tuple[str, ...] = ()):
        self.out = check_out(out)
        self.t0 = time.perf_counter()
        cfg_path = self.out / "config.json"
        config = json.loads(json.dumps(config))
        self._check(cfg_path, config, resume, ignore)  # a refusal touches nothing
        self.out.mkdir(parents=True, exist_ok=True)
        # held until close() or until this object is collected; released also on a refusal below
        key = _lock(self.out)
        self._release = weakref.finalize(self, _unlock, key)
        try:  # again under the lock: another process may have started or changed the run meanwhile
            self._open(cfg_path, config, ignore, self._check(cfg_path, config, resume, ignore))
            if key is None:
                self.log(f"{self.out} cannot be locked here ({'no fcntl' if fcntl is None else 'its file system'}):"
                         " nothing keeps a second process from writing to it at the same time")
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Release the folder's lock (also done when the object is collected; idempotent)."""
        self._release()

    def __enter__(self) -> RunFolder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _check(self, cfg_path: Path, config: dict, resume: bool, ignore: tuple[str, ...]) -> dict | None:
        """The refusals of ``__init__`` (reading only); the saved settings of the run found, or ``None``."""
        if not cfg_path.exists():
            if resume:
                raise RunFolderError(f"--resume: {self.out} holds no run to resume (no config.json); "
                                     "drop --resume to start one")
            return None
        if not resume:
            raise RunFolderError(f"{self.out} already holds a run: pass --resume to continue it, or choose a new --out")
        try:
            old = json.loads(cfg_path.read_text())
        except json.JSONDecodeError as e:
            raise RunFolderError(f"{cfg_path} is not valid JSON ({e}); the run cannot be resumed") from e
        old = upgrade_settings(old)  # a run saved by older code, as today's code writes it
        diff = _differences({k: v for k, v in old.items() if k not in ignore},
                            {k: v for k, v in config.items() if k not in ignore})
        if diff:
            raise RunFolderError(f"{self.out} holds a run with other settings ({'; '.join(diff)}): "
                                 "rerun its own command with --resume, or choose a new --out")
        return old

    def _open(self, cfg_path: Path, config: dict, ignore: tuple[str, ...], old: dict | None) -> None:
        """``__init__``'s writes, under the folder's lock, for the saved settings ``old`` (``None``: a new run)."""
        self.resumed = old is not None
        self.finished = self.resumed and any((self.out / n).exists() for n in ("summary.json", "result.json"))
        changed = [k for k in ignore if self.resumed and config.get(k) != old.get(k)]
        if not self.resumed or (changed and not self.finished):
            atomic_write(cfg_path, json.dumps(config, indent=1))
        self.config = config
        # what a finished run left as it is says so (already_finished); a redo applies the new values
        self._not_applied = {k: (old.get(k), config.get(k)) for k in changed} if self.finished else {}
        if self.resumed:
            self.log(f"resuming the {'finished ' if self.finished else ''}run in {self.out}")
            for tmp in sorted(self.out.rglob(".*.tmp")):  # atomic_write's, from a write that was killed
                tmp.unlink()
                self.log(f"removed an unfinished temporary file {tmp} (the file it was to replace is whole)")

    def path(self, *parts: str) -> Path:
        """``out/parts...`` with its parent folder created."""
        p = self.out.joinpath(*parts)
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def log(self, msg: str) -> None:
        """Print ``msg`` and append it with a timestamp to ``log.txt``."""
        line = f"[{time.strftime('%H:%M:%S')} +{fmt_seconds(time.perf_counter() - self.t0)}] {msg}"
        print(line, flush=True)
        with open(self.out / "log.txt", "a") as f:
            f.write(line + "\n")

    def done(self, name: str) -> bool:
        """Whether stage ``name`` has finished (its result is on disk)."""
        return (self.out / "stages" / f"{name}.json").exists()

    def result(self, name: str) -> Any:
        """Stage ``name``'s stored JSON result (``None`` if it has not finished)."""
        p = self.out / "stages" / f"{name}.json"
        return json.loads(p.read_text()) if p.exists() else None

    def redo(self, name: str, why: str) -> None:
        """Forget the run's summary, then stage ``name``'s result (in that order: a run killed
        between the two is not finished and redoes the stage), so that the stage runs again and
        the run finishes again; the stages before it stay done. ``why`` is logged."""
        for p in (self.out / "summary.json", self.out / "stages" / f"{name}.json"):
            p.unlink(missing_ok=True)
        self.finished, self._not_applied = False, {}
        atomic_write(self.out / "config.json", json.dumps(self.config, indent=1))  # what the redone stage uses
        self.log(f"stage {name}: to be done again ({why})")

    def stage(self, name: str, fn: Callable[[], Any]) -> Any:
        """Run ``fn()`` once: return its stored JSON result if stage ``name`` already finished,
        otherwise run it, store the (JSON-able) result atomically and return it."""
        p = self.out / "stages" / f"{name}.json"
        if p.exists():
            self.log(f"stage {name}: already done, skipped")
            return json.loads(p.read_text())
        t, start = time.perf_counter(), utc_now()
        self.log(f"stage {name}: start")
        result = fn()
        seconds = time.perf_counter() - t
        self.record(name, start, seconds)  # first: a stage counted as done always has its record
        atomic_write(self.path("stages", f"{name}.json"), finite_json(result, indent=1))
        self.log(f"stage {name}: done in {fmt_seconds(seconds)}")
        return json.loads(finite_json(result))

    def record(self, name: str, start: str, seconds: float) -> None:
        """Add a finished piece of work (a stage, a part of one) to ``stages/records.json``: its
        ``start`` and ``end`` (UTC, ISO 8601; the end is now), wall ``seconds`` and the ``machine``
        (``raidjax.io.machine``: the commit, devices and host) of the invocation that did it. A run
        resumed on another machine or commit says so piece by piece."""
        records = self.records()
        stamp = machine()
        records[name] = {"start": start, "end": stamp.pop("date"), "seconds": seconds, "machine": stamp}
        atomic_write(self.path("stages", "records.json"), json.dumps(records, indent=1))

    def records(self) -> dict:
        """``record``'s entries by name, in the order they finished."""
        p = self.out / "stages" / "records.json"
        return json.loads(p.read_text()) if p.exists() else {}

    def stage_seconds(self) -> dict:
        """Wall seconds of every finished stage (of the invocation that finished it): ``records``'
        stages, with ``stages/seconds.json`` for a run folder saved before the records existed."""
        p = self.out / "stages" / "seconds.json"
        saved = json.loads(p.read_text()) if p.exists() else {}
        return {**saved, **{n: r["seconds"] for n, r in self.records().items() if self.done(n)}}

    def write_csv(self, name: str, rows: Sequence[dict]) -> Path:
        """Write ``rows`` (dicts with the same keys) to ``csv/<name>.csv``."""
        buf = io.StringIO()
        if rows:
            w = csv.DictWriter(buf, list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        return atomic_write(self.path("csv", f"{name}.csv"), buf.getvalue())

    def write_table(self, name: str, markdown: str) -> Path:
        """Write a Markdown table (or section) to ``tables/<name>.md``."""
        return atomic_write(self.path("tables", f"{name}.md"), markdown.rstrip() + "\n")

    def save_figure(self, name: str, fig, dpi: int = 90) -> Path:
        """Save a matplotlib figure as ``figures/<name>.png`` (atomically) and close it."""
        import matplotlib.pyplot as plt

        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
        plt.close(fig)
        return atomic_write(self.path("figures", f"{name}.png"), buf.getvalue())

    def already_finished(self) -> dict:
        """For a finished run resumed: say so, print its stored summary (or result) as the last
        line and return it; nothing is recomputed or rewritten."""
        name = "summary.json" if (self.out / "summary.json").exists() else "result.json"
        summary = json.loads((self.out / name).read_text())
        self.log(f"this run has already finished: nothing to do ({self.out / name} unchanged)")
        if self._not_applied:
            self.log("it finished with " + "; ".join(f"{k} {json.dumps(a)}" for k, (a, _) in self._not_applied.items())
                     + "; the value given now (" + "; ".join(json.dumps(b) for _, b in self._not_applied.values())
                     + ") applies to a new run only: choose a new --out")
        print(finite_json(summary), flush=True)
        return summary

    def finish(self, summary: dict) -> dict:
        """Write ``summary.json`` (with the machine, the wall seconds of each stage and their sum)
        and print it as the last line (full precision: the tests recompute its numbers exactly)."""
        stages = self.stage_seconds()
        summary = {**summary, "machine": machine(), "stage_seconds": stages, "seconds": sum(stages.values()),
                   "seconds_this_invocation": time.perf_counter() - self.t0}
        atomic_write(self.out / "summary.json", finite_json(summary, indent=1))
        self.log("finished")
        print(finite_json(summary), flush=True)
        return summary


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A Markdown table; floats are printed with 3 decimals."""
    fmt = lambda v: f"{v:.3f}" if isinstance(v, float) else str(v)
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(fmt(v) for v in r) + " |" for r in rows]
    return "\n".join(lines)
