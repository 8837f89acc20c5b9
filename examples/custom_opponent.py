"""Write your own opponent script (batched form) and use it without editing the package.

A batched script handles every battle of a batch in one call: ``plan(frame, orders)`` sees (R, n) arrays of the
R active battles and fills an order plan with boolean masks of units. This one focuses fire: every unit attacks
the weakest enemy already within its weapon range, or else walks to the enemy nearest the army's centre; wounded
marines step back while an enemy can reach them.

Use it by path anywhere an opponent is accepted::

    python examples/custom_opponent.py                                   # duels it against built-ins
    smac-hard-gym duel --map 8m --red stop --blue examples/custom_opponent.py:FocusInRange --episodes 20
    StarCraft2Env(map_name="8m", opponent="examples/custom_opponent.py:FocusInRange")
    StarCraft2Env(map_name="8m", opponent=["default", ...])  # or mixed with built-ins, with opponent_probs

User scripts run inside a guard: if one raises, runs too long or writes an invalid command, a ScriptError names
the script, the map and the cause.
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.envs.duel import run_duel
from smac_hard_gym.opponents import BatchScript, Frame, Memory, Orders
from smac_hard_gym.opponents.helpers import argmin_masked, away, lowest


class FocusInRange(BatchScript):
    """Attack the weakest enemy in range, else close in on the enemy nearest our centre; the wounded back off."""

    name = "focus_in_range"
    description = "attack the weakest enemy in range, else close in; wounded units back off"
    wounded = 0.3  # health + shield fraction below which a threatened unit backs off

    def __init__(self) -> None:
        # Episode memory: arrays (B, ...) over the whole batch, reset per battle at its episode start.
        self.memory = Memory(retreats=(("own",), np.int64, 0))

    def plan(self, frame: Frame, orders: Orders) -> None:
        alive = frame.own_alive  # (R, n)
        in_range = frame.targetable & (frame.edge <= frame.own_range[:, :, None])  # (R, n, m)
        hp = np.broadcast_to(frame.enemy_hp[:, None, :], frame.dist.shape)
        target = lowest(hp, in_range, tie=frame.dist)  # (R, n): -1 where nothing is in range
        orders.attack(alive, target)

        # Nothing in range: all close in on the enemy nearest the army's centre.
        cx, cy = frame.own_centroid
        d = np.hypot(frame.enemy_x - cx[:, None], frame.enemy_y - cy[:, None])
        focus = argmin_masked(d, frame.enemy_alive)  # (R,)
        orders.attack(alive & (target < 0), np.broadcast_to(focus[:, None], alive.shape))

        # Wounded units with an enemy within 4 step 2 away from it (later orders override earlier ones).
        near = argmin_masked(frame.dist, frame.hittable)
        near_d = np.take_along_axis(frame.dist, np.maximum(near, 0)[:, :, None], axis=2)[:, :, 0]
        back = alive & (frame.own_hp_frac < self.wounded) & (near >= 0) & (near_d < 4.0)
        ex = np.take_along_axis(frame.enemy_x, np.maximum(near, 0), axis=1)
        ey = np.take_along_axis(frame.enemy_y, np.maximum(near, 0), axis=1)
        bx, by = away(frame.own_x, frame.own_y, ex, ey, 2.0)
        orders.move(back, bx, by)
        self.memory.retreats[frame.rows] += back


if __name__ == "__main__":
    for opponent in ("base", "nearest", "default"):
        # Our script plays blue (the opponent's side) against a red side driven by a built-in script.
        result = run_duel("8m", red=opponent, blue=FocusInRange(), episodes=20, seed=0)
        print(f"8m, focus_in_range (blue) vs {opponent} (red): blue wins {result.blue_win_rate:.0%}, "
              f"red wins {result.red_win_rate:.0%}, draws {result.draw_rate:.0%}")
    # The same by reference, as a user would pass it to an env or the command line.
    result = run_duel("8m", red="stop", blue=f"{__file__}:FocusInRange", episodes=4)
    print(f"by path against a side that stops: blue wins {result.blue_win_rate:.0%}")
