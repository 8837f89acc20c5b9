"""SC2's automatic targeting for units that acquire (docs/smac_interface.md §9): idle and attack-moving units take the
closest enemy within scan range (max(5, range + 0.5), edge to edge), prefer an enemy that is attacking them, answer
a hit from beyond that range, and holding units only shoot what is in weapon range. SMAC's *_RL units are passive.
"""

from __future__ import annotations

import pytest
from engine_helpers import WIND_UP, engine_with, shot_loop

from smac_hard_gym.engine import CMD_ATTACK, CMD_ATTACK_MOVE, CMD_HOLD, CMD_MOVE
from smac_hard_gym.engine.kernels import POSITION_GRID
from smac_hard_gym.engine.state import ORDER_IDLE

R = 0.375  # marine radius
STALKER_PERIOD = 1.87 * 16  # game loops between a stalker's shots


def test_idle_unit_acquires_the_closest_enemy_in_scan_range():
    # Marine scan range 5.5 edge to edge = 6.25 centre to centre. Enemies at 6.0 (in) and 6.1 (in, farther).
    engine = engine_with(["Marine_RL", "Marine_RL"], ["Marine"], {0: (10.0, 16.0), 1: (16.0, 22.1),
                                                                    2: (16.0, 16.0)})
    engine.step(n_loops=1)
    assert engine.state.target[0, 2] == 0


def test_idle_unit_ignores_enemies_beyond_scan_range():
    engine = engine_with(["Marine_RL"], ["Marine"], {0: (10.0, 16.0), 1: (10.0 + 5.5 + 2 * R + 0.05, 16.0)})
    engine.step(n_loops=8)
    assert engine.state.target[0, 1] == -1 and engine.state.health[0, 0] == 45.0


def test_attack_move_walks_then_engages_and_resumes():
    engine = engine_with(["Marine_RL"], ["Marine"], {0: (20.0, 16.0), 1: (5.0, 16.0)})
    engine.commands.kind[0, 1] = CMD_ATTACK_MOVE
    engine.commands.x[0, 1], engine.commands.y[0, 1] = 28.0, 16.0
    engine.step()
    assert engine.state.x[0, 1] == pytest.approx(5.0 + 1.125)  # walking, nothing in range yet
    for _ in range(12):
        engine.step()
    assert engine.state.target[0, 1] == 0 and engine.state.health[0, 0] < 45.0


def test_a_unit_prefers_the_enemy_attacking_it():
    # Blue marine has two red marines in range; the farther one is ordered to shoot it: blue answers that one.
    engine = engine_with(["Marine_RL", "Marine_RL"], ["Marine"], {0: (12.0, 16.0), 1: (11.0, 19.0),
                                                                    2: (14.0, 16.0)})
    engine.commands.kind[0, 1] = CMD_ATTACK
    engine.commands.target[0, 1] = 2
    engine.step(n_loops=1)
    engine.commands.clear()
    engine.place(0, 2, target=-1)  # forget the first pick: the next scan ranks threats first
    engine.step(n_loops=1)
    assert engine.state.target[0, 2] == 1


def test_response_to_a_hit_from_beyond_scan_range():
    # A stalker (range 6, + radii) shoots a blue zergling 6.8 away (edge to edge), beyond its scan range (5): it
    # runs at it. The stalker walks 0.8 at 2.9531 / 16 a loop, reaching range in loop 4 (centre distance 6.877),
    # where its attack starts; it fires WIND_UP = 3 loops later, in loop 7; the missile flies
    # ceil(6.877 / 1.171875) = 6 loops and lands in loop 4 + 3 + 6 = 13; the zergling answers in 14.
    engine = engine_with(["Stalker_RL"], ["Zergling"], {0: (10.0, 16.0), 1: (10.0 + 6.8 + 0.625 + 0.375, 16.0)})
    engine.commands.kind[0, 0] = CMD_ATTACK
    engine.commands.target[0, 0] = 1
    x0 = engine.state.x[0, 1]
    engine.step(n_loops=4 + shot_loop(0, STALKER_PERIOD, WIND_UP["Stalker"]) + 6)  # loops 0-12
    assert engine.state.health[0, 1] == 35.0
    engine.step(n_loops=1)
    # It has not moved: the same point on SC2's position grid (1/4096, kernels.POSITION_GRID).
    assert engine.state.x[0, 1] == pytest.approx(x0, abs=0.5 / POSITION_GRID)
    assert engine.state.health[0, 1] == pytest.approx(35.0 - 13.0)
    engine.step(n_loops=1)
    assert engine.state.target[0, 1] == 0 and engine.state.x[0, 1] < x0


