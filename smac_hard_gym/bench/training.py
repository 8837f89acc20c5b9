"""``bench train``: MaskablePPO's training throughput (rollouts and updates) with sb3-contrib's stock policy and buffer
against the joint ones ``smac-hard-gym train`` uses, and ``train --policy shared``'s unit-shared policy
(wrappers/sb3_shared.py), each at ``train``'s defaults for its policy, interleaved round by round.

The stock and joint variants start from the same seed and learn the same steps, so their weights must come out
equal; the result says whether they did, next to the steps/s (the shared policy is another network: not applicable).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from smac_hard_gym.bench.timing import Measurement

# stock: sb3-contrib's MlpPolicy and buffer; joint: MaskableJointPolicy and MaskableJointRolloutBuffer; shared:
# SharedUnitPolicy and SharedUnitRolloutBuffer
VARIANTS = ("stock", "joint", "shared")


def _model(variant: str, map_name: str, num_envs: int, seed: int) -> Any:
    from sb3_contrib import MaskablePPO
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import VecMonitor

    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.training import TrainConfig
    from smac_hard_gym.wrappers.sb3 import SB3VecEnv
    from smac_hard_gym.wrappers.sb3_buffers import MaskableJointRolloutBuffer
    from smac_hard_gym.wrappers.sb3_policy import MaskableJointPolicy
    from smac_hard_gym.wrappers.sb3_shared import SharedUnitPolicy, SharedUnitRolloutBuffer

    config = TrainConfig(map_name=map_name, seed=seed, num_envs=num_envs,
                         policy="shared" if variant == "shared" else "joint")
    venv = VecMonitor(SB3VecEnv(NativeVectorEnv(num_envs=num_envs, autoreset_mode="SameStep", opponent="smac",
                                                **config.env_kwargs())))
    policy, buffer = {"stock": ("MlpPolicy", None), "joint": (MaskableJointPolicy, MaskableJointRolloutBuffer),
                      "shared": (SharedUnitPolicy, SharedUnitRolloutBuffer)}[variant]
    model = MaskablePPO(policy, venv, rollout_buffer_class=buffer, **config.ppo_kwargs())
    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


def _random_streams(state: tuple | None = None) -> tuple:
    """The global random streams SB3 draws from (torch, numpy, random): returns them, or sets ``state``."""
    import random

    import torch

    if state is not None:
        torch.set_rng_state(state[0])
        np.random.set_state(state[1])
        random.setstate(state[2])
    return torch.get_rng_state(), np.random.get_state(), random.getstate()


def bench_training(map_name: str, timesteps: int = 8192, rounds: int = 3, num_envs: int = 64,
                   seed: int = 0) -> list[Measurement]:
    """Per variant: the median env-steps/s of ``model.learn(timesteps)`` over ``rounds`` (rollouts and updates
    together), after one untimed rollout and update (compilation, first allocations). One torch thread, one engine
    thread, torch.distributions' argument checks off: as ``smac-hard-gym train`` runs."""
    import numba
    import torch

    from smac_hard_gym.training import distribution_checks_off

    torch.set_num_threads(1)
    numba.set_num_threads(1)
    with distribution_checks_off():
        models = {v: _model(v, map_name, num_envs, seed) for v in VARIANTS}
        # Each model seeds the global random streams when built; interleaved, each learns on its own copy of them,
        # so both draw the same numbers and must train the same weights.
        streams = {v: _random_streams() for v in VARIANTS}

        def learn(variant: str, steps: int) -> int:
            model = models[variant]
            _random_streams(streams[variant])
            before = model.num_timesteps
            model.learn(steps, reset_num_timesteps=before == 0)  # whole rollouts: at least `steps` steps
            streams[variant] = _random_streams()
            return model.num_timesteps - before

        for variant in VARIANTS:
            learn(variant, models[variant].n_steps * num_envs)
        runs: dict[str, list[float]] = {v: [] for v in VARIANTS}
        for _ in range(rounds):  # interleaved: a busy spell on a shared machine hits both
            for variant in VARIANTS:
                start = time.perf_counter()
                steps = learn(variant, timesteps)
                runs[variant].append(steps / (time.perf_counter() - start))
        same = all(torch.equal(a, b) for a, b in zip(models["stock"].policy.parameters(),
                                                         models["joint"].policy.parameters(), strict=True))
        for model in models.values():
            model.get_env().close()
    speed = {v: float(np.median(r)) for v, r in runs.items()}
    return [Measurement("train", map_name, num_envs, speed[v], runs[v], mode=v,
                        extra={"timesteps_per_round": timesteps, "same_weights": same if v != "shared" else None,
                               "speedup_vs_stock": speed[v] / speed["stock"],
                               "speedup_vs_joint": speed[v] / speed["joint"]})
            for v in VARIANTS]
