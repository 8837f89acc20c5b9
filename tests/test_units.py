"""The unit table, through fights worked by hand from StarCraft II's published unit facts.

Each expected number below is derived in a comment from SC2's values (docs/smac_interface.md §8 collects them with
their sources: the SC2 5.0.3 tech-tree dump, SMAC's UnitData.xml, Liquipedia LotV), not read from
``smac_hard_gym/engine/units.py``: a wrong health, shield, armour, damage, bonus, weapon period, range or radius in the
table changes a kill loop or a first shot here. Only two kinds of test compare the table itself, each against a
figure stated outside the code in another form: Liquipedia's Faster-speed speeds and rates, converted.

Normal speed: 16 game loops per second. Weapon periods in loops: marine 0.8608 s = 13.7728, zergling 0.696 s = 11.136,
zealot 1.2 s = 19.2, stalker 1.87 s = 29.92, marauder and colossus 1.5 s = 24, hydralisk 0.825 s = 13.2, spine crawler
1.85 s = 29.6. Each attack first winds up for its weapon's damage point, in whole loops (``WIND_UP``: marine 1, colossus
2, stalker, hydralisk and zergling 3, spine crawler 6, zealot and marauder 0). A weapon whose first attack starts in
loop 0 fires its n-th shot (0-based) at loop W + ceil(n * period), W its wind-up: the later wind-ups overlap the
cooldown (``shot_loop``); without SC2's random weapon delay (``engine_with``). Missiles (stalker 18.75/s, marauder 20/s,
hydralisk 40/s) land ceil(distance / speed per loop) loops after they are fired. Zerg units regenerate 0.2734 HP per
Normal second (SMAC's UnitData.xml) = 0.0170875 per loop, which matters in the zergling and hydralisk fights.
"""

from __future__ import annotations

import pytest
from engine_helpers import WIND_UP, engine_with, loops_until, shot_loop

from smac_hard_gym.engine import CMD_ATTACK, CMD_HOLD
from smac_hard_gym.engine.units import STATS, UNITS, S, unit_index

LOOPS = 16  # game loops per Normal second
FASTER = 1.4  # Normal seconds per Faster second
REGEN = 0.2734 / LOOPS  # zerg HP per loop


def _death_loop(red: str, blue: str, distance: float, max_loops: int = 1000) -> int:
    """0-based loop in which the passive red unit dies to the blue one placed ``distance`` east (centre to centre).

    The blue unit is standard: it acquires the red unit by itself (everything here is within its scan range,
    max(5, range + 0.5) edge to edge) and keeps shooting; the red *_RL unit never answers.
    """
    engine = engine_with([red], [blue], {0: (10.0, 16.0), 1: (10.0 + distance, 16.0)})
    return loops_until(engine, lambda e: not e.state.alive[0, 0], max_loops) - 1


# ---------------------------------------------------------------------------------------------------------------
# Who kills whom, and in which loop: health, shields, armour, damage, hits, bonus and weapon period together.