def test_hold_position_does_not_chase():
    # Zealot on hold with a marine 2 away (in scan, out of melee reach): it neither moves nor attacks.
    engine = engine_with(["Marine_RL"], ["Zealot"], {0: (10.0, 16.0), 1: (12.0, 16.0)})
    engine.commands.kind[0, 1] = CMD_HOLD
    engine.step()
    assert engine.state.x[0, 1] == 12.0 and engine.state.health[0, 0] == 45.0


def test_ordered_attack_completes_when_the_target_dies():
    engine = engine_with(["Marine_RL"], ["Marine"], {0: (10.0, 16.0), 1: (14.0, 16.0)})
    engine.place(0, 1, health=6.0)
    engine.commands.kind[0, 0] = CMD_ATTACK
    engine.commands.target[0, 0] = 1
    engine.step()
    assert not engine.state.alive[0, 1]
    assert engine.state.order[0, 0] == ORDER_IDLE and engine.state.target[0, 0] == -1


# --- Re-acquisition while chasing (SC2: a target out of weapon range is re-evaluated; see docs/engine_targeting.md).
# Zealot: radius 0.5, melee range 0.1, scan range 5 edge to edge (5.875 centre to centre against a marine).


def _marine_zealot_marine(a: tuple[float, float], b: tuple[float, float], zealot=(16.0, 16.0)):
    """Two red marines (slots 0, 1) and a blue zealot (slot 2) that is already chasing marine 0."""
    engine = engine_with(["Marine_RL", "Marine_RL"], ["Zealot"], {0: a, 1: b, 2: zealot})
    engine.place(0, 2, target=0)
    return engine


def _order_attack(engine, shooter: int, target: int) -> None:
    engine.commands.kind[0, shooter] = CMD_ATTACK
    engine.commands.target[0, shooter] = target


def test_chasing_unit_switches_to_the_enemy_that_attacks_it():
    # Marine 0 is 3 away (edge 2.125: out of melee reach, being chased); marine 1, 4.5 away (edge 3.625, inside the
    # zealot's scan range), starts shooting it: the zealot turns on marine 1.
    engine = _marine_zealot_marine((19.0, 16.0), (16.0, 20.5))
    _order_attack(engine, 1, 2)
    engine.step(n_loops=1)
    assert engine.state.target[0, 2] == 1


def test_a_chased_target_that_also_attacks_keeps_the_chase_against_a_farther_shooter():
    # Both marines shoot the zealot; marine 0 (being chased, 3 away) is closer than marine 1 (5.5 away): no switch.
    engine = _marine_zealot_marine((19.0, 16.0), (16.0, 21.5))
    _order_attack(engine, 0, 2)
    _order_attack(engine, 1, 2)
    engine.step(n_loops=1)
    assert engine.state.target[0, 2] == 0


def test_an_attack_moving_unit_does_not_turn_on_a_shooter_beyond_its_scan_range():
    # SC2's Response belongs to idle units: a zergling carrying out an attack-move keeps walking to its point when a
    # stalker shoots it from 5.8 edge to edge (inside the stalker's range 6, beyond the zergling's scan range 5).
    # The attack starts in loop 0 and shoots in loop 3 (WIND_UP), the zergling 4 x 0.185 north by then: centre
    # distance hypot(6.8, 0.738) = 6.840 < 7 (still in reach), a flight of ceil(6.840 / 1.171875) = 6 loops, the hit
    # in loop 9; loop 10 is the zergling's first look after it.
    engine = engine_with(["Stalker_RL"], ["Zergling"], {0: (10.0, 10.0), 1: (10.0 + 5.8 + 0.625 + 0.375, 10.0)})
    engine.commands.kind[0, 0] = CMD_ATTACK
    engine.commands.target[0, 0] = 1
    engine.commands.kind[0, 1] = CMD_ATTACK_MOVE
    engine.commands.x[0, 1], engine.commands.y[0, 1] = 16.8, 30.0
    engine.step(n_loops=shot_loop(0, STALKER_PERIOD, WIND_UP["Stalker"]) + 6 + 2)  # loops 0-10
    assert engine.state.health[0, 1] < 35.0  # it was hit
    assert engine.state.target[0, 1] == -1  # and does not answer
    assert engine.state.x[0, 1] == pytest.approx(16.8, abs=0.5 / POSITION_GRID)  # walking on to its point
    assert engine.state.y[0, 1] > 10.5


