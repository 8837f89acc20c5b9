"""Each agent's last ``k`` SMAC observations: the memory a feed-forward policy gets from stacked frames.

SMAC's observation has no weapon cooldown, so a policy that sees one step cannot tell when its unit can fire again;
MAPPO's SMAC runs give the policy memory with a recurrent core, or with stacked frames (the SMAC-HARD repository's
feed-forward MAPPO script for 3s_vs_5z: ``--use_stacked_frames --stacked_frames 4``). :class:`UnitFrames` keeps, per
battle, every agent's last ``k`` observations; the envs' ``frame_stack`` option hands them out agent-major, newest
first: agent i's block is ``[obs_i(t), obs_i(t-1), ..., obs_i(t-k+1)]``, so a policy that reads one block per agent
(``SharedUnitPolicy``) sees ``k * obs_size`` values per agent. Frames before an episode's first step are zeros, as
SMAC zeroes a dead agent's observation.
"""

from __future__ import annotations

import numpy as np

__all__ = ["UnitFrames", "check_frame_stack", "MAX_FRAME_STACK"]

MAX_FRAME_STACK = 64  # beyond this a typo is likelier than a wish (SMAC episodes are 60-400 steps)


def check_frame_stack(frame_stack: object) -> int:
    """``frame_stack`` as an int in ``1..MAX_FRAME_STACK``, or a ValueError naming it."""
    if isinstance(frame_stack, bool) or not isinstance(frame_stack, (int, np.integer)) \
            or not 1 <= frame_stack <= MAX_FRAME_STACK:
        raise ValueError(f"frame_stack must be an int in 1..{MAX_FRAME_STACK} (1: no stacking), got {frame_stack!r}")
    return int(frame_stack)


class UnitFrames:
    """The last ``k`` observations of every agent of ``num_battles`` battles (see the module docstring)."""

    def __init__(self, num_battles: int, n_agents: int, obs_size: int, k: int) -> None:
        self.k = check_frame_stack(k)
        # (battle, agent, frame, feature): agent-major, newest frame first, so one battle's row flattens to the layout
        self.frames = np.zeros((num_battles, n_agents, self.k, obs_size), dtype=np.float32)

    def clear(self, rows: np.ndarray) -> None:
        """Start new episodes in ``rows`` (a bool mask or indices of battles): their frames become zeros."""
        self.frames[rows] = 0.0

    def push(self, rows: np.ndarray, obs: np.ndarray) -> None:
        """Add ``obs`` (one ``(n_agents, obs_size)`` row per battle of ``rows``, a bool mask or indices) as those
        battles' newest frame; their oldest is dropped."""
        frames = self.frames
        if self.k > 1:
            frames[rows, :, 1:] = frames[rows, :, :-1]  # fancy indexing reads a copy: no overlap
        frames[rows, :, 0] = obs

    def stacked(self, rows: np.ndarray | None = None) -> np.ndarray:
        """The stacked observations of ``rows`` (default: every battle), ``(len, n_agents, k * obs_size)``, a new
        array, agent-major with each agent's newest frame first."""
        frames = self.frames if rows is None else self.frames[rows]
        return frames.reshape(frames.shape[0], frames.shape[1], -1).copy()

    def advance(self, rows: np.ndarray, obs: np.ndarray, restart: np.ndarray | None = None) -> np.ndarray:
        """An env's step: battles in the bool mask ``restart`` start new episodes, those in ``rows`` take their
        current observation from ``obs`` (every battle's, ``(B, n_agents, obs_size)``); returns every battle's
        stacked observation."""
        if restart is not None and restart.any():
            self.clear(restart)
        if rows.any():
            self.push(rows, obs[rows])
        return self.stacked()
