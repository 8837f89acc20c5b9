"""The ``ray`` section of ``smac-hard-gym bench vector``: :class:`~smac_hard_gym.wrappers.ray_vec.RayVectorEnv` with
1, 2, ... actors of K battles against :class:`~smac_hard_gym.envs.subproc.SubprocVectorEnv` with as many workers, in
the same run, and the bytes each actor sends and receives per step.

Every configuration is built first and then timed in interleaved rounds (round r times each configuration once, in
turn), so that a load from other processes that comes and goes falls on all of them alike; the figure is the median
over rounds. Needs ``ray`` (``pip install smac-hard-gym[ray]``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import cloudpickle
import numpy as np

from smac_hard_gym.bench.machine import CpuMeter
from smac_hard_gym.bench.policy import VectorLoop, warm_up
from smac_hard_gym.bench.timing import Measurement, timed_repeats

__all__ = ["bench_ray", "payload_bytes"]


def _build(kind: str, map_name: str, workers: int, k: int, opponent: str, seed: int,
           cpus_per_actor: float = 1.0) -> tuple[Any, VectorLoop]:
    if kind == "ray":
        from smac_hard_gym.wrappers.ray_vec import make_ray_vec

        env = make_ray_vec(map_name, workers, k, autoreset_mode="SameStep", opponent=opponent,
                           actor_options={"num_cpus": cpus_per_actor})
    else:
        from smac_hard_gym.envs.subproc import make_subproc_env

        env = make_subproc_env(map_name, num_workers=workers, envs_per_worker=k, autoreset_mode="SameStep",
                               opponent=opponent)
    env.reset(seed=seed)
    nvec = env.single_action_space.nvec
    loop = VectorLoop(env, len(nvec), int(nvec[0]), seed)
    warm_up(loop)
    return env, loop


def _pids(kind: str, env: Any) -> list[int]:
    if kind == "ray":
        import ray

        return ray.get([a.pid.remote() for a in env.actors])
    return [p.pid for p in env.processes]


def payload_bytes(env: Any, loop: VectorLoop, steps: int = 50) -> dict[str, float]:
    """Mean bytes per step per actor (worker) of what crosses between the learner and one actor, over ``steps``
    steps of ``loop``: actions sent; observations, action masks, rewards + end flags, and the other infos (pickled:
    opponents drawn, final observations and infos of ended episodes) received."""
    sums = dict.fromkeys(("actions", "observations", "action_masks", "rewards_and_flags", "infos_other"), 0.0)
    for _ in range(steps):
        actions = loop.policy(env.action_masks())
        obs, reward, terminated, truncated, infos = env.step(actions)
        loop.episodes += int(np.count_nonzero(terminated | truncated))
        sums["actions"] += actions.nbytes
        sums["observations"] += (sum(v.nbytes for v in obs.values()) if isinstance(obs, dict) else obs.nbytes)
        sums["action_masks"] += np.asarray(infos.get("action_mask", np.zeros(0, np.int8))).nbytes
        sums["rewards_and_flags"] += reward.nbytes + terminated.nbytes + truncated.nbytes
        others = {k: v for k, v in infos.items() if k not in ("action_mask", "_action_mask")}
        sums["infos_other"] += len(cloudpickle.dumps(others))
    actors = len(getattr(env, "actors", None) or env.processes)
    out = {key: value / steps / actors for key, value in sums.items()}
    out["total"] = sum(out.values())
    return out


def bench_ray(map_name: str, actors: Sequence[int] = (1, 2), envs_per_actor: int = 256, *,
              opponent: str = "base", seconds: float = 1.0, repeats: int = 3, seed: int = 0,
              address: str | None = None, subproc: bool = True,
              log: Callable[[str], None] = print) -> tuple[list[Measurement], dict[str, Any]]:
    """Ray actors (and, with ``subproc``, subprocess workers) of ``envs_per_actor`` battles each, timed in interleaved
    rounds; returns one :class:`Measurement` per configuration (section ``"ray"``, ``mode`` ``"ray"`` or
    ``"subproc"``, ``workers`` = actors) and the per-step payload of one actor.

    Starts a local Ray unless Ray is running already or ``address`` names a cluster. Every configuration is alive
    at once, so when their actors together outnumber the cluster's CPUs each actor reserves a share of a CPU
    instead of a whole one (otherwise Ray would hold the last ones back)."""
    import ray

    started_ray = False
    if not ray.is_initialized():
        ray.init(address=address, include_dashboard=False, log_to_driver=False)
        started_ray = True
    cpus_per_actor = min(1.0, float(ray.cluster_resources().get("CPU", 1.0)) / sum(actors))
    kinds = ["ray", "subproc"] if subproc else ["ray"]
    configs = [(kind, n) for n in actors for kind in kinds]
    built: dict[tuple[str, int], tuple[Any, VectorLoop, float]] = {}
    try:
        for kind, n in configs:
            t0 = time.perf_counter()
            env, loop = _build(kind, map_name, n, envs_per_actor, opponent, seed, cpus_per_actor)
            built[kind, n] = env, loop, time.perf_counter() - t0
            log(f"  built {kind} {n}x{envs_per_actor} on {map_name} in {built[kind, n][2]:.1f} s")
        payload = payload_bytes(*built["ray", actors[0]][:2])
        runs: dict[tuple[str, int], list[float]] = {c: [] for c in configs}
        cpu: dict[tuple[str, int], list[dict[str, float]]] = {c: [] for c in configs}
        episodes: dict[tuple[str, int], list[float]] = {c: [] for c in configs}
        for _ in range(repeats):
            for config in configs:
                env, loop, _ = built[config]
                loop.episodes = 0
                t0 = time.perf_counter()
                with CpuMeter(_pids(config[0], env)) as meter:
                    runs[config] += timed_repeats(loop.step, seconds, 1)
                episodes[config].append(loop.episodes / (time.perf_counter() - t0))
                cpu[config].append(meter.result)
        results = []
        for kind, n in configs:
            meters = cpu[kind, n]
            mean_cpu = {key: round(float(np.mean([m[key] for m in meters])), 2) for key in meters[0]}
            results.append(Measurement(
                "ray", map_name, n * envs_per_actor, float(np.median(runs[kind, n])), runs[kind, n],
                opponent=opponent, workers=n, mode=kind, setup_seconds=built[kind, n][2],
                episodes_per_second=float(np.median(episodes[kind, n])),
                extra={"envs_per_worker": envs_per_actor, "cpu": mean_cpu, "interleaved_rounds": repeats,
                       "address": address or "local"}))
        return results, {"map": map_name, "envs_per_actor": envs_per_actor, "bytes_per_step_per_actor": payload}
    finally:
        for env, _, _ in built.values():
            env.close()
        if started_ray:
            ray.shutdown()
