"""Script isolation: read-only state under the guard, its thread-safe time limit, ScriptError across processes, and
the process sandbox (hangs in C, os._exit and segfaults become ScriptErrors; the host and the next reset survive)."""

from __future__ import annotations

import gc
import os
import pickle
import signal
import textwrap
import threading
import time
from pathlib import Path

import cloudpickle
import numpy as np
import pytest

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.engine.state import BLUE, CMD_ATTACK, CMD_STOP, Commands
from smac_hard_gym.opponents import (
    GuardedScript,
    PerBattleScript,
    ProcessIsolatedScript,
    Script,
    ScriptError,
    SideView,
    make_opponent,
)

LIMIT = 0.3  # seconds: small, so the endless cases stay fast
HANG_BOUND = 60.0  # seconds: far more than the limit plus a child's start on a loaded machine


def _setup(batch: int = 2):
    engine = BattleEngine("3m", batch_size=batch)
    engine.reset(seeds=np.arange(batch))
    view = SideView.of(engine.state, engine.spec, BLUE, np.zeros(batch, dtype=np.int64))
    rngs = [np.random.default_rng(b) for b in range(batch)]
    return engine, view, rngs, Commands.empty(batch, engine.n_units)


def _snapshot(engine: BattleEngine) -> list[np.ndarray]:
    return [a.copy() for a in engine.state] + [engine.spec.pathable.copy(), engine.spec.cliff.copy()]


def _assert_unchanged(engine: BattleEngine, before: list[np.ndarray]) -> None:
    after = _snapshot(engine)
    for old, new in zip(before, after, strict=True):
        np.testing.assert_array_equal(old, new)


class _Writer(Script):
    """Writes into what it was given, then orders its units to stop (which must not reach the buffer on failure)."""

    name = "writer"

    def __init__(self, write):
        self.write = write

    def act(self, view, commands, active):
        self.write(view)
        commands.kind[active, view.own] = CMD_STOP


def _nan_positions(view):
    view.state.x[:] = np.nan


def _kill_units(view):
    view.state.alive[:, view.enemy] = False


def _zero_health(view):
    view.enemy_health[:] = 0.0


def _change_types(view):
    view.state.utype[:] = 0


def _rewind_steps(view):
    view.episode_step[:] = 99


def _block_terrain(view):
    view.spec.pathable[:] = False


@pytest.mark.parametrize("write", [_nan_positions, _kill_units, _zero_health, _change_types, _rewind_steps,
                                   _block_terrain])
def test_guarded_writes_to_the_state_fail_and_leave_the_engine_as_it_was(write):
    engine, view, rngs, commands = _setup()
    before = _snapshot(engine)
    script = make_opponent("3m", _Writer(write))
    with pytest.raises(ScriptError, match=r"act\(\) raised ValueError: .*read-only") as info:
        script.act(view, commands, np.ones(2, dtype=bool))
    assert info.value.script == "writer" and info.value.map_name == "3m"
    _assert_unchanged(engine, before)
    assert (commands.kind == 0).all()
    engine.step(commands)  # the engine runs on (a NaN position used to segfault here)
    assert np.isfinite(engine.state.x).all()


def test_turning_writeable_back_on_changes_only_the_scripts_copy():
    def flip(view):
        for array in (view.state.x, view.state.health, view.state.alive, view.own_x):
            try:
                array.flags.writeable = True
            except ValueError:  # a view of a read-only copy refuses
                continue
            array[...] = 0

    engine, view, rngs, commands = _setup()
    before = _snapshot(engine)
    script = make_opponent("3m", _Writer(flip))
    script.act(view, commands, np.ones(2, dtype=bool))
    _assert_unchanged(engine, before)


def test_per_battle_scripts_see_read_only_rows():
    class Healer(PerBattleScript):
        name = "healer"

        def act_battle(self, battle):
            battle.own.health[:] = 1000.0

    engine, view, rngs, commands = _setup()
    before = _snapshot(engine)
    script = make_opponent("3m", Healer())
    script.reset(view, np.arange(2), rngs)
    with pytest.raises(ScriptError, match="read-only"):
        script.act(view, commands, np.ones(2, dtype=bool))
    _assert_unchanged(engine, before)


def test_builtin_scripts_still_get_the_live_views():
    engine, view, rngs, commands = _setup()
    seen = []

    class Spy(Script):
        name = "spy"

        def act(self, view, commands, active):
            seen.append(view.state.x)

    make_opponent("3m", Spy(), guard=False).act(view, commands, np.ones(2, dtype=bool))
    assert seen[0] is engine.state.x


