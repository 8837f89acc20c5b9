"""``base``: SMAC's default opponent.

On each battle's first step every unit gets the map's enemy order (smac_interface §9): attack-move to the learner's
spawn on most maps, to a random point between the two marines on 2m_vs_1z, an attack on the nearest colossus on
2c_vs_64zg, nothing on 2s_vs_1sc. Afterwards the script sends no command: SC2's automatic targeting drives the units
(acquire the closest target in scan range, prefer attackers, respond when hit, resume the attack-move).

Playing the red side (the duel runner), ``base`` mirrors the usual order: every unit attack-moves to the blue spawn.
Red's passive ``*_RL`` units acquire targets only while attack-moving, so once they arrive they stand idle.
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.engine.state import CMD_ATTACK, CMD_ATTACK_MOVE, Commands
from smac_hard_gym.opponents.api import RED, Script, SideView


class BaseScript(Script):
    """SMAC's default opponent: the map's spawn order once, then the game's automatic targeting."""

    name = "base"
    description = "SMAC default: the map's attack-move order at spawn, then SC2 automatic targeting"

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
