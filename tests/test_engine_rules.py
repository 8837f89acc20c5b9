"""Pushing, missiles and the zealot's second blade, against situations worked by hand from StarCraft II's rules
(docs/engine_rules.md cites each rule: sections 1 and 2).

Speeds per game loop: marine and zealot 2.25 / 16 = 0.140625. Without SC2's random weapon delay (``engine_with``).
"""

from __future__ import annotations

import numpy as np
import pytest
from engine_helpers import engine_with, on_grid

from smac_hard_gym.engine import CMD_ATTACK, CMD_HOLD, CMD_MOVE, CMD_STOP
from smac_hard_gym.engine.kernels import POSITION_GRID

STEP = 0.140625


def _order(engine, slot: int, kind: int, target: int = -1, point: tuple[float, float] = (0.0, 0.0)) -> None:
    engine.commands.kind[0, slot] = kind
    engine.commands.target[0, slot] = target
    engine.commands.x[0, slot], engine.commands.y[0, slot] = point


def _run(engine, loops: int) -> None:
    """The orders given so far, then ``loops`` game loops with no new command (orders persist)."""
    engine.step(n_loops=loops)
    engine.commands.clear()


# --- Pushing (section 1). Every SMAC unit has push priority 10: enemies neither push nor are pushed.


def test_a_walker_does_not_push_an_enemy_it_walks_into_and_goes_round_it():
    # A zealot (r 0.5) walks east into an idle marine (r 0.375) 2 away: it touches at 15.125 (centre distance 0.875)
    # after 8 loops and is put back there in loop 9 (enemies push nobody). In loop 10 it steers (C11): straight on,
    # 30 and 60 degrees still bring it closer than 0.875, 90 degrees does not; with the marine dead ahead it turns
    # north first. The marine never moves, and the zealot passes it.
    engine = engine_with(["Marine_RL"], ["Zealot"], {0: (16.0, 16.0), 1: (14.0, 16.0)})
    _order(engine, 1, CMD_MOVE, point=(20.0, 16.0))
    _run(engine, 9)
    st = engine.state
    assert st.x[0, 1] == pytest.approx(15.125) and st.y[0, 1] == pytest.approx(16.0)
    _run(engine, 1)
    assert st.x[0, 1] == pytest.approx(15.125) and st.y[0, 1] == pytest.approx(16.0 + STEP)
    closest = _closest_approach(engine, [0], 1, 40)
    assert (st.x[0, 0], st.y[0, 0]) == (16.0, 16.0)
    assert closest >= 0.875 - 1e-9 and st.x[0, 1] > 16.875


def _closest_approach(engine, others: list[int], j: int, loops: int) -> float:
    """Run ``loops`` single loops; the smallest centre distance from unit j to any of ``others`` seen after each."""
    st = engine.state
    closest = float("inf")
    for _ in range(loops):
        _run(engine, 1)
        closest = min(closest, float(np.hypot(st.x[0, others] - st.x[0, j], st.y[0, others] - st.y[0, j]).min()))
    return closest


@pytest.mark.parametrize("stand", [CMD_ATTACK, CMD_HOLD], ids=["firing", "holding"])
def test_own_units_standing_in_the_way_are_not_pushed_and_a_walker_goes_round(stand):
    # Marine A fires at a medivac 4 away (in range 5 + radii), or holds; marine B walks from 8 toward 13 behind it.
    # B touches A (radii 0.75) at 9.25 in loop 9 and is put back there; in loop 10 it steps north (90 degrees:
    # 30 and 60 would close in on A), then goes round and reaches its point. A never moves. (A is not idle, so B
    # does not arrive by bumping into it.)
    engine = engine_with(["Marine_RL", "Marine_RL"], ["Medivac"], {0: (10.0, 16.0), 1: (8.0, 16.0), 2: (14.0, 16.0)})
    _order(engine, 0, stand, target=2)
    _order(engine, 1, CMD_MOVE, point=(13.0, 16.0))
    _run(engine, 9)
    st = engine.state
    assert (st.x[0, 1], st.y[0, 1]) == (pytest.approx(9.25), pytest.approx(16.0))
    _run(engine, 1)
    assert (st.x[0, 1], st.y[0, 1]) == (pytest.approx(9.25), pytest.approx(16.0 + STEP))
    closest = _closest_approach(engine, [0], 1, 50)
    assert (st.x[0, 0], st.y[0, 0]) == (10.0, 16.0) and closest >= 0.75 - 1e-9
    assert np.hypot(st.x[0, 1] - 13.0, st.y[0, 1] - 16.0) <= 0.05
    if stand == CMD_ATTACK:
        assert st.health[0, 2] < 150.0  # A kept firing


