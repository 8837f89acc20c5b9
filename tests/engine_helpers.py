"""Hand-built scenarios for engine tests: an open map and a way to place units exactly."""

from __future__ import annotations

import math

import numpy as np

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.engine.kernels import POSITION_GRID, Rows, battle_rows
from smac_hard_gym.engine.state import Scratch, allocate_state
from smac_hard_gym.maps import parse_map


def open_map(red: list[str], blue: list[str], name: str = "test_open", band: tuple[int, int] | None = None):
    """A 32x32 flat map with one unit per listed name (spawns far apart; tests re-place units): fully pathable, or,
    with ``band = (y0, y1)``, only the rows y0 <= y < y1 (a corridor along x; spawns on its middle row)."""
    rows = ["." * 32 if band is None or band[0] <= y < band[1] else "#" * 32 for y in range(32)]
    red_y, blue_y = (4.0, 24.0) if band is None else (0.5 * (band[0] + band[1]),) * 2
    row_step = 2.5 if band is None else 0.0
    doc = {
        "name": name,
        "episode_limit": 1000,
        "races": {"red": "T", "blue": "T"},
        "unit_type_bits": 0,
        "map_type": "marines",
        "size": [32, 32],
        "units": {
            "red": [{"unit": u, "count": 1, "spawn": [4.0 + 2.5 * (k % 10), red_y + row_step * (k // 10)]}
                    for k, u in enumerate(red)],
            "blue": [{"unit": u, "count": 1, "spawn": [4.0 + 2.5 * (k % 10), blue_y + row_step * (k // 10)]}
                     for k, u in enumerate(blue)],
        },
        "enemy_order": {"kind": "none"},
        "terrain": {"pathable": rows, "cliff": ["1" * 32] * 32},
    }
    return parse_map(doc, name)


def battle_rows_of(x: np.ndarray, y: np.ndarray, alive: np.ndarray, order: np.ndarray | None = None) -> Rows:
    """The :class:`Rows` of a one-battle state with units at (``x``, ``y``), for calling a phase directly (the
    views write through to that state's arrays): red, ``alive`` as given, idle unless ``order`` says, no targets."""
    n = len(x)
    st, scratch = allocate_state(1, n), Scratch.empty(1, n)
    st.x[0], st.y[0], st.alive[0] = x, y, alive
    if order is not None:
        st.order[0] = order
    return getattr(battle_rows, "py_func", battle_rows)(st, scratch, 0)


def engine_with(red: list[str], blue: list[str], positions: dict[int, tuple[float, float]], batch: int = 1,
                band: tuple[int, int] | None = None, **engine_kwargs) -> BattleEngine:
    """An engine on an open map (``open_map``, ``band`` as there) with units at ``positions[slot]`` (red slots first,
    in the listed order).

    Without SC2's random weapon delay unless asked (``cooldown_jitter=...``): fights are then computable by hand.
    """
    engine_kwargs.setdefault("cooldown_jitter", None)
    engine = BattleEngine(open_map(red, blue, band=band), batch_size=batch, **engine_kwargs)
    for slot, (x, y) in positions.items():
        for b in range(batch):
            engine.place(b, slot, x=x, y=y)
    return engine


def loops_until(engine: BattleEngine, condition, max_loops: int) -> int:
    """Run single game loops until ``condition(engine)`` holds; returns how many loops ran."""
    for n in range(1, max_loops + 1):
        engine.step(n_loops=1)
        engine.commands.clear()
        if condition(engine):
            return n
    raise AssertionError(f"condition not reached within {max_loops} loops")


# The wind-up before each shot: the weapon data's DamagePoint in Normal seconds (SC2GameData 5.0.14, WeaponData.xml:
# GuassRifle 0.05, ThermalLances 0.0832, NeedleSpines 0.14 in voidmulti, ImpalerTentacle 0.3332, PunisherGrenades,
# PsiBlades and VolatileBurst 0; ParticleDisruptors and Claws keep core's default 0.167), as whole game loops: an
# attack that starts in loop L shoots in loop L + ceil(seconds x 16).
WIND_UP = {name: math.ceil(seconds * 16 - 1e-9) for name, seconds in {
    "Marine": 0.05, "Marauder": 0.0, "Stalker": 0.167, "Zealot": 0.0, "Colossus": 0.0832, "Hydralisk": 0.14,
    "Zergling": 0.167, "Baneling": 0.0, "SpineCrawler": 0.3332}.items()}


def shot_loop(n: int, period_loops: float, wind_up: int = 0) -> int:
    """Loop index (0-based) of the n-th shot (n = 0 first) of a weapon with the given period whose first attack
    starts in loop 0 and takes ``wind_up`` loops: the wind-ups after the first overlap the cooldown, so shots keep
    the period."""
    return wind_up + math.ceil(n * period_loops - 1e-9)


def overlaps(engine: BattleEngine, b: int) -> list[tuple[int, int, float]]:
    """Pairs of alive units of one collision plane whose circles overlap, with the overlap depth."""
    from smac_hard_gym.engine.units import STATS, S

    st = engine.state
    alive = np.flatnonzero(st.alive[b])
    out = []
    for a_idx, i in enumerate(alive):
        for j in alive[a_idx + 1:]:
            ti, tj = st.utype[b, i], st.utype[b, j]
            if STATS[ti, S["mover"]] != STATS[tj, S["mover"]]:
                continue
            depth = STATS[ti, S["radius"]] + STATS[tj, S["radius"]] - math.hypot(
                st.x[b, i] - st.x[b, j], st.y[b, i] - st.y[b, j])
            if depth > 0:
                out.append((int(i), int(j), float(depth)))
    return out


def on_grid(v):
    """v (a number or an array) rounded to SC2's position grid, 1/4096, half to even: where every move lands."""
    return np.rint(np.asarray(v) * POSITION_GRID) / POSITION_GRID
