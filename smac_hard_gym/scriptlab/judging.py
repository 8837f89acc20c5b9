"""Judging by duels: seeded episodes of one script against another on the two-player core, with the numbers the
critic reads (win rates, health left, survivors, time-outs, which unit type died first).

:func:`play_pairing` runs :func:`smac_hard_gym.envs.duel.play` (the duel runner's loop: episode ``e`` is a battle
seeded ``seed + e``) and reads the final state of every finished battle. A lab script is a live
:class:`~smac_hard_gym.opponents.ProcessIsolatedScript` passed through ``make_opponent(..., isolation="process")``
(command checks included); library names are built by ``make_opponent``; ``solution:NAME`` is a known-solution
controller (trusted project code, red side only).
"""

from __future__ import annotations

import hashlib
from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from smac_hard_gym.engine.units import STATS, S
from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.envs.duel import WinRates, play
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.opponents import ProcessIsolatedScript, Script, ScriptError, make_opponent
from smac_hard_gym.smac.features import BLUE_WON, RED_WON

__all__ = ["LIBRARY_PARTNER", "SOLUTION_PREFIX", "PairingResult", "play_pairing", "library_opponents",
           "format_table", "side_score", "error_result", "code_key"]

LIBRARY_PARTNER = "nearest"  # the red script a blue script's smoke test plays against
SOLUTION_PREFIX = "solution:"
MAX_BATCH = 64


@dataclass
class PairingResult(WinRates):
    """One pairing's outcome over ``episodes`` seeded episodes (rates from each side's point of view)."""

    red: str
    blue: str
    episodes: int = 0
    red_wins: int = 0
    blue_wins: int = 0
    draws: int = 0
    timeouts: int = 0
    mean_steps: float = 0.0
    red_health_left: float = 0.0  # mean health + shield left at the end, as a share of the side's total
    blue_health_left: float = 0.0
    red_survivors: float = 0.0  # mean units alive at the end
    blue_survivors: float = 0.0
    red_first_death: str = ""  # the unit type that most often died first on each side
    blue_first_death: str = ""
    error: str = ""  # a ScriptError that ended the pairing (its counts are then empty)
    lab_sides: tuple[str, ...] = field(default=())  # which sides a lab script played

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["lab_sides"] = list(self.lab_sides)
        out.update(red_win_rate=round(self.red_win_rate, 4), blue_win_rate=round(self.blue_win_rate, 4))
        return out


def _build(spec: MapSpec, entry: Any) -> Script:
    if isinstance(entry, ProcessIsolatedScript):
        return make_opponent(spec, entry, isolation="process")  # the guard's command checks around the child
    if isinstance(entry, str) and entry.startswith(SOLUTION_PREFIX):
        from smac_hard_gym.opponents.known_solutions import make_controller

        return make_opponent(spec, make_controller(entry[len(SOLUTION_PREFIX):]), guard=False)
    if isinstance(entry, str):
        return make_opponent(spec, entry)
    raise TypeError(f"a pairing entry is a library name, 'solution:NAME' or a ProcessIsolatedScript, got {entry!r}")


def _label(entry: Any, label: str | None) -> str:
    if label:
        return label
    return entry.name if isinstance(entry, ProcessIsolatedScript) else str(entry)


class _Tally:
    """Per-episode end-of-battle numbers, gathered from each step's state before the finished battles restart."""

    def __init__(self, core: TwoPlayerCore) -> None:
        spec = core.spec
        state = core.state
        self.core = core
        self.red = slice(0, spec.n_red)
        self.blue = slice(spec.n_red, spec.n_red + spec.n_blue)
        utype = state.utype[0]
        self.max_hp = STATS[utype, S["health"]] + STATS[utype, S["shield"]]
        names = [u.removesuffix("_RL") for u in (*spec.red_unit_names, *spec.blue_unit_names)]
        self.names = np.array(names, dtype=object)
        self.prev = state.alive.copy()
        b = core.batch_size
        self.first = {"red": [""] * b, "blue": [""] * b}
        self.ended: dict[int, tuple[float, float, int, int, str, str]] = {}

    def on_step(self, result: Any) -> None:
        alive = self.core.state.alive
        fresh = (result.episode_step == 1)[:, None]  # first step of an episode: every unit was alive before it
        died = np.where(fresh, True, self.prev) & ~alive & result.stepped[:, None]
        for b in np.flatnonzero(died.any(axis=1)):
            for side, sl in (("red", self.red), ("blue", self.blue)):
                slots = np.flatnonzero(died[b, sl])
                if slots.size and not self.first[side][b]:
                    self.first[side][b] = self.names[sl][slots[0]]
        self.prev = alive.copy()
        for b in np.flatnonzero(result.stepped & (result.terminated | result.truncated)):
            st = self.core.state
            hp = np.where(st.alive[b], st.health[b] + st.shield[b], 0.0)
            red_left = float(hp[self.red].sum() / max(1e-9, self.max_hp[self.red].sum()))
            blue_left = float(hp[self.blue].sum() / max(1e-9, self.max_hp[self.blue].sum()))
            self.ended[int(b)] = (red_left, blue_left, int(st.alive[b, self.red].sum()),
                                  int(st.alive[b, self.blue].sum()), self.first["red"][b], self.first["blue"][b])
            self.first["red"][b] = self.first["blue"][b] = ""