M, ZL, ST, HY, CO, SP = (WIND_UP[u] for u in ("Marine", "Zergling", "Stalker", "Hydralisk", "Colossus", "SpineCrawler"))
KILLS = [
    # Marine 6 on a zergling (35 HP, armour 0), first shot at loop 1: 6 shots would be 36, but the zergling
    # regenerates from loop 2, 69 x 0.0170875 = 1.18 HP by the 6th shot (loop 1 + ceil(5 x 13.7728) = 70): 35 - 36 +
    # 1.18 = 0.18 left. The 7th, at 1 + ceil(6 x 13.7728) = 84, kills.
    ("Zergling_RL", "Marine", 5.5, shot_loop(6, 13.7728, M), 84),
    # SMAC's hydralisk has 80 HP (UnitData.xml; the standard one 90). Marine 6 per shot: 13 shots (78) by loop
    # 1 + ceil(12 x 13.7728) = 167 leave 2 + 166 x 0.0170875 = 4.8; the 14th at 1 + ceil(13 x 13.7728) = 181 kills
    # (80 - 84 + 3.1 < 0). A 90-HP hydralisk would live to the 16th shot, at loop 208.
    ("Hydralisk_RL", "Marine", 5.5, shot_loop(13, 13.7728, M), 181),
    # Zergling 5 per hit on a marine (45 HP, armour 0): 9 hits, the 9th at 3 + ceil(8 x 11.136) = 93. Melee range
    # 0.1: centre distance 0.8 is 0.05 edge to edge (radii 0.375 + 0.375).
    ("Marine_RL", "Zergling", 0.8, shot_loop(8, 11.136, ZL), 93),
    # Zealot 2 x 8 (no wind-up), the second blade 5 loops after the first, on a zergling (35 HP): blades at 0, 5, 20,
    # 25 (attacks at ceil(19.2) = 20) leave 35 - 32 + 25 x 0.0170875 = 3.4; the 5th, at ceil(2 x 19.2) = 39, kills.
    ("Zergling_RL", "Zealot", 0.925, shot_loop(2, 19.2), 39),
    # Stalker 13 on a marine (light: no +5 armoured bonus): 45 / 13 -> 4 shots, the 4th fired at
    # 3 + ceil(3 x 29.92) = 93 and landing ceil(5 / 1.171875) = 5 loops later.
    ("Marine_RL", "Stalker", 5.0, shot_loop(3, 29.92, ST) + 5, 98),
    # Stalker 13 + 5 on a marauder (armoured, armour 1): 17 per shot, 125 HP -> 8 shots (7 x 17 = 119): the 8th
    # fired at 3 + ceil(7 x 29.92) = 213, landing 5 loops later.
    ("Marauder_RL", "Stalker", 5.0, shot_loop(7, 29.92, ST) + 5, 218),
    # Marauder 10 (no wind-up) on a zealot (light: no +10 armoured bonus): shields 50 take 5 shots; then 10 - 1
    # armour = 9 on 100 HP: 12 shots (11 x 9 = 99). The 17th, fired at 16 x 24 = 384, lands 5 / 1.25 = 4 loops later.
    ("Zealot_RL", "Marauder", 5.0, shot_loop(16, 24.0) + 4, 388),
    # Hydralisk 12 on a marine: 4 shots (48 >= 45), the 4th fired at 3 + ceil(3 x 13.2) = 43, landing
    # ceil(5 / 2.5) = 2 loops later.
    ("Marine_RL", "Hydralisk", 5.0, shot_loop(3, 13.2, HY) + 2, 45),
    # Colossus 2 x 10 on a stalker (armoured, not light: no +5): shields 80 take 4 attacks; then 2 x (10 - 1) = 18
    # per attack on 80 HP: 5 attacks (72, then 90). The 9th attack, at 2 + 8 x 24 = 194, kills. Range 7: centre 8
    # is 6.375 edge to edge (radii 1 + 0.625).
    ("Stalker_RL", "Colossus", 8.0, shot_loop(8, 24.0, CO), 194),
    # Colossus 2 x (10 + 5 light) = 30 per attack on a zergling, the first at loop 2: 5 left (+ 24 x 0.017 regen),
    # dead at the second attack, loop 26.
    ("Zergling_RL", "Colossus", 8.0, shot_loop(1, 24.0, CO), 26),
    # Spine crawler 25 + 5 armoured on a marauder, armour 1: 29 per shot, 125 HP -> 5 shots (4 x 29 = 116): the 5th
    # at 6 + ceil(4 x 29.6) = 125, its tentacle landing ceil(8 / (31 / 16)) = 5 loops later. Range 7: centre 8 is
    # 6.3125 edge to edge (radii 1.125 + 0.5625).
    ("Marauder_RL", "SpineCrawler", 8.0, shot_loop(4, 29.6, SP) + 5, 130),
    # Spine crawler 25 on a zergling (35 HP): 2 shots, the second at 6 + ceil(29.6) = 36, landing 5 loops later.
    ("Zergling_RL", "SpineCrawler", 8.0, shot_loop(1, 29.6, SP) + 5, 41),
]


