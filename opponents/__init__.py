"""Opponent scripts: the script API, SMAC's default ``base``, the built-in library per map, mixtures, user scripts.

>>> from smac_hard_gym.opponents import make_opponent, scripts_for_map
>>> sorted(scripts_for_map("3m"))[:3]
['base', 'chase', 'focus_fire']
>>> make_opponent("3m", "default").names
['line_front', 'base']

``make_opponent(spec, opponent, opponent_probs)`` accepts:

- ``"default"``: the map's SMAC-HARD pool as a mixture; ``"blackbox"``: the pool without ``base``;
- a built-in script name (``scripts_for_map(map)`` lists them, ``smac-hard-gym scripts --map M`` prints them);
- a user script reference: ``path/to/file.py:ClassName``, ``path/to/file.py`` (one Script subclass in it) or
  ``package.module:Name``;
- a trained policy: a saved MaskablePPO model (``path/to/model.zip``), an SB3 model, a torch module or a function
  of observations and masks (:mod:`smac_hard_gym.opponents.policy`);
- a :class:`Script` object, or a list of any of these (a mixture).

``opponent_probs`` gives one probability per script of the mixture (equal by default). User scripts run inside a
guard (:class:`GuardedScript`) that turns exceptions, overlong calls, ``sys.exit`` and invalid commands into a
:class:`ScriptError` naming the script, the map and the cause, and hands them read-only copies of the state.
``isolation="process"`` runs them in a child process instead (:class:`ProcessIsolatedScript`), which also stops
hangs inside C calls, crashes and ``os._exit`` (see ``make_opponent``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from smac_hard_gym.maps import MapSpec, load_map
from smac_hard_gym.opponents.api import Script, ScriptError, SideView
from smac_hard_gym.opponents.base import BaseScript, SmacScript
from smac_hard_gym.opponents.guard import DEFAULT_TIME_LIMIT, GuardedScript
from smac_hard_gym.opponents.helpers import BatchScript, Frame, Memory, Orders
from smac_hard_gym.opponents.league import League
from smac_hard_gym.opponents.library import (
    MIXTURE_NAMES,
    POOLS,
    SCRIPTS,
    ScriptInfo,
    is_builtin,
    pool_for_map,
    scripts_for_map,
)
from smac_hard_gym.opponents.loader import is_reference, load_script
from smac_hard_gym.opponents.mixture import Mixture, check_probs
from smac_hard_gym.opponents.per_battle import BattleView, PerBattleScript
from smac_hard_gym.opponents.policy import PolicyScript, is_policy_file
from smac_hard_gym.opponents.sandbox import ProcessIsolatedScript

__all__ = [
    "Script", "SideView", "ScriptError", "BaseScript", "SmacScript", "BatchScript", "Frame", "Memory", "Orders",
    "PerBattleScript", "BattleView", "Mixture", "GuardedScript", "ProcessIsolatedScript", "ScriptInfo", "SCRIPTS",
    "POOLS", "ISOLATION_MODES", "make_opponent", "opponent_from_text", "make_script", "scripts_for_map",
    "pool_for_map", "load_script", "PolicyScript", "League",
]

OpponentSpec = str | Script | Sequence[str | Script]

ISOLATION_MODES = ("none", "guard", "process")


def opponent_from_text(text: str) -> str | list[str]:
    """A command line's opponent: one name or reference, or names joined by commas (a mixture, as a list)."""
    return text.split(",") if "," in text else text


def check_isolation(isolation: str, guard: bool | None = None) -> str:
    """``isolation`` if it is one of ``ISOLATION_MODES`` and agrees with ``guard``; raises ValueError otherwise."""
    if not isinstance(isolation, str) or isolation not in ISOLATION_MODES:
        raise ValueError(f"isolation must be one of {ISOLATION_MODES}, got {isolation!r}")
    if guard is False and isolation == "process":
        raise ValueError("guard=False cannot be combined with isolation='process' (sandboxed scripts are always "
                         "checked); drop one of them")
    return isolation


def _from_outside(entry: str | Script) -> bool:
    """A script from outside the library: a Script object not built in, or a file or module reference."""
    if isinstance(entry, Script):
        return not is_builtin(entry)
    return isinstance(entry, str) and entry not in SCRIPTS and entry not in MIXTURE_NAMES and is_reference(entry)


