"""Measure env steps per second of a SMAC-HARD vector env yourself: the loop that `smac-hard-gym bench vector` times.

    python examples/benchmark_vector.py                      # 3m, 1 / 256 / 4096 battles
    python examples/benchmark_vector.py --map 8m --num-envs 64,1024 --seconds 3

What one measurement does:

1. Build ``num_envs`` battles in one native vector env, through gymnasium's own ``make_vec``. ``SameStep``
   autoreset restarts a finished battle inside the step that ended it, so resets are part of what is timed.
2. Warm up for two steps (the engine's compiled kernels load from numba's disk cache, or compile, on first use).
3. Step with random *legal* actions for a few seconds: one uniform draw per (battle, agent, action) plus the action
   mask, then argmax. Legal actions score in [1, 2), illegal ones in [0, 1), so the pick is always legal and
   uniform among the legal ones, and the whole batch costs three array operations.
4. Report env steps per second: N battles stepped once count N.

The full suite (more maps, subprocess workers, the engine alone, StarCraft2Env, memory, SMAX side by side) is
``smac-hard-gym bench vector --help``; benchmarks/README.md has the published run.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import smac_hard_gym  # noqa: F401  (registers the SMACHard-* ids)


def random_legal_actions(masks: np.ndarray, n_agents: int, rng: np.random.Generator) -> np.ndarray:
    """One legal action per agent, uniform among that agent's legal ones: int (num_envs, n_agents)."""
    masks = masks.reshape(masks.shape[0], n_agents, -1)
    scores = rng.random(masks.shape, dtype=np.float32) + masks
    return scores.argmax(axis=2)


def measure(map_name: str, num_envs: int, seconds: float, opponent: str) -> tuple[float, int]:
    """Env steps per second over ``seconds`` of random legal play, and the episodes finished meanwhile."""
    envs = gym.make_vec(f"SMACHard-{map_name}-v0", num_envs=num_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode="SameStep", opponent=opponent)
    n_agents = len(envs.single_action_space.nvec)
    rng = np.random.default_rng(0)
    envs.reset(seed=0)
    for _ in range(2):  # warm-up, not timed
        envs.step(random_legal_actions(envs.action_masks(), n_agents, rng))

    steps = episodes = 0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        actions = random_legal_actions(envs.action_masks(), n_agents, rng)
        _, _, terminated, truncated, _ = envs.step(actions)
        steps += num_envs
        episodes += int(np.count_nonzero(terminated | truncated))
    elapsed = time.perf_counter() - start
    envs.close()
    return steps / elapsed, episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--map", default="3m")
    parser.add_argument("--num-envs", default="1,256,4096", help="comma-separated batch sizes")
    parser.add_argument("--seconds", type=float, default=2.0, help="timed seconds per batch size")
    parser.add_argument("--opponent", default="base", help="base (SMAC's) or default (the SMAC-HARD mixture)")
    args = parser.parse_args()

    print(f"{'map':<12}{'num_envs':>9}{'env steps/s':>14}{'episodes':>10}")
    for num_envs in (int(n) for n in args.num_envs.split(",")):
        rate, episodes = measure(args.map, num_envs, args.seconds, args.opponent)
        print(f"{args.map:<12}{num_envs:>9}{rate:>14,.0f}{episodes:>10}")


if __name__ == "__main__":
    main()
