"""Numba kernels of the battle engine: one game loop of one battle, chained over ``step_mul`` loops and run in
parallel over the batch.

``step_battles`` steps a range of battles on the calling thread; ``step_batch`` spreads the batch over numba's
threads in chunks, each a call of ``step_battles``; nothing else runs the battle loop. Both take the engine's bundles
whole: the state (``BattleState``), the commands (``Commands``), the map's ``Terrain`` and the working arrays
(``Scratch``). For each battle (``_step_battle``) the driver takes its 1-D row views once per env step, as one
:class:`Rows` bundle, and hands them to small mechanics, one function per mechanic, inlined into the loop body:

1. ``_timers``: weapon cooldowns, shield regeneration after the no-damage delay, zerg regeneration, energy;
2. ``_targeting``: ordered targets, SC2's automatic acquisition for units that acquire (idle, hold, attack-move)
   and the response to being attacked; SMAC's ``*_RL`` units are passive and acquire only while attack-moving;
3. ``_movement`` toward the order point or the target, along the terrain's path tables (air ignores terrain),
   steering round units in the way;
4. ``_separation``: overlapping units of the same plane push apart (colossi walk over small units);
5. ``_attacks``: shots, heals and baneling bursts; every unit alive when the loop began acts, so two marines can
   kill each other in the same loop (SC2 resolves in sequence; simultaneity keeps the batch order-free);
6. ``_deaths``.

Simplifications against SC2 (listed in the README): a shot comes a whole number of loops after its wind-up starts
(the data's damage point, rounded up), separation is a positional push, and a walker blocked by a unit that does not
give way steers round it by a few fixed headings (SC2's steering is not published). The only random draw is SC2's
random attack delay, from each battle's seeded xorshift stream (``BattleState.rng``).

Speed notes (each measured; see ``tests/test_engine_speedups.py`` for the mechanisms' own tests):

- ``slot_stats[i, column]`` is the unit table row of the unit in slot i. A slot's type never changes (the map's
  layout fixes it), so the kernels read stats per slot, without going through ``utype``.
- ``step_battles`` inlines the battle (``_step_battle``) and its phases into its loop over a range of battles (the
  phases' helpers are called: LLVM inlines the small ones), and both drivers are
  compiled without numba's reference counting (``_nrt=False``): they allocate nothing, and every row view and
  inlined helper argument otherwise cost an atomic increment and decrement on the state arrays' shared counters
  (half the serial time on 3m, and cache-line ping-pong between the threads). So the :class:`Rows` bundle the
  inlined phases share costs nothing either; the called helpers take the arrays they use one by one, since a bundle
  passed to a call travels by value. Called as a function, a battle also received the state (a tuple of 25 arrays)
  by value on every call; ``step_batch`` pays that once per chunk.
- ``step_kernels_for`` gives the drivers' overloads for one map's unit count, for big batches.
- Compile time: the phases are inlined into the battle, the helpers they call are not (see ``helper``), and the
  unit count is a type (``units_marker``), not a closure, so one cached dispatcher serves every count.
- Separation finds overlapping pairs by sweeping the units in x order (``_sort_by_x``) instead of testing all
  pairs: 27m_vs_30m's step took half the time after this.
- Most separation passes find no overlap; a battle of up to ``_FEW_UNITS`` units tests its pairs and skips such
  a pass without sorting (measured where ``_FEW_UNITS`` is set).
- ``step_batch`` hands battles to the worker threads in small chunks from a shared counter (``scheduling``), so a
  thread that another process delays does not hold up the step.
"""

from __future__ import annotations

import math
import os
from typing import Any, NamedTuple

import numba
import numpy as np
from numba import njit, prange

from smac_hard_gym.engine.scheduling import CHUNKS_PER_THREAD, fetch_add
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
    STANCE_BLOCKED,
    STANCE_FIRING,
    STANCE_KIND,
    STANCE_LEFT,
    STANCE_NONE,
    STANCE_RIGHT,
    STANCE_SIDE,
    STANCE_WALKED,
    STANCE_YIELDS,
)
from smac_hard_gym.engine.terrain import MOVER_AIR
from smac_hard_gym.engine.units import (
    BIO,
    CALL_FOR_HELP_PERIOD_LOOPS,
    CALL_FOR_HELP_RADIUS,
    MIN_DAMAGE,
    SHIELD_REGEN_DELAY_LOOPS,
    WEAPON_BURST,
    WEAPON_HEAL,
    S,
)
from smac_hard_gym.engine.units import WEAPON_LINE_SPLASH as _LINE

# numba's OpenMP layer spins and yields badly when the cores are shared (a 16-battle step took 8 ms instead of
# 0.2 ms on a loaded 2-core machine) and is unsafe after fork; the workqueue layer has neither problem. It must not be
# entered from two Python threads at once: use one env per process (vector envs do). NUMBA_THREADING_LAYER overrides.
if os.environ.get("NUMBA_THREADING_LAYER", "workqueue") == "workqueue":
    numba.config.THREADING_LAYER = "workqueue"

# Stat columns as compile-time constants.
_HEALTH, _SHIELD, _ARMOR = S["health"], S["shield"], S["armor"]
_DAMAGE, _HITS, _BONUS, _BONUS_ATTR = S["damage"], S["hits"], S["bonus_damage"], S["bonus_attribute"]
_COOLDOWN, _RANGE, _HITS_GROUND, _HITS_AIR = S["cooldown"], S["range"], S["hits_ground"], S["hits_air"]
_SPEED, _RADIUS, _ATTR, _IS_AIR = S["speed"], S["radius"], S["attributes"], S["is_air"]
_WEAPON, _MOVER = S["weapon"], S["mover"]
_SPLASH_R, _SPLASH_L, _SPLASH_W = S["splash_radius"], S["splash_length"], S["splash_width"]
_ENERGY_MAX, _ENERGY_REGEN = S["energy_max"], S["energy_regen"]
_HEAL_RATE, _HEAL_COST, _REGEN, _DECAY = S["heal_rate"], S["heal_energy_per_hp"], S["regen"], S["decay"]
_PASSIVE, _SCAN, _SHIELD_REGEN = S["passive"], S["scan_range"], S["shield_regen"]
_MISSILE_SPEED, _SECOND_DELAY, _SECOND_REACH = S["missile_speed"], S["second_hit_delay"], S["second_hit_reach"]
_WIND_UP, _SLOP = S["wind_up"], S["range_slop"]

_SHIELD_DELAY = SHIELD_REGEN_DELAY_LOOPS
_MIN_DAMAGE = MIN_DAMAGE
_BIO = BIO
_ARRIVE = 0.05  # a move order is complete this close to its point
_CROWD_ARRIVE = 3.0  # ... or this close, bumping into a unit of its side that has arrived (SC2's group arrival)
_ARRIVING = 99  # order of a unit that arrived during a separation pass (idle once the pass ends)
_LEASH = 3.0  # an acquired target is dropped once it is this far beyond the scan range
# SC2 holds numbers in 20.12 fixed point (SC2Mapster, "Types/Fixed": the Galaxy type and the game files' fixed32);
# every move (``_slide``) lands on that grid (docs/engine_rules.md, C12).
POSITION_GRID = 4096.0
_GRID_STEP = 1.0 / POSITION_GRID  # exact: the grid is a power of two, so dividing by it is multiplying by this
_EDGE = _GRID_STEP  # keeps positions strictly inside the map (a grid point)
_INF = 1e300
_TOUCHING = 0.1  # two walkers whose edges are this close meet (C14's pair pass)
_SETTLE_PASSES = 16  # at most this many extra separation passes after the last loop of an env step
_SETTLED = 0.05  # ... stopping once no overlap is deeper than this
# Battles of at most this many units test every pair for an overlap before a separation pass, and skip the pass
# when none overlaps: most passes push nothing (92% on 3m with random orders), and up to here the pairs cost less
# than the sort and the sweep (engine steps/s against the sweep alone: 5m_vs_6m 1.19, 8m 1.17, MMM2 1.05; with every
# pair tested on 27m_vs_30m, 0.87).
_FEW_UNITS = 24

