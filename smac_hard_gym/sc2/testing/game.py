"""The game behind the protocol test server: one battle of the native engine dressed as a two-player SC2 game.

It answers in s2clientprotocol messages what a SMAC-HARD map in the real game answers: units with tags, owners
(1 = red, the custom ``*_RL`` units; 2 = blue, standard units) and unit type ids resolved from names (custom types
numbered after the standard ids, in alphabetical order of their names, as the maps do); raw unit commands from each
player; debug kills; and the maps' "all units died" trigger, which respawns both armies at the map layout at the end
of the game loop in which no unit is left. Time runs in lockstep: the game advances when every joined player has
asked it to (:class:`Lockstep`).

Conventions that the real game does not pin down here: tags are ``generation << 32 | (slot + 1)`` (a new generation
at every respawn), image rows of game_info grids are world rows ``y`` (row 0 at y = 0, as python-sc2 reads them),
terrain height bytes encode ``z = -16 + 32 * byte / 255``. The fields a raw unit reports as 32-bit floats (position,
health, shield, energy, weapon cooldown, order point) are rounded to float32 in the game itself after every
advance, so the game is exactly what its players observe: a client that rounds its command points the way the
protocol does sees the same trajectory as the native engine run under the same rounding.
"""

from __future__ import annotations

import asyncio
import json

import numpy as np
from s2clientprotocol import common_pb2, debug_pb2, error_pb2, raw_pb2
from s2clientprotocol import sc2api_pb2 as sc_pb

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.engine.state import CMD_NOOP, NO_UNIT, ORDER_IDLE, RED, Commands
from smac_hard_gym.engine.units import STATS, UNITS, S
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.sc2 import abilities
from smac_hard_gym.sc2.convert import RACES

__all__ = ["TestGame", "Lockstep", "DEFAULT_CUSTOM_ID_BASE", "REPLAY_MAGIC"]

DEFAULT_CUSTOM_ID_BASE = 1970  # the first custom (*_RL) unit type id on SC2 4.10 for Linux
REPLAY_MAGIC = b"SMAC-HARD-GYM test server replay\n"
# State fields a raw Unit carries as protobuf floats (32-bit).
REPORTED_FIELDS = ("x", "y", "health", "shield", "energy", "cooldown", "order_x", "order_y")
_CLIFF_TO_Z = ((0.0, 1.0, 2.0), (0.0, 8.0, 10.0))  # cliff level -> terrain z (docs/smac_interface.md §9)


def _height_bytes(z: np.ndarray) -> np.ndarray:
    return np.clip(np.rint((z + 16.0) / 32.0 * 255.0), 0, 255).astype(np.uint8)


def _image(grid_xy: np.ndarray, bits: int) -> common_pb2.ImageData:
    """An ImageData of a grid indexed [x, y]: rows are world y, columns world x."""
    rows = np.ascontiguousarray(grid_xy.T)
    data = np.packbits(rows.astype(bool), axis=None) if bits == 1 else rows.astype(np.uint8)
    return common_pb2.ImageData(bits_per_pixel=bits, size=common_pb2.Size2DI(x=grid_xy.shape[0], y=grid_xy.shape[1]),
                                data=data.tobytes())


