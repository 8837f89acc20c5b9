"""Numba kernels of the battle engine: one game loop of one battle, chained over ``step_mul`` loops and run in
parallel over the batch.

Each mechanic is a small ``@njit`` function over one battle ``b``; ``step_batch`` is the only parallel kernel and
calls them in SC2's order for every loop:

1. timers: weapon cooldowns, shield regeneration after the no-damage delay, zerg regeneration, energy;
2. targeting: ordered targets, SC2's automatic acquisition for units that acquire (idle, hold, attack-move), and the
   response to being attacked; SMAC's ``*_RL`` units are passive and only acquire during an attack-move;
3. movement toward the order point or the target, along the terrain's path tables (air ignores terrain);
4. separation: overlapping units of the same plane push apart (colossi walk over small units);
5. attacks, heals and baneling bursts, all units that were alive when the loop began acting simultaneously
   (so two marines can kill each other in the same loop);
6. deaths.

Simplifications against SC2 (documented in the README): damage lands when the weapon fires (no projectile travel
or damage point), no random cooldown jitter, separation is a positional push rather than SC2's steering.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from smac_hard_gym.engine.state import (
    CMD_ATTACK,
    CMD_ATTACK_MOVE,
    CMD_HEAL,
    CMD_HOLD,
    CMD_MOVE,
    CMD_NOOP,
    CMD_STOP,
    NO_UNIT,
    ORDER_ATTACK,
    ORDER_ATTACK_MOVE,
    ORDER_HEAL,
    ORDER_HOLD,
    ORDER_IDLE,
    ORDER_MOVE,
)
from smac_hard_gym.engine.terrain import MOVER_AIR, MOVER_CLIFF, MOVER_GROUND
from smac_hard_gym.units import (
    BIO,
    MIN_DAMAGE,
    SHIELD_REGEN_DELAY_LOOPS,
    WEAPON_BURST,
    WEAPON_HEAL,
    WEAPON_LINE_SPLASH,
    S,
)

# Stat columns as compile-time constants.
_HEALTH, _SHIELD, _ARMOR = S["health"], S["shield"], S["armor"]
_DAMAGE, _HITS, _BONUS, _BONUS_ATTR = S["damage"], S["hits"], S["bonus_damage"], S["bonus_attribute"]
_COOLDOWN, _RANGE, _HITS_GROUND, _HITS_AIR = S["cooldown"], S["range"], S["hits_ground"], S["hits_air"]
_SPEED, _RADIUS, _SIGHT, _ATTR = S["speed"], S["radius"], S["sight"], S["attributes"]
_IS_AIR, _CLIFF_WALK, _WEAPON = S["is_air"], S["cliff_walk"], S["weapon"]
_SPLASH_R, _SPLASH_L, _SPLASH_W = S["splash_radius"], S["splash_length"], S["splash_width"]
_ENERGY_MAX, _ENERGY_REGEN = S["energy_max"], S["energy_regen"]
_HEAL_RATE, _HEAL_COST, _REGEN = S["heal_rate"], S["heal_energy_per_hp"], S["regen"]
_PASSIVE, _SCAN, _SHIELD_REGEN = S["passive"], S["scan_range"], S["shield_regen"]

_SHIELD_DELAY = SHIELD_REGEN_DELAY_LOOPS
_MIN_DAMAGE = MIN_DAMAGE
_BIO = BIO
_ARRIVE = 0.05  # a move order is complete this close to its point
_LEASH = 3.0  # an acquired target is dropped once it is this far beyond the scan range
_EDGE = 1e-4  # keeps positions strictly inside the map


# ---------------------------------------------------------------------------------------------------------------
# Small helpers.


@njit(cache=True, inline="always")
def _mover(stats, t):
    if stats[t, _IS_AIR] > 0:
        return MOVER_AIR
    if stats[t, _CLIFF_WALK] > 0:
        return MOVER_CLIFF
    return MOVER_GROUND


@njit(cache=True, inline="always")
def _can_hit(stats, attacker_type, target_type):
    if stats[target_type, _IS_AIR] > 0:
        return stats[attacker_type, _HITS_AIR] > 0
    return stats[attacker_type, _HITS_GROUND] > 0


@njit(cache=True, inline="always")
def _edge_distance(x, y, stats, utype, b, i, j):
    dx = x[b, j] - x[b, i]
    dy = y[b, j] - y[b, i]
    return math.sqrt(dx * dx + dy * dy) - stats[utype[b, i], _RADIUS] - stats[utype[b, j], _RADIUS]


@njit(cache=True, inline="always")
def _reach(stats, t):
    """How close (edge to edge) a unit must be to its target to act: weapon or heal range."""
    return stats[t, _RANGE]


# ---------------------------------------------------------------------------------------------------------------
# Commands.


@njit(cache=True, inline="always")
def _apply_commands(b, st, kind, cmd_target, cmd_x, cmd_y, stats):
    st_alive = st.alive
    st_burst = st.burst
    st_fired_at = st.fired_at
    st_order = st.order
    st_order_target = st.order_target
    st_order_x = st.order_x
    st_order_y = st.order_y
    st_side = st.side
    st_target = st.target
    st_utype = st.utype
    n = st_alive.shape[1]
    for i in range(n):
        st_fired_at[b, i] = NO_UNIT
        st_burst[b, i] = False
        k = kind[b, i]
        if k == CMD_NOOP or not st_alive[b, i]:
            continue
        if k == CMD_STOP:
            st_order[b, i] = ORDER_IDLE
            st_target[b, i] = NO_UNIT
        elif k == CMD_HOLD:
            st_order[b, i] = ORDER_HOLD
            st_target[b, i] = NO_UNIT
        elif k == CMD_MOVE or k == CMD_ATTACK_MOVE:
            st_order[b, i] = ORDER_MOVE if k == CMD_MOVE else ORDER_ATTACK_MOVE
            st_order_x[b, i] = cmd_x[b, i]
            st_order_y[b, i] = cmd_y[b, i]
            st_target[b, i] = NO_UNIT
        elif k == CMD_ATTACK or k == CMD_HEAL:
            j = cmd_target[b, i]
            if j < 0 or j >= n or j == i or not st_alive[b, j]:
                continue
            ti, tj = st_utype[b, i], st_utype[b, j]
            healer = stats[ti, _WEAPON] == WEAPON_HEAL
            if k == CMD_ATTACK and not healer and st_side[b, j] != st_side[b, i] and _can_hit(stats, ti, tj):
                st_order[b, i] = ORDER_ATTACK
            elif k == CMD_HEAL and healer and st_side[b, j] == st_side[b, i]:
                st_order[b, i] = ORDER_HEAL
            else:
                continue
            st_order_target[b, i] = j
            st_target[b, i] = j


# ---------------------------------------------------------------------------------------------------------------
# 1. Timers.


@njit(cache=True, inline="always")
def _timers(b, st, stats):
    st_alive = st.alive
    st_alive_at_loop = st.alive_at_loop
    st_cooldown = st.cooldown
    st_energy = st.energy
    st_health = st.health
    st_shield = st.shield
    st_shield_wait = st.shield_wait
    st_utype = st.utype
    n = st_alive.shape[1]
    for i in range(n):
        st_alive_at_loop[b, i] = st_alive[b, i]
        if not st_alive[b, i]:
            continue
        t = st_utype[b, i]
        if st_cooldown[b, i] > 0.0:
            st_cooldown[b, i] -= 1.0
        regen = stats[t, _REGEN]
        if regen > 0.0 and st_health[b, i] < stats[t, _HEALTH]:
            st_health[b, i] = min(stats[t, _HEALTH], st_health[b, i] + regen)
        if stats[t, _SHIELD] > 0.0:
            if st_shield_wait[b, i] > 0.0:
                st_shield_wait[b, i] -= 1.0
            elif st_shield[b, i] < stats[t, _SHIELD]:
                st_shield[b, i] = min(stats[t, _SHIELD], st_shield[b, i] + stats[t, _SHIELD_REGEN])
        if stats[t, _ENERGY_MAX] > 0.0 and st_energy[b, i] < stats[t, _ENERGY_MAX]:
            st_energy[b, i] = min(stats[t, _ENERGY_MAX], st_energy[b, i] + stats[t, _ENERGY_REGEN])


# ---------------------------------------------------------------------------------------------------------------
# 2. Targeting.


@njit(cache=True, inline="always")
def _heal_wanted(st, stats, b, j):
    st_alive = st.alive
    st_health = st.health
    st_utype = st.utype
    t = st_utype[b, j]
    return (st_alive[b, j] and stats[t, _IS_AIR] == 0 and (int(stats[t, _ATTR]) & _BIO) != 0
            and st_health[b, j] < stats[t, _HEALTH])


@njit(cache=True, inline="always")
def _acquire_heal(b, i, st, stats):
    """Non-passive medivacs heal the nearest damaged biological ally within scan range."""
    st_alive = st.alive
    st_side = st.side
    st_target = st.target
    st_utype = st.utype
    st_x = st.x
    st_y = st.y
    n = st_alive.shape[1]
    t = st_utype[b, i]
    cur = st_target[b, i]
    scan = stats[t, _SCAN]
    if cur >= 0 and _heal_wanted(st, stats, b, cur) and (
            _edge_distance(st_x, st_y, stats, st_utype, b, i, cur) <= scan + _LEASH):
        return
    best = NO_UNIT
    best_d = np.inf
    for j in range(n):
        if j == i or st_side[b, j] != st_side[b, i] or not _heal_wanted(st, stats, b, j):
            continue
        d = _edge_distance(st_x, st_y, stats, st_utype, b, i, j)
        if d <= scan and d < best_d:
            best_d = d
            best = j
    st_target[b, i] = best


@njit(cache=True, inline="always")
def _acquire_weapon(b, i, st, stats):
    """SC2's automatic targeting: keep a valid target, else prefer units attacking us, then the closest.

    Idle and attack-moving units scan within ``scan_range`` and also answer the last unit that hit them (response
    when attacked); holding units only look within weapon range. Passive (*_RL) units acquire only while
    attack-moving and never respond.
    """
    st_alive = st.alive
    st_attacker = st.attacker
    st_order = st.order
    st_side = st.side
    st_target = st.target
    st_utype = st.utype
    st_x = st.x
    st_y = st.y
    n = st_alive.shape[1]
    t = st_utype[b, i]
    order = st_order[b, i]
    passive = stats[t, _PASSIVE] > 0
    if order == ORDER_MOVE or (passive and order != ORDER_ATTACK_MOVE):
        st_target[b, i] = NO_UNIT
        return
    reach = stats[t, _RANGE] if order == ORDER_HOLD else stats[t, _SCAN]
    leash = stats[t, _RANGE] if order == ORDER_HOLD else stats[t, _SCAN] + _LEASH
    cur = st_target[b, i]
    if cur >= 0 and st_alive[b, cur] and _edge_distance(st_x, st_y, stats, st_utype, b, i, cur) <= leash:
        return
    responder = (not passive) and order != ORDER_HOLD
    best = NO_UNIT
    best_rank = 3
    best_d = np.inf
    for j in range(n):
        if not st_alive[b, j] or st_side[b, j] == st_side[b, i]:
            continue
        if not _can_hit(stats, t, st_utype[b, j]):
            continue
        d = _edge_distance(st_x, st_y, stats, st_utype, b, i, j)
        if d <= reach:
            rank = 0 if st_target[b, j] == i else 1
        elif responder and st_attacker[b, i] == j:
            rank = 2
        else:
            continue
        if rank < best_rank or (rank == best_rank and d < best_d):
            best_rank = rank
            best_d = d
            best = j
    st_target[b, i] = best


@njit(cache=True, inline="always")
def _targeting(b, st, stats):
    st_alive = st.alive
    st_order = st.order
    st_order_target = st.order_target
    st_target = st.target
    st_utype = st.utype
    n = st_alive.shape[1]
    for i in range(n):
        if not st_alive[b, i]:
            continue
        t = st_utype[b, i]
        order = st_order[b, i]
        if order == ORDER_ATTACK or order == ORDER_HEAL:
            j = st_order_target[b, i]
            if j >= 0 and st_alive[b, j]:
                st_target[b, i] = j
                continue
            st_order[b, i] = ORDER_IDLE  # the ordered target is gone: the order is complete
            st_target[b, i] = NO_UNIT
            order = ORDER_IDLE
        if stats[t, _WEAPON] == WEAPON_HEAL:
            if stats[t, _PASSIVE] > 0 or order == ORDER_MOVE:
                st_target[b, i] = NO_UNIT
            else:
                _acquire_heal(b, i, st, stats)
        elif stats[t, _DAMAGE] > 0:
            _acquire_weapon(b, i, st, stats)


# ---------------------------------------------------------------------------------------------------------------
# 3. Movement.


@njit(cache=True, inline="always")
def _cell(v, size):
    c = int(v)
    if c < 0:
        return 0
    if c >= size:
        return size - 1
    return c


@njit(cache=True, inline="always")
def _waypoint(mover, x, y, gx, gy, walk, next_hop, los):
    """Where to head now to reach (gx, gy): the goal if visible, else the farthest visible cell on the path."""
    if mover == MOVER_AIR:
        return gx, gy
    mx, my = walk.shape[1], walk.shape[2]
    c = _cell(x, mx) * my + _cell(y, my)
    g = _cell(gx, mx) * my + _cell(gy, my)
    if c == g or los[mover, c, g]:
        return gx, gy
    hop = next_hop[mover, g, c]
    if hop < 0:
        return gx, gy  # unreachable goal: head straight and slide along walls
    for _ in range(12):
        nxt = next_hop[mover, g, hop]
        if nxt < 0 or nxt == hop or not los[mover, c, nxt]:
            break
        hop = nxt
    if hop == g:
        return gx, gy
    return (hop // my) + 0.5, (hop % my) + 0.5


@njit(cache=True, inline="always")
def _commit(b, i, st, nx, ny, mover, walk):
    """Move unit i to (nx, ny) if its centre stays walkable, else slide along one axis, else stay."""
    st_x = st.x
    st_y = st.y
    mx, my = walk.shape[1], walk.shape[2]
    nx = min(max(nx, _EDGE), mx - _EDGE)
    ny = min(max(ny, _EDGE), my - _EDGE)
    if mover == MOVER_AIR:
        st_x[b, i] = nx
        st_y[b, i] = ny
        return
    x, y = st_x[b, i], st_y[b, i]
    if walk[mover, int(nx), int(ny)]:
        st_x[b, i] = nx
        st_y[b, i] = ny
    elif walk[mover, int(nx), int(y)]:
        st_x[b, i] = nx
    elif walk[mover, int(x), int(ny)]:
        st_y[b, i] = ny


@njit(cache=True, inline="always")
def _movement(b, st, stats, walk, next_hop, los):
    st_alive = st.alive
    st_order = st.order
    st_order_x = st.order_x
    st_order_y = st.order_y
    st_target = st.target
    st_utype = st.utype
    st_x = st.x
    st_y = st.y
    n = st_alive.shape[1]
    for i in range(n):
        if not st_alive[b, i]:
            continue
        t = st_utype[b, i]
        speed = stats[t, _SPEED]
        order = st_order[b, i]
        if speed <= 0.0 or order == ORDER_HOLD:
            continue
        j = st_target[b, i]
        if j >= 0:
            if _edge_distance(st_x, st_y, stats, st_utype, b, i, j) <= _reach(stats, t):
                continue  # in range: stand and act
            gx, gy = st_x[b, j], st_y[b, j]
        elif order == ORDER_MOVE or order == ORDER_ATTACK_MOVE:
            gx, gy = st_order_x[b, i], st_order_y[b, i]
            dx, dy = gx - st_x[b, i], gy - st_y[b, i]
            if dx * dx + dy * dy <= _ARRIVE * _ARRIVE:
                st_order[b, i] = ORDER_IDLE
                continue
        else:
            continue
        mover = _mover(stats, t)
        wx, wy = _waypoint(mover, st_x[b, i], st_y[b, i], gx, gy, walk, next_hop, los)
        dx, dy = wx - st_x[b, i], wy - st_y[b, i]
        d = math.sqrt(dx * dx + dy * dy)
        if d < 1e-12:
            continue
        step = min(speed, d)
        _commit(b, i, st, st_x[b, i] + dx / d * step, st_y[b, i] + dy / d * step, mover, walk)


# ---------------------------------------------------------------------------------------------------------------
# 4. Separation.


@njit(cache=True, inline="always")
def _collide(stats, ti, tj):
    """Same plane: air with air; cliff walkers (massive) only with each other; other ground units together."""
    if stats[ti, _IS_AIR] != stats[tj, _IS_AIR]:
        return False
    if stats[ti, _IS_AIR] > 0:
        return True
    return stats[ti, _CLIFF_WALK] == stats[tj, _CLIFF_WALK]


@njit(cache=True, inline="always")
def _separation(b, st, stats, walk):
    st_alive = st.alive
    st_order = st.order
    st_utype = st.utype
    st_x = st.x
    st_y = st.y
    n = st_alive.shape[1]
    for i in range(n):
        if not st_alive[b, i]:
            continue
        ti = st_utype[b, i]
        wi = 1.0 if stats[ti, _SPEED] > 0.0 and st_order[b, i] != ORDER_HOLD else 0.0
        for j in range(i + 1, n):
            if not st_alive[b, j]:
                continue
            tj = st_utype[b, j]
            if not _collide(stats, ti, tj):
                continue
            dx = st_x[b, j] - st_x[b, i]
            dy = st_y[b, j] - st_y[b, i]
            rr = stats[ti, _RADIUS] + stats[tj, _RADIUS]
            d2 = dx * dx + dy * dy
            if d2 >= rr * rr:
                continue
            wj = 1.0 if stats[tj, _SPEED] > 0.0 and st_order[b, j] != ORDER_HOLD else 0.0
            if wi + wj == 0.0:
                continue
            d = math.sqrt(d2)
            if d < 1e-9:  # exactly stacked: split along a fixed, index-dependent direction
                angle = 2.399963229728653 * (i * 31 + j)
                ux, uy, d = math.cos(angle), math.sin(angle), 0.0
            else:
                ux, uy = dx / d, dy / d
            overlap = rr - d
            si = overlap * wi / (wi + wj)
            sj = overlap * wj / (wi + wj)
            if si > 0.0:
                _commit(b, i, st, st_x[b, i] - ux * si, st_y[b, i] - uy * si, _mover(stats, ti), walk)
            if sj > 0.0:
                _commit(b, j, st, st_x[b, j] + ux * sj, st_y[b, j] + uy * sj, _mover(stats, tj), walk)


# ---------------------------------------------------------------------------------------------------------------
# 5. Attacks, heals, bursts.


@njit(cache=True, inline="always")
def _damage(b, st, stats, j, amount, source):
    """One hit of ``amount`` on unit j: shields absorb first, then armour applies, at least 0.5 on health."""
    st_attacker = st.attacker
    st_health = st.health
    st_shield = st.shield
    st_shield_wait = st.shield_wait
    st_utype = st.utype
    t = st_utype[b, j]
    if st_shield[b, j] > 0.0:
        absorbed = min(st_shield[b, j], amount)
        st_shield[b, j] -= absorbed
        amount -= absorbed
        if amount > 0.0:
            st_health[b, j] -= max(amount - stats[t, _ARMOR], _MIN_DAMAGE)
    else:
        st_health[b, j] -= max(amount - stats[t, _ARMOR], _MIN_DAMAGE)
    if stats[t, _SHIELD] > 0.0:
        st_shield_wait[b, j] = _SHIELD_DELAY
    st_attacker[b, j] = source


@njit(cache=True, inline="always")
def _hit_amount(stats, attacker_type, target_type):
    amount = stats[attacker_type, _DAMAGE]
    if (int(stats[target_type, _ATTR]) & int(stats[attacker_type, _BONUS_ATTR])) != 0:
        amount += stats[attacker_type, _BONUS]
    return amount


@njit(cache=True, inline="always")
def _line_splash(b, st, stats, i, j):
    """Colossus: every hit lands on all enemy ground units touching a line across the target (length x width)."""
    st_alive = st.alive
    st_alive_at_loop = st.alive_at_loop
    st_side = st.side
    st_utype = st.utype
    st_x = st.x
    st_y = st.y
    n = st_alive.shape[1]
    ti = st_utype[b, i]
    ux, uy = st_x[b, j] - st_x[b, i], st_y[b, j] - st_y[b, i]
    norm = math.sqrt(ux * ux + uy * uy)
    if norm < 1e-9:
        ux, uy = 1.0, 0.0
    else:
        ux, uy = ux / norm, uy / norm
    half_l = 0.5 * stats[ti, _SPLASH_L]
    half_w = 0.5 * stats[ti, _SPLASH_W]
    hits = int(stats[ti, _HITS])
    for k in range(n):
        if not st_alive_at_loop[b, k] or st_side[b, k] == st_side[b, i]:
            continue
        tk = st_utype[b, k]
        if stats[tk, _IS_AIR] > 0:
            continue
        vx, vy = st_x[b, k] - st_x[b, j], st_y[b, k] - st_y[b, j]
        across = abs(vx * -uy + vy * ux)  # along the line, perpendicular to the shot
        along = abs(vx * ux + vy * uy)  # along the shot, the line's thickness
        rk = stats[tk, _RADIUS]
        if k == j or (across <= half_l + rk and along <= half_w + rk):
            amount = _hit_amount(stats, ti, tk)
            for _ in range(hits):
                _damage(b, st, stats, k, amount, i)


@njit(cache=True, inline="always")
def _burst(b, st, stats, i):
    """Baneling: damage every enemy ground unit within the splash radius (of its edge), then die."""
    st_alive = st.alive
    st_alive_at_loop = st.alive_at_loop
    st_burst = st.burst
    st_health = st.health
    st_side = st.side
    st_utype = st.utype
    st_x = st.x
    st_y = st.y
    n = st_alive.shape[1]
    ti = st_utype[b, i]
    radius = stats[ti, _SPLASH_R]
    for k in range(n):
        if not st_alive_at_loop[b, k] or st_side[b, k] == st_side[b, i]:
            continue
        tk = st_utype[b, k]
        if stats[tk, _IS_AIR] > 0:
            continue
        dx, dy = st_x[b, k] - st_x[b, i], st_y[b, k] - st_y[b, i]
        if math.sqrt(dx * dx + dy * dy) - stats[tk, _RADIUS] <= radius:
            _damage(b, st, stats, k, _hit_amount(stats, ti, tk), i)
    st_health[b, i] = 0.0
    st_burst[b, i] = True


@njit(cache=True, inline="always")
def _heal(b, st, stats, i, j):
    st_energy = st.energy
    st_fired_at = st.fired_at
    st_health = st.health
    st_utype = st.utype
    ti, tj = st_utype[b, i], st_utype[b, j]
    missing = stats[tj, _HEALTH] - st_health[b, j]
    if missing <= 0.0 or (int(stats[tj, _ATTR]) & _BIO) == 0 or stats[tj, _IS_AIR] > 0:
        return
    cost = stats[ti, _HEAL_COST]
    amount = min(stats[ti, _HEAL_RATE], missing, st_energy[b, i] / cost)
    if amount <= 0.0:
        return
    st_health[b, j] += amount
    st_energy[b, i] -= amount * cost
    st_fired_at[b, i] = j


@njit(cache=True, inline="always")
def _attacks(b, st, stats):
    st_alive = st.alive
    st_alive_at_loop = st.alive_at_loop
    st_cooldown = st.cooldown
    st_fired_at = st.fired_at
    st_target = st.target
    st_utype = st.utype
    st_x = st.x
    st_y = st.y
    n = st_alive.shape[1]
    for i in range(n):
        if not st_alive_at_loop[b, i]:
            continue
        j = st_target[b, i]
        if j < 0 or not st_alive_at_loop[b, j]:
            continue
        t = st_utype[b, i]
        if _edge_distance(st_x, st_y, stats, st_utype, b, i, j) > _reach(stats, t):
            continue
        weapon = stats[t, _WEAPON]
        if weapon == WEAPON_HEAL:
            _heal(b, st, stats, i, j)
        elif weapon == WEAPON_BURST:
            _burst(b, st, stats, i)
        elif st_cooldown[b, i] <= 0.0:
            if weapon == WEAPON_LINE_SPLASH:
                _line_splash(b, st, stats, i, j)
            else:
                amount = _hit_amount(stats, t, st_utype[b, j])
                for _ in range(int(stats[t, _HITS])):
                    _damage(b, st, stats, j, amount, i)
            st_cooldown[b, i] += stats[t, _COOLDOWN]
            st_fired_at[b, i] = j


# ---------------------------------------------------------------------------------------------------------------
# 6. Deaths, and the drivers.


@njit(cache=True, inline="always")
def _deaths(b, st):
    st_alive = st.alive
    st_health = st.health
    st_order = st.order
    st_shield = st.shield
    st_target = st.target
    n = st_alive.shape[1]
    for i in range(n):
        if st_alive[b, i] and st_health[b, i] <= 0.0:
            st_alive[b, i] = False
            st_health[b, i] = 0.0
            st_shield[b, i] = 0.0
            st_order[b, i] = ORDER_IDLE
            st_target[b, i] = NO_UNIT


@njit(cache=True)
def game_loop(b, st, stats, walk, next_hop, los):
    """Advance battle ``b`` by one game loop."""
    st_loop = st.loop
    _timers(b, st, stats)
    _targeting(b, st, stats)
    _movement(b, st, stats, walk, next_hop, los)
    _separation(b, st, stats, walk)
    _attacks(b, st, stats)
    _deaths(b, st)
    st_loop[b] += 1


@njit(cache=True)
def step_battle(b, st, kind, cmd_target, cmd_x, cmd_y, stats, walk, next_hop, los, n_loops):
    """Apply battle b's commands, then run ``n_loops`` game loops."""
    _apply_commands(b, st, kind, cmd_target, cmd_x, cmd_y, stats)
    for _ in range(n_loops):
        game_loop(b, st, stats, walk, next_hop, los)


@njit(cache=True, parallel=True)
def step_batch(st, kind, cmd_target, cmd_x, cmd_y, stats, walk, next_hop, los, n_loops, active):
    """Apply the commands, then run ``n_loops`` game loops, for every battle with ``active[b]``."""
    st_alive = st.alive
    for b in prange(st_alive.shape[0]):
        if active[b]:
            step_battle(b, st, kind, cmd_target, cmd_x, cmd_y, stats, walk, next_hop, los, n_loops)
