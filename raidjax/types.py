"""Pytrees of the boss-raid simulator: content (``Params``), dynamic ``State``, ``Observation``.

Units are stored in one axis of size ``U = n_players + 1``: players first, the boss last
(index ``n_players``). Every unit has ``S = 3`` skill slots; ``Skills.in_use`` masks the
slots a unit actually has. All static sizes come from array shapes or from the small
static ``EnvConfig`` carried (as non-pytree metadata) inside ``Params``.
"""

from __future__ import annotations

import dataclasses
import functools

import jax
from flax import struct

from raidjax import validate

# The game's constants (GAME.md §1, §8).
TICK = 0.02  # physics tick of the reference build (s)
TICKS_PER_DECISION = 5  # the reference's decision period: 5 ticks of 0.02 s
HALF_ARENA = 12.25  # walls at x, y = +-HALF_ARENA
DAMAGE_REWARD = 0.01  # reward per point of damage a player's hits deal to the boss
WIN_REWARD = 1.0  # reward to every player when the boss dies

N_SLOTS = 3  # skill slots per unit
# Discrete actions of a player (GAME.md §4). Casting slot k is action 7 + k.
NOOP, FORWARD, BACKWARD, ROTATE_LEFT, ROTATE_RIGHT, STRAFE_LEFT, STRAFE_RIGHT = range(7)
CAST_1 = 7
N_ACTIONS = CAST_1 + N_SLOTS  # 10; slots not in use are masked
# Reserved id: the player is driven by the built-in scripted heuristic (PT-HR, GAME.md §9) this
# decision. It moves by setting positions, which no learner action can express.
ACTION_HEURISTIC = N_ACTIONS

# The reference player's action space (``EnvConfig(action_space="reference")``): one branch of 8,
# no mask (RaidPlayerAgent.cs, GAME.md §4). Reference id k plays raidjax action REFERENCE_ACTIONS[k]:
# the reference's 3 turns clockwise seen from above (right) and 4 anticlockwise, the reverse of ours.
REFERENCE_ACTIONS = (NOOP, FORWARD, BACKWARD, ROTATE_RIGHT, ROTATE_LEFT, STRAFE_LEFT, STRAFE_RIGHT, CAST_1)
# The players' senses, what they observe (``EnvConfig.observation``) and how they act
# (``EnvConfig.action_space``): raidjax's own (the default) or the reference build's (GAME.md §8).
SENSES = ("raidjax", "reference")

# Outcomes (``State.result`` / ``info["result"]``).
RUNNING, WIN, LOSS, DRAW = 0, 1, 2, 3

# Skill enums.
HIT_ATTACK, HIT_SPELL = 0, 1
TARGET_NONE, TARGET_UNIT, TARGET_REGION = 0, 1, 2  # straight missile / homing / area
TRIGGER_ACTIVE, TRIGGER_PASSIVE = 0, 1
# Projectile kinds in the pool.
PROJ_HOMING, PROJ_STRAIGHT, PROJ_AREA = 0, 1, 2


# Rule switches of ``EnvConfig`` (docs/GAME.md, "Rule sets", cites the reference source of each).
RULE_SWITCHES = (
    "carry_cooldowns", "keep_dead_target", "reset_exception", "one_step_area", "unity_timers", "ties_are_losses",
)
# Named rule sets: "reference" is the game the RaidEnv paper measured (the 2023 reference build,
# quirks included); "clean" is the intended game (independent episodes, exact timers).
RULE_SETS = {
    "reference": dict.fromkeys(RULE_SWITCHES, True),
    "clean": dict.fromkeys(RULE_SWITCHES, False),
}


