"""Marine maps: SMAC-HARD's line scripts (s_8m: 3m, 8m, 5m_vs_6m, 8m_vs_9m, 10m_vs_11m) and column scripts (s_27m:
25m, 27m_vs_30m), written from their strategy descriptions.

Geometry is taken from the map (own spawn, direction of advance), not hard-coded, so the scripts also play the red
side. SMAC-HARD's line at x=25 is "2 behind the own spawn" here.
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.opponents.helpers import (
    BatchScript,
    Frame,
    Memory,
    Orders,
    across_rank,
    argmin_masked,
    line_points,
    lowest,
    nearest,
)

__all__ = ["LineAdvance", "ColumnAdvance"]

FORM_STEPS = 5  # steps spent forming up before the advance
LINE_BEHIND_SPAWN = 2.0  # the formation line sits this far behind the own spawn


def _formation(frame: Frame, spacing: float, per_rank: int | None) -> tuple[np.ndarray, np.ndarray]:
    """Slot points of a line across the direction of advance, 2 behind the own spawn, assigned left to right."""
    f = frame.forward
    centre = frame.view.own_spawn - LINE_BEHIND_SPAWN * f
    cx = np.full(frame.size, centre[0])
    cy = np.full(frame.size, centre[1])
    px, py = line_points(cx, cy, f, frame.n_own, spacing=spacing, per_rank=per_rank)
    rank = across_rank(frame.own_x, frame.own_y, f)
    return np.take_along_axis(px, rank, axis=1), np.take_along_axis(py, rank, axis=1)


class LineAdvance(BatchScript):
    """SMAC-HARD ``s_8m/script`` (focus ``"front"``) and ``script_1`` (focus ``"weakest"``).

    1. Steps 0-4: form a line across the direction of advance, 2 behind the own spawn, spacing 1.
    2. Advance 1 per step while the nearest enemy is more than 8 from the own centre; the first contact ends the
       advance for good.
    3. Engaged: every marine attacks one enemy: the frontmost (the one nearest the own centre along the axis of
       advance) or the one with the lowest health + shield.
    4. A marine that lost health since the last step and is below 30% steps 1 back.
    """

    contact_distance = 8.0
    wounded_fraction = 0.3

    def __init__(self, focus: str = "front") -> None:
        if focus not in ("front", "weakest"):
            raise ValueError(f"focus must be 'front' or 'weakest', got {focus!r}")
        self.focus = focus
        self.name = "line_front" if focus == "front" else "line_weakest"
        self.description = (
            "form a line, advance to contact, all focus the " + ("frontmost" if focus == "front" else "weakest")
            + " enemy; wounded step back (SMAC-HARD s_8m/" + ("script" if focus == "front" else "script_1") + ")")
        self.memory = Memory(engaged=((), bool, False), last_hp=(("own",), np.float64, np.inf))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, f = frame.rows, frame.forward
        alive = frame.own_alive
        cx, cy = frame.own_centroid
        forming = frame.step < FORM_STEPS
        centre_dist = np.hypot(frame.enemy_x - cx[:, None], frame.enemy_y - cy[:, None])
        contact = (np.where(frame.enemy_alive, centre_dist, np.inf).min(axis=1) <= self.contact_distance)
        engaged = self.memory.engaged[rows] | (~forming & contact)
        self.memory.engaged[rows] = engaged

        if forming.any():
            fx, fy = _formation(frame, spacing=1.0, per_rank=None)
            orders.move(alive & forming[:, None], fx, fy)
        advance = alive & (~forming & ~engaged)[:, None]
        orders.move(advance, frame.own_x + f[0], frame.own_y + f[1])

        fight = alive & engaged[:, None]
        if fight.any():
            if self.focus == "front":
                along = (frame.enemy_x - cx[:, None]) * f[0] + (frame.enemy_y - cy[:, None]) * f[1]
                target = argmin_masked(np.abs(along), frame.enemy_alive)
            else:
                target = lowest(frame.enemy_hp, frame.enemy_alive, tie=centre_dist)
            common = np.broadcast_to(target[:, None], alive.shape)
            can = np.take_along_axis(frame.targetable, np.maximum(common, 0)[:, :, None], axis=2)[:, :, 0]
            can &= common >= 0
            if (fight & ~can).any():  # units that cannot hit the focus target take their nearest
                orders.attack(fight & ~can, nearest(frame.dist, frame.targetable))
            orders.attack(fight & can, common)
            hurt = (frame.own_hp < self.memory.last_hp[rows]) & (frame.own_hp_frac < self.wounded_fraction)
            orders.move(fight & hurt, frame.own_x - f[0], frame.own_y - f[1])
        self.memory.last_hp[rows] = frame.own_hp


class ColumnAdvance(BatchScript):
    """SMAC-HARD ``s_27m`` scripts: ``script_a`` (mode ``"centroid"``), ``script_l`` (``"weakest"``) and
    ``script_ap`` (``"point"``).

    1. Steps 0-4: form ranks of up to 14 across the direction of advance, 2 behind the own spawn.
    2. Advance 2 per step until some marine has an enemy within 9 (then engaged for good).
    3. Engaged: ``centroid`` attack-moves everyone to the enemy centre; ``weakest`` has each marine attack the
       weakest of its 5 nearest enemies; ``point`` attack-moves each marine to that enemy's position.
    """

    contact_distance = 9.0
    advance_step = 2.0
    per_rank = 14
    _MODES = {
        "centroid": ("column_centroid", "attack-move to the enemy centre", "script_a"),
        "weakest": ("column_weakest", "each attacks the weakest of its 5 nearest enemies", "script_l"),
        "point": ("column_point", "each attack-moves onto the weakest of its 5 nearest enemies", "script_ap"),
    }

    def __init__(self, mode: str = "centroid") -> None:
        if mode not in self._MODES:
            raise ValueError(f"mode must be one of {sorted(self._MODES)}, got {mode!r}")
        self.mode = mode
        self.name, what, origin = self._MODES[mode]
        self.description = f"form ranks, advance 2 per step to contact, then {what} (SMAC-HARD s_27m/{origin})"
        self.memory = Memory(engaged=((), bool, False))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, f = frame.rows, frame.forward
        alive = frame.own_alive
        forming = frame.step < FORM_STEPS
        contact = (np.where(frame.hittable, frame.dist, np.inf).min(axis=(1, 2)) <= self.contact_distance)
        engaged = self.memory.engaged[rows] | (~forming & contact)
        self.memory.engaged[rows] = engaged

        if forming.any():
            fx, fy = _formation(frame, spacing=1.0, per_rank=self.per_rank)
            orders.move(alive & forming[:, None], fx, fy)
        advance = alive & (~forming & ~engaged)[:, None]
        orders.move(advance, frame.own_x + self.advance_step * f[0], frame.own_y + self.advance_step * f[1])

        fight = alive & engaged[:, None]
        if not fight.any():
            return
        if self.mode == "centroid":
            ex, ey = frame.enemy_centroid
            orders.attack_move(fight, ex[:, None], ey[:, None])
            return
        target = _weakest_of_nearest(frame, k=5)
        if self.mode == "weakest":
            orders.attack(fight, target)
        else:
            safe = np.maximum(target, 0)
            tx = np.take_along_axis(frame.enemy_x, safe, axis=1)
            ty = np.take_along_axis(frame.enemy_y, safe, axis=1)
            orders.attack_move(fight & (target >= 0), tx, ty)


def _weakest_of_nearest(frame: Frame, k: int) -> np.ndarray:
    """(R, n): for each unit, the lowest health + shield enemy among its ``k`` nearest targetable ones."""
    d = np.where(frame.targetable, frame.dist, np.inf)
    k = min(k, frame.n_enemy)
    near = np.argsort(d, axis=2, kind="stable")[:, :, :k]  # (R, n, k)
    valid = np.take_along_axis(d, near, axis=2) < np.inf
    hp = np.take_along_axis(np.broadcast_to(frame.enemy_hp[:, None, :], d.shape), near, axis=2)
    pick = lowest(hp, valid, tie=np.take_along_axis(d, near, axis=2))  # index into the k nearest
    chosen = np.take_along_axis(near, np.maximum(pick, 0)[:, :, None], axis=2)[:, :, 0]
    return np.where(pick >= 0, chosen, -1)
