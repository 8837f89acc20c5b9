"""Marine maps: SMAC-HARD's line scripts (``s_8m``: 3m, 8m, 5m_vs_6m, 8m_vs_9m, 10m_vs_11m) and column scripts
(``s_27m``: 25m, 27m_vs_30m), as SMAC-HARD's code runs them.

SMAC-HARD's map coordinates are kept exactly for blue (the line at x = 25, one west step per env step); red plays
them reflected through the midpoint of the two spawns (:meth:`~smac_hard_gym.opponents.helpers.Frame.blue_frame`),
which on these maps is (32 - x, 32 - y). SMAC-HARD's lists of own units are sorted by tag and its enemy lists are in
raw observation order; both are our index order, so "first" on a tie means the lowest index.
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.engine.state import CMD_ATTACK, CMD_MOVE
from smac_hard_gym.opponents.helpers import (
    BatchScript,
    Frame,
    Memory,
    Orders,
    _any,
    argmin_masked,
    from_blue_frame,
    list_rank,
    weakest_of_nearest,
)

__all__ = ["LineAdvance", "ColumnAdvance"]

FORM_STEPS = 5  # steps 0-4 form up
LINE_X, LINE_Y = 25.0, 16.0  # SMAC-HARD's formation line, blue side


def _centre_distance(frame: Frame, cx: np.ndarray, cy: np.ndarray) -> np.ndarray:
    """(R,) distance from (cx, cy) to the nearest alive enemy (inf where none)."""
    d = np.hypot(frame.enemy_x - cx[:, None], frame.enemy_y - cy[:, None])
    return np.minimum.reduce(np.where(frame.enemy_alive, d, np.inf), axis=1)


def _clip(v: float, lo: float, hi: float) -> float:
    """numpy's clip of one float (its order of comparisons: NaN stays, then max with ``lo``, then min with ``hi``)."""
    if v != v:
        return v
    v = v if v > lo else lo
    return v if v < hi else hi


def _live(frame: Frame) -> np.ndarray:
    """(R,) rows where both sides have a unit alive (SMAC-HARD's scripts return no actions otherwise)."""
    return _any(frame.own_alive, axis=1) & _any(frame.enemy_alive, axis=1)


