"""The opponent contract: a script sees a side view of a batch of battles and writes commands for its units.

This is the hook of the two-player core (and of the duel runner). For the scripted side the caller does:

- ``script.reset(view, battles, rngs)`` when the battles with indices ``battles`` start a new episode (``rngs[b]`` is
  battle b's seeded generator: every random choice a script makes comes from it);
- ``script.act(view, commands, active)`` once per env step before the engine advances; the script writes
  ``commands.kind/target/x/y[b, slot]`` for its own slots in battles where ``active[b]`` (``CMD_NOOP`` keeps the
  unit's current order). Targets are absolute unit slots (``view.enemy_slot(k)`` converts an enemy index).

Built-in scripts handle the whole batch in one call with per-battle memory kept in arrays (see
:mod:`smac_hard_gym.opponents.helpers` for the gathered :class:`~smac_hard_gym.opponents.helpers.Frame` and the
:class:`~smac_hard_gym.opponents.helpers.Orders` command builder). A plain per-battle script is written with
:class:`~smac_hard_gym.opponents.per_battle.PerBattleScript`. A trained policy, a pool of scripts or any callable can
sit behind the same two methods.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from smac_hard_gym.engine.state import BLUE, RED, BattleState, Commands
from smac_hard_gym.engine.units import STATS, S
from smac_hard_gym.maps import MapSpec, UnitGroup

__all__ = ["SideView", "Script", "ScriptError", "RED", "BLUE", "spawn_centre", "read_only_spec", "frozen_copy"]


class ScriptError(RuntimeError):
    """An opponent script failed: it raised, ran past its time limit or wrote an invalid command.

    The message names the script, the map and the cause; ``script``, ``map_name`` and ``cause`` hold them too.
    """

    def __init__(self, script: str, map_name: str, cause: str) -> None:
        super().__init__(f"opponent script {script!r} on map {map_name!r}: {cause}")
        self.script = script
        self.map_name = map_name
        self.cause = cause

    def __reduce__(self):
        # The default reduce rebuilds from the one-string ``args``, which does not fit __init__: crossing a process
        # boundary (vector env workers, the sandbox) would lose the class and its fields. __dict__ carries notes.
        return type(self), (self.script, self.map_name, self.cause), dict(self.__dict__)


def spawn_centre(groups: tuple[UnitGroup, ...]) -> np.ndarray:
    """Mean spawn point of a side's unit groups, weighted by unit count (shape (2,))."""
    points = np.array([g.spawn for g in groups], dtype=np.float64)
    counts = np.array([g.count for g in groups], dtype=np.float64)
    return (points * counts[:, None]).sum(axis=0) / counts.sum()


class lazy_property(cached_property):
    """:func:`functools.cached_property` without its lock: computed on first access, then stored in the instance's
    ``__dict__`` (which later lookups find first). Python 3.11's cached_property takes an RLock on every first
    access, a large share of a B=1 script step that reads a dozen fresh attributes."""

    def __get__(self, instance, owner=None):
        if instance is None:
            return self
        value = self.func(instance)
        instance.__dict__[self.attrname] = value
        return value


# Per-map geometry of each side, keyed by the spec object's identity (the spec is kept in the entry, so an id is
# never reused while its entry lives): computed once per map and side instead of once per view.
_GEOMETRY: dict[tuple[int, int], tuple[MapSpec, np.ndarray, np.ndarray, np.ndarray]] = {}