# The phases (and the battle) are inlined into ``step_battles`` by numba, before typing; every helper they call is a
# kernel of its own, compiled once and called (LLVM still inlines the small ones into the loops). Inlining the
# helpers too, at every call site, made ``step_battles`` take 60 s of CPU to compile, against 9 s now plus 6 s for
# the helpers (numba 0.68). Speed: the same within noise on an idle 16-core host; on a loaded 2-core machine, one
# thread, 3m at 4096 battles with the unit-count overloads, about 4% fewer steps per CPU second (median of 12
# interleaved pairs). Calling the phases too compiled in 18 s but stepped 20-35% slower.
inline = njit(cache=True, inline="always", error_model="numpy")
helper = njit(cache=True, error_model="numpy", _nrt=False)


class Rows(NamedTuple):
    """One battle's rows: 1-D views (U,) into the batch's arrays, taken once per env step by ``_step_battle`` and
    handed to the phases. Each field is row b of the :class:`~smac_hard_gym.engine.state.BattleState` or
    :class:`~smac_hard_gym.engine.state.Scratch` field of the same name (shapes, dtypes and units are documented
    there), except ``loop`` and ``rng``: one-element views ``[b:b + 1]`` of those (B,) fields, so that writes land
    (see ``_step_battle``).

    The phases are inlined into the drivers, which run without reference counting, so the bundle costs nothing: its
    fields are read like local variables. The helpers the phases call still take the arrays they use one by one.
    """

    side: np.ndarray
    alive: np.ndarray
    alive_at_loop: np.ndarray
    x: np.ndarray
    y: np.ndarray
    health: np.ndarray
    shield: np.ndarray
    energy: np.ndarray
    cooldown: np.ndarray
    shield_wait: np.ndarray
    order: np.ndarray
    order_target: np.ndarray
    order_x: np.ndarray
    order_y: np.ndarray
    target: np.ndarray
    attacker: np.ndarray
    help_at: np.ndarray
    fired_at: np.ndarray
    burst: np.ndarray
    stance: np.ndarray
    pending_target: np.ndarray
    pending_eta: np.ndarray
    pending_hits: np.ndarray
    windup: np.ndarray
    windup_target: np.ndarray
    loop: np.ndarray
    rng: np.ndarray
    by_x: np.ndarray
    key: np.ndarray
    engaged: np.ndarray
    x0: np.ndarray
    y0: np.ndarray
    life0: np.ndarray


@inline
def battle_rows(st, scratch, b):
    """Battle b's :class:`Rows` of the state ``st`` and the scratch arrays ``scratch``."""
    return Rows(st.side[b], st.alive[b], st.alive_at_loop[b], st.x[b], st.y[b], st.health[b], st.shield[b],
                st.energy[b], st.cooldown[b], st.shield_wait[b], st.order[b], st.order_target[b], st.order_x[b],
                st.order_y[b], st.target[b], st.attacker[b], st.help_at[b], st.fired_at[b], st.burst[b],
                st.stance[b], st.pending_target[b], st.pending_eta[b], st.pending_hits[b], st.windup[b],
                st.windup_target[b], st.loop[b:b + 1], st.rng[b:b + 1], scratch.by_x[b], scratch.key[b],
                scratch.engaged[b], scratch.x0[b], scratch.y0[b], scratch.life0[b])


# ---------------------------------------------------------------------------------------------------------------
# Small helpers.


@helper
def _can_hit(slot_stats, i, j):
    if slot_stats[j, _IS_AIR] > 0:
        return slot_stats[i, _HITS_AIR] > 0
    return slot_stats[i, _HITS_GROUND] > 0


@helper
def _edge_distance(xi, yi, xj, yj, radii):
    """Edge-to-edge distance of two units whose radii sum to ``radii``."""
    dx = xj - xi
    dy = yj - yi
    return math.sqrt(dx * dx + dy * dy) - radii


@helper
def _within(xi, yi, xj, yj, limit):
    """Centre distance <= limit (reach plus both radii), without a square root."""
    dx = xj - xi
    dy = yj - yi
    return dx * dx + dy * dy <= limit * limit


# ---------------------------------------------------------------------------------------------------------------
# Commands.


@helper
def _repeats_order(k, j, px, py, order, order_target, order_x, order_y):
    """Command ``k`` (target ``j``, point ``px, py``) asks for the order the unit already carries out."""
    if k == CMD_STOP:
        return order == ORDER_IDLE
    if k == CMD_HOLD:
        return order == ORDER_HOLD
    if k == CMD_ATTACK:
        return order == ORDER_ATTACK and order_target == j
    if k == CMD_HEAL:
        return order == ORDER_HEAL and order_target == j
    same_point = order_x == px and order_y == py
    if k == CMD_MOVE:
        return order == ORDER_MOVE and same_point
    return order == ORDER_ATTACK_MOVE and same_point


@inline
def _apply_commands(n, r, cmd, b, slot_stats):
    """Battle b's commands (``cmd``, a :class:`~smac_hard_gym.engine.state.Commands`) become its units' orders.

    A command that changes a unit's order cancels its attack wind-up (no shot, no cooldown spent); one that repeats
    the order (SMAC's controllers re-send theirs every step) leaves it (docs/engine_rules.md, C5)."""
    side, alive, order, order_target, order_x, order_y = r.side, r.alive, r.order, r.order_target, r.order_x, r.order_y
    target, fired_at, burst, windup_target = r.target, r.fired_at, r.burst, r.windup_target
    kind, cmd_target, cmd_x, cmd_y = cmd.kind[b], cmd.target[b], cmd.x[b], cmd.y[b]
    for i in range(n):
        fired_at[i] = NO_UNIT
        burst[i] = False
        k = kind[i]
        if k == CMD_NOOP or not alive[i]:
            continue
        if not _repeats_order(k, cmd_target[i], cmd_x[i], cmd_y[i], order[i], order_target[i], order_x[i],
                              order_y[i]):
            windup_target[i] = NO_UNIT
        if k == CMD_STOP:
            order[i] = ORDER_IDLE
            target[i] = NO_UNIT
        elif k == CMD_HOLD:
            order[i] = ORDER_HOLD
            target[i] = NO_UNIT
        elif k == CMD_MOVE or k == CMD_ATTACK_MOVE:
            order[i] = ORDER_MOVE if k == CMD_MOVE else ORDER_ATTACK_MOVE
            order_x[i] = cmd_x[i]
            order_y[i] = cmd_y[i]
            target[i] = NO_UNIT
        elif k == CMD_ATTACK or k == CMD_HEAL:
            j = cmd_target[i]
            if j < 0 or j >= n or j == i or not alive[j]:
                continue
            healer = slot_stats[i, _WEAPON] == WEAPON_HEAL
            if k == CMD_ATTACK and not healer and side[j] != side[i] and _can_hit(slot_stats, i, j):
                order[i] = ORDER_ATTACK
            elif k == CMD_HEAL and healer and side[j] == side[i]:
                order[i] = ORDER_HEAL
            else:
                continue
            order_target[i] = j
            target[i] = j


# ---------------------------------------------------------------------------------------------------------------
# 1. Timers.


@inline
def _timers(n, r, slot_stats):
    """Start of a loop: the snapshots the loop's phases read (who is alive, who engages whom), then the timers, then
    each unit's life as the attacks will find it (``life0``: who was hit calls for help)."""
    alive, alive0, target, engaged = r.alive, r.alive_at_loop, r.target, r.engaged
    health, shield, energy, cooldown, shield_wait = r.health, r.shield, r.energy, r.cooldown, r.shield_wait
    life0 = r.life0
    for i in range(n):
        alive0[i] = alive[i]
        engaged[i] = target[i]
        if not alive[i]:
            continue
        if cooldown[i] > 0.0:
            cooldown[i] -= 1.0
        regen = slot_stats[i, _REGEN]
        if regen > 0.0 and health[i] < slot_stats[i, _HEALTH]:
            health[i] = min(slot_stats[i, _HEALTH], health[i] + regen)
        decay = slot_stats[i, _DECAY]  # a Zerg structure off creep; a unit it kills dies in _deaths
        if decay > 0.0:
            health[i] -= decay
        if slot_stats[i, _SHIELD] > 0.0:
            if shield_wait[i] > 0.0:
                shield_wait[i] -= 1.0
            if shield_wait[i] <= 0.0 and shield[i] < slot_stats[i, _SHIELD]:
                shield[i] = min(slot_stats[i, _SHIELD], shield[i] + slot_stats[i, _SHIELD_REGEN])
        if slot_stats[i, _ENERGY_MAX] > 0.0 and energy[i] < slot_stats[i, _ENERGY_MAX]:
            energy[i] = min(slot_stats[i, _ENERGY_MAX], energy[i] + slot_stats[i, _ENERGY_REGEN])
        life0[i] = health[i] + shield[i]  # nothing changes life between here and the attacks


