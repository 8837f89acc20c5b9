"""Where a step's wall time goes: the core reports each phase of its step to a hook while random play runs."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from smac_hard_gym.bench.policy import RandomLegalPolicy, VectorLoop, warm_up


class _Splits:
    """Wall time accumulated per phase of the core's step, through its ``profile_hook``."""

    LABELS = {"actions": "action checks + decoding", "opponent": "opponent script", "engine": "engine step",
              "outcome and features": "outcome, rewards, masks, observations, state (one pass)"}

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    def __call__(self, phase: str, seconds: float) -> None:
        label = self.LABELS.get(phase, phase)
        self.seconds[label] = self.seconds.get(label, 0.0) + seconds


def _attach(splits: _Splits, core: Any) -> None:
    core.profile_hook = splits


def _split_table(splits: _Splits, total: float, steps: int, policy_seconds: float) -> dict[str, Any]:
    parts = dict(splits.seconds)
    parts["random policy"] = policy_seconds
    parts["Python overhead (env, core, infos)"] = max(0.0, total - sum(parts.values()))
    return {"total_seconds": total, "steps": steps,
            "us_per_step": {k: 1e6 * v / steps for k, v in parts.items()},
            "share": {k: v / total for k, v in parts.items()}}


def profile_native(map_name: str, num_envs: int, *, opponent: str = "base", seconds: float = 2.0,
                   seed: int = 0) -> dict[str, Any]:
    """Wall-time split of NativeVectorEnv steps (random legal policy, SameStep) between the engine, opponent,
    observations, masks, rewards, action handling, the policy, and the rest (Python overhead)."""
    from smac_hard_gym.envs.vector import NativeVectorEnv

    env = NativeVectorEnv(map_name, num_envs, opponent=opponent, autoreset_mode="SameStep")
    env.reset(seed=seed)
    loop = VectorLoop(env, env.view.n_agents, env.view.n_actions, seed)
    warm_up(loop)
    splits = _Splits()
    _attach(splits, env.core)
    policy, policy_time = loop.policy, [0.0]

    def timed_policy(masks: np.ndarray) -> np.ndarray:
        t = time.perf_counter()
        out = policy(masks)
        policy_time[0] += time.perf_counter() - t
        return out

    loop.policy = timed_policy
    steps, t0 = 0, time.perf_counter()
    try:
        while time.perf_counter() - t0 < seconds or steps < 2:
            loop.step()
            steps += 1
    finally:
        total = time.perf_counter() - t0
        env.core.profile_hook = None
        env.close()
    table = _split_table(splits, total, steps, policy_time[0])
    table.update(what="native", map=map_name, num_envs=num_envs, opponent=opponent,
                 steps_per_second=steps * num_envs / total)
    return table


def profile_starcraft2(map_name: str = "3m", *, opponent: str = "base", seconds: float = 2.0,
                       seed: int = 0) -> dict[str, Any]:
    """The same split for StarCraft2Env's pymarl loop on one battle."""
    from smac_hard_gym.envs.starcraft2 import StarCraft2Env

    env = StarCraft2Env(map_name=map_name, opponent=opponent, seed=seed)
    info = env.get_env_info()
    policy = RandomLegalPolicy(1, info["n_agents"], info["n_actions"], seed)
    env.reset()
    splits = _Splits()
    _attach(splits, env._core)
    policy_time, steps, t0 = 0.0, 0, time.perf_counter()
    try:
        while time.perf_counter() - t0 < seconds or steps < 2:
            env.get_state()
            avail = np.asarray(env.get_avail_actions())
            env.get_obs()
            t = time.perf_counter()
            actions = policy(avail[None])[0]
            policy_time += time.perf_counter() - t
            _, terminated, _ = env.step(actions)
            if terminated:
                env.reset()
            steps += 1
    finally:
        total = time.perf_counter() - t0
        env._core.profile_hook = None
        env.close()
    table = _split_table(splits, total, steps, policy_time)
    table.update(what="starcraft2", map=map_name, num_envs=1, opponent=opponent, steps_per_second=steps / total)
    return table
