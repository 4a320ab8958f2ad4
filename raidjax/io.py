"""Host-side plumbing shared by the simulator's commands, the trainers and the experiments (never
traced): ``atomic_write`` (every file a user keeps), ``finite_json``, ``machine`` and ``fmt_seconds``
(reports and progress lines), and the command-line helpers ``HelpFormatter``,
``whole_number_arg``, ``number_arg``, ``check_output_file`` and ``run_cli`` (with
``use_compilation_cache``)."""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import subprocess
from functools import partial
from pathlib import Path

import jax

from raidjax.files import atomic_write, cache_folder  # noqa: F401  (callers find every host helper here)


def source_commit() -> str | None:
    """The git commit of the raidjax source this process imported (short hash, ``"+dirty"`` appended
    when tracked files differ from it), or ``None`` outside a git checkout (an installed wheel)."""
    here = Path(__file__).resolve().parent
    try:
        run = partial(subprocess.run, cwd=here, capture_output=True, text=True, timeout=10, check=True)
        head = run(["git", "rev-parse", "--short", "HEAD"]).stdout.strip()
        dirty = run(["git", "status", "--porcelain", "--untracked-files=no"]).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "") if head else None


# Read once, when the first command or benchmark imports this module: a result records the code the
# process runs, even if the checkout moves on (a commit made during a long run) before it is written.
SOURCE_COMMIT = source_commit()


def utc_now() -> str:
    """The current time, UTC, ISO 8601 to the second (``machine``'s ``date``)."""
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


def machine(load: bool = False) -> dict:
    """A JSON-able description of the run, so a stored result says what produced it: ``date`` (UTC,
    ISO 8601), ``commit`` (``SOURCE_COMMIT``, read at import), the JAX devices (``platform``, ``device``,
    ``device_count``: devices JAX sees, all hosts), the host (``cpu_count``, ``processor``), the
    ``jax`` version, and with ``load`` the 1-minute load average (``load_average_1m``; timings on a
    shared machine depend on it)."""
    dev = jax.devices()[0]
    out = {"date": utc_now(),
           "commit": SOURCE_COMMIT,
           "platform": dev.platform, "device": str(dev.device_kind), "device_count": jax.device_count(),
           "cpu_count": os.cpu_count(),
           "processor": platform.processor() or platform.machine(), "jax": jax.__version__}
    if load:
        out["load_average_1m"] = round(os.getloadavg()[0], 2)
    return out


def fmt_seconds(s: float) -> str:
    """A duration for progress lines: ``"1h02m"``, ``"3m07s"`` or ``"12s"``."""
    if s >= 3600:
        return f"{int(s // 3600)}h{int(s % 3600 // 60):02d}m"
    return f"{int(s // 60)}m{int(s % 60):02d}s" if s >= 60 else f"{s:.0f}s"


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """``--help`` of every raidjax command line: each option's default as ``(default: X)``, unless its
    help already says it (an option defaulting to ``None`` says in words what happens without it,
    e.g. ``(default: the preset's)``); flags (``False``) and required options show none."""

    def _get_help_string(self, action):
        text = action.help or ""
        if ("default" in text or action.required or not action.option_strings
                or action.default is None or action.default is False or action.default is argparse.SUPPRESS):
            return text
        return text + " (default: %(default)s)"


def whole_number_arg(low: int = 1, high: int | None = None):
    """An ``argparse`` type: a whole number ``>= low`` (and ``<= high`` when given), else a one-line
    usage error naming the value (checked before anything compiles; ``raidjax.validate.whole_number``
    checks Python values)."""
    allowed = f"a whole number >= {low}" if high is None else f"a whole number in [{low}, {high}]"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"value {text!r}; allowed: {allowed}")
        return value

    parse.__name__ = allowed.removeprefix("a ")
    return parse