def test_a_walker_shoves_an_idle_own_unit_sharing_the_overlap():
    # As above with A idle and B walking to a point far beyond (no group arrival): B overlaps A by 0.015625 in loop
    # 9 (each moves half), then by one step a loop, so both advance half a step a loop for the 15 loops after.
    engine = engine_with(["Marine_RL", "Marine_RL"], ["Medivac"], {0: (10.0, 16.0), 1: (8.0, 16.0), 2: (14.0, 4.0)})
    _order(engine, 1, CMD_MOVE, point=(30.0, 16.0))
    _run(engine, 24)
    st = engine.state
    assert st.x[0, 0] == pytest.approx(10.0 + 0.015625 / 2 + 15 * STEP / 2)  # 11.0625
    assert st.x[0, 1] == pytest.approx(8.0 + 9 * STEP - 0.015625 / 2 + 15 * STEP / 2)  # 10.3125


# A wall of marines on hold across a corridor 4 high (rows 14-17, so centres 14 <= y < 18): B, a marine, walks east
# into it from (8, 16.6). Ends: the wall's outer marines leave less than B's diameter (0.75) to the corridor's walls.
WIDE_GAP = (14.375, 15.0, 16.75, 17.5)  # 1.0 free between 15.0 and 16.75 (edges 15.375, 16.375)
NARROW_GAP = (14.375, 15.125, 16.5, 17.25)  # 0.625 free between 15.125 and 16.5: less than 0.75


@pytest.mark.parametrize(("wall", "passes"), [(WIDE_GAP, True), (NARROW_GAP, False)], ids=["room", "no-room"])
def test_a_walker_goes_through_a_gap_with_room_and_waits_behind_one_without(wall, passes):
    # With room, B (blocked by the marine at 16.75, on its left) turns right first and goes through the gap. Without
    # room it can at most wedge into the gap until it touches both sides, 0.6875 above and below its centre line:
    # x = 10 - sqrt(0.75^2 - 0.6875^2) = 9.70; it waits there, never closer than 0.75 to any.
    positions = {k: (10.0, y) for k, y in enumerate(wall)} | {len(wall): (8.0, 16.6), len(wall) + 1: (14.0, 4.0)}
    engine = engine_with(["Marine_RL"] * (len(wall) + 1), ["Medivac"], positions, band=(14, 18))
    for k in range(len(wall)):
        _order(engine, k, CMD_HOLD)
    walker = len(wall)
    _order(engine, walker, CMD_MOVE, point=(13.0, 16.6))
    closest = _closest_approach(engine, list(range(len(wall))), walker, 60)
    st = engine.state
    assert closest >= 0.75 - 1 / POSITION_GRID  # positions end each loop on SC2's 1/4096 grid
    assert [(st.x[0, k], st.y[0, k]) for k in range(len(wall))] == [(10.0, y) for y in wall]
    if passes:
        assert st.x[0, walker] > 10.75
    else:
        assert st.x[0, walker] <= 10.0 - np.sqrt(0.75**2 - 0.6875**2) + 1e-9


def test_a_walker_in_a_pocket_between_two_units_slides_out_along_one_and_goes_round():
    # Marines A (10, 16.4) and C (10, 15.6) hold, 0.8 apart: 0.05 between them, no room for a marine. B walks from
    # (8, 16) to (13, 16) into the crack. In loop 10 it overlaps both by 0.75 - hypot(0.59375, 0.4) and is put back
    # by the sum of the two pushes: x = 9.40625 - 2 * depth * 0.59375 / hypot(0.59375, 0.4) = 9.3497 (on the grid:
    # 9.349609375). In loop 11 every turn up to 90 degrees either way closes on A or C (the 90-degree turns end
    # 0.700 from them), so it slides along A, the unit in its way (A and C equally deep; the first found): the
    # tangent on C's side closes on C, the one on A's far side is free (0.776 from A, moving away from C). It keeps
    # that side, goes round A and reaches its point. With turns up to 90 degrees only, it waited at 9.3497 for ever.
    engine = engine_with(["Marine_RL"] * 3, ["Medivac"], {0: (10.0, 16.4), 1: (10.0, 15.6), 2: (8.0, 16.0),
                                                         3: (14.0, 4.0)})
    _order(engine, 0, CMD_HOLD)
    _order(engine, 1, CMD_HOLD)
    _order(engine, 2, CMD_MOVE, point=(13.0, 16.0))
    _run(engine, 10)
    st = engine.state
    d = np.hypot(10.0 - 9.40625, 0.4)
    x10 = on_grid(9.40625 - 2 * (0.75 - d) * (10.0 - 9.40625) / d)
    assert (st.x[0, 2], st.y[0, 2]) == (x10, 16.0)
    _run(engine, 1)
    cx, cy = 10.0 - x10, 0.4  # A seen from B
    c = np.hypot(cx, cy)
    assert (st.x[0, 2], st.y[0, 2]) == (on_grid(x10 - cy / c * STEP), on_grid(16.0 + cx / c * STEP))
    closest = _closest_approach(engine, [0, 1], 2, 60)
    assert closest >= 0.75 - 1 / POSITION_GRID
    assert [(st.x[0, k], st.y[0, k]) for k in (0, 1)] == [(10.0, 16.4), (10.0, 15.6)]
    assert np.hypot(st.x[0, 2] - 13.0, st.y[0, 2] - 16.0) <= 0.05