def play_pairing(spec: MapSpec, red: Any, blue: Any, episodes: int, seed: int = 0, *, max_steps: int | None = None,
                 labels: tuple[str | None, str | None] = (None, None)) -> PairingResult:
    """Play ``episodes`` seeded episodes of ``red`` against ``blue`` and tally them (see the module docstring).

    A ScriptError propagates (the caller decides whether it is a script's failure); ``max_steps`` shortens the
    episodes (a smoke test)."""
    red_script, blue_script = _build(spec, red), _build(spec, blue)
    out = PairingResult(_label(red, labels[0]), _label(blue, labels[1]), int(episodes))
    core = TwoPlayerCore(spec, min(int(episodes), MAX_BATCH), opponent=blue_script, red_script=red_script,
                         seed=seed, opponent_isolation="none", encode_state=False, episode_limit=max_steps)
    tally = _Tally(core)
    sums = np.zeros(4)
    firsts: dict[str, Counter] = {"red": Counter(), "blue": Counter()}
    steps = 0
    try:
        for done in play(core, seed, int(episodes), on_step=tally.on_step):
            out.red_wins += done.outcome == RED_WON
            out.blue_wins += done.outcome == BLUE_WON
            out.draws += done.outcome not in (RED_WON, BLUE_WON)
            out.timeouts += bool(done.truncated)
            steps += done.steps
            red_left, blue_left, red_alive, blue_alive, red_first, blue_first = tally.ended.pop(done.battle)
            sums += (red_left, blue_left, red_alive, blue_alive)
            for side, name in (("red", red_first), ("blue", blue_first)):
                if name:
                    firsts[side][name] += 1
    finally:
        core.close()
    n = max(1, int(episodes))
    out.mean_steps = steps / n
    out.red_health_left, out.blue_health_left, out.red_survivors, out.blue_survivors = (float(v) / n for v in sums)
    out.red_first_death = firsts["red"].most_common(1)[0][0] if firsts["red"] else ""
    out.blue_first_death = firsts["blue"].most_common(1)[0][0] if firsts["blue"] else ""
    return out


def library_opponents(spec: MapSpec, side: str, solutions: bool = True) -> list[str]:
    """What a lab script of ``side`` is judged against: the map's SMAC-HARD pool and ``smac``, and for a blue
    script the map's known-solution controllers (red-side controllers, ``solution:NAME``)."""
    from smac_hard_gym.opponents import pool_for_map

    names = list(dict.fromkeys([*pool_for_map(spec), "smac"]))
    if side == "blue" and solutions:
        from smac_hard_gym.opponents.known_solutions import CLAIMS

        names += [SOLUTION_PREFIX + c for c in dict.fromkeys(c.red for c in CLAIMS if c.map_name == spec.name)]
    return names


def error_result(red: str, blue: str, err: ScriptError, lab_sides: tuple[str, ...]) -> PairingResult:
    """The row of a pairing a script error ended."""
    return PairingResult(red, blue, error=err.cause, lab_sides=lab_sides)


def code_key(*parts: str) -> str:
    """A cache key for a pairing of scripts given by their code (same code, same seeds: same result)."""
    return hashlib.sha256("\x00".join(parts).encode()).hexdigest()


def format_table(rows: list[PairingResult]) -> str:
    """A compact markdown table of the pairings (what the critic and report.md show)."""
    head = ("| red | blue | games | red win | blue win | draws | time-outs | steps | red hp left | blue hp left | "
            "red alive | blue alive | red first dead | blue first dead |")
    lines = [head, "|" + "---|" * 14]
    for r in rows:
        if r.error:
            lines.append(f"| {r.red} | {r.blue} | ERROR: {r.error[:200]} |" + " |" * 11)
            continue
        lines.append(f"| {r.red} | {r.blue} | {r.episodes} | {r.red_win_rate:.0%} | {r.blue_win_rate:.0%} | "
                     f"{r.draws} | {r.timeouts} | {r.mean_steps:.0f} | {r.red_health_left:.0%} | "
                     f"{r.blue_health_left:.0%} | {r.red_survivors:.1f} | {r.blue_survivors:.1f} | "
                     f"{r.red_first_death or '-'} | {r.blue_first_death or '-'} |")
    return "\n".join(lines)


def side_score(rows: list[PairingResult], side: str) -> float | None:
    """A lab side's win rate over every game its script played this round (None: it played none)."""
    games = wins = 0
    for r in rows:
        if side in r.lab_sides and not r.error:
            games += r.episodes
            wins += r.red_wins if side == "red" else r.blue_wins
    return wins / games if games else None
