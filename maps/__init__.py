"""Scenario data: one JSON file per map, a validating loader and the registry of known maps.

A map file holds, per side, the units with counts and spawn points; the pathing grid and cliff levels; the episode
limit; races, ``unit_type_bits`` and ``map_type`` (SMAC's feature settings); and the default enemy order. The 23 SMAC
maps ship in ``maps/data``. A user adds a scenario by writing a file in the same format and either passing its path
(``load_map("my_map.json")``), calling :func:`register_map`, or listing its folder in ``SMAC_HARD_GYM_MAP_PATH``
(``os.pathsep``-separated folders). No code change is needed.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from smac_hard_gym.engine.units import UNITS, unit_index

DATA_DIR = Path(__file__).parent / "data"
MAP_PATH_ENV = "SMAC_HARD_GYM_MAP_PATH"

RACES = ("T", "P", "Z")
MAP_TYPES = (
    "marines", "MMM", "stalkers_and_zealots", "colossi_stalkers_zealots", "stalkers", "zealots",
    "hydralisks", "bane", "colossus",
)
ORDER_KINDS = ("attack_move", "attack_move_between", "attack_units", "none")

__all__ = [
    "MapError", "UnitGroup", "EnemyOrder", "MapSpec", "load_map", "load_map_file", "register_map",
    "list_maps", "MAP_TYPES", "DATA_DIR",
]


class MapError(ValueError):
    """A map file is missing, unreadable or has an invalid field (the message names it)."""


@dataclass(frozen=True)
class UnitGroup:
    """``count`` units of one type created around ``spawn`` (like SC2's CreateUnitsWithDefaultFacing)."""

    unit: str  # SC2 unit name, e.g. "Marine_RL"
    count: int
    spawn: tuple[float, float]

    @property
    def type_id(self) -> int:
        return unit_index(self.unit)


@dataclass(frozen=True)
class EnemyOrder:
    """The order the map script gives the opponent at spawn (SMAC's default opponent replays it)."""

    kind: str  # one of ORDER_KINDS
    point: tuple[float, float] | None = None
    points: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class MapSpec:
    """One scenario. ``pathable[x, y]`` and ``cliff[x, y]`` index cells (x, y) covering [x, x+1) x [y, y+1)."""

    name: str
    episode_limit: int
    red_race: str
    blue_race: str
    unit_type_bits: int
    map_type: str
    size: tuple[int, int]
    red: tuple[UnitGroup, ...]
    blue: tuple[UnitGroup, ...]
    enemy_order: EnemyOrder
    pathable: np.ndarray  # bool (map_x, map_y)
    cliff: np.ndarray  # float (map_x, map_y): cliff level, ramps half-way
    source: str = ""

    @property
    def n_red(self) -> int:
        return sum(g.count for g in self.red)

    @property
    def n_blue(self) -> int:
        return sum(g.count for g in self.blue)

    # SMAC's names, from the learner's point of view.
    n_agents = n_red
    n_enemies = n_blue

    @property
    def red_unit_names(self) -> list[str]:
        return [g.unit for g in self.red for _ in range(g.count)]

    @property
    def blue_unit_names(self) -> list[str]:
        return [g.unit for g in self.blue for _ in range(g.count)]

    def describe(self) -> str:
        """One line: units per side and limits."""

        def side(groups: tuple[UnitGroup, ...]) -> str:
            counts: dict[str, int] = {}
            for g in groups:
                counts[g.unit] = counts.get(g.unit, 0) + g.count
            return " + ".join(f"{n} {u}" for u, n in counts.items())

        return (f"{self.name:<18} {self.n_red:>2} vs {self.n_blue:<2} limit {self.episode_limit:<4} "
                f"{self.red_race}v{self.blue_race}  {side(self.red)}  vs  {side(self.blue)}")


# ---------------------------------------------------------------------------------------------------------------
# Validation: each _check_* names the file and the bad field.


def _fail(source: str, field: str, problem: str) -> MapError:
    return MapError(f"{source}: field {field!r} {problem}")


def _require(doc: dict, key: str, kind: type | tuple, source: str, where: str = "") -> Any:
    field = f"{where}{key}"
    if key not in doc:
        raise _fail(source, field, "is missing")
    value = doc[key]
    if isinstance(value, bool) and kind is not bool:
        raise _fail(source, field, f"must be {_kind_name(kind)}, got {value!r}")
    if not isinstance(value, kind):
        raise _fail(source, field, f"must be {_kind_name(kind)}, got {value!r}")
    return value


def _kind_name(kind: type | tuple) -> str:
    if isinstance(kind, tuple):
        return " or ".join(k.__name__ for k in kind)
    return kind.__name__


def _point(value: Any, source: str, field: str, size: tuple[int, int]) -> tuple[float, float]:
    ok = isinstance(value, (list, tuple)) and len(value) == 2 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
    if not ok:
        raise _fail(source, field, f"must be a point [x, y], got {value!r}")
    x, y = float(value[0]), float(value[1])
    if not (0 <= x <= size[0] and 0 <= y <= size[1]):
        raise _fail(source, field, f"point {value!r} lies outside the map (0..{size[0]}, 0..{size[1]})")
    return x, y


def _check_groups(doc: dict, side: str, source: str, size: tuple[int, int]) -> tuple[UnitGroup, ...]:
    groups = _require(doc, side, list, source, "units.")
    if not groups:
        raise _fail(source, f"units.{side}", "must list at least one unit group")
    out = []
    for i, g in enumerate(groups):
        where = f"units.{side}[{i}]."
        if not isinstance(g, dict):
            raise _fail(source, f"units.{side}[{i}]", "must be an object {unit, count, spawn}")
        unit = _require(g, "unit", str, source, where)
        try:
            unit_index(unit)
        except KeyError as err:
            raise _fail(source, where + "unit", str(err.args[0])) from None
        count = _require(g, "count", int, source, where)
        if count < 1:
            raise _fail(source, where + "count", f"must be >= 1, got {count}")
        spawn = _point(_require(g, "spawn", list, source, where), source, where + "spawn", size)
        out.append(UnitGroup(unit, count, spawn))
    return tuple(out)


def _check_grid(rows: Any, field: str, alphabet: str, source: str, size: tuple[int, int]) -> list[str]:
    if not isinstance(rows, list) or len(rows) != size[1]:
        raise _fail(source, field, f"must be a list of {size[1]} row strings (one per y)")
    for y, row in enumerate(rows):
        if not isinstance(row, str) or len(row) != size[0]:
            raise _fail(source, f"{field}[{y}]", f"must be a string of {size[0]} characters")
        bad = set(row) - set(alphabet)
        if bad:
            raise _fail(source, f"{field}[{y}]", f"has characters {sorted(bad)}; allowed: {list(alphabet)}")
    return rows


def _cliff_value(ch: str) -> float:
    return 0.5 if ch == "r" else float(ch)


def parse_map(doc: Any, source: str) -> MapSpec:
    """Validate a decoded map document and build its :class:`MapSpec`."""
    if not isinstance(doc, dict):
        raise MapError(f"{source}: a map file must hold a JSON object")
    name = _require(doc, "name", str, source)
    limit = _require(doc, "episode_limit", int, source)
    if limit < 1:
        raise _fail(source, "episode_limit", f"must be >= 1, got {limit}")
    races = _require(doc, "races", dict, source)
    red_race = _require(races, "red", str, source, "races.")
    blue_race = _require(races, "blue", str, source, "races.")
    for key, race in (("races.red", red_race), ("races.blue", blue_race)):
        if race not in RACES:
            raise _fail(source, key, f"must be one of {RACES}, got {race!r}")
    bits = _require(doc, "unit_type_bits", int, source)
    if bits < 0:
        raise _fail(source, "unit_type_bits", f"must be >= 0, got {bits}")
    map_type = _require(doc, "map_type", str, source)
    if map_type not in MAP_TYPES:
        raise _fail(source, "map_type", f"must be one of {MAP_TYPES}, got {map_type!r}")
    size_v = _require(doc, "size", list, source)
    if len(size_v) != 2 or not all(isinstance(v, int) and v > 0 for v in size_v):
        raise _fail(source, "size", f"must be [map_x, map_y] of positive ints, got {size_v!r}")
    size = (int(size_v[0]), int(size_v[1]))
    units = _require(doc, "units", dict, source)
    red = _check_groups(units, "red", source, size)
    blue = _check_groups(units, "blue", source, size)
    order_doc = _require(doc, "enemy_order", dict, source)
    kind = _require(order_doc, "kind", str, source, "enemy_order.")
    if kind not in ORDER_KINDS:
        raise _fail(source, "enemy_order.kind", f"must be one of {ORDER_KINDS}, got {kind!r}")
    point = None
    points: tuple = ()
    if kind == "attack_move":
        point = _point(_require(order_doc, "point", list, source, "enemy_order."), source,
                       "enemy_order.point", size)
    elif kind == "attack_move_between":
        raw = _require(order_doc, "points", list, source, "enemy_order.")
        if len(raw) != 2:
            raise _fail(source, "enemy_order.points", "must hold exactly two points")
        points = tuple(_point(p, source, f"enemy_order.points[{i}]", size) for i, p in enumerate(raw))
    terrain = _require(doc, "terrain", dict, source)
    path_rows = _check_grid(terrain.get("pathable"), "terrain.pathable", ".#", source, size)
    cliff_rows = _check_grid(terrain.get("cliff"), "terrain.cliff", "0123456789r", source, size)
    # Rows are y (row 0 = bottom); arrays are indexed [x, y] like SMAC's pathing_grid.
    pathable = np.array([[ch == "." for ch in row] for row in path_rows], dtype=bool).T.copy()
    cliff = np.array([[_cliff_value(ch) for ch in row] for row in cliff_rows], dtype=np.float64).T.copy()
    spec = MapSpec(
        name=name, episode_limit=limit, red_race=red_race, blue_race=blue_race, unit_type_bits=bits,
        map_type=map_type, size=size, red=red, blue=blue, enemy_order=EnemyOrder(kind, point, points),
        pathable=pathable, cliff=cliff, source=str(doc.get("source", "")),
    )
    for side, groups in (("red", red), ("blue", blue)):
        for i, g in enumerate(groups):
            if UNITS[g.type_id].is_air:
                continue
            cx, cy = min(int(g.spawn[0]), size[0] - 1), min(int(g.spawn[1]), size[1] - 1)
            if not pathable[cx, cy]:
                raise _fail(source, f"units.{side}[{i}].spawn", f"{list(g.spawn)} is not on a pathable cell")
    return spec


def load_map_file(path: str | os.PathLike) -> MapSpec:
    """Load and validate one map file."""
    path = Path(path)
    if not path.is_file():
        raise MapError(f"map file {str(path)!r} does not exist")
    try:
        doc = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise MapError(f"{path}: not valid JSON ({err})") from None
    return parse_map(doc, str(path))


# ---------------------------------------------------------------------------------------------------------------
# Registry.

_USER_FILES: dict[str, Path] = {}


def _search_dirs() -> list[Path]:
    extra = [Path(p) for p in os.environ.get(MAP_PATH_ENV, "").split(os.pathsep) if p]
    return [DATA_DIR, *extra]


def _map_files() -> dict[str, Path]:
    files: dict[str, Path] = {}
    for folder in _search_dirs():
        if folder.is_dir():
            for path in sorted(folder.glob("*.json")):
                files[path.stem] = path
    files.update(_USER_FILES)
    return files


def register_map(path: str | os.PathLike) -> MapSpec:
    """Add a map file to the registry under its ``name`` field (validated now)."""
    spec = load_map_file(path)
    _USER_FILES[spec.name] = Path(path)
    _cached_load.cache_clear()
    return spec


def list_maps() -> list[str]:
    """Names of every known map: the 23 SMAC maps plus user maps."""
    return sorted(_map_files(), key=_smac_order)


_SMAC_ORDER = (
    "3m", "8m", "25m", "5m_vs_6m", "8m_vs_9m", "10m_vs_11m", "27m_vs_30m", "MMM", "MMM2", "2s3z", "3s5z",
    "3s5z_vs_3s6z", "3s_vs_3z", "3s_vs_4z", "3s_vs_5z", "1c3s5z", "2m_vs_1z", "corridor", "6h_vs_8z",
    "2s_vs_1sc", "so_many_baneling", "bane_vs_bane", "2c_vs_64zg",
)
SMAC_MAPS: tuple[str, ...] = _SMAC_ORDER


def _smac_order(name: str) -> tuple[int, str]:
    return (_SMAC_ORDER.index(name) if name in _SMAC_ORDER else len(_SMAC_ORDER), name)


@lru_cache(maxsize=64)
def _cached_load(path: str) -> MapSpec:
    return load_map_file(path)


def load_map(name_or_path: str | os.PathLike) -> MapSpec:
    """A map by registry name ("3m") or by path to a map file."""
    if isinstance(name_or_path, MapSpec):
        return name_or_path
    key = str(name_or_path)
    files = _map_files()
    if key in files:
        return _cached_load(str(files[key]))
    if key.endswith(".json") or os.sep in key:
        return _cached_load(str(Path(key).resolve()))
    raise MapError(f"unknown map {key!r}; known maps: {', '.join(list_maps())} (or pass a path to a map file)")