def test_alternating_aggro_pulls_the_zealot_back_and_forth():
    # Marine 1 shoots while marine 0 runs; then marine 1 runs and marine 0 shoots: the zealot follows the shooter.
    engine = _marine_zealot_marine((19.0, 16.0), (16.0, 20.5))
    _order_attack(engine, 1, 2)
    engine.step(n_loops=1)
    assert engine.state.target[0, 2] == 1
    engine.commands.clear()
    engine.commands.kind[0, 1] = CMD_MOVE
    engine.commands.x[0, 1], engine.commands.y[0, 1] = 16.0, 27.0
    _order_attack(engine, 0, 2)
    engine.step(n_loops=1)
    assert engine.state.target[0, 2] == 0


def test_chasing_unit_switches_to_a_closer_threat_but_keeps_its_target_on_a_tie():
    # Neither marine attacks (both idle and passive): same rank, so the closer one wins; at equal distance the
    # zealot keeps chasing the one it had.
    closer = _marine_zealot_marine((19.0, 16.0), (16.0, 18.0))
    closer.step(n_loops=1)
    assert closer.state.target[0, 2] == 1
    tie = _marine_zealot_marine((19.0, 16.0), (16.0, 19.0))
    tie.step(n_loops=1)
    assert tie.state.target[0, 2] == 0


def test_target_in_weapon_range_is_kept_when_another_enemy_attacks():
    # The zealot is hitting marine 0 (edge distance 0.05 <= 0.1); marine 1 shoots it from 4.5 away: the zealot
    # keeps the marine in reach (a target that can hurt it is not dropped while in range).
    engine = _marine_zealot_marine((16.925, 16.0), (16.0, 20.5))
    _order_attack(engine, 1, 2)
    engine.step(n_loops=1)
    assert engine.state.target[0, 2] == 0


@pytest.mark.parametrize(("gap", "expected"), [(4.0, 0), (5.25, 1)])
def test_target_that_cannot_hurt_yields_to_a_threat_in_weapon_range(gap, expected):
    # A blue marine shooting a red medivac (in range, harmless); a red marine stands idle ``gap`` away edge to edge.
    # At 4.0, inside the blue marine's weapon range 5, the red marine is a threat (a weapon that can hit the blue
    # marine) whether or not it shoots, and the blue marine turns on it (Liquipedia, Automatic Targeting: a target is
    # kept until a higher-priority one enters weapon range, threats first). At 5.25, inside the scan range 5.5 but
    # not the weapon range, nothing has entered weapon range: it keeps the medivac. The layout puts the red marine in
    # slot 0, the medivac in 1.
    engine = engine_with(["Marine_RL", "Medivac_RL"], ["Marine"], {0: (16.0, 16.0 + gap + 2 * R), 1: (13.0, 16.0),
                                                                   2: (16.0, 16.0)})
    engine.place(0, 2, target=1)
    engine.step(n_loops=1)
    assert engine.state.target[0, 2] == expected


def test_target_that_cannot_hurt_yields_first_to_the_threat_attacking_it():
    # Two red marines in the blue marine's weapon range: slot 0 at 3.0 edge to edge, idle; slot 1 at 4.5, ordered
    # to shoot it. Both are threats; the one attacking it ranks first (as in acquisition), though farther.
    engine = engine_with(["Marine_RL", "Marine_RL", "Medivac_RL"], ["Marine"],
                         {0: (16.0, 16.0 + 3.0 + 2 * R), 1: (16.0, 16.0 - 4.5 - 2 * R), 2: (13.0, 16.0),
                          3: (16.0, 16.0)})
    engine.place(0, 3, target=2)
    _order_attack(engine, 1, 3)
    engine.step(n_loops=1)
    assert engine.state.target[0, 3] == 1


