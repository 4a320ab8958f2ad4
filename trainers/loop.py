"""The one chunked training loop of every learner: initialise or restore, run jitted chunks of
updates, write metrics rows, checkpoint, print progress, stop and resume exactly.

Both trainers' runs (``trainers.runs``), Benchmark 1's MA-POCA runs and Benchmark 2's PPO
generator all train through ``train``; what differs between them is a ``Learner`` (the jittable
pieces of one algorithm, batched over a leading axis of seeds or runs). The run folder's
contract (``trainers.runfolder``) holds: a row is written before the checkpoint of its chunk, so a
resume drops the rows past the checkpoint (``trainers.metrics``) and recomputes them bit for bit;
checkpoints are verified on restore and the rejected ones moved aside (``trainers.checkpoint``).

    learner = Learner(init=..., init_args=(keys,), chunk=..., policy=..., rows=..., ...)
    done = train(learner, folder / "checkpoints", folder, log=print)
    if done.finished: ...
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax

from raidjax.io import fmt_seconds
from raidjax.sharding import batch_sharding, put_batch
from trainers import checkpoint, metrics


@dataclasses.dataclass(frozen=True)
class Learner:
    """The pieces of one algorithm that ``train`` drives (all batched over ``n_runs``).

    Attributes:
        init: ``init(*init_args) -> state``, the training state of every run (leading axis
            ``n_runs``); jitted by ``train``.
        init_args: its arguments (keys, contents, targets: arrays, not baked into the program).
        chunk: ``chunk(n) -> f`` with ``f(state, *chunk_args) -> (state, metrics)`` running ``n``
            updates of every run; ``train`` compiles one program per distinct ``n``.
        policy: ``policy(state) -> weights`` saved beside the state (what ``load_policy`` reads).
        rows: ``rows(first_update, n, host_metrics, clock) -> [row, ...]``: the metrics rows of
            one chunk, each a dict with an ``update`` key (``clock``: ``seconds`` of training so
            far and ``steps_per_s``, to merge in).
        describe: ``describe(last_row) -> str``, the learner's part of a progress line.
        config: the JSON-able config saved in every checkpoint.
        n_runs: the size of the leading axis (runs split over the visible devices).
        num_updates: updates of a whole run.
        updates_per_chunk: updates per chunk (the last one may be shorter).
        steps_per_update: environment steps per update and run (for the rate and the ETA).
        chunk_args: extra arguments of every chunk (e.g. per-run targets).
        donate: donate the state's buffers to the chunk (saves memory; the state is replaced).
    """

    init: Callable[..., Any]
    init_args: tuple
    chunk: Callable[[int], Callable[..., tuple[Any, dict]]]
    policy: Callable[[Any], Any]
    rows: Callable[[int, int, dict, dict], list[dict]]
    describe: Callable[[dict], str]
    config: dict
    n_runs: int
    num_updates: int
    updates_per_chunk: int
    steps_per_update: int
    chunk_args: tuple = ()
    donate: bool = False

    def abstract_state(self):
        """The state's shapes and dtypes (what a restore fills), without computing it."""
        return jax.eval_shape(self.init, *self.init_args)


@dataclasses.dataclass(frozen=True)
class Trained:
    """What ``train`` returns.

    Attributes:
        state: the training state after the last chunk run (restored, if none ran).
        update: updates done (``== num_updates`` when finished).
        finished: whether the run reached ``num_updates``.
        start_update: the update it started from (0, or the checkpoint resumed from).
        seconds: training seconds over every invocation (compiles excluded).
        compile_seconds: seconds of this invocation's init or restore and compiles.
        steps_per_s: environment steps per second of the run's training (every invocation,
            compiles excluded; every run counted): a run resumed with nothing left to train keeps its rate.
    """

    state: Any
    update: int
    finished: bool
    start_update: int
    seconds: float
    compile_seconds: float
    steps_per_s: float


# The progress line's rate and ETA are those of the last chunks: a run that shared its cores for a
# while, or was paused, shows its rate now, not its average since it started. The metrics rows
# keep the invocation's average (``steps_per_s``).
RECENT_CHUNKS = 10


def _lowering_state(state, n_runs: int):
    """What a chunk is lowered with: on one device (the runs not split, ``batch_sharding``) only
    the shapes and dtypes of ``state``, since a restored state is committed to its device and a
    fresh one is not, which gives the lowered program sharding annotations in one case only: the
    same chunk would compile again on resume instead of being read from JAX's persistent
    compilation cache. Split runs are lowered with their shardings."""
    if batch_sharding(n_runs) is not None:
        return state
    return jax.tree.map(lambda x: jax.ShapeDtypeStruct(x.shape, x.dtype), state)


