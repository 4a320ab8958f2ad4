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
