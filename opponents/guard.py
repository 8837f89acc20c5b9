"""The guard around untrusted scripts: exceptions, time limits and invalid commands become a :class:`ScriptError`.

A guarded script writes into a private command buffer; the guard checks every command of the active battles and
copies only this side's commands into the real buffer, so a faulty script can neither crash the engine with a bad
slot nor steer the other side. Checks (the error names script, map, battle, unit slot and the rule broken):

- the command kind is one of ``COMMAND_NAMES``;
- ``attack`` targets an alive unit of the other side; ``heal`` targets another alive unit of this side;
- ``move``/``attack_move`` points are finite (points outside the map are clamped by the engine);
- nothing is written for the other side's slots.

Time limits: a call that runs past ``time_limit`` seconds fails. In the main thread on POSIX an interval timer
interrupts a script that never returns; elsewhere the limit is checked when the call returns.
"""

from __future__ import annotations

import signal
import threading
import time
from contextlib import contextmanager

import numpy as np

from smac_hard_gym.engine.state import (
    CMD_ATTACK,
    CMD_ATTACK_MOVE,
    CMD_HEAL,
    CMD_MOVE,
    CMD_NOOP,
    COMMAND_NAMES,
    Commands,
)
from smac_hard_gym.opponents.api import Script, ScriptError, SideView

__all__ = ["GuardedScript", "DEFAULT_TIME_LIMIT"]

DEFAULT_TIME_LIMIT = 5.0  # seconds per reset/act call


class _Timeout(BaseException):
    """Raised inside the script by the interval timer (a BaseException, so ``except Exception`` cannot eat it)."""


@contextmanager
def _deadline(seconds: float | None):
    usable = (seconds is not None and hasattr(signal, "setitimer")
              and threading.current_thread() is threading.main_thread()
              and signal.getitimer(signal.ITIMER_REAL)[0] == 0.0)
    if not usable:
        yield
        return

    def on_alarm(signum, frame):
        raise _Timeout()

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)


class GuardedScript(Script):
    """Runs ``script`` under the guard; ``name``/``name_of`` are the wrapped script's."""

    def __init__(self, script: Script, time_limit: float | None = DEFAULT_TIME_LIMIT) -> None:
        if not isinstance(script, Script):
            raise TypeError(f"GuardedScript wraps a Script, got {script!r}")
        if time_limit is not None and not time_limit > 0:
            raise ValueError(f"time_limit must be a positive number of seconds or None, got {time_limit!r}")
        self.script = script
        self.time_limit = time_limit
        self.name = script.name
        self.description = script.description
        self._scratch: Commands | None = None

    def name_of(self, battle: int) -> str:
        return self.script.name_of(battle)

    def names_of(self, battles: np.ndarray) -> list[str]:
        return self.script.names_of(battles)

    def __repr__(self) -> str:
        return f"<GuardedScript {self.script!r} time_limit={self.time_limit}>"

    def _call(self, what: str, view: SideView, fn, *args) -> None:
        name = self.script.name
        start = time.perf_counter()
        try:
            with _deadline(self.time_limit):
                fn(*args)
        except _Timeout:
            raise ScriptError(name, view.spec.name, f"{what}() ran past its time limit of {self.time_limit:g} s "
                              "and was interrupted") from None
        except ScriptError:
            raise
        except Exception as err:
            raise ScriptError(name, view.spec.name, f"{what}() raised {type(err).__name__}: {err}") from err
        elapsed = time.perf_counter() - start
        if self.time_limit is not None and elapsed > self.time_limit:
            raise ScriptError(name, view.spec.name, f"{what}() took {elapsed:.3g} s, over its time limit of "
                              f"{self.time_limit:g} s")

    def reset(self, view: SideView, battles: np.ndarray, rngs: list[np.random.Generator]) -> None:
        self._call("reset", view, self.script.reset, view, battles, rngs)

    def act(self, view: SideView, commands: Commands, active: np.ndarray) -> None:
        shape = commands.kind.shape
        if self._scratch is None or self._scratch.kind.shape != shape:
            self._scratch = Commands.empty(*shape)
        scratch = self._scratch
        scratch.clear()
        scratch.x[:] = 0.0
        scratch.y[:] = 0.0
        self._call("act", view, self.script.act, view, scratch, active)
        rows = np.flatnonzero(active)
        if rows.size == 0:
            return
        problem = check_commands(view, scratch, rows)
        if problem:
            raise ScriptError(self.script.name, view.spec.name, problem)
        own = view.own
        wrote = scratch.kind[rows, own] != CMD_NOOP
        for dst, src in ((commands.kind, scratch.kind), (commands.target, scratch.target),
                         (commands.x, scratch.x), (commands.y, scratch.y)):
            block = dst[rows, own]
            np.copyto(block, src[rows, own], where=wrote)
            dst[rows, own] = block


