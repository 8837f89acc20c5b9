"""The embedded battle engine: B battles of one map, stepped together by numba kernels.

>>> from smac_hard_gym.engine import BattleEngine
>>> engine = BattleEngine("3m", batch_size=4)
>>> engine.state.health.shape
(4, 6)

Modules, in import order: ``units`` (the unit table, Normal-speed values with their sources), ``state`` (the batched
state and command bundles), ``terrain`` and ``scenario`` (a map's grids and spawn layout), ``kernels`` (the numba
step, which picks numba's threading layer), ``battle`` (:class:`BattleEngine`, which ties them together). The names
below are exported lazily, so that ``smac_hard_gym.maps`` can read the unit table without loading the kernels (maps
sit between the unit table and the engine that builds battles from them).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from smac_hard_gym.engine.battle import BattleEngine
    from smac_hard_gym.engine.scenario import Layout
    from smac_hard_gym.engine.state import (
        BLUE,
        CMD_ATTACK,
        CMD_ATTACK_MOVE,
        CMD_HEAL,
        CMD_HOLD,
        CMD_MOVE,
        CMD_NOOP,
        CMD_STOP,
        NO_UNIT,
        RED,
        BattleState,
        Commands,
    )
    from smac_hard_gym.engine.terrain import Terrain

_STATE_NAMES = ("BattleState", "Commands", "RED", "BLUE", "NO_UNIT", "CMD_NOOP", "CMD_STOP", "CMD_HOLD", "CMD_MOVE",
                "CMD_ATTACK", "CMD_ATTACK_MOVE", "CMD_HEAL")
_LAZY_EXPORTS = {
    "BattleEngine": "battle", "Terrain": "terrain", "Layout": "scenario",
    **dict.fromkeys(_STATE_NAMES, "state"),
}

__all__ = [
    "BattleEngine", "BattleState", "Commands", "Terrain", "Layout", "RED", "BLUE", "NO_UNIT",
    "CMD_NOOP", "CMD_STOP", "CMD_HOLD", "CMD_MOVE", "CMD_ATTACK", "CMD_ATTACK_MOVE", "CMD_HEAL",
]


def __getattr__(name: str) -> Any:
    module = _LAZY_EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value  # later lookups skip __getattr__
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY_EXPORTS))
