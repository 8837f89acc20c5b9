"""SubprocVectorEnv: same results as a native batch, cloudpickled factories, start methods, workers that die or hang
(restart or raise), env errors, and no child process left behind."""

import functools
import multiprocessing as mp
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import cloudpickle
import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from test_vector_env import assert_same

from smac_hard_gym.envs.gym_env import SMACHardEnv
from smac_hard_gym.envs.subproc import SubprocVectorEnv, WorkerError, concat_infos, make_subproc_env
from smac_hard_gym.envs.vector import NativeVectorEnv
from smac_hard_gym.smac.actions import InvalidActionError, ResetNeededError

GENEROUS = 60.0  # seconds: about 10x what a quiet machine needs; bounds hangs, asserts no speed


class TickEnv(gym.Env):
    """A counter: obs [steps, marker], episodes of 5 steps, reward 1 per step; hangs on the step that finds
    ``hang_file`` (deleting it, so a rebuilt worker runs on); with ``die`` its process exits on every step."""

    metadata = {"render_modes": []}

    def __init__(self, marker: float = 0.0, hang_file: str | None = None, die: bool = False) -> None:
        self.observation_space = gym.spaces.Box(-1e3, 1e3, (2,), np.float32)
        self.action_space = gym.spaces.Discrete(3)
        self.marker, self.hang_file, self.die, self.steps = marker, hang_file, die, 0

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.steps = 0
        return np.array([0, self.marker], np.float32), {}

    def step(self, action):
        if self.hang_file and os.path.exists(self.hang_file):
            os.remove(self.hang_file)
            time.sleep(600)
        if self.die:
            os._exit(3)
        self.steps += 1
        return np.array([self.steps, self.marker], np.float32), 1.0, self.steps >= 5, False, {"steps": self.steps}


def _broken_factory():
    raise RuntimeError("no StarCraft II here")


def _workers_alive(env_or_processes):
    processes = env_or_processes.processes if hasattr(env_or_processes, "processes") else env_or_processes
    return [p for p in processes if p.is_alive()]


@pytest.fixture(autouse=True)
def no_leaked_workers():
    yield
    deadline = time.monotonic() + GENEROUS  # workers exit within a second on a quiet machine
    while any(p.name.startswith("smac-hard-gym-worker") for p in mp.active_children()):
        assert time.monotonic() < deadline, f"worker processes left alive: {mp.active_children()}"
        time.sleep(0.1)


def _timestep_reader(map_name="3m"):
    probe = NativeVectorEnv(map_name, 1, obs_timestep_number=True)
    column = probe.core.features[0].obs_feature_names().index("own_timestep")
    probe.close()
    return lambda obs: np.rint(np.asarray(obs)[..., column] * 60).astype(int).tolist()


def test_matches_a_native_batch_of_the_same_size():
    kwargs = {"opponent": "default", "invalid_action": "noop", "max_episode_steps": 12}
    with make_subproc_env("3m", 2, 2, autoreset_mode="SameStep", **kwargs) as env:
        native = NativeVectorEnv("3m", 4, autoreset_mode="SameStep", **kwargs)
        for got, want in zip(env.reset(seed=3), native.reset(seed=3), strict=True):
            assert_same(got, want)
        rng = np.random.default_rng(0)
        for _ in range(30):
            masks = native.action_masks().reshape(4, 3, 9)
            np.testing.assert_array_equal(env.action_masks(), native.action_masks())
            actions = np.array([[rng.choice(np.flatnonzero(m)) for m in row] for row in masks])
            for name, x, y in zip("obs reward terminated truncated infos".split(), env.step(actions),
                                  native.step(actions), strict=True):
                assert_same(x, y, name)
        processes = env.processes
    assert not _workers_alive(processes)


def test_default_start_method_runs_a_cloudpickled_lambda():
    factory = lambda: NativeVectorEnv("2m_vs_1z", 2, autoreset_mode="SameStep", opponent="base")  # noqa: E731
    env = SubprocVectorEnv([factory])
    try:
        assert env.start_method in ("forkserver", "spawn")
        obs, infos = env.reset(seed=0)
        direct = factory()
        np.testing.assert_array_equal(obs, direct.reset(seed=0)[0])
        obs, reward, terminated, truncated, infos = env.step(np.ones((2, 2), dtype=np.int64))
        np.testing.assert_array_equal(obs, direct.step(np.ones((2, 2), dtype=np.int64))[0])
        assert env.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    finally:
        env.close()


