"""Hostile user scripts, loaded by path as a user would: what each of them gets under each isolation.

The process sandbox (the default for scripts loaded by reference) must turn every attack into a ScriptError and
leave the host untouched: replies that would run code when unpickled, malformed or oversized replies, endless
loops that catch every exception, forks, os._exit, segfaults, memory hogs, leftover threads and monkeypatching.
The guard promises less (docs/script_isolation.md): the tests of it here pin down what it does catch and document
what it cannot stop, without letting that hang the suite.

One sandboxed child serves most tests (its script picks its mischief from ``episode_step``); a test whose mischief
kills it gets a fresh one on its next call, as a user's env would.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.engine.state import BLUE, Commands
from smac_hard_gym.opponents import GuardedScript, ProcessIsolatedScript, Script, ScriptError, SideView, make_opponent
from smac_hard_gym.opponents.sandbox import _MAGIC, SUPPORTED, _like, _unpack, _WireError

pytestmark = pytest.mark.skipif(not SUPPORTED, reason="the process sandbox needs a POSIX system")

LIMIT = 10.0  # seconds per call of the scripts that must answer: generous for a loaded machine
SHORT = 1.0  # seconds per call of the scripts that never answer (they are cut off at it)
BOUND = 10 * SHORT + 10.0  # what a call that must be cut off may take at most, start of a fresh child included

_HOSTILE = '''
import ctypes
import gc
import json
import os
import struct
import sys
import threading
import time

import numpy as np

from smac_hard_gym.engine.state import CMD_ATTACK
from smac_hard_gym.opponents import Script
from smac_hard_gym.opponents.sandbox import _pack

HERE = os.path.dirname(os.path.abspath(__file__))
MODES = {modes!r}


class Payload:
    """Runs a shell command in whichever process unpickles it."""

    def __reduce__(self):
        return os.system, (f"touch {{os.path.join(HERE, 'pwned')}}",)


def pipe():
    from multiprocessing.connection import Connection

    return next(o for o in gc.get_objects() if isinstance(o, Connection) and not o.closed)


def seq():
    return sys._getframe(2).f_locals["seq"]  # act <- _answer, which holds the request's number


def fork_sleeper(name):
    pid = os.fork()
    if pid == 0:
        time.sleep(1000)
        os._exit(0)
    with open(os.path.join(HERE, name), "w") as f:
        f.write(str(pid))


def forever():
    while True:
        try:
            while True:
                pass
        except BaseException:
            continue


class Mischief(Script):
    name = "mischief"

    def act(self, view, commands, active):
        mode = MODES[int(view.episode_step[0])]
        arrays = tuple(commands)
        if mode == "fds":
            raise RuntimeError("fds=" + json.dumps(sorted(int(fd) for fd in os.listdir("/proc/self/fd"))))
        if mode == "hog":
            bytearray(10 << 30)
        if mode == "resize":
            commands.kind.resize((3,), refcheck=False)
            return
        if mode == "generator_exit":
            raise GeneratorExit
        if mode == "keyboard_interrupt":
            raise KeyboardInterrupt
        if mode == "monkeypatch":
            import smac_hard_gym.opponents.guard as guard
            import smac_hard_gym.smac.actions as actions

            actions._raise_range = lambda *args, **kwargs: None
            guard.check_commands = lambda *args, **kwargs: ""
        if mode == "pickle_bomb":
            pipe().send(("ok", Payload(), {{}}))
        if mode == "oversized":
            pipe().send_bytes(b"x" * (64 << 20))
        if mode == "bad_arrays":
            wrong = tuple(a.astype(np.float64) for a in arrays)
            pipe().send_bytes(_pack({{"kind": "ok", "seq": seq(), "rngs": []}}, wrong))
        if mode == "bad_rng":
            state = {{"bit_generator": "PCG64", "state": {{"state": "evil", "inc": 1}}, "has_uint32": 0,
                     "uinteger": 0}}
            pipe().send_bytes(_pack({{"kind": "ok", "seq": seq(), "rngs": [[0, state]]}}, arrays))
        if mode == "half_message":
            os.write(pipe().fileno(), struct.pack("!i", 1000) + b"SHG")
            time.sleep(1000)
        if mode == "exit0":
            os._exit(0)
        if mode == "segfault":
            ctypes.string_at(0)
        if mode == "swallow_forever":
            forever()
        if mode == "fork_and_hang":
            fork_sleeper("fork_and_hang.pid")
            time.sleep(1000)
        if mode == "fork":
            fork_sleeper("fork.pid")
        if mode == "thread":
            threading.Thread(target=time.sleep, args=(1000,), daemon=False).start()
            fork_sleeper("thread.pid")
        commands.kind[active, view.own] = CMD_ATTACK
        commands.target[active, view.own] = view.enemy_slot(0)
'''

MODES = ["fine", "fds", "hog", "resize", "generator_exit", "keyboard_interrupt", "monkeypatch", "pickle_bomb",
         "oversized", "bad_arrays", "bad_rng", "half_message", "exit0", "segfault", "swallow_forever",
         "fork_and_hang", "fork", "thread"]


@pytest.fixture(scope="module")
def hostile(tmp_path_factory) -> Path:
    """The hostile script's file (its forks write their pids next to it)."""
    path = tmp_path_factory.mktemp("hostile") / "hostile.py"
    path.write_text(textwrap.dedent(_HOSTILE.format(modes=MODES)))
    return path


