"""How sure a trained model is of its actions where its units can attack, and how its greedy choices of target differ
from sampled ones: why a policy can win with sampled actions and lose with its most likely ones.

Plays ``--episodes`` test games of a ``model.zip`` from ``smac-hard-gym train`` against ``--opponent`` (default
``smac``) with the most likely actions (the protocol's), on the test battles ``train`` evaluates on (seeded from
``TEST_SEED_BASE``), one battle at a time. In every step where at least ``--min-attackers`` units may attack, over
those units:

- ``p_top``: the probability of each unit's most likely action (mean over units and steps);
- ``p_attack``: the probability the unit puts on its attack actions in all;
- ``attacking``: the share of the units whose greedy / sampled action is an attack;
- ``distinct_targets``: distinct targets per attacking unit, greedy / sampled (1: every attacker on its own target;
  lower: attackers share targets), over steps with two or more attackers.

Sampled actions are drawn from the same distributions in the same states (numpy, seeded per game and step), so the
two columns compare choices, not games.

    python benchmarks/action_spread.py --model runs/bane_vs_bane-smac-s0/model.zip --episodes 16
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def spread(model_path: Path, episodes: int, opponent: str, min_attackers: int) -> dict[str, float]:
    """The module docstring's figures for ``episodes`` greedy test games of the model at ``model_path``."""
    import torch

    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.smac.kernels import N_ACTIONS_NO_ATTACK
    from smac_hard_gym.training.protocol import TEST_SEED_BASE
    from smac_hard_gym.training.run_files import load_trained

    torch.set_num_threads(1)
    model, config, env_kwargs = load_trained(model_path)
    seen: dict[str, list[float]] = {k: [] for k in ("p_top", "p_attack", "attacking_greedy", "attacking_sampled",
                                                    "distinct_targets_greedy", "distinct_targets_sampled")}
    for episode in range(episodes):
        venv = NativeVectorEnv(config.map_name, 1, autoreset_mode="SameStep", opponent=opponent, **env_kwargs)
        try:
            obs, _ = venv.reset(seed=TEST_SEED_BASE + episode)
            for step in range(venv.episode_limit):
                masks = venv.action_masks()
                with torch.no_grad():
                    dist = model.policy.get_distribution(torch.as_tensor(obs), action_masks=masks)
                probs = np.asarray(dist.distribution.probs[:, 0, :], dtype=np.float64)  # (units, actions)
                may_attack = masks.reshape(probs.shape)[:, N_ACTIONS_NO_ATTACK:].any(axis=1)
                if may_attack.sum() >= min_attackers:
                    p = probs[may_attack]
                    rng = np.random.default_rng([episode, step])
                    sampled = np.array([rng.choice(len(row), p=row / row.sum()) for row in p])
                    seen["p_top"].append(float(p.max(axis=1).mean()))
                    seen["p_attack"].append(float(p[:, N_ACTIONS_NO_ATTACK:].sum(axis=1).mean()))
                    for name, chosen in (("greedy", p.argmax(axis=1)), ("sampled", sampled)):
                        attacks = chosen[chosen >= N_ACTIONS_NO_ATTACK]
                        seen[f"attacking_{name}"].append(attacks.size / chosen.size)
                        if attacks.size >= 2:
                            seen[f"distinct_targets_{name}"].append(np.unique(attacks).size / attacks.size)
                action, _ = model.predict(obs, action_masks=masks, deterministic=True)
                obs, _, terminated, truncated, _ = venv.step(action)
                if terminated[0] or truncated[0]:
                    break
        finally:
            venv.close()
    return {k: float(np.mean(v)) if v else float("nan") for k, v in seen.items()} | {
        "steps": len(seen["p_top"]), "episodes": episodes, "map": config.map_name, "opponent": opponent}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", type=Path, required=True, help="a model.zip written by `smac-hard-gym train`")
    p.add_argument("--episodes", type=int, default=16, help="greedy test games (default 16)")
    p.add_argument("--opponent", default="smac", help="the opponent script (default smac)")
    p.add_argument("--min-attackers", type=int, default=4,
                   help="count a step only when at least this many units may attack (default 4)")
    p.add_argument("--json", type=Path, help="also write the figures here")
    a = p.parse_args(argv)
    if a.episodes < 1 or a.min_attackers < 1:
        p.error(f"--episodes and --min-attackers must be >= 1, got {a.episodes} and {a.min_attackers}")
    if not a.model.is_file():
        p.error(f"no model at {a.model}")
    figures = spread(a.model, a.episodes, a.opponent, a.min_attackers)
    for name, value in figures.items():
        print(f"{name:26s} {value:.3f}" if isinstance(value, float) else f"{name:26s} {value}")
    if a.json:
        a.json.write_text(json.dumps(figures, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
