"""What ``train`` plugs into stable-baselines3: a vector-env wrapper that times the env, the callback that
evaluates on a schedule and draws the progress bar, and torch.distributions' argument checks switched off.

The classes subclass stable-baselines3's, so they are built on first use (:func:`timed_vec_env_class`,
:func:`eval_callback_class`): importing this module does not import stable-baselines3.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

__all__ = ["timed_vec_env_class", "eval_callback_class", "distribution_checks_off"]


def timed_vec_env_class() -> type:
    """``TimedVecEnv``: a stable-baselines3 ``VecEnvWrapper`` that adds up the seconds spent inside the env."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    class TimedVecEnv(VecEnvWrapper):
        """Adds up the wall time spent inside the env: ``step_async/step_wait``, ``reset`` and the masks."""

        def __init__(self, venv: Any) -> None:
            super().__init__(venv)
            self.env_seconds = 0.0

        def _timed(self, call: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
            """``call(*args, **kwargs)``, its wall time added to ``env_seconds`` (also when it raises)."""
            start = time.perf_counter()
            try:
                return call(*args, **kwargs)
            finally:
                self.env_seconds += time.perf_counter() - start

        def reset(self) -> Any:
            return self._timed(self.venv.reset)

        def step_async(self, actions: np.ndarray) -> None:
            self._timed(self.venv.step_async, actions)

        def step_wait(self) -> Any:
            return self._timed(self.venv.step_wait)

        def env_method(self, method_name: str, *args: Any, indices: Any = None, **kwargs: Any) -> list[Any]:
            return self._timed(self.venv.env_method, method_name, *args, indices=indices, **kwargs)

    return TimedVecEnv


def eval_callback_class() -> type:
    """``EvalAndProgress``: the stable-baselines3 callback that evaluates every ``interval`` steps and draws the
    progress bar."""
    from stable_baselines3.common.callbacks import BaseCallback

    class EvalAndProgress(BaseCallback):
        """Progress bar, a masked win-rate evaluation every ``interval`` steps (plus at the start and end), and a
        call to ``checkpoint`` every ``checkpoint_interval`` steps; a resumed run passes the steps it starts from
        (``start``) and its next evaluation's step."""

        def __init__(self, evaluate_now: Callable[..., dict[str, Any]], interval: int, total: int,
                     progress: bool, checkpoint: Callable[[], None] | None = None, checkpoint_interval: int = 0,
                     start: int = 0, next_eval: int | None = None) -> None:
            super().__init__()
            self.evaluate_now = evaluate_now
            self.interval = interval
            self.total = total
            self.progress = progress
            self.bar: Any = None
            self.start = start  # the steps a resumed run had trained before this process
            self.next_eval = interval if next_eval is None else next_eval
            self.train_results: list[bool] = []
            self.checkpoint = checkpoint
            self.checkpoint_interval = checkpoint_interval
            self.next_checkpoint = start + checkpoint_interval

        def take_train_results(self) -> list[bool]:
            results, self.train_results = self.train_results, []
            return results

        def _on_training_start(self) -> None:
            if self.progress:
                import sys

                from tqdm import tqdm

                # SB3 stops at the first whole rollout past the requested steps.
                rollout = self.training_env.num_envs * self.model.n_steps
                total = -(-self.total // rollout) * rollout
                self.bar = tqdm(total=total, initial=self.start, unit="step", desc="train", dynamic_ncols=True,
                                mininterval=0.5 if sys.stderr.isatty() else 30.0)

        def _on_step(self) -> bool:
            if self.bar is not None:
                self.bar.update(self.training_env.num_envs)
            for done, info in zip(self.locals["dones"], self.locals["infos"], strict=True):
                if done:  # the sampling policy's own results, between two evaluations
                    self.train_results.append(bool(info.get("is_success", False)))
            return True

        def _on_rollout_start(self) -> None:
            # Evaluated here, after the update that follows the rollout which crossed the mark: the weights then
            # are those trained on ``num_timesteps`` steps (during a rollout they lag one update behind, and the
            # last evaluation would not be of the saved model). The end of training evaluates after ``learn``.
            if self.num_timesteps >= self.next_eval:
                while self.next_eval <= self.num_timesteps:
                    self.next_eval += self.interval
                row = self.evaluate_now(self.num_timesteps, self.take_train_results())
                if self.bar is not None:
                    self.bar.set_postfix(win_rate=f"{row['win_rate']:.2f}", env=f"{row['env_fraction']:.0%}")
            # Checkpointed here too, where the weights are those trained on exactly ``num_timesteps`` steps.
            if self.checkpoint is not None and self.checkpoint_interval and self.num_timesteps >= self.next_checkpoint:
                while self.next_checkpoint <= self.num_timesteps:
                    self.next_checkpoint += self.checkpoint_interval
                self.checkpoint()

        def _on_training_end(self) -> None:
            self.close_bar()

        def close_bar(self) -> None:
            """Close the progress bar (at the end of training, or after an interrupt, which skips the end)."""
            if self.bar is not None:
                self.bar.close()
                self.bar = None

    return EvalAndProgress


@contextlib.contextmanager
def distribution_checks_off() -> Iterator[None]:
    """torch.distributions' argument checks off inside, restored after.

    torch.distributions checks the arguments of every distribution it builds, and MaskablePPO builds two
    Categoricals per agent per forward pass (27 agents on 27m_vs_30m): the checks took about 12% of the training
    time there. They only raise on malformed logits (what comes out does not change).
    """
    from torch.distributions import Distribution

    validate = Distribution._validate_args
    Distribution.set_default_validate_args(False)
    try:
        yield
    finally:
        Distribution.set_default_validate_args(validate)
