"""The process sandbox: an untrusted script runs in a child process that the host kills at the time limit.

:class:`ProcessIsolatedScript` runs the script in a child process. Each ``reset``/``act`` ships a copy of the side
view to the child and waits at most ``time_limit`` seconds for its commands; past that, or when the child dies or
breaks the wire format, the child's whole process group is killed and a :class:`ScriptError` names the script, the
map and the cause ("timed out after 0.5 s", "exited with code 3", "died from signal SIGSEGV", "sent a malformed
message"). The next call starts a fresh child (with no memory of earlier episodes: reset every battle after a
ScriptError).

What the child gets (POSIX; see docs/script_isolation.md for what it can still do):

- its own session and process group, killed as a whole (so processes a script forks die with it) on
  :meth:`~ProcessIsolatedScript.close`, at a timeout or failure, when the wrapper is collected and at interpreter
  exit; on Linux the kernel also kills the child when the host dies (``PR_SET_PDEATHSIG``);
- ``memory_limit`` bytes of address space on top of what it holds after its start (``RLIMIT_AS``): an allocation
  past it raises MemoryError in the child, which becomes a ScriptError;
- a CPU-time backstop per call (``RLIMIT_CPU``: the call's limit on every CPU, plus 2 s): the host's kill at the
  deadline is what enforces the limit, the backstop covers a host that is stopped;
- no file descriptors but stdin (``/dev/null``), stdout, stderr and its pipe; no core dumps; SIGINT ignored (Ctrl-C
  is the host's to handle).

The wire format: the host sends pickled requests (the host is trusted). The child answers in a fixed format that
runs no code when read (see :func:`_pack`): a magic tag, a small JSON header of plain values and raw array
buffers, which the host reads with a size cap and a deadline and checks field by field (types, string lengths,
array dtypes and shapes, the generators' states against the battle's bit generator). Nothing from the child is
ever unpickled.

A script given by reference (``file.py:Name``, ``module:Name``) is only ever imported in the child; a Script object
is sent with cloudpickle. The script's generators are copies: they start from the battles' seeded states and the
host's generators are set to where the child's ended after each call, so runs are as reproducible as in-process.
Commands come back through :class:`~smac_hard_gym.opponents.guard.GuardedScript`'s checks (``make_script`` wraps
the sandbox in the guard).
"""

from __future__ import annotations

import json
import math
import multiprocessing as mp
import os
import select
import signal
import socket
import struct
import sys
import time
import traceback
import weakref
from contextlib import contextmanager
from multiprocessing.connection import Connection
from multiprocessing.reduction import ForkingPickler
from typing import Any

import cloudpickle
import numpy as np

from smac_hard_gym.engine.state import BattleState, Commands
from smac_hard_gym.lifetime import die_with_parent
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.opponents.api import Script, ScriptError, SideView
from smac_hard_gym.opponents.guard import DEFAULT_TIME_LIMIT

__all__ = ["ProcessIsolatedScript", "DEFAULT_START_TIMEOUT", "DEFAULT_MEMORY_LIMIT", "SUPPORTED"]

SUPPORTED = os.name == "posix"  # raw pipe I/O with poll(), sessions and resource limits
DEFAULT_START_TIMEOUT = 60.0  # seconds for a child to start and load its script
DEFAULT_MEMORY_LIMIT = 2 << 30  # bytes of address space a script may add to the child's own
_EXIT_WAIT = 2.0  # seconds to wait for a dead child's exit code
_CPU_SLACK = 2  # seconds of CPU past a call's limit before the kernel's backstop fires

_MAGIC = b"SHG\x01"  # first bytes of every message from the child
_NAME_CAP = 200  # characters in a script's name
_TEXT_CAP = 2_000  # characters in a description, an error or a failure's cause
_TRACE_CAP = 20_000  # characters of a failure's traceback
_HEADER_CAP = 64 << 10  # bytes of JSON header, plus _STATE_CAP per battle of generator states
_STATE_CAP = 16 << 10  # an MT19937 state is about 7 kB as JSON
_INT_BOUND = 1 << 128  # generator state integers are at most 128 bits
_CHUNK = 1 << 20  # bytes per read
_SEND_BUFFER = 4 << 20  # bytes of socket send buffer asked for