def number_arg(low: float, high: float):
    """An ``argparse`` type: a finite number in ``[low, high]``, else a one-line usage error naming
    the value (no clipping)."""
    import math

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not low <= value <= high:  # NaN fails too
            raise argparse.ArgumentTypeError(f"value {text!r}; allowed: a number in [{low:g}, {high:g}]")
        return value

    parse.__name__ = f"number in [{low:g}, {high:g}]"
    return parse


def check_output_file(flag: str, path: str | Path, suffixes: tuple[str, ...] = (), what: str = "a file") -> Path:
    """Check a command line's output file before anything runs (a long run must not fail at its
    last write): not a folder, inside an existing folder this process may write to, and ending
    in one of ``suffixes`` (any case) when given. An existing file is allowed (replaced
    atomically by ``atomic_write``).

    Returns:
        ``path`` as a ``Path``.

    Raises:
        ValueError: one line, ``"<flag>: value '<path>' <what is wrong>; allowed: <what is allowed>"``.
    """
    text = str(path)
    ends = " or ".join(suffixes)
    allowed = f"{what} path{' ending in ' + ends if suffixes else ''}, in an existing folder"
    path = Path(path)
    folder = path.parent
    if not text.strip():
        wrong = "is empty"
    elif path.is_dir() or text.endswith(("/", os.sep)):
        wrong = "is a folder"
    elif suffixes and not path.name.lower().endswith(tuple(s.lower() for s in suffixes)):
        wrong = f"does not end in {ends}"
    elif not folder.is_dir():
        wrong = f"is in a folder that does not exist ({folder})"
        if folder.exists():
            wrong = f"is under a file ({folder})"
    elif not os.access(folder, os.W_OK | os.X_OK):
        wrong = f"is in a folder this process cannot write to ({folder})"
    else:
        return path
    raise ValueError(f"{flag}: value {text!r} {wrong}; allowed: {allowed}")


def _exit_on_ctrl_c(line: str) -> None:
    """From now on, SIGINT prints ``line`` to stderr and exits 130 at once, whatever the main thread
    is doing. A KeyboardInterrupt would not do: it waits until an XLA compile (tens of seconds)
    returns, and when it is raised inside jax's garbage-collection callback Python reports it as
    "Exception ignored" and carries on, so the user's Ctrl-C is lost. Instead the signal's wakeup
    fd is read by a watcher thread, which exits the process."""
    import signal
    import sys
    import threading

    read_end, write_end = os.pipe()
    os.set_blocking(write_end, False)
    signal.signal(signal.SIGINT, lambda *_: None)  # the watcher acts; the main thread must not raise
    signal.set_wakeup_fd(write_end, warn_on_full_buffer=False)

    def watch():
        while True:
            if signal.SIGINT in os.read(read_end, 64):
                sys.stdout.flush()
                print(line, file=sys.stderr, flush=True)
                # Straight out: a normal interpreter exit can crash (SIGSEGV) while XLA threads are
                # still compiling or running; every user file is written atomically, so nothing
                # is half-written.
                os._exit(130)

    threading.Thread(target=watch, name="raidjax-ctrl-c", daemon=True).start()


COMPILATION_CACHE_BYTES = 1 << 30  # 1 GiB: a few hundred of raidjax's larger programs


def use_compilation_cache(folder: str | Path | None = None, max_bytes: int = COMPILATION_CACHE_BYTES) -> Path | None:
    """Keep this process's compiled programs for later ones: JAX's persistent compilation cache in
    ``folder`` (default ``$XDG_CACHE_HOME/raidjax/jax``, i.e. ``~/.cache/raidjax/jax``). A command
    run again, or resumed after an interruption, then reads its programs instead of compiling them
    (JAX keeps the programs that took over a second to compile). Before use the folder is cut to
    ``max_bytes``, the oldest files first. Every raidjax command line calls it (``run_cli``); call
    it in your own scripts before the first JAX computation.

    Returns:
        The folder in use: JAX's own when one is set already (``JAX_COMPILATION_CACHE_DIR`` or
        ``jax.config``), left as it is; ``None`` with ``RAIDJAX_COMPILATION_CACHE=0``.
    """
    if os.environ.get("RAIDJAX_COMPILATION_CACHE") == "0":
        return None
    current = os.environ.get("JAX_COMPILATION_CACHE_DIR") or _jax_cache_dir()
    if current:
        return Path(current)
    if folder is None:
        folder = cache_folder() / "jax"
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        prune_folder(folder, max_bytes)
    except OSError:  # an unwritable cache costs only the compiles
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    return folder