@pytest.mark.parametrize(("red", "blue", "distance", "by_rule", "by_hand"), KILLS,
                         ids=[f"{b}-kills-{r}" for r, b, *_ in KILLS])
def test_kill_loop_matches_the_hand_computed_fight(red, blue, distance, by_rule, by_hand):
    assert by_rule == by_hand  # the comment's arithmetic, through the same shot rule the engine follows
    assert _death_loop(red, blue, distance) == by_hand


def test_first_hits_show_shields_then_armour():
    # Stalker 13 on a zealot (light, shields 50): the first missile, fired in loop 3 after the wind-up, lands in
    # loop 8 on the shields (50 -> 37). Marauder 10 + 10 on a stalker (armoured): its first grenade (no wind-up)
    # lands in loop 4 on the shields (80 -> 60; shields take no armour).
    stalker = engine_with(["Zealot_RL"], ["Stalker"], {0: (10.0, 16.0), 1: (15.0, 16.0)})
    stalker.step(n_loops=8)
    assert stalker.state.shield[0, 0] == 50.0  # still in flight
    stalker.step(n_loops=1)
    assert (stalker.state.shield[0, 0], stalker.state.health[0, 0]) == pytest.approx((37.0, 100.0))
    marauder = engine_with(["Stalker_RL"], ["Marauder"], {0: (10.0, 16.0), 1: (15.0, 16.0)})
    marauder.step(n_loops=5)
    assert (marauder.state.shield[0, 0], marauder.state.health[0, 0]) == pytest.approx((60.0, 80.0))


# ---------------------------------------------------------------------------------------------------------------
# Weapon range plus both radii: a shooter on hold position starts its attack in loop 0 on a target 0.05 inside its
# range (edge to edge), firing after its wind-up, and never attacks one 0.05 beyond it. Radii: marine and zergling
# 0.375, marauder 0.5625, stalker and hydralisk 0.625, zealot 0.5, colossus 1, spine crawler 1.125. The target is a
# passive *_RL marine (radius 0.375).

RANGES = {"Marine": (5.0, 0.375), "Marauder": (6.0, 0.5625), "Stalker": (6.0, 0.625), "Hydralisk": (5.0, 0.625),
          "Colossus": (7.0, 1.0), "SpineCrawler": (7.0, 1.125), "Zealot": (0.1, 0.5), "Zergling": (0.1, 0.375)}


@pytest.mark.parametrize("inside", [True, False], ids=["inside", "beyond"])
@pytest.mark.parametrize("shooter", sorted(RANGES))
def test_a_holding_shooter_fires_only_within_range_plus_radii(shooter, inside):
    weapon_range, radius = RANGES[shooter]
    centre = weapon_range + radius + 0.375 + (-0.05 if inside else 0.05)
    engine = engine_with(["Marine_RL"], [shooter], {0: (10.0, 16.0), 1: (10.0 + centre, 16.0)})
    engine.commands.kind[0, 1] = CMD_HOLD
    engine.step(n_loops=WIND_UP[shooter] + 1)
    assert bool(engine.state.fired_at[0, 1] == 0) is inside


# ---------------------------------------------------------------------------------------------------------------
# Air: a medivac (air, armour 1, 150 HP) is shot by a marine (hits air) and ignored by a zergling (ground only).