@pytest.fixture(scope="module")
def sandboxed(hostile):
    """The hostile script as make_opponent loads it by path with no isolation named (one child for the module)."""
    script = make_opponent("3m", f"{hostile}:Mischief", time_limit=LIMIT)
    yield script
    script.close()


@pytest.fixture(scope="module")
def hanging(hostile):
    """The same with a short time limit, for the mischief that never answers."""
    script = make_opponent("3m", f"{hostile}:Mischief", time_limit=SHORT)
    yield script
    script.close()


def _setup(batch: int = 2):
    engine = BattleEngine("3m", batch_size=batch)
    engine.reset(seeds=np.arange(batch))
    return engine, [np.random.default_rng(b) for b in range(batch)]


def _act(script: Script, mode: str, *, reset: bool = False) -> Commands:
    """One act() of ``script`` in which the hostile script does ``mode``."""
    engine, rngs = _setup()
    view = SideView.of(engine.state, engine.spec, BLUE, np.full(2, MODES.index(mode), dtype=np.int64))
    if reset:
        script.reset(view, np.arange(2), rngs)
    commands = Commands.empty(2, engine.n_units)
    script.act(view, commands, np.ones(2, dtype=bool))
    return commands


def _dead(pid: int) -> bool:
    """Gone, or a zombie waiting for a reaper (it runs no more code)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rpartition(")")[2].split()[0] in ("Z", "X")
    except FileNotFoundError:
        return True
    except OSError:
        pass
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def _gone_soon(pid: int, within: float = BOUND) -> bool:
    end = time.monotonic() + within
    while time.monotonic() < end:
        if _dead(pid):
            return True
        time.sleep(0.05)
    return _dead(pid)


def _failure(script: Script, mode: str, **kwargs) -> tuple[ScriptError, float]:
    start = time.monotonic()
    with pytest.raises(ScriptError) as info:
        _act(script, mode, **kwargs)
    return info.value, time.monotonic() - start


# ---------------------------------------------------------------------------------------------------------------
# Defaults.


def test_a_script_loaded_by_path_defaults_to_the_process_sandbox(sandboxed, hostile):
    assert isinstance(sandboxed, GuardedScript) and isinstance(sandboxed.script, ProcessIsolatedScript)
    assert sandboxed.name == "mischief"
    commands = _act(sandboxed, "fine")
    assert (commands.kind[:, 3:] != 0).all()
    in_process = make_opponent("3m", f"{hostile}:Mischief", isolation="guard")  # an explicit choice wins
    assert isinstance(in_process, GuardedScript) and not isinstance(in_process.script, ProcessIsolatedScript)
    built = make_opponent("3m", _GeneratorExit())  # a Script object built in the host keeps the guard
    assert isinstance(built, GuardedScript) and not isinstance(built.script, ProcessIsolatedScript)


# ---------------------------------------------------------------------------------------------------------------
# The wire: nothing the child sends can run code in the host.


@pytest.mark.parametrize("mode, cause", [
    ("pickle_bomb", r"act\(\): sent a malformed message \(it is not in the sandbox's wire format\)"),
    ("oversized", r"act\(\): sent a malformed message \(it is 67108864 bytes long, over the limit"),
    ("bad_arrays", r"act\(\): sent a malformed message \(an array came back as \['<f8', \[2, 6\]\]"),
    ("bad_rng", r"act\(\): sent a malformed message \(battle 0's generator state\['state'\]\['state'\] is not an "
                r"integer"),
    ("half_message", rf"act\(\) timed out after {SHORT:g} s"),
])
def test_a_forged_reply_is_a_script_error_and_kills_the_child(sandboxed, hanging, hostile, mode, cause):
    script = hanging if mode == "half_message" else sandboxed
    error, took = _failure(script, mode, reset=mode == "bad_rng")
    assert error.script == "mischief" and error.map_name == "3m"
    assert re.search(cause, error.cause), error.cause
    assert "its process was killed" in error.cause
    assert took < BOUND
    assert script.script.pid is None  # killed; the next call starts a fresh child
    assert not (hostile.parent / "pwned").exists()  # the payload never ran in the host


@pytest.mark.parametrize("data, problem", [
    (b"\x80\x04K\x01.", "not in the sandbox's wire format"),
    (_MAGIC + (100).to_bytes(4, "little") + b"{}", "header runs past the end"),
    (_MAGIC + (4).to_bytes(4, "little") + b"\xff\xfe{}", "not readable JSON"),
    (_MAGIC + (20_000).to_bytes(4, "little") + b"[" * 20_000, "not readable JSON"),
    (_MAGIC + (4_400).to_bytes(4, "little") + b"9" * 4_400, "not readable JSON"),  # a 4,400-digit int
    (_MAGIC + (2).to_bytes(4, "little") + b"[]", "not an object with a kind"),
])
def test_the_host_reads_replies_as_data_only(data, problem):
    with pytest.raises(_WireError, match=problem):
        _unpack(data)


@pytest.mark.parametrize("state, problem", [
    ({"bit_generator": "MT19937", "state": {}, "has_uint32": 0, "uinteger": 0}, r"\['bit_generator'\] is not"),
    ({"bit_generator": "PCG64", "state": {"state": 1}, "has_uint32": 0, "uinteger": 0}, "does not have the keys"),
    ({"bit_generator": "PCG64", "state": {"state": 2 ** 128, "inc": 1}, "has_uint32": 0, "uinteger": 0},
     r"is not an integer in \[0, 2\*\*128\)"),
    ({"bit_generator": "PCG64", "state": {"state": True, "inc": 1}, "has_uint32": 0, "uinteger": 0},
     "is not an integer"),
    ([1, 2], "does not have the keys"),
])
def test_generator_states_must_match_the_battles_bit_generator(state, problem):
    template = np.random.default_rng(0).bit_generator.state
    with pytest.raises(_WireError, match=problem):
        _like(template, state, "state")
    mt = np.random.Generator(np.random.MT19937(0)).bit_generator.state
    back = _like(mt, json.loads(json.dumps({**mt, "state": {**mt["state"], "key": mt["state"]["key"].tolist()}})),
                 "state")
    np.testing.assert_array_equal(back["state"]["key"], mt["state"]["key"])
    with pytest.raises(_WireError, match="is not a list of 624 uint32 integers"):
        _like(mt, {**mt, "state": {**mt["state"], "key": [-1] * 624}}, "state")


# ---------------------------------------------------------------------------------------------------------------
# Crashes, hangs, forks and threads.


@pytest.mark.parametrize("mode, cause", [
    ("exit0", r"act\(\): its process exited with code 0"),
    ("segfault", r"act\(\): its process died from signal SIGSEGV \(-11\)"),
    ("swallow_forever", rf"act\(\) timed out after {SHORT:g} s; its process was killed"),
])
def test_crashes_and_endless_loops_are_script_errors_and_the_host_lives_on(sandboxed, hanging, mode, cause):
    error, took = _failure(hanging if mode == "swallow_forever" else sandboxed, mode)
    assert re.search(cause, error.cause), error.cause
    assert took < BOUND
    assert (_act(sandboxed, "fine").kind[:, 3:] != 0).all()  # a fresh child plays on


@pytest.mark.parametrize("how", ["timeout", "close"])
def test_what_a_script_forks_dies_with_its_child(sandboxed, hanging, hostile, how):
    if how == "timeout":
        _failure(hanging, "fork_and_hang")
    else:
        _act(sandboxed, "fork")
        sandboxed.close()
    pid = int((hostile.parent / f"{'fork_and_hang' if how == 'timeout' else 'fork'}.pid").read_text())
    assert _gone_soon(pid), f"the script's grandchild {pid} outlived its child"


_HOST = '''
import sys

import numpy as np

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.engine.state import BLUE, Commands
from smac_hard_gym.opponents import SideView, make_opponent

if __name__ == "__main__":
    engine = BattleEngine("3m", batch_size=1)
    engine.reset(seeds=np.arange(1))
    view = SideView.of(engine.state, engine.spec, BLUE, np.full(1, int(sys.argv[2]), dtype=np.int64))
    script = make_opponent("3m", sys.argv[1])
    script.act(view, Commands.empty(1, engine.n_units), np.ones(1, dtype=bool))
    print(script.script.pid, flush=True)
    # exits without close(): the child's non-daemon thread and its fork must not keep anything alive
'''


def test_a_host_exits_despite_a_thread_and_a_fork_left_in_the_child(hostile, tmp_path):
    host = tmp_path / "host.py"
    host.write_text(_HOST)
    done = subprocess.run([sys.executable, str(host), f"{hostile}:Mischief", str(MODES.index("thread"))],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    child = int(done.stdout.split()[-1])
    grandchild = int((hostile.parent / "thread.pid").read_text())
    assert _gone_soon(child) and _gone_soon(grandchild)


def test_a_leftover_thread_is_killed_with_the_child_on_close(hostile):
    script = make_opponent("3m", f"{hostile}:Mischief", time_limit=LIMIT)
    _act(script, "thread")
    child = script.script.pid
    script.close()
    assert _gone_soon(child)


# ---------------------------------------------------------------------------------------------------------------
# Resources and the host's state.


def test_a_memory_hog_is_a_script_error_and_the_child_lives_on(sandboxed):
    error, _ = _failure(sandboxed, "hog")
    assert error.cause == "act() raised MemoryError: "
    pid = sandboxed.script.pid
    _act(sandboxed, "fine")
    assert sandboxed.script.pid == pid  # a failure the script raised keeps its child


def test_the_child_holds_only_stdio_and_its_pipe(sandboxed):
    error, _ = _failure(sandboxed, "fds")
    fds = json.loads(error.cause.partition("fds=")[2])
    # 0, 1, 2, the pipe, and the descriptor listdir() opened on /proc/self/fd to list them
    assert fds[:3] == [0, 1, 2] and len(fds) <= 5, fds


def test_monkeypatching_in_the_child_leaves_the_host_alone(sandboxed):
    import gymnasium as gym

    import smac_hard_gym  # noqa: F401  (registers the ids)
    from smac_hard_gym.smac.actions import InvalidActionError

    _act(sandboxed, "monkeypatch")
    env = gym.make("SMACHard-3m-v0")
    try:
        env.reset(seed=0)
        with pytest.raises(InvalidActionError, match="action 99 is out of range"):
            env.step(np.array([99, 0, 0]))
    finally:
        env.close()


# ---------------------------------------------------------------------------------------------------------------
# Raw errors: every exception a script raises is a ScriptError (KeyboardInterrupt only in the sandbox).


class _Resize(Script):
    name = "resize"

    def act(self, view, commands, active):
        commands.kind.resize((3,), refcheck=False)


class _GeneratorExit(Script):
    name = "generator_exit"

    def act(self, view, commands, active):
        raise GeneratorExit


class _Own(BaseException):
    """A BaseException of the script's own."""


