"""The process sandbox: an untrusted script runs in a child process that the host kills at the time limit.

The in-process guard (:mod:`~smac_hard_gym.opponents.guard`) cannot stop a script stuck in one C call, and a script
that crashes the interpreter or calls ``os._exit`` ends the host with it. :class:`ProcessIsolatedScript` runs the
script in a child process instead. Each ``reset``/``act`` ships a copy of the side view to the child and waits at
most ``time_limit`` seconds for its commands; past that, or when the child dies, the child is killed and a
:class:`ScriptError` names the script, the map and the cause ("timed out after 0.5 s", "exited with code 3", "died
from signal SIGSEGV"). The next call starts a fresh child (with no memory of earlier episodes: reset every battle
after a ScriptError). A child never outlives its host: it is killed on :meth:`~ProcessIsolatedScript.close`, when
the wrapper is collected, at interpreter exit, and by the kernel when the host dies (Linux).

A script given by reference (``file.py:Name``, ``module:Name``) is only ever imported in the child; a Script object
is sent with cloudpickle. The script's generators are copies: they start from the battles' seeded states and the
host's generators are set to where the child's ended after each call, so runs are as reproducible as in-process.
Commands come back through :class:`~smac_hard_gym.opponents.guard.GuardedScript`'s checks (``make_script`` wraps
the sandbox in the guard). The cost: one pickled round trip per call, and a process start (about a second) at
construction and after each failure.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
import traceback
import weakref
from contextlib import contextmanager
from multiprocessing.connection import Connection
from typing import Any

import cloudpickle
import numpy as np

from smac_hard_gym.engine.state import BattleState, Commands
from smac_hard_gym.lifetime import die_with_parent
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.opponents.api import Script, ScriptError, SideView
from smac_hard_gym.opponents.guard import DEFAULT_TIME_LIMIT

__all__ = ["ProcessIsolatedScript", "DEFAULT_START_TIMEOUT"]

DEFAULT_START_TIMEOUT = 60.0  # seconds for a child to start and load its script
_EXIT_WAIT = 2.0  # seconds to wait for a dead child's exit code


def _read_only(arrays: Any) -> None:
    for a in arrays:
        a.flags.writeable = False


def _load(entry: bytes) -> Script:
    from smac_hard_gym.opponents.loader import load_script

    loaded = cloudpickle.loads(entry)
    script = load_script(loaded) if isinstance(loaded, str) else loaded
    if not isinstance(script, Script):
        raise TypeError(f"the sandbox runs Script objects, got {script!r}")
    return script


def _child_main(conn: Connection, entry: bytes) -> None:
    """The child's loop: load the script, then answer ``reset``/``act`` requests until the host closes the pipe
    (or kills us)."""
    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the host's to handle; it kills us
    try:
        script = _load(entry)
    except BaseException as err:
        conn.send(("error", f"{type(err).__name__}: {err}"))
        return
    conn.send(("ready", script.name, script.description))
    spec: MapSpec | None = None
    rngs: list[Any] = []
    while True:
        try:
            request = conn.recv()
        except (EOFError, OSError):  # the host closed the pipe
            return
        what, new_spec, side, own, enemy, state, step, rows, extra = request
        spec = new_spec if new_spec is not None else spec
        _read_only((*state, step, rows))
        view = SideView(BattleState(*state), spec, side, own, enemy, step)
        if len(rngs) != view.batch_size:
            rngs = [None] * view.batch_size
        try:
            if what == "reset":
                for b, rng in zip(rows, extra, strict=True):
                    rngs[b] = rng
                script.reset(view, rows, rngs)
                touched, reply = rows, None
            else:
                commands = Commands(*extra)
                active = np.zeros(view.batch_size, dtype=bool)
                active[rows] = True
                active.flags.writeable = False
                script.act(view, commands, active)
                touched, reply = rows, tuple(commands)
            states = {int(b): rngs[b].bit_generator.state for b in touched if rngs[b] is not None}
        except SystemExit as err:
            conn.send(("failed", f"called sys.exit({err.code!r})", ""))
            continue
        except BaseException as err:
            text = "".join(traceback.format_exception(type(err), err, err.__traceback__))
            conn.send(("failed", f"raised {type(err).__name__}: {err}", text))
            continue
        conn.send(("ok", reply, states))


def _stop(process: mp.process.BaseProcess, conn: Connection) -> None:
    """Kill the child and close its pipe (safe to call twice; also the finaliser)."""
    try:
        conn.close()
    except OSError:
        pass
    if process.is_alive():
        process.kill()
    process.join(_EXIT_WAIT)


def _rebuild(entry: bytes, time_limit: float | None, start_timeout: float, start_method: str) -> Script:
    return ProcessIsolatedScript(cloudpickle.loads(entry), time_limit, start_timeout=start_timeout,
                                 start_method=start_method)


@contextmanager
def _children_allowed():
    """Let a daemonic process (a SubprocVectorEnv worker) start the sandbox child.

    multiprocessing refuses because a daemon's children would be orphaned when it is terminated; on Linux our
    child asks the kernel to kill it with its parent (PR_SET_PDEATHSIG), so that cannot happen. Elsewhere the
    refusal stands.
    """
    config = getattr(mp.current_process(), "_config", {})
    if not (config.get("daemon") and sys.platform.startswith("linux")):
        yield
        return
    config["daemon"] = False
    try:
        yield
    finally:
        config["daemon"] = True


def _start_method(start_method: str | None) -> str:
    methods = mp.get_all_start_methods()
    if start_method is None:
        return "forkserver" if "forkserver" in methods else "spawn"
    allowed = [m for m in ("forkserver", "spawn") if m in methods]
    if start_method not in allowed:
        raise ValueError(f"start_method must be one of {allowed} (fork is unsafe once the host runs threads), got "
                         f"{start_method!r}")
    return start_method


class ProcessIsolatedScript(Script):
    """Runs a user script in a child process with a hard wall-clock limit per call (see the module docstring).

    ``entry``: a script reference (``path/to/file.py[:Name]``, ``module:Name``; imported in the child only) or a
    picklable Script object. ``time_limit``: seconds per ``reset``/``act`` call (None: wait for ever).
    ``start_timeout``: seconds for the child to start and load the script. ``start_method``: ``"forkserver"``
    (default where available) or ``"spawn"``. Raises ValueError when the script cannot be loaded. Call
    :meth:`close` to stop the child early.
    """

    def __init__(self, entry: str | Script, time_limit: float | None = DEFAULT_TIME_LIMIT, *,
                 start_timeout: float = DEFAULT_START_TIMEOUT, start_method: str | None = None) -> None:
        for label, value in (("time_limit", time_limit), ("start_timeout", start_timeout)):
            if label == "time_limit" and value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise ValueError(f"{label} must be a positive number of seconds, got {value!r}")
        if not isinstance(entry, (str, Script)):
            raise TypeError(f"the sandbox runs a script reference or a Script object, got {entry!r}")
        if isinstance(entry, str) and os.path.exists(entry.rpartition(":")[0] or entry):
            entry = os.path.abspath(entry)  # the child may start in another directory
        try:
            self._entry = cloudpickle.dumps(entry)
        except Exception as err:
            raise ValueError(f"script {entry!r} cannot be sent to a child process: {type(err).__name__}: {err}") \
                from err
        self.time_limit = time_limit
        self.start_timeout = start_timeout
        self.start_method = _start_method(start_method)
        self._context = mp.get_context(self.start_method)
        self._process: mp.process.BaseProcess | None = None
        self._conn: Connection | None = None
        self._finalizer: weakref.finalize | None = None
        self._child_spec: MapSpec | None = None
        self._rngs: list[np.random.Generator | None] = []
        self.name = entry.name if isinstance(entry, Script) else str(entry)
        self.description = entry.description if isinstance(entry, Script) else ""
        try:
            self._start()
        except ScriptError as err:
            hint = ""
            if "exited with code" in err.cause and self.start_method != "fork":
                # multiprocessing re-imports the parent's main module in the child: an unguarded top level reruns
                hint = ("; if this runs from a script, guard its top level with `if __name__ == \"__main__\":` "
                        "(the child process imports the main module again)")
            raise ValueError(f"user script {self.name!r} could not start in a child process: {err.cause}{hint}") \
                from None

    def __reduce__(self):
        # A copy (e.g. in a vector env worker) starts a child of its own.
        return _rebuild, (self._entry, self.time_limit, self.start_timeout, self.start_method)

    def __repr__(self) -> str:
        return f"<ProcessIsolatedScript {self.name!r} time_limit={self.time_limit} pid={self.pid}>"

    @property
    def pid(self) -> int | None:
        """The child's process id while one runs."""
        return self._process.pid if self._process is not None and self._process.is_alive() else None

    def close(self) -> None:
        """Stop the child (a later call starts a new one)."""
        if self._finalizer is not None:
            self._finalizer()  # runs _stop once
        self._process = self._conn = self._finalizer = None
        self._child_spec = None

    def _start(self, map_name: str = "?") -> None:
        parent_end, child_end = self._context.Pipe(duplex=True)
        process = self._context.Process(target=_child_main, args=(child_end, self._entry), daemon=True,
                                        name=f"smac-hard-gym sandbox {self.name}")
        with _children_allowed():
            process.start()
        child_end.close()
        self._process, self._conn = process, parent_end
        self._finalizer = weakref.finalize(self, _stop, process, parent_end)
        reply = self._receive("start", map_name, self.start_timeout)
        if reply[0] == "error":
            self.close()
            raise ScriptError(self.name, map_name, f"loading it failed: {reply[1]}")
        _, self.name, self.description = reply

    def _receive(self, what: str, map_name: str, timeout: float | None) -> tuple:
        """The child's next message; kills it and raises ScriptError when it hangs or dies."""
        try:
            if self._conn.poll(timeout):
                return self._conn.recv()
            cause = f"{what}() timed out after {timeout:g} s; its process was killed"
        except (EOFError, OSError):
            cause = self._death(f"{what}():")
        self.close()
        raise ScriptError(self.name, map_name, cause)

    def _death(self, when: str) -> str:
        self._process.join(_EXIT_WAIT)
        code = self._process.exitcode
        if code is not None and code < 0:
            return f"{when} its process died from signal {signal.Signals(-code).name} ({code})"
        return f"{when} its process exited with code {code}"

    def _call(self, what: str, view: SideView, rows: np.ndarray, extra: Any) -> tuple:
        map_name = view.spec.name
        if self._process is not None and not self._process.is_alive():
            # Killed from outside between calls: its memory is gone, so say so rather than restart silently.
            cause = self._death(f"before {what}():")
            self.close()
            raise ScriptError(self.name, map_name, cause)
        if self._process is None:
            self._start(map_name)
        spec = None if self._child_spec is view.spec else view.spec
        request = (what, spec, view.side, view.own, view.enemy, tuple(view.state), view.episode_step, rows, extra)
        try:
            self._conn.send(request)
        except (BrokenPipeError, ConnectionResetError, OSError):
            pass  # the child died: _receive reports how
        self._child_spec = view.spec
        reply = self._receive(what, map_name, self.time_limit)
        if reply[0] == "failed":
            err = ScriptError(self.name, map_name, f"{what}() {reply[1]}")
            if reply[2]:
                err.add_note(f"(raised in the script's child process; its traceback:)\n{reply[2]}")
            raise err
        for b, state in reply[2].items():
            if b < len(self._rngs) and self._rngs[b] is not None:
                self._rngs[b].bit_generator.state = state
        return reply

    def reset(self, view: SideView, battles: np.ndarray, rngs: list[np.random.Generator]) -> None:
        rows = np.asarray(battles, dtype=np.int64)
        if len(self._rngs) != view.batch_size:
            self._rngs = [None] * view.batch_size
        for b in rows:
            self._rngs[b] = rngs[b]
        self._call("reset", view, rows, [rngs[b] for b in rows])

    def act(self, view: SideView, commands: Commands, active: np.ndarray) -> None:
        rows = np.flatnonzero(active)
        reply = self._call("act", view, rows, tuple(commands))
        for dst, src in zip(commands, reply[1], strict=True):
            dst[rows] = src[rows]
