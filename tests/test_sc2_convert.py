"""Raw SC2 units <-> battle state and commands -> raw unit commands, on hand-built protobuf messages.

Facts checked: SMAC's agent order (red units sorted by (unit_type, x, y), enemies in raw order), SMAC's ability ids
(stop 4, move 16, hold 18, attack 23, heal 386), SMAC's custom-id rule (the smallest red type id is the first custom
type in alphabetical order), and python-sc2's ImageData layout (rows are world y, bits most significant first).
"""

from __future__ import annotations

import numpy as np
import pytest
from s2clientprotocol import common_pb2, raw_pb2

from smac_hard_gym.engine.scenario import build_layout
from smac_hard_gym.engine.state import (
    CMD_ATTACK,
    CMD_ATTACK_MOVE,
    CMD_HEAL,
    CMD_HOLD,
    CMD_MOVE,
    CMD_STOP,
    NO_UNIT,
    ORDER_ATTACK,
    ORDER_IDLE,
    ORDER_MOVE,
    Commands,
    allocate_state,
)
from smac_hard_gym.maps import load_map
from smac_hard_gym.sc2.convert import decode_grid, fill_battle, raw_actions, read_roster
from smac_hard_gym.sc2.errors import Sc2GameError

MMM = load_map("MMM")
LAYOUT = build_layout(MMM)
# MMM's custom types numbered alphabetically from an arbitrary base, standard ids for blue.
IDS = {"Marauder_RL": 3000, "Marine_RL": 3001, "Medivac_RL": 3002, "Marine": 48, "Marauder": 51, "Medivac": 54}
NAMES = {i: n for n, i in IDS.items()}


def _unit(tag, owner, name, x, y, **fields):
    return raw_pb2.Unit(tag=tag, owner=owner, unit_type=IDS[name], pos=common_pb2.Point(x=x, y=y), **fields)


def _spawned_mmm():
    """MMM's armies as the game reports them: red in a scrambled order, blue in creation order."""
    red = [_unit(100 + i, 1, g.unit, 9.0 + 0.3 * (i % 4), 15.0 + 0.25 * i)
           for i, g in enumerate(g for g in MMM.red for _ in range(g.count))]
    blue = [_unit(200 + i, 2, g.unit, 23.0, 14.0 + 0.3 * i) for i, g in enumerate(
        g for g in MMM.blue for _ in range(g.count))]
    scrambled = red[::-1][:4] + blue[:3] + red[::-1][4:] + blue[3:]
    return red, blue, scrambled


def test_roster_follows_smac_agent_and_enemy_order():
    red, blue, scrambled = _spawned_mmm()
    roster = read_roster(scrambled, NAMES, LAYOUT, "MMM")
    expected_red = sorted(red, key=lambda u: (u.unit_type, u.pos.x, u.pos.y))
    assert roster.tags.tolist() == [u.tag for u in expected_red] + [u.tag for u in blue]
    # MMM's agents: 2 marauders (smallest custom id), 7 marines, the medivac.
    assert [NAMES[u.unit_type] for u in expected_red] == ["Marauder_RL"] * 2 + ["Marine_RL"] * 7 + ["Medivac_RL"]


def test_unnamed_custom_types_resolve_by_smacs_offset_rule():
    red, blue, scrambled = _spawned_mmm()
    anonymous = {i: n for i, n in NAMES.items() if not n.endswith("_RL")}
    assert read_roster(scrambled, anonymous, LAYOUT, "MMM").tags.tolist() == \
        read_roster(scrambled, NAMES, LAYOUT, "MMM").tags.tolist()


def test_a_game_that_differs_from_the_map_file_is_refused():
    red, blue, _ = _spawned_mmm()
    with pytest.raises(Sc2GameError, match="expects red"):
        read_roster(red + blue[:-1], NAMES, LAYOUT, "MMM")
    strange = raw_pb2.Unit(tag=999, owner=2, unit_type=77, pos=common_pb2.Point(x=23, y=20))
    with pytest.raises(Sc2GameError, match="unit type 77"):
        read_roster(red + blue[:-1] + [strange], NAMES, LAYOUT, "MMM")