class TestGame:
    """One game of map ``spec`` on the native engine, seen by players 1 (red) and 2 (blue)."""

    __test__ = False  # not a pytest test class

    def __init__(self, spec: MapSpec, custom_id_base: int = DEFAULT_CUSTOM_ID_BASE) -> None:
        self.spec = spec
        # Deterministic stand-in: no weapon-delay randomness, so a native run without it is an exact reference.
        self.engine = BattleEngine(spec, batch_size=1, step_mul=1, cooldown_jitter=None)
        layout = self.engine.layout
        self.n_units = self.engine.n_units
        self.owner = np.where(layout.side == RED, 1, 2).astype(np.int32)
        # The map's own spelling of each slot's unit name ("Colosus_RL" in 1c3s5z).
        spelling = {UNITS[g.type_id].sc2_name: g.unit for g in (*spec.red, *spec.blue)}
        self.slot_names = [spelling[UNITS[t].sc2_name] for t in layout.utype]
        custom = sorted({n for n, t in zip(self.slot_names, layout.utype, strict=True) if UNITS[t].passive})
        self.type_ids: dict[str, int] = {u.sc2_name: u.sc2_id for u in UNITS if not u.passive}
        self.type_ids.update({name: custom_id_base + rank for rank, name in enumerate(custom)})
        self.slot_type_ids = np.array([self.type_ids[n] for n in self.slot_names], dtype=np.int64)
        self.game_loop = 0
        self.generation = 0
        self.tags = np.zeros(self.n_units, dtype=np.uint64)
        self.slot_of_tag: dict[int, int] = {}
        self.pending = Commands.empty(1, self.n_units)
        self._z = np.interp(spec.cliff, *_CLIFF_TO_Z)
        self._spawn()

    # -----------------------------------------------------------------------------------------------------------
    # Time and the respawn trigger.

    def _spawn(self) -> None:
        """Both armies at the map layout with fresh tags (game start and the "all units died" trigger)."""
        self.engine.reset()
        self.generation += 1
        self.tags = (np.uint64(self.generation) << np.uint64(32)) + np.arange(1, self.n_units + 1, dtype=np.uint64)
        self.slot_of_tag = {int(t): i for i, t in enumerate(self.tags)}
        self.pending.clear()
        self._round_reported()

    def advance(self, loops: int) -> None:
        """Run ``loops`` game loops with the commands received since the last advance."""
        if loops <= 0:
            return
        if self.engine.state.alive[0].any():
            self.engine.step(self.pending, n_loops=loops)
            self._round_reported()
        self.pending.clear()
        self.game_loop += loops
        if not self.engine.state.alive[0].any():
            self._spawn()

    def _round_reported(self) -> None:
        """Keep the fields the protocol reports at float32, so the game is exactly what the players observe."""
        st = self.engine.state
        for name in REPORTED_FIELDS:
            array = getattr(st, name)
            array[:] = array.astype(np.float32)

    # -----------------------------------------------------------------------------------------------------------
    # Requests.

    def live_slot(self, tag: int) -> int:
        """The slot of a live unit's tag, or NO_UNIT."""
        slot = self.slot_of_tag.get(int(tag), NO_UNIT)
        return slot if slot != NO_UNIT and self.engine.state.alive[0, slot] else NO_UNIT

    def unit_command(self, player: int, cmd: raw_pb2.ActionRawUnitCommand) -> int:
        """Queue one raw unit command from ``player``; returns an ``ActionResult`` value."""
        kind = abilities.target_kind(cmd.HasField("target_unit_tag"), cmd.HasField("target_world_space_pos"))
        command = abilities.RAW_TO_COMMAND.get((cmd.ability_id, kind))
        if command is None:
            return error_pb2.NotSupported
        target = NO_UNIT
        if kind == abilities.UNIT:
            target = self.live_slot(cmd.target_unit_tag)
            if target == NO_UNIT:
                return error_pb2.CantTargetThatUnit
        slots = [self.live_slot(t) for t in cmd.unit_tags]
        if not slots or any(s == NO_UNIT or self.owner[s] != player for s in slots):
            return error_pb2.YouCantControlThatUnit  # a dead, unknown or foreign unit
        p = self.pending
        for s in slots:
            p.kind[0, s] = command
            p.target[0, s] = target
            p.x[0, s] = cmd.target_world_space_pos.x
            p.y[0, s] = cmd.target_world_space_pos.y
        return error_pb2.Success

    def debug(self, command: debug_pb2.DebugCommand) -> None:
        """Kill units or set a unit's life, shields or energy; other debug commands are ignored."""
        st = self.engine.state
        if command.HasField("kill_unit"):
            for tag in command.kill_unit.tag:
                slot = self.live_slot(tag)
                if slot != NO_UNIT:
                    st.alive[0, slot] = False
                    st.health[0, slot] = st.shield[0, slot] = 0.0
                    st.order[0, slot] = ORDER_IDLE
                    self.pending.kind[0, slot] = CMD_NOOP
        elif command.HasField("unit_value"):
            value = command.unit_value
            slot = self.live_slot(value.unit_tag)
            field = {debug_pb2.DebugSetUnitValue.Life: st.health, debug_pb2.DebugSetUnitValue.Shields: st.shield,
                     debug_pb2.DebugSetUnitValue.Energy: st.energy}.get(value.unit_value)
            if slot != NO_UNIT and field is not None:
                field[0, slot] = value.value  # already a float32 in the request

    # -----------------------------------------------------------------------------------------------------------
    # Responses.

    def units(self, player: int) -> list[raw_pb2.Unit]:
        """Every live unit (fog is off on SMAC maps), from ``player``'s point of view."""
        st = self.engine.state
        out = []
        for s in np.flatnonzero(st.alive[0]):
            t = int(st.utype[0, s])
            x, y = float(st.x[0, s]), float(st.y[0, s])
            cx, cy = min(int(x), self.spec.size[0] - 1), min(int(y), self.spec.size[1] - 1)
            unit = raw_pb2.Unit(
                display_type=raw_pb2.Visible,
                alliance=raw_pb2.Self if self.owner[s] == player else raw_pb2.Enemy,
                tag=int(self.tags[s]), unit_type=int(self.slot_type_ids[s]), owner=int(self.owner[s]),
                pos=common_pb2.Point(x=x, y=y, z=float(self._z[cx, cy])), facing=0.0,
                radius=float(STATS[t, S["radius"]]), build_progress=1.0,
                health=float(st.health[0, s]), health_max=float(STATS[t, S["health"]]),
                shield=float(st.shield[0, s]), shield_max=float(STATS[t, S["shield"]]),
                energy=float(st.energy[0, s]), energy_max=float(STATS[t, S["energy_max"]]),
                is_flying=bool(UNITS[t].is_air), weapon_cooldown=max(float(st.cooldown[0, s]), 0.0),
            )
            target = int(st.target[0, s])
            if target != NO_UNIT:  # reported as the engine holds it, even in the loop its target died
                unit.engaged_target_tag = int(self.tags[target])
            order = abilities.ORDER_TO_RAW.get(int(st.order[0, s]))
            if order is not None:
                raw_order = unit.orders.add(ability_id=order.ability)
                if order.target == abilities.UNIT:
                    raw_order.target_unit_tag = int(self.tags[st.order_target[0, s]])
                elif order.target == abilities.POINT:
                    raw_order.target_world_space_pos.x = float(st.order_x[0, s])
                    raw_order.target_world_space_pos.y = float(st.order_y[0, s])
            out.append(unit)
        return out

    def observation(self, player: int) -> sc_pb.ResponseObservation:
        obs = sc_pb.ResponseObservation()
        obs.observation.game_loop = self.game_loop
        obs.observation.player_common.player_id = player
        obs.observation.raw_data.units.extend(self.units(player))
        return obs

    def game_info(self, map_path: str, races: dict[int, int],
                  options: sc_pb.InterfaceOptions) -> sc_pb.ResponseGameInfo:
        sx, sy = self.spec.size
        info = sc_pb.ResponseGameInfo(map_name=self.spec.name, local_map_path=map_path, options=options)
        for player_id, race in sorted(races.items()):
            info.player_info.add(player_id=player_id, type=sc_pb.Participant, race_requested=race, race_actual=race)
        raw = info.start_raw
        raw.map_size.x, raw.map_size.y = sx, sy
        raw.pathing_grid.CopyFrom(_image(self.spec.pathable, 1))
        raw.placement_grid.CopyFrom(_image(self.spec.pathable, 1))
        raw.terrain_height.CopyFrom(_image(_height_bytes(self._z), 8))
        raw.playable_area.p0.x, raw.playable_area.p0.y = 0, 0
        raw.playable_area.p1.x, raw.playable_area.p1.y = sx, sy
        return info

    def data(self) -> sc_pb.ResponseData:
        """Unit type names and ids (standard ids, then the map's custom types) and the abilities it understands."""
        res = sc_pb.ResponseData()
        for ability_id, name in sorted(abilities.ABILITY_NAMES.items()):
            res.abilities.add(ability_id=ability_id, link_name=name, friendly_name=name, available=True)
        races = {u.sc2_name: RACES[u.race] for u in UNITS}
        slot_types = zip(self.slot_names, self.engine.layout.utype, strict=True)
        races.update({name: RACES[UNITS[int(t)].race] for name, t in slot_types})
        for name, unit_id in sorted(self.type_ids.items(), key=lambda item: item[1]):
            res.units.add(unit_id=unit_id, name=name, available=True, race=races[name])
        return res

    def replay(self) -> bytes:
        doc = {"map": self.spec.name, "game_loop": self.game_loop, "respawns": self.generation - 1}
        return REPLAY_MAGIC + json.dumps(doc).encode()


