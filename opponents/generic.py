"""Generic scripts: tactics that need no map knowledge and run on every map, for either side.

Units that cannot move (the spine crawler) only pick targets already in range; medivacs follow the army and heal
the most injured unit (:func:`~smac_hard_gym.opponents.helpers.support_healers`).
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.opponents.helpers import (
    BatchScript,
    Frame,
    Memory,
    Orders,
    argmin_masked,
    lowest,
    nearest,
    retreat_points,
    threatened,
)

__all__ = ["Nearest", "Weakest", "WeakestEach", "FocusFire", "Kite", "RetreatWounded", "Stop", "Chase",
           "RoundRobin", "RoundRobinIntended", "attack_nearest", "attack_shared", "nearest_threat", "back_off"]

READY_LOOPS = 8.0  # a weapon whose cooldown ends within one env step (8 game loops) will fire this step


def attack_nearest(frame: Frame, orders: Orders, units: np.ndarray | None = None) -> None:
    """Units (all alive by default) attack their nearest enemy they can hit."""
    units = frame.own_alive if units is None else units
    orders.attack(units, nearest(frame.dist, frame.targetable))


def attack_shared(frame: Frame, orders: Orders, target: np.ndarray) -> None:
    """Every living unit attacks the row's shared ``target`` (R,) (-1: none), or its nearest enemy where it cannot
    hit that one."""
    common = np.broadcast_to(target[:, None], frame.own_alive.shape)
    can = np.take_along_axis(frame.targetable, np.maximum(common, 0)[:, :, None], axis=2)[:, :, 0] & (common >= 0)
    attack_nearest(frame, orders, frame.own_alive & ~can)
    orders.attack(can, common)


def nearest_threat(frame: Frame, margin: float) -> np.ndarray:
    """(R, n) index of the nearest enemy that could hit each unit after closing ``margin``; -1 if none."""
    return argmin_masked(frame.dist, threatened(frame, margin))


def back_off(frame: Frame, orders: Orders, units: np.ndarray, threat: np.ndarray, distance: float) -> None:
    """``units`` that can move step ``distance`` away from enemy ``threat`` (R, n), turning along walls."""
    units = units & (frame.own_speed > 0) & (threat >= 0)
    if not units.any():
        return
    k = np.maximum(threat, 0)
    fx = np.take_along_axis(frame.enemy_x, k, axis=1)
    fy = np.take_along_axis(frame.enemy_y, k, axis=1)
    rx, ry = retreat_points(frame.own_x, frame.own_y, fx, fy, distance, frame.spec, tuple(frame.view.own_spawn))
    orders.move(units, rx, ry)


class Nearest(BatchScript):
    """Every unit attacks the nearest enemy it can hit, re-chosen each step."""

    name = "nearest"
    description = "every unit attacks its nearest enemy, re-chosen every step"

    def plan(self, frame: Frame, orders: Orders) -> None:
        attack_nearest(frame, orders)


class Weakest(BatchScript):
    """SMAC-HARD's ``s_3m/script.py`` (in its test pool only): every unit attacks one shared target, the enemy with
    the lowest health (hull, not shields), the first in index order on a tie.

    Deliberate difference: the shared target is chosen among the enemies some own unit can hit, and a unit that
    cannot hit it attacks its nearest enemy instead (on SMAC-HARD's marine maps every unit can hit every enemy).
    Earlier releases had each unit pick its own lowest health + shield enemy, nearest on a tie, which can split
    the fire; that rule on hull health is ``weakest_each``.
    """

    name = "weakest"
    description = ("every unit attacks one shared target: the enemy with the lowest health, the first on a tie "
                   "(SMAC-HARD s_3m; until this release each unit chose its own, now weakest_each)")

    def plan(self, frame: Frame, orders: Orders) -> None:
        target = argmin_masked(frame.enemy_health, frame.enemy_alive & frame.targetable.any(axis=1))
        attack_shared(frame, orders, target)


class WeakestEach(BatchScript):
    """Every unit attacks the enemy with the lowest health (hull) that it can hit, the nearest on a tie.

    SMAC-HARD's ``s_2m_vs_1z/script.py`` as it runs: the zealot attacks the marine with the lower health, the
    nearer one on a tie, and the last marine when one is left. (Earlier releases' per-unit ``weakest``, which used
    health + shield.)
    """

    name = "weakest_each"
    description = ("each unit attacks the enemy with the lowest health it can hit, the nearest on a tie "
                   "(SMAC-HARD s_2m_vs_1z)")

    def plan(self, frame: Frame, orders: Orders) -> None:
        health = np.broadcast_to(frame.enemy_health[:, None, :], frame.dist.shape)
        orders.attack(frame.own_alive, lowest(health, frame.targetable, tie=frame.dist))


class FocusFire(BatchScript):
    """The whole side attacks one enemy, the one nearest its centre, and keeps it until it dies."""

    name = "focus_fire"
    description = "all units attack one enemy (nearest the army's centre) until it dies, then the next"

    def __init__(self) -> None:
        self.memory = Memory(target=((), np.int64, -1))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows = frame.rows
        kept = self.memory.target[rows]
        cx, cy = frame.own_centroid
        d = np.hypot(frame.enemy_x - cx[:, None], frame.enemy_y - cy[:, None])
        fresh = argmin_masked(d, frame.enemy_alive & frame.hittable.any(axis=1))
        still = (kept >= 0) & np.take_along_axis(frame.enemy_alive, np.maximum(kept, 0)[:, None], axis=1)[:, 0]
        target = np.where(still, kept, fresh)
        self.memory.target[rows] = target
        attack_shared(frame, orders, target)


class Kite(BatchScript):
    """Ranged units shoot when their weapon is ready and step back from enemies that could reach them while it
    cools down; melee units attack the nearest enemy."""

    name = "kite"
    description = "ranged units fire when ready and back off from enemies that could reach them while reloading"
    retreat_distance = 2.5

    def plan(self, frame: Frame, orders: Orders) -> None:
        near = nearest_threat(frame, margin=2.5)
        ranged = frame.own_range >= 2.0
        reloading = frame.own_cooldown > READY_LOOPS
        back = frame.own_alive & ranged & reloading & (near >= 0)
        attack_nearest(frame, orders, frame.own_alive & ~back)
        back_off(frame, orders, back, near, self.retreat_distance)


class RetreatWounded(BatchScript):
    """Units attack the nearest enemy; a unit below 35% health + shield pulls back while an enemy threatens it."""

    name = "retreat_wounded"
    description = "attack nearest; units below 35% health+shield pull back while an enemy can reach them"
    wounded_fraction = 0.35
    retreat_distance = 3.0

    def plan(self, frame: Frame, orders: Orders) -> None:
        near = nearest_threat(frame, margin=2.0)
        back = frame.own_alive & (frame.own_hp_frac < self.wounded_fraction) & (near >= 0)
        attack_nearest(frame, orders, frame.own_alive & ~back)
        back_off(frame, orders, back, near, self.retreat_distance)


class Stop(BatchScript):
    """Every unit is told to stop every step: a side that does nothing (SMAC's passive ``*_RL`` units then never
    fight back). The sparring partner of the duel runner's competence checks."""

    name = "stop"
    description = "every unit stops every step (a side that does nothing)"
    heal_support = False

    def plan(self, frame: Frame, orders: Orders) -> None:
        orders.stop(frame.own_alive)


class Chase(BatchScript):
    """Every unit attack-moves to the current position of its nearest enemy, the first in index order on a tie:
    SMAC-HARD's ``s_6h_vs_8z/script_easy.py`` as it runs."""

    name = "chase"
    description = "every unit attack-moves to the position of its nearest enemy"

    def plan(self, frame: Frame, orders: Orders) -> None:
        k = nearest(frame.dist, frame.hittable)
        safe = np.maximum(k, 0)
        x = np.take_along_axis(frame.enemy_x, safe, axis=1)
        y = np.take_along_axis(frame.enemy_y, safe, axis=1)
        orders.attack_move(frame.own_alive & (k >= 0), x, y)


class RoundRobin(BatchScript):
    """SMAC-HARD's ``s_3s_vs_Nz/script_group.py`` and ``s_6h_vs_8z/script_hard.py`` as they run: every unit
    attacks its nearest enemy (the first in index order on a tie), re-chosen every step.

    Both scripts deal the zealots over the enemies in turn on the first step and retarget to the nearest only when
    the stored target's ``is_active`` is false. That protobuf field says whether a building is training; it is
    always false for units, so the retarget runs every step and the round-robin never does. Earlier releases
    played the intended round-robin under this name; it is now ``round_robin_intended``.
    """

    name = "round_robin"
    description = ("every unit attacks its nearest enemy every step: SMAC-HARD's round-robin scripts as they run "
                   "(their round-robin branch is dead; the intended one is now round_robin_intended)")

    def plan(self, frame: Frame, orders: Orders) -> None:
        attack_nearest(frame, orders)


class RoundRobinIntended(BatchScript):
    """The round-robin that SMAC-HARD's ``script_group`` / ``script_hard`` meant to play (it never runs there, see
    :class:`RoundRobin`): on the first step unit k (index order) is dealt enemy k mod m; each unit attacks its
    stored target until that dies, then takes its nearest and keeps that one until it dies."""

    name = "round_robin_intended"
    description = ("units are dealt over the enemies in turn and keep their target until it dies, then take their "
                   "nearest (the round-robin SMAC-HARD's script_group intended)")

    def __init__(self) -> None:
        self.memory = Memory(target=(("own",), np.int64, -1), dealt=((), bool, False))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows = frame.rows
        fresh = ~self.memory.dealt[rows]
        self.memory.dealt[rows] = True
        dealt = np.broadcast_to(np.arange(frame.n_own) % frame.n_enemy, frame.own_alive.shape)
        stored = np.where(fresh[:, None], dealt, self.memory.target[rows])
        keep = (stored >= 0) & np.take_along_axis(frame.targetable, np.maximum(stored, 0)[:, :, None], axis=2)[..., 0]
        target = np.where(keep, stored, nearest(frame.dist, frame.targetable))
        self.memory.target[rows] = np.where(frame.own_alive, target, stored)
        orders.attack(frame.own_alive, target)
