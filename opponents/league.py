"""A league for self-play: a mixture that grows with snapshots of the learner and re-weights its members by how
the learner fares against each.

>>> from smac_hard_gym.opponents import make_opponent
>>> from smac_hard_gym.opponents.league import League
>>> league = League(make_opponent("3m", "default").scripts, weighting="prioritized")
>>> league.names
['line_front', 'base']

Training (``smac-hard-gym train --league``, :mod:`smac_hard_gym.training.league`) adds a frozen copy of the learner
every N steps (:meth:`League.add`, a :class:`~smac_hard_gym.opponents.policy.PolicyScript`) and feeds back the
learner's win rate against each member (:meth:`League.update`). Each battle draws its member per episode from its
own seeded generator, as a mixture does, with weights:

- ``"uniform"``: every member equally;
- ``"prioritized"``: prioritized fictitious self-play, weight ``(1 - win_rate) ** power`` (members the learner
  beats are met less; members not met yet count as unbeaten), floored so no member drops out entirely.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from smac_hard_gym.opponents.api import Script
from smac_hard_gym.opponents.mixture import Mixture

__all__ = ["League", "WEIGHTINGS"]

WEIGHTINGS = ("uniform", "prioritized")
_FLOOR = 0.05  # a member's least weight relative to the heaviest: beaten members still come round


class League(Mixture):
    """Scripts and learner snapshots as one opponent whose members and weights change between episodes."""

    def __init__(self, scripts: Sequence[Script], weighting: str = "uniform", power: float = 2.0,
                 name: str = "league") -> None:
        if weighting not in WEIGHTINGS:
            raise ValueError(f"weighting must be one of {WEIGHTINGS}, got {weighting!r}")
        if isinstance(power, bool) or not isinstance(power, (int, float)) or not power > 0:
            raise ValueError(f"power must be a positive number, got {power!r}")
        super().__init__(scripts, None, name=name)
        self.weighting = weighting
        self.power = float(power)
        self.win_rates: dict[str, float] = {}
        self._reweigh()

    def add(self, script: Script) -> None:
        """A new member (its name must be new); it plays from the next episodes on."""
        if script.name in self.names:
            raise ValueError(f"the league already has a member named {script.name!r}")
        self.scripts.append(script)
        self._reweigh()

    def update(self, win_rates: Mapping[str, float]) -> None:
        """The learner's win rate against members, by name (others keep theirs); re-weighs the members."""
        for name, rate in win_rates.items():
            if name in self.names:
                self.win_rates[name] = float(rate)
        self._reweigh()

    def _reweigh(self) -> None:
        n = len(self.scripts)
        if self.weighting == "uniform":
            weights = np.ones(n)
        else:
            weights = np.array([(1.0 - self.win_rates.get(s.name, 0.0)) ** self.power for s in self.scripts])
            weights = np.maximum(weights, _FLOOR * max(weights.max(), 1e-12))
        self.probs = weights / weights.sum()
        self._cumulative = np.cumsum(self.probs)
        self.description = "league of " + ", ".join(f"{s.name} ({p:.2f})"
                                                    for s, p in zip(self.scripts, self.probs, strict=True))
