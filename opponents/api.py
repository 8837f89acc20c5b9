"""The opponent contract: a script sees a side view of a batch of battles and writes commands for its units.

This is the hook of the two-player core. The core calls, for the scripted side:

- ``script.reset(view, battles, rngs)`` when the battles with indices ``battles`` start a new episode (``rngs[b]`` is
  battle b's seeded generator: every random choice a script makes comes from it);
- ``script.act(view, commands, active)`` once per env step before the engine advances; the script writes
  ``commands.kind/target/x/y[b, slot]`` for its own slots in battles where ``active[b]`` (``CMD_NOOP`` keeps the
  unit's current order). Targets are absolute unit slots (``view.enemy_slot(k)`` converts an enemy index).

Built-in scripts handle the whole batch in one call with per-battle memory kept in arrays. A trained policy, a pool of
scripts or any callable can sit behind the same two methods.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smac_hard_gym.engine.state import BattleState, Commands
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.units import STATS, S


@dataclass
class SideView:
    """One side's view of B battles: its own units and the enemy's, as (B, n) array views (no copies).

    ``episode_step[b]`` counts env steps since battle b's reset (0 on the first step).
    """

    state: BattleState
    spec: MapSpec
    side: int  # RED (0) or BLUE (1)
    own: slice  # slots of this side's units
    enemy: slice  # slots of the other side's units
    episode_step: np.ndarray  # int64 (B,)

    @property
    def n_own(self) -> int:
        return self.own.stop - self.own.start

    @property
    def n_enemy(self) -> int:
        return self.enemy.stop - self.enemy.start

    @property
    def batch_size(self) -> int:
        return self.state.alive.shape[0]

    def enemy_slot(self, k: np.ndarray | int) -> np.ndarray | int:
        """Absolute slot of enemy index ``k`` (0-based within the enemy side)."""
        return self.enemy.start + k

    def own_slot(self, k: np.ndarray | int) -> np.ndarray | int:
        return self.own.start + k

    def _field(self, name: str, which: slice) -> np.ndarray:
        return getattr(self.state, name)[:, which]

    def _stat(self, column: str, which: slice) -> np.ndarray:
        return STATS[self.state.utype[:, which], S[column]]

    # Own units.
    own_type = property(lambda self: self._field("utype", self.own))
    own_alive = property(lambda self: self._field("alive", self.own))
    own_x = property(lambda self: self._field("x", self.own))
    own_y = property(lambda self: self._field("y", self.own))
    own_health = property(lambda self: self._field("health", self.own))
    own_shield = property(lambda self: self._field("shield", self.own))
    own_energy = property(lambda self: self._field("energy", self.own))
    own_cooldown = property(lambda self: self._field("cooldown", self.own))
    own_order = property(lambda self: self._field("order", self.own))
    own_target = property(lambda self: self._field("target", self.own))
    own_health_max = property(lambda self: self._stat("health", self.own))
    own_shield_max = property(lambda self: self._stat("shield", self.own))
    # Enemy units.
    enemy_type = property(lambda self: self._field("utype", self.enemy))
    enemy_alive = property(lambda self: self._field("alive", self.enemy))
    enemy_x = property(lambda self: self._field("x", self.enemy))
    enemy_y = property(lambda self: self._field("y", self.enemy))
    enemy_health = property(lambda self: self._field("health", self.enemy))
    enemy_shield = property(lambda self: self._field("shield", self.enemy))
    enemy_energy = property(lambda self: self._field("energy", self.enemy))
    enemy_cooldown = property(lambda self: self._field("cooldown", self.enemy))
    enemy_order = property(lambda self: self._field("order", self.enemy))
    enemy_target = property(lambda self: self._field("target", self.enemy))
    enemy_health_max = property(lambda self: self._stat("health", self.enemy))
    enemy_shield_max = property(lambda self: self._stat("shield", self.enemy))


class Script:
    """Base class of batched opponent scripts. Subclasses set ``name``/``description`` and override ``act``."""

    name: str = "script"
    description: str = ""

    def reset(self, view: SideView, battles: np.ndarray, rngs: list[np.random.Generator]) -> None:
        """Clear per-battle memory for ``battles`` (int indices) at the start of their episodes."""

    def act(self, view: SideView, commands: Commands, active: np.ndarray) -> None:
        """Write this side's commands for every battle with ``active[b]``."""
        raise NotImplementedError

    def name_of(self, battle: int) -> str:
        """Name of the script playing battle ``battle`` this episode (a mixture answers per battle)."""
        return self.name

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}>"
