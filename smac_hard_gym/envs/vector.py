"""``NativeVectorEnv``: N battles of one map stepped as one batch of the embedded engine (the ``vector_entry_point``
of every ``SMACHard-*`` id).

>>> import gymnasium, smac_hard_gym
>>> envs = gymnasium.make_vec("SMACHard-3m-v0", num_envs=4, autoreset_mode="SameStep")
>>> obs, infos = envs.reset(seed=0)
>>> obs.shape, envs.action_masks().shape
((4, 90), (4, 27))
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from smac_hard_gym.engine.state import RED
from smac_hard_gym.envs.autoreset import parse_autoreset_mode
from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.envs.gym_env import RAISE_HINT, RENDER_FPS, check_invalid_action, keywords_of, make_options
from smac_hard_gym.envs.joint_view import OBS_MODES, JointView
from smac_hard_gym.smac.actions import ResetNeededError
from smac_hard_gym.smac.features import SmacOptions
from smac_hard_gym.smac.frame_stack import UnitFrames, check_frame_stack

__all__ = ["NativeVectorEnv", "parse_autoreset_mode", "AutoresetMode"]


def _masked(values: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``values`` (a fresh array, changed in place) with rows outside ``rows`` zeroed, as gymnasium's info batching
    leaves them."""
    if rows.all():
        return values
    if values.ndim > 1:
        values[~rows] = 0  # row assignment: far faster than a broadcast where= for 2-D arrays
    else:
        np.copyto(values, None if values.dtype == object else values.dtype.type(0), where=~rows)
    return values


