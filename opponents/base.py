"""The two base opponents, named so they cannot be confused.

- ``smac`` (:class:`SmacScript`): SMAC's one-player maps. On each battle's first step every unit gets the map's
  enemy order once (docs/smac_interface.md §9): attack-move to the learner's spawn on most maps, to a random point
  between
  the two marines on 2m_vs_1z, an attack on the nearest colossus on 2c_vs_64zg, nothing on 2s_vs_1sc. Afterwards
  the script sends no command: SC2's automatic targeting drives the units, and once the attack-move arrives they
  stand idle at the point (the "stuck at the destination" weakness the SMAC-HARD paper describes, section 3.1).
- ``base`` (:class:`BaseScript`): SMAC-HARD's ``smac_hard/env/scripts/base_script.py`` as it runs. It re-issues an
  attack-move every step to a fixed point per map (:data:`SMAC_HARD_BASE_POINTS`) and gives no order at all on
  2m_vs_1z, 2s_vs_1sc and 2c_vs_64zg (units idle and only auto-acquire or respond). This is the ``base`` of
  SMAC-HARD's pools, so the ``default`` mixtures use it.

A re-issued attack-move replaces the unit's order, so it also drops the unit's current target and re-acquires from
scratch (SC2 does the same when an order is replaced): units under ``base`` never stand idle at the point while an
enemy is in scan range, and they never keep chasing a target that left scan range.

Playing the red side (the duel runner), both mirror the usual order: ``smac`` attack-moves to the blue spawn once,
``base`` every step (to the mirrored point on maps where SMAC-HARD uses (9, 16), to the blue spawn elsewhere).
Red's passive ``*_RL`` units acquire targets only while attack-moving.
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.engine.state import CMD_ATTACK, CMD_ATTACK_MOVE, Commands
from smac_hard_gym.opponents.api import RED, Script, SideView

__all__ = ["SmacScript", "BaseScript", "SMAC_HARD_BASE_POINTS"]

_MARINE_AND_PROTOSS = ("3m", "8m", "25m", "5m_vs_6m", "8m_vs_9m", "10m_vs_11m", "27m_vs_30m", "MMM", "MMM2", "2s3z",
                       "3s5z", "3s5z_vs_3s6z", "1c3s5z", "3s_vs_3z", "3s_vs_4z", "3s_vs_5z")

# SMAC-HARD base_script.py: the attack-move point per map; None = no order at all. Not the learner's spawn on
# corridor ((4, 4) vs SMAC's (4.47, 4.33)) nor exactly on 6h_vs_8z, so the table is SMAC-HARD's, not the map's.
SMAC_HARD_BASE_POINTS: dict[str, tuple[float, float] | None] = {
    **{name: (9.0, 16.0) for name in _MARINE_AND_PROTOSS},
    "bane_vs_bane": (16.0, 8.0),
    "so_many_baneling": (4.5, 4.5),
    "corridor": (4.0, 4.0),
    "6h_vs_8z": (14.5, 9.5),
    "2m_vs_1z": None,
    "2s_vs_1sc": None,
    "2c_vs_64zg": None,
}


class SmacScript(Script):
    """SMAC's default opponent: the map's spawn order once, then the game's automatic targeting."""

    name = "smac"
    description = "SMAC's one-player maps: the map's attack-move order once at spawn, then SC2 automatic targeting"

    def __init__(self) -> None:
        self._points: np.ndarray | None = None  # (B, 2) attack-move point per battle
        self._waiting = False  # some battle was reset and has not had its order yet (most steps: no)

    def _order_kind(self, view: SideView) -> str:
        return "attack_move" if view.side == RED else view.spec.enemy_order.kind

    def reset(self, view: SideView, battles: np.ndarray, rngs: list[np.random.Generator]) -> None:
        order = view.spec.enemy_order
        kind = self._order_kind(view)
        if self._points is None or self._points.shape[0] != view.batch_size:
            self._points = np.zeros((view.batch_size, 2))
        battles = np.asarray(battles, dtype=np.int64)
        if kind == "attack_move_between":
            (x0, y0), (x1, y1) = order.points
            u = np.fromiter((rngs[b].random() for b in battles), dtype=np.float64, count=battles.size)
            self._points[battles, 0] = x0 + u * (x1 - x0)
            self._points[battles, 1] = y0 + u * (y1 - y0)
        elif kind == "attack_move":
            self._points[battles] = view.enemy_spawn if view.side == RED else order.point
        self._waiting = True

    def act(self, view: SideView, commands: Commands, active: np.ndarray) -> None:
        if not self._waiting:
            return
        fresh = view.episode_step == 0
        first = active & fresh
        self._waiting = bool((fresh & ~active).any())  # reset battles that sat this step out still wait
        if not first.any():
            return
        kind = self._order_kind(view)
        own = view.own
        if kind in ("attack_move", "attack_move_between"):
            commands.kind[first, own] = CMD_ATTACK_MOVE
            commands.x[first, own] = self._points[first, 0:1]
            commands.y[first, own] = self._points[first, 1:2]
        elif kind == "attack_units":
            # SC2's attack on the enemy unit group: each unit goes for the nearest enemy.
            dx = view.own_x[first][:, :, None] - view.enemy_x[first][:, None, :]
            dy = view.own_y[first][:, :, None] - view.enemy_y[first][:, None, :]
            dist = np.where(view.enemy_alive[first][:, None, :], dx * dx + dy * dy, np.inf)
            commands.kind[first, own] = CMD_ATTACK
            commands.target[first, own] = view.enemy_slot(dist.argmin(axis=2))


