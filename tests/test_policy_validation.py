"""Policy opponents are checked like scripts: their actions go through the learner's validator, their exceptions and
overruns become ScriptError naming the policy, and an in-range unavailable action is still replaced."""

from __future__ import annotations

import time

import numpy as np
import pytest

from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.opponents.api import ScriptError
from smac_hard_gym.opponents.guard import DEFAULT_TIME_LIMIT
from smac_hard_gym.opponents.policy import PolicyScript

N_ACTIONS_3M = 6 + 3  # SMAC: no-op, stop, 4 moves, one attack per enemy


def _core(policy, name="pol", **kwargs) -> TwoPlayerCore:
    return TwoPlayerCore("3m", 2, opponent=PolicyScript(policy, name, **kwargs), seed=0)


def _step(core: TwoPlayerCore):
    return core.step(np.ones((2, 3), dtype=np.int64))


def _returning(value):
    """A policy answering ``value`` for agent 1 of every battle, legal actions elsewhere."""
    def policy(obs, masks):
        out = masks.argmax(axis=2).astype(object)
        out[:, 1] = value
        return out
    return policy


@pytest.mark.parametrize(("value", "shown"), [
    (float("nan"), "nan"), (float("inf"), "inf"), (-float("inf"), "-inf"), (3.7, "3.7"), (999, "999"), (-5, "-5"),
    (N_ACTIONS_3M, str(N_ACTIONS_3M)), ("1", "'1'"), (True, "True"), (False, "False"), (np.bool_(True), "True"),
    (None, "None"), (2**70, str(2**70)), (1 + 2j, "(1+2j)"),
])
def test_bad_policy_actions_raise_script_error_naming_policy_value_and_range(value, shown):
    core = _core(_returning(value), name="wonky")
    with pytest.raises(ScriptError) as info:
        _step(core)
    message = str(info.value)
    assert "'wonky'" in message and "'3m'" in message
    assert f"action {shown} " in message, message
    assert f"0..{N_ACTIONS_3M - 1}" in message
    assert "blue agent 1" in message


@pytest.mark.parametrize("dtype_value", [np.array([[np.nan] * 3] * 2), np.full((2, 3), 3.7),
                                         np.full((2, 3), True), np.full((2, 3), "1"), np.full((2, 3), -5)])
def test_whole_bad_arrays_are_rejected_too(dtype_value):
    core = _core(lambda obs, masks: dtype_value)
    with pytest.raises(ScriptError, match=r"invalid actions: .*0\.\.8"):
        _step(core)


def test_wrong_shape_is_rejected():
    core = _core(lambda obs, masks: np.ones((2, 4), dtype=np.int64))
    with pytest.raises(ScriptError, match=r"must have shape \(2, 3\)"):
        _step(core)


def test_integral_floats_and_unavailable_actions_still_play():
    # 3.0 is the int 3 (as for a learner); 8 (attack enemy 2, out of range at the start) is replaced by the agent's
    # first legal action: the documented rule, not an error.
    floats = _core(lambda obs, masks: np.full(masks.shape[:2], 1.0))
    ints = _core(lambda obs, masks: np.full(masks.shape[:2], 1, dtype=np.int64))
    for _ in range(3):
        a, b = _step(floats), _step(ints)
        np.testing.assert_array_equal(a.reward, b.reward)
    np.testing.assert_array_equal(floats.opponent.last_action, ints.opponent.last_action)
    stubborn = _core(lambda obs, masks: np.full(masks.shape[:2], 8))
    _step(stubborn)
    np.testing.assert_array_equal(stubborn.opponent.last_action, np.ones((2, 3)))


def test_policy_exceptions_become_script_errors():
    def broken(obs, masks):
        return 1 / 0

    core = _core(broken, name="broken")
    with pytest.raises(ScriptError, match=r"'broken'.*raised ZeroDivisionError") as info:
        _step(core)
    assert isinstance(info.value.__cause__, ZeroDivisionError)

    def leaves(obs, masks):
        raise SystemExit(3)

    with pytest.raises(ScriptError, match=r"sys\.exit\(3\)"):
        _step(_core(leaves))


def test_keyboard_interrupt_still_propagates():
    def interrupted(obs, masks):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _step(_core(interrupted))


def test_a_slow_policy_is_stopped_at_its_time_limit():
    def slow(obs, masks):
        end = time.monotonic() + 600.0
        while time.monotonic() < end:  # Python-level waiting: the watchdog interrupts it
            time.sleep(0.01)
        return masks.argmax(axis=2)

    core = _core(slow, name="slow", time_limit=0.5)
    start = time.monotonic()
    with pytest.raises(ScriptError, match=r"'slow'.*time limit of 0\.5 s"):
        _step(core)
    assert time.monotonic() - start < 60.0  # interrupted, not waited out (the policy wanted 600 s; a hang bound)


def test_a_policy_stuck_in_one_c_call_fails_when_it_returns():
    def stuck(obs, masks):
        time.sleep(0.6)  # one C call: interrupted only when it returns, then reported as over its limit
        return masks.argmax(axis=2)

    with pytest.raises(ScriptError, match=r"'stuck'.*time limit of 0\.2 s"):
        _step(_core(stuck, name="stuck", time_limit=0.2))


def test_time_limit_defaults_and_none():
    assert PolicyScript(lambda o, m: m.argmax(axis=2)).time_limit == DEFAULT_TIME_LIMIT

    def slowish(obs, masks):
        time.sleep(0.3)
        return masks.argmax(axis=2)

    _step(_core(slowish, time_limit=None))  # no limit: plays
    for bad in (0, -1, float("nan"), True, "5"):
        with pytest.raises(ValueError, match="time_limit must be"):
            PolicyScript(slowish, time_limit=bad)


def test_load_docstring_warns_about_pickle():
    doc = PolicyScript.load.__doc__
    assert "pickle" in doc and "trust" in doc


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04 truncated", b"random \x00\xff bytes"])
def test_a_malformed_model_file_as_opponent_is_one_line(tmp_path, capsys, content):
    pytest.importorskip("sb3_contrib")
    from smac_hard_gym.cli import main

    model = tmp_path / "blue.zip"
    model.write_bytes(content)
    with pytest.raises(ValueError, match="is not a saved MaskablePPO model"):
        PolicyScript.load(model)
    with pytest.raises(SystemExit, match="not a saved MaskablePPO model") as info:
        main(["train", "--map", "3m", "--opponent", str(model), "--timesteps", "64", "--out", str(tmp_path / "r")])
    assert "\n" not in str(info.value.code)
