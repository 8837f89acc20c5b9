"""Known solutions played out: :func:`check_claim` runs a claim of ``opponents/known_solutions.py`` (and its
comparison) as duels on the two-player core (:func:`smac_hard_gym.envs.duel.run_duel`: episode ``e`` is a battle
seeded ``seed + e``)."""

from __future__ import annotations

from smac_hard_gym.envs.duel import run_duel
from smac_hard_gym.opponents.known_solutions import Claim, Verdict, make_controller

__all__ = ["check_claim", "Verdict"]


def check_claim(claim: Claim, episodes: int = 32, seed: int = 0) -> Verdict:
    """Play ``episodes`` seeded episodes of the claim (and of its comparison) on the embedded engine."""

    def rate(red: str) -> float:
        return run_duel(claim.map_name, make_controller(red), claim.blue, episodes=episodes, seed=seed,
                        guard=False).red_win_rate

    other = rate(claim.better_than) if claim.better_than is not None else None
    return Verdict(claim, rate(claim.red), other, episodes)
