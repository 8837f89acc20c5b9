"""The two-player core: B battles of one map, a backend, SMAC features for both sides, and the opponent hook.

Every environment API (``StarCraft2Env``, the gymnasium env, the vector envs) is a thin layer over this class.

Public surface::

    core = TwoPlayerCore(map_name, batch_size=1, *, mode="script", opponent="smac", opponent_probs=None,
                         backend="native", step_mul=8, options=SmacOptions(), seed=None, backend_options=None,
                         opponent_isolation=None, encode_state=True, episode_limit=None, red_script=None)

    core.reset(battles=None, seed=None)          # start new episodes (all battles, or the indices given)
    result = core.step(red_actions, blue_actions=None, *, replace_invalid=False, hint="", checked=False)
                                                 # actions int (B, n_red) / (B, n_blue); a StepResult
    core.avail_actions(side=RED)                 # bool (B, n, n_actions)   side: RED=0 / BLUE=1
    core.observations(side=RED, out=None)        # float32 (B, n, obs_size)
    core.global_state(side=RED, out=None)        # float32 (B, state_size)
    core.encode(side=RED)                        # (masks, observations, state) of the current state
    core.visibility(side=RED)                    # bool (B, n, n + m)
    core.side_view(side)                         # opponents.api.SideView over the live state
    core.opponent_names()                        # list[str], the opponent playing each battle's episode
    core.opponent_name_array()                   # the same as an object array (B,)
    core.stats()                                 # dict: games, wins, draws, timeouts, per-opponent table
    core.invalidate()                            # after writing into core.state by hand (tests, scenarios)
    core.close()

Attributes: ``spec`` (MapSpec), ``batch_size``, ``mode``, ``options``, ``backend``, ``features`` (the two
:class:`~smac_hard_gym.smac.features.SideFeatures`, indexed by side: sizes ``obs_size``, ``state_size``,
``n_actions``, ``n_agents``), ``rewards`` (``max_reward`` per side), ``episode_step`` (int64 (B,)), ``done`` (bool
(B,): battles that finished and wait for a reset), ``last_action`` (per side, int64 (B, n), -1 = none), ``rngs``
(one seeded ``np.random.Generator`` per battle), ``opponent`` (the script, None in self-play).

``step`` goes down once and up once. Down: red's actions are checked and decoded into engine commands in one kernel
call (blue's too in self-play), the opponent script writes blue's, the backend steps. Up: one kernel call writes the
outcome, both sides' rewards, the counters and red's encoding of the new state (masks, observations, and the global
state when ``encode_state``). It returns a :class:`StepResult` holding all of it per battle: ``reward`` float32
(B, 2) [red, blue], ``terminated`` (win, loss or draw), ``truncated`` (episode limit reached first), ``outcome``
(RUNNING / RED_WON / BLUE_WON / DRAW), ``dead_red`` / ``dead_blue`` counts, ``stepped`` (the battles advanced),
``opponent`` names, ``replaced`` (red's unavailable actions replaced under ``replace_invalid``), ``episode_step``,
and red's ``avail``, ``obs`` and ``state``. Finished battles stay frozen until ``reset(battles)``; the core never
resets on its own (the env layers choose their autoreset policy). ``episode_limit`` (default: the map's) is the
step count at which an episode is truncated.

``profile_hook``: None, or a callable ``hook(phase, seconds)`` that ``step`` calls after each phase ("actions",
"opponent", "engine", "outcome and features") with its wall time: how the benchmarks split a step.

Modes: ``"script"``: the opponent (a :class:`~smac_hard_gym.opponents.api.Script`, a built-in name or what
``make_opponent`` accepts) gets ``reset(view, battles, rngs)`` at each episode start and ``act(view, commands,
active)`` every step; ``"self-play"``: ``step`` takes blue's SMAC actions, validated and decoded like red's.
``red_script`` (script mode): a script plays red as well, with a generator of its own per battle (seeded from
``[s, 2]``); ``step(None)`` then takes no actions (duels and recordings run this way). ``backend``: a name
(``"native"``, ``"sc2"``) or a :class:`~smac_hard_gym.backend.Backend` the caller built.

Seeding: ``reset(seed=s)`` gives battle b the generator ``np.random.default_rng(s + b)`` (so battle b of a batch
draws like a single env seeded ``s + b``); a sequence seeds the listed battles one by one; ``None`` keeps each
battle's generator running (fresh entropy the first time). The simulator's own randomness (SC2's weapon delays) has a
separate stream per battle, restarted from the same seed and otherwise left running across episodes.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from smac_hard_gym.backend import BACKENDS, Backend, make_backend
from smac_hard_gym.engine.direct import DirectKernel, is_plain
from smac_hard_gym.engine.state import BLUE, RED, Commands
from smac_hard_gym.engine.units import STATS, WEAPON_HEAL, S
from smac_hard_gym.maps import MapSpec, load_map
from smac_hard_gym.opponents import Script, SideView, make_opponent
from smac_hard_gym.smac.actions import raise_unavailable, validate_actions
from smac_hard_gym.smac.features import (
    BLUE_WON,
    DRAW,
    RED_WON,
    SIDE_NAMES,
    RewardFunction,
    SideFeatures,
    SmacOptions,
)
from smac_hard_gym.smac.kernels import (
    Counters,
    StepInputs,
    StepOutcome,
    check_decode_batch,
    finish_encode,
    make_bundle,
)

__all__ = ["TwoPlayerCore", "StepResult", "MODES", "SELF_PLAY_NAME", "RED", "BLUE"]

MODES = ("script", "self-play")
SELF_PLAY_NAME = "self-play"  # info["opponent"] when blue is a second learner


class StepResult(NamedTuple):
    """What one core step produced, per battle (arrays over the batch)."""

    reward: np.ndarray  # float32 (B, 2): [red, blue], each scaled by its own max_reward
    terminated: np.ndarray  # bool (B,): the battle ended this step (win, loss or draw)
    truncated: np.ndarray  # bool (B,): the episode limit was reached without a result
    outcome: np.ndarray  # int8 (B,): RUNNING, RED_WON, BLUE_WON or DRAW
    dead_red: np.ndarray  # int64 (B,): red units dead
    dead_blue: np.ndarray  # int64 (B,): blue units dead
    stepped: np.ndarray  # bool (B,): battles advanced by this step
    opponent: list[str]  # opponent playing each battle
    restarted: np.ndarray  # bool (B,): the backend restarted a lost game; the episode ended without a result
    replaced: np.ndarray  # int64 (B,): red's unavailable actions replaced by the first available (replace_invalid)
    episode_step: np.ndarray  # int64 (B,): env steps of each battle's episode so far (a copy)
    avail: np.ndarray  # bool (B, n_red, n_actions): red's available actions in the new state
    obs: np.ndarray  # float32 (B, n_red, obs_size): red's observations of the new state
    state: np.ndarray | None  # float32 (B, state_size): red's global state (None unless the core encodes it)

    @property
    def battle_won(self) -> np.ndarray:
        """bool (B, 2): [red won, blue won]."""
        return np.stack([self.outcome == RED_WON, self.outcome == BLUE_WON], axis=1)


class _OpponentStats:
    """Games, red wins, blue wins, draws and timeouts, per opponent name (a count table, one row per name)."""

    COLUMNS = ("games", "wins", "losses", "draws", "timeouts")

    def __init__(self) -> None:
        self.names: list[str] = []
        self._ids: dict[str, int] = {}
        self.counts = np.zeros((0, len(self.COLUMNS)), dtype=np.int64)

    def name_id(self, name: str) -> int:
        """The row of ``name``, added on first sight."""
        if name not in self._ids:
            self._ids[name] = len(self.names)
            self.names.append(name)
            self.counts = np.vstack([self.counts, np.zeros((1, len(self.COLUMNS)), np.int64)])
        return self._ids[name]

    def record(self, name_ids: np.ndarray, outcome: np.ndarray, timeout: np.ndarray) -> None:
        """Count finished games: the opponent row, outcome and timeout flag of each."""
        rows = len(self.names)
        for col, hits in enumerate((np.ones(len(name_ids), bool), outcome == RED_WON, outcome == BLUE_WON,
                                    outcome == DRAW, timeout)):
            self.counts[:, col] += np.bincount(name_ids, weights=hits, minlength=rows).astype(np.int64)

    def summary(self) -> dict[str, Any]:
        totals = {key: int(self.counts[:, col].sum()) for col, key in enumerate(self.COLUMNS)}
        totals["win_rate"] = totals["wins"] / totals["games"] if totals["games"] else 0.0
        table = {name: dict(zip(self.COLUMNS, map(int, self.counts[k]), strict=True))
                 for k, name in enumerate(self.names) if self.counts[k, 0]}
        totals["opponents"] = {name: {**row, "win_rate": row["wins"] / row["games"]}
                               for name, row in sorted(table.items())}
        return totals


# Actions of the one type the step's direct kernel calls compile for (what validation and every env layer produce).
_INT64 = np.dtype(np.int64)


class TwoPlayerCore:
    """B battles of one map with SMAC's interface for both sides; see the module docstring for the API."""

    def __init__(self, map_name: str | MapSpec, batch_size: int = 1, *, mode: str = "script",
                 opponent: Any = "smac", opponent_probs: Sequence[float] | None = None, backend: str = "native",
                 step_mul: int = 8, options: SmacOptions | None = None, seed: int | None = None,
                 backend_options: dict | None = None, opponent_isolation: str | None = None, encode_state: bool = True,
                 episode_limit: int | None = None, red_script: Any = None) -> None:
        """See the module docstring. Keyword options, each with a default, rather than an options object: every env
        layer passes the subset it exposes by name, and SMAC's own options already travel as one ``SmacOptions``."""
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        if not isinstance(batch_size, (int, np.integer)) or isinstance(batch_size, bool) or batch_size < 1:
            raise ValueError(f"batch_size must be a positive int, got {batch_size!r}")
        self.spec: MapSpec = load_map(map_name)
        self.batch_size = int(batch_size)
        self.episode_limit = self.spec.episode_limit
        if episode_limit is not None:
            if isinstance(episode_limit, bool) or not isinstance(episode_limit, (int, np.integer)) or episode_limit < 1:
                raise ValueError(f"episode_limit must be a positive int or None, got {episode_limit!r}")
            self.episode_limit = min(self.episode_limit, int(episode_limit))
        self.encode_state = bool(encode_state)
        self.profile_hook: Any = None
        self.mode = mode
        self.options = options or SmacOptions()
        self.features: tuple[SideFeatures, SideFeatures] = (
            SideFeatures(self.spec, RED, self.options), SideFeatures(self.spec, BLUE, self.options))
        self.rewards = RewardFunction(*self.features, self.options)
        self.n_red, self.n_blue = self.features[RED].n_agents, self.features[BLUE].n_agents
        # The way up's rules: a side is beaten when no unit of it that fights is alive; the reward options; the limit.
        self._rules = self.rewards.rules(STATS[self.features[RED].utype, S["weapon"]] != WEAPON_HEAL,
                                         self.episode_limit)

        self.opponent: Script | None = None
        if mode == "script":
            self.opponent = make_opponent(self.spec, opponent, opponent_probs, isolation=opponent_isolation)
        elif opponent not in (None, "smac") or opponent_probs is not None:
            raise ValueError(f"mode 'self-play' takes blue's actions from step(); opponent={opponent!r} and "
                             f"opponent_probs={opponent_probs!r} apply to mode 'script' only")
        # A script can drive red too (duels, recordings): step() then takes no red actions.
        self.red_script: Script | None = None
        if red_script is not None:
            if mode != "script":
                raise ValueError(f"red_script={red_script!r} needs mode 'script' (a script on each side)")
            self.red_script = make_opponent(self.spec, red_script, isolation=opponent_isolation)

        if isinstance(backend, str):
            self.backend: Backend = make_backend(backend, self.spec, batch_size=self.batch_size, step_mul=step_mul,
                                                 **(backend_options or {}))
        elif isinstance(backend, Backend) and backend.batch_size == self.batch_size and backend_options is None:
            self.backend = backend  # a backend built by the caller (its map must be this one: checked below)
        else:
            raise ValueError(f"backend must be one of {BACKENDS} or a Backend of {self.batch_size} battles built "
                             f"without backend_options here, got {backend!r}")
        shape = self.backend.state.alive.shape
        if shape != (self.batch_size, self.n_red + self.n_blue):
            raise RuntimeError(f"backend {backend!r} state has shape {shape}, expected "
                               f"({self.batch_size}, {self.n_red + self.n_blue}) for map {self.spec.name!r}")
        b = self.batch_size
        self.commands = Commands.empty(b, self.n_red + self.n_blue)
        self.episode_step = np.zeros(b, dtype=np.int64)
        self.done = np.zeros(b, dtype=bool)
        self.last_action = (np.full((b, self.n_red), -1, dtype=np.int64),
                            np.full((b, self.n_blue), -1, dtype=np.int64))
        self.rngs: list[np.random.Generator | None] = [None] * b
        self.red_rngs: list[np.random.Generator | None] = [None] * b  # the red script's, a stream of its own
        self._has_rng = np.zeros(b, dtype=bool)
        self.seeds: list[int | None] = [None] * b
        self._stats = _OpponentStats()
        self._names = np.full(b, SELF_PLAY_NAME, dtype=object)  # opponent per battle, fixed for an episode
        self._name_ids = np.full(b, self._stats.name_id(SELF_PLAY_NAME), dtype=np.int64)  # its row in the stats
        self._encoded: list[tuple | None] = [None, None]  # each side's (masks, obs, state or None) of the state
        self._avail_cache: list[np.ndarray | None] = [None, None]  # its masks alone, when only they were asked for
        self._views: list[SideView | None] = [None, None]
        self._no_replaced = np.zeros(b, dtype=np.int64)  # result.replaced without replace_invalid
        self._reject = np.zeros(0, dtype=np.int64)  # check_decode_batch's "reject unavailable actions"
        self._no_restarts = np.zeros(b, dtype=bool)
        self._no_actions = np.zeros((0, self.n_blue), dtype=np.int64)  # blue's actions when a script plays it
        self._no_red_actions = np.zeros((0, self.n_red), dtype=np.int64)  # red's, when red_script plays it
        self._counters = Counters(self.episode_step, self.done, *self.last_action)  # the way up updates them
        # The way up, and each side's way down, called past numba's dispatcher once compiled.
        self._finish_encode = DirectKernel(finish_encode)
        self._check_decode = (DirectKernel(check_decode_batch), DirectKernel(check_decode_batch))
        self._error: BaseException | None = None
        self._closed = False
        self.reset(seed=seed)

    def __repr__(self) -> str:
        return (f"TwoPlayerCore(map={self.spec.name!r}, batch_size={self.batch_size}, mode={self.mode!r}, "
                f"opponent={self.opponent!r})")

    @property
    def state(self):
        """The backend's current :class:`~smac_hard_gym.engine.state.BattleState`."""
        return self.backend.state

    # -----------------------------------------------------------------------------------------------------------
    # Episodes.

    def reset(self, battles: Sequence[int] | np.ndarray | None = None,
              seed: int | Sequence[int] | None = None, *, in_place: bool = False) -> None:
        """Start new episodes in ``battles`` (indices; all when None), seeding their generators (module docstring).

        A partial reset re-encodes the restarted rows of red's current encoding into copies of its arrays (the last
        step's result may be held by the caller); ``in_place`` writes them into those arrays instead, for a caller
        that has not handed them out (a vector env's autoreset right after its step: copying 4096 battles'
        observations cost 8% of an 8m step). After an opponent error only a reset of every battle is accepted.
        """
        self._check_open()
        rows = np.arange(self.batch_size) if battles is None else self._battle_indices(battles)
        if len(rows) == 0:
            return
        if self._error is not None and np.unique(rows).size < self.batch_size:
            raise RuntimeError(f"the opponent failed ({self._error!r}); reset() every battle before going on")
        restart, engine_seeds = self._seed(rows, seed)
        if engine_seeds is None:  # every simulator stream goes on, like the scripts' generators
            self.backend.reset(None if battles is None else rows)
        elif restart.all():
            self.backend.reset(None if battles is None else rows, seeds=engine_seeds)
        else:
            self.backend.reset(rows[restart], seeds=engine_seeds[restart])
            self.backend.reset(rows[~restart])
        self.episode_step[rows] = 0
        self.done[rows] = False
        self.last_action[RED][rows] = -1
        self.last_action[BLUE][rows] = -1
        self._refresh(rows, in_place)
        if self.opponent is not None:
            self._script_call(self.opponent.reset, BLUE, rows, self.rngs)
            names = self.opponent.names_of(rows)
            ids = {name: self._stats.name_id(name) for name in set(names)}
            self._names[rows] = names
            self._name_ids[rows] = [ids[name] for name in names]
        if self.red_script is not None:
            self._script_call(self.red_script.reset, RED, rows, self.red_rngs)
        self._error = None

    def step(self, red_actions: Any, blue_actions: Any = None, *, replace_invalid: bool = False,
             hint: str = "", checked: bool = False) -> StepResult:
        """Advance every battle that is not done by one env step (``step_mul`` game loops).

        Actions are checked (:func:`~smac_hard_gym.smac.actions.validate_actions`, then availability in the battles
        that step). An unavailable red action raises :class:`~smac_hard_gym.smac.actions.InvalidActionError`
        (message ending with ``hint``), or with ``replace_invalid`` is replaced by the agent's first available one
        and counted in ``result.replaced``. A rejected step changes nothing. ``checked``: the actions given (red's,
        and blue's in self-play) are already fresh int64 arrays ``(B, n)`` of in-range values (an env layer
        validated them): not validated again, so every API validates once.
        """
        self._check_open()
        if self._error is not None:
            raise RuntimeError(f"the opponent failed ({self._error!r}); call reset() before stepping again")
        if self.mode == "self-play" and blue_actions is None:
            raise ValueError("mode 'self-play' needs blue's actions: step(red_actions, blue_actions)")
        if self.mode == "script" and blue_actions is not None:
            raise ValueError("mode 'script' plays blue with the opponent script; pass red's actions only")
        hook = self.profile_hook
        clock = time.perf_counter() if hook is not None else 0.0
        size, active, state, commands = self.batch_size, ~self.done, self.backend.state, self.commands

        # Down: actions to commands (red's in one call, blue's too in self-play), then the opponent.
        commands.clear()
        replaced = np.zeros(size, dtype=np.int64) if replace_invalid else self._no_replaced
        if self.red_script is None:
            red = self._decode(RED, red_actions, active, replaced if replace_invalid else self._reject, hint, checked)
        elif red_actions is not None:
            raise ValueError("red is played by red_script: step() takes no red actions (pass None)")
        else:
            red = self._no_red_actions
            self._script_call(self.red_script.act, RED, commands, active)
        blue = self._no_actions
        if self.mode == "self-play":
            blue = self._decode(BLUE, blue_actions, active, self._reject, "", checked)
        if hook is not None:
            clock = self._lap(hook, "actions", clock)
        if self.opponent is not None:
            self._script_call(self.opponent.act, BLUE, commands, active)
            if hook is not None:
                clock = self._lap(hook, "opponent", clock)

        prev_hs = state.health + state.shield
        prev_alive = state.alive.copy()
        self.backend.step(commands, active)
        state = self.backend.state
        self._invalidate()
        if hook is not None:
            clock = self._lap(hook, "engine", clock)

        # Up: outcome, rewards, counters and red's encoding of the new state, in one call. A backend that lost its
        # game (sc2: protocol or connection error) restarted it: that episode ended without a result, earns nothing.
        restarted = getattr(self.backend, "restarted", None)
        restarted = self._no_restarts if restarted is None else np.ascontiguousarray(restarted, dtype=bool)
        outcome, reward = np.empty(size, np.int8), np.empty((size, 2), np.float32)
        terminated, truncated = np.empty(size, bool), np.empty(size, bool)
        dead_red, dead_blue = np.empty(size, np.int64), np.empty(size, np.int64)
        feats = self.features[RED]
        out = feats.outputs(size, self.encode_state)
        avail, obs = out.avail, out.obs
        units, plain = feats.kernel_units(state)
        n_ended = self._finish_encode(
            plain and is_plain(red, _INT64, 2) and (blue is self._no_actions or is_plain(blue, _INT64, 2)),
            units,
            make_bundle(StepInputs, (prev_hs, prev_alive, active, restarted, red, blue, feats.all_rows(state))),
            self._counters, make_bundle(StepOutcome, (outcome, reward, terminated, truncated, dead_red, dead_blue)),
            out, feats.constants, feats.columns, self._rules)
        global_state = feats.finish_state(obs, out.state) if self.encode_state else None
        self._encoded[RED] = (avail, obs, global_state)
        if n_ended:
            ended = terminated | truncated
            self._stats.record(self._name_ids[ended], outcome[ended], truncated[ended])
        if hook is not None:
            self._lap(hook, "outcome and features", clock)
        return StepResult(reward, terminated, truncated, outcome, dead_red, dead_blue, active, self._names.tolist(),
                          restarted & active, replaced, self.episode_step.copy(), avail, obs, global_state)

    def _script_call(self, method: Any, side: int, *args: Any) -> None:
        """A script's ``reset`` or ``act`` on ``side``'s view; a failure is kept, so only a full reset goes on."""
        try:
            method(self.side_view(side), *args)
        except Exception as err:
            self._error = err
            raise

    def _decode(self, side: int, actions: Any, active: np.ndarray, replaced: np.ndarray, hint: str,
                checked: bool) -> np.ndarray:
        """One side's actions, validated, checked against its masks and written as engine commands (one kernel);
        unavailable ones are replaced and counted in ``replaced`` (B,), or rejected when it is empty."""
        feats = self.features[side]
        acts = actions if checked else validate_actions(actions, (self.batch_size, feats.n_agents), feats.n_actions,
                                                        SIDE_NAMES[side])
        avail = self.avail_actions(side)
        state = self.backend.state
        units, plain = feats.kernel_units(state)
        bad = self._check_decode[side](plain and is_plain(acts, _INT64, 2), acts, avail, active, replaced, units.x,
                                       units.y, self.commands, feats.constants.actions)
        if bad >= 0:
            raise_unavailable(feats, acts, avail, bad, hint)
        return acts

    @staticmethod
    def _lap(hook: Any, phase: str, since: float) -> float:
        now = time.perf_counter()
        hook(phase, now - since)
        return now

    # -----------------------------------------------------------------------------------------------------------
    # Features.

    def avail_actions(self, side: int = RED) -> np.ndarray:
        """bool ``(B, n, n_actions)``; computed once per state (treat as read-only)."""
        side = self._side(side)
        if self._encoded[side] is not None:
            return self._encoded[side][0]
        if self._avail_cache[side] is None:
            self._avail_cache[side] = self.features[side].available_actions(self.backend.state)
        return self._avail_cache[side]

    def observations(self, side: int = RED, out: np.ndarray | None = None) -> np.ndarray:
        """float32 ``(B, n, obs_size)`` (a new array unless ``out`` is given)."""
        obs = self.encode(side)[1]
        if out is None:
            return obs.copy()
        out[...] = obs
        return out

    def global_state(self, side: int = RED, out: np.ndarray | None = None) -> np.ndarray:
        """float32 ``(B, state_size)`` (a new array unless ``out`` is given)."""
        side = self._side(side)
        state = self.encode(side)[2]
        if state is None:  # this side's encoding left the state out: the env layer did not need it
            feats = self.features[side]
            return feats.global_state(self.backend.state, self.last_action[side], self.episode_step, out=out,
                                      obs=self.encode(side)[1] if self.options.obs_instead_of_state else None)
        if out is None:
            return state.copy()
        out[...] = state
        return out

    def encode(self, side: int = RED) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The masks, observations and global state of the current state, as the last step or reset left them
        (encoded now when nothing has since: one kernel call). The state is None when the last step's encoding
        left it out (``encode_state=False``). Shared arrays: treat them as read-only."""
        side = self._side(side)
        if self._encoded[side] is None:
            feats = self.features[side]
            avail, obs, state = feats.encode(self.backend.state, self.last_action[side], self.episode_step)
            self._encoded[side] = (avail, obs, state)
        return self._encoded[side]

    def visibility(self, side: int = RED) -> np.ndarray:
        """bool ``(B, n, n + m)``: SMAC's visibility matrix per battle."""
        side = self._side(side)
        return self.features[side].visibility(self.backend.state)

    def side_view(self, side: int) -> SideView:
        """A :class:`~smac_hard_gym.opponents.api.SideView` of ``side`` over the live state (one per side, kept
        while the backend keeps its state arrays, so what a view caches about the map is worked out once)."""
        side = self._side(side)
        view, state = self._views[side], self.backend.state
        if view is None or view.state is not state:
            feats = self.features[side]
            view = SideView(state, self.spec, feats.side, feats.own, feats.enemy, self.episode_step)
            self._views[side] = view
        return view

    def opponent_names(self) -> list[str]:
        """The opponent playing each battle's current episode (asked of the script at each reset)."""
        return self._names.tolist()

    def opponent_name_array(self) -> np.ndarray:
        """:meth:`opponent_names` as a fresh object array (what batched infos hold)."""
        return self._names.copy()

    def stats(self) -> dict[str, Any]:
        """Finished games so far: ``games``, ``wins`` (red), ``losses``, ``draws`` (both sides beaten),
        ``timeouts``, ``win_rate`` and ``opponents``: the same per opponent name (script mode: red's record
        against each script; self-play: under ``"self-play"``)."""
        return self._stats.summary()

    def close(self) -> None:
        """Release the backend. Idempotent."""
        if not self._closed:
            self._closed = True
            self.backend.close()

    # -----------------------------------------------------------------------------------------------------------
    # Helpers.

    def invalidate(self) -> None:
        """Forget the cached masks and encodings: call after writing into ``state`` by hand."""
        self._avail_cache = [None, None]
        self._encoded = [None, None]

    _invalidate = invalidate

    def _refresh(self, rows: np.ndarray, in_place: bool) -> None:
        """After battles ``rows`` restarted: a partial reset re-encodes those rows into red's cached arrays (copies
        of them unless ``in_place``); a full one forgets the caches."""
        encoded = self._encoded[RED]
        self._invalidate()
        if encoded is None or (len(rows) >= self.batch_size and np.unique(rows).size == self.batch_size):
            return
        feats = self.features[RED]
        fresh = feats.encode(self.backend.state, self.last_action[RED], self.episode_step, rows=rows)
        spliced = []
        for old, new in zip(encoded, fresh, strict=True):
            if old is None:
                spliced.append(None)
                continue
            array = old if in_place else old.copy()
            array[rows] = new
            spliced.append(array)
        self._encoded[RED] = tuple(spliced)

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("this core is closed")

    @staticmethod
    def _side(side: int) -> int:
        if side not in (RED, BLUE):
            raise ValueError(f"side must be 0 (red, the learner) or 1 (blue, the opponent), got {side!r}")
        return int(side)

    def _battle_indices(self, battles: Sequence[int] | np.ndarray) -> np.ndarray:
        rows = np.asarray(battles)
        if rows.dtype == bool:
            if rows.shape != (self.batch_size,):
                raise ValueError(f"a battle mask must have shape ({self.batch_size},), got {rows.shape}")
            return np.flatnonzero(rows)
        rows = rows.astype(np.int64).reshape(-1)
        if len(rows) and (rows.min() < 0 or rows.max() >= self.batch_size):
            raise ValueError(f"battle indices must lie in 0..{self.batch_size - 1}, got {battles!r}")
        return rows

    def _seed(self, rows: np.ndarray, seed: int | Sequence[int] | None) -> tuple[np.ndarray, np.ndarray | None]:
        """Seed the scripts' generators of ``rows``. Returns which rows' simulator streams restart, and their seeds.

        The simulator's randomness (weapon delays) has a stream of its own per battle, so that the scripts' draws do
        not depend on it: seeded from ``[s, 1]`` with the battle's seed s, from fresh entropy on a battle's first
        unseeded reset, and otherwise left running.
        """
        if seed is None:
            restart = ~self._has_rng[rows]
            for b in rows[restart]:
                self.rngs[b] = np.random.default_rng()
                self.red_rngs[b] = np.random.default_rng()
            self._has_rng[rows] = True
            fresh = np.random.default_rng().integers(0, 2**63, size=len(rows)) if restart.any() else None
            return restart, fresh
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + int(b) for b in rows]
        else:
            seeds = list(seed)
            if len(seeds) != len(rows) or not all(
                    isinstance(s, (int, np.integer)) and not isinstance(s, bool) for s in seeds):
                raise ValueError(f"seed must be an int or one int per reset battle ({len(rows)}), got {seed!r}")
        engine_seeds = np.empty(len(rows), dtype=np.int64)
        for k, (b, s) in enumerate(zip(rows, seeds, strict=True)):
            if s < 0:
                raise ValueError(f"seeds must be non-negative, got {s} for battle {b}")
            self.seeds[b] = int(s)
            self.rngs[b] = np.random.default_rng(int(s))
            self.red_rngs[b] = np.random.default_rng([int(s), 2])
            self._has_rng[b] = True
            engine_seeds[k] = np.random.default_rng([int(s), 1]).integers(0, 2**63)
        return np.ones(len(rows), dtype=bool), engine_seeds
