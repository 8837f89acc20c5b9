"""The training loop (``smac-hard-gym train``): MaskablePPO on the native vector env, evaluated on a schedule.

:func:`train` runs MaskablePPO on a :class:`~smac_hard_gym.envs.vector.NativeVectorEnv` (``SAME_STEP``; with
``ray``, a :class:`~smac_hard_gym.wrappers.ray_vec.RayVectorEnv` of ``ray_actors`` actors instead) through the SB3
adapter, a masked deterministic win-rate evaluation on a schedule (:mod:`.evaluation`, on the test battles of
:mod:`.protocol`), and writes the run's files in ``out`` (:mod:`.run_files`): ``model.zip``, ``config.json``,
``curve.csv`` (timesteps, win rate, return, time inside the env), ``curve.png`` and ``summary.json``, and the
checkpoints a resumed run carries on from (:mod:`.checkpoints`). Time spent in
``env.step`` and ``action_masks`` is measured, so the env's share of the wall time is part of every report.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from smac_hard_gym.files import atomic_path, write_json
from smac_hard_gym.training.checkpoints import (
    CHECKPOINT_MODEL,
    CHECKPOINT_STATE,
    RunState,
    check_resumable,
    read_checkpoint,
    write_state,
)
from smac_hard_gym.training.config import TrainConfig
from smac_hard_gym.training.evaluation import evaluate
from smac_hard_gym.training.league import evaluate_league, league_callback_class, league_win_rates, make_league
from smac_hard_gym.training.protocol import TEST_SEED_BASE, format_spread
from smac_hard_gym.training.run_files import load_run_config, plot_curve, run_summary, write_curve
from smac_hard_gym.training.sb3_hooks import distribution_checks_off, eval_callback_class, timed_vec_env_class

__all__ = ["train"]


def train(config: TrainConfig, log: Callable[[str], None] = print, resume: bool = False) -> dict[str, Any]:
    """Train MaskablePPO as ``config`` says; returns the summary (also written to ``summary.json``). ``resume``:
    carry on the run in ``config.out`` from its checkpoint (:mod:`.checkpoints`) up to ``config.timesteps``; its
    other settings must be the run's own."""
    with distribution_checks_off():
        return _train(config, log, resume)