def test_ordered_attack_never_switches():
    # The same situation as the first test, but the zealot was ordered to attack marine 0: it keeps chasing it.
    engine = _marine_zealot_marine((19.0, 16.0), (16.0, 20.5))
    _order_attack(engine, 2, 0)
    _order_attack(engine, 1, 2)
    engine.step(n_loops=8)
    assert engine.state.target[0, 2] == 0 and engine.state.order_target[0, 2] == 0


def test_passive_learner_units_ignore_attackers_even_while_attack_moving_past_a_target():
    # A red *_RL marine attack-moving engages the enemy in its scan range, but a hit from beyond that range (a
    # stalker at edge distance 5.9) does not pull it: passive units never respond.
    engine = engine_with(["Marine_RL"], ["Stalker"], {0: (10.0, 16.0), 1: (10.0 + 5.9 + 0.375 + 0.625, 16.0)})
    engine.commands.kind[0, 0] = CMD_ATTACK_MOVE
    engine.commands.x[0, 0], engine.commands.y[0, 0] = 10.0, 4.0
    engine.place(0, 1, target=0)
    engine.step(n_loops=1)
    assert engine.state.target[0, 0] == -1


# --- Call for help (SC2: a unit hit by a weapon calls its allies within CallForHelpRadius 4, at most every
# CallForHelpPeriod 2 s; those whose weapon is acquiring, idle or attack-moving, acquire the attacker;
# docs/engine_rules.md C13).
# A red stalker (passive, so it answers nothing itself) is ordered onto blue zealot A, which holds position 6.8
# beyond the stalker's edge (outside A's scan range, 5). The stalker walks 2.9531 / 16 = 0.1846 a loop from 7.925
# (centre to centre) until within 6 + 0.625 + 0.5 = 7.125: 7.002 in the 5th loop after the order, when its attack
# starts; it shoots WIND_UP = 3 loops later and then every 1.87 x 16 = 29.92 loops (shot_loop: 3, 33, 63), each
# missile flying ceil(7.002 / 1.171875) = 6 loops: hits land in loops 5 + 3 + 6 = 14, 5 + 33 + 6 = 44, 5 + 63 + 6 = 74.
# The helpers are zerglings (radius 0.375), idle and beyond the stalker's reach and scan range (edge >= 7.9).
_A = (10.0 + 6.8 + 0.625 + 0.5, 16.0)
_HITS = tuple(5 + shot_loop(n, STALKER_PERIOD, WIND_UP["Stalker"]) + 6 for n in range(3))  # loops after the order


def _stalker_on_held_zealot(helpers: dict[int, tuple[float, float]]):
    engine = engine_with(["Stalker_RL"], ["Zealot"] + ["Zergling"] * len(helpers),
                         {0: (10.0, 16.0), 1: _A, **helpers})
    engine.commands.kind[0, 1] = CMD_HOLD  # A calls for help, but a held unit answers nothing itself
    engine.step(n_loops=1)
    engine.commands.clear()
    _order_attack(engine, 0, 1)
    return engine


def _life(engine, slot: int) -> float:
    return float(engine.state.health[0, slot] + engine.state.shield[0, slot])


def test_a_hit_unit_calls_idle_allies_within_four_of_it():
    # B 2.0 behind A; D 4.3 to A's side (edge 3.925: inside 4); C 4.5 to the other side (edge 4.125: outside).
    b, c, d = (_A[0] + 2.0, 16.0), (_A[0], 16.0 + 4.5), (_A[0], 16.0 - 4.3)
    engine = _stalker_on_held_zealot({2: b, 3: c, 4: d})
    engine.step(n_loops=_HITS[0] - 1)
    assert _life(engine, 1) == 150.0 and engine.state.attacker[0, 2] == -1
    engine.step(n_loops=1)  # loop 14: the hit, and the call
    assert _life(engine, 1) == 150.0 - 13.0
    assert engine.state.attacker[0, 2] == 0 and engine.state.attacker[0, 4] == 0
    assert engine.state.attacker[0, 3] == -1
    engine.step(n_loops=2)
    assert engine.state.target[0, 2] == 0 and engine.state.x[0, 2] < b[0]  # B runs at the stalker
    assert engine.state.target[0, 4] == 0
    assert engine.state.target[0, 3] == -1 and (engine.state.x[0, 3], engine.state.y[0, 3]) == c
    assert engine.state.x[0, 1] == _A[0]  # A holds


