"""SC2's automatic targeting for units that acquire (smac_interface §9): idle and attack-moving units take the
closest enemy within scan range (max(5, range + 0.5), edge to edge), prefer an enemy that is attacking them, answer
a hit from beyond that range, and holding units only shoot what is in weapon range. SMAC's *_RL units are passive.
"""

from __future__ import annotations

import pytest
from engine_helpers import engine_with

from smac_hard_gym.engine import CMD_ATTACK, CMD_ATTACK_MOVE, CMD_HOLD
from smac_hard_gym.engine.state import ORDER_IDLE

R = 0.375  # marine radius


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
    # A stalker (range 6, + radii) shoots a blue zergling from 6.8 away, beyond its scan range (5): it runs at it.
    engine = engine_with(["Stalker_RL"], ["Zergling"], {0: (10.0, 16.0), 1: (10.0 + 6.8 + 0.625 + 0.375, 16.0)})
    engine.commands.kind[0, 0] = CMD_ATTACK
    engine.commands.target[0, 0] = 1
    x0 = engine.state.x[0, 1]
    engine.step()
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