@struct.dataclass
class EnvConfig:
    """Static configuration (hashable; not a pytree leaf, so it never enters a vmap).

    The defaults are the ``"reference"`` rule set at the reference's 0.02 s tick. Build other
    rule sets with ``EnvConfig.from_rules("clean")`` or ``make_params(rules="clean")``; every
    rule switch can also be set alone (``EnvConfig(carry_cooldowns=False)``) for ablations.

    Attributes:
        n_substeps: simulation sub-steps per 0.1 s decision: 5 (the reference's 0.02 s tick) or 1.
        max_projectiles: size M of the projectile pool of each arena.
        obs_projectiles: K, number of nearest hostile projectiles each player observes.
        max_decisions: episode limit in decisions (2000 = 200 s).
        carry_cooldowns: a cooldown timer running when an episode ends keeps running in the
            arena's next episode (``next_episode``) and then adds a charge with no cap; units that
            died (were deactivated) lose their timers.
        keep_dead_target: the boss chases, aims and casts at its target after it died, until its
            next skill fires (then it re-picks the nearest alive player).
        reset_exception: when any projectile is in flight at an episode's end, the boss starts
            the next episode where it ended and every in-flight projectile but the first (lowest
            pool slot) keeps flying.
        one_step_area: an area (the boss's slash) exists for one 0.02 s tick and hits at most one
            unit (the nearest inside it); otherwise it lingers 5 ticks and hits up to ``hit_count``.
        unity_timers: cast and cooldown timers count down by float32 ``-= 0.02`` once per tick and
            fire on the first tick they are below 0 (0.1 s lasts 6 ticks, 1.0 s 51); otherwise a
            timer of T seconds lasts exactly T.
        ties_are_losses: the boss and the last player dying in the same tick is a loss (else a win).
        random_spawns: every episode draws each unit's position and heading (players in the
            arena's lower half, the boss in its upper half, inside the walls; headings uniform)
            instead of the fixed spawn; off in both rule sets (the reference spawns are fixed).
        observation: ``"raidjax"`` (``Observation``, the default) or ``"reference"``
            (``ReferenceObservation``: the reference players' rays, teammate buffer and stacked
            vector, 204 floats for 3 players); not a rule switch: it changes what players see, not the game.
        action_space: ``"raidjax"`` (``N_ACTIONS`` = 10 ids with an action mask, the default) or
            ``"reference"`` (8 ids, ``REFERENCE_ACTIONS``, an all-true mask: the reference masks nothing).

    Raises:
        ValueError: on construction (``EnvConfig(...)``, ``replace``, ``from_rules``), one line naming
            the field, the value and what is allowed: ``n_substeps`` not 1 or 5; a pool size or
            ``max_decisions`` not a whole number >= 1 (``int`` or numpy integer; no ``float``,
            ``str`` or ``bool``); ``obs_projectiles > max_projectiles``; a rule switch not a
            ``bool``; ``observation`` or ``action_space`` not one of their names; an unknown field name.
    """

    # Every field is static (``pytree_node=False``): an ``EnvConfig`` has no leaves, so tree maps
    # pass it through unchanged and never rebuild it from placeholder leaves.
    n_substeps: int = struct.field(pytree_node=False, default=5)
    max_projectiles: int = struct.field(pytree_node=False, default=16)
    obs_projectiles: int = struct.field(pytree_node=False, default=4)
    max_decisions: int = struct.field(pytree_node=False, default=2000)
    carry_cooldowns: bool = struct.field(pytree_node=False, default=True)
    keep_dead_target: bool = struct.field(pytree_node=False, default=True)
    reset_exception: bool = struct.field(pytree_node=False, default=True)
    one_step_area: bool = struct.field(pytree_node=False, default=True)
    unity_timers: bool = struct.field(pytree_node=False, default=True)
    ties_are_losses: bool = struct.field(pytree_node=False, default=True)
    random_spawns: bool = struct.field(pytree_node=False, default=False)
    observation: str = struct.field(pytree_node=False, default="raidjax")
    action_space: str = struct.field(pytree_node=False, default="raidjax")

    def __post_init__(self):
        """Validate every field on construction (``EnvConfig(...)``, ``replace``, ``from_rules``),
        on the host, before anything compiles; numpy integers and bools become Python ones.

        Raises:
            ValueError: one line naming the field, the value and what is allowed.
        """
        n = validate.whole_number("n_substeps", self.n_substeps, 1, "1 or 5 (sub-steps per 5-tick decision)")
        if n not in (1, 5):
            raise ValueError(f"n_substeps: value {n!r}; allowed: 1 or 5 (sub-steps per 5-tick decision)")
        fixed = {"n_substeps": n}
        for name in ("max_projectiles", "obs_projectiles", "max_decisions"):
            fixed[name] = validate.whole_number(name, getattr(self, name), 1)
        if fixed["obs_projectiles"] > fixed["max_projectiles"]:
            raise ValueError(f"obs_projectiles: value {fixed['obs_projectiles']} exceeds max_projectiles "
                             f"{fixed['max_projectiles']}; allowed: a whole number in [1, max_projectiles]")
        for name in (*RULE_SWITCHES, "random_spawns"):
            fixed[name] = validate.flag(name, getattr(self, name))
        validate.name("observation", self.observation, SENSES, "observation")
        validate.name("action_space", self.action_space, SENSES, "action space")
        for name, value in fixed.items():  # frozen: set through object (hash and == see Python values)
            object.__setattr__(self, name, value)

    @classmethod
    def from_rules(cls, rules: str = "reference", **fields) -> EnvConfig:
        """The named rule set (``"reference"`` or ``"clean"``), then ``fields`` on top.

        Raises:
            ValueError: an unknown rule set, or a field as in ``EnvConfig``.
        """
        return cls().with_rules(rules).replace(**fields)

    def with_rules(self, rules: str) -> EnvConfig:
        """This config with every rule switch set as in the named rule set; other fields kept.

        Raises:
            ValueError: ``rules`` not a ``str`` naming a rule set of ``RULE_SETS``.
        """
        validate.name("rules", rules, RULE_SETS, "rule set")
        return self.replace(**RULE_SETS[rules])

    @property
    def rules(self) -> str:
        """``"reference"``, ``"clean"`` or ``"custom"`` (any other mix of switches)."""
        mine = {k: getattr(self, k) for k in RULE_SWITCHES}
        return next((name for name, preset in RULE_SETS.items() if preset == mine), "custom")

    @property
    def n_actions(self) -> int:
        """Learner action ids per player: 10 (``"raidjax"``) or 8 (``"reference"``)."""
        return N_ACTIONS if self.action_space == "raidjax" else len(REFERENCE_ACTIONS)

    @property
    def chains_episodes(self) -> bool:
        """Whether an arena's episodes depend on the one before (``next_episode`` differs from ``reset``)."""
        return bool(self.carry_cooldowns or self.reset_exception)


