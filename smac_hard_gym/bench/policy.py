"""The benchmark's policy (uniform over legal actions, compiled) and the loop that steps a vector env with it."""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit


@njit(cache=True)
def _pick_legal(masks, draws, out):
    """out[b, i] = the legal action of rank int(draws[b, i] * legal count) among agent i's legal actions."""
    for b in range(masks.shape[0]):
        for i in range(masks.shape[1]):
            count = 0
            for a in range(masks.shape[2]):
                count += masks[b, i, a] != 0
            rank = int(draws[b, i] * count)
            for a in range(masks.shape[2]):
                if masks[b, i, a] != 0:
                    if rank == 0:
                        out[b, i] = a
                        break
                    rank -= 1


class RandomLegalPolicy:
    """Uniform over each agent's legal actions: one uniform draw per (battle, agent) picks a rank among the legal
    actions (a compiled loop, so that the policy costs little next to the env). Every agent always has a legal action
    (no-op when dead, stop when alive), so the result is always legal.
    """

    def __init__(self, num_envs: int, n_agents: int, n_actions: int, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)
        self.shape = (num_envs, n_agents, n_actions)
        self._draws = np.empty((num_envs, n_agents), dtype=np.float64)

    def __call__(self, masks: np.ndarray) -> np.ndarray:
        """``masks``: bool or int ``(N, n_agents * n_actions)`` or ``(N, n_agents, n_actions)``; int64 (N, n_agents)."""
        self.rng.random(out=self._draws)
        out = np.empty(self.shape[:2], dtype=np.int64)
        _pick_legal(np.ascontiguousarray(masks).reshape(self.shape), self._draws, out)
        return out


class VectorLoop:
    """Steps a gymnasium vector env with the random legal policy; ``step()`` returns the env steps made."""

    def __init__(self, env: Any, n_agents: int, n_actions: int, seed: int) -> None:
        self.env = env
        self.policy = RandomLegalPolicy(env.num_envs, n_agents, n_actions, seed)
        self.episodes = 0

    def step(self) -> int:
        env = self.env
        _, _, terminated, truncated, _ = env.step(self.policy(env.action_masks()))
        self.episodes += int(np.count_nonzero(terminated | truncated))
        return env.num_envs


def warm_up(loop: VectorLoop) -> None:
    loop.step()
    loop.step()