def _jax_cache_dir() -> str | None:
    return getattr(jax.config, "jax_compilation_cache_dir", None)


def prune_folder(folder: str | Path, max_bytes: int) -> int:
    """Delete the oldest files (by modification time) of ``folder`` until the rest hold at most
    ``max_bytes``; returns the bytes deleted. Files another process removes meanwhile are skipped."""
    files = []
    for f in Path(folder).iterdir():
        try:
            st = f.stat()
        except OSError:
            continue
        if f.is_file():
            files.append((st.st_mtime, st.st_size, f))
    total, freed = sum(size for _, size, _ in files), 0
    for _, size, f in sorted(files):
        if total - freed <= max_bytes:
            break
        try:
            f.unlink()
            freed += size
        except OSError:
            pass
    return freed


def run_cli(main, errors: tuple[type[BaseException], ...] = (ValueError,), interrupted: str = "") -> None:
    """Run a command line's ``main()`` the way users expect: a user's mistake (``errors``) prints
    ``error: <message>`` on one line and exits 2; Ctrl-C prints one line (with ``interrupted``, e.g.
    how to resume) and exits 130. ``RAIDJAX_DEBUG=1`` re-raises with the traceback. Before
    ``main`` runs, the process gets raidjax's recommended XLA flags (``raidjax.xla_flags``) and
    the persistent compilation cache (``use_compilation_cache``)."""
    import sys

    from raidjax.xla_flags import use_recommended_xla_flags

    use_recommended_xla_flags()
    use_compilation_cache()
    if not os.environ.get("RAIDJAX_DEBUG"):
        _exit_on_ctrl_c(f"interrupted{'; ' + interrupted if interrupted else ''}")
    try:
        main()
    except errors as e:
        if os.environ.get("RAIDJAX_DEBUG"):
            raise
        print(f"error: {e}", file=sys.stderr, flush=True)
        sys.exit(2)
    except KeyboardInterrupt:
        if os.environ.get("RAIDJAX_DEBUG"):
            raise
        print(f"interrupted{'; ' + interrupted if interrupted else ''}", file=sys.stderr, flush=True)
        sys.stdout.flush()
        # Straight out: a normal interpreter exit can crash (SIGSEGV) while XLA threads are still
        # compiling or running; every user file is written atomically, so nothing is half-written.
        os._exit(130)


def finite_json(obj, digits: int | None = None, **kwargs) -> str:
    """``json.dumps`` with NaN and infinities written as ``null`` (bare ``NaN`` is not JSON for most
    parsers), numpy scalars as numbers and, with ``digits``, floats rounded to that many decimals
    (``0.726``, not float32's ``0.7260000109672546``); ``kwargs`` go to ``json.dumps``."""
    import json
    import math

    import numpy as np

    def clean(x):
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, list | tuple):
            return [clean(v) for v in x]
        if isinstance(x, np.ndarray | np.generic) or hasattr(x, "__jax_array__") or type(x).__name__ == "ArrayImpl":
            x = np.asarray(x)
            return clean(x.tolist()) if x.ndim else clean(x.item())
        if isinstance(x, float) and not math.isfinite(x):
            return None
        if isinstance(x, float) and digits is not None:
            return round(x, digits)
        return x

    return json.dumps(clean(obj), allow_nan=False, **kwargs)
