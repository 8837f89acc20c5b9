"""Weighted mixtures of scripts: one script is drawn per battle per episode from that battle's seeded generator."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from smac_hard_gym.engine.state import Commands
from smac_hard_gym.opponents.api import Script, SideView

__all__ = ["Mixture", "check_probs"]

PROB_TOLERANCE = 1e-6


def check_probs(probs: Sequence[float] | np.ndarray | None, names: Sequence[str], where: str = "") -> np.ndarray:
    """Validated probabilities for ``names`` (equal when ``probs`` is None): one finite, non-negative number per
    script, summing to 1. Raises ValueError naming the scripts and the problem."""
    n = len(names)
    if n == 0:
        raise ValueError(f"a mixture needs at least one script{where}")
    if probs is None:
        return np.full(n, 1.0 / n)
    if isinstance(probs, (str, bytes)) or not hasattr(probs, "__len__"):
        raise ValueError(f"opponent_probs must be a list of {n} numbers (one per script {list(names)}){where}, "
                         f"got {probs!r}")
    if len(probs) != n:
        raise ValueError(f"opponent_probs has {len(probs)} entries but there are {n} scripts {list(names)}{where}; "
                         "give one probability per script")
    values = []
    for name, p in zip(names, probs, strict=True):
        if isinstance(p, bool) or not isinstance(p, (int, float, np.integer, np.floating)):
            raise ValueError(f"opponent_probs entry for {name!r} must be a number, got {p!r}{where}")
        if not math.isfinite(float(p)) or p < 0:
            raise ValueError(f"opponent_probs entry for {name!r} must be finite and >= 0, got {p!r}{where}")
        values.append(float(p))
    total = sum(values)
    if abs(total - 1.0) > PROB_TOLERANCE:
        raise ValueError(f"opponent_probs must sum to 1, got {total:g} for scripts {list(names)}{where}")
    return np.asarray(values) / total


class Mixture(Script):
    """A list of scripts with probabilities (equal by default); each battle plays one of them per episode.

    ``reset`` draws the script of every restarting battle from ``rngs[b]`` (one uniform draw, so a seed fixes the
    sequence) and resets each sub-script on the battles it got; ``act`` calls each sub-script once per step on its
    own battles (``active`` masked to them), so a mixture costs no more than its parts. ``name_of(b)`` names the
    script battle b plays; ``choice`` holds the drawn indices.
    """

    def __init__(self, scripts: Sequence[Script], probs: Sequence[float] | np.ndarray | None = None,
                 name: str = "mixture") -> None:
        scripts = list(scripts)
        names = [s.name for s in scripts]
        for s in scripts:
            if not isinstance(s, Script):
                raise TypeError(f"a mixture holds Script objects, got {s!r}")
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"scripts in a mixture need distinct names (set each script's ``name``); repeated: "
                             f"{duplicates}")
        self.scripts = scripts
        self.probs = check_probs(probs, names)
        self._cumulative = np.cumsum(self.probs)
        self.name = name
        self.description = "mixture of " + ", ".join(f"{n} ({p:.2f})" for n, p in zip(names, self.probs, strict=True))
        self.choice = np.zeros(0, dtype=np.int64)

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.scripts]

    def draw(self, rng: np.random.Generator) -> int:
        """The index of the script a battle plays, from one uniform draw of its generator."""
        k = int(np.searchsorted(self._cumulative, rng.random(), side="right"))
        return min(k, len(self.scripts) - 1)

    def reset(self, view: SideView, battles: np.ndarray, rngs: list[np.random.Generator]) -> None:
        if self.choice.shape[0] != view.batch_size:
            self.choice = np.full(view.batch_size, -1, dtype=np.int64)
        battles = np.asarray(battles, dtype=np.int64)
        # One uniform per battle from its own generator, then one vectorised lookup.
        u = np.fromiter((rngs[b].random() for b in battles), dtype=np.float64, count=battles.size)
        picked = np.searchsorted(self._cumulative, u, side="right")
        self.choice[battles] = np.minimum(picked, len(self.scripts) - 1)
        for k, script in enumerate(self.scripts):
            mine = battles[self.choice[battles] == k]
            if mine.size:
                script.reset(view, mine, rngs)

    def act(self, view: SideView, commands: Commands, active: np.ndarray) -> None:
        if active.shape[0] == 1 and self.choice.shape[0] == 1:  # one battle (a single env): no masks to build
            k = int(self.choice[0])
            if k >= 0 and active[0]:
                self.scripts[k].act(view, commands, active.astype(bool))
            return
        for k, script in enumerate(self.scripts):
            mine = active & (self.choice == k)
            if mine.any():
                script.act(view, commands, mine)

    def names_of(self, battles: np.ndarray) -> list[str]:
        battles = np.asarray(battles, dtype=np.int64)
        if self.choice.shape[0] == 0:  # before the first reset
            return [self.name] * len(battles)
        choice = self.choice[battles]
        names = np.full(len(battles), self.name, dtype=object)
        for k, script in enumerate(self.scripts):
            mine = choice == k
            if mine.any():
                names[mine] = script.names_of(battles[mine])
        return names.tolist()

    def name_of(self, battle: int) -> str:
        if battle >= self.choice.shape[0] or self.choice[battle] < 0:
            return self.name
        return self.scripts[self.choice[battle]].name_of(battle)
