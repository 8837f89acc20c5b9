"""Raw SC2 observations -> :class:`BattleState` rows, and :class:`Commands` -> raw unit commands.

Unit types are resolved by name from the game's own ``ResponseData`` (``"Marine_RL"`` -> the unit table row), never
from hard-coded ids: SC2 numbers the maps' custom ``*_RL`` types after its built-in ones, so the ids change with the
game version and platform (where the data leaves a custom type unnamed, SMAC's own rule applies: see
:class:`_TypeResolver`). Slots follow SMAC: red (player 1) units sorted by (unit_type, x, y), then blue (player 2)
units in raw observation order, and every episode's roster must match the map's layout type by type.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import NamedTuple

import numpy as np
from s2clientprotocol import common_pb2, raw_pb2
from s2clientprotocol import sc2api_pb2 as sc_pb

from smac_hard_gym.engine.scenario import Layout
from smac_hard_gym.engine.state import CMD_NOOP, NO_UNIT, ORDER_IDLE, BattleState, Commands
from smac_hard_gym.engine.units import UNITS, unit_index
from smac_hard_gym.sc2 import abilities
from smac_hard_gym.sc2.errors import Sc2GameError

__all__ = ["Roster", "RACES", "type_names", "read_roster", "fill_battle", "raw_actions", "decode_grid"]

RED_PLAYER, BLUE_PLAYER = 1, 2
RACES = {"T": common_pb2.Terran, "P": common_pb2.Protoss, "Z": common_pb2.Zerg}  # map races -> protocol races


class Roster(NamedTuple):
    """Which unit (tag) sits in which slot for the current episode of one battle."""

    tags: np.ndarray  # uint64 (U,)
    slot_of_tag: dict[int, int]


def type_names(data: sc_pb.ResponseData) -> dict[int, str]:
    """Unit type id -> name, from the game's ResponseData."""
    return {int(u.unit_id): u.name for u in data.units if u.name}


class _TypeResolver:
    """Unit type id -> unit table row: by the game's own names, else SMAC's rule for the custom red types.

    SMAC reads no names: it takes the smallest red type id as the first custom type and numbers the map's custom
    types from it in alphabetical order. That rule is the fallback when the game's data leaves a red type unnamed
    (or names it with a standard name), so a game version that reports custom types differently still resolves.
    """

    def __init__(self, names: dict[int, str], red_ids: Iterable[int], layout: Layout, map_name: str) -> None:
        self.names = names
        self.map_name = map_name
        red_ids = sorted(set(red_ids))
        self.base = red_ids[0] if red_ids else 0
        self.customs = sorted({UNITS[int(t)].sc2_name for t in layout.utype[: layout.n_red]})

    def row(self, unit: raw_pb2.Unit) -> int:
        name = self.names.get(int(unit.unit_type))
        row = None
        if name is not None:
            try:
                row = unit_index(name)
            except KeyError:
                row = None
        if unit.owner == RED_PLAYER and (row is None or not UNITS[row].passive):
            rank = int(unit.unit_type) - self.base
            if 0 <= rank < len(self.customs):
                return unit_index(self.customs[rank])
        if row is None:
            shown = f"{name!r}" if name is not None else "unnamed in the game's unit data"
            raise Sc2GameError(f"map {self.map_name!r}: unit type {unit.unit_type} ({shown}) of player {unit.owner} "
                               "is not a SMAC unit")
        return row


def read_roster(units: Iterable[raw_pb2.Unit], names: dict[int, str], layout: Layout, map_name: str) -> Roster:
    """Slots for the units of a freshly spawned battle; a :class:`Sc2GameError` if they differ from the layout."""
    red, blue = [], []
    for unit in units:
        if unit.owner == RED_PLAYER:
            red.append(unit)
        elif unit.owner == BLUE_PLAYER:
            blue.append(unit)
    red.sort(key=lambda u: (u.unit_type, u.pos.x, u.pos.y))  # SMAC's agent order
    ordered = red + blue
    resolver = _TypeResolver(names, (u.unit_type for u in red), layout, map_name)
    got = [resolver.row(u) for u in ordered]
    expected = [int(t) for t in layout.utype]
    if (len(red), len(blue)) != (layout.n_red, layout.n_blue) or got != expected:
        def show(rows: Sequence[int]) -> list[str]:
            return [UNITS[t].sc2_name for t in rows]

        raise Sc2GameError(f"map {map_name!r}: the game spawned red {show(got[:len(red)])} and blue "
                           f"{show(got[len(red):])}, but the map file expects red {show(expected[:layout.n_red])} "
                           f"and blue {show(expected[layout.n_red:])}; is the installed .SC2Map SMAC-HARD's?")
    tags = np.array([u.tag for u in ordered], dtype=np.uint64)
    return Roster(tags, {int(t): i for i, t in enumerate(tags)})


