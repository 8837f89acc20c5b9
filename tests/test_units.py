"""The unit table against the facts of docs/smac_interface.md §8: Normal-speed units, SMAC's *_RL variants."""

from __future__ import annotations

import pytest

from smac_hard_gym.units import ARMORED, BIO, LIGHT, MASSIVE, STATS, UNITS, S, unit_index

LOOPS = 16  # game loops per Normal second
FASTER = 1.4  # Normal seconds per Faster second

# (health, shield, armor, damage x hits, bonus, weapon period in Normal seconds, range, radius, sight), from §8.
FACTS = {
    "Marine": (45, 0, 0, 6, 1, 0, 0.8608, 5, 0.375, 9),
    "Marauder": (125, 0, 1, 10, 1, 10, 1.5, 6, 0.5625, 10),
    "Stalker": (80, 80, 1, 13, 1, 5, 1.87, 6, 0.625, 10),
    "Zealot": (100, 50, 1, 8, 2, 0, 1.2, 0.1, 0.5, 9),
    "Colossus": (200, 150, 1, 10, 2, 5, 1.5, 7, 1.0, 10),
    "Hydralisk": (90, 0, 0, 12, 1, 0, 0.825, 5, 0.625, 9),
    "Zergling": (35, 0, 0, 5, 1, 0, 0.696, 0.1, 0.375, 8),
    "SpineCrawler": (300, 0, 2, 25, 1, 5, 1.85, 7, 1.125, 11),
}
# Faster-speed movement speeds (Liquipedia LotV) -> Normal speed = / 1.4.
FASTER_SPEED = {"Marine": 3.15, "Marauder": 3.15, "Stalker": 4.13, "Zealot": 3.15, "Colossus": 3.15,
                "Hydralisk": 3.15, "Zergling": 4.13, "Baneling": 3.5, "Medivac": 3.5}


@pytest.mark.parametrize("name", sorted(FACTS))
def test_standard_stats(name):
    u = UNITS[unit_index(name)]
    health, shield, armor, damage, hits, bonus, period_s, rng, radius, sight = FACTS[name]
    assert (u.health, u.shield, u.armor, u.damage, u.hits, u.bonus_damage) == (health, shield, armor, damage, hits,
                                                                               bonus)
    assert u.cooldown == pytest.approx(period_s * LOOPS)
    assert (u.range, u.radius, u.sight) == (rng, radius, sight)
    assert not u.passive


@pytest.mark.parametrize("name", sorted(FASTER_SPEED))
def test_speeds_are_normal_speed(name):
    # Never Faster numbers on the Normal clock (both peer simulators mix them).
    assert UNITS[unit_index(name)].speed == pytest.approx(FASTER_SPEED[name] / FASTER, abs=5e-3)  # LQP rounds to 0.01


def test_rates_are_per_loop_in_the_kernel_table():
    medivac = unit_index("Medivac")
    assert STATS[medivac, S["heal_rate"]] == pytest.approx(12.6 / FASTER / LOOPS)  # 9 HP per Normal second
    assert STATS[medivac, S["energy_regen"]] == pytest.approx(0.7875 / FASTER / LOOPS)
    assert STATS[unit_index("Marine"), S["speed"]] == pytest.approx(2.25 / LOOPS)
    assert STATS[unit_index("Zergling"), S["regen"]] == pytest.approx(0.2734 / LOOPS)
    assert STATS[unit_index("Stalker"), S["shield_regen"]] == pytest.approx(2.0 / LOOPS)


def test_attributes_and_bonuses():
    assert UNITS[unit_index("Marauder")].bonus_attribute == ARMORED
    assert UNITS[unit_index("Colossus")].bonus_attribute == LIGHT
    assert UNITS[unit_index("Colossus")].attributes & MASSIVE and UNITS[unit_index("Colossus")].cliff_walk
    assert UNITS[unit_index("Baneling")].bonus_damage == 19 and UNITS[unit_index("Baneling")].splash_radius == 2.2
    assert UNITS[unit_index("Medivac")].is_air and not UNITS[unit_index("Medivac")].hits_ground
    assert UNITS[unit_index("Marine")].attributes == LIGHT | BIO


def test_rl_variants_are_passive_with_smac_custom_values():
    for name in ("Marine", "Marauder", "Medivac", "Stalker", "Zealot", "Colossus", "Hydralisk", "Zergling",
                 "Baneling"):
        assert UNITS[unit_index(name + "_RL")].passive
    assert UNITS[unit_index("Hydralisk_RL")].health == 80  # SMAC's custom value (standard 90)
    assert UNITS[unit_index("Medivac_RL")].speed == 2.75  # SMAC's faster medivac
    assert UNITS[unit_index("Colosus_RL")] == UNITS[unit_index("Colossus_RL")]  # SMAC's 1c3s5z spelling


def test_every_value_has_a_source():
    for u in UNITS:
        assert u.sources, u.name


def test_unknown_unit_names_the_allowed_ones():
    with pytest.raises(KeyError, match="unknown unit 'Thor'.*Marine"):
        unit_index("Thor")
