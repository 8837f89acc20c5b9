"""Combat mechanics against hand-computed fights from the unit facts of docs/smac_interface.md §8.

Periods in game loops (Normal speed, 16 loops per second): marine 0.8608 s, stalker 1.87 s, zealot 1.2 s,
marauder 1.5 s, colossus 1.5 s. Each attack winds up for its weapon's damage point first (``WIND_UP``, whole loops:
marine 1, stalker 3, colossus 2, zealot and marauder 0), so a weapon whose first attack starts in loop 0 fires its
n-th shot at loop W + ceil(n * period) (``shot_loop``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from engine_helpers import WIND_UP, engine_with, loops_until, shot_loop

from smac_hard_gym.engine import CMD_ATTACK

MARINE_PERIOD = 0.8608 * 16
STALKER_PERIOD = 1.87 * 16
ZEALOT_PERIOD = 1.2 * 16
MARAUDER_PERIOD = 1.5 * 16


def _attack(engine, shooter: int, target: int) -> None:
    engine.commands.kind[:, shooter] = CMD_ATTACK
    engine.commands.target[:, shooter] = target


def _death_loop(engine, slot: int, max_loops: int = 2000) -> int:
    """0-based index of the loop in which ``slot`` dies."""
    return loops_until(engine, lambda e: not e.state.alive[0, slot], max_loops) - 1


def test_marine_duel_is_a_simultaneous_draw():
    # 45 HP / 6 damage, no armour: 8 shots each; both start attacking in loop 0, fire first in loop 1 and die in the
    # same loop.
    engine = engine_with(["Marine_RL"], ["Marine"], {0: (10.0, 16.0), 1: (14.0, 16.0)})
    _attack(engine, 0, 1)  # red is passive and must be ordered; blue acquires it (within 5.5 edge-to-edge)
    health = []
    wind_up = WIND_UP["Marine"]
    for _ in range(shot_loop(7, MARINE_PERIOD, wind_up) + 1):
        engine.step(n_loops=1)
        engine.commands.clear()
        health.append(engine.state.health[0].copy())
    shots = [shot_loop(n, MARINE_PERIOD, wind_up) for n in range(8)]
    assert shots[-1] == 98
    for loop, hp in enumerate(health):
        fired = sum(1 for s in shots if s <= loop)
        expected = max(45.0 - 6.0 * fired, 0.0)
        assert hp[0] == pytest.approx(expected) and hp[1] == pytest.approx(expected), loop
    assert not engine.state.alive[0].any()


def test_stalker_kills_zealot_in_13_shots():
    # 13 damage (no bonus: zealot is light): shields 50 -> 37, 24, 11; 4th shot: 11 absorbed, 2 - 1 armour = 1 HP;
    # then 12 per shot: 99 HP needs 9 more. 13 shots, the last fired at 3 + ceil(12 * 29.92) = 363 (3 loops of
    # wind-up). Each is a missile at 18.75 per second (1.171875 a loop) over 5 centre to centre: it lands
    # ceil(4.27) = 5 loops after it is fired.
    engine = engine_with(["Zealot_RL"], ["Stalker"], {0: (10.0, 16.0), 1: (15.0, 16.0)})
    engine.step(n_loops=8)
    assert engine.state.shield[0, 0] == pytest.approx(50.0)  # fired in loop 3, still in flight
    engine.step(n_loops=1)
    assert engine.state.shield[0, 0] == pytest.approx(37.0)
    assert engine.state.health[0, 0] == pytest.approx(100.0)
    engine.reset()
    for slot, pos in {0: (10.0, 16.0), 1: (15.0, 16.0)}.items():
        engine.place(0, slot, x=pos[0], y=pos[1])
    assert _death_loop(engine, 0) == shot_loop(12, STALKER_PERIOD, WIND_UP["Stalker"]) + 5 == 368


def test_zealot_two_hits_against_stalker_shields_and_armour():
    # 8 x 2 per attack, the second blade 0.28 s (ceil(4.48) = 5 loops) after the first (PsiBladesBurst). Shields 80
    # absorb 10 hits; then 8 - 1 armour = 7 per hit on 80 HP: 12 hits. 22 hits: the second blade of the 11th
    # attack, which starts at ceil(10 * 19.2) = 192, lands at 197.
    engine = engine_with(["Stalker_RL"], ["Zealot"], {0: (10.0, 16.0), 1: (11.2, 16.0)})
    engine.step(n_loops=1)
    assert engine.state.shield[0, 0] == pytest.approx(72.0)  # the first blade
    engine.step(n_loops=4)
    assert engine.state.shield[0, 0] == pytest.approx(72.0)
    engine.step(n_loops=1)
    assert engine.state.shield[0, 0] == pytest.approx(64.0)  # the second blade, in loop 5
    engine.reset()
    for slot, pos in {0: (10.0, 16.0), 1: (11.2, 16.0)}.items():
        engine.place(0, slot, x=pos[0], y=pos[1])
    assert _death_loop(engine, 0) == shot_loop(10, ZEALOT_PERIOD) + 5 == 197


def test_zealot_hits_armour_twice_per_attack():
    # Against a marauder (armour 1, 125 HP): 2 x (8 - 1) = 14 per attack, the second hit 5 loops after the first.
    engine = engine_with(["Marauder_RL"], ["Zealot"], {0: (10.0, 16.0), 1: (11.1, 16.0)})
    engine.step(n_loops=1)
    assert engine.state.health[0, 0] == pytest.approx(118.0)
    engine.step(n_loops=5)
    assert engine.state.health[0, 0] == pytest.approx(111.0)


@pytest.mark.parametrize("victim, first_hit, shots_to_kill", [
    # Marauder 10 (+10 armoured). Marine: light, armour 0 -> 10 per shot, 45 HP: 5 shots.
    ("Marine_RL", {"health": 35.0}, 5),
    # Stalker: armoured -> 20 per shot; shields 80 take 4; then 20 - 1 = 19 on 80 HP: 5 more. 9 shots.
    ("Stalker_RL", {"shield": 60.0, "health": 80.0}, 9),
])
def test_marauder_bonus_against_armoured(victim, first_hit, shots_to_kill):
    # The grenade is a missile at 20 per second (1.25 a loop): over 5 it lands exactly 4 loops after it is fired.
    engine = engine_with([victim], ["Marauder"], {0: (10.0, 16.0), 1: (15.0, 16.0)})
    engine.step(n_loops=5)
    for field, value in first_hit.items():
        assert getattr(engine.state, field)[0, 0] == pytest.approx(value)
    assert 5 + _death_loop(engine, 0) == shot_loop(shots_to_kill - 1, MARAUDER_PERIOD) + 4  # five loops already ran


def test_colossus_line_splash_hits_a_marine_line():
    # Line 2.8 long, 0.3 wide, centred on the target, across the shot. Marines (r 0.375) on the line at offsets
    # 0, +-0.8, +-1.6 touch it (1.6 <= 1.4 + 0.375); at +-2.4 they do not; one 0.8 behind the target does not
    # (0.8 > 0.15 + 0.375). Each touched marine takes 2 x (10 + 5 light) = 30, after the 2-loop wind-up.
    offsets = [0.0, 0.8, -0.8, 1.6, -1.6, 2.4, -2.4]
    red = ["Marine_RL"] * (len(offsets) + 1)
    positions = {k: (16.0, 16.0 + dy) for k, dy in enumerate(offsets)}
    positions[len(offsets)] = (16.8, 16.0)  # behind the target, along the shot
    positions[len(red)] = (10.0, 16.0)  # the colossus, 6 to the west: in range 7 (+ radii)
    engine = engine_with(red, ["Colossus"], positions)
    _attack(engine, len(red), 0)
    engine.step(n_loops=WIND_UP["Colossus"])
    assert (engine.state.health[0, : len(red)] == 45.0).all()
    engine.step(n_loops=1)
    hp = engine.state.health[0]
    expected = [15.0, 15.0, 15.0, 15.0, 15.0, 45.0, 45.0, 45.0]
    np.testing.assert_allclose(hp[: len(red)], expected)


def test_baneling_burst_kills_a_zergling_clump_and_itself():
    # 16 (+19 light) = 35 = a zergling's life; radius 2.2 to the victim's edge (zergling radius 0.375).
    # Edge distances: 0.3 (in melee reach 0.25 + radii), 1.0, 2.1 -> dead; 2.5 -> untouched.
    centre = (16.0, 16.0)
    dists = [0.3 + 0.375 + 0.375, 1.0 + 0.375, 2.1 + 0.375, 2.5 + 0.375]
    positions = {k: (centre[0] + d, centre[1]) if k % 2 == 0 else (centre[0], centre[1] + d)
                 for k, d in enumerate(dists)}
    positions[len(dists)] = centre
    engine = engine_with(["Zergling_RL"] * len(dists), ["Baneling"], positions)
    _attack(engine, len(dists), 0)
    engine.step(n_loops=1)
    st = engine.state
    assert list(st.alive[0, : len(dists)]) == [False, False, False, True]
    assert st.health[0, 3] == pytest.approx(35.0)
    assert not st.alive[0, len(dists)] and st.burst[0, len(dists)]


def test_medivac_heal_rate_and_energy():
    # 12.6 HP per Faster second = 9 HP per Normal second = 0.5625 per loop, 1 energy per 3 HP.
    # Energy regenerates 0.7875 per Faster second = 0.5625 per Normal second.
    engine = engine_with(["Zergling_RL"], ["Medivac", "Marine"], {0: (2.0, 2.0), 1: (16.0, 16.0), 2: (17.0, 16.0)})
    engine.place(0, 2, health=20.0)
    engine.step(n_loops=16)
    st = engine.state
    assert st.health[0, 2] == pytest.approx(29.0)
    assert st.energy[0, 1] == pytest.approx(50.0 + 0.5625 - 3.0)
    assert st.fired_at[0, 1] == 2  # heal link recorded for rendering


def test_medivac_auto_heal_takes_the_lowest_life_fraction_first():
    # MedivacHeal's auto-cast sorts targets by life fraction, then distance (game data, docs/engine_rules.md): of two
    # damaged marines in heal range 4, the one at 10/45 is healed before the nearer one at 40/45. Radii 0.75 + 0.375:
    # edge distances 0.375 and 3.375, so the medivac heals without moving: 8 loops x 0.5625 HP.
    engine = engine_with(["Marine_RL"], ["Medivac", "Marine", "Marine"],
                         {0: (30.0, 16.0), 1: (10.0, 16.0), 2: (11.5, 16.0), 3: (14.5, 16.0)})
    engine.place(0, 2, health=40.0)
    engine.place(0, 3, health=10.0)
    engine.step(n_loops=8)
    st = engine.state
    assert st.health[0, 2] == pytest.approx(40.0)
    assert st.health[0, 3] == pytest.approx(14.5)
    assert (st.x[0, 1], st.y[0, 1]) == pytest.approx((10.0, 16.0))


@pytest.mark.parametrize(("gap", "healed"), [(5.5, True), (6.5, False)])
def test_medivac_auto_heal_reaches_six(gap, healed):
    # AutoCastRange 6, edge to edge: a damaged marine 5.5 away is taken (the medivac flies into heal range 4 and
    # heals); one 6.5 away is not.
    engine = engine_with(["Marine_RL"], ["Medivac", "Marine"],
                         {0: (30.0, 4.0), 1: (10.0, 16.0), 2: (10.0 + 1.125 + gap, 16.0)})
    engine.place(0, 2, health=20.0)
    engine.step(n_loops=48)
    assert bool(engine.state.health[0, 2] > 20.0) is healed


def test_medivac_stops_when_out_of_energy():
    engine = engine_with(["Zergling_RL"], ["Medivac", "Marine"], {0: (2.0, 2.0), 1: (16.0, 16.0), 2: (17.0, 16.0)})
    engine.place(0, 2, health=10.0)
    engine.place(0, 1, energy=1.0)
    engine.step(n_loops=16)
    st = engine.state
    regen = 0.5625 / 16
    # Each loop regen comes first, then the heal spends what it can: total healed = 3 x (1 + 16 x regen).
    assert st.health[0, 2] == pytest.approx(10.0 + 3.0 * (1.0 + 16 * regen))
    assert st.energy[0, 1] == pytest.approx(0.0, abs=1e-9)


def test_shields_regenerate_after_ten_seconds_without_damage():
    # One marine shot (6, in loop 1 after the wind-up) on a stalker's shield, then the marine is removed. Shields
    # wait 160 loops (10 Normal seconds), then regenerate 2 per second = 0.125 per loop.
    engine = engine_with(["Stalker_RL"], ["Marine"], {0: (10.0, 16.0), 1: (14.0, 16.0)})
    engine.step(n_loops=2)
    assert engine.state.shield[0, 0] == pytest.approx(74.0)
    engine.place(0, 1, alive=False, health=0.0)
    engine.step(n_loops=159)  # 160 loops since the hit (it landed in loop 1)
    assert engine.state.shield[0, 0] == pytest.approx(74.0)
    engine.step(n_loops=8)
    assert engine.state.shield[0, 0] == pytest.approx(74.0 + 8 * 0.125)
    engine.step(n_loops=16 * 4)
    assert engine.state.shield[0, 0] == pytest.approx(80.0)


def test_zerg_health_regeneration():
    engine = engine_with(["Zergling_RL"], ["Marine"], {0: (4.0, 4.0), 1: (28.0, 28.0)})
    engine.place(0, 0, health=20.0)
    engine.step(n_loops=16)
    assert engine.state.health[0, 0] == pytest.approx(20.0 + 0.2734)


def test_a_spine_crawler_off_creep_decays_and_dies():
    # Game data: a Zerg structure off creep (ZergBuildingNotOnCreep) takes 1 damage every 0.3332 Normal s, armour
    # aside, while it keeps regenerating 0.2734 HP per Normal s (Liquipedia, Creep: 4.2 - 0.38 = 3.82 per Faster s).
    # SMAC's maps have no creep. From full health the first loop has nothing to regenerate: after 16 loops the
    # crawler has lost 16 x (1 / 0.3332) / 16 and regained 15 x 0.2734 / 16.
    engine = engine_with(["Stalker_RL"], ["SpineCrawler"], {0: (4.0, 4.0), 1: (28.0, 28.0)})
    engine.step(n_loops=16)
    assert engine.state.health[0, 1] == pytest.approx(300.0 - 1.0 / 0.3332 + 15 * 0.2734 / 16)
    # Net 2.7278 HP a Normal second: 300 HP last 109.98 s, loop 1760 (no kill credit: nobody attacked it).
    engine.step(n_loops=1759 - 16)
    assert engine.state.alive[0, 1]
    engine.step(n_loops=2)
    assert not engine.state.alive[0, 1]
    assert engine.state.health[0, 0] == 80.0  # the stalker never fought


def test_passive_learner_units_do_not_respond():
    # A *_RL marine being shot does nothing; a standard marine being shot answers (response when attacked).
    engine = engine_with(["Marine_RL"], ["Marine"], {0: (10.0, 16.0), 1: (14.0, 16.0)})
    engine.step(n_loops=32)
    assert engine.state.health[0, 1] == pytest.approx(45.0)
    assert engine.state.health[0, 0] < 45.0


def _shot_loops(seed: int, loops: int = 600, jitter=(-1.0, 2.0)) -> list[int]:
    """Loops at which a blue marine fires at a passive colossus (enough life for ~65 shots)."""
    engine = engine_with(["Colossus_RL"], ["Marine"], {0: (10.0, 16.0), 1: (15.0, 16.0)}, cooldown_jitter=jitter)
    engine.reset(seeds=[seed])
    for slot, pos in {0: (10.0, 16.0), 1: (15.0, 16.0)}.items():
        engine.place(0, slot, x=pos[0], y=pos[1])
    shots = []
    for loop in range(loops):
        engine.step(n_loops=1)
        if engine.state.fired_at[0, 1] == 0:
            shots.append(loop)
    return shots


def test_random_weapon_delay_stays_in_sc2_bounds_and_is_seeded():
    # SC2 delays each attack by -0.0625..+0.125 game seconds = -1..+2 loops around the 13.77-loop period.
    shots = _shot_loops(seed=11)
    gaps = np.diff(shots)
    assert len(gaps) > 30
    assert gaps.min() >= math.floor(MARINE_PERIOD - 1.0) and gaps.max() <= math.ceil(MARINE_PERIOD + 2.0)
    assert len(set(gaps.tolist())) > 1  # not a fixed rhythm
    # The mean period is the base period plus the mean delay (+0.5 loop), within sampling error.
    assert np.mean(gaps) == pytest.approx(MARINE_PERIOD + 0.5, abs=0.35)
    assert _shot_loops(seed=11) == shots
    assert _shot_loops(seed=12) != shots
    assert np.diff(_shot_loops(seed=11, jitter=None)).max() <= math.ceil(MARINE_PERIOD)