@pytest.mark.parametrize("where", ["reset", "act"])
def test_sys_exit_becomes_a_script_error(where):
    class Quitter(Script):
        name = "quitter"

        def reset(self, view, battles, rngs):
            if where == "reset":
                raise SystemExit(2)

        def act(self, view, commands, active):
            raise SystemExit("bye")

    engine, view, rngs, commands = _setup()
    script = make_opponent("3m", Quitter())
    with pytest.raises(ScriptError, match=rf"{where}\(\) called sys.exit\("):
        script.reset(view, np.arange(2), rngs)
        script.act(view, commands, np.ones(2, dtype=bool))


class _Endless(Script):
    """Never returns; with ``swallow`` it also catches every exception, the watchdog's included, once."""

    name = "endless"

    def __init__(self, swallow: bool = False):
        self.swallow = swallow

    def act(self, view, commands, active):
        if self.swallow:
            try:
                while True:
                    pass
            except BaseException:  # noqa: BLE001 - the case under test
                pass
        while True:
            pass


def _run_in_thread(fn):
    errors: list[BaseException] = []

    def run():
        try:
            fn()
        except BaseException as err:  # handed over to the test thread
            errors.append(err)

    worker = threading.Thread(target=run)
    worker.start()
    worker.join(timeout=10)
    assert not worker.is_alive(), "the endless script was not interrupted"
    return errors


@pytest.mark.parametrize("thread", ["main", "other"])
@pytest.mark.parametrize("swallow", [False, True])
def test_an_endless_script_is_interrupted_on_any_thread(thread, swallow):
    engine, view, rngs, commands = _setup()
    script = make_opponent("3m", _Endless(swallow), time_limit=LIMIT)
    start = time.perf_counter()

    def call():
        script.act(view, commands, np.ones(2, dtype=bool))

    if thread == "main":
        with pytest.raises(ScriptError) as info:
            call()
        error = info.value
    else:
        errors = _run_in_thread(call)
        assert len(errors) == 1
        error = errors[0]
    assert isinstance(error, ScriptError)
    assert f"ran past its time limit of {LIMIT:g} s and was interrupted" in error.cause
    assert time.perf_counter() - start < HANG_BOUND  # the script never ends by itself: this bounds a hang only
    time.sleep(2 * LIMIT)
    for _ in range(100_000):  # a late shot of the watchdog would land in this loop
        pass


def test_the_users_interval_timer_is_left_alone():
    fired = []

    def handler(signum, frame):
        fired.append(signum)

    previous = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, 100.0)
    try:
        engine, view, rngs, commands = _setup()
        script = make_opponent("3m", _Endless(), time_limit=LIMIT)
        with pytest.raises(ScriptError, match="interrupted"):  # the guard works with the user's timer running
            script.act(view, commands, np.ones(2, dtype=bool))
        remaining, interval = signal.getitimer(signal.ITIMER_REAL)
        assert 90.0 < remaining <= 100.0 and interval == 0.0
        assert signal.getsignal(signal.SIGALRM) is handler and not fired
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)


@pytest.mark.parametrize("dumps, loads", [(pickle.dumps, pickle.loads), (cloudpickle.dumps, cloudpickle.loads)])
def test_script_error_survives_pickling_with_its_fields(dumps, loads):
    err = ScriptError("mine", "3m", "act() raised KeyError: 'x'")
    err.add_note("a note")
    back = loads(dumps(err))
    assert type(back) is ScriptError and str(back) == str(err)
    assert (back.script, back.map_name, back.cause) == ("mine", "3m", "act() raised KeyError: 'x'")
    assert back.__notes__ == ["a note"]


_BOOM = '''
from smac_hard_gym.opponents import Script


class Boom(Script):
    name = "boom"

    def act(self, view, commands, active):
        raise KeyError("no such unit")
'''


def test_the_subprocess_vector_env_reraises_the_script_error(tmp_path):
    from smac_hard_gym.envs.subproc import make_subproc_env

    path = tmp_path / "boom.py"
    path.write_text(_BOOM)
    env = make_subproc_env("3m", 1, 1, autoreset_mode="SameStep", opponent=f"{path}:Boom")
    try:
        env.reset(seed=0)
        with pytest.raises(ScriptError) as info:
            env.step(np.zeros((1, 3), dtype=np.int64))
    finally:
        env.close()
    assert (info.value.script, info.value.map_name) == ("boom", "3m")
    assert info.value.cause == "act() raised KeyError: 'no such unit'"