# ---------------------------------------------------------------------------------------------------------------
# 2. Targeting.


@helper
def _heal_wanted(alive, health, slot_stats, j):
    return (alive[j] and slot_stats[j, _IS_AIR] == 0 and (int(slot_stats[j, _ATTR]) & _BIO) != 0
            and health[j] < slot_stats[j, _HEALTH])


@helper
def _acquire_heal(n, i, side, alive, x, y, health, target, slot_stats):
    """Non-passive medivacs keep healing their target while it needs it and stays near; otherwise they take the
    damaged biological ally with the lowest life fraction within their auto-cast range (the nearest among equals),
    as MedivacHeal's TargetSorts (TSLifeFraction, TSDistance) order them (docs/engine_rules.md)."""
    scan = slot_stats[i, _SCAN]
    cur = target[i]
    if cur >= 0 and _heal_wanted(alive, health, slot_stats, cur) and _within(
            x[i], y[i], x[cur], y[cur], scan + _LEASH + slot_stats[i, _RADIUS] + slot_stats[cur, _RADIUS]):
        return
    best = NO_UNIT
    best_f = _INF
    best_d = _INF
    for j in range(n):
        if j == i or side[j] != side[i] or not _heal_wanted(alive, health, slot_stats, j):
            continue
        radii = slot_stats[i, _RADIUS] + slot_stats[j, _RADIUS]
        if _within(x[i], y[i], x[j], y[j], scan + radii):
            f = health[j] / slot_stats[j, _HEALTH]
            d = _edge_distance(x[i], y[i], x[j], y[j], radii)
            if f < best_f or (f == best_f and d < best_d):
                best_f = f
                best_d = d
                best = j
    target[i] = best


@helper
def _threatens(slot_stats, j, i):
    """Unit j has a weapon that can damage unit i (medivacs threaten nobody)."""
    return slot_stats[j, _DAMAGE] > 0 and slot_stats[j, _WEAPON] != WEAPON_HEAL and _can_hit(slot_stats, j, i)


@helper
def _rank(i, j, engaged, slot_stats):
    """SC2's acquisition priority of enemy j for unit i, best first: 0 j is attacking i, 1 j can hurt i, 2 other.

    ``engaged`` is every unit's target when the loop began, so the answer does not depend on which of the two units
    has the lower slot (both sides acquire from the same snapshot).
    """
    if engaged[j] == i:
        return 0
    if _threatens(slot_stats, j, i):
        return 1
    return 2


@helper
def _scan(n, i, reach, responder, side, alive, x, y, engaged, attacker, slot_stats):
    """SC2's automatic acquisition: the best enemy for unit i, or NO_UNIT.

    Among enemies within ``reach`` (edge to edge): those attacking i, then those that can hurt i, then the rest
    (:func:`_rank`); the closest within a rank. Failing all, a unit that responds takes the last enemy that hit it,
    wherever it is (rank 3).
    """
    best = NO_UNIT
    best_rank = 4
    best_d = _INF
    for j in range(n):
        if not alive[j] or side[j] == side[i] or not _can_hit(slot_stats, i, j):
            continue
        radii = slot_stats[i, _RADIUS] + slot_stats[j, _RADIUS]
        if _within(x[i], y[i], x[j], y[j], reach + radii):
            rank = _rank(i, j, engaged, slot_stats)
        elif responder and attacker[i] == j:
            rank = 3
        else:
            continue
        if rank > best_rank:
            continue
        d = _edge_distance(x[i], y[i], x[j], y[j], radii)
        if rank < best_rank or d < best_d:
            best_rank = rank
            best_d = d
            best = j
    return best


@helper
def _acquire(n, i, o, passive, side, alive, x, y, target, engaged, attacker, slot_stats):
    """SC2's target choice for a unit that acquires on its own (idle, attack-moving or holding); see ``_targeting``."""
    hold = o == ORDER_HOLD
    # SC2's Response (turn on an attacker beyond scan range) is how an idle unit reacts; a unit carrying out an
    # attack-move keeps to its order and engages only what it acquires, so SMAC-HARD's base, re-issuing its order
    # every step, cannot be pulled away one unit at a time, while SMAC's opponent, idle at its point, can.
    responder = (not passive) and o == ORDER_IDLE
    cur = target[i]
    if cur >= 0 and alive[cur]:
        radii = slot_stats[i, _RADIUS] + slot_stats[cur, _RADIUS]
        if _within(x[i], y[i], x[cur], y[cur], slot_stats[i, _RANGE] + radii):
            # In weapon range: keep it, unless it cannot hurt i and a threat to i is in weapon range too (SC2: a
            # target is kept until a higher-priority one, a threat, enters weapon range; docs/engine_rules.md, C15).
            # The best enemy in weapon range ranks threats first, so it is a threat if any is there.
            if not _threatens(slot_stats, cur, i):
                j = _scan(n, i, slot_stats[i, _RANGE], False, side, alive, x, y, engaged, attacker, slot_stats)
                if j >= 0 and _rank(i, j, engaged, slot_stats) < 2:
                    target[i] = j
            return
        if not hold and _within(x[i], y[i], x[cur], y[cur], slot_stats[i, _SCAN] + _LEASH + radii):
            # Chasing: re-acquire, and switch only to a better-ranked or (same rank) closer enemy.
            best = _scan(n, i, slot_stats[i, _SCAN], responder, side, alive, x, y, engaged, attacker, slot_stats)
            if best >= 0 and best != cur:
                cur_rank = _rank(i, cur, engaged, slot_stats)
                best_rank = _rank(i, best, engaged, slot_stats)
                if not _within(x[i], y[i], x[best], y[best],
                               slot_stats[i, _SCAN] + slot_stats[i, _RADIUS] + slot_stats[best, _RADIUS]):
                    best_rank = 3  # the responder's fallback: its last attacker, out of scan range
                if best_rank < cur_rank or (best_rank == cur_rank and _edge_distance(
                        x[i], y[i], x[best], y[best], slot_stats[i, _RADIUS] + slot_stats[best, _RADIUS])
                        < _edge_distance(x[i], y[i], x[cur], y[cur], radii)):
                    target[i] = best
            return
    reach = slot_stats[i, _RANGE] if hold else slot_stats[i, _SCAN]
    target[i] = _scan(n, i, reach, responder, side, alive, x, y, engaged, attacker, slot_stats)


@inline
def _targeting(n, r, slot_stats):
    """Who each unit engages this loop (SC2's rules; docs/engine_targeting.md lists each rule with its source).

    - Ordered attacks and heals keep their target until it dies (then the order completes): no switching.
    - Moving units acquire nothing. Passive (SMAC's ``*_RL``) units acquire only while attack-moving, never respond.
    - Units that acquire (idle, attack-moving, holding): a target in weapon range is kept, except that a target that
      cannot hurt the unit (a medivac) yields to the best-ranked threat within weapon range. A target out of weapon
      range is chased (not on hold) while the unit re-acquires every loop: it switches to an enemy attacking it, else
      to one that can hurt it, else to any enemy in scan range, and within a rank to a closer one (ties keep the
      chase).
      Without a target: the best enemy within scan range (weapon range on hold); a responder (not passive, idle: no
      order) then answers the last enemy that hit it, wherever it is.

    "Attacking it" is read from ``engaged``, the targets when the loop began (``_timers`` takes the snapshot).
    """
    side, alive, x, y, health = r.side, r.alive, r.x, r.y, r.health
    order, order_target, target, engaged, attacker = r.order, r.order_target, r.target, r.engaged, r.attacker
    for i in range(n):
        if not alive[i]:
            continue
        o = order[i]
        if o == ORDER_ATTACK or o == ORDER_HEAL:
            j = order_target[i]
            if j >= 0 and alive[j]:
                target[i] = j
                continue
            order[i] = ORDER_IDLE  # the ordered target is gone: the order is complete
            target[i] = NO_UNIT
            o = ORDER_IDLE
        passive = slot_stats[i, _PASSIVE] > 0
        if o == ORDER_MOVE or (passive and o != ORDER_ATTACK_MOVE):
            target[i] = NO_UNIT
        elif slot_stats[i, _WEAPON] == WEAPON_HEAL:
            _acquire_heal(n, i, side, alive, x, y, health, target, slot_stats)
        elif slot_stats[i, _DAMAGE] > 0:
            _acquire(n, i, o, passive, side, alive, x, y, target, engaged, attacker, slot_stats)


