"""numba's on-disk cache for what ``smac-hard-gym train`` runs: its 64-battle training env and 16-battle evaluation env
on one engine thread. A first process compiles the kernels; a second one compiles nothing, and neither does a first
run on another map (no kernel is compiled per map); ``kernels_cached()`` says False on an empty cache and True once
a run has filled it, before anything is compiled in the asking process.

Each program runs in a new interpreter with ``NUMBA_CACHE_DIR`` pointing at a folder of this test's own (see
``tests/test_cold_start.py``, which covers the other entry points at 4 battles). The cold program compiles about
30 s of CPU (``benchmarks/compile_time.py``); the warm ones take a few seconds each. Marked slow to keep the default
run near ten minutes: ``pytest -m slow tests/test_kernel_cache.py``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

BOUND = 1800  # seconds for one cold program: minutes on a loaded 2-core machine

# Steps the envs train steps, as train does (one numba thread), and prints, as JSON on the last line: what
# missing_kernels() said before anything ran, and the project's kernels compiled while it ran.
_PROGRAM = """
import json
import sys

import numba
import numpy as np
from numba.core import event

from smac_hard_gym.kernel_cache import kernels_cached, missing_kernels

compiled = event.RecordingListener()
event.register("numba:compile", compiled)
before = {"cached": kernels_cached(), "missing": missing_kernels()}

from smac_hard_gym.envs.vector import NativeVectorEnv

numba.set_num_threads(1)  # train's --env-threads 1
map_name = sys.argv[1]
rng = np.random.default_rng(0)
for num_envs in (64, 16):  # the training env, then the evaluation env
    env = NativeVectorEnv(map_name, num_envs, autoreset_mode="SameStep")
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        masks = env.action_masks().reshape(num_envs, env.view.n_agents, -1)
        actions = np.argmax(np.where(masks, rng.random(masks.shape), -1.0), axis=2)
        obs, reward, terminated, truncated, infos = env.step(actions)
    assert np.isfinite(obs).all() and infos["action_mask"].shape == (num_envs, masks.shape[1] * masks.shape[2])
    env.close()
names = sorted({ev.data["dispatcher"].py_func.__qualname__ for _, ev in compiled.buffer
                if ev.is_start and ev.data["dispatcher"].py_func.__module__.startswith("smac_hard_gym")})
print(json.dumps({**before, "compiled": names, "cached_after": kernels_cached()}))
"""


def _run(tmp_path: Path, cache: Path, map_name: str) -> dict:
    program = tmp_path / "program.py"
    program.write_text(textwrap.dedent(_PROGRAM))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "NUMBA_NUM_THREADS": "2"}
    result = subprocess.run([sys.executable, str(program), map_name], cwd=tmp_path, env=env, capture_output=True,
                            text=True, timeout=BOUND)
    assert result.returncode == 0, result.stderr[-4000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


@pytest.mark.slow  # three fresh processes, one compiling from empty (~40 s CPU); the default run keeps
# tests/test_cold_start.py's second-process check
def test_train_envs_compile_once_for_every_map_and_kernels_cached_says_so(tmp_path):
    cache = tmp_path / "numba-cache"
    cold = _run(tmp_path, cache, "3m")
    assert cold["cached"] is False
    # What the cold run compiled is what kernels_cached() checks (the engine's serial step kernel, the vector env's
    # feature kernels, the terrain's path tables, the battle resets), and nothing more.
    assert set(cold["missing"]) == {"step_battles", "encode_batch", "finish_encode", "check_decode_batch",
                                    "terrain", "batch_ops"}
    assert {"step_battles", "encode_batch", "finish_encode", "check_decode_batch"} <= set(cold["compiled"])
    assert "step_batch" not in cold["compiled"]  # one engine thread: the parallel driver is never compiled
    assert cold["cached_after"] is True

    second = _run(tmp_path, cache, "3m")
    assert second["cached"] is True and second["missing"] == []
    assert second["compiled"] == []

    other_map = _run(tmp_path, cache, "8m")  # a first run on another map
    assert other_map["cached"] is True
    assert other_map["compiled"] == []
