"""Zerg maps: SMAC-HARD's corridor, so_many_baneling, bane_vs_bane, 2c_vs_64zg and 2s_vs_1sc scripts, as SMAC-HARD's
code runs them.

SMAC-HARD's map coordinates (waypoints, group cut-offs, cliff level) are kept exactly for blue; red plays them
reflected through the midpoint of the two spawns (:meth:`~smac_hard_gym.opponents.helpers.Frame.blue_frame`), and
points that land off pathable ground are moved onto it (these maps are not symmetric). SMAC-HARD's lists are in
tag or raw observation order, both our index order, so "first" on a tie means the lowest index.
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.opponents.helpers import (
    BatchScript,
    Frame,
    Memory,
    Orders,
    argmin_masked,
    from_blue_frame,
    list_rank,
    lowest,
    nearest,
    of_kind,
    weakest_of_nearest,
)

__all__ = ["Blob", "Pincer", "PairBombing", "BaneCluster", "CliffGroups", "SpineWeaker"]

_FAR = 1000.0  # SMAC-HARD's centre of an empty group, and its mark for a group already given a pair


def _take(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    """values (R, m) at index (R, k) (index clipped at 0)."""
    return np.take_along_axis(values, np.maximum(index, 0), axis=1)


def _live(frame: Frame) -> np.ndarray:
    """(R,) rows where both sides have a unit alive."""
    return frame.own_alive.any(axis=1) & frame.enemy_alive.any(axis=1)


def _group_centres(frame: Frame, members: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, G) centres in blue's frame of the (R, G, n) member masks; (1000, 1000) for an empty group."""
    count = members.sum(axis=2)
    safe = np.maximum(count, 1)
    cx = (members * frame.own_hx[:, None, :]).sum(axis=2) / safe
    cy = (members * frame.own_hy[:, None, :]).sum(axis=2) / safe
    return np.where(count > 0, cx, _FAR), np.where(count > 0, cy, _FAR)


def _members(group: np.ndarray, alive: np.ndarray, n_groups: int) -> np.ndarray:
    """(R, G, n) alive members of each group."""
    return (group[:, None, :] == np.arange(n_groups)[None, :, None]) & alive[:, None, :]


def _lowest_first(member: np.ndarray, y: np.ndarray, key: np.ndarray, k: np.ndarray) -> np.ndarray:
    """(R, n) the ``k`` (R,) members with the lowest ``y``, ties in ``key`` order (Python's stable sort)."""
    order = np.lexsort((key, np.where(member, y, np.inf)), axis=-1)
    rank = np.argsort(order, axis=-1, kind="stable")
    return member & (rank < k[:, None])


class Blob(BatchScript):
    """SMAC-HARD ``s_corridor/script_d.py`` as it runs: while the zerglings' centre is more than 3 from the enemy
    centre, every zergling moves to the enemy centre; otherwise (re-checked every step, so the blob can go back to
    moving) each attack-moves to the position of its nearest enemy, the first in index order on a tie.

    SMAC-HARD also deals the zealots out to the zerglings in turn, but keeps a dealt one only while its
    ``is_active`` is true, which it never is for a unit: that branch is dead. Earlier releases engaged for good once
    any zergling was within 3 of a zealot and kept the dealt targets.
    """

    name = "blob"
    description = ("move as one blob to the enemy centre while the two centres are over 3 apart, else each "
                   "attack-moves onto its nearest enemy (SMAC-HARD s_corridor/script_d)")
    contact_distance = 3.0

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive = frame.own_alive & _live(frame)[:, None]
        ox, oy = frame.own_centroid
        ex, ey = frame.enemy_centroid
        apart = np.hypot(ex - ox, ey - oy) > self.contact_distance
        orders.move(alive & apart[:, None], ex[:, None], ey[:, None])
        near = nearest(frame.dist, frame.targetable)
        orders.attack_move(alive & ~apart[:, None] & (near >= 0), _take(frame.enemy_x, near),
                           _take(frame.enemy_y, near))


