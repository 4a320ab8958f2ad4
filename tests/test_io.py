"""Host plumbing: what every stored result records about the run that produced it."""

from __future__ import annotations

import datetime
import shutil
import subprocess
from functools import partial
from pathlib import Path

from raidjax import io


def test_machine_records_date_commit_and_devices():
    m = io.machine(load=True)
    # The date is now, in UTC; the commit is one git itself knows in this checkout, HEAD or an
    # ancestor of it (it is read at import, and a commit may land while a session's tests run).
    age = datetime.datetime.now(datetime.UTC) - datetime.datetime.fromisoformat(m["date"])
    assert datetime.timedelta(0) <= age < datetime.timedelta(minutes=5)
    repo = Path(io.__file__).resolve().parent
    git = partial(subprocess.run, cwd=repo, capture_output=True, text=True)
    if shutil.which("git") and git(["git", "rev-parse", "HEAD"]).stdout.strip():  # a checkout; a wheel records None
        commit = m["commit"].removesuffix("+dirty")
        assert len(commit) >= 7 and git(["git", "merge-base", "--is-ancestor", commit, "HEAD"]).returncode == 0
    assert m["device_count"] >= 1 and m["cpu_count"] >= 1 and "load_average_1m" in m


def test_source_commit_is_none_outside_a_git_checkout(monkeypatch, tmp_path):
    monkeypatch.setattr(io, "__file__", str(tmp_path / "io.py"))
    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path.parent))
    assert io.source_commit() is None


def test_prune_folder_deletes_the_oldest_files_first(tmp_path):
    import os

    for i, name in enumerate(["old", "mid", "new"]):
        (tmp_path / name).write_bytes(b"x" * 100)
        os.utime(tmp_path / name, (1000 + i, 1000 + i))
    assert io.prune_folder(tmp_path, 250) == 100
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mid", "new"]
    assert io.prune_folder(tmp_path, 200) == 0
    assert io.prune_folder(tmp_path, 0) == 200 and not list(tmp_path.iterdir())


def test_use_compilation_cache_sets_a_folder_only_where_none_is_set(monkeypatch, tmp_path):
    import jax

    set_to = []
    monkeypatch.setattr(jax.config, "update", lambda name, value: set_to.append((name, value)))
    monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", str(tmp_path / "theirs"))  # the tests' own cache
    assert io.use_compilation_cache(tmp_path / "ours") == tmp_path / "theirs" and not set_to
    monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR")
    monkeypatch.setattr(io, "_jax_cache_dir", lambda: None)
    (tmp_path / "ours").mkdir()
    (tmp_path / "ours" / "stale").write_bytes(b"x" * 10)
    assert io.use_compilation_cache(tmp_path / "ours", max_bytes=5) == tmp_path / "ours"
    assert set_to == [("jax_compilation_cache_dir", str(tmp_path / "ours"))]
    assert not (tmp_path / "ours" / "stale").exists()  # cut to max_bytes first
    monkeypatch.setenv("RAIDJAX_COMPILATION_CACHE", "0")
    assert io.use_compilation_cache(tmp_path / "ours") is None and len(set_to) == 1


def test_atomic_write_replaces_whole_files_with_the_usual_mode_and_leaves_no_temporary(tmp_path, monkeypatch):
    import os
    import stat

    target = tmp_path / "sub" / "result.json"
    io.atomic_write(target, "old")
    io.atomic_write(target, b"new")
    assert target.read_bytes() == b"new" and os.listdir(target.parent) == ["result.json"]
    umask = os.umask(0)  # reads the process's umask (and puts it back): mkstemp alone gives 0600
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask
    synced = []  # the folder is synced after the rename, so the new name is on disk too
    real_fsync = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (synced.append(stat.S_ISDIR(os.fstat(fd).st_mode)), real_fsync(fd)))
    io.atomic_write(target, "newer")
    assert synced == [False, True] and target.read_text() == "newer"