# ---------------------------------------------------------------------------------------------------------------
# The wire format (child -> host).


class _WireError(Exception):
    """A message from the child that breaks the wire format (the child is then killed)."""


class _Hangup(Exception):
    """The child closed its end of the pipe (it died)."""


class _Late(Exception):
    """The deadline passed before the message was complete."""


def _cap(text: str, limit: int) -> str:
    return text if len(text) <= limit else text[:limit - 15] + " ...(truncated)"


def _plain(value: Any) -> Any:
    """A generator state as JSON-able plain values (arrays become lists of ints)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.integer):
        return int(value)
    return value


def _pack(header: dict, arrays: tuple[np.ndarray, ...] = ()) -> bytes:
    """One message: ``_MAGIC``, the JSON header's length (4 bytes, little-endian), the header, the array buffers
    (C order, the dtypes and shapes the header lists)."""
    if arrays:
        header = {**header, "arrays": [[a.dtype.str, list(a.shape)] for a in arrays]}
    head = json.dumps(header, separators=(",", ":")).encode()
    return b"".join((_MAGIC, len(head).to_bytes(4, "little"), head, *(np.ascontiguousarray(a).tobytes()
                                                                        for a in arrays)))


def _unpack(data: bytes) -> tuple[dict, memoryview]:
    """(header, array bytes) of a message; raises _WireError when it is not in the format."""
    if len(data) < 8 or data[:4] != _MAGIC:
        raise _WireError("it is not in the sandbox's wire format")
    size = int.from_bytes(data[4:8], "little")
    if 8 + size > len(data):
        raise _WireError("its header runs past the end of the message")
    try:
        header = json.loads(data[8:8 + size].decode("utf-8"))
    except (ValueError, RecursionError) as err:  # UnicodeDecodeError and JSONDecodeError are ValueErrors
        raise _WireError(f"its header is not readable JSON ({type(err).__name__})") from None
    if not isinstance(header, dict) or not isinstance(header.get("kind"), str):
        raise _WireError("its header is not an object with a kind")
    return header, memoryview(data)[8 + size:]


def _text(header: dict, key: str, limit: int) -> str:
    value = header.get(key)
    if not isinstance(value, str) or len(value) > limit:
        raise _WireError(f"its {key!r} is not a string of at most {limit} characters")
    return value


def _arrays(header: dict, payload: memoryview, like: tuple[np.ndarray, ...]) -> list[np.ndarray]:
    """The array buffers of a message, which must have exactly the dtypes and shapes of ``like`` (zero-copy,
    read-only views of the message)."""
    specs = header.get("arrays")
    if not isinstance(specs, list) or len(specs) != len(like):
        raise _WireError(f"it carries no list of {len(like)} arrays")
    out, offset = [], 0
    for spec, model in zip(specs, like, strict=True):
        want = [model.dtype.str, list(model.shape)]
        if spec != want:
            raise _WireError(f"an array came back as {_cap(repr(spec), 100)}, expected {want}")
        out.append(np.frombuffer(payload, dtype=model.dtype, count=model.size, offset=offset).reshape(model.shape))
        offset += model.nbytes
    if offset != len(payload):
        raise _WireError(f"it carries {len(payload)} bytes of arrays, expected {offset}")
    return out


def _like(template: Any, value: Any, where: str) -> Any:
    """``value`` (plain JSON values) checked against ``template`` (a bit generator's state) and converted to its
    types; raises _WireError on any difference of keys, types or ranges."""
    if isinstance(template, dict):
        if not isinstance(value, dict) or value.keys() != template.keys():
            raise _WireError(f"{where} does not have the keys {sorted(template)}")
        return {k: _like(template[k], value[k], f"{where}[{k!r}]") for k in template}
    if isinstance(template, str):
        if value != template:
            raise _WireError(f"{where} is not {template!r}")
        return value
    if isinstance(template, (int, np.integer)) and not isinstance(template, bool):
        if type(value) is not int or not 0 <= value < _INT_BOUND:
            raise _WireError(f"{where} is not an integer in [0, 2**128)")
        return value
    if isinstance(template, np.ndarray) and template.dtype.kind in "ui":
        info = np.iinfo(template.dtype)
        if (not isinstance(value, list) or len(value) != template.size
                or not all(type(v) is int and info.min <= v <= info.max for v in value)):
            raise _WireError(f"{where} is not a list of {template.size} {template.dtype} integers")
        return np.array(value, dtype=template.dtype).reshape(template.shape)
    raise _WireError(f"{where}: the sandbox does not carry a {type(template).__name__} in a generator state")


# ---------------------------------------------------------------------------------------------------------------
# Raw pipe I/O on the host's end, bounded by a deadline (a child that sends half a message cannot hang the host).


def _wait(fd: int, event: int, deadline: float | None) -> bool:
    """Whether ``fd`` became ready for ``event`` (or hung up) before ``deadline`` (time.monotonic())."""
    poller = select.poll()
    poller.register(fd, event)
    while True:
        left = None if deadline is None else deadline - time.monotonic()
        if poller.poll(None if left is None else max(0, math.ceil(left * 1000))):
            return True
        if left is not None and left <= 0:
            return False


def _read_exact(fd: int, size: int, deadline: float | None) -> bytes:
    data = bytearray()
    while len(data) < size:
        if not _wait(fd, select.POLLIN, deadline):
            raise _Late
        try:
            chunk = os.read(fd, min(size - len(data), _CHUNK))
        except BlockingIOError:
            continue
        except OSError:
            raise _Hangup from None
        if not chunk:
            raise _Hangup
        data += chunk
    return bytes(data)


def _read_message(fd: int, deadline: float | None, limit: int) -> bytes:
    """One message framed as multiprocessing frames it (a 4-byte big-endian length, then the bytes); raises
    _WireError for one longer than ``limit`` bytes before reading it."""
    size, = struct.unpack("!i", _read_exact(fd, 4, deadline))
    if not 0 <= size <= limit:
        shown = "over 2 GiB" if size < 0 else f"{size} bytes"
        raise _WireError(f"it is {shown} long, over the limit of {limit} bytes for this call")
    return _read_exact(fd, size, deadline)


def _write_all(fd: int, data: bytes, deadline: float | None) -> None:
    view = memoryview(data)
    while view:
        if not _wait(fd, select.POLLOUT, deadline):
            raise _Late
        try:
            view = view[os.write(fd, view):]
        except BlockingIOError:
            continue
        except OSError:  # BrokenPipeError, ConnectionResetError: the child is gone
            raise _Hangup from None


def _widen(fd: int) -> None:
    """Ask for a send buffer that holds a large batch's request in one write (the kernel caps it at wmem_max)."""
    try:
        with socket.fromfd(fd, socket.AF_UNIX, socket.SOCK_STREAM) as sock:  # a duplicate of the same socket
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, _SEND_BUFFER)
    except OSError:
        pass