def _reject_unknown_fields(cls):
    """Make ``cls(...)`` (and so ``replace``) raise a one-line ``ValueError`` naming an unknown field
    and the known ones, instead of ``TypeError: unexpected keyword argument``."""
    known = [f.name for f in dataclasses.fields(cls)]
    init = cls.__init__

    @functools.wraps(init)
    def checked_init(self, *args, **kwargs):
        bad = next((k for k in kwargs if k not in known), None)
        if bad is not None:
            raise ValueError(f"{cls.__name__}: unknown field {bad!r} (value {validate.show(kwargs[bad])}); "
                             f"allowed fields: {', '.join(known)}")
        init(self, *args, **kwargs)

    cls.__init__ = checked_init
    return cls


_reject_unknown_fields(EnvConfig)


@struct.dataclass
class Stats:
    """Character statistics, every field ``float32[U]`` (GAME.md §3; ranges in ``content.STAT_SPECS``)."""

    max_hp: jax.Array
    hp_regen: jax.Array  # HP per second
    max_mana: jax.Array
    mana_regen: jax.Array  # mana per second
    spell_power: jax.Array
    move_speed: jax.Array  # player: impulse per tick; boss: chase speed (units/s)
    attack_power: jax.Array  # base of hit-type "attack" damage and of the basic attack
    attack_range: jax.Array  # reach of the basic melee attack
    attack_speed: jax.Array  # basic attacks per second
    armor: jax.Array
    evasion: jax.Array
    parry: jax.Array
    strength: jax.Array
    agility: jax.Array
    intelligence: jax.Array
    critical: jax.Array
    crit_multiplier: jax.Array
    haste: jax.Array
    versatility: jax.Array
    mastery: jax.Array
    back_attack_multiplier: jax.Array
    radius: jax.Array  # collision radius