class Pincer(BatchScript):
    """SMAC-HARD ``s_corridor/script_y.py`` as it runs.

    - Groups, once on the first step: zerglings with x > 28.25, or x > 27.5 and y < 27.8, are group 0, the rest
      group 1 (SMAC-HARD's cut-offs through the blue spawn at (27.91, 28.24)).
    - Before step 13, while no enemy stands east of group 0's centre and north of group 1's, and neither group's
      centre is closer than 6 to an enemy (once either fails, for good), group 0 moves to (15, 22) and group 1 to
      (22, 15).
    - Otherwise each zergling attacks the enemy with the lowest health (hull) among its 2 nearest (among all of
      them, first in index order on a tie, while 2 or fewer are alive).

    Deliberate differences: red plays the reflected cut-offs and waypoints, moved onto pathable ground. Earlier
    releases split the swarm in halves across the advance, stopped on any zergling within 6 of an enemy and
    compared health + shield.
    """

    name = "pincer"
    description = ("two groups swing out via (15, 22) and (22, 15) until contact, then each attacks the "
                   "lower-health of its 2 nearest enemies (SMAC-HARD s_corridor/script_y)")
    waypoints = np.array([(15.0, 22.0), (22.0, 15.0)])
    flank_steps = 13
    contact_distance = 6.0

    def __init__(self) -> None:
        self.memory = Memory(group=(("own",), np.int64, -1), grouped=((), bool, False), start=((), bool, True))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, alive = frame.rows, frame.own_alive
        hx, hy = frame.own_hx, frame.own_hy
        fresh = ~self.memory.grouped[rows] & alive.any(axis=1)
        if fresh.any():
            first = (hx > 28.25) | ((hx > 27.5) & (hy < 27.8))
            group = np.where(alive, np.where(first, 0, 1), -1)
            self.memory.group[rows[fresh]] = group[fresh]
            self.memory.grouped[rows[fresh]] = True
        members = _members(self.memory.group[rows], alive, 2)
        gx, gy = _group_centres(frame, members)

        e_alive, ex, ey = frame.enemy_alive, frame.enemy_hx, frame.enemy_hy
        past = (e_alive & (ex > gx[:, 0:1]) & (ey > gy[:, 1:2])).any(axis=1)
        to_enemy = np.hypot(ex[:, None, :] - gx[:, :, None], ey[:, None, :] - gy[:, :, None])  # (R, 2, m)
        close = (np.where(e_alive[:, None, :], to_enemy, np.inf).min(axis=2) < self.contact_distance).any(axis=1)
        checked = (frame.step < self.flank_steps) & self.memory.start[rows]
        flanking = checked & ~past & ~close & _live(frame)
        self.memory.start[rows] &= ~(checked & (past | close))

        for g in range(2):
            orders.move(members[:, g] & flanking[:, None], *from_blue_frame(frame, *self.waypoints[g]))
        target = weakest_of_nearest(frame.dist, frame.enemy_health, frame.targetable, k=2)
        orders.attack(alive & ~flanking[:, None], target)


# so_many_baneling: SMAC-HARD's group points (the first 6 also seed the groups of 5).
_BANE_POINTS = np.array([(19, 27), (23, 23), (27, 19), (23, 31), (27, 27), (31, 23), (31, 31)], dtype=np.float64)
BANELING_HIT = 35.0  # what SMAC-HARD counts per baneling against a zealot's health + shield