def _send_request(fd: int, request: Any, deadline: float | None) -> None:
    """``request`` pickled and framed as ``Connection.recv`` in the child expects it."""
    data = bytes(ForkingPickler.dumps(request))
    head = struct.pack("!i", len(data)) if len(data) <= 0x7FFFFFFF else struct.pack("!iQ", -1, len(data))
    _write_all(fd, head + data, deadline)


# ---------------------------------------------------------------------------------------------------------------
# The child.


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


def _close_inherited_fds(keep: int) -> None:
    """Close every descriptor but stdin/stdout/stderr and the pipe: the host's other files, sockets and pipes
    (the forkserver's and the resource tracker's included) are none of the script's business."""
    try:
        fds = [int(fd) for fd in os.listdir("/proc/self/fd")]
    except OSError:  # not Linux
        fds = list(range(3, os.sysconf("SC_OPEN_MAX") if hasattr(os, "sysconf") else 256))
    for fd in fds:
        if fd > 2 and fd != keep:
            try:
                os.close(fd)
            except OSError:  # the listing's own descriptor, already closed
                pass
    try:  # multiprocessing's records of the closed descriptors: start afresh if the script uses them
        from multiprocessing import forkserver, resource_tracker

        resource_tracker._resource_tracker._fd = None
        forkserver._forkserver._forkserver_alive_fd = None
        forkserver._forkserver._inherited_fds = None
    except (ImportError, AttributeError):
        pass