# ---------------------------------------------------------------------------------------------------------------
# 3. Movement.


@helper
def _cell(v, size):
    c = int(v)
    if c < 0:
        return 0
    if c >= size:
        return size - 1
    return c


@helper
def _waypoint(mover, px, py, gx, gy, walk, next_hop, los):
    """Where a walker heads now to reach (gx, gy): the goal if visible, else the farthest visible path cell."""
    mx, my = walk.shape[1], walk.shape[2]
    c = _cell(px, mx) * my + _cell(py, my)
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


@helper
def _slide(px, py, nx, ny, mover, walk):
    """Where a unit at (px, py) heading to (nx, ny) ends up: there if its centre stays walkable, else sliding
    along one axis, else staying put.

    Every move lands on SC2's fixed-point grid (``POSITION_GRID``), rounded half to even: a crowd pressing round
    units that stand turns rounding error into ever larger differences from loop to loop, and on the grid the same
    battle mirrored through the map's centre line keeps landing on the mirror image (the grid and even rounding are
    symmetric about any integer width)."""
    mx, my = walk.shape[1], walk.shape[2]
    nx = np.rint(min(max(nx, _EDGE), mx - _EDGE) * POSITION_GRID) * _GRID_STEP
    ny = np.rint(min(max(ny, _EDGE), my - _EDGE) * POSITION_GRID) * _GRID_STEP
    # Unsigned cell indices: a position is inside the map, so numba's code for negative indices is not needed (3m
    # with 4096 battles stepped about 3% faster).
    m = np.uint32(mover)
    if mover == MOVER_AIR or walk[m, np.uint32(nx), np.uint32(ny)]:
        return nx, ny
    if walk[m, np.uint32(nx), np.uint32(py)]:
        return nx, py
    if walk[m, np.uint32(px), np.uint32(ny)]:
        return px, ny
    return px, py


@helper
def _movable(i, order, slot_stats):
    """Whether unit i can be pushed at all: not rooted (speed 0) and not holding position."""
    return slot_stats[i, _SPEED] > 0.0 and order[i] != ORDER_HOLD


@helper
def _stands_in_way(k, i, side, order, stance, slot_stats):
    """Whether unit k stands in the way of walker i instead of giving way (docs/engine_rules.md, C11): an own unit
    standing to fire, holding or rooted (own units that walk or idle are shoved aside), or an enemy that is not
    walking (enemies push nobody, P1). Reads the stances movement decided before anyone stepped."""
    s = stance[k]
    if s == STANCE_FIRING or not _movable(k, order, slot_stats):
        return True
    return side[k] != side[i] and s == STANCE_NONE


@helper
def _blocker(n, i, nx, ny, side, alive, x, y, order, target, stance, slot_stats):
    """The unit that walker i, stepping to (nx, ny), would walk into most deeply among those that stand in its way
    (``_stands_in_way``; its own target excepted: it walks to that one), or -1. A step that does not bring it closer
    to a unit it already touches is free: it may slide along it. ``x, y``: the positions when movement began (units
    that stand in the way do not move in it, and the walker has not stepped yet)."""
    px, py = x[i], y[i]
    ri = slot_stats[i, _RADIUS]
    mover = slot_stats[i, _MOVER]
    best = -1
    deepest = 0.0
    for k in range(n):
        if k == i or k == target[i] or not alive[k] or slot_stats[k, _MOVER] != mover:
            continue
        rr = ri + slot_stats[k, _RADIUS]
        dx, dy = x[k] - nx, y[k] - ny
        d2 = dx * dx + dy * dy
        if d2 >= rr * rr:
            continue
        cx, cy = x[k] - px, y[k] - py
        if d2 >= cx * cx + cy * cy or not _stands_in_way(k, i, side, order, stance, slot_stats):
            continue
        depth = rr - math.sqrt(d2)
        if depth > deepest:
            deepest = depth
            best = k
    return best


@helper
def _steer(n, i, ux, uy, step, side, alive, x, y, order, target, stance, slot_stats, centre_x, turn_side):
    """The heading of blocked walker i (desired unit heading (ux, uy), ``step`` long) and the side it turns to
    (+1 left, -1 right, 0 none): straight if free; else the nearest free turn of 30, 60 or 90 degrees; else a slide
    along the unit in the way (its tangent), which takes a walker out of a pocket between two units where every turn
    up to 90 degrees closes on one of them; (0, 0, 0) if nothing is free, and the walker waits its turn (SC2's
    movers flow round units standing to fire where there is room, C11).

    A walker already going round (``turn_side`` != 0) keeps to that side, so it does not swing back into the pocket
    it left. Otherwise it tries the side away from the unit in the way first; a unit dead ahead is passed on the side
    that heads north (higher y), or, heading along y, toward the map's centre line ``centre_x``: rules that a battle
    mirrored through that line mirrors. ``x, y`` as in ``_blocker``."""
    px, py = x[i], y[i]
    k = _blocker(n, i, px + ux * step, py + uy * step, side, alive, x, y, order, target, stance, slot_stats)
    if k < 0:
        return ux, uy, 0.0
    cross = ux * (y[k] - py) - uy * (x[k] - px)  # > 0: the unit is on the walker's left, so turn right first
    if turn_side != 0.0:
        first = turn_side
    elif cross != 0.0:
        first = -1.0 if cross > 0.0 else 1.0
    elif ux != 0.0:
        first = 1.0 if ux > 0.0 else -1.0
    else:
        first = 1.0 if -uy * (centre_x - px) >= 0.0 else -1.0
    sides = 1 if turn_side != 0.0 else 2
    for turn in range(1, 4):
        angle = turn * (math.pi / 6.0)
        c, s = math.cos(angle), math.sin(angle)
        for t in range(sides):
            sign = first if t == 0 else -first
            vx, vy = ux * c - uy * s * sign, ux * s * sign + uy * c
            if _blocker(n, i, px + vx * step, py + vy * step, side, alive, x, y, order, target, stance,
                        slot_stats) < 0:
                return vx, vy, sign
    cx, cy = x[k] - px, y[k] - py
    d = math.sqrt(cx * cx + cy * cy)
    if d > 0.0:
        for t in range(sides):
            sign = first if t == 0 else -first
            vx, vy = -cy / d * sign, cx / d * sign  # the unit in the way turned 90 degrees toward that side
            if _blocker(n, i, px + vx * step, py + vy * step, side, alive, x, y, order, target, stance,
                        slot_stats) < 0:
                return vx, vy, sign
    return 0.0, 0.0, 0.0


@helper
def _goal(i, x0, y0, target, order_x, order_y):
    """Where walker i walks: its target (where it stood as movement began), else its order point."""
    j = target[i]
    if j >= 0:
        return x0[j], y0[j]
    return order_x[i], order_y[i]


@helper
def _goal_distance2(i, x0, y0, target, order_x, order_y):
    """Squared distance from walker i to its ``_goal``."""
    gx, gy = _goal(i, x0, y0, target, order_x, order_y)
    dx, dy = gx - x0[i], gy - y0[i]
    return dx * dx + dy * dy


@helper
def _round_side(s):
    """The side (``STANCE_LEFT`` or ``STANCE_RIGHT``) a walker with stance ``s`` is going round on: it was blocked
    last loop and keeps a side; 0 otherwise."""
    if (s & STANCE_KIND) != STANCE_WALKED or (s & STANCE_BLOCKED) == 0:
        return 0
    return s & STANCE_SIDE


@helper
def _yield_crossing(n, x0, y0, side, stance, target, order_x, order_y, slot_stats):
    """Walkers that give way (docs/engine_rules.md, C14): two own walkers going round on opposite sides (both blocked
    last loop, ``STANCE_LEFT`` against ``STANCE_RIGHT``) whose edges are within ``_TOUCHING`` would walk into each
    other, be shoved apart and stand there, each one's only free turn leading into the other; the one farther from
    its goal (its target, else its order point; the higher slot on a tie) takes the other's side instead, and they
    go round one after the other. Decided for every pair from the stances as movement began, then applied, so the
    slot order does not matter. ``x0, y0``: positions as movement began."""
    for i in range(n):
        si = _round_side(stance[i])
        if si == 0:
            continue
        for j in range(i + 1, n):
            sj = _round_side(stance[j])
            if side[j] != side[i] or sj == 0 or sj == si:
                continue
            if not _within(x0[i], y0[i], x0[j], y0[j], slot_stats[i, _RADIUS] + slot_stats[j, _RADIUS] + _TOUCHING):
                continue
            if _goal_distance2(i, x0, y0, target, order_x, order_y) > _goal_distance2(j, x0, y0, target, order_x,
                                                                                      order_y):
                stance[i] |= STANCE_YIELDS
            else:
                stance[j] |= STANCE_YIELDS
    for i in range(n):
        if stance[i] & STANCE_YIELDS:
            stance[i] = (stance[i] & ~(STANCE_YIELDS | STANCE_SIDE)) | (
                STANCE_RIGHT if (stance[i] & STANCE_LEFT) else STANCE_LEFT)


