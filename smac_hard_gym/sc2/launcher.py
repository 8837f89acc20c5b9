"""Starting, joining and stopping two-player StarCraft II games, with bounded time and no leftovers.

Each game is a :class:`GamePair`: two game processes started through pysc2_evolved's ``run_configs`` (so the real
binary, or the test server's stand-in, gets ``-listen 127.0.0.1 -port P -dataDir ...``), one controller each, four
game ports from ``portspicker``. :func:`launch_games` starts several games together and gives every attempt a hard
deadline; failed attempts are cleaned up and retried a bounded number of times, then a :class:`Sc2LaunchError`
lists what each attempt hit.

Nothing outlives its owner: :meth:`GamePair.close` quits the controllers, terminates and waits for the processes
(no zombie) and returns every port; pairs still open when the interpreter exits are closed by an ``atexit`` hook;
on Linux each process gets ``PR_SET_PDEATHSIG`` = SIGKILL, so a parent killed outright takes its games along. The
signal fires when the *thread* that started the process ends, so processes are always started from the calling
thread, and only from the main thread (a game started from another thread relies on close/atexit alone).
"""

from __future__ import annotations

import atexit
import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import websocket
from s2clientprotocol import sc2api_pb2 as sc_pb

from smac_hard_gym.lifetime import die_with_parent_hook
from smac_hard_gym.sc2.compat import portspicker, remote_controller, run_configs
from smac_hard_gym.sc2.errors import Sc2LaunchError

__all__ = ["LaunchOptions", "GameProcess", "GamePair", "GameSetup", "launch_games", "close_all"]