class _OwnBaseException(Script):
    name = "own"

    def act(self, view, commands, active):
        raise _Own("mine")


class _KeyboardInterrupt(Script):
    name = "keyboard_interrupt"

    def act(self, view, commands, active):
        raise KeyboardInterrupt


@pytest.mark.parametrize("script, cause", [
    (_Resize(), r"act\(\) broke its command buffer: commands.kind is now \(3,\) int8, expected \(2, 6\) int8"),
    (_GeneratorExit(), r"act\(\) raised GeneratorExit"),
    (_OwnBaseException(), r"act\(\) raised _Own: mine"),
])
def test_raw_errors_become_script_errors_under_the_guard(script, cause):
    guarded = make_opponent("3m", script)
    with pytest.raises(ScriptError, match=cause):
        _act(guarded, "fine")


@pytest.mark.parametrize("mode, cause", [
    ("resize", r"act\(\) broke its command buffer: commands.kind is now \(3,\) int8, expected \(2, 6\) int8"),
    ("generator_exit", r"act\(\) raised GeneratorExit"),
    ("keyboard_interrupt", r"act\(\) raised KeyboardInterrupt"),
])
def test_raw_errors_become_script_errors_in_the_sandbox(sandboxed, mode, cause):
    error, _ = _failure(sandboxed, mode)
    assert re.search(cause, error.cause), error.cause