@inline
def _movement(n, r, slot_stats, terrain):
    """Every unit steps toward its target (unless in range) or its order point; ``stance`` records who walked and
    who stood to fire, for separation. A walker that separation found blocked by a unit that does not give way
    (``STANCE_BLOCKED``) steers round it (``_steer``), or waits.

    Simultaneous: whether a unit is in range and where its target stands are read from ``x0, y0``, the positions
    when the phase began, and who stands and who walks is decided for every unit before anyone steps (steering reads
    it). Read live, the lower slots (red) would move first and the higher slots would find the gap already closed,
    so red always advanced further than blue in a mirrored fight. (Group arrival, the other way a move completes, is
    decided where units bump: in ``_separation``.)
    """
    alive, x, y, x0, y0, stance, side = r.alive, r.x, r.y, r.x0, r.y0, r.stance, r.side
    order, order_x, order_y, target, windup_target = r.order, r.order_x, r.order_y, r.target, r.windup_target
    walk, next_hop, los, open_field = terrain.walk, terrain.next_hop, terrain.los, terrain.open_field
    for i in range(n):
        x0[i] = x[i]
        y0[i] = y[i]
    going_round = 0  # walkers blocked last loop with a kept side: only two or more can meet head on (C14)
    for i in range(n):
        blocked = stance[i] & (STANCE_BLOCKED | STANCE_SIDE)
        stance[i] = STANCE_NONE
        if not alive[i] or slot_stats[i, _SPEED] <= 0.0 or order[i] == ORDER_HOLD:
            continue
        j = target[i]
        o = order[i]
        if j >= 0:
            # in range, or within the slop of an attack in progress on it (C8): stand and act
            slop = slot_stats[i, _SLOP] if windup_target[i] == j else 0.0
            if _within(x0[i], y0[i], x0[j], y0[j],
                       slot_stats[i, _RANGE] + slop + slot_stats[i, _RADIUS] + slot_stats[j, _RADIUS]):
                stance[i] = STANCE_FIRING
                continue
            windup_target[i] = NO_UNIT  # walking after the target abandons the attack in progress
        elif o == ORDER_MOVE or o == ORDER_ATTACK_MOVE:
            dx, dy = order_x[i] - x0[i], order_y[i] - y0[i]
            if dx * dx + dy * dy <= _ARRIVE * _ARRIVE:
                order[i] = ORDER_IDLE
                continue
        else:
            continue
        stance[i] = STANCE_WALKED | blocked
        if _round_side(stance[i]):
            going_round += 1
    if going_round >= 2:
        _yield_crossing(n, x0, y0, side, stance, target, order_x, order_y, slot_stats)
    centre_x = 0.5 * walk.shape[1]
    for i in range(n):
        if (stance[i] & STANCE_KIND) != STANCE_WALKED:
            continue
        gx, gy = _goal(i, x0, y0, target, order_x, order_y)
        mover = int(slot_stats[i, _MOVER])
        if mover == MOVER_AIR or open_field[mover]:  # checked here: even an early-returning call costs
            wx, wy = gx, gy
        else:
            wx, wy = _waypoint(mover, x[i], y[i], gx, gy, walk, next_hop, los)
        dx, dy = wx - x[i], wy - y[i]
        d = math.sqrt(dx * dx + dy * dy)
        if d < 1e-12:
            stance[i] = STANCE_NONE
            continue
        step = min(slot_stats[i, _SPEED], d)
        ux, uy = dx / d, dy / d
        if stance[i] & STANCE_BLOCKED:
            kept = stance[i] & STANCE_SIDE
            turn_side = 1.0 if kept == STANCE_LEFT else -1.0 if kept == STANCE_RIGHT else 0.0
            vx, vy, turned = _steer(n, i, ux, uy, step, side, alive, x0, y0, order, target, stance, slot_stats,
                                    centre_x, turn_side)
            if vx == 0.0 and vy == 0.0:
                stance[i] = STANCE_BLOCKED  # waits: stands this loop, and looks again (either side) next loop
                continue
            if turned > 0.0:  # going round: keeps looking, on the same side, until straight is free
                stance[i] = STANCE_WALKED | STANCE_BLOCKED | STANCE_LEFT
            elif turned < 0.0:
                stance[i] = STANCE_WALKED | STANCE_BLOCKED | STANCE_RIGHT
            else:
                stance[i] = STANCE_WALKED
            ux, uy = vx, vy
        x[i], y[i] = _slide(x[i], y[i], x[i] + ux * step, y[i] + uy * step, mover, walk)


# ---------------------------------------------------------------------------------------------------------------
# 4. Separation.


@helper
def _sort_by_x(n, by_x, key, x):
    """Order the slots by (x, slot) into ``by_x``, with ``key[a] = x[by_x[a]]``.

    An insertion sort: units move little between passes, so the order left by the previous pass is nearly right and
    sorting costs about one comparison per unit. The slot breaks ties, so the order depends on the positions alone.
    """
    for a in range(n):
        key[a] = x[by_x[a]]
    for a in range(1, n):
        k = key[a]
        s = by_x[a]
        c = a - 1
        while c >= 0 and (key[c] > k or (key[c] == k and by_x[c] > s)):
            key[c + 1] = key[c]
            by_x[c + 1] = by_x[c]
            c -= 1
        key[c + 1] = k
        by_x[c + 1] = s


@inline
def _any_overlap(n, alive, x, y, slot_stats):
    """Whether two live units of the same plane overlap, every pair tested (for a few units, cheaper than sorting;
    inlined, so with the unit count fixed at compile time LLVM unrolls the pairs)."""
    for i in range(n):
        if not alive[i]:
            continue
        for j in range(i + 1, n):
            rr = slot_stats[i, _RADIUS] + slot_stats[j, _RADIUS]
            dx = x[j] - x[i]
            dy = y[j] - y[i]
            if dx * dx + dy * dy < rr * rr and alive[j] and slot_stats[j, _MOVER] == slot_stats[i, _MOVER]:
                return True
    return False


@helper
def _push_weights(i, j, side, order, stance, slot_stats):
    """How the overlap of units i and j is shared: ``(wi, wj)``, each unit's part in proportion to its weight.

    SC2 (docs/engine_rules.md, section 1): units on hold or rooted are not pushed. Every SMAC unit has the same push
    priority, so enemies push nobody: a unit that walked into an enemy is put back (when neither walked, both shoved
    there by their own side, they share it, an approximation). Among own units a walker shoves an idle one but not
    one standing to fire; walkers steer round those (``_steer``).
    """
    wi = 1.0 if _movable(i, order, slot_stats) else 0.0
    wj = 1.0 if _movable(j, order, slot_stats) else 0.0
    si, sj = stance[i] & STANCE_KIND, stance[j] & STANCE_KIND
    if side[i] != side[j]:
        if si == STANCE_WALKED or sj == STANCE_WALKED:
            if si != STANCE_WALKED:
                wi = 0.0
            if sj != STANCE_WALKED:
                wj = 0.0
    elif si == STANCE_FIRING and sj == STANCE_WALKED:
        wi = 0.0
    elif sj == STANCE_FIRING and si == STANCE_WALKED:
        wj = 0.0
    return wi, wj


@helper
def _push_apart(i, j, dx, dy, d2, rr, wi, wj, push_x, push_y):
    """Add the pushes that part overlapping units i and j (j - i = (dx, dy), d2 = dx^2 + dy^2 < rr^2), shared by
    the weights ``wi, wj`` (``_push_weights``), to ``push_x, push_y``; return the depth of the overlap (0 when
    neither may move).
    """
    if wi + wj == 0.0:
        return 0.0
    d = math.sqrt(d2)
    if d < 1e-9:  # exactly stacked: split along a fixed direction that depends on the pair, not on its order
        angle = 2.399963229728653 * (min(i, j) * 31 + max(i, j))
        ux, uy = math.cos(angle), math.sin(angle)
        if i > j:
            ux, uy = -ux, -uy
    else:
        ux, uy = dx / d, dy / d
    overlap = rr - d
    share_i = overlap * wi / (wi + wj)
    share_j = overlap - share_i
    push_x[i] -= ux * share_i
    push_y[i] -= uy * share_i
    push_x[j] += ux * share_j
    push_y[j] += uy * share_j
    return overlap


