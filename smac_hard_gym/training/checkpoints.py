"""Checkpoints of a training run, so that ``smac-hard-gym train --resume`` can carry an interrupted run on.

:func:`~smac_hard_gym.training.loop.train` writes two files into the run's folder at the start of a rollout (after an
update, so the weights are exactly those trained on the steps counted), every ``checkpoint_every`` env steps and at
the end of training: ``checkpoint.zip`` (the model with its optimiser state, stable-baselines3's format) and
``checkpoint.json`` (the step count, the learning curve so far, the evaluation schedule and the clocks). The JSON is
written last, so a checkpoint whose JSON names a different step than its model holds was cut short and is refused.

A resumed run reloads the networks, the optimiser, the value normaliser and the step count, and starts new training
battles (seeded ``seed + steps``, so a resume is reproducible); it does not restore the battles in progress or the
partial rollout, so it is not bit-identical to an uninterrupted run, and steps trained after the last checkpoint are
trained again.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from smac_hard_gym.files import read_json, write_json
from smac_hard_gym.training.config import TrainConfig

__all__ = ["CHECKPOINT_MODEL", "CHECKPOINT_STATE", "RESUMABLE_OPTIONS", "RunState", "read_checkpoint",
           "check_resumable", "write_state"]

CHECKPOINT_MODEL = "checkpoint.zip"
CHECKPOINT_STATE = "checkpoint.json"
# Settings a resume may change: how long to train, where the run's folder now is, and how the run is shown and
# threaded (nothing it learns from).
RESUMABLE_OPTIONS = ("timesteps", "out", "progress", "torch_threads", "env_threads", "checkpoint_every")


@dataclass
class RunState:
    """What a run needs besides its model to carry on: the step count the model was saved at, the curve's rows,
    the next evaluation's step, the training episodes' results since the last evaluation, the training wall time and
    time inside the env so far, and the step counts the run was resumed from."""

    timesteps: int
    rows: list[dict[str, Any]]
    next_eval: int
    train_results: list[bool] = field(default_factory=list)
    wall_s: float = 0.0
    env_s: float = 0.0
    resumed_from: list[int] = field(default_factory=list)


def write_state(out: Path, state: RunState) -> None:
    """``checkpoint.json`` (NaN, which JSON lacks, is stored as null)."""
    data = asdict(state)
    data["rows"] = [{k: None if isinstance(v, float) and math.isnan(v) else v for k, v in row.items()}
                    for row in state.rows]
    write_json(out / CHECKPOINT_STATE, data)


def read_checkpoint(out: Path) -> RunState:
    """The run state of the checkpoint in ``out``; a missing or malformed one raises a ValueError that says what."""
    path = out / CHECKPOINT_STATE
    if not (out / CHECKPOINT_MODEL).is_file() or not path.is_file():
        raise ValueError(f"no checkpoint to resume in {str(out)!r} (it needs {CHECKPOINT_MODEL} and "
                         f"{CHECKPOINT_STATE}, which train writes every --checkpoint-every steps)")
    data = read_json(path, "checkpoint state")
    names = {f.name for f in fields(RunState)}
    if not isinstance(data, dict) or not {"timesteps", "rows", "next_eval"} <= data.keys() \
            or not isinstance(data["rows"], list) or not data["rows"]:
        raise ValueError(f"{path}: malformed checkpoint state (an object with timesteps, rows and next_eval expected)")
    rows = [{k: math.nan if v is None else v for k, v in row.items()} for row in data["rows"]]
    state = RunState(**{k: v for k, v in data.items() if k in names and k != "rows"}, rows=rows)
    if not isinstance(state.timesteps, int) or state.timesteps < 0:
        raise ValueError(f"{path}: malformed checkpoint state (timesteps {state.timesteps!r})")
    return state


def check_resumable(saved: TrainConfig, config: TrainConfig, state: RunState) -> None:
    """Raise a ValueError naming the first setting ``config`` changes from the run's ``saved`` one (other than
    :data:`RESUMABLE_OPTIONS`), or a ``timesteps`` the checkpoint has already reached."""
    for name in (f.name for f in fields(TrainConfig)):
        if name not in RESUMABLE_OPTIONS and getattr(saved, name) != getattr(config, name):
            raise ValueError(f"cannot resume with {name}={getattr(config, name)!r}: the run was started with "
                             f"{getattr(saved, name)!r} (a resume may change only {', '.join(RESUMABLE_OPTIONS)})")
    if config.timesteps <= state.timesteps:
        raise ValueError(f"the checkpoint has {state.timesteps} steps already; pass --timesteps above that to train "
                         f"on (got {config.timesteps})")