@dataclass(frozen=True)
class LaunchOptions:
    """How games are started. Times in seconds."""

    game_version: str | None = None  # None: the newest Versions/Base* folder
    launch_timeout: float = 120.0  # one attempt: start both processes, connect, create and join the game
    launch_attempts: int = 3
    request_timeout: float = 60.0  # any single request once the game runs

    def __post_init__(self) -> None:
        for name in ("launch_timeout", "request_timeout"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not value > 0:
                raise ValueError(f"{name} must be a positive number of seconds, got {value!r}")
        if not isinstance(self.launch_attempts, int) or isinstance(self.launch_attempts, bool) \
                or self.launch_attempts < 1:
            raise ValueError(f"launch_attempts must be an int >= 1, got {self.launch_attempts!r}")


@dataclass(frozen=True)
class GameSetup:
    """What a new game needs: the map (path relative to ``<SC2PATH>/Maps`` and its bytes) and both races."""

    map_path: str
    map_data: bytes
    races: tuple[int, int]  # common_pb2.Race of player 1 (red) and player 2 (blue)
    seed: int | None = None


def _death_signal_hook() -> Any:
    """A ``preexec_fn`` that makes the child die with its parent (Linux, main thread), or None."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return die_with_parent_hook()


class _Controller(remote_controller.RemoteController):
    """pysc2's controller with a connect loop bounded by a wall-clock deadline.

    pysc2 retries once a second for ``timeout_seconds`` attempts, each of which may itself block that long on a
    process that accepts connections but never answers; here the whole connect and first ping end by ``deadline``.
    """

    def __init__(self, host: str, port: int, popen: Any, deadline: float) -> None:
        self._popen = popen
        self._deadline = deadline
        super().__init__(host, port, None, timeout_seconds=1)

    def _connect(self, host: str, port: int, proc: Any, timeout_seconds: int) -> websocket.WebSocket:
        url = f"ws://{host}:{port}/sc2api"
        last = "nothing listening yet"
        while True:
            remaining = self._deadline - time.monotonic()
            if remaining <= 0:
                raise Sc2LaunchError(f"the game at {url} did not answer in time ({last})")
            code = self._popen.poll() if self._popen is not None else None
            if code is not None:
                raise Sc2LaunchError(f"the game process exited with code {code} before {url} answered")
            try:
                return websocket.create_connection(url, timeout=remaining)
            except websocket.WebSocketBadStatusException as err:
                last = f"HTTP {err.status_code}"
            except (OSError, websocket.WebSocketException) as err:
                last = f"{type(err).__name__}: {err}" if str(err) else type(err).__name__
            time.sleep(min(0.1, max(remaining, 0.0)))

    def set_timeout(self, seconds: float) -> None:
        self._client._sock.settimeout(max(seconds, 0.01))


class GameProcess:
    """One game process and (once connected) its controller."""

    def __init__(self, run_config: Any) -> None:
        hook = _death_signal_hook()
        extra = {"preexec_fn": hook} if hook is not None else {}
        self.process = run_config.start(want_rgb=False, connect=False, **extra)
        self.port: int = self.process.port
        self.controller: _Controller | None = None

    @property
    def popen(self) -> Any:
        return getattr(self.process, "_proc", None)  # pysc2 keeps the Popen private; its `running` is unreliable

    @property
    def pid(self) -> int | None:
        popen = self.popen
        return popen.pid if popen is not None else None

    def connect(self, deadline: float) -> None:
        self.controller = _Controller(self.process.host, self.port, self.popen, deadline)

    def close(self) -> None:
        """Quit, terminate and reap the process, remove its temp folder and return its port. Idempotent."""
        if self.controller is not None:
            try:
                self.controller.quit()
            except Exception:  # noqa: BLE001 - a dead game cannot quit; the process is reaped below regardless
                pass
            self.controller = None
        process, self.process = self.process, None
        if process is not None:
            popen = getattr(process, "_proc", None)
            try:
                process.close()  # terminate, wait up to 3 s, kill and wait: never leaves a zombie
            finally:
                if popen is not None and popen.poll() is None:
                    popen.kill()
                    popen.wait()
                portspicker.return_ports([self.port])


_LIVE: set[GamePair] = set()
_LIVE_LOCK = threading.Lock()


class GamePair:
    """Two game processes playing one game: player 1 (red) and player 2 (blue)."""

    def __init__(self, run_config: Any) -> None:
        self.processes: list[GameProcess] = []
        self.ports: list[int] = []
        with _LIVE_LOCK:
            _LIVE.add(self)
        try:
            self.ports = portspicker.pick_unused_ports(4)
            for _ in range(2):
                self.processes.append(GameProcess(run_config))
        except BaseException:
            self.close()
            raise

    @property
    def controllers(self) -> list[_Controller]:
        return [p.controller for p in self.processes]

    @property
    def pids(self) -> list[int]:
        return [p.pid for p in self.processes if p.pid is not None]

    def join(self, setup: GameSetup, deadline: float) -> None:
        """Connect both controllers, create the game on player 1's process and join both players in parallel."""
        for process in self.processes:
            process.connect(deadline)
            process.controller.set_timeout(deadline - time.monotonic())
        first = self.controllers[0]
        for controller in self.controllers:
            controller.save_map(setup.map_path, setup.map_data)
        create = sc_pb.RequestCreateGame(local_map=sc_pb.LocalMap(map_path=setup.map_path), realtime=False)
        for _ in range(2):
            create.player_setup.add(type=sc_pb.Participant)
        if setup.seed is not None:
            create.random_seed = int(setup.seed)
        first.create_game(create)
        joins = []
        for race in setup.races:
            join = sc_pb.RequestJoinGame(race=race, options=sc_pb.InterfaceOptions(raw=True, score=False))
            join.server_ports.game_port, join.server_ports.base_port = self.ports[0], self.ports[1]
            join.client_ports.add(game_port=self.ports[2], base_port=self.ports[3])
            joins.append(join)
        with ThreadPoolExecutor(2, thread_name_prefix="sc2-join") as pool:
            for future in [pool.submit(c.join_game, j) for c, j in zip(self.controllers, joins, strict=True)]:
                future.result()

    def set_timeout(self, seconds: float) -> None:
        for controller in self.controllers:
            controller.set_timeout(seconds)

    def close(self) -> None:
        """Stop both processes and return every port. Idempotent."""
        for process in self.processes:  # ask both to quit first, so they wind down together
            if process.controller is not None:
                try:
                    process.controller.quit()
                except Exception:  # noqa: BLE001 - see GameProcess.close
                    pass
                process.controller = None
        for process in self.processes:
            process.close()
        self.processes = []
        if self.ports:
            portspicker.return_ports(self.ports)
            self.ports = []
        with _LIVE_LOCK:
            _LIVE.discard(self)


def _run_config(game_version: str | None, sc2_root: str) -> Any:
    """pysc2's run config for this platform; SC2PATH is pinned to the folder we checked."""
    previous = os.environ.get("SC2PATH")
    os.environ["SC2PATH"] = sc2_root
    try:
        return run_configs.get(version=game_version)
    finally:
        if previous is None:
            del os.environ["SC2PATH"]
        else:
            os.environ["SC2PATH"] = previous


def launch_games(setups: list[GameSetup], options: LaunchOptions, sc2_root: str) -> list[GamePair]:
    """Start one game per setup, all together; retry failed ones up to ``options.launch_attempts`` times.

    Each attempt of each game must be joined within ``options.launch_timeout`` seconds. On final failure every game
    started here is closed and a :class:`Sc2LaunchError` names the cause of each attempt.
    """
    run_config = _run_config(options.game_version, sc2_root)
    pairs: list[GamePair | None] = [None] * len(setups)
    failures: dict[int, list[str]] = {i: [] for i in range(len(setups))}
    try:
        for attempt in range(1, options.launch_attempts + 1):
            pending = [i for i, p in enumerate(pairs) if p is None]
            if not pending:
                break
            started: dict[int, GamePair] = {}
            for i in pending:  # start from this thread: see the module docstring on PR_SET_PDEATHSIG
                try:
                    started[i] = GamePair(run_config)
                except Exception as err:  # noqa: BLE001 - reported in the final error
                    failures[i].append(f"attempt {attempt}: could not start the game: {err}")
            deadline = time.monotonic() + options.launch_timeout
            with ThreadPoolExecutor(max(len(started), 1), thread_name_prefix="sc2-launch") as pool:
                futures = {i: pool.submit(pair.join, setups[i], deadline) for i, pair in started.items()}
                for i, future in futures.items():
                    try:
                        future.result()
                    except Exception as err:  # noqa: BLE001 - reported in the final error
                        started[i].close()
                        failures[i].append(f"attempt {attempt}: {type(err).__name__}: {err}")
                        continue
                    started[i].set_timeout(options.request_timeout)
                    pairs[i] = started[i]
    except BaseException:
        for pair in pairs:
            if pair is not None:
                pair.close()
        raise
    if any(p is None for p in pairs):
        for pair in pairs:
            if pair is not None:
                pair.close()
        detail = "; ".join(f"game {i}: " + "; ".join(msgs) for i, msgs in failures.items() if msgs)
        raise Sc2LaunchError(
            f"could not start StarCraft II at {sc2_root} in {options.launch_attempts} attempt(s) of at most "
            f"{options.launch_timeout:g} s each ({detail}); check that the game runs (a first start can be slow: "
            f"raise launch_timeout) and that the map installed with `smac-hard-gym maps install` matches")
    return [p for p in pairs if p is not None]


def close_all() -> None:
    """Close every game still open in this process (also run at interpreter exit)."""
    with _LIVE_LOCK:
        pairs = list(_LIVE)
    for pair in pairs:
        pair.close()


atexit.register(close_all)
