"""Terrain tables the movement kernels read: walkable grids, path next-hops and cell line-of-sight.

Three mover classes share one map: ground units walk the pathing grid; cliff walkers (colossus) also cross the
unpathable cliff bands that separate two pathable levels; air units (medivac) ignore terrain inside the map bounds.

For each walking class we precompute, once per map and process:

- ``next_hop[goal_cell, cell]``: the first cell on a shortest 8-connected path from ``cell`` to ``goal_cell``
  (-1 if unreachable). Diagonal steps are allowed whenever the diagonal cell is walkable, so units squeeze through
  cells that touch only at a corner (corridor's neck), as SC2's finer footprint pathing lets them.
- ``los[cell_a, cell_b]``: whether the straight segment between the two cell centres stays on walkable cells, so a
  unit can head straight for a visible waypoint and path smoothing skips needless zig-zags.

Cells are numbered ``x * map_y + y``.
"""

from __future__ import annotations

import heapq
from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numba import njit

from smac_hard_gym.maps import MapSpec

MOVER_GROUND, MOVER_CLIFF, MOVER_AIR = 0, 1, 2

_LOS_SAMPLE = 0.2  # world units between line-of-sight samples
# A cell's 8 neighbours as (dx, dy, step length), in the order the path tables scan them: the order breaks ties
# between equally short paths, so it is part of the tables' contents.
_NEIGHBOURS = tuple((dx, dy, 1.4142135623730951 if dx != 0 and dy != 0 else 1.0)
                    for dx in (-1, 0, 1) for dy in (-1, 0, 1) if dx != 0 or dy != 0)


class Terrain(NamedTuple):
    """Per-map terrain arrays shared by every battle of a batch."""

    walk: np.ndarray  # uint8 (2, map_x, map_y): walkable for [ground, cliff walker]
    next_hop: np.ndarray  # int16 (2, cells, cells): next cell toward goal, indexed [mover, goal, cell]
    los: np.ndarray  # uint8 (2, cells, cells)
    height: np.ndarray  # float64 (map_x, map_y): world height z of each cell
    open_field: np.ndarray  # uint8 (2,): every walkable cell sees every other (no path lookups needed)
    map_x: int
    map_y: int


def cliff_walk_grid(pathable: np.ndarray, cliff: np.ndarray, reach: int = 2) -> np.ndarray:
    """Cells a cliff walker may stand on: pathable cells plus unpathable cells inside a cliff band.

    A cell belongs to a cliff band when, along x or along y, pathable cells lie within ``reach`` cells on both sides
    and those two sides are at different cliff levels or the band is at most ``reach`` cells wide (a colossus steps
    over a 2-cell cliff between the low and high ground of 2c_vs_64zg, but not off the edge of the playable strip).
    """
    mx, my = pathable.shape
    out = pathable.copy()
    for x in range(mx):
        for y in range(my):
            if pathable[x, y]:
                continue
            for dx, dy in ((1, 0), (0, 1)):
                lo = hi = None
                for k in range(1, reach + 1):
                    ax, ay = x - dx * k, y - dy * k
                    if lo is None and 0 <= ax < mx and 0 <= ay < my and pathable[ax, ay]:
                        lo = (ax, ay)
                    bx, by = x + dx * k, y + dy * k
                    if hi is None and 0 <= bx < mx and 0 <= by < my and pathable[bx, by]:
                        hi = (bx, by)
                if lo is not None and hi is not None:
                    out[x, y] = True
                    break
    return out


@njit(cache=True)
def _walkable(walk: np.ndarray, x: int, y: int) -> int:
    """Cell number of (x, y) if it is on the map and walkable, else -1."""
    mx, my = walk.shape
    if 0 <= x < mx and 0 <= y < my and walk[x, y]:
        return x * my + y
    return -1


@njit(cache=True)
def _distance_field(walk: np.ndarray, goal: int) -> np.ndarray:
    """Octile shortest-path distance from every cell to ``goal`` (Dijkstra, 8-connected)."""
    mx, my = walk.shape
    dist = np.full(mx * my, np.inf)
    dist[goal] = 0.0
    heap = [(0.0, goal)]
    while len(heap) > 0:
        d, c = heapq.heappop(heap)
        if d > dist[c]:
            continue
        cx, cy = c // my, c % my
        for dx, dy, step in _NEIGHBOURS:
            nc = _walkable(walk, cx + dx, cy + dy)
            nd = d + step
            if nc >= 0 and nd < dist[nc]:
                dist[nc] = nd
                heapq.heappush(heap, (nd, nc))
    return dist