@struct.dataclass
class Skills:
    """Skill parameters, every field of shape ``[U, S]`` (GAME.md §3; ranges in ``content.SKILL_SPECS``).

    Enums and booleans are stored as ``int32``; everything else ``float32``.
    """

    in_use: jax.Array  # bool-like int32: the slot holds a skill
    trigger: jax.Array  # TRIGGER_ACTIVE / TRIGGER_PASSIVE
    school: jax.Array  # cosmetic, 0..9
    hit_type: jax.Array  # HIT_ATTACK / HIT_SPELL
    target_type: jax.Array  # TARGET_NONE / TARGET_UNIT / TARGET_REGION
    projectile_speed: jax.Array  # 0 = instant
    affect_ally: jax.Array
    affect_enemy: jax.Array
    cool_time: jax.Array
    cast_time: jax.Array
    cost: jax.Array
    range: jax.Array
    charge: jax.Array  # int32, 1..3
    cast_on_moving: jax.Array
    cast_on_casting: jax.Array
    cast_on_channeling: jax.Array
    coefficient: jax.Array
    # Delivery details (not in the paper's table; raidjax makes them data too).
    projectile_radius: jax.Array  # missile collision radius, or area radius for regions
    hit_count: jax.Array  # int32: units an area can hit
    area_offset: jax.Array  # region centre = caster + offset * (target - caster)


@struct.dataclass
class Params:
    """The content of one arena. Batch it (leading axes) to give every arena its own content."""

    stats: Stats
    skills: Skills
    team: jax.Array  # int32[U]: 0 players, 1 boss
    config: EnvConfig = struct.field(pytree_node=False, default_factory=EnvConfig)

    def __post_init__(self):
        # ``config`` is static metadata: a wrong type would fail deep inside the traced step.
        if not isinstance(self.config, EnvConfig):
            raise validate.fail("config", self.config, "an EnvConfig (raidjax.EnvConfig(...) or EnvConfig.from_rules)")


@struct.dataclass
class Projectiles:
    """The projectile pool, ``M = config.max_projectiles`` slots, ``live`` masks the used ones."""

    live: jax.Array  # bool[M]
    kind: jax.Array  # int32[M]: PROJ_HOMING / PROJ_STRAIGHT / PROJ_AREA
    pos: jax.Array  # float32[M, 2]
    direction: jax.Array  # float32[M, 2] unit vector (straight missiles)
    owner: jax.Array  # int32[M] unit index
    slot: jax.Array  # int32[M] skill slot of the owner
    target: jax.Array  # int32[M] unit index (homing)
    life: jax.Array  # float32[M] seconds left (areas)
    hit_mask: jax.Array  # bool[M, U] units already hit (areas)


@struct.dataclass
class Effects:
    """What a hit needs to know about its sources, one entry per source (a unit's skill slot or
    basic attack, ``damage.effect_sources``): every field ``float32[n]`` (lane axes follow). Built
    once per decision; ``n`` is ``len(base)``."""

    base: jax.Array  # damage before multipliers: int(coefficient x power) x the primary stat's scale
    heal: jax.Array  # healing: int(coefficient x spell power x the intelligence scale)
    crit: jax.Array  # critical chance, 0..1
    crit_mult: jax.Array  # damage multiplier of a critical hit
    back_mult: jax.Array  # damage multiplier of a back attack (players; 1 for the boss)
    vers: jax.Array  # versatility multiplier, 1 + versatility / 100
    agility: jax.Array  # the source's agility (lowers the target's evasion)
    team: jax.Array  # the source's team, 0 players, 1 boss
    enemy: jax.Array  # 1 if it affects enemies
    ally: jax.Array  # 1 if it affects allies
    speed: jax.Array  # projectile speed (0: instant)
    radius: jax.Array  # projectile or area radius
    hits: jax.Array  # how many units an area hits