def test_two_walkers_going_round_a_wall_the_opposite_ways_pass_instead_of_standing():
    # A wall of three marines holds at x = 10 (y 15.25, 16.0, 16.75: touching, no gap). B (9.2, 15.6) walks to
    # (13, 18), round the wall's north end, C (9.2, 16.4) to (13, 14), round its south end: their paths cross behind
    # the wall. Each is put back by the wall and steers away from the wall unit in its way, B north (left), C south
    # (right), into each other; own walkers shove each other apart, so without C14 each one's only free turn led
    # into the other and both stood at (9.26, 15.62) and (9.26, 16.38) for ever. SC2's units retry any opening (PATH)
    # and go round (FLOW). With C14 the one farther from its goal takes the other's side; here the two are equally
    # far (3.8^2 + 2.4^2 each), so C (the higher slot) follows B round the north end, and both get there.
    wall = {0: (10.0, 15.25), 1: (10.0, 16.0), 2: (10.0, 16.75)}
    engine = engine_with(["Marine_RL"] * 5, ["Medivac"], wall | {3: (9.2, 15.6), 4: (9.2, 16.4), 5: (20.0, 4.0)})
    for k in wall:
        _order(engine, k, CMD_HOLD)
    _order(engine, 3, CMD_MOVE, point=(13.0, 18.0))
    _order(engine, 4, CMD_MOVE, point=(13.0, 14.0))
    st = engine.state
    crossed = {}
    closest = float("inf")
    for _ in range(120):
        _run(engine, 1)
        for k in (3, 4):
            if k not in crossed and st.x[0, k] >= 10.0:
                crossed[k] = float(st.y[0, k])
        gaps = np.hypot(st.x[0, :3, None] - st.x[0, None, 3:5], st.y[0, :3, None] - st.y[0, None, 3:5])
        closest = min(closest, float(gaps.min()))
    assert [(st.x[0, k], st.y[0, k]) for k in wall] == list(wall.values())
    assert closest >= 0.75 - 1 / POSITION_GRID
    assert set(crossed) == {3, 4} and min(crossed.values()) >= 16.75 + 0.75 - 1 / POSITION_GRID  # both went north
    assert np.hypot(st.x[0, 3] - 13.0, st.y[0, 3] - 18.0) <= 0.05
    assert np.hypot(st.x[0, 4] - 13.0, st.y[0, 4] - 14.0) <= 0.05


# --- The wind-up (section 2, C5): a weapon fires its data's DamagePoint after the attack starts, in whole loops
# (stalker 0.167 s = 2.67 loops: 3). A changed order during the wind-up cancels the shot and spends no cooldown
# (Liquipedia, Stutter Step: a move given once the shot is out keeps its damage); a repeated order changes nothing.


def _stalker_on_a_marine():
    """A passive stalker 5 from a marine (in range 6 + radii), ordered onto it."""
    engine = engine_with(["Stalker_RL"], ["Marine_RL"], {0: (10.0, 16.0), 1: (15.0, 16.0)})
    _order(engine, 0, CMD_ATTACK, target=1)
    return engine


def test_a_changed_order_in_the_wind_up_cancels_the_shot_at_no_cost():
    engine = _stalker_on_a_marine()
    _run(engine, 2)  # two of the three wind-up loops
    assert engine.state.pending_target[0, 0] == -1 and engine.state.cooldown[0, 0] == 0.0
    _order(engine, 0, CMD_STOP)  # the passive stalker then stands idle
    _run(engine, 6)
    assert engine.state.pending_target[0, 0] == -1 and engine.state.cooldown[0, 0] == 0.0
    assert engine.state.health[0, 1] == 45.0
    _order(engine, 0, CMD_ATTACK, target=1)  # a new attack winds up from the start: 3 loops, not the 1 left
    _run(engine, 3)
    assert engine.state.pending_target[0, 0] == -1
    _run(engine, 1)
    assert engine.state.pending_target[0, 0] == 1 and engine.state.cooldown[0, 0] == pytest.approx(29.92)


