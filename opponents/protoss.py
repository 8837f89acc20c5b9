"""Protoss maps: SMAC-HARD's stalker/zealot scripts (2s3z, 3s5z, 3s5z_vs_3s6z), the 1c3s5z colossus script and the
3s_vs_Nz staged surround, as SMAC-HARD's code runs them.

SMAC-HARD's fixed retreat point (23, 16) and its axis-aligned surround slots are kept exactly for blue; red plays
them reflected through the midpoint of the two spawns (:meth:`~smac_hard_gym.opponents.helpers.Frame.blue_frame`).
SMAC-HARD compares ``unit.health / unit.health_max``: the hull alone, shields not counted. Its lists are in tag or
raw observation order, both our index order, so "first" on a tie means the lowest index.
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.opponents.helpers import (
    BatchScript,
    Frame,
    Memory,
    Orders,
    _any,
    _sum,
    argmin_masked,
    centroid,
    from_blue_frame,
    nearest,
    of_kind,
    unit_vector,
)

__all__ = ["StalkerRetreat", "CenterFocus", "KitePush", "ColossusSplash", "Surround"]

HOME = (23.0, 16.0)  # SMAC-HARD's retreat point: blue's spawn
SHOOT_RANGE = 6.0  # SMAC-HARD's SHOOT_RANGE, compared with centre distances


def _retreat_home(frame: Frame, orders: Orders, units: np.ndarray) -> None:
    orders.move(units, *from_blue_frame(frame, *HOME))


def _nearest(frame: Frame) -> tuple[np.ndarray, np.ndarray]:
    """(R, n) each unit's nearest enemy (first in index order on a tie, -1 if none) and its centre distance."""
    near = nearest(frame.dist, frame.targetable)
    r, n = near.shape  # take_along_axis by plain indexing (same values, less Python overhead)
    d = frame.dist[np.arange(r)[:, None], np.arange(n), np.maximum(near, 0)]
    return near, np.where(near >= 0, d, np.inf)


def _enemy_weak(frame: Frame) -> np.ndarray:
    """(R,) SMAC-HARD's "the enemy is weak": fewer than 4 alive, or more than 2 below 20% hull health."""
    n_enemy = _sum(frame.enemy_alive, axis=1)
    n_weak = _sum(frame.enemy_alive & (frame.enemy_health_frac < 0.2), axis=1)
    return (n_enemy < 4) | (n_weak > 2)


class StalkerRetreat(BatchScript):
    """SMAC-HARD ``s_2s3z/script.py`` (also its ``s_3s5z/script.py``, same code, for 3s5z and 3s5z_vs_3s6z) as it
    runs.

    - A stalker attacks its nearest enemy; if that enemy is within 6 and the stalker is below 50% hull health, it
      moves to (23, 16) instead.
    - A zealot attacks its nearest enemy. (Its retreat below 40% needs the nearest enemy within 0.1 of its centre,
      which collision never allows: dead code, left out.)
    - When fewer than 4 enemies are alive, or more than 2 are below 20% hull health, every unit attack-moves to the
      enemy centre instead.

    Deliberate differences: red retreats to the reflected point ((9, 16) on these maps). Earlier releases compared
    health + shield with both thresholds.
    """

    name = "stalker_retreat"
    description = ("attack nearest; stalkers below 50% hull health with an enemy within 6 retreat home; all-in on "
                   "the enemy centre once it is weak (SMAC-HARD s_2s3z/script)")

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive = frame.own_alive
        stalker = of_kind(frame.own_type, "stalker") & alive
        zealot = of_kind(frame.own_type, "zealot") & alive
        near, d = _nearest(frame)
        orders.attack(stalker | zealot, near)
        _retreat_home(frame, orders, stalker & (d <= SHOOT_RANGE) & (frame.own_health_frac < 0.5))
        ex, ey = frame.enemy_centroid
        all_in = _enemy_weak(frame) & _any(frame.enemy_alive, axis=1)
        orders.attack_move(alive & all_in[:, None], ex[:, None], ey[:, None])


