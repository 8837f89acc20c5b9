"""Masked win-rate evaluation of a trained model (``smac-hard-gym eval``, and ``train``'s evaluations).

- :func:`evaluate`: win rate of a model over exactly ``episodes`` episodes of a vector env, per opponent script;
- :func:`evaluate_against`: the same on a fresh native vector env against one opponent;
- :func:`evaluate_scripts`: one evaluation per script of a pool, and the pool's mixture (the paper's black-box
  evaluation when the pool is ``"blackbox"``).

Every evaluation plays the test battles of :mod:`smac_hard_gym.training.protocol` unless told another seed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from smac_hard_gym.training.protocol import TEST_SEED_BASE, eval_seeds, format_spread, win_rate_spread

__all__ = ["EvalResult", "evaluate", "evaluate_against", "evaluate_scripts", "resolve_opponents", "MIXTURE_ROW"]

MIXTURE_ROW = "mixture"


@dataclass
class EvalResult:
    """Masked win rate over ``episodes`` episodes, and per opponent script."""

    episodes: int
    wins: int
    mean_return: float
    mean_length: float
    per_opponent: dict[str, dict[str, float]]

    @property
    def win_rate(self) -> float:
        return self.wins / self.episodes if self.episodes else 0.0

    @property
    def spread(self) -> dict[str, Any]:
        """Episodes, standard error and 95% Wilson interval of the win rate (:func:`win_rate_spread`)."""
        return win_rate_spread(self.wins, self.episodes)


def evaluate(model: Any, venv: Any, episodes: int, *, seed: int | None = None,
             deterministic: bool = True) -> EvalResult:
    """Run ``model`` (anything with SB3's ``predict(obs, action_masks=..., deterministic=...)``) with action masks
    on a ``SAME_STEP`` gymnasium vector env until exactly ``episodes`` episodes have finished.

    Battle i contributes the first ``(episodes + i) // num_envs`` of its episodes, so short episodes are not
    over-counted (the bias of stopping at the first ``episodes`` finishes).
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    n = venv.num_envs
    quota = np.array([(episodes + i) // n for i in range(n)])
    counted = np.zeros(n, dtype=np.int64)
    returns = np.zeros(n)
    lengths = np.zeros(n, dtype=np.int64)
    wins, total_return, total_length = 0, 0.0, 0
    per_opponent: dict[str, dict[str, float]] = {}
    obs, _ = venv.reset(seed=seed)
    while (counted < quota).any():
        actions, _ = model.predict(obs, action_masks=venv.action_masks(), deterministic=deterministic)
        obs, rewards, terminated, truncated, infos = venv.step(actions)
        returns += rewards
        lengths += 1
        for i in np.flatnonzero(terminated | truncated):
            if counted[i] < quota[i]:
                final = infos["final_info"]
                won = bool(final["battle_won"][i])
                name = str(final["opponent"][i])
                row = per_opponent.setdefault(name, {"episodes": 0, "wins": 0})
                row["episodes"] += 1
                row["wins"] += won
                wins += won
                total_return += returns[i]
                total_length += lengths[i]
                counted[i] += 1
            returns[i] = 0.0
            lengths[i] = 0
    for row in per_opponent.values():
        row["win_rate"] = row["wins"] / row["episodes"]
    return EvalResult(episodes, wins, total_return / episodes, total_length / episodes,
                      dict(sorted(per_opponent.items())))


def resolve_opponents(map_name: str, opponent: str) -> tuple[list[str], np.ndarray]:
    """The scripts an evaluation covers and their mixture weights: ``"all"`` (every script that plays the map),
    ``"default"`` / ``"blackbox"`` (the map's pools), a script name, or names joined by commas (equal weights)."""
    from smac_hard_gym.opponents import make_opponent, opponent_from_text, scripts_for_map

    if opponent == "all":
        names = sorted(scripts_for_map(map_name))
        return names, np.full(len(names), 1.0 / len(names))
    script = make_opponent(map_name, opponent_from_text(opponent))
    names = getattr(script, "names", None) or [script.name]
    probs = getattr(script, "probs", None)
    return list(names), np.full(len(names), 1.0 / len(names)) if probs is None else np.asarray(probs)


def evaluate_against(model: Any, map_name: str, opponent: Any, episodes: int, num_envs: int, seed: int,
                      env_kwargs: dict[str, Any] | None, deterministic: bool = True) -> EvalResult:
    """:func:`evaluate` on a fresh native vector env of ``map_name`` against one ``opponent``, closed afterwards.

    With ``deterministic=False`` every unit's action is sampled from the policy, from torch's generator seeded with
    ``seed`` (a fork of it: the caller's generator is left as it was), so the same call plays the same games."""
    from smac_hard_gym.envs.vector import NativeVectorEnv

    kwargs = {k: v for k, v in (env_kwargs or {}).items() if k != "map_name"}
    venv = NativeVectorEnv(map_name, min(num_envs, episodes), autoreset_mode="SameStep", opponent=opponent, **kwargs)
    try:
        if deterministic:
            return evaluate(model, venv, episodes, seed=seed)
        import torch  # a sampling policy is a torch one

        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            return evaluate(model, venv, episodes, seed=seed, deterministic=False)
    finally:
        venv.close()


def evaluate_scripts(model: Any, map_name: str, opponent: str, episodes: int, *, num_envs: int = 16,
                     seed: int = TEST_SEED_BASE, env_kwargs: dict[str, Any] | None = None,
                     log: Callable[[str], None] | None = None, deterministic: bool = True) -> dict[str, Any]:
    """Evaluate ``model`` for ``episodes`` episodes against each script of ``opponent`` (see
    :func:`resolve_opponents`); the mixture's win rate is the weighted mean of the scripts' (its expectation), its
    standard error ``sqrt(sum(w_i^2 se_i^2))`` and its 95% interval the weighted sum of the scripts' Wilson bounds.
    Each script plays the test battles seeded ``seed + b`` (by default the test seeds that ``train`` evaluates on,
    :data:`TEST_SEED_BASE`), with the most likely actions (the protocol's), or sampled ones with
    ``deterministic=False`` (:func:`evaluate_against`); the result's ``actions`` says which."""
    names, probs = resolve_opponents(map_name, opponent)
    rows: dict[str, dict[str, Any]] = {}
    for name in names:
        result = evaluate_against(model, map_name, name, episodes, num_envs, seed, env_kwargs, deterministic)
        spread = result.spread
        rows[name] = {"episodes": result.episodes, "wins": result.wins, "win_rate": result.win_rate,
                      "stderr": spread["stderr"], "ci95": spread["ci95"],
                      "mean_return": result.mean_return, "mean_length": result.mean_length}
        if log is not None:
            log(f"  {name:<20} win rate {result.win_rate:6.3f}  ({format_spread(result.wins, result.episodes)})")
    mixture = float(sum(p * rows[n]["win_rate"] for n, p in zip(names, probs, strict=True)))
    stderr = math.sqrt(sum((p * rows[n]["stderr"]) ** 2 for n, p in zip(names, probs, strict=True)))
    # The weighted sum of the scripts' Wilson bounds: conservative, and never a zero-width interval at 0 or 1.
    ci95 = [float(sum(p * rows[n]["ci95"][k] for n, p in zip(names, probs, strict=True))) for k in (0, 1)]
    return {"map": map_name, "opponent": opponent, "episodes_per_script": episodes, "seed": seed,
            "actions": "deterministic" if deterministic else "sampled",
            "test_seeds": eval_seeds(min(num_envs, episodes), seed),
            "scripts": rows, "weights": dict(zip(names, (float(p) for p in probs), strict=True)),
            MIXTURE_ROW: {"win_rate": mixture, "stderr": stderr, "ci95": ci95}}
