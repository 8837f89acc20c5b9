"""Env-steps/s of our environments: the native and subprocess vector envs, StarCraft2Env, and the engine alone."""

from __future__ import annotations

import time
import tracemalloc
from collections.abc import Callable
from typing import Any

import numpy as np

from smac_hard_gym.bench.machine import CpuMeter, peak_rss_of
from smac_hard_gym.bench.policy import RandomLegalPolicy, VectorLoop, warm_up
from smac_hard_gym.bench.timing import Measurement, timed_repeats


def _measure_loop(make: Callable[[], tuple[Any, VectorLoop]], seconds: float, repeats: int,
                  trace_memory: bool) -> tuple[Any, VectorLoop, list[float], float, float | None, float, dict]:
    """Build (traced when asked), warm up, time. Returns env, loop, runs, setup s, peak bytes, episodes/s and the
    :class:`CpuMeter` reading of the timed windows."""
    if trace_memory:
        tracemalloc.start()
    t0 = time.perf_counter()
    try:
        env, loop = make()
        warm_up(loop)
        peak = tracemalloc.get_traced_memory()[1] if trace_memory else None
    finally:
        if trace_memory:
            tracemalloc.stop()
    setup = time.perf_counter() - t0
    loop.episodes = 0
    t1 = time.perf_counter()
    with CpuMeter([p.pid for p in getattr(env, "processes", [])]) as meter:
        runs = timed_repeats(loop.step, seconds, repeats)
    episodes_per_second = loop.episodes / (time.perf_counter() - t1)
    return env, loop, runs, setup, peak, episodes_per_second, meter.result


def bench_native(map_name: str, num_envs: int, *, opponent: str = "base", seconds: float = 1.0, repeats: int = 3,
                 seed: int = 0, trace_memory: bool = True, section: str = "native") -> Measurement:
    """``NativeVectorEnv`` through the gymnasium vector API: random legal actions, SameStep autoreset."""
    from smac_hard_gym.envs.vector import NativeVectorEnv

    def make(n: int = num_envs) -> tuple[Any, VectorLoop]:
        env = NativeVectorEnv(map_name, n, opponent=opponent, autoreset_mode="SameStep")
        env.reset(seed=seed)
        return env, VectorLoop(env, env.view.n_agents, env.view.n_actions, seed)

    if trace_memory:  # one-time costs (lazy imports, kernel loads, map caches) must not count as this config's
        primer, loop = make(1)
        warm_up(loop)
        primer.close()
    env, _, runs, setup, peak, eps, cpu = _measure_loop(make, seconds, repeats, trace_memory)
    env.close()
    return Measurement(section, map_name, num_envs, float(np.median(runs)), runs, opponent=opponent,
                       setup_seconds=setup, episodes_per_second=eps,
                       peak_bytes_per_env=None if peak is None else peak / num_envs, extra={"cpu": cpu})


def bench_subproc(map_name: str, workers: int, envs_per_worker: int, *, opponent: str = "base",
                  seconds: float = 1.0, repeats: int = 3, seed: int = 0) -> Measurement:
    """``SubprocVectorEnv``: ``workers`` processes of ``envs_per_worker`` battles each, one numba thread each."""
    from smac_hard_gym.envs.subproc import make_subproc_env

    def make() -> tuple[Any, VectorLoop]:
        env = make_subproc_env(map_name, num_workers=workers, envs_per_worker=envs_per_worker,
                               autoreset_mode="SameStep", opponent=opponent)
        env.reset(seed=seed)
        n_agents = len(env.single_action_space.nvec)
        return env, VectorLoop(env, n_agents, int(env.single_action_space.nvec[0]), seed)

    env, _, runs, setup, _, eps, cpu = _measure_loop(make, seconds, repeats, trace_memory=False)
    worker_rss = [peak_rss_of(p.pid) for p in env.processes]
    env.close()
    rss = [r for r in worker_rss if r is not None]
    return Measurement("subproc", map_name, workers * envs_per_worker, float(np.median(runs)), runs,
                       opponent=opponent, workers=workers, setup_seconds=setup, episodes_per_second=eps,
                       extra={"envs_per_worker": envs_per_worker, "cpu": cpu,
                              "worker_peak_rss_mib": [round(r / 2**20, 1) for r in rss]})