@helper
def _bump(mover, other, order, order_x, order_y, target, x, y):
    """Whether ``mover``, walking on a move or attack-move with no target, has bumped into ``other``, a unit of its
    side that was idle when the pass began, within 3 of its point: SC2's group arrival, its order is then complete."""
    o = order[mover]
    if order[other] != ORDER_IDLE or target[mover] >= 0 or not (o == ORDER_MOVE or o == ORDER_ATTACK_MOVE):
        return False
    return _within(x[mover], y[mover], order_x[mover], order_y[mover], _CROWD_ARRIVE)


@inline
def _separation(n, r, slot_stats, walk, max_radius):
    """One pass of pushes over every pair that overlaps when the pass begins; returns the deepest overlap pushed
    (0: nothing moved).

    Simultaneous (Jacobi): every push is computed from the positions when the pass began and the pushes a unit
    receives add up (in ``push_x, push_y``, scratch, zeroed once the first overlap is found); then each pushed unit
    slides from where it was toward its pushed position, stopping at walls. Pushes applied one pair after another
    (Gauss-Seidel) favour the units met first, and in a mirrored fight that decided battles: blue lost 2s3z 64-0 to
    red with the same script on both sides.

    Sweep and prune: with the units sorted by x, unit i's partners lie within ``radius_i + max_radius`` further
    along the sorted list, so the pass stops looking at the first unit beyond that (27 marines against 30: about 4
    pairs per unit instead of 28). A battle of a few units (``_FEW_UNITS``) first tests every pair, and a pass that
    would find no overlap ends there (``by_x`` may then be out of date: the next sort restores the order, which
    depends on the positions alone).

    Group arrival happens here, where units bump: a unit walking to a point that bumps into a unit of its side
    already idle within 3 of that point stops there, idle (SC2: a crowd sent to one point stops as a clump around it
    instead of pushing toward it for ever). Units that arrive in a pass are marked ``_ARRIVING`` and become idle
    when it ends, so no one arrives by bumping into a unit that only arrived in the same pass.

    ``walk`` is the terrain's walkable grids; ``max_radius`` the largest radius among the battle's units.
    """
    side, alive, x, y, order, order_x, order_y = r.side, r.alive, r.x, r.y, r.order, r.order_x, r.order_y
    target, stance, by_x, key = r.target, r.stance, r.by_x, r.key
    push_x, push_y = r.x0, r.y0  # movement is done with its snapshot: the arrays sum the pushes now
    if n <= _FEW_UNITS and not _any_overlap(n, alive, x, y, slot_stats):
        return 0.0  # most passes find nothing to push: skip the sort and the sweep
    _sort_by_x(n, by_x, key, x)
    worst = 0.0
    pushed = False
    arriving = False
    for a in range(n):
        i = by_x[a]
        if not alive[i]:
            continue
        window = slot_stats[i, _RADIUS] + max_radius
        for c in range(a + 1, n):
            if key[c] - key[a] >= window:
                break
            j = by_x[c]
            if not alive[j] or slot_stats[j, _MOVER] != slot_stats[i, _MOVER]:
                continue
            rr = slot_stats[i, _RADIUS] + slot_stats[j, _RADIUS]
            dx = x[j] - x[i]
            dy = y[j] - y[i]
            d2 = dx * dx + dy * dy
            if d2 >= rr * rr:
                continue
            if not pushed:
                for k in range(n):
                    push_x[k] = 0.0
                    push_y[k] = 0.0
                pushed = True
            wi, wj = _push_weights(i, j, side, order, stance, slot_stats)
            worst = max(worst, _push_apart(i, j, dx, dy, d2, rr, wi, wj, push_x, push_y))
            # A walker put back by a unit that does not give way steers round it next loop (``_movement``).
            if wj == 0.0 and wi > 0.0 and (stance[i] & STANCE_KIND) == STANCE_WALKED:
                stance[i] |= STANCE_BLOCKED
            elif wi == 0.0 and wj > 0.0 and (stance[j] & STANCE_KIND) == STANCE_WALKED:
                stance[j] |= STANCE_BLOCKED
            if side[i] == side[j]:
                if _bump(i, j, order, order_x, order_y, target, x, y):
                    order[i] = _ARRIVING
                    arriving = True
                elif _bump(j, i, order, order_x, order_y, target, x, y):
                    order[j] = _ARRIVING
                    arriving = True
    if arriving:
        for i in range(n):
            if order[i] == _ARRIVING:
                order[i] = ORDER_IDLE
    if pushed:
        for i in range(n):
            if push_x[i] != 0.0 or push_y[i] != 0.0:
                x[i], y[i] = _slide(x[i], y[i], x[i] + push_x[i], y[i] + push_y[i], int(slot_stats[i, _MOVER]), walk)
    return worst


# ---------------------------------------------------------------------------------------------------------------
# 5. Attacks, heals, bursts.


@helper
def _damage(j, amount, source, health, shield, shield_wait, attacker, slot_stats):
    """One hit of ``amount`` on unit j: shields absorb first, then armour applies, at least 0.5 on health."""
    if shield[j] > 0.0:
        absorbed = min(shield[j], amount)
        shield[j] -= absorbed
        amount -= absorbed
        if amount > 0.0:
            health[j] -= max(amount - slot_stats[j, _ARMOR], _MIN_DAMAGE)
    else:
        health[j] -= max(amount - slot_stats[j, _ARMOR], _MIN_DAMAGE)
    if slot_stats[j, _SHIELD] > 0.0:
        shield_wait[j] = _SHIELD_DELAY
    attacker[j] = source


@helper
def _hit_amount(slot_stats, i, j):
    """Damage per hit of unit i's weapon on unit j, with the bonus against j's attributes."""
    amount = slot_stats[i, _DAMAGE]
    if (int(slot_stats[j, _ATTR]) & int(slot_stats[i, _BONUS_ATTR])) != 0:
        amount += slot_stats[i, _BONUS]
    return amount


@helper
def _line_splash(n, i, j, side, alive0, x, y, health, shield, shield_wait, attacker, slot_stats):
    """Colossus: each hit lands on every enemy ground unit touching a line across the target."""
    ux, uy = x[j] - x[i], y[j] - y[i]
    norm = math.sqrt(ux * ux + uy * uy)
    if norm < 1e-9:
        ux, uy = 1.0, 0.0
    else:
        ux, uy = ux / norm, uy / norm
    half_length = 0.5 * slot_stats[i, _SPLASH_L]
    half_width = 0.5 * slot_stats[i, _SPLASH_W]
    hits = int(slot_stats[i, _HITS])
    for k in range(n):
        if not alive0[k] or side[k] == side[i] or slot_stats[k, _IS_AIR] > 0:
            continue
        vx, vy = x[k] - x[j], y[k] - y[j]
        along_line = abs(-vx * uy + vy * ux)  # the line runs perpendicular to the shot
        across_line = abs(vx * ux + vy * uy)
        rk = slot_stats[k, _RADIUS]
        if k == j or (along_line <= half_length + rk and across_line <= half_width + rk):
            amount = _hit_amount(slot_stats, i, k)
            for _ in range(hits):
                _damage(k, amount, i, health, shield, shield_wait, attacker, slot_stats)


@helper
def _burst(n, i, side, alive0, x, y, health, shield, shield_wait, attacker, burst, slot_stats):
    """Baneling: damage every enemy ground unit whose edge is within the splash radius, then die."""
    radius = slot_stats[i, _SPLASH_R]
    for k in range(n):
        if not alive0[k] or side[k] == side[i] or slot_stats[k, _IS_AIR] > 0:
            continue
        dx, dy = x[k] - x[i], y[k] - y[i]
        if math.sqrt(dx * dx + dy * dy) - slot_stats[k, _RADIUS] <= radius:
            _damage(k, _hit_amount(slot_stats, i, k), i, health, shield, shield_wait, attacker, slot_stats)
    health[i] = 0.0
    burst[i] = True


