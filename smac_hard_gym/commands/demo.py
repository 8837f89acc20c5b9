"""``smac-hard-gym demo``: a scripted battle on the embedded engine, no StarCraft II needed.

The learner's side attack-moves to the opponent's spawn (SMAC's *_RL units acquire targets during an attack-move),
the opponent plays SMAC's default ``base`` script. Prints win/draw/loss rates over a batch of battles.
"""

from __future__ import annotations

import argparse

HELP = "run a scripted battle on the embedded engine and print the outcome"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--map", default="3m", help="map name (see `smac-hard-gym maps`)")
    parser.add_argument("--battles", type=int, default=64, help="battles run side by side (default 64)")
    parser.add_argument("--seed", type=int, default=0)


def run(args: argparse.Namespace) -> int:
    import numpy as np
    from tqdm import tqdm

    from smac_hard_gym.engine import CMD_ATTACK_MOVE, BattleEngine
    from smac_hard_gym.opponents import make_opponent
    from smac_hard_gym.opponents.api import SideView

    if args.battles < 1:
        raise SystemExit(f"--battles must be >= 1, got {args.battles}")
    engine = BattleEngine(args.map, batch_size=args.battles)
    spec = engine.spec
    print(f"map {spec.name}: {spec.n_red} vs {spec.n_blue}, limit {spec.episode_limit} steps, "
          f"{args.battles} battles, opponent 'base'")
    steps = np.zeros(args.battles, dtype=np.int64)
    view = SideView(engine.state, spec, 1, engine.blue_slots, engine.red_slots, steps)
    opponent = make_opponent(spec, "base")
    rngs = [np.random.default_rng([args.seed, b]) for b in range(args.battles)]
    opponent.reset(view, np.arange(args.battles), rngs)
    blue_x = engine.layout.x[engine.blue_slots].mean()
    blue_y = engine.layout.y[engine.blue_slots].mean()
    done = np.zeros(args.battles, dtype=bool)
    outcome = np.zeros(args.battles, dtype=np.int8)  # 1 red win, -1 loss, 0 draw/timeout
    for step in tqdm(range(spec.episode_limit), desc="steps", unit="step"):
        cmd = engine.commands
        cmd.clear()
        if step == 0:
            cmd.kind[:, engine.red_slots] = CMD_ATTACK_MOVE
            cmd.x[:, engine.red_slots] = blue_x
            cmd.y[:, engine.red_slots] = blue_y
        active = ~done
        opponent.act(view, cmd, active)
        engine.step(cmd, active)
        steps[active] += 1
        red, blue = engine.alive_counts()
        ended = active & ((red == 0) | (blue == 0))
        outcome[ended & (blue == 0) & (red > 0)] = 1
        outcome[ended & (red == 0) & (blue > 0)] = -1
        done |= ended
        if done.all():
            break
    n = args.battles
    print(f"red (attack-move) wins {np.mean(outcome == 1):.2f}, losses {np.mean(outcome == -1):.2f}, "
          f"draws/timeouts {np.mean(outcome == 0):.2f} over {n} battles; mean length {steps.mean():.1f} steps")
    return 0
