"""Zerg swarm maps: SMAC-HARD's corridor, so_many_baneling, bane_vs_bane and 2c_vs_64zg scripts, written from their
strategy descriptions. Waypoints are derived from the map's spawns where the original hard-coded them, except for
the 2c_vs_64zg staging points, which belong to that map's cliffs."""

from __future__ import annotations

import numpy as np

from smac_hard_gym.maps import UnitGroup
from smac_hard_gym.opponents.api import RED, spawn_centre
from smac_hard_gym.opponents.generic import attack_nearest
from smac_hard_gym.opponents.helpers import (
    BatchScript,
    Frame,
    Memory,
    Orders,
    across_rank,
    arc_points,
    argmin_masked,
    centroid,
    lowest,
    nearest,
    of_kind,
    to_pathable,
)

__all__ = ["Blob", "Pincer", "PairBombing", "BaneCluster", "CliffGroups"]


def _contact(frame: Frame, distance: float) -> np.ndarray:
    """(R,) some own unit is within ``distance`` (centres) of an enemy it can hit."""
    return np.where(frame.hittable, frame.dist, np.inf).min(axis=(1, 2)) <= distance


def _take(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    """values (R, m) at index (R, k) (index clipped at 0)."""
    return np.take_along_axis(values, np.maximum(index, 0), axis=1)


class Blob(BatchScript):
    """SMAC-HARD ``s_corridor/script_d``: the zerglings move as one blob to the enemy centre until one of them is
    within 3 of an enemy; then each attack-moves onto its assigned enemy (dealt in turn, unit i gets enemy
    i mod m) while it lives, else onto its nearest."""

    name = "blob"
    description = ("move as one blob to the enemy centre, then each attack-moves onto its assigned or nearest "
                   "enemy (SMAC-HARD s_corridor/script_d)")
    contact_distance = 3.0

    def __init__(self) -> None:
        self.memory = Memory(engaged=((), bool, False))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, alive = frame.rows, frame.own_alive
        engaged = self.memory.engaged[rows] | _contact(frame, self.contact_distance)
        self.memory.engaged[rows] = engaged
        ex, ey = frame.enemy_centroid
        orders.move(alive & ~engaged[:, None], ex[:, None], ey[:, None])
        assigned = np.broadcast_to(np.arange(frame.n_own) % frame.n_enemy, alive.shape)
        keep = np.take_along_axis(frame.hittable, assigned[:, :, None], axis=2)[:, :, 0]
        pick = np.where(keep, assigned, nearest(frame.dist, frame.hittable))
        orders.attack_move(alive & engaged[:, None] & (pick >= 0), _take(frame.enemy_x, pick),
                           _take(frame.enemy_y, pick))


class Pincer(BatchScript):
    """SMAC-HARD ``s_corridor/script_y``: two halves (split across the direction of advance) swing out to flanking
    waypoints on either side of the enemy spawn for at most 13 steps or until one is within 6 of an enemy; then each
    zergling attacks the weaker of its 2 nearest enemies.

    The waypoints are the enemy spawn moved 0.82 toward the enemy's side and 4.89 to either side: on corridor that
    is SMAC-HARD's (15, 22) and (22, 15).
    """

    name = "pincer"
    description = ("two groups swing round both flanks, then each attacks the weaker of its 2 nearest enemies "
                   "(SMAC-HARD s_corridor/script_y)")
    flank_steps = 13
    contact_distance = 6.0
    along, across = 0.82, 4.89

    def __init__(self) -> None:
        self.memory = Memory(engaged=((), bool, False), wing=(("own",), np.int64, -1))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, alive, f = frame.rows, frame.own_alive, frame.forward
        unset = self.memory.wing[rows, 0] < 0
        if unset.any():
            rank = across_rank(frame.own_x[unset], frame.own_y[unset], f)
            self.memory.wing[rows[unset]] = (rank >= frame.n_own // 2).astype(np.int64)
        wing = self.memory.wing[rows]
        engaged = (self.memory.engaged[rows] | _contact(frame, self.contact_distance)
                   | (frame.step >= self.flank_steps))
        self.memory.engaged[rows] = engaged

        e = frame.view.enemy_spawn
        side = np.where(wing == 1, 1.0, -1.0)
        wx = e[0] + self.along * f[0] - side * self.across * f[1]
        wy = e[1] + self.along * f[1] + side * self.across * f[0]
        wx, wy = to_pathable(wx, wy, frame.spec)
        orders.move(alive & ~engaged[:, None], wx, wy)

        d = np.where(frame.hittable, frame.dist, np.inf)
        two = np.argsort(d, axis=2, kind="stable")[:, :, :2]
        valid = np.take_along_axis(d, two, axis=2) < np.inf
        hp = _take(frame.enemy_hp, two.reshape(frame.size, -1)).reshape(two.shape)
        pick = lowest(hp, valid, tie=np.take_along_axis(d, two, axis=2))
        target = np.where(pick >= 0, np.take_along_axis(two, np.maximum(pick, 0)[:, :, None], axis=2)[:, :, 0], -1)
        orders.attack(alive & engaged[:, None], target)


BANELING_HIT = 35.0  # baneling damage against light units (16 + 19): SMAC-HARD counts this per baneling


class PairBombing(BatchScript):
    """SMAC-HARD ``s_so_many_baneling``: banelings in groups of 5 bomb pairs of enemies standing within 2 of each
    other, where one burst hits both.

    Each step the groups, in turn, take the nearest enemy that has a partner within 2 and is not yet covered by an
    earlier group (the pair is then covered); a group needs ceil(health / 35) banelings for the pair's healthier
    unit and the surplus waits with the uncommitted groups. Uncommitted groups sweep toward the enemy and wait 5
    short of it. Once no pair is left anywhere, groups take single enemies the same way.
    """

    name = "pair_bombing"
    description = ("groups of 5 banelings bomb enemies standing in pairs, the rest close in and wait; singles "
                   "last (SMAC-HARD s_so_many_baneling)")
    group_size = 5
    pair_distance = 2.0
    standoff = 7.0

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive = frame.own_alive
        n, R = frame.n_own, frame.size
        group = np.arange(n) // self.group_size  # (n,) fixed by slot
        n_groups = int(group[-1]) + 1

        ex, ey, e_alive = frame.enemy_x, frame.enemy_y, frame.enemy_alive
        pair_d = np.hypot(ex[:, :, None] - ex[:, None, :], ey[:, :, None] - ey[:, None, :])
        partners = (pair_d <= self.pair_distance) & e_alive[:, :, None] & e_alive[:, None, :]
        partners &= ~np.eye(frame.n_enemy, dtype=bool)[None]
        paired = partners.any(axis=2)  # (R, m)
        pairs_left = paired.any(axis=1)  # (R,)
        candidates = np.where(pairs_left[:, None], paired, e_alive)
        # The health a group must burn through: the worse of the enemy and its partners.
        pair_hp = np.where(partners, frame.enemy_hp[:, None, :], 0.0).max(axis=2)
        need = np.ceil(np.maximum(frame.enemy_hp, pair_hp) / BANELING_HIT).astype(np.int64)

        covered = np.zeros_like(e_alive)
        target = np.full((R, n), -1, dtype=np.int64)
        r = np.arange(R)
        for g in range(n_groups):
            in_group = (group == g)[None, :] & alive
            if not in_group.any():
                continue
            gx, gy = centroid(frame.own_x, frame.own_y, in_group)
            d = np.hypot(ex - gx[:, None], ey - gy[:, None])
            pick = argmin_masked(d, candidates & ~covered & in_group.any(axis=1)[:, None])
            ok = pick >= 0
            covered[r[ok], pick[ok]] = True
            covered[ok] |= partners[r[ok], pick[ok]]
            # The first ``need`` living members of the group commit; the surplus stays uncommitted.
            live_rank = np.cumsum(in_group, axis=1) - 1
            needed = np.where(ok, need[r, np.maximum(pick, 0)], 0)
            commit = in_group & (live_rank < needed[:, None]) & ok[:, None]
            target = np.where(commit, pick[:, None], target)

        orders.attack(alive & (target >= 0), target)
        waiting = alive & (target < 0)
        cx, cy = frame.enemy_centroid
        near_d = np.where(e_alive[:, None, :], frame.dist, np.inf).min(axis=2)
        # Waiting units stop short of the enemy (outside its 5.9 auto-acquire reach) but never hold: a holding
        # unit cannot be pushed aside and would wall in the bombers behind it.
        orders.move(waiting & (near_d > self.standoff), cx[:, None], cy[:, None])
        orders.stop(waiting & (near_d <= self.standoff) & (frame.view.own_order[frame.rows] != 0))


class BaneCluster(BatchScript):
    """SMAC-HARD ``s_bane_vs_bane``: banelings attack the enemy zergling with the most enemy zerglings within 2
    (nearest on a tie; any enemy once no zergling is left); zerglings fan out on a half circle of radius 10 around
    their spawn, facing the enemy, for 10 steps, then attack their nearest enemy."""

    name = "bane_cluster"
    description = ("banelings hit the densest zergling cluster; zerglings fan out on a half circle for 10 steps, "
                   "then attack nearest (SMAC-HARD s_bane_vs_bane)")
    fan_steps = 10
    fan_radius = 10.0
    cluster_radius = 2.0

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive, f = frame.own_alive, frame.forward
        bane = of_kind(frame.own_type, "baneling") & alive
        ling = of_kind(frame.own_type, "zergling") & alive

        e_ling = of_kind(frame.enemy_type, "zergling") & frame.enemy_alive
        ex, ey = frame.enemy_x, frame.enemy_y
        close = np.hypot(ex[:, :, None] - ex[:, None, :], ey[:, :, None] - ey[:, None, :]) <= self.cluster_radius
        crowd = (close & e_ling[:, None, :]).sum(axis=2).astype(np.float64)  # (R, m)
        score = -crowd[:, None, :] * 100.0 + frame.dist
        ling_targets = frame.targetable & e_ling[:, None, :]
        pick = argmin_masked(score, ling_targets)
        pick = np.where(pick >= 0, pick, nearest(frame.dist, frame.targetable))
        orders.attack(bane, pick)

        fanning = frame.step < self.fan_steps
        ling_slots = of_kind(frame.own_type[0], "zergling")
        n_ling = int(ling_slots.sum())
        if n_ling:
            groups = _zergling_groups(frame)
            centre = spawn_centre(groups) if groups else frame.view.own_spawn
            ax, ay = arc_points(np.full(frame.size, centre[0]), np.full(frame.size, centre[1]), f, n_ling,
                                self.fan_radius)
            ax, ay = to_pathable(ax, ay, frame.spec)
            # Each zergling takes the arc point of its rank across the direction of advance.
            rank = across_rank(frame.own_x[:, ling_slots], frame.own_y[:, ling_slots], f)
            px = np.zeros_like(frame.own_x)
            py = np.zeros_like(frame.own_y)
            px[:, ling_slots] = np.take_along_axis(ax, rank, axis=1)
            py[:, ling_slots] = np.take_along_axis(ay, rank, axis=1)
            orders.move(ling & fanning[:, None], px, py)
        attack_nearest(frame, orders, ling & ~fanning[:, None])


def _zergling_groups(frame: Frame) -> tuple[UnitGroup, ...]:
    """This side's zergling groups in the map file (their spawn is the fan's centre)."""
    groups = frame.spec.red if frame.view.side == RED else frame.spec.blue
    return tuple(g for g in groups if g.unit.lower().startswith("zergling"))


# 2c_vs_64zg staging points (map cells): the tops of the west and east ramps onto the colossi's plateau, and the low
# ground under its cliff on either side.
_CLIFF_STAGING = np.array([[8.5, 15.5], [23.5, 15.5], [10.0, 10.5], [22.0, 10.5]])


class CliffGroups(BatchScript):
    """SMAC-HARD ``s_2c_vs_64zg``: four groups by cliff level and side.

    The swarm splits into west and east halves, each half into an upper group (which climbs the ramp onto the
    plateau) and a lower group (which waits on the low ground under the cliff). For 10 steps the groups go to their
    staging points; then the upper groups attack the nearest enemy, and the lower groups attack the nearest enemy
    standing on their own (low) level, holding their ground while none is.
    """

    name = "cliff_groups"
    description = ("four groups (ramp climbers and low-ground ambushers, west and east) stage for 10 steps, then "
                   "attack enemies on their level (SMAC-HARD s_2c_vs_64zg)")
    stage_steps = 10

    def __init__(self) -> None:
        self.memory = Memory(group=(("own",), np.int64, -1))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, alive = frame.rows, frame.own_alive
        unset = self.memory.group[rows, 0] < 0
        if unset.any():
            x = frame.own_x[unset]
            order = np.argsort(np.argsort(x, axis=1, kind="stable"), axis=1, kind="stable")
            east = order >= frame.n_own // 2
            lower = (order % 2) == 1  # alternate within each half: equal upper and lower groups
            self.memory.group[rows[unset]] = east.astype(np.int64) + 2 * lower
        group = self.memory.group[rows]
        upper = group < 2

        staging = frame.step < self.stage_steps
        sx, sy = to_pathable(_CLIFF_STAGING[group, 0], _CLIFF_STAGING[group, 1], frame.spec)
        orders.move(alive & staging[:, None], sx, sy)

        fight = alive & ~staging[:, None]
        attack_nearest(frame, orders, fight & upper)
        spec = frame.spec
        own_level = spec.cliff[int(frame.view.own_spawn[0]), int(frame.view.own_spawn[1])]
        cx = np.clip(frame.enemy_x, 0, spec.size[0] - 1).astype(np.int64)
        cy = np.clip(frame.enemy_y, 0, spec.size[1] - 1).astype(np.int64)
        low = spec.cliff[cx, cy] <= own_level  # (R, m)
        pick = nearest(frame.dist, frame.targetable & low[:, None, :])
        lower_fight = fight & ~upper
        orders.attack(lower_fight, pick)
        at_post = np.hypot(frame.own_x - sx, frame.own_y - sy) <= 1.0
        orders.hold(lower_fight & (pick < 0) & at_post)
        orders.move(lower_fight & (pick < 0) & ~at_post, sx, sy)