class CenterFocus(BatchScript):
    """SMAC-HARD ``s_2s3z/script_1.py`` as it runs.

    Stalkers attack the enemy zealot nearest the centre of the own units (else the enemy stalker nearest it);
    zealots attack the enemy nearest that centre; the first in index order on a tie. Any stalker or zealot below
    50% hull health moves to (23, 16) instead.

    Deliberate differences: red retreats to the reflected point. SMAC-HARD's last fallback (no enemy zealot or
    stalker alive: attack the enemy centre) cannot happen on its maps; here stalkers then take the enemy nearest
    the centre. Earlier releases compared health + shield with the 50% threshold.
    """

    name = "center_focus"
    description = ("stalkers focus the enemy zealot nearest the army centre, zealots the enemy nearest it; units "
                   "below 50% hull health retreat home (SMAC-HARD s_2s3z/script_1)")

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive = frame.own_alive
        cx, cy = frame.own_centroid
        d = np.hypot(frame.enemy_x - cx[:, None], frame.enemy_y - cy[:, None])
        any_pick = argmin_masked(d, frame.enemy_alive)
        zealot_pick = argmin_masked(d, frame.enemy_alive & of_kind(frame.enemy_type, "zealot"))
        stalker_pick = argmin_masked(d, frame.enemy_alive & of_kind(frame.enemy_type, "stalker"))
        pick = np.where(zealot_pick >= 0, zealot_pick, np.where(stalker_pick >= 0, stalker_pick, any_pick))
        stalker = of_kind(frame.own_type, "stalker") & alive
        zealot = of_kind(frame.own_type, "zealot") & alive
        orders.attack(stalker, pick[:, None])  # Orders broadcasts (R, 1) over the units
        orders.attack(zealot, any_pick[:, None])
        _retreat_home(frame, orders, (stalker | zealot) & (frame.own_health_frac < 0.5))


class KitePush(BatchScript):
    """SMAC-HARD ``s_3s5z/script_1.py`` as it runs. "Near" is the unit's nearest enemy, "in range" within 6.

    - Zealots: attack near when it is out of range; in range, move to (23, 16) below 50% hull health, else
      attack it.
    - Stalkers while 3 or more are alive: the same, with 70% for the retreat.
    - Fewer than 3 stalkers before step 100: attack near when it is out of range, else move to (23, 16).
    - Fewer than 3 stalkers from step 100: when the enemy is weak (fewer than 4 alive, or more than 2 below 20%
      hull health) attack near when it is closer than 6, else move (not attack-move) to the enemy centre;
      otherwise, on steps divisible by 50, stalkers with near closer than 6 move to (23, 16); on other steps the
      stalkers get no order and keep their last one.

    Deliberate differences: red retreats to the reflected point. Earlier releases kited on the weapon cooldown,
    compared the two sides' health shares and pulled back for 4 steps of every 50.
    """

    name = "kite_push"
    description = ("stalkers fall back home when in range after losing one (before step 100), then push on a weak "
                   "enemy or pull back every 50 steps (SMAC-HARD s_3s5z/script_1)")
    full_strength = 3
    kite_until = 100
    regroup_every = 50

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive, step = frame.own_alive, frame.step
        stalker = of_kind(frame.own_type, "stalker") & alive
        zealot = of_kind(frame.own_type, "zealot") & alive
        frac = frame.own_health_frac
        near, d = _nearest(frame)
        out = d > SHOOT_RANGE
        closer = d < SHOOT_RANGE

        n_stalkers = stalker.sum(axis=1)
        full = n_stalkers >= self.full_strength
        early = ~full & (step < self.kite_until)
        late = ~full & ~early
        weak = _enemy_weak(frame)

        orders.attack(zealot, near)
        _retreat_home(frame, orders, zealot & ~out & (frac < 0.5))

        held = stalker & full[:, None]
        orders.attack(held, near)
        _retreat_home(frame, orders, held & ~out & (frac < 0.7))

        kiting = stalker & early[:, None]
        orders.attack(kiting & out, near)
        _retreat_home(frame, orders, kiting & ~out)

        push = stalker & (late & weak)[:, None]
        orders.attack(push & closer, near)
        ex, ey = frame.enemy_centroid
        orders.move(push & ~closer & frame.enemy_alive.any(axis=1)[:, None], ex[:, None], ey[:, None])
        pull = stalker & (late & ~weak & (step % self.regroup_every == 0))[:, None]
        _retreat_home(frame, orders, pull & closer)


