"""The EPyMARL recipe in examples/epymarl, without EPyMARL: its ``gymma`` door (``env_args.key``) and its ``smac``
import door, each driven the way EPyMARL's episode runner drives it."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

RECIPE = Path(__file__).resolve().parents[1] / "examples" / "epymarl"


class GymmaLike:
    """The parts of EPyMARL's ``envs.gymma.GymmaWrapper`` (uoe-agents/epymarl, src/envs/gymma.py) the runner uses:
    make the key with the remaining env_args, TimeLimit, flatten each agent's observation, pad, all-ones masks."""

    def __init__(self, key, time_limit, seed, **kwargs):
        self._env = gym.wrappers.TimeLimit(gym.make(key, **kwargs), max_episode_steps=time_limit)
        self.n_agents = self._env.unwrapped.n_agents
        self.episode_limit = time_limit
        self.longest_action_space = max(self._env.action_space, key=lambda x: x.n)
        self.longest_observation_space = max(self._env.observation_space, key=lambda x: x.shape)
        try:
            self._env.unwrapped.seed(seed)
        except Exception:  # as EPyMARL: envs without seed() are seeded by reset
            self._env.reset(seed=seed)

    def _flat(self, obs):
        return [gym.spaces.flatten(space, o) for space, o in zip(self._env.observation_space, obs, strict=True)]

    def reset(self):
        obs, _ = self._env.reset()
        self._obs = self._flat(obs)

    def step(self, actions):
        obs, reward, done, truncated, info = self._env.step([int(a) for a in actions])
        self._obs = self._flat(obs)
        return self._obs, reward, done, truncated, info

    def get_obs(self):
        return self._obs

    def get_state(self):
        return np.concatenate(self._obs, axis=0).astype(np.float32)

    def get_state_size(self):
        if hasattr(self._env.unwrapped, "state_size"):
            return self._env.unwrapped.state_size
        return self.n_agents * gym.spaces.flatdim(self.longest_observation_space)

    def get_avail_actions(self):
        return [[1] * self.longest_action_space.n for _ in range(self.n_agents)]


def test_gymma_door_runs_episodes(monkeypatch):
    monkeypatch.syspath_prepend(str(RECIPE))
    env = GymmaLike("smac_hard_epymarl:SMACHardMA-3m-v0", time_limit=60, seed=1)
    assert env.n_agents == 3 and env.longest_action_space.n == 9
    rng = np.random.default_rng(0)
    for _ in range(3):
        env.reset()
        terminated, steps = False, 0
        while not terminated:
            state = env.get_state()
            assert state.shape == (env.get_state_size(),)  # EPyMARL's state: the concatenated observations
            assert len(env.get_obs()) == 3 and len(env.get_avail_actions()) == 3
            actions = rng.integers(0, 9, size=3)  # gymma shows no masks: anything goes, the env replaces
            _, reward, terminated, truncated, info = env.step(actions)
            assert isinstance(reward, float)
            assert all(isinstance(v, (bool, int, float)) for v in info.values())  # the runner sums them
            terminated = terminated or truncated
            steps += 1
        assert steps <= 60
        if info.get("episode_limit"):  # only a timeout: EPyMARL then bootstraps instead of ending the return
            assert steps == 60 and not info["battle_won"]

def test_smac_import_door_runs_episodes():
    """EPyMARL's SMACWrapper (src/envs/smac_wrapper.py) path: ``from smac.env import StarCraft2Env`` with sc2.yaml's
    env_args, a torch tensor of actions per step as the episode runner passes; in a subprocess so that the
    ``smac`` shim stays out of this process's modules."""
    pytest.importorskip("torch")
    code = textwrap.dedent("""
        import torch
        from smac.env import StarCraft2Env
        env_args = dict(continuing_episode=False, difficulty="7", game_version=None, map_name="3m", move_amount=2,
                        obs_all_health=True, obs_instead_of_state=False, obs_last_action=False, obs_own_health=True,
                        obs_pathing_grid=False, obs_terrain_height=False, obs_timestep_number=False,
                        reward_death_value=10, reward_defeat=0, reward_negative_scale=0.5, reward_only_positive=True,
                        reward_scale=True, reward_scale_rate=20, reward_sparse=False, reward_win=200, replay_dir="",
                        replay_prefix="", state_last_action=False, state_timestep_number=False, step_mul=8,
                        seed=12345, heuristic_ai=False, heuristic_rest=False, debug=False, opponent="default")
        env = StarCraft2Env(**env_args)
        info_env = env.get_env_info()
        gen = torch.Generator().manual_seed(0)
        for _ in range(3):
            env.reset()
            terminated = False
            while not terminated:
                state, obs = env.get_state(), env.get_obs()
                assert len(state) == info_env["state_shape"] and len(obs) == info_env["n_agents"]
                avail = torch.tensor(env.get_avail_actions(), dtype=torch.float32)
                actions = torch.multinomial(avail, 1, generator=gen).squeeze(1)
                reward, terminated, info = env.step(actions)
        print("ok", env.get_stats()["battles_game"])
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONPATH": str(RECIPE / "smac_shim")})
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["ok", "3"]


def test_the_smac_door_pays_smacs_reward_unless_told_otherwise():
    """SMAC (and pymarl2's copy of it) pays abs(damage + kills), so enemy regeneration earns reward
    (tests/test_rewards.py works it by hand). The shim stands in for SMAC, so it defaults to that; an explicit
    reward_abs=False still wins."""
    code = textwrap.dedent("""
        from smac.env import StarCraft2Env
        for kwargs in ({}, {"reward_abs": False}):
            env = StarCraft2Env(map_name="3s_vs_3z", **kwargs)
            print(env._core.rewards.options.reward_abs)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONPATH": str(RECIPE / "smac_shim")})
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "False"]