class LineAdvance(BatchScript):
    """SMAC-HARD ``s_8m/script.py`` (focus ``"front"``, name ``line_front``) and ``s_8m/script_1.py`` (focus
    ``"weakest"``, name ``line_weakest``), as they run.

    1. Steps 0-4: alive marine k of n (index order, SMAC-HARD's tag order) moves to (25, 16 + k - n/2): a vertical
       line at x = 25, spacing 1, centred on y = 15.5.
    2. Then, until the first contact, every marine moves 1 west per step while the nearest enemy is more than 8
       from the marines' centre; contact (8 or less) ends the advance for good.
    3. Engaged: every marine attacks one enemy: ``"front"`` the one whose x is nearest the centre's x, ``"weakest"``
       the one with the lowest health; the first in index order on a tie.
    4. A marine whose health fraction changed since the last step and is below 30% steps 1 east instead.

    Deliberate differences: red plays the same coordinates reflected through the midpoint of the spawns (x = 7, one
    east step per env step on these maps). Earlier releases formed the line by lateral rank around y = 16 and broke
    ``line_weakest``'s ties (all at full health) by distance to the centre; SMAC-HARD's first-enemy tie-break focuses
    every marine on the same, possibly far, unit.
    """

    contact_distance = 8.0
    wounded_fraction = 0.3
    scalar_path = True  # one blue battle past forming up plans with Python scalars (same result, less overhead)

    def __init__(self, focus: str = "front") -> None:
        if focus not in ("front", "weakest"):
            raise ValueError(f"focus must be 'front' or 'weakest', got {focus!r}")
        self.focus = focus
        self.name = "line_front" if focus == "front" else "line_weakest"
        self.description = (
            "line at x=25 for 5 steps, advance 1 west per step to contact, all focus the "
            + ("frontmost" if focus == "front" else "lowest-health (first on a tie)")
            + " enemy; wounded step back (SMAC-HARD s_8m/" + ("script" if focus == "front" else "script_1") + ")")
        self.memory = Memory(engaged=((), bool, False), last_frac=(("own",), np.float64, 1.0))

    def plan(self, frame: Frame, orders: Orders) -> None:
        if self.scalar_path and frame.size == 1 and frame.reflection is None and int(frame.step[0]) >= FORM_STEPS:
            self._plan_one(frame, orders)  # one blue battle past forming up: the same plan, scalar by scalar
            return
        rows = frame.index  # memory rows: a slice (a view, no gather) when every battle is active
        live = _live(frame)
        alive = frame.own_alive & live[:, None]
        hx, hy = frame.own_hx, frame.own_hy
        cx, cy = frame.blue_frame(*frame.own_centroid)
        forming = frame.step < FORM_STEPS
        contact = _centre_distance(frame, *frame.own_centroid) <= self.contact_distance
        engaged = self.memory.engaged[rows] | (live & ~forming & contact)
        self.memory.engaged[rows] = engaged

        if _any(forming, axis=None):
            k = list_rank(frame.own_alive)
            n = frame.own_alive.sum(axis=1, keepdims=True)
            orders.move(alive & forming[:, None], *from_blue_frame(frame, LINE_X, LINE_Y + k - n / 2.0))
        advance = alive & (~forming & ~engaged)[:, None]
        if _any(advance, axis=None):
            orders.move(advance, *from_blue_frame(frame, hx - 1.0, hy))

        frac = frame.own_health_frac
        fight = alive & (~forming & engaged)[:, None]
        if _any(fight, axis=None):
            if self.focus == "front":
                target = argmin_masked(np.abs(frame.enemy_hx - cx[:, None]), frame.enemy_alive)
            else:
                target = argmin_masked(frame.enemy_health, frame.enemy_alive)
            orders.attack(fight, target[:, None])
            hurt = (frac != self.memory.last_frac[rows]) & (frac < self.wounded_fraction)
            orders.move(fight & hurt, *from_blue_frame(frame, hx + 1.0, hy))
        # SMAC-HARD remembers the fraction of the marines it saw this step (rows it returned early from keep theirs).
        self.memory.last_frac[rows] = np.where(alive, frac, self.memory.last_frac[rows])

    def _plan_one(self, frame: Frame, orders: Orders) -> None:
        """:meth:`plan` for one blue battle past forming up, with Python scalars where numpy's per-call cost on a
        handful of units outweighs the work. Every float comes from the same numpy operations as in ``plan``
        (centroid, distances, fractions) or from exact ones (comparisons, +-1, clipping), so the orders and the
        memory are bit for bit those of ``plan`` (tests/test_opponents_fast_paths.py compares them)."""
        b = int(frame.rows[0])
        memory = self.memory
        own_alive = frame.own_alive[0].tolist()
        enemy_alive = frame.enemy_alive[0].tolist()
        live = any(own_alive) and any(enemy_alive)
        engaged = bool(memory.engaged[b])
        if live and not engaged:
            engaged = bool(_centre_distance(frame, *frame.own_centroid)[0] <= self.contact_distance)
        memory.engaged[b] = engaged
        if not live:
            return
        n = frame.n_own
        hx, hy = frame.own_x[0].tolist(), frame.own_y[0].tolist()
        mx, my = frame.spec.size
        mx, my = mx - 0.0, my - 0.0  # clamp_to_map's bounds with margin 0
        kind, ox, oy = orders.kind[0], orders.x[0], orders.y[0]
        if not engaged:  # advance 1 west
            for i in range(n):
                if own_alive[i]:
                    kind[i] = CMD_MOVE
                    ox[i] = _clip(hx[i] - 1.0, 0.0, mx)
                    oy[i] = _clip(hy[i], 0.0, my)
                    orders._points = True
        frac = frame.own_health_frac[0].tolist()
        last = memory.last_frac[b]
        if engaged:
            ex, ea = (frame.enemy_x if self.focus == "front" else frame.enemy_health)[0].tolist(), enemy_alive
            if self.focus == "front":
                cx = float(frame.own_centroid[0][0])
                ex = [abs(v - cx) for v in ex]
            target, best = -1, np.inf
            for k in range(len(ex)):
                if ea[k] and ex[k] < best:
                    target, best = k, ex[k]
            if best == np.inf:  # argmin_masked when every candidate reads inf: index 0 (-1 without candidates)
                target = 0 if True in ea else -1
            otarget = orders.target[0]
            orders._targets = True  # as Orders.attack: set once an attack is planned for some units
            slot = frame.view.enemy.start + target
            last_list = last.tolist()
            for i in range(n):
                if not own_alive[i]:
                    continue
                if target >= 0:
                    kind[i] = CMD_ATTACK
                    otarget[i] = slot
                if frac[i] != last_list[i] and frac[i] < self.wounded_fraction:
                    kind[i] = CMD_MOVE
                    ox[i] = _clip(hx[i] + 1.0, 0.0, mx)
                    oy[i] = _clip(hy[i], 0.0, my)
                    orders._points = True
        for i in range(n):
            if own_alive[i]:
                last[i] = frac[i]


