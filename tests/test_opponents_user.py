"""User scripts: loading by file path or import path, the per-battle adapter, and the guard's errors."""

from __future__ import annotations

import sys
import textwrap
import time

import numpy as np
import pytest

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.engine.state import BLUE, CMD_ATTACK, RED, Commands
from smac_hard_gym.opponents import (
    GuardedScript,
    PerBattleScript,
    Script,
    ScriptError,
    SideView,
    load_script,
    make_opponent,
)


def _setup(map_name: str = "3m", batch: int = 2):
    engine = BattleEngine(map_name, batch_size=batch)
    steps = np.zeros(batch, dtype=np.int64)
    view = SideView.of(engine.state, engine.spec, BLUE, steps)
    rngs = [np.random.default_rng(b) for b in range(batch)]
    return engine, view, rngs, Commands.empty(batch, engine.n_units)


_USER_FILE = '''
import numpy as np
from smac_hard_gym.opponents import Script
from smac_hard_gym.engine.state import CMD_ATTACK


class AllOnFirst(Script):
    name = "all_on_first"

    def act(self, view, commands, active):
        commands.kind[active, view.own] = CMD_ATTACK
        commands.target[active, view.own] = view.enemy_slot(0)
'''


def _write(tmp_path, name: str, body: str):
    path = tmp_path / name
    path.write_text(textwrap.dedent(body))
    return path


# ---------------------------------------------------------------------------------------------------------------
# Loading.


def test_load_by_file_with_and_without_class_name(tmp_path):
    path = _write(tmp_path, "my_script.py", _USER_FILE)
    for ref in (f"{path}:AllOnFirst", str(path)):
        script = make_opponent("3m", ref)
        assert isinstance(script, GuardedScript) and script.name == "all_on_first"
    engine, view, rngs, commands = _setup()
    script.reset(view, np.arange(2), rngs)
    script.act(view, commands, np.array([True, False]))
    np.testing.assert_array_equal(commands.kind[0, 3:], [CMD_ATTACK] * 3)
    np.testing.assert_array_equal(commands.target[0, 3:], [0, 0, 0])
    assert (commands.kind[1] == 0).all()  # inactive battle untouched


def test_load_by_module_path(tmp_path, monkeypatch):
    _write(tmp_path, "user_pkg_mod.py", _USER_FILE)
    monkeypatch.syspath_prepend(str(tmp_path))
    script = load_script("user_pkg_mod:AllOnFirst")
    assert script.name == "all_on_first"
    sys.modules.pop("user_pkg_mod", None)


def test_user_scripts_mix_with_builtins(tmp_path):
    path = _write(tmp_path, "my_script.py", _USER_FILE)
    mix = make_opponent("3m", ["base", f"{path}:AllOnFirst"], [0.3, 0.7])
    assert mix.names == ["base", "all_on_first"]


@pytest.mark.parametrize("body, ref_suffix, message", [
    (_USER_FILE + "\nclass Second(AllOnFirst):\n    name = 'second'\n", "", "exactly one Script subclass"),
    (_USER_FILE, ":Missing", "has no attribute 'Missing'"),
    ("x = 1\n", ":x", "not a Script subclass or Script object"),
    ("raise RuntimeError('boom')\n", "", "importing user script file .* failed: RuntimeError: boom"),
    (_USER_FILE.replace("class AllOnFirst(Script):", "class AllOnFirst(Script):\n    def __init__(self, k):\n"
                        "        self.k = k\n"), "", "must be callable without arguments"),
])
def test_load_errors_name_the_problem(tmp_path, body, ref_suffix, message):
    path = _write(tmp_path, "bad.py", body)
    with pytest.raises(ValueError, match=message):
        load_script(f"{path}{ref_suffix}")


def test_missing_file_and_module():
    with pytest.raises(ValueError, match="does not exist"):
        load_script("no/such/file.py:Thing")
    with pytest.raises(ValueError, match="cannot import module 'no_such_module_xyz'"):
        load_script("no_such_module_xyz:Thing")


# ---------------------------------------------------------------------------------------------------------------
# The guard.


class _Faulty(Script):
    """Writes one configurable bad command on unit 0 of battle 0 (or raises / sleeps)."""

    name = "faulty"

    def __init__(self, fault: str):
        self.fault = fault

    def act(self, view, commands, active):
        own0 = view.own_slot(0)
        if self.fault == "raise":
            raise KeyError("no such unit")
        if self.fault == "sleep":
            time.sleep(0.5)
            self.woke = True  # only reached when the guard let the sleep run its course
        if self.fault == "forever":
            while True:
                pass
        if self.fault == "kind":
            commands.kind[0, own0] = 9
        if self.fault == "dead_target":
            commands.kind[0, own0] = CMD_ATTACK
            commands.target[0, own0] = view.enemy_slot(1)
        if self.fault == "own_target":
            commands.kind[0, own0] = CMD_ATTACK
            commands.target[0, own0] = view.own_slot(1)
        if self.fault == "heal_enemy":
            commands.kind[0, own0] = 6
            commands.target[0, own0] = view.enemy_slot(0)
        if self.fault == "nan_point":
            commands.kind[0, own0] = 3
            commands.x[0, own0] = np.nan
        if self.fault == "other_side":
            commands.kind[0, view.enemy_slot(0)] = 1