def _first(mask: np.ndarray, rows: np.ndarray, start: int) -> tuple[int, int]:
    r, i = np.argwhere(mask)[0]
    return int(rows[r]), int(start + i)


def check_commands(view: SideView, commands: Commands, rows: np.ndarray) -> str:
    """The first rule broken by the commands of battles ``rows`` for ``view``'s side, or "" if they are valid."""
    state = view.state
    own, enemy = view.own, view.enemy
    other = np.ones(commands.kind.shape[1], dtype=bool)
    other[own] = False
    foreign = commands.kind[rows][:, other] != CMD_NOOP
    if foreign.any():
        r, i = np.argwhere(foreign)[0]
        slot = int(np.flatnonzero(other)[i])
        return (f"wrote a command for slot {slot} in battle {int(rows[r])}, which belongs to the other side "
                f"(this side's slots are {own.start}..{own.stop - 1})")
    kind = commands.kind[rows, own].astype(np.int64)
    target = commands.target[rows, own].astype(np.int64)
    bad_kind = (kind < 0) | (kind >= len(COMMAND_NAMES))
    if bad_kind.any():
        b, slot = _first(bad_kind, rows, own.start)
        allowed = ", ".join(f"{k} {n}" for k, n in enumerate(COMMAND_NAMES))
        return f"unknown command kind {int(commands.kind[b, slot])} for unit slot {slot} in battle {b}; " \
               f"allowed: {allowed}"
    n_units = commands.kind.shape[1]
    safe = np.clip(target, 0, n_units - 1)
    target_alive = (target >= 0) & (target < n_units) & state.alive[rows[:, None], safe]
    is_enemy = (target >= enemy.start) & (target < enemy.stop)
    is_own = (target >= own.start) & (target < own.stop)
    self_slot = own.start + np.arange(view.n_own)[None, :]
    bad_attack = (kind == CMD_ATTACK) & ~(is_enemy & target_alive)
    if bad_attack.any():
        b, slot = _first(bad_attack, rows, own.start)
        t = int(commands.target[b, slot])
        return (f"attack by unit slot {slot} in battle {b} targets slot {t}, which is not an alive enemy "
                f"(enemy slots are {enemy.start}..{enemy.stop - 1})")
    bad_heal = (kind == CMD_HEAL) & ~(is_own & target_alive & (target != self_slot))
    if bad_heal.any():
        b, slot = _first(bad_heal, rows, own.start)
        t = int(commands.target[b, slot])
        return (f"heal by unit slot {slot} in battle {b} targets slot {t}, which is not another alive unit of its "
                f"side (slots {own.start}..{own.stop - 1})")
    point = (kind == CMD_MOVE) | (kind == CMD_ATTACK_MOVE)
    bad_point = point & ~(np.isfinite(commands.x[rows, own]) & np.isfinite(commands.y[rows, own]))
    if bad_point.any():
        b, slot = _first(bad_point, rows, own.start)
        return (f"{COMMAND_NAMES[int(commands.kind[b, slot])]} by unit slot {slot} in battle {b} has a non-finite "
                f"point ({commands.x[b, slot]}, {commands.y[b, slot]})")
    return ""
