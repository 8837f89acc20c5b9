"""``smac.env`` for EPyMARL and pymarl: smac-hard-gym's SMAC-compatible ``StarCraft2Env`` (embedded engine, no SC2).

Every ``env_args`` key of EPyMARL's ``sc2.yaml`` is a SMAC constructor argument it accepts; smac-hard-gym's own
(``opponent``, ``opponent_probs``, ``mode``, ``backend``) pass through ``env_args`` too.
"""

from smac_hard_gym import StarCraft2Env

__all__ = ["StarCraft2Env", "MultiAgentEnv"]

MultiAgentEnv = object  # SMAC exports a base class of this name; nothing here subclasses it
