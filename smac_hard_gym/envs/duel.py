"""Script against script on the two-player core: duels (win rates over many episodes) and recordings (one battle,
frame by frame). Both run the same loop, :func:`play`, over a :class:`~smac_hard_gym.envs.core.TwoPlayerCore` that
has a script on each side (``red_script`` and ``opponent``), so they share the core's rules:

>>> from smac_hard_gym.envs.duel import run_duel
>>> result = run_duel("3m", red="stop", blue="base", episodes=4, seed=0)
>>> result.blue_wins
4

- **Outcome** (the core's): a side is out when none of its fighting units is alive (medivacs do not count, as in
  SMAC); the other side then wins, both out in the same step is a draw, and an episode that reaches the episode
  limit first is truncated (a draw at the limit, counted in ``timeouts``).
- **Seeding** (the core's): episode ``e`` of a run seeded ``s`` is a battle seeded ``s + e``: blue's script draws
  from ``default_rng(s + e)``, red's from ``default_rng([s + e, 2])``, the engine's weapon delays from ``[s + e, 1]``.
  So results do not depend on the batch size, and on blue's side episode ``e`` plays exactly like
  ``SMACHardEnv(map, opponent=blue).reset(seed=s + e)`` given the actions red's script orders.

The red side's units are SMAC's passive ``*_RL`` units: they never act on their own (not even to shoot back) but do
acquire targets while attack-moving, so a red script must give explicit orders. ``red=None`` (or ``"idle"``) leaves
them idle: :class:`Idle` gives no orders at all.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, NamedTuple

import numpy as np

from smac_hard_gym.backend import Backend
from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.maps import MapSpec, load_map
from smac_hard_gym.opponents import Script, make_opponent
from smac_hard_gym.render.recorder import EpisodeRecorder
from smac_hard_gym.smac.features import BLUE_WON, DRAW, RED_WON

__all__ = ["DuelResult", "WinRates", "Finished", "Idle", "IDLE", "play", "run_duel", "record_engine_episode"]

MAX_BATCH = 64
IDLE = "idle"  # the name that, like None, leaves a side without orders


class Idle(Script):
    """A side that gives no orders at all (SMAC's passive ``*_RL`` units then stand and never fight back)."""

    name = IDLE
    description = "gives no orders (passive units stand idle)"

    def act(self, view: Any, commands: Any, active: np.ndarray) -> None:
        return None


class Finished(NamedTuple):
    """One episode :func:`play` finished."""

    episode: int  # 0, 1, ... in the order the episodes were started
    battle: int  # the core's battle (row) that played it
    seed: int  # the battle's seed: the run's seed + episode
    outcome: int  # RED_WON, BLUE_WON or DRAW (the core's outcome codes); DRAW at the limit too
    truncated: bool  # the episode limit came first
    steps: int  # env steps the episode lasted
    red: str  # the script that played each side (a mixture's pick for this episode)
    blue: str


def play(core: TwoPlayerCore, seed: int, episodes: int,
         on_step: Callable[[Any], None] | None = None) -> Iterator[Finished]:
    """Play episodes ``0 .. episodes - 1`` on ``core`` (a script on each side), episode ``e`` in a battle seeded
    ``seed + e``, and yield each as it finishes. Battle ``b`` starts with episode ``b`` (the core is reset so unless
    it was just built or reset with ``seed=seed``); a battle that finishes takes the next episode not started.
    ``on_step(result)`` sees every core step's :class:`~smac_hard_gym.envs.core.StepResult` before its episodes are
    yielded and restarted. A game the backend lost (``restarted``, sc2 only) is played again from the same seed."""
    if core.red_script is None or core.opponent is None:
        raise ValueError("play() needs a script on each side: TwoPlayerCore(..., opponent=..., red_script=...)")
    size = core.batch_size
    if not isinstance(episodes, (int, np.integer)) or isinstance(episodes, bool) or episodes < size:
        raise ValueError(f"episodes must be an int >= the core's batch size {size}, got {episodes!r}")
    rows = np.arange(size)
    fresh = core.seeds == [seed + b for b in range(size)] and not core.episode_step.any() and not core.done.any()
    if not fresh:
        core.reset(seed=seed)
    episode_of = rows.copy()
    red_names = np.array(core.red_script.names_of(rows), dtype=object)
    blue_names = np.array(core.opponent.names_of(rows), dtype=object)
    started, finished = size, 0
    while finished < episodes:
        result = core.step(None)
        if on_step is not None:
            on_step(result)
        ended = np.flatnonzero(result.stepped & (result.terminated | result.truncated))
        if not len(ended):
            continue
        lost = result.restarted[ended]
        replay, ended = ended[lost], ended[~lost]
        for b in ended:
            outcome = int(result.outcome[b]) if result.terminated[b] else DRAW
            yield Finished(int(episode_of[b]), int(b), seed + int(episode_of[b]), outcome, bool(result.truncated[b]),
                           int(result.episode_step[b]), red_names[b], blue_names[b])
        finished += len(ended)
        restart = ended[:max(0, episodes - started)]
        episode_of[restart] = np.arange(started, started + len(restart))
        started += len(restart)
        restart = np.concatenate([replay, restart])
        if len(restart):
            core.reset(restart, seed=[seed + int(episode_of[b]) for b in restart])
            red_names[restart] = core.red_script.names_of(restart)
            blue_names[restart] = core.opponent.names_of(restart)


class WinRates:
    """Win and draw rates from ``red_wins``, ``blue_wins``, ``draws`` and ``episodes`` (shared by results of duels)."""

    red_wins: int
    blue_wins: int
    draws: int
    episodes: int

    @property
    def red_win_rate(self) -> float:
        return self.red_wins / max(1, self.episodes)

    @property
    def blue_win_rate(self) -> float:
        return self.blue_wins / max(1, self.episodes)

    @property
    def draw_rate(self) -> float:
        return self.draws / max(1, self.episodes)


@dataclass
class DuelResult(WinRates):
    """Outcome counts of a duel, from red's point of view for ``red_wins`` and blue's for ``blue_wins``."""

    map: str
    red: str
    blue: str
    episodes: int
    seed: int
    batch_size: int
    red_wins: int = 0
    blue_wins: int = 0
    draws: int = 0
    timeouts: int = 0  # draws at the episode limit
    mean_steps: float = 0.0
    by_script: dict[str, dict[str, int]] = field(default_factory=dict)  # "red_name vs blue_name" -> counts

    def to_dict(self) -> dict:
        out = asdict(self)
        out.update(red_win_rate=self.red_win_rate, blue_win_rate=self.blue_win_rate, draw_rate=self.draw_rate)
        return out

    def summary(self) -> str:
        return (f"{self.map}: red {self.red} vs blue {self.blue}, {self.episodes} episodes: red wins "
                f"{self.red_win_rate:.1%}, blue wins {self.blue_win_rate:.1%}, draws {self.draw_rate:.1%} "
                f"({self.timeouts} at the limit), mean length {self.mean_steps:.1f} steps")


def _script(spec: MapSpec, entry: Any, probs: Sequence[float] | None, guard: bool | None,
            isolation: str) -> Script:
    """One side's script as the caller asked for it to run (None / "idle": :class:`Idle`)."""
    if entry is None or (isinstance(entry, str) and entry == IDLE):
        if probs is not None:
            raise ValueError(f"probabilities {probs!r} given for an idle side")
        return Idle()
    return make_opponent(spec, entry, probs, guard=guard, isolation=isolation)


def _core(spec: MapSpec, red: Script, blue: Script, batch: int, backend: Any, step_mul: int, seed: int,
          episode_limit: int | None = None) -> TwoPlayerCore:
    # The scripts come wrapped as the caller asked (guard / isolation): the core takes them as they are.
    return TwoPlayerCore(spec, batch, opponent=blue, red_script=red, backend=backend, step_mul=step_mul, seed=seed,
                         opponent_isolation="none", encode_state=False, episode_limit=episode_limit)


def _check_seed(seed: Any) -> int:
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise ValueError(f"seed must be a non-negative int, got {seed!r}")
    return int(seed)


def run_duel(map_name: MapSpec | str, red: Any, blue: Any, episodes: int = 10, seed: int = 0,
             batch_size: int | None = None, *, red_probs: Sequence[float] | None = None,
             blue_probs: Sequence[float] | None = None, step_mul: int = 8, progress: bool = False,
             guard: bool | None = None, isolation: str | None = None) -> DuelResult:
    """Play ``episodes`` episodes of ``red`` against ``blue`` (anything :func:`make_opponent` accepts, or None /
    ``"idle"`` for a side without orders), running up to ``batch_size`` battles at once (default: all episodes, at
    most 64). Episode ``e`` is a battle seeded ``seed + e`` (module docstring).

    How user scripts run is :func:`make_opponent`'s choice, made once here for both sides (the core then takes the
    scripts as they are): ``isolation`` None (default, auto: scripts loaded from a file or module in a child process,
    Script objects under the guard, built-in scripts bare), ``"guard"``, ``"process"`` or ``"none"``; ``guard=False``
    runs everything bare (as ``isolation="none"``), ``guard=True`` also checks the built-in scripts' commands."""
    if not isinstance(episodes, (int, np.integer)) or isinstance(episodes, bool) or episodes < 1:
        raise ValueError(f"episodes must be a positive int, got {episodes!r}")
    seed = _check_seed(seed)
    if batch_size is None:
        batch_size = min(int(episodes), MAX_BATCH)
    if not isinstance(batch_size, (int, np.integer)) or isinstance(batch_size, bool) or batch_size < 1:
        raise ValueError(f"batch_size must be a positive int, got {batch_size!r}")
    spec = load_map(map_name)
    red_script = _script(spec, red, red_probs, guard, isolation)
    blue_script = _script(spec, blue, blue_probs, guard, isolation)
    batch = min(int(batch_size), int(episodes))
    result = DuelResult(spec.name, red_script.name, blue_script.name, int(episodes), seed, batch)
    keys = {RED_WON: "red_wins", BLUE_WON: "blue_wins", DRAW: "draws"}
    total_steps = 0

    from tqdm import tqdm

    core = _core(spec, red_script, blue_script, batch, "native", step_mul, seed)
    try:
        with tqdm(total=int(episodes), disable=not progress, unit="ep", desc=f"duel {spec.name}") as bar:
            for done in play(core, seed, int(episodes)):
                key = keys[done.outcome]
                setattr(result, key, getattr(result, key) + 1)
                result.timeouts += done.truncated
                counts = result.by_script.setdefault(f"{done.red} vs {done.blue}",
                                                     {"games": 0, "red_wins": 0, "blue_wins": 0, "draws": 0})
                counts["games"] += 1
                counts[key] += 1
                total_steps += done.steps
                bar.update(1)
    finally:
        core.close()
    result.mean_steps = total_steps / int(episodes)
    return result


def record_engine_episode(source: Any, red: Any = None, blue: Any = "base", *, battle: int = 0, seed: int = 0,
                          max_steps: int | None = None, recorder: EpisodeRecorder | None = None) -> EpisodeRecorder:
    """Play one episode of two scripts against each other and record battle ``battle``.

    ``source`` is a :class:`~smac_hard_gym.backend.Backend` (all its battles are reset and stepped together; it is
    left open) or a map (a native backend of one battle is built). ``red`` and ``blue`` are
    :class:`~smac_hard_gym.opponents.Script` objects or anything :func:`make_opponent` accepts; None leaves a side
    idle (``red=None``: the learner's passive units). Battle ``b`` is seeded ``seed + b`` (the duel's rule: battle
    0 recorded with seed ``s`` is episode 0 of ``run_duel(..., seed=s)``). The episode ends by the core's outcome
    rule, or after ``max_steps`` (default and at most: the map's episode limit). The recorder's metadata gets the
    scripts' names, the seed, the battle and the ``winner`` (red, blue, draw, or none at the limit).
    """
    seed = _check_seed(seed)
    own = not isinstance(source, Backend)  # a backend built here is closed here
    if own:
        spec, backend, batch = load_map(source), "native", 1
    else:
        spec, backend, batch = source.spec, source, source.batch_size
    if not isinstance(battle, (int, np.integer)) or isinstance(battle, bool) or not 0 <= battle < batch:
        raise ValueError(f"battle must be an int in 0..{batch - 1}, got {battle!r}")
    if max_steps is not None and (not isinstance(max_steps, (int, np.integer)) or int(max_steps) < 1):
        raise ValueError(f"max_steps must be >= 1, got {max_steps!r}")
    red_script = _script(spec, red, None, None, "guard")
    blue_script = _script(spec, blue, None, None, "guard")
    core = _core(spec, red_script, blue_script, batch, backend, 8, seed, max_steps)
    try:
        red_name, blue_name = red_script.name_of(int(battle)), blue_script.name_of(int(battle))
        rec = recorder if recorder is not None else EpisodeRecorder(spec, step_mul=core.backend.step_mul)
        rec.metadata.update({"red": red_name, "blue": blue_name, "seed": seed, "battle": int(battle)})
        rec.capture(core.state, battle, step=0, opponent=blue_name)

        def capture(result: Any) -> None:
            if result.stepped[battle]:
                rec.capture(core.state, battle, step=int(result.episode_step[battle]), actions=core.commands,
                            opponent=blue_name)

        winners = {RED_WON: "red", BLUE_WON: "blue", DRAW: "draw"}
        for done in play(core, seed, batch, on_step=capture):
            if done.battle == battle:
                rec.metadata["winner"] = "none" if done.truncated else winners[done.outcome]
                break
    finally:
        if own:
            core.close()
    return rec