def test_a_call_is_not_answered_by_units_with_an_order():
    # B (2.0 behind A) holds position, E (1.0 above A) walks away north: neither turns on the stalker. At the hit
    # (loop 14) E is 1.0 + 14 x 0.185 = 3.58 above A, within the call's 4 + 0.375 (centre to centre); from 2.0 above,
    # as before the wind-up delayed the hit, it would be 4.58 away: out of the call, and the test would prove nothing.
    b, e = (_A[0] + 2.0, 16.0), (_A[0], 17.0)
    engine = _stalker_on_held_zealot({2: b, 3: e})
    engine.commands.kind[0, 2] = CMD_HOLD
    engine.commands.kind[0, 3] = CMD_MOVE
    engine.commands.x[0, 3], engine.commands.y[0, 3] = _A[0], 31.0
    engine.step(n_loops=_HITS[0] + 2)
    assert _life(engine, 1) == 150.0 - 13.0
    assert engine.state.target[0, 2] == -1 and engine.state.x[0, 2] == b[0]
    assert engine.state.target[0, 3] == -1 and engine.state.y[0, 3] > e[1]


def test_a_unit_calls_at_most_once_every_two_seconds():
    # F is parked far away through the first call (loop 14), then put 2.0 above A: the hit of loop 44 comes 30 loops
    # after the call (< 32: no call); the hit of loop 74, 60 loops after it, calls again and F answers.
    engine = _stalker_on_held_zealot({2: (28.0, 28.0)})
    engine.step(n_loops=_HITS[0])
    assert _life(engine, 1) == 150.0 - 13.0
    engine.place(0, 2, x=_A[0], y=18.0)
    engine.step(n_loops=_HITS[1] - _HITS[0])  # loops 15-44
    assert _life(engine, 1) == 150.0 - 26.0
    assert engine.state.attacker[0, 2] == -1
    engine.step(n_loops=_HITS[2] - _HITS[1])  # loops 45-74
    assert _life(engine, 1) == 150.0 - 39.0
    assert engine.state.attacker[0, 2] == 0


def test_an_attack_moving_ally_acquires_the_attacker_within_its_leash():
    # G and H walk east on attack-move from the loop before the hit (zergling speed 2.9531 / 16 = 0.185 a loop): at
    # the hit G stands 19.610 - 10.923 = 8.69 from the stalker (centre to centre), within its scan range 5 + leash 3
    # + radii 1.0 = 9.0, so it keeps the stalker and runs back at it; H, 10.76 away, acquires it and drops it at its
    # next look, walking on east.
    g, h = (_A[0] + 1.5, 16.0), (_A[0] + 3.575, 16.0)
    engine = _stalker_on_held_zealot({2: g, 3: h})
    engine.step(n_loops=_HITS[0] - 1)
    for slot in (2, 3):
        engine.commands.kind[0, slot] = CMD_ATTACK_MOVE
        engine.commands.x[0, slot], engine.commands.y[0, slot] = 31.0, 16.0
    engine.step(n_loops=1)  # loop 14: both step east, then the hit and the call
    engine.commands.clear()
    assert _life(engine, 1) == 150.0 - 13.0
    assert engine.state.target[0, 2] == 0 and engine.state.target[0, 3] == 0
    x_g, x_h = engine.state.x[0, 2], engine.state.x[0, 3]
    engine.step(n_loops=2)
    assert engine.state.target[0, 2] == 0 and engine.state.x[0, 2] < x_g
    assert engine.state.target[0, 3] == -1 and engine.state.x[0, 3] > x_h
