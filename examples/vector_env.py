"""Many battles at once: the native vector env, its autoreset modes and masks, and the subprocess vector env.

    python examples/vector_env.py
"""

from __future__ import annotations

import functools

import gymnasium as gym
import numpy as np

import smac_hard_gym  # noqa: F401  (registers the SMACHard-* ids)
from smac_hard_gym.envs.subproc import SubprocVectorEnv
from smac_hard_gym.envs.vector import NativeVectorEnv


def random_legal_actions(masks: np.ndarray, n_agents: int, rng: np.random.Generator) -> np.ndarray:
    """One legal action per agent and battle, drawn uniformly from the mask rows."""
    per_agent = masks.reshape(len(masks), n_agents, -1)
    scores = rng.random(per_agent.shape) * per_agent  # illegal actions score 0, legal ones in (0, 1)
    return scores.argmax(axis=2)


def main() -> None:
    rng = np.random.default_rng(0)

    # 1. Eight battles of 3m in one engine batch. NEXT_STEP (gymnasium's default): a finished battle shows its
    #    last observation once, and its next action starts a new episode.
    envs = gym.make_vec("SMACHard-3m-v0", num_envs=8)
    obs, infos = envs.reset(seed=0)
    print(envs, "obs", obs.shape, "masks", envs.action_masks().shape)
    for _ in range(100):
        obs, rewards, terminated, truncated, infos = envs.step(random_legal_actions(envs.action_masks(), 3, rng))
    envs.close()

    # 2. SAME_STEP (what SB3 expects): the finished battle restarts inside the step, and its last observation and
    #    info move to infos["final_obs"] / infos["final_info"].
    envs = gym.make_vec("SMACHard-3m-v0", num_envs=8, autoreset_mode="SameStep", opponent="default")
    envs.reset(seed=0)
    finished = []
    while len(finished) < 16:
        *_, terminated, truncated, infos = envs.step(random_legal_actions(envs.action_masks(), 3, rng))
        for i in np.flatnonzero(terminated | truncated):
            finished.append((infos["final_info"]["opponent"][i], bool(infos["final_info"]["battle_won"][i])))
    print("random play, first finished episodes (opponent, won):", finished[:4])
    envs.close()

    # 3. Two worker processes with four battles each; a crashed or hung worker is rebuilt and its episodes are
    #    reported as truncated with infos["worker_restarted"].
    factory = functools.partial(NativeVectorEnv, "3m", num_envs=4, autoreset_mode="SameStep")
    with SubprocVectorEnv([factory, factory], on_worker_error="restart", timeout=30) as envs:
        obs, infos = envs.reset(seed=0)
        for _ in range(50):
            obs, *_ = envs.step(random_legal_actions(envs.action_masks(), 3, rng))
        print(envs, "obs", obs.shape)


if __name__ == "__main__":  # worker processes re-import this file: keep the work behind this guard
    main()