def test_factories_survive_cloudpickle():
    for factory in (lambda: NativeVectorEnv("3m", 2, opponent="base"),
                    functools.partial(NativeVectorEnv, "3m", num_envs=2, opponent="base"),
                    functools.partial(TickEnv, 7.0)):
        rebuilt = cloudpickle.loads(cloudpickle.dumps(factory))()
        original = factory()
        assert_same(rebuilt.reset(seed=1)[0], original.reset(seed=1)[0])


def test_single_env_factories_and_mixed_sizes():
    factories = [functools.partial(TickEnv, 1.0), functools.partial(TickEnv, 2.0)]
    with SubprocVectorEnv(factories, autoreset_mode="NextStep", start_method="fork") as env:
        obs, _ = env.reset()
        assert obs.tolist() == [[0, 1], [0, 2]]
        for step in range(1, 6):
            obs, reward, terminated, truncated, infos = env.step(np.zeros(2, dtype=np.int64))
            assert obs[:, 0].tolist() == [step, step] and terminated.tolist() == [step == 5] * 2
            assert infos["steps"].tolist() == [step, step]
        obs, reward, *_ = env.step(np.zeros(2, dtype=np.int64))
        assert obs[:, 0].tolist() == [0, 0] and reward.tolist() == [0.0, 0.0]  # NEXT_STEP restart
        with pytest.raises(AttributeError, match="no action masks"):
            env.action_masks()


def test_sigkill_mid_episode_restarts_the_worker():
    steps_of = _timestep_reader()
    env = make_subproc_env("3m", 2, 2, autoreset_mode="SameStep", opponent="stop", on_worker_error="restart",
                           obs_timestep_number=True)
    try:
        stop = np.ones((4, 3), dtype=np.int64)
        env.reset(seed=0)
        for _ in range(3):
            obs, *_ = env.step(stop)
        assert steps_of(obs) == [3, 3, 3, 3]
        victim = env.processes[1]
        os.kill(victim.pid, signal.SIGKILL)
        obs, reward, terminated, truncated, infos = env.step(stop)
        assert truncated.tolist() == [False, False, True, True] and not terminated.any()
        assert infos["worker_restarted"].tolist() == [False, False, True, True]
        assert infos["_worker_restarted"].tolist() == [False, False, True, True]
        assert steps_of(obs) == [4, 4, 0, 0]  # the rebuilt worker's battles start new episodes (SAME_STEP)
        assert [steps_of(infos["final_obs"][i]) for i in (2, 3)] == [3, 3]  # the last observations seen
        assert env.restarts == 1 and not victim.is_alive() and env.processes[1].pid != victim.pid
        obs, *_ = env.step(stop)
        assert steps_of(obs) == [5, 5, 1, 1]
        processes = env.processes
    finally:
        env.close()
    assert not _workers_alive(processes)


def test_a_worker_that_keeps_dying_is_not_restarted_forever():
    factories = [functools.partial(TickEnv, 0.0), functools.partial(TickEnv, 1.0, die=True)]
    env = SubprocVectorEnv(factories, autoreset_mode="SameStep", start_method="fork", on_worker_error="restart",
                           max_failures=2)
    env.reset()
    for _ in range(2):
        *_, truncated, infos = env.step(np.zeros(2, dtype=np.int64))
        assert truncated.tolist() == [False, True] and infos["worker_restarted"].tolist() == [False, True]
    with pytest.raises(WorkerError, match="worker 1 .* failed 3 times in a row"):
        env.step(np.zeros(2, dtype=np.int64))
    assert env.closed


def test_sigkill_with_raise_closes_everything_and_names_the_worker():
    env = make_subproc_env("3m", 2, 1, autoreset_mode="SameStep", opponent="base")
    env.reset(seed=0)
    processes = env.processes
    os.kill(processes[0].pid, signal.SIGKILL)
    with pytest.raises(WorkerError, match=r"worker 0 \(battles 0\.\.0\): died during step"):
        env.step(np.ones((2, 3), dtype=np.int64))
    assert env.closed and not _workers_alive(processes)
    with pytest.raises(RuntimeError, match="closed"):
        env.reset()


