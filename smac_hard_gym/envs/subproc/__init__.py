"""``SubprocVectorEnv``: battles spread over worker processes, each owning a batch of K battles of any backend.

Each worker builds its own vector env from a factory (cloudpickled, so lambdas work under every start method): a
:class:`~smac_hard_gym.envs.vector.NativeVectorEnv` of K battles, StarCraft II instances (``backend="sc2"``), or any
gymnasium env (run as a batch of one). Observations and action masks come back through shared memory; rewards,
flags and infos through a pipe.

Two layers keep the worker protocol free of pipe specifics (a Ray actor can wrap :class:`BatchWorker` as it is):

- :class:`BatchWorker` (``worker.py``): build from a factory, ``describe()``, ``reset(seed, options)``,
  ``step(actions)``, ``call(name, ...)``; plain arrays in, plain arrays out.
- the pipe loop (``worker.worker_main``, with the message protocol) and :class:`SubprocVectorEnv` (``env.py``):
  messages, shared memory (``shared_memory.py``), timeouts, restarts; ``batch.py`` joins the workers' parts.

A worker that dies, or does not answer within ``timeout`` seconds, is killed and then either rebuilt
(``on_worker_error="restart"``: its battles report ``truncated=True`` with ``infos["worker_restarted"]``) or reported
(``"raise"``: :class:`WorkerError`, after closing every worker). Workers never outlive the parent: they die with it
(``PR_SET_PDEATHSIG`` on Linux, and a closed pipe everywhere), and ``close()`` joins, then kills, each one.

>>> from smac_hard_gym.envs.subproc import make_subproc_env
>>> envs = make_subproc_env("3m", num_workers=2, envs_per_worker=4, autoreset_mode="SameStep")
>>> obs, infos = envs.reset(seed=0)
>>> obs.shape
(8, 90)
>>> envs.close()
"""

from __future__ import annotations

from smac_hard_gym.envs.subproc.batch import concat_infos
from smac_hard_gym.envs.subproc.env import (
    COLD_START_TIMEOUT,
    ON_WORKER_ERROR,
    RESTART_KEY,
    START_METHODS,
    WARM_START_TIMEOUT,
    SubprocVectorEnv,
    WorkerError,
    make_subproc_env,
)
from smac_hard_gym.envs.subproc.shared_memory import MASK_KEY
from smac_hard_gym.envs.subproc.worker import BatchWorker

__all__ = ["SubprocVectorEnv", "BatchWorker", "WorkerError", "make_subproc_env", "concat_infos",
           "ON_WORKER_ERROR", "START_METHODS", "COLD_START_TIMEOUT", "WARM_START_TIMEOUT", "MASK_KEY", "RESTART_KEY"]
