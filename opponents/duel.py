"""The duel runner: both sides driven by scripts on the embedded engine, to check that scripts are competent.

>>> from smac_hard_gym.opponents.duel import run_duel
>>> result = run_duel("3m", red="stop", blue="base", episodes=4, seed=0)
>>> result.blue_wins
4

A battle ends when one side has no fighting units left (medivacs do not count, as in SMAC), or at the map's episode
limit. Win = the other side is out; draw = both sides out in the same step, or the limit. Episode ``e`` seeds its
scripts' generators from ``(seed, e)``, so results do not depend on the batch size.

The red side's units are SMAC's passive ``*_RL`` units: they never act on their own (not even to shoot back) but
do acquire targets while attack-moving, so a red script must give explicit orders.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.engine.state import BLUE, RED, Commands
from smac_hard_gym.maps import MapSpec, load_map
from smac_hard_gym.opponents.api import Script, SideView
from smac_hard_gym.units import STATS, S

__all__ = ["DuelResult", "run_duel"]

MAX_BATCH = 64


@dataclass
class DuelResult:
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

    @property
    def red_win_rate(self) -> float:
        return self.red_wins / max(1, self.episodes)

    @property
    def blue_win_rate(self) -> float:
        return self.blue_wins / max(1, self.episodes)

    @property
    def draw_rate(self) -> float:
        return self.draws / max(1, self.episodes)

    def to_dict(self) -> dict:
        out = asdict(self)
        out.update(red_win_rate=self.red_win_rate, blue_win_rate=self.blue_win_rate, draw_rate=self.draw_rate)
        return out

    def summary(self) -> str:
        return (f"{self.map}: red {self.red} vs blue {self.blue}, {self.episodes} episodes: red wins "
                f"{self.red_win_rate:.1%}, blue wins {self.blue_win_rate:.1%}, draws {self.draw_rate:.1%} "
                f"({self.timeouts} at the limit), mean length {self.mean_steps:.1f} steps")


def _opponent(spec: MapSpec, script: str | Script | Sequence, probs: Sequence[float] | None,
              guard: bool | None) -> Script:
    from smac_hard_gym.opponents import make_opponent  # imported late: the package imports this module's siblings

    return make_opponent(spec, script, probs, guard=guard)


def run_duel(map_name: MapSpec | str, red: str | Script | Sequence, blue: str | Script | Sequence,
             episodes: int = 10, seed: int = 0, batch_size: int | None = None, *,
             red_probs: Sequence[float] | None = None, blue_probs: Sequence[float] | None = None,
             step_mul: int = 8, progress: bool = False, guard: bool | None = None) -> DuelResult:
    """Play ``episodes`` episodes of ``red`` against ``blue`` (anything :func:`make_opponent` accepts), running up
    to ``batch_size`` battles at once (default: all episodes, at most 64). ``guard=True`` checks built-in scripts'
    commands too (user scripts are always checked unless ``guard=False``)."""
    if not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"episodes must be a positive int, got {episodes!r}")
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative int, got {seed!r}")
    if batch_size is None:
        batch_size = min(int(episodes), MAX_BATCH)
    if not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
        raise ValueError(f"batch_size must be a positive int, got {batch_size!r}")
    spec = load_map(map_name)
    red_script = _opponent(spec, red, red_probs, guard)
    blue_script = _opponent(spec, blue, blue_probs, guard)
    batch = min(int(batch_size), int(episodes))
    engine = BattleEngine(spec, batch_size=batch, step_mul=step_mul)
    state = engine.state
    steps = np.zeros(batch, dtype=np.int64)
    views = {RED: SideView.of(state, spec, RED, steps), BLUE: SideView.of(state, spec, BLUE, steps)}
    scripts = {RED: red_script, BLUE: blue_script}
    commands = Commands.empty(batch, engine.n_units)
    armed = STATS[state.utype[0], S["damage"]] > 0  # medivacs do not keep a side in the fight
    red_slots, blue_slots = engine.red_slots, engine.blue_slots
    result = DuelResult(spec.name, red_script.name, blue_script.name, int(episodes), int(seed), batch)

    rngs: dict[int, list] = {RED: [None] * batch, BLUE: [None] * batch}
    active = np.zeros(batch, dtype=bool)
    next_episode = 0

    def start(battles: np.ndarray) -> None:
        nonlocal next_episode
        mask = np.zeros(batch, dtype=bool)
        mask[battles] = True
        engine_seeds = []
        for b in np.sort(battles):
            for side in (RED, BLUE):
                rngs[side][b] = np.random.default_rng([int(seed), next_episode, side])
            # The engine's weapon-delay randomness is seeded per episode too.
            engine_seeds.append(int(np.random.default_rng([int(seed), next_episode, 2]).integers(2**63)))
            next_episode += 1
        engine.reset(mask, seeds=np.array(engine_seeds, dtype=np.int64))
        steps[battles] = 0
        active[battles] = True
        for side in (RED, BLUE):
            scripts[side].reset(views[side], battles, rngs[side])

    from tqdm import tqdm

    total_steps = 0
    finished = 0
    start(np.arange(batch))
    with tqdm(total=int(episodes), disable=not progress, unit="ep", desc=f"duel {spec.name}") as bar:
        while finished < episodes:
            commands.clear()
            red_script.act(views[RED], commands, active)
            blue_script.act(views[BLUE], commands, active)
            engine.step(commands, active)
            steps[active] += 1
            fighting = state.alive & armed
            red_out = ~fighting[:, red_slots].any(axis=1)
            blue_out = ~fighting[:, blue_slots].any(axis=1)
            at_limit = steps >= spec.episode_limit
            done = active & (red_out | blue_out | at_limit)
            if not done.any():
                continue
            ended = np.flatnonzero(done)
            for b in ended:
                outcome = ("red_wins" if blue_out[b] and not red_out[b]
                           else "blue_wins" if red_out[b] and not blue_out[b] else "draws")
                setattr(result, outcome, getattr(result, outcome) + 1)
                if outcome == "draws" and not (red_out[b] and blue_out[b]):
                    result.timeouts += 1
                key = f"{red_script.name_of(int(b))} vs {blue_script.name_of(int(b))}"
                counts = result.by_script.setdefault(key, {"games": 0, "red_wins": 0, "blue_wins": 0, "draws": 0})
                counts["games"] += 1
                counts[outcome] += 1
                total_steps += int(steps[b])
                finished += 1
                bar.update(1)
            active[ended] = False
            remaining = int(episodes) - next_episode
            if remaining > 0:
                start(ended[:remaining])
    result.mean_steps = total_steps / max(1, finished)
    return result
