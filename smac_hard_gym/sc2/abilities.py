"""SC2 ability ids and how they map to engine commands and unit orders, in both directions.

The client (the sc2 backend) turns :class:`~smac_hard_gym.engine.state.Commands` into raw unit commands with the
specific ability ids SMAC uses; the test server turns raw unit commands back into engine commands and engine orders
into ``UnitOrder`` entries. Both read these tables, so the two directions cannot drift apart.

Ids (``pysc2.lib.actions``): Stop_Stop 4, Move_Move 16, HoldPosition_Hold 18, Attack_Attack 23, Effect_Heal 386;
the general ids that pysc2's ``RAW_FUNCTIONS`` send (Stop 3665, HoldPosition 3793, Move 3794, Attack 3674) are
accepted by the test server too.
"""

from __future__ import annotations

from typing import NamedTuple

from smac_hard_gym.engine.state import (
    CMD_ATTACK,
    CMD_ATTACK_MOVE,
    CMD_HEAL,
    CMD_HOLD,
    CMD_MOVE,
    CMD_STOP,
    ORDER_ATTACK,
    ORDER_ATTACK_MOVE,
    ORDER_HEAL,
    ORDER_HOLD,
    ORDER_MOVE,
)

STOP, MOVE, HOLD, ATTACK, HEAL = 4, 16, 18, 23, 386
GENERAL_STOP, GENERAL_HOLD, GENERAL_MOVE, GENERAL_ATTACK = 3665, 3793, 3794, 3674

# What a command needs besides the unit: nothing, a point, or a unit tag.
NO_TARGET, POINT, UNIT = "none", "point", "unit"


class RawCommand(NamedTuple):
    ability: int
    target: str  # NO_TARGET, POINT or UNIT


# Engine command -> the raw unit command the backend sends (CMD_NOOP sends nothing).
COMMAND_TO_RAW: dict[int, RawCommand] = {
    CMD_STOP: RawCommand(STOP, NO_TARGET),
    CMD_HOLD: RawCommand(HOLD, NO_TARGET),
    CMD_MOVE: RawCommand(MOVE, POINT),
    CMD_ATTACK: RawCommand(ATTACK, UNIT),
    CMD_ATTACK_MOVE: RawCommand(ATTACK, POINT),
    CMD_HEAL: RawCommand(HEAL, UNIT),
}

# (ability, target kind) -> engine command, as the test server reads raw unit commands.
RAW_TO_COMMAND: dict[tuple[int, str], int] = {
    (STOP, NO_TARGET): CMD_STOP, (GENERAL_STOP, NO_TARGET): CMD_STOP,
    (HOLD, NO_TARGET): CMD_HOLD, (GENERAL_HOLD, NO_TARGET): CMD_HOLD,
    (MOVE, POINT): CMD_MOVE, (GENERAL_MOVE, POINT): CMD_MOVE,
    (ATTACK, UNIT): CMD_ATTACK, (GENERAL_ATTACK, UNIT): CMD_ATTACK,
    (ATTACK, POINT): CMD_ATTACK_MOVE, (GENERAL_ATTACK, POINT): CMD_ATTACK_MOVE,
    (HEAL, UNIT): CMD_HEAL,
}

# Engine order -> the UnitOrder a unit reports (ORDER_IDLE reports no order).
ORDER_TO_RAW: dict[int, RawCommand] = {
    ORDER_MOVE: RawCommand(MOVE, POINT),
    ORDER_ATTACK: RawCommand(ATTACK, UNIT),
    ORDER_ATTACK_MOVE: RawCommand(ATTACK, POINT),
    ORDER_HOLD: RawCommand(HOLD, NO_TARGET),
    ORDER_HEAL: RawCommand(HEAL, UNIT),
}

# (ability, target kind) of a reported UnitOrder -> engine order, as the backend reads observations.
RAW_TO_ORDER: dict[tuple[int, str], int] = {
    (MOVE, POINT): ORDER_MOVE, (GENERAL_MOVE, POINT): ORDER_MOVE,
    (ATTACK, UNIT): ORDER_ATTACK, (GENERAL_ATTACK, UNIT): ORDER_ATTACK,
    (ATTACK, POINT): ORDER_ATTACK_MOVE, (GENERAL_ATTACK, POINT): ORDER_ATTACK_MOVE,
    (HOLD, NO_TARGET): ORDER_HOLD, (GENERAL_HOLD, NO_TARGET): ORDER_HOLD,
    (HEAL, UNIT): ORDER_HEAL,
}

# Names the test server reports in its ability data.
ABILITY_NAMES: dict[int, str] = {
    STOP: "Stop_Stop", MOVE: "Move_Move", HOLD: "HoldPosition_Hold", ATTACK: "Attack_Attack",
    HEAL: "Effect_Heal", GENERAL_STOP: "Stop", GENERAL_HOLD: "HoldPosition", GENERAL_MOVE: "Move",
    GENERAL_ATTACK: "Attack",
}


def target_kind(has_unit: bool, has_point: bool) -> str:
    """The target kind of a raw command or order from which of its target fields are set."""
    if has_unit:
        return UNIT
    return POINT if has_point else NO_TARGET