def _address_space() -> int:
    """Bytes of address space the calling process maps now (Linux; 0 elsewhere)."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError):
        pass
    return 0


def _set_limit(which: int, soft: int, hard: int) -> None:
    import resource

    _, top = resource.getrlimit(which)
    if top != resource.RLIM_INFINITY:  # never ask for more than we were given
        soft, hard = min(soft, top), min(hard, top)
    try:
        resource.setrlimit(which, (soft, hard))
    except (ValueError, OSError):  # a platform that does not support this limit: the host's kill still holds
        pass


def _confine(keep_fd: int, memory_limit: int | None) -> None:
    """What the child does before it loads any of the script's code (see the module docstring)."""
    import resource

    die_with_parent()
    if hasattr(os, "setsid"):
        os.setsid()  # a group of our own: the host kills it whole, and Ctrl-C at the terminal does not reach it
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _close_inherited_fds(keep_fd)
    _set_limit(resource.RLIMIT_CORE, 0, 0)
    if memory_limit is not None:
        limit = _address_space() + memory_limit
        _set_limit(resource.RLIMIT_AS, limit, limit)


def _cpu_backstop(seconds: float | None) -> None:
    """Let the kernel end this call (SIGXCPU) once it used more CPU than ``seconds`` of wall time on every CPU
    allow (a script's BLAS may run one thread per CPU), plus ``_CPU_SLACK``, should the host not kill it first."""
    if seconds is None:
        return
    import resource

    usage = resource.getrusage(resource.RUSAGE_SELF)
    budget = usage.ru_utime + usage.ru_stime + seconds * (os.cpu_count() or 1)
    _set_limit(resource.RLIMIT_CPU, int(budget) + _CPU_SLACK, resource.RLIM_INFINITY)