@pytest.mark.parametrize("fault, cause", [
    ("raise", r"act\(\) raised KeyError: 'no such unit'"),
    ("sleep", r"act\(\) ran past its time limit of 0.2 s and was interrupted"),
    ("forever", r"act\(\) ran past its time limit of 0.2 s and was interrupted"),
    ("kind", r"unknown command kind 9 for unit slot 3 in battle 0; allowed: 0 noop, 1 stop"),
    ("dead_target", r"attack by unit slot 3 in battle 0 targets slot 1, which is not an alive enemy"),
    ("own_target", r"attack by unit slot 3 in battle 0 targets slot 4, which is not an alive enemy "
                   r"\(enemy slots are 0..2\)"),
    ("heal_enemy", r"heal by unit slot 3 in battle 0 targets slot 0, which is not another alive unit"),
    ("nan_point", r"move by unit slot 3 in battle 0 has a non-finite point"),
    ("other_side", r"wrote a command for slot 0 in battle 0, which belongs to the other side"),
])
def test_guard_errors_name_script_map_and_cause(fault, cause):
    engine, view, rngs, commands = _setup()
    engine.place(0, 1, alive=False, health=0.0)  # red marine 1 is dead
    faulty = _Faulty(fault)
    script = make_opponent("3m", faulty, time_limit=0.2)
    script.reset(view, np.arange(2), rngs)
    with pytest.raises(ScriptError, match=r"opponent script 'faulty' on map '3m': " + cause) as info:
        script.act(view, commands, np.ones(2, dtype=bool))
    # A script past its limit is interrupted, not waited for: the sleeper never got past its sleep (an endless one
    # would hang here instead of raising).
    assert not getattr(faulty, "woke", False)
    assert info.value.script == "faulty" and info.value.map_name == "3m"
    assert (commands.kind == 0).all()  # nothing of the faulty plan reached the real buffer


def test_time_limit_interrupts_an_endless_script_off_the_main_thread():
    import threading

    engine, view, rngs, commands = _setup()
    script = make_opponent("3m", _Faulty("forever"), time_limit=0.2)
    errors: list[BaseException] = []

    def run():
        try:
            script.act(view, commands, np.ones(2, dtype=bool))
        except BaseException as err:  # handed over to the test thread
            errors.append(err)

    worker = threading.Thread(target=run)
    worker.start()
    worker.join(timeout=10)
    assert len(errors) == 1 and isinstance(errors[0], ScriptError)
    assert "ran past its time limit of 0.2 s and was interrupted" in str(errors[0])


def test_after_a_script_error_reset_and_act_work_again():
    class Flaky(Script):
        name = "flaky"

        def reset(self, view, battles, rngs):
            self.calls = 0

        def act(self, view, commands, active):
            self.calls += 1
            if self.calls == 2:
                raise ValueError("second call fails")
            commands.kind[active, view.own] = 1

    engine, view, rngs, commands = _setup()
    script = make_opponent("3m", Flaky())
    script.reset(view, np.arange(2), rngs)
    script.act(view, commands, np.ones(2, bool))
    with pytest.raises(ScriptError, match="second call fails"):
        script.act(view, commands, np.ones(2, bool))
    script.reset(view, np.arange(2), rngs)
    commands.clear()
    script.act(view, commands, np.ones(2, bool))
    assert (commands.kind[:, 3:] == 1).all()


def test_builtins_are_not_guarded_unless_asked():
    assert not isinstance(make_opponent("3m", "nearest"), GuardedScript)
    assert isinstance(make_opponent("3m", "nearest", guard=True), GuardedScript)
    with pytest.raises(ValueError, match="time_limit must be a positive number"):
        GuardedScript(_Faulty("raise"), time_limit=0)


# ---------------------------------------------------------------------------------------------------------------
# Per-battle scripts.


class _PerBattleNearest(PerBattleScript):
    name = "pb_nearest"

    def reset_battle(self, battle):
        battle.memory["seen"] = 0

    def act_battle(self, battle):
        battle.memory["seen"] += 1
        for i in battle.own.alive_indices():
            k = battle.nearest_enemy(i)
            if k >= 0:
                battle.attack(i, k)


def test_per_battle_script_matches_the_batched_nearest():
    engine, view, rngs, commands = _setup("8m", batch=3)
    engine.place(1, 2, x=14.0, y=12.0)  # make the battles differ
    engine.place(2, 0, alive=False, health=0.0)
    per_battle = make_opponent("8m", _PerBattleNearest())
    batched = make_opponent("8m", "nearest")
    for script in (per_battle, batched):
        script.reset(view, np.arange(3), rngs)
    active = np.array([True, True, True])
    mine, theirs = Commands.empty(3, 16), Commands.empty(3, 16)
    per_battle.act(view, mine, active)
    batched.act(view, theirs, active)
    np.testing.assert_array_equal(mine.kind, theirs.kind)
    np.testing.assert_array_equal(mine.target, theirs.target)
    assert [m["seen"] for m in per_battle.script._memory] == [1, 1, 1]


def test_per_battle_script_plays_the_red_side():
    engine = BattleEngine("3m", batch_size=1)
    steps = np.zeros(1, dtype=np.int64)
    view = SideView.of(engine.state, engine.spec, RED, steps)
    script = _PerBattleNearest()
    script.reset(view, np.arange(1), [np.random.default_rng(0)])
    commands = Commands.empty(1, 6)
    script.act(view, commands, np.ones(1, bool))
    assert (commands.kind[0, :3] == CMD_ATTACK).all() and (commands.target[0, :3] >= 3).all()
    assert (commands.kind[0, 3:] == 0).all()


def test_orders_in_reset_battle_raise():
    class Eager(PerBattleScript):
        def reset_battle(self, battle):
            battle.stop(0)

    engine, view, rngs, _ = _setup()
    with pytest.raises(RuntimeError, match="only be given in act_battle"):
        Eager().reset(view, np.arange(2), rngs)
