"""``RayVectorEnv``: battles spread over Ray actors, each owning a batch of K battles, on one machine or a cluster.

The subprocess env's worker protocol, hosted by Ray instead of a pipe: each actor builds a
:class:`~smac_hard_gym.envs.subproc.BatchWorker` from the same cloudpickled factory and answers the same commands
(``reset``, ``step``, ``call``) through the same :class:`~smac_hard_gym.envs.subproc.worker.Server`; the parent side
is :class:`~smac_hard_gym.envs.subproc.SubprocVectorEnv` with its transport swapped (launch, send, gather, stop).
Everything above the transport is the subprocess env's own code, so spaces, ``action_masks()``, autoreset modes, info
keys, action checks and seeding (``reset(seed=s)`` gives battle ``i`` the seed ``s + i``) are the same, and the same
seeds give the same episodes.

Data. Actions go to each actor as a small array (K x agents int64). Each actor's reply (observations, rewards, flags,
infos with the action masks) is one Ray object; Ray serialises its numpy arrays out of band (pickle protocol 5), so
above Ray's inline limit (100 KiB) they are written once into the object store and ``ray.get`` maps them zero-copy
(read-only); the only copy on the parent is the join of the actors' rows into the batch (as the subprocess env copies
out of its shared memory). Between nodes Ray moves the same buffers.

Failures. An actor that dies (``ray.kill``, a crashed process, a lost node) or does not answer within ``timeout``
seconds is killed and then rebuilt (``on_worker_error="restart"``: its battles report ``truncated=True`` with
``infos["worker_restarted"]``) or reported (``"raise"``: :class:`~smac_hard_gym.envs.subproc.WorkerError`, after
closing every actor). ``close()`` kills every actor and waits until Ray reports them gone; actors are owned by the
driver, so they also die with it.

>>> from smac_hard_gym import make_ray_vec
>>> envs = make_ray_vec("3m", num_actors=2, envs_per_actor=4, autoreset_mode="SameStep")  # doctest: +SKIP
>>> envs.reset(seed=0)[0].shape  # doctest: +SKIP
(8, 90)
>>> envs.close()  # doctest: +SKIP

Needs ``pip install smac-hard-gym[ray]`` (Ray core; RLlib is not needed).
"""

from __future__ import annotations

import functools
import os
import time
import uuid
from collections.abc import Callable, Sequence
from typing import Any

import cloudpickle
import numpy as np
from gymnasium.vector import AutoresetMode

try:
    import ray
    from ray.exceptions import GetTimeoutError, RayError
except ImportError as err:  # pragma: no cover - the message is the point
    raise ImportError("RayVectorEnv needs Ray: pip install 'smac-hard-gym[ray]' (or pip install 'ray>=2.40')") from err

from smac_hard_gym.envs.autoreset import parse_autoreset_mode
from smac_hard_gym.envs.subproc.batch import concat_obs
from smac_hard_gym.envs.subproc.env import (
    SubprocVectorEnv,
    _Worker,
)
from smac_hard_gym.envs.subproc.shared_memory import MASK_KEY
from smac_hard_gym.envs.subproc.worker import BatchWorker, Server, limit_threads, pack_error, unpack_error

__all__ = ["RayVectorEnv", "make_ray_vec", "ACTOR_PREFIX"]

ACTOR_PREFIX = "smac-hard-gym-actor"  # actor names: <prefix>-<env id>-<worker index>-<generation>
_THREAD_VARS = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
_CLOSE_WAIT = 5.0  # seconds close() waits for actors to close their envs, then for Ray to report them dead


class BatchActor:
    """The body of one Ray actor: a :class:`BatchWorker` behind the subprocess worker's :class:`Server` (no shared
    block: observations and masks travel in the reply, through Ray's object store)."""

    def __init__(self, factory_bytes: bytes, autoreset_mode: Any, threads: int) -> None:
        limit_threads(threads)
        self.server: Server | None = None
        self.error: tuple[bytes | None, str] | None = None
        try:
            self.server = Server(BatchWorker(cloudpickle.loads(factory_bytes), autoreset_mode))
        except BaseException as err:  # noqa: BLE001 - reported by start()
            self.error = pack_error(err)

    def start(self) -> tuple[str, Any]:
        """The first answer, as in the pipe protocol: ``("ok", describe())`` or ``("error", packed)``."""
        if self.server is None:
            return "error", self.error
        return "ok", self.server.worker.describe()

    def handle(self, command: str, payload: Any) -> tuple[str, Any]:
        return self.server.answer(command, payload)

    def close(self) -> None:
        if self.server is not None:
            self.server.close()
            self.server = None

    def pid(self) -> int:
        return os.getpid()


