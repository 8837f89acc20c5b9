"""Moved: the duel runner plays on the two-player core, above this package: ``smac_hard_gym.envs.duel``."""

raise ImportError("smac_hard_gym.opponents.duel moved to smac_hard_gym.envs.duel (one runner on the two-player core "
                  "for duels and recordings): from smac_hard_gym.envs.duel import run_duel, DuelResult")
