"""The generator's parameter space: which content fields it edits, within which bounds
(GAME.md §10). The paper's space is the players' skill slot 1 range, cool time, cast time and
coefficient; a user may list any skill parameters and character stats of any unit instead.

A parameter is named ``[who.][skillK.]field[=low:high]``:

- ``who``: ``players`` (every player; the default), ``boss``, a class preset name (``warrior``:
  every player of that class in the team) or ``playerI`` (player ``I``, 0-based);
- ``skillK.field``: field of skill slot ``K`` (1-based), a ``float`` field of ``content.SKILL_SPECS``
  (enums, flags and counts cannot be edited by ticks); ``field`` alone: a stat of ``content.STAT_SPECS``;
- ``=low:high``: bounds inside the field's allowed range for that unit (default: the whole range).

Whole-number stats (``max_hp``, ``armor``, ...) are rounded when they are written into content,
so every generated content is valid ``make_params`` content.

    space = parse_space(["skill1.range", "skill1.coefficient", "boss.max_hp=500:3000", "warrior.armor"],
                        players=("warrior", "mage", "priest"))
    game = space.apply(base, jnp.asarray([10.0, 0.8, 1500.0, 40.0]))
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from raidjax import catalogue
from raidjax.content import REFERENCE_PLAYERS, SKILL_SPECS, STAT_SPECS
from raidjax.types import N_SLOTS, Params

# +1 where a larger value of a *player's* field makes the raid easier for the players (a boss's
# field counts the other way). PCG-HR moves along these signs; 0: it leaves the parameter alone.
EASIER_FIELDS = {
    "range": 1, "cool_time": -1, "cast_time": -1, "coefficient": 1, "cost": -1, "projectile_speed": 1,
    "projectile_radius": 1, "max_hp": 1, "hp_regen": 1, "max_mana": 1, "mana_regen": 1, "spell_power": 1,
    "move_speed": 1, "attack_power": 1, "attack_range": 1, "attack_speed": 1, "armor": 1, "evasion": 1, "parry": 1,
    "critical": 1, "crit_multiplier": 1, "haste": 1, "versatility": 1, "mastery": 1, "back_attack_multiplier": 1,
}


@dataclasses.dataclass(frozen=True)
class Knob:
    """One edited parameter. ``units``: the unit indices it writes; ``slot``: the 0-based skill
    slot, ``None`` for a stat; ``whole``: rounded when written; ``easier``: +1 / -1 / 0."""

    name: str
    field: str
    slot: int | None
    units: tuple[int, ...]
    low: float
    high: float
    easier: int
    whole: bool


@dataclasses.dataclass(frozen=True)
class Space:
    """An ordered, hashable set of ``Knob``s (a static field of ``PCGParams``).

    Attributes (arrays of length ``K = size``): ``low``, ``high``, ``easier`` (``float32[K]``),
    ``names`` (``tuple[str]``, the parameters as written) and ``fields`` (the content fields).
    """

    knobs: tuple[Knob, ...]

    @property
    def size(self) -> int:
        """``K``, the number of edited parameters (``int``)."""
        return len(self.knobs)

    @property
    def names(self) -> tuple[str, ...]:
        """``tuple[str]`` of length ``K``: each parameter as written (``"skill1.range=1:20"``)."""
        return tuple(k.name for k in self.knobs)

    @property
    def fields(self) -> tuple[str, ...]:
        """The content field each knob writes (``"range"``, ``"max_hp"``, ...)."""
        return tuple(k.field for k in self.knobs)

    @property
    def low(self) -> np.ndarray:
        """Lower bounds, numpy ``float32[K]``."""
        return np.asarray([k.low for k in self.knobs], np.float32)

    @property
    def high(self) -> np.ndarray:
        """Upper bounds, numpy ``float32[K]``."""
        return np.asarray([k.high for k in self.knobs], np.float32)

    @property
    def easier(self) -> np.ndarray:
        """Numpy ``float32[K]`` of +1 / -1 / 0: the sign that makes the raid easier for the players
        (``EASIER_FIELDS``; 0: PCG-HR leaves the parameter alone)."""
        return np.asarray([k.easier for k in self.knobs], np.float32)

    def apply(self, game: Params, values: jax.Array) -> Params:
        """``game`` with every knob's field set to ``values`` (``float32[K]``, traced ok; whole
        stats rounded); jittable, no validation (keep values within ``low``..``high``)."""
        stats, skills = game.stats, game.skills
        for i, k in enumerate(self.knobs):
            v = jnp.round(values[i]) if k.whole else values[i]
            idx = np.asarray(k.units)
            if k.slot is None:
                arr = getattr(stats, k.field)
                stats = stats.replace(**{k.field: arr.at[idx].set(v.astype(arr.dtype))})
            else:
                arr = getattr(skills, k.field)
                skills = skills.replace(**{k.field: arr.at[idx, k.slot].set(v.astype(arr.dtype))})
        return game.replace(stats=stats, skills=skills)


def parse_knob(text: str, players: Sequence[str]) -> Knob:
    """One parameter name (module docstring) for a team of ``players`` (class names), checked;
    raises ``ValueError`` naming the parameter, what is wrong and what is allowed."""
    if not isinstance(text, str):
        raise ValueError(f"parameters: {text!r} is a {type(text).__name__}; allowed: a name such as 'skill1.range'")
    name, _, bounds = text.partition("=")
    parts = name.split(".")
    n = len(players)
    who = "players"
    if parts[0] == "boss" or parts[0] == "players" or parts[0] in catalogue.CLASSES or (
            parts[0].startswith("player") and parts[0][6:].isdigit()):
        who, parts = parts[0], parts[1:]
    if who == "players":
        units = tuple(range(n))
    elif who == "boss":
        units = (n,)
    elif who in catalogue.CLASSES:
        units = tuple(i for i, c in enumerate(players) if c == who)
        if not units:
            raise ValueError(f"parameters: {text!r}: no {who} in the team {list(players)}")
    else:
        i = int(who[6:])
        if not 0 <= i < n:
            raise ValueError(f"parameters: {text!r}: player {i} not in 0..{n - 1}")
        units = (i,)
    team = 1 if who == "boss" else 0
    allowed = ("[who.][skillK.]field[=low:high] with who in players, boss, a class or playerI, "
               "field a stat or a float skill parameter")
    if len(parts) == 1 and parts[0] in STAT_SPECS:
        field, slot, spec = parts[0], None, STAT_SPECS[parts[0]]
    elif (len(parts) == 2 and parts[0].startswith("skill") and parts[0][5:].isdigit()
          and parts[1] in SKILL_SPECS and 1 <= int(parts[0][5:]) <= N_SLOTS):
        field, slot, spec = parts[1], int(parts[0][5:]) - 1, SKILL_SPECS[parts[1]]
        if spec[0] != "float":
            raise ValueError(f"parameters: {text!r}: skill field {field!r} is a {spec[0]}; allowed: a float "
                             f"skill parameter ({sorted(k for k, s in SKILL_SPECS.items() if s[0] == 'float')})")
    else:
        raise ValueError(f"parameters: {text!r} is not a parameter; allowed: {allowed}")
    lo, hi = spec[1 + team]
    if bounds:
        try:
            lo2, hi2 = (float(b) for b in bounds.split(":"))
        except ValueError:
            raise ValueError(f"parameters: {text!r}: bounds {bounds!r} must be low:high numbers") from None
        if not lo <= lo2 < hi2 <= hi:
            raise ValueError(f"parameters: {text!r}: bounds {lo2:g}:{hi2:g} must satisfy "
                             f"{lo:g} <= low < high <= {hi:g}")
        lo, hi = lo2, hi2
    easier = EASIER_FIELDS.get(field, 0) * (-1 if who == "boss" else 1)
    return Knob(text, field, slot, units, float(lo), float(hi), easier, spec[0] == "int")


def parse_space(parameters: Sequence[str], players: Sequence[str] = REFERENCE_PLAYERS) -> Space:
    """A ``Space`` from parameter names (module docstring) for a team of ``players``; raises
    ``ValueError`` for an empty or repeated list or a bad name."""
    if isinstance(parameters, str) or not len(parameters):
        raise ValueError(f"parameters: {parameters!r}; allowed: a non-empty list of names such as 'skill1.range'")
    knobs = tuple(parse_knob(p, tuple(players)) for p in parameters)
    seen = [(k.field, k.slot, u) for k in knobs for u in k.units]
    if len(seen) != len(set(seen)):
        raise ValueError(f"parameters: {list(parameters)} edit one field of one unit twice")
    return Space(knobs)


# The paper's space (GAME.md §10): the players' skill slot 1, with the reference generator's bounds.
PAPER_PARAMETERS = ("skill1.range=1:20", "skill1.cool_time=0.5:0.6", "skill1.cast_time=0.5:1.5",
                    "skill1.coefficient=0.5:1")
PAPER_SPACE = parse_space(PAPER_PARAMETERS)


def make_space(parameters: Sequence[str] | None = None, players: Sequence[str] = REFERENCE_PLAYERS) -> Space:
    """``parse_space(parameters, players)``, or with no parameters (``None`` or empty) the paper's
    four, which only a team of three mages has; raises ``ValueError`` naming what is wrong."""
    if parameters:
        return parse_space(parameters, players)
    if tuple(players) != REFERENCE_PLAYERS:
        raise ValueError(f"parameters: none given with the team {list(players)}: the paper's four edit the skill "
                         "slot 1 of three mages; name the parameters for another team (e.g. 'mage.skill1.range=1:20', "
                         "'warrior.skill1.coefficient')")
    return PAPER_SPACE


def low(space: Space = PAPER_SPACE) -> jax.Array:
    """Lower bounds ``float32[K]`` of ``space`` (default the paper's four)."""
    return jnp.asarray(space.low)


def high(space: Space = PAPER_SPACE) -> jax.Array:
    """Upper bounds ``float32[K]`` of ``space`` (default the paper's four)."""
    return jnp.asarray(space.high)


def tick(space: Space = PAPER_SPACE) -> jax.Array:
    """One tick per parameter, ``(max - min) / 6``: ``float32[K]``."""
    return (high(space) - low(space)) / 6.0
