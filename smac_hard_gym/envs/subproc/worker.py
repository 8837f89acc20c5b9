"""The child side of :class:`~smac_hard_gym.envs.subproc.SubprocVectorEnv`: :class:`BatchWorker` and the process
loop that serves it over a pipe.

The message protocol (every message is a tuple, sent with ``Connection.send``):

- parent to worker: ``(command, payload)`` with
    ``("attach", (block_name, layout, start, stop))``: write rows ``start:stop`` of that shared block from now on;
    ``("reset", (seed, options))``; ``("step", (actions, checked))`` (``checked``: the parent validated the
    actions, see ``BatchWorker.step``); ``("call", (name, args, kwargs))``; ``("close", None)``.
- worker to parent: ``("ok", value)`` or ``("error", (pickled_exception_or_None, traceback_text))``; one answer per
  command (none to ``close``), and a first one when the worker starts: ``describe()``, or the error that stopped it
  building its env. ``reset`` answers ``(obs_or_None, infos)``, ``step`` answers ``(obs_or_None, rewards,
  terminated, truncated, infos)``: observations and action masks that fit in the shared block are written there
  and left out of the message.
"""

from __future__ import annotations

import functools
import os
import sys
import traceback
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

import cloudpickle
import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, SyncVectorEnv, VectorEnv

from smac_hard_gym.engine.direct import is_plain
from smac_hard_gym.envs.autoreset import AUTORESET_NAMES
from smac_hard_gym.envs.subproc.safe_pickle import safe_loads
from smac_hard_gym.envs.subproc.shared_memory import SharedBlock, write_masks, write_obs
from smac_hard_gym.lifetime import die_with_parent

__all__ = ["BatchWorker", "Server", "worker_main", "pack_error", "unpack_error", "limit_threads"]

_ORPHAN_POLL = 1.0  # seconds between checks that the parent is still there
_INT64 = np.dtype(np.int64)