class _ActorHandle(_Worker):
    """The parent's handle on one actor: the actor, its name, and the reply it owes."""

    def __init__(self, index: int, factory_bytes: bytes) -> None:
        super().__init__(index, factory_bytes)
        self.actor: Any = None
        self.name = ""
        self.ref: Any = None  # the ObjectRef of the reply awaited
        self.generation = 0  # rebuilds so far (part of the actor's name)


class RayVectorEnv(SubprocVectorEnv):
    """Battles in Ray actors: each of ``len(factories)`` actors builds a batch env from its factory.

    Arguments (the others are :class:`~smac_hard_gym.envs.subproc.SubprocVectorEnv`'s)
        ``factories``: one callable per actor returning a gymnasium ``VectorEnv`` of K battles (e.g.
        ``functools.partial(NativeVectorEnv, "27m_vs_30m", num_envs=256, autoreset_mode="SameStep")``) or a
        single ``gymnasium.Env``; cloudpickled, so they must be importable where the actors run (the same package
        on every node). ``address``: the Ray cluster to join when Ray is not initialised yet (``"auto"``,
        ``"ray://head:10001"``, ``"head:6379"``); None starts a local Ray, which ``close()`` shuts down again.
        A Ray initialised by the caller is used as it is. ``actor_options``: passed to ``.options()`` of each
        actor (default ``{"num_cpus": worker_threads}``: one core reserved per actor, so Ray places N actors on N
        free cores across the cluster; add e.g. ``scheduling_strategy="SPREAD"``), with a ``runtime_env`` that runs
        the actor at normal priority and limits its engine threads (its ``env_vars`` are merged).
        ``ray_init_kwargs``: for ``ray.init`` when this env starts Ray.
    """

    _worker_type = _ActorHandle  # SubprocVectorEnv._start_workers builds one per factory

    def __init__(self, factories: Sequence[Callable[[], Any]], *, address: str | None = None,
                 autoreset_mode: AutoresetMode | str | None = None, timeout: float = 60.0,
                 start_timeout: float | None = None, on_worker_error: str = "raise", max_failures: int = 3,
                 worker_threads: int = 1, actor_options: dict[str, Any] | None = None,
                 ray_init_kwargs: dict[str, Any] | None = None) -> None:
        factories = self._settings(factories, autoreset_mode, timeout, start_timeout, on_worker_error, max_failures,
                                   worker_threads)
        self._owns_ray = False
        self.start_method = "ray"
        self.actor_options = _actor_options(actor_options, self.worker_threads)
        self._env_id = uuid.uuid4().hex[:8]
        if not ray.is_initialized():
            ray.init(address=address, **{"include_dashboard": False, "log_to_driver": False,
                                         **(ray_init_kwargs or {})})
            self._owns_ray = True
        self.address = address
        self._actor_class = ray.remote(BatchActor)
        try:
            self._check_room(len(factories))
            self._start_workers(factories)
        except BaseException:
            self.close()
            raise

    # -----------------------------------------------------------------------------------------------------------
    # The transport: SubprocVectorEnv's hooks, over Ray.

    def _check_room(self, n: int) -> None:
        """Raise rather than wait forever when the cluster has fewer CPUs than ``n`` actors reserve."""
        need = n * float(self.actor_options.get("num_cpus") or 0)
        have = float(ray.cluster_resources().get("CPU", 0.0))
        if need > have:
            raise ValueError(f"{n} actors reserving {self.actor_options['num_cpus']} CPU each need {need:g} CPUs but "
                             f"the Ray cluster has {have:g}; use fewer actors (more battles each), add nodes, or pass "
                             "actor_options={'num_cpus': <a fraction>}")

    def _new_block(self) -> None:
        return None  # observations and masks travel in the replies, through Ray's object store

    def _launch(self, worker: _ActorHandle) -> None:
        worker.warm = False
        worker.generation += 1
        worker.name = f"{ACTOR_PREFIX}-{self._env_id}-{worker.index}-{worker.generation}"
        worker.actor = self._actor_class.options(name=worker.name, max_restarts=0, **self.actor_options).remote(
            worker.factory_bytes, self._requested_mode, self.worker_threads)
        worker.process = worker.actor
        worker.ref = worker.actor.start.remote()

    def _attach(self, worker: _ActorHandle) -> None:
        pass  # nothing to attach: no shared block

    def _send(self, worker: _ActorHandle, command: str, payload: Any = None) -> bool:
        if worker.actor is None:
            return False
        worker.ref = worker.actor.handle.remote(command, payload)
        return True

    def _gather(self, workers: list[_ActorHandle], timeout: float, what: str) -> dict[int, tuple[bool, Any]]:
        """One reply from each actor: ``(True, reply)``, or ``(False, why)`` for an actor that died or hung; env
        errors are raised once every actor has answered."""
        if what in ("reset", "step") and not all(w.warm for w in workers):
            timeout = max(timeout, self.start_timeout)
        refs = [w.ref for w in workers]
        ready, _ = ray.wait(refs, num_returns=len(refs), timeout=timeout, fetch_local=True)
        ready = set(ready)
        results: dict[int, tuple[bool, Any]] = {}
        env_error: BaseException | None = None
        for worker, ref in zip(workers, refs, strict=True):
            worker.ref = None
            if ref not in ready:
                results[worker.index] = (False, f"no answer to {what} within {timeout:g} s (hung)")
                continue
            try:
                status, value = ray.get(ref)
            except RayError as err:
                results[worker.index] = (False, f"died during {what} ({type(err).__name__}: "
                                                f"{_first_line(str(err))})")
                continue
            if status == "error" and what != "start":
                env_error = env_error or unpack_error(value, worker.index, "RayVectorEnv actor")
                results[worker.index] = (True, None)
            elif status == "error":
                results[worker.index] = (False, value[1])
            else:
                worker.warm = worker.warm or what == "step"
                results[worker.index] = (True, value)
        if env_error is not None:
            raise env_error
        return results

    def _stop_process(self, worker: _ActorHandle, graceful: bool) -> None:
        if worker.actor is None:
            return
        if graceful:
            try:
                ray.get(worker.actor.close.remote(), timeout=_CLOSE_WAIT)
            except (RayError, GetTimeoutError):
                pass
        _kill(worker.actor)
        worker.actor = worker.process = worker.ref = None

    def close_extras(self, **kwargs: Any) -> None:
        """Ask every actor to close its env, kill them all, and wait until Ray reports them dead."""
        if not ray.is_initialized():
            return
        live = [w for w in self._workers if w.actor is not None]
        closing = [w.actor.close.remote() for w in live]
        if closing:
            ray.wait(closing, num_returns=len(closing), timeout=_CLOSE_WAIT)
        names = [w.name for w in live]
        for worker in live:
            _kill(worker.actor)
            worker.actor = worker.process = worker.ref = None
        _wait_gone(names, _CLOSE_WAIT)
        if self._owns_ray:
            ray.shutdown()
            self._owns_ray = False

    # -----------------------------------------------------------------------------------------------------------
    # Observations and masks arrive in the replies.

    def _observations(self, parts: list[dict[str, Any]]) -> Any:
        """The batch's observations: each actor's rows from its reply (read-only object-store views, joined into
        one new array here), or kept from before."""
        rows = []
        for worker, part in zip(self._workers, parts, strict=True):
            self._restore_masks(worker, part["infos"])
            rows.append(worker.last_obs if part.get("restored") else part["obs"])
        obs = concat_obs(rows)
        for worker in self._workers:
            worker.last_obs = ({k: v[worker.rows] for k, v in obs.items()} if isinstance(obs, dict)
                               else obs[worker.rows])
        return obs

    def _restore_masks(self, worker: _ActorHandle, infos: dict[str, Any]) -> None:
        """Keep the actor's masks (in its infos) for ``action_masks()``."""
        present = infos.get(f"_{MASK_KEY}")
        if not self.mask_size or present is None or MASK_KEY not in infos:
            return
        present = np.asarray(present)
        masks = np.asarray(infos[MASK_KEY]).reshape(worker.size, -1)
        self._masks_seen = True
        if present.all():
            np.not_equal(masks, 0, out=self._masks[worker.rows])
        else:
            self._masks[worker.rows][present] = masks[present] != 0

    # -----------------------------------------------------------------------------------------------------------

    @property
    def actors(self) -> list[Any]:
        """The live actors' handles (for monitoring; do not kill them by hand, except to test recovery)."""
        return [w.actor for w in self._workers if w.actor is not None]

    @property
    def actor_names(self) -> list[str]:
        """The live actors' names (``ray.get_actor(name)`` finds them while the env is open)."""
        return [w.name for w in self._workers if w.actor is not None]

    def __enter__(self) -> RayVectorEnv:
        return self

    def __repr__(self) -> str:
        sizes = [w.size for w in self._workers]
        mode = getattr(self, "autoreset_mode", None)
        return (f"RayVectorEnv(num_envs={getattr(self, 'num_envs', '?')}, actors={sizes}, "
                f"address={getattr(self, 'address', None)!r}, autoreset_mode={getattr(mode, 'value', None)})")

    def _check_open(self) -> None:
        if self.closed:
            raise RuntimeError("this RayVectorEnv is closed")