def test_a_repeated_order_keeps_the_wind_up():
    # SMAC's controllers send their order every step: the same attack, sent in each of loops 0 to 3, fires in loop 3.
    engine = _stalker_on_a_marine()
    for loop in range(4):
        assert engine.state.pending_target[0, 0] == -1, loop
        _order(engine, 0, CMD_ATTACK, target=1)
        _run(engine, 1)
    assert engine.state.pending_target[0, 0] == 1


def test_a_move_after_the_shot_keeps_its_damage():
    # Stutter step: the stalker fires in loop 3 and is sent walking in loop 4; its missile still lands in loop 8
    # (5 centre to centre at 1.171875 a loop: 5 loops).
    engine = _stalker_on_a_marine()
    _run(engine, 4)
    _order(engine, 0, CMD_MOVE, point=(4.0, 16.0))
    _run(engine, 4)
    assert engine.state.health[0, 1] == 45.0
    _run(engine, 1)
    assert engine.state.health[0, 1] == pytest.approx(45.0 - 13.0)
    assert engine.state.x[0, 0] < 10.0


# --- Range slop (section 2, C8): a weapon's RangeSlop (1 by core's default, 0 for the colossus's ThermalLances and
# the spine crawler's ImpalerTentacle) is how far past its range the target of an attack in progress may go before
# the attack is cancelled. Starting an attack still needs the plain range.


def _hydralisk_on_a_marine(distance: float):
    """A passive hydralisk (r 0.625, range 5: reach 6 centre to centre with the marine's r 0.375) ordered onto a
    marine ``distance`` east of it, run one loop: its 3-loop wind-up (0.14 s) has started."""
    engine = engine_with(["Hydralisk_RL"], ["Marine_RL"], {0: (10.0, 16.0), 1: (10.0 + distance, 16.0)})
    _order(engine, 0, CMD_ATTACK, target=1)
    _run(engine, 1)
    return engine


def test_a_target_walking_out_of_range_in_the_wind_up_still_takes_the_shot():
    # The marine, 5.9 away, walks east at the hydralisk's own speed from loop 1: 6.04, 6.18, 6.32 at loops 1-3, out
    # of range but within 6 + 1 of slop. The hydralisk stands through its wind-up and fires in loop 3; the spine
    # flies ceil(6.32 / 2.5) = 3 loops and lands in loop 6 (12 damage, armour 0). Then it chases at equal speed and
    # never gets in range again.
    engine = _hydralisk_on_a_marine(5.9)
    _order(engine, 1, CMD_MOVE, point=(30.0, 16.0))
    _run(engine, 3)
    assert engine.state.x[0, 0] == 10.0
    assert engine.state.pending_target[0, 0] == 1
    _run(engine, 2)
    assert engine.state.health[0, 1] == 45.0
    _run(engine, 1)
    assert engine.state.health[0, 1] == pytest.approx(33.0)
    _run(engine, 24)
    assert engine.state.health[0, 1] == pytest.approx(33.0)
    assert engine.state.x[0, 0] > 10.0


@pytest.mark.parametrize(("distance", "fires"), [(6.95, True), (7.05, False)])
def test_the_attack_in_progress_is_cancelled_beyond_the_slop(distance, fires):
    # The marine is moved to ``distance`` (reach 6 plus slop 1 = 7) once the wind-up has started; a cancelled attack
    # spends no cooldown (the hydralisk then walks after it).
    engine = _hydralisk_on_a_marine(5.9)
    engine.place(0, 1, x=10.0 + distance)
    _order(engine, 1, CMD_HOLD)
    _run(engine, 3)  # loops 1-3: the shot is due in loop 3
    assert (engine.state.pending_target[0, 0] == 1) == fires
    assert (engine.state.cooldown[0, 0] > 0.0) == fires


def test_the_colossus_has_no_slop():
    # ThermalLances' RangeSlop is 0: a colossus (r 1, range 7: reach 8.375 to a marine) whose target steps from 8.3
    # to 8.5 during its 2-loop wind-up (0.0832 s, due in loop 2) walks after it instead. Its new attack starts in
    # loop 1, back in reach (8.359), and is due in loop 3: nothing has fired after loops 0-2.
    engine = engine_with(["Colossus_RL"], ["Marine_RL"], {0: (10.0, 16.0), 1: (18.3, 16.0)})
    _order(engine, 0, CMD_ATTACK, target=1)
    _run(engine, 1)
    engine.place(0, 1, x=18.5)
    _order(engine, 1, CMD_HOLD)
    _run(engine, 2)
    assert engine.state.health[0, 1] == 45.0 and engine.state.cooldown[0, 0] == 0.0