class ColumnAdvance(BatchScript):
    """SMAC-HARD ``s_27m`` scripts as they run: ``script_a.py`` (mode ``"centroid"``), ``script_l.py``
    (``"weakest"``) and ``script_ap.py`` (``"point"``).

    1. Steps 0-4: the alive marines, sorted by y (index order on a tie), take (25, 16 + (k - n/2) * 0.65): one
       north-south column at x = 25, spacing 0.65.
    2. Then, every step: while the nearest enemy is more than 9 from the marines' centre, every marine moves 2
       west. Otherwise (this is re-checked every step, so the column can go back to moving):
       ``centroid`` attack-moves everyone to the enemy centre; ``weakest`` has each marine attack the enemy with
       the lowest health among its 5 nearest (among all of them, first in index order on a tie, while 5 or fewer
       are alive); ``point`` attack-moves each marine to that enemy's position.

    Deliberate differences: red plays the coordinates reflected through the midpoint of the spawns. Earlier
    releases formed ranks of 14 across the advance, engaged for good once any marine had an enemy within 9, and
    broke ties by distance.
    """

    contact_distance = 9.0
    advance_step = 2.0
    spacing = 0.65
    _MODES = {
        "centroid": ("column_centroid", "attack-move to the enemy centre", "script_a"),
        "weakest": ("column_weakest", "each attacks the lowest-health of its 5 nearest enemies", "script_l"),
        "point": ("column_point", "each attack-moves onto the lowest-health of its 5 nearest enemies", "script_ap"),
    }

    def __init__(self, mode: str = "centroid") -> None:
        if mode not in self._MODES:
            raise ValueError(f"mode must be one of {sorted(self._MODES)}, got {mode!r}")
        self.mode = mode
        self.name, what, origin = self._MODES[mode]
        self.description = (f"column at x=25 for 5 steps, move 2 west per step while the enemy is over 9 from the "
                            f"centre, else {what} (SMAC-HARD s_27m/{origin})")

    def plan(self, frame: Frame, orders: Orders) -> None:
        live = _live(frame)
        alive = frame.own_alive & live[:, None]
        hx, hy = frame.own_hx, frame.own_hy
        forming = frame.step < FORM_STEPS

        if _any(forming, axis=None):
            by_y = np.argsort(np.where(frame.own_alive, hy, np.inf), axis=1, kind="stable")
            k = np.argsort(by_y, axis=1, kind="stable")  # rank by y; the dead sort last and get no order
            n = frame.own_alive.sum(axis=1, keepdims=True)
            orders.move(alive & forming[:, None],
                        *from_blue_frame(frame, LINE_X, LINE_Y + (k - n / 2.0) * self.spacing))

        far = _centre_distance(frame, *frame.own_centroid) > self.contact_distance
        advance = alive & (~forming & far)[:, None]
        if _any(advance, axis=None):
            orders.move(advance, *from_blue_frame(frame, hx - self.advance_step, hy))

        fight = alive & (~forming & ~far)[:, None]
        if not _any(fight, axis=None):
            return
        if self.mode == "centroid":
            ex, ey = frame.enemy_centroid
            orders.attack_move(fight, ex[:, None], ey[:, None])
            return
        target = weakest_of_nearest(frame.dist, frame.enemy_health, frame.hittable, k=5)
        if self.mode == "weakest":
            orders.attack(fight, target)
        else:
            safe = np.maximum(target, 0)
            row = np.arange(safe.shape[0])[:, None]  # take_along_axis by plain indexing (same values)
            orders.attack_move(fight & (target >= 0), frame.enemy_x[row, safe], frame.enemy_y[row, safe])