class BatchWorker:
    """Owns one vector env built from ``factory`` and steps it: the part of a worker that any transport can host.

    ``factory()`` returns a gymnasium ``VectorEnv`` (used as it is) or a single ``gymnasium.Env`` (run as a
    ``SyncVectorEnv`` of one, with ``autoreset_mode``).
    """

    def __init__(self, factory: Callable[[], Any], autoreset_mode: AutoresetMode | None = None) -> None:
        env = factory()
        if isinstance(env, gym.Env):
            env = SyncVectorEnv([functools.partial(_identity, env)],
                                autoreset_mode=autoreset_mode or AutoresetMode.NEXT_STEP)
        if not isinstance(env, VectorEnv):
            raise TypeError(f"a worker factory must return a gymnasium VectorEnv or Env, got {type(env).__name__}")
        self.env = env
        from smac_hard_gym.envs.vector import NativeVectorEnv

        self._takes_checked = isinstance(env, NativeVectorEnv)  # its step can skip validating (``step``)

    def describe(self) -> dict[str, Any]:
        """Sizes, spaces and modes of this worker's batch."""
        env = self.env
        mode = env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
        return {
            "num_envs": env.num_envs, "single_observation_space": env.single_observation_space,
            "single_action_space": env.single_action_space, "autoreset_mode": AUTORESET_NAMES.get(mode, mode),
            "render_mode": getattr(env, "render_mode", None), "mask_size": _mask_size(env),
            "invalid_action": getattr(env, "invalid_action", None),
        }

    def reset(self, seed: Any = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        return self.env.reset(seed=seed, options=options)

    def step(self, actions: np.ndarray, checked: bool = False
             ) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step the batch. ``checked``: ``actions`` is what :func:`~smac_hard_gym.smac.actions.validate_actions`
        returned for this batch's shape and action count (the parent validated them), so a
        :class:`~smac_hard_gym.envs.vector.NativeVectorEnv` does not validate them again; other envs check their
        actions as they always do, and so does it when they arrive read-only (a transport's zero-copy buffer: the
        core writes replacements into the array it is given, and validation copies)."""
        if checked and self._takes_checked and is_plain(actions, _INT64, 2):
            return self.env.step(actions, checked=True)
        return self.env.step(actions)

    def call(self, name: str, *args: Any, **kwargs: Any) -> Any:
        """Call method ``name`` of the batch env (or read the attribute when it is not callable)."""
        if hasattr(self.env, name):
            value = getattr(self.env, name)
        elif hasattr(self.env, "call"):
            return self.env.call(name, *args, **kwargs)
        else:
            raise AttributeError(f"{type(self.env).__name__} has no attribute {name!r}")
        return value(*args, **kwargs) if callable(value) else value

    def close(self) -> None:
        self.env.close()


def _identity(env: Any) -> Any:
    return env


def _mask_size(env: VectorEnv) -> int | None:
    """Length of one env's flat action mask, when the batch env gives masks."""
    if hasattr(env, "action_masks"):
        return int(np.prod(np.asarray(env.action_masks()).shape[1:]))
    space = env.single_action_space
    if isinstance(space, spaces.MultiDiscrete):
        return int(space.nvec.sum())
    if isinstance(space, spaces.Discrete):
        return int(space.n)
    return None


# ---------------------------------------------------------------------------------------------------------------
# Errors across the pipe.


def pack_error(err: BaseException) -> tuple[bytes | None, str]:
    """An exception as ``(cloudpickled exception or None, traceback text)``."""
    text = "".join(traceback.format_exception(type(err), err, err.__traceback__))
    try:
        return cloudpickle.dumps(err), text
    except Exception:  # an exception that does not pickle still travels as text
        return None, text


def unpack_error(value: tuple[bytes | None, str], index: int, where: str = "SubprocVectorEnv worker") -> BaseException:
    """The exception :func:`pack_error` packed in worker ``index``, with the worker's traceback as a note."""
    blob, text = value
    err: BaseException | None = None
    if blob is not None:
        try:
            err = safe_loads(blob)  # an exception of a class outside the allow-list travels as text
        except Exception:
            err = None
        if not isinstance(err, BaseException):
            err = None
    if err is None:
        err = RuntimeError(text.strip().splitlines()[-1] if text.strip() else "unknown error")
    if hasattr(err, "add_note"):
        err.add_note(f"(raised in {where} {index}; its traceback:)\n{text}")
    return err


# ---------------------------------------------------------------------------------------------------------------
# The worker process.


def limit_threads(threads: int) -> None:
    """One worker per core is the point: keep numba and BLAS from starting a thread per core in each worker.

    Before numba is imported, ``NUMBA_NUM_THREADS`` sizes its pool. Once it is imported (a forkserver that preloaded
    the main module, a forked parent), the variable must keep the value numba read: every compile re-reads the
    environment, and a changed pool size after the pool started is an error ("Cannot set NUMBA_NUM_THREADS to a
    different value once the threads have been launched"), which is how a worker on an empty cache used to fail.
    ``numba.set_num_threads`` limits the threads used instead.
    """
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = str(threads)
    numba = sys.modules.get("numba")
    if numba is None:
        os.environ["NUMBA_NUM_THREADS"] = str(threads)
    else:
        os.environ["NUMBA_NUM_THREADS"] = str(numba.config.NUMBA_NUM_THREADS)
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(threads)


class Server:
    """A worker's state between messages: its batch env and the shared rows it writes."""

    def __init__(self, worker: BatchWorker) -> None:
        self.worker = worker
        self.block: SharedBlock | None = None
        self.start = self.stop = 0

    def handle(self, command: str, payload: Any) -> Any:
        """The reply to one command (other than ``close``)."""
        if command == "attach":
            name, layout, self.start, self.stop = payload
            self.block = SharedBlock(layout, name)
            return None
        if command == "reset":
            obs, infos = self.worker.reset(*payload)
            return self._obs(obs), self._infos(infos)
        if command == "step":
            obs, rewards, terminated, truncated, infos = self.worker.step(*payload)
            return (self._obs(obs), np.asarray(rewards), np.asarray(terminated), np.asarray(truncated),
                    self._infos(infos))
        if command == "call":
            name, args, kwargs = payload
            return self.worker.call(name, *args, **kwargs)
        raise ValueError(f"unknown worker command {command!r}")

    def answer(self, command: str, payload: Any) -> tuple[str, Any]:
        """The message that answers one command: ``("ok", reply)``, or ``("error", packed)`` for an env error (the
        worker keeps serving). Shared by the pipe loop and Ray actors."""
        try:
            return "ok", self.handle(command, payload)
        except Exception as err:  # an env error: report it, keep serving
            return "error", pack_error(err)

    def _obs(self, obs: Any) -> Any:
        return write_obs(self.block, obs, self.start, self.stop)

    def _infos(self, infos: dict[str, Any]) -> dict[str, Any]:
        return write_masks(self.block, infos, self.start, self.stop)

    def close(self) -> None:
        try:
            self.worker.close()
        finally:
            if self.block is not None:
                self.block.close()


def _build(conn: Connection, factory_bytes: bytes, autoreset_mode: Any) -> BatchWorker | None:
    """Build the worker's env and send the first answer: its description, or the error (then None)."""
    try:
        worker = BatchWorker(cloudpickle.loads(factory_bytes), autoreset_mode)
        conn.send(("ok", worker.describe()))
    except BaseException as err:  # noqa: BLE001 - the parent reports it
        conn.send(("error", pack_error(err)))
        return None
    return worker


def _serve(conn: Connection, server: Server, parent: int) -> None:
    """Answer commands until ``close``, a closed pipe, or the parent's death."""
    while True:
        if not conn.poll(_ORPHAN_POLL):
            if os.getppid() != parent:  # orphaned: the parent died without closing the pipe
                return
            continue
        command, payload = conn.recv()
        if command == "close":
            return
        conn.send(server.answer(command, payload))


def worker_main(conn: Connection, parent_end: Connection, factory_bytes: bytes, autoreset_mode: Any,
                threads: int) -> None:
    """A worker process's body: build the env from the cloudpickled factory, then serve the parent's commands."""
    parent_end.close()
    die_with_parent()
    limit_threads(threads)
    parent = os.getppid()
    worker = _build(conn, factory_bytes, autoreset_mode)
    if worker is None:
        return
    server = Server(worker)
    try:
        _serve(conn, server, parent)
    except (EOFError, BrokenPipeError, KeyboardInterrupt):
        pass
    finally:
        server.close()
