"""Numba kernels of the SMAC layer: available actions, observations, global state, outcome and rewards, and action
checking and decoding, each one pass over a batch of battles.

The formulas are those documented in :mod:`smac_hard_gym.smac.features` and :mod:`smac_hard_gym.smac.actions`,
which hold the per-side constants and call these kernels. Written as loops rather than numpy because a numpy step
made some twenty array passes and temporaries per feature block: half of a vector env step, and nearly all of a
one-battle step. Each kernel takes plain arrays (never the state tuple) and writes into caller-owned outputs.

Float rounding follows the numpy formulation: ratios are computed in float64 and stored as float32, and offsets
are scaled by float32's 1/9, as SMAC's float32 arrays do.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from smac_hard_gym.engine.state import CMD_ATTACK, CMD_HEAL, CMD_MOVE, CMD_NOOP, CMD_STOP, NO_UNIT

__all__ = [
    "SHOOT_RANGE", "SIGHT_RANGE", "N_ACTIONS_NO_ATTACK", "RUNNING", "RED_WON", "BLUE_WON", "DRAW",
    "OBS_FLAGS", "OBS_LAYOUT", "STATE_FLAGS", "STATE_LAYOUT", "REWARD_VALUES", "REWARD_FLAGS", "pack", "bind",
    "available_actions_batch", "observations_batch", "global_state_batch", "encode_batch",
    "finish_encode", "first_invalid_action", "check_decode_batch",
]

SHOOT_RANGE = 6.0  # SMAC: attack/heal available within this centre distance (<=), every unit
SIGHT_RANGE = 9.0  # SMAC: units closer than this (<) are observed, every unit
N_ACTIONS_NO_ATTACK = 6  # no-op, stop, move north/south/east/west

# Battle outcomes.
RUNNING, RED_WON, BLUE_WON, DRAW = 0, 1, 2, 3

# Offsets scaled by sight range: SMAC divides float32 arrays, so the factor is float32's 1/9.
_SIGHT_SCALE = float(np.float32(1.0) / np.float32(SIGHT_RANGE))
# Probe directions of moves 2..5 (north, south, east, west) and of the pathing/height features.
_MOVE_DX = np.array([0.0, 0.0, 1.0, -1.0])
_MOVE_DY = np.array([1.0, -1.0, 0.0, 0.0])

# The small vectors of options and offsets the kernels take: each is built by name with :func:`pack` from one of
# these tables, and the kernels read it through the index constants unpacked from the same table.
OBS_FLAGS = ("all_health", "own_health", "shield_ally", "shield_enemy", "last_action", "pathing", "height",
             "timestep")
_O_ALL_HEALTH, _O_OWN_HEALTH, _O_SHIELD_ALLY, _O_SHIELD_ENEMY, _O_LAST_ACTION, _O_PATHING, _O_HEIGHT, \
    _O_TIMESTEP = range(len(OBS_FLAGS))
OBS_LAYOUT = ("enemy_offset", "ally_offset", "own_offset", "enemy_feats", "ally_feats")
_L_ENEMY_OFFSET, _L_ALLY_OFFSET, _L_OWN_OFFSET, _L_ENEMY_FEATS, _L_ALLY_FEATS = range(len(OBS_LAYOUT))
STATE_FLAGS = ("shield_ally", "shield_enemy", "last_action", "timestep")
_S_SHIELD_ALLY, _S_SHIELD_ENEMY, _S_LAST_ACTION, _S_TIMESTEP = range(len(STATE_FLAGS))
STATE_LAYOUT = ("ally_feats", "enemy_feats", "enemy_offset", "action_offset", "n_actions")
_T_ALLY_FEATS, _T_ENEMY_FEATS, _T_ENEMY_OFFSET, _T_ACTION_OFFSET, _T_N_ACTIONS = range(len(STATE_LAYOUT))
FRAME = ("centre_x", "centre_y", "width", "height")
REWARD_VALUES = ("death_value", "win", "defeat", "negative_scale")
_R_DEATH_VALUE, _R_WIN, _R_DEFEAT, _R_NEGATIVE_SCALE = range(len(REWARD_VALUES))
REWARD_FLAGS = ("sparse", "only_positive")
_R_SPARSE, _R_ONLY_POSITIVE = range(len(REWARD_FLAGS))

kernel = njit(cache=True, error_model="numpy")
inline = njit(cache=True, inline="always", error_model="numpy")


def pack(table: tuple[str, ...], dtype: type = np.int64, **values: float) -> np.ndarray:
    """The vector of ``values`` in the order of ``table`` (OBS_FLAGS, STATE_LAYOUT, ...): every name, no other."""
    if set(values) != set(table):
        raise KeyError(f"pack needs exactly {table}; missing {sorted(set(table) - set(values))}, "
                       f"unknown {sorted(set(values) - set(table))}")
    return np.array([values[name] for name in table], dtype=dtype)


def bind(function: object, constants: dict[str, object]) -> tuple:
    """The constant arguments of a kernel, by name: its parameters from the first one named in ``constants`` to the
    last, looked up there. Call it as ``function(*call_arguments, *bind(function, constants))``.

    Every kernel here takes its per-call arrays first and its per-side constants (SideFeatures.constants, plus the
    core's outcome and reward constants) last, so no caller orders those by hand.
    """
    import inspect

    names = list(inspect.signature(getattr(function, "py_func", function)).parameters)
    first = next((k for k, name in enumerate(names) if name in constants), len(names))
    missing = [name for name in names[first:] if name not in constants]
    if missing:
        raise KeyError(f"{getattr(function, '__name__', function)} needs the constants {missing}")
    return tuple(constants[name] for name in names[first:])


@inline
def _distance(x0, y0, x1, y1):
    dx = x1 - x0
    dy = y1 - y0
    return math.sqrt(dx * dx + dy * dy)


@inline
def _cell_value(grid, fx, fy, outside):
    """``grid`` at the cell of (fx, fy) (truncated toward zero, as Python's int), ``outside`` off the map."""
    cx = int(fx)
    cy = int(fy)
    if cx < 0 or cx >= grid.shape[0] or cy < 0 or cy >= grid.shape[1]:
        return outside
    return grid[cx, cy]


# ---------------------------------------------------------------------------------------------------------------
# Available actions.


@inline
def _avail_battle(k, b, x, y, alive, own_lo, enemy_lo, healer, heal_target_ok, pathable, half_move, n_heal_targets,
                  out):
    n = out.shape[1]
    m = out.shape[2] - N_ACTIONS_NO_ATTACK
    for i in range(n):
        u = own_lo + i
        live = alive[b, u]
        row = out[k, i]
        row[0] = not live
        row[1] = live
        xi, yi = x[b, u], y[b, u]
        for d in range(4):
            row[2 + d] = live and _cell_value(pathable, xi + _MOVE_DX[d] * half_move, yi + _MOVE_DY[d] * half_move,
                                              False)
        if healer[i]:
            for j in range(m):
                row[N_ACTIONS_NO_ATTACK + j] = False
            for j in range(n_heal_targets):
                v = own_lo + j
                row[N_ACTIONS_NO_ATTACK + j] = (live and alive[b, v] and heal_target_ok[j]
                                                and _distance(xi, yi, x[b, v], y[b, v]) <= SHOOT_RANGE)
        else:
            for j in range(m):
                e = enemy_lo + j
                row[N_ACTIONS_NO_ATTACK + j] = (live and alive[b, e]
                                                and _distance(xi, yi, x[b, e], y[b, e]) <= SHOOT_RANGE)


@kernel
def available_actions_batch(rows, x, y, alive, out, own_lo, enemy_lo, healer, heal_target_ok, pathable, half_move,
                            n_heal_targets):
    """Write the available actions of every agent of battles ``rows`` into ``out`` (bool (len(rows), n,
    n_actions)); see smac_hard_gym.smac.actions."""
    for k in range(rows.shape[0]):
        _avail_battle(k, rows[k], x, y, alive, own_lo, enemy_lo, healer, heal_target_ok, pathable, half_move,
                      n_heal_targets, out)


# ---------------------------------------------------------------------------------------------------------------
# Observations.


@inline
def _observe_battle(k, b, x, y, alive, health, shield, avail, last_action, episode_step, own_lo, enemy_lo,
                    own_health_max, own_shield_max, enemy_health_max, enemy_shield_max, own_onehot, enemy_onehot,
                    flags, pathable, heights, probe_dx, probe_dy, layout, episode_limit, out):
    n, obs_size = out.shape[1], out.shape[2]
    m = enemy_health_max.shape[0]
    bits = own_onehot.shape[1]
    enemy_offset, ally_offset, own_offset = layout[_L_ENEMY_OFFSET], layout[_L_ALLY_OFFSET], layout[_L_OWN_OFFSET]
    enemy_feats, ally_feats = layout[_L_ENEMY_FEATS], layout[_L_ALLY_FEATS]
    for i in range(n):
        o = out[k, i]
        for c in range(obs_size):
            o[c] = 0.0
        if flags[_O_TIMESTEP]:
            o[obs_size - 1] = episode_step[b] / episode_limit
        u = own_lo + i
        if not alive[b, u]:
            continue
        xi, yi = x[b, u], y[b, u]

        # Move block: the four move actions, then the probed pathing and heights.
        for d in range(4):
            o[d] = avail[k, i, 2 + d]
        col = 4
        if flags[_O_PATHING] or flags[_O_HEIGHT]:
            cx0, cy0 = int(xi), int(yi)
            if flags[_O_PATHING]:
                for p in range(8):
                    o[col + p] = _cell_value(pathable, cx0 + probe_dx[p], cy0 + probe_dy[p], True)
                col += 8
            if flags[_O_HEIGHT]:
                for p in range(9):
                    o[col + p] = _cell_value(heights, cx0 + probe_dx[p], cy0 + probe_dy[p], np.float32(1.0))

        # Enemies within sight.
        for j in range(m):
            e = enemy_lo + j
            if not alive[b, e]:
                continue
            dx, dy = x[b, e] - xi, y[b, e] - yi
            d = math.sqrt(dx * dx + dy * dy)
            if not d < SIGHT_RANGE:
                continue
            c = enemy_offset + j * enemy_feats
            o[c] = avail[k, i, N_ACTIONS_NO_ATTACK + j]
            o[c + 1] = d * _SIGHT_SCALE
            o[c + 2] = dx * _SIGHT_SCALE
            o[c + 3] = dy * _SIGHT_SCALE
            c += 4
            if flags[_O_ALL_HEALTH]:
                o[c] = health[b, e] / enemy_health_max[j]
                c += 1
                if flags[_O_SHIELD_ENEMY]:
                    o[c] = shield[b, e] / enemy_shield_max[j]
                    c += 1
            for t in range(bits):
                o[c + t] = enemy_onehot[j, t]

        # The other agents of this side, in id order.
        rank = 0  # the ally's row among the others
        for j in range(n):
            if j == i:
                continue
            c = ally_offset + rank * ally_feats
            rank += 1
            v = own_lo + j
            if not alive[b, v]:
                continue
            dx, dy = x[b, v] - xi, y[b, v] - yi
            d = math.sqrt(dx * dx + dy * dy)
            if not d < SIGHT_RANGE:
                continue
            o[c] = 1.0
            o[c + 1] = d * _SIGHT_SCALE
            o[c + 2] = dx * _SIGHT_SCALE
            o[c + 3] = dy * _SIGHT_SCALE
            c += 4
            if flags[_O_ALL_HEALTH]:
                o[c] = health[b, v] / own_health_max[j]
                c += 1
                if flags[_O_SHIELD_ALLY]:
                    o[c] = shield[b, v] / own_shield_max[j]
                    c += 1
            for t in range(bits):
                o[c + t] = own_onehot[j, t]
            c += bits
            if flags[_O_LAST_ACTION]:
                a = last_action[b, j]
                if a >= 0:
                    o[c + a] = 1.0

        # Own block.
        c = own_offset
        if flags[_O_OWN_HEALTH]:
            o[c] = health[b, u] / own_health_max[i]
            c += 1
            if flags[_O_SHIELD_ALLY]:
                o[c] = shield[b, u] / own_shield_max[i]
                c += 1
        for t in range(bits):
            o[c + t] = own_onehot[i, t]


@kernel
def observations_batch(rows, x, y, alive, health, shield, avail, last_action, episode_step, out, own_lo, enemy_lo,
                       own_health_max, own_shield_max, enemy_health_max, enemy_shield_max, own_onehot, enemy_onehot,
                       obs_flags, pathable, heights, probe_dx, probe_dy, obs_layout, episode_limit):
    """Write the observations of every agent of battles ``rows`` into ``out`` (float32 (len(rows), n,
    obs_size)); ``avail`` is aligned with ``out``. ``obs_flags`` follow OBS_FLAGS, ``obs_layout`` OBS_LAYOUT.

    One thread: writing the observations is bound by memory bandwidth, and a second thread measured no faster (3m,
    4096 battles: 0.58 ms on one thread, 0.75 ms on two).
    """
    for k in range(rows.shape[0]):
        _observe_battle(k, rows[k], x, y, alive, health, shield, avail, last_action, episode_step, own_lo, enemy_lo,
                        own_health_max, own_shield_max, enemy_health_max, enemy_shield_max, own_onehot,
                        enemy_onehot, obs_flags, pathable, heights, probe_dx, probe_dy, obs_layout, episode_limit, out)


# ---------------------------------------------------------------------------------------------------------------
# Global state.


@inline
def _state_battle(k, b, x, y, alive, health, shield, energy, cooldown, last_action, episode_step, own_lo, enemy_lo,
                  own_health_max, own_shield_max, enemy_health_max, enemy_shield_max, own_onehot, enemy_onehot, healer,
                  max_cooldown, frame, flags, layout, episode_limit, out):
    size = out.shape[1]
    n, m = own_health_max.shape[0], enemy_health_max.shape[0]
    bits = own_onehot.shape[1]
    cx, cy, width, height = frame[0], frame[1], frame[2], frame[3]  # as FRAME names them
    ally_feats, enemy_feats, n_actions = layout[_T_ALLY_FEATS], layout[_T_ENEMY_FEATS], layout[_T_N_ACTIONS]
    enemy_offset, action_offset = layout[_T_ENEMY_OFFSET], layout[_T_ACTION_OFFSET]
    o = out[k]
    for c in range(size):
        o[c] = 0.0
    for i in range(n):
        u = own_lo + i
        if not alive[b, u]:
            continue
        c = i * ally_feats
        o[c] = health[b, u] / own_health_max[i]
        # Medivacs report energy, every other unit its weapon cooldown (loops until it may fire again).
        timer = energy[b, u] if healer[i] else max(cooldown[b, u], 0.0)
        o[c + 1] = timer / max_cooldown[i]
        o[c + 2] = (x[b, u] - cx) / width
        o[c + 3] = (y[b, u] - cy) / height
        c += 4
        if flags[_S_SHIELD_ALLY]:
            o[c] = shield[b, u] / own_shield_max[i]
            c += 1
        for t in range(bits):
            o[c + t] = own_onehot[i, t]
    for j in range(m):
        e = enemy_lo + j
        if not alive[b, e]:
            continue
        c = enemy_offset + j * enemy_feats
        o[c] = health[b, e] / enemy_health_max[j]
        o[c + 1] = (x[b, e] - cx) / width
        o[c + 2] = (y[b, e] - cy) / height
        c += 3
        if flags[_S_SHIELD_ENEMY]:
            o[c] = shield[b, e] / enemy_shield_max[j]
            c += 1
        for t in range(bits):
            o[c + t] = enemy_onehot[j, t]
    c = action_offset
    if flags[_S_LAST_ACTION]:
        for i in range(n):
            a = last_action[b, i]
            if a >= 0:
                o[c + i * n_actions + a] = 1.0
        c += n * n_actions
    if flags[_S_TIMESTEP]:
        o[c] = episode_step[b] / episode_limit


@kernel
def global_state_batch(rows, x, y, alive, health, shield, energy, cooldown, last_action, episode_step, out, own_lo,
                       enemy_lo, own_health_max, own_shield_max, enemy_health_max, enemy_shield_max, own_onehot,
                       enemy_onehot, healer, max_cooldown, frame, state_flags, state_layout, episode_limit):
    """Write the global state of battles ``rows`` into ``out`` (float32 (len(rows), state_size)).

    ``frame`` follows FRAME, ``state_flags`` STATE_FLAGS and ``state_layout`` STATE_LAYOUT.
    """
    for k in range(rows.shape[0]):
        _state_battle(k, rows[k], x, y, alive, health, shield, energy, cooldown, last_action, episode_step, own_lo,
                      enemy_lo, own_health_max, own_shield_max, enemy_health_max, enemy_shield_max, own_onehot,
                      enemy_onehot, healer, max_cooldown, frame, state_flags, state_layout, episode_limit, out)


@kernel
def encode_batch(rows, x, y, alive, health, shield, energy, cooldown, last_action, episode_step, avail, obs, state,
                 own_lo, enemy_lo, healer, heal_target_ok, pathable, half_move, n_heal_targets, own_health_max,
                 own_shield_max, enemy_health_max, enemy_shield_max, own_onehot, enemy_onehot, obs_flags, heights,
                 probe_dx, probe_dy, obs_layout, max_cooldown, frame, state_flags, state_layout, episode_limit):
    """Available actions, observations and (when ``state`` has rows) the global state of battles ``rows`` in one
    call, into ``avail``, ``obs`` and ``state`` (row k for battle ``rows[k]``)."""
    for k in range(rows.shape[0]):
        b = rows[k]
        _avail_battle(k, b, x, y, alive, own_lo, enemy_lo, healer, heal_target_ok, pathable, half_move,
                      n_heal_targets, avail)
        _observe_battle(k, b, x, y, alive, health, shield, avail, last_action, episode_step, own_lo, enemy_lo,
                        own_health_max, own_shield_max, enemy_health_max, enemy_shield_max, own_onehot, enemy_onehot,
                        obs_flags, pathable, heights, probe_dx, probe_dy, obs_layout, episode_limit, obs)
        if state.shape[0] > 0:
            _state_battle(k, b, x, y, alive, health, shield, energy, cooldown, last_action, episode_step, own_lo,
                          enemy_lo, own_health_max, own_shield_max, enemy_health_max, enemy_shield_max, own_onehot,
                          enemy_onehot, healer, max_cooldown, frame, state_flags, state_layout, episode_limit, state)


# ---------------------------------------------------------------------------------------------------------------
# Outcome and rewards.


@inline
def _battle_outcome(b, alive, fighter, n_red, outcome, dead_red, dead_blue):
    n_units = alive.shape[1]
    red_left = blue_left = False
    dead = 0
    for u in range(n_red):
        dead += not alive[b, u]
        red_left |= alive[b, u] and fighter[u]
    dead_red[b] = dead
    dead = 0
    for u in range(n_red, n_units):
        dead += not alive[b, u]
        blue_left |= alive[b, u] and fighter[u]
    dead_blue[b] = dead
    if red_left:
        outcome[b] = RUNNING if blue_left else RED_WON
    else:
        outcome[b] = BLUE_WON if blue_left else DRAW


@inline
def _battle_rewards(b, prev_hs, prev_alive, alive, health, shield, n_red, outcome, values, flags, divisor, reward):
    death_value, win, defeat = values[_R_DEATH_VALUE], values[_R_WIN], values[_R_DEFEAT]
    negative_scale = values[_R_NEGATIVE_SCALE]
    sparse, only_positive = flags[_R_SPARSE], flags[_R_ONLY_POSITIVE]
    lost_red = lost_blue = 0.0
    died_red = died_blue = 0
    for u in range(alive.shape[1]):
        if not prev_alive[b, u]:
            continue
        live = alive[b, u]
        lost = prev_hs[b, u] - (health[b, u] + shield[b, u] if live else 0.0)  # a dying unit's last health counts
        if u < n_red:
            lost_red += lost
            died_red += not live
        else:
            lost_blue += lost
            died_blue += not live
    for s in range(2):
        won = outcome[b] == (RED_WON if s == 0 else BLUE_WON)
        beaten = outcome[b] == (BLUE_WON if s == 0 else RED_WON)
        if sparse:
            r = 1.0 if won else (-1.0 if beaten else 0.0)
        else:
            lost_enemy, lost_own = (lost_blue, lost_red) if s == 0 else (lost_red, lost_blue)
            died_enemy, died_own = (died_blue, died_red) if s == 0 else (died_red, died_blue)
            if only_positive:
                r = max(0.0, lost_enemy + death_value * died_enemy)
            else:
                r = (lost_enemy + (death_value * died_enemy - death_value * negative_scale * died_own)
                     - negative_scale * lost_own)
            r += won * win + beaten * defeat
        reward[b, s] = r / divisor[s]


@kernel
def finish_encode(prev_hs, prev_alive, x, y, alive, health, shield, energy, cooldown, active, restarted, red_actions,
                  blue_actions, last_red, last_blue, episode_step, done, outcome, reward, terminated, truncated,
                  dead_red, dead_blue, avail, obs, state, fighter, n_red, step_limit, reward_values, reward_flags,
                  divisor, own_lo, enemy_lo, healer, heal_target_ok, pathable, half_move, n_heal_targets,
                  own_health_max, own_shield_max, enemy_health_max, enemy_shield_max, own_onehot, enemy_onehot,
                  obs_flags, heights, probe_dx, probe_dy, obs_layout, max_cooldown, frame, state_flags, state_layout,
                  episode_limit):
    """The way up of a core step, one pass per battle: the bookkeeping after the engine stepped the ``active``
    battles, then red's encoding (``encode_batch``'s outputs) of every battle.

    Bookkeeping: counts the step and records the actions (zero rows of ``red_actions`` or ``blue_actions``: a script
    played that side),
    then writes outcome (a side is beaten when none of its ``fighter`` units is alive, SMAC's "only medivacs left"
    rule; both beaten at once is a draw), both sides' rewards (``reward_values`` follow REWARD_VALUES,
    ``reward_flags`` REWARD_FLAGS, ``divisor`` scales each side's), dead counts, ``terminated`` (a result, or a
    ``restarted`` game), ``truncated`` (``step_limit`` reached without one) and marks ended battles ``done``.
    Battles not active, and restarted ones, get RUNNING and zero reward. Returns the number of battles that ended.
    """
    ended = 0
    for b in range(alive.shape[0]):
        _battle_outcome(b, alive, fighter, n_red, outcome, dead_red, dead_blue)
        terminated[b] = truncated[b] = False
        if active[b]:
            episode_step[b] += 1
            if red_actions.shape[0] > 0:
                for i in range(red_actions.shape[1]):
                    last_red[b, i] = red_actions[b, i]
            if blue_actions.shape[0] > 0:
                for i in range(blue_actions.shape[1]):
                    last_blue[b, i] = blue_actions[b, i]
        if not active[b] or restarted[b]:
            outcome[b] = RUNNING
            reward[b, 0] = reward[b, 1] = 0.0
            if active[b]:  # the backend lost the game: the episode ends without a result
                terminated[b] = done[b] = True
                ended += 1
        else:
            _battle_rewards(b, prev_hs, prev_alive, alive, health, shield, n_red, outcome, reward_values,
                            reward_flags, divisor, reward)
            terminated[b] = outcome[b] != RUNNING
            truncated[b] = not terminated[b] and episode_step[b] >= step_limit
            if terminated[b] or truncated[b]:
                done[b] = True
                ended += 1
        # Red's encoding of the new state (the inline phases of encode_batch: a call per battle cost 6x).
        _avail_battle(b, b, x, y, alive, own_lo, enemy_lo, healer, heal_target_ok, pathable, half_move,
                      n_heal_targets, avail)
        _observe_battle(b, b, x, y, alive, health, shield, avail, last_red, episode_step, own_lo, enemy_lo,
                        own_health_max, own_shield_max, enemy_health_max, enemy_shield_max, own_onehot, enemy_onehot,
                        obs_flags, pathable, heights, probe_dx, probe_dy, obs_layout, episode_limit, obs)
        if state.shape[0] > 0:
            _state_battle(b, b, x, y, alive, health, shield, energy, cooldown, last_red, episode_step, own_lo,
                          enemy_lo, own_health_max, own_shield_max, enemy_health_max, enemy_shield_max, own_onehot,
                          enemy_onehot, healer, max_cooldown, frame, state_flags, state_layout, episode_limit, state)
    return ended


# ---------------------------------------------------------------------------------------------------------------
# Actions.


@inline
def _first_invalid(actions, avail, active):
    n_battles, n, n_actions = avail.shape
    for b in range(n_battles):
        if not active[b]:
            continue
        for i in range(n):
            a = actions[b, i]
            if a < 0 or a >= n_actions or not avail[b, i, a]:
                return b * n + i
    return -1


@kernel
def first_invalid_action(actions, avail, active):
    """Flat index (battle * n + agent) of the first illegal action in an active battle, or -1."""
    return _first_invalid(actions, avail, active)


@kernel
def check_decode_batch(actions, avail, active, replace, replaced, x, y, kind, target, cmd_x, cmd_y, own_lo, enemy_lo,
                       healer, move_amount):
    """The way down of a core step for one side: check in-range ``actions`` (B, n) against ``avail``, then write
    their engine commands for active battles.

    An unavailable action in an active battle is, with ``replace``, replaced in ``actions`` by the agent's first
    available one (no-op for a dead agent, stop for a living one) and counted in ``replaced`` (B,); without it,
    nothing is written and the flat index (battle * n + agent) of the first one is returned. Returns -1 once the
    commands are written.
    """
    n_battles, n = actions.shape
    if not replace:
        bad = _first_invalid(actions, avail, active)
        if bad >= 0:
            return bad
    for b in range(n_battles):
        replaced[b] = 0
        if not active[b]:
            continue
        for i in range(n):
            u = own_lo + i
            a = actions[b, i]
            if not avail[b, i, a]:
                a = 0
                while not avail[b, i, a]:
                    a += 1
                actions[b, i] = a
                replaced[b] += 1
            k, t = CMD_NOOP, NO_UNIT
            px, py = x[b, u], y[b, u]
            if a == 1:
                k = CMD_STOP
            elif 2 <= a < N_ACTIONS_NO_ATTACK:
                k = CMD_MOVE
                px += _MOVE_DX[a - 2] * move_amount
                py += _MOVE_DY[a - 2] * move_amount
            elif a >= N_ACTIONS_NO_ATTACK:
                j = a - N_ACTIONS_NO_ATTACK
                if healer[i]:
                    k, t = CMD_HEAL, own_lo + j
                else:
                    k, t = CMD_ATTACK, enemy_lo + j
            kind[b, u] = k
            target[b, u] = t
            cmd_x[b, u] = px
            cmd_y[b, u] = py
    return -1
