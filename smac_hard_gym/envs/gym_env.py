"""``SMACHardEnv``: the Gymnasium single-agent view of a SMAC-HARD battle (one joint controller for all agents).

``gymnasium.make("SMACHard-3m-v0")`` builds one: a two-player core of one battle, whose step result row 0 the
:class:`~smac_hard_gym.envs.joint_view.JointView` translates, as it translates every row for the native vector env
(so its battles match single envs exactly).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from smac_hard_gym.engine.state import RED
from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.envs.joint_view import OBS_MODES, JointView
from smac_hard_gym.envs.one_battle import RendersOneBattle
from smac_hard_gym.smac.actions import ResetNeededError, validate_actions
from smac_hard_gym.smac.features import SmacOptions
from smac_hard_gym.smac.frame_stack import UnitFrames, check_frame_stack

__all__ = ["SMACHardEnv", "JointView", "OBS_MODES", "INVALID_ACTION_POLICIES", "RENDER_FPS", "make_options",
           "check_invalid_action"]

INVALID_ACTION_POLICIES = ("noop", "raise")  # the first is the default
# Appended to an unavailable action's error in the gymnasium envs: how to get the other policy.
RAISE_HINT = ("; invalid_action='raise' is set (for debugging): the default invalid_action='noop' "
              "(gymnasium.make(id, invalid_action='noop')) replaces unavailable actions by a legal one and counts them "
              "in info['invalid_actions']")
_ONE = np.ones(1, dtype=bool)  # the single env's one battle, as a row mask for UnitFrames
RENDER_FPS = 8  # frames per second when shown: 4x the Normal-speed game time of step_mul=8 loops per step


def make_options(options: SmacOptions | dict | None, smac_options: dict[str, Any],
                 env_keywords: Sequence[str] = ()) -> SmacOptions:
    """SMAC's observation and reward options from an ``options`` object or dict plus keyword overrides.

    An unknown keyword is a TypeError that lists every keyword the env takes: ``env_keywords`` (its own) and SMAC's.
    """
    if isinstance(options, SmacOptions):
        base = {name: getattr(options, name) for name in options.__dataclass_fields__}
    elif options is None:
        base = {}
    elif isinstance(options, dict):
        base = dict(options)
    else:
        raise TypeError(f"options must be a SmacOptions, a dict of SMAC options or None, got {options!r}")
    base.update(smac_options)
    return SmacOptions.from_kwargs(env_keywords, **base)


def keywords_of(function: Any) -> list[str]:
    """The keyword parameters of ``function`` (an env's ``__init__``), for error messages."""
    import inspect

    return [name for name, p in inspect.signature(function).parameters.items()
            if name != "self" and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]


def check_invalid_action(policy: str) -> str:
    """``policy`` when it is one of :data:`INVALID_ACTION_POLICIES`, else a ``ValueError`` listing them."""
    if not isinstance(policy, str) or policy not in INVALID_ACTION_POLICIES:
        raise ValueError(f"invalid_action must be one of {INVALID_ACTION_POLICIES}, got {policy!r}")
    return policy


class SMACHardEnv(RendersOneBattle, gym.Env):
    """SMAC-HARD as a Gymnasium environment: one controller chooses every agent's SMAC action each step.

    Description
        The learner's team (red, SMAC's agents) fights an opponent script on one of the 23 SMAC maps with the
        embedded battle engine (or StarCraft II, ``backend="sc2"``). The opponent is the map's SMAC-HARD mixture of
        scripts by default, one script drawn per episode from the episode's seed (``info["opponent"]`` names it).

    Action Space
        ``MultiDiscrete([n_actions] * n_agents)``: SMAC's action per agent (0 no-op, 1 stop, 2-5 move N/S/E/W,
        6+j attack enemy j, or heal ally j for medivacs). ``action_masks()`` returns the legal ones, flat bool of
        length ``n_agents * n_actions`` (agent-major; MaskablePPO reads it), and ``info["action_mask"]`` the same
        as a fresh int8 array; every agent always has at least one legal action (no-op when dead, stop when alive).
        An action is an int (or an integral float) in ``0..n_actions-1``; anything else raises ``TypeError`` or
        :class:`~smac_hard_gym.smac.actions.InvalidActionError` (a ``ValueError``), and the env is left as it was. An
        unavailable action (in range, masked out) is replaced by the agent's first legal action (``invalid_action=
        "noop"``, the default, so ``action_space.sample()`` and gymnasium's and SB3's checkers work: no-op when dead,
        stop when alive) and ``info["invalid_actions"]`` counts the replacements; ``invalid_action="raise"`` (for
        debugging) raises ``InvalidActionError`` naming the agent and its legal actions instead.

    Observation Space
        ``obs_mode="joint"`` (default): Box float32 ``(n_agents * obs_size,)``, every agent's SMAC observation
        (``docs/smac_interface.md`` §3), agent-major, in [-1, 1]. ``"joint+state"``: the same followed by SMAC's global
        state (§4). ``"dict"``: ``{"obs": (n_agents, obs_size), "state": (state_size,), "action_mask":
        (n_agents, n_actions) int8}``. ``frame_stack=k`` (default 1): each agent's observation is its last k SMAC
        observations, newest first (``obs_size`` becomes k times SMAC's; zeros before the episode's first step), the
        memory MAPPO's SMAC runs give a feed-forward policy (:mod:`~smac_hard_gym.smac.frame_stack`).

    Rewards
        SMAC's shaped reward (damage dealt, kills, win bonus), scaled so an episode's maximum is ``reward_scale_rate``
        (20); every ``reward_*`` option of SMAC applies.

    Starting State
        Both teams at the map's spawn points; ``reset(seed=s)`` fixes the opponent draw and every script's random
        choices for the episode.

    Episode End
        ``terminated`` when one team is destroyed (win, loss or draw); ``truncated`` when the map's episode limit is
        reached (also on a step that ends the battle, as gymnasium's ``TimeLimit`` reports it; ``gymnasium.make``
        sets ``max_episode_steps`` to the limit, and a smaller ``max_episode_steps`` ends episodes earlier).

    Info
        ``battle_won``, ``dead_allies``, ``dead_enemies``, ``opponent`` (the script playing this episode) and
        ``action_mask`` after every step (and ``invalid_actions`` under ``invalid_action="noop"``); ``opponent`` and
        ``action_mask`` after reset.

    Arguments
        Keyword options, gymnasium-style, each passed by name to the core (hence more than a dozen parameters).
        ``map_name``; ``opponent`` (``"default"`` = the map's SMAC-HARD pool, ``"blackbox"``, ``"base"``, any script
        name, a user script reference, a Script, or a list of them) and ``opponent_probs``; ``obs_mode`` and
        ``frame_stack``; ``invalid_action`` (``"noop"``, the default, or ``"raise"``); ``render_mode``
        (``"rgb_array"`` or ``"human"``); ``backend`` and ``backend_options``; ``step_mul``; ``options`` (a
        :class:`~smac_hard_gym.smac.features.SmacOptions` or dict) and any SMAC observation/reward option as a
        keyword (``reward_sparse=True``, ...);
        ``opponent_isolation`` (None, the default: a script loaded from a file or module runs in a child process,
        a Script object you built runs in-process under the guard; ``"process"``: in a child process that a hang,
        crash or exit cannot take down; ``"guard"``: in-process on a read-only copy of the state under a time limit,
        a bug catcher, not a security boundary; ``"none"``; docs/script_isolation.md).

    Version History
        v0: first version.
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": RENDER_FPS}
    render_hint = "to the constructor (gymnasium.make(id, render_mode=...))"

    def __init__(self, map_name: str = "3m", *, opponent: Any = "default",
                 opponent_probs: Sequence[float] | None = None, obs_mode: str = "joint",
                 invalid_action: str = "noop", render_mode: str | None = None, backend: str = "native",
                 backend_options: dict | None = None, step_mul: int = 8, options: SmacOptions | dict | None = None,
                 opponent_isolation: str | None = None, frame_stack: int = 1, **smac_options: Any) -> None:
        check_invalid_action(invalid_action)
        frame_stack = check_frame_stack(frame_stack)
        if obs_mode not in OBS_MODES:
            raise ValueError(f"obs_mode must be one of {OBS_MODES}, got {obs_mode!r}")
        from smac_hard_gym.render import check_render_mode  # the renderer itself loads on the first render()

        self.render_mode = check_render_mode(render_mode)
        self.invalid_action = invalid_action
        self.core = TwoPlayerCore(map_name, 1, opponent=opponent, opponent_probs=opponent_probs, backend=backend,
                                  step_mul=step_mul,
                                  options=make_options(options, smac_options, keywords_of(SMACHardEnv.__init__)),
                                  backend_options=backend_options, opponent_isolation=opponent_isolation,
                                  encode_state=obs_mode != "joint")
        feats = self.core.features[RED]
        self.view = JointView(feats, obs_mode, self.core.episode_limit, frame_stack)
        self._frames = UnitFrames(1, feats.n_agents, feats.obs_size, frame_stack) if frame_stack > 1 else None
        self.map_name = self.core.spec.name
        self.obs_mode = obs_mode
        self.n_agents, self.n_actions = self.view.n_agents, self.view.n_actions
        self.episode_limit = self.core.spec.episode_limit
        self.action_space = self.view.action_space
        self.observation_space = self.view.observation_space
        self._renderer = None
        self._needs_reset = True

    def __repr__(self) -> str:
        return (f"SMACHardEnv(map_name={self.map_name!r}, opponent={self.core.opponent!r}, "
                f"obs_mode={self.obs_mode!r})")

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Start a new episode; ``seed`` fixes the opponent draw and every script choice of the episode."""
        super().reset(seed=seed)
        self.core.reset(seed=seed)
        self._needs_reset = False
        avail, obs, state = self.core.encode(RED)
        if self._frames is not None:
            obs = self._frames.advance(_ONE, obs, restart=_ONE)
        return self._row(self.view.observation(avail, obs, state)), {
            "opponent": self.core.opponent_names()[0], "action_mask": self.view.masks(avail, np.int8)[0]}

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        """One step with every agent's action (see Action Space); a rejected action changes nothing."""
        if self._needs_reset:
            raise ResetNeededError("call reset() before step(): the episode is over (or never started)")
        acts = validate_actions(action, (self.n_agents,), self.n_actions, "red")
        result = self.core.step(acts[None], replace_invalid=self.invalid_action == "noop", hint=RAISE_HINT,
                                checked=True)
        step = self.view.translate(result, None if self._frames is None else self._frames.advance(_ONE, result.obs))
        terminated, truncated = bool(step.terminated[0]), bool(step.truncated[0])
        self._needs_reset = terminated or truncated
        values = step.info
        info: dict[str, Any] = {
            "battle_won": bool(values["battle_won"][0]), "dead_allies": int(values["dead_allies"][0]),
            "dead_enemies": int(values["dead_enemies"][0]), "opponent": result.opponent[0],
            "action_mask": self.view.masks(result.avail, np.int8)[0],
        }
        if self.invalid_action == "noop":
            info["invalid_actions"] = int(values["invalid_actions"][0])
        if values["restarted"][0]:
            info["restarted"] = True
        return self._row(step.obs), float(step.reward[0]), terminated, truncated, info

    def action_masks(self) -> np.ndarray:
        """Legal actions of the current state: flat bool ``(n_agents * n_actions,)``, agent-major (a new array)."""
        return self.view.masks(self.core.avail_actions(RED))[0]

    @staticmethod
    def _row(obs: Any) -> Any:
        if isinstance(obs, dict):
            return {key: value[0] for key, value in obs.items()}
        return obs[0]
