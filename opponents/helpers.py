"""Building blocks of batched scripts: a gathered frame, geometry helpers, episode memory, and the order builder.

A batched script handles all active battles of a batch in one call. Subclass :class:`BatchScript` and write
``plan(frame, orders)``::

    class Closest(BatchScript):
        name = "closest"

        def plan(self, frame, orders):
            target = nearest(frame.dist, frame.targetable)  # (R, n) enemy index, -1 where none
            orders.attack(frame.own_alive, target)         # masks of units, (R, n)

``frame`` (:class:`Frame`) holds the R active battles as (R, n) own and (R, m) enemy arrays, gathered on first use,
with cached distances, masks and centroids; ``orders`` (:class:`Orders`) is a (R, n) plan, NOOP everywhere, that
``BatchScript.act`` scatters into the batch's Commands. Per-battle episode memory lives in a :class:`Memory` of
(B, ...) arrays indexed with ``frame.rows``. Everything is vectorised over battles and units: no Python loop per
battle. Indices are side-local (0-based within own or enemy units); :class:`Orders` turns them into slots.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

try:  # the clip ufunc itself: np.clip's Python wrapper costs more than the clipping on a script's tiny arrays
    from numpy._core.umath import clip as _clip
except ImportError:  # numpy < 2
    from numpy.core.umath import clip as _clip

from smac_hard_gym.engine.state import (
    CMD_ATTACK,
    CMD_ATTACK_MOVE,
    CMD_HEAL,
    CMD_HOLD,
    CMD_MOVE,
    CMD_NOOP,
    CMD_STOP,
    NO_UNIT,
    Commands,
)
from smac_hard_gym.engine.units import BIO, STATS, UNITS, WEAPON_HEAL, S
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.opponents.api import RED, Script, SideView, lazy_property

__all__ = [
    "CAN_HIT", "Frame", "Memory", "Orders", "nearest", "lowest", "argmin_masked", "within", "centroid",
    "toward", "away", "unit_vector", "line_points", "arc_points", "is_pathable", "to_pathable", "clamp_to_map",
    "retreat_points", "support_healers", "threatened", "BatchScript", "of_kind", "slots_of", "across_rank",
    "from_blue_frame", "weakest_of_nearest", "list_rank",
]


def _can_hit_table() -> np.ndarray:
    """CAN_HIT[a, b]: a unit of type a has a weapon that can damage a unit of type b (air or ground)."""
    armed = (STATS[:, S["damage"]] > 0) & (STATS[:, S["weapon"]] != WEAPON_HEAL)
    target_air = STATS[:, S["is_air"]] > 0
    hits = np.where(target_air[None, :], STATS[:, S["hits_air"]][:, None] > 0, STATS[:, S["hits_ground"]][:, None] > 0)
    return armed[:, None] & hits


CAN_HIT: np.ndarray = _can_hit_table()
_HEALER = STATS[:, S["weapon"]] == WEAPON_HEAL
_BASE_NAMES = np.array([u.base for u in UNITS])
_HP_MAX = STATS[:, S["health"]] + STATS[:, S["shield"]]
_HEALTH_MAX = STATS[:, S["health"]]
_HEALABLE = ((STATS[:, S["attributes"]].astype(np.int64) & BIO) != 0) & (STATS[:, S["is_air"]] == 0)
_any = np.logical_or.reduce  # ``a.any(axis)`` without the method's Python wrapper (same result)
_sum = np.add.reduce  # ``a.sum(axis)`` likewise (same dtype rules and summation order)
_ALL_ROWS = np.zeros(1, dtype=np.intp)  # the rows of a one-battle batch (read-only, shared)
_ALL_ROWS.flags.writeable = False
_HAS_HEALER: dict[bytes, bool] = {}  # unit-type row (bytes) -> whether any of its types heals


def _expand(values: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """The values ``np.broadcast_to(values, shape)`` reads, as a fresh array (without broadcast_to's Python cost)."""
    full = np.empty(shape, dtype=values.dtype)
    full[...] = values
    return full


_CAN_HIT_BLOCKS: dict[tuple, np.ndarray] = {}


def _can_hit(shooters: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """``CAN_HIT[shooters[:, :, None], targets[:, None, :]]`` for (1, n) and (1, m) type rows, cached per pair of
    rows (a map fixes them) and read-only."""
    key = (shooters.tobytes(), shooters.shape, shooters.dtype.str, targets.tobytes(), targets.shape, targets.dtype.str)
    block = _CAN_HIT_BLOCKS.get(key)
    if block is None:
        if len(_CAN_HIT_BLOCKS) >= 256:
            _CAN_HIT_BLOCKS.clear()
        block = _CAN_HIT_BLOCKS[key] = CAN_HIT[shooters[:, :, None], targets[:, None, :]]
        block.flags.writeable = False
    return block


def _has_healer(types: np.ndarray) -> bool:
    """Whether any unit type of the (1, n) row ``types`` is a healer (cached per row: a map fixes it)."""
    key = types.tobytes()
    found = _HAS_HEALER.get(key)
    if found is None:
        found = _HAS_HEALER[key] = bool(_HEALER[types].any())
    return found


_OF_KIND: dict[tuple, np.ndarray] = {}  # (types' bytes, shape, dtype, bases) -> mask


def of_kind(types: np.ndarray, *bases: str) -> np.ndarray:
    """Mask of units whose type is one of the standard units ``bases`` ("marine" covers marine and marine_rl)."""
    # Scripts ask this of the same (1, n) type row every step: the mask is cached per row and handed out as a copy
    # (np.isin costs tens of microseconds; a copy well under one).
    types = np.asarray(types)
    key = (types.tobytes(), types.shape, types.dtype.str, bases)
    mask = _OF_KIND.get(key)
    if mask is None:
        if len(_OF_KIND) >= 1024:
            _OF_KIND.clear()
        mask = _OF_KIND[key] = np.isin(_BASE_NAMES[types], bases)
    return mask.copy()


def slots_of(view: SideView, *bases: str) -> np.ndarray:
    """Own indices of the units of kinds ``bases``. A map fixes which unit sits in which slot, so this is the same
    in every battle of a batch."""
    return np.flatnonzero(of_kind(view.state.utype[0, view.own], *bases))


# ---------------------------------------------------------------------------------------------------------------
# The gathered frame.


class Frame:
    """The rows ``rows`` of a :class:`SideView`, gathered into (R, n) own and (R, m) enemy arrays on first use.

    Derived arrays (distances, masks, centroids) are computed once per frame and cached. ``hp`` is health + shield.
    Unit types and per-type stats (``own_type``, ``own_radius``, ``own_hp_max``...) are (1, n) rows: a map fixes
    which unit sits in which slot, and they broadcast against the (R, n) arrays.
    """

    def __init__(self, view: SideView, rows: np.ndarray) -> None:
        self.view = view
        self.rows = rows
        self.spec = view.spec
        self.n_own = view.n_own
        self.n_enemy = view.n_enemy
        # All battles (the usual case outside mixtures): plain slices are views, far cheaper than gathers.
        self.index: np.ndarray | slice = slice(None) if rows.size == view.batch_size else rows

    def _gather(self, name: str, which: slice) -> np.ndarray:
        block = getattr(self.view.state, name)[self.index, which]
        if block.base is not None:  # a view of the live state (a fresh view object): scripts must not write it
            block.flags.writeable = False
        return block

    def _own(self, name: str) -> np.ndarray:
        return self._gather(name, self.view.own)

    def _enemy(self, name: str) -> np.ndarray:
        return self._gather(name, self.view.enemy)

    @property
    def size(self) -> int:
        return self.rows.size

    @lazy_property
    def step(self) -> np.ndarray:
        """Env steps since each row's reset, (R,)."""
        step = self.view.episode_step
        return step.copy() if self.rows is _ALL_ROWS else step[self.rows]

    # Own units (R, n). A map fixes the unit type of every slot, so types and per-type stats are (1, n) rows that
    # broadcast against the (R, n) arrays.
    own_type = lazy_property(lambda self: self.view.state.utype[0:1, self.view.own])
    own_alive = lazy_property(lambda self: self._own("alive"))
    own_x = lazy_property(lambda self: self._own("x"))
    own_y = lazy_property(lambda self: self._own("y"))
    own_health = lazy_property(lambda self: self._own("health"))
    own_shield = lazy_property(lambda self: self._own("shield"))
    own_energy = lazy_property(lambda self: self._own("energy"))
    own_cooldown = lazy_property(lambda self: self._own("cooldown"))
    own_hp = lazy_property(lambda self: self.own_health + self.own_shield)
    own_hp_max = lazy_property(lambda self: _HP_MAX[self.own_type])
    own_hp_frac = lazy_property(lambda self: self.own_hp / self.own_hp_max)
    own_health_max = lazy_property(lambda self: _HEALTH_MAX[self.own_type])
    own_health_frac = lazy_property(lambda self: self.own_health / self.own_health_max)  # hull only
    own_radius = lazy_property(lambda self: STATS[self.own_type, S["radius"]])
    own_range = lazy_property(lambda self: STATS[self.own_type, S["range"]])
    own_speed = lazy_property(lambda self: STATS[self.own_type, S["speed"]])
    own_healer = lazy_property(lambda self: _HEALER[self.own_type] & self.own_alive)
    # Enemy units (R, m); types and stats (1, m).
    enemy_type = lazy_property(lambda self: self.view.state.utype[0:1, self.view.enemy])
    enemy_alive = lazy_property(lambda self: self._enemy("alive"))
    enemy_x = lazy_property(lambda self: self._enemy("x"))
    enemy_y = lazy_property(lambda self: self._enemy("y"))
    enemy_health = lazy_property(lambda self: self._enemy("health"))
    enemy_shield = lazy_property(lambda self: self._enemy("shield"))
    enemy_cooldown = lazy_property(lambda self: self._enemy("cooldown"))
    enemy_hp = lazy_property(lambda self: self.enemy_health + self.enemy_shield)
    enemy_hp_max = lazy_property(lambda self: _HP_MAX[self.enemy_type])
    enemy_hp_frac = lazy_property(lambda self: self.enemy_hp / self.enemy_hp_max)
    enemy_health_max = lazy_property(lambda self: _HEALTH_MAX[self.enemy_type])
    enemy_health_frac = lazy_property(lambda self: self.enemy_health / self.enemy_health_max)  # hull only
    enemy_radius = lazy_property(lambda self: STATS[self.enemy_type, S["radius"]])
    enemy_range = lazy_property(lambda self: STATS[self.enemy_type, S["range"]])
    enemy_speed = lazy_property(lambda self: STATS[self.enemy_type, S["speed"]])

    @lazy_property
    def dist(self) -> np.ndarray:
        """Centre distance from each own unit to each enemy, (R, n, m)."""
        dx = self.enemy_x[:, None, :] - self.own_x[:, :, None]
        dy = self.enemy_y[:, None, :] - self.own_y[:, :, None]
        return np.sqrt(dx * dx + dy * dy)

    @lazy_property
    def edge(self) -> np.ndarray:
        """Edge-to-edge distance (what weapon ranges measure), (R, n, m)."""
        return self.dist - self.own_radius[:, :, None] - self.enemy_radius[:, None, :]

    @lazy_property
    def hittable(self) -> np.ndarray:
        """Own unit i (alive, armed) can damage enemy k (alive, right plane), (R, n, m)."""
        can = _can_hit(self.own_type, self.enemy_type)
        return can & self.own_alive[:, :, None] & self.enemy_alive[:, None, :]

    @lazy_property
    def targetable(self) -> np.ndarray:
        """``hittable``, and for units that cannot move (spine crawler) only targets already in range."""
        static = self.own_speed <= 0
        if not static.any():
            return self.hittable
        return self.hittable & (~static[:, :, None] | (self.edge <= self.own_range[:, :, None]))

    @lazy_property
    def own_centroid(self) -> tuple[np.ndarray, np.ndarray]:
        """Mean position of alive own units, (R,) each (the side's spawn where none is alive)."""
        return centroid(self.own_x, self.own_y, self.own_alive, self.view.own_spawn)

    @lazy_property
    def enemy_centroid(self) -> tuple[np.ndarray, np.ndarray]:
        """Mean position of alive enemies, (R,) each (the enemy spawn where none is alive)."""
        return centroid(self.enemy_x, self.enemy_y, self.enemy_alive, self.view.enemy_spawn)

    @lazy_property
    def forward(self) -> np.ndarray:
        """Unit vector of advance (own spawn toward enemy spawn), (2,)."""
        return self.view.forward

    # SMAC-HARD's frame. Its scripts always play blue and hard-code blue's map coordinates; red plays them
    # reflected through the midpoint of the two spawns, which swaps the spawns (the map centre on every map with
    # mirrored spawns). The reflection keeps distances, so thresholds carry over unchanged.
    @lazy_property
    def reflection(self) -> np.ndarray | None:
        """None for blue; for red the (2,) point S of the reflection (x, y) -> (S - x, S - y)."""
        return None if self.view.side != RED else self.view.own_spawn + self.view.enemy_spawn

    def blue_frame(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (x, y) as SMAC-HARD's blue side sees them: unchanged for blue, reflected for red."""
        s = self.reflection
        return (x, y) if s is None else (s[0] - x, s[1] - y)

    own_hx = lazy_property(lambda self: self.blue_frame(self.own_x, self.own_y)[0])
    own_hy = lazy_property(lambda self: self.blue_frame(self.own_x, self.own_y)[1])
    enemy_hx = lazy_property(lambda self: self.blue_frame(self.enemy_x, self.enemy_y)[0])
    enemy_hy = lazy_property(lambda self: self.blue_frame(self.enemy_x, self.enemy_y)[1])


# ---------------------------------------------------------------------------------------------------------------
# Selection.


def argmin_masked(values: np.ndarray, mask: np.ndarray, axis: int = -1) -> np.ndarray:
    """Index of the smallest ``values`` where ``mask`` holds, along ``axis``; -1 where the mask is empty."""
    idx = np.where(mask, values, np.inf).argmin(axis=axis)
    return np.where(_any(mask, axis=axis), idx, -1)


def nearest(dist: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """For each own unit the index of the nearest enemy allowed by ``mask``; (R, n, m) -> (R, n), -1 if none."""
    return argmin_masked(dist, mask, axis=-1)


def lowest(values: np.ndarray, mask: np.ndarray, tie: np.ndarray | None = None) -> np.ndarray:
    """Index of the lowest ``values`` where ``mask`` holds along the last axis, ties broken by the lowest ``tie``.

    Values are compared to 1e-6 so equal health reads as a tie; -1 where the mask is empty.
    """
    if tie is None:
        return argmin_masked(values, mask)
    vmin = np.minimum.reduce(np.where(mask, values, np.inf), axis=-1, keepdims=True)
    return argmin_masked(tie, mask & (values <= vmin + 1e-6))


def across_rank(x: np.ndarray, y: np.ndarray, facing: np.ndarray) -> np.ndarray:
    """Rank (0..n-1) of each of the (R, n) points along the line across ``facing`` (left to right seen facing it):
    assigning formation slots by this rank keeps units from crossing each other's paths."""
    across = x * -facing[1] + y * facing[0]
    return np.argsort(np.argsort(across, axis=-1, kind="stable"), axis=-1, kind="stable")


def list_rank(mask: np.ndarray) -> np.ndarray:
    """Position of each unit in the list of units where ``mask`` holds, in index order (SMAC-HARD's lists are
    sorted by tag, which is our index order); -1 where the mask is false. (R, n) -> (R, n)."""
    return np.where(mask, np.cumsum(mask, axis=-1) - 1, -1)


def weakest_of_nearest(dist: np.ndarray, values: np.ndarray, mask: np.ndarray, k: int) -> np.ndarray:
    """SMAC-HARD's ``min(nearest_n_units(unit, enemies, k), key=value)`` for each (R, n, m) row of ``dist``.

    With at most ``k`` candidates (``mask``) all of them count, in index order: a tie goes to the lowest index,
    not the nearest (``nearest_n_units`` returns a list that short unsorted). With more, the ``k`` nearest count
    (a stable sort: equal distances keep index order) and a tie goes to the nearer. ``values`` (R, m) or (R, n, m);
    returns (R, n) indices, -1 without candidates.
    """
    values = values if values.ndim == 3 else values[:, None, :]  # (R, 1, m) broadcasts in lowest's comparisons
    d = np.where(mask, dist, np.inf)
    by_distance = np.argsort(np.argsort(d, axis=-1, kind="stable"), axis=-1, kind="stable")  # rank, (R, n, m)
    few = (_sum(mask, axis=-1) <= k)[..., None]
    order = np.where(few, np.arange(dist.shape[-1]), by_distance)
    return lowest(values, mask & (few | (by_distance < k)), tie=order)


def within(dist: np.ndarray, reach: np.ndarray | float) -> np.ndarray:
    """``dist <= reach`` (distances and reaches broadcast)."""
    return dist <= reach


# ---------------------------------------------------------------------------------------------------------------
# Geometry.


def centroid(x: np.ndarray, y: np.ndarray, mask: np.ndarray,
             fallback: np.ndarray | tuple[float, float] = (16.0, 16.0)) -> tuple[np.ndarray, np.ndarray]:
    """Mean of the (R, n) points where ``mask`` holds, per row; ``fallback`` (x, y) for rows with none."""
    count = _sum(mask, axis=-1)
    if count.shape == (1,) and count[0] > 0:  # one row with points (a single battle): no fallback to blend in
        return _sum(x * mask, axis=-1) / count, _sum(y * mask, axis=-1) / count
    safe = np.maximum(count, 1)
    some = count > 0
    cx = np.where(some, _sum(x * mask, axis=-1) / safe, fallback[0])
    cy = np.where(some, _sum(y * mask, axis=-1) / safe, fallback[1])
    return cx, cy


def unit_vector(dx: np.ndarray, dy: np.ndarray, default: tuple[float, float] = (1.0, 0.0)
                ) -> tuple[np.ndarray, np.ndarray]:
    """(dx, dy) scaled to length 1; ``default`` where the vector is (almost) zero."""
    norm = np.hypot(dx, dy)
    ok = norm > 1e-9
    safe = np.where(ok, norm, 1.0)
    return np.where(ok, dx / safe, default[0]), np.where(ok, dy / safe, default[1])


def toward(x: np.ndarray, y: np.ndarray, tx: np.ndarray, ty: np.ndarray, d: np.ndarray | float
           ) -> tuple[np.ndarray, np.ndarray]:
    """The point ``d`` from (x, y) in the direction of (tx, ty); negative ``d`` goes away from it."""
    ux, uy = unit_vector(np.asarray(tx) - x, np.asarray(ty) - y)
    return x + d * ux, y + d * uy


def away(x: np.ndarray, y: np.ndarray, fx: np.ndarray, fy: np.ndarray, d: np.ndarray | float
         ) -> tuple[np.ndarray, np.ndarray]:
    """The point ``d`` from (x, y) directly away from (fx, fy)."""
    return toward(x, y, fx, fy, -np.asarray(d))


def line_points(cx: np.ndarray, cy: np.ndarray, facing: np.ndarray, n: int, spacing: float = 1.0,
                per_rank: int | None = None, rank_gap: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Formation points of ``n`` units in a line across ``facing`` (a (2,) unit vector), centred on (cx, cy).

    Slot i sits at offset ``(i - centre) * spacing`` along the line; with ``per_rank`` the line wraps into ranks
    placed ``rank_gap`` behind each other. Returns (R, n) x and y for (R,) centres.
    """
    per_rank = n if per_rank is None else max(1, per_rank)
    slot = np.arange(n)
    rank, file = slot // per_rank, slot % per_rank
    in_rank = np.minimum(per_rank, n - rank * per_rank)
    across = (file - (in_rank - 1) / 2.0) * spacing
    back = -rank * rank_gap
    px, py = -facing[1], facing[0]
    ox = across * px + back * facing[0]
    oy = across * py + back * facing[1]
    return np.asarray(cx)[..., None] + ox, np.asarray(cy)[..., None] + oy


def arc_points(cx: np.ndarray, cy: np.ndarray, facing: np.ndarray, n: int, radius: float,
               spread: float = np.pi) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points on an arc of ``radius`` around (cx, cy), centred on ``facing`` and ``spread`` radians wide."""
    angles = np.linspace(-spread / 2, spread / 2, n) if n > 1 else np.zeros(1)
    base = np.arctan2(facing[1], facing[0])
    return (np.asarray(cx)[..., None] + radius * np.cos(base + angles),
            np.asarray(cy)[..., None] + radius * np.sin(base + angles))


def from_blue_frame(frame: Frame, x: np.ndarray | float, y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """SMAC-HARD's point (x, y), written for blue, on ``frame``'s side: exact for blue; for red reflected (see
    :meth:`Frame.blue_frame`) and moved onto pathable ground, since the reflection of a map whose terrain is not
    symmetric can land on a wall."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    if frame.reflection is None:
        return x, y
    return to_pathable(*frame.blue_frame(x, y), frame.spec)


def clamp_to_map(x: np.ndarray, y: np.ndarray, spec: MapSpec, margin: float = 0.5
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Points pulled inside the map rectangle, ``margin`` from its border."""
    mx, my = spec.size
    return _clip(x, margin, mx - margin), _clip(y, margin, my - margin)


def is_pathable(x: np.ndarray, y: np.ndarray, spec: MapSpec) -> np.ndarray:
    """Whether each point lies on a pathable ground cell (outside the map counts as not pathable)."""
    mx, my = spec.size
    inside = (x >= 0) & (x < mx) & (y >= 0) & (y < my)
    cx = np.clip(x, 0, mx - 1).astype(np.int64)
    cy = np.clip(y, 0, my - 1).astype(np.int64)
    return inside & spec.pathable[cx, cy]


@lru_cache(maxsize=64)
def _nearest_pathable_cell(spec_name: str, pathable_bytes: bytes, shape: tuple[int, int]) -> np.ndarray:
    pathable = np.frombuffer(pathable_bytes, dtype=np.bool_).reshape(shape)
    cells = np.argwhere(pathable).astype(np.float64) + 0.5  # (P, 2) centres
    gx, gy = np.meshgrid(np.arange(shape[0]) + 0.5, np.arange(shape[1]) + 0.5, indexing="ij")
    d = (gx[..., None] - cells[:, 0]) ** 2 + (gy[..., None] - cells[:, 1]) ** 2
    return cells[d.argmin(axis=-1)]  # (mx, my, 2)


def to_pathable(x: np.ndarray, y: np.ndarray, spec: MapSpec) -> tuple[np.ndarray, np.ndarray]:
    """Points moved to the centre of the nearest pathable cell when they are not on a pathable cell."""
    x, y = clamp_to_map(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64), spec, margin=0.0)
    if not spec.pathable.any():
        return x, y
    table = _nearest_pathable_cell(spec.name, np.ascontiguousarray(spec.pathable).tobytes(), spec.pathable.shape)
    ok = is_pathable(x, y, spec)
    cx = np.clip(x, 0, spec.size[0] - 1).astype(np.int64)
    cy = np.clip(y, 0, spec.size[1] - 1).astype(np.int64)
    near = table[cx, cy]
    return np.where(ok, x, near[..., 0]), np.where(ok, y, near[..., 1])


_RETREAT_TURNS = np.deg2rad([0.0, 45.0, -45.0, 90.0, -90.0, 135.0, -135.0])


def retreat_points(x: np.ndarray, y: np.ndarray, fx: np.ndarray, fy: np.ndarray, d: float, spec: MapSpec,
                   fallback: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Points ``d`` away from the threats at (fx, fy), turned up to 135 degrees to stay on pathable ground.

    Tries straight away first, then 45, 90 and 135 degrees either side; ``fallback`` (x, y) where none is pathable
    (a unit cornered against walls falls back toward its own side instead of pressing into a wall).
    """
    ux, uy = unit_vector(x - fx, y - fy)
    cos, sin = np.cos(_RETREAT_TURNS), np.sin(_RETREAT_TURNS)
    px = x[..., None] + d * (ux[..., None] * cos - uy[..., None] * sin)
    py = y[..., None] + d * (ux[..., None] * sin + uy[..., None] * cos)
    ok = is_pathable(px, py, spec)
    first = ok.argmax(axis=-1)[..., None]
    any_ok = ok.any(axis=-1)
    bx = np.take_along_axis(px, first, axis=-1)[..., 0]
    by = np.take_along_axis(py, first, axis=-1)[..., 0]
    return (np.where(any_ok, bx, np.broadcast_to(fallback[0], bx.shape)),
            np.where(any_ok, by, np.broadcast_to(fallback[1], by.shape)))


# ---------------------------------------------------------------------------------------------------------------
# Episode memory.


class Memory:
    """Per-battle episode memory: named arrays shaped (B, *shape), restored to their defaults at episode start.

    A field is ``name=(shape, dtype, default)``; ``"own"`` and ``"enemy"`` in a shape stand for the side's unit
    counts::

        mem = Memory(engaged=((), bool, False), last_hp=(("own",), float, 0.0))
        mem.clear(view, battles)   # allocates (B,) and (B, n_own) arrays, then resets ``battles``
        mem.engaged[frame.rows]    # read and write with the frame's rows
    """

    def __init__(self, **fields: tuple[tuple[int | str, ...], Any, Any]) -> None:
        self._fields = fields
        self._key: tuple[int, int, int] | None = None

    def clear(self, view: SideView, battles: np.ndarray) -> None:
        """Allocate for the view's batch (when its size changed), then reset ``battles`` to the defaults."""
        key = (view.batch_size, view.n_own, view.n_enemy)
        if key != self._key:
            dims = {"own": view.n_own, "enemy": view.n_enemy}
            for name, (shape, dtype, default) in self._fields.items():
                full = (view.batch_size, *(dims[d] if isinstance(d, str) else d for d in shape))
                setattr(self, name, np.full(full, default, dtype=dtype))
            self._key = key
            return
        for name, (_, _, default) in self._fields.items():
            getattr(self, name)[battles] = default

    def __getattr__(self, name: str) -> np.ndarray:
        # Only reached when the attribute is missing: memory used before any reset.
        if name.startswith("_"):
            raise AttributeError(name)
        raise AttributeError(f"memory field {name!r} is not allocated: reset() must run before act()")


# ---------------------------------------------------------------------------------------------------------------
# The order builder.


class Orders:
    """A plan of commands for the own units of a frame's rows, (R, n) arrays; ``write`` scatters it into Commands.

    Each builder takes a (R, n) bool mask of units; later calls override earlier ones for the same units. Dead
    units and units without a valid target (index -1) get no command, so a plan never holds an invalid order.
    """

    def __init__(self, frame: Frame) -> None:
        self.frame = frame
        self.kind = np.zeros((frame.size, frame.n_own), dtype=np.int8)
        self._targets = self._points = False  # which parts of the plan hold data, so write skips the rest

    # Allocated on first use (most plans give only some kinds of order).
    target = lazy_property(lambda self: np.full(self.kind.shape, NO_UNIT, dtype=np.int32))
    x = lazy_property(lambda self: np.zeros(self.kind.shape, dtype=np.float64))
    y = lazy_property(lambda self: np.zeros(self.kind.shape, dtype=np.float64))

    def _mask(self, units: np.ndarray) -> np.ndarray:
        return units & self.frame.own_alive  # own_alive is (R, n): the result always has the plan's shape

    def _full(self, values: np.ndarray | float) -> np.ndarray:
        values = np.asarray(values)
        shape = self.kind.shape
        if values.shape == shape:
            return values
        return _expand(values, shape)

    def _point(self, kind: int, units: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
        m = self._mask(units)
        if not _any(m, axis=None):
            return
        x, y = clamp_to_map(self._full(x), self._full(y), self.frame.spec, 0.0)
        self.kind[m] = kind
        self.x[m] = x[m]
        self.y[m] = y[m]
        self._points = True

    def attack(self, units: np.ndarray, enemy: np.ndarray) -> None:
        """Attack enemy index ``enemy`` (R, n) (no command where it is -1)."""
        enemy = self._full(enemy)
        m = self._mask(units) & (enemy >= 0)
        self.kind[m] = CMD_ATTACK
        self.target[m] = self.frame.view.enemy.start + enemy[m]
        self._targets = True

    def heal(self, units: np.ndarray, ally: np.ndarray) -> None:
        """Heal own unit index ``ally`` (R, n) (no command where it is -1)."""
        ally = self._full(ally)
        m = self._mask(units) & (ally >= 0)
        self.kind[m] = CMD_HEAL
        self.target[m] = self.frame.view.own.start + ally[m]
        self._targets = True

    def attack_move(self, units: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
        """Attack-move to (x, y): walk there, engaging enemies met on the way."""
        self._point(CMD_ATTACK_MOVE, units, x, y)

    def move(self, units: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
        """Move to (x, y), ignoring enemies."""
        self._point(CMD_MOVE, units, x, y)

    def stop(self, units: np.ndarray) -> None:
        self.kind[self._mask(units)] = CMD_STOP

    def hold(self, units: np.ndarray) -> None:
        self.kind[self._mask(units)] = CMD_HOLD

    def noop(self, units: np.ndarray) -> None:
        """Withdraw planned commands: the units keep their current orders."""
        m = self._mask(units)
        self.kind[m] = CMD_NOOP
        self.target[m] = NO_UNIT

    def write(self, commands: Commands) -> None:
        """Write the planned (non-NOOP) commands into ``commands`` at the frame's rows and own slots."""
        index, own = self.frame.index, self.frame.view.own
        planned = self.kind != CMD_NOOP
        pairs = [(commands.kind, self.kind)]
        if self._targets:
            pairs.append((commands.target, self.target))
        if self._points:
            pairs += [(commands.x, self.x), (commands.y, self.y)]
        for dst, src in pairs:
            if isinstance(index, slice):
                np.copyto(dst[index, own], src, where=planned)  # a view: writes straight into the buffer
            else:
                block = dst[index, own]
                np.copyto(block, src, where=planned)
                dst[index, own] = block


# ---------------------------------------------------------------------------------------------------------------
# Shared behaviours.


def support_healers(orders: Orders, frame: Frame, follow: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """Healers (medivacs) heal the most injured own biological ground unit; with nobody hurt they move to
    ``follow`` (R,) x and y, by default the centre of the own units that are not healers. It overrides any order
    given to healers, so call it after the rest of the plan."""
    if not _has_healer(frame.own_type):  # no healer type on this side (most maps): nothing to gather
        return
    healers = frame.own_healer
    if not _any(healers, axis=None):
        return
    health_max = STATS[frame.own_type, S["health"]]
    eligible = _HEALABLE[frame.own_type] & frame.own_alive & (frame.own_health < health_max)
    patient = argmin_masked(frame.own_health / health_max, eligible)  # (R,)
    orders.heal(healers & (patient >= 0)[:, None], np.broadcast_to(patient[:, None], healers.shape))
    if follow is None:
        follow = centroid(frame.own_x, frame.own_y, frame.own_alive & ~healers, frame.own_centroid)
    idle = healers & (patient < 0)[:, None]
    orders.move(idle, np.asarray(follow[0])[:, None], np.asarray(follow[1])[:, None])


def threatened(frame: Frame, margin: float) -> np.ndarray:
    """(R, n, m): enemy k could hit own unit i after closing ``margin`` more than its weapon range."""
    can = CAN_HIT[frame.enemy_type[:, None, :], frame.own_type[:, :, None]] & frame.enemy_alive[:, None, :]
    return can & frame.own_alive[:, :, None] & (frame.edge <= frame.enemy_range[:, None, :] + margin)


# ---------------------------------------------------------------------------------------------------------------
# The batched script skeleton.


class BatchScript(Script):
    """A batched script written as ``plan(frame, orders)`` over the active rows.

    Subclasses set ``self.memory`` (a :class:`Memory`, or None) in ``__init__`` and may override ``on_reset``.
    ``act`` gathers a :class:`Frame` of the active battles, lets ``plan`` fill an :class:`Orders`, has medivacs
    follow and heal (``heal_support``), and writes the plan: one call per step for the whole batch.
    """

    heal_support: bool = True
    memory: Memory | None = None

    def reset(self, view: SideView, battles: np.ndarray, rngs: list[np.random.Generator]) -> None:
        battles = np.asarray(battles, dtype=np.int64)
        if self.memory is not None:
            self.memory.clear(view, battles)
        if battles.size:
            self.on_reset(view, battles, rngs)

    def on_reset(self, view: SideView, battles: np.ndarray, rngs: list[np.random.Generator]) -> None:
        """Fill episode memory for ``battles`` (called after the memory is cleared)."""

    def act(self, view: SideView, commands: Commands, active: np.ndarray) -> None:
        if active.shape[0] == 1:  # one battle: its row, or nothing to do
            if not active[0]:
                return
            rows = _ALL_ROWS
        else:
            rows = np.flatnonzero(active)
            if rows.size == 0:
                return
        frame = Frame(view, rows)
        orders = Orders(frame)
        self.plan(frame, orders)
        if self.heal_support:
            support_healers(orders, frame)
        orders.write(commands)

    def plan(self, frame: Frame, orders: Orders) -> None:
        """Fill ``orders`` for the rows of ``frame``."""
        raise NotImplementedError
