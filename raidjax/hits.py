"""What a sub-step's hit events touch and read: the units each event touches (``Hits``) and the
per-unit columns a hit reads from the unit it touches (``UnitColumns``). Lane arrays: one arena's
shapes, then any lane axes (``raidjax.lanes``)."""

from __future__ import annotations

import jax
from flax import struct


@struct.dataclass
class Hits:
    """The units a group of ``n`` hit events touches (projectiles, instant skills, basic attacks), one
    type for both forms; lane axes follow every shape.

    ``unit`` is ``None``: ``hit`` is ``bool[n, U]``, every unit each event touches (areas that hit
    several). Otherwise each event touches at most one unit: ``hit`` is ``bool[n]`` (it touches one)
    and ``unit`` ``int32[n]`` (which): only that unit's dice and damage are then computed."""

    hit: jax.Array
    unit: jax.Array | None = None

    @property
    def single(self) -> bool:
        """Whether each event touches at most one unit (``unit`` given)."""
        return self.unit is not None


@struct.dataclass
class UnitColumns:
    """What a hit or a projectile reads from the unit it touches, every field ``float32[U]`` (lane
    axes follow): ``damage.unit_columns`` builds them once per sub-step, after the casts fired."""

    x: jax.Array  # position
    y: jax.Array
    cos_h: jax.Array  # heading's cosine and sine (the body's frame; a hit from behind)
    sin_h: jax.Array
    evasion: jax.Array
    agility: jax.Array
    parry: jax.Array
    armor: jax.Array  # the damage factor of armour and versatility, (1 - armor/200)(1 - versatility/200)
    team: jax.Array  # 0 players, 1 boss