def _side_geometry(spec: MapSpec, side: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(own spawn, enemy spawn, forward) of ``side`` on ``spec``, read-only (2,) arrays shared by every view."""
    entry = _GEOMETRY.get((id(spec), side))
    if entry is None or entry[0] is not spec:
        own = spawn_centre(spec.red if side == RED else spec.blue)
        enemy = spawn_centre(spec.blue if side == RED else spec.red)
        d = enemy - own
        norm = float(np.hypot(d[0], d[1]))
        forward = d / norm if norm > 1e-9 else np.array([1.0, 0.0])
        for a in (own, enemy, forward):
            a.flags.writeable = False
        if len(_GEOMETRY) >= 256:
            _GEOMETRY.clear()
        entry = _GEOMETRY[(id(spec), side)] = (spec, own, enemy, forward)
    return entry[1], entry[2], entry[3]


def frozen_copy(array: np.ndarray) -> np.ndarray:
    """A read-only copy of ``array`` (what untrusted scripts are handed)."""
    out = np.array(array, copy=True)
    out.flags.writeable = False
    return out


def read_only_spec(spec: MapSpec) -> MapSpec:
    """``spec`` with read-only copies of its terrain arrays (the engine's own spec stays as it is)."""
    return replace(spec, pathable=frozen_copy(spec.pathable), cliff=frozen_copy(spec.cliff))


@dataclass
class SideView:
    """One side's view of B battles: its own units and the enemy's, as (B, n) array views (no copies).

    Built-in scripts get views of the live state and must not write them; the guard hands user scripts
    :meth:`read_only` copies instead, so a write fails there rather than corrupting the battle.

    ``episode_step[b]`` counts env steps since battle b's reset (0 on the first step). Own and enemy indices are
    0-based within each side; ``own_slot``/``enemy_slot`` turn them into the absolute slots that commands use.
    """

    state: BattleState
    spec: MapSpec
    side: int  # RED (0) or BLUE (1)
    own: slice  # slots of this side's units
    enemy: slice  # slots of the other side's units
    episode_step: np.ndarray  # int64 (B,)

    @classmethod
    def of(cls, state: BattleState, spec: MapSpec, side: int, episode_step: np.ndarray) -> SideView:
        """The view of ``side`` (RED or BLUE) over a state whose red slots come first."""
        if side not in (RED, BLUE):
            raise ValueError(f"side must be RED ({RED}) or BLUE ({BLUE}), got {side!r}")
        n_red, n_units = spec.n_red, state.alive.shape[1]
        red, blue = slice(0, n_red), slice(n_red, n_units)
        own, enemy = (red, blue) if side == RED else (blue, red)
        return cls(state=state, spec=spec, side=side, own=own, enemy=enemy, episode_step=episode_step)

    def read_only(self, spec: MapSpec | None = None) -> SideView:
        """A copy of this view over read-only copies of the state and step counter, for untrusted scripts.

        Writes raise ValueError, and a script that turns ``flags.writeable`` back on only changes its copy, never
        the engine. ``spec``: a read-only twin of ``self.spec`` made earlier by :func:`read_only_spec` (made here
        when None).
        """
        state = BattleState(*(frozen_copy(a) for a in self.state))
        return SideView(state=state, spec=read_only_spec(self.spec) if spec is None else spec, side=self.side,
                        own=self.own, enemy=self.enemy, episode_step=frozen_copy(self.episode_step))

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
        """Absolute slot of own index ``k`` (0-based within this side)."""
        return self.own.start + k

    # Map geometry from this side's point of view (fixed for the view's life).
    # Computed once per map and side (see _side_geometry) and shared read-only by every view of it.
    @lazy_property
    def own_spawn(self) -> np.ndarray:
        """This side's spawn point (count-weighted mean of its groups), shape (2,), read-only."""
        return _side_geometry(self.spec, self.side)[0]

    @lazy_property
    def enemy_spawn(self) -> np.ndarray:
        """The other side's spawn point, shape (2,), read-only."""
        return _side_geometry(self.spec, self.side)[1]

    @lazy_property
    def forward(self) -> np.ndarray:
        """Unit vector from this side's spawn toward the enemy's (the direction of advance), read-only."""
        return _side_geometry(self.spec, self.side)[2]

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
    own_radius = property(lambda self: self._stat("radius", self.own))
    own_range = property(lambda self: self._stat("range", self.own))
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
    enemy_radius = property(lambda self: self._stat("radius", self.enemy))
    enemy_range = property(lambda self: self._stat("range", self.enemy))


class Script:
    """Base class of batched opponent scripts. Subclasses set ``name``/``description`` and override ``act``.

    ``reset`` receives the battles that start an episode and their seeded generators; ``act`` writes commands for
    this side's units in every active battle. ``name_of(b)`` names the script playing battle b (a mixture answers
    per battle; it is what ``info["opponent"]`` reports).
    """

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

    def names_of(self, battles: np.ndarray) -> list[str]:
        """:meth:`name_of` for each of ``battles`` (asked after every reset, so kept cheap for large batches)."""
        if type(self).name_of is Script.name_of:
            return [self.name] * len(battles)
        return [self.name_of(int(b)) for b in battles]

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}>"