@helper
def _heal(i, j, health, energy, fired_at, slot_stats):
    missing = slot_stats[j, _HEALTH] - health[j]
    if missing <= 0.0 or (int(slot_stats[j, _ATTR]) & _BIO) == 0 or slot_stats[j, _IS_AIR] > 0:
        return
    cost = slot_stats[i, _HEAL_COST]
    amount = min(slot_stats[i, _HEAL_RATE], missing, energy[i] / cost)
    if amount <= 0.0:
        return
    health[j] += amount
    energy[i] -= amount * cost
    fired_at[i] = j


@helper
def _uniform(rng):
    """Next number in [0, 1) of a battle's xorshift64* stream (``rng`` is its one-element state)."""
    z = rng[0]
    z ^= z >> np.uint64(12)
    z ^= z << np.uint64(25)
    z ^= z >> np.uint64(27)
    rng[0] = z
    return float((z * np.uint64(2685821657736338717)) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@helper
def _target_in_reach(i, alive0, x, y, target, slot_stats, extra=0.0):
    """Unit i's target if both were alive when the loop began and it is within i's weapon range (plus ``extra``),
    else NO_UNIT."""
    j = target[i]
    if not alive0[i] or j < 0 or not alive0[j]:
        return NO_UNIT
    reach = slot_stats[i, _RANGE] + extra + slot_stats[i, _RADIUS] + slot_stats[j, _RADIUS]
    if not _within(x[i], y[i], x[j], y[j], reach):
        return NO_UNIT
    return j


@helper
def _land_pending(n, alive0, x, y, health, shield, shield_wait, attacker, pending_target, pending_eta, pending_hits,
                  slot_stats):
    """Delayed hits due this loop land: missiles (they home and never miss, and land even if their shooter has
    died) and the zealot's second blade (only while the zealot lives and its target is within the blade's reach).
    Returns whether any landed."""
    landed = False
    for i in range(n):
        j = pending_target[i]
        if j < 0:
            continue
        pending_eta[i] -= 1
        if pending_eta[i] > 0:
            continue
        pending_target[i] = NO_UNIT
        if not alive0[j]:
            continue
        if slot_stats[i, _MISSILE_SPEED] <= 0.0 and not (
                alive0[i] and _within(x[i], y[i], x[j], y[j], slot_stats[i, _SECOND_REACH])):
            continue
        amount = _hit_amount(slot_stats, i, j)
        for _ in range(pending_hits[i]):
            _damage(j, amount, i, health, shield, shield_wait, attacker, slot_stats)
        landed = True
    return landed


@helper
def _fire(i, j, x, y, health, shield, shield_wait, attacker, pending_target, pending_eta, pending_hits,
          slot_stats):
    """Unit i's plain weapon fires at unit j: instant hits land now, a missile's when it arrives (flight centre to
    centre at the missile's speed), a zealot's second blade ``second_hit_delay`` loops after the first.

    One pending hit per unit is enough: every SMAC missile's flight and the blade's delay are shorter than the
    weapon's period (docs/engine_rules.md, section 2).
    """
    hits = int(slot_stats[i, _HITS])
    speed = slot_stats[i, _MISSILE_SPEED]
    if speed > 0.0:
        dx, dy = x[j] - x[i], y[j] - y[i]
        pending_target[i] = j
        pending_eta[i] = max(1, math.ceil(math.sqrt(dx * dx + dy * dy) / speed))
        pending_hits[i] = hits
        return
    now = hits
    if slot_stats[i, _SECOND_DELAY] > 0.0 and hits > 1:
        now = 1
        pending_target[i] = j
        pending_eta[i] = max(1, math.ceil(slot_stats[i, _SECOND_DELAY]))
        pending_hits[i] = hits - 1
    amount = _hit_amount(slot_stats, i, j)
    for _ in range(now):
        _damage(j, amount, i, health, shield, shield_wait, attacker, slot_stats)


@helper
def _answers_call(m, j, source, alive0, health, order, target, slot_stats):
    """Unit m, an ally of unit j (``_calls_for_help`` picks them), answers j's call for help against ``source``: m is
    not j, its weapon is acquiring (idle and not passive, or attack-moving: the answer is an acquisition, CWeapon's
    AcquireCallForHelpFilters), it can hit the source and has no live target. Holding units acquire only in weapon
    range and answer nothing; a move or an ordered attack acquires nothing."""
    if m == j or not alive0[m] or health[m] <= 0.0:
        return False
    acquiring = order[m] == ORDER_ATTACK_MOVE or (order[m] == ORDER_IDLE and slot_stats[m, _PASSIVE] == 0)
    if not acquiring or slot_stats[m, _DAMAGE] <= 0 or slot_stats[m, _WEAPON] == WEAPON_HEAL:
        return False
    t = target[m]
    return (t < 0 or not alive0[t]) and _can_hit(slot_stats, m, source)


@inline
def _calls_for_help(n, r, slot_stats, now):
    """SC2's call for help (docs/engine_rules.md, C13): a unit hit by an enemy this loop calls, unless it called in
    the last ``CALL_FOR_HELP_PERIOD_LOOPS`` (``help_at``: the battle loop ``now`` from which it may call again), the
    allies whose edge is within ``CALL_FOR_HELP_RADIUS`` of it. Each that answers (``_answers_call``) acquires the
    caller's attacker: an attack-moving unit takes it as its target (chased while within its scan range plus the
    leash, like any acquired target); an idle one takes it as if it had been hit by it, so its response (``_scan``'s
    last resort) turns it on that attacker wherever it is."""
    side, alive0, x, y, health, shield = r.side, r.alive_at_loop, r.x, r.y, r.health, r.shield
    order, target, attacker, help_at, life0, burst = r.order, r.target, r.attacker, r.help_at, r.life0, r.burst
    for j in range(n):
        source = attacker[j]
        if (health[j] + shield[j] >= life0[j] or help_at[j] > now or not alive0[j] or burst[j] or source < 0
                or side[source] == side[j]):
            continue
        help_at[j] = now + CALL_FOR_HELP_PERIOD_LOOPS
        for m in range(n):
            if side[m] != side[j] or not _within(x[j], y[j], x[m], y[m], CALL_FOR_HELP_RADIUS + slot_stats[m, _RADIUS]):
                continue
            if _answers_call(m, j, source, alive0, health, order, target, slot_stats):
                if order[m] == ORDER_ATTACK_MOVE:
                    target[m] = source
                else:
                    attacker[m] = source


@inline
def _attacks(n, r, slot_stats, jitter_lo, jitter_hi, now):
    """Every unit alive when the loop began and in reach of its target acts: delayed hits land, weapons fire once
    their wind-up is over and they are off cooldown (each shot's cooldown gets a uniform random delay in
    [``jitter_lo``, ``jitter_hi``) loops), banelings burst, then medivacs heal.

    The wind-up (SC2's DamagePoint, docs/engine_rules.md C5) lasts ``wind_up`` loops. It starts once the
    target is in reach and the cooldown has at most that many loops left, so in steady fire it overlaps the end of
    the cooldown and the period stays the weapon's. The target changing, dying or going further than the weapon's
    range slop past its range cancels it (so does a new order, ``_apply_commands``) without spending the
    cooldown."""
    side, alive0, x, y, health, shield = r.side, r.alive_at_loop, r.x, r.y, r.health, r.shield
    energy, cooldown, shield_wait, target, attacker = r.energy, r.cooldown, r.shield_wait, r.target, r.attacker
    fired_at, burst, rng, windup, windup_target = r.fired_at, r.burst, r.rng, r.windup, r.windup_target
    pending_target, pending_eta, pending_hits = r.pending_target, r.pending_eta, r.pending_hits
    hit = _land_pending(n, alive0, x, y, health, shield, shield_wait, attacker, pending_target, pending_eta,
                        pending_hits, slot_stats)
    heals = False
    for i in range(n):
        j = _target_in_reach(i, alive0, x, y, target, slot_stats)
        if windup_target[i] >= 0 and windup_target[i] != j:
            # an attack in progress goes on while its target stays within the range slop (docs/engine_rules.md C8)
            if _target_in_reach(i, alive0, x, y, target, slot_stats, slot_stats[i, _SLOP]) == windup_target[i]:
                j = windup_target[i]
            else:
                windup_target[i] = NO_UNIT
        if j < 0:
            continue
        weapon = slot_stats[i, _WEAPON]
        if weapon == WEAPON_HEAL:
            heals = True
        elif weapon == WEAPON_BURST:
            _burst(n, i, side, alive0, x, y, health, shield, shield_wait, attacker, burst, slot_stats)
            hit = True
        else:
            if windup_target[i] < 0:  # the attack starts (the cooldown has at most the wind-up left)
                if cooldown[i] > slot_stats[i, _WIND_UP]:
                    continue  # reloading: too early to start an attack
                windup_target[i] = j
                windup[i] = int(slot_stats[i, _WIND_UP])
            if windup[i] > 0:
                windup[i] -= 1
                continue
            windup_target[i] = NO_UNIT  # the shot; the cooldown has run out (it was at most the wind-up)
            hit = True
            if weapon == _LINE:
                _line_splash(n, i, j, side, alive0, x, y, health, shield, shield_wait, attacker, slot_stats)
            else:
                _fire(i, j, x, y, health, shield, shield_wait, attacker, pending_target, pending_eta, pending_hits,
                      slot_stats)
            cooldown[i] += slot_stats[i, _COOLDOWN]
            if jitter_hi > jitter_lo:  # SC2 adds a random delay to every attack
                cooldown[i] += jitter_lo + (jitter_hi - jitter_lo) * _uniform(rng)
            fired_at[i] = j
    if hit:
        _calls_for_help(n, r, slot_stats, now)  # before heals, which could hide a small hit
    # Heals land after every shot of the loop, so a unit killed this loop stays dead and a heal never depends on
    # whether the medivac's slot comes before or after the shooters' (red's medivac healed before blue fired, blue's
    # after red fired: the same fight went differently for the two sides).
    if heals:
        for i in range(n):
            if slot_stats[i, _WEAPON] == WEAPON_HEAL:
                j = _target_in_reach(i, alive0, x, y, target, slot_stats)
                if j >= 0 and health[j] > 0.0:
                    _heal(i, j, health, energy, fired_at, slot_stats)


# ---------------------------------------------------------------------------------------------------------------
# 6. Deaths, and the drivers.


@inline
def _deaths(n, r):
    alive, health, shield, order, target = r.alive, r.health, r.shield, r.order, r.target
    for i in range(n):
        if alive[i] and health[i] <= 0.0:
            alive[i] = False
            health[i] = 0.0
            shield[i] = 0.0
            order[i] = ORDER_IDLE
            target[i] = NO_UNIT
            for j in range(n):  # nobody engages a dead unit (ordered attacks complete in the next targeting)
                if target[j] == i:
                    target[j] = NO_UNIT


@inline
def _step_battle(n, b, st, cmd, slot_stats, terrain, n_loops, jitter, scratch):
    """Apply battle b's commands, then run ``n_loops`` game loops on it (``n`` units).

    ``st``: the :class:`~smac_hard_gym.engine.state.BattleState`; ``cmd``: the
    :class:`~smac_hard_gym.engine.state.Commands`; ``slot_stats`` (U, columns) float64: the unit table row of each
    slot; ``terrain``: the map's :class:`~smac_hard_gym.engine.terrain.Terrain`; ``jitter`` (2,) float64 = (low, high):
    each attack's cooldown gets a uniform random delay in [low, high) game loops, (0, 0) for none; ``scratch``: the
    :class:`~smac_hard_gym.engine.state.Scratch` working arrays.
    """
    r = battle_rows(st, scratch, b)
    jitter_lo, jitter_hi = jitter[0], jitter[1]
    walk = terrain.walk
    max_radius = 0.0
    for i in range(n):
        max_radius = max(max_radius, slot_stats[i, _RADIUS])
    worst = 0.0
    _apply_commands(n, r, cmd, b, slot_stats)
    loop0 = r.loop[0]
    for k in range(n_loops):
        _timers(n, r, slot_stats)
        _targeting(n, r, slot_stats)
        _movement(n, r, slot_stats, terrain)
        worst = _separation(n, r, slot_stats, walk, max_radius)
        _attacks(n, r, slot_stats, jitter_lo, jitter_hi, loop0 + k)
        _deaths(n, r)
    # Crowds chasing one target re-compress a little every loop; settle them before anyone observes the state. When
    # the last pass pushed nothing, nothing has moved since, and a settling pass would push nothing either.
    if worst > 0.0:
        for _ in range(_SETTLE_PASSES):
            if _separation(n, r, slot_stats, walk, max_radius) < _SETTLED:
                break
    # Through a view: inlined into step_batch's prange body, ``st.loop[b] += n_loops`` wrote to a private copy
    # (numba 0.68 drops item writes to a named tuple's 1-D field in a parfor; writes through views land).
    r.loop[0] += n_loops


@njit(cache=True, error_model="numpy", _nrt=False)
def step_battles(start, stop, st, cmd, slot_stats, terrain, n_loops, active, jitter, scratch, units):
    """Apply the commands, then run ``n_loops`` game loops, for battles ``start`` to ``stop - 1`` with ``active[b]``,
    on the calling thread.

    ``st``: the :class:`~smac_hard_gym.engine.state.BattleState`; ``cmd``: the
    :class:`~smac_hard_gym.engine.state.Commands`; ``slot_stats`` (U, columns) float64: the unit table row of each
    slot; ``terrain``: the map's :class:`~smac_hard_gym.engine.terrain.Terrain`; ``active`` (B,) bool; ``jitter``
    (2,) float64: the cooldown delay's range in game loops, (0, 0) for none; ``scratch``: the
    :class:`~smac_hard_gym.engine.state.Scratch` working arrays. ``units`` selects the overload: ``GENERIC`` (an empty
    tuple) reads the number of units from the state's shape; ``units_marker(n)`` (a tuple of n zeros) compiles an
    overload for exactly n units (``step_kernels_for``).
    """
    n = st.alive.shape[1] if len(units) == 0 else len(units)
    for b in range(start, stop):
        if active[b]:
            _step_battle(n, b, st, cmd, slot_stats, terrain, n_loops, jitter, scratch)


@njit(cache=True, parallel=True, error_model="numpy", _nrt=False)
def step_batch(st, cmd, slot_stats, terrain, n_loops, active, jitter, scratch, workers, next_battle, units):
    """``step_battles`` over the whole batch on numba's threads (the arguments and ``units`` as there).

    One prange iteration per worker thread (``workers``: numba's thread count); each takes chunks of battles from
    ``next_battle`` (an int64 array of one element, the shared counter) until all are taken (see ``scheduling``).
    Each chunk is one call of the compiled ``step_battles``: inlining the battle here instead made numba's parfor
    passes take 87 s to compile this kernel on 2 cores, against 4 s (and the unit-count overloads, which inlined it
    until they took the count as a tuple type, stepped no faster for it). The map's constants stay apart
    (``slot_stats``, ``terrain``, ``jitter``): numba's parfor cannot hand a prange body a tuple nested in a tuple (a
    Setup bundle holding the Terrain failed to lower here, and so did building it inside the body).
    """
    n_battles = st.alive.shape[0]
    chunk = max(1, n_battles // (workers * CHUNKS_PER_THREAD))
    next_battle[0] = 0
    for _ in prange(workers):
        while True:
            start = fetch_add(next_battle, chunk)
            if start >= n_battles:
                break
            step_battles(start, min(start + chunk, n_battles), st, cmd, slot_stats, terrain, n_loops, active, jitter,
                         scratch, units)


GENERIC = ()  # ``units`` of the overloads that read the unit count from the state's shape


def units_marker(n_units: int) -> tuple:
    """``units`` of the overloads compiled for exactly ``n_units`` units per battle: a tuple of that many int8 zeros,
    whose type (``UniTuple(int8, n)``) carries the count. A type, not a closure: one dispatcher holds every count's
    overload, numba's cache keeps them under one index, and ``step_batch`` calls ``step_battles``'s for its own."""
    if isinstance(n_units, bool) or not isinstance(n_units, int) or n_units < 1:
        raise ValueError(f"n_units must be a positive int (units per battle), got {n_units!r}")
    return (np.int8(0),) * n_units


def step_kernels_for(n_units: int) -> tuple[Any, Any, tuple]:
    """``(step_batch, step_battles, units)``: the drivers and the ``units`` argument that selects their overloads
    compiled for battles of exactly ``n_units`` units.

    With the count fixed at compile time LLVM can unroll the phases' loops over units and drop their bounds (3m at
    4096 battles stepped about 10% faster when every helper was inlined too; with the helpers called, the gain was
    within the noise of the measurement). The price is a compilation per unit count (about 20 s of CPU, once: numba
    caches it on disk like every kernel), so the engine takes these for big batches only (``BattleEngine``'s
    ``specialize``).
    """
    return step_batch, step_battles, units_marker(n_units)
