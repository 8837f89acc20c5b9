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


def shares(model_path: Path, episodes: int, opponent: str) -> dict[str, dict[str, float]]:
    import torch

    from smac_hard_gym.engine.units import STATS, S
    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.training.protocol import TEST_SEED_BASE
    from smac_hard_gym.training.run_files import load_model, load_run_config

    torch.set_num_threads(1)
    config = load_run_config(model_path)
    if config is None:
        raise SystemExit(f"no config.json next to {model_path}")
    kwargs = {k: v for k, v in config.env_kwargs().items() if k != "map_name"}
    model = load_model(model_path)
    venv = NativeVectorEnv(config.map_name, 1, autoreset_mode="SameStep", opponent=opponent, **kwargs)
    st = venv.core.backend.state
    counts = {"learner": dict.fromkeys(CLASSES, 0), "opponent": dict.fromkeys(CLASSES, 0)}
    try:
        for episode in range(episodes):
            obs, _ = venv.reset(seed=TEST_SEED_BASE + episode)
            utype = st.utype[0]
            reach = STATS[utype, S["range"]] + STATS[utype, S["radius"]]
            stall = 0.25 * venv.core.backend.step_mul * STATS[utype, S["speed"]]
            red = np.arange(utype.size) < venv.core.n_red
            while True:
                x, y, alive, target = st.x[0].copy(), st.y[0].copy(), st.alive[0].copy(), st.target[0].copy()
                actions, _ = model.predict(obs, action_masks=venv.action_masks(), deterministic=True)
                obs, _, terminated, truncated, _ = venv.step(actions)
                if terminated[0] or truncated[0]:
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
                    counts["learner" if red[i] else "opponent"][kind] += 1
    finally:
        venv.close()
    return {side: {k: v / max(1, sum(c.values())) for k, v in c.items()} for side, c in counts.items()}


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
    print("side      " + "".join(f"{k:>10}" for k in CLASSES))
    for side, row in result.items():
        print(f"{side:<10}" + "".join(f"{row[k]:>10.3f}" for k in CLASSES))
    if a.json:
        a.json.write_text(json.dumps({"model": str(a.model), "episodes": a.episodes, "opponent": a.opponent,
                                      "shares": result}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