def train(learner: Learner, ckpt_dir: str | Path, metrics_dir: str | Path, *, metrics_name: str = "metrics",
          log: Callable[[str], None] = print, checkpoint_every: int = 1, max_chunks: int | None = None,
          max_to_keep: int = 3) -> Trained:
    """Train ``learner`` from its newest intact checkpoint in ``ckpt_dir`` (or from scratch).

    Args:
        learner: the algorithm's pieces.
        ckpt_dir: its checkpoints folder; a checkpoint at update ``u`` is step ``u``.
        metrics_dir, metrics_name: rows go to ``metrics_dir/metrics_name.{jsonl,csv}``.
        log: prints a progress line (``print`` or ``RunFolder.log``).
        checkpoint_every: chunks between checkpoints; the last chunk of a run and the last one of
            an invocation stopped by ``max_chunks`` are always checkpointed, so a resume continues.
        max_chunks: stop after this many chunks of this invocation (``None``: run to the end).
        max_to_keep: older checkpoints beyond this many are deleted.

    Returns:
        ``Trained``.
    """
    t0 = time.perf_counter()
    ckpt_dir, total, per = Path(ckpt_dir), learner.num_updates, learner.updates_per_chunk
    if checkpoint.latest_step(ckpt_dir) is not None:
        state, _, meta = checkpoint.restore(ckpt_dir, learner.abstract_state(), quarantine=True)
        start, seconds_before = int(meta["update"]), float(meta.get("seconds", 0.0))
        log(f"resumed from the checkpoint at update {start}/{total}")
    else:  # a new run, or one stopped before its first checkpoint
        init = jax.jit(learner.init).lower(*learner.init_args).compile()
        state, start, seconds_before = init(*learner.init_args), 0, 0.0
    state = put_batch(state, learner.n_runs)  # the runs split over every visible device (raidjax.sharding)
    rows_log = metrics.MetricsLog(metrics_dir, resume_update=start, name=metrics_name)
    compiled, compile_s = {}, time.perf_counter() - t0
    u, chunks_here, train_s = start, 0, 0.0
    recent = deque(maxlen=RECENT_CHUNKS)  # (steps, seconds) of the last chunks, for the progress line
    while u < total and (max_chunks is None or chunks_here < max_chunks):
        n = min(per, total - u)
        if n not in compiled:
            t = time.perf_counter()
            compiled[n] = jax.jit(learner.chunk(n), donate_argnums=(0,) if learner.donate else ()).lower(
                _lowering_state(state, learner.n_runs), *learner.chunk_args).compile()
            compile_s += time.perf_counter() - t
            log(f"compiled a {n}-update chunk in {fmt_seconds(time.perf_counter() - t)}")
        t = time.perf_counter()
        state, m = compiled[n](state, *learner.chunk_args)
        m = jax.device_get(m)  # waits for the chunk
        chunk_s = time.perf_counter() - t
        train_s += chunk_s
        chunks_here += 1
        recent.append((n * learner.steps_per_update * learner.n_runs, chunk_s))
        rate = (u + n - start) * learner.steps_per_update * learner.n_runs / max(train_s, 1e-9)
        clock = {"seconds": seconds_before + train_s, "steps_per_s": rate}
        new_rows = learner.rows(u, n, m, clock)
        for row in new_rows:  # before the checkpoint: a resume drops rows past it, never leaves gaps
            rows_log.write(row)
        u += n
        now = sum(steps for steps, _ in recent) / max(sum(sec for _, sec in recent), 1e-9)
        eta = (total - u) * learner.steps_per_update * learner.n_runs / max(now, 1e-9)
        log(f"update {u}/{total}  steps {u * learner.steps_per_update / 1e6:.3g}M/"
            f"{total * learner.steps_per_update / 1e6:.3g}M per run  {now:,.0f} steps/s  ETA {fmt_seconds(eta)}  "
            + learner.describe(new_rows[-1]))
        stopping = u == total or chunks_here == max_chunks
        if (u // per) % checkpoint_every == 0 or stopping:
            meta = {"update": u, "env_steps": u * learner.steps_per_update,
                    "seconds": seconds_before + train_s}
            checkpoint.save(ckpt_dir, state, learner.policy(state), learner.config, meta, max_to_keep=max_to_keep)
    if u < total:
        log(f"stopped at update {u}/{total} (--max-chunks); rerun the same command with --resume to continue")
    return Trained(state=state, update=u, finished=u == total, start_update=start,
                   seconds=seconds_before + train_s, compile_seconds=compile_s,
                   steps_per_s=u * learner.steps_per_update * learner.n_runs / max(seconds_before + train_s, 1e-9))
