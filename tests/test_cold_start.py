"""A machine's first run: every entry point works in a fresh interpreter on an empty numba cache, and a second process
finds every kernel it needs on disk (compiles nothing).

Each case runs a small program in a new interpreter with ``NUMBA_CACHE_DIR`` pointing at an empty folder, so no kernel
compiled by another test can rescue it (as on CI's clean clone). ``NUMBA_NUM_THREADS=2`` is forced so that numba's pool
size differs from the one thread a vector env worker asks for, whatever the machine's core count: that mismatch is what
broke a worker that had to compile ("Cannot set NUMBA_NUM_THREADS to a different value once the threads have been
launched"). The default run covers the subprocess vector env (the case that failed) and the second-process check; the
other entry points compile the engine again each (about a minute of CPU apiece) and are marked slow:
``pytest -m slow tests/test_cold_start.py``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

BOUND = 1800  # seconds for one cold program: a cold compile takes 1-3 minutes on a loaded 2-core machine

# Prints the qualified names of the project's kernels compiled while ``body`` ran, as JSON on the last line.
_RECORDER = """
from numba.core import event as _event
_compiled = _event.RecordingListener()
_event.register("numba:compile", _compiled)


def _report():
    import json
    names = sorted({ev.data["dispatcher"].py_func.__qualname__ for _, ev in _compiled.buffer
                    if ev.is_start and ev.data["dispatcher"].py_func.__module__.startswith("smac_hard_gym")})
    print(json.dumps(names))
"""

_SUBPROC = """
import sys

import numpy as np
import numba

from smac_hard_gym.envs.subproc import make_subproc_env

if __name__ == "__main__":
    numba.set_num_threads(1)  # the parent's pool is running before any worker starts
    with make_subproc_env("3m", 1, 2, start_method=sys.argv[1]) as env:  # one worker compiles: enough to fail
        env.reset(seed=0)
        for _ in range(3):
            env.step(np.ones((2, 3), dtype=np.int64))
    print("ok")
"""

_SECOND_PROCESS = """
import gymnasium as gym
import numpy as np

import smac_hard_gym
from smac_hard_gym import StarCraft2Env
from smac_hard_gym.envs.vector import NativeVectorEnv

env = gym.make("SMACHard-3m-v0")
env.reset(seed=0)
env.step(np.ones(3, dtype=np.int64))
vec = NativeVectorEnv("3m", num_envs=4)
vec.reset(seed=0)
vec.step(np.ones((4, 3), dtype=np.int64))
_report()
"""

# The other entry points, each on its own empty cache (slow).
_ENTRY_POINTS = {
    "gymnasium": """
import gymnasium as gym
import numpy as np
import smac_hard_gym
env = gym.make("SMACHard-3m-v0")
env.reset(seed=0)
env.step(np.ones(3, dtype=np.int64))
print("ok")
""",
    "starcraft2env": """
from smac_hard_gym import StarCraft2Env
env = StarCraft2Env(map_name="3m")
env.reset()
env.get_avail_agent_actions(0)
env.step([1, 1, 1])
env.get_state()
print("ok")
""",
    "pettingzoo": """
from smac_hard_gym.pettingzoo import parallel_env
env = parallel_env("3m")
env.reset(seed=0)
env.step({agent: 1 for agent in env.agents})
print("ok")
""",
    "native-big-batch": """
import numpy as np
from smac_hard_gym.envs.vector import NativeVectorEnv
env = NativeVectorEnv("3m", num_envs=4096)  # big batches take the engine's parallel driver
env.reset(seed=0)
env.step(np.ones((4096, 3), dtype=np.int64))
print("ok")
""",
    "subproc-spawn": _SUBPROC,
    "ray": """
import numpy as np
from smac_hard_gym.wrappers import make_ray_vec

if __name__ == "__main__":
    import ray
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    env = make_ray_vec("3m", 2, 1)
    env.reset(seed=0)
    env.step(np.ones((2, 3), dtype=np.int64))
    env.close()
    ray.shutdown()
    print("ok")
""",
}


def _run(tmp_path: Path, name: str, source: str, cache: Path, *args: str) -> subprocess.CompletedProcess:
    program = tmp_path / f"entry_{name.replace('-', '_')}.py"  # gymnasium.py or ray.py would shadow the package
    program.write_text(textwrap.dedent(_RECORDER + source))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "NUMBA_NUM_THREADS": "2"}
    return subprocess.run([sys.executable, str(program), *args], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=BOUND)


def _assert_ran(result: subprocess.CompletedProcess) -> None:
    assert result.returncode == 0, result.stderr[-4000:]
    assert result.stdout.strip().splitlines()[-1] in ("ok", "[]"), result.stdout[-2000:]


@pytest.mark.long  # compiles every kernel from empty in worker processes: 213 s at load 8 on 2 cores
def test_subproc_env_starts_on_an_empty_cache_and_a_second_process_compiles_nothing(tmp_path):
    cache = tmp_path / "numba-cache"
    cold = _run(tmp_path, "subproc", _SUBPROC, cache, "forkserver")
    _assert_ran(cold)
    assert any(cache.rglob("*.nbi")), "the workers compiled but wrote nothing to the cache"
    second = _run(tmp_path, "second", _SECOND_PROCESS, cache)
    assert second.returncode == 0, second.stderr[-4000:]
    assert json.loads(second.stdout.strip().splitlines()[-1]) == []


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(_ENTRY_POINTS))
def test_entry_point_runs_on_an_empty_cache(tmp_path, name):
    if name == "ray":
        pytest.importorskip("ray")
    if name == "pettingzoo":
        pytest.importorskip("pettingzoo")
    args = ("spawn",) if name == "subproc-spawn" else ()
    _assert_ran(_run(tmp_path, name, _ENTRY_POINTS[name], tmp_path / "numba-cache", *args))
