"""MMM and MMM2: SMAC-HARD's marine-marauder-medivac scripts (``s_MMM/script.py`` and ``script_2.py``), as SMAC-HARD's
code runs them.

SMAC-HARD's coordinates (x - 2 ahead, x + 1 behind, one west step per env step) are kept exactly for blue; red
plays them reflected through the midpoint of the two spawns
(:meth:`~smac_hard_gym.opponents.helpers.Frame.blue_frame`). Its lists are sorted by tag (own units) or in raw
observation order (enemies), both our index order, so "first" on a tie means the lowest index.
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.opponents.helpers import (
    BatchScript,
    Frame,
    Memory,
    Orders,
    _any,
    _expand,
    argmin_masked,
    centroid,
    from_blue_frame,
    list_rank,
    lowest,
    of_kind,
    weakest_of_nearest,
)

__all__ = ["MMMFormation", "MarauderFront"]

CONTACT = 8.0  # a marauder "sees" an enemy within this distance (SMAC-HARD's closer_than, inclusive)
FORM_STEPS = 6  # steps 0-5 form up ("iteration <= 5")


class _MMMScript(BatchScript):
    """What both s_MMM scripts share: the army's kinds, the advance, the marauders' front line and the medivac."""

    heal_support = False  # the medivac's orders are part of the script

    def __init__(self) -> None:
        self.memory = Memory(engaged=((), bool, False))

    def _kinds(self, frame: Frame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        alive = frame.own_alive
        return (of_kind(frame.own_type, "marine") & alive, of_kind(frame.own_type, "marauder") & alive,
                of_kind(frame.own_type, "medivac") & alive)

    @staticmethod
    def _sees(frame: Frame, marauder: np.ndarray) -> np.ndarray:
        """(R, n) marauders with an enemy (any, medivacs included) within 8."""
        near = np.minimum.reduce(np.where(frame.enemy_alive[:, None, :], frame.dist, np.inf), axis=2)
        return marauder & (near <= CONTACT)

    def _advance_or_fight(self, frame: Frame, orders: Orders, formed: np.ndarray, blind: np.ndarray) -> np.ndarray:
        """Rows past forming up advance 1 west (blue's frame, medivacs included) while ``blind`` and never engaged;
        the others fight, and stay engaged. Returns the fighting rows."""
        advancing = formed & blind & ~self.memory.engaged[frame.rows]
        orders.move(frame.own_alive & advancing[:, None],
                    *from_blue_frame(frame, frame.own_hx - 1.0, frame.own_hy))
        fight = formed & ~advancing
        self.memory.engaged[frame.rows] |= fight
        return fight

    def _front(self, frame: Frame, orders: Orders, marine: np.ndarray, marauder: np.ndarray, fight: np.ndarray,
               target: np.ndarray) -> None:
        """Marauders west of the front line (2 west of the marines' centre, else of the army's) attack ``target``
        (R, n); the others move onto the line."""
        alive = frame.own_alive
        mx, _ = centroid(frame.own_hx, frame.own_hy, marine)
        # The army's centre: for blue (hx = x) that is the frame's cached own_centroid, except in rows without a
        # unit alive, whose orders below are all masked out anyway.
        ax = frame.own_centroid[0] if frame.reflection is None else centroid(frame.own_hx, frame.own_hy, alive)[0]
        front = np.where(_any(marine, axis=1), mx, ax) - 2.0
        ahead = frame.own_hx < front[:, None]
        orders.attack(marauder & fight[:, None] & ahead, target)
        orders.move(marauder & fight[:, None] & ~ahead,
                    *from_blue_frame(frame, _expand(front[:, None], alive.shape), frame.own_hy))

    def _medivac(self, frame: Frame, orders: Orders, marine: np.ndarray, marauder: np.ndarray,
                 medivac: np.ndarray, fight: np.ndarray) -> None:
        """Medivacs heal the marine or marauder with the lowest health fraction (marines listed first), else move
        1 east of the army's centre."""
        units = medivac & fight[:, None]
        patients = marine | marauder
        if not _any(units, axis=None) or not _any(patients, axis=None):
            return
        listed = np.where(of_kind(frame.own_type, "marine"), 0, frame.n_own) + np.arange(frame.n_own)
        patient = lowest(frame.own_health_frac, patients, tie=listed)  # (n,) broadcasts over the rows
        hurt = frame.own_health_frac[np.arange(patient.shape[0]), np.maximum(patient, 0)] < 1.0
        hurt &= patient >= 0
        orders.heal(units & hurt[:, None], patient[:, None])
        if frame.reflection is None:  # blue: own_centroid (every row here has its medivac alive: no fallback)
            cx, cy = frame.own_centroid
        else:
            cx, cy = centroid(frame.own_hx, frame.own_hy, frame.own_alive)
        orders.move(units & ~hurt[:, None], *from_blue_frame(frame, cx[:, None] + 1.0, cy[:, None]))


class MMMFormation(_MMMScript):
    """SMAC-HARD ``s_MMM/script.py`` as it runs.

    1. Steps 0-5: with (cx, cy) the centre of the marines and marauders (recomputed every step), marauders move to
       (cx - 2, own y), marines to (cx, own y), medivacs to (cx + 1, own y).
    2. Then, until the first contact, every unit moves 1 west per step while some marauder has no enemy within 8.
    3. Engaged (for good): one target, the enemy with the lowest health + shield among the 3 nearest the centre of
       all own units, taken from the enemy marines (else marauders, else any enemy); with 3 or fewer candidates all
       count and a tie goes to the first in index order. Marines attack it. Marauders west of the front line (2
       west of the marines' centre) attack it, the others move onto the line. Medivacs heal the marine or marauder
       with the lowest health fraction, else move 1 east of the army's centre.

    The marines' retreat (below 30% and losing health) never runs in SMAC-HARD (the health it compares is never
    updated): left out. Deliberate differences: red plays the reflected frame. SMAC-HARD gives the medivac an
    attack order on its patient; a medivac has no weapon, and SC2 makes it follow and heal that unit, which our
    heal order does. Earlier releases formed lines around a fixed anchor, kept the marauders a line ahead, and had
    the medivac heal from the first step.
    """

    name = "mmm_formation"
    description = ("form up for 6 steps, advance 1 west per step to contact, marines focus the weakest of the 3 "
                   "enemies nearest the army (marines first), marauders hold a front line, medivac heals "
                   "(SMAC-HARD s_MMM/script)")

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive = frame.own_alive
        marine, marauder, medivac = self._kinds(frame)
        live = _any(marine | marauder, axis=1) & _any(frame.enemy_alive, axis=1)
        forming = live & (frame.step < FORM_STEPS)
        if _any(forming, axis=None):
            cx, _ = centroid(frame.own_hx, frame.own_hy, marine | marauder)
            offset = np.where(of_kind(frame.own_type, "marauder"), -2.0,
                              np.where(of_kind(frame.own_type, "medivac"), 1.0, 0.0))
            orders.move(alive & forming[:, None], *from_blue_frame(frame, cx[:, None] + offset, frame.own_hy))

        blind = _any(marauder & ~self._sees(frame, marauder), axis=1)  # some marauder sees no enemy
        fight = self._advance_or_fight(frame, orders, live & ~forming, blind)
        if not _any(fight, axis=None):
            return

        e_alive = frame.enemy_alive
        pool = e_alive
        for kind in ("marauder", "marine"):  # the last kind with units alive wins: marines, else marauders
            of = e_alive & of_kind(frame.enemy_type, kind)
            pool = np.where(_any(of, axis=1)[:, None], of, pool)
        cx, cy = frame.own_centroid
        to_centre = np.hypot(frame.enemy_x - cx[:, None], frame.enemy_y - cy[:, None])
        target = weakest_of_nearest(to_centre[:, None, :], frame.enemy_hp, pool[:, None, :], k=3)[:, 0]
        common = target[:, None]  # one target per row; Orders broadcasts it over the units
        orders.attack(marine & fight[:, None], common)
        self._front(frame, orders, marine, marauder, fight, common)
        self._medivac(frame, orders, marine, marauder, medivac, fight)


class MarauderFront(_MMMScript):
    """SMAC-HARD ``s_MMM/script_2.py`` as it runs.

    1. Steps 0-5: with (cx, cy) the centre of the marines and marauders (recomputed every step), marauder 0 moves
       to (cx - 2, cy - 1) and marauder 1 to (cx - 2, cy + 1) (a third marauder, on MMM2, gets no order); marine k of
       n moves to (cx, own y - n/2 + k); medivacs to (cx + 1, own y).
    2. Then, until the first contact, every unit moves 1 west per step while no marauder has an enemy within 8
       (with no marauder alive that holds trivially).
    3. Engaged (for good): each marine attacks its nearest enemy. Marauders west of the front line (2 west of the
       marines' centre) attack their nearest enemy marine or marauder (marines listed first on a tie), the others
       move onto the line. Medivacs heal the marine or marauder with the lowest health fraction, else move 1 east
       of the army's centre.

    The marines' retreat never runs in SMAC-HARD: left out. Deliberate differences: red plays the reflected frame;
    the medivac's attack order on its patient is our heal order (see :class:`MMMFormation`). Earlier releases
    walked the marauders side by side in front, engaged on the first marauder contact, had the marauders attack
    wherever they stood and the medivac heal from the first step.
    """

    name = "marauder_front"
    description = ("form up for 6 steps, advance 1 west per step until a marauder sees an enemy, then marines "
                   "attack nearest and marauders past the front line the nearest marine/marauder (SMAC-HARD "
                   "s_MMM/script_2)")

    def plan(self, frame: Frame, orders: Orders) -> None:
        marine, marauder, medivac = self._kinds(frame)
        live = _any(marine | marauder, axis=1) & _any(frame.enemy_alive, axis=1)
        forming = live & (frame.step < FORM_STEPS)
        if _any(forming, axis=None):
            cx, cy = centroid(frame.own_hx, frame.own_hy, marine | marauder)
            hy = frame.own_hy
            k = list_rank(marine)
            n = marine.sum(axis=1, keepdims=True)
            orders.move(marine & forming[:, None], *from_blue_frame(frame, cx[:, None], hy - n / 2.0 + k))
            which = list_rank(marauder)
            for j, side in enumerate((-1.0, 1.0)):
                orders.move(marauder & (which == j) & forming[:, None],
                            *from_blue_frame(frame, cx[:, None] - 2.0, cy[:, None] + side))
            orders.move(medivac & forming[:, None], *from_blue_frame(frame, cx[:, None] + 1.0, hy))

        all_blind = ~_any(self._sees(frame, marauder), axis=1)
        fight = self._advance_or_fight(frame, orders, live & ~forming, all_blind)
        if not _any(fight, axis=None):
            return

        e_alive = frame.enemy_alive
        m = frame.n_enemy
        orders.attack(marine & fight[:, None], argmin_masked(frame.dist, frame.targetable))
        ground = e_alive & of_kind(frame.enemy_type, "marine", "marauder")
        listed = np.where(of_kind(frame.enemy_type, "marine"), 0, m) + np.arange(m)  # marines, then marauders
        near = lowest(frame.dist, frame.targetable & ground[:, None, :],
                      tie=listed)  # (m,) broadcasts over rows and units
        self._front(frame, orders, marine, marauder, fight, near)
        self._medivac(frame, orders, marine, marauder, medivac, fight)
