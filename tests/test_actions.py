"""SMAC's available actions and their decoding into engine commands (docs/smac_interface.md §2)."""

from __future__ import annotations

import numpy as np
import pytest

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.engine.state import (
    BLUE,
    CMD_ATTACK,
    CMD_HEAL,
    CMD_MOVE,
    CMD_NOOP,
    CMD_STOP,
    RED,
    Commands,
)
from smac_hard_gym.smac.actions import (
    InvalidActionError,
    available_actions,
    check_actions,
    decode_actions,
    validate_actions,
)
from smac_hard_gym.smac.features import SideFeatures, SmacOptions


def _avail(engine, side=RED, **options):
    feats = SideFeatures(engine.spec, side, SmacOptions(**options))
    return feats, available_actions(feats, engine.state)[0]


@pytest.fixture
def marines():
    engine = BattleEngine("3m", batch_size=1)
    engine.place(0, 0, x=10.0, y=16.0)
    engine.place(0, 1, x=10.0, y=12.0)
    engine.place(0, 2, x=5.0, y=20.0)
    engine.place(0, 3, x=16.0, y=16.0)  # exactly 6 from agent 0
    engine.place(0, 4, x=10.0 + 6.0 + 1e-6, y=12.0)  # just beyond 6 from agent 1
    engine.place(0, 5, x=28.0, y=20.0)
    return engine


def test_alive_agents_cannot_noop_and_attack_range_is_inclusive(marines):
    _, avail = _avail(marines)
    assert avail.shape == (3, 9)
    np.testing.assert_array_equal(avail[0], [0, 1, 1, 1, 1, 1, 1, 0, 0])  # enemy 0 at exactly 6.0
    np.testing.assert_array_equal(avail[1], [0, 1, 1, 1, 1, 1, 0, 0, 0])  # enemy 1 at 6.000001: out
    np.testing.assert_array_equal(avail[2], [0, 1, 1, 1, 1, 1, 0, 0, 0])


def test_dead_agents_can_only_noop_and_dead_enemies_cannot_be_attacked(marines):
    marines.place(0, 1, alive=False, health=0.0)
    marines.place(0, 3, alive=False, health=0.0)
    _, avail = _avail(marines)
    np.testing.assert_array_equal(avail[1], [1, 0, 0, 0, 0, 0, 0, 0, 0])
    assert not avail[0, 6]


@pytest.mark.parametrize("y,north,south", [
    (8.4, True, False),  # south probe int(7.4) = 7: outside the 3m strip (y 8..23)
    (9.0, True, True),  # int(8.0) = 8: inside
    (22.9, True, True),  # north probe int(23.9) = 23: inside
    (23.1, False, True),  # int(24.1) = 24: outside
])
def test_move_probe_on_the_pathing_grid(y, north, south):
    engine = BattleEngine("3m", batch_size=1)
    engine.place(0, 0, x=10.2, y=y)
    _, avail = _avail(engine)
    assert (avail[0, 2], avail[0, 3]) == (north, south)


def test_move_probe_at_the_map_edge_and_int_truncation():
    engine = BattleEngine("3s_vs_3z", batch_size=1)  # the whole 32x32 grid is pathable
    assert engine.spec.pathable.all()
    engine.place(0, 0, x=31.2, y=0.6)
    engine.place(0, 1, x=0.4, y=31.5)
    _, avail = _avail(engine)
    # Agent 0: east probe int(32.2) = 32 is off the map; south probe int(-0.4) = 0 (Python int truncates toward
    # zero, as SMAC does) is on it.
    np.testing.assert_array_equal(avail[0, 2:6], [1, 1, 0, 1])
    # Agent 1: north int(32.5) = 32 off; west int(-0.6) = 0 on.
    np.testing.assert_array_equal(avail[1, 2:6], [0, 1, 1, 1])


def test_move_probe_uses_half_the_move_amount():
    engine = BattleEngine("3m", batch_size=1)
    engine.place(0, 0, x=10.2, y=9.6)
    _, avail = _avail(engine, move_amount=4)  # south probe int(9.6 - 2) = 7: outside the strip
    assert not avail[0, 3]
    _, avail = _avail(engine, move_amount=2)  # int(8.6) = 8: inside
    assert avail[0, 3]