def make_script(spec: MapSpec | str, entry: str | Script, guard: bool | None = None,
                time_limit: float | None = DEFAULT_TIME_LIMIT, isolation: str = "guard") -> Script:
    """One script for map ``spec``: a built-in name, a user script reference or a Script object.

    ``isolation`` says how scripts that are not built-in (user files, user objects) run: ``"guard"`` in-process
    under :class:`GuardedScript`, ``"process"`` in a child process (:class:`ProcessIsolatedScript`, a reference is
    then imported in the child only) behind the guard's command checks, ``"none"`` bare. ``guard`` True also
    guards built-in scripts; False runs every script bare.
    """
    spec = load_map(spec)
    isolation = check_isolation(isolation, guard)
    if guard is False:
        isolation = "none"
    if isolation == "process" and _from_outside(entry):
        if isinstance(entry, GuardedScript):
            entry = entry.script
        return GuardedScript(ProcessIsolatedScript(entry, time_limit=time_limit), time_limit=None)
    if isinstance(entry, Script):
        script = entry
    elif isinstance(entry, str):
        if entry in MIXTURE_NAMES:
            raise ValueError(f"{entry!r} names a whole pool; pass it alone as opponent={entry!r}, not in a list")
        if entry in SCRIPTS:
            info = SCRIPTS[entry]
            if not info.plays(spec.name):
                raise ValueError(f"script {entry!r} does not play map {spec.name!r} (it plays {list(info.maps)}); "
                                 f"scripts for {spec.name}: {sorted(scripts_for_map(spec))}")
            script = info.factory()
        elif is_policy_file(entry):
            script = PolicyScript.load(entry)
        elif is_reference(entry):
            script = load_script(entry)
        else:
            raise ValueError(f"unknown opponent {entry!r} for map {spec.name!r}; allowed: "
                             f"{', '.join(MIXTURE_NAMES)}, {', '.join(sorted(scripts_for_map(spec)))}, or a user "
                             "script 'path/to/file.py[:ClassName]' / 'module:Name'")
    elif callable(entry) or hasattr(entry, "predict"):
        name = getattr(entry, "name", None) or getattr(entry, "__name__", None) or type(entry).__name__
        script = PolicyScript(entry, name=str(name))
    else:
        raise TypeError(f"an opponent is a script name, a script reference, a saved model (.zip), a Script or a "
                        f"policy (a function of observations and masks, an SB3 model, a torch module), got {entry!r}")
    # A PolicyScript is library code (it writes commands by the SMAC decoding); the user's policy inside it only
    # ever sees fresh feature arrays, never the state, so it runs unguarded unless asked. A League holds scripts
    # made here and snapshots of the learner.
    trusted = is_builtin(script) or type(script) in (PolicyScript, League)
    wrap = (not trusted and isolation != "none") if guard is None else guard
    if wrap and not isinstance(script, GuardedScript):
        script = GuardedScript(script, time_limit=time_limit)
    return script


def make_opponent(spec: MapSpec | str, opponent: OpponentSpec = "base",
                  opponent_probs: Sequence[float] | np.ndarray | None = None, *, guard: bool | None = None,
                  time_limit: float | None = DEFAULT_TIME_LIMIT, isolation: str = "guard") -> Script:
    """The opponent for map ``spec`` (see the module docstring for what ``opponent`` may be).

    A single script comes back as itself; ``"default"``, ``"blackbox"`` and lists come back as a :class:`Mixture`
    named after the pool (or ``"mixture"``) whose ``name_of(b)`` names the script battle b plays. Raises
    ValueError for unknown names, scripts that do not play the map, and invalid ``opponent_probs`` (one per script,
    finite, non-negative, summing to 1).

    How user scripts (files, references, Script objects that are not built-in) run is this function's
    ``isolation``, the single entry point for it (built-in scripts are trusted and always run in-process, zero
    copy):

    - ``"guard"`` (default): in-process under :class:`GuardedScript`: read-only copies of the state, checked
      commands, ``time_limit`` seconds per call on any thread. A hang inside one C call or a crash of the
      interpreter is beyond it.
    - ``"process"``: in a child process (:class:`ProcessIsolatedScript`) killed at ``time_limit``; hangs in C
      calls, segfaults and ``os._exit`` become a :class:`ScriptError` and the next call starts a new child. Costs
      a process start and a pickled round trip per call.
    - ``"none"``: bare, for code you trust (same as ``guard=False``).

    ``guard=True`` additionally guards built-in scripts; ``guard=False`` runs everything bare.
    """
    spec = load_map(spec)
    check_isolation(isolation, guard)
    where = f" (map {spec.name!r})"
    if isinstance(opponent, str) and opponent in MIXTURE_NAMES:
        names = pool_for_map(spec, opponent)
        if not names:
            raise ValueError(f"map {spec.name!r} has an empty {opponent!r} pool")
        probs = check_probs(opponent_probs, names, where)
        return Mixture([make_script(spec, n, guard, time_limit, isolation) for n in names], probs, name=opponent)
    if isinstance(opponent, (str, Script)) or callable(opponent) or hasattr(opponent, "predict"):
        entries: list[str | Script] = [opponent]
    elif isinstance(opponent, Sequence) and not isinstance(opponent, (bytes, bytearray)):
        entries = list(opponent)
        if not entries:
            raise ValueError(f"opponent list is empty{where}; give at least one script")
    else:
        raise TypeError(f"opponent must be a name, a script reference, a Script or a list of them{where}, "
                        f"got {opponent!r}")
    scripts = [make_script(spec, e, guard, time_limit, isolation) for e in entries]
    probs = check_probs(opponent_probs, [s.name for s in scripts], where)
    if len(scripts) == 1:
        return scripts[0]
    return Mixture(scripts, probs)