# ---------------------------------------------------------------------------------------------------------------
# The process sandbox.

_SANDBOXED = '''
import ctypes
import os
import sys
import time

from smac_hard_gym.engine.state import CMD_ATTACK
from smac_hard_gym.opponents import Script


class Good(Script):
    name = "good"

    def reset(self, view, battles, rngs):
        self.rngs = rngs
        self.first = {int(b): float(rngs[b].random()) for b in battles}

    def act(self, view, commands, active):
        for b in range(view.batch_size):
            if active[b]:
                k = int(self.rngs[b].integers(view.n_enemy))
                commands.kind[b, view.own] = CMD_ATTACK
                commands.target[b, view.own] = view.enemy_slot(k)


class Hang(Good):
    name = "hang"

    def act(self, view, commands, active):
        time.sleep(1000)  # one C call: only the sandbox stops it


class Exit(Good):
    name = "exit"

    def act(self, view, commands, active):
        os._exit(3)


class Segfault(Good):
    name = "segfault"

    def act(self, view, commands, active):
        ctypes.string_at(0)


class Quit(Good):
    name = "quit"

    def act(self, view, commands, active):
        sys.exit(2)


class Writer(Good):
    name = "writer"

    def act(self, view, commands, active):
        view.state.x[:] = float("nan")
'''


def _pid_gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


@pytest.fixture(scope="module")
def sandboxed(tmp_path_factory):
    path = tmp_path_factory.mktemp("sandbox") / "sandboxed.py"
    path.write_text(textwrap.dedent(_SANDBOXED))
    return lambda name: f"{path}:{name}"


def test_a_sandboxed_script_plays_like_the_in_process_one(sandboxed):
    engine, view, rngs, _ = _setup()
    inside = make_opponent("3m", sandboxed("Good"), isolation="guard")
    outside = make_opponent("3m", sandboxed("Good"), isolation="process")
    try:
        assert isinstance(outside, GuardedScript) and isinstance(outside.script, ProcessIsolatedScript)
        assert outside.name == "good"
        twins = [np.random.default_rng(b) for b in range(2)]
        inside.reset(view, np.arange(2), rngs)
        outside.reset(view, np.arange(2), twins)
        for _ in range(3):
            mine, theirs = Commands.empty(2, 6), Commands.empty(2, 6)
            inside.act(view, mine, np.array([True, False]))
            outside.act(view, theirs, np.array([True, False]))
            for a, b in zip(mine, theirs, strict=True):
                np.testing.assert_array_equal(a, b)
        # The host's generators advanced exactly as the child's did.
        assert [r.bit_generator.state for r in rngs] == [r.bit_generator.state for r in twins]
    finally:
        outside.close()


@pytest.mark.parametrize("name, cause", [
    ("Hang", rf"act\(\) timed out after {LIMIT:g} s; its process was killed"),
    ("Exit", r"act\(\): its process exited with code 3"),
    ("Segfault", r"act\(\): its process died from signal SIGSEGV \(-11\)"),
    ("Quit", r"act\(\) called sys.exit\(2\)"),
    ("Writer", r"act\(\) raised ValueError: .*read-only"),
])
def test_sandbox_failures_become_script_errors_and_the_next_reset_works(sandboxed, name, cause):
    engine, view, rngs, commands = _setup()
    before = _snapshot(engine)
    script = make_opponent("3m", sandboxed(name), isolation="process", time_limit=LIMIT)
    try:
        script.reset(view, np.arange(2), rngs)
        first = script.script.pid
        start = time.perf_counter()
        with pytest.raises(ScriptError, match=cause) as info:
            script.act(view, commands, np.ones(2, dtype=bool))
        assert time.perf_counter() - start < HANG_BOUND  # killed, not waited out: a hang bound, not a speed check
        assert info.value.script == name.lower() and info.value.map_name == "3m"
        _assert_unchanged(engine, before)
        assert (commands.kind == 0).all()
        if name in ("Hang", "Exit", "Segfault"):
            assert script.script.pid is None and _pid_gone(first)
        script.reset(view, np.arange(2), rngs)  # a fresh child when the old one is gone
        assert script.script.pid is not None
    finally:
        script.close()


