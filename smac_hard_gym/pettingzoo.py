"""PettingZoo door of smac-hard-gym (``pip install 'smac-hard-gym[pettingzoo]'``): SMAC-HARD as a PettingZoo
``ParallelEnv`` (:class:`SMACHardParallelEnv`), one agent per unit of one team or both, and its AEC view (:func:`env`).

>>> from smac_hard_gym.pettingzoo import parallel_env
>>> env = parallel_env(map_name="3m")                      # red's units as agents, blue a script
>>> observations, infos = env.reset(seed=0)
>>> sorted(observations["red_0"])
['action_mask', 'observation']
>>> env = parallel_env(map_name="3m", teams="both")        # self-play: red and blue units as agents
>>> env.possible_agents
['red_0', 'red_1', 'red_2', 'blue_0', 'blue_1', 'blue_2']

Built on the same two-player core as every other env (one battle). Importing this module imports PettingZoo;
``import smac_hard_gym`` alone does not.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

try:
    from pettingzoo import ParallelEnv
    from pettingzoo.utils.conversions import parallel_to_aec_wrapper
    from pettingzoo.utils.wrappers import OrderEnforcingWrapper
except ImportError as err:  # the extra is not installed: say which one
    raise ImportError("smac_hard_gym.pettingzoo needs PettingZoo: pip install 'smac-hard-gym[pettingzoo]'") from err
from gymnasium import spaces

from smac_hard_gym.engine.state import BLUE, RED
from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.envs.gym_env import RAISE_HINT, RENDER_FPS, check_invalid_action, keywords_of, make_options
from smac_hard_gym.envs.joint_view import OBS_LOW, state_high
from smac_hard_gym.envs.one_battle import RendersOneBattle
from smac_hard_gym.smac.actions import InvalidActionError, ResetNeededError, raise_unavailable, validate_actions
from smac_hard_gym.smac.features import BLUE_WON, RED_WON, SIDE_NAMES, SmacOptions

__all__ = ["SMACHardParallelEnv", "parallel_env", "env", "TEAMS", "check_agent_action"]

TEAMS = ("red", "both")  # the first is the default
_PZ_HINT = RAISE_HINT.replace("(gymnasium.make(id, invalid_action='noop'))",
                              "(parallel_env(..., invalid_action='noop'))")


class SMACHardParallelEnv(RendersOneBattle, ParallelEnv):
    """SMAC-HARD as a PettingZoo ``ParallelEnv``: every unit of the learning team(s) is an agent.

    Description
        One battle of one of the 23 SMAC maps on the embedded engine (or StarCraft II, ``backend="sc2"``).
        ``teams="red"`` (default): the agents are red's units (SMAC's agents, ``"red_0" .. "red_{n-1}"``) and blue
        is played by an opponent script (``opponent``, default the map's SMAC-HARD pool, one script drawn per
        episode). ``teams="both"``: self-play, blue's units are agents too (``"blue_0" ..``), and each blue agent
        sees its own side's features (the same SMAC encoding, from blue's point of view).

    Action Space
        ``Discrete(n_actions)`` per agent (SMAC's: 0 no-op, 1 stop, 2-5 move N/S/E/W, 6+j attack enemy j, or heal
        ally j for medivacs; a team's ``n_actions`` is 6 + the other team's size). ``step`` takes a dict with an
        int for every live agent; entries for agents already removed are ignored. Under ``invalid_action="noop"``
        (the default, so unmasked sampling works) an unavailable action is replaced by the agent's first legal one
        and ``info["invalid_actions"]`` counts the team's replacements; ``"raise"`` raises ``InvalidActionError``.

    Observation Space
        ``Dict({"observation": Box(-1, 1, (obs_size,), float32), "action_mask": Box(0, 1, (n_actions,), int8)})``
        per agent: the agent's SMAC observation (``docs/smac_interface.md`` §3) and its legal actions, PettingZoo's
        action-mask convention.

    State
        ``state()`` is the global state for centralised critics (§4). ``teams="red"``: red's SMAC state.
        ``teams="both"``: red's state followed by blue's (each side's state from its own point of view, sizes
        ``state_sizes``); ``team_state("red" | "blue")`` returns one side's part. ``state_space`` bounds it.

    Rewards
        Every agent gets its team's SMAC reward for the step (the same number for all agents of a team; each side
        scaled by its own ``max_reward``), every ``reward_*`` option applies.

    Episode End
        An agent whose unit dies gets that step's observation with ``terminated=True`` and then leaves
        ``env.agents``. A win, loss or draw terminates every remaining agent; the map's episode limit truncates them
        (``truncated=True``). ``env.agents`` is then empty; call ``reset``.

    Info
        Per agent, numbers only (TorchRL turns infos into tensors; pymarl-style code sums them): ``battle_won`` (its
        team won), ``dead_allies`` / ``dead_enemies`` (counted from its team) and, under ``invalid_action="noop"``,
        ``invalid_actions`` (its team's replaced actions); empty after reset. ``opponent_name()`` names the script of
        the episode (``"self-play"`` with ``teams="both"``).

    Arguments
        ``map_name``; ``teams``; ``opponent`` / ``opponent_probs`` (``teams="red"`` only; what
        :func:`smac_hard_gym.opponents.make_opponent` accepts); ``invalid_action``; ``seed`` (the first episode's;
        ``reset(seed=s)`` seeds later ones); ``render_mode`` (``"rgb_array"`` or ``"human"``); ``backend``,
        ``backend_options``, ``step_mul``, ``opponent_isolation``; ``options`` (a
        :class:`~smac_hard_gym.smac.features.SmacOptions` or dict) and any SMAC observation/reward option as a
        keyword (``reward_sparse=True``, ...).
    """

    metadata = {"name": "smac_hard_v0", "render_modes": ["rgb_array", "human"], "render_fps": RENDER_FPS,
                "is_parallelizable": True}
    render_hint = "to parallel_env(...)"

    def __init__(self, map_name: str = "3m", *, teams: str = "red", opponent: Any = "default",
                 opponent_probs: Sequence[float] | None = None, invalid_action: str = "noop",
                 seed: int | None = None, render_mode: str | None = None, backend: str = "native",
                 backend_options: dict | None = None, step_mul: int = 8, options: SmacOptions | dict | None = None,
                 opponent_isolation: str | None = None, **smac_options: Any) -> None:
        """A public constructor with gymnasium-style keyword options (PettingZoo's envs take their settings by
        name), hence the long list; SMAC's options may come as ``options`` or as keywords."""
        if not isinstance(teams, str) or teams not in TEAMS:
            raise ValueError(f"teams must be one of {TEAMS}, got {teams!r}")
        check_invalid_action(invalid_action)
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
            raise ValueError(f"seed must be a non-negative int or None, got {seed!r}")
        from smac_hard_gym.render import check_render_mode

        self.render_mode = check_render_mode(render_mode)
        self.teams = teams
        self.invalid_action = invalid_action
        self._replace = invalid_action == "noop"
        self_play = teams == "both"
        if self_play and (opponent != "default" or opponent_probs is not None):
            raise ValueError(f"teams='both' has no opponent script (blue's units are agents); drop opponent="
                             f"{opponent!r} / opponent_probs={opponent_probs!r}, or use teams='red'")
        self.core = TwoPlayerCore(
            map_name, 1, mode="self-play" if self_play else "script", opponent=None if self_play else opponent,
            opponent_probs=opponent_probs, backend=backend, step_mul=step_mul,
            options=make_options(options, smac_options, keywords_of(SMACHardParallelEnv.__init__)),
            seed=None if seed is None else int(seed), backend_options=backend_options,
            opponent_isolation=opponent_isolation, encode_state=False)  # until state() is first called: see there
        self.map_name = self.core.spec.name
        self._sides = (RED, BLUE) if self_play else (RED,)
        feats = self.core.features
        self._n = tuple(feats[side].n_agents for side in (RED, BLUE))
        self._names = tuple([f"{SIDE_NAMES[side]}_{i}" for i in range(feats[side].n_agents)] for side in (RED, BLUE))
        self.possible_agents: list[str] = [name for side in self._sides for name in self._names[side]]
        self._possible = frozenset(self.possible_agents)
        self.observation_spaces: dict[str, spaces.Dict] = {}
        self.action_spaces: dict[str, spaces.Discrete] = {}
        for side in self._sides:
            f = feats[side]
            for name in self._names[side]:  # one space object per agent, so seeding one leaves the others alone
                self.observation_spaces[name] = spaces.Dict({
                    "observation": spaces.Box(OBS_LOW, 1.0, (f.obs_size,), np.float32),
                    "action_mask": spaces.Box(0, 1, (f.n_actions,), np.int8)})
                self.action_spaces[name] = spaces.Discrete(f.n_actions)
        self.state_sizes = tuple(feats[side].state_size for side in self._sides)
        high = np.concatenate([np.full(feats[side].state_size, state_high(feats[side]), np.float32)
                               for side in self._sides])
        self.state_space = spaces.Box(np.full_like(high, OBS_LOW), high, dtype=np.float32)
        self.agents: list[str] = []
        self._n_actions = tuple(feats[side].n_actions for side in (RED, BLUE))
        self._live = [[False] * self._n[RED], [False] * self._n[BLUE]]  # per agent: still in env.agents
        self._dead = (0, 0)  # dead units (red, blue) after the latest step
        self._renderer = None

    def __repr__(self) -> str:
        return (f"SMACHardParallelEnv(map_name={self.map_name!r}, teams={self.teams!r}, "
                f"opponent={self.core.opponent!r})")

    # -----------------------------------------------------------------------------------------------------------
    # Spaces.

    def observation_space(self, agent: str) -> spaces.Dict:
        """The agent's observation space (the same object on every call)."""
        try:
            return self.observation_spaces[agent]
        except (KeyError, TypeError):
            raise ValueError(f"unknown agent {agent!r}; the agents are {self.possible_agents}") from None

    def action_space(self, agent: str) -> spaces.Discrete:
        """The agent's action space (the same object on every call)."""
        try:
            return self.action_spaces[agent]
        except (KeyError, TypeError):
            raise ValueError(f"unknown agent {agent!r}; the agents are {self.possible_agents}") from None

    # -----------------------------------------------------------------------------------------------------------
    # Episode.

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, dict], dict[str, dict]]:
        """Start a new episode; ``seed`` fixes the opponent draw and every script choice of the episode."""
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
            raise ValueError(f"seed must be a non-negative int or None, got {seed!r}")
        self.core.reset(seed=seed)
        self.agents = self.possible_agents[:]
        for side in self._sides:
            self._live[side] = [True] * self._n[side]
        self._dead = (0, 0)
        observations: dict[str, dict] = {}
        for side in self._sides:
            avail, obs, _ = self.core.encode(side)
            self._observe(observations, side, avail[0], obs[0], self._live[side])
        return observations, {name: {} for name in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict[str, dict], dict[str, float], dict[str, bool],
                                                    dict[str, bool], dict[str, dict]]:
        """One step with an action for every live agent (see Action Space); a rejected step changes nothing."""
        if not self.agents:
            raise ResetNeededError("call reset() before step(): the episode is over (or never started)")
        if not isinstance(actions, dict):
            raise TypeError(f"actions must be a dict from agent name to action, got {type(actions).__name__}")
        if len(actions) != len(self.agents):  # extra entries for removed agents are fine, unknown names are not
            self._check_keys(actions)
        core = self.core
        red = self._team_actions(RED, actions)
        blue, blue_replaced = None, 0
        if len(self._sides) == 2:
            blue, blue_replaced = self._blue_actions(self._team_actions(BLUE, actions))
        result = core.step(red[None], None if blue is None else blue[None], replace_invalid=self._replace,
                           hint=_PZ_HINT, checked=True)
        terminated = result.terminated.item()
        truncated = result.truncated.item() or result.restarted.item()
        outcome = result.outcome.item()
        dead = (result.dead_red.item(), result.dead_blue.item())
        # Per-unit life only when someone died this step (the dead counts moved): most steps skip the read.
        alive = core.state.alive[0].tolist() if dead != self._dead else None
        self._dead = dead
        team_rewards = result.reward[0].tolist()
        observations: dict[str, dict] = {}
        rewards: dict[str, float] = {}
        terms: dict[str, bool] = {}
        truncs: dict[str, bool] = {}
        infos: dict[str, dict] = {}
        agents: list[str] = []
        for side in self._sides:
            live = self._live[side]
            if side == RED:
                avail, obs, n_replaced = result.avail[0], result.obs[0], result.replaced.item()
                own_alive = live if alive is None else alive[:self._n[RED]]
            else:
                avail, obs = core.encode(BLUE)[:2]
                avail, obs, n_replaced = avail[0], obs[0], blue_replaced
                own_alive = live if alive is None else alive[self._n[RED]:]
            masks = avail.astype(np.int8)
            reward = team_rewards[side]
            info = {"battle_won": outcome == (RED_WON if side == RED else BLUE_WON),
                    "dead_allies": dead[side], "dead_enemies": dead[1 - side]}
            if self._replace:
                info["invalid_actions"] = n_replaced
            for i, name in enumerate(self._names[side]):
                if live[i]:
                    died = terminated or not own_alive[i]
                    observations[name] = {"observation": obs[i], "action_mask": masks[i]}
                    rewards[name] = reward
                    terms[name] = died
                    truncs[name] = truncated
                    infos[name] = info.copy()
                    if not (died or truncated):
                        agents.append(name)
            if terminated or truncated:
                self._live[side] = [False] * self._n[side]
            elif alive is not None:
                self._live[side] = [was and now for was, now in zip(live, own_alive, strict=True)]
        self.agents = agents
        return observations, rewards, terms, truncs, infos

    def _observe(self, out: dict[str, dict], side: int, avail: np.ndarray, obs: np.ndarray, live: list[bool]) -> None:
        """Write the observation dict of each live agent of ``side`` into ``out`` (rows of fresh arrays)."""
        masks = avail.astype(np.int8)
        for i, name in enumerate(self._names[side]):
            if live[i]:
                out[name] = {"observation": obs[i], "action_mask": masks[i]}

    def _check_keys(self, actions: dict[str, Any]) -> None:
        unknown = [key for key in actions if key not in self._possible]
        if unknown:
            raise ValueError(f"actions name unknown agent(s) {unknown}; the agents are {self.possible_agents}")
        missing = [name for name in self.agents if name not in actions]
        if missing:
            raise ValueError(f"actions has no entry for live agent(s) {missing}; step() needs one for every agent in "
                             f"env.agents ({self.agents})")

    def _team_actions(self, side: int, actions: dict[str, Any]) -> np.ndarray:
        """One team's actions as an int64 array in range (no-op for agents already removed)."""
        live, names, n_actions = self._live[side], self._names[side], self._n_actions[side]
        try:
            row = ([actions[name] for name in names] if all(live) else
                   [actions[name] if is_live else 0 for name, is_live in zip(names, live, strict=True)])
        except KeyError:
            self._check_keys(actions)  # names the missing agents
            raise
        for action in row:  # the usual call is plain ints in range: no detour (a loop beats set/min/max at n ~ 10)
            if type(action) is not int or not 0 <= action < n_actions:
                break
        else:
            return np.array(row, dtype=np.int64)
        # Each agent's action on its own, before any conversion: np.array over a mix of bools and ints (or floats)
        # would turn True into 1 (or 1.0) and hide it from the check.
        return np.array([check_agent_action(name, action, n_actions) if is_live else 0
                         for name, action, is_live in zip(names, row, live, strict=True)], dtype=np.int64)

    def check_action(self, agent: str, action: Any) -> int:
        """``agent``'s action checked on its own (see :func:`check_agent_action`), as an int; nothing changes."""
        if agent not in self._possible:
            raise ValueError(f"unknown agent {agent!r}; the agents are {self.possible_agents}")
        side = BLUE if agent.startswith(SIDE_NAMES[BLUE]) else RED
        return check_agent_action(agent, action, self._n_actions[side])

    def _blue_actions(self, blue: np.ndarray) -> tuple[np.ndarray, int]:
        """Blue's actions with unavailable ones replaced (``"noop"``) or rejected (``"raise"``)."""
        avail = self.core.avail_actions(BLUE)
        ok = avail[0, np.arange(len(blue)), blue]
        if ok.all():
            return blue, 0
        bad = ~ok
        if not self._replace:
            raise_unavailable(self.core.features[BLUE], blue[None], avail, int(np.flatnonzero(bad)[0]), _PZ_HINT)
        blue = blue.copy()
        blue[bad] = avail[0, bad].argmax(axis=1)
        return blue, int(bad.sum())

    def opponent_name(self) -> str:
        """The opponent script playing this episode (``"self-play"`` with ``teams="both"``)."""
        return self.core.opponent_names()[0]

    # -----------------------------------------------------------------------------------------------------------
    # State, rendering.

    def state(self) -> np.ndarray:
        """The global state (float32, ``state_space.shape``): red's, then blue's with ``teams="both"``."""
        # Steps skip encoding red's state until someone asks for it (about 1% of a B=1 step on 3m); from the first
        # call on (a centralised critic asks every step) it comes with each step's encoding. This call reads it
        # either way (global_state computes it when this step's encoding left it out).
        self.core.encode_state = True
        if len(self._sides) == 1:
            return self.core.global_state(RED)[0]
        return np.concatenate([self.core.global_state(RED)[0], self.core.global_state(BLUE)[0]])

    def team_state(self, team: str) -> np.ndarray:
        """One side's global state from its own point of view: ``team`` is ``"red"`` or (self-play) ``"blue"``."""
        allowed = [SIDE_NAMES[side] for side in self._sides]
        if team not in allowed:
            raise ValueError(f"team must be one of {allowed} with teams={self.teams!r}, got {team!r}")
        self.core.encode_state = True  # as in state()
        return self.core.global_state(SIDE_NAMES.index(team))[0]

