"""The built-in script library: every script by name, the maps it plays, and SMAC-HARD's per-map pools.

- The two base opponents: ``smac`` (SMAC's one-player map behaviour: one attack-move at spawn, then SC2's automatic
  targeting) and ``base`` (SMAC-HARD's ``base_script``: a per-map attack-move re-issued every step). See
  :mod:`smac_hard_gym.opponents.base`.
- Generic scripts (``nearest``, ``weakest``, ``weakest_each``, ``focus_fire``, ``kite``, ``retreat_wounded``,
  ``round_robin``, ``round_robin_intended``, ``chase``, ``stop``) play every map.
- Map scripts are the SMAC-HARD strategies, written anew; each plays the maps whose pool lists it.
- Every script in a pool behaves as SMAC-HARD's code runs (dead branches dead, its own tie-breaks and thresholds);
  each class docstring names its SMAC-HARD file and every deliberate difference. ``round_robin`` is SMAC-HARD's
  round-robin as it runs (attack the nearest every step); the round-robin it intended is ``round_robin_intended``,
  in no pool.
- ``default`` on a map is its SMAC-HARD pool (``SCRIPT_DICT`` at SMAC-HARD's newest commit, with SMAC-HARD's
  ``base``); ``blackbox`` is that pool without ``base`` (the paper's black-box evaluation set). A map without a
  SMAC-HARD pool (a user's map) gets :data:`FALLBACK_POOL`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from smac_hard_gym.maps import MapSpec, load_map
from smac_hard_gym.opponents.api import Script
from smac_hard_gym.opponents.base import BaseScript, SmacScript
from smac_hard_gym.opponents.generic import (
    Chase,
    FocusFire,
    Kite,
    Nearest,
    RetreatWounded,
    RoundRobin,
    RoundRobinIntended,
    Stop,
    Weakest,
    WeakestEach,
)
from smac_hard_gym.opponents.marines import ColumnAdvance, LineAdvance
from smac_hard_gym.opponents.mmm import MarauderFront, MMMFormation
from smac_hard_gym.opponents.protoss import CenterFocus, ColossusSplash, KitePush, StalkerRetreat, Surround
from smac_hard_gym.opponents.zerg import BaneCluster, Blob, CliffGroups, PairBombing, Pincer, SpineWeaker

__all__ = ["ScriptInfo", "SCRIPTS", "POOLS", "FALLBACK_POOL", "MIXTURE_NAMES", "scripts_for_map", "pool_for_map",
           "is_builtin"]

MIXTURE_NAMES = ("default", "blackbox")

_MARINE_LINE = ("3m", "8m", "5m_vs_6m", "8m_vs_9m", "10m_vs_11m")
_LINE_POOL = ("line_front", "line_weakest", "base")
_COLUMN_POOL = ("column_weakest", "column_centroid", "column_point", "base")
_SURROUND_POOL = ("round_robin", "surround", "base")
_MMM_POOL = ("mmm_formation", "marauder_front", "base")

POOLS: dict[str, tuple[str, ...]] = {
    "3m": ("line_front", "base"),  # SMAC-HARD's s_3m (one shared weakest target) is only in its test dict: ``weakest``
    "8m": _LINE_POOL,
    "5m_vs_6m": _LINE_POOL,
    "8m_vs_9m": _LINE_POOL,
    "10m_vs_11m": _LINE_POOL,
    "25m": _COLUMN_POOL,
    "27m_vs_30m": _COLUMN_POOL,
    "2s3z": ("stalker_retreat", "center_focus", "base"),
    "3s5z": ("stalker_retreat", "kite_push", "base"),
    "3s5z_vs_3s6z": ("stalker_retreat", "base"),
    "3s_vs_3z": _SURROUND_POOL,
    "3s_vs_4z": _SURROUND_POOL,
    "3s_vs_5z": _SURROUND_POOL,
    "1c3s5z": ("colossus_splash", "base"),
    "2m_vs_1z": ("weakest_each", "base"),  # s_2m_vs_1z: the lower-health marine, the nearer on a tie
    "2s_vs_1sc": ("spine_weaker", "base"),
    "2c_vs_64zg": ("cliff_groups", "base"),
    "so_many_baneling": ("pair_bombing", "base"),
    "bane_vs_bane": ("bane_cluster", "base"),
    "MMM": _MMM_POOL,
    "MMM2": _MMM_POOL,
    "6h_vs_8z": ("chase", "round_robin"),  # SMAC-HARD's easy and hard scripts; this pool never had base
    "corridor": ("blob", "pincer", "base"),
}
FALLBACK_POOL: tuple[str, ...] = ("nearest", "weakest", "focus_fire", "base")


@dataclass(frozen=True)
class ScriptInfo:
    """One library entry: ``factory()`` builds a fresh script; ``maps`` is None for scripts that play every map."""

    name: str
    description: str
    factory: Callable[[], Script]
    maps: tuple[str, ...] | None = None

    def plays(self, map_name: str) -> bool:
        return self.maps is None or map_name in self.maps


def _maps_with(name: str) -> tuple[str, ...]:
    return tuple(m for m, pool in POOLS.items() if name in pool)


_GENERIC: list[Callable[[], Script]] = [SmacScript, BaseScript, Nearest, Weakest, WeakestEach, FocusFire, Kite,
                                        RetreatWounded, RoundRobin, RoundRobinIntended, Chase, Stop]
_MAP_SCRIPTS: list[Callable[[], Script]] = [
    lambda: LineAdvance("front"), lambda: LineAdvance("weakest"),
    lambda: ColumnAdvance("weakest"), lambda: ColumnAdvance("centroid"), lambda: ColumnAdvance("point"),
    StalkerRetreat, CenterFocus, KitePush, ColossusSplash, Surround, MMMFormation, MarauderFront,
    Blob, Pincer, PairBombing, BaneCluster, CliffGroups, SpineWeaker,
]


def _build_registry() -> dict[str, ScriptInfo]:
    registry: dict[str, ScriptInfo] = {}
    for factory, generic in [(f, True) for f in _GENERIC] + [(f, False) for f in _MAP_SCRIPTS]:
        probe = factory()
        maps = None if generic else _maps_with(probe.name)
        if not generic and not maps:
            raise AssertionError(f"library script {probe.name!r} is in no map's pool")
        registry[probe.name] = ScriptInfo(probe.name, probe.description, factory, maps)
    unknown = {n for pool in POOLS.values() for n in pool} - set(registry)
    if unknown:
        raise AssertionError(f"pools name unknown scripts: {sorted(unknown)}")
    return registry


SCRIPTS: dict[str, ScriptInfo] = _build_registry()
_BUILTIN_TYPES = tuple({type(info.factory()) for info in SCRIPTS.values()})


def _map_name(spec: MapSpec | str) -> str:
    return spec.name if isinstance(spec, MapSpec) else load_map(spec).name


def pool_for_map(spec: MapSpec | str, which: str = "default") -> tuple[str, ...]:
    """The script names of a map's ``default`` pool (SMAC-HARD's) or its ``blackbox`` pool (without ``base``)."""
    if which not in MIXTURE_NAMES:
        raise ValueError(f"pool must be one of {MIXTURE_NAMES}, got {which!r}")
    pool = POOLS.get(_map_name(spec), FALLBACK_POOL)
    return pool if which == "default" else tuple(n for n in pool if n != "base")


def scripts_for_map(spec: MapSpec | str) -> dict[str, ScriptInfo]:
    """Every built-in script that plays this map, by name (generic scripts first, then the map's own)."""
    name = _map_name(spec)
    return {n: info for n, info in SCRIPTS.items() if info.plays(name)}


def is_builtin(script: Script) -> bool:
    """Whether ``script`` is an instance of a library class (trusted: not wrapped in the guard by default)."""
    return type(script) in _BUILTIN_TYPES
