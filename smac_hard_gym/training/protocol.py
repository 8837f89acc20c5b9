"""The test protocol that ``train``, ``eval`` and the baselines sweep share: which battles are test battles, and how
a win rate's spread is reported.

A test evaluation steps ``min(eval_envs, episodes)`` battles seeded ``TEST_SEED_BASE + b`` (battle b; later episodes
of a battle continue its generator), whatever the run's seed, so ``train``'s evaluations and ``smac-hard-gym eval``
with its defaults play the same test battles. Training battles are seeded ``seed + b`` for b < ``num_envs``
(stable-baselines3 seeds the vector env from the run's seed), and a run's seed is checked to keep them below
``TEST_SEED_BASE`` (:class:`~smac_hard_gym.training.config.TrainConfig`): test and training battles never share a
seed. Every win rate comes with its number of episodes, its standard error and a 95% Wilson interval
(:func:`win_rate_spread`).
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["TEST_SEED_BASE", "eval_seeds", "training_seeds", "win_rate_spread", "format_spread"]

TEST_SEED_BASE = 1_000_000_000  # test battle b is seeded TEST_SEED_BASE + b; training battles stay below it


def eval_seeds(battles: int, base: int = TEST_SEED_BASE) -> list[int]:
    """The seeds of a test evaluation's ``battles`` battles (``min(eval_envs, episodes)`` of them)."""
    return [base + b for b in range(battles)]


def training_seeds(seed: int, num_envs: int) -> list[int]:
    """The seeds of a run's ``num_envs`` training battles: stable-baselines3 seeds the vector env from the run's seed,
    battle b with ``seed + b`` (``VecEnv.seed``)."""
    return [seed + b for b in range(num_envs)]


def win_rate_spread(wins: int, episodes: int, z: float = 1.959964) -> dict[str, Any]:
    """The spread of a win rate over ``episodes`` episodes: ``stderr`` (binomial standard error, sqrt(p(1-p)/n)) and
    ``ci95`` (the 95% Wilson score interval, sensible at 0 and 1 wins too)."""
    if episodes < 1:
        return {"episodes": int(episodes), "stderr": None, "ci95": None}
    p = wins / episodes
    denom = 1 + z * z / episodes
    centre = (p + z * z / (2 * episodes)) / denom
    half = z * math.sqrt(p * (1 - p) / episodes + z * z / (4 * episodes * episodes)) / denom
    return {"episodes": int(episodes), "stderr": math.sqrt(p * (1 - p) / episodes),
            "ci95": [max(0.0, centre - half), min(1.0, centre + half)]}


def format_spread(wins: int, episodes: int) -> str:
    """``"30/32 won, stderr 0.043, 95% CI [0.80, 0.98]"``."""
    spread = win_rate_spread(wins, episodes)
    low, high = spread["ci95"]
    return f"{wins}/{episodes} won, stderr {spread['stderr']:.3f}, 95% Wilson interval [{low:.3f}, {high:.3f}]"
