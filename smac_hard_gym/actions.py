"""SMAC's discrete actions: which are available, and how a choice becomes an engine command.

Per agent, ``n_actions = 6 + n_enemies`` (``shared/reference/smac_interface.md`` §2):

====  ====================================  ===========================================================
id    meaning                               available when
====  ====================================  ===========================================================
0     no-op                                 the agent is dead (then it is the only choice)
1     stop                                  alive
2-5   move north / south / east / west      alive and the probe cell at move_amount/2 is pathable
6+j   attack enemy j                        alive, enemy j alive, centre distance <= 6
6+j   heal ally j (medivacs)                alive, ally j alive and not a medivac, centre distance <= 6
====  ====================================  ===========================================================

A move goes to ``(x, y +- move_amount)`` or ``(x +- move_amount, y)``; every command replaces the current order.
The probe cell is ``(int(x), int(y + move_amount / 2))`` and so on, with Python's ``int`` truncation toward zero.
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.engine.state import BattleState, Commands
from smac_hard_gym.feature_kernels import (
    N_ACTIONS_NO_ATTACK,
    available_actions_batch,
    decode_actions_batch,
    first_invalid_action,
)
from smac_hard_gym.features import SIDE_NAMES, SideFeatures

__all__ = ["InvalidActionError", "available_actions", "check_actions", "decode_actions", "action_name"]

ACTION_NOOP, ACTION_STOP = 0, 1
_MOVE_WORDS = ("move north", "move south", "move east", "move west")


class InvalidActionError(ValueError):
    """An agent chose an action that is out of range or not available (the message names agent and action)."""


def action_name(action: int, healer: bool = False) -> str:
    """Readable name of a SMAC action id."""
    if action == ACTION_NOOP:
        return "no-op"
    if action == ACTION_STOP:
        return "stop"
    if action < N_ACTIONS_NO_ATTACK:
        return _MOVE_WORDS[action - 2]
    j = action - N_ACTIONS_NO_ATTACK
    return f"heal ally {j}" if healer else f"attack enemy {j}"


def available_actions(feats: SideFeatures, state: BattleState, out: np.ndarray | None = None,
                      rows: np.ndarray | None = None) -> np.ndarray:
    """Available actions of every agent of ``feats``'s side: bool ``(B, n_agents, n_actions)`` (of battles ``rows``
    only, when given: ``(len(rows), n_agents, n_actions)``)."""
    rows = feats.all_rows(state) if rows is None else np.ascontiguousarray(rows, dtype=np.int64)
    if out is None:
        out = np.empty((len(rows), feats.n_agents, feats.n_actions), dtype=bool)
    available_actions_batch(rows, state.x, state.y, state.alive, feats.own.start, feats.enemy.start, feats.own_healer,
                            feats.heal_target_ok, feats.pathable, feats.move_amount / 2.0, feats.n_heal_targets, out)
    return out


def check_actions(feats: SideFeatures, actions: np.ndarray, avail: np.ndarray,
                  active: np.ndarray | None = None) -> np.ndarray:
    """Validate a side's actions ``(B, n_agents)`` against ``avail``; returns them as int64.

    Raises :class:`InvalidActionError` naming the first offending agent, its action and the available ones.
    Battles with ``active[b]`` False are not checked.
    """
    batch, n = avail.shape[0], feats.n_agents
    try:
        acts = np.asarray(actions, dtype=np.int64)
    except (TypeError, ValueError, OverflowError):
        raise InvalidActionError(f"{SIDE_NAMES[feats.side]} actions must be integers, got {actions!r}") from None
    if acts.shape != (batch, n):
        raise InvalidActionError(f"{SIDE_NAMES[feats.side]} actions must have shape ({batch}, {n}) "
                                 f"(battles, agents), got {acts.shape}")
    check = np.ones(batch, dtype=bool) if active is None else np.ascontiguousarray(active, dtype=bool)
    acts = np.ascontiguousarray(acts)
    bad = first_invalid_action(acts, avail, check)
    if bad >= 0:
        b, i = divmod(int(bad), n)
        a = int(acts[b, i])
        where = f"battle {b}, " if batch > 1 else ""
        who = f"{where}{SIDE_NAMES[feats.side]} agent {i}"
        if not 0 <= a < feats.n_actions:
            raise InvalidActionError(f"{who}: action {a} is out of range; actions are 0..{feats.n_actions - 1}")
        healer = bool(feats.own_healer[i])
        allowed = [int(v) for v in np.flatnonzero(avail[b, i])]
        names = ", ".join(f"{v} ({action_name(v, healer)})" for v in allowed)
        raise InvalidActionError(f"{who}: action {a} ({action_name(a, healer)}) is not available; "
                                 f"available: {names}")
    return acts


def decode_actions(feats: SideFeatures, state: BattleState, actions: np.ndarray, commands: Commands,
                   active: np.ndarray) -> None:
    """Write the engine commands of validated ``actions`` ``(B, n_agents)`` into ``commands`` for this side's slots
    in battles with ``active[b]`` (other battles' commands are left as they are)."""
    decode_actions_batch(np.ascontiguousarray(actions, dtype=np.int64), np.ascontiguousarray(active, dtype=bool),
                         state.x, state.y, feats.own.start, feats.enemy.start, feats.own_healer, feats.move_amount,
                         commands.kind, commands.target, commands.x, commands.y)