class ColossusSplash(BatchScript):
    """SMAC-HARD ``s_1c3s5z/script_m.py`` as it runs: zealots and stalkers attack their nearest enemy; the colossus
    attacks the enemy with the most enemies within 3 of it (itself included), the first in index order on a tie.

    SMAC-HARD's regroup order (when a unit is over 12 from the army centre, move there) is given before the same
    step's attack orders, which replace it: dead code, left out. Earlier releases broke the colossus's ties by
    distance.
    """

    name = "colossus_splash"
    description = ("stalkers and zealots attack nearest; the colossus fires at the enemy with the most enemies "
                   "within 3 (SMAC-HARD s_1c3s5z/script_m)")
    cluster_radius = 3.0

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive = frame.own_alive
        near, _ = _nearest(frame)
        orders.attack(of_kind(frame.own_type, "stalker", "zealot") & alive, near)
        colossus = of_kind(frame.own_type, "colossus") & alive
        if not colossus.any():
            return
        ex, ey = frame.enemy_x, frame.enemy_y
        close = np.hypot(ex[:, :, None] - ex[:, None, :], ey[:, :, None] - ey[:, None, :]) <= self.cluster_radius
        crowd = (close & frame.enemy_alive[:, None, :]).sum(axis=2)  # (R, m), the enemy itself counted
        densest = argmin_masked(-crowd.astype(np.float64), frame.enemy_alive)  # argmin: the first of the densest
        orders.attack(colossus, np.broadcast_to(densest[:, None], alive.shape))


_R3 = 4.0 * np.sqrt(3.0)
# SMAC-HARD's s_3s_vs_{3,4,5}z/script_attack.py, by number of zealots: the role picks made on the first step, the
# formation's reference (zealot 0 of the list, or the list's centre) and the slot offsets of list positions 0, 1, ...
# per stage, in blue's frame (x - 8 is toward the stalkers). Stage 1 puts zealots 8 from the target at +-90 degrees
# (and +-30 degrees from the reference's side), stage 2 at +-150 degrees.
_SURROUND: dict[int, tuple[tuple[str, ...], str, np.ndarray]] = {
    3: (("max_x", "min_y"), "first", np.array([
        [(0, 0), (0, -4), (0, 4)],
        [(0, 0), (-8, -8), (-8, 8)],
        [(0, 0), (-8 - _R3, -4), (-8 - _R3, 4)]], dtype=np.float64)),
    4: (("max_x", "max_y", "min_y"), "centre", np.array([
        [(0, 2), (0, 4), (0, -4), (0, -2)],
        [(-8 + _R3, 4), (-8, 8), (-8, -8), (-8 + _R3, -4)],
        [(-8 + _R3, 4), (-8 - _R3, 4), (-8 - _R3, -4), (-8 + _R3, -4)]], dtype=np.float64)),
    5: (("max_x", "max_y", "min_y", "min_x"), "first", np.array([
        [(0, 0), (0, 4), (0, -4), (0, 2), (0, -2)],
        [(0, 0), (-8, 8), (-8, -8), (-8 + _R3, 4), (-8 + _R3, -4)],
        [(0, 0), (-8 - _R3, 4), (-8 - _R3, -4), (-8 + _R3, 4), (-8 + _R3, -4)]], dtype=np.float64)),
}
_NO_UNIT = 1 << 30  # an empty role entry (sorts after every unit index)


