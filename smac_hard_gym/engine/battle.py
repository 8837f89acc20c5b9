"""BattleEngine: ``batch_size`` battles of one map, their state, commands and the step that runs the kernels."""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

from smac_hard_gym.engine.batch_ops import count_alive, reset_battles
from smac_hard_gym.engine.direct import compiled_entry, is_plain
from smac_hard_gym.engine.kernels import GENERIC, step_batch, step_battles, step_kernels_for
from smac_hard_gym.engine.scenario import Layout, build_layout
from smac_hard_gym.engine.state import BattleState, Commands, Scratch, allocate_state
from smac_hard_gym.engine.terrain import Terrain, build_terrain
from smac_hard_gym.engine.units import STATS, UNITS
from smac_hard_gym.maps import MapSpec, load_map

PARALLEL_MIN_BATCH = 16  # below this many battles a step runs on the calling thread
# From this many battles on, the engine steps with kernel overloads compiled for the map's unit count
# (``specialize``; same results), for one compilation of about 20 s of CPU per unit count (then cached on disk; it
# was 90-130 s while they inlined every helper): worth it for long runs of big batches only.
SPECIALIZE_MIN_BATCH = 1024
# SC2 delays every attack by a random -0.0625 to +0.125 game seconds (weapon data RandomDelayMin/Max; SMAX draws the
# same range): -1 to +2 game loops.
SC2_COOLDOWN_JITTER = (-1.0, 2.0)
_MASK64 = (1 << 64) - 1
_BOOL, _INT8, _INT32, _FLOAT64 = (np.dtype(t) for t in (np.bool_, np.int8, np.int32, np.float64))


def _plain_commands(cmd: Commands) -> bool:
    """Commands of the one type the direct serial step compiles for: plain (B, U) int8, int32, float64, float64."""
    return (is_plain(cmd.kind, _INT8, 2) and is_plain(cmd.target, _INT32, 2) and is_plain(cmd.x, _FLOAT64, 2)
            and is_plain(cmd.y, _FLOAT64, 2))


def _splitmix64(value: int) -> int:
    """A well-mixed nonzero 64-bit state from any integer (seeds the battles' xorshift streams)."""
    z = (value + 0x9E3779B97F4A7C15) & _MASK64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK64
    return (z ^ (z >> 31)) or 1


