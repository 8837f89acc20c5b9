"""The backend interface between the two-player core and a battle simulator.

A backend runs B battles of one map and exposes them as a :class:`~smac_hard_gym.engine.state.BattleState` snapshot
(red slots first, SMAC's agent order; blue slots in SMAC's enemy order). The core, the SMAC feature layer and the
opponent scripts only ever read that snapshot and write :class:`~smac_hard_gym.engine.state.Commands`, so the
embedded engine (``"native"``) and real StarCraft II (``"sc2"``) are interchangeable.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.engine.battle import SC2_COOLDOWN_JITTER
from smac_hard_gym.engine.state import BattleState, Commands
from smac_hard_gym.maps import MapSpec

BACKENDS = ("native", "sc2")


@runtime_checkable
class Backend(Protocol):
    """What the core needs from a simulator."""

    spec: MapSpec
    batch_size: int
    step_mul: int
    n_red: int
    n_blue: int
    state: BattleState  # current snapshot, updated by reset() and step()

    def reset(self, battles: np.ndarray | None = None, seeds: np.ndarray | None = None) -> None:
        """Restart the battles whose indices are in ``battles`` (all when None) at their spawn layout; ``seeds``
        (one per battle) seed the simulator's own randomness where it has any."""

    def step(self, commands: Commands, active: np.ndarray) -> None:
        """Send commands and advance ``step_mul`` game loops in every battle with ``active[b]``."""

    def close(self) -> None:
        """Release processes, ports and memory. Idempotent."""


class NativeBackend:
    """The embedded engine behind the backend interface. ``step`` is the engine's own (it takes the interface's
    ``commands, active``), so a core step calls the engine without a hop."""

    def __init__(self, spec: MapSpec | str, batch_size: int = 1, step_mul: int = 8,
                 cooldown_jitter: tuple[float, float] | None = SC2_COOLDOWN_JITTER) -> None:
        self.engine = BattleEngine(spec, batch_size=batch_size, step_mul=step_mul, cooldown_jitter=cooldown_jitter)
        self.spec = self.engine.spec
        self.batch_size = self.engine.batch_size
        self.step_mul = self.engine.step_mul
        self.n_red = self.engine.n_red
        self.n_blue = self.engine.n_blue
        self.state = self.engine.state
        self.step = self.engine.step

    def reset(self, battles: np.ndarray | None = None, seeds: np.ndarray | None = None) -> None:
        if battles is None:
            self.engine.reset(seeds=seeds)
            return
        battles = np.asarray(battles, dtype=np.int64)
        order = np.argsort(battles)  # the engine takes seeds in battle order
        mask = np.zeros(self.batch_size, dtype=bool)
        mask[battles] = True
        self.engine.reset(mask, None if seeds is None else np.asarray(seeds)[order])

    def close(self) -> None:
        pass


def make_backend(name: str, spec: MapSpec | str, batch_size: int = 1, step_mul: int = 8, **options) -> Backend:
    """Build a backend by name: ``"native"`` (embedded engine) or ``"sc2"`` (StarCraft II through PySC2)."""
    if name == "native":
        unknown = set(options) - {"cooldown_jitter"}
        if unknown:
            raise TypeError(f"backend 'native' takes only the option 'cooldown_jitter', got {sorted(unknown)}")
        return NativeBackend(spec, batch_size=batch_size, step_mul=step_mul, **options)
    if name == "sc2":
        from smac_hard_gym.sc2 import Sc2Backend  # optional extra, imported only when asked for

        return Sc2Backend(spec, batch_size=batch_size, step_mul=step_mul, **options)
    raise ValueError(f"unknown backend {name!r}; allowed: {', '.join(BACKENDS)}")
