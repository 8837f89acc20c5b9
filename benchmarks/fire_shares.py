"""What each side's units do in the env steps of a trained model's test games: fire, wait out the weapon's cooldown
in reach, walk toward a target out of reach, stand stalled with a target out of reach, or have no target.

Plays ``--episodes`` test games of a ``model.zip`` from ``smac-hard-gym train`` against ``--opponent`` (default
``smac``) on the test battles ``train`` evaluates on (seeded from ``TEST_SEED_BASE``), one battle at a time, and
reads the engine's state before and after every env step (internal access: ``smac_hard_gym/engine/state.py``).
A unit alive through a step is counted once in one class, in this order:

- ``fired``: it fired (or healed) during the step;
- ``no_target``: its weapon engaged nobody at the step's start;
- ``in_reach``: its target was within weapon range (centre to centre, range plus both radii) at the step's start;
- ``stalled``: out of reach, and it moved less than a quarter of its step's walk;
- ``walking``: out of reach, and it moved.

It also counts **long hold-ups**: runs of ``LONG_HOLDUP`` or more consecutive env steps (2 Normal game seconds)
that a unit spends *held up*, per game, and the longest run seen. Held up: out of reach, and it got less than a
quarter of its step's walk closer to where its target stood at the step's start (stalled, or walking without closing
in: pushed back and forth behind its own line). SC2's units blocked behind their own firing line go round it or take
the first opening (docs/engine_rules.md, 7.5, sources FLOW, ARC, PATH); walking round a long line also makes little
progress, so the count holds some of that too.

Example (docs/engine_rules.md, 4.5)::

    python benchmarks/fire_shares.py --model runs/5m_vs_6m-smac-s0/model.zip --episodes 32
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

CLASSES = ("fired", "in_reach", "no_target", "walking", "stalled")
LONG_HOLDUP = 4  # env steps of 8 game loops: 2 Normal game seconds


def shares(model_path: Path, episodes: int, opponent: str) -> dict[str, dict[str, float]]:
    """Per side (``learner``, ``opponent``): the share of unit-steps in each of ``CLASSES``, ``held_up`` (the share
    of unit-steps held up), ``long_holdups`` (runs of at least ``LONG_HOLDUP`` held-up steps, per game) and
    ``longest_holdup`` (steps)."""
    import torch

    from smac_hard_gym.engine.units import STATS, S
    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.training.protocol import TEST_SEED_BASE
    from smac_hard_gym.training.run_files import load_trained

    torch.set_num_threads(1)
    model, config, kwargs = load_trained(model_path)
    venv = NativeVectorEnv(config.map_name, 1, autoreset_mode="SameStep", opponent=opponent, **kwargs)
    st = venv.core.backend.state
    counts = {"learner": dict.fromkeys(CLASSES, 0), "opponent": dict.fromkeys(CLASSES, 0)}
    long_runs = {"learner": 0, "opponent": 0}
    longest = {"learner": 0, "opponent": 0}
    held = {"learner": 0, "opponent": 0}

    def close_runs(units: np.ndarray, run: np.ndarray, red: np.ndarray) -> None:
        """End the held-up runs of ``units``: count the long ones, keep the longest."""
        for i in units:
            side = "learner" if red[i] else "opponent"
            long_runs[side] += int(run[i] >= LONG_HOLDUP)
            longest[side] = max(longest[side], int(run[i]))
            run[i] = 0

    try:
        for episode in range(episodes):
            obs, _ = venv.reset(seed=TEST_SEED_BASE + episode)
            utype = st.utype[0]
            reach = STATS[utype, S["range"]] + STATS[utype, S["radius"]]
            stall = 0.25 * venv.core.backend.step_mul * STATS[utype, S["speed"]]
            red = np.arange(utype.size) < venv.core.n_red
            run = np.zeros(utype.size, dtype=np.int64)  # consecutive held-up steps so far, per unit

            while True:
                x, y, alive, target = st.x[0].copy(), st.y[0].copy(), st.alive[0].copy(), st.target[0].copy()
                actions, _ = model.predict(obs, action_masks=venv.action_masks(), deterministic=True)
                obs, _, terminated, truncated, _ = venv.step(actions)
                if terminated[0] or truncated[0]:
                    close_runs(np.flatnonzero(run), run, red)
                    break
                for i in np.flatnonzero(alive & st.alive[0]):
                    k = target[i]
                    if st.fired_at[0, i] >= 0:
                        kind = "fired"
                    elif k < 0:
                        kind = "no_target"
                    elif np.hypot(x[i] - x[k], y[i] - y[k]) <= reach[i] + STATS[utype[k], S["radius"]]:
                        kind = "in_reach"
                    elif np.hypot(st.x[0, i] - x[i], st.y[0, i] - y[i]) < stall[i]:
                        kind = "stalled"
                    else:
                        kind = "walking"
                    side = "learner" if red[i] else "opponent"
                    counts[side][kind] += 1
                    held_up = kind == "stalled" or (kind == "walking" and np.hypot(x[i] - x[k], y[i] - y[k])
                                                     - np.hypot(st.x[0, i] - x[k], st.y[0, i] - y[k]) < stall[i])
                    if held_up:
                        held[side] += 1
                        run[i] += 1
                    elif run[i]:
                        close_runs([i], run, red)
                close_runs(np.flatnonzero((run > 0) & ~st.alive[0]), run, red)
    finally:
        venv.close()
    result = {}
    for side, c in counts.items():
        steps = max(1, sum(c.values()))
        result[side] = {**{k: v / steps for k, v in c.items()}, "held_up": held[side] / steps,
                        "long_holdups": long_runs[side] / episodes, "longest_holdup": longest[side]}
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", type=Path, required=True, help="a model.zip from `smac-hard-gym train`")
    p.add_argument("--episodes", type=int, default=32)
    p.add_argument("--opponent", default="smac")
    p.add_argument("--json", type=Path, help="also write the shares here")
    a = p.parse_args(argv)
    if a.episodes < 1:
        p.error(f"--episodes must be >= 1, got {a.episodes}")
    result = shares(a.model, a.episodes, a.opponent)
    extra = ("held_up", "long_holdups", "longest_holdup")
    print("side      " + "".join(f"{k:>10}" for k in CLASSES) + "".join(f"{k:>15}" for k in extra))
    for side, row in result.items():
        print(f"{side:<10}" + "".join(f"{row[k]:>10.3f}" for k in CLASSES)
              + f"{row['held_up']:>15.3f}{row['long_holdups']:>15.2f}{row['longest_holdup']:>15d}")
    if a.json:
        a.json.write_text(json.dumps({"model": str(a.model), "episodes": a.episodes, "opponent": a.opponent,
                                      "shares": result}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
