"""Files a user keeps: ``atomic_write``, and ``cache_folder`` (where raidjax keeps what it can
recompute). A leaf module (standard library only), so that
``raidjax.xla_flags``, which runs before JAX starts, and ``raidjax.io``, which sets the flags for every
command line, can both use it without importing each other. ``raidjax.io`` re-exports it."""

from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path

# The process's umask, read once: reading it means setting it, which other threads would see.
_UMASK = os.umask(0)
os.umask(_UMASK)


def atomic_write(path: str | Path, data: str | bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and ``os.replace``, so
    a reader sees the old file or the new one, never half of one; the folder is synced after the
    rename where the system allows it, so the new name survives a power loss too. Returns ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data.encode() if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp creates 0600; give the file the usual mode
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    if hasattr(os, "O_DIRECTORY"):  # POSIX; elsewhere a folder cannot be opened to sync it
        folder = os.open(path.parent, os.O_RDONLY | os.O_DIRECTORY)
        try:
            os.fsync(folder)
        except OSError as e:  # some network and virtual file systems cannot sync a folder; the file is whole
            if e.errno not in (errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP):
                raise
        finally:
            os.close(folder)
    return path


def cache_folder() -> Path:
    """raidjax's folder for what it can recompute (the XLA flags' probe, compiled programs):
    ``$XDG_CACHE_HOME/raidjax``, by default ``~/.cache/raidjax``."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "raidjax"