def fill_battle(state: BattleState, b: int, roster: Roster, units: Iterable[raw_pb2.Unit], loop: int) -> None:
    """Write battle ``b``'s row of ``state`` from raw units; roster units missing from ``units`` are dead."""
    seen = np.zeros(len(roster.tags), dtype=bool)
    slot_of = roster.slot_of_tag
    for unit in units:
        s = slot_of.get(int(unit.tag))
        if s is None:
            continue  # a unit of a later spawn (the respawn trigger fired after a draw)
        seen[s] = True
        state.x[b, s], state.y[b, s] = unit.pos.x, unit.pos.y
        state.health[b, s], state.shield[b, s], state.energy[b, s] = unit.health, unit.shield, unit.energy
        state.cooldown[b, s] = unit.weapon_cooldown
        state.target[b, s] = slot_of.get(int(unit.engaged_target_tag), NO_UNIT) if unit.engaged_target_tag \
            else NO_UNIT
        order, order_target = ORDER_IDLE, NO_UNIT
        if unit.orders:
            first = unit.orders[0]
            has_unit = first.HasField("target_unit_tag")
            kind = abilities.target_kind(has_unit, first.HasField("target_world_space_pos"))
            order = abilities.RAW_TO_ORDER.get((first.ability_id, kind), ORDER_IDLE)
            if has_unit:
                order_target = slot_of.get(int(first.target_unit_tag), NO_UNIT)
            elif kind == abilities.POINT:
                state.order_x[b, s] = first.target_world_space_pos.x
                state.order_y[b, s] = first.target_world_space_pos.y
        state.order[b, s], state.order_target[b, s] = order, order_target
    dead = ~seen
    state.alive[b] = seen
    state.health[b, dead] = 0.0
    state.shield[b, dead] = 0.0
    state.order[b, dead] = ORDER_IDLE
    state.order_target[b, dead] = NO_UNIT
    state.target[b, dead] = NO_UNIT
    state.loop[b] = loop


def raw_actions(commands: Commands, b: int, slots: range, roster: Roster, alive: np.ndarray) -> list[sc_pb.Action]:
    """Raw unit commands for battle ``b``'s ``slots`` (one player's units); NOOPs and dead units send nothing.

    Commands on a dead or unknown target are dropped, as the engine ignores them.
    """
    out: list[sc_pb.Action] = []
    kinds = commands.kind[b]
    n_units = len(roster.tags)
    for s in slots:
        kind = int(kinds[s])
        if kind == CMD_NOOP or not alive[s]:
            continue
        raw = abilities.COMMAND_TO_RAW.get(kind)
        if raw is None:
            raise ValueError(f"battle {b} slot {s}: unknown command kind {kind}; allowed: "
                             f"{sorted(abilities.COMMAND_TO_RAW)} and CMD_NOOP ({CMD_NOOP})")
        cmd = raw_pb2.ActionRawUnitCommand(ability_id=raw.ability, unit_tags=[int(roster.tags[s])])
        if raw.target == abilities.UNIT:
            t = int(commands.target[b, s])
            if not (0 <= t < n_units) or not alive[t]:
                continue
            cmd.target_unit_tag = int(roster.tags[t])
        elif raw.target == abilities.POINT:
            cmd.target_world_space_pos.CopyFrom(common_pb2.Point2D(x=float(commands.x[b, s]),
                                                                   y=float(commands.y[b, s])))
        out.append(sc_pb.Action(action_raw=raw_pb2.ActionRaw(unit_command=cmd)))
    return out


def decode_grid(image: common_pb2.ImageData) -> np.ndarray:
    """An ImageData grid as an array indexed [x, y] (rows are world y, as python-sc2 reads them)."""
    width, height = image.size.x, image.size.y
    data = np.frombuffer(image.data, dtype=np.uint8)
    if image.bits_per_pixel == 1:
        data = np.unpackbits(data)[: width * height]
    elif image.bits_per_pixel != 8:
        raise ValueError(f"ImageData with {image.bits_per_pixel} bits per pixel; expected 1 or 8")
    return data.reshape(height, width).T.copy()
