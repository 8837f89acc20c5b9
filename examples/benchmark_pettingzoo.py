"""B=1 step speed: the PettingZoo parallel env against ``StarCraft2Env`` on the same map and opponent, same run.

    python examples/benchmark_pettingzoo.py                          # 3m, opponent smac, 5 rounds of 2 s each
    python examples/benchmark_pettingzoo.py --map 27m_vs_30m --rounds 7 --seconds 3

What one round does, for each loop in turn (the order alternates between rounds, so drifting machine load hits both
alike), each loop on its own env built once and warmed up:

- ``smac``: pymarl's loop over ``StarCraft2Env``: ``get_obs()``, ``get_state()``, ``get_avail_actions()``, pick,
  ``step(actions)``; ``reset()`` when the episode ends.
- ``pz``: ``step(dict of actions)`` on ``smac_hard_gym.pettingzoo.parallel_env`` (observations and masks come with
  the step); ``reset()`` when ``env.agents`` is empty.
- ``pz+state``: the same plus ``state()`` every step (what a centralised critic reads, as pymarl's ``get_state``).

Both pick a random legal action per agent the same way (uniform scores plus the mask, argmax). Reported: env steps
per second (one battle, B=1, stepped once = 1), as CPU seconds of this process (``time.process_time``: robust to other
work on a shared machine) and wall seconds, the median over rounds, and the ratio of medians pz / smac.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

from smac_hard_gym import StarCraft2Env
from smac_hard_gym.bench.machine import machine_info
from smac_hard_gym.pettingzoo import parallel_env


def pick(masks: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A legal action per row of ``masks`` (n, n_actions), uniform among the legal ones."""
    return (rng.random(masks.shape) + masks).argmax(axis=1)


def smac_loop(env: StarCraft2Env, seconds: float, rng: np.random.Generator) -> tuple[int, float, float]:
    """pymarl's loop for ``seconds`` of CPU time: (steps, cpu seconds, wall seconds)."""
    steps, cpu0, wall0 = 0, time.process_time(), time.perf_counter()
    while time.process_time() - cpu0 < seconds:
        env.get_obs()
        env.get_state()
        avail = env.get_avail_actions()
        _, done, _ = env.step(pick(np.asarray(avail), rng).tolist())
        steps += 1
        if done:
            env.reset()
    return steps, time.process_time() - cpu0, time.perf_counter() - wall0


def pz_loop(env, seconds: float, rng: np.random.Generator, with_state: bool) -> tuple[int, float, float]:
    """PettingZoo's loop for ``seconds`` of CPU time: (steps, cpu seconds, wall seconds)."""
    observations, _ = env.reset()
    steps, cpu0, wall0 = 0, time.process_time(), time.perf_counter()
    while time.process_time() - cpu0 < seconds:
        agents = env.agents
        masks = np.array([observations[agent]["action_mask"] for agent in agents])
        actions = dict(zip(agents, pick(masks, rng).tolist(), strict=True))
        observations, _, _, _, _ = env.step(actions)
        if with_state and env.agents:
            env.state()
        steps += 1
        if not env.agents:
            observations, _ = env.reset()
    return steps, time.process_time() - cpu0, time.perf_counter() - wall0


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--map", default="3m")
    parser.add_argument("--opponent", default="smac", help="the opponent script of both envs (default: smac)")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=2.0, help="CPU seconds per loop per round")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print the result as JSON too")
    args = parser.parse_args(argv)
    if args.rounds < 1 or args.seconds <= 0:
        parser.error(f"--rounds must be >= 1 and --seconds > 0, got {args.rounds} and {args.seconds}")

    machine = machine_info()
    print(f"machine: {machine['cpu']}, {machine['cores']} cores, load {machine['load_average']}, "
          f"python {machine['python']}, numba {machine['numba']}")
    print(f"map {args.map}, opponent {args.opponent}, batch size 1, {args.rounds} interleaved rounds of "
          f"{args.seconds} CPU s per loop")
    smac = StarCraft2Env(args.map, opponent=args.opponent)
    smac.reset(seed=args.seed)
    pz = parallel_env(args.map, opponent=args.opponent)
    pz.reset(seed=args.seed)
    pz_state = parallel_env(args.map, opponent=args.opponent)  # its own env: state() changes what steps encode
    pz_state.reset(seed=args.seed)
    loops = {
        "smac": lambda s, rng: smac_loop(smac, s, rng),
        "pz": lambda s, rng: pz_loop(pz, s, rng, False),
        "pz+state": lambda s, rng: pz_loop(pz_state, s, rng, True),
    }
    rng = np.random.default_rng(args.seed)
    for loop in loops.values():  # warm-up: compiled kernels load, caches fill
        loop(0.2, rng)
    cpu_rates: dict[str, list[float]] = {name: [] for name in loops}
    wall_rates: dict[str, list[float]] = {name: [] for name in loops}
    for r in range(args.rounds):
        order = list(loops) if r % 2 == 0 else list(reversed(loops))
        for name in order:
            steps, cpu, wall = loops[name](args.seconds, rng)
            cpu_rates[name].append(steps / cpu)
            wall_rates[name].append(steps / wall)
        print(f"round {r + 1}: " + ", ".join(f"{name} {cpu_rates[name][-1]:,.0f}" for name in loops)
              + " steps/s (CPU)")
    med = {name: statistics.median(v) for name, v in cpu_rates.items()}
    med_wall = {name: statistics.median(v) for name, v in wall_rates.items()}
    print("\nmedian env steps/s, B=1 (CPU time | wall time):")
    for name in loops:
        print(f"  {name:9s} {med[name]:10,.0f} | {med_wall[name]:10,.0f}   ratio to smac {med[name] / med['smac']:.2f}")
    result = {"map": args.map, "opponent": args.opponent, "batch_size": 1, "rounds": args.rounds,
              "median_cpu_steps_per_s": med, "median_wall_steps_per_s": med_wall, "machine": machine}
    if args.json:
        print(json.dumps(result, indent=1))
    smac.close()
    pz.close()
    pz_state.close()
    return result


if __name__ == "__main__":
    main()
