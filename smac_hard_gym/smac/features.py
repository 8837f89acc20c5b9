"""SMAC's observations, global state, reward and battle outcome, batched, for either side of a battle.

Everything here is a function of a :class:`~smac_hard_gym.engine.state.BattleState` (arrays ``(B, U)`` over B
battles) and a side: :class:`SideFeatures` holds one side's constants (which slots are "own" and "enemy", health
and shield normalisers, unit-type one-hots) and the feature-name lists that define every offset and size. The red
side's view is SMAC's (``docs/smac_interface.md`` §3-§6); the blue side gets the same encoding from its
own side (SMAC-HARD's self-play layout). The arithmetic runs in :mod:`smac_hard_gym.smac.kernels`, one compiled
pass per feature block over the batch; this module holds the constants, sizes and names the kernels are given.

Observation of agent i (float32), blocks in this order; a dead agent's observation is all zero except the timestep:

=====================  ==================================================================================
block                  columns
=====================  ==================================================================================
move                   can move north, south, east, west; [8 pathing values]; [9 terrain heights]
enemy e (each)         attackable, distance/9, dx/9, dy/9, [health, [shield]], [type one-hot]
ally k (others, each)  visible, distance/9, dx/9, dy/9, [health, [shield]], [type one-hot], [last action]
own                    [health, [shield]], [type one-hot], [timestep]
=====================  ==================================================================================

Enemy and ally rows are zero unless the unit is alive and closer than the sight range 9. Global state (float32):
own rows (health, energy/cooldown, rel_x, rel_y, [shield], [type]) then enemy rows (health, rel_x, rel_y,
[shield], [type]), then [last actions of every own agent] and [timestep]; rows of dead units are zero.

Unit-type one-hots: each team keeps one scheme in both teams' views. Red's ``*_RL`` units are numbered in
alphabetical order of their SC2 names (SMAC's ``unit_type - min_unit_type``); blue's standard units follow SMAC's
enemy table per ``map_type`` (on ``stalkers_and_zealots`` maps that puts the zealot first, the reverse of red's
order: SMAC's quirk, kept so that red's view is SMAC's).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np

from smac_hard_gym.engine.direct import DirectKernel, is_plain
from smac_hard_gym.engine.state import BLUE, RED, BattleState
from smac_hard_gym.engine.terrain import cliff_height
from smac_hard_gym.engine.units import STATS, UNITS, WEAPON_HEAL, S, unit_index
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.smac import kernels as fk
from smac_hard_gym.smac.kernels import (
    BLUE_WON,
    DRAW,
    N_ACTIONS_NO_ATTACK,
    RED_WON,
    RUNNING,
    SHOOT_RANGE,
    SIGHT_RANGE,
)

__all__ = [
    "SmacOptions", "SideFeatures", "RewardFunction", "last_action_onehot",
    "SHOOT_RANGE", "SIGHT_RANGE", "N_ACTIONS_NO_ATTACK", "RUNNING", "RED_WON", "BLUE_WON", "DRAW", "SIDE_NAMES",
]

MOVE_NAMES = ("move_north", "move_south", "move_east", "move_west")

SIDE_NAMES = ("red", "blue")

# Points around (int(x), int(y)) probed by obs_pathing_grid / obs_terrain_height, in units of move_amount, in
# SMAC's order; the terrain-height block adds the unit's own cell last.
_SURROUNDING = ((0, 2), (0, -2), (2, 0), (-2, 0), (1, 1), (-1, -1), (1, -1), (-1, 1))
_SURROUNDING_NAMES = ("n2", "s2", "e2", "w2", "ne", "sw", "se", "nw")

# SMAC's one-hot index of the opponent's standard units per map_type (docs/smac_interface.md §3).
_STANDARD_TYPE_ORDER = {
    "MMM": ("marauder", "marine", "medivac"),
    "stalkers_and_zealots": ("zealot", "stalker"),
    "colossi_stalkers_zealots": ("colossus", "stalker", "zealot"),
    "bane": ("baneling", "zergling"),
}

_INT64, _BOOL = np.dtype(np.int64), np.dtype(np.bool_)

_SMAC_MAX_COOLDOWN = np.array([u.smac_max_cooldown for u in UNITS], dtype=np.float64)


@dataclass(frozen=True)
class SmacOptions:
    """SMAC's observation, state and reward options (constructor arguments of SMAC's ``StarCraft2Env``).

    ``obs_all_health=True`` implies own health (SMAC forces ``obs_own_health`` on); see :attr:`own_health`.
    """

    obs_all_health: bool = True
    obs_own_health: bool = True
    obs_last_action: bool = False
    obs_pathing_grid: bool = False
    obs_terrain_height: bool = False
    obs_instead_of_state: bool = False
    obs_timestep_number: bool = False
    state_last_action: bool = True
    state_timestep_number: bool = False
    reward_sparse: bool = False
    reward_only_positive: bool = True
    reward_abs: bool = False  # with reward_only_positive: SMAC v1's |dmg + kills| (pays enemy regeneration)
    reward_death_value: float = 10.0
    reward_win: float = 200.0
    reward_defeat: float = 0.0
    reward_negative_scale: float = 0.5
    reward_scale: bool = True
    reward_scale_rate: float = 20.0
    move_amount: float = 2.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.type in ("bool", bool):
                if not isinstance(value, (bool, np.bool_)):
                    raise TypeError(f"option {f.name} must be True or False, got {value!r}")
            elif isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                    or not math.isfinite(value):
                raise TypeError(f"option {f.name} must be a finite number, got {value!r}")
        if self.move_amount <= 0:
            raise ValueError(f"option move_amount must be > 0, got {self.move_amount!r}")
        if self.reward_scale and self.reward_scale_rate <= 0:
            raise ValueError(f"option reward_scale_rate must be > 0 when reward_scale is on, "
                             f"got {self.reward_scale_rate!r}")

    @property
    def own_health(self) -> bool:
        return bool(self.obs_all_health or self.obs_own_health)

    @classmethod
    def from_kwargs(cls, env_keywords: Sequence[str] = (), /, **kwargs) -> SmacOptions:
        """Build from keyword arguments, naming any unknown one; an env passes its own keywords as
        ``env_keywords`` so the error lists every keyword it takes."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(kwargs) - known)
        if unknown and env_keywords:
            raise TypeError(f"unknown keyword(s) {unknown}; the env takes {sorted(env_keywords)} and SMAC's options "
                            f"{sorted(known)}")
        if unknown:
            raise TypeError(f"unknown SMAC option(s) {unknown}; allowed: {sorted(known)}")
        return cls(**kwargs)


