"""Checkpoints of both trainers (orbax-checkpoint): save, restore, the latest step.

A run folder ``DIR`` holds ``DIR/checkpoints/<update>/`` with four items: ``state`` (the whole
training state of every seed: weights, optimiser, environments, PRNG key), ``policy`` (the
policy's weights alone, leading seed axis), ``config`` (the trainer's config as a dict) and
``meta`` (update, chunk, decisions, seconds). Orbax writes each checkpoint into a temporary
directory and renames it when complete, so an interrupted save never shows up as a checkpoint.
Loading a trained policy is each algorithm's (``trainers.mapoca.load_policy``), on top of
``load_policy_weights``.
"""

from __future__ import annotations

from pathlib import Path

import orbax.checkpoint as ocp


class CheckpointError(RuntimeError):
    """A checkpoint is missing, incomplete or unreadable (the message says which and where)."""


def _manager(directory: Path, max_to_keep: int | None = 3, create: bool = True) -> ocp.CheckpointManager:
    opts = ocp.CheckpointManagerOptions(max_to_keep=max_to_keep, enable_async_checkpointing=False, create=create)
    return ocp.CheckpointManager(directory.absolute(), options=opts,
                                 item_names=("state", "policy", "config", "meta"))


def save(directory: str | Path, state, policy, config: dict, meta: dict, max_to_keep: int = 3) -> Path:
    """Write a checkpoint at step ``meta['update']``.

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
    with _manager(directory, max_to_keep) as mngr:
        mngr.save(step, args=ocp.args.Composite(
            state=ocp.args.StandardSave(state),
            policy=ocp.args.StandardSave(policy),
            config=ocp.args.JsonSave(config),
            meta=ocp.args.JsonSave(meta),
        ), force=True)
        mngr.wait_until_finished()
    return directory / str(step)


def _resolve(path: str | Path) -> tuple[Path, int]:
    """``(checkpoints dir, step)`` from a run dir, its ``checkpoints`` dir or one step dir."""
    path = Path(path)
    if not path.exists():
        raise CheckpointError(f"checkpoint path {path} does not exist")
    if path.name.isdigit() and (path / "meta").exists() | (path / "state").exists():
        return path.parent, int(path.name)
    directory = path / "checkpoints" if (path / "checkpoints").is_dir() else path
    steps = sorted(int(p.name) for p in directory.iterdir() if p.is_dir() and p.name.isdigit())
    if not steps:
        raise CheckpointError(f"no finished checkpoint in {directory} (expected sub-directories named by update)")
    return directory, steps[-1]


def latest_step(directory: str | Path) -> int | None:
    """The last finished checkpoint step under ``directory`` (None if there is none)."""
    try:
        return _resolve(directory)[1]
    except CheckpointError:
        return None


def _restore(directory: Path, step: int, **items):
    try:
        with _manager(directory, max_to_keep=None, create=False) as mngr:
            return mngr.restore(step, args=ocp.args.Composite(**items))
    except Exception as e:  # noqa: BLE001 - any orbax/tensorstore failure means a bad checkpoint
        raise CheckpointError(f"checkpoint {directory / str(step)} is corrupted or incomplete: "
                              f"{type(e).__name__}: {e}") from e


def restore(path: str | Path, abstract_state) -> tuple[object, dict, dict]:
    """Restore the latest (or the given) checkpoint into the structure of ``abstract_state``
    (e.g. ``jax.eval_shape`` of the vmapped ``init``).

    Returns:
        ``(state, config dict, meta dict)``.

    Raises:
        CheckpointError: missing, incomplete or corrupted checkpoint, or one of another shape.
    """
    directory, step = _resolve(path)
    out = _restore(directory, step, state=ocp.args.StandardRestore(abstract_state),
                   config=ocp.args.JsonRestore(), meta=ocp.args.JsonRestore())
    if out.meta is None or out.config is None:
        raise CheckpointError(f"checkpoint {directory / str(step)} is corrupted or incomplete: no config/meta")
    return out.state, dict(out.config), dict(out.meta)


def saved_config(path: str | Path) -> dict:
    """The config dict stored with the latest (or the given) checkpoint."""
    directory, step = _resolve(path)
    return dict(_restore(directory, step, config=ocp.args.JsonRestore()).config)


def load_policy_weights(path: str | Path) -> tuple[object, dict]:
    """``(policy weights with the leading seed axis, config dict)`` of the latest (or the given)
    checkpoint; raises ``CheckpointError`` when missing or unreadable."""
    directory, step = _resolve(path)
    out = _restore(directory, step, policy=ocp.args.StandardRestore(), config=ocp.args.JsonRestore())
    return out.policy, dict(out.config)
