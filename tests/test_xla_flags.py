"""``import raidjax`` leaves the process alone; ``use_recommended_xla_flags`` is an explicit opt-in."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from in_one_process import run_all

from raidjax import xla_flags


def run(code: str, **env: str) -> str:
    base = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "RAIDJAX_KEEP_XLA_FLAGS")}
    out = subprocess.run([sys.executable, "-c", code], env={**base, **env}, capture_output=True, text=True,
                         timeout=120, cwd=os.path.dirname(os.path.dirname(__file__)))
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.strip()


def test_import_changes_no_flag_and_starts_no_backend():
    code = ("import os, raidjax, trainers.mapoca, trainers.ppo_pcgrl, experiments.benchmark1, experiments.benchmark2\n"
            "from jax._src import xla_bridge\n"
            "print(repr(os.environ.get('XLA_FLAGS')), xla_bridge.backends_are_initialized())")
    assert run(code) == "None False"
    assert run(code, XLA_FLAGS="--xla_dump_to=/nowhere") == "'--xla_dump_to=/nowhere' False"


def test_opt_in_appends_what_is_missing_and_keeps_the_users_values():
    assert xla_flags.with_recommended("") == " ".join(xla_flags.RECOMMENDED)
    mine = "--xla_cpu_enable_concurrency_optimized_scheduler=true --xla_force_host_platform_device_count=4"
    assert xla_flags.with_recommended(mine) == " ".join([mine, xla_flags.RECOMMENDED[0], *xla_flags.RECOMMENDED[2:]])
    code = "import os, raidjax\nprint(raidjax.use_recommended_xla_flags(), os.environ['XLA_FLAGS'])"
    assert run(code) == "True " + " ".join(xla_flags.known_flags())
    assert run(code, RAIDJAX_KEEP_XLA_FLAGS="1", XLA_FLAGS="-x") == "False -x"


def test_only_flags_the_installed_xla_accepts_are_added(tmp_path, monkeypatch):
    """XLA aborts on a flag it does not know, so XLA itself is asked (a child process) once per jaxlib."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    xla_flags.known_flags.cache_clear()
    try:
        mixed = ("--xla_raidjax_no_such_flag=1", "--xla_backend_optimization_level=3", "--xla_raidjax_nor_this=2")
        assert xla_flags.known_flags(mixed) == ("--xla_backend_optimization_level=3",)
        assert xla_flags.known_flags(("--xla_raidjax_no_such_flag=1",)) == ()
        stored = json.loads((tmp_path / "raidjax" / "xla_flags.json").read_text())
        assert sorted(stored.values()) == [[], ["--xla_backend_optimization_level=3"]]
        # The next process reads the answer instead of asking again: a planted answer is believed.
        key = next(k for k, v in stored.items() if v == [])
        (tmp_path / "raidjax" / "xla_flags.json").write_text(json.dumps({key: ["--xla_raidjax_no_such_flag=1"]}))
        xla_flags.known_flags.cache_clear()
        assert xla_flags.known_flags(("--xla_raidjax_no_such_flag=1",)) == ("--xla_raidjax_no_such_flag=1",)
    finally:
        xla_flags.known_flags.cache_clear()


def test_commands_run_with_the_flags():
    """raidjax's command lines opt in before JAX starts (through ``raidjax.io.run_cli``): each
    ``--help`` in one fresh process, ``XLA_FLAGS`` unset before each."""
    modules = ["raidjax.calibrate", "trainers.mapoca_cli", "experiments.benchmark1"]
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "RAIDJAX_KEEP_XLA_FLAGS")}
    results = run_all([{"target": f"-m {m}", "argv": ["--help"], "env": {"XLA_FLAGS": None}} for m in modules], env)
    for m, r in zip(modules, results, strict=True):
        assert r["code"] == 0 and not r["backend"], (m, r["stderr"][-2000:])
        assert r["xla_flags"] == " ".join(xla_flags.known_flags()), m
