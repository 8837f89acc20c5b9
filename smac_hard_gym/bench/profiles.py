"""Where a step's wall time goes: the core's collaborators are wrapped with timers while random play runs."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from smac_hard_gym.bench.policy import RandomLegalPolicy, VectorLoop, warm_up


class _Splits:
    """Wall time accumulated per component by wrapping callables in place (restored by ``restore``)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._undo: list[tuple[Any, str, Any]] = []

    def wrap(self, owner: Any, attr: str, label: str) -> None:
        original = getattr(owner, attr)
        seconds = self.seconds
        seconds.setdefault(label, 0.0)

        def timed(*args: Any, **kwargs: Any) -> Any:
            t = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                seconds[label] += time.perf_counter() - t

        self._undo.append((owner, attr, original))
        setattr(owner, attr, timed)

    def restore(self) -> None:
        for owner, attr, original in reversed(self._undo):
            setattr(owner, attr, original)
        self._undo.clear()


# (owner path, attribute, label): the core's collaborators, wrapped where the core looks them up.
_CORE_PARTS = (
    ("backend", "step", "engine step"),
    ("opponent", "act", "opponent script"),
    ("features.0", "observations", "observations"),
    ("features.0", "global_state", "global state"),
    ("features.0", "encode", "masks, observations and state in one pass (StarCraft2Env)"),
    ("core_module", "available_actions", "action masks"),
    ("core_module", "check_actions", "action checks + decoding"),
    ("core_module", "decode_actions", "action checks + decoding"),
    ("core_module", "finish_step", "outcome, rewards, counters"),
)


def _wrap_core(splits: _Splits, core: Any) -> None:
    import smac_hard_gym.envs.core as core_module

    owners = {"backend": core.backend, "opponent": core.opponent, "features.0": core.features[0],
              "core_module": core_module, "core": core}
    for owner, attr, label in _CORE_PARTS:
        if owners[owner] is not None:
            splits.wrap(owners[owner], attr, label)


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
    _wrap_core(splits, env.core)
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
        splits.restore()
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
    _wrap_core(splits, env._core)
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
        splits.restore()
        env.close()
    table = _split_table(splits, total, steps, policy_time)
    table.update(what="starcraft2", map=map_name, num_envs=1, opponent=opponent, steps_per_second=steps / total)
    return table
