"""Run many command lines in one fresh process, each as ``python -m MODULE ARGS`` (or ``python
SCRIPT ARGS``) would run it, and record what each did. As a script::

    python tests/in_one_process.py CASES.json RESULTS.json

CASES is a list of ``{"target": "-m module" | "path/script.py", "argv": [...], "cwd": "...", "env":
{...}}`` (``cwd`` and ``env`` optional; ``env`` sets variables before the case, ``None`` unsets one);
RESULTS gets, per case, ``{"code": exit status, "stdout": ..., "stderr": ..., "backend": bool,
"xla_flags": XLA_FLAGS after the case}``.
Output is captured at the file descriptors, so whatever writes to them (a logging handler, C code)
is caught; ``backend`` says whether a JAX backend had started after the case ran.

Starting Python and importing JAX costs about 1.5 s per process on 2 cores; the command-line tests
run dozens of commands that stop before compiling anything (``--help``, refused flags), so they share
one process. A case that started a backend would change the next cases' XLA flags (they are read
when a backend starts), hence ``backend``, which the callers check.
"""

from __future__ import annotations

import json
import os
import runpy
import subprocess
import sys
import tempfile
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _run_one(target: str, argv: list[str]) -> int:
    """Run one command in this process; its exit status as the interpreter would report it."""
    try:
        if target.startswith("-m "):
            sys.argv = [target[3:], *argv]  # run_module replaces argv[0] with the module's file
            sys.modules.pop(target[3:], None)  # imported by an earlier case: run it afresh, as -m does
            runpy.run_module(target[3:], run_name="__main__", alter_sys=True)
        else:  # a script: its folder first on the path, as the interpreter puts it
            sys.argv = [target, *argv]
            sys.path.insert(0, str(Path(target).resolve().parent))
            try:
                runpy.run_path(target, run_name="__main__")
            finally:
                sys.path.pop(0)
    except SystemExit as e:
        if e.code is None or isinstance(e.code, int):
            return e.code or 0
        print(e.code, file=sys.stderr)
        return 1
    except BaseException:  # noqa: BLE001 - reported as the interpreter would, then the next case
        traceback.print_exc()
        return 1
    return 0


def _flush() -> None:
    sys.stdout.flush()
    sys.stderr.flush()


def _captured(case: dict) -> dict:
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        _flush()
        saved = os.dup(1), os.dup(2)
        os.dup2(out.fileno(), 1)
        os.dup2(err.fileno(), 2)
        here = os.getcwd()
        for k, v in case.get("env", {}).items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        try:
            os.chdir(case.get("cwd", ROOT))
            code = _run_one(case["target"], case["argv"])
        finally:
            _flush()
            for fd, copy in zip((1, 2), saved, strict=True):
                os.dup2(copy, fd)
                os.close(copy)
            os.chdir(here)
        texts = []
        for f in (out, err):
            f.seek(0)
            texts.append(f.read().decode(errors="replace"))
    started = "jax" in sys.modules and sys.modules["jax._src.xla_bridge"].backends_are_initialized()
    return {"code": code, "stdout": texts[0], "stderr": texts[1], "backend": bool(started),
            "xla_flags": os.environ.get("XLA_FLAGS")}


def run_all(cases: list[dict], env: dict[str, str] | None = None, timeout: float = 300) -> list[dict]:
    """Run ``cases`` (see the module docstring) in one fresh process with ``env`` (default: this
    process's, the repository on ``PYTHONPATH``); returns their results in order."""
    env = dict(os.environ if env is None else env)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "cases.json").write_text(json.dumps(cases))
        p = subprocess.run([sys.executable, __file__, str(Path(tmp) / "cases.json"), str(Path(tmp) / "results.json")],
                           cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout)
        assert p.returncode == 0, p.stderr[-3000:]
        return json.loads((Path(tmp) / "results.json").read_text())


if __name__ == "__main__":
    cases_path, results_path = sys.argv[1:3]
    sys.path.insert(0, str(ROOT))
    results = [_captured(c) for c in json.loads(Path(cases_path).read_text())]
    Path(results_path).write_text(json.dumps(results))
