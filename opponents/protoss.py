"""Protoss maps: SMAC-HARD's stalker/zealot scripts (2s3z, 3s5z, 3s5z_vs_3s6z), the 1c3s5z colossus script and the
3s_vs_Nz staged surround, written from their strategy descriptions.

SMAC-HARD's fixed retreat point (23, 16) is the own spawn here. "Health" for protoss units is health + shield.
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.opponents.generic import READY_LOOPS, attack_nearest, back_off, nearest_threat
from smac_hard_gym.opponents.helpers import (
    BatchScript,
    Frame,
    Memory,
    Orders,
    argmin_masked,
    nearest,
    of_kind,
    to_pathable,
)

__all__ = ["StalkerRetreat", "CenterFocus", "KitePush", "ColossusSplash", "Surround"]


def _retreat_home(frame: Frame, orders: Orders, units: np.ndarray) -> None:
    sx, sy = frame.view.own_spawn
    orders.move(units, sx, sy)


def _nearest_enemy_distance(frame: Frame) -> np.ndarray:
    """(R, n) centre distance to the nearest alive enemy (inf if none)."""
    return np.where(frame.enemy_alive[:, None, :], frame.dist, np.inf).min(axis=2)


class StalkerRetreat(BatchScript):
    """SMAC-HARD ``s_2s3z/script`` (also its 3s5z and 3s5z_vs_3s6z script).

    Stalkers and zealots attack their nearest enemy; a stalker below 50% with an enemy within 6 retreats to the own
    spawn. When fewer than 4 enemies remain or more than 2 are below 20%, everyone attack-moves to the enemy centre.
    (The original's zealot retreat below 40% could never trigger and is left out.)
    """

    name = "stalker_retreat"
    description = ("attack nearest; wounded stalkers near an enemy retreat home; all-in on the enemy centre once "
                   "it is weak (SMAC-HARD s_2s3z/script)")

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive = frame.own_alive
        attack_nearest(frame, orders)
        stalker = of_kind(frame.own_type, "stalker") & alive
        wounded = stalker & (frame.own_hp_frac < 0.5) & (_nearest_enemy_distance(frame) <= 6.0)
        _retreat_home(frame, orders, wounded)
        n_enemy = frame.enemy_alive.sum(axis=1)
        n_weak = (frame.enemy_alive & (frame.enemy_hp_frac < 0.2)).sum(axis=1)
        all_in = (n_enemy < 4) | (n_weak > 2)
        ex, ey = frame.enemy_centroid
        orders.attack_move(alive & all_in[:, None], ex[:, None], ey[:, None])


class CenterFocus(BatchScript):
    """SMAC-HARD ``s_2s3z/script_1``: stalkers focus the enemy zealot nearest the own centre (else the enemy
    nearest it), zealots the enemy nearest the own centre; any unit below 50% retreats to the own spawn."""

    name = "center_focus"
    description = ("stalkers focus the enemy zealot nearest the army centre, zealots the enemy nearest it; units "
                   "below 50% retreat home (SMAC-HARD s_2s3z/script_1)")

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive = frame.own_alive
        cx, cy = frame.own_centroid
        d = np.hypot(frame.enemy_x - cx[:, None], frame.enemy_y - cy[:, None])
        any_pick = argmin_masked(d, frame.enemy_alive)
        zealots = frame.enemy_alive & of_kind(frame.enemy_type, "zealot")
        zealot_pick = np.where(zealots.any(axis=1), argmin_masked(d, zealots), any_pick)
        stalker = of_kind(frame.own_type, "stalker")
        pick = np.where(stalker, zealot_pick[:, None], any_pick[:, None])
        can = np.take_along_axis(frame.targetable, np.maximum(pick, 0)[:, :, None], axis=2)[:, :, 0] & (pick >= 0)
        attack_nearest(frame, orders, alive & ~can)
        orders.attack(alive & can, pick)
        _retreat_home(frame, orders, alive & (frame.own_hp_frac < 0.5))


class KitePush(BatchScript):
    """SMAC-HARD ``s_3s5z/script_1`` (kiting).

    - Zealots attack their nearest enemy and retreat home below 50%.
    - Stalkers, all alive: attack nearest, but fall back home when an enemy is within 6 and they are below 70%.
    - After the first stalker loss, before step 100: kite (fire when the weapon is ready, else step back from
      enemies that could reach them).
    - From step 100: push (attack nearest) while the enemy holds a smaller share of its health than we do, else pull
      back home for 4 steps out of every 50 and fight in between.
    """

    name = "kite_push"
    description = ("stalkers kite after the first loss, then push when ahead and pull back every 50 steps "
                   "otherwise (SMAC-HARD s_3s5z/script_1)")
    kite_until = 100
    regroup_every = 50
    regroup_steps = 4

    def __init__(self) -> None:
        self.memory = Memory(stalkers=((), np.int64, -1))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, alive, step = frame.rows, frame.own_alive, frame.step
        stalker = of_kind(frame.own_type, "stalker") & alive
        zealot = of_kind(frame.own_type, "zealot") & alive
        n_stalkers = stalker.sum(axis=1)
        first = self.memory.stalkers[rows] < 0
        self.memory.stalkers[rows] = np.where(first, n_stalkers, self.memory.stalkers[rows])
        lost = n_stalkers < self.memory.stalkers[rows]

        attack_nearest(frame, orders)
        _retreat_home(frame, orders, zealot & (frame.own_hp_frac < 0.5))

        intact = stalker & ~lost[:, None]
        _retreat_home(frame, orders, intact & (frame.own_hp_frac < 0.7) & (_nearest_enemy_distance(frame) <= 6.0))

        kiting = stalker & (lost & (step < self.kite_until))[:, None]
        near = nearest_threat(frame, margin=2.5)
        back_off(frame, orders, kiting & (frame.own_cooldown > READY_LOOPS), near, 2.5)

        late = stalker & (lost & (step >= self.kite_until))[:, None]
        own_share = (frame.own_hp * alive).sum(axis=1) / frame.own_hp_max.sum(axis=1)
        enemy_share = (frame.enemy_hp * frame.enemy_alive).sum(axis=1) / frame.enemy_hp_max.sum(axis=1)
        regroup = (enemy_share >= own_share) & (step % self.regroup_every < self.regroup_steps)
        _retreat_home(frame, orders, late & regroup[:, None])


class ColossusSplash(BatchScript):
    """SMAC-HARD ``s_1c3s5z/script_m``: zealots and stalkers attack their nearest enemy; the colossus attacks the
    enemy with the most other enemies within 3 (its line splash hits them too), nearest on a tie. (The original's
    regroup order was overridden by the same step's attacks and is left out.)"""

    name = "colossus_splash"
    description = ("stalkers and zealots attack nearest; the colossus fires at the densest enemy cluster "
                   "(SMAC-HARD s_1c3s5z/script_m)")
    cluster_radius = 3.0

    def plan(self, frame: Frame, orders: Orders) -> None:
        attack_nearest(frame, orders)
        colossus = of_kind(frame.own_type, "colossus") & frame.own_alive
        if not colossus.any():
            return
        dx = frame.enemy_x[:, :, None] - frame.enemy_x[:, None, :]
        dy = frame.enemy_y[:, :, None] - frame.enemy_y[:, None, :]
        close = (np.hypot(dx, dy) <= self.cluster_radius) & frame.enemy_alive[:, None, :]
        crowd = close.sum(axis=2).astype(np.float64)  # (R, m), counting the enemy itself
        # Most neighbours first, then the nearest: one score, crowd dominating distance (< 100 on a 32 map).
        score = -crowd[:, None, :] * 100.0 + frame.dist
        orders.attack(colossus, argmin_masked(score, frame.targetable))


_ROOT3 = float(np.sqrt(3.0))
# Surround slots as (along, across) offsets from the target centre, per role and stage; "along" points from our
# side toward the enemy. Role 0 is the bait in front, 1 and 2 the flanks, 3 goes round behind, 4+ wait in front.
_SLOTS = np.array([
    # stage 0: a line 13 in front      stage 1: flanks at 8            stage 2: behind and flanks
    [[-13.0, 0.0], [-8.0, 0.0], [-8.0, 0.0]],
    [[-13.0, 1.5], [-4.0, 4 * _ROOT3], [4.0, 4 * _ROOT3]],
    [[-13.0, -1.5], [-4.0, -4 * _ROOT3], [4.0, -4 * _ROOT3]],
    [[-13.0, 3.0], [0.0, 8.0], [8.0, 0.0]],
])
_EXTRA_ACROSS = 1.5  # roles 4+ spread in front of the bait at this spacing


class Surround(BatchScript):
    """SMAC-HARD ``s_3s_vs_Nz/script_attack``: zealots surround the stalkers in stages before engaging.

    Roles (fixed on the first step): the rearmost zealot is the bait, then the leftmost and rightmost take the
    flanks, the frontmost goes round behind, the rest wait with the bait. The target centre is the enemy centroid
    when the enemies stand within 3 of it, else the enemy nearest the zealots. Stage 0 is a line 13 in front of
    it, stage 1 puts the flanks at 8 on either side, stage 2 closes behind; a stage ends when every zealot is within
    1 of its slot (or after 12 steps, so an unreachable slot cannot stall it). After stage 2, or as soon as a
    zealot comes within 6.5 of an enemy, every zealot attacks its nearest enemy.
    """

    name = "surround"
    description = ("zealots take staged positions around the stalkers (front line, flanks, behind), then attack "
                   "nearest (SMAC-HARD s_3s_vs_Nz/script_attack)")
    contact_distance = 6.5
    arrive_distance = 1.0
    stage_timeout = 12

    def __init__(self) -> None:
        self.memory = Memory(stage=((), np.int64, 0), stage_steps=((), np.int64, 0), engaged=((), bool, False),
                             role=(("own",), np.int64, -1))

    def _assign_roles(self, frame: Frame, rows_local: np.ndarray) -> None:
        f = frame.forward
        x, y = frame.own_x[rows_local], frame.own_y[rows_local]
        along = x * f[0] + y * f[1]
        across = -x * f[1] + y * f[0]
        role = np.full(x.shape, -1, dtype=np.int64)
        free = np.ones(x.shape, dtype=bool)
        r = np.arange(x.shape[0])
        for slot, key in enumerate((along, -across, across, -along)):  # rearmost, left, right, frontmost
            pick = argmin_masked(key, free)
            ok = pick >= 0
            role[r[ok], pick[ok]] = slot
            free[r[ok], pick[ok]] = False
        rest = np.cumsum(free, axis=1) - 1  # the others in index order
        role = np.where(free, len(_SLOTS) + rest, role)
        self.memory.role[frame.rows[rows_local]] = role

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, alive, f = frame.rows, frame.own_alive, frame.forward
        unset = self.memory.role[rows, 0] < 0
        if unset.any():
            self._assign_roles(frame, np.flatnonzero(unset))
        role = self.memory.role[rows]
        stage = self.memory.stage[rows]

        contact = (np.where(frame.hittable, frame.dist, np.inf).min(axis=(1, 2)) <= self.contact_distance)
        engaged = self.memory.engaged[rows] | contact | (stage >= 3)
        self.memory.engaged[rows] = engaged

        # Target centre: the enemy centroid if they stand together, else the enemy nearest our centre.
        ex, ey = frame.enemy_centroid
        spread = np.hypot(frame.enemy_x - ex[:, None], frame.enemy_y - ey[:, None])
        together = np.all(~frame.enemy_alive | (spread <= 3.0), axis=1)
        ox, oy = frame.own_centroid
        near = np.maximum(argmin_masked(np.hypot(frame.enemy_x - ox[:, None], frame.enemy_y - oy[:, None]),
                                        frame.enemy_alive), 0)[:, None]
        tx = np.where(together, ex, np.take_along_axis(frame.enemy_x, near, axis=1)[:, 0])
        ty = np.where(together, ey, np.take_along_axis(frame.enemy_y, near, axis=1)[:, 0])

        s = np.minimum(stage, 2)[:, None]
        base_role = np.minimum(role, len(_SLOTS) - 1)
        offset = _SLOTS[np.where(role < len(_SLOTS), base_role, 0), s]  # (R, n, 2)
        extra = role - len(_SLOTS) + 1
        extra_across = np.where(role >= len(_SLOTS), np.where(extra % 2 == 1, 1, -1) * ((extra + 1) // 2), 0)
        along_off = offset[..., 0]
        across_off = offset[..., 1] + extra_across * _EXTRA_ACROSS
        sx = tx[:, None] + along_off * f[0] - across_off * f[1]
        sy = ty[:, None] + along_off * f[1] + across_off * f[0]
        sx, sy = to_pathable(sx, sy, frame.spec)

        forming = alive & ~engaged[:, None]
        orders.move(forming, sx, sy)
        arrived = np.all(~forming | (np.hypot(frame.own_x - sx, frame.own_y - sy) <= self.arrive_distance), axis=1)
        steps = self.memory.stage_steps[rows] + 1
        advance = ~engaged & (arrived | (steps >= self.stage_timeout))
        self.memory.stage[rows] = stage + advance
        self.memory.stage_steps[rows] = np.where(advance, 0, steps)

        orders.attack(alive & engaged[:, None], nearest(frame.dist, frame.targetable))
