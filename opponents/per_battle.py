"""Plain per-battle scripts: write the tactic for one battle, the adapter runs it over the batch.

Subclass :class:`PerBattleScript` and implement ``act_battle(battle)``; optionally ``reset_battle(battle)``::

    class Closest(PerBattleScript):
        name = "closest"

        def act_battle(self, battle):
            for i in battle.own.alive_indices():
                k = battle.nearest_enemy(i)
                if k >= 0:
                    battle.attack(i, k)

``battle`` is a :class:`BattleView`: this side's units (``battle.own``) and the enemy's (``battle.enemy``) as small
1-D arrays, the step number, the battle's seeded generator ``rng`` and a ``memory`` dict kept for the episode.
Orders use side-local indices (unit i of this side, enemy k). The adapter calls ``act_battle`` once per active
battle per step: simple to write, but a Python call per battle; built-in scripts use the batched form instead
(:class:`~smac_hard_gym.opponents.helpers.BatchScript`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smac_hard_gym.engine.state import (
    CMD_ATTACK,
    CMD_ATTACK_MOVE,
    CMD_HEAL,
    CMD_HOLD,
    CMD_MOVE,
    CMD_STOP,
    Commands,
)
from smac_hard_gym.engine.units import STATS, S
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.opponents.api import Script, SideView

__all__ = ["PerBattleScript", "BattleView", "UnitRows"]


class UnitRows:
    """One side's units in one battle as 1-D arrays (views into the batch state: read-only under the guard, whose
    state is a read-only copy; do not write them either way)."""

    def __init__(self, view: SideView, battle: int, which: slice) -> None:
        st = view.state
        self.type = st.utype[battle, which]
        self.alive = st.alive[battle, which]
        self.x = st.x[battle, which]
        self.y = st.y[battle, which]
        self.health = st.health[battle, which]
        self.shield = st.shield[battle, which]
        self.energy = st.energy[battle, which]
        self.cooldown = st.cooldown[battle, which]
        self.order = st.order[battle, which]
        self.health_max = STATS[self.type, S["health"]]
        self.shield_max = STATS[self.type, S["shield"]]
        self.radius = STATS[self.type, S["radius"]]
        self.range = STATS[self.type, S["range"]]

    def __len__(self) -> int:
        return len(self.alive)

    def alive_indices(self) -> np.ndarray:
        return np.flatnonzero(self.alive)

    @property
    def hp(self) -> np.ndarray:
        """Health + shield."""
        return self.health + self.shield


class BattleView:
    """One battle seen by one side, with order methods that write this battle's commands."""

    def __init__(self, view: SideView, commands: Commands | None, battle: int, rng: np.random.Generator | None,
                 memory: dict[str, Any]) -> None:
        self.index = battle
        self.spec: MapSpec = view.spec
        self.side = view.side
        self.step = int(view.episode_step[battle])
        self.rng = rng
        self.memory = memory
        self.own = UnitRows(view, battle, view.own)
        self.enemy = UnitRows(view, battle, view.enemy)
        self._own_start = view.own.start
        self._enemy_start = view.enemy.start
        self._commands = commands

    # Queries.
    def distances(self, i: int) -> np.ndarray:
        """Centre distance from own unit i to every enemy (inf for dead enemies)."""
        d = np.hypot(self.enemy.x - self.own.x[i], self.enemy.y - self.own.y[i])
        return np.where(self.enemy.alive, d, np.inf)

    def nearest_enemy(self, i: int) -> int:
        """Index of the alive enemy nearest own unit i, or -1."""
        d = self.distances(i)
        return int(d.argmin()) if np.isfinite(d).any() else -1

    def weakest_enemy(self) -> int:
        """Index of the alive enemy with the lowest health + shield, or -1."""
        hp = np.where(self.enemy.alive, self.enemy.hp, np.inf)
        return int(hp.argmin()) if np.isfinite(hp).any() else -1

    # Orders (side-local indices).
    def _write(self, i: int, kind: int, target: int = -1, x: float = 0.0, y: float = 0.0) -> None:
        if self._commands is None:
            raise RuntimeError("orders can only be given in act_battle(), not in reset_battle()")
        slot = self._own_start + int(i)
        self._commands.kind[self.index, slot] = kind
        self._commands.target[self.index, slot] = target
        self._commands.x[self.index, slot] = x
        self._commands.y[self.index, slot] = y

    def attack(self, i: int, k: int) -> None:
        """Own unit i attacks enemy k."""
        self._write(i, CMD_ATTACK, target=self._enemy_start + int(k))

    def heal(self, i: int, j: int) -> None:
        """Own unit i (a medivac) heals own unit j."""
        self._write(i, CMD_HEAL, target=self._own_start + int(j))

    def move(self, i: int, x: float, y: float) -> None:
        self._write(i, CMD_MOVE, x=float(x), y=float(y))

    def attack_move(self, i: int, x: float, y: float) -> None:
        self._write(i, CMD_ATTACK_MOVE, x=float(x), y=float(y))

    def stop(self, i: int) -> None:
        self._write(i, CMD_STOP)

    def hold(self, i: int) -> None:
        self._write(i, CMD_HOLD)


class PerBattleScript(Script):
    """Adapter for scripts written one battle at a time (see the module docstring)."""

    name = "per_battle"

    def __init__(self) -> None:
        self._memory: list[dict[str, Any]] = []
        self._rngs: list[np.random.Generator | None] = []

    def _ensure(self, batch: int) -> None:
        # Subclasses may forget super().__init__(): allocate lazily.
        if not hasattr(self, "_memory") or len(self._memory) != batch:
            self._memory = [{} for _ in range(batch)]
            self._rngs = [None] * batch

    def reset(self, view: SideView, battles: np.ndarray, rngs: list[np.random.Generator]) -> None:
        self._ensure(view.batch_size)
        for b in np.asarray(battles, dtype=np.int64):
            b = int(b)
            self._memory[b] = {}
            self._rngs[b] = rngs[b]
            self.reset_battle(BattleView(view, None, b, rngs[b], self._memory[b]))

    def act(self, view: SideView, commands: Commands, active: np.ndarray) -> None:
        self._ensure(view.batch_size)
        for b in np.flatnonzero(active):
            b = int(b)
            self.act_battle(BattleView(view, commands, b, self._rngs[b], self._memory[b]))

    def reset_battle(self, battle: BattleView) -> None:
        """Called when the battle starts an episode (``battle.memory`` is a fresh dict). Give orders in
        ``act_battle``: order methods raise here."""

    def act_battle(self, battle: BattleView) -> None:
        """Give this battle's orders for the step."""
        raise NotImplementedError
