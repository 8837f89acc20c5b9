"""The learner's side of a battle batch as one joint agent: its gymnasium spaces, and the one translation of a core
step's arrays to what gymnasium returns (observations, rewards, terminated, truncated, info values).

A pure reshaper: it reads the arrays a :class:`~smac_hard_gym.envs.core.StepResult` (or ``core.encode``) already
holds and never calls back into the core. :class:`~smac_hard_gym.envs.gym_env.SMACHardEnv` takes row 0 of what it
returns; :class:`~smac_hard_gym.envs.vector.NativeVectorEnv` takes every row and adds autoreset.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from smac_hard_gym.engine.units import STATS, S
from smac_hard_gym.smac.features import RED_WON, SideFeatures
from smac_hard_gym.smac.frame_stack import check_frame_stack

__all__ = ["JointView", "Transition", "OBS_MODES", "OBS_LOW"]

OBS_MODES = ("joint", "joint+state", "dict")
_ONE_BYTE = frozenset((bool, np.bool_, np.int8, np.uint8))  # mask dtypes that share bool's layout
OBS_LOW = -1.0  # SMAC features are ratios in [-1, 1] (offsets / sight range, health / max, one-hots); see state_high


def state_high(feats: SideFeatures) -> float:
    """Upper bound of the global state: its cooldown column (cooldown / SMAC's normaliser) exceeds 1 for some units
    (hydralisk: 13.2 loops over SMAC's 10), so it is the largest such ratio among the side's units, at least 1."""
    utype = feats.utype[feats.own]
    timer_max = np.where(feats.own_healer, STATS[utype, S["energy_max"]], STATS[utype, S["cooldown"]])
    return max(1.0, float((timer_max / feats.own_max_cooldown).max()))


class Transition(NamedTuple):
    """One step of a batch as gymnasium sees it (arrays over the battles)."""

    obs: Any  # (B, dim) float32, or a dict of (B, ...) arrays in "dict" mode
    reward: np.ndarray  # float32 (B,): red's reward
    terminated: np.ndarray  # bool (B,): a result (win, loss or draw); never for a restarted game
    truncated: np.ndarray  # bool (B,): the episode limit was reached (also on a step with a result), or restarted
    info: dict[str, np.ndarray]  # battle_won, dead_allies, dead_enemies, invalid_actions, restarted: (B,) each


class JointView:
    """Spaces and batched encodings of one side as a joint agent (see the module docstring).

    ``obs_mode`` picks the observation: ``"joint"`` (every agent's SMAC observation, flattened agent-major),
    ``"joint+state"`` (that, then SMAC's global state) or ``"dict"`` (``obs`` (n_agents, obs_size), ``state``
    (state_size,) and ``action_mask`` (n_agents, n_actions) int8). ``episode_limit``: the step count at which an
    episode is truncated. ``frame_stack``: each agent's observation is its last ``frame_stack`` SMAC observations
    (:mod:`~smac_hard_gym.smac.frame_stack`; the env keeps them), so ``obs_size`` is that many times SMAC's.
    """

    def __init__(self, feats: SideFeatures, obs_mode: str = "joint", episode_limit: int | None = None,
                 frame_stack: int = 1) -> None:
        if obs_mode not in OBS_MODES:
            raise ValueError(f"obs_mode must be one of {OBS_MODES}, got {obs_mode!r}")
        self.obs_mode = obs_mode
        self.needs_state = obs_mode != "joint"
        self.episode_limit = feats.episode_limit if episode_limit is None else int(episode_limit)
        self.n_agents, self.n_actions = feats.n_agents, feats.n_actions
        self.frame_stack = check_frame_stack(frame_stack)
        self.obs_size, self.state_size = feats.obs_size * self.frame_stack, feats.state_size
        self.mask_size = self.n_agents * self.n_actions
        self.action_space = spaces.MultiDiscrete(np.full(self.n_agents, self.n_actions, dtype=np.int64))
        joint = self.n_agents * self.obs_size
        high_state = state_high(feats)
        if obs_mode == "joint":
            self.observation_space: spaces.Space = spaces.Box(OBS_LOW, 1.0, (joint,), np.float32)
        elif obs_mode == "joint+state":
            high = np.concatenate([np.ones(joint), np.full(self.state_size, high_state)]).astype(np.float32)
            self.observation_space = spaces.Box(np.full_like(high, OBS_LOW), high, dtype=np.float32)
        else:
            self.observation_space = spaces.Dict({
                "obs": spaces.Box(OBS_LOW, 1.0, (self.n_agents, self.obs_size), np.float32),
                "state": spaces.Box(OBS_LOW, high_state, (self.state_size,), np.float32),
                "action_mask": spaces.Box(0, 1, (self.n_agents, self.n_actions), np.int8),
            })

    def observation(self, avail: np.ndarray, obs: np.ndarray, state: np.ndarray | None) -> Any:
        """The batched observation of an encoding (masks, observations, state): ``(B, dim)`` float32, or a dict of
        ``(B, ...)`` arrays in ``"dict"`` mode."""
        batch = obs.shape[0]
        if self.obs_mode == "joint":
            return obs.reshape(batch, -1)
        if self.obs_mode == "joint+state":
            return np.concatenate([obs.reshape(batch, -1), state], axis=1)
        return {"obs": obs, "state": state, "action_mask": avail.view(np.int8).copy()}

    def masks(self, avail: np.ndarray, dtype: type = bool) -> np.ndarray:
        """Fresh ``(B, n_agents * n_actions)`` array of an encoding's masks, agent-major (bool, or ``dtype``)."""
        masks = avail.reshape(-1, self.mask_size)
        # bool and int8 share a layout: a plain copy is several times faster than a conversion.
        return masks.view(dtype).copy() if dtype in _ONE_BYTE else masks.astype(dtype)

    def translate(self, result: Any, obs: np.ndarray | None = None) -> Transition:
        """A core :class:`~smac_hard_gym.envs.core.StepResult` as gymnasium's step values, per battle (``obs``: the
        agents' observations to hand out instead of the result's, the stacked frames under ``frame_stack``).

        Truncated at the limit even when the battle also ended on that step, as gymnasium's ``TimeLimit`` says; a
        game the sc2 backend lost and restarted ended without a result: truncated, not terminated, and flagged.
        """
        restarted = result.restarted
        terminated = result.terminated & ~restarted
        truncated = result.stepped & ((result.episode_step >= self.episode_limit) | restarted)
        info = {"battle_won": result.outcome == RED_WON, "dead_allies": result.dead_red,
                "dead_enemies": result.dead_blue, "invalid_actions": result.replaced, "restarted": restarted}
        obs = result.obs if obs is None else obs
        return Transition(self.observation(result.avail, obs, result.state), result.reward[:, 0],
                          terminated, truncated, info)