@struct.dataclass
class Spawns:
    """The projectiles and areas one sub-step's fired skills request and the pool slots they take:
    ``combat.fire`` makes the requests, ``combat.take_slots`` assigns the slots (``got`` and ``src``
    are ``None`` until then) and ``combat.spawn`` writes them. ``R = U * S`` requests (request ``r``
    is unit ``r // S``'s skill slot ``r % S``), ``M`` pool slots; lane axes follow every shape."""

    requested: jax.Array  # bool[R]: request r spawns a projectile or an area in this sub-step
    got: jax.Array  # bool[M]: slot m takes a request in this sub-step
    src: jax.Array  # int32[M]: the request slot m takes (where got)
    pos: jax.Array  # float32[R, 2]: where the projectile or area appears
    kind: jax.Array  # int32[R]: PROJ_HOMING / PROJ_STRAIGHT / PROJ_AREA
    target: jax.Array  # int32[R]: the unit it is aimed at
    tick: jax.Array  # int32[R]: the tick of the sub-step the skill fired in (1..n_ticks)
    life: jax.Array  # float32[R]: seconds it lives
    facing: jax.Array  # float32[U, 2]: each caster's facing while casting (straight missiles fly along it)


@struct.dataclass
class State:
    """Dynamic state of one arena (leading batch axes when vmapped).

    Shapes with ``U`` units and ``S`` skill slots.
    """

    pos: jax.Array  # float32[U, 2]
    heading: jax.Array  # float32[U] radians, 0 = +x
    vel: jax.Array  # float32[U, 2]
    hp: jax.Array  # float32[U]
    mana: jax.Array  # float32[U]
    alive: jax.Array  # bool[U]
    moving: jax.Array  # bool[U] moved faster than MOVING_SPEED in the last sub-step
    cast_left: jax.Array  # float32[U, S] seconds until a cast in progress fires
    casting: jax.Array  # bool[U, S] a cast of this slot is in progress
    charges: jax.Array  # int32[U, S] (may exceed the skill's charge under carry_cooldowns)
    recharging: jax.Array  # bool[U, S] a cooldown timer runs (it adds a charge when it ends)
    recharge_left: jax.Array  # float32[U, S] seconds until the running cooldown adds its charge
    basic_cooldown: jax.Array  # float32[U] seconds until the next basic attack
    target: jax.Array  # int32[U] current enemy target of each unit
    orbit_sign: jax.Array  # float32[U] +1 / -1: PT-HR's per-episode circling direction
    clock: jax.Array  # float32[] seconds: PT-HR's circling phase (random start, shared by the team)
    projectiles: Projectiles
    decision: jax.Array  # int32[] decisions played
    result: jax.Array  # int32[] RUNNING / WIN / LOSS / DRAW
    # Per-episode accumulators for game logs (float32[U] / int32[]).
    damage_dealt: jax.Array  # damage each unit's hits dealt to enemies
    back_attacks: jax.Array  # int32[U] back attacks landed
    dropped: jax.Array  # int32[] projectiles dropped because the pool was full
    # What the reference observation remembers between decisions (``reference_observation.Memory``);
    # None under raidjax's own observation, so the default state carries nothing for it.
    memory: object = None


@struct.dataclass
class Observation:
    """What each player sees (GAME.md §8), every field with a leading player axis ``P``.

    Shapes with ``P`` players, ``S`` skill slots, ``K`` observed projectiles.
    """

    self_features: jax.Array  # float32[P, 10 + 5 S]
    boss: jax.Array  # float32[P, 11]
    teammates: jax.Array  # float32[P, P - 1, 7 + 3 S]
    teammate_mask: jax.Array  # bool[P, P - 1] teammate alive
    projectiles: jax.Array  # float32[P, K, 6]
    projectile_mask: jax.Array  # bool[P, K]
    walls: jax.Array  # float32[P, 4]
    action_mask: jax.Array  # bool[P, A], A = config.n_actions (10, or 8 under the reference action space)
    alive: jax.Array  # bool[P]

    def flat(self) -> jax.Array:
        """Flat vector view for MLP policies: ``float32[..., P, D]`` (masks included as 0/1), for one
        arena's observation or a batch of them (any leading axes)."""
        import jax.numpy as jnp

        lead = self.alive.shape  # [..., P]
        parts = [
            self.self_features,
            self.boss,
            self.teammates.reshape(*lead, -1),
            self.teammate_mask.astype(jnp.float32),
            self.projectiles.reshape(*lead, -1),
            self.projectile_mask.astype(jnp.float32),
            self.walls,
            self.action_mask.astype(jnp.float32),
        ]
        return jnp.concatenate(parts, axis=-1)