def test_keyboard_interrupt_propagates_through_the_guard():
    # Documented: the guard cannot tell a raised KeyboardInterrupt from Ctrl-C, and Ctrl-C must stop the program.
    with pytest.raises(KeyboardInterrupt):
        _act(make_opponent("3m", _KeyboardInterrupt()), "fine")


# ---------------------------------------------------------------------------------------------------------------
# What the guard cannot stop (documented): a script that swallows every exception in a loop.


class _Swallower(Script):
    """Catches the guard's interruptions; gives up after ``shots`` of them (a real hostile script never would)."""

    name = "swallower"

    def __init__(self, shots: int):
        self.shots = shots
        self.caught = 0

    def act(self, view, commands, active):
        while self.caught < self.shots:
            try:
                while True:
                    pass
            except BaseException:  # noqa: BLE001 - the case under test
                self.caught += 1


def test_the_guard_cannot_stop_a_script_that_swallows_its_interruptions():
    script = _Swallower(shots=3)
    guarded = make_opponent("3m", script, time_limit=0.1)
    with pytest.raises(ScriptError, match=r"act\(\) took .* s, over its time limit of 0.1 s"):
        _act(guarded, "fine")
    # The guard fired again and again; the call only ended because the script chose to return. With no such
    # choice it would run for ever: use the process sandbox for scripts you do not trust.
    assert script.caught == 3