def base_point(view: SideView) -> tuple[float, float] | None:
    """Where ``base`` attack-moves on this view's map and side; None for no order.

    Blue uses SMAC-HARD's table; a map outside it (a user's map) attack-moves to the learner's spawn, SMAC-HARD's
    choice on every map with a "Team 1" point. Red mirrors: the point reflected through the map centre where
    SMAC-HARD uses the learner's spawn (9, 16), the blue spawn elsewhere; no order where SMAC-HARD gives none.
    """
    name = view.spec.name
    if name in SMAC_HARD_BASE_POINTS and SMAC_HARD_BASE_POINTS[name] is None:
        return None
    if view.side != RED:
        point = SMAC_HARD_BASE_POINTS.get(name)
        return point if point is not None else (float(view.enemy_spawn[0]), float(view.enemy_spawn[1]))
    if SMAC_HARD_BASE_POINTS.get(name) == (9.0, 16.0):
        width, _ = view.spec.size
        return (float(width) - 9.0, 16.0)
    return float(view.enemy_spawn[0]), float(view.enemy_spawn[1])


class BaseScript(Script):
    """SMAC-HARD's ``base``: every unit attack-moves to the map's fixed point, re-issued every step (see module)."""

    name = "base"
    description = ("SMAC-HARD's base_script: attack-move to a fixed point (the learner's spawn on marine and protoss "
                   "maps) re-issued every step; no orders on 2m_vs_1z, 2s_vs_1sc, 2c_vs_64zg")

    _point_of: tuple[object, int, tuple[float, float] | None] | None = None  # (spec, side, point), set by act

    def act(self, view: SideView, commands: Commands, active: np.ndarray) -> None:
        cached = self._point_of  # base_point is fixed per map and side: worked out once, not every step
        if cached is None or cached[0] is not view.spec or cached[1] != view.side:
            cached = self._point_of = (view.spec, view.side, base_point(view))
        point = cached[2]
        if point is None:
            return
        own = view.own
        alive = view.own_alive & active[:, None]
        kind = commands.kind[:, own]
        kind[alive] = CMD_ATTACK_MOVE
        commands.x[:, own][alive] = point[0]
        commands.y[:, own][alive] = point[1]
