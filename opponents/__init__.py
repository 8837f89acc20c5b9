"""Opponent scripts: the script API (:mod:`.api`), SMAC's default ``base`` and the built-in library."""

from __future__ import annotations

from smac_hard_gym.maps import MapSpec
from smac_hard_gym.opponents.api import Script, SideView
from smac_hard_gym.opponents.base import BaseScript

__all__ = ["Script", "SideView", "BaseScript", "make_opponent"]

_BUILTIN = {"base": BaseScript}


def make_opponent(spec: MapSpec, opponent: str | Script = "base") -> Script:
    """An opponent for ``spec``: a script object, or the name of a built-in script."""
    if isinstance(opponent, Script):
        return opponent
    if opponent not in _BUILTIN:
        raise ValueError(f"unknown opponent {opponent!r} for map {spec.name!r}; allowed: {sorted(_BUILTIN)}")
    return _BUILTIN[opponent]()
