"""Register smac-hard-gym under EPyMARL's Gymnasium door (``--env-config=gymma``, ``env_args.key``).

EPyMARL's ``gymma`` wrapper calls ``gymnasium.make(env_args.key, **other env_args)``; a key ``"module:Id"`` makes
gymnasium import ``module`` first, so with this file's folder on ``PYTHONPATH``::

    python src/main.py --config=qmix --env-config=gymma with env_args.key="smac_hard_epymarl:SMACHardMA-3m-v0" \
        env_args.time_limit=60

The env it builds is what ``gymma`` expects: ``n_agents``; ``Tuple`` spaces with a ``Box`` observation and a
``Discrete`` action per agent; ``step(list of ints) -> (obs tuple, team reward, terminated, truncated, info)`` with
numbers-only info (``battle_won``, ``dead_allies``, ``dead_enemies``, ``invalid_actions`` and ``episode_limit`` when
the map's limit ended the episode, which EPyMARL reads to bootstrap). ``gymma`` gives the learner no action masks
(every action looks available to it) and uses the concatenated observations as the state, so unavailable actions
are replaced here by each agent's first legal one (no-op when dead, stop when alive) and counted in
``info["invalid_actions"]``. With masks and SMAC's real global state, use the ``smac`` import door instead (README).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from smac_hard_gym.engine.state import RED
from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.maps import list_maps, load_map
from smac_hard_gym.smac.actions import ResetNeededError, validate_actions
from smac_hard_gym.smac.features import RED_WON, SmacOptions

__all__ = ["SMACHardMultiAgentEnv", "register", "env_key"]


def env_key(map_name: str) -> str:
    """The ``env_args.key`` of a map."""
    return f"smac_hard_epymarl:SMACHardMA-{map_name}-v0"


class SMACHardMultiAgentEnv(gym.Env):
    """One battle with red's units as a tuple of agents, for EPyMARL's ``gymma`` wrapper (see the module doc).

    Keywords: ``map_name``, ``opponent`` (default ``"default"``, the map's SMAC-HARD pool), ``opponent_probs``,
    ``step_mul`` and any SMAC observation/reward option (``reward_sparse=True``, ...).
    """

    metadata = {"render_modes": []}

    def __init__(self, map_name: str = "3m", opponent: Any = "default", opponent_probs: Any = None,
                 step_mul: int = 8, **smac_options: Any) -> None:
        self.core = TwoPlayerCore(map_name, 1, opponent=opponent, opponent_probs=opponent_probs, step_mul=step_mul,
                                  options=SmacOptions.from_kwargs(["map_name", "opponent", "opponent_probs",
                                                                   "step_mul"], **smac_options),
                                  encode_state=False)
        feats = self.core.features[RED]
        self.n_agents, self.n_actions = feats.n_agents, feats.n_actions
        self.episode_limit = self.core.episode_limit
        self.observation_space = spaces.Tuple(
            [spaces.Box(-1.0, 1.0, (feats.obs_size,), np.float32) for _ in range(self.n_agents)])
        self.action_space = spaces.Tuple([spaces.Discrete(self.n_actions) for _ in range(self.n_agents)])
        self._needs_reset = True

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[tuple, dict]:
        super().reset(seed=seed)
        self.core.reset(seed=seed)
        self._needs_reset = False
        return tuple(self.core.encode(RED)[1][0]), {}

    def step(self, actions: Any) -> tuple[tuple, float, bool, bool, dict[str, Any]]:
        if self._needs_reset:
            raise ResetNeededError("call reset() before step(): the episode is over (or never started)")
        acts = validate_actions([int(a) for a in actions], (self.n_agents,), self.n_actions, "red")
        result = self.core.step(acts[None], replace_invalid=True, checked=True)
        terminated, truncated = bool(result.terminated[0]), bool(result.truncated[0] or result.restarted[0])
        self._needs_reset = terminated or truncated
        info: dict[str, Any] = {"battle_won": bool(result.outcome[0] == RED_WON),
                                "dead_allies": int(result.dead_red[0]), "dead_enemies": int(result.dead_blue[0]),
                                "invalid_actions": int(result.replaced[0])}
        if truncated and not terminated:
            info["episode_limit"] = True
        return tuple(result.obs[0]), float(result.reward[0, RED]), terminated, truncated, info

    def close(self) -> None:
        self.core.close()


def register() -> list[str]:
    """Register ``SMACHardMA-<map>-v0`` for every map (kept if already there); returns the ids."""
    ids = []
    for name in list_maps():
        env_id = f"SMACHardMA-{name}-v0"
        if env_id not in gym.registry:
            gym.register(env_id, entry_point=SMACHardMultiAgentEnv, kwargs={"map_name": name},
                         max_episode_steps=load_map(name).episode_limit)
        ids.append(env_id)
    return ids


register()