def _train(config: TrainConfig, log: Callable[[str], None], resume: bool) -> dict[str, Any]:
    import numba
    import torch
    from sb3_contrib import MaskablePPO
    from stable_baselines3.common.vec_env import VecMonitor

    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.opponents import opponent_from_text
    from smac_hard_gym.wrappers.sb3 import SB3VecEnv
    from smac_hard_gym.wrappers.sb3_buffers import MaskableJointDictRolloutBuffer, MaskableJointRolloutBuffer
    from smac_hard_gym.wrappers.sb3_policy import MaskableJointMultiInputPolicy, MaskableJointPolicy
    from smac_hard_gym.wrappers.sb3_shared import SharedUnitPolicy, SharedUnitRolloutBuffer

    torch.set_num_threads(config.torch_threads)
    numba.set_num_threads(min(config.env_threads, numba.config.NUMBA_NUM_THREADS))
    out = Path(config.out)
    state = _resume_state(config) if resume else None
    out.mkdir(parents=True, exist_ok=True)
    if state is None:  # a new run in an old run's folder: its checkpoint must not be resumed as this run's
        for name in (CHECKPOINT_STATE, CHECKPOINT_MODEL):
            (out / name).unlink(missing_ok=True)
    write_json(out / "config.json", asdict(config))

    opponent = opponent_from_text(config.opponent)
    kwargs = config.env_kwargs()  # the evaluation battles': SMAC's default reward whatever config.reward says
    train_kwargs = config.train_env_kwargs()
    map_name = kwargs.pop("map_name")
    train_kwargs.pop("map_name")
    league = make_league(map_name, opponent, config.league_weighting) if config.league else None
    if config.ray:
        from smac_hard_gym.wrappers.ray_vec import make_ray_vec

        native = make_ray_vec(map_name, config.ray_actors, config.num_envs // config.ray_actors,
                              autoreset_mode="SameStep", address=config.ray_address, worker_threads=config.env_threads,
                              opponent=opponent, **train_kwargs)
        log(f"training battles on Ray: {native!r}")
    else:
        native = NativeVectorEnv(map_name, config.num_envs, autoreset_mode="SameStep",
                                 opponent=opponent if league is None else league, **train_kwargs)
    timed = timed_vec_env_class()(SB3VecEnv(native))
    venv = VecMonitor(timed)
    eval_env = NativeVectorEnv(map_name, min(config.eval_envs, config.eval_episodes), autoreset_mode="SameStep",
                               opponent=opponent, **kwargs)
    # sb3-contrib's MlpPolicy / MultiInputPolicy with the joint action as one batched categorical, and its buffers
    # without a second copy of each minibatch: the same weights for the same seed, less training time
    # (wrappers/sb3_policy.py, wrappers/sb3_buffers.py)
    dict_obs = config.obs_mode == "dict"
    policy = MaskableJointMultiInputPolicy if dict_obs else MaskableJointPolicy
    buffer = MaskableJointDictRolloutBuffer if dict_obs else MaskableJointRolloutBuffer
    if config.policy == "shared":  # one actor for every unit, state critic, value normalisation (sb3_shared.py)
        policy, buffer = SharedUnitPolicy, SharedUnitRolloutBuffer
    algorithm = MaskablePPO
    if config.ratio == "unit":  # MAPPO's loss: each unit's ratio clipped (sb3_unit_ppo.py)
        from smac_hard_gym.wrappers.sb3_unit_ppo import UnitRatioMaskablePPO

        algorithm = UnitRatioMaskablePPO
    if state is None:
        model = algorithm(policy, venv, rollout_buffer_class=buffer, tensorboard_log=config.tensorboard or None,
                          **config.ppo_kwargs())
    else:
        model = algorithm.load(out / CHECKPOINT_MODEL, env=venv, device="cpu",
                               tensorboard_log=config.tensorboard or None)
        if model.num_timesteps != state.timesteps:
            raise ValueError(f"{out / CHECKPOINT_MODEL} holds {model.num_timesteps} steps but {CHECKPOINT_STATE} "
                             f"says {state.timesteps}: the checkpoint was cut short while written")
        # New training battles, seeded by the step count so that a resume is reproducible and does not replay
        # the run's first battles.
        model.set_random_seed(config.seed + state.timesteps)
        log(f"resuming {out} from its checkpoint at {state.timesteps} steps")
    if not config.tensorboard:
        # SB3's default logger makes an empty folder /tmp/SB3-<time> on every learn(), even when it writes nothing.
        from stable_baselines3.common.logger import Logger

        model.set_logger(Logger(folder=None, output_formats=[]))

    rows: list[dict[str, Any]] = [] if state is None else list(state.rows)
    clock = {"start": time.perf_counter(), "eval": 0.0}

    def train_wall() -> float:  # training time so far, evaluations left out
        return time.perf_counter() - clock["start"] - clock["eval"]

    def evaluate_now(timesteps: int, train_results: Sequence[bool] = ()) -> dict[str, Any]:
        start = time.perf_counter()
        result = evaluate(model, eval_env, config.eval_episodes, seed=TEST_SEED_BASE)
        clock["eval"] += time.perf_counter() - start
        wall = train_wall()
        row = {"timesteps": timesteps, "win_rate": result.win_rate, "mean_return": result.mean_return,
               "mean_length": result.mean_length, "episodes": result.episodes,
               "train_win_rate": float(np.mean(train_results)) if len(train_results) else float("nan"),
               "train_episodes": len(train_results), "wall_s": wall,
               "env_s": timed.env_seconds, "env_fraction": timed.env_seconds / wall if wall > 0 else 0.0,
               "wins": result.wins,
               "per_opponent": {k: v["win_rate"] for k, v in result.per_opponent.items()},
               "per_opponent_episodes": {k: int(v["episodes"]) for k, v in result.per_opponent.items()}}
        rows.append(row)
        write_curve(out / "curve.csv", rows)
        return row

    def checkpoint() -> None:
        with atomic_path(out / CHECKPOINT_MODEL) as tmp:
            model.save(tmp)
        write_state(out, RunState(timesteps=int(model.num_timesteps), rows=rows, next_eval=progress.next_eval,
                                  train_results=list(progress.train_results), wall_s=train_wall(),
                                  env_s=timed.env_seconds, resumed_from=resumed_from))

    resumed_from = [] if state is None else [*state.resumed_from, state.timesteps]
    next_eval = None
    if state is not None:  # a finished run trained further was evaluated at its end, after its last checkpoint
        next_eval = state.next_eval
        while next_eval <= rows[-1]["timesteps"]:
            next_eval += config.eval_interval
    progress: Any = eval_callback_class()(
        evaluate_now, config.eval_interval, config.timesteps, config.progress,
        checkpoint=None if league is not None else checkpoint,  # a league's members are not checkpointed
        checkpoint_interval=config.checkpoint_every, start=0 if state is None else state.timesteps,
        next_eval=next_eval)
    if state is not None:
        progress.train_results = list(state.train_results)
    callback: Any = progress
    callbacks = [progress]
    if league is not None:
        callbacks.append(league_callback_class()(league, native.core, config.league_interval))
    if config.ent_coef_final is not None:
        callbacks.append(_entropy_schedule(config))
    if len(callbacks) > 1:
        from stable_baselines3.common.callbacks import CallbackList

        callback = CallbackList(callbacks)
    if state is None:
        evaluate_now(0)
    clock["start"] = time.perf_counter() - (0.0 if state is None else state.wall_s)
    clock["eval"] = 0.0
    timed.env_seconds = 0.0 if state is None else state.env_s
    interrupted = False
    try:
        model.learn(config.timesteps - model.num_timesteps, callback=callback, reset_num_timesteps=state is None)
        if rows[-1]["timesteps"] != model.num_timesteps:
            evaluate_now(model.num_timesteps, progress.take_train_results())
        if league is None:  # the end too, so that `--resume --timesteps MORE` can train a finished run further
            checkpoint()
    except KeyboardInterrupt:  # Ctrl-C: keep what was learned, the curve so far and a summary that says so
        interrupted = True
    finally:
        # SB3 skips the callback's end on an exception: close the bar here, so it does not draw itself again after
        # the caller's "interrupted" message.
        progress.close_bar()
        venv.close()
        eval_env.close()
    with atomic_path(out / "model.zip") as tmp:
        model.save(tmp)
    plotted = plot_curve(out / "curve.png", rows, f"MaskablePPO on {config.map_name} vs {config.opponent}")
    summary = run_summary(config, rows, int(model.num_timesteps))
    if league is not None and not interrupted:
        league.update(league_win_rates(native.core))
        summary["league"] = evaluate_league(model, league, config, native.core)
    summary["interrupted"] = interrupted
    summary["resumed_from"] = resumed_from
    summary["timesteps_trained"] = int(model.num_timesteps)
    summary["files"] = {"model": str(out / "model.zip"), "curve_csv": str(out / "curve.csv"),
                        "curve_png": str(out / "curve.png") if plotted else None,
                        "config": str(out / "config.json")}
    write_json(out / "summary.json", summary)
    if summary["final_win_rate"] is not None:
        final = next(r for r in reversed(rows) if r["timesteps"] == summary["final_win_rate_at"])
        log(f"test evaluation at {final['timesteps']} steps: {format_spread(final['wins'], final['episodes'])}; "
            f"{len(summary['test_seeds'])} test battles seeded {summary['test_seeds'][0]}..{summary['test_seeds'][-1]} "
            "(the battles `smac-hard-gym eval` plays by default), training battles seeded "
            f"{config.seed}..{config.seed + config.num_envs - 1}")
    return summary


def _resume_state(config: TrainConfig) -> RunState:
    """The checkpoint of the run in ``config.out``, after checking that ``config`` may carry it on."""
    out = Path(config.out)
    state = read_checkpoint(out)
    saved = load_run_config(out / CHECKPOINT_MODEL)
    if saved is None:
        raise ValueError(f"no config.json in {str(out)!r}: the checkpoint's run settings are unknown")
    check_resumable(saved, config, state)
    return state


def _entropy_schedule(config: TrainConfig) -> Any:
    """A stable-baselines3 callback that sets the model's ``ent_coef`` to ``config.ent_coef_at(steps so far)`` after
    each rollout, before the update that uses it (``--ent-coef-final``)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class EntropySchedule(BaseCallback):
        def _on_rollout_end(self) -> None:
            self.model.ent_coef = config.ent_coef_at(self.model.num_timesteps)

        def _on_step(self) -> bool:
            return True

    return EntropySchedule()
