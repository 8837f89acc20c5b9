"""Step-by-step trace of a trained model's test games: what every unit does, and who shoots whom.

Plays test games of a ``model.zip`` from ``smac-hard-gym train`` against ``--opponent`` (default ``smac``) with the
most likely actions, game g a fresh battle seeded ``TEST_SEED_BASE + g`` (the seeds of the test battles), one
battle at a time, reading the engine's state after every env step (internal access:
``smac_hard_gym/engine/state.py``). For each game it prints the outcome; with ``--show G`` it prints game G step by
step, one line per step:

    step  learner: health+shield, order and how many hit it  ||  opponent: the same

Each unit reads like ``125a**``: 125 health + shield, its order (``i`` idle, ``m`` move, ``a`` attack, ``A``
attack-move, ``h`` hold, ``H`` heal) and a ``*`` per unit whose last shot or heal of the step went to it; ``-`` is
dead. ``--orders`` adds each learner unit's order target or point and position; ``--enemy`` adds each opponent
unit's weapon target (the slot it is engaging) and position. The column ``gap`` is the shortest distance between
the two sides' units, centre to centre.

    python benchmarks/trace_model.py --model runs/MMM2-smac-s0/model.zip --games 8 --show 5
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from smac_hard_gym.engine import state as engine_state

ORDER_LETTERS = {engine_state.ORDER_IDLE: "i", engine_state.ORDER_MOVE: "m", engine_state.ORDER_ATTACK: "a",
                 engine_state.ORDER_ATTACK_MOVE: "A", engine_state.ORDER_HOLD: "h", engine_state.ORDER_HEAL: "H"}
ON_UNIT = (engine_state.ORDER_ATTACK, engine_state.ORDER_HEAL)  # orders with a unit as their target
ON_POINT = (engine_state.ORDER_MOVE, engine_state.ORDER_ATTACK_MOVE)  # orders with a point


def _unit(health: float, order: int, hits: int, alive: bool) -> str:
    return f"{health:.0f}{ORDER_LETTERS[order]}{'*' * hits}" if alive else "-"


def trace(model_path: Path, games: int, opponent: str, show: int | None, orders: bool,
          enemy: bool = False) -> list[bool]:
    """Play ``games`` greedy test games; print game ``show`` step by step. Returns who won each game."""
    import torch

    from smac_hard_gym.engine.units import UNITS
    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.training.protocol import TEST_SEED_BASE
    from smac_hard_gym.training.run_files import load_trained

    torch.set_num_threads(1)
    model, config, kwargs = load_trained(model_path)
    won = []
    for game in range(games):
        venv = NativeVectorEnv(config.map_name, 1, autoreset_mode="SameStep", opponent=opponent, **kwargs)
        st = venv.core.backend.state
        red = np.arange(st.alive.shape[1]) < venv.core.n_red
        try:
            obs, _ = venv.reset(seed=TEST_SEED_BASE + game)
            if game == show:
                names = [UNITS[t].base for t in st.utype[0]]
                print(f"game {game} on {config.map_name}: learner {' '.join(names[:red.sum()])} || opponent "
                      f"{' '.join(names[red.sum():])}")
            for step in range(venv.episode_limit + 1):
                if game == show:
                    print(_line(step, st, red, orders, enemy))
                actions, _ = model.predict(obs, action_masks=venv.action_masks(), deterministic=True)
                obs, _, terminated, truncated, infos = venv.step(actions)
                if terminated[0] or truncated[0]:
                    won.append(bool(infos["final_info"]["battle_won"][0]))
                    break
        finally:
            venv.close()
        print(f"game {game}: {'won' if won[-1] else 'lost'} in {step + 1} steps")
    return won


def _line(step: int, st: object, red: np.ndarray, orders: bool, enemy: bool = False) -> str:
    alive, x, y = st.alive[0], st.x[0], st.y[0]
    life = st.health[0] + st.shield[0]
    fired = st.fired_at[0]
    hits = np.bincount(fired[fired >= 0], minlength=alive.size)
    d = np.hypot(x[red][:, None] - x[~red][None], y[red][:, None] - y[~red][None])
    pair = alive[red][:, None] & alive[~red][None]
    gap = f"{d[pair].min():5.1f}" if pair.any() else "    -"
    units = [_unit(life[i], int(st.order[0, i]), int(hits[i]), bool(alive[i])) for i in range(alive.size)]
    text = f"{step:3d} gap {gap} | {' '.join(u for u, r in zip(units, red, strict=True) if r)} || " \
           f"{' '.join(u for u, r in zip(units, red, strict=True) if not r)}"
    if orders:
        own = [f"{i}:{ORDER_LETTERS[int(st.order[0, i])]}"
               + (f">{st.order_target[0, i]}" if st.order_target[0, i] >= 0 and st.order[0, i] in ON_UNIT else
                  f">({st.order_x[0, i]:.1f},{st.order_y[0, i]:.1f})" if st.order[0, i] in ON_POINT else "")
               + f"@({x[i]:.1f},{y[i]:.1f})" for i in np.flatnonzero(red & alive)]
        text += "\n      " + " ".join(own)
    if enemy:
        theirs = [f"{i}:>{st.target[0, i] if st.target[0, i] >= 0 else '-'}@({x[i]:.1f},{y[i]:.1f})"
                  for i in np.flatnonzero(~red & alive)]
        text += "\n   vs " + " ".join(theirs)
    return text


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", type=Path, required=True, help="a model.zip written by `smac-hard-gym train`")
    p.add_argument("--games", type=int, default=8, help="greedy test games (default 8)")
    p.add_argument("--opponent", default="smac", help="the opponent script (default smac)")
    p.add_argument("--show", type=int, default=None, help="print this game (0-based) step by step")
    p.add_argument("--orders", action="store_true", help="with --show: each learner unit's order and position")
    p.add_argument("--enemy", action="store_true", help="with --show: each opponent unit's target and position")
    a = p.parse_args(argv)
    if a.games < 1:
        p.error(f"--games must be >= 1, got {a.games}")
    if a.show is not None and not 0 <= a.show < a.games:
        p.error(f"--show must be a game in 0..{a.games - 1}, got {a.show}")
    if not a.model.is_file():
        p.error(f"no model at {a.model}")
    won = trace(a.model, a.games, a.opponent, a.show, a.orders, a.enemy)
    print(f"won {sum(won)} of {len(won)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
