"""An SB3 ``VecEnv`` over any gymnasium vector env, so Stable-Baselines3 and sb3-contrib train on native batches.

SB3 has no adapter for ``gymnasium.vector.VectorEnv`` (it rejects them). :class:`SB3VecEnv` only translates:

- autoreset: SB3 resets a finished env inside the step. ``SAME_STEP`` vector envs already do; ``DISABLED`` ones
  are reset here through ``reset(options={"reset_mask": done})``. ``NEXT_STEP`` cannot be translated (the reset
  would cost an action), so it is refused with an error that says which mode to pick.
- infos: gymnasium's dict of arrays becomes SB3's list of dicts (without ``action_mask``: see masks); a finished
  env's dict carries the terminal ``info`` keys, ``terminal_observation``, ``TimeLimit.truncated`` (truncated and
  not terminated, so PPO bootstraps from the terminal value) and ``is_success`` (``battle_won``, which
  ``MaskableEvalCallback`` reports).
- masks: ``env_method("action_masks")`` answers from the ``action_mask`` of the latest infos (or the vector env's
  own ``action_masks()``), so MaskablePPO costs no extra round trip to worker processes.

>>> import gymnasium, smac_hard_gym
>>> from smac_hard_gym.wrappers.sb3 import SB3VecEnv
>>> venv = SB3VecEnv(gymnasium.make_vec("SMACHard-3m-v0", num_envs=4, autoreset_mode="SameStep"))
>>> venv.reset().shape, len(venv.env_method("action_masks"))
((4, 90), 4)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

__all__ = ["SB3VecEnv"]

MASK_KEY = "action_mask"
# Batched keys that SB3's per-env dicts do not carry: the terminal data moves into terminal_observation and the
# finished env's dict, and the masks are served by env_method("action_masks").
_NOT_PER_ENV = ("final_obs", "final_info", MASK_KEY)
_SUPPORTED_MODES = (AutoresetMode.SAME_STEP, AutoresetMode.DISABLED)


def infos_to_list(infos: dict[str, Any], num_envs: int, skip: tuple[str, ...] = ()) -> list[dict[str, Any]]:
    """Gymnasium's batched infos (dict of arrays with ``_key`` masks) as one dict per env; keys in ``skip`` are
    left out. Numeric scalars become Python numbers, array rows stay arrays."""
    out: list[dict[str, Any]] = [{} for _ in range(num_envs)]
    for key, value in infos.items():
        if key.startswith("_") or key in skip:
            continue
        if isinstance(value, dict):
            items: Any = infos_to_list(value, num_envs)
        elif isinstance(value, np.ndarray) and value.ndim == 1 and value.dtype != object:
            items = value.tolist()  # one C call instead of an .item() per env
        else:
            items = list(value)
        present = infos.get(f"_{key}")
        rows = range(num_envs) if present is None or present.all() else np.flatnonzero(present).tolist()
        for i in rows:
            out[i][key] = items[i]
    return out


class SB3VecEnv(VecEnv):
    """Stable-Baselines3 ``VecEnv`` view of a gymnasium vector env (native, subprocess, Sync or Async).

    The vector env must autoreset in ``SAME_STEP`` or ``DISABLED`` mode. Wrap the result in ``VecMonitor`` for
    episode statistics. ``env_is_wrapped`` answers False (the sub-envs are battles, not wrapped envs).
    """

    def __init__(self, venv: VectorEnv) -> None:
        if not isinstance(venv, VectorEnv):
            raise TypeError(f"SB3VecEnv wraps a gymnasium.vector.VectorEnv, got {type(venv).__name__}")
        mode = venv.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
        mode = AutoresetMode(mode) if isinstance(mode, str) else mode
        if mode not in _SUPPORTED_MODES:
            raise ValueError(f"SB3 resets finished envs inside step(); build the vector env with autoreset_mode="
                             f"'SameStep' (or 'Disabled'), got {mode.value!r} "
                             "(gymnasium.make_vec(id, num_envs=N, autoreset_mode='SameStep'))")
        self.venv = venv
        self.autoreset_mode = mode
        self._masks: np.ndarray | None = None
        self._actions: np.ndarray | None = None
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)

    def __repr__(self) -> str:
        return f"SB3VecEnv({self.venv!r})"

    @property
    def unwrapped_venv(self) -> VectorEnv:
        """The gymnasium vector env underneath (its own wrappers included)."""
        return self.venv

    # -----------------------------------------------------------------------------------------------------------
    # VecEnv API.

    def reset(self) -> VecEnvObs:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        options = self._options[0] if self._options and self._options[0] else None
        obs, infos = self.venv.reset(seed=seeds, options=options)
        self._reset_seeds()
        self._reset_options()
        self._masks = None
        self._update_masks(infos)
        self.reset_infos = infos_to_list(infos, self.num_envs, skip=(MASK_KEY,))
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async(actions)")
        obs, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        self._actions = None
        done = np.logical_or(terminated, truncated)
        self._update_masks(infos)
        info_list = infos_to_list(infos, self.num_envs, skip=_NOT_PER_ENV)
        if done.any():
            if self.autoreset_mode == AutoresetMode.SAME_STEP:
                # The returned row already starts the next episode: the terminal step lives in final_obs/info.
                final_list = infos_to_list(infos.get("final_info", {}), self.num_envs, skip=(MASK_KEY,))
                terminal = [infos["final_obs"][i] for i in range(self.num_envs)]
                for i in np.flatnonzero(done):
                    self.reset_infos[i] = info_list[i]
                    info_list[i] = final_list[i]
            else:
                terminal = [_obs_row(obs, i) if done[i] else None for i in range(self.num_envs)]
                obs, reset_infos = self.venv.reset(options={"reset_mask": done.copy()})
                self._update_masks(reset_infos)
                reset_list = infos_to_list(reset_infos, self.num_envs, skip=(MASK_KEY,))
                for i in np.flatnonzero(done):
                    self.reset_infos[i] = reset_list[i]
            for i in np.flatnonzero(done):
                info = info_list[i]
                info["terminal_observation"] = terminal[i]
                info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                if "battle_won" in info:
                    info["is_success"] = bool(info["battle_won"])
        return obs, np.asarray(rewards, dtype=np.float32), done, info_list

    def close(self) -> None:
        self.venv.close()

    # -----------------------------------------------------------------------------------------------------------
    # Attributes and methods of the sub-envs.

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        """``action_masks`` is answered from the latest masks (no round trip); other names go to the vector env's
        ``call`` (Sync/Async/subprocess envs), or to a method of that name on the vector env itself."""
        rows = list(self._get_indices(indices))
        if method_name == "action_masks" and not method_args and not method_kwargs:
            masks = self.action_masks()
            return [masks[i] for i in rows]
        if hasattr(self.venv, "call"):
            results = self.venv.call(method_name, *method_args, **method_kwargs)
            return [results[i] for i in rows] if _per_env(results, self.num_envs) else [results] * len(rows)
        raise AttributeError(f"{type(self.venv).__name__} has no per-env method {method_name!r}")

    def action_masks(self) -> np.ndarray:
        """bool ``(num_envs, mask_size)``: the legal actions of the current observations."""
        if self._masks is None:
            if hasattr(self.venv, "action_masks"):
                self._masks = np.asarray(self.venv.action_masks(), dtype=bool)
            elif hasattr(self.venv, "call"):
                self._masks = np.stack([np.asarray(m, dtype=bool) for m in self.venv.call("action_masks")])
            else:
                raise AttributeError(f"{type(self.venv).__name__} gives no action masks (no info['action_mask'], "
                                     "no action_masks() method)")
        return self._masks

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        rows = list(self._get_indices(indices))
        if attr_name == "render_mode":
            return [getattr(self.venv, "render_mode", None)] * len(rows)
        if hasattr(self.venv, "get_attr"):
            values = self.venv.get_attr(attr_name)
            return [values[i] for i in rows] if _per_env(values, self.num_envs) else [values] * len(rows)
        return [getattr(self.venv, attr_name)] * len(rows)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        if hasattr(self.venv, "set_attr"):
            self.venv.set_attr(attr_name, value)
            return
        setattr(self.venv, attr_name, value)

    def has_attr(self, attr_name: str) -> bool:
        if attr_name == "action_masks":
            return True
        try:
            self.get_attr(attr_name, [0])
        except AttributeError:
            return False
        return True

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        rows = list(self._get_indices(indices))
        envs = getattr(self.venv, "envs", None)  # SyncVectorEnv keeps its sub-envs
        if envs is None:
            return [False] * len(rows)
        from stable_baselines3.common.env_util import is_wrapped

        return [is_wrapped(envs[i], wrapper_class) for i in rows]

    def get_images(self) -> Sequence[np.ndarray | None]:
        frame = self.venv.render()
        if isinstance(frame, (tuple, list)):
            return list(frame)
        return [frame] + [None] * (self.num_envs - 1)

    # -----------------------------------------------------------------------------------------------------------
    # Helpers.

    def _update_masks(self, infos: dict[str, Any]) -> None:
        """Keep the masks of the latest observations from ``infos`` (rows without one keep theirs)."""
        if MASK_KEY not in infos:
            self._masks = None  # ask the vector env when they are needed
            return
        masks = np.asarray(infos[MASK_KEY]).reshape(self.num_envs, -1) != 0
        present = infos.get(f"_{MASK_KEY}", np.ones(self.num_envs, dtype=bool))
        if present.all():
            self._masks = masks
        elif self._masks is not None:
            self._masks = self._masks.copy()
            self._masks[present] = masks[present]


def _per_env(values: Any, num_envs: int) -> bool:
    return isinstance(values, (tuple, list)) and len(values) == num_envs


def _obs_row(obs: Any, i: int) -> Any:
    if isinstance(obs, dict):
        return {k: v[i].copy() for k, v in obs.items()}
    return np.array(obs[i], copy=True)