def slot_types(spec: MapSpec) -> np.ndarray:
    """Unit-table row of every slot, as the engine lays them out: red sorted by SMAC's custom type id (the ``*_RL``
    ids follow the alphabetical order of their names), then blue in creation order."""
    red = [unit_index(g.unit) for g in spec.red for _ in range(g.count)]
    red.sort(key=lambda t: UNITS[t].sc2_name)  # stable: same-type units keep their places
    blue = [unit_index(g.unit) for g in spec.blue for _ in range(g.count)]
    return np.array(red + blue, dtype=np.int32)


def team_type_columns(spec: MapSpec, utype: np.ndarray, n_red: int) -> np.ndarray:
    """One-hot column of every slot's unit type (-1 where the map has no type bits); see the module docstring."""
    bits = spec.unit_type_bits
    cols = np.full(len(utype), -1, dtype=np.int64)
    if bits == 0:
        return cols
    red_names = sorted({UNITS[t].sc2_name for t in utype[:n_red]})
    for k, t in enumerate(utype[:n_red]):
        cols[k] = red_names.index(UNITS[t].sc2_name)
    table = _STANDARD_TYPE_ORDER.get(spec.map_type, ())
    seen: list[str] = []
    for k, t in enumerate(utype[n_red:], start=n_red):
        base = UNITS[t].base
        if base in table:
            cols[k] = table.index(base)
        else:
            if base not in seen:
                seen.append(base)
            cols[k] = seen.index(base)
    if cols.max() >= bits:
        raise ValueError(f"map {spec.name!r}: unit_type_bits={bits} cannot one-hot its unit types "
                         f"(column {int(cols.max())} needed); raise unit_type_bits in the map file")
    return cols