class Surround(BatchScript):
    """SMAC-HARD ``s_3s_vs_{3,4,5}z/script_attack.py`` as it runs (the variant of the number of own units, 3 to 5).

    - Roles, once on the first step (blue's frame, index order on ties): the zealot with the largest x, then (by
      variant) the largest y, the smallest y, the smallest x, then the first zealot not yet picked. The picks can
      repeat a zealot and leave others out. Every step the list is these picks, still alive, **sorted by index**
      (repeats kept): list position k takes slot k. A zealot left out never gets an order; a repeated one gets two
      and the later counts, and since it cannot stand on two slots the stage never completes.
    - Until some listed zealot comes closer than 6.5 to a stalker (for good), the list forms up around a target:
      the stalkers' centre if every stalker is within 3 of it, else the stalker nearest the list's centre.
    - The formation's anchor: in stage 0, the reference (zealot 0 of the list, or on 3s_vs_4z the list's centre)
      itself while it is more than 13 from the target, else the point 13 from the target toward it; from stage 1,
      the point 8 from the target toward the reference. Slots are axis-aligned offsets from the anchor (stage 0: a
      north-south line, spacing 2; stages 1 and 2: 8 from the target at +-90 then +-150 degrees, the 4- and
      5-zealot variants also at +-30 degrees).
    - When every listed zealot is within 1 of its slot the stage advances (possibly several in one step, with the
      same anchor); after stage 2 the formation is over.
    - Then every listed zealot attacks its nearest stalker, every step.

    Deliberate differences: red plays the reflected frame (slots mirrored through the spawns' midpoint). Battles
    in which every listed zealot died but others live make SMAC-HARD raise an IndexError; here those zealots get no
    order. Earlier releases formed 13 in front, at +-60/+-120 degrees following the advance direction, gave roles
    by position, spaced the line 1.5 and ended a stage after 12 steps.
    """

    name = "surround"
    description = ("zealots form up on an axis-aligned line, then flank the stalkers at 8 in stages, attacking "
                   "nearest on contact within 6.5 (SMAC-HARD s_3s_vs_Nz/script_attack)")
    contact_distance = 6.5
    together_radius = 3.0
    arrive_distance = 1.0
    form_distance, flank_distance = 13.0, 8.0

    def __init__(self) -> None:
        self.memory = Memory(roles=((5,), np.int64, _NO_UNIT), picked=((), bool, False), stage=((), np.int64, 0),
                             engaged=((), bool, False))

    def _pick_roles(self, frame: Frame, local: np.ndarray, picks: tuple[str, ...]) -> None:
        alive = frame.own_alive[local]
        x, y = frame.own_hx[local], frame.own_hy[local]
        keys = {"max_x": -x, "max_y": -y, "min_y": y, "min_x": x}
        chosen = [argmin_masked(keys[p], alive) for p in picks]  # argmin: the first on a tie, as np.argmax
        index = np.arange(frame.n_own)
        taken = np.zeros_like(alive)
        for c in chosen:
            taken |= index[None, :] == c[:, None]
        extra = argmin_masked(np.broadcast_to(index, alive.shape).astype(np.float64), alive & ~taken)
        roles = np.stack(chosen + [extra], axis=1)
        roles = np.sort(np.where(roles >= 0, roles, _NO_UNIT), axis=1)
        full = np.full((local.size, 5), _NO_UNIT, dtype=np.int64)
        full[:, :roles.shape[1]] = roles
        rows = frame.rows[local]
        self.memory.roles[rows] = full
        self.memory.picked[rows] = True

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, alive, n = frame.rows, frame.own_alive, frame.n_own
        picks, reference, table = _SURROUND[min(max(n, 3), 5)]
        width = table.shape[1]
        fresh = ~self.memory.picked[rows] & alive.any(axis=1)
        if fresh.any():
            self._pick_roles(frame, np.flatnonzero(fresh), picks)

        entries = self.memory.roles[rows][:, :width]  # (R, L) own indices, sorted
        safe = np.minimum(entries, n - 1)
        valid = (entries < n) & np.take_along_axis(alive, safe, axis=1)
        position = np.cumsum(valid, axis=1) - 1  # list position of each valid entry
        count = valid.sum(axis=1)
        live = (count > 0) & frame.enemy_alive.any(axis=1)
        ux, uy = np.take_along_axis(frame.own_hx, safe, axis=1), np.take_along_axis(frame.own_hy, safe, axis=1)
        to_nearest = np.where(frame.enemy_alive[:, None, :], frame.dist, np.inf).min(axis=2)
        contact = (valid & (np.take_along_axis(to_nearest, safe, axis=1) < self.contact_distance)).any(axis=1)
        engaged = self.memory.engaged[rows] | (live & contact)
        forming = live & ~engaged

        if forming.any():
            stage = self.memory.stage[rows].copy()
            ax, ay = self._anchor(frame, valid, count, ux, uy, stage, reference)
            looping = forming.copy()
            for _ in range(3):  # a stage whose slots are all held advances, and the next is checked at once
                sx, sy = self._slots(table, stage, position, ax, ay)
                held = np.all(~valid | (np.hypot(ux - sx, uy - sy) <= self.arrive_distance), axis=1)
                looping &= held & (stage < 3)
                stage = stage + looping
            self.memory.stage[rows] = np.where(forming, stage, self.memory.stage[rows])
            done = forming & (stage >= 3)
            engaged |= done
            forming &= ~done
            px, py = from_blue_frame(frame, *self._slots(table, stage, position, ax, ay))
            index = np.arange(n)
            for k in range(width):  # list order: a repeated zealot's later slot replaces its earlier one
                unit = (index[None, :] == entries[:, k:k + 1]) & (valid[:, k] & forming)[:, None]
                orders.move(unit, px[:, k:k + 1], py[:, k:k + 1])
        self.memory.engaged[rows] = engaged

        listed = np.zeros_like(alive)
        for k in range(width):
            listed |= (np.arange(n)[None, :] == entries[:, k:k + 1]) & valid[:, k:k + 1]
        orders.attack(listed & engaged[:, None], nearest(frame.dist, frame.targetable))

    def _anchor(self, frame: Frame, valid: np.ndarray, count: np.ndarray, ux: np.ndarray, uy: np.ndarray,
                stage: np.ndarray, reference: str) -> tuple[np.ndarray, np.ndarray]:
        """(R,) the formation's anchor in blue's frame (see the class docstring)."""
        e_alive = frame.enemy_alive
        ex, ey = frame.enemy_hx, frame.enemy_hy
        cx, cy = centroid(ex, ey, e_alive)
        together = np.all(~e_alive | (np.hypot(ex - cx[:, None], ey - cy[:, None]) <= self.together_radius), axis=1)
        safe_count = np.maximum(count, 1)
        lx, ly = (ux * valid).sum(axis=1) / safe_count, (uy * valid).sum(axis=1) / safe_count  # repeats weigh twice
        near = np.maximum(argmin_masked(np.hypot(ex - lx[:, None], ey - ly[:, None]), e_alive), 0)[:, None]
        tx = np.where(together, cx, np.take_along_axis(ex, near, axis=1)[:, 0])
        ty = np.where(together, cy, np.take_along_axis(ey, near, axis=1)[:, 0])
        if reference == "first":
            first = np.argmax(valid, axis=1)[:, None]
            rx, ry = np.take_along_axis(ux, first, axis=1)[:, 0], np.take_along_axis(uy, first, axis=1)[:, 0]
        else:
            rx, ry = lx, ly
        vx, vy = unit_vector(rx - tx, ry - ty)
        far = np.hypot(rx - tx, ry - ty) > self.form_distance
        ax = np.where(stage > 0, tx + self.flank_distance * vx, np.where(far, rx, tx + self.form_distance * vx))
        ay = np.where(stage > 0, ty + self.flank_distance * vy, np.where(far, ry, ty + self.form_distance * vy))
        return ax, ay

    @staticmethod
    def _slots(table: np.ndarray, stage: np.ndarray, position: np.ndarray, ax: np.ndarray, ay: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
        """(R, L) slot of each list entry for the rows' stages (stage 3 reads as 2; unused then)."""
        offset = table[np.minimum(stage, 2)[:, None], np.maximum(position, 0)]  # (R, L, 2)
        return ax[:, None] + offset[..., 0], ay[:, None] + offset[..., 1]
