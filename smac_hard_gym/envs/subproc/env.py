"""The parent side of the subprocess vector env: :class:`SubprocVectorEnv`, its handle on each worker process
(:class:`_Worker`), and :func:`make_subproc_env`."""

from __future__ import annotations

import functools
import multiprocessing as mp
import time
from collections.abc import Callable, Sequence
from multiprocessing import resource_tracker
from multiprocessing.connection import Connection, wait
from typing import Any

import cloudpickle
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from smac_hard_gym.envs.autoreset import parse_autoreset_mode
from smac_hard_gym.envs.subproc.batch import compact_seed, concat_infos, concat_obs, obs_row, split_seed
from smac_hard_gym.envs.subproc.safe_pickle import safe_loads
from smac_hard_gym.envs.subproc.shared_memory import MASK_KEY, SharedBlock, block_layout, read_obs
from smac_hard_gym.envs.subproc.worker import unpack_error, worker_main
from smac_hard_gym.smac.actions import InvalidActionError, ResetNeededError, validate_actions

__all__ = ["SubprocVectorEnv", "WorkerError", "make_subproc_env", "ON_WORKER_ERROR", "START_METHODS",
           "COLD_START_TIMEOUT", "WARM_START_TIMEOUT", "RESTART_KEY"]

ON_WORKER_ERROR = ("raise", "restart")
START_METHODS = tuple(mp.get_all_start_methods())
RESTART_KEY = "worker_restarted"
COLD_START_TIMEOUT = 600.0  # seconds for a worker's first answer when it must compile the engine's kernels
WARM_START_TIMEOUT = 120.0  # ... when numba's cache holds them (a hang before the first answer is caught sooner)
_AGREED_KEYS = ("single_observation_space", "single_action_space", "autoreset_mode", "mask_size", "invalid_action")


class WorkerError(RuntimeError):
    """A worker process died, hung past the timeout, or could not be built."""


class _Worker:
    """The parent's handle on one worker process."""

    def __init__(self, index: int, factory_bytes: bytes) -> None:
        self.index = index
        self.factory_bytes = factory_bytes
        self.process: Any = None
        self.conn: Connection | None = None
        self.start = self.stop = 0
        self.needs_reset = False  # NEXT_STEP: rebuilt after a failure, starts its next episode on the next step
        self.last_obs: Any = None  # its rows of the latest observations
        self.failures = 0  # failures since its last successful step
        self.warm = False  # has answered a step: from then on `timeout` applies, before it `start_timeout`

    @property
    def size(self) -> int:
        return self.stop - self.start

    @property
    def rows(self) -> slice:
        return slice(self.start, self.stop)