class BattleEngine:
    """``batch_size`` battles of one map on the embedded simulator.

    The state is a :class:`BattleState` of arrays shaped ``(batch_size, n_units)``; red (learner) slots come first.
    ``step(commands)`` applies per-unit commands and advances ``step_mul`` game loops (8 = one SMAC step = half a
    Normal-speed second). Everything is deterministic: no random draw happens inside the engine.

    ``specialize`` steps with kernels compiled for this map's number of units (same results; the first use of a
    unit count compiles for about 20 s of CPU). None (default): only from ``SPECIALIZE_MIN_BATCH`` battles on. With
    one numba thread (``numba.set_num_threads(1)``, as ``train`` runs the engine) every batch steps on the calling
    thread, so the parallel driver is never compiled.
    """

    def __init__(self, map_spec: MapSpec | str, batch_size: int = 1, step_mul: int = 8,
                 cooldown_jitter: tuple[float, float] | None = SC2_COOLDOWN_JITTER, seed: int = 0,
                 specialize: bool | None = None) -> None:
        if not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
            raise ValueError(f"batch_size must be a positive int, got {batch_size!r}")
        if specialize is not None and not isinstance(specialize, bool):
            raise ValueError(f"specialize must be True, False or None (from {SPECIALIZE_MIN_BATCH} battles on), "
                             f"got {specialize!r}")
        if not isinstance(step_mul, (int, np.integer)) or step_mul < 1:
            raise ValueError(f"step_mul must be a positive int (game loops per step), got {step_mul!r}")
        self.spec: MapSpec = load_map(map_spec)
        self.layout: Layout = build_layout(self.spec)
        need_cliff = any(UNITS[t].cliff_walk for t in self.layout.utype)
        self.terrain: Terrain = build_terrain(self.spec, need_cliff)
        self.batch_size = int(batch_size)
        self.step_mul = int(step_mul)
        self.n_red = self.layout.n_red
        self.n_blue = self.layout.n_blue
        self.n_units = self.n_red + self.n_blue
        self.state: BattleState = allocate_state(self.batch_size, self.n_units)
        # The kernels read each slot's unit table row directly (a slot's type is fixed by the layout).
        self._slot_stats = np.ascontiguousarray(STATS[self.layout.utype])
        self._scratch = Scratch.empty(self.batch_size, self.n_units)  # the kernels' working arrays
        self._next_battle = np.zeros(1, dtype=np.int64)  # the parallel kernel's shared work counter
        self.commands = Commands.empty(self.batch_size, self.n_units)
        self._own_commands = self.commands  # plain by construction, whatever is later assigned to ``commands``
        self._all_active = np.ones(self.batch_size, dtype=np.bool_)
        if specialize is None:
            specialize = self.batch_size >= SPECIALIZE_MIN_BATCH
        self.specialized = specialize
        self._step_batch, self._step_battles, self._units = (step_kernels_for(self.n_units) if specialize
                                                             else (step_batch, step_battles, GENERIC))
        # numba's dispatcher types every argument on every call, each array of the state's 25 included: about 6 us a
        # step, as long as 3m's eight game loops at B=1. Every argument is this engine's own except the commands and
        # ``active``: once a serial step has compiled, steps whose commands and ``active`` are plain arrays of the
        # engine's dtypes call the overload the dispatcher chose for them directly.
        self._direct_serial: Any = None
        lo, hi = (0.0, 0.0) if cooldown_jitter is None else (float(cooldown_jitter[0]), float(cooldown_jitter[1]))
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi and lo > -8):
            raise ValueError(f"cooldown_jitter must be (low, high) game loops with -8 < low <= high, or None; "
                             f"got {cooldown_jitter!r}")
        self.cooldown_jitter = np.array([lo, hi], dtype=np.float64)
        self.state.rng[:] = [_splitmix64(int(seed) * self.batch_size + b) for b in range(self.batch_size)]
        self.reset()

    def __repr__(self) -> str:
        return f"BattleEngine(map={self.spec.name!r}, batch_size={self.batch_size}, step_mul={self.step_mul})"

    @property
    def red_slots(self) -> slice:
        return slice(0, self.n_red)

    @property
    def blue_slots(self) -> slice:
        return slice(self.n_red, self.n_units)

    def reset(self, mask: np.ndarray | None = None, seeds: np.ndarray | None = None) -> None:
        """Put battles back at their spawn layout (all battles, or those where ``mask`` is True).

        ``seeds`` (one int per reset battle) restarts their random streams; without it each battle's stream goes on.
        """
        if mask is None:
            rows = np.arange(self.batch_size)
        else:
            mask = np.asarray(mask, dtype=bool)
            if mask.shape != (self.batch_size,):
                raise ValueError(f"mask must be one bool per battle, shape ({self.batch_size},); "
                                 f"got shape {mask.shape}")
            rows = np.flatnonzero(mask)
        st, lay = self.state, self.layout
        if seeds is not None:
            seeds = np.atleast_1d(np.asarray(seeds))
            if seeds.shape != rows.shape:
                raise ValueError(f"seeds must give one int per reset battle ({len(rows)}), got shape {seeds.shape}")
            st.rng[rows] = [_splitmix64(int(s)) for s in seeds]
        reset_battles(st, rows, lay)

    def step(self, commands: Commands | None = None, active: np.ndarray | None = None,
             n_loops: int | None = None) -> None:
        """Apply ``commands`` (default: the engine's own ``self.commands`` buffer) and run the game loops.

        ``active`` (bool, per battle) skips battles that are waiting for a reset.
        """
        cmd = self.commands if commands is None else commands
        act = self._all_active if active is None else np.ascontiguousarray(active, dtype=np.bool_)
        args = (self.state, cmd, self._slot_stats, self.terrain, self.step_mul if n_loops is None else int(n_loops),
                act, self.cooldown_jitter, self._scratch, self._units)
        # One thread (a training run's engine: ``train --env-threads 1``) steps on the calling thread whatever the
        # batch: the parallel driver would run the same battles in the same order, and it is not compiled at all.
        threads = numba.get_num_threads() if self.batch_size >= PARALLEL_MIN_BATCH else 1
        if threads > 1:
            self._step_batch(*args[:-1], threads, self._next_battle, self._units)
            return
        plain = ((cmd is self._own_commands or _plain_commands(cmd))
                 and (act is self._all_active or is_plain(act, _BOOL, 1)))
        if plain and self._direct_serial is not None:
            self._direct_serial(0, self.batch_size, *args)
            return
        self._step_battles(0, self.batch_size, *args)
        if plain:
            self._direct_serial = compiled_entry(self._step_battles, (0, self.batch_size, *args))

    def alive_counts(self) -> tuple[np.ndarray, np.ndarray]:
        """Alive units per battle: (red, blue), each shaped (B,)."""
        return count_alive(self.state.alive, self.n_red)

    def place(self, battle: int, slot: int, **values: float) -> None:
        """Set fields of one unit by hand (tests, constructed scenarios): x, y, health, shield, energy, alive....

        A slot's unit type is fixed by the map's layout: build a map with the units you need instead.
        """
        for name, value in values.items():
            if name not in BattleState._fields:
                raise KeyError(f"unknown state field {name!r}; fields: {', '.join(BattleState._fields)}")
            if name == "utype":
                raise ValueError(f"a slot's unit type is fixed by the map's layout (slot {slot} is "
                                 f"{UNITS[self.layout.utype[slot]].name!r}); use a map with the units you need")
            getattr(self.state, name)[battle, slot] = value