def _actor_options(given: dict[str, Any] | None, threads: int) -> dict[str, Any]:
    """``.options()`` of every actor: one CPU per engine thread, and a worker process at normal priority with the
    engine's threads limited (Ray starts workers at niceness 15, so on a busy machine an actor gets a fraction of
    the core that a subprocess worker gets; ``RAY_worker_niceness`` in the actor's own runtime env undoes that on
    every node). Entries of ``given`` win, its ``env_vars`` are merged."""
    options = {"num_cpus": threads, **(given or {})}
    runtime_env = dict(options.get("runtime_env") or {})
    env_vars = {"RAY_worker_niceness": "0", **{v: str(threads) for v in _THREAD_VARS},
                **(runtime_env.get("env_vars") or {})}
    options["runtime_env"] = {**runtime_env, "env_vars": env_vars}
    return options


def _kill(actor: Any) -> None:
    try:
        ray.kill(actor, no_restart=True)
    except (RayError, ValueError):
        pass


def _wait_gone(names: list[str], timeout: float) -> None:
    """Wait until no actor of ``names`` can be found by name (Ray reports it dead), for up to ``timeout`` s."""
    deadline = time.monotonic() + timeout
    pending = list(names)
    while pending and time.monotonic() < deadline:
        still = []
        for name in pending:
            try:
                ray.get_actor(name)
                still.append(name)
            except ValueError:
                pass
        pending = still
        if pending:
            time.sleep(0.05)