class SubprocVectorEnv(VectorEnv):
    """Battles in worker processes: each of ``len(factories)`` workers builds a batch env from its factory.

    Arguments
        ``factories``: one callable per worker, returning a gymnasium ``VectorEnv`` of K battles (e.g.
        ``functools.partial(NativeVectorEnv, "3m", num_envs=4, autoreset_mode="SameStep")``) or a single
        ``gymnasium.Env``. Workers may own different numbers of battles; they must agree on spaces and autoreset
        mode. ``autoreset_mode``: required to match the workers' (and used for single-env factories); None takes
        theirs. ``start_method``: ``"forkserver"`` (default where available), ``"spawn"`` or ``"fork"`` (fast,
        but unsafe once the parent runs threads: torch, numba). ``timeout``: seconds a worker may take to answer
        a reset or step before it counts as hung; ``start_timeout``: seconds to build, and to answer until its
        first step; by default 600 when numba's cache does not hold the engine yet (the first use compiles it, tens of
        seconds per worker on a busy machine), else 120 (enough to launch StarCraft II for the sc2 backend).
        ``on_worker_error``: ``"raise"`` or ``"restart"``; ``max_failures``: a worker that fails more often than
        this without a good step in between raises :class:`WorkerError` even under ``"restart"`` (a worker that can
        never run is not restarted forever). ``worker_threads``: numba/BLAS threads per worker.

    Battle ``i`` of the batch is battle ``i - start`` of the worker owning rows ``start..stop-1``; ``reset(seed=s)``
    gives it the seed ``s + i``, so a subprocess batch reproduces a native batch of the same size.
    """

    def __init__(self, factories: Sequence[Callable[[], Any]], *,
                 autoreset_mode: AutoresetMode | str | None = None, start_method: str | None = None,
                 timeout: float = 60.0, start_timeout: float | None = None, on_worker_error: str = "raise",
                 max_failures: int = 3, worker_threads: int = 1) -> None:
        start_method = _checked_start_method(start_method)
        factories = self._settings(factories, autoreset_mode, timeout, start_timeout, on_worker_error, max_failures,
                                   worker_threads)
        self.start_method = start_method
        self._ctx = _context(start_method)
        # Workers must share the parent's resource tracker: one of their own would unlink the shared memory when
        # its worker exits (a forked worker starts its own unless the parent's already runs).
        resource_tracker.ensure_running()
        try:
            self._start_workers(factories)
        except BaseException:
            self.close()
            raise

    # -----------------------------------------------------------------------------------------------------------
    # Setup.

    _worker_type: type[_Worker] = _Worker  # the parent's handle on one worker (a transport may extend it)

    def _settings(self, factories: Sequence[Callable[[], Any]], autoreset_mode: AutoresetMode | str | None,
                  timeout: float, start_timeout: float | None, on_worker_error: str, max_failures: int,
                  worker_threads: int) -> list[Callable[[], Any]]:
        """Check the arguments every transport shares and keep them; returns the factories as a list."""
        factories = list(factories)
        if not factories or not all(callable(f) for f in factories):
            raise ValueError(f"factories must be a non-empty list of callables, got {factories!r}")
        if on_worker_error not in ON_WORKER_ERROR:
            raise ValueError(f"on_worker_error must be one of {ON_WORKER_ERROR}, got {on_worker_error!r}")
        if start_timeout is None:
            start_timeout = _default_start_timeout()
        for name, value in (("timeout", timeout), ("start_timeout", start_timeout)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise ValueError(f"{name} must be a positive number of seconds, got {value!r}")
        self._workers: list[_Worker] = []
        self._block: SharedBlock | None = None
        self.timeout = float(timeout)
        self.start_timeout = float(start_timeout)
        self.on_worker_error = on_worker_error
        self.max_failures = int(max_failures)
        self.worker_threads = int(worker_threads)
        self._requested_mode = None if autoreset_mode is None else parse_autoreset_mode(autoreset_mode)
        self.restarts = 0
        return factories

    def _start_workers(self, factories: list[Callable[[], Any]]) -> None:
        """Launch every worker, wait for their descriptions, lay out the batch, and attach the shared memory."""
        self._workers = [self._worker_type(i, cloudpickle.dumps(f)) for i, f in enumerate(factories)]
        for worker in self._workers:
            self._launch(worker)
        descriptions = [self._receive_start(w) for w in self._workers]
        self._configure(descriptions)
        for worker in self._workers:
            self._attach(worker)

    def _configure(self, descriptions: list[dict[str, Any]]) -> None:
        """The batch's sizes, spaces and modes from the workers' descriptions, and its shared memory."""
        mode = self._agreed_mode(descriptions)
        first = descriptions[0]
        self.num_envs = self._assign_rows(descriptions)
        self.autoreset_mode = mode
        self.render_mode = first["render_mode"]
        self.metadata = {"autoreset_mode": mode, "render_modes": [] if self.render_mode is None else
                         [self.render_mode]}
        self.single_observation_space = first["single_observation_space"]
        self.single_action_space = first["single_action_space"]
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.mask_size = first["mask_size"]
        self.invalid_action = first["invalid_action"]  # the workers' policy for unavailable actions, if they say
        self._needs_reset = True  # until the first reset()
        self._ended = np.zeros(self.num_envs, dtype=bool)  # episodes that ended on the last step
        self._block = self._new_block()
        self._masks = np.ones((self.num_envs, self.mask_size or 0), dtype=bool)
        self._masks_seen = False

    def _new_block(self) -> SharedBlock | None:
        """The shared memory the workers write observations and masks into (a transport without it returns None)."""
        return SharedBlock(block_layout(self.single_observation_space, self.num_envs, self.mask_size))

    def _agreed_mode(self, descriptions: list[dict[str, Any]]) -> AutoresetMode:
        """The workers' common autoreset mode; raises when they differ, or differ from the one asked for."""
        first = descriptions[0]
        for w, desc in enumerate(descriptions[1:], start=1):
            for key in _AGREED_KEYS:
                if desc[key] != first[key]:
                    raise ValueError(f"worker {w} differs from worker 0 in {key}: {desc[key]!r} != {first[key]!r}")
        mode = first["autoreset_mode"]
        if self._requested_mode is not None and mode != self._requested_mode:
            raise ValueError(f"the workers' envs autoreset in mode {mode.value!r} but autoreset_mode="
                             f"{self._requested_mode.value!r} was asked; build them with that mode")
        return mode

    def _assign_rows(self, descriptions: list[dict[str, Any]]) -> int:
        """Give each worker its consecutive rows of the batch; returns the batch size."""
        start = 0
        for worker, desc in zip(self._workers, descriptions, strict=True):
            worker.start, worker.stop = start, start + desc["num_envs"]
            start = worker.stop
        return start

    def _launch(self, worker: _Worker) -> None:
        worker.warm = False
        parent_end, child_end = self._ctx.Pipe()
        process = self._ctx.Process(
            target=worker_main, name=f"smac-hard-gym-worker-{worker.index}", daemon=True,
            args=(child_end, parent_end, worker.factory_bytes, self._requested_mode, self.worker_threads))
        process.start()
        child_end.close()
        worker.process, worker.conn = process, parent_end

    def _receive_start(self, worker: _Worker) -> dict[str, Any]:
        ok, value = self._receive(worker, self.start_timeout, "start")
        if not ok:
            raise WorkerError(f"worker {worker.index} failed to build its env: {_first_line(value)}\n{value}")
        return value

    def _attach(self, worker: _Worker) -> None:
        self._send(worker, "attach", (self._block.name, self._block.layout, worker.start, worker.stop))
        ok, value = self._receive(worker, self.timeout, "attach")
        if not ok:
            raise WorkerError(f"worker {worker.index} could not attach the shared memory: {value}")

    # -----------------------------------------------------------------------------------------------------------
    # Messages.

    def _send(self, worker: _Worker, command: str, payload: Any = None) -> bool:
        try:
            worker.conn.send((command, payload))
            return True
        except (BrokenPipeError, ConnectionResetError, OSError):
            return False

    def _receive(self, worker: _Worker, timeout: float, what: str) -> tuple[bool, Any]:
        """``(True, reply)``, or ``(False, why)`` when the worker died or hung; env errors are raised."""
        replies = self._gather([worker], timeout, what)
        return replies[worker.index]

    def _gather(self, workers: list[_Worker], timeout: float, what: str) -> dict[int, tuple[bool, Any]]:
        """Wait for one reply from each worker. Failures map to ``(False, why)``; env errors are raised once every
        worker has answered (so the protocol stays in step)."""
        if what in ("reset", "step") and not all(w.warm for w in workers):
            timeout = max(timeout, self.start_timeout)  # a new worker's first calls may compile the engine
        deadline = time.monotonic() + timeout
        pending = {w.conn: w for w in workers}
        sentinels = {w.process.sentinel: w for w in workers}
        results: dict[int, tuple[bool, Any]] = {}
        env_error: BaseException | None = None
        while pending:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                for worker in pending.values():
                    results[worker.index] = (False, f"no answer to {what} within {timeout:g} s (hung)")
                break
            ready = wait(list(pending) + [s for s, w in sentinels.items() if w.conn in pending], remaining)
            for item in ready:
                worker = pending.get(item) or sentinels.get(item)
                if worker is None or worker.conn not in pending:
                    continue
                status, value = _read_message(worker, item)
                del pending[worker.conn]
                if status == "error" and what != "start":
                    env_error = env_error or unpack_error(value, worker.index)
                    results[worker.index] = (True, None)
                else:
                    results[worker.index] = _outcome(worker, status, value, what)
        if env_error is not None:
            raise env_error
        return results

    def _fail(self, failures: dict[int, str]) -> None:
        """Deal with workers that died or hung: raise (after closing everything) or rebuild them."""
        if self.on_worker_error == "raise":
            self.close()
            lines = "; ".join(f"worker {w} (battles {self._span(w)}): {why}" for w, why in failures.items())
            raise WorkerError(f"{lines}. The env is closed; use on_worker_error='restart' to rebuild failed "
                              "workers instead")
        for w in failures:
            self._rebuild(self._workers[w], failures[w])

    def _rebuild(self, worker: _Worker, why: str) -> None:
        """Replace a failed worker's process by a new one (attached to the shared memory), unless it failed too
        often; a failure to rebuild closes everything and raises."""
        w = worker.index
        worker.failures += 1
        if worker.failures > self.max_failures:
            self.close()
            raise WorkerError(f"worker {w} (battles {self._span(w)}) failed {worker.failures} times in a row "
                              f"(last: {why}); the env is closed")
        self._stop_process(worker, graceful=False)
        self._launch(worker)
        ok, value = self._receive(worker, self.start_timeout, "start")
        if not ok:
            self.close()
            raise WorkerError(f"worker {w} failed again while restarting: {value}")
        self._attach(worker)
        self.restarts += 1

    def _span(self, w: int) -> str:
        worker = self._workers[w]
        return f"{worker.start}..{worker.stop - 1}"

    # -----------------------------------------------------------------------------------------------------------
    # Gymnasium API.

    def reset(self, *, seed: int | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset every battle (or those of ``options["reset_mask"]``); an int seed gives battle i ``seed + i``."""
        self._check_open()
        seeds = split_seed(seed, self.num_envs)
        options = dict(options or {})
        mask = self._checked_reset_mask(options.pop("reset_mask", None))
        if isinstance(seed, (int, np.integer)):
            super().reset(seed=int(seed))
        chosen = [w for w in self._workers if mask is None or mask[w.rows].any()]
        payloads = {}
        for worker in chosen:
            payloads[worker.index] = self._reset_payload(worker, seeds, options, mask)
            self._send(worker, "reset", payloads[worker.index])
        replies = self._gather(chosen, self.timeout, "reset")
        failures = _failures(replies)
        if failures:
            replies.update(self._reset_rebuilt(failures, payloads))
        for worker in chosen:
            worker.needs_reset = False
        self._needs_reset = False
        self._ended[slice(None) if mask is None else mask] = False
        parts = [self._unpack_reset(w, replies.get(w.index)) for w in self._workers]
        obs = self._observations(parts)  # also restores the masks into each part's infos
        return obs, self._infos(parts)

    def _checked_reset_mask(self, mask: Any) -> np.ndarray | None:
        if mask is not None and (not isinstance(mask, np.ndarray) or mask.dtype != np.bool_
                                 or mask.shape != (self.num_envs,) or not mask.any()):
            raise ValueError(f"options['reset_mask'] must be a bool numpy array of shape ({self.num_envs},) with "
                             f"at least one True, got {mask!r}")
        return mask

    @staticmethod
    def _reset_payload(worker: _Worker, seeds: list[int | None] | None, options: dict[str, Any],
                       mask: np.ndarray | None) -> tuple[Any, dict[str, Any] | None]:
        """A worker's ``(seed, options)``: its battles' seeds, and its rows of the reset mask when not all."""
        part = None if seeds is None else seeds[worker.rows]
        opts = dict(options)
        if mask is not None and not mask[worker.rows].all():
            opts["reset_mask"] = mask[worker.rows].copy()
        return compact_seed(part), opts or None

    def _reset_rebuilt(self, failures: dict[int, str], payloads: dict[int, Any]) -> dict[int, tuple[bool, Any]]:
        """Rebuild the workers that failed a reset and give them the reset they missed; their replies."""
        self._fail(failures)
        for w in failures:  # a rebuilt worker gets the reset it missed
            self._send(self._workers[w], "reset", payloads[w])
        retry = self._gather([self._workers[w] for w in failures], self.timeout, "reset")
        if not all(ok for ok, _ in retry.values()):
            self.close()
            raise WorkerError(f"workers {sorted(failures)} failed again during reset")
        return retry

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every worker's battles. Actions are checked here, before any worker steps, so a rejected step
        (``TypeError`` / ``ValueError``, as the native env raises them) leaves every battle as it was, and the
        error comes without a round trip; the workers' native envs then do not validate them again."""
        self._check_open()
        self._check_steppable()
        actions, checked = self._check_actions(actions)
        for worker in self._workers:
            if worker.needs_reset:
                self._send(worker, "reset", (None, None))
            else:
                self._send(worker, "step", (actions[worker.rows], checked))
        replies = self._gather(self._workers, self.timeout, "step")
        failures = _failures(replies)
        restarted: dict[int, Any] = {}
        if failures:
            self._fail(failures)
            restarted = self._after_restart(failures)
        parts, rewards, terminated, truncated = self._step_parts(replies, restarted)
        for w in failures:
            self._workers[w].needs_reset = self.autoreset_mode == AutoresetMode.NEXT_STEP
        if self.autoreset_mode != AutoresetMode.SAME_STEP:  # SAME_STEP has reset them already
            self._ended = terminated | truncated
        obs = self._observations(parts)  # also restores the masks into each part's infos
        return obs, rewards, terminated, truncated, self._infos(parts)

    def _check_steppable(self) -> None:
        if self._needs_reset:
            raise ResetNeededError("call reset() before step(): no episode has started")
        if self.autoreset_mode == AutoresetMode.DISABLED and self._ended.any():
            raise ResetNeededError(f"battles {np.flatnonzero(self._ended).tolist()} ended and autoreset is "
                                   "disabled; reset them with reset(options={'reset_mask': mask}) before stepping")

    def _step_parts(self, replies: dict[int, tuple[bool, Any]], restarted: dict[int, dict[str, Any]]
                    ) -> tuple[list[dict[str, Any]], np.ndarray, np.ndarray, np.ndarray]:
        """Each worker's part of a step (stepped, reset after last step's rebuild, or just rebuilt), and the
        batch's rewards and end flags."""
        parts = []
        rewards = np.zeros(self.num_envs, dtype=np.float64)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.zeros(self.num_envs, dtype=bool)
        for worker in self._workers:
            rows = worker.rows
            if worker.index in restarted:
                parts.append(restarted[worker.index])
                truncated[rows] = True
            elif worker.needs_reset:  # rebuilt last step: this step starts its new episodes
                parts.append(self._unpack_reset(worker, replies[worker.index]))
                worker.needs_reset = False
            else:
                worker.failures = 0
                obs_part, r, te, tr, info = replies[worker.index][1]
                rewards[rows], terminated[rows], truncated[rows] = r, te, tr
                parts.append({"obs": obs_part, "infos": info})
        return parts, rewards, terminated, truncated

    def _check_actions(self, actions: Any) -> tuple[np.ndarray, bool]:
        """Type, shape and range against the action space; availability against the latest masks when the workers
        raise on unavailable actions (rows whose episode ended last step are reset by it, so not checked). Returns
        the actions and whether they were validated (SMAC-like spaces; the workers' envs check other spaces)."""
        shape = _checked_action_shape(self.single_action_space, self.num_envs)
        if shape is None:
            acts = np.asarray(actions)
            if acts.shape[:1] != (self.num_envs,):
                raise ValueError(f"actions must have one row per battle ({self.num_envs}), got shape {acts.shape}")
            return acts, False
        acts = validate_actions(actions, *shape, "red")
        if self.invalid_action == "raise" and self.mask_size and self._masks_seen:
            self._check_available(acts)
        return acts, True

    def _check_available(self, acts: np.ndarray) -> None:
        """Raise :class:`InvalidActionError` for the first unavailable action of a battle that did not just end."""
        flat = acts.reshape(self.num_envs, -1)
        n_actions = self.mask_size // flat.shape[1]
        masks = self._masks.reshape(self.num_envs, flat.shape[1], n_actions)
        rows, agents = np.indices(flat.shape)
        bad = ~masks[rows, agents, flat] & ~self._ended[:, None]
        if bad.any():
            from smac_hard_gym.envs.gym_env import RAISE_HINT

            b, i = (int(v) for v in np.argwhere(bad)[0])
            legal = np.flatnonzero(masks[b, i]).tolist()
            raise InvalidActionError(f"battle {b}, red agent {i}: action {int(flat[b, i])} is not available; "
                                     f"available: {legal}{RAISE_HINT}")

    def _after_restart(self, failures: dict[int, str]) -> dict[int, dict[str, Any]]:
        """What the rebuilt workers report this step: their episodes end as truncated, flagged in the infos.

        SAME_STEP: the new episode's first observation, the last one seen in ``final_obs``. NEXT_STEP and DISABLED:
        the last observation seen (the new episode starts on the next step, or at the user's reset).
        """
        out = {}
        for w in failures:
            worker = self._workers[w]
            n = worker.size
            flag = {RESTART_KEY: np.ones(n, dtype=bool), f"_{RESTART_KEY}": np.ones(n, dtype=bool)}
            if self.autoreset_mode == AutoresetMode.SAME_STEP:
                out[w] = self._restarted_same_step(worker, flag)
            else:
                if self.autoreset_mode == AutoresetMode.DISABLED:
                    self._reset_restarted(worker)
                out[w] = {"obs": worker.last_obs, "infos": dict(flag), "restored": True}
        return out

    def _restarted_same_step(self, worker: _Worker, flag: dict[str, np.ndarray]) -> dict[str, Any]:
        """A rebuilt worker's part under SAME_STEP: reset now, its last observations in ``final_obs``."""
        n, last = worker.size, worker.last_obs
        part = self._unpack_reset(worker, (True, self._reset_restarted(worker)))
        final_obs = np.full(n, None, dtype=object)
        for i in range(n):
            final_obs[i] = obs_row(last, i)
        part["infos"] = {**part["infos"], **flag, "final_obs": final_obs, "_final_obs": np.ones(n, bool),
                         "final_info": dict(flag), "_final_info": np.ones(n, dtype=bool)}
        return part

    def _reset_restarted(self, worker: _Worker) -> Any:
        """Reset a rebuilt worker's battles and return its reply; a second failure closes everything and raises."""
        self._send(worker, "reset", (None, None))
        ok, reply = self._receive(worker, self.timeout, "reset")
        if not ok:
            self.close()
            raise WorkerError(f"worker {worker.index} failed again after its restart: {reply}")
        return reply

    def action_masks(self) -> np.ndarray:
        """bool ``(num_envs, mask_size)``: legal actions of the latest observations (kept from the infos)."""
        if not self.mask_size or not self._masks_seen:
            raise AttributeError("the workers' envs give no action masks (no info['action_mask'])")
        return self._masks.copy()

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call ``name`` on every worker's batch env; one result per worker."""
        self._check_open()
        for worker in self._workers:
            self._send(worker, "call", (name, args, kwargs))
        replies = self._gather(self._workers, self.timeout, f"call {name!r}")
        failures = _failures(replies)
        if failures:
            self._fail(failures)
            raise WorkerError(f"workers {sorted(failures)} failed during call {name!r} and were rebuilt")
        return tuple(replies[w.index][1] for w in self._workers)

    def render(self) -> tuple[Any, ...]:
        """Each worker's ``render()`` result."""
        return self.call("render")

    def close_extras(self, **kwargs: Any) -> None:
        for worker in self._workers:
            if worker.process is not None and worker.process.is_alive():
                self._send(worker, "close")
        for worker in self._workers:
            self._stop_process(worker, graceful=True)
        if self._block is not None:
            self._block.close()
            self._block = None

    def close(self, **kwargs: Any) -> None:
        """Stop every worker (asking first, then killing) and free the shared memory. Idempotent."""
        if self.closed:
            return
        self.close_extras(**kwargs)
        self.closed = True

    def __enter__(self) -> SubprocVectorEnv:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass

    def __repr__(self) -> str:
        sizes = [w.size for w in self._workers]
        mode = getattr(self, "autoreset_mode", None)
        return (f"SubprocVectorEnv(num_envs={getattr(self, 'num_envs', '?')}, workers={sizes}, "
                f"start_method={self.start_method!r}, autoreset_mode={getattr(mode, 'value', None)})")

    @property
    def processes(self) -> list[Any]:
        """The live worker processes (for monitoring; do not stop them by hand)."""
        return [w.process for w in self._workers if w.process is not None]

    # -----------------------------------------------------------------------------------------------------------
    # Helpers.

    def _check_open(self) -> None:
        if self.closed:
            raise RuntimeError("this SubprocVectorEnv is closed")

    def _stop_process(self, worker: _Worker, graceful: bool) -> None:
        process = worker.process
        if process is None:
            return
        if graceful:
            process.join(2.0)
        if process.is_alive():
            process.kill()
            process.join(5.0)
        if worker.conn is not None:
            worker.conn.close()
        worker.process = worker.conn = None

    def _unpack_reset(self, worker: _Worker, reply: tuple[bool, Any] | None) -> dict[str, Any]:
        if reply is None:  # not reset this time: its rows keep their observations, no infos
            return {"obs": None, "infos": {}, "restored": True}
        obs_part, infos = reply[1]
        return {"obs": obs_part, "infos": infos}

    def _infos(self, parts: list[dict[str, Any]]) -> dict[str, Any]:
        return concat_infos([p["infos"] for p in parts], [w.size for w in self._workers])

    def _observations(self, parts: list[dict[str, Any]]) -> Any:
        """The batch's observations: each worker's rows from shared memory, from the pipe, or kept from before."""
        for worker, part in zip(self._workers, parts, strict=True):
            self._restore_masks(worker, part["infos"])
        if "obs" in self._block.arrays and not any(p.get("restored") or p.get("obs") is not None for p in parts):
            # The usual step: every worker wrote its rows into shared memory, so one copy reads them all.
            obs = self._block.arrays["obs"][:self.num_envs].copy()
            for worker in self._workers:
                worker.last_obs = obs[worker.rows]
            return obs
        rows = []
        for worker, part in zip(self._workers, parts, strict=True):
            if part.get("restored"):
                obs = worker.last_obs
            elif part.get("obs") is not None:
                obs = part["obs"]
            else:
                obs = read_obs(self._block, worker.start, worker.stop)
            worker.last_obs = obs
            rows.append(obs)
        return concat_obs(rows)

    def _restore_masks(self, worker: _Worker, infos: dict[str, Any]) -> None:
        """Put a worker's masks from shared memory back into its infos and keep them for ``action_masks()``."""
        present = infos.get(f"_{MASK_KEY}")
        if not self.mask_size or present is None or MASK_KEY in infos:
            return
        masks = self._block.arrays["mask"][worker.rows]
        present = np.asarray(present)
        self._masks_seen = True
        if present.all():  # the usual step: every battle reported its masks
            np.not_equal(masks, 0, out=self._masks[worker.rows])
            infos[MASK_KEY] = masks.astype(np.int8)
            return
        self._masks[worker.rows][present] = masks[present] != 0
        infos[MASK_KEY] = np.where(present[:, None], masks, 0).astype(np.int8)


# ---------------------------------------------------------------------------------------------------------------
# Module helpers.


def _checked_start_method(start_method: str | None) -> str:
    if start_method is None:
        start_method = "forkserver" if "forkserver" in START_METHODS else "spawn"
    if start_method not in START_METHODS:
        raise ValueError(f"start_method must be one of {START_METHODS} on this platform, got {start_method!r}")
    return start_method


def _default_start_timeout() -> float:
    from smac_hard_gym.kernel_cache import kernels_cached

    return COLD_START_TIMEOUT if not kernels_cached() else WARM_START_TIMEOUT


def _context(start_method: str) -> Any:
    ctx = mp.get_context(start_method)
    if start_method == "forkserver":
        # The server imports the engine once, so each worker forks ready to run: no per-worker imports,
        # and no threads are running in the server when it forks (numba's GNU OpenMP layer is not fork-safe
        # in a process that has run parallel code, which is why "fork" from a busy parent is not).
        ctx.set_forkserver_preload(["smac_hard_gym.envs.vector"])
    return ctx


def _read_message(worker: _Worker, item: Any) -> tuple[str, Any]:
    """The worker's message once ``wait`` returned ``item`` (its pipe or its process sentinel); ``("died", None)``
    when the process ended without one."""
    if not (item is worker.conn or worker.conn.poll()):
        return "died", None
    try:
        data = worker.conn.recv_bytes()
    except (EOFError, OSError):
        return "died", None
    try:
        status, value = safe_loads(data)  # never pickle.loads: the worker's process may not be ours any more
        if status not in ("ok", "error"):
            raise ValueError(f"unknown status {status!r}")
    except Exception as err:  # noqa: BLE001 - any malformed reply: the worker is treated as failed
        return "unsafe", f"{type(err).__name__}: {err}"
    return status, value


def _outcome(worker: _Worker, status: str, value: Any, what: str) -> tuple[bool, Any]:
    """``(True, reply)`` for an answer, ``(False, why)`` for a worker that could not build its env or died."""
    if status == "ok":
        worker.warm = worker.warm or what == "step"
        return True, value
    if status == "error":  # only at "start": later env errors are raised by _gather
        return False, value[1]
    if status == "unsafe":
        worker.process.kill()
        return False, f"sent a reply to {what} that the parent does not read ({value}); its process was killed"
    worker.process.join(0.1)
    return False, f"died during {what} (exit code {worker.process.exitcode})"


def _failures(replies: dict[int, tuple[bool, Any]]) -> dict[int, Any]:
    """The workers that died or hung, and why."""
    return {w: why for w, (ok, why) in replies.items() if not ok}


def _checked_action_shape(space: spaces.Space, num_envs: int) -> tuple[tuple[int, ...], int] | None:
    """``(shape, n_actions)`` of a batch's actions when the space is SMAC-like (one Discrete or a uniform
    MultiDiscrete), so that :func:`validate_actions` checks them; None for other spaces."""
    if isinstance(space, spaces.MultiDiscrete) and space.nvec.ndim == 1 and (space.nvec == space.nvec[0]).all():
        return (num_envs, len(space.nvec)), int(space.nvec[0])
    if isinstance(space, spaces.Discrete) and space.start == 0:
        return (num_envs,), int(space.n)
    return None


def _first_line(text: str) -> str:
    """The exception line of a traceback text (the text itself when it is one line)."""
    lines = str(text).strip().splitlines()
    return lines[-1] if lines else ""


def make_subproc_env(map_name: str = "3m", num_workers: int = 2, envs_per_worker: int = 4, *,
                     autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, start_method: str | None = None,
                     timeout: float = 60.0, on_worker_error: str = "raise", **env_kwargs: Any) -> SubprocVectorEnv:
    """``num_workers`` processes, each running a :class:`~smac_hard_gym.envs.vector.NativeVectorEnv` of
    ``envs_per_worker`` battles of ``map_name`` (``env_kwargs`` go to it: opponent, obs_mode, backend, ...)."""
    for name, value in (("num_workers", num_workers), ("envs_per_worker", envs_per_worker)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be a positive int, got {value!r}")
    from smac_hard_gym.envs.vector import NativeVectorEnv

    mode = parse_autoreset_mode(autoreset_mode)
    factory = functools.partial(NativeVectorEnv, map_name, num_envs=int(envs_per_worker), autoreset_mode=mode,
                                **env_kwargs)
    return SubprocVectorEnv([factory] * int(num_workers), autoreset_mode=mode, start_method=start_method,
                            timeout=timeout, on_worker_error=on_worker_error)
