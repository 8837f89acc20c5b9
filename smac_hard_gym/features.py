"""SMAC's observations, global state, reward and battle outcome, batched, for either side of a battle.

Everything here is a function of a :class:`~smac_hard_gym.engine.state.BattleState` (arrays ``(B, U)`` over B
battles) and a side: :class:`SideFeatures` holds one side's constants (which slots are "own" and "enemy", health
and shield normalisers, unit-type one-hots) and the feature-name lists that define every offset and size. The red
side's view is SMAC's (``shared/reference/smac_interface.md`` §3-§6); the blue side gets the same encoding from its
own side (SMAC-HARD's self-play layout).

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
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from smac_hard_gym.engine.state import BLUE, RED, BattleState
from smac_hard_gym.engine.terrain import cliff_height
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.units import STATS, UNITS, WEAPON_HEAL, S, unit_index

__all__ = [
    "SmacOptions", "SideFeatures", "Geometry", "RewardFunction", "battle_outcome", "last_action_onehot",
    "SHOOT_RANGE", "SIGHT_RANGE", "N_ACTIONS_NO_ATTACK", "RUNNING", "RED_WON", "BLUE_WON", "DRAW", "SIDE_NAMES",
]

SHOOT_RANGE = 6.0  # SMAC: attack/heal available within this centre distance (<=), every unit
SIGHT_RANGE = 9.0  # SMAC: units closer than this (<) are observed, every unit
N_ACTIONS_NO_ATTACK = 6  # no-op, stop, move north/south/east/west
MOVE_NAMES = ("move_north", "move_south", "move_east", "move_west")

# Battle outcomes (``battle_outcome``).
RUNNING, RED_WON, BLUE_WON, DRAW = 0, 1, 2, 3
SIDE_NAMES = ("red", "blue")

# Points around (int(x), int(y)) probed by obs_pathing_grid / obs_terrain_height, in units of move_amount, in
# SMAC's order; the terrain-height block adds the unit's own cell last.
_SURROUNDING = ((0, 2), (0, -2), (2, 0), (-2, 0), (1, 1), (-1, -1), (1, -1), (-1, 1))
_SURROUNDING_NAMES = ("n2", "s2", "e2", "w2", "ne", "sw", "se", "nw")

# SMAC's one-hot index of the opponent's standard units per map_type (smac_interface §3).
_STANDARD_TYPE_ORDER = {
    "MMM": ("marauder", "marine", "medivac"),
    "stalkers_and_zealots": ("zealot", "stalker"),
    "colossi_stalkers_zealots": ("colossus", "stalker", "zealot"),
    "bane": ("baneling", "zergling"),
}

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
    def from_kwargs(cls, **kwargs) -> SmacOptions:
        """Build from keyword arguments, naming any unknown one."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(kwargs) - known)
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


