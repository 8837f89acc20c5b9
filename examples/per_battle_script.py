"""Write an opponent one battle at a time: the simplest way to script (a Python call per battle and step).

Subclass ``PerBattleScript`` and implement ``act_battle(battle)``. ``battle.own`` and ``battle.enemy`` hold this
battle's units as small arrays (``x``, ``y``, ``health``, ``shield``, ``alive``, ``type``, ``cooldown``...), orders
take side-local indices (own unit i, enemy k), ``battle.memory`` is a dict kept for the episode and ``battle.rng``
is the battle's seeded generator (same seed, same game).

    python examples/per_battle_script.py
    smac-hard-gym duel --map 3s_vs_3z --red examples/per_battle_script.py --blue base --episodes 10

(With no ``:ClassName`` the file must define exactly one Script subclass, as this one does.)
"""

from __future__ import annotations

import numpy as np

from smac_hard_gym.envs.duel import run_duel
from smac_hard_gym.opponents import BattleView, PerBattleScript


class HitAndRun(PerBattleScript):
    """Shoot the nearest enemy when the weapon is ready; while reloading, run from enemies closer than 3.

    The first order of each episode is a random feint (seeded): half the battles open by stepping sideways.
    """

    name = "hit_and_run"
    description = "shoot when ready, run while reloading; a seeded random opening feint"

    def reset_battle(self, battle: BattleView) -> None:
        battle.memory["feint"] = bool(battle.rng.random() < 0.5)

    def act_battle(self, battle: BattleView) -> None:
        own, enemy = battle.own, battle.enemy
        for i in own.alive_indices():
            if battle.step == 0 and battle.memory["feint"]:
                battle.move(i, own.x[i], own.y[i] + 2.0)
                continue
            k = battle.nearest_enemy(i)
            if k < 0:
                continue
            distance = float(np.hypot(enemy.x[k] - own.x[i], enemy.y[k] - own.y[i]))
            if own.cooldown[i] > 8 and distance < 3.0:  # reloading (more than one step's 8 loops left)
                dx, dy = own.x[i] - enemy.x[k], own.y[i] - enemy.y[k]
                norm = max(float(np.hypot(dx, dy)), 1e-6)
                battle.move(i, own.x[i] + 2.0 * dx / norm, own.y[i] + 2.0 * dy / norm)
            else:
                battle.attack(i, k)


if __name__ == "__main__":
    # Stalkers (red side here: the learner's units, which act only on orders) against SMAC's default zealots.
    for red in (HitAndRun(), "nearest"):
        result = run_duel("3s_vs_3z", red=red, blue="base", episodes=10, seed=0)
        name = red if isinstance(red, str) else red.name
        print(f"3s_vs_3z, {name} (red stalkers) vs base zealots: red wins {result.red_win_rate:.0%}, "
              f"blue wins {result.blue_win_rate:.0%}, draws {result.draw_rate:.0%}")