def test_a_child_killed_between_calls_is_reported_then_replaced(sandboxed):
    engine, view, rngs, commands = _setup()
    script = make_opponent("3m", sandboxed("Good"), isolation="process", time_limit=LIMIT)
    try:
        script.reset(view, np.arange(2), rngs)
        os.kill(script.script.pid, signal.SIGKILL)
        # "before act(): ..." once the death is seen, "act(): ..." when the kill lands as the request is sent.
        with pytest.raises(ScriptError, match=r"act\(\): its process died from signal SIGKILL"):
            script.act(view, commands, np.ones(2, dtype=bool))
        script.reset(view, np.arange(2), rngs)
        script.act(view, commands, np.ones(2, dtype=bool))
        assert (commands.kind[:, 3:] == CMD_ATTACK).all()
    finally:
        script.close()


def test_no_child_outlives_its_script(sandboxed):
    script = ProcessIsolatedScript(sandboxed("Good"), time_limit=LIMIT)
    pid = script.pid
    assert pid is not None and not _pid_gone(pid)
    script.close()
    assert _pid_gone(pid)
    script = ProcessIsolatedScript(sandboxed("Good"), time_limit=LIMIT)
    pid = script.pid
    del script
    gc.collect()
    assert _pid_gone(pid)


def test_sandbox_load_errors_and_bad_options(sandboxed, tmp_path):
    with pytest.raises(ValueError, match="could not start in a child process: .*no attribute 'Missing'"):
        make_opponent("3m", sandboxed("Missing"), isolation="process")
    with pytest.raises(ValueError, match=r"isolation must be one of \('none', 'guard', 'process'\), got 'box'"):
        make_opponent("3m", "base", isolation="box")
    with pytest.raises(ValueError, match="guard=False cannot be combined with isolation='process'"):
        make_opponent("3m", sandboxed("Good"), guard=False, isolation="process")
    with pytest.raises(ValueError, match="time_limit must be a positive number"):
        ProcessIsolatedScript(sandboxed("Good"), time_limit=0)
    assert not isinstance(make_opponent("3m", "nearest", isolation="process"), GuardedScript)  # built-ins: trusted
    assert not isinstance(make_opponent("3m", sandboxed("Good"), isolation="none"), GuardedScript)


def test_a_sandboxed_script_inside_a_vector_env_worker(sandboxed):
    from smac_hard_gym.envs.subproc import make_subproc_env

    opponent = make_opponent("3m", sandboxed("Segfault"), isolation="process", time_limit=5.0)
    opponent.close()  # the worker rebuilds it with a child of its own
    env = make_subproc_env("3m", 1, 1, autoreset_mode="SameStep", opponent=opponent)
    try:
        env.reset(seed=0)
        with pytest.raises(ScriptError, match=r"died from signal SIGSEGV") as info:
            env.step(np.zeros((1, 3), dtype=np.int64))
        assert (info.value.script, info.value.map_name) == ("segfault", "3m")
        env.reset(seed=1)  # the worker survived and starts a fresh child
    finally:
        env.close()


def test_envs_take_opponent_isolation_and_name_every_keyword_they_take():
    import gymnasium as gym

    import smac_hard_gym  # noqa: F401  (registers the ids)
    from smac_hard_gym import StarCraft2Env

    script = str(Path(__file__).resolve().parents[1] / "examples" / "per_battle_script.py")
    env = gym.make("SMACHard-3m-v0", opponent=script, opponent_isolation="process")
    try:
        env.reset(seed=0)
        env.step(env.action_space.sample())
        opponent = env.unwrapped.core.opponent  # the guard's command checks around the sandbox
        assert isinstance(opponent.script, ProcessIsolatedScript)
    finally:
        env.close()
    with pytest.raises(ValueError, match="isolation"):
        StarCraft2Env(map_name="3m", opponent=script, opponent_isolation="sandbox")
    with pytest.raises(TypeError, match="opponent_isolation") as err:
        gym.make("SMACHard-3m-v0", oponent="base")
    assert "oponent" in str(err.value) and "reward_sparse" in str(err.value)


def test_a_sandbox_built_by_hand_is_only_wrapped_in_the_command_checks(sandboxed):
    sandbox = ProcessIsolatedScript(sandboxed("Good"), time_limit=LIMIT, memory_limit=1 << 30)
    try:
        for isolation in (None, "guard", "process"):
            script = make_opponent("3m", sandbox, isolation=isolation)
            assert isinstance(script, GuardedScript) and script.script is sandbox and script.time_limit is None
        copy = pickle.loads(pickle.dumps(sandbox))  # a vector env worker's copy, with a child of its own
        copy.close()
        assert copy.memory_limit == 1 << 30
    finally:
        sandbox.close()
    with pytest.raises(ValueError, match="memory_limit must be a positive number of bytes or None"):
        ProcessIsolatedScript(sandboxed("Good"), memory_limit=0)
