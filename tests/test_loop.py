"""The one training loop (``trainers.loop.train``) on a toy learner whose state counts its updates:
chunking (a shorter last chunk), checkpoint cadence, metrics rows, stopping and resuming exactly."""

from __future__ import annotations

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from trainers import checkpoint
from trainers.loop import Learner, train


def counter(num_updates: int, per_chunk: int, n_runs: int = 2) -> Learner:
    """State ``x[n_runs]`` starts at the run's index and adds 1 per update; a chunk reports the sum."""

    def chunk(n):
        def run(state):
            return {"x": state["x"] + n}, {"x_sum": jnp.sum(state["x"] + n)}
        return run

    def rows(u, n, m, clock):
        return [{"update": u + n, "x_sum": float(m["x_sum"]), **clock}]

    return Learner(init=lambda: {"x": jnp.arange(n_runs, dtype=jnp.float32)}, init_args=(), chunk=chunk,
                   policy=lambda s: s, rows=rows, describe=lambda r: f"x_sum {r['x_sum']:g}", config={"toy": 1},
                   n_runs=n_runs, num_updates=num_updates, updates_per_chunk=per_chunk, steps_per_update=10)


def _rows(folder):
    return [{k: v for k, v in json.loads(line).items() if k not in ("seconds", "steps_per_s")}
            for line in (folder / "metrics.jsonl").read_text().splitlines()]


def test_chunks_rows_checkpoints_and_a_shorter_last_chunk(tmp_path):
    lines = []
    done = train(counter(7, 3), tmp_path / "ckpt", tmp_path, log=lines.append, checkpoint_every=2)
    assert done.finished and done.update == 7 and done.start_update == 0
    np.testing.assert_array_equal(np.asarray(done.state["x"]), [7.0, 8.0])
    # chunks of 3, 3 and 1 updates; sums of x = (0 + 1) + 2 * updates so far
    assert _rows(tmp_path) == [{"update": 3, "x_sum": 7.0}, {"update": 6, "x_sum": 13.0}, {"update": 7, "x_sum": 15.0}]
    # every second chunk, and the last one
    assert sorted(int(p.name) for p in (tmp_path / "ckpt").iterdir() if p.name.isdigit()) == [6, 7]
    assert sum("compiled a" in s for s in lines) == 2  # one program per chunk length
    assert any(s.startswith("update 7/7") and "x_sum 15" in s for s in lines)


def test_a_stopped_run_resumes_to_the_same_end(tmp_path):
    ref = train(counter(6, 2), tmp_path / "ref" / "ckpt", tmp_path / "ref", log=lambda s: None)
    out = tmp_path / "run"
    lines = []
    first = train(counter(6, 2), out / "ckpt", out, log=lines.append, checkpoint_every=5, max_chunks=1)
    assert not first.finished and first.update == 2
    assert any("stopped at update 2/6" in s for s in lines)  # and checkpointed despite checkpoint_every=5
    assert checkpoint.latest_step(out / "ckpt") == 2
    again = train(counter(6, 2), out / "ckpt", out, log=lines.append)
    assert any("resumed from the checkpoint at update 2/6" in s for s in lines)
    assert again.finished and again.start_update == 2
    np.testing.assert_array_equal(np.asarray(again.state["x"]), np.asarray(ref.state["x"]))
    assert _rows(out) == _rows(tmp_path / "ref")


def test_a_finished_run_resumed_runs_no_chunk(tmp_path):
    first = train(counter(4, 2), tmp_path / "ckpt", tmp_path, log=lambda s: None)
    lines = []
    done = train(counter(4, 2), tmp_path / "ckpt", tmp_path, log=lines.append)
    assert done.finished and done.start_update == 4 and not any("compiled" in s for s in lines)
    # the run's rate, not this invocation's (which trained nothing: result.json said 0 steps/s)
    assert done.seconds == first.seconds > 0 and first.steps_per_s > 0
    assert done.steps_per_s == pytest.approx(first.steps_per_s)
    assert len(_rows(tmp_path)) == 2
    assert jax.tree.leaves(done.state)[0].shape == (2,)


def test_a_resumed_run_lowers_the_chunk_of_a_fresh_run(tmp_path):
    """A restored state is committed to its device and a fresh one is not, which JAX lowers with and
    without sharding annotations: a resumed run would compile its chunk again instead of reading it
    from JAX's persistent compilation cache. ``train`` lowers both from the same shapes."""
    from trainers.loop import _lowering_state

    learner = counter(6, 2)
    train(learner, tmp_path / "ckpt", tmp_path, log=lambda s: None, max_chunks=1)
    restored, _, _ = checkpoint.restore(tmp_path / "ckpt", learner.abstract_state())
    fresh = jax.jit(learner.init)()
    program = lambda s: jax.jit(learner.chunk(2)).lower(s).as_text()
    if program(restored) == program(fresh):
        pytest.skip("this JAX lowers a restored and a fresh state alike")
    assert program(_lowering_state(restored, 2)) == program(_lowering_state(fresh, 2))


def test_progress_line_shows_the_rate_of_the_last_chunks(tmp_path):
    """One chunk stalls (as a run paused or sharing its cores does); once it is more than
    RECENT_CHUNKS chunks old, the progress line's rate is that of the chunks since, while the metrics
    rows keep the invocation's average."""
    import re
    import time

    from trainers.loop import RECENT_CHUNKS

    def stall_at_update_1(x):
        if x[0] == 1.0:  # the state after the first update (run 0 starts at 0)
            time.sleep(1.0)
        return x

    learner = counter(RECENT_CHUNKS + 3, 1)
    plain = learner.chunk

    def chunk(n):
        def run(state):
            x = jax.pure_callback(stall_at_update_1, jax.ShapeDtypeStruct(state["x"].shape, state["x"].dtype),
                                  state["x"])
            return plain(n)({"x": x})
        return run

    lines = []
    train(dataclasses.replace(learner, chunk=chunk), tmp_path / "ckpt", tmp_path, log=lines.append)
    rates = [float(re.search(r"([\d,]+) steps/s", s).group(1).replace(",", "")) for s in lines if "steps/s" in s]
    rows = [json.loads(line) for line in (tmp_path / "metrics.jsonl").read_text().splitlines()]
    assert len(rates) == len(rows) == RECENT_CHUNKS + 3
    # 20 steps a chunk (10 per update, 2 runs): while the stall is among the last chunks, at most
    # 20 x RECENT_CHUNKS steps in over 1 s; after, the chunks of a few milliseconds alone
    assert all(r <= 20 * RECENT_CHUNKS for r in rates[1:RECENT_CHUNKS + 1])
    assert rows[-1]["steps_per_s"] <= 20 * len(rows) < rates[-1]
