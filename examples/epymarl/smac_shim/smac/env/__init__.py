"""``smac.env`` for EPyMARL and pymarl: smac-hard-gym's SMAC-compatible ``StarCraft2Env`` (embedded engine, no SC2).

Every ``env_args`` key of EPyMARL's ``sc2.yaml`` is a SMAC constructor argument it accepts; smac-hard-gym's own
(``opponent``, ``opponent_probs``, ``mode``, ``backend``) pass through ``env_args`` too.

It stands in for SMAC, so it pays SMAC's reward: with ``reward_only_positive`` SMAC takes ``abs(damage + kills)``,
which also pays for enemy regeneration and healing (``reward_abs=True``; smac-hard-gym's own default is
SMAC-HARD's ``max(0, .)``). sacred refuses ``env_args`` keys that ``sc2.yaml`` lacks, so the default is set here.
"""

from functools import partialmethod

from smac_hard_gym import StarCraft2Env as _StarCraft2Env

__all__ = ["StarCraft2Env", "MultiAgentEnv"]

MultiAgentEnv = object  # SMAC exports a base class of this name; nothing here subclasses it


class StarCraft2Env(_StarCraft2Env):
    """smac-hard-gym's ``StarCraft2Env`` with SMAC's reward (``reward_abs=True``) unless told otherwise."""

    __init__ = partialmethod(_StarCraft2Env.__init__, reward_abs=True)