def bench_starcraft2(map_name: str = "3m", *, opponent: str = "base", seconds: float = 1.0, repeats: int = 3,
                     seed: int = 0) -> Measurement:
    """``StarCraft2Env``, one battle, in pymarl's episode-runner loop: each step reads ``get_state()``,
    ``get_avail_actions()`` and ``get_obs()``, picks random legal actions, calls ``step``; resets on episode end."""
    from smac_hard_gym.envs.starcraft2 import StarCraft2Env

    env = StarCraft2Env(map_name=map_name, opponent=opponent, seed=seed)
    info = env.get_env_info()
    policy = RandomLegalPolicy(1, info["n_agents"], info["n_actions"], seed)
    episodes = [0]

    def step() -> int:
        env.get_state()
        avail = np.asarray(env.get_avail_actions())
        env.get_obs()
        _, terminated, _ = env.step(policy(avail[None])[0])
        if terminated:
            episodes[0] += 1
            env.reset()
        return 1

    t0 = time.perf_counter()
    env.reset()
    step()
    step()
    setup = time.perf_counter() - t0
    episodes[0] = 0
    t1 = time.perf_counter()
    with CpuMeter() as meter:
        runs = timed_repeats(step, seconds, repeats)
    eps = episodes[0] / (time.perf_counter() - t1)
    env.close()
    return Measurement("starcraft2", map_name, 1, float(np.median(runs)), runs, opponent=opponent,
                       setup_seconds=setup, episodes_per_second=eps, extra={"cpu": meter.result})


def _random_command_pool(engine: Any, rng: np.random.Generator, size: int) -> list:
    """A pool of random command sets (move to a nearby point, or attack a random unit) to cycle through."""
    from smac_hard_gym.engine.state import CMD_ATTACK, CMD_MOVE, Commands

    b, u = engine.batch_size, engine.n_units
    pool = []
    for _ in range(size):
        c = Commands.empty(b, u)
        attack = rng.random((b, u)) < 0.5
        c.kind[:] = np.where(attack, CMD_ATTACK, CMD_MOVE)
        c.target[:] = rng.integers(0, u, size=(b, u))
        c.x[:] = engine.layout.x + rng.uniform(-6, 6, size=(b, u))
        c.y[:] = engine.layout.y + rng.uniform(-6, 6, size=(b, u))
        pool.append(c)
    return pool


def bench_engine(map_name: str, batch: int, steps: int | None = None, repeats: int = 3, seed: int = 0,
                 seconds: float = 1.0) -> Measurement:
    """The engine alone: random commands every step, battles reset when one side is dead or at the limit.

    ``steps`` fixes the steps per timed repeat; None runs each repeat for ``seconds``. ``extra`` holds
    ``resets_per_second`` and ``state_bytes_per_battle`` (the engine state arrays).
    """
    from smac_hard_gym.engine import BattleEngine
    from smac_hard_gym.engine.state import state_nbytes

    t0 = time.perf_counter()
    engine = BattleEngine(map_name, batch_size=batch)
    engine.step()
    setup = time.perf_counter() - t0
    engine.reset()
    pool = _random_command_pool(engine, np.random.default_rng(seed), 16)
    limit = engine.spec.episode_limit * engine.step_mul
    counter = {"k": 0, "resets": 0}

    def step() -> int:
        engine.step(pool[counter["k"] % len(pool)])
        counter["k"] += 1
        red, blue = engine.alive_counts()
        done = (red == 0) | (blue == 0) | (engine.state.loop >= limit)
        if done.any():
            counter["resets"] += int(done.sum())
            engine.reset(done)
        return batch

    step()
    t1 = time.perf_counter()
    with CpuMeter() as meter:
        if steps is None:
            runs = timed_repeats(step, seconds, repeats)
        else:
            runs = []
            for _ in range(repeats):
                t = time.perf_counter()
                for _ in range(steps):
                    step()
                runs.append(steps * batch / (time.perf_counter() - t))
    resets = counter["resets"] / (time.perf_counter() - t1)
    extra = {"resets_per_second": resets, "state_bytes_per_battle": state_nbytes(engine.state) / batch,
             "cpu": meter.result}
    return Measurement("engine", map_name, batch, float(np.median(runs)), runs, setup_seconds=setup,
                       episodes_per_second=resets, extra=extra)
