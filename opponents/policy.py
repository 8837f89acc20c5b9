"""Trained policies as opponents: anything that maps a side's SMAC observations and masks to actions plays where a
script does (alone, in a mixture with scripts, or as a league member).

>>> from smac_hard_gym.opponents.policy import PolicyScript
>>> stand = PolicyScript(lambda obs, masks: masks.argmax(axis=2), name="first-legal")

A :class:`PolicyScript` encodes its own side's SMAC features (the blue side sees blue's own units first, with the
same options as the learner's env by default), asks the policy for one action per agent, replaces an unavailable
action by the agent's first available one, and decodes the actions into engine commands exactly as the learner's
are. It keeps its own last actions per battle, so observations and states that include last actions are right.

A policy is checked like a script (:mod:`smac_hard_gym.opponents.guard`): its actions go through the same validator
as a learner's (:func:`~smac_hard_gym.smac.actions.validate_actions`: ints, or floats with an integral value, in
``0..n_actions-1``, of shape (battles, agents)); bools, strings, NaN, fractional or out-of-range values and a wrong
shape raise a :class:`~smac_hard_gym.opponents.api.ScriptError` naming the policy, the value and the allowed range
(an in-range action that is merely unavailable is not an error: it becomes the agent's first legal one, as above).
The call runs under the guard's time limit (``time_limit``, :data:`~smac_hard_gym.opponents.guard.DEFAULT_TIME_LIMIT`
seconds by default, None for none), and an exception it raises becomes a ScriptError too (Ctrl-C still stops the
program).

Loading a saved model (``PolicyScript.load("model.zip")``, or ``opponent="path/model.zip"`` anywhere an opponent is
named) unpickles the file, as stable-baselines3 loads every model: it runs whatever code the file holds. Load only
files you trust.

What a policy may be (:func:`as_policy`):

- a function ``f(obs, masks) -> actions``: ``obs`` float32 ``(R, n_agents, obs_size)``, ``masks`` bool
  ``(R, n_agents, n_actions)``, actions int ``(R, n_agents)``;
- a stable-baselines3 model or policy with ``predict`` (MaskablePPO, PPO, ...) trained on the joint view of the
  mirrored map (``gymnasium.make("SMACHard-<map>-v0")``, ``obs_mode`` "joint" or "joint+state": told apart by the
  size of its observation space); a MaskablePPO gets the masks; ``PolicyScript.load("model.zip")`` loads one;
- a torch module mapping the joint observation ``(R, n_agents * obs_size)`` to logits ``(R, n_agents * n_actions)``
  (or ``(R, n_agents, n_actions)``): the masked argmax is played.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from smac_hard_gym.engine.state import Commands
from smac_hard_gym.opponents.api import Script, ScriptError, SideView
from smac_hard_gym.opponents.guard import DEFAULT_TIME_LIMIT, call_guarded
from smac_hard_gym.smac.actions import validate_actions
from smac_hard_gym.smac.features import SIDE_NAMES, SideFeatures, SmacOptions
from smac_hard_gym.smac.frame_stack import UnitFrames, check_frame_stack
from smac_hard_gym.smac.kernels import check_decode_batch

__all__ = ["PolicyScript", "as_policy", "is_policy_file"]

Policy = Callable[[np.ndarray, np.ndarray, np.ndarray | None], np.ndarray]


def is_policy_file(text: Any) -> bool:
    """Whether ``text`` names a saved stable-baselines3 model (a ``.zip`` path)."""
    return isinstance(text, (str, Path)) and str(text).endswith(".zip")


def _sb3_policy(model: Any) -> Policy:
    """A stable-baselines3 model or policy as a policy over the joint view."""
    space = model.observation_space
    masked = "action_masks" in inspect.signature(model.predict).parameters

    def act(obs: np.ndarray, masks: np.ndarray, state: np.ndarray | None) -> np.ndarray:
        batch = obs.shape[0]
        joint = obs.reshape(batch, -1)
        size = int(np.prod(space.shape))
        if state is not None and size == joint.shape[1] + state.shape[1]:
            joint = np.concatenate([joint, state], axis=1)  # trained with obs_mode="joint+state"
        if joint.shape[1] != size:
            raise ValueError(f"the model takes observations of {size} values; this side's joint observation has "
                             f"{joint.shape[1]}: was it trained on the joint view of this map (or its mirror)?")
        kwargs = {"action_masks": masks.reshape(batch, -1)} if masked else {}
        actions, _ = model.predict(joint, deterministic=True, **kwargs)
        return np.asarray(actions).reshape(batch, -1)

    return act


def _torch_policy(module: Any) -> Policy:
    """A torch module from joint observations to logits, played by masked argmax."""
    import torch

    def act(obs: np.ndarray, masks: np.ndarray, state: np.ndarray | None) -> np.ndarray:
        with torch.no_grad():
            logits = module(torch.as_tensor(obs.reshape(obs.shape[0], -1)))
        logits = np.asarray(logits.detach().cpu().numpy(), dtype=np.float64).reshape(masks.shape)
        return np.where(masks, logits, -np.inf).argmax(axis=2)

    return act


def as_policy(policy: Any) -> Policy:
    """``policy`` (see the module docstring) as a function ``(obs, masks, state) -> actions``."""
    if hasattr(policy, "predict") and hasattr(policy, "observation_space"):
        return _sb3_policy(policy)
    try:
        import torch

        if isinstance(policy, torch.nn.Module):
            return _torch_policy(policy)
    except ImportError:
        pass
    if not callable(policy):
        raise TypeError(f"a policy is a function (obs, masks) -> actions, a stable-baselines3 model or a torch "
                        f"module, got {policy!r}")

    def act(obs: np.ndarray, masks: np.ndarray, state: np.ndarray | None) -> np.ndarray:
        return policy(obs, masks)

    return act


class PolicyScript(Script):
    """A trained policy (or any function of observations and masks) playing one side; see the module docstring.

    ``options``: the SMAC options the policy was trained with (default: SMAC's defaults, what the envs use unless
    told otherwise). ``name`` names it in infos and statistics. ``time_limit``: seconds one call of the policy may
    take (the guard's watchdog interrupts it past that; None: no limit).

    Actions the policy returns are validated as a learner's are; invalid ones, exceptions and overrunning the time
    limit raise :class:`~smac_hard_gym.opponents.api.ScriptError` (see the module docstring).
    """

    description = "a trained policy: SMAC observations and masks of its side in, one action per agent out"

    def __init__(self, policy: Any, name: str = "policy", options: SmacOptions | None = None,
                 time_limit: float | None = DEFAULT_TIME_LIMIT) -> None:
        if not isinstance(name, str) or not name:
            raise ValueError(f"name must be a non-empty string, got {name!r}")
        if time_limit is not None and (isinstance(time_limit, bool) or not isinstance(time_limit, (int, float))
                                       or not time_limit > 0 or time_limit != time_limit):
            raise ValueError(f"time_limit must be a positive number of seconds or None, got {time_limit!r}")
        self.time_limit = None if time_limit is None else float(time_limit)
        self.policy = policy
        self._act = as_policy(policy)
        self.name = name
        self.options = options or SmacOptions()
        self._features: dict[tuple[str, int], SideFeatures] = {}
        self.last_action = np.zeros((0, 0), dtype=np.int64)
        # frames per agent the policy reads (the env option it was trained with, saved with SB3 models by our
        # policies): 1 for anything that does not say
        self.frame_stack = check_frame_stack(getattr(getattr(policy, "policy", policy), "frame_stack", 1))
        self._frames: UnitFrames | None = None

    @classmethod
    def load(cls, path: str | Path, name: str | None = None, options: SmacOptions | None = None,
             time_limit: float | None = DEFAULT_TIME_LIMIT) -> PolicyScript:
        """A saved MaskablePPO model (``model.zip``; needs the ``[train]`` extra) as an opponent.

        Security: a ``model.zip`` holds pickled Python objects, and stable-baselines3 unpickles them to load the
        model, so loading a file runs whatever code its author put in it. Load only files you trust (the same holds
        for ``opponent="path/model.zip"``, which calls this).
        """
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"no saved model at {str(path)!r} (an opponent ending in .zip is a saved "
                                    "MaskablePPO model)")
        try:
            from sb3_contrib import MaskablePPO
        except ImportError as err:
            raise ImportError("loading a model as an opponent needs the [train] extra: "
                              "pip install 'smac-hard-gym[train]'") from err
        try:
            model = MaskablePPO.load(str(path), device="cpu")
        except MemoryError:
            raise
        except Exception as err:  # a truncated zip, random bytes, another library's pickle: whatever SB3 raises
            detail = " ".join(str(err).split())
            raise ValueError(f"{str(path)!r} is not a saved MaskablePPO model ({type(err).__name__}"
                             f"{': ' + detail if detail else ''})") from None
        return cls(model, name=name or f"model:{path.stem}", options=options, time_limit=time_limit)

    def features(self, view: SideView) -> SideFeatures:
        """This side's features on the view's map (built once per map and side)."""
        key = (view.spec.name, view.side)
        if key not in self._features:
            self._features[key] = SideFeatures(view.spec, view.side, self.options)
        return self._features[key]

    def reset(self, view: SideView, battles: np.ndarray, rngs: list[np.random.Generator]) -> None:
        n = view.n_own
        if self.last_action.shape != (view.batch_size, n):
            self.last_action = np.full((view.batch_size, n), -1, dtype=np.int64)
        battles = np.asarray(battles, dtype=np.int64)
        self.last_action[battles] = -1
        if self.frame_stack > 1:
            feats = self.features(view)
            if self._frames is None or self._frames.frames.shape[:2] != (view.batch_size, n):
                self._frames = UnitFrames(view.batch_size, n, feats.obs_size, self.frame_stack)
            self._frames.clear(battles)

    def act(self, view: SideView, commands: Commands, active: np.ndarray) -> None:
        rows = np.flatnonzero(active)
        if rows.size == 0:
            return
        feats = self.features(view)
        masks, obs, state = feats.encode(view.state, self.last_action, view.episode_step, rows=rows)
        if self._frames is not None:
            self._frames.push(rows, obs)
            obs = self._frames.stacked(rows)
        actions = self._validated(self._call(view, obs, masks, state), view, feats, rows)
        batch = view.batch_size
        played = np.zeros((batch, feats.n_agents), dtype=np.int64)
        played[rows] = actions
        legal = np.ones((batch, feats.n_agents, feats.n_actions), dtype=bool)  # rows not active are not read
        legal[rows] = masks
        # The learner's way down: a policy that ignores masks still plays legally (an unavailable action becomes the
        # agent's first legal one), decoded into this side's commands in one kernel call.
        check_decode_batch(played, legal, active, np.zeros(batch, dtype=np.int64), view.state.x, view.state.y,
                           commands, feats.constants.actions)
        self.last_action[rows] = played[rows]

    def _call(self, view: SideView, obs: np.ndarray, masks: np.ndarray, state: np.ndarray | None) -> Any:
        """The policy's answer for ``obs``/``masks``, under the time limit; its failures raise ScriptError."""
        out: list[Any] = []
        call_guarded(self.name, view.spec.name, "the policy", self.time_limit,
                     lambda: out.append(self._act(obs, masks, state)))
        return out[0]

    def _validated(self, actions: Any, view: SideView, feats: SideFeatures, rows: np.ndarray) -> np.ndarray:
        """``actions`` checked as a learner's are (:func:`validate_actions`), as int64 ``(len(rows), n_agents)``."""
        shape = (len(rows), feats.n_agents)
        try:
            return validate_actions(actions, shape, feats.n_actions, SIDE_NAMES[view.side])
        except (TypeError, ValueError) as err:
            where = (f"one row per active battle, in order, {len(rows)} rows" if len(rows) > 1
                     else f"battle {int(rows[0])}")
            raise ScriptError(self.name, view.spec.name, f"the policy returned invalid actions: {err} (expected "
                              f"ints 0..{feats.n_actions - 1} of shape {shape} (battles, agents); {where})") from None