class NativeVectorEnv(VectorEnv):
    """``num_envs`` battles of one map in one engine batch, with gymnasium's vector API.

    Each battle is exactly a :class:`~smac_hard_gym.envs.gym_env.SMACHardEnv` (same spaces, rewards, info keys; battle b
    of ``reset(seed=s)`` plays like a single env reset with seed ``s + b``), but all battles advance in one engine
    call and the features are computed for the whole batch at once.

    Autoreset (``autoreset_mode``, recorded in ``metadata``):

    - ``NEXT_STEP`` (default): a battle that ends returns its terminal observation; on the next step its action is
      ignored and it returns the first observation of a new episode with reward 0 and both flags False.
    - ``SAME_STEP`` (what SB3 wants): a battle that ends is reset inside the same step; the returned observation is
      the new episode's, and ``infos["final_obs"]`` / ``infos["final_info"]`` hold the terminal ones.
    - ``DISABLED``: ended battles wait for ``reset(options={"reset_mask": mask})``; stepping them is an error.

    Infos are gymnasium's dict of arrays with ``_key`` masks: ``battle_won``, ``dead_allies``, ``dead_enemies``,
    ``opponent``, ``action_mask`` ((N, n_agents * n_actions) int8) and ``invalid_actions`` (the unavailable actions
    replaced, under ``invalid_action="noop"``, the default; ``"raise"`` raises instead, as the single env does).
    ``action_masks()`` returns the bool masks of the current observations, shape (N, n_agents * n_actions).
    ``frame_stack``: as in the single env, per battle. ``max_episode_steps`` shortens the map's episode limit (never
    lengthens it). ``render()`` draws battle ``render_battles`` (an int), or a tiled grid of the listed battles (a
    list, or ``"all"``).
    """

    def __init__(self, map_name: str = "3m", num_envs: int = 1, *,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, max_episode_steps: int | None = None,
                 opponent: Any = "default", opponent_probs: Sequence[float] | None = None, obs_mode: str = "joint",
                 invalid_action: str = "noop", render_mode: str | None = None,
                 render_battles: int | Sequence[int] | str = 0, backend: str = "native",
                 backend_options: dict | None = None, step_mul: int = 8, options: SmacOptions | dict | None = None,
                 opponent_isolation: str | None = None, frame_stack: int = 1, **smac_options: Any) -> None:
        """A public constructor with gymnasium-style keyword options (what ``gymnasium.make_vec`` passes through by
        name), hence the long list; SMAC's options may come as ``options`` or as keywords."""
        frame_stack = check_frame_stack(frame_stack)
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive int, got {num_envs!r}")
        check_invalid_action(invalid_action)
        from smac_hard_gym.render import check_render_mode  # the renderer itself loads on the first render()

        self.render_mode = check_render_mode(render_mode)
        self.autoreset_mode = parse_autoreset_mode(autoreset_mode)
        self.num_envs = int(num_envs)
        self.invalid_action = invalid_action
        if max_episode_steps is not None and (isinstance(max_episode_steps, bool) or not isinstance(
                max_episode_steps, (int, np.integer)) or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps must be a positive int or None, got {max_episode_steps!r}")
        if obs_mode not in OBS_MODES:
            raise ValueError(f"obs_mode must be one of {OBS_MODES}, got {obs_mode!r}")
        self.core = TwoPlayerCore(map_name, self.num_envs, opponent=opponent, opponent_probs=opponent_probs,
                                  backend=backend, step_mul=step_mul,
                                  options=make_options(options, smac_options, keywords_of(NativeVectorEnv.__init__)),
                                  backend_options=backend_options, opponent_isolation=opponent_isolation,
                                  encode_state=obs_mode != "joint", episode_limit=max_episode_steps)
        self.map_name = self.core.spec.name
        self.episode_limit = self.core.episode_limit
        feats = self.core.features[RED]
        self.view = JointView(feats, obs_mode, self.episode_limit, frame_stack)
        self._frames = (UnitFrames(self.num_envs, feats.n_agents, feats.obs_size, frame_stack) if frame_stack > 1
                        else None)
        self.render_battles = self._check_render_battles(render_battles)
        self.metadata = {"autoreset_mode": self.autoreset_mode, "render_modes": ["rgb_array", "human"],
                         "render_fps": RENDER_FPS}
        self.single_action_space = self.view.action_space
        self.single_observation_space = self.view.observation_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._ended = np.zeros(self.num_envs, dtype=bool)  # ended episodes that wait for a reset
        self._needs_reset = True  # until the first reset()
        self._renderer = None

    def __repr__(self) -> str:
        # getattr: also called on an env whose __init__ raised (a traceback's locals), before these are set
        spec = getattr(self, "spec", None)
        env_id = spec.id if spec is not None else getattr(self, "map_name", "?")
        mode = getattr(self, "autoreset_mode", None)
        return (f"NativeVectorEnv({env_id}, num_envs={getattr(self, 'num_envs', '?')}, "
                f"autoreset_mode={getattr(mode, 'value', None)})")

    # -----------------------------------------------------------------------------------------------------------
    # Gymnasium API.

    def reset(self, *, seed: int | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset every battle, or those of ``options["reset_mask"]`` (bool (num_envs,)). An int ``seed`` gives
        battle b the seed ``seed + b``; a list gives one seed (or None) per battle."""
        rows = self._reset_rows(options)
        seeds = self._seed_list(seed)
        if isinstance(seed, (int, np.integer)):
            super().reset(seed=int(seed))
        self._reset_battles(rows, seeds)
        self._needs_reset = False
        avail, obs, state = self.core.encode(RED)
        if self._frames is not None:
            obs = self._frames.advance(rows, obs, restart=rows)
        return self.view.observation(avail, obs, state), self._info(np.zeros(self.num_envs, dtype=bool), rows, avail)

    def step(self, actions: Any, *, checked: bool = False
             ) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One step of every battle with actions ``(num_envs, n_agents)``; actions are checked as in
        :class:`~smac_hard_gym.envs.gym_env.SMACHardEnv`, and a rejected step changes nothing.

        ``checked``: ``actions`` is already what :func:`~smac_hard_gym.smac.actions.validate_actions` returns (a
        fresh int64 array of that shape, in range), as a :class:`~smac_hard_gym.envs.subproc.SubprocVectorEnv`
        sends its workers: not validated again (availability still is)."""
        if self._needs_reset:
            raise ResetNeededError("call reset() before step(): no episode has started")
        mode = self.autoreset_mode
        if mode == AutoresetMode.DISABLED and self._ended.any():
            raise ResetNeededError(f"battles {np.flatnonzero(self._ended).tolist()} ended and autoreset is "
                                   "disabled; reset them with reset(options={'reset_mask': mask}) before stepping")
        core, view = self.core, self.view
        result = core.step(actions, replace_invalid=self.invalid_action == "noop", hint=RAISE_HINT, checked=checked)
        frames = self._frames
        step = view.translate(result, None if frames is None else frames.advance(result.stepped, result.obs))
        terminated, truncated = step.terminated, step.truncated
        ended = terminated | truncated
        rewards = step.reward.astype(np.float64)

        stepped = result.stepped.copy()
        resets = np.zeros(self.num_envs, dtype=bool)
        infos: dict[str, Any] = {}
        if mode == AutoresetMode.SAME_STEP and ended.any():
            # The terminal observations are rows of this step's encoding; the new episodes' replace them below.
            rows = np.flatnonzero(ended)
            final_obs = step.obs
            infos["final_obs"] = np.full(self.num_envs, None, dtype=object)
            if isinstance(final_obs, dict):
                for b in rows.tolist():
                    infos["final_obs"][b] = {key: v[b].copy() for key, v in final_obs.items()}
            else:
                for b in rows.tolist():
                    infos["final_obs"][b] = final_obs[b].copy()
            infos["_final_obs"] = ended.copy()
            masks = np.zeros((self.num_envs, view.mask_size), dtype=np.int8)
            masks[rows] = view.masks(result.avail[rows], np.int8)
            infos["final_info"] = self._info(ended, resets, result.avail, step, masks)
            infos["_final_info"] = ended.copy()
            resets, stepped = ended, stepped & ~ended
        elif mode == AutoresetMode.NEXT_STEP:
            resets = self._ended.copy()
        self._reset_battles(resets, None, in_place=True)  # this step's arrays are not handed out yet
        self._ended = ended if mode != AutoresetMode.SAME_STEP else np.zeros(self.num_envs, dtype=bool)
        if resets.any():
            avail, obs, state = core.encode(RED)
            if frames is not None:
                obs = frames.advance(resets, obs, restart=resets)
            observation = view.observation(avail, obs, state)
        else:
            avail, observation = result.avail, step.obs
        infos.update(self._info(stepped, resets, avail, step))
        return observation, rewards, terminated, truncated, infos

    def action_masks(self) -> np.ndarray:
        """Legal actions of the current observations: bool ``(num_envs, n_agents * n_actions)`` (a new array)."""
        return self.view.masks(self.core.avail_actions(RED))

    def render(self) -> np.ndarray | None:
        """Battle ``render_battles`` as an RGB frame, or a grid of several (``"rgb_array"``); ``"human"`` shows it."""
        if self.render_mode is None:
            gym.logger.warn("render() called with render_mode=None; pass render_mode='rgb_array' or 'human'")
            return None
        if self._renderer is None:
            from smac_hard_gym.render import EnvRenderer

            self._renderer = EnvRenderer(self.core.spec, self.render_mode, step_mul=self.core.backend.step_mul)
        names = self.core.opponent_names()
        steps = self.core.episode_step
        if isinstance(self.render_battles, list):
            return self._renderer.render(self.core.state, self.render_battles,
                                         [int(steps[b]) for b in self.render_battles],
                                         [names[b] for b in self.render_battles])
        b = self.render_battles
        return self._renderer.render(self.core.state, b, int(steps[b]), names[b])

    def __enter__(self) -> NativeVectorEnv:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close_extras(self, **kwargs: Any) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self.core.close()

    # -----------------------------------------------------------------------------------------------------------
    # Helpers.

    def _reset_battles(self, rows: np.ndarray, seeds: list[int | None] | None, in_place: bool = False) -> None:
        """Reset the battles of bool ``rows``; ``seeds`` holds one seed (or None) per battle; ``in_place``: see
        ``TwoPlayerCore.reset``."""
        if not rows.any():
            return
        indices = np.flatnonzero(rows)
        if seeds is None:
            self.core.reset(indices, in_place=in_place)
            self._ended[rows] = False
            return
        seeded = [b for b in indices if seeds[b] is not None]
        unseeded = [b for b in indices if seeds[b] is None]
        if seeded:
            self.core.reset(seeded, seed=[seeds[b] for b in seeded])
        if unseeded:
            self.core.reset(unseeded)
        self._ended[rows] = False

    def _info(self, stepped: np.ndarray, resets: np.ndarray, avail: np.ndarray, step: Any = None,
              masks: np.ndarray | None = None) -> dict[str, Any]:
        """Batched infos as single envs give them: the step's keys for the ``stepped`` battles, ``opponent`` and
        ``action_mask`` (of the masks ``avail``, or ``masks``: given already zero outside those battles) for those
        and the ``resets`` battles; each key with its ``_key``."""
        values: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        if stepped.any():
            info = step.info
            values["battle_won"] = (info["battle_won"].copy(), stepped)
            values["dead_allies"] = (info["dead_allies"].copy(), stepped)
            values["dead_enemies"] = (info["dead_enemies"].copy(), stepped)
            if self.invalid_action == "noop":
                values["invalid_actions"] = (info["invalid_actions"].copy(), stepped)
            if info["restarted"].any():
                values["restarted"] = (info["restarted"].copy(), stepped)
        shown = stepped | resets
        if shown.any():
            values["opponent"] = (self.core.opponent_name_array(), shown)
            values["action_mask"] = (self.view.masks(avail, np.int8) if masks is None else masks, shown)
        infos: dict[str, Any] = {}
        for key, (value, rows) in values.items():
            # Given masks already hold zeros outside their rows.
            infos[key] = value if key == "action_mask" and masks is not None else _masked(value, rows)
            infos[f"_{key}"] = rows.copy()
        return infos

    def _reset_rows(self, options: dict[str, Any] | None) -> np.ndarray:
        if options is None or "reset_mask" not in options:
            return np.ones(self.num_envs, dtype=bool)
        mask = options["reset_mask"]
        if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (self.num_envs,):
            raise ValueError(f"options['reset_mask'] must be a bool numpy array of shape ({self.num_envs},), "
                             f"got {mask!r}")
        if not mask.any():
            raise ValueError("options['reset_mask'] must select at least one battle")
        return mask.copy()

    def _seed_list(self, seed: Any) -> list[int | None] | None:
        if seed is None:
            return None
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            return [int(seed) + b for b in range(self.num_envs)]
        if isinstance(seed, Sequence) and len(seed) == self.num_envs and all(
                s is None or (isinstance(s, (int, np.integer)) and not isinstance(s, bool)) for s in seed):
            return [None if s is None else int(s) for s in seed]
        raise ValueError(f"seed must be None, an int, or a list of {self.num_envs} ints or None, got {seed!r}")

    def _check_render_battles(self, battles: Any) -> int | list[int]:
        if isinstance(battles, str) and battles == "all":
            return list(range(self.num_envs))
        if isinstance(battles, (int, np.integer)) and not isinstance(battles, bool):
            if not 0 <= battles < self.num_envs:
                raise ValueError(f"render_battles must lie in 0..{self.num_envs - 1}, got {battles}")
            return int(battles)
        if isinstance(battles, Sequence) and battles and all(
                isinstance(b, (int, np.integer)) and 0 <= b < self.num_envs for b in battles):
            return [int(b) for b in battles]
        raise ValueError(f"render_battles must be a battle index, a non-empty list of them, or 'all' "
                         f"(battles 0..{self.num_envs - 1}), got {battles!r}")
