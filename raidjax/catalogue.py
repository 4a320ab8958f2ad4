"""Named content presets: skills, player classes and bosses, built only from parameters.

Every preset is plain data (dicts of the fields of ``types.Stats`` / ``types.Skills``);
``content.make_params`` turns names into validated arrays. Skill fields left out take the
values of ``BASE_SKILL``; stats left out take the class's team defaults in ``content``.
"""

from __future__ import annotations

from raidjax.types import HIT_ATTACK, HIT_SPELL, TARGET_NONE, TARGET_REGION, TARGET_UNIT, TRIGGER_PASSIVE

BASE_SKILL: dict[str, float] = dict(
    in_use=1, trigger=0, school=0, hit_type=HIT_SPELL, target_type=TARGET_UNIT,
    projectile_speed=15.0, affect_ally=0, affect_enemy=1, cool_time=0.5, cast_time=0.5,
    cost=1.0, range=5.0, charge=1, cast_on_moving=1, cast_on_casting=0,
    cast_on_channeling=0, coefficient=0.5, projectile_radius=0.2, hit_count=1, area_offset=1.0,
)

# fmt: off
SKILLS: dict[str, dict[str, float]] = {
    # The reference player skill (GAME.md §4); its range is the experiment variable.
    "magic_missile": dict(school=1),
    # Mage.
    "fireball": dict(school=2, target_type=TARGET_NONE, projectile_speed=12.0, cast_time=1.0,
                     cool_time=3.0, cost=10.0, range=12.0, coefficient=1.0, projectile_radius=0.4),
    "frost_bolt": dict(school=3, projectile_speed=20.0, cast_time=1.5, cool_time=1.0, cost=5.0,
                       range=15.0, coefficient=0.7),
    "arcane_blast": dict(school=4, projectile_speed=0.0, cast_time=1.0, cool_time=2.0, cost=8.0,
                         range=10.0, coefficient=0.6),
    "meteor": dict(school=2, target_type=TARGET_REGION, projectile_speed=0.0, cast_time=2.0,
                   cool_time=12.0, cost=20.0, range=18.0, coefficient=1.5, projectile_radius=3.0,
                   hit_count=3, cast_on_moving=0),
    # Melee fighter.
    "slash": dict(school=0, hit_type=HIT_ATTACK, projectile_speed=0.0, cast_time=0.1,
                  cool_time=1.0, cost=0.0, range=2.5, coefficient=0.8),
    "cleave": dict(school=0, hit_type=HIT_ATTACK, target_type=TARGET_REGION, projectile_speed=0.0,
                   cast_time=0.3, cool_time=2.0, cost=5.0, range=3.0, coefficient=0.6,
                   projectile_radius=1.5, hit_count=3, area_offset=0.5),
    "lunge": dict(school=0, hit_type=HIT_ATTACK, projectile_speed=0.0, cast_time=0.0,
                  cool_time=8.0, cost=10.0, range=6.0, coefficient=1.0, charge=2,
                  cast_on_casting=1),
    # Ranger.
    "arrow_shot": dict(school=5, hit_type=HIT_ATTACK, target_type=TARGET_NONE,
                       projectile_speed=30.0, cast_time=0.3, cool_time=0.7, cost=0.0,
                       range=18.0, coefficient=0.6),
    "aimed_shot": dict(school=5, hit_type=HIT_ATTACK, projectile_speed=25.0, cast_time=1.5,
                       cool_time=4.0, cost=5.0, range=20.0, coefficient=1.5, cast_on_moving=0),
    "double_tap": dict(school=5, hit_type=HIT_ATTACK, projectile_speed=25.0, cast_time=0.2,
                       cool_time=5.0, cost=4.0, range=14.0, coefficient=0.5, charge=2,
                       cast_on_casting=1),
    # Healer.
    "heal": dict(school=6, projectile_speed=0.0, affect_ally=1, affect_enemy=0, cast_time=1.0,
                 cool_time=1.5, cost=10.0, range=15.0, coefficient=0.4),
    "healing_circle": dict(school=6, target_type=TARGET_REGION, projectile_speed=0.0,
                           affect_ally=1, affect_enemy=0, cast_time=1.5, cool_time=6.0,
                           cost=20.0, range=20.0, coefficient=0.3, projectile_radius=4.0,
                           hit_count=3, area_offset=0.0),
    "holy_bolt": dict(school=7, projectile_speed=18.0, cast_time=0.5, cool_time=1.0, cost=2.0,
                      range=12.0, coefficient=0.3),
    "renew": dict(school=6, trigger=TRIGGER_PASSIVE, projectile_speed=0.0, affect_ally=1,
                  affect_enemy=0, cast_time=0.0, cool_time=2.0, cost=0.0, range=20.0,
                  coefficient=0.1, cast_on_casting=1, cast_on_channeling=1),
    "thorns_aura": dict(school=8, trigger=TRIGGER_PASSIVE, target_type=TARGET_REGION,
                        projectile_speed=0.0, cast_time=0.0, cool_time=1.0, cost=0.0, range=2.5,
                        coefficient=0.1, projectile_radius=2.5, hit_count=1, area_offset=0.0,
                        cast_on_casting=1, cast_on_channeling=1),
    # The reference boss (GAME.md §7).
    "dragon_breath": dict(school=9, target_type=TARGET_NONE, projectile_speed=20.0, cast_time=0.1,
                          cool_time=0.5, cost=0.0, range=12.0, coefficient=1.1),
    "dragon_slash": dict(school=9, target_type=TARGET_REGION, projectile_speed=0.0,
                         cast_time=4.0, cool_time=7.0, cost=0.0, range=6.0, coefficient=1.2,
                         projectile_radius=2.4, hit_count=3, area_offset=0.5),
}

# Player classes: stat overrides on top of the player defaults, and up to 3 skills.
CLASSES: dict[str, dict] = {
    "mage": dict(stats={}, skills=["magic_missile"]),
    "battle_mage": dict(stats={}, skills=["magic_missile", "fireball", "frost_bolt"]),
    "warrior": dict(stats=dict(max_hp=180, attack_power=60, armor=40, spell_power=0,
                               attack_range=2, attack_speed=1.0),
                    skills=["slash", "cleave", "lunge"]),
    "ranger": dict(stats=dict(attack_power=70, spell_power=0, evasion=15, critical=10),
                   skills=["arrow_shot", "aimed_shot", "double_tap"]),
    "priest": dict(stats=dict(spell_power=80, hp_regen=1.0),
                   skills=["heal", "holy_bolt", "renew"]),
    "druid": dict(stats=dict(spell_power=70), skills=["healing_circle", "holy_bolt", "thorns_aura"]),
}

BOSSES: dict[str, dict] = {
    "dragon": dict(stats={}, skills=["dragon_breath", "dragon_slash"]),
    "enraged_dragon": dict(stats=dict(spell_power=70, haste=30), skills=["dragon_breath", "dragon_slash"]),
}
# fmt: on


def skill_fields(name: str) -> dict[str, float]:
    """All fields of the named skill (``BASE_SKILL`` filled in). Raises ``ValueError`` if unknown."""
    if name not in SKILLS:
        raise ValueError(f"unknown skill preset {name!r}; known: {sorted(SKILLS)}")
    return {**BASE_SKILL, **SKILLS[name]}
