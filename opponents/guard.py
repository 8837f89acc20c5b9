"""The guard around user scripts: exceptions, time limits and invalid commands become a :class:`ScriptError`.

The guard is a convenience and a bug catcher for scripts you wrote or trust, not a security boundary: the script
runs in the host's interpreter, with the host's memory, files and modules in reach. What it does promise, for a
script that is not trying to get around it:

- read-only copies of the battle state (:meth:`SideView.read_only`): a write raises and becomes a ScriptError, and
  nothing the script does to its copy reaches the engine;
- checked commands: the script writes into a private command buffer; the guard checks every command of the active
  battles and copies only this side's valid commands into the real buffer, so a faulty script can neither crash the
  engine with a bad slot nor steer the other side (a buffer the script resized or retyped is a ScriptError too).
  The error names script, map, battle, unit slot and the rule broken:

  - the command kind is one of ``COMMAND_NAMES``;
  - ``attack`` targets an alive unit of the other side; ``heal`` targets another alive unit of this side;
  - ``move``/``attack_move`` points are finite (points outside the map are clamped by the engine);
  - nothing is written for the other side's slots;

- every exception a script raises becomes a ScriptError: ``sys.exit()``, ``GeneratorExit`` and other
  BaseExceptions included. KeyboardInterrupt is the exception: it propagates, because a real Ctrl-C must still stop
  the program and the guard cannot cheaply tell it from one the script raised;
- a time limit, best effort: a watchdog thread raises an exception inside the script's thread once ``time_limit``
  has passed, and again every limit while it keeps running (on any thread; no signal or interval timer is used, so
  the caller's own ``SIGALRM``/``ITIMER_REAL`` are never touched). A call that returns late is still reported as
  over its limit.

What it cannot stop (in-process Python cannot): a script that catches BaseException in a loop keeps running for
ever (the host hangs); Python only delivers the exception between bytecodes, so a script stuck in one C call (a
long ``time.sleep``, a blocking read, a C extension loop) is interrupted only when that call returns; a script can
monkeypatch the project or any module (later envs in the host see the change), leave threads that keep the host
alive at exit, fork processes that outlive it, read and write anything the host can, end the host with
``os._exit`` or crash it (a segfault). On Python implementations without ``ctypes.pythonapi`` (not CPython) the
limit is only checked when the call returns. For scripts you do not trust, run them in a child process:
``make_opponent(..., isolation="process")`` (:class:`~smac_hard_gym.opponents.sandbox.ProcessIsolatedScript`, the
default for scripts loaded from a file or module reference).
"""

from __future__ import annotations

import ctypes
import os
import threading
import time

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
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.opponents.api import Script, ScriptError, SideView, frozen_copy, read_only_spec

__all__ = ["GuardedScript", "DEFAULT_TIME_LIMIT", "check_commands", "call_guarded"]

DEFAULT_TIME_LIMIT = 5.0  # seconds per reset/act call
_MIN_REPEAT = 0.05  # seconds between shots at a script that keeps running past its limit


class _Timeout(BaseException):
    """Raised inside the script by the watchdog (a BaseException, so ``except Exception`` cannot eat it)."""


_set_async_exc = getattr(getattr(ctypes, "pythonapi", None), "PyThreadState_SetAsyncExc", None)


class _Alarm:
    """One armed call: the thread to interrupt, when, and how many shots were fired at it."""

    __slots__ = ("thread_id", "deadline", "repeat", "shots")

    def __init__(self, seconds: float) -> None:
        self.thread_id = threading.get_ident()
        self.deadline = time.monotonic() + seconds
        self.repeat = max(seconds, _MIN_REPEAT)
        self.shots = 0


class _Watchdog:
    """One daemon thread for every guarded call in the process: it fires :class:`_Timeout` into the thread of
    each call past its deadline. Arming and disarming take one lock, and the thread only wakes at deadlines."""

    def __init__(self) -> None:
        self._after_fork()

    def _after_fork(self) -> None:
        # A forked child has no watchdog thread and may have copied the lock while held: start afresh.
        self._cond = threading.Condition()
        self._armed: set[_Alarm] = set()
        self._wake_at = float("inf")
        self._thread: threading.Thread | None = None

    def arm(self, seconds: float) -> _Alarm:
        alarm = _Alarm(seconds)
        with self._cond:
            self._armed.add(alarm)
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._run, name="smac-hard-gym script watchdog", daemon=True)
                self._thread.start()
            if alarm.deadline < self._wake_at:
                self._cond.notify()
        return alarm

    def disarm(self, alarm: _Alarm) -> None:
        """After this returns no shot is pending or will be fired for ``alarm``. A shot fired just before may
        still be raised while this runs: callers catch :class:`_Timeout` around it."""
        with self._cond:
            self._armed.discard(alarm)
            if alarm.shots:
                _set_async_exc(ctypes.c_ulong(alarm.thread_id), None)  # drop a shot not raised yet

    def _run(self) -> None:
        with self._cond:
            while True:
                now = time.monotonic()
                for alarm in self._armed:
                    if alarm.deadline <= now:
                        _set_async_exc(ctypes.c_ulong(alarm.thread_id), ctypes.py_object(_Timeout))
                        alarm.shots += 1
                        alarm.deadline = now + alarm.repeat
                self._wake_at = min((a.deadline for a in self._armed), default=float("inf"))
                self._cond.wait(None if self._wake_at == float("inf") else self._wake_at - now)


