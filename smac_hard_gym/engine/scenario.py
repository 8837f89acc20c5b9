"""Initial unit layout of a map: which unit sits in which slot, and where it spawns.

SC2's ``CreateUnitsWithDefaultFacing`` puts the first unit of a group exactly on the spawn point and each further one
at the nearest free placement around it. The exact placements come from the game's placement search and are stored
nowhere (docs/smac_interface.md §9), so we pack each group tightly: candidates on rings around the point, nearest
first,
taking the first one whose circle overlaps no placed unit of the same plane and whose centre is on a walkable cell.
The layout is the same every episode.

Red slots follow SMAC's agent order: units sorted by (SC2 type id, x, y), where SMAC's custom ``*_RL`` ids are
numbered in alphabetical order of their names. Blue slots follow creation order, as SMAC's enemy indices do.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from smac_hard_gym.engine.state import BLUE, RED
from smac_hard_gym.engine.units import UNITS, unit_index
from smac_hard_gym.maps import MapSpec

_GAP = 0.05  # space left between packed units


class Layout(NamedTuple):
    """Per-slot initial values (arrays of length U)."""

    utype: np.ndarray  # int32
    side: np.ndarray  # int8
    x: np.ndarray
    y: np.ndarray
    health: np.ndarray
    shield: np.ndarray
    energy: np.ndarray
    n_red: int
    n_blue: int


def _walkable(spec: MapSpec, x: float, y: float, radius: float, is_air: bool) -> bool:
    mx, my = spec.size
    if not (radius <= x <= mx - radius and radius <= y <= my - radius):
        return False
    return is_air or bool(spec.pathable[int(x), int(y)])


def _place(spec: MapSpec, point: tuple[float, float], radius: float, is_air: bool,
           placed: list[tuple[float, float, float, bool]], mirror: bool) -> tuple[float, float]:
    px, py = point
    flip = -1.0 if mirror else 1.0  # blue packs as red's mirror image, so neither side starts a step ahead
    # Candidate rings every half radius; on each ring, angles spaced about one radius apart.
    for ring in range(0, 80):
        dist = ring * radius * 0.5
        n_angles = 1 if ring == 0 else max(6, int(2 * math.pi * dist / radius))
        for k in range(n_angles):
            angle = 2 * math.pi * k / n_angles + (0.5 * math.pi)
            x, y = px + flip * dist * math.cos(angle), py + dist * math.sin(angle)
            if not _walkable(spec, x, y, radius, is_air):
                continue
            if all(air != is_air or math.hypot(x - ox, y - oy) >= radius + orad + _GAP
                   for ox, oy, orad, air in placed):
                return round(x, 6), round(y, 6)
    raise ValueError(f"map {spec.name!r}: no free spawn placement near {point}")


def _alphabetical_rank(names: list[str]) -> dict[str, int]:
    return {name: rank for rank, name in enumerate(sorted(set(names)))}


def build_layout(spec: MapSpec) -> Layout:
    """Slots, types and spawn positions for a map."""
    placed: list[tuple[float, float, float, bool]] = []
    units: list[tuple[int, int, float, float]] = []  # (side, type, x, y)
    for side, groups in ((RED, spec.red), (BLUE, spec.blue)):
        for group in groups:
            t = unit_index(group.unit)
            u = UNITS[t]
            for _ in range(group.count):
                x, y = _place(spec, group.spawn, u.radius, u.is_air, placed, mirror=side == BLUE)
                placed.append((x, y, u.radius, u.is_air))
                units.append((side, t, x, y))
    red = [u for u in units if u[0] == RED]
    blue = [u for u in units if u[0] == BLUE]
    rank = _alphabetical_rank([UNITS[t].sc2_name for _, t, _, _ in red])
    red.sort(key=lambda u: (rank[UNITS[u[1]].sc2_name], u[2], u[3]))
    ordered = red + blue
    utype = np.array([u[1] for u in ordered], dtype=np.int32)
    return Layout(
        utype=utype,
        side=np.array([u[0] for u in ordered], dtype=np.int8),
        x=np.array([u[2] for u in ordered], dtype=np.float64),
        y=np.array([u[3] for u in ordered], dtype=np.float64),
        health=np.array([UNITS[t].health for t in utype], dtype=np.float64),
        shield=np.array([UNITS[t].shield for t in utype], dtype=np.float64),
        energy=np.array([UNITS[t].energy_start for t in utype], dtype=np.float64),
        n_red=len(red),
        n_blue=len(blue),
    )
