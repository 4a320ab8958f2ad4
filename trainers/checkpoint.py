"""Checkpoints of both trainers (orbax-checkpoint): save, restore with an integrity check and a
fallback to the newest intact checkpoint, the latest step.

A run folder ``DIR`` holds ``DIR/checkpoints/<update>/`` with four items: ``state`` (the whole
training state of every seed: weights, optimiser, environments, PRNG key), ``policy`` (the
policy's weights alone, leading seed axis), ``config`` (the trainer's config as a dict) and
``meta`` (update, chunk, decisions, seconds, and the SHA-256 ``digest`` of ``state`` and
``policy``), plus ``files.json``, the size and SHA-256 of every file of the checkpoint. Orbax
writes each checkpoint into a temporary directory and renames it when complete, so an
interrupted save never shows up as a checkpoint; the two digests catch what the rename cannot
(bytes changed or lost on disk afterwards): the file list before orbax reads anything, the
pytree digest after it did. A checkpoint that fails either check or does not load is named in a
one-line warning and the next older one is tried; resuming trainers move the rejected ones aside
to ``DIR/checkpoints_rejected/<update>`` (beside any other checkpoints folder ``X``, to
``X_rejected/``; an update rejected again gets ``<update>.1``, ``.2``, ...: nothing is deleted or
overwritten).
Loading a trained policy is each algorithm's (``trainers.mapoca.load_policy``), on top of
``load_policy_weights``.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import jax
import numpy as np
import orbax.checkpoint as ocp

from raidjax.io import atomic_write


class CheckpointError(RuntimeError):
    """A checkpoint is missing, incomplete or unreadable (the message says which and where)."""


def _manager(directory: Path, max_to_keep: int | None = 3, create: bool = True) -> ocp.CheckpointManager:
    opts = ocp.CheckpointManagerOptions(max_to_keep=max_to_keep, enable_async_checkpointing=False, create=create)
    return ocp.CheckpointManager(directory.absolute(), options=opts,
                                 item_names=("state", "policy", "config", "meta"))


def digest(tree) -> str:
    """SHA-256 (hex) of a pytree's leaves: dtype, shape and bytes, in flattening order (typed PRNG
    keys by their key data). Equal trees give equal digests on any host."""
    h = hashlib.sha256()
    for leaf in jax.tree.leaves(tree):
        if jax.dtypes.issubdtype(getattr(leaf, "dtype", None), jax.dtypes.prng_key):
            leaf = jax.random.key_data(leaf)
        a = np.ascontiguousarray(jax.device_get(leaf))
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def save(directory: str | Path, state, policy, config: dict, meta: dict, max_to_keep: int = 3) -> Path:
    """Write a checkpoint at step ``meta['update']``, with the digests of ``state`` and ``policy``.

    Args:
        directory: the checkpoints folder (``DIR/checkpoints``).
        state: the training state (pytree, any leading seed axis).
        policy: the policy's weights (pytree, same leading axis).
        config: JSON-able dict of the trainer's config.
        meta: JSON-able dict with at least ``update``.
        max_to_keep: older checkpoints beyond this many are deleted.

    Returns:
        The checkpoint's directory ``directory/<update>``.
    """
    directory = Path(directory)
    step = int(meta["update"])
    meta = {**meta, "digest": {"state": digest(state), "policy": digest(policy)}}
    with _manager(directory, max_to_keep) as mngr:
        mngr.save(step, args=ocp.args.Composite(
            state=ocp.args.StandardSave(state),
            policy=ocp.args.StandardSave(policy),
            config=ocp.args.JsonSave(config),
            meta=ocp.args.JsonSave(meta),
        ), force=True)
        mngr.wait_until_finished()
    step_dir = directory / str(step)
    atomic_write(step_dir / FILES, json.dumps(_file_digests(step_dir), indent=0))
    return step_dir


FILES = "files.json"  # the file list of a checkpoint, beside orbax's own files


def _file_digests(step_dir: Path) -> dict[str, list]:
    """``relative path -> [size, sha256]`` of every file of a checkpoint but ``files.json``."""
    out = {}
    for f in sorted(step_dir.rglob("*")):
        if f.is_file() and f.name != FILES:
            out[str(f.relative_to(step_dir))] = [f.stat().st_size, hashlib.sha256(f.read_bytes()).hexdigest()]
    return out


def _check_files(step_dir: Path) -> None:
    """Compare a checkpoint's files with its ``files.json`` (absent: written before file lists
    existed, or the save was killed just before it; the pytree digest still applies)."""
    listed = step_dir / FILES
    if not listed.exists():
        return
    try:
        expected = json.loads(listed.read_text())
    except json.JSONDecodeError:
        raise CheckpointError(f"checkpoint {step_dir} is corrupted ({FILES} is not valid JSON)") from None
    actual = _file_digests(step_dir)
    for name, (size, sha) in expected.items():
        if name not in actual:
            raise CheckpointError(f"checkpoint {step_dir} is incomplete ({name} is missing)")
        if actual[name][0] != size:
            raise CheckpointError(f"checkpoint {step_dir} is corrupted ({name}: {actual[name][0]} bytes, "
                                  f"{size} written)")
        if actual[name][1] != sha:
            raise CheckpointError(f"checkpoint {step_dir} is corrupted ({name} does not match its saved digest)")


def _candidates(path: str | Path) -> tuple[Path, list[int]]:
    """``(checkpoints dir, steps to try, newest first)`` from a run dir, its ``checkpoints`` dir
    (every finished step) or one step dir (that step alone)."""
    path = Path(path)
    if not path.exists():
        raise CheckpointError(f"checkpoint path {path} does not exist")
    if path.name.isdigit() and path.is_dir() and not path.parent.name.endswith("_rejected"):
        return path.parent, [int(path.name)]
    directory = path / "checkpoints" if (path / "checkpoints").is_dir() else path
    steps = sorted((int(p.name) for p in directory.iterdir() if p.is_dir() and p.name.isdigit()), reverse=True)
    if not steps:
        raise CheckpointError(f"no finished checkpoint in {directory} (expected sub-directories named by update)")
    return directory, steps


def latest_step(directory: str | Path) -> int | None:
    """The last finished checkpoint step under ``directory`` (None if there is none); whether it
    is intact is only known when it is restored."""
    try:
        return _candidates(directory)[1][0]
    except CheckpointError:
        return None


def _short(e: Exception) -> str:
    """One line of an exception (orbax/TensorStore messages can run to kilobytes)."""
    text = str(e).strip().splitlines()
    line = text[0] if text else ""
    return f"{type(e).__name__}: {line[:160]}{'...' if len(line) > 160 else ''}"


def _placed(abstract):
    """``abstract`` (shapes and dtypes) placed on this process's first device: a checkpoint saved on
    another backend (trained on a CPU, read on a GPU) restores here instead of failing orbax's
    topology check on the sharding it was saved with."""
    device = jax.sharding.SingleDeviceSharding(jax.devices()[0])
    return jax.tree.map(lambda a: jax.ShapeDtypeStruct(a.shape, a.dtype, sharding=device), abstract)


def _as_saved(where: Path, name: str) -> ocp.args.StandardRestore:
    """Restore arguments for item ``name`` of the step ``where`` in the shapes and dtypes it was
    saved with (its metadata), placed on this device (``_placed``). The item's handler reads it:
    a ``StandardCheckpointer`` would look for a step's ``_CHECKPOINT_METADATA`` inside the item's
    folder and log a warning that it does not exist."""
    md = ocp.StandardCheckpointHandler().metadata((where / name).absolute())
    return ocp.args.StandardRestore(_placed(getattr(md, "tree", md)))


def _restore_one(directory: Path, step: int, **items):
    """Restore ``items`` of one step and check them against the saved digests (a
    ``StandardRestore()`` without a target restores the item as it was saved, on this device)."""
    where = directory / str(step)
    _check_files(where)
    try:
        items = {k: _as_saved(where, k) if isinstance(v, ocp.args.StandardRestore) and v.item is None else v
                 for k, v in items.items()}
        with _manager(directory, max_to_keep=None, create=False) as mngr:
            out = mngr.restore(step, args=ocp.args.Composite(meta=ocp.args.JsonRestore(), **items))
    except Exception as e:  # noqa: BLE001 - any orbax/tensorstore failure means a bad checkpoint
        raise CheckpointError(f"checkpoint {where} is unreadable ({_short(e)})") from e
    if not isinstance(out.meta, dict) or "update" not in out.meta:
        raise CheckpointError(f"checkpoint {where} is incomplete (no meta)")
    saved = out.meta.get("digest")  # checkpoints written before digests existed are not verified
    for name in ("state", "policy"):
        if saved is not None and name in items and digest(out[name]) != saved.get(name):
            raise CheckpointError(f"checkpoint {where} is corrupted ({name} does not match its saved digest)")
    return out


def _set_aside(directory: Path, step: int) -> Path:
    """Move ``directory/<step>`` to ``<directory>_rejected/<step>`` (``<step>.1``, ``.2``, ... when
    that name is taken: the same update rejected twice, or in another run's folder) and return
    where it went. One folder per checkpoints folder, so the groups of a run that share a parent
    (``checkpoints/mapoca/group0``, ``group1``) never take each other's names."""
    home = directory.parent / f"{directory.name}_rejected"
    home.mkdir(parents=True, exist_ok=True)
    dest, n = home / str(step), 0
    while dest.exists():
        n += 1
        dest = home / f"{step}.{n}"
    (directory / str(step)).rename(dest)
    return dest


def _restore(path: str | Path, quarantine: bool = False, **items):
    """The newest checkpoint under ``path`` that loads and matches its digests, warning (one line
    on stderr) about each newer one that does not; with ``quarantine`` those are moved aside
    (``_set_aside``). Returns ``(orbax Composite result, step)``."""
    directory, steps = _candidates(path)
    rejected = []
    for step in steps:
        try:
            out = _restore_one(directory, step, **items)
        except CheckpointError as e:
            rejected.append(step)
            more = "trying the previous one" if step != steps[-1] else "no older checkpoint"
            print(f"warning: {e}; {more}", file=sys.stderr, flush=True)
            continue
        if quarantine:
            for bad in rejected:
                dest = _set_aside(directory, bad)
                print(f"warning: moved the unusable checkpoint {directory / str(bad)} to {dest}",
                      file=sys.stderr, flush=True)
        return out, step
    raise CheckpointError(f"no intact checkpoint in {directory}: tried {', '.join(map(str, steps))}")


def restore(path: str | Path, abstract_state, quarantine: bool = False) -> tuple[object, dict, dict]:
    """Restore the newest intact checkpoint (or the given step dir) into the structure of
    ``abstract_state`` (e.g. ``jax.eval_shape`` of the vmapped ``init``).

    Args:
        path: a run dir, its ``checkpoints`` dir, or one step dir (then no fallback).
        abstract_state: the state's structure, shapes and dtypes.
        quarantine: move newer checkpoints that failed aside, to ``<run>/checkpoints_rejected/`` (a
            resuming trainer does, so its next saves do not collide with them).

    Returns:
        ``(state, config dict, meta dict)``.

    Raises:
        CheckpointError: no checkpoint, or none that loads and matches its digests.
    """
    out, _ = _restore(path, quarantine, state=ocp.args.StandardRestore(_placed(abstract_state)),
                      config=ocp.args.JsonRestore())
    return out.state, dict(out.config), dict(out.meta)


def load_config(path: str | Path) -> dict:
    """The config dict saved with the newest intact (or the given) checkpoint, without its arrays;
    raises ``CheckpointError`` when there is none."""
    out, _ = _restore(path, config=ocp.args.JsonRestore())
    return dict(out.config)


def load_policy_weights(path: str | Path) -> tuple[object, dict]:
    """``(policy weights with the leading seed axis, config dict)`` of the newest intact (or the
    given) checkpoint; raises ``CheckpointError`` when there is none."""
    out, _ = _restore(path, policy=ocp.args.StandardRestore(), config=ocp.args.JsonRestore())
    return out.policy, dict(out.config)
