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

from smac_hard_gym.engine.state import CMD_ATTACK, CMD_HEAL, CMD_MOVE, CMD_NOOP, CMD_STOP, BattleState, Commands
from smac_hard_gym.features import N_ACTIONS_NO_ATTACK, SHOOT_RANGE, SIDE_NAMES, Geometry, SideFeatures

__all__ = ["InvalidActionError", "available_actions", "check_actions", "decode_actions", "action_name"]

ACTION_NOOP, ACTION_STOP = 0, 1
# (dx, dy) unit steps of actions 2..5: north, south, east, west.
MOVE_STEPS = np.array([(0.0, 1.0), (0.0, -1.0), (1.0, 0.0), (-1.0, 0.0)])
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


def available_actions(feats: SideFeatures, state: BattleState, geo: Geometry | None = None,
                      out: np.ndarray | None = None) -> np.ndarray:
    """Available actions of every agent of ``feats``'s side: bool ``(B, n_agents, n_actions)``."""
    if geo is None or (feats.any_healer and geo.ally_dist is None):
        geo = feats.geometry(state, allies=feats.any_healer)
    if out is None:
        out = np.zeros((state.alive.shape[0], feats.n_agents, feats.n_actions), dtype=bool)
    alive = geo.own_alive
    out[..., ACTION_NOOP] = ~alive
    out[..., ACTION_STOP] = alive

    # Probe cells of the four moves at once: (B, n, 4).
    half = feats.move_amount / 2.0
    cx = np.trunc(state.x[:, feats.own, None] + MOVE_STEPS[:, 0] * half).astype(np.int64)
    cy = np.trunc(state.y[:, feats.own, None] + MOVE_STEPS[:, 1] * half).astype(np.int64)
    inside = (cx >= 0) & (cx < feats.map_x) & (cy >= 0) & (cy < feats.map_y)
    pathable = feats.pathable[np.where(inside, cx, 0), np.where(inside, cy, 0)]
    out[..., 2:N_ACTIONS_NO_ATTACK] = alive[..., None] & inside & pathable

    targets = out[..., N_ACTIONS_NO_ATTACK:]
    np.logical_and(alive[:, :, None] & geo.enemy_alive[:, None, :], geo.enemy_dist <= SHOOT_RANGE, out=targets)
    if feats.any_healer:
        k = feats.n_heal_targets
        healable = (alive[:, :, None] & alive[:, None, :] & (geo.ally_dist <= SHOOT_RANGE)
                    & ~feats.own_healer[None, None, :])[:, :, :k]
        healers = feats.own_healer
        targets[:, healers, :] = False
        targets[:, healers, :k] = healable[:, healers]
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
    check = np.ones(batch, dtype=bool) if active is None else np.asarray(active, dtype=bool)
    in_range = (acts >= 0) & (acts < feats.n_actions)
    ok = in_range & avail[np.arange(batch)[:, None], np.arange(n)[None, :], np.clip(acts, 0, feats.n_actions - 1)]
    bad = np.argwhere(~ok & check[:, None])
    if len(bad):
        b, i = (int(v) for v in bad[0])
        a = int(acts[b, i])
        where = f"battle {b}, " if batch > 1 else ""
        who = f"{where}{SIDE_NAMES[feats.side]} agent {i}"
        if not in_range[b, i]:
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
    own = feats.own
    rows = np.flatnonzero(active)
    acts = actions[rows]
    kind = np.full(acts.shape, CMD_NOOP, dtype=np.int8)
    target = np.full(acts.shape, -1, dtype=np.int32)
    x = state.x[rows, own].copy()
    y = state.y[rows, own].copy()

    kind[acts == ACTION_STOP] = CMD_STOP
    is_move = (acts >= 2) & (acts < N_ACTIONS_NO_ATTACK)
    kind[is_move] = CMD_MOVE
    step = MOVE_STEPS[np.clip(acts - 2, 0, 3)] * feats.move_amount
    x = np.where(is_move, x + step[..., 0], x)
    y = np.where(is_move, y + step[..., 1], y)

    is_target = acts >= N_ACTIONS_NO_ATTACK
    heals = is_target & feats.own_healer[None, :]
    attacks = is_target & ~heals
    j = acts - N_ACTIONS_NO_ATTACK
    kind[attacks] = CMD_ATTACK
    target[attacks] = feats.enemy.start + j[attacks]
    kind[heals] = CMD_HEAL
    target[heals] = own.start + j[heals]

    commands.kind[rows, own] = kind
    commands.target[rows, own] = target
    commands.x[rows, own] = x
    commands.y[rows, own] = y