def test_a_hung_worker_is_detected_within_the_timeout(tmp_path):
    hang = tmp_path / "hang"
    factories = [functools.partial(TickEnv, 0.0), functools.partial(TickEnv, 1.0, str(hang))]
    with SubprocVectorEnv(factories, autoreset_mode="NextStep", start_method="fork", timeout=1.0,
                          on_worker_error="restart") as env:
        env.reset()
        env.step(np.zeros(2, dtype=np.int64))
        hang.touch()
        start = time.monotonic()
        obs, reward, terminated, truncated, infos = env.step(np.zeros(2, dtype=np.int64))
        # 1 s to notice, then a rebuild; the hung step sleeps 600 s, so this only tells "restarted" from "waited"
        assert time.monotonic() - start < 2 * GENEROUS
        assert truncated.tolist() == [False, True] and infos["worker_restarted"].tolist() == [False, True]
        assert obs.tolist() == [[2, 0], [1, 1]]  # NEXT_STEP: the last observation seen, then ...
        obs, reward, terminated, truncated, infos = env.step(np.zeros(2, dtype=np.int64))
        assert obs.tolist() == [[3, 0], [0, 1]] and reward.tolist() == [1.0, 0.0]  # ... a new episode


def test_env_errors_reach_the_parent_and_the_env_goes_on():
    # Single envs in the workers: the parent cannot read their policy, so the worker rejects the action itself.
    factory = functools.partial(SMACHardEnv, "3m", opponent="base", invalid_action="raise")
    with SubprocVectorEnv([factory, factory]) as env:
        env.reset(seed=0)
        with pytest.raises(InvalidActionError, match="agent 0: action 8 .* not available"):
            env.step(np.array([[8, 1, 1], [1, 1, 1]]))
        obs, _ = env.reset(seed=0)
        assert obs.shape == (2, 90)
        env.step(np.ones((2, 3), dtype=np.int64))


class _Payload:
    """Pickles as a call of os.system: what a subverted worker would send to run a command in the parent."""

    def __init__(self, marker: str) -> None:
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


class PayloadEnv(TickEnv):
    def payload(self, marker: str) -> _Payload:
        return _Payload(marker)

    def step(self, action):
        obs, reward, terminated, truncated, info = super().step(action)
        return obs, reward, terminated, truncated, {"steps": self.steps, "odd": _Payload(self.hang_file)}


def test_the_parent_never_runs_code_a_worker_sends(tmp_path):
    marker = tmp_path / "ran-in-the-parent"
    with SubprocVectorEnv([functools.partial(PayloadEnv, 0.0)]) as env:
        env.reset(seed=0)
        with pytest.raises(WorkerError, match="does not read .*posix.system"):
            env.call("payload", str(marker))
        assert not marker.exists()
    with SubprocVectorEnv([functools.partial(PayloadEnv, 0.0, str(marker))]) as env:
        env.reset(seed=0)
        with pytest.raises(WorkerError, match="does not read .*its process was killed"):
            env.step(np.zeros(1, dtype=np.int64))
    assert not marker.exists()


def test_a_worker_exception_outside_the_allow_list_arrives_as_text():
    # An exception class the parent cannot vouch for (a test module's own, sent by value) becomes a RuntimeError
    # with the worker's traceback; the package's and Python's own exceptions keep their class.
    from smac_hard_gym.envs.subproc.worker import pack_error, unpack_error

    class Odd(Exception):
        pass

    assert type(unpack_error(pack_error(Odd("odd")), 0)) is RuntimeError
    assert "odd" in str(unpack_error(pack_error(Odd("odd")), 0))
    kept = unpack_error(pack_error(InvalidActionError("agent 0: action 8")), 0)
    assert type(kept) is InvalidActionError and str(kept) == "agent 0: action 8"
    assert type(unpack_error(pack_error(ZeroDivisionError("x")), 0)) is ZeroDivisionError


def test_actions_are_checked_before_any_worker_steps():
    read_steps = _timestep_reader()
    with make_subproc_env("3m", 2, 1, opponent="base", invalid_action="raise", obs_timestep_number=True) as env:
        with pytest.raises(ResetNeededError, match=r"call reset\(\) before step\(\)"):
            env.step(np.ones((2, 3), dtype=np.int64))
        env.reset(seed=0)
        with pytest.raises(InvalidActionError, match="battle 1, red agent 0: action 8 is not available.*"
                                                     "invalid_action='noop'"):
            env.step(np.array([[1, 1, 1], [8, 1, 1]]))
        with pytest.raises(TypeError, match="battle 0, red agent 0: action 1.5 is not a whole number"):
            env.step(np.full((2, 3), 1.5))
        with pytest.raises(InvalidActionError, match="action 9 is out of range"):
            env.step(np.array([[1, 1, 1], [1, 1, 9]]))
        obs, *_ = env.step(np.ones((2, 3), dtype=np.int64))
        assert read_steps(obs) == [1, 1]  # one step in each battle: no worker stepped before