class PairBombing(BatchScript):
    """SMAC-HARD ``s_so_many_baneling/script.py`` as it runs.

    - Groups, once on the first step: for each of the first 6 points, the 5 banelings nearest it (of those left);
      group 6 is the rest. Members are listed in SMAC-HARD's order (descending index, group 6 ascending; members
      that join later at the end).
    - Steps 0-4: group g moves to point g: (19, 27), (23, 23), (27, 19), (23, 31), (27, 27), (31, 23), (31, 31).
    - Then, every step: pairs of enemies closer than 2 to each other are matched greedily (closest pair first);
      each pair in turn takes the group whose centre is nearest the pair's centre (a group takes at most one).
      Along the group's list, a member within 2 of both enemies attacks the pair's first enemy and counts 35
      against both; the others move to the pair's centre; once both enemies' health + shield minus the count is
      below 0, the remaining members leave for another group (one with 1-4 members, nearest centre, else an empty
      one, nearest sweep point) and get no order this step.
    - Groups without a pair sweep: point g minus (d, d), d = (step - 5) // 2; until the final phase, when
      19 - d is at most the smallest coordinate of any enemy (or below 2): then each enemy without a pair, in
      index order, takes the nearest remaining group, bombed the same way (members within 2 attack, the others move
      to it); groups left over get no order.

    Deliberate differences: red plays the reflected points, moved onto pathable ground. When a surplus member finds
    no group to join SMAC-HARD raises an UnboundLocalError; here it stays in its group. Earlier releases sized
    the bombing from the healthier enemy, made uncommitted groups wait 7 short of the enemy and picked pairs by
    group.
    """

    name = "pair_bombing"
    description = ("seven baneling groups sweep diagonally; the nearest group bombs each pair of enemies standing "
                   "within 2, leftover groups take single enemies at the end (SMAC-HARD s_so_many_baneling)")
    init_steps = 5
    group_size = 5
    pair_distance = 2.0

    def __init__(self) -> None:
        self.memory = Memory(group=(("own",), np.int64, -1), key=(("own",), np.int64, 0), counter=((), np.int64, 0),
                             grouped=((), bool, False))

    def _form_groups(self, frame: Frame, local: np.ndarray) -> None:
        alive, hx, hy = frame.own_alive[local], frame.own_hx[local], frame.own_hy[local]
        n = frame.n_own
        r = np.arange(local.size)[:, None]
        free = alive.copy()
        group = np.full(alive.shape, -1, dtype=np.int64)
        for g, (px, py) in enumerate(_BANE_POINTS[:6]):
            d = np.where(free, np.hypot(hx - px, hy - py), np.inf)
            nearest5 = np.argsort(d, axis=1, kind="stable")[:, :self.group_size]
            ok = np.take_along_axis(d, nearest5, axis=1) < np.inf
            chosen = np.zeros_like(free)
            chosen[np.broadcast_to(r, ok.shape)[ok], nearest5[ok]] = True
            group[chosen] = g
            free &= ~chosen
        group[free] = len(_BANE_POINTS) - 1
        index = np.arange(n)[None, :]
        rows = frame.rows[local]
        self.memory.group[rows] = group
        self.memory.key[rows] = np.where(group < 6, -index, index)
        self.memory.counter[rows] = n
        self.memory.grouped[rows] = True

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, alive = frame.rows, frame.own_alive
        live = _live(frame)
        fresh = ~self.memory.grouped[rows] & alive.any(axis=1)
        if fresh.any():
            self._form_groups(frame, np.flatnonzero(fresh))
        n_groups = len(_BANE_POINTS)
        members = _members(self.memory.group[rows], alive, n_groups) & live[:, None, None]
        gx, gy = _group_centres(frame, members)
        step = frame.step
        forming = step < self.init_steps
        if forming.any():
            for g in range(n_groups):
                orders.move(members[:, g] & forming[:, None], *from_blue_frame(frame, *_BANE_POINTS[g]))
        acting = live & ~forming
        if not acting.any():
            return

        m = frame.n_enemy
        R = frame.size
        r = np.arange(R)
        e_alive, ex, ey = frame.enemy_alive, frame.enemy_hx, frame.enemy_hy
        sweep = (step - self.init_steps) // 2
        lowest_enemy = np.where(e_alive, np.minimum(ex, ey), np.inf).min(axis=1)
        final = ((19 - sweep) <= lowest_enemy) | ((19 - sweep) < 2)
        counts = members.sum(axis=2)  # live group sizes, updated as members change group

        # Pairs, closest first.
        d = np.hypot(ex[:, :, None] - ex[:, None, :], ey[:, :, None] - ey[:, None, :])
        d = np.where(e_alive[:, :, None] & e_alive[:, None, :] & ~np.eye(m, dtype=bool)[None], d, _FAR)
        pairs = []
        for _ in range(m // 2):
            flat = d.reshape(R, -1).argmin(axis=1)
            a, b = flat // m, flat % m
            ok = acting & (d[r, a, b] < self.pair_distance)
            for k in (a[ok], b[ok]):
                d[ok, k, :] = _FAR
                d[ok, :, k] = _FAR
            pairs.append((np.where(ok, a, -1), np.where(ok, b, -1)))
        paired = np.zeros_like(e_alive)
        for a, b in pairs:
            paired[r[a >= 0], a[a >= 0]] = True
            paired[r[b >= 0], b[b >= 0]] = True

        # Each pair takes the nearest group not yet taken (SMAC-HARD marks a taken group's centre 1000 away).
        cx, cy = gx.copy(), gy.copy()
        open_rows = acting.copy()
        taken = np.zeros((R, n_groups), dtype=bool)
        for a, b in pairs:
            px = (_take(ex, a[:, None])[:, 0] + _take(ex, b[:, None])[:, 0]) / 2
            py = (_take(ey, a[:, None])[:, 0] + _take(ey, b[:, None])[:, 0]) / 2
            to_group = np.hypot(cx - px[:, None], cy - py[:, None])
            has = a >= 0
            open_rows &= ~(has & (to_group.min(axis=1) > 100.0))  # SMAC-HARD breaks out of its loop here
            take = has & open_rows
            g = np.argmin(to_group, axis=1)
            cx[take, g[take]] = _FAR
            cy[take, g[take]] = _FAR
            taken[take, g[take]] = True
            group_units = members[r, g] & take[:, None]
            hp = np.maximum(_take(frame.enemy_hp, a[:, None])[:, 0], _take(frame.enemy_hp, b[:, None])[:, 0])
            both_close = np.maximum(_take_dist(frame, a), _take_dist(frame, b)) < self.pair_distance
            self._bomb(frame, orders, group_units, hp, both_close, a, (px, py), step, counts, (cx, cy))

        if final.any():
            rest = members.any(axis=2) & ~taken & (acting & final)[:, None]
            for e in range(m):
                wants = e_alive[:, e] & ~paired[:, e] & rest.any(axis=1)
                if not wants.any():
                    continue
                to_group = np.where(rest, np.hypot(gx - ex[:, e:e + 1], gy - ey[:, e:e + 1]), np.inf)
                g = np.argmin(to_group, axis=1)
                rest[wants, g[wants]] = False
                group_units = members[r, g] & wants[:, None]
                target = np.full(R, e)
                close = frame.dist[:, :, e] < self.pair_distance
                self._bomb(frame, orders, group_units, frame.enemy_hp[:, e], close, target,
                           (frame.enemy_x[:, e], frame.enemy_y[:, e]), step, counts, (cx, cy), blue_frame=False)
        sweeping = acting & ~final
        if sweeping.any():
            for g in range(n_groups):
                units = members[:, g] & (sweeping & ~taken[:, g])[:, None]
                px, py = from_blue_frame(frame, _BANE_POINTS[g, 0] - sweep, _BANE_POINTS[g, 1] - sweep)
                orders.move(units, px[:, None], py[:, None])

    def _bomb(self, frame: Frame, orders: Orders, units: np.ndarray, hp: np.ndarray, close: np.ndarray,
              target: np.ndarray, point: tuple[np.ndarray, np.ndarray], step: np.ndarray, counts: np.ndarray,
              centres: tuple[np.ndarray, np.ndarray], blue_frame: bool = True) -> None:
        """Along each group's list: members ``close`` attack ``target`` and count 35 each; the rest move to
        ``point``; members after the count exceeds ``hp`` leave the group (see :meth:`_leave`)."""
        if not units.any():
            return
        key = self.memory.key[frame.rows]
        ahead = units[:, None, :] & (key[:, None, :] < key[:, :, None])  # (R, i, j): j is listed before i
        bombs_before = (ahead & close[:, None, :]).sum(axis=2)
        surplus = units & (hp[:, None] - BANELING_HIT * bombs_before < 0)
        stay = units & ~surplus
        orders.attack(stay & close, np.broadcast_to(target[:, None], units.shape))
        px, py = from_blue_frame(frame, *point) if blue_frame else point
        orders.move(stay & ~close, np.asarray(px)[:, None], np.asarray(py)[:, None])
        if surplus.any():
            self._leave(frame, surplus, step, counts, centres)

    def _leave(self, frame: Frame, surplus: np.ndarray, step: np.ndarray, counts: np.ndarray,
               centres: tuple[np.ndarray, np.ndarray]) -> None:
        """SMAC-HARD's ``add_to_group``, one surplus member at a time in list order (rare: a loop is fine)."""
        group, key, counter = self.memory.group, self.memory.key, self.memory.counter
        for local in np.flatnonzero(surplus.any(axis=1)):
            row = frame.rows[local]
            units = np.flatnonzero(surplus[local])
            for unit in units[np.argsort(key[row, units], kind="stable")]:
                g = group[row, unit]
                others = np.arange(len(_BANE_POINTS)) != g
                fewer = others & (counts[local] > 0) & (counts[local] < self.group_size)
                empty = others & (counts[local] == 0)
                ux, uy = frame.own_hx[local, unit], frame.own_hy[local, unit]
                if fewer.any():
                    d = np.where(fewer, np.hypot(centres[0][local] - ux, centres[1][local] - uy), np.inf)
                elif empty.any():
                    sweep = (step[local] - self.init_steps) // 2
                    d = np.where(empty, np.hypot(_BANE_POINTS[:, 0] - sweep - ux, _BANE_POINTS[:, 1] - sweep - uy),
                                 np.inf)
                else:
                    continue  # SMAC-HARD raises here (no group to join); the member stays
                new = int(np.argmin(d))
                group[row, unit] = new
                key[row, unit] = counter[row]
                counter[row] += 1
                counts[local, g] -= 1
                counts[local, new] += 1


def _take_dist(frame: Frame, enemy: np.ndarray) -> np.ndarray:
    """(R, n) centre distance of each own unit to enemy ``enemy`` (R,) (clipped at 0)."""
    return np.take_along_axis(frame.dist, np.maximum(enemy, 0)[:, None, None], axis=2)[:, :, 0]


class BaneCluster(BatchScript):
    """SMAC-HARD ``s_bane_vs_bane/script.py`` as it runs.

    - Every baneling attacks one enemy: the enemy zergling with the most enemy zerglings within 2 (itself
      included), the first on a tie; with no enemy zergling left, the enemy with the most enemies within 2.
    - Steps 0-9: alive zergling k of n (index order) moves to (16 + 10 cos(pi k/n), 21 + 10 sin(pi k/n)): a half
      circle of radius 10 round (16, 21), on its north side (away from the enemy).
    - Then every zergling attacks its nearest enemy.

    SMAC-HARD lists the enemy banelings before the enemy zerglings: ties go to the first in that list. Deliberate
    differences: red plays the reflected half circle, moved onto pathable ground. Earlier releases fanned out toward
    the enemy and picked each baneling's target nearest first.
    """

    name = "bane_cluster"
    description = ("banelings hit the densest zergling cluster; zerglings fan out on a half circle round (16, 21) "
                   "for 10 steps, then attack nearest (SMAC-HARD s_bane_vs_bane)")
    fan_steps = 10
    fan_radius = 10.0
    fan_centre = (16.0, 21.0)
    cluster_radius = 2.0

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive = frame.own_alive & _live(frame)[:, None]
        bane = of_kind(frame.own_type, "baneling") & alive
        ling = of_kind(frame.own_type, "zergling") & alive
        e_alive = frame.enemy_alive
        e_ling = of_kind(frame.enemy_type, "zergling") & e_alive
        m = frame.n_enemy
        listed = np.where(of_kind(frame.enemy_type, "baneling"), 0, m) + np.arange(m)  # SMAC-HARD's list order
        listed = np.broadcast_to(listed, e_alive.shape).astype(np.float64)

        ex, ey = frame.enemy_x, frame.enemy_y
        close = np.hypot(ex[:, :, None] - ex[:, None, :], ey[:, :, None] - ey[:, None, :]) <= self.cluster_radius
        ling_crowd = (close & e_ling[:, None, :]).sum(axis=2).astype(np.float64)
        crowd = (close & e_alive[:, None, :]).sum(axis=2).astype(np.float64)
        pick = np.where(e_ling.any(axis=1), lowest(-ling_crowd, e_ling, tie=listed),
                        lowest(-crowd, e_alive, tie=listed))
        orders.attack(bane, np.broadcast_to(pick[:, None], alive.shape))

        fanning = frame.step < self.fan_steps
        if fanning.any():
            k = list_rank(ling)
            n = np.maximum(ling.sum(axis=1, keepdims=True), 1)
            angle = np.pi / n * k
            px = self.fan_centre[0] + self.fan_radius * np.cos(angle)
            py = self.fan_centre[1] + self.fan_radius * np.sin(angle)
            orders.move(ling & fanning[:, None], *from_blue_frame(frame, px, py))
        near = lowest(frame.dist, frame.targetable, tie=np.broadcast_to(listed[:, None, :], frame.dist.shape))
        orders.attack(ling & ~fanning[:, None], near)


# 2c_vs_64zg: SMAC-HARD's points per group (up_left, up_right, down_left, down_right): staging, then waiting.
_CLIFF_POINTS = np.array([
    [(3.5, 14.0), (2.0, 16.5)],
    [(26.5, 14.0), (28.0, 16.5)],
    [(3.5, 6.0), (2.5, 10.0)],
    [(26.5, 6.0), (27.5, 10.0)],
])
_UP_LEFT, _UP_RIGHT, _DOWN_LEFT, _DOWN_RIGHT = range(4)


class CliffGroups(BatchScript):
    """SMAC-HARD ``s_2c_vs_64zg/script.py`` as it runs.

    - Groups, once on the first step, by SMAC-HARD's cut-offs round the blue spawn (16, 9): up_left if x < 15.6 and
      y > 7.9, or x < 16.3 and y > 10.1; else up_right if x > 16.3 and y > 7.9, or y > 8.6; else down_right if
      x > 15.6 and y < 7.2, or x > 16.3; else down_left.
    - Every step, first on the left then (only if the left did not change) on the right: when the up group has
      more than twice the down group plus 2, its (up - 2 down - 1) // 2 lowest (smallest y) members join the down
      group; when it has fewer than twice the down group minus 2, the (2 down - 1 - up) // 2 lowest of the down
      group join the up group.
    - Steps 0-9: up_left moves to (3.5, 14), up_right (26.5, 14), down_left (3.5, 6), down_right (26.5, 6).
    - Then the up groups attack the colossus with y > 11.9 nearest their centre, the down groups the one with
      y < 12.1; a group with no such colossus moves to its waiting point: (2, 16.5), (28, 16.5), (2.5, 10),
      (27.5, 10).

    Deliberate differences: red plays the reflected cut-offs and points, moved onto pathable ground. Earlier
    releases split the swarm by x rank into alternating groups, staged at the ramps and judged levels by the map's
    cliff heights.
    """

    name = "cliff_groups"
    description = ("four groups (up and down, left and right) stage for 10 steps, then attack the colossus on "
                   "their side of y=12 or wait (SMAC-HARD s_2c_vs_64zg)")
    stage_steps = 10
    cliff_y = 12.0

    def __init__(self) -> None:
        self.memory = Memory(group=(("own",), np.int64, -1), key=(("own",), np.int64, 0), counter=((), np.int64, 0),
                             grouped=((), bool, False))

    def plan(self, frame: Frame, orders: Orders) -> None:
        rows, alive = frame.rows, frame.own_alive
        x, y = frame.own_hx, frame.own_hy
        fresh = ~self.memory.grouped[rows] & alive.any(axis=1)
        if fresh.any():
            up_left = ((x < 15.6) & (y > 7.9)) | ((x < 16.3) & (y > 10.1))
            up_right = ((x > 16.3) & (y > 7.9)) | (y > 8.6)
            down_right = ((x > 15.6) & (y < 7.2)) | (x > 16.3)
            group = np.select([up_left, up_right, down_right], [_UP_LEFT, _UP_RIGHT, _DOWN_RIGHT], _DOWN_LEFT)
            group = np.where(alive, group, -1)
            local = np.flatnonzero(fresh)
            self.memory.group[rows[local]] = group[local]
            self.memory.key[rows[local]] = np.arange(frame.n_own)
            self.memory.counter[rows[local]] = frame.n_own
            self.memory.grouped[rows[local]] = True

        changed = self._rebalance(frame, _UP_LEFT, _DOWN_LEFT, np.ones(frame.size, dtype=bool))
        self._rebalance(frame, _UP_RIGHT, _DOWN_RIGHT, ~changed)
        members = _members(self.memory.group[rows], alive, 4) & frame.enemy_alive.any(axis=1)[:, None, None]
        staging = frame.step < self.stage_steps
        fighting = ~staging
        gx, gy = _group_centres(frame, members)
        e_alive, ex, ey = frame.enemy_alive, frame.enemy_hx, frame.enemy_hy
        levels = {True: e_alive & (ey > self.cliff_y - 0.1), False: e_alive & (ey < self.cliff_y + 0.1)}
        for g in range(4):
            units = members[:, g]
            orders.move(units & staging[:, None], *from_blue_frame(frame, *_CLIFF_POINTS[g, 0]))
            on_level = levels[g in (_UP_LEFT, _UP_RIGHT)]
            target = argmin_masked(np.hypot(ex - gx[:, g:g + 1], ey - gy[:, g:g + 1]), on_level)
            orders.attack(units & (fighting & (target >= 0))[:, None], np.broadcast_to(target[:, None], units.shape))
            orders.move(units & (fighting & (target < 0))[:, None], *from_blue_frame(frame, *_CLIFF_POINTS[g, 1]))

    def _rebalance(self, frame: Frame, up: int, down: int, rows_ok: np.ndarray) -> np.ndarray:
        """SMAC-HARD's ``switch_group`` for one side on rows ``rows_ok``; returns (R,) where it moved units."""
        rows = frame.rows
        group = self.memory.group[rows]
        key = self.memory.key[rows]
        alive = frame.own_alive
        in_up, in_down = alive & (group == up), alive & (group == down)
        n_up, n_down = in_up.sum(axis=1), in_down.sum(axis=1)
        to_down = rows_ok & (n_up > 2 * n_down + 2)
        to_up = rows_ok & ~to_down & (n_up < 2 * n_down - 2)
        count = np.where(to_down, (n_up - 2 * n_down - 1) // 2, np.where(to_up, (2 * n_down - 1 - n_up) // 2, 0))
        source = np.where(to_down[:, None], in_up, in_down) & (to_down | to_up)[:, None]
        moving = _lowest_first(source, frame.own_hy, key, count)
        if moving.any():
            # Joiners are appended to the other group's list in the order SMAC-HARD sorted them (lowest y first).
            order = np.lexsort((key, np.where(moving, frame.own_hy, np.inf)), axis=-1)
            rank = np.argsort(order, axis=-1, kind="stable")
            counter = self.memory.counter[rows]
            self.memory.key[rows] = np.where(moving, counter[:, None] + rank, key)
            self.memory.counter[rows] = counter + moving.sum(axis=1)
            self.memory.group[rows] = np.where(moving, np.where(to_down, down, up)[:, None], group)
        return to_down | to_up


class SpineWeaker(BatchScript):
    """SMAC-HARD ``s_2s_vs_1sc/script.py`` as it runs: with two or more stalkers alive, the spine crawler attacks the
    one with the lowest health (hull) among those closer than 8.7 (centres), the nearest on a tie; no order when
    none is that close, and none at all once a single stalker is left (SMAC-HARD picks it but never appends the
    order), so the crawler then only acquires targets by itself.

    Deliberate difference: every own unit plays the crawler's rule (SMAC-HARD orders only its first crawler; the
    map has one). Earlier releases used ``weakest`` here: health + shield, the crawler's weapon reach (8.75) and an
    order for the last stalker too.
    """

    name = "spine_weaker"
    description = ("the spine crawler attacks the lower-health stalker within 8.7 while two are alive "
                   "(SMAC-HARD s_2s_vs_1sc)")
    reach = 8.7

    def plan(self, frame: Frame, orders: Orders) -> None:
        several = frame.enemy_alive.sum(axis=1) >= 2
        close = frame.hittable & (frame.dist < self.reach)
        health = np.broadcast_to(frame.enemy_health[:, None, :], frame.dist.shape)
        orders.attack(frame.own_alive & several[:, None], lowest(health, close, tie=frame.dist))