class Geometry(NamedTuple):
    """Pairwise offsets of one side's units to the enemy's and to each other, for one state snapshot."""

    own_alive: np.ndarray  # bool (B, n)
    enemy_alive: np.ndarray  # bool (B, m)
    enemy_dx: np.ndarray  # (B, n, m): enemy x - own x
    enemy_dy: np.ndarray
    enemy_dist: np.ndarray
    ally_dx: np.ndarray | None  # (B, n, n): ally j x - own i x (None when not asked for)
    ally_dy: np.ndarray | None
    ally_dist: np.ndarray | None


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
        self.any_healer = bool(self.own_healer.any())
        self.n_heal_targets = min(self.n_agents, self.n_enemies)  # 6+j addresses ally j only for j < n_enemies
        cols = team_type_columns(spec, utype, n_red)
        onehot = np.zeros((n_units, bits), dtype=np.float32)
        if bits:
            onehot[np.arange(n_units), cols] = 1.0
        self.own_onehot, self.enemy_onehot = onehot[self.own], onehot[self.enemy]
        n = self.n_agents
        self.others = np.array([[j for j in range(n) if j != i] for i in range(n)], dtype=np.int64).reshape(
            n, n - 1)

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

    def geometry(self, state: BattleState, allies: bool = True) -> Geometry:
        """Offsets and distances from this side's units to every enemy and (if ``allies``) every ally."""
        ox, oy = state.x[:, self.own], state.y[:, self.own]
        ex, ey = state.x[:, self.enemy], state.y[:, self.enemy]
        edx = ex[:, None, :] - ox[:, :, None]
        edy = ey[:, None, :] - oy[:, :, None]
        adx = ady = adist = None
        if allies:
            adx = ox[:, None, :] - ox[:, :, None]
            ady = oy[:, None, :] - oy[:, :, None]
            adist = np.sqrt(adx * adx + ady * ady)
        return Geometry(state.alive[:, self.own], state.alive[:, self.enemy], edx, edy,
                        np.sqrt(edx * edx + edy * edy), adx, ady, adist)

    def observations(self, state: BattleState, avail: np.ndarray, last_action: np.ndarray,
                     episode_step: np.ndarray, geo: Geometry | None = None,
                     out: np.ndarray | None = None) -> np.ndarray:
        """Per-agent observations ``(B, n_agents, obs_size)`` float32.

        ``avail`` is this side's available actions ``(B, n, n_actions)``, ``last_action`` its previous actions
        ``(B, n)`` (-1: none), ``episode_step`` the env steps since each battle's reset ``(B,)``.
        """
        opt = self.options
        geo = self.geometry(state, allies=False) if geo is None else geo
        batch, n, m = state.alive.shape[0], self.n_agents, self.n_enemies
        if out is None:
            out = np.zeros((batch, n, self.obs_size), dtype=np.float32)
        else:
            out[:] = 0.0
        alive = geo.own_alive
        alive_f = alive.astype(np.float32)
        mul = np.multiply

        # Move block.
        out[:, :, 0:4] = avail[:, :, 2:6]
        col = 4
        if opt.obs_pathing_grid or opt.obs_terrain_height:
            inside, cx, cy = self._surrounding_cells(state)
            if opt.obs_pathing_grid:
                values = np.where(inside[..., :8], self.pathable[cx[..., :8], cy[..., :8]], True)
                out[:, :, col:col + 8] = values * alive_f[..., None]
                col += 8
            if opt.obs_terrain_height:
                values = np.where(inside, self.terrain_height[cx, cy], 1.0)
                out[:, :, col:col + 9] = values * alive_f[..., None]

        # Enemy rows. Products go straight into the output views (no float64 temporaries per column).
        enemy = out[:, :, self.enemy_offset:self.ally_offset].reshape(batch, n, m, self.enemy_feats)
        seen = alive[:, :, None] & geo.enemy_alive[:, None, :] & (geo.enemy_dist < SIGHT_RANGE)
        seen_f = seen.astype(np.float32)
        scaled = seen_f / np.float32(SIGHT_RANGE)
        enemy[..., 0] = avail[:, :, N_ACTIONS_NO_ATTACK:N_ACTIONS_NO_ATTACK + m] & seen
        mul(geo.enemy_dist, scaled, out=enemy[..., 1], casting="same_kind")
        mul(geo.enemy_dx, scaled, out=enemy[..., 2], casting="same_kind")
        mul(geo.enemy_dy, scaled, out=enemy[..., 3], casting="same_kind")
        col = 4
        if opt.obs_all_health:
            ratio = (state.health[:, self.enemy] / self.enemy_health_max).astype(np.float32)
            mul(ratio[:, None, :], seen_f, out=enemy[..., col])
            col += 1
            if self.shield_bits_enemy:
                ratio = (state.shield[:, self.enemy] / self.enemy_shield_max).astype(np.float32)
                mul(ratio[:, None, :], seen_f, out=enemy[..., col])
                col += 1
        if self.unit_type_bits:
            mul(self.enemy_onehot[None, None], seen_f[..., None], out=enemy[..., col:col + self.unit_type_bits])

        # Ally rows: every other agent of this side, in id order.
        if n > 1:
            ally = out[:, :, self.ally_offset:self.own_offset].reshape(batch, n, n - 1, self.ally_feats)
            ox, oy = state.x[:, self.own], state.y[:, self.own]
            dx = ox[:, self.others] - ox[:, :, None]
            dy = oy[:, self.others] - oy[:, :, None]
            dist = np.sqrt(dx * dx + dy * dy)
            seen = alive[:, :, None] & alive[:, self.others] & (dist < SIGHT_RANGE)
            seen_f = seen.astype(np.float32)
            scaled = seen_f / np.float32(SIGHT_RANGE)
            ally[..., 0] = seen_f
            mul(dist, scaled, out=ally[..., 1], casting="same_kind")
            mul(dx, scaled, out=ally[..., 2], casting="same_kind")
            mul(dy, scaled, out=ally[..., 3], casting="same_kind")
            col = 4
            if opt.obs_all_health:
                ratio = (state.health[:, self.own] / self.own_health_max).astype(np.float32)
                mul(ratio[:, self.others], seen_f, out=ally[..., col])
                col += 1
                if self.shield_bits_ally:
                    ratio = (state.shield[:, self.own] / self.own_shield_max).astype(np.float32)
                    mul(ratio[:, self.others], seen_f, out=ally[..., col])
                    col += 1
            if self.unit_type_bits:
                mul(self.own_onehot[self.others][None], seen_f[..., None],
                    out=ally[..., col:col + self.unit_type_bits])
                col += self.unit_type_bits
            if opt.obs_last_action:
                onehot = last_action_onehot(last_action, self.n_actions)
                mul(onehot[:, self.others], seen_f[..., None], out=ally[..., col:col + self.n_actions])

        # Own block.
        own = out[:, :, self.own_offset:]
        col = 0
        if opt.own_health:
            own[..., col] = state.health[:, self.own] / self.own_health_max * alive_f
            col += 1
            if self.shield_bits_ally:
                own[..., col] = state.shield[:, self.own] / self.own_shield_max * alive_f
                col += 1
        if self.unit_type_bits:
            own[..., col:col + self.unit_type_bits] = self.own_onehot[None] * alive_f[..., None]
            col += self.unit_type_bits
        if opt.obs_timestep_number:
            own[..., col] = (episode_step / self.episode_limit)[:, None]
        return out

    def global_state(self, state: BattleState, last_action: np.ndarray, episode_step: np.ndarray,
                     obs: np.ndarray | None = None, out: np.ndarray | None = None) -> np.ndarray:
        """The global state ``(B, state_size)`` float32 from this side's point of view.

        With ``obs_instead_of_state`` the state is the concatenation of the agents' observations ``obs``.
        """
        opt = self.options
        batch, n, m = state.alive.shape[0], self.n_agents, self.n_enemies
        if opt.obs_instead_of_state:
            if obs is None:
                raise ValueError("obs_instead_of_state: pass this side's observations as obs=")
            flat = obs.reshape(batch, n * self.obs_size)
            if out is None:
                return flat.astype(np.float32, copy=True)
            out[:] = flat
            return out
        if out is None:
            out = np.zeros((batch, self.state_size), dtype=np.float32)
        else:
            out[:] = 0.0
        cx, cy = self.center
        mdx, mdy = self.max_distance

        own = out[:, :self.state_enemy_offset].reshape(batch, n, self.ally_state_feats)
        alive_f = state.alive[:, self.own].astype(np.float32)
        own[..., 0] = state.health[:, self.own] / self.own_health_max * alive_f
        # Medivacs report energy, every other unit its weapon cooldown (game loops until it may fire again).
        timer = np.where(self.own_healer, state.energy[:, self.own], np.maximum(state.cooldown[:, self.own], 0.0))
        own[..., 1] = timer / self.own_max_cooldown * alive_f
        own[..., 2] = (state.x[:, self.own] - cx) / mdx * alive_f
        own[..., 3] = (state.y[:, self.own] - cy) / mdy * alive_f
        col = 4
        if self.shield_bits_ally:
            own[..., col] = state.shield[:, self.own] / self.own_shield_max * alive_f
            col += 1
        if self.unit_type_bits:
            own[..., col:] = self.own_onehot[None] * alive_f[..., None]

        enemy = out[:, self.state_enemy_offset:self.state_action_offset].reshape(batch, m, self.enemy_state_feats)
        alive_f = state.alive[:, self.enemy].astype(np.float32)
        enemy[..., 0] = state.health[:, self.enemy] / self.enemy_health_max * alive_f
        enemy[..., 1] = (state.x[:, self.enemy] - cx) / mdx * alive_f
        enemy[..., 2] = (state.y[:, self.enemy] - cy) / mdy * alive_f
        col = 3
        if self.shield_bits_enemy:
            enemy[..., col] = state.shield[:, self.enemy] / self.enemy_shield_max * alive_f
            col += 1
        if self.unit_type_bits:
            enemy[..., col:] = self.enemy_onehot[None] * alive_f[..., None]

        col = self.state_action_offset
        if opt.state_last_action:
            width = n * self.n_actions
            out[:, col:col + width] = last_action_onehot(last_action, self.n_actions).reshape(batch, width)
            col += width
        if opt.state_timestep_number:
            out[:, col] = episode_step / self.episode_limit
        return out

    def visibility(self, state: BattleState, geo: Geometry | None = None) -> np.ndarray:
        """SMAC's visibility matrix ``(B, n_agents, n_agents + n_enemies)`` bool: alive units within sight of an
        alive agent (allies first, symmetric among allies, never oneself)."""
        if geo is None or geo.ally_dist is None:
            geo = self.geometry(state)
        alive = geo.own_alive
        allies = alive[:, :, None] & alive[:, None, :] & (geo.ally_dist < SIGHT_RANGE)
        allies &= ~np.eye(self.n_agents, dtype=bool)
        enemies = alive[:, :, None] & geo.enemy_alive[:, None, :] & (geo.enemy_dist < SIGHT_RANGE)
        return np.concatenate([allies, enemies], axis=2)

    def _surrounding_cells(self, state: BattleState) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cells around each agent's ``(int(x), int(y))`` probed by the pathing/height features: the 8 points of
        SMAC's order then the agent's own cell; returns (inside the map, cx, cy), each (B, n, 9), with cells outside
        the map replaced by cell 0 so that they can index the grids (their values are then overridden)."""
        xi = np.trunc(state.x[:, self.own]).astype(np.int64)
        yi = np.trunc(state.y[:, self.own]).astype(np.int64)
        cx = xi[..., None] + self._probe_dx
        cy = yi[..., None] + self._probe_dy
        inside = (cx >= 0) & (cx < self.map_x) & (cy >= 0) & (cy < self.map_y)
        return inside, np.where(inside, cx, 0), np.where(inside, cy, 0)


# ---------------------------------------------------------------------------------------------------------------
# Outcome and reward.


def battle_outcome(alive: np.ndarray, fighter: np.ndarray, n_red: int) -> np.ndarray:
    """Outcome per battle (int8 ``(B,)``: RUNNING, RED_WON, BLUE_WON or DRAW).

    A side is beaten when none of its ``fighter`` units (every unit but medivacs: SMAC's "only medivacs left" rule
    of MMM maps, applied to both sides) is alive; both beaten in the same step is a draw.
    """
    live = alive & fighter
    red_left = live[:, :n_red].any(axis=1)
    blue_left = live[:, n_red:].any(axis=1)
    outcome = np.full(alive.shape[0], RUNNING, dtype=np.int8)
    outcome[red_left & ~blue_left] = RED_WON
    outcome[~red_left & blue_left] = BLUE_WON
    outcome[~red_left & ~blue_left] = DRAW
    return outcome


class RewardFunction:
    """SMAC's dense or sparse reward for both sides of a batch of battles, scaled per side.

    Each side is credited its own kills and damage (separate death bookkeeping per side, unlike SMAC-HARD's shared
    tracker that gives blue nothing). With ``reward_only_positive`` a step's reward is ``max(0, damage + kills)``
    (SMAC-HARD's fix; SMAC takes ``abs``, which pays for enemy regeneration).
    """

    def __init__(self, red: SideFeatures, blue: SideFeatures, options: SmacOptions) -> None:
        self.options = options
        self.sides = (red, blue)
        self.max_reward = np.array([red.max_reward(), blue.max_reward()], dtype=np.float64)
        self.divisor = (self.max_reward / options.reward_scale_rate) if options.reward_scale else np.ones(2)

    def __call__(self, prev_hs: np.ndarray, prev_alive: np.ndarray, state: BattleState,
                 outcome: np.ndarray) -> np.ndarray:
        """Rewards ``(B, 2)`` float32 ([red, blue]) for the step from (``prev_hs``, ``prev_alive``), the health plus
        shield and alive flags of every unit before the step, to ``state``; ``outcome`` from :func:`battle_outcome`."""
        opt = self.options
        alive = state.alive
        batch = alive.shape[0]
        reward = np.zeros((batch, 2), dtype=np.float64)
        won = np.stack([outcome == RED_WON, outcome == BLUE_WON], axis=1)
        lost = np.stack([outcome == BLUE_WON, outcome == RED_WON], axis=1)
        if opt.reward_sparse:
            reward[won] = 1.0
            reward[lost] = -1.0
        else:
            hs_now = np.where(alive, state.health + state.shield, 0.0)
            lost_hs = np.where(prev_alive, prev_hs - hs_now, 0.0)  # includes a dying unit's last health
            died = prev_alive & ~alive
            neg = opt.reward_negative_scale
            for s, feats in enumerate(self.sides):
                delta_enemy = lost_hs[:, feats.enemy].sum(axis=1)
                delta_deaths = opt.reward_death_value * died[:, feats.enemy].sum(axis=1)
                if opt.reward_only_positive:
                    reward[:, s] = np.maximum(0.0, delta_enemy + delta_deaths)
                else:
                    delta_deaths = delta_deaths - opt.reward_death_value * neg * died[:, feats.own].sum(axis=1)
                    delta_ally = neg * lost_hs[:, feats.own].sum(axis=1)
                    reward[:, s] = delta_enemy + delta_deaths - delta_ally
            reward += won * opt.reward_win + lost * opt.reward_defeat
        return (reward / self.divisor).astype(np.float32)