def test_medivac_heals_allies_not_enemies():
    engine = BattleEngine("MMM", batch_size=1)
    for slot in range(20):
        engine.place(0, slot, x=1.0 + 1.5 * slot, y=23.0)
    medivac = 9
    engine.place(0, medivac, x=10.0, y=12.0)
    engine.place(0, 0, x=10.0, y=17.0)  # marauder ally 0: 5 away
    engine.place(0, 2, x=16.0, y=12.0)  # marine ally 2: exactly 6 away
    engine.place(0, 3, x=10.0, y=13.0, alive=False, health=0.0)  # dead ally 3
    engine.place(0, 10 + 1, x=11.0, y=12.0)  # enemy 1 right next to the medivac
    feats, avail = _avail(engine)
    targets = np.flatnonzero(avail[medivac, 6:])
    np.testing.assert_array_equal(targets, [0, 2])  # allies 0 and 2; never itself (9), not dead 3, not enemies


def test_decode_commands_for_every_action_kind():
    engine = BattleEngine("MMM", batch_size=2)
    state = engine.state
    feats = SideFeatures(engine.spec, RED, SmacOptions(move_amount=3))
    actions = np.array([[1, 2, 3, 4, 5, 6, 6 + 9, 1, 1, 6 + 4]] * 2)  # medivac (slot 9) heals ally 4
    commands = Commands.empty(2, 20)
    active = np.array([True, False])
    decode_actions(feats, state, actions, commands, active)
    kind, target = commands.kind[0], commands.target[0]
    x0, y0 = state.x[0], state.y[0]
    np.testing.assert_array_equal(kind[:10], [CMD_STOP, CMD_MOVE, CMD_MOVE, CMD_MOVE, CMD_MOVE, CMD_ATTACK,
                                              CMD_ATTACK, CMD_STOP, CMD_STOP, CMD_HEAL])
    assert (commands.x[0, 1], commands.y[0, 1]) == (x0[1], y0[1] + 3)  # north by move_amount
    assert (commands.x[0, 2], commands.y[0, 2]) == (x0[2], y0[2] - 3)
    assert (commands.x[0, 3], commands.y[0, 3]) == (x0[3] + 3, y0[3])
    assert (commands.x[0, 4], commands.y[0, 4]) == (x0[4] - 3, y0[4])
    assert target[5] == 10 + 0 and target[6] == 10 + 9  # enemy j is blue slot n_red + j
    assert target[9] == 4  # ally 4 is red slot 4
    np.testing.assert_array_equal(commands.kind[1], CMD_NOOP)  # inactive battle untouched
    np.testing.assert_array_equal(commands.kind[0, 10:], CMD_NOOP)  # blue slots untouched


def test_decode_blue_side_targets_red_slots():
    engine = BattleEngine("3m", batch_size=1)
    feats = SideFeatures(engine.spec, BLUE)
    commands = Commands.empty(1, 6)
    decode_actions(feats, engine.state, np.array([[6, 8, 0]]), commands, np.array([True]))
    np.testing.assert_array_equal(commands.kind[0], [CMD_NOOP] * 3 + [CMD_ATTACK, CMD_ATTACK, CMD_NOOP])
    np.testing.assert_array_equal(commands.target[0, 3:5], [0, 2])


def test_a_move_command_moves_the_unit_north():
    engine = BattleEngine("3m", batch_size=1)
    feats = SideFeatures(engine.spec, RED)
    x, y = engine.state.x[0, 0], engine.state.y[0, 0]
    commands = Commands.empty(1, 6)
    decode_actions(feats, engine.state, np.array([[2, 1, 1]]), commands, np.array([True]))
    engine.step(commands)
    # Marines move 2.25 per Normal second: at most 1.125 in one 8-loop step, and all of it northward here.
    assert engine.state.y[0, 0] - y == pytest.approx(1.125, abs=0.05)
    assert engine.state.x[0, 0] == pytest.approx(x, abs=0.05)


def test_invalid_actions_name_agent_action_and_choices(marines):
    feats = SideFeatures(marines.spec, RED)
    avail = available_actions(feats, marines.state)
    with pytest.raises(InvalidActionError, match=r"red agent 1: action 6 \(attack enemy 0\) is not available; "
                                                 r"available: 1 \(stop\), 2 \(move north\)"):
        check_actions(feats, [[6, 6, 1]], avail)
    with pytest.raises(InvalidActionError, match=r"red agent 2: action 0 \(no-op\) is not available"):
        check_actions(feats, [[1, 1, 0]], avail)
    with pytest.raises(InvalidActionError, match=r"action 9 is out of range; actions are 0..8"):
        check_actions(feats, [[1, 1, 9]], avail)
    with pytest.raises(InvalidActionError, match=r"shape \(1, 3\)"):
        check_actions(feats, [[1, 1]], avail)
    with pytest.raises(TypeError, match="red agent 0: action 'stop' is of type str"):
        check_actions(feats, [["stop", 1, 1]], avail)
    # A battle that is not active is not checked.
    np.testing.assert_array_equal(check_actions(feats, [[0, 0, 0]], avail, active=np.array([False])), 0)


