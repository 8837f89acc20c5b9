"""The unit table: one source of truth for every unit the engine simulates.

All values are in **Normal game speed** units: times in game loops (16 loops = 1 Normal second), speeds and rates per
second of Normal time converted to per loop where the engine needs them. Public LotV figures (Liquipedia) are quoted
at Faster speed; a Faster second is 1.4 Normal seconds, so Faster times are multiplied by 1.4 and Faster rates divided
by 1.4 before they enter this table.

Sources (keys used in each row's ``sources``):

- ``xml``: the custom ``*_RL`` unit data inside SMAC's map files (UnitData.xml), Normal speed.
- ``techtree``: the SC2 5.0.3 game-data dump (BurnySc2/sc2-techtree ``data_readable.json``), Normal speed;
  weapon damage, bonus, period, range, radius, sight, attributes.
- ``lqp``: Liquipedia LotV pages (Faster speed, converted here).
- ``smac``: SMAC's own constants (``unit_max_cooldown``, ``unit_max_shield``).
- ``lotv``: general LotV knowledge that could not be re-retrieved (marked * in the reference table).
- ``gamedata``: the game's own data files (SC2Mapster/SC2GameData, ``liberty`` AbilData.xml), cited in
  docs/engine_rules.md.

Every fact comes from ``docs/smac_interface.md`` §8, which collects these sources.

Learner (red) units are SMAC's ``*_RL`` copies: passive (never auto-acquire while idle or holding, never respond when
attacked) with SMAC's custom values (hydralisk 80 HP, medivac speed 2.75). Opponent (blue) units are standard.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

LOOPS_PER_SECOND = 16.0  # Normal speed: 16 game loops per game second
FASTER_PER_NORMAL = 1.4  # a Faster (ladder) second is 1.4 Normal seconds

# Attribute bits.
LIGHT, ARMORED, BIO, MECH, MASSIVE, STRUCTURE = 1, 2, 4, 8, 16, 32

# Special weapon kinds.
WEAPON_PLAIN, WEAPON_LINE_SPLASH, WEAPON_BURST, WEAPON_HEAL = 0, 1, 2, 3

SHIELD_REGEN_DELAY_LOOPS = 10.0 * LOOPS_PER_SECOND  # xml: shields regenerate after 10 Normal s without damage
SHIELD_REGEN_PER_SECOND = 2.0  # xml: 2 shield per Normal second
ZERG_REGEN_PER_SECOND = 0.2734  # xml: 0.2734 HP per Normal second (0.38 Faster)
# gamedata: a Zerg structure off creep (behaviour ZergBuildingNotOnCreep) takes ZergBuildingNotOnCreepDamage, 1 HP
# every 0.3332 Normal s, armour aside (Liquipedia, Creep: 4.2 HP per Faster second); SMAC's maps have no creep.
OFF_CREEP_DECAY_PER_SECOND = 1.0 / 0.3332
MIN_DAMAGE = 0.5  # SC2: a hit on health deals at least 0.5 after armour
# gamedata (core GameData.xml, CGame): a unit hit by a weapon calls its allies within CallForHelpRadius 4 for help,
# at most once every CallForHelpPeriod 2 Normal s (docs/engine_rules.md, C13).
CALL_FOR_HELP_RADIUS = 4.0
CALL_FOR_HELP_PERIOD_LOOPS = int(2 * LOOPS_PER_SECOND)


@dataclass(frozen=True)
class UnitSpec:
    """One row of the unit table. Speeds are per Normal second; times in game loops."""

    name: str  # table key, e.g. "marine" or "marine_rl"
    sc2_name: str  # the SC2 unit name used by map files ("Marine", "Marine_RL")
    base: str  # the standard unit this row is (a variant of)
    sc2_id: int  # standard SC2 unit type id of ``base`` (docs/smac_interface.md §8)
    race: str  # "T", "P" or "Z"
    health: float
    shield: float
    armor: float
    damage: float  # per hit
    hits: int  # hits per attack (zealot and colossus: 2)
    bonus_damage: float
    bonus_attribute: int  # attribute bits that receive the bonus
    cooldown: float  # weapon period, game loops
    range: float  # edge to edge
    hits_ground: bool
    hits_air: bool
    speed: float  # distance per Normal second
    radius: float
    sight: float
    attributes: int
    is_air: bool = False
    cliff_walk: bool = False
    weapon: int = WEAPON_PLAIN
    splash_radius: float = 0.0  # burst radius (baneling)
    splash_length: float = 0.0  # line splash length (colossus), centred on the target
    splash_width: float = 0.0
    energy_start: float = 0.0
    energy_max: float = 0.0
    energy_regen: float = 0.0  # per Normal second
    heal_rate: float = 0.0  # HP per Normal second
    heal_energy_per_hp: float = 0.0
    regen: float = 0.0  # health per Normal second (zerg)
    decay: float = 0.0  # health lost per Normal second, armour aside (a Zerg structure off creep)
    passive: bool = False  # SMAC *_RL: no auto-acquire while idle, no response when attacked
    smac_max_cooldown: float = 15.0  # smac: normaliser of the state's cooldown/energy column
    autocast_range: float = 0.0  # a healer's heal auto-cast reach, edge to edge (0: no auto-cast)
    missile_speed: float = 0.0  # the weapon launches a homing missile at this speed per Normal second (0: instant)
    second_hit_delay: float = 0.0  # game loops from the first hit to the last (zealot's second blade; 0: together)
    second_hit_reach: float = 0.0  # ... which lands only within this centre distance of the attacker
    damage_point: float = 0.0  # game loops from the start of an attack to its shot (the weapon's DamagePoint)
    range_slop: float = 0.0  # how far past its range the target of an attack in progress may go (RangeSlop)
    sources: dict[str, str] = field(default_factory=dict, compare=False)


def _normal_loops(faster_seconds: float) -> float:
    """A Faster-speed duration in Normal game loops."""
    return faster_seconds * FASTER_PER_NORMAL * LOOPS_PER_SECOND


_STANDARD: list[UnitSpec] = [
    UnitSpec(
        "marine", "Marine", "marine", 48, "T", health=45, shield=0, armor=0, damage=6, hits=1,
        bonus_damage=0, bonus_attribute=0, cooldown=0.8608 * LOOPS_PER_SECOND, range=5,
        hits_ground=True, hits_air=True, speed=2.25, radius=0.375, sight=9, attributes=LIGHT | BIO,
        smac_max_cooldown=15,
        damage_point=0.05 * LOOPS_PER_SECOND, range_slop=1.0,
        sources={"health,armor,damage,range,radius,sight,attributes": "techtree",
                 "cooldown": "techtree 0.8608 Normal s (lqp 0.61 Faster)", "speed": "xml 2.25 (lqp 3.15 Faster)",
                 "smac_max_cooldown": "smac",
                 "damage_point": "gamedata WeaponData DamagePoint: GuassRifle 0.05 s",
                 "range_slop": "gamedata WeaponData RangeSlop: core default 1"},
    ),
    UnitSpec(
        "marauder", "Marauder", "marauder", 51, "T", health=125, shield=0, armor=1, damage=10, hits=1,
        bonus_damage=10, bonus_attribute=ARMORED, cooldown=1.5 * LOOPS_PER_SECOND, range=6,
        hits_ground=True, hits_air=False, speed=2.25, radius=0.5625, sight=10, attributes=ARMORED | BIO,
        smac_max_cooldown=25, missile_speed=20.0, range_slop=1.0,
        sources={"health,armor,speed,sight,radius,attributes": "xml", "damage,bonus,range": "techtree",
                 "cooldown": "techtree 1.5 Normal s (lqp 1.07 Faster)", "smac_max_cooldown": "smac",
                 "missile_speed": "gamedata PunisherGrenadesWeapon MaxSpeed 20",
                 "range_slop": "gamedata WeaponData RangeSlop: core default 1"},
    ),
    UnitSpec(
        "medivac", "Medivac", "medivac", 54, "T", health=150, shield=0, armor=1, damage=0, hits=0,
        bonus_damage=0, bonus_attribute=0, cooldown=0, range=4, hits_ground=False, hits_air=False,
        speed=3.5 / FASTER_PER_NORMAL, radius=0.75, sight=11, attributes=ARMORED | MECH, is_air=True,
        weapon=WEAPON_HEAL, energy_start=50, energy_max=200, energy_regen=0.7875 / FASTER_PER_NORMAL,
        heal_rate=12.6 / FASTER_PER_NORMAL, heal_energy_per_hp=1.0 / 3.0, smac_max_cooldown=200, autocast_range=6.0,
        sources={"health,armor,sight,radius,energy_start,energy_max": "xml",
                 "autocast_range": "gamedata MedivacHeal AutoCastRange 6 (targets sorted by life fraction)",
                 "speed": "lqp 3.5 Faster -> 2.5 Normal", "energy_regen": "lqp 0.7875/s Faster",
                 "heal_rate,heal_energy_per_hp,range": "lotv* 12.6 HP/s Faster, 1 energy per 3 HP, range 4",
                 "smac_max_cooldown": "smac (energy normaliser 200)"},
    ),
    UnitSpec(
        "stalker", "Stalker", "stalker", 74, "P", health=80, shield=80, armor=1, damage=13, hits=1,
        bonus_damage=5, bonus_attribute=ARMORED, cooldown=1.87 * LOOPS_PER_SECOND, range=6,
        hits_ground=True, hits_air=True, speed=2.9531, radius=0.625, sight=10, attributes=ARMORED | MECH,
        smac_max_cooldown=35, missile_speed=18.75,
        damage_point=0.167 * LOOPS_PER_SECOND, range_slop=1.0,
        sources={"health,shield,armor,speed,sight,radius,attributes": "xml", "damage,bonus,range": "techtree",
                 "cooldown": "techtree 1.87 Normal s (lqp 1.34 Faster)", "smac_max_cooldown": "smac",
                 "missile_speed": "gamedata StalkerWeapon (MissileDefault) MaxSpeed 18.75",
                 "damage_point": "gamedata WeaponData DamagePoint: ParticleDisruptors: core default 0.167 s",
                 "range_slop": "gamedata WeaponData RangeSlop: core default 1"},
    ),
    UnitSpec(
        "zealot", "Zealot", "zealot", 73, "P", health=100, shield=50, armor=1, damage=8, hits=2,
        bonus_damage=0, bonus_attribute=0, cooldown=1.2 * LOOPS_PER_SECOND, range=0.1,
        hits_ground=True, hits_air=False, speed=2.25, radius=0.5, sight=9, attributes=LIGHT | BIO,
        smac_max_cooldown=22, second_hit_delay=0.28 * LOOPS_PER_SECOND, second_hit_reach=2.1,
        range_slop=1.0,
        sources={"health,shield,armor,speed,sight,attributes": "xml", "radius": "techtree 0.5 (xml unset)",
                 "damage,hits,range": "techtree", "cooldown": "techtree 1.2 Normal s (lqp 0.86 Faster)",
                 "smac_max_cooldown": "smac",
                 "second_hit_delay,second_hit_reach": "gamedata PsiBladesBurst periods 0, 0.28 s; validator "
                                                      "ZealotAttackDamageMaxRange 2.1",
                 "range_slop": "gamedata WeaponData RangeSlop: core default 1"},
    ),
    UnitSpec(
        "colossus", "Colossus", "colossus", 4, "P", health=200, shield=150, armor=1, damage=10, hits=2,
        bonus_damage=5, bonus_attribute=LIGHT, cooldown=1.5 * LOOPS_PER_SECOND, range=7,
        hits_ground=True, hits_air=False, speed=2.25, radius=1.0, sight=10,
        attributes=ARMORED | MECH | MASSIVE, cliff_walk=True, weapon=WEAPON_LINE_SPLASH,
        splash_length=2.8, splash_width=0.3, smac_max_cooldown=24,
        damage_point=0.0832 * LOOPS_PER_SECOND, range_slop=0.0,
        sources={"health,shield,armor,speed,sight,radius,attributes,cliff_walk": "xml (SC2 4.10 values)",
                 "damage,hits,bonus,range": "techtree", "cooldown": "techtree 1.5 Normal s (lqp 1.07 Faster)",
                 "splash_length,splash_width": "2.8 x 0.3 line centred on the target (smaclite's model)",
                 "smac_max_cooldown": "smac",
                 "damage_point": "gamedata WeaponData DamagePoint: ThermalLances 0.0832 s",
                 "range_slop": "gamedata WeaponData RangeSlop: ThermalLances 0 (liberty)"},
    ),
    UnitSpec(
        "hydralisk", "Hydralisk", "hydralisk", 107, "Z", health=90, shield=0, armor=0, damage=12, hits=1,
        bonus_damage=0, bonus_attribute=0, cooldown=0.825 * LOOPS_PER_SECOND, range=5,
        hits_ground=True, hits_air=True, speed=2.25, radius=0.625, sight=9, attributes=LIGHT | BIO,
        regen=ZERG_REGEN_PER_SECOND, smac_max_cooldown=10, missile_speed=40.0,
        damage_point=0.14 * LOOPS_PER_SECOND, range_slop=1.0,
        sources={"health": "lqp 90 (standard unit)", "damage,range,radius,sight,attributes": "techtree",
                 "cooldown": "techtree 0.825 Normal s (lqp 0.59 Faster)", "speed": "xml 2.25 off creep",
                 "regen": "xml", "smac_max_cooldown": "smac", "missile_speed": "gamedata NeedleSpinesWeapon Speed 40",
                 "damage_point": "gamedata WeaponData DamagePoint: NeedleSpines 0.14 s (voidmulti)",
                 "range_slop": "gamedata WeaponData RangeSlop: core default 1"},
    ),
    UnitSpec(
        "zergling", "Zergling", "zergling", 105, "Z", health=35, shield=0, armor=0, damage=5, hits=1,
        bonus_damage=0, bonus_attribute=0, cooldown=0.696 * LOOPS_PER_SECOND, range=0.1,
        hits_ground=True, hits_air=False, speed=2.9531, radius=0.375, sight=8, attributes=LIGHT | BIO,
        regen=ZERG_REGEN_PER_SECOND, smac_max_cooldown=11,
        damage_point=0.167 * LOOPS_PER_SECOND, range_slop=1.0,
        sources={"health,speed,sight,radius,attributes,regen": "xml", "damage,range": "techtree",
                 "cooldown": "techtree 0.696 Normal s (lqp 0.497 Faster)", "smac_max_cooldown": "smac",
                 "damage_point": "gamedata WeaponData DamagePoint: Claws: core default 0.167 s",
                 "range_slop": "gamedata WeaponData RangeSlop: core default 1"},
    ),
    UnitSpec(
        "baneling", "Baneling", "baneling", 9, "Z", health=30, shield=0, armor=0, damage=16, hits=1,
        bonus_damage=19, bonus_attribute=LIGHT, cooldown=0, range=0.25, hits_ground=True, hits_air=False,
        speed=2.5, radius=0.375, sight=8, attributes=BIO, weapon=WEAPON_BURST, splash_radius=2.2,
        regen=ZERG_REGEN_PER_SECOND, smac_max_cooldown=1, range_slop=1.0,
        sources={"health,speed,sight,radius,attributes,regen": "xml",
                 "damage,bonus,splash_radius,range": "lotv* 16 (+19 light), radius 2.2, range 0.25",
                 "smac_max_cooldown": "smac",
                 "range_slop": "gamedata WeaponData RangeSlop: core default 1 (no wind-up: unused)"},
    ),
    UnitSpec(
        "spine_crawler", "SpineCrawler", "spine_crawler", 98, "Z", health=300, shield=0, armor=2, damage=25,
        hits=1, bonus_damage=5, bonus_attribute=ARMORED, cooldown=1.85 * LOOPS_PER_SECOND, range=7,
        hits_ground=True, hits_air=False, speed=0.0, radius=1.125, sight=11,
        attributes=ARMORED | BIO | STRUCTURE, regen=ZERG_REGEN_PER_SECOND, decay=OFF_CREEP_DECAY_PER_SECOND,
        smac_max_cooldown=15, missile_speed=31.0,
        damage_point=0.3332 * LOOPS_PER_SECOND, range_slop=0.0,
        sources={"health,armor,damage,bonus,range,radius,sight,attributes": "techtree / lqp",
                 "cooldown": "techtree 1.85 Normal s (lqp 1.32 Faster)", "speed": "rooted structure",
                 "regen": "zerg regeneration (xml rate)",
                 "decay": "gamedata ZergBuildingNotOnCreep: 1 HP per 0.3332 s off creep (no creep on SMAC's maps)",
                 "missile_speed": "gamedata ImpalerTentacleLM, mover SpineCrawlerTentacleExtendLong: speed 12 rising "
                                  "at 140/s^2 (max 200) covers 8.5 in 0.27 s; taken as a constant 31",
                 "damage_point": "gamedata WeaponData DamagePoint: ImpalerTentacle 0.3332 s",
                 "range_slop": "gamedata WeaponData RangeSlop: ImpalerTentacle 0 (liberty)"},
    ),
]

# SMAC's *_RL rows differ from the standard ones only where UnitData.xml says so (docs/smac_interface.md §8).
_RL_OVERRIDES: dict[str, dict] = {
    "marine": {},
    "marauder": {},
    "medivac": {"speed": 2.75},
    "stalker": {},
    "zealot": {},
    "colossus": {},
    "hydralisk": {"health": 80.0},
    "zergling": {},
    "baneling": {},
}


def _rl_variant(spec: UnitSpec) -> UnitSpec:
    overrides = _RL_OVERRIDES[spec.name]
    sources = dict(spec.sources)
    for key in overrides:
        sources[key] = "xml (*_RL custom value)"
    sources["passive"] = "xml: DefaultAcquireLevel=Passive, Response=Nothing"
    return replace(spec, name=spec.name + "_rl", sc2_name=spec.sc2_name + "_RL", passive=True,
                   sources=sources, **overrides)


UNITS: tuple[UnitSpec, ...] = tuple(_STANDARD) + tuple(
    _rl_variant(s) for s in _STANDARD if s.name in _RL_OVERRIDES
)
UNIT_INDEX: dict[str, int] = {u.name: i for i, u in enumerate(UNITS)}
BASE_NAMES: tuple[str, ...] = tuple(s.name for s in _STANDARD)

# SC2 names as they appear in map files, including SMAC's "Colosus_RL" spelling (1c3s5z).
_SC2_NAME_ALIASES = {"Colosus_RL": "Colossus_RL"}
SC2_NAME_INDEX: dict[str, int] = {u.sc2_name: i for i, u in enumerate(UNITS)}


def unit_index(name: str) -> int:
    """Row of the table for a unit name: table key ("marine_rl") or SC2 name ("Marine_RL", "Colosus_RL")."""
    name = _SC2_NAME_ALIASES.get(name, name)
    if name in SC2_NAME_INDEX:
        return SC2_NAME_INDEX[name]
    if name in UNIT_INDEX:
        return UNIT_INDEX[name]
    allowed = sorted(SC2_NAME_INDEX)
    raise KeyError(f"unknown unit {name!r}; allowed unit names: {', '.join(allowed)}")


# ---------------------------------------------------------------------------------------------------------------
# The numeric table the kernels read: STATS[type, column], per-loop rates.

STAT_COLUMNS = (
    "health", "shield", "armor", "damage", "hits", "bonus_damage", "bonus_attribute", "cooldown", "range",
    "hits_ground", "hits_air", "speed", "radius", "sight", "attributes", "is_air", "cliff_walk", "weapon",
    "splash_radius", "splash_length", "splash_width", "energy_start", "energy_max", "energy_regen", "heal_rate",
    "heal_energy_per_hp", "regen", "passive", "scan_range", "shield_regen", "mover", "missile_speed",
    "second_hit_delay", "second_hit_reach", "decay", "wind_up", "range_slop",
)
S = {name: i for i, name in enumerate(STAT_COLUMNS)}  # column index by name

_PER_SECOND_COLUMNS = ("speed", "energy_regen", "heal_rate", "regen", "shield_regen", "missile_speed", "decay")


def scan_range(spec: UnitSpec) -> float:
    """Automatic-acquisition range, edge to edge: max(5, weapon range + 0.5) (docs/smac_interface.md §9); a healer's
    is its heal auto-cast range (the medivac's 6, docs/engine_rules.md)."""
    if spec.weapon == WEAPON_HEAL:
        return spec.autocast_range
    return max(5.0, spec.range + 0.5)


def build_stats(units: tuple[UnitSpec, ...] = UNITS) -> np.ndarray:
    """The float64 table ``STATS[type, column]`` with rates converted to per game loop."""
    table = np.zeros((len(units), len(STAT_COLUMNS)), dtype=np.float64)
    spec_fields = {f.name for f in fields(UnitSpec)}
    for row, spec in enumerate(units):
        for col, name in enumerate(STAT_COLUMNS):
            if name == "scan_range":
                value = scan_range(spec)
            elif name == "shield_regen":
                value = SHIELD_REGEN_PER_SECOND if spec.shield > 0 else 0.0
            elif name == "wind_up":  # the damage point in whole game loops: a shot lands on a loop
                value = float(math.ceil(spec.damage_point - 1e-9))
            elif name == "mover":  # movement plane: 0 ground, 1 cliff walker, 2 air (engine.terrain.MOVER_*)
                value = 2.0 if spec.is_air else (1.0 if spec.cliff_walk else 0.0)
            else:
                assert name in spec_fields
                value = float(getattr(spec, name))
            if name in _PER_SECOND_COLUMNS:
                value /= LOOPS_PER_SECOND
            table[row, col] = value
    return table


STATS: np.ndarray = build_stats()
STATS.flags.writeable = False  # shared by every battle and script: a script in the process must not rewrite it