def check_agent_action(name: str, action: Any, n_actions: int) -> int:
    """One agent's action, checked on its own as every API checks actions (:func:`validate_actions`): a Python or
    NumPy int, a 0-d integer array, or a float with an integral value, in ``0..n_actions-1``. Bools (NumPy's too),
    strings, None, sequences, fractional floats, NaN and out-of-range values raise ``TypeError`` or
    :class:`~smac_hard_gym.smac.actions.InvalidActionError` naming the agent and the value."""
    if type(action) is int and 0 <= action < n_actions:
        return action
    value = action
    if isinstance(value, np.ndarray):
        if value.ndim != 0:
            raise InvalidActionError(f"{name}: action {action!r} is an array of shape {value.shape}; each agent "
                                     f"takes one int 0..{n_actions - 1}")
        value = value[()]  # the NumPy scalar, its type kept (a 0-d bool array stays a bool)
    if isinstance(value, (list, tuple, dict, set, frozenset)):
        raise TypeError(f"{name}: action {action!r} is a {type(value).__name__}; each agent takes one int "
                        f"0..{n_actions - 1}")
    try:
        return int(validate_actions([value], (1,), n_actions, name)[0])
    except (TypeError, InvalidActionError) as err:  # "<name> agent 0: action ... " -> "<name>: action ..."
        detail = str(err).split(": ", 1)[-1]
        raise type(err)(f"{name}: {detail}") from None


class _CheckedAEC(parallel_to_aec_wrapper):
    """PettingZoo's AEC view of the parallel env, checking each agent's action when it is given: a bad one raises
    at once and leaves the turn order and the actions collected so far as they were."""

    def step(self, action: Any) -> None:
        agent = self.agent_selection
        if not (self.terminations[agent] or self.truncations[agent]):  # a done agent's step takes None
            self.env.check_action(agent, action)
        super().step(action)


def parallel_env(map_name: str = "3m", **kwargs: Any) -> SMACHardParallelEnv:
    """A :class:`SMACHardParallelEnv` (PettingZoo's ``parallel_env`` door); keywords as the class takes them."""
    return SMACHardParallelEnv(map_name, **kwargs)


def env(map_name: str = "3m", **kwargs: Any):
    """The same env as PettingZoo's turn-based ``AECEnv`` (``parallel_to_aec`` over :func:`parallel_env`, with each
    agent's action checked when it is given)."""
    return OrderEnforcingWrapper(_CheckedAEC(parallel_env(map_name, **kwargs)))