def test_dead_agent_must_noop(marines):
    marines.place(0, 0, alive=False, health=0.0)
    feats = SideFeatures(marines.spec, RED)
    avail = available_actions(feats, marines.state)
    with pytest.raises(InvalidActionError, match=r"red agent 0: action 1 \(stop\) is not available; "
                                                 r"available: 0 \(no-op\)$"):
        check_actions(feats, [[1, 1, 1]], avail)
    check_actions(feats, [[0, 1, 1]], avail)


# validate_actions: one rule per row. (actions for 3 agents with 9 actions, error type, message fragment)
REJECTED = [
    ([1, 1, 3.5], TypeError, "red agent 2: action 3.5 is not a whole number"),
    (np.array([1.0, 1.0, 3.5]), TypeError, "action 3.5 is not a whole number"),
    ([1, True, 1], TypeError, "red agent 1: action True is a bool"),
    (np.array([True, True, True]), TypeError, "action True is a bool"),
    ([1, 1, "3"], TypeError, "action '3' is of type str"),
    ([1, 1, 3j], TypeError, "action 3j is of type complex"),
    ([1, None, 1], TypeError, "action None is of type NoneType"),
    ([1, 1, [3]], TypeError, r"action \[3\] is of type list"),
    ("113", TypeError, "must be a sequence or array of ints"),
    (None, TypeError, "must be a sequence or array of ints"),
    ([1, 1, float("nan")], InvalidActionError, "action nan is out of range"),
    ([1, 1, float("inf")], InvalidActionError, "action inf is out of range"),
    ([1, 1, 1e19], InvalidActionError, r"action 1e\+19 is out of range"),  # not a wrapped int64
    (np.array([1, 1, 1e19]), InvalidActionError, r"action 1e\+19 is out of range"),
    ([1, 1, 2**70], InvalidActionError, f"action {2**70} is out of range"),
    ([1, 1, -1], InvalidActionError, "action -1 is out of range; actions are 0..8"),
    (np.array([1, 1, 9], dtype=np.uint8), InvalidActionError, "action 9 is out of range"),
    ([1, 1], InvalidActionError, r"shape \(3,\) \(one action per agent\), got \(2,\)"),
    ([[1, 1, 1]], InvalidActionError, r"got \(1, 3\)"),
    ([[1, 1], 1, 1], TypeError, r"red agent 0: action \[1, 1\] is of type list"),
    (3, InvalidActionError, r"got \(\)"),
]


@pytest.mark.parametrize(("actions", "error", "message"), REJECTED, ids=[repr(r[0])[:30] for r in REJECTED])
def test_validate_actions_rejects_what_is_not_an_action_naming_it_as_passed(actions, error, message):
    with pytest.raises(error, match=message):
        validate_actions(actions, (3,), 9)
    assert error in (TypeError, InvalidActionError) and issubclass(InvalidActionError, ValueError)


@pytest.mark.parametrize("actions", [[1, 2, 8], (np.int8(1), np.uint64(2), np.int32(8)), np.array([1, 2, 8]),
                                     np.array([1.0, 2.0, 8.0], dtype=np.float32), [1.0, 2, np.float64(8.0)]],
                         ids=["ints", "numpy-scalars", "int-array", "float32-array", "integral-floats"])
def test_validate_actions_accepts_ints_and_integral_floats(actions):
    out = validate_actions(actions, (3,), 9)
    assert out.dtype == np.int64 and out.tolist() == [1, 2, 8]


def test_validate_actions_names_the_battle_in_a_batch():
    with pytest.raises(InvalidActionError, match="battle 1, blue agent 2: action 9 is out of range"):
        validate_actions(np.array([[1, 1, 1], [1, 1, 9]]), (2, 3), 9, "blue")
    source = np.array([[1, 1, 1], [1, 1, 2]])
    out = validate_actions(source, (2, 3), 9)
    out[0, 0] = 5
    assert source[0, 0] == 1  # a fresh array: callers may change it
