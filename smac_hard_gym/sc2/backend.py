"""``Sc2Backend``: real StarCraft II behind the same backend interface as the embedded engine.

Each battle of the batch is its own two-player game (two game processes) on SMAC-HARD's map. ``reset`` kills every
unit with a debug command and waits, a bounded number of game loops, for the map's "all units died" trigger to
respawn both armies (a newly started game is only observed); ``step`` sends both players' raw unit commands, steps
both in parallel by ``step_mul`` loops and observes both. Raw units become the engine's
:class:`~smac_hard_gym.engine.state.BattleState` (see :mod:`smac_hard_gym.sc2.convert`), so the SMAC features,
opponent scripts and every env above are shared with the native backend.

A protocol or connection error while playing closes that battle's game, starts a new one and marks the battle in
``restarted`` (bool per battle, set by the ``step`` that hit the error); the battle's state is then the new game's
spawn layout and its episode should be treated as over. ``restarts`` counts them all.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from s2clientprotocol import debug_pb2, raw_pb2
from s2clientprotocol import sc2api_pb2 as sc_pb

from smac_hard_gym.engine.scenario import build_layout
from smac_hard_gym.engine.state import BattleState, Commands, allocate_state
from smac_hard_gym.maps import MapSpec, load_map
from smac_hard_gym.sc2 import convert
from smac_hard_gym.sc2.compat import GAME_ERRORS
from smac_hard_gym.sc2.errors import Sc2Error, Sc2GameError
from smac_hard_gym.sc2.launcher import GamePair, GameSetup, LaunchOptions, launch_games
from smac_hard_gym.sc2.maps import find_sc2

__all__ = ["Sc2Backend"]

log = logging.getLogger(__name__)


def _positive_int(name: str, value: Any) -> int:
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < 1:
        raise ValueError(f"{name} must be a positive int, got {value!r}")
    return int(value)


class Sc2Backend:
    """``batch_size`` battles of one SMAC-HARD map on StarCraft II, through pysc2_evolved.

    Options (all keyword): ``sc2path`` (the game folder; default ``$SC2PATH``, then the platform default),
    ``game_version`` (a ``Versions/Base*`` build, default the newest), ``launch_timeout`` (seconds for one attempt to
    start and join a game, default 120), ``launch_attempts`` (default 3), ``request_timeout`` (seconds for any one
    request while playing, default 60), ``respawn_loops`` (game loops ``reset`` waits for the respawn, default 64),
    ``seed`` (the games' random seed; battle b gets ``seed + b``).

    Games start on the first ``reset`` (constructing the backend only checks that the game and the map exist).
    """

    def __init__(self, spec: MapSpec | str, batch_size: int = 1, step_mul: int = 8, *,
                 sc2path: str | os.PathLike | None = None, game_version: str | None = None,
                 launch_timeout: float = 120.0, launch_attempts: int = 3, request_timeout: float = 60.0,
                 respawn_loops: int = 64, seed: int | None = None) -> None:
        self.batch_size = _positive_int("batch_size", batch_size)
        self.step_mul = _positive_int("step_mul", step_mul)
        self.respawn_loops = _positive_int("respawn_loops", respawn_loops)
        if seed is not None and (not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0):
            raise ValueError(f"seed must be a non-negative int or None, got {seed!r}")
        self.spec = load_map(spec)
        self.layout = build_layout(self.spec)
        self.n_red, self.n_blue = self.layout.n_red, self.layout.n_blue
        self.n_units = self.n_red + self.n_blue
        self.options = LaunchOptions(game_version=game_version, launch_timeout=launch_timeout,
                                     launch_attempts=launch_attempts, request_timeout=request_timeout)
        self.install = find_sc2(sc2path)
        map_file = self.install.require_map(self.spec.name)
        self._setups = [GameSetup(self.install.relative_map_path(self.spec.name), map_file.read_bytes(),
                                  (convert.RACES[self.spec.red_race], convert.RACES[self.spec.blue_race]),
                                  None if seed is None else int(seed) + b)
                        for b in range(self.batch_size)]
        self.state: BattleState = allocate_state(self.batch_size, self.n_units)
        self.state.utype[:] = self.layout.utype
        self.state.side[:] = self.layout.side
        self.restarted = np.zeros(self.batch_size, dtype=bool)
        self.restarts = 0
        self.game_info: sc_pb.ResponseGameInfo | None = None
        self._games: list[GamePair | None] = [None] * self.batch_size
        self._names: list[dict[int, str]] = [{} for _ in range(self.batch_size)]
        self._rosters: list[convert.Roster | None] = [None] * self.batch_size
        self._latest: list[list[raw_pb2.Unit]] = [[] for _ in range(self.batch_size)]
        self._fresh = np.zeros(self.batch_size, dtype=bool)  # just started: units are there, nothing to kill
        self._episode_start = np.zeros(self.batch_size, dtype=np.int64)
        self._pool: ThreadPoolExecutor | None = None
        self._closed = False

    def __repr__(self) -> str:
        return (f"Sc2Backend(map={self.spec.name!r}, batch_size={self.batch_size}, step_mul={self.step_mul}, "
                f"sc2path={str(self.install.root)!r})")

    def __enter__(self) -> Sc2Backend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def pids(self) -> list[int]:
        """Process ids of every running game process."""
        return [pid for game in self._games if game is not None for pid in game.pids]

    # -----------------------------------------------------------------------------------------------------------
    # Backend interface.

    def reset(self, battles: np.ndarray | Sequence[int] | None = None, seeds: np.ndarray | None = None) -> None:
        """Start new episodes in ``battles`` (all when None): start games where none runs, else kill and respawn.

        ``seeds`` is accepted for the backend interface and ignored: the game draws its own randomness from the
        game seed (``seed`` option)."""
        self._check_open()
        rows = self._rows(battles)
        self._start([b for b in rows if self._games[b] is None])
        failed = self._respawn(rows)
        for b, err in failed.items():  # a broken game during reset: replace it, then the fresh game's units count
            self._replace(b, err)
        if failed:
            still = self._respawn(list(failed))
            if still:
                b, err = next(iter(still.items()))
                raise Sc2Error(f"battle {b}: the game failed again right after a restart: {err!r}") from err

    def step(self, commands: Commands, active: np.ndarray) -> None:
        """Send both players' commands, step both games by ``step_mul`` loops in parallel, observe both."""
        self._check_open()
        active = np.asarray(active, dtype=bool)
        if active.shape != (self.batch_size,):
            raise ValueError(f"active must have shape ({self.batch_size},), got {active.shape}")
        self.restarted[:] = False
        rows = [int(b) for b in np.flatnonzero(active)]
        if any(self._rosters[b] is None for b in rows):
            raise RuntimeError("reset() the battles before stepping them")
        players = (range(0, self.n_red), range(self.n_red, self.n_units))
        calls = {}
        for b in rows:
            for p, slots in enumerate(players):
                actions = convert.raw_actions(commands, b, slots, self._rosters[b], self.state.alive[b])
                calls[(b, p)] = (self._turn, self._games[b].controllers[p], actions, self.step_mul)
        results = self._parallel(calls)
        for b in rows:
            obs = (results[(b, 0)], results[(b, 1)])
            err = next((o for o in obs if isinstance(o, BaseException)), None)
            if err is None:
                err = self._ended(obs)
            if err is not None:
                self._replace(b, err)
                failed = self._respawn([b])
                if failed:
                    raise Sc2Error(f"battle {b}: the game failed again right after a restart: "
                                   f"{failed[b]!r}") from failed[b]
                self.restarted[b] = True
                continue
            self._store(b, obs)

    def close(self) -> None:
        """Stop every game (processes reaped, ports returned). Idempotent."""
        if getattr(self, "_closed", True):
            return
        self._closed = True
        for b, game in enumerate(self._games):
            if game is not None:
                game.close()
                self._games[b] = None
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __del__(self) -> None:
        self.close()

    def save_replay(self, path: str | os.PathLike, battle: int = 0) -> Path:
        """Save battle ``battle``'s replay to ``path`` (a ``.SC2Replay`` file, or a folder to put one in)."""
        self._check_open()
        b = self._rows([battle])[0]
        game = self._games[b]
        if game is None:
            raise RuntimeError(f"battle {b} has no running game; reset() first")
        data = game.controllers[0].save_replay()
        target = Path(path)
        if target.suffix.lower() != ".sc2replay":
            target = target / f"{self.spec.name}_battle{b}_loop{int(self._latest_loop(b))}.SC2Replay"
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
        return target

    # -----------------------------------------------------------------------------------------------------------
    # Games.

    def _start(self, rows: list[int]) -> None:
        if not rows:
            return
        pairs = launch_games([self._setups[b] for b in rows], self.options, str(self.install.root))
        for b, pair in zip(rows, pairs, strict=True):
            self._games[b] = pair
            self._fresh[b] = True
            self._rosters[b] = None
        first = pairs[0].controllers[0]
        info = first.game_info()
        size = (info.start_raw.map_size.x, info.start_raw.map_size.y)
        if size != tuple(self.spec.size):
            for b in rows:
                self._games[b].close()
                self._games[b] = None
            raise Sc2GameError(f"map {self.spec.name!r}: the game's map is {size[0]}x{size[1]} but the map file says "
                               f"{self.spec.size[0]}x{self.spec.size[1]}; is {self._setups[0].map_path} SMAC-HARD's?")
        self.game_info = info
        for b, pair in zip(rows, pairs, strict=True):
            data = pair.controllers[0].data_raw(ability_id=False, unit_type_id=True, upgrade_id=False,
                                                buff_id=False, effect_id=False)
            self._names[b] = convert.type_names(data)

    def _replace(self, b: int, cause: BaseException) -> None:
        """Close battle ``b``'s broken game and start a new one."""
        log.warning("battle %d of map %s: %s; restarting its game", b, self.spec.name, cause)
        game, self._games[b] = self._games[b], None
        self._rosters[b] = None  # until the new game has spawned: step() refuses the battle meanwhile
        if game is not None:
            game.close()
        self.restarts += 1
        self._start([b])

    def _respawn(self, rows: list[int]) -> dict[int, BaseException]:
        """Bring ``rows`` to a fresh spawn; returns the battles whose game failed (with the error)."""
        failed: dict[int, BaseException] = {}
        killed: dict[int, set[int]] = {}
        for b in rows:
            killed[b] = set()
            if self._fresh[b]:
                continue
            tags = [u.tag for u in self._latest[b]]
            killed[b] = set(tags)
            if tags:
                try:
                    self._games[b].controllers[0].debug(
                        debug_pb2.DebugCommand(kill_unit=debug_pb2.DebugKillUnit(tag=tags)))
                except GAME_ERRORS as err:
                    failed[b] = err
        waiting = [b for b in rows if b not in failed]
        for loop in range(self.respawn_loops + 1):
            calls = {(b, p): (self._game_observe, self._games[b].controllers[p]) for b in waiting for p in (0, 1)}
            results = self._parallel(calls)
            still = []
            for b in waiting:
                obs = (results[(b, 0)], results[(b, 1)])
                err = next((o for o in obs if isinstance(o, BaseException)), None) or self._ended(obs)
                if err is not None:
                    failed[b] = err
                elif self._spawned(b, obs, killed[b]):
                    self._begin(b, obs)
                else:
                    still.append(b)
            waiting = still
            if not waiting:
                return failed
            if loop < self.respawn_loops:
                calls = {(b, p): (self._game_step, self._games[b].controllers[p]) for b in waiting for p in (0, 1)}
                for (b, _), result in self._parallel(calls).items():
                    if isinstance(result, BaseException):
                        failed.setdefault(b, result)
                waiting = [b for b in waiting if b not in failed]
        b = waiting[0]
        units = self._merge(results[(b, 0)], results[(b, 1)])
        counts = [sum(u.owner == p for u in units) for p in (1, 2)]
        raise Sc2GameError(f"battle {b} of map {self.spec.name!r}: {self.respawn_loops} game loops after killing "
                           f"every unit the map's respawn trigger had brought back {counts[0]} red and {counts[1]} "
                           f"blue units (expected {self.n_red} and {self.n_blue}); is the installed map "
                           "SMAC-HARD's (its \"all units died\" trigger respawns both armies)?")

    def _spawned(self, b: int, obs: tuple, killed: set[int]) -> bool:
        units = self._merge(*obs)
        if any(u.tag in killed for u in units):
            return False
        red = sum(u.owner == convert.RED_PLAYER for u in units)
        blue = sum(u.owner == convert.BLUE_PLAYER for u in units)
        return (red, blue) == (self.n_red, self.n_blue)

    def _begin(self, b: int, obs: tuple) -> None:
        units = self._merge(*obs)
        self._rosters[b] = convert.read_roster(units, self._names[b], self.layout, self.spec.name)
        self._fresh[b] = False
        self._episode_start[b] = obs[0].observation.game_loop
        self.state.utype[b] = self.layout.utype
        self.state.side[b] = self.layout.side
        self._store(b, obs)

    def _store(self, b: int, obs: tuple) -> None:
        units = self._merge(*obs)
        self._latest[b] = units
        convert.fill_battle(self.state, b, self._rosters[b], units,
                            int(obs[0].observation.game_loop) - int(self._episode_start[b]))

    def _latest_loop(self, b: int) -> int:
        return int(self.state.loop[b] + self._episode_start[b])

    # -----------------------------------------------------------------------------------------------------------
    # Requests.

    @staticmethod
    def _merge(red_obs: sc_pb.ResponseObservation, blue_obs: sc_pb.ResponseObservation) -> list[raw_pb2.Unit]:
        """Red's units from player 1's view and blue's from player 2's (each side always sees its own units)."""
        red = [u for u in red_obs.observation.raw_data.units if u.owner == convert.RED_PLAYER]
        blue = [u for u in blue_obs.observation.raw_data.units if u.owner == convert.BLUE_PLAYER]
        return red + blue

    @staticmethod
    def _ended(obs: tuple) -> BaseException | None:
        if any(len(o.player_result) for o in obs):
            return Sc2Error("the game ended (a player left or was defeated)")
        return None

    @staticmethod
    def _turn(controller: Any, actions: list, loops: int) -> sc_pb.ResponseObservation:
        if actions:
            controller.actions(sc_pb.RequestAction(actions=actions))
        controller.step(loops)
        return controller.observe()

    @staticmethod
    def _game_step(controller: Any) -> None:
        controller.step(1)

    @staticmethod
    def _game_observe(controller: Any) -> sc_pb.ResponseObservation:
        return controller.observe()

    def _parallel(self, calls: dict[Any, tuple[Callable, ...]]) -> dict[Any, Any]:
        """Run every call at once (both players must step together); game errors come back as values."""
        if self._pool is None:
            self._pool = ThreadPoolExecutor(2 * self.batch_size, thread_name_prefix="sc2-player")
        futures = {key: self._pool.submit(fn, *args) for key, (fn, *args) in calls.items()}
        results = {}
        for key, future in futures.items():
            try:
                results[key] = future.result()
            except GAME_ERRORS as err:
                results[key] = err
        return results

    # -----------------------------------------------------------------------------------------------------------
    # Checks.

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("this Sc2Backend is closed")

    def _rows(self, battles: np.ndarray | Sequence[int] | None) -> list[int]:
        if battles is None:
            return list(range(self.batch_size))
        rows = np.asarray(battles).reshape(-1)
        if rows.dtype == bool:
            if rows.shape != (self.batch_size,):
                raise ValueError(f"a battle mask must have shape ({self.batch_size},), got {rows.shape}")
            return [int(b) for b in np.flatnonzero(rows)]
        if len(rows) and (rows.min() < 0 or rows.max() >= self.batch_size):
            raise ValueError(f"battle indices must lie in 0..{self.batch_size - 1}, got {battles!r}")
        return sorted({int(b) for b in rows})