def _first_line(text: str) -> str:
    lines = text.strip().splitlines()
    return lines[0] if lines else ""


def make_ray_vec(map_name: str = "3m", num_actors: int = 2, envs_per_actor: int = 4, *,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, address: str | None = None,
                 timeout: float = 60.0, on_worker_error: str = "raise", actor_options: dict[str, Any] | None = None,
                 worker_threads: int = 1, **env_kwargs: Any) -> RayVectorEnv:
    """``num_actors`` Ray actors, each running a :class:`~smac_hard_gym.envs.vector.NativeVectorEnv` of
    ``envs_per_actor`` battles of ``map_name`` (``env_kwargs`` go to it: opponent, obs_mode, ...) on
    ``worker_threads`` engine threads; battle ``i`` of the batch is battle ``i % envs_per_actor`` of actor
    ``i // envs_per_actor``."""
    for name, value in (("num_actors", num_actors), ("envs_per_actor", envs_per_actor)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be a positive int, got {value!r}")
    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.maps import list_maps

    if map_name not in list_maps():
        raise ValueError(f"unknown map {map_name!r}; maps: {', '.join(list_maps())}")
    mode = parse_autoreset_mode(autoreset_mode)
    factory = functools.partial(NativeVectorEnv, map_name, num_envs=int(envs_per_actor), autoreset_mode=mode,
                                **env_kwargs)
    return RayVectorEnv([factory] * int(num_actors), autoreset_mode=mode, address=address, timeout=timeout,
                        on_worker_error=on_worker_error, actor_options=actor_options, worker_threads=worker_threads)