def test_a_marine_shoots_a_medivac_a_zergling_cannot():
    # The marine: 6 - 1 armour = 5 per shot, at loops 1 and 15 (1 + ceil(13.7728)): 140 after 16 loops. The zergling,
    # touching the medivac's ground position, never hits it.
    engine = engine_with(["Medivac_RL"], ["Zergling", "Marine"], {0: (10.0, 16.0), 1: (10.8, 16.0), 2: (15.0, 16.0)})
    engine.step(n_loops=shot_loop(1, 13.7728, WIND_UP["Marine"]) + 1)
    assert engine.state.health[0, 0] == pytest.approx(150.0 - 2 * 5.0)
    engine.place(0, 2, alive=False, health=0.0)
    engine.step(n_loops=48)
    assert engine.state.health[0, 0] == pytest.approx(140.0)


def test_an_ordered_rl_unit_fights_with_the_standard_weapon():
    # SMAC's *_RL marine is passive but its weapon is the marine's: ordered onto a passive *_RL zergling it takes
    # the same 7 shots, to loop 84, as the standard marine of the first fight.
    engine = engine_with(["Marine_RL"], ["Zergling_RL"], {0: (10.0, 16.0), 1: (15.5, 16.0)})
    engine.commands.kind[0, 0] = CMD_ATTACK
    engine.commands.target[0, 0] = 1
    assert loops_until(engine, lambda e: not e.state.alive[0, 1], 200) - 1 == 84


# ---------------------------------------------------------------------------------------------------------------
# The table against figures published in another form: Liquipedia quotes Faster speed; the table is Normal speed.

# Faster-speed movement speeds (Liquipedia LotV) -> Normal speed = / 1.4.
FASTER_SPEED = {"Marine": 3.15, "Marauder": 3.15, "Stalker": 4.13, "Zealot": 3.15, "Colossus": 3.15,
                "Hydralisk": 3.15, "Zergling": 4.13, "Baneling": 3.5, "Medivac": 3.5}


@pytest.mark.parametrize("name", sorted(FASTER_SPEED))
def test_speeds_are_normal_speed(name):
    # Never Faster numbers on the Normal clock (both peer simulators mix them).
    assert UNITS[unit_index(name)].speed == pytest.approx(FASTER_SPEED[name] / FASTER, abs=5e-3)  # LQP rounds to 0.01


def test_rates_are_per_loop_in_the_kernel_table():
    # Liquipedia (Faster): medivac heal 12.6 HP/s, energy 0.7875/s; SMAC's UnitData.xml (Normal): marine speed
    # 2.25, zerg regeneration 0.2734 HP/s, shield regeneration 2/s. The kernels read them per game loop.
    medivac = unit_index("Medivac")
    assert STATS[medivac, S["heal_rate"]] == pytest.approx(12.6 / FASTER / LOOPS)  # 9 HP per Normal second
    assert STATS[medivac, S["energy_regen"]] == pytest.approx(0.7875 / FASTER / LOOPS)
    assert STATS[unit_index("Marine"), S["speed"]] == pytest.approx(2.25 / LOOPS)
    assert STATS[unit_index("Zergling"), S["regen"]] == pytest.approx(0.2734 / LOOPS)
    assert STATS[unit_index("Stalker"), S["shield_regen"]] == pytest.approx(2.0 / LOOPS)


# ---------------------------------------------------------------------------------------------------------------
# The table's shape.

def test_rl_variants_are_passive_and_colosus_is_an_alias():
    for name in ("Marine", "Marauder", "Medivac", "Stalker", "Zealot", "Colossus", "Hydralisk", "Zergling",
                 "Baneling"):
        assert UNITS[unit_index(name + "_RL")].passive
        assert not UNITS[unit_index(name)].passive
    assert UNITS[unit_index("Colosus_RL")] == UNITS[unit_index("Colossus_RL")]  # SMAC's 1c3s5z spelling


def test_every_value_has_a_source():
    for u in UNITS:
        assert u.sources, u.name


def test_unknown_unit_names_the_allowed_ones():
    with pytest.raises(KeyError, match="unknown unit 'Thor'.*Marine"):
        unit_index("Thor")