def last_action_onehot(last_action: np.ndarray, n_actions: int) -> np.ndarray:
    """One-hot float32 ``(B, n, n_actions)`` of actions ``(B, n)``; -1 (no action yet) gives a zero row."""
    return (last_action[..., None] == np.arange(n_actions)).astype(np.float32)


# A Columns field names its feature as the feature-name lists do, except these (the first column of a group).
_COLUMN_NAMES = {"type": "type_0", "last_action": "last_action_0", "cooldown": "energy/cooldown"}


def _column(names: list[str], name: str) -> int:
    """Where ``name`` is in ``names``; -1 when the options leave it out."""
    return names.index(name) if name in names else -1


def _row_columns(prefix: str, names: list[str]) -> dict[str, int]:
    """The :class:`~smac_hard_gym.smac.kernels.Columns` fields ``{prefix}_{feature}`` of one row's name list:
    each feature's column in the row (the row's offset and width are the caller's)."""
    columns = {}
    for field in fk.Columns._fields:
        feature = field.removeprefix(f"{prefix}_")
        if feature != field and feature not in ("offset", "feats"):
            columns[field] = _column(names, _COLUMN_NAMES.get(feature, feature))
    return columns


class SideFeatures:
    """SMAC's features from one side's point of view on one map, for a batch of battles.

    ``side`` is RED (SMAC's agents) or BLUE (the opponent, self-play). Sizes and offsets all derive from the
    feature-name lists (``move_names``, ``enemy_names``, ``ally_names``, ``own_names``, ``ally_state_names``,
    ``enemy_state_names``); ``obs_feature_names()`` / ``state_feature_names()`` name every column.
    """

    def __init__(self, spec: MapSpec, side: int, options: SmacOptions | None = None) -> None:
        if side not in (RED, BLUE):
            raise ValueError(f"side must be RED (0) or BLUE (1), got {side!r}")
        self.spec = spec
        self.side = side
        self.options = opt = options or SmacOptions()
        utype = slot_types(spec)
        n_red, n_units = spec.n_red, len(utype)
        red, blue = slice(0, n_red), slice(n_red, n_units)
        self.own, self.enemy = (red, blue) if side == RED else (blue, red)
        self.n_agents = self.own.stop - self.own.start
        self.n_enemies = self.enemy.stop - self.enemy.start
        self.n_actions = N_ACTIONS_NO_ATTACK + self.n_enemies
        own_race, enemy_race = (spec.red_race, spec.blue_race) if side == RED else (spec.blue_race, spec.red_race)
        self.shield_bits_ally = int(own_race == "P")
        self.shield_bits_enemy = int(enemy_race == "P")
        self.unit_type_bits = bits = spec.unit_type_bits
        self.episode_limit = spec.episode_limit
        self.move_amount = float(opt.move_amount)

        # Per-slot constants.
        self.utype = utype
        health_max = STATS[utype, S["health"]]
        shield_max = STATS[utype, S["shield"]]
        self.own_health_max, self.enemy_health_max = health_max[self.own], health_max[self.enemy]
        # Units without shields on a Protoss side get a zero column instead of a division by zero.
        self.own_shield_max = np.where(shield_max[self.own] > 0, shield_max[self.own], np.inf)
        self.enemy_shield_max = np.where(shield_max[self.enemy] > 0, shield_max[self.enemy], np.inf)
        self.own_max_cooldown = _SMAC_MAX_COOLDOWN[utype[self.own]]
        healer = STATS[utype, S["weapon"]] == WEAPON_HEAL
        self.own_healer = healer[self.own]
        self.n_heal_targets = min(self.n_agents, self.n_enemies)  # 6+j addresses ally j only for j < n_enemies
        cols = team_type_columns(spec, utype, n_red)
        onehot = np.zeros((n_units, bits), dtype=np.float32)
        if bits:
            onehot[np.arange(n_units), cols] = 1.0
        self.own_onehot, self.enemy_onehot = onehot[self.own], onehot[self.enemy]
        n = self.n_agents

        # Terrain.
        self.map_x, self.map_y = spec.size
        self.pathable = np.ascontiguousarray(spec.pathable, dtype=bool)
        self.terrain_height = ((cliff_height(spec.cliff) + 16.0) / 32.0).astype(np.float32)  # SC2 byte / 255
        self.center = (self.map_x / 2.0, self.map_y / 2.0)
        self.max_distance = (float(self.map_x), float(self.map_y))
        ma = int(self.move_amount)
        self._probe_dx = np.array([dx * ma for dx, _ in _SURROUNDING] + [0], dtype=np.int64)
        self._probe_dy = np.array([dy * ma for _, dy in _SURROUNDING] + [0], dtype=np.int64)

        # Feature-name lists: every size and offset below derives from them.
        health = (["health"] + ["shield"] * self.shield_bits_ally) if opt.obs_all_health else []
        enemy_health = (["health"] + ["shield"] * self.shield_bits_enemy) if opt.obs_all_health else []
        types = [f"type_{k}" for k in range(bits)]
        self.move_names = list(MOVE_NAMES)
        if opt.obs_pathing_grid:
            self.move_names += [f"pathing_{p}" for p in _SURROUNDING_NAMES]
        if opt.obs_terrain_height:
            self.move_names += [f"height_{p}" for p in _SURROUNDING_NAMES] + ["height_self"]
        self.enemy_names = ["attackable", "distance", "rel_x", "rel_y"] + enemy_health + types
        self.ally_names = ["visible", "distance", "rel_x", "rel_y"] + health + types
        if opt.obs_last_action:
            self.ally_names += [f"last_action_{a}" for a in range(self.n_actions)]
        own_health = (["health"] + ["shield"] * self.shield_bits_ally) if opt.own_health else []
        # SMAC reserves an own-block slot for the timestep and then appends another one (obs one longer than
        # get_obs_size); we write the timestep into the reserved slot, so the length is get_obs_size().
        self.own_names = own_health + types + (["timestep"] * opt.obs_timestep_number)
        self.ally_state_names = ["health", "energy/cooldown", "rel_x", "rel_y"] + ["shield"] * \
            self.shield_bits_ally + types
        self.enemy_state_names = ["health", "rel_x", "rel_y"] + ["shield"] * self.shield_bits_enemy + types

        self.move_size = len(self.move_names)
        self.enemy_feats = len(self.enemy_names)
        self.ally_feats = len(self.ally_names)
        self.own_size = len(self.own_names)
        self.enemy_offset = self.move_size
        self.ally_offset = self.enemy_offset + self.n_enemies * self.enemy_feats
        self.own_offset = self.ally_offset + (n - 1) * self.ally_feats
        self.obs_size = self.own_offset + self.own_size
        self.ally_state_feats = len(self.ally_state_names)
        self.enemy_state_feats = len(self.enemy_state_names)
        self.state_enemy_offset = n * self.ally_state_feats
        self.state_action_offset = self.state_enemy_offset + self.n_enemies * self.enemy_state_feats
        if opt.obs_instead_of_state:
            self.state_size = n * self.obs_size
        else:
            self.state_size = (self.state_action_offset + opt.state_last_action * n * self.n_actions
                               + opt.state_timestep_number)

        self.heal_target_ok = ~self.own_healer[:self.n_heal_targets]
        self._all_rows = np.arange(0, dtype=np.int64)
        self._units: tuple[BattleState | None, fk.UnitArrays | None, bool] = (None, None, False)  # the last state's
        # The kernels called on every step of some APIs (blue's encoding in self-play, a policy opponent's), past
        # numba's dispatcher once compiled for plain arrays.
        self._encode_batch = DirectKernel(fk.encode_batch)
        self._available_actions_batch = DirectKernel(fk.available_actions_batch)

        # The kernels' inputs: this side's constants, and every column from the name lists above.
        self.constants = fk.SideConstants(
            actions=fk.ActionConstants(own_lo=self.own.start, enemy_lo=self.enemy.start, healer=self.own_healer,
                                       heal_target_ok=self.heal_target_ok, pathable=self.pathable,
                                       move_amount=self.move_amount),
            heights=self.terrain_height, own_health_max=self.own_health_max, own_shield_max=self.own_shield_max,
            enemy_health_max=self.enemy_health_max, enemy_shield_max=self.enemy_shield_max,
            own_onehot=self.own_onehot, enemy_onehot=self.enemy_onehot, max_cooldown=self.own_max_cooldown,
            probe_dx=self._probe_dx, probe_dy=self._probe_dy, centre_x=self.center[0], centre_y=self.center[1],
            map_width=self.max_distance[0], map_height=self.max_distance[1],
            episode_limit=float(self.episode_limit))
        self.columns = self._columns()

    def _columns(self) -> fk.Columns:
        """Every column the kernels write, looked up in the feature-name lists."""
        state_names = self._state_table_names()
        return fk.Columns(
            move=_column(self.move_names, MOVE_NAMES[0]), pathing=_column(self.move_names, "pathing_n2"),
            height=_column(self.move_names, "height_n2"),
            enemy_offset=self.enemy_offset, enemy_feats=self.enemy_feats, **_row_columns("enemy", self.enemy_names),
            ally_offset=self.ally_offset, ally_feats=self.ally_feats, **_row_columns("ally", self.ally_names),
            own_offset=self.own_offset, **_row_columns("own", self.own_names),
            state_ally_feats=self.ally_state_feats, **_row_columns("state_ally", self.ally_state_names),
            state_enemy_offset=self.state_enemy_offset, state_enemy_feats=self.enemy_state_feats,
            **_row_columns("state_enemy", self.enemy_state_names),
            state_last_action=_column(state_names, "ally_0_last_action_0"),
            state_timestep=_column(state_names, "timestep"))

    def __repr__(self) -> str:
        return (f"SideFeatures(map={self.spec.name!r}, side={SIDE_NAMES[self.side]!r}, "
                f"obs_size={self.obs_size}, state_size={self.state_size}, n_actions={self.n_actions})")

    # -----------------------------------------------------------------------------------------------------------
    # Names.

    def obs_feature_names(self) -> list[str]:
        """Name of every observation column."""
        names = list(self.move_names)
        names += [f"enemy_{e}_{f}" for e in range(self.n_enemies) for f in self.enemy_names]
        names += [f"ally_{k}_{f}" for k in range(self.n_agents - 1) for f in self.ally_names]
        names += [f"own_{f}" for f in self.own_names]
        return names

    def state_feature_names(self) -> list[str]:
        """Name of every global-state column."""
        if self.options.obs_instead_of_state:
            return [f"agent_{i}_{f}" for i in range(self.n_agents) for f in self.obs_feature_names()]
        return self._state_table_names()

    def _state_table_names(self) -> list[str]:
        """The global state's columns as the state kernel writes them (what the state is unless
        ``obs_instead_of_state``)."""
        names = [f"ally_{i}_{f}" for i in range(self.n_agents) for f in self.ally_state_names]
        names += [f"enemy_{e}_{f}" for e in range(self.n_enemies) for f in self.enemy_state_names]
        if self.options.state_last_action:
            names += [f"ally_{i}_last_action_{a}" for i in range(self.n_agents) for a in range(self.n_actions)]
        if self.options.state_timestep_number:
            names.append("timestep")
        return names

    def max_reward(self) -> float:
        """SMAC's reward normaliser: every enemy killed from full health and shields, plus the win bonus."""
        opt = self.options
        return float(self.n_enemies * opt.reward_death_value + opt.reward_win
                     + (self.enemy_health_max + STATS[self.utype[self.enemy], S["shield"]]).sum())

    # -----------------------------------------------------------------------------------------------------------
    # Features.

    def observations(self, state: BattleState, avail: np.ndarray, last_action: np.ndarray,
                     episode_step: np.ndarray, out: np.ndarray | None = None,
                     rows: np.ndarray | None = None) -> np.ndarray:
        """Per-agent observations ``(B, n_agents, obs_size)`` float32.

        ``avail`` is this side's available actions ``(B, n, n_actions)``, ``last_action`` its previous actions
        ``(B, n)`` (-1: none), ``episode_step`` the env steps since each battle's reset ``(B,)``. With ``rows``
        (battle indices) only those battles are encoded: ``avail`` and the result then have ``len(rows)`` rows.
        """
        rows = self.all_rows(state) if rows is None else np.ascontiguousarray(rows, dtype=np.int64)
        if out is None:
            out = np.empty((len(rows), self.n_agents, self.obs_size), dtype=np.float32)
        fk.observations_batch(rows, self.kernel_units(state)[0], avail, last_action, episode_step, out, self.constants,
                              self.columns)
        return out

    def global_state(self, state: BattleState, last_action: np.ndarray, episode_step: np.ndarray,
                     obs: np.ndarray | None = None, out: np.ndarray | None = None,
                     rows: np.ndarray | None = None) -> np.ndarray:
        """The global state ``(B, state_size)`` float32 from this side's point of view (of battles ``rows`` only,
        when given, as in :meth:`observations`).

        With ``obs_instead_of_state`` the state is the concatenation of the agents' observations ``obs``.
        """
        rows = self.all_rows(state) if rows is None else np.ascontiguousarray(rows, dtype=np.int64)
        if self.options.obs_instead_of_state:
            if obs is None:
                raise ValueError("obs_instead_of_state: pass this side's observations as obs=")
            flat = obs.reshape(len(rows), self.n_agents * self.obs_size)
            if out is None:
                return flat.astype(np.float32, copy=True)
            out[:] = flat
            return out
        if out is None:
            out = np.empty((len(rows), self.state_size), dtype=np.float32)
        fk.global_state_batch(rows, self.kernel_units(state)[0], last_action, episode_step, out, self.constants,
                              self.columns)
        return out

    def encode(self, state: BattleState, last_action: np.ndarray, episode_step: np.ndarray,
               rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Available actions, observations and global state in one kernel call (fresh arrays, the values of
        :func:`~smac_hard_gym.smac.actions.available_actions`, :meth:`observations` and :meth:`global_state`)."""
        rows = self.all_rows(state) if rows is None else np.ascontiguousarray(rows, dtype=np.int64)
        out = self.outputs(len(rows), with_state=True)  # plain, as every output allocated here
        units, plain = self.kernel_units(state)
        plain = (plain and is_plain(rows, _INT64, 1) and is_plain(last_action, _INT64, 2)
                 and is_plain(episode_step, _INT64, 1))
        self._encode_batch(plain, rows, units, last_action, episode_step, out, self.constants,
                           self.columns)
        return out.avail, out.obs, self.finish_state(out.obs, out.state)

    def available_actions(self, state: BattleState, out: np.ndarray | None = None,
                          rows: np.ndarray | None = None) -> np.ndarray:
        """Available actions of every agent: bool ``(B, n_agents, n_actions)`` (of battles ``rows`` only, when given:
        ``(len(rows), n_agents, n_actions)``); see :mod:`smac_hard_gym.smac.actions`."""
        rows = self.all_rows(state) if rows is None else np.ascontiguousarray(rows, dtype=np.int64)
        if out is None:
            out = np.empty((len(rows), self.n_agents, self.n_actions), dtype=bool)
        units, plain = self.kernel_units(state)
        plain = plain and is_plain(rows, _INT64, 1) and is_plain(out, _BOOL, 3)
        self._available_actions_batch(plain, rows, units, out, self.constants.actions)
        return out

    def outputs(self, batch: int, with_state: bool) -> fk.Encoding:
        """Fresh arrays for an encoding of ``batch`` battles: masks, observations and the global state (zero rows
        when the kernel is not to write it: not wanted, or copied from the observations)."""
        avail = np.empty((batch, self.n_agents, self.n_actions), dtype=bool)
        obs = np.empty((batch, self.n_agents, self.obs_size), dtype=np.float32)
        rows = batch if with_state and not self.options.obs_instead_of_state else 0
        return fk.make_bundle(fk.Encoding, (avail, obs, np.empty((rows, self.state_size), dtype=np.float32)))

    def kernel_units(self, state: BattleState) -> tuple[fk.UnitArrays, bool]:
        """The kernels' view of ``state``, and whether its arrays are of the one type direct kernel calls compile
        for (:meth:`~smac_hard_gym.smac.kernels.UnitArrays.is_plain`); kept for the last state seen, as a backend
        keeps its state arrays."""
        seen, units, plain = self._units
        if state is not seen:
            units = fk.UnitArrays.of(state)
            plain = units.is_plain()
            self._units = (state, units, plain)
        return units, plain

    def finish_state(self, obs: np.ndarray, global_state: np.ndarray) -> np.ndarray:
        """The global state of an encoding the kernel wrote: with ``obs_instead_of_state``, the observations."""
        if self.options.obs_instead_of_state:
            return obs.reshape(obs.shape[0], self.state_size).copy()
        return global_state

    def all_rows(self, state: BattleState) -> np.ndarray:
        """Indices of every battle of ``state`` (cached per batch size)."""
        batch = state.alive.shape[0]
        if self._all_rows.shape[0] != batch:
            self._all_rows = np.arange(batch, dtype=np.int64)
        return self._all_rows

    def visibility(self, state: BattleState) -> np.ndarray:
        """SMAC's visibility matrix ``(B, n_agents, n_agents + n_enemies)`` bool: alive units within sight of an
        alive agent (allies first, symmetric among allies, never oneself)."""
        x, y, alive = state.x, state.y, state.alive
        own = self.own

        def within_sight(targets: slice) -> np.ndarray:
            dx = x[:, None, targets] - x[:, own, None]
            dy = y[:, None, targets] - y[:, own, None]
            return alive[:, own, None] & alive[:, None, targets] & (np.sqrt(dx * dx + dy * dy) < SIGHT_RANGE)

        allies = within_sight(own) & ~np.eye(self.n_agents, dtype=bool)
        return np.concatenate([allies, within_sight(self.enemy)], axis=2)


# ---------------------------------------------------------------------------------------------------------------
# Outcome and reward.


class RewardFunction:
    """SMAC's dense or sparse reward for both sides of a batch of battles, scaled per side.

    Each side is credited its own kills and damage (separate death bookkeeping per side, unlike SMAC-HARD's shared
    tracker that gives blue nothing). With ``reward_only_positive`` a step's reward is ``max(0, damage + kills)``
    (SMAC-HARD's fix), or with ``reward_abs`` SMAC v1's ``abs(damage + kills)``, which pays for enemy shield and
    health regeneration and healing as for damage (what SMAC, pymarl2 and the SMAC-HARD paper's runs used).
    """

    def __init__(self, red: SideFeatures, blue: SideFeatures, options: SmacOptions) -> None:
        self.options = options
        self.sides = (red, blue)
        self.n_red = red.n_agents
        self.max_reward = np.array([red.max_reward(), blue.max_reward()], dtype=np.float64)
        self.divisor = (self.max_reward / options.reward_scale_rate) if options.reward_scale else np.ones(2)

    def rules(self, fighter: np.ndarray, step_limit: int) -> fk.StepRules:
        """The kernels' form of the reward options, with the outcome rule (``fighter``: bool (U,), the slots that
        can win a battle) and the episode limit ``step_limit`` (env steps), for
        :func:`~smac_hard_gym.smac.kernels.finish_encode`."""
        opt = self.options
        return fk.StepRules(
            fighter=np.ascontiguousarray(fighter, dtype=bool), n_red=int(self.n_red), step_limit=int(step_limit),
            reward=fk.RewardOptions(
                death_value=float(opt.reward_death_value), win=float(opt.reward_win),
                defeat=float(opt.reward_defeat), negative_scale=float(opt.reward_negative_scale),
                sparse=bool(opt.reward_sparse), only_positive=bool(opt.reward_only_positive),
                absolute=bool(opt.reward_abs)),
            divisor=self.divisor)