def test_closing_from_an_exception_stops_every_worker():
    with pytest.raises(KeyError, match="boom"):
        with make_subproc_env("3m", 2, 1, opponent="base") as env:
            processes = env.processes
            env.reset(seed=0)
            raise KeyError("boom")
    assert len(processes) == 2 and not _workers_alive(processes)


def test_a_factory_that_fails_is_reported_with_its_cause():
    with pytest.raises(WorkerError, match="worker 1 failed to build its env.*no StarCraft II here"):
        SubprocVectorEnv([functools.partial(TickEnv, 0.0), _broken_factory], start_method="fork")


def test_workers_do_not_outlive_a_killed_parent(tmp_path):
    script = tmp_path / "parent.py"
    script.write_text(textwrap.dedent(f"""
        import functools, os, signal, sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_subproc import TickEnv
        from smac_hard_gym.envs.subproc import SubprocVectorEnv
        if __name__ == "__main__":
            env = SubprocVectorEnv([functools.partial(TickEnv, 0.0)] * 2, start_method="fork")
            env.reset()
            print(" ".join(str(p.pid) for p in env.processes), flush=True)
            os.kill(os.getpid(), signal.SIGKILL)
    """))
    result = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    pids = [int(p) for p in result.stdout.split()]
    assert len(pids) == 2, result.stderr

    def running(pid):
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError):
            return False
        return state != "Z"

    deadline = time.monotonic() + GENEROUS
    while any(running(pid) for pid in pids):
        assert time.monotonic() < deadline, f"workers {pids} outlived their parent"
        time.sleep(0.1)


def test_concat_infos_fills_missing_keys():
    joined = concat_infos([{"a": np.array([1, 2]), "_a": np.array([True, False])}, {"b": np.array(["x"], object),
                                                                                  "_b": np.array([True])}], [2, 1])
    assert joined["a"].tolist() == [1, 2, 0] and joined["_a"].tolist() == [True, False, False]
    assert joined["b"].tolist() == [None, None, "x"] and joined["_b"].tolist() == [False, False, True]


def test_bad_subproc_arguments_raise_naming_the_argument():
    with pytest.raises(ValueError, match="on_worker_error must be one of"):
        SubprocVectorEnv([functools.partial(TickEnv)], on_worker_error="ignore")
    with pytest.raises(ValueError, match="start_method must be one of"):
        SubprocVectorEnv([functools.partial(TickEnv)], start_method="thread")
    with pytest.raises(ValueError, match="factories must be a non-empty list"):
        SubprocVectorEnv([])
    with pytest.raises(ValueError, match="autoreset in mode 'NextStep' but autoreset_mode='SameStep'"):
        SubprocVectorEnv([functools.partial(gym.vector.SyncVectorEnv, [TickEnv])], autoreset_mode="SameStep",
                         start_method="fork")


def test_a_hang_before_the_first_answer_is_caught_in_minutes_once_kernels_are_cached():
    from smac_hard_gym.envs.subproc import COLD_START_TIMEOUT, WARM_START_TIMEOUT
    from smac_hard_gym.kernel_cache import kernels_cached

    native = NativeVectorEnv("3m", 16, autoreset_mode="SameStep")  # compiles (or loads) the kernels here
    native.reset(seed=0)
    native.step(np.ones((16, 3), dtype=np.int64))
    native.close()
    assert kernels_cached() is True
    env = make_subproc_env("3m", num_workers=1, envs_per_worker=1, autoreset_mode="SameStep")
    try:
        assert env.start_timeout == WARM_START_TIMEOUT < COLD_START_TIMEOUT
    finally:
        env.close()


def test_the_unit_table_cannot_be_rewritten():
    from smac_hard_gym.engine.units import STATS

    with pytest.raises(ValueError, match="read-only"):
        STATS[0, 0] = 1.0


def test_a_subproc_worker_does_not_validate_actions_its_parent_checked(validation_calls):
    """The parent validates a step's actions before any worker steps; the worker's native env then skips the core's
    own check (``checked``), and validates what it was not told is checked, so each action is validated once."""
    from smac_hard_gym.envs.subproc.worker import BatchWorker

    calls = validation_calls
    worker = BatchWorker(functools.partial(NativeVectorEnv, "3m", 2))
    try:
        worker.reset(0, None)
        worker.step(np.ones((2, 3), dtype=np.int64), checked=True)
        assert calls == []
        worker.step(np.ones((2, 3), dtype=np.int64), checked=False)
        assert calls == ["red"]
    finally:
        worker.env.close()
