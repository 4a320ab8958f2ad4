"""What the reference build's players observe (``EnvConfig(observation="reference")``, GAME.md §8).

The reference player (``RaidPlayerAgent`` with its ML-Agents sensors) sends 204 floats per decision:

* a teammate buffer, 2 rows of 9 (absolute position, world velocity, HP, skill-0 features; a dead
  teammate's row is zeros, which the reference trainer's attention masks out);
* two sphere-cast ray sensors, 21 rays each in a +-70 degree fan in front of the player, length 20,
  sphere radius 0.5, 3 floats per ray ``[hit, 1 - hit, distance / 20 or 1]``: one sees every live
  projectile (any owner), the other the arena's walls; a sphere that overlaps an object where
  the cast starts does not report it (the physics engine's sphere cast);
* a 15-float vector (own position, body-frame velocity, boss position, facing and two cooldowns,
  own HP and skill-0 features) stacked over the last 4 decisions, oldest first, zeroed when an
  episode starts.

The rays run once per decision, on the state the decision ends in, never inside the sub-steps.
Shapes: ``P`` players, ``U = P + 1`` units, ``S`` skill slots, ``M`` pool slots.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
from flax import struct

from raidjax.damage import source_index
from raidjax.lanes import pick
from raidjax.types import HALF_ARENA, Effects, Params, State

STACK = 4  # NumStackedVectorObservations of the player's BehaviorParameters
VECTOR = 15  # the stacked vector's size with one boss
BUFFER_ROW = 9  # one teammate's row in the BufferSensor
N_RAYS = 21  # RaysPerDirection 10 on each side of the forward ray
RAY_LENGTH = 20.0
CAST_RADIUS = 0.5  # SphereCastRadius
PREFAB_RADIUS = 0.2  # the trigger sphere every pooled projectile carries (DefaultProjectile.prefab)
POS_SCALE = VEL_SCALE = RANGE_SCALE = 20.0  # RaidPlayerAgent's normalisation factors
COOL_SCALE = CAST_SCALE = 5.0
HP_SCALE = DAMAGE_SCALE = 100.0
# ML-Agents orders the rays forward, then alternately 7 degrees right and left of it (angles from
# the player's right axis: 90 forward, 83 one step right, 97 one step left, ...).
RAY_ANGLES_DEG = tuple([90.0] + [90.0 + sign * 7.0 * k for k in range(1, 11) for sign in (-1.0, 1.0)])
RAY_OFFSETS = tuple(math.radians(a - 90.0) for a in RAY_ANGLES_DEG)  # added to the heading (CCW)


@struct.dataclass
class ReferenceObservation:
    """The reference player's observation, every field with a leading player axis ``P``.

    Attributes:
        teammates: ``float32[P, P - 1, 9]`` the other players in index order: position / 20,
            world velocity / 20, HP / 100, skill-0 cooldown left / 5, range / 20,
            coefficient x spell power / 100, cast time / 5; zeros for a dead teammate.
        teammate_mask: ``bool[P, P - 1]`` the row is a live teammate (zero rows are padding).
        projectile_rays: ``float32[P, 63]`` 21 rays x ``[hit, 1 - hit, distance / 20 or 1]``.
        wall_rays: ``float32[P, 63]`` the same against the walls.
        stack: ``float32[P, 60]`` the last 4 15-vectors, oldest first (zeros before the episode's first).
        action_mask: ``bool[P, A]`` ``A = config.n_actions``: all true under the reference action space
            (the reference masks nothing), raidjax's mask otherwise.
        alive: ``bool[P]``.

    A dead player observes zeros.
    """

    teammates: jax.Array
    teammate_mask: jax.Array
    projectile_rays: jax.Array
    wall_rays: jax.Array
    stack: jax.Array
    action_mask: jax.Array
    alive: jax.Array

    def flat(self) -> jax.Array:
        """``float32[..., P, 9 (P - 1) + 186]`` (204 for the reference's 3 players) in ML-Agents' sensor
        order: buffer (9 per teammate), projectile rays (63), wall rays (63), stack (60), with any
        leading batch axes."""
        mates = self.teammates.reshape(*self.stack.shape[:-1], -1)
        return jnp.concatenate([mates, self.projectile_rays, self.wall_rays, self.stack], -1)


@struct.dataclass
class Memory:
    """What the reference observation carries between decisions (``State.memory``).

    Attributes:
        stack: ``float32[P, STACK, VECTOR]`` the last 15-vectors, oldest first.
        cooldown_unstarted: ``bool[U, S]`` no cooldown of the slot has run this episode: the
            reference shows such a slot's cooldown as its full cool time (it sets ``cooltimeLeft``
            to the cool time at every episode start; only a running cooldown changes it).
    """

    stack: jax.Array
    cooldown_unstarted: jax.Array


def ray_directions(heading: jax.Array) -> jax.Array:
    """Unit vectors ``float32[P, 21, 2]`` of every player's rays (``heading: float32[P]``), in sensor order."""
    angle = heading[:, None] + jnp.asarray(RAY_OFFSETS, jnp.float32)[None]
    return jnp.stack([jnp.cos(angle), jnp.sin(angle)], axis=-1)


def wall_distances(origin: jax.Array, dirs: jax.Array) -> jax.Array:
    """How far a sphere of radius 0.5 travels from ``origin[P, 2]`` along ``dirs[P, R, 2]`` before it
    touches a wall (``float32[P, R]``); ``inf`` where it starts overlapping one.

    The sphere's centre touches the wall at ``x = +-12.25`` when it reaches ``+-11.75``.
    """
    lim = HALF_ARENA - CAST_RADIUS
    safe = jnp.where(jnp.abs(dirs) < 1e-9, 1e-9, dirs)
    t = (jnp.sign(safe) * lim - origin[:, None]) / safe  # [P, R, 2] per axis
    t = jnp.where((jnp.abs(dirs) < 1e-9) | (t < 0), jnp.inf, t)
    return jnp.min(t, axis=-1)


def sphere_distances(origin: jax.Array, dirs: jax.Array, centres: jax.Array, radii: jax.Array,
                     present: jax.Array) -> jax.Array:
    """How far a sphere of radius 0.5 travels from ``origin[P, 2]`` along ``dirs[P, R, 2]`` before it
    touches the first ``present`` sphere of ``centres[M, 2]`` and ``radii[M]`` (``float32[P, R]``,
    ``inf`` if none; a sphere it overlaps at the start is not reported)."""
    rel = centres[None, None] - origin[:, None, None]  # [P, 1, M, 2]
    along = jnp.sum(rel * dirs[:, :, None], axis=-1)  # [P, R, M]
    reach = radii + CAST_RADIUS
    c = jnp.sum(rel * rel, axis=-1) - reach**2  # > 0: apart at the start
    disc = along**2 - c
    t = along - jnp.sqrt(jnp.maximum(disc, 0.0))
    hit = present[None, None] & (c > 0) & (disc >= 0) & (t >= 0)
    return jnp.min(jnp.where(hit, t, jnp.inf), axis=-1)


def encode_rays(distance: jax.Array) -> jax.Array:
    """``float32[P, R]`` distances -> ``float32[P, 3 R]``, per ray ``[hit, 1 - hit, distance / 20 or 1]``."""
    hit = distance <= RAY_LENGTH
    frac = jnp.where(hit, distance / RAY_LENGTH, 1.0)
    per_ray = jnp.stack([hit.astype(jnp.float32), (~hit).astype(jnp.float32), frac], axis=-1)
    return per_ray.reshape(distance.shape[0], -1)


def shown_cooldowns(state: State, params: Params) -> jax.Array:
    """``float32[U, S]``: each slot's ``cooltimeLeft`` as the reference shows it (seconds)."""
    unstarted = state.memory.cooldown_unstarted
    return jnp.where(state.recharging, state.recharge_left, jnp.where(unstarted, params.skills.cool_time, 0.0))


def _skill0(state: State, params: Params) -> jax.Array:
    """``float32[U, 4]``: slot 0's cooldown / 5, range / 20, coefficient x spell power / 100, cast time / 5
    (the reference always uses spell power and the cast time as written)."""
    sk = params.skills
    damage = sk.coefficient[:, 0] * params.stats.spell_power
    return jnp.stack([shown_cooldowns(state, params)[:, 0] / COOL_SCALE, sk.range[:, 0] / RANGE_SCALE,
                      damage / DAMAGE_SCALE, sk.cast_time[:, 0] / CAST_SCALE], -1)


def vector(state: State, params: Params) -> jax.Array:
    """Every player's 15-vector, ``float32[P, 15]`` (RaidPlayerAgent.CollectObservations)."""
    n_players = params.team.shape[0] - 1
    b = n_players
    h = state.heading[:n_players]
    fwd = jnp.stack([jnp.cos(h), jnp.sin(h)], -1)
    right = jnp.stack([jnp.sin(h), -jnp.cos(h)], -1)
    vel = state.vel[:n_players]
    boss = jnp.concatenate([state.pos[b] / POS_SCALE, jnp.stack([jnp.cos(state.heading[b]), jnp.sin(state.heading[b])]),
                            shown_cooldowns(state, params)[b, :2] / COOL_SCALE])
    return jnp.concatenate([
        state.pos[:n_players] / POS_SCALE,
        jnp.sum(vel * fwd, -1, keepdims=True) / VEL_SCALE,
        jnp.sum(vel * right, -1, keepdims=True) / VEL_SCALE,
        jnp.broadcast_to(boss, (n_players, 6)),
        state.hp[:n_players, None] / HP_SCALE,
        _skill0(state, params)[:n_players],
    ], axis=-1)


def start_memory(state: State, params: Params) -> State:
    """``state`` with a new episode's ``Memory``: every cooldown unstarted, the stack zeroed, then
    the first decision's vector pushed (as ML-Agents zeroes its stacking sensor at episode end)."""
    n_players = params.team.shape[0] - 1
    memory = Memory(stack=jnp.zeros((n_players, STACK, VECTOR)),
                    cooldown_unstarted=~state.recharging)
    return remember(state.replace(memory=memory), params)


def remember(state: State, params: Params) -> State:
    """Advance the memory by one decision: slots whose cooldown now runs are no longer unstarted,
    then the stack shifts and takes this decision's vector.

    A cooldown that starts and ends between two decisions (cool time under 0.1 s) goes unseen,
    as a cooldown is only looked at once per decision.
    """
    m = state.memory
    state = state.replace(memory=m.replace(cooldown_unstarted=m.cooldown_unstarted & ~state.recharging))
    stack = jnp.concatenate([m.stack[:, 1:], vector(state, params)[:, None]], axis=1)  # vector reads the flags
    return state.replace(memory=state.memory.replace(stack=stack))


def observe_reference(state: State, params: Params, table: Effects, action_mask: jax.Array) -> ReferenceObservation:
    """Build every player's ``ReferenceObservation`` from ``state`` (its ``memory`` already holds
    this decision's vector). ``table``: ``damage.effect_table(params)`` (``Effects``);
    ``action_mask``: ``bool[P, A]``."""
    n_players = params.team.shape[0] - 1
    alive = state.alive[:n_players]
    others = jnp.array([[j for j in range(n_players) if j != i] for i in range(n_players)], jnp.int32)
    rows = jnp.concatenate([state.pos[:n_players] / POS_SCALE, state.vel[:n_players] / VEL_SCALE,
                            state.hp[:n_players, None] / HP_SCALE, _skill0(state, params)[:n_players]], -1)
    mate_mask = alive[others] & alive[:, None]
    mates = rows[others] * mate_mask[..., None]

    p = state.projectiles
    # A barrier keeps XLA from constant-folding the rays of a freshly reset batch (an empty pool at
    # fixed spawns is constant): folding them took 27 s of compile for 8192 arenas, not 1 ms of work.
    pos, heading, centres, live = jax.lax.optimization_barrier((state.pos, state.heading, p.pos, p.live))
    origin, dirs = pos[:n_players], ray_directions(heading[:n_players])
    # Every pooled projectile also carries the prefab's 0.2 sphere (DefaultProjectile.prefab): the
    # larger of the two co-centred spheres is what a ray meets.
    radii = jnp.maximum(pick(table.radius, source_index(p.owner, p.slot, params.skills.in_use.shape[1])),
                        PREFAB_RADIUS)
    proj_rays = encode_rays(sphere_distances(origin, dirs, centres, radii, live))
    wall_rays = encode_rays(wall_distances(origin, dirs))
    seen = alive[:, None]
    return ReferenceObservation(
        teammates=mates, teammate_mask=mate_mask,
        projectile_rays=proj_rays * seen, wall_rays=wall_rays * seen,
        stack=state.memory.stack.reshape(n_players, STACK * VECTOR) * seen,
        action_mask=action_mask, alive=alive,
    )

