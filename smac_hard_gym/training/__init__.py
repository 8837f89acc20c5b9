"""Training, evaluation and the baselines sweep: everything that learns a policy or measures one.

Needs the ``[train]`` extra (torch, stable-baselines3, sb3-contrib, matplotlib) to run; everything heavy is imported
inside the functions, so importing the package is cheap. It sits above the envs, opponents and wrappers and
imports them; nothing below imports it.

- :mod:`.protocol`: the test protocol ``train``, ``eval`` and the sweep share (test and training seeds, the spread
  of a win rate);
- :mod:`.config`: :class:`TrainConfig`, a run's settings;
- :mod:`.loop`: :func:`train`, MaskablePPO on the native vector env (``smac-hard-gym train``);
- :mod:`.sb3_hooks`: the env timer, evaluation callback and progress bar the loop plugs into stable-baselines3;
- :mod:`.league`: self-play league training (snapshots of the learner join a
  :class:`~smac_hard_gym.opponents.league.League`);
- :mod:`.evaluation`: masked win rate of a model per opponent script and for their mixture (``smac-hard-gym eval``);
- :mod:`.run_files`: a run's curve, plot and summary, and its config and model read back;
- :mod:`.baselines`: the SMAC-HARD paper's experiments as a resumable sweep of runs (``smac-hard-gym baselines``).
"""

from __future__ import annotations

from smac_hard_gym.training.config import TrainConfig
from smac_hard_gym.training.evaluation import EvalResult, evaluate, evaluate_scripts, resolve_opponents
from smac_hard_gym.training.loop import train
from smac_hard_gym.training.protocol import TEST_SEED_BASE, eval_seeds, training_seeds, win_rate_spread
from smac_hard_gym.training.run_files import CURVE_COLUMNS, load_model, load_run_config
from smac_hard_gym.training.sb3_hooks import distribution_checks_off

__all__ = ["TrainConfig", "EvalResult", "train", "evaluate", "evaluate_scripts", "resolve_opponents",
           "load_run_config", "load_model", "CURVE_COLUMNS", "TEST_SEED_BASE", "eval_seeds", "training_seeds",
           "win_rate_spread", "distribution_checks_off"]
