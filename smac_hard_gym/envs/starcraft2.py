"""``StarCraft2Env``: SMAC's multi-agent API (and SMAC-HARD's two-player one) over the two-player core.

Code written for SMAC switches by changing one import::

    from smac_hard_gym import StarCraft2Env   # was: from smac.env import StarCraft2Env

and code written for SMAC-HARD runs unchanged (``mode="single"|"multi"``, ``strategy_prob=``, ``player_id=``).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from smac_hard_gym.engine.state import BLUE, RED
from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.smac.actions import ResetNeededError, validate_actions
from smac_hard_gym.smac.features import (
    BLUE_WON,
    N_ACTIONS_NO_ATTACK,
    RED_WON,
    SideFeatures,
    SmacOptions,
    last_action_onehot,
)

__all__ = ["StarCraft2Env"]

# SMAC-HARD's spellings of the modes.
_MODE_ALIASES = {"script": "script", "single": "script", "self-play": "self-play", "multi": "self-play"}


class StarCraft2Env:
    """SMAC's ``StarCraft2Env`` on the embedded engine (or real StarCraft II with ``backend="sc2"``).

    Description
        The learner controls red's units (SMAC's agents) on one of the 23 SMAC maps. Blue (SMAC's enemies) is played
        by an opponent script (``mode="script"``, SMAC-HARD's ``"single"``) or by a second learner
        (``mode="self-play"``, SMAC-HARD's ``"multi"``), which then gets observations, state and available
        actions of its own side in the same encoding.

    Arguments
        SMAC's constructor arguments with SMAC's defaults (``map_name="8m"``, ``step_mul=8``, ``move_amount=2``,
        ``seed``, ``continuing_episode`` and every ``obs_*``, ``state_*`` and ``reward_*`` option). ``difficulty``,
        ``game_version``, ``replay_dir``, ``replay_prefix``, ``window_size_x/y`` and ``debug`` are accepted and
        ignored by the native backend; ``heuristic_ai`` / ``heuristic_rest`` are not supported. New:

        - ``mode``: ``"script"`` (default) or ``"self-play"``; ``"single"`` / ``"multi"`` are accepted.
        - ``opponent``: a script name, a Script object, or anything ``opponents.make_opponent`` accepts
          (default ``"smac"``: SMAC's own opponent; ``"base"`` is SMAC-HARD's); ``opponent_probs``: weights of a
          list of scripts.
          ``strategy_prob`` (SMAC-HARD) gives weights over the map's default pool (``opponent="default"``).
        - ``backend``: ``"native"`` (embedded engine) or ``"sc2"``; ``backend_options``: passed to it.
        - ``reward_abs``: with ``reward_only_positive``, pay ``abs(damage + kills)`` as SMAC v1 does (enemy shield
          and health regeneration and healing then earn reward) instead of SMAC-HARD's ``max(0, .)`` (default).
          SMAC, pymarl2 and the SMAC-HARD paper's runs used ``abs``.

    Return values
        SMAC's: ``reset() -> (obs_list, state)``, ``step(actions) -> (reward, terminated, info)`` with ``info``
        keys ``battle_won``, ``dead_allies``, ``dead_enemies`` (and ``episode_limit`` on a timeout when
        ``continuing_episode``); ``get_opponent_name()`` names the opponent script of the episode. In self-play
        ``reset()`` returns ``([obs_red, obs_blue], [state_red, state_blue])`` and ``step([red_actions,
        blue_actions])`` returns ``([r_red, r_blue], [terminated, terminated], info)`` with per-side lists in
        ``info``. Query methods take ``player_id`` (0 red, 1 blue).

    Episode end
        Win, loss or draw ends the episode; so does the episode limit (SMAC counts it as a timeout).
    """

    def __init__(
        self,
        map_name: str = "8m",
        step_mul: int = 8,
        move_amount: float = 2,
        difficulty: str = "7",
        game_version: str | None = None,
        seed: int | None = None,
        continuing_episode: bool = False,
        obs_all_health: bool = True,
        obs_own_health: bool = True,
        obs_last_action: bool = False,
        obs_pathing_grid: bool = False,
        obs_terrain_height: bool = False,
        obs_instead_of_state: bool = False,
        obs_timestep_number: bool = False,
        state_last_action: bool = True,
        state_timestep_number: bool = False,
        reward_sparse: bool = False,
        reward_only_positive: bool = True,
        reward_death_value: float = 10,
        reward_win: float = 200,
        reward_defeat: float = 0,
        reward_negative_scale: float = 0.5,
        reward_scale: bool = True,
        reward_scale_rate: float = 20,
        replay_dir: str = "",
        replay_prefix: str = "",
        window_size_x: int = 1920,
        window_size_y: int = 1200,
        heuristic_ai: bool = False,
        heuristic_rest: bool = False,
        debug: bool = False,
        mode: str = "script",
        opponent: Any = "smac",
        opponent_probs: Sequence[float] | None = None,
        strategy_prob: Sequence[float] | None = None,
        backend: str = "native",
        backend_options: dict | None = None,
        opponent_isolation: str | None = None,
        reward_abs: bool = False,
    ) -> None:
        """Every keyword of SMAC's own ``StarCraft2Env`` constructor, in its order, so that code written for SMAC
        runs unchanged (hence the long list), then smac-hard-gym's own (``mode`` onwards)."""
        if mode not in _MODE_ALIASES:
            raise ValueError(f"mode must be one of {sorted(_MODE_ALIASES)}, got {mode!r}")
        if heuristic_ai or heuristic_rest:
            raise ValueError("heuristic_ai / heuristic_rest are not supported by smac-hard-gym; drive the agents "
                             "with a policy, or play a script against a script with `smac-hard-gym duel`")
        if strategy_prob is not None:
            if opponent_probs is not None:
                raise ValueError("pass either opponent_probs or SMAC-HARD's strategy_prob, not both")
            if opponent != "smac":
                raise ValueError(f"strategy_prob weights the map's default pool; it cannot be combined with "
                                 f"opponent={opponent!r} (use opponent=[...] with opponent_probs=[...])")
            opponent, opponent_probs = "default", strategy_prob
        if seed is not None and (not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0):
            raise ValueError(f"seed must be a non-negative int or None, got {seed!r}")
        self.mode = _MODE_ALIASES[mode]
        self.map_name = map_name
        self.continuing_episode = bool(continuing_episode)
        self.difficulty = difficulty
        self.game_version = game_version
        self.replay_dir, self.replay_prefix = replay_dir, replay_prefix
        self.window_size = (window_size_x, window_size_y)
        self.debug = debug
        self._seed = None if seed is None else int(seed)
        options = SmacOptions(
            obs_all_health=obs_all_health, obs_own_health=obs_own_health, obs_last_action=obs_last_action,
            obs_pathing_grid=obs_pathing_grid, obs_terrain_height=obs_terrain_height,
            obs_instead_of_state=obs_instead_of_state, obs_timestep_number=obs_timestep_number,
            state_last_action=state_last_action, state_timestep_number=state_timestep_number,
            reward_sparse=reward_sparse, reward_only_positive=reward_only_positive,
            reward_death_value=reward_death_value, reward_win=reward_win, reward_defeat=reward_defeat,
            reward_negative_scale=reward_negative_scale, reward_scale=reward_scale,
            reward_scale_rate=reward_scale_rate, move_amount=move_amount, reward_abs=reward_abs,
        )
        if self.mode == "self-play" and (opponent != "smac" or opponent_probs is not None):
            raise ValueError("mode 'self-play' has no opponent script; drop opponent= / opponent_probs=")
        self._core = TwoPlayerCore(
            map_name, 1, mode=self.mode, opponent=opponent if self.mode == "script" else None,
            opponent_probs=opponent_probs, backend=backend, step_mul=step_mul, options=options, seed=self._seed,
            backend_options=backend_options, opponent_isolation=opponent_isolation,
        )
        red = self._core.features[RED]
        spec = self._core.spec
        self.n_agents = red.n_agents
        self.n_enemies = red.n_enemies
        self.n_actions = red.n_actions
        self.n_actions_no_attack = N_ACTIONS_NO_ATTACK
        self.n_actions_move = 4
        self.episode_limit = spec.episode_limit
        self.map_type = spec.map_type
        self.unit_type_bits = spec.unit_type_bits
        self.shield_bits_ally = red.shield_bits_ally
        self.shield_bits_enemy = red.shield_bits_enemy
        self.map_x, self.map_y = spec.size
        self.max_reward = float(self._core.rewards.max_reward[RED])
        self.n_agents_list = [self.n_agents, self.n_enemies]  # SMAC-HARD's per-player lists
        self.n_actions_list = [self.n_actions, self._core.features[BLUE].n_actions]
        self.max_reward_list = [float(v) for v in self._core.rewards.max_reward]
        self._episode_steps = 0
        self._total_steps = 0
        self._episode_count = 0
        self._needs_reset = True  # until the first reset(), and again once an episode ends
        self._cache: dict[int, dict[str, np.ndarray]] = {}  # per player: battle 0's encoded features
        self._renderer = None

    def __repr__(self) -> str:
        return f"StarCraft2Env(map_name={self.map_name!r}, mode={self.mode!r}, opponent={self._core.opponent!r})"

    # -----------------------------------------------------------------------------------------------------------
    # Episode.

    def reset(self, seed: int | None = None) -> tuple[Any, Any]:
        """Start a new episode; returns ``(obs, state)`` (self-play: ``([obs_r, obs_b], [state_r, state_b])``)."""
        if seed is not None:
            self._seed = int(seed)
        self._core.reset(seed=seed)
        self._cache.clear()
        self._episode_steps = 0
        self._episode_count += 1
        self._needs_reset = False
        if self.mode == "self-play":
            return [self.get_obs(RED), self.get_obs(BLUE)], [self.get_state(RED), self.get_state(BLUE)]
        return self.get_obs(), self.get_state()

    def step(self, actions: Any) -> tuple[Any, Any, dict[str, Any]]:
        """One env step; ``actions`` lists each agent's action (self-play: ``[red_actions, blue_actions]``).

        Actions are ints (or integral floats); anything else raises ``TypeError``, a wrong length, a value out of
        range or an unavailable action :class:`~smac_hard_gym.smac.actions.InvalidActionError` (a ``ValueError``), and
        the env is left as it was. Stepping before ``reset()`` or after the episode ended raises
        :class:`~smac_hard_gym.smac.actions.ResetNeededError`."""
        if self._needs_reset:
            raise ResetNeededError("call reset() before step(): the episode " +
                                   ("has not started" if self._episode_count == 0 else "is over"))
        if self.mode == "self-play":
            if isinstance(actions, (str, bytes, dict, set)) or not hasattr(actions, "__len__"):
                raise TypeError(f"mode 'self-play' steps with [red_actions, blue_actions], got {actions!r}")
            if len(actions) != 2 or not all(hasattr(side, "__len__") for side in actions):
                raise ValueError(f"mode 'self-play' steps with [red_actions, blue_actions], got {actions!r}")
            red = validate_actions(actions[0], (self.n_agents,), self.n_actions, "red")
            blue = validate_actions(actions[1], (self.n_enemies,), self.n_actions_list[BLUE], "blue")
            result = self._core.step(red[None], blue[None], checked=True)
        else:
            result = self._core.step(validate_actions(actions, (self.n_agents,), self.n_actions, "red")[None],
                                     checked=True)
        self._cache.clear()
        self._episode_steps += 1
        self._total_steps += 1
        terminated = bool(result.terminated[0] or result.truncated[0])
        self._needs_reset = terminated
        outcome = int(result.outcome[0])
        won = (outcome == RED_WON, outcome == BLUE_WON)
        dead_red, dead_blue = int(result.dead_red[0]), int(result.dead_blue[0])
        if self.mode == "self-play":
            reward: Any = [float(result.reward[0, RED]), float(result.reward[0, BLUE])]
            info: dict[str, Any] = {"battle_won": [bool(won[RED]), bool(won[BLUE])],
                                    "dead_allies": [dead_red, dead_blue], "dead_enemies": [dead_blue, dead_red]}
            done: Any = [terminated, terminated]
        else:
            reward = float(result.reward[0, RED])
            # Numbers only: pymarl sums every info value over episodes. The opponent's name is in
            # get_opponent_name() and get_stats()["opponents"].
            info = {"battle_won": bool(won[RED]), "dead_allies": dead_red, "dead_enemies": dead_blue}
            done = terminated
        if result.truncated[0] and self.continuing_episode:
            info["episode_limit"] = True
        if result.restarted[0]:  # sc2 backend: the game was lost and restarted (SMAC returns 0, True, {} here)
            info["restarted"] = True
        return reward, done, info

    # -----------------------------------------------------------------------------------------------------------
    # Observations, state, actions.

    def _cached(self, what: str, player_id: int) -> np.ndarray:
        """Battle 0's ``"avail"``, ``"obs"`` or ``"state"``: all three are encoded together on the first request
        after a step (pymarl reads all three every step)."""
        if player_id not in self._cache:
            avail, obs, state = self._core.encode(player_id)
            self._cache[player_id] = {"avail": avail[0], "obs": obs[0], "state": state[0]}
        return self._cache[player_id][what]

    def _features(self, player_id: int) -> SideFeatures:
        if player_id not in (RED, BLUE):
            raise ValueError(f"player_id must be 0 (red, the learner) or 1 (blue), got {player_id!r}")
        return self._core.features[player_id]

    def _agent(self, agent_id: int, player_id: int) -> int:
        n = self._features(player_id).n_agents
        if not isinstance(agent_id, (int, np.integer)) or not 0 <= agent_id < n:
            raise ValueError(f"agent_id must be an int in 0..{n - 1}, got {agent_id!r}")
        return int(agent_id)

    def get_obs(self, player_id: int = RED) -> list[np.ndarray]:
        """Every agent's observation (float32 arrays of length ``get_obs_size()``)."""
        self._features(player_id)
        return [row.copy() for row in self._cached("obs", player_id)]

    def get_obs_agent(self, agent_id: int, player_id: int = RED) -> np.ndarray:
        return self._cached("obs", player_id)[self._agent(agent_id, player_id)].copy()

    def get_state(self, player_id: int = RED) -> np.ndarray:
        """The global state (float32, length ``get_state_size()``)."""
        self._features(player_id)
        return self._cached("state", player_id).copy()

    def get_state_dict(self, player_id: int = RED) -> dict[str, np.ndarray]:
        """The global state split into ``allies``, ``enemies`` and, when enabled, ``last_action``/``timestep``."""
        feats = self._features(player_id)
        if feats.options.obs_instead_of_state:
            raise ValueError("get_state_dict is not available with obs_instead_of_state=True")
        state = self._cached("state", player_id)
        out = {
            "allies": state[:feats.state_enemy_offset].reshape(feats.n_agents, feats.ally_state_feats).copy(),
            "enemies": state[feats.state_enemy_offset:feats.state_action_offset].reshape(
                feats.n_enemies, feats.enemy_state_feats).copy(),
        }
        cols = feats.columns
        if cols.state_last_action >= 0:
            col, width = cols.state_last_action, feats.n_agents * feats.n_actions
            out["last_action"] = state[col:col + width].reshape(feats.n_agents, feats.n_actions).copy()
        if cols.state_timestep >= 0:
            out["timestep"] = state[cols.state_timestep:cols.state_timestep + 1].copy()
        return out

    def get_avail_actions(self, player_id: int = RED) -> list[list[int]]:
        self._features(player_id)
        return self._cached("avail", player_id).astype(np.int64).tolist()

    def get_avail_agent_actions(self, agent_id: int, player_id: int = RED) -> list[int]:
        return self._cached("avail", player_id)[self._agent(agent_id, player_id)].astype(np.int64).tolist()

    def get_visibility_matrix(self, player_id: int = RED) -> np.ndarray:
        """bool ``(n_agents, n_agents + n_enemies)``: which units each alive agent sees (allies first)."""
        self._features(player_id)
        return self._core.visibility(player_id)[0]

    @property
    def last_action(self) -> np.ndarray:
        """Red's previous actions, one-hot ``(n_agents, n_actions)`` (zeros after reset)."""
        return last_action_onehot(self._core.last_action[RED][0], self.n_actions)

    # -----------------------------------------------------------------------------------------------------------
    # Sizes and info.

    def get_total_actions(self, player_id: int = RED) -> int:
        return self._features(player_id).n_actions

    def get_obs_size(self, player_id: int = RED) -> int:
        return self._features(player_id).obs_size

    def get_state_size(self, player_id: int = RED) -> int:
        return self._features(player_id).state_size

    def get_obs_move_feats_size(self, player_id: int = RED) -> int:
        return self._features(player_id).move_size

    def get_obs_enemy_feats_size(self, player_id: int = RED) -> tuple[int, int]:
        feats = self._features(player_id)
        return feats.n_enemies, feats.enemy_feats

    def get_obs_ally_feats_size(self, player_id: int = RED) -> tuple[int, int]:
        feats = self._features(player_id)
        return feats.n_agents - 1, feats.ally_feats

    def get_obs_own_feats_size(self, player_id: int = RED) -> int:
        return self._features(player_id).own_size

    def get_ally_num_attributes(self, player_id: int = RED) -> int:
        return self._features(player_id).ally_state_feats

    def get_enemy_num_attributes(self, player_id: int = RED) -> int:
        return self._features(player_id).enemy_state_feats

    def get_obs_feature_names(self, player_id: int = RED) -> list[str]:
        return self._features(player_id).obs_feature_names()

    def get_state_feature_names(self, player_id: int = RED) -> list[str]:
        return self._features(player_id).state_feature_names()

    def _env_info(self, player_id: int) -> dict[str, Any]:
        feats = self._features(player_id)
        return {
            "state_shape": feats.state_size,
            "obs_shape": feats.obs_size,
            "n_actions": feats.n_actions,
            "n_agents": feats.n_agents,
            "episode_limit": self.episode_limit,
            "agent_features": list(feats.ally_state_names),
            "enemy_features": list(feats.enemy_state_names),
        }

    def get_env_info(self) -> dict[str, Any] | list[dict[str, Any]]:
        """SMAC's env info dict (self-play: one dict per player, as SMAC-HARD)."""
        if self.mode == "self-play":
            return [self._env_info(RED), self._env_info(BLUE)]
        return self._env_info(RED)

    def get_stats(self) -> dict[str, Any]:
        """SMAC's counters (``battles_won``, ``battles_game``, ``battles_draw`` = timeouts as in SMAC,
        ``win_rate``, ``timeouts``, ``restarts``) plus ``opponents``: games, wins and win rate per opponent name.
        In self-play ``battles_won`` and ``win_rate`` are ``[red, blue]``."""
        s = self._core.stats()
        games = s["games"]
        stats: dict[str, Any] = {
            "battles_won": s["wins"], "battles_game": games, "battles_draw": s["timeouts"],
            "win_rate": s["win_rate"], "timeouts": s["timeouts"],
            "restarts": int(getattr(self._core.backend, "restarts", 0)), "opponents": s["opponents"],
        }
        if self.mode == "self-play":
            stats["battles_won"] = [s["wins"], s["losses"]]
            stats["win_rate"] = [s["win_rate"], s["losses"] / games if games else 0.0]
        return stats

    def get_opponent_name(self) -> str:
        """The opponent script playing this episode (``"self-play"`` in self-play)."""
        return self._core.opponent_names()[0]

    # -----------------------------------------------------------------------------------------------------------
    # Misc.

    def seed(self) -> int | None:
        """The seed given at construction (or to the latest ``reset(seed=...)``)."""
        return self._seed

    def render(self, mode: str = "human") -> np.ndarray | None:
        """Draw the battle: ``"rgb_array"`` returns the frame (H, W, 3) uint8, ``"human"`` shows it."""
        from smac_hard_gym.render import EnvRenderer, check_render_mode  # only when rendering is asked for

        if check_render_mode(mode) is None:
            raise ValueError("render mode must be 'rgb_array' or 'human', got None")
        if self._renderer is None or self._renderer.render_mode != mode:
            if self._renderer is not None:
                self._renderer.close()
            self._renderer = EnvRenderer(self._core.spec, mode, step_mul=self._core.backend.step_mul)
        return self._renderer.render(self._core.state, 0, self._episode_steps, self._core.opponent_names()[0])

    def save_replay(self) -> None:
        """Save an SC2 replay into ``replay_dir`` (``backend="sc2"``); the native engine records episodes with
        ``smac_hard_gym.render.EpisodeRecorder`` instead and warns here."""
        backend = self._core.backend
        if hasattr(backend, "save_replay"):
            folder = Path(self.replay_dir or ".")
            name = f"{self.replay_prefix or self._core.spec.name}_{time.strftime('%Y%m%d-%H%M%S')}.SC2Replay"
            path = backend.save_replay(folder / name, battle=0)
            print(f"replay saved to {path}")
            return
        warnings.warn("save_replay() does nothing on the native backend; record episodes with "
                      "smac_hard_gym.render.EpisodeRecorder", stacklevel=2)

    def close(self) -> None:
        """Release the backend (and the render window). Idempotent."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self._core.close()

    def full_restart(self) -> None:
        """SMAC restarts the game after a crash; the native engine has nothing to restart, so this resets."""
        self.reset()
