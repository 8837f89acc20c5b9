"""A StarCraft II protocol test server: s2clientprotocol over a loopback websocket, played by the native engine.

It stands in for the game binary wherever a PySC2 client has to be exercised without StarCraft II: it takes the
game's command line (``-listen HOST -port PORT -dataDir DIR ...``), serves ``ws://HOST:PORT/sc2api`` and answers
ping, available_maps, save_map, create_game, join_game, game_info, data, observation, action, step, debug, leave_game,
save_replay and quit. A two-player game spans two processes, as in the real game: the one that received create_game
hosts the game (:class:`~smac_hard_gym.sc2.testing.game.TestGame`) and opens a link on the ``server_ports.game_port`` of
the join request; the other joins through that port and forwards its requests. Players step in lockstep.

Debugging a client by hand::

    python -m smac_hard_gym.sc2.testing.server -listen 127.0.0.1 -port 5000 -dataDir "$SC2PATH"   # host
    python -m smac_hard_gym.sc2.testing.server -listen 127.0.0.1 -port 5001 -dataDir "$SC2PATH"   # second player

Maps are found by name: ``<dataDir>/Maps/SMAC_HARD_maps/3m.SC2Map`` (any content) plays the ``3m`` map file of
this package. What is not modelled: Computer players, replays (save_replay returns a small JSON document), queued
commands (``queue_command`` is treated as immediate), debug commands other than kill_unit and unit_value, fog.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import struct
import sys
from dataclasses import dataclass, field
from http import HTTPStatus
from pathlib import Path

from s2clientprotocol import sc2api_pb2 as sc_pb

from smac_hard_gym.maps import MapError, load_map
from smac_hard_gym.sc2.maps import MAP_SUFFIX

__all__ = ["main", "GAME_VERSION", "BASE_BUILD", "MODES"]

GAME_VERSION = "4.10.0"
BASE_BUILD = 75689
JOIN_TIMEOUT = 60.0  # seconds a join waits for the other player
MODES = ("serve", "hang", "silent")  # serve the protocol; accept connections but never answer; never listen

_LAUNCHED, _INIT, _IN_GAME, _ENDED, _QUIT = (sc_pb.launched, sc_pb.init_game, sc_pb.in_game, sc_pb.ended,
                                             sc_pb.quit)
_FRAME = struct.Struct(">I")


async def _read_frame(reader: asyncio.StreamReader) -> bytes:
    (size,) = _FRAME.unpack(await reader.readexactly(_FRAME.size))
    return await reader.readexactly(size)


def _write_frame(writer: asyncio.StreamWriter, payload: bytes) -> None:
    writer.write(_FRAME.pack(len(payload)) + payload)


def _error(request: sc_pb.Request, status: int, message: str) -> sc_pb.Response:
    res = sc_pb.Response(id=request.id, status=status)
    res.error.append(f"test server: {message}")
    return res


@dataclass
class _Player:
    player_id: int
    race: int
    options: sc_pb.InterfaceOptions
    status: int = _IN_GAME


@dataclass
class _Host:
    """The game and its players, in the process that received create_game."""

    game: object  # TestGame (imported lazily: it loads the engine)
    lockstep: object
    map_path: str
    players: dict[int, _Player] = field(default_factory=dict)
    everyone: asyncio.Event = field(default_factory=asyncio.Event)

    def join(self, player_id: int, request: sc_pb.RequestJoinGame) -> None:
        self.players[player_id] = _Player(player_id, request.race, request.options)
        self.lockstep.join(player_id)
        if len(self.players) == 2:
            self.everyone.set()

    def leave(self, player_id: int) -> None:
        player = self.players.get(player_id)
        if player is not None and player.status == _IN_GAME:
            player.status = _LAUNCHED
        self.lockstep.leave(player_id)

    async def handle(self, player_id: int, request: sc_pb.Request) -> sc_pb.Response:
        name = request.WhichOneof("request")
        player = self.players[player_id]
        handler, allowed = _GAME_REQUESTS.get(name, (None, ()))
        if handler is None:
            return _error(request, player.status, f"request {name!r} is not supported by the test server")
        if player.status not in allowed:
            return _error(request, player.status, f"{name} is not valid in status {sc_pb.Status.Name(player.status)}")
        res = sc_pb.Response(id=request.id)
        await handler(self, player, getattr(request, name), res)
        res.status = player.status
        return res

    async def _game_info(self, player: _Player, req, res: sc_pb.Response) -> None:
        races = {p.player_id: p.race for p in self.players.values()}
        res.game_info.CopyFrom(self.game.game_info(self.map_path, races, player.options))

    async def _data(self, player: _Player, req, res: sc_pb.Response) -> None:
        res.data.CopyFrom(self.game.data())

    async def _observation(self, player: _Player, req, res: sc_pb.Response) -> None:
        res.observation.CopyFrom(self.game.observation(player.player_id))

    async def _action(self, player: _Player, req: sc_pb.RequestAction, res: sc_pb.Response) -> None:
        from s2clientprotocol import error_pb2

        for action in req.actions:
            if action.HasField("action_raw") and action.action_raw.HasField("unit_command"):
                res.action.result.append(self.game.unit_command(player.player_id, action.action_raw.unit_command))
            else:
                res.action.result.append(error_pb2.NotSupported)

    async def _step(self, player: _Player, req: sc_pb.RequestStep, res: sc_pb.Response) -> None:
        res.step.simulation_loop = await self.lockstep.step(player.player_id, req.count or 1)

    async def _debug(self, player: _Player, req: sc_pb.RequestDebug, res: sc_pb.Response) -> None:
        for command in req.debug:
            self.game.debug(command)
        res.debug.SetInParent()

    async def _save_replay(self, player: _Player, req, res: sc_pb.Response) -> None:
        res.save_replay.data = self.game.replay()

    async def _leave(self, player: _Player, req, res: sc_pb.Response) -> None:
        self.leave(player.player_id)
        res.leave_game.SetInParent()


_PLAYING = (_IN_GAME,)
_GAME_REQUESTS = {
    "game_info": (_Host._game_info, _PLAYING),
    "data": (_Host._data, _PLAYING),
    "observation": (_Host._observation, (_IN_GAME, _ENDED)),
    "action": (_Host._action, _PLAYING),
    "step": (_Host._step, _PLAYING),
    "debug": (_Host._debug, _PLAYING),
    "save_replay": (_Host._save_replay, (_IN_GAME, _ENDED)),
    "leave_game": (_Host._leave, (_IN_GAME, _ENDED)),
}


class StandIn:
    """One game process: its own client's status, the hosted game or the link to the host."""

    def __init__(self, data_dir: Path, custom_id_base: int) -> None:
        self.data_dir = data_dir
        self.custom_id_base = custom_id_base
        self.status = _LAUNCHED
        self.saved_maps: dict[str, bytes] = {}
        self.host: _Host | None = None
        self._link_server: asyncio.AbstractServer | None = None
        self._link: tuple[asyncio.StreamReader, asyncio.StreamWriter] | None = None
        self.stop = asyncio.Event()

    async def handle(self, request: sc_pb.Request) -> sc_pb.Response:
        name = request.WhichOneof("request")
        try:
            local = getattr(self, f"_on_{name}", None)
            if local is not None:
                res = await local(request)
            elif self.host is not None:
                res = await self.host.handle(1, request)
            elif self._link is not None:
                res = await self._forward(request)
            else:
                res = _error(request, self.status, f"{name} needs a game; status is {sc_pb.Status.Name(self.status)}")
        except Exception as err:  # a bug here must reach the client as an error, not hang it
            res = _error(request, self.status, f"{name} failed: {err!r}")
        self.status = res.status
        if name == "leave_game":
            await self._drop_link()
        return res

    # Requests every process answers itself.

    async def _on_ping(self, request: sc_pb.Request) -> sc_pb.Response:
        res = sc_pb.Response(id=request.id, status=self.status)
        res.ping.game_version, res.ping.data_build, res.ping.base_build = GAME_VERSION, BASE_BUILD, BASE_BUILD
        return res

    async def _on_quit(self, request: sc_pb.Request) -> sc_pb.Response:
        self.stop.set()
        res = sc_pb.Response(id=request.id, status=_QUIT)
        res.quit.SetInParent()
        return res

    async def _on_available_maps(self, request: sc_pb.Request) -> sc_pb.Response:
        res = sc_pb.Response(id=request.id, status=self.status)
        maps_root = self.data_dir / "Maps"
        paths = sorted(maps_root.rglob(f"*{MAP_SUFFIX}")) if maps_root.is_dir() else []
        res.available_maps.local_map_paths.extend(str(p.relative_to(maps_root)) for p in paths)
        return res

    async def _on_save_map(self, request: sc_pb.Request) -> sc_pb.Response:
        if self.status not in (_LAUNCHED, _INIT):
            return _error(request, self.status, "save_map is valid before the game starts")
        self.saved_maps[request.save_map.map_path] = request.save_map.map_data
        res = sc_pb.Response(id=request.id, status=self.status)
        res.save_map.SetInParent()
        return res

    async def _on_create_game(self, request: sc_pb.Request) -> sc_pb.Response:
        if self.status not in (_LAUNCHED, _ENDED):
            return _error(request, self.status, "create_game is valid only outside a game")
        req = request.create_game
        res = sc_pb.Response(id=request.id, status=self.status)
        out = res.create_game

        def fail(code: int, details: str) -> sc_pb.Response:
            out.error, out.error_details = code, f"test server: {details}"
            return res

        players = [p.type for p in req.player_setup]
        if players != [sc_pb.Participant, sc_pb.Participant]:
            return fail(sc_pb.ResponseCreateGame.InvalidPlayerSetup,
                        f"plays two Participant players only, got {[sc_pb.PlayerType.Name(t) for t in players]}")
        if not req.HasField("local_map"):
            return fail(sc_pb.ResponseCreateGame.MissingMap, "needs local_map (battlenet maps are not served)")
        path = req.local_map.map_path
        on_disk = Path(path) if Path(path).is_absolute() else self.data_dir / "Maps" / path
        if not (req.local_map.map_data or path in self.saved_maps or on_disk.is_file()):
            return fail(sc_pb.ResponseCreateGame.InvalidMapPath, f"map {path!r} not found at {on_disk}")
        name = Path(path).name
        name = name[: -len(MAP_SUFFIX)] if name.endswith(MAP_SUFFIX) else name
        try:
            spec = load_map(name)
        except MapError as err:
            return fail(sc_pb.ResponseCreateGame.InvalidMapName, str(err))
        from smac_hard_gym.sc2.testing.game import Lockstep, TestGame  # loads the engine: only the host needs it

        if self._link_server is not None:  # a new game after leaving the last one
            self._link_server.close()
            self._link_server = None
        game = TestGame(spec, self.custom_id_base)
        self.host = _Host(game, Lockstep(game), path)
        out.SetInParent()
        res.status = _INIT
        return res

    async def _on_join_game(self, request: sc_pb.Request) -> sc_pb.Response:
        req = request.join_game
        if self.status not in (_LAUNCHED, _INIT):
            return _error(request, self.status, f"join_game is not valid in status {sc_pb.Status.Name(self.status)}")
        res = sc_pb.Response(id=request.id, status=self.status)
        if not req.HasField("server_ports") or not req.server_ports.game_port:
            res.join_game.error = sc_pb.ResponseJoinGame.MissingPorts
            res.join_game.error_details = "test server: a two-player game needs server_ports"
            return res
        if self.host is None:
            return await self._join_remote(request)
        host = self.host
        self._link_server = await asyncio.start_server(self._serve_link, "127.0.0.1", req.server_ports.game_port)
        host.join(1, req)
        try:
            await asyncio.wait_for(host.everyone.wait(), JOIN_TIMEOUT)
        except asyncio.TimeoutError:
            res.join_game.error = sc_pb.ResponseJoinGame.OtherError
            res.join_game.error_details = f"test server: the second player did not join within {JOIN_TIMEOUT:.0f} s"
            return res
        res.join_game.player_id = 1
        res.status = _IN_GAME
        return res

    # The second player: join through the host's game port, then forward every game request.

    async def _join_remote(self, request: sc_pb.Request) -> sc_pb.Response:
        port = request.join_game.server_ports.game_port
        loop = asyncio.get_running_loop()
        deadline = loop.time() + JOIN_TIMEOUT
        while True:
            try:
                self._link = await asyncio.open_connection("127.0.0.1", port)
                break
            except OSError:
                if loop.time() > deadline:
                    res = sc_pb.Response(id=request.id, status=self.status)
                    res.join_game.error = sc_pb.ResponseJoinGame.NetworkError
                    res.join_game.error_details = f"test server: no game host on 127.0.0.1:{port}"
                    return res
                await asyncio.sleep(0.05)
        return await self._forward(request)

    async def _forward(self, request: sc_pb.Request) -> sc_pb.Response:
        reader, writer = self._link
        try:
            _write_frame(writer, request.SerializeToString())
            await writer.drain()
            return sc_pb.Response.FromString(await _read_frame(reader))
        except (OSError, asyncio.IncompleteReadError):
            await self._drop_link()
            return _error(request, _ENDED, "lost the connection to the game host")

    async def _drop_link(self) -> None:
        if self._link is not None:
            writer = self._link[1]
            self._link = None
            writer.close()
            with contextlib.suppress(OSError):
                await writer.wait_closed()

    async def _serve_link(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        """The host's end of the link: the second player's requests."""
        host = self.host
        try:
            request = sc_pb.Request.FromString(await _read_frame(reader))
            res = sc_pb.Response(id=request.id, status=_LAUNCHED)
            if request.WhichOneof("request") != "join_game" or 2 in host.players:
                res.join_game.error = sc_pb.ResponseJoinGame.GameFull
                _write_frame(writer, res.SerializeToString())
                return
            host.join(2, request.join_game)
            try:
                await asyncio.wait_for(host.everyone.wait(), JOIN_TIMEOUT)
                res.join_game.player_id, res.status = 2, _IN_GAME
            except asyncio.TimeoutError:
                res.join_game.error = sc_pb.ResponseJoinGame.OtherError
            _write_frame(writer, res.SerializeToString())
            await writer.drain()
            while True:
                request = sc_pb.Request.FromString(await _read_frame(reader))
                _write_frame(writer, (await host.handle(2, request)).SerializeToString())
                await writer.drain()
        except (OSError, asyncio.IncompleteReadError, asyncio.CancelledError):
            pass  # the second player went away, or this process is shutting down
        finally:
            if 2 in host.players:
                host.leave(2)
            writer.close()


async def _watch_parent(parent: int) -> None:
    """Exit when the launching process is gone (the child is re-parented), so no stand-in outlives its parent."""
    while os.getppid() == parent:
        await asyncio.sleep(0.25)
    os._exit(0)


async def _serve(args: argparse.Namespace) -> None:
    if args.exit_with_parent:
        watchdog = asyncio.create_task(_watch_parent(os.getppid()))  # noqa: F841 (kept alive by this frame)
    if args.mode == "silent":
        await asyncio.Event().wait()
    if args.mode == "hang":
        async def never_answer(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            await asyncio.Event().wait()

        server = await asyncio.start_server(never_answer, args.listen, args.port)
        async with server:
            await asyncio.Event().wait()

    from websockets.asyncio.server import serve
    from websockets.exceptions import ConnectionClosed

    standin = StandIn(Path(args.dataDir).expanduser(), args.custom_id_base)

    def only_sc2api(connection, request):
        if request.path != "/sc2api":
            return connection.respond(HTTPStatus.NOT_FOUND, "the SC2 API lives at /sc2api\n")
        return None

    async def client(connection) -> None:
        while True:
            try:  # pysc2 sends protobuf bytes in *text* frames, as the game accepts: read them undecoded
                message = await connection.recv(decode=False)
            except ConnectionClosed:
                return
            request = sc_pb.Request.FromString(message)
            response = await standin.handle(request)
            with contextlib.suppress(Exception):  # a quitting client does not wait for the answer
                await connection.send(response.SerializeToString())
            if standin.stop.is_set():
                break

    async with serve(client, args.listen, args.port, process_request=only_sc2api, max_size=None,
                     ping_interval=None, compression=None):
        print(f"SC2 protocol test server on ws://{args.listen}:{args.port}/sc2api", file=sys.stderr, flush=True)
        await standin.stop.wait()
    await standin._drop_link()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="SC2_x64 (smac-hard-gym test server)", description=__doc__.split("\n")[0])
    parser.add_argument("-listen", default="127.0.0.1", help="address to listen on (loopback)")
    parser.add_argument("-port", type=int, required=True, help="websocket port")
    parser.add_argument("-dataDir", default=os.environ.get("SC2PATH", "."), help="game folder holding Maps/")
    parser.add_argument("--custom-id-base", type=int, default=1970,
                        help="unit type id of the first custom *_RL unit (1970 as SC2 4.10 on Linux)")
    parser.add_argument("--mode", choices=MODES, default="serve",
                        help="serve: answer the protocol; hang: accept connections and never answer; "
                             "silent: never listen (both to test launch timeouts)")
    parser.add_argument("--exit-with-parent", action="store_true",
                        help="exit as soon as the launching process is gone")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the server with the game's command line; unknown game flags (-tempDir, -dataVersion...) are ignored."""
    args, _unknown = build_parser().parse_known_args(argv)
    if not args.listen.startswith("127.") and args.listen not in ("localhost", "::1"):
        print(f"test server: refusing to listen on {args.listen!r}; loopback only", file=sys.stderr)
        return 2
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(_serve(args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