def _exit_child() -> None:
    """End the child now: threads a script started must not keep it alive."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass
    os._exit(0)


def _check_buffer(commands: Commands, like: tuple[tuple, ...]) -> str:
    """How the script broke its command buffer (resized it, changed a dtype), or "" when it did not."""
    for name, array, (shape, dtype) in zip(Commands._fields, commands, like, strict=True):
        if not isinstance(array, np.ndarray) or array.shape != shape or array.dtype != dtype:
            got = f"{array.shape} {array.dtype}" if isinstance(array, np.ndarray) else type(array).__name__
            return f"broke its command buffer: commands.{name} is now {got}, expected {shape} {dtype}"
    return ""


def _changed_states(rngs: list, rows: np.ndarray, sent: dict[int, Any]) -> list[list]:
    """[battle, state] of the generators of ``rows`` whose state the host does not have yet (most scripts draw
    nothing in most calls: their replies carry no states)."""
    out = []
    for b in rows:
        if rngs[b] is not None:
            state = _plain(rngs[b].bit_generator.state)
            if state != sent.get(int(b)):
                sent[int(b)] = state
                out.append([int(b), state])
    return out


def _answer(script: Script, request: tuple, rngs: list, sent: dict[int, Any], spec: MapSpec) -> bytes:
    """Run one request on the script; the reply message (a failure is a "failed" message). ``sent``: the states
    of the generators as the host has them."""
    seq, what, _, side, own, enemy, state, step, rows, extra = request
    _read_only((*state, step, rows))
    view = SideView(BattleState(*state), spec, side, own, enemy, step)
    if len(rngs) != view.batch_size:
        rngs[:] = [None] * view.batch_size
    try:
        arrays: tuple[np.ndarray, ...] = ()
        if what == "reset":
            for b, rng in zip(rows, extra, strict=True):
                rngs[b] = rng
                sent[int(b)] = _plain(rng.bit_generator.state)
            script.reset(view, rows, rngs)
        else:
            commands = Commands(*extra)
            like = tuple((a.shape, a.dtype) for a in commands)
            active = np.zeros(view.batch_size, dtype=bool)
            active[rows] = True
            active.flags.writeable = False
            script.act(view, commands, active)
            broken = _check_buffer(commands, like)
            if broken:
                return _pack({"kind": "failed", "seq": seq, "cause": broken, "traceback": ""})
            arrays = tuple(commands)
        return _pack({"kind": "ok", "seq": seq, "rngs": _changed_states(rngs, rows, sent)}, arrays)
    except SystemExit as err:
        cause, text = f"called sys.exit({err.code!r})", ""
    except BaseException as err:  # KeyboardInterrupt and GeneratorExit included: SIGINT is ignored here
        cause = f"raised {type(err).__name__}: {err}"
        text = "".join(traceback.format_exception(type(err), err, err.__traceback__))
    return _pack({"kind": "failed", "seq": seq, "cause": _cap(cause, _TEXT_CAP), "traceback": _cap(text, _TRACE_CAP)})


def _child_main(conn: Connection, entry: bytes, time_limit: float | None, memory_limit: int | None) -> None:
    """The child's loop: confine itself, load the script, then answer ``reset``/``act`` requests until the host
    closes the pipe (or kills us)."""
    _confine(conn.fileno(), memory_limit)
    try:
        script = _load(entry)
        ready = {"kind": "ready", "name": _cap(str(script.name), _NAME_CAP),
                 "description": _cap(str(script.description), _TEXT_CAP)}
    except BaseException as err:
        conn.send_bytes(_pack({"kind": "error", "message": _cap(f"{type(err).__name__}: {err}", _TEXT_CAP)}))
        _exit_child()
    conn.send_bytes(_pack(ready))
    spec: MapSpec | None = None
    rngs: list[Any] = []
    sent: dict[int, Any] = {}
    while True:
        try:
            request = conn.recv()
        except (EOFError, OSError):  # the host closed the pipe
            _exit_child()
        spec = request[2] if request[2] is not None else spec
        _cpu_backstop(time_limit)
        conn.send_bytes(_answer(script, request, rngs, sent, spec))


# ---------------------------------------------------------------------------------------------------------------
# The host.


def _kill_group(pid: int | None) -> None:
    """SIGKILL the child's process group (the child and whatever it forked). The group id is the child's pid,
    which stays reserved while any member lives."""
    if pid is None or not hasattr(os, "killpg"):
        return
    try:
        os.killpg(pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):  # gone already, or not yet in a group of its own
        pass


def _stop(process: mp.process.BaseProcess, conn: Connection) -> None:
    """Kill the child with its process group and close its pipe (safe to call twice; also the finaliser)."""
    try:
        conn.close()
    except OSError:
        pass
    _kill_group(process.pid)
    if process.is_alive():
        process.kill()
    process.join(_EXIT_WAIT)


def _rebuild(entry: bytes, time_limit: float | None, start_timeout: float, start_method: str,
             memory_limit: int | None = DEFAULT_MEMORY_LIMIT) -> Script:
    return ProcessIsolatedScript(cloudpickle.loads(entry), time_limit, start_timeout=start_timeout,
                                 start_method=start_method, memory_limit=memory_limit)


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


def _check_options(time_limit: float | None, start_timeout: float, memory_limit: int | None) -> None:
    for label, value in (("time_limit", time_limit), ("start_timeout", start_timeout)):
        if label == "time_limit" and value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
            raise ValueError(f"{label} must be a positive number of seconds, got {value!r}")
    if memory_limit is not None and (isinstance(memory_limit, bool) or not isinstance(memory_limit, int)
                                     or memory_limit <= 0):
        raise ValueError(f"memory_limit must be a positive number of bytes or None, got {memory_limit!r}")


class ProcessIsolatedScript(Script):
    """Runs a user script in a child process with a hard wall-clock limit per call (see the module docstring).

    ``entry``: a script reference (``path/to/file.py[:Name]``, ``module:Name``; imported in the child only) or a
    picklable Script object. ``time_limit``: seconds per ``reset``/``act`` call (None: wait for ever).
    ``start_timeout``: seconds for the child to start and load the script. ``start_method``: ``"forkserver"``
    (default where available) or ``"spawn"``. ``memory_limit``: bytes of address space the script may add to the
    child's own (``DEFAULT_MEMORY_LIMIT``, 2 GiB; None: no limit). Raises ValueError when the script cannot be
    loaded, RuntimeError on a platform without the sandbox (not POSIX). Call :meth:`close` to stop the child early.
    """

    def __init__(self, entry: str | Script, time_limit: float | None = DEFAULT_TIME_LIMIT, *,
                 start_timeout: float = DEFAULT_START_TIMEOUT, start_method: str | None = None,
                 memory_limit: int | None = DEFAULT_MEMORY_LIMIT) -> None:
        if not SUPPORTED:
            raise RuntimeError("the process sandbox needs a POSIX system; use isolation='guard' here")
        _check_options(time_limit, start_timeout, memory_limit)
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
        self.memory_limit = memory_limit
        self.start_method = _start_method(start_method)
        self._context = mp.get_context(self.start_method)
        self._process: mp.process.BaseProcess | None = None
        self._conn: Connection | None = None
        self._finalizer: weakref.finalize | None = None
        self._child_spec: MapSpec | None = None
        self._rngs: list[np.random.Generator | None] = []
        self._seq = 0
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
        return _rebuild, (self._entry, self.time_limit, self.start_timeout, self.start_method, self.memory_limit)

    def __repr__(self) -> str:
        return f"<ProcessIsolatedScript {self.name!r} time_limit={self.time_limit} pid={self.pid}>"

    @property
    def pid(self) -> int | None:
        """The child's process id while one runs."""
        return self._process.pid if self._process is not None and self._process.is_alive() else None

    def close(self) -> None:
        """Stop the child and everything it started (a later call starts a new one)."""
        if self._finalizer is not None:
            self._finalizer()  # runs _stop once
        self._process = self._conn = self._finalizer = None
        self._child_spec = None

    def _start(self, map_name: str = "?") -> None:
        parent_end, child_end = self._context.Pipe(duplex=True)
        process = self._context.Process(target=_child_main, daemon=True,
                                        args=(child_end, self._entry, self.time_limit, self.memory_limit),
                                        name=f"smac-hard-gym sandbox {self.name}")
        with _children_allowed():
            process.start()
        child_end.close()
        os.set_blocking(parent_end.fileno(), False)  # all host I/O is polled against a deadline
        _widen(parent_end.fileno())
        self._process, self._conn = process, parent_end
        self._finalizer = weakref.finalize(self, _stop, process, parent_end)
        header = self._receive("start", map_name, time.monotonic() + self.start_timeout, _HEADER_CAP)[0]
        try:
            if header["kind"] == "error":
                message = _text(header, "message", _TEXT_CAP)
            elif header["kind"] == "ready":
                name, description = _text(header, "name", _NAME_CAP), _text(header, "description", _TEXT_CAP)
            else:
                raise _WireError(f"its kind is {_cap(header['kind'], 20)!r}, not 'ready' or 'error'")
        except _WireError as err:
            self._fail("start", map_name, f"start: sent a malformed message ({err}); its process was killed")
        if header["kind"] == "error":
            self.close()
            raise ScriptError(self.name, map_name, f"loading it failed: {message}")
        self.name, self.description = name, description

    def _fail(self, what: str, map_name: str, cause: str) -> None:
        self.close()
        raise ScriptError(self.name, map_name, cause)

    def _receive(self, what: str, map_name: str, deadline: float | None, limit: int) -> tuple[dict, memoryview]:
        """The child's next message; kills it and raises ScriptError when it hangs, dies or breaks the format."""
        try:
            return _unpack(_read_message(self._conn.fileno(), deadline, limit))
        except _Late:
            cause = f"{what}() timed out after {self._limit_of(what):g} s; its process was killed"
        except _Hangup:
            cause = self._death(f"{what}():")
        except _WireError as err:
            cause = f"{what}(): sent a malformed message ({err}); its process was killed"
        self._fail(what, map_name, cause)

    def _limit_of(self, what: str) -> float:
        return self.start_timeout if what == "start" else self.time_limit

    def _death(self, when: str) -> str:
        _kill_group(self._process.pid)  # what it forked dies with it
        self._process.join(_EXIT_WAIT)
        code = self._process.exitcode
        if code is not None and code < 0:
            return f"{when} its process died from signal {signal.Signals(-code).name} ({code})"
        return f"{when} its process exited with code {code}"

    def _call(self, what: str, view: SideView, rows: np.ndarray, extra: Any) -> list[np.ndarray]:
        """One request to the child; the command arrays it sent back (act) or [] (reset)."""
        map_name = view.spec.name
        if self._process is not None and not self._process.is_alive():
            # Killed from outside between calls: its memory is gone, so say so rather than restart silently.
            self._fail(what, map_name, self._death(f"before {what}():"))
        try:
            if self._process is None:
                self._start(map_name)
            return self._exchange(what, view, rows, extra)
        except ScriptError:
            raise
        except BaseException:  # Ctrl-C (or a guard's shot) mid-exchange: the pipe is out of step, start afresh
            self.close()
            raise

    def _exchange(self, what: str, view: SideView, rows: np.ndarray, extra: Any) -> list[np.ndarray]:
        map_name = view.spec.name
        deadline = None if self.time_limit is None else time.monotonic() + self.time_limit
        self._seq += 1
        spec = None if self._child_spec is view.spec else view.spec
        request = (self._seq, what, spec, view.side, view.own, view.enemy, tuple(view.state), view.episode_step,
                   rows, extra)
        try:
            _send_request(self._conn.fileno(), request, deadline)
        except _Late:
            self._fail(what, map_name, f"{what}() timed out after {self.time_limit:g} s (it stopped reading its "
                                       "requests); its process was killed")
        except _Hangup:
            pass  # the child died: _receive reports how
        self._child_spec = view.spec
        like = tuple(extra) if what == "act" else ()
        limit = _HEADER_CAP + _STATE_CAP * len(rows) + sum(a.nbytes for a in like)
        header, payload = self._receive(what, map_name, deadline, 8 + limit)
        try:
            return self._read_reply(what, map_name, header, payload, rows, like)
        except _WireError as err:
            self._fail(what, map_name, f"{what}(): sent a malformed message ({err}); its process was killed")

    def _read_reply(self, what: str, map_name: str, header: dict, payload: memoryview, rows: np.ndarray,
                    like: tuple[np.ndarray, ...]) -> list[np.ndarray]:
        if header.get("seq") != self._seq or header["kind"] not in ("ok", "failed"):
            raise _WireError(f"it is not the reply to request {self._seq}")
        if header["kind"] == "failed":
            err = ScriptError(self.name, map_name, f"{what}() {_text(header, 'cause', _TEXT_CAP)}")
            text = _text(header, "traceback", _TRACE_CAP)
            if text:
                err.add_note(f"(raised in the script's child process; its traceback:)\n{text}")
            raise err
        arrays = _arrays(header, payload, like) if like else []
        self._set_rngs(header.get("rngs"), rows)
        return arrays

    def _set_rngs(self, states: Any, rows: np.ndarray) -> None:
        """Move the host's generators of ``rows`` to the states the child sent, each checked against the state of
        the battle's own bit generator first."""
        if not isinstance(states, list):
            raise _WireError("it carries no list of generator states")
        allowed = {int(b) for b in rows if b < len(self._rngs) and self._rngs[b] is not None}
        checked = {}
        for item in states:
            if not (isinstance(item, list) and len(item) == 2 and type(item[0]) is int and item[0] in allowed
                    and item[0] not in checked):
                raise _WireError("a generator state is not a [battle, state] pair for a battle of this call")
            b = item[0]
            checked[b] = _like(self._rngs[b].bit_generator.state, item[1], f"battle {b}'s generator state")
        for b, state in checked.items():
            try:
                self._rngs[b].bit_generator.state = state
            except (TypeError, ValueError, OverflowError) as err:
                raise _WireError(f"battle {b}'s generator refused its state ({type(err).__name__})") from None

    def reset(self, view: SideView, battles: np.ndarray, rngs: list[np.random.Generator]) -> None:
        rows = np.asarray(battles, dtype=np.int64)
        if len(self._rngs) != view.batch_size:
            self._rngs = [None] * view.batch_size
        for b in rows:
            self._rngs[b] = rngs[b]
        self._call("reset", view, rows, [rngs[b] for b in rows])

    def act(self, view: SideView, commands: Commands, active: np.ndarray) -> None:
        rows = np.flatnonzero(active)
        arrays = self._call("act", view, rows, tuple(commands))
        for dst, src in zip(commands, arrays, strict=True):
            dst[rows] = src[rows]