# --- Missiles (section 2): the stalker's, hydralisk's and marauder's shots fly; they home, never miss, and land
# even if the shooter has died.


def test_a_hydralisk_spine_lands_after_its_flight():
    # Hydralisk (r 0.625) 4 from a zealot (r 0.5) on hold: in range 5 + radii, it starts its attack in loop 0 and
    # fires in loop 3 (wind-up 0.14 s = 2.24 loops, rounded up). 40 per second = 2.5 a loop: ceil(4 / 2.5) = 2
    # loops, so the 12 damage lands in loop 5 (on the shield).
    engine = engine_with(["Hydralisk_RL"], ["Zealot"], {0: (10.0, 16.0), 1: (14.0, 16.0)})
    _order(engine, 1, CMD_HOLD)
    _order(engine, 0, CMD_ATTACK, target=1)
    shields = []
    for _ in range(7):
        _run(engine, 1)
        shields.append(float(engine.state.shield[0, 1]))
    assert shields == [50.0] * 5 + [38.0, 38.0]


def test_a_missile_lands_after_its_shooter_died():
    # A stalker fires at a marine 5 away in loop 3, after its 3-loop wind-up (flight ceil(5 / 1.171875) = 5 loops,
    # landing in loop 8), and is killed right after.
    engine = engine_with(["Marine_RL"], ["Stalker"], {0: (10.0, 16.0), 1: (15.0, 16.0)})
    _run(engine, 4)
    engine.place(0, 1, alive=False, health=0.0)
    _run(engine, 4)
    assert engine.state.health[0, 0] == 45.0
    _run(engine, 1)
    assert engine.state.health[0, 0] == pytest.approx(45.0 - 13.0)


def test_a_missile_at_a_unit_that_died_in_flight_hits_nobody():
    # The stalker fires at marine 0 in loop 3 (wind-up), its missile due in loop 8; marine 0 dies in flight. The
    # stalker turns on marine 1 (6.4 away) from loop 4 and fires in loop 7, a 6-loop flight: nothing lands on
    # marine 1 by loop 11.
    engine = engine_with(["Marine_RL", "Marine_RL"], ["Stalker"], {0: (10.0, 16.0), 1: (10.0, 12.0), 2: (15.0, 16.0)})
    _order(engine, 2, CMD_ATTACK, target=0)
    _run(engine, 4)
    assert engine.state.pending_target[0, 2] == 0
    engine.place(0, 0, alive=False, health=0.0)
    _run(engine, 8)
    assert engine.state.health[0, 1] == 45.0 and engine.state.health[0, 0] == 0.0


# --- The zealot's second blade (section 2): PsiBladesBurst deals its second hit 0.28 s (5 loops) after the
# first, only within 2.1 of the zealot (validator ZealotAttackDamageMaxRange; centre to centre is a guess).


@pytest.mark.parametrize(("marine_x", "second_lands"), [(12.5, True), (13.0, False)])
def test_the_second_blade_needs_the_target_within_reach(marine_x, second_lands):
    # The zealot hits a marine (edge distance 0.025) in loop 0; the marine is then moved away. The zealot chases
    # 5 steps (10.703125 at loop 5): centre distance 1.797 <= 2.1 lands the second blade, 2.297 does not.
    engine = engine_with(["Marine_RL"], ["Zealot"], {0: (10.9, 16.0), 1: (10.0, 16.0)})
    _order(engine, 1, CMD_ATTACK, target=0)
    _run(engine, 1)
    assert engine.state.health[0, 0] == pytest.approx(37.0)
    engine.place(0, 0, x=marine_x)
    _run(engine, 5)
    assert engine.state.x[0, 1] == pytest.approx(10.0 + 5 * STEP)
    assert engine.state.health[0, 0] == pytest.approx(29.0 if second_lands else 37.0)


def test_the_second_blade_is_lost_if_the_zealot_dies():
    engine = engine_with(["Marine_RL"], ["Zealot"], {0: (10.9, 16.0), 1: (10.0, 16.0)})
    _order(engine, 1, CMD_ATTACK, target=0)
    _run(engine, 1)
    engine.place(0, 1, alive=False, health=0.0)
    _run(engine, 8)
    assert engine.state.health[0, 0] == pytest.approx(37.0)
