"""A run's files: the learning curve (``curve.csv``, ``curve.png``) and ``summary.json`` that
:func:`~smac_hard_gym.training.loop.train` writes, and the run config and model read back from a run folder (``eval``
and the baselines sweep)."""

from __future__ import annotations

import csv
import math
from dataclasses import fields
from pathlib import Path
from typing import Any

from smac_hard_gym.files import atomic_path, atomic_write, read_json
from smac_hard_gym.training.config import TrainConfig
from smac_hard_gym.training.protocol import eval_seeds, win_rate_spread

__all__ = ["CURVE_COLUMNS", "write_curve", "plot_curve", "run_summary", "load_run_config", "load_model", "load_trained"]

CURVE_COLUMNS = ("timesteps", "win_rate", "mean_return", "mean_length", "episodes", "train_win_rate",
                 "train_episodes", "wall_s", "env_s", "env_fraction")


def run_summary(config: TrainConfig, rows: list[dict[str, Any]], trained: int) -> dict[str, Any]:
    """The run's summary: ``timesteps`` is the steps trained (``trained``); ``final_win_rate`` is the last test win
    rate measured after training began and ``final_win_rate_at`` the step count it was measured at (both None when
    the run stopped before its first evaluation after step 0: the untrained model's rate is in ``curve.csv``)."""
    final = rows[-1]
    measured = final if final["timesteps"] > 0 or trained == 0 else None
    reached = next((r["timesteps"] for r in rows if r["win_rate"] >= 0.8), None)
    spread = win_rate_spread(measured["wins"], measured["episodes"]) if measured else \
        {"stderr": None, "ci95": None}
    return {
        "map": config.map_name, "opponent": config.opponent, "timesteps": trained,
        "final_win_rate": measured["win_rate"] if measured else None,
        "final_win_rate_at": measured["timesteps"] if measured else None,
        "best_win_rate": max(r["win_rate"] for r in rows),
        "final_train_win_rate": final["train_win_rate"] if final["train_episodes"] else None,
        "final_train_episodes": final["train_episodes"],
        "first_timesteps_at_0.8": reached, "train_wall_s": final["wall_s"], "env_s": final["env_s"],
        "env_fraction": final["env_fraction"], "final_per_opponent": final["per_opponent"],
        "eval_episodes": config.eval_episodes,
        "final_win_rate_stderr": spread["stderr"], "final_win_rate_ci95": spread["ci95"],
        "final_per_opponent_episodes": final["per_opponent_episodes"],
        "test_seeds": eval_seeds(min(config.eval_envs, config.eval_episodes)),
        "training_seeds": [config.seed, config.seed + config.num_envs - 1],
    }


def write_curve(path: Path, rows: list[dict[str, Any]]) -> None:
    with atomic_write(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(CURVE_COLUMNS)
        for row in rows:
            writer.writerow([_fmt(row[c]) for c in CURVE_COLUMNS])


def _fmt(value: Any) -> Any:
    if isinstance(value, float):
        return f"{value:.4f}" if math.isfinite(value) else ""
    return value


def plot_curve(path: Path, rows: list[dict[str, Any]], title: str) -> bool:
    """Win rate and mean return against env steps; False when matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    steps = [r["timesteps"] for r in rows]
    fig, left = plt.subplots(figsize=(7, 4), dpi=100)
    left.plot(steps, [r["win_rate"] for r in rows], "o-", color="tab:red", label="test win rate (deterministic)")
    left.plot(steps, [r["train_win_rate"] for r in rows], ".:", color="tab:orange",
              label="training episodes (sampled)")
    left.set_xlabel("env steps")
    left.set_ylabel("win rate")
    left.set_ylim(-0.02, 1.02)
    left.grid(alpha=0.3)
    right = left.twinx()
    right.plot(steps, [r["mean_return"] for r in rows], "s--", color="tab:blue", alpha=0.6, label="mean return")
    right.set_ylabel("mean return")
    left.set_title(title)
    handles = left.get_legend_handles_labels()[0] + right.get_legend_handles_labels()[0]
    left.legend(handles=handles, loc="center right", fontsize="small")
    fig.tight_layout()
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=path.suffix.lstrip(".") or "png")
    finally:
        plt.close(fig)
    return True


def load_run_config(model_path: str | Path) -> TrainConfig | None:
    """The :class:`TrainConfig` saved next to a model by :func:`~smac_hard_gym.training.loop.train`, if there is one."""
    path = Path(model_path).with_name("config.json")
    if not path.is_file():
        return None
    data = read_json(path, "run config")
    if not isinstance(data, dict):
        raise ValueError(f"{path}: malformed run config (a JSON object of TrainConfig fields expected, got "
                         f"{type(data).__name__})")
    # Runs saved before frame stacking existed trained on single frames (their other settings are all saved).
    data.setdefault("frame_stack", 1)
    # Runs saved before `train --policy` existed trained the joint MLP, the default of the time.
    data.setdefault("policy", "joint")
    # Runs saved before the shared actor could read its unit's state row trained without it.
    data.setdefault("actor_state", False)
    known = {f.name for f in fields(TrainConfig)}
    for key in ("map_name", "opponent", "obs_mode", "policy", "out", "tensorboard", "league_weighting"):
        if key in data and not isinstance(data[key], str):
            raise ValueError(f"{path}: malformed run config ({key} is {data[key]!r}, expected a string)")
    try:
        return TrainConfig(**{k: v for k, v in data.items() if k in known})
    except (TypeError, ValueError) as err:
        raise ValueError(f"{path}: malformed run config ({err})") from None


def load_model(path: str | Path) -> Any:
    """A MaskablePPO model saved by :func:`~smac_hard_gym.training.loop.train` (``model.zip``), on the CPU; a file
    that is not one raises one ValueError naming it. Loading runs the pickled code the file holds (stable-baselines3's
    format): load only files you trust."""
    from sb3_contrib import MaskablePPO

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no model at {str(path)!r}")
    try:
        return MaskablePPO.load(path, device="cpu")
    except MemoryError:
        raise
    except Exception as err:  # a truncated zip, random bytes, another library's pickle: whatever SB3 raises
        detail = str(err).strip().splitlines()[0] if str(err).strip() else ""
        raise ValueError(f"{path}: not a saved MaskablePPO model ({type(err).__name__}"
                         f"{': ' + detail if detail else ''})") from None


def load_trained(model_path: str | Path) -> tuple[Any, TrainConfig, dict[str, Any]]:
    """``(model, config, env_options)``: a model saved by ``train``, its run's :class:`TrainConfig` and the env
    options it was trained with, less the map (``config.map_name``): what it takes to play the model's games, as
    ``NativeVectorEnv(config.map_name, n, **env_options)``. The run's ``config.json`` must be beside the model."""
    config = load_run_config(model_path)
    if config is None:
        raise FileNotFoundError(f"no config.json next to {str(model_path)!r}")
    options = {k: v for k, v in config.env_kwargs().items() if k != "map_name"}
    return load_model(model_path), config, options
