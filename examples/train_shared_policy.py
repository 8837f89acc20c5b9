"""MAPPO's recipe inside SB3's MaskablePPO: one actor shared by the units, on stacked frames, against SMAC's opponent.

    pip install -e ".[train]"
    python examples/train_shared_policy.py                                    # 3m, 200k steps
    python examples/train_shared_policy.py --map 3s_vs_5z --timesteps 2000000  # kiting (docs/training_results.md)

What ``smac-hard-gym train --policy shared`` builds, written out:

- the env: the ``joint+state`` view (every unit's SMAC observation, then the global state for the critic) with each
  unit's last 4 observations stacked (``frame_stack=4``) where MAPPO's run for the map has memory (a recurrent actor,
  or stacked frames as on 3s_vs_5z) and no measurement of ours says it buys nothing: SMAC's observation has no
  weapon cooldown, and kiting needs to know when the weapon is ready again;
- the policy: :class:`~smac_hard_gym.wrappers.sb3_shared.SharedUnitPolicy`, whose layout (one unit's block, the state,
  the last-action block) :func:`~smac_hard_gym.wrappers.sb3_shared.shared_policy_kwargs` reads from the env, with
  its rollout buffer, which keeps the value normalisation's statistics;
- PPO: MAPPO's SMAC settings: 64 battles x 50 steps an update (MAPPO's 8 x 400), and the epochs and minibatches
  of MAPPO's launch script for the map with the clip measured for those epochs
  (``smac_hard_gym.training.mappo_settings``; on 3s_vs_5z: one minibatch, 15 epochs, clip 0.05).
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numba
import torch
from sb3_contrib import MaskablePPO
from stable_baselines3.common.vec_env import VecMonitor

import smac_hard_gym  # noqa: F401  (registers the SMACHard-* ids)
from smac_hard_gym.training import TEST_SEED_BASE, evaluate
from smac_hard_gym.training.mappo_settings import shared_map_defaults
from smac_hard_gym.wrappers.sb3 import SB3VecEnv
from smac_hard_gym.wrappers.sb3_shared import SharedUnitPolicy, SharedUnitRolloutBuffer, shared_policy_kwargs


def env_options(map_name: str) -> dict:
    """The env's options: SMAC's opponent, the joint view with the state, MAPPO's memory for the map as frames."""
    return {"opponent": "smac", "obs_mode": "joint+state", "frame_stack": shared_map_defaults(map_name)["frame_stack"]}


def win_rate(model: MaskablePPO, map_name: str, episodes: int = 32) -> float:
    """Masked, deterministic win rate on ``smac-hard-gym eval``'s test battles (same env options as training)."""
    env = gym.make_vec(f"SMACHard-{map_name}-v0", num_envs=16, autoreset_mode="SameStep", **env_options(map_name))
    try:
        return evaluate(model, env, episodes, seed=TEST_SEED_BASE).win_rate
    finally:
        env.close()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Train the unit-shared policy with MaskablePPO against SMAC's AI.")
    parser.add_argument("--map", default="3m", help="map name (default: %(default)s)")
    parser.add_argument("--timesteps", type=int, default=200_000, help="training steps (default: %(default)s)")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)  # learner and engine take turns: one thread each
    numba.set_num_threads(1)
    mappo = shared_map_defaults(args.map)
    envs = gym.make_vec(f"SMACHard-{args.map}-v0", num_envs=64, autoreset_mode="SameStep", **env_options(args.map))
    venv = VecMonitor(SB3VecEnv(envs))
    policy_kwargs = {"net_arch": {"pi": [64, 64], "vf": [128, 128]}, **shared_policy_kwargs(venv)}
    model = MaskablePPO(SharedUnitPolicy, venv, rollout_buffer_class=SharedUnitRolloutBuffer, n_steps=50,
                        batch_size=64 * 50 // mappo["minibatches"], n_epochs=mappo["n_epochs"],
                        clip_range=mappo["clip_range"], learning_rate=5e-4, ent_coef=0.01,
                        policy_kwargs=policy_kwargs, seed=0, device="cpu", verbose=0)
    print(f"win rate before training: {win_rate(model, args.map):.2f}")
    model.learn(args.timesteps)
    print(f"win rate after training:  {win_rate(model, args.map):.2f}")
    venv.close()


if __name__ == "__main__":
    main()