class Lockstep:
    """Advances a :class:`TestGame` once every joined player has asked for the loops.

    Each player's ``step(count)`` raises its own goal to ``max(goal, game_loop) + count``; the game runs to the
    smallest goal among joined players, and each ``step`` returns once the game has reached that player's goal.
    A player who leaves no longer holds the game back.
    """

    def __init__(self, game: TestGame) -> None:
        self.game = game
        self.goals: dict[int, int] = {}
        self._waiters: list[tuple[int, asyncio.Future]] = []

    def join(self, player: int) -> None:
        self.goals[player] = self.game.game_loop

    def leave(self, player: int) -> None:
        self.goals.pop(player, None)
        self._run()

    async def step(self, player: int, count: int) -> int:
        goal = max(self.goals.get(player, self.game.game_loop), self.game.game_loop) + max(int(count), 1)
        self.goals[player] = goal
        self._run()
        if self.game.game_loop < goal:
            future = asyncio.get_running_loop().create_future()
            self._waiters.append((goal, future))
            await future
        return self.game.game_loop

    def _run(self) -> None:
        if self.goals:
            target = min(self.goals.values())
            self.game.advance(target - self.game.game_loop)
        still = []
        for goal, future in self._waiters:
            if goal <= self.game.game_loop or not self.goals:
                if not future.done():
                    future.set_result(None)
            else:
                still.append((goal, future))
        self._waiters = still
