"""Checkpoints of MA-POCA runs (orbax-checkpoint) and loading a trained policy.

A run directory ``DIR`` holds ``DIR/checkpoints/<update>/`` with four items: ``state`` (the
whole ``Runner`` of every seed: weights, optimiser, arenas, PRNG key), ``policy`` (the actor
weights alone, leading seed axis), ``config`` (``Config.to_dict``) and ``meta`` (chunk, update,
decisions, seconds). Orbax writes each checkpoint into a temporary directory and renames it
when complete, so an interrupted save never shows up as a checkpoint.
"""

from __future__ import annotations

from pathlib import Path

import jax
import orbax.checkpoint as ocp

from trainers.config import Config
from trainers.mapoca import sample_actions
from trainers.networks import Actor


class CheckpointError(RuntimeError):
    """A checkpoint is missing, incomplete or unreadable (the message says which and where)."""


def _manager(directory: Path, max_to_keep: int | None = 3, create: bool = True) -> ocp.CheckpointManager:
    opts = ocp.CheckpointManagerOptions(max_to_keep=max_to_keep, enable_async_checkpointing=False, create=create)
    return ocp.CheckpointManager(directory.absolute(), options=opts,
                                 item_names=("state", "policy", "config", "meta"))


def save(directory: str | Path, runner, config: Config, meta: dict, max_to_keep: int = 3) -> Path:
    """Write a checkpoint of ``runner`` (pytree, any leading seed axis) at step ``meta['update']``.

    Returns:
        The checkpoint's directory ``directory/<update>``.
    """
    directory = Path(directory)
    step = int(meta["update"])
    with _manager(directory, max_to_keep) as mngr:
        mngr.save(step, args=ocp.args.Composite(
            state=ocp.args.StandardSave(runner),
            policy=ocp.args.StandardSave(runner.params["actor"]),
            config=ocp.args.JsonSave(config.to_dict()),
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


def restore(path: str | Path, abstract_runner) -> tuple[object, Config, dict]:
    """Restore the latest (or the given) checkpoint into the structure of ``abstract_runner``
    (e.g. ``jax.eval_shape`` of the vmapped ``init``).

    Returns:
        ``(runner, config, meta)``.

    Raises:
        CheckpointError: missing, incomplete or corrupted checkpoint, or one of another shape.
    """
    directory, step = _resolve(path)
    out = _restore(directory, step, state=ocp.args.StandardRestore(abstract_runner),
                   config=ocp.args.JsonRestore(), meta=ocp.args.JsonRestore())
    if out.meta is None or out.config is None:
        raise CheckpointError(f"checkpoint {directory / str(step)} is corrupted or incomplete: no config/meta")
    return out.state, Config.from_dict(out.config), dict(out.meta)


def load_config(path: str | Path) -> Config:
    """The ``Config`` stored with the latest (or the given) checkpoint."""
    directory, step = _resolve(path)
    out = _restore(directory, step, config=ocp.args.JsonRestore())
    return Config.from_dict(out.config)


def make_policy(actor: Actor, actor_params, deterministic: bool = False):
    """A pure ``policy(key, obs, state, params) -> int32[P]`` for one arena (``raidjax.playtest``
    compatible; the weights are baked in as constants, the function is hashable by identity)."""

    def policy(key, obs, state, params):
        actions, _ = sample_actions(key, actor.apply(actor_params, obs), obs.alive, deterministic)
        return actions

    return policy


def load_policy(path: str | Path, seed: int = 0, deterministic: bool | None = None):
    """Load a trained team as ``policy(key, obs, state, params) -> int32[P]``.

    Args:
        path: the run directory (``--out``), its ``checkpoints`` directory, or one checkpoint.
        seed: which of the run's seeds (index into the seed axis).
        deterministic: greedy actions instead of sampling (default: the run's ``deterministic_eval``).

    Returns:
        The policy (reuse the same object across ``playtest`` calls to avoid recompiling).

    Raises:
        CheckpointError: missing, incomplete or corrupted checkpoint, or ``seed`` out of range.
    """
    directory, step = _resolve(path)
    out = _restore(directory, step, policy=ocp.args.StandardRestore(), config=ocp.args.JsonRestore())
    cfg = Config.from_dict(out.config)
    weights = out.policy
    n_seeds = jax.tree.leaves(weights)[0].shape[0]
    if not 0 <= seed < n_seeds:
        raise CheckpointError(f"seed: {seed} not in the checkpoint's {n_seeds} seeds")
    weights = jax.tree.map(lambda x: jax.numpy.asarray(x[seed]), weights)
    actor = Actor(cfg.hidden, cfg.layers, cfg.heads, cfg.proj_attention)
    det = cfg.deterministic_eval if deterministic is None else deterministic
    return make_policy(actor, weights, det)
