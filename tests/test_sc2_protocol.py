"""The protocol test server, driven the way a PySC2 client drives the game: pysc2_evolved's controllers over a real
websocket, the stand-in SC2_x64 started through pysc2's run_configs from a temporary SC2PATH.

Expected values come from the SMAC reference (docs/smac_interface.md): 3m's pathable strip y 8-23 (512 cells), spawns
at (9, 16) and (23, 16), marines with 45 HP moving 2.25 per Normal second (8 loops = 0.5 s), SC2's standard id 48
for Marine, custom types numbered after the built-in ids.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest
from s2clientprotocol import common_pb2, debug_pb2, error_pb2, raw_pb2
from s2clientprotocol import sc2api_pb2 as sc_pb

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.maps import load_map
from smac_hard_gym.sc2.compat import protocol
from smac_hard_gym.sc2.convert import decode_grid
from smac_hard_gym.sc2.errors import Sc2LaunchError
from smac_hard_gym.sc2.launcher import GameSetup, LaunchOptions, launch_games
from smac_hard_gym.sc2.testing.server import main as server_main
from smac_hard_gym.sc2.testing.standin import make_sc2path

MARINE_ID, CUSTOM_BASE = 48, 1970
MAP_PATH = "SMAC_HARD_maps/3m.SC2Map"


@pytest.fixture(scope="module")
def game(tmp_path_factory):
    root = make_sc2path(tmp_path_factory.mktemp("sc2"), maps=["3m"], custom_id_base=CUSTOM_BASE)
    setup = GameSetup(MAP_PATH, (root / "Maps" / MAP_PATH).read_bytes(), (common_pb2.Terran, common_pb2.Terran))
    BattleEngine("3m").step()  # compile (or load) the engine here first: the game host loads it from the cache
    [pair] = launch_games([setup], LaunchOptions(launch_timeout=300, launch_attempts=1), str(root))
    yield pair
    pair.close()


def _units(controller, owner=None):
    units = controller.observe().observation.raw_data.units
    return [u for u in units if owner is None or u.owner == owner]


def _step_both(pair, loops):
    results = [None, None]

    def run(i):
        results[i] = pair.controllers[i].step(loops)

    threads = [threading.Thread(target=run, args=(i,)) for i in (0, 1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    return results


def _command(tag, ability, x=None, y=None, target=None):
    cmd = raw_pb2.ActionRawUnitCommand(ability_id=ability, unit_tags=[tag])
    if target is not None:
        cmd.target_unit_tag = target
    if x is not None:
        cmd.target_world_space_pos.x, cmd.target_world_space_pos.y = x, y
    return sc_pb.RequestAction(actions=[sc_pb.Action(action_raw=raw_pb2.ActionRaw(unit_command=cmd))])


def test_game_info_reports_the_map_grid(game):
    info = game.controllers[0].game_info()
    raw = info.start_raw
    assert (raw.map_size.x, raw.map_size.y) == (32, 32)
    assert (raw.playable_area.p1.x, raw.playable_area.p1.y) == (32, 32)
    grid = decode_grid(raw.pathing_grid).astype(bool)
    assert grid.sum() == 32 * 16  # 3m: a 32x16 strip, rows y 8..23
    assert grid[:, 8:24].all() and not grid[:, :8].any() and not grid[:, 24:].any()
    assert np.array_equal(grid, load_map("3m").pathable)
    assert [p.race_actual for p in info.player_info] == [common_pb2.Terran, common_pb2.Terran]


def test_unit_data_names_standard_and_custom_ids(game):
    names = {u.unit_id: u.name for u in game.controllers[1].data_raw().units}
    assert names[MARINE_ID] == "Marine"
    assert names[CUSTOM_BASE] == "Marine_RL"
    assert max(i for i, n in names.items() if not n.endswith("_RL")) < CUSTOM_BASE


def test_both_players_see_both_armies_at_their_spawns(game):
    red_view, blue_view = (_units(c) for c in game.controllers)
    assert len(red_view) == len(blue_view) == 6
    red = [u for u in red_view if u.owner == 1]
    blue = [u for u in red_view if u.owner == 2]
    assert [u.unit_type for u in red] == [CUSTOM_BASE] * 3 and [u.unit_type for u in blue] == [MARINE_ID] * 3
    assert all(u.health == u.health_max == 45 for u in red_view)
    assert all(abs(u.pos.x - 9) < 1.5 and abs(u.pos.y - 16) < 1.5 for u in red)
    assert all(abs(u.pos.x - 23) < 1.5 and abs(u.pos.y - 16) < 1.5 for u in blue)
    assert {u.alliance for u in red} == {raw_pb2.Self} and {u.alliance for u in blue} == {raw_pb2.Enemy}
    flipped = {u.tag: u.alliance for u in blue_view}
    assert all(flipped[u.tag] == raw_pb2.Enemy for u in red) and all(flipped[u.tag] == raw_pb2.Self for u in blue)
    assert len({u.tag for u in red_view}) == 6


def test_step_waits_for_both_players(game):
    first, second = game.controllers
    loop0 = first.observe().observation.game_loop
    done = threading.Event()
    result = {}

    def step_first():
        result["loop"] = first.step(8).simulation_loop
        done.set()

    thread = threading.Thread(target=step_first)
    thread.start()
    assert not done.wait(0.5), "player 1's step returned before player 2 stepped"
    assert second.step(8).simulation_loop == loop0 + 8
    thread.join(30)
    assert result["loop"] == loop0 + 8
    assert first.observe().observation.game_loop == second.observe().observation.game_loop == loop0 + 8


def test_move_command_moves_a_marine_half_a_second(game):
    first = game.controllers[0]
    unit = max(_units(first, owner=1), key=lambda u: u.pos.x)  # the front marine: nothing ahead of it
    x0, y0 = unit.pos.x, unit.pos.y
    res = first.actions(_command(unit.tag, 16, x0 + 5, y0))
    assert list(res.result) == [error_pb2.Success]
    _step_both(game, 8)
    moved = {u.tag: u for u in _units(first)}[unit.tag]
    assert moved.pos.x - x0 == pytest.approx(2.25 * 0.5, abs=1e-4)  # 2.25 per Normal second, 8 loops
    assert moved.pos.y == pytest.approx(y0, abs=1e-4)
    assert moved.orders[0].ability_id == 16
    assert moved.orders[0].target_world_space_pos.x == pytest.approx(x0 + 5, abs=1e-4)


def test_commands_on_foreign_units_and_unknown_abilities_are_refused(game):
    first = game.controllers[0]
    blue = _units(first, owner=2)[0]
    red = _units(first, owner=1)[0]
    assert list(first.actions(_command(blue.tag, 4)).result) == [error_pb2.YouCantControlThatUnit]
    assert list(first.actions(_command(red.tag, 9999)).result) == [error_pb2.NotSupported]
    assert list(first.actions(_command(red.tag, 23, target=12345)).result) == [error_pb2.CantTargetThatUnit]


def test_debug_sets_life_and_kills_and_the_map_respawns_both_armies(game):
    first, second = game.controllers
    before = _units(first)
    first.debug(debug_pb2.DebugCommand(unit_value=debug_pb2.DebugSetUnitValue(
        unit_value=debug_pb2.DebugSetUnitValue.Life, value=20.0, unit_tag=before[0].tag)))
    assert {u.tag: u.health for u in _units(second)}[before[0].tag] == 20.0
    first.debug(debug_pb2.DebugCommand(kill_unit=debug_pb2.DebugKillUnit(tag=[before[1].tag])))
    assert before[1].tag not in {u.tag for u in _units(second)}
    first.debug(debug_pb2.DebugCommand(kill_unit=debug_pb2.DebugKillUnit(tag=[u.tag for u in before])))
    assert _units(first) == []
    _step_both(game, 1)
    after = _units(first)
    assert len(after) == 6 and not {u.tag for u in after} & {u.tag for u in before}
    assert all(u.health == 45 for u in after)
    red = sorted((u.pos.x, u.pos.y) for u in after if u.owner == 1)
    assert all(abs(x - 9) < 1.5 and abs(y - 16) < 1.5 for x, y in red)


def test_save_replay_and_unsupported_requests(game):
    first = game.controllers[0]
    assert b'"map": "3m"' in first.save_replay()
    with pytest.raises(protocol.ProtocolError, match="not supported"):
        first._client.send(restart_game=sc_pb.RequestRestartGame())


def test_a_player_who_leaves_no_longer_holds_the_game_back(game):
    # Last test of the module: the game cannot be rejoined afterwards.
    first, second = game.controllers
    loop0 = first.observe().observation.game_loop
    second.leave()
    assert second.status == protocol.Status.launched
    # A game held back by the departed player would block this step until the request timeout and raise; it
    # answers with the advanced loop instead.
    assert first.step(4).simulation_loop == loop0 + 4
    assert first.observe().observation.game_loop == loop0 + 4


def test_unknown_map_fails_the_launch_with_the_servers_reason(tmp_path):
    root = make_sc2path(tmp_path, maps=["3m"])
    setup = GameSetup("SMAC_HARD_maps/nope.SC2Map", b"MPQ\x1b", (common_pb2.Terran, common_pb2.Terran))
    with pytest.raises(Sc2LaunchError, match="unknown map 'nope'"):
        launch_games([setup], LaunchOptions(launch_timeout=30, launch_attempts=1), str(root))


def test_server_refuses_non_loopback_addresses(capsys):
    assert server_main(["-listen", "0.0.0.0", "-port", "5000"]) == 2
    assert "loopback only" in capsys.readouterr().err