@njit(cache=True)
def _next_hops_from_fields(walk: np.ndarray, dist: np.ndarray, goal: int, out: np.ndarray) -> None:
    """``out[cell]`` = the neighbour of ``cell`` that is nearest to ``goal`` along the distance field."""
    mx, my = walk.shape
    for cx in range(mx):
        for cy in range(my):
            c = cx * my + cy
            if not walk[cx, cy] or not np.isfinite(dist[c]):
                out[c] = -1
                continue
            if c == goal:
                out[c] = c
                continue
            best = -1
            best_d = np.inf
            for dx, dy, step in _NEIGHBOURS:
                nc = _walkable(walk, cx + dx, cy + dy)
                if nc < 0:
                    continue
                d = dist[nc] + step
                if d < best_d - 1e-9:
                    best_d = d
                    best = nc
            out[c] = best


@njit(cache=True)
def _line_of_sight(walk: np.ndarray, out: np.ndarray, sample: float) -> None:
    """``out[a, b]`` = 1 if every sample of the segment between the centres of cells a and b is walkable."""
    mx, my = walk.shape
    n = mx * my
    for a in range(n):
        ax, ay = a // my, a % my
        if not walk[ax, ay]:
            continue
        out[a, a] = 1
        for b in range(a + 1, n):
            bx, by = b // my, b % my
            if not walk[bx, by]:
                continue
            x0, y0 = ax + 0.5, ay + 0.5
            dx, dy = bx - ax, by - ay
            length = np.sqrt(dx * dx + dy * dy)
            steps = int(length / sample) + 1
            ok = 1
            for k in range(1, steps):
                t = k / steps
                cx = int(x0 + dx * t)
                cy = int(y0 + dy * t)
                if not walk[cx, cy]:
                    ok = 0
                    break
            out[a, b] = ok
            out[b, a] = ok


def _tables(walk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mx, my = walk.shape
    n = mx * my
    next_hop = np.full((n, n), -1, dtype=np.int16)
    flat = walk.ravel()
    for goal in range(n):
        if flat[goal]:
            dist = _distance_field(walk, goal)
            _next_hops_from_fields(walk, dist, goal, next_hop[goal])
    los = np.zeros((n, n), dtype=np.uint8)
    _line_of_sight(walk, los, _LOS_SAMPLE)
    return next_hop, los


def cliff_height(cliff: np.ndarray) -> np.ndarray:
    """World height z per cell: cliff level 1 is z=8 and each level adds 2 (docs/smac_interface.md §9)."""
    return 6.0 + 2.0 * cliff


@lru_cache(maxsize=16)
def _build(pathable_bytes: bytes, cliff_bytes: bytes, shape: tuple[int, int], need_cliff: bool) -> Terrain:
    pathable = np.frombuffer(pathable_bytes, dtype=bool).reshape(shape)
    cliff = np.frombuffer(cliff_bytes, dtype=np.float64).reshape(shape)
    ground = pathable.astype(np.uint8)
    climb = cliff_walk_grid(pathable, cliff).astype(np.uint8) if need_cliff else ground
    hop_g, los_g = _tables(ground)
    if need_cliff:
        hop_c, los_c = _tables(climb)
    else:
        hop_c, los_c = hop_g, los_g
    def _open(walk: np.ndarray, los: np.ndarray) -> bool:
        cells = np.flatnonzero(walk.ravel())
        return bool(los[np.ix_(cells, cells)].all())

    return Terrain(
        open_field=np.array([_open(ground, los_g), _open(climb, los_c)], dtype=np.uint8),
        walk=np.ascontiguousarray(np.stack([ground, climb])),
        next_hop=np.ascontiguousarray(np.stack([hop_g, hop_c])),
        los=np.ascontiguousarray(np.stack([los_g, los_c])),
        height=cliff_height(cliff),
        map_x=shape[0],
        map_y=shape[1],
    )


def build_terrain(spec: MapSpec, need_cliff: bool) -> Terrain:
    """Terrain tables for a map (cached per process by grid contents)."""
    pathable = np.ascontiguousarray(spec.pathable, dtype=bool)
    cliff = np.ascontiguousarray(spec.cliff, dtype=np.float64)
    return _build(pathable.tobytes(), cliff.tobytes(), pathable.shape, need_cliff)