def test_fill_battle_reads_fields_orders_and_deaths():
    red, blue, scrambled = _spawned_mmm()
    roster = read_roster(scrambled, NAMES, LAYOUT, "MMM")
    slot = {int(t): s for s, t in enumerate(roster.tags)}
    state = allocate_state(2, LAYOUT.n_red + LAYOUT.n_blue)
    attacker, mover, victim = red[0], red[5], blue[0]
    attacker.orders.add(ability_id=23, target_unit_tag=victim.tag)
    attacker.engaged_target_tag = victim.tag
    attacker.health, attacker.weapon_cooldown = 30.0, 7.0
    mover.orders.add(ability_id=16).target_world_space_pos.CopyFrom(common_pb2.Point(x=5.0, y=6.0))
    gone = blue[4]
    units = [u for u in scrambled if u.tag != gone.tag]
    fill_battle(state, 1, roster, units, loop=40)
    a, m, v, g = slot[attacker.tag], slot[mover.tag], slot[victim.tag], slot[gone.tag]
    assert state.order[1, a] == ORDER_ATTACK and state.order_target[1, a] == v and state.target[1, a] == v
    assert state.health[1, a] == 30.0 and state.cooldown[1, a] == 7.0
    assert state.order[1, m] == ORDER_MOVE and (state.order_x[1, m], state.order_y[1, m]) == (5.0, 6.0)
    assert not state.alive[1, g] and state.health[1, g] == 0 and state.order[1, g] == ORDER_IDLE
    assert state.alive[1].sum() == len(units) and state.loop[1] == 40
    assert state.target[1, m] == NO_UNIT
    assert not state.alive[0].any()  # the other battle is untouched


def test_commands_become_smacs_raw_unit_commands():
    red, blue, scrambled = _spawned_mmm()
    roster = read_roster(scrambled, NAMES, LAYOUT, "MMM")
    n = len(roster.tags)
    commands = Commands.empty(1, n)
    alive = np.ones(n, dtype=bool)
    medivac = LAYOUT.n_red - 1
    table = {0: (CMD_STOP, None), 1: (CMD_HOLD, None), 2: (CMD_MOVE, (4.0, 5.0)), 3: (CMD_ATTACK, 12),
             4: (CMD_ATTACK_MOVE, (20.0, 16.0)), medivac: (CMD_HEAL, 2)}
    for s, (kind, arg) in table.items():
        commands.kind[0, s] = kind
        if isinstance(arg, tuple):
            commands.x[0, s], commands.y[0, s] = arg
        elif arg is not None:
            commands.target[0, s] = arg
    commands.kind[0, 5], commands.target[0, 5] = CMD_ATTACK, 13  # a dead target: dropped
    commands.kind[0, 6] = CMD_STOP  # a dead unit: sends nothing
    alive[[13, 6]] = False
    sent = [a.action_raw.unit_command for a in raw_actions(commands, 0, range(LAYOUT.n_red), roster, alive)]
    by_unit = {int(c.unit_tags[0]): c for c in sent}
    assert len(sent) == len(table)
    tag = roster.tags
    assert by_unit[tag[0]].ability_id == 4 and by_unit[tag[1]].ability_id == 18
    move = by_unit[tag[2]]
    assert move.ability_id == 16 and (move.target_world_space_pos.x, move.target_world_space_pos.y) == (4.0, 5.0)
    assert by_unit[tag[3]].ability_id == 23 and by_unit[tag[3]].target_unit_tag == tag[12]
    amove = by_unit[tag[4]]
    assert amove.ability_id == 23 and not amove.HasField("target_unit_tag") and amove.target_world_space_pos.x == 20
    assert by_unit[tag[medivac]].ability_id == 386 and by_unit[tag[medivac]].target_unit_tag == tag[2]


def test_decode_grid_indexes_x_then_y():
    # 16 x 2 cells, 1 bit each, rows of world y, most significant bit first: (0, 0) and (9, 1) are set.
    image = common_pb2.ImageData(bits_per_pixel=1, size=common_pb2.Size2DI(x=16, y=2),
                                 data=bytes([0b10000000, 0, 0, 0b01000000]))
    grid = decode_grid(image)
    assert grid.shape == (16, 2)
    assert {tuple(p) for p in np.argwhere(grid)} == {(0, 0), (9, 1)}
    heights = common_pb2.ImageData(bits_per_pixel=8, size=common_pb2.Size2DI(x=2, y=3), data=bytes(range(6)))
    assert decode_grid(heights)[1, 2] == 5
