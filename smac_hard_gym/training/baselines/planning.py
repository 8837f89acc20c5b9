"""What a sweep runs: its settings (:class:`SweepConfig`), its runs (:func:`plan`), the state of a run's folder
(:func:`run_state`, :func:`resumable`) and the command line of each job (``smac-hard-gym train``, or ``train --resume``
for a run cut short after a checkpoint, the black-box ``eval``, the value estimate)."""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from smac_hard_gym.training.checkpoints import read_checkpoint
from smac_hard_gym.training.protocol import TEST_SEED_BASE

__all__ = ["SweepConfig", "Run", "EXPERIMENTS", "SWEEP_OPPONENTS", "plan", "run_state", "resumable", "resume_command",
           "train_command", "blackbox_command", "value_command"]

EXPERIMENTS: dict[str, dict[str, Any]] = {
    "mixing": {"maps": ["10m_vs_11m"], "opponents": ["nearest", "weakest", "nearest,weakest"], "blackbox": False,
               "values": True},
}


SWEEP_OPPONENTS = ("smac", "default")


@dataclass
class SweepConfig:
    """What a sweep trains and evaluates (written to ``results.json``)."""

    maps: list[str] = field(default_factory=list)  # [] means every map
    seeds: int = 3
    timesteps: int = 1_000_000
    out: str = "results"
    opponents: list[str] = field(default_factory=lambda: list(SWEEP_OPPONENTS))
    eval_episodes: int = 32
    num_envs: int = 64
    jobs: int = 1
    experiment: str = ""  # "" (the baseline sweep) or a key of EXPERIMENTS
    train_args: list[str] = field(default_factory=list)  # extra arguments for `smac-hard-gym train`

    def __post_init__(self) -> None:
        from smac_hard_gym.maps import list_maps

        if self.experiment:
            if self.experiment not in EXPERIMENTS:
                raise ValueError(f"unknown experiment {self.experiment!r}; experiments: {', '.join(EXPERIMENTS)}")
            spec = EXPERIMENTS[self.experiment]
            self.maps = list(self.maps or spec["maps"])
            self.opponents = list(spec["opponents"])
        known = list_maps()
        if not self.maps:
            self.maps = list(known)
        unknown = [m for m in self.maps if m not in known]
        if unknown:
            raise ValueError(f"unknown map {unknown[0]!r}; maps: {', '.join(known)}")
        for name in ("seeds", "timesteps", "eval_episodes", "num_envs", "jobs"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a positive int, got {value!r}")
        if not self.opponents:
            raise ValueError("opponents must name at least one opponent (smac, default, ...)")
        from smac_hard_gym.opponents import make_opponent, opponent_from_text

        for map_name in self.maps:
            for opponent in self.opponents:
                make_opponent(map_name, opponent_from_text(opponent))  # ValueError naming script and map

    @property
    def blackbox(self) -> bool:
        return EXPERIMENTS[self.experiment]["blackbox"] if self.experiment else "smac" in self.opponents

    @property
    def values(self) -> bool:
        return bool(self.experiment and EXPERIMENTS[self.experiment]["values"])


@dataclass(frozen=True)
class Run:
    """One training run of a sweep."""

    map_name: str
    opponent: str
    seed: int

    @property
    def label(self) -> str:
        return f"{self.map_name}-{self.opponent.replace(',', '+')}-s{self.seed}"

    def path(self, out: str | Path) -> Path:
        return Path(out) / "runs" / self.label


def plan(config: SweepConfig) -> list[Run]:
    """Every run of the sweep, map by map, then opponent, then seed (0 .. seeds-1)."""
    return [Run(m, o, s) for m in config.maps for o in config.opponents for s in range(config.seeds)]


def run_state(path: Path, timesteps: int | None = None) -> str:
    """``"done"`` (``summary.json`` of an uninterrupted run), ``"partial"`` (the directory exists without one) or
    ``"todo"``; given the sweep's ``timesteps``, a partial run with a checkpoint short of them is ``"resumable"``."""
    summary = path / "summary.json"
    if summary.is_file():
        try:
            data = json.loads(summary.read_bytes().decode("utf-8"))
        except (OSError, ValueError, RecursionError):  # unreadable or malformed: the run is redone
            data = None
        if isinstance(data, dict) and data.get("interrupted", False) is False:
            return "done"
    elif not path.exists():
        return "todo"
    return "resumable" if timesteps is not None and resumable(path, timesteps) else "partial"


def resumable(path: Path, timesteps: int) -> bool:
    """Whether a run cut short in ``path`` left a checkpoint that ``train --resume`` can carry on to ``timesteps``."""
    try:
        return read_checkpoint(path).timesteps < timesteps
    except (ValueError, FileNotFoundError):
        return False


def resume_command(run: Run, config: SweepConfig) -> list[str]:
    return [sys.executable, "-m", "smac_hard_gym.cli", "train", "--resume", "--out", str(run.path(config.out)),
            "--timesteps", str(config.timesteps), "--no-progress"]


def train_command(run: Run, config: SweepConfig) -> list[str]:
    return [sys.executable, "-m", "smac_hard_gym.cli", "train", "--map", run.map_name, "--opponent", run.opponent,
            "--timesteps", str(config.timesteps), "--num-envs", str(config.num_envs), "--seed", str(run.seed),
            "--eval-episodes", str(config.eval_episodes), "--out", str(run.path(config.out)), "--no-progress",
            *config.train_args]


def blackbox_command(run: Run, config: SweepConfig) -> list[str]:
    path = run.path(config.out)
    return [sys.executable, "-m", "smac_hard_gym.cli", "eval", "--model", str(path / "model.zip"), "--opponent",
            "blackbox", "--episodes", str(config.eval_episodes), "--json", str(path / "blackbox.json")]


def value_command(run: Run, config: SweepConfig) -> list[str]:
    path = run.path(config.out)
    code = (f"from smac_hard_gym.training.baselines.values import value_main; value_main({str(path / 'model.zip')!r}, "
            f"{run.opponent!r}, {config.eval_episodes}, {TEST_SEED_BASE}, {str(path / 'value.json')!r})")
    return [sys.executable, "-c", code]
