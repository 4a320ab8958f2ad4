"""Building and validating content (``Params``): field ranges, defaults and ``make_params``.

Validation happens here, on the host, when parameters are built: out-of-range, NaN, wrongly
shaped or unknown content, and values of the wrong Python type (a ``str`` or ``bool`` for a
number, ``None``, a list for a scalar), raise a one-line ``ValueError`` naming the field, the
value and what is allowed (helpers in ``raidjax.validate``). The jitted step never clips content
silently.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import fields

import jax.numpy as jnp
import numpy as np

from raidjax import catalogue, validate
from raidjax.types import N_SLOTS, SENSES, EnvConfig, Params, Skills, Stats

# name: (kind, player range, boss range, player default, boss default).
# kind "int" values must be whole numbers. Neutral values reproduce the reference game.
STAT_SPECS: dict[str, tuple] = {
    "max_hp": ("int", (0, 1000), (0, 10000), 100, 1000),
    "hp_regen": ("float", (0, 100), (0, 100), 0.0, 0.0),
    "max_mana": ("int", (0, 100), (0, 100), 100, 100),
    "mana_regen": ("float", (0, 100), (0, 100), 1.0, 1.0),
    "spell_power": ("int", (0, 100), (0, 100), 100, 50),
    "move_speed": ("float", (1, 2), (0, 20), 1.0, 6.0),
    "attack_power": ("int", (0, 100), (0, 100), 0, 0),
    "attack_range": ("int", (1, 10), (1, 10), 1, 1),
    "attack_speed": ("float", (1, 2), (1, 2), 1.0, 1.0),
    "armor": ("int", (0, 100), (0, 100), 0, 0),
    "evasion": ("int", (0, 100), (0, 100), 0, 0),
    "parry": ("float", (0, 100), (0, 100), 0.0, 0.0),
    "strength": ("int", (1, 100), (1, 100), 50, 50),
    "agility": ("int", (1, 100), (1, 100), 50, 50),
    "intelligence": ("int", (1, 100), (1, 100), 50, 50),
    "critical": ("int", (0, 100), (0, 100), 0, 0),
    "crit_multiplier": ("float", (1, 5), (1, 5), 1.5, 1.5),
    "haste": ("int", (0, 100), (0, 100), 0, 0),
    "versatility": ("int", (0, 100), (0, 100), 0, 0),
    "mastery": ("int", (0, 100), (0, 100), 0, 0),
    "back_attack_multiplier": ("float", (1, 3), (1, 3), 1.2, 1.0),
    # Reference colliders (docs/GAME.md "Geometry"): a player's 1 x 1 box, the dragon's 2.25 box.
    "radius": ("float", (0.1, 3), (0.1, 3), 0.5, 1.125),
}

# name: (kind, player range, boss range). Defaults live in catalogue.BASE_SKILL.
SKILL_SPECS: dict[str, tuple] = {
    "in_use": ("bool", (0, 1), (0, 1)),
    "trigger": ("int", (0, 1), (0, 1)),
    "school": ("int", (0, 9), (0, 9)),
    "hit_type": ("int", (0, 1), (0, 1)),
    "target_type": ("int", (0, 2), (0, 2)),
    "projectile_speed": ("float", (0, 50), (0, 50)),
    "affect_ally": ("bool", (0, 1), (0, 1)),
    "affect_enemy": ("bool", (0, 1), (0, 1)),
    "cool_time": ("float", (0, 60), (0, 60)),
    "cast_time": ("float", (0, 2), (0, 10)),
    "cost": ("float", (0, 100), (0, 100)),
    "range": ("float", (1, 20), (1, 20)),
    "charge": ("int", (1, 3), (1, 3)),
    "cast_on_moving": ("bool", (0, 1), (0, 1)),
    "cast_on_casting": ("bool", (0, 1), (0, 1)),
    "cast_on_channeling": ("bool", (0, 1), (0, 1)),
    "coefficient": ("float", (0, 2), (0, 2)),
    "projectile_radius": ("float", (0.05, 5), (0.05, 5)),
    "hit_count": ("int", (1, 8), (1, 8)),
    "area_offset": ("float", (0, 1), (0, 1)),
}
_INT_KINDS = ("int", "bool")
assert set(STAT_SPECS) == {f.name for f in fields(Stats)}
assert set(SKILL_SPECS) == {f.name for f in fields(Skills)}

REFERENCE_PLAYERS = ("mage", "mage", "mage")


def _unit_dicts(cls_name: str, table: Mapping, team: int) -> tuple[dict, list[dict]]:
    preset = table[cls_name]  # the name was checked by make_params
    col = 3 if team == 0 else 4
    stats = {k: spec[col] for k, spec in STAT_SPECS.items()}
    stats.update(preset["stats"])
    slots = [catalogue.skill_fields(s) for s in preset["skills"]]
    while len(slots) < N_SLOTS:  # unused slots: valid values, masked out
        slots.append({**catalogue.BASE_SKILL, "in_use": 0})
    return stats, slots


def _number(field: str, value, spec: tuple, team: int, who: str) -> float:
    """``value`` as a float if it is a real number (0/1 flags may be ``bool``), else one line naming
    ``field``, the value and the allowed range of ``spec`` for ``team`` (0 players, 1 the boss)."""
    kind, (lo, hi) = spec[0], spec[1 + team]
    allowed = {"float": f"a number in [{lo}, {hi}]", "int": f"a whole number in [{lo}, {hi}]"}
    allowed = allowed.get(kind, "0 or 1 (or a bool)")
    try:
        return validate.number(field, value, allowed, allow_bool=kind == "bool")
    except ValueError:
        if who == "make_params":
            raise
        raise validate.fail(field, value, allowed, f"{validate.kind_of(value)} in {who}") from None


def _apply_override(key: str, value, stats: dict, slots: list[dict], who: str, team: int = 0) -> None:
    if not isinstance(key, str):
        raise validate.fail(f"{who}: key", key, "a field name (a str)")
    if key in STAT_SPECS:
        stats[key] = _number(key, value, STAT_SPECS[key], team, who)
        return
    head, _, field = key.partition(".")
    if head.startswith("skill") and head[5:].isdigit() and field in SKILL_SPECS:
        k = int(head[5:])
        if not 1 <= k <= N_SLOTS:
            raise ValueError(f"{who}: override {key!r}: skill slot {k} not in [1, {N_SLOTS}]")
        slots[k - 1][field] = _number(key, value, SKILL_SPECS[field], team, who)
        return
    if head.startswith("skill") and head[5:].isdigit() and not field and 1 <= int(head[5:]) <= N_SLOTS:
        slots[int(head[5:]) - 1] = catalogue.skill_fields(validate.name(key, value, catalogue.SKILLS, "skill preset"))
        return
    if key in {f.name for f in fields(EnvConfig)}:
        raise ValueError(f"{who}: unknown field {key!r} (value {validate.show(value)}); it is an EnvConfig "
                         f"field: pass config=raidjax.EnvConfig({key}=...)")
    raise ValueError(
        f"{who}: unknown field {key!r} (value {validate.show(value)}); use a stat ({', '.join(STAT_SPECS)}), "
        f"'skill<k>.<param>' with param in ({', '.join(SKILL_SPECS)}), or 'skill<k>' = a skill preset"
    )


def player_names(players) -> list[str]:
    """The class preset names of ``players`` (a name means a team of 3), checked (one ``ValueError``
    line naming the value); plain Python, so a config can check its team before JAX starts."""
    allowed = f"a class preset name or a list of 1 to 8 of them, from {sorted(catalogue.CLASSES)}"
    if isinstance(players, str):
        return [validate.name("players", players, catalogue.CLASSES, "class preset")] * 3
    if not isinstance(players, Sequence):
        raise validate.fail("players", players, allowed)
    if not 1 <= len(players) <= 8:
        raise validate.fail("players", players, allowed, f"{len(players)} players")
    return [validate.name(f"players[{i}]", n, catalogue.CLASSES, "class preset") for i, n in enumerate(players)]


def _override_maps(player_overrides, boss_overrides, n_players: int) -> tuple[list[Mapping], Mapping]:
    """``player_overrides`` (``None`` or one mapping per player) and ``boss_overrides`` (``None`` or a
    mapping), checked; ``None`` becomes empty mappings."""
    allowed = f"None or a list of {n_players} mappings (one per player) of field overrides"
    if player_overrides is None:
        per_player = [{}] * n_players
    elif isinstance(player_overrides, str | Mapping) or not isinstance(player_overrides, Sequence):
        raise validate.fail("player_overrides", player_overrides, allowed)
    elif len(player_overrides) != n_players:
        raise validate.fail("player_overrides", player_overrides, allowed, f"{len(player_overrides)} mappings")
    else:
        per_player = list(player_overrides)
    for i, m in enumerate(per_player):
        if not isinstance(m, Mapping):
            raise validate.fail(f"player_overrides[{i}]", m, "a mapping of field overrides, e.g. {'armor': 50}")
    if boss_overrides is not None and not isinstance(boss_overrides, Mapping):
        raise validate.fail("boss_overrides", boss_overrides, "None or a mapping of field overrides, e.g. {'armor': 5}")
    return per_player, boss_overrides or {}


def make_params(
    *,
    players: str | Sequence[str] = REFERENCE_PLAYERS,
    boss: str = "dragon",
    skill_range: float | None = None,
    player_overrides: Sequence[Mapping] | None = None,
    boss_overrides: Mapping | None = None,
    config: EnvConfig | None = None,
    rules: str | None = None,
    observation: str | None = None,
    action_space: str | None = None,
    **overrides,
) -> Params:
    """Build and validate the content of one arena.

    Args:
        players: class preset names, one per player (or one name for a team of 3); see
            ``catalogue.CLASSES``. Default: three reference mages.
        boss: boss preset name (``catalogue.BOSSES``).
        skill_range: if given, the range of every player's skill slot 1 (the experiment variable).
        player_overrides: one mapping per player of field overrides (see ``overrides``).
        boss_overrides: field overrides for the boss.
        config: static ``EnvConfig`` (sub-steps, pool sizes, episode length, rule switches);
            default ``EnvConfig()``, the ``"reference"`` rules at 5 sub-steps.
        rules: a named rule set, ``"reference"`` (the game the paper measured) or ``"clean"``
            (the intended game); sets every rule switch of ``config``, keeping its other fields.
        observation: ``"raidjax"`` or ``"reference"`` (the reference players' senses); sets
            ``config.observation``.
        action_space: ``"raidjax"`` or ``"reference"`` (the reference's 8 unmasked actions); sets
            ``config.action_space``.
        **overrides: applied to every player: a stat name (``armor=50``), a skill parameter of
            slot k as ``**{"skill1.cool_time": 1.0}``, or ``skill2="heal"`` to put a skill preset in a slot.

    Returns:
        ``Params`` with stats ``[U]`` and skills ``[U, 3]``, ``U = n_players + 1``.

    Raises:
        ValueError: one line naming the field, the value and what is allowed, on the host before
            anything compiles: an unknown preset, field or rule set; a value of the wrong type
            (numbers are Python ``int``/``float`` or 0-d numpy/JAX numbers, never a ``str``,
            ``bool``, ``None`` or list; ``players`` a name or a list of names; ``boss`` a name;
            ``player_overrides`` a list of mappings; ``boss_overrides`` a mapping; ``config`` an
            ``EnvConfig``); a value that is NaN, not a whole number where one is required, or
            outside its allowed range.
    """
    names = player_names(players)
    validate.name("boss", boss, catalogue.BOSSES, "boss preset")
    per_player, boss_map = _override_maps(player_overrides, boss_overrides, len(names))
    if skill_range is not None:
        skill_range = _number("skill_range", skill_range, SKILL_SPECS["range"], 0, "make_params")
    config = check_config(EnvConfig() if config is None else config, rules)
    senses = {k: v for k, v in (("observation", observation), ("action_space", action_space)) if v is not None}
    config = config.replace(**senses) if senses else config
    units = []
    for i, name in enumerate(names):
        stats, slots = _unit_dicts(name, catalogue.CLASSES, 0)
        if skill_range is not None:
            slots[0]["range"] = skill_range
        for key, value in overrides.items():
            _apply_override(key, value, stats, slots, "make_params")
        for key, value in per_player[i].items():
            _apply_override(key, value, stats, slots, f"player_overrides[{i}]")
        units.append((stats, slots))
    stats, slots = _unit_dicts(boss, catalogue.BOSSES, 1)
    for key, value in boss_map.items():
        _apply_override(key, value, stats, slots, "boss_overrides", team=1)
    units.append((stats, slots))

    stat_arrays = {k: np.array([u[0][k] for u in units], dtype=np.float64) for k in STAT_SPECS}
    skill_arrays = {
        k: np.array([[s[k] for s in u[1]] for u in units], dtype=np.float64) for k in SKILL_SPECS
    }
    team = np.array([0] * len(names) + [1], dtype=np.int32)
    params = Params(
        stats=Stats(**{k: jnp.asarray(v, jnp.float32) for k, v in stat_arrays.items()}),
        skills=Skills(**{k: jnp.asarray(v, _dtype(SKILL_SPECS[k][0])) for k, v in skill_arrays.items()}),
        team=jnp.asarray(team),
        config=config,
    )
    validate_params(params, _raw=(stat_arrays, skill_arrays))
    return params


def check_config(config: EnvConfig, rules: str | None = None) -> EnvConfig:
    """Check that ``config`` is an ``EnvConfig`` and apply the named ``rules``, on the host, before
    anything compiles. Its fields were validated when it was built (``EnvConfig.__post_init__``).

    Args:
        config: an ``EnvConfig``. rules: ``None`` or a rule set name (``RULE_SETS``).

    Returns:
        The ``EnvConfig``, with every rule switch set as in ``rules`` when given.

    Raises:
        ValueError: ``config`` is not an ``EnvConfig`` or ``rules`` not a rule set (one line naming
            the field, the value and what is allowed).
    """
    if not isinstance(config, EnvConfig):
        raise validate.fail("config", config, "None or an EnvConfig (EnvConfig(...), EnvConfig.from_rules(...))")
    return config if rules is None else config.with_rules(rules)


def _dtype(kind: str):
    return jnp.int32 if kind in _INT_KINDS else jnp.float32


def with_player_skill(params: Params, slot: int = 0, **fields) -> Params:
    """Set skill fields of every player's skill slot ``slot`` (0-based); jittable, no validation.

    For sweeps inside ``jit``/``vmap`` (e.g. a traced skill range per arena). Values are not
    checked here: build the base with ``make_params`` and keep edits inside the ranges of
    ``SKILL_SPECS`` (``validate_params`` checks concrete results).

    Args:
        params: one arena's ``Params`` (skills ``[U, S]``).
        slot: skill slot index, a whole number in ``[0, S)`` (static).
        **fields: skill field name -> a value of the field's dtype (``float32``, or ``int32`` for
            the integer fields), a scalar ``[]`` (every player) or ``[P]`` (one per player); traced
            values are fine.

    Returns:
        ``Params`` with ``skills.<field>[:P, slot]`` replaced.

    Raises:
        ValueError: an unknown skill field, a slot outside ``[0, S)`` or a value of another shape
            (one line naming it).
    """
    unknown = set(fields) - set(SKILL_SPECS)
    if unknown:
        raise ValueError(f"with_player_skill: unknown skill field(s) {sorted(unknown)}; known: {list(SKILL_SPECS)}")
    n_players = params.team.shape[-1] - 1
    n_slots = params.skills.in_use.shape[-1]
    allowed = f"a whole number in [0, {n_slots}) (0-based skill slot)"
    slot = validate.whole_number("slot", slot, 0, allowed)
    if slot >= n_slots:
        raise ValueError(f"slot: value {slot} is too large; allowed: {allowed}")
    for k, v in fields.items():
        if jnp.shape(v) not in ((), (n_players,)):
            raise ValueError(f"{k}: value of shape {list(jnp.shape(v))}; allowed: a scalar or one value per player "
                             f"(shape [{n_players}])")
    sk = params.skills
    new = {k: getattr(sk, k).at[:n_players, slot].set(jnp.asarray(v, getattr(sk, k).dtype)) for k, v in fields.items()}
    return params.replace(skills=sk.replace(**new))


def with_senses(params: Params, senses: str) -> Params:
    """``params`` whose players observe and act as ``senses`` names: ``"raidjax"`` (raidjax's
    observation and 10 masked actions) or ``"reference"`` (the reference player's observation and
    its 8 actions). Only the static ``config`` changes; works on batched and traced params.

    Raises:
        ValueError: ``senses`` not one of those names (one line).
    """
    validate.name("senses", senses, SENSES, "observation and action space")
    if params.config.observation == senses and params.config.action_space == senses:
        return params
    return params.replace(config=params.config.replace(observation=senses, action_space=senses))


def sensed_by(params: Params, policy: Callable) -> Params:
    """``params`` played with the senses ``policy`` declares: a policy object with a ``senses``
    attribute (``"raidjax"`` or ``"reference"``, e.g. a trained ``trainers.mapoca.TeamPolicy``)
    observes and acts that way whatever the content's config says (``raidjax.with_senses``);
    other policies play the content as it is."""
    senses = getattr(policy, "senses", None)
    return params if senses is None else with_senses(params, senses)


def default_params() -> Params:
    """The reference content (three mages with MagicMissile, range 5, against the Dragon).

    Returns:
        ``Params`` with ``U = 4`` units (stats ``[4]``, skills ``[4, 3]``).
    """
    return make_params()


def _check(name: str, values: np.ndarray, kind: str, lo: float, hi: float, where: str) -> None:
    bad = ~np.isfinite(values)
    if bad.any():
        raise ValueError(f"{name}: value {values[bad].flat[0]} at {where} is not finite; allowed range [{lo}, {hi}]")
    out = (values < lo) | (values > hi)
    if out.any():
        raise ValueError(f"{name}: value {values[out].flat[0]:g} at {where} is outside the allowed range [{lo}, {hi}]")
    if kind in _INT_KINDS and (values != np.round(values)).any():
        v = values[values != np.round(values)].flat[0]
        raise ValueError(f"{name}: value {v:g} at {where} must be a whole number in [{lo}, {hi}]")


def validate_params(params: Params, _raw: tuple | None = None) -> Params:
    """Check every field of (possibly batched) concrete ``params``; return them unchanged.

    Args:
        params: ``Params`` with stats ``[..., U]``, skills ``[..., U, 3]``, ``team[..., U]``.

    Raises:
        ValueError: naming the field, the offending value and the allowed range, for NaN,
            out-of-range, non-integral or wrongly shaped fields.
    """
    team = np.asarray(params.team)
    if team.ndim < 1 or team.shape[-1] < 2:
        raise ValueError(f"team: shape {team.shape}; expected [..., U] with U >= 2")
    batch, u = team.shape[:-1], team.shape[-1]
    expected_team = np.array([0] * (u - 1) + [1])
    if not (team == expected_team).all():
        raise ValueError(f"team: value {team.tolist()} must be {expected_team.tolist()} (players, then the boss)")
    stat_raw, skill_raw = _raw or ({}, {})
    for specs, group, shape, raw, axis in (
        (STAT_SPECS, params.stats, (*batch, u), stat_raw, -1),
        (SKILL_SPECS, params.skills, (*batch, u, N_SLOTS), skill_raw, -2),
    ):
        for name, spec in specs.items():
            arr = raw[name] if name in raw else np.asarray(getattr(group, name), np.float64)
            if arr.shape != shape:
                raise ValueError(f"{name}: shape {arr.shape}; expected {shape}")
            kind, prange, brange = spec[0], spec[1], spec[2]
            players, boss = np.split(arr, [u - 1], axis=axis)
            _check(name, players, kind, *prange, "a player")
            _check(name, boss, kind, *brange, "the boss")
    skills = params.skills
    in_use = np.asarray(skills.in_use)
    if not in_use[..., :, 0].all():
        raise ValueError("in_use: value 0 in skill slot 1; every unit needs a skill in slot 1")
    return params
