"""MMM and MMM2: SMAC-HARD's marine-marauder-medivac scripts (s_MMM ``script`` and ``script_2``), written from their
strategy descriptions. The medivac follows the army and heals the most injured unit in both."""

from __future__ import annotations

import numpy as np

from smac_hard_gym.opponents.generic import attack_nearest
from smac_hard_gym.opponents.helpers import (
    BatchScript,
    Frame,
    Memory,
    Orders,
    across_rank,
    centroid,
    line_points,
    lowest,
    nearest,
    of_kind,
    support_healers,
)

__all__ = ["MMMFormation", "MarauderFront"]

CONTACT = 8.0  # a marauder "sees" the enemy within this distance


def _marauder_contact(frame: Frame) -> tuple[np.ndarray, np.ndarray]:
    """Per row: (every alive marauder has an enemy within 8, some alive marauder has one)."""
    marauder = of_kind(frame.own_type, "marauder") & frame.own_alive
    seen = (np.where(frame.enemy_alive[:, None, :], frame.dist, np.inf).min(axis=2) <= CONTACT)
    return np.all(~marauder | seen, axis=1), np.any(marauder & seen, axis=1)


class MMMFormation(BatchScript):
    """SMAC-HARD ``s_MMM/script``.

    1. Steps 0-5: form up around the army's starting centre: marauders 2 ahead, marines on it, the medivac 1 back.
    2. Advance 1 per step while some marauder has no enemy within 8 (engaged for good once all have one).
    3. One target for the army: among enemy marines (else marauders, else anything), the weakest of the 3 nearest
       the army centre. Marines attack it; marauders hold a front line 2 ahead of the marine centre, attacking once
       they are on it and moving up to it otherwise; the medivac heals the most injured unit, else waits 1 behind
       the centre. (The original's marine retreat never ran and is left out.)
    """

    name = "mmm_formation"
    description = ("form up, advance to contact, marines focus the weakest of the 3 nearest (marines first), "
                   "marauders hold a front line, medivac heals (SMAC-HARD s_MMM/script)")
    heal_support = False
    form_steps = 6

    def __init__(self) -> None:
        self.memory = Memory(engaged=((), bool, False), anchor_x=((), np.float64, np.nan),
                             anchor_y=((), np.float64, np.nan))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, alive, f = frame.rows, frame.own_alive, frame.forward
        marine = of_kind(frame.own_type, "marine") & alive
        marauder = of_kind(frame.own_type, "marauder") & alive
        fighters = alive & ~frame.own_healer
        cx, cy = centroid(frame.own_x, frame.own_y, fighters, frame.own_centroid)

        fresh = np.isnan(self.memory.anchor_x[rows])
        self.memory.anchor_x[rows] = np.where(fresh, cx, self.memory.anchor_x[rows])
        self.memory.anchor_y[rows] = np.where(fresh, cy, self.memory.anchor_y[rows])
        ax, ay = self.memory.anchor_x[rows], self.memory.anchor_y[rows]

        forming = frame.step < self.form_steps
        all_seen, _ = _marauder_contact(frame)
        engaged = self.memory.engaged[rows] | (~forming & all_seen)
        self.memory.engaged[rows] = engaged

        # Formation: marauders in a line 2 ahead, marines in two ranks on the anchor.
        rank = across_rank(frame.own_x, frame.own_y, f)
        mx, my = line_points(ax + 2 * f[0], ay + 2 * f[1], f, frame.n_own, spacing=1.2)
        lx, ly = line_points(ax, ay, f, frame.n_own, spacing=0.9, per_rank=max(1, (frame.n_own + 1) // 2))
        px = np.where(of_kind(frame.own_type, "marauder"), np.take_along_axis(mx, rank, axis=1),
                      np.take_along_axis(lx, rank, axis=1))
        py = np.where(of_kind(frame.own_type, "marauder"), np.take_along_axis(my, rank, axis=1),
                      np.take_along_axis(ly, rank, axis=1))
        orders.move(fighters & forming[:, None], px, py)

        advance = fighters & (~forming & ~engaged)[:, None]
        orders.move(advance, frame.own_x + f[0], frame.own_y + f[1])

        fight = engaged[:, None]
        if fight.any():
            target = self._army_target(frame, cx, cy)
            common = np.broadcast_to(target[:, None], alive.shape)
            can = np.take_along_axis(frame.targetable, np.maximum(common, 0)[:, :, None], axis=2)[:, :, 0]
            can &= common >= 0
            attack_nearest(frame, orders, (marine | marauder) & fight & ~can)
            orders.attack(marine & fight & can, common)
            # Marauders: the front line is 2 ahead of the marine centre along the axis of advance.
            mcx, mcy = centroid(frame.own_x, frame.own_y, marine, (cx, cy))
            line = (mcx + 2 * f[0]) * f[0] + (mcy + 2 * f[1]) * f[1]
            along = frame.own_x * f[0] + frame.own_y * f[1]
            behind = along < line[:, None] - 0.5
            orders.attack(marauder & fight & can & ~behind, common)
            gap = (line[:, None] - along)
            orders.move(marauder & fight & behind, frame.own_x + gap * f[0], frame.own_y + gap * f[1])
        support_healers(orders, frame, (cx - f[0], cy - f[1]))

    @staticmethod
    def _army_target(frame: Frame, cx: np.ndarray, cy: np.ndarray) -> np.ndarray:
        """(R,) the weakest of the 3 enemies nearest the army centre, marines first, then marauders, then any."""
        d = np.hypot(frame.enemy_x - cx[:, None], frame.enemy_y - cy[:, None])
        pool = frame.enemy_alive
        for kind in ("marauder", "marine"):  # the last one that has alive units wins
            of = frame.enemy_alive & of_kind(frame.enemy_type, kind)
            pool = np.where(of.any(axis=1)[:, None], of, pool)
        ranked = np.argsort(np.where(pool, d, np.inf), axis=1, kind="stable")
        third = np.take_along_axis(np.where(pool, d, np.inf), ranked[:, 2:3], axis=1) if pool.shape[1] > 2 else None
        near3 = pool if third is None else pool & (d <= third)
        return lowest(frame.enemy_hp, near3, tie=d)


class MarauderFront(BatchScript):
    """SMAC-HARD ``s_MMM/script_2``: marauders walk side by side (1 apart) at the army centre and the army advances
    1 per step until some marauder has an enemy within 8; then each marine attacks its nearest enemy and the
    marauders attack the nearest enemy marine or marauder. The medivac follows and heals."""

    name = "marauder_front"
    description = ("advance with marauders side by side in front until contact, then marines attack nearest and "
                   "marauders the nearest marine/marauder (SMAC-HARD s_MMM/script_2)")

    def __init__(self) -> None:
        self.memory = Memory(engaged=((), bool, False))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, alive, f = frame.rows, frame.own_alive, frame.forward
        marine = of_kind(frame.own_type, "marine") & alive
        marauder = of_kind(frame.own_type, "marauder") & alive
        _, some_seen = _marauder_contact(frame)
        engaged = self.memory.engaged[rows] | some_seen | ~marauder.any(axis=1)
        self.memory.engaged[rows] = engaged

        cx, cy = centroid(frame.own_x, frame.own_y, alive & ~frame.own_healer, frame.own_centroid)
        walking = ~engaged[:, None]
        n_mar = int(of_kind(frame.own_type[0], "marauder").sum())
        if n_mar:
            lx, ly = line_points(cx + f[0], cy + f[1], f, n_mar, spacing=1.0)
            rank = np.cumsum(of_kind(frame.own_type, "marauder"), axis=1) - 1  # marauder k takes slot k
            slot = np.clip(rank, 0, n_mar - 1)
            orders.move(marauder & walking, np.take_along_axis(lx, slot, axis=1), np.take_along_axis(ly, slot, axis=1))
        orders.move(marine & walking, frame.own_x + f[0], frame.own_y + f[1])

        fight = engaged[:, None]
        attack_nearest(frame, orders, marine & fight)
        ground = frame.targetable & of_kind(frame.enemy_type, "marine", "marauder")[:, None, :]
        pick = nearest(frame.dist, ground)
        fallback = nearest(frame.dist, frame.targetable)
        orders.attack(marauder & fight, np.where(pick >= 0, pick, fallback))