_WATCHDOG = _Watchdog() if _set_async_exc is not None else None
if _WATCHDOG is not None and hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_WATCHDOG._after_fork)


def _run_limited(seconds: float | None, fn, args) -> bool:
    """Call ``fn(*args)``; True when the watchdog interrupted it past ``seconds`` (its other exceptions
    propagate)."""
    if seconds is None or _WATCHDOG is None:
        fn(*args)
        return False
    alarm = _WATCHDOG.arm(seconds)
    try:
        try:
            fn(*args)
        finally:
            _WATCHDOG.disarm(alarm)
    except _Timeout:
        _WATCHDOG.disarm(alarm)
        if not alarm.shots:  # an outer guard's shot (nested guards on one thread): not ours to report
            raise
        return True
    return False


def call_guarded(name: str, map_name: str, label: str, time_limit: float | None, fn, args: tuple = ()) -> None:
    """Call ``fn(*args)`` under the time limit (None: none); what goes wrong raises a ScriptError for script ``name``
    on ``map_name``, its cause starting with ``label`` ("act()", "the policy"): an exception, ``sys.exit``, running
    past the limit (interrupted, or returning late from one C call). Ctrl-C and a wrapped sandbox's ScriptError pass
    through unchanged."""
    start = time.perf_counter()
    try:
        timed_out = _run_limited(time_limit, fn, args)
    except (ScriptError, KeyboardInterrupt, _Timeout):
        raise  # a wrapped sandbox's error, Ctrl-C (see the module docstring), an outer guard's shot
    except SystemExit as err:
        raise ScriptError(name, map_name, f"{label} called sys.exit({err.code!r})") from None
    except BaseException as err:  # GeneratorExit and the script's own BaseException subclasses too
        raise ScriptError(name, map_name, f"{label} raised {type(err).__name__}: {err}") from err
    if timed_out:
        raise ScriptError(name, map_name, f"{label} ran past its time limit of {time_limit:g} s and was interrupted")
    elapsed = time.perf_counter() - start
    if time_limit is not None and elapsed > time_limit:
        raise ScriptError(name, map_name, f"{label} took {elapsed:.3g} s, over its time limit of {time_limit:g} s")


class GuardedScript(Script):
    """Runs ``script`` under the guard (see the module docstring); ``name``/``name_of`` are the wrapped script's.

    ``time_limit``: seconds per ``reset``/``act`` call, None for no limit.
    """

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
        self._specs: tuple[MapSpec, MapSpec] | None = None  # (live spec, its read-only twin)

    def name_of(self, battle: int) -> str:
        return self.script.name_of(battle)

    def names_of(self, battles: np.ndarray) -> list[str]:
        return self.script.names_of(battles)

    def __repr__(self) -> str:
        return f"<GuardedScript {self.script!r} time_limit={self.time_limit}>"

    def close(self) -> None:
        """Close the wrapped script when it holds resources (a sandboxed script's child process)."""
        close = getattr(self.script, "close", None)
        if callable(close):
            close()

    def _read_only(self, view: SideView) -> SideView:
        if self._specs is None or self._specs[0] is not view.spec:
            self._specs = (view.spec, read_only_spec(view.spec))
        return view.read_only(self._specs[1])

    def _call(self, what: str, view: SideView, fn, *args) -> None:
        call_guarded(self.script.name, view.spec.name, f"{what}()", self.time_limit, fn, args)

    def reset(self, view: SideView, battles: np.ndarray, rngs: list[np.random.Generator]) -> None:
        # A copy of the list: the script may keep or draw from the generators, not replace the caller's.
        self._call("reset", view, self.script.reset, self._read_only(view),
                   frozen_copy(np.asarray(battles, dtype=np.int64)), list(rngs))

    def act(self, view: SideView, commands: Commands, active: np.ndarray) -> None:
        shape = commands.kind.shape
        if self._scratch is None or self._scratch.kind.shape != shape:
            self._scratch = Commands.empty(*shape)
        scratch = self._scratch
        scratch.clear()
        scratch.x[:] = 0.0
        scratch.y[:] = 0.0
        self._call("act", view, self.script.act, self._read_only(view), scratch,
                   frozen_copy(np.asarray(active, dtype=bool)))
        rows = np.flatnonzero(active)
        problem = _broken_buffer(scratch, commands)
        if problem:
            self._scratch = None  # the next call gets a fresh one
            raise ScriptError(self.script.name, view.spec.name, problem)
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


def _broken_buffer(scratch: Commands, like: Commands) -> str:
    """How a script broke its command buffer (``resize``, a new ``shape``/``dtype``/``strides``), or "" when each
    array still has the shape and dtype of the real buffer's."""
    for name, array, model in zip(Commands._fields, scratch, like, strict=True):
        if array.shape != model.shape or array.dtype != model.dtype or not array.flags.c_contiguous:
            return (f"act() broke its command buffer: commands.{name} is now {array.shape} {array.dtype}, expected "
                    f"{model.shape} {model.dtype}")
    return ""


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
