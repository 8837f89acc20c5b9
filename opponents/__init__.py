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

``opponent_probs`` gives one probability per script of the mixture (equal by default). By default (``isolation=
None``, "auto") a script loaded from a file or module reference runs in a child process
(:class:`ProcessIsolatedScript`: killed at its time limit, crashes and ``os._exit`` cannot reach the host), and a
Script object you built runs in-process inside a guard (:class:`GuardedScript`, a bug catcher for your own code,
not a security boundary). Both turn exceptions, overlong calls, ``sys.exit`` and invalid commands into a
:class:`ScriptError` naming the script, the map and the cause (see ``make_opponent`` and docs/script_isolation.md).
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
from smac_hard_gym.opponents.sandbox import SUPPORTED as SANDBOX_SUPPORTED
from smac_hard_gym.opponents.sandbox import ProcessIsolatedScript

__all__ = [
    "Script", "SideView", "ScriptError", "BaseScript", "SmacScript", "BatchScript", "Frame", "Memory", "Orders",
    "PerBattleScript", "BattleView", "Mixture", "GuardedScript", "ProcessIsolatedScript", "ScriptInfo", "SCRIPTS",
    "POOLS", "ISOLATION_MODES", "AUTO_ISOLATION", "make_opponent", "opponent_from_text", "make_script",
    "scripts_for_map", "pool_for_map", "load_script", "PolicyScript", "League",
]

OpponentSpec = str | Script | Sequence[str | Script]

ISOLATION_MODES = ("none", "guard", "process")
AUTO_ISOLATION = None  # isolation=None: "process" for scripts loaded by reference where supported, else "guard"


def opponent_from_text(text: str) -> str | list[str]:
    """A command line's opponent: one name or reference, or names joined by commas (a mixture, as a list)."""
    return text.split(",") if "," in text else text


def check_isolation(isolation: str | None, guard: bool | None = None) -> str | None:
    """``isolation`` if it is one of ``ISOLATION_MODES`` or None (auto) and agrees with ``guard``; raises
    ValueError otherwise."""
    if isolation is not AUTO_ISOLATION and (not isinstance(isolation, str) or isolation not in ISOLATION_MODES):
        raise ValueError(f"isolation must be one of {ISOLATION_MODES}, got {isolation!r} (or None: auto)")
    if guard is False and isolation == "process":
        raise ValueError("guard=False cannot be combined with isolation='process' (sandboxed scripts are always "
                         "checked); drop one of them")
    return isolation


def _from_outside(entry: str | Script) -> bool:
    """A script from outside the library: a Script object not built in, or a file or module reference."""
    if isinstance(entry, Script):
        return not is_builtin(entry)
    return isinstance(entry, str) and entry not in SCRIPTS and entry not in MIXTURE_NAMES and is_reference(entry)


def _loaded_by_reference(entry: str | Script) -> bool:
    """A user script the host would import from a file or module reference (not a built-in name, not a saved
    policy)."""
    return isinstance(entry, str) and _from_outside(entry) and not is_policy_file(entry)


def _sandboxed(entry: str | Script) -> bool:
    """A ProcessIsolatedScript, bare or in a guard: it already runs in a child process."""
    return isinstance(getattr(entry, "script", entry), ProcessIsolatedScript)


def resolve_isolation(entry: str | Script, isolation: str | None) -> str:
    """The isolation ``entry`` gets: ``isolation`` when given; with None (auto), ``"process"`` for a script loaded
    from a file or module reference where the sandbox is supported (POSIX), ``"guard"`` for everything else (a
    Script object you built already runs your code in the host)."""
    if isolation is not AUTO_ISOLATION:
        return isolation
    return "process" if SANDBOX_SUPPORTED and _loaded_by_reference(entry) else "guard"


def make_script(spec: MapSpec | str, entry: str | Script, guard: bool | None = None,
                time_limit: float | None = DEFAULT_TIME_LIMIT, isolation: str | None = AUTO_ISOLATION) -> Script:
    """One script for map ``spec``: a built-in name, a user script reference or a Script object.

    ``isolation`` says how scripts that are not built-in (user files, user objects) run: ``"guard"`` in-process
    under :class:`GuardedScript`, ``"process"`` in a child process (:class:`ProcessIsolatedScript`, a reference is
    then imported in the child only) behind the guard's command checks, ``"none"`` bare, None (auto, the default)
    as :func:`resolve_isolation` decides. ``guard`` True also guards built-in scripts; False runs every script bare.
    """
    spec = load_map(spec)
    isolation = resolve_isolation(entry, check_isolation(isolation, guard))
    if guard is False:
        isolation = "none"
    if isolation != "none" and _sandboxed(entry):  # already in a child: only add the command checks
        return entry if isinstance(entry, GuardedScript) else GuardedScript(entry, time_limit=None)
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
                  time_limit: float | None = DEFAULT_TIME_LIMIT, isolation: str | None = AUTO_ISOLATION) -> Script:
    """The opponent for map ``spec`` (see the module docstring for what ``opponent`` may be).

    A single script comes back as itself; ``"default"``, ``"blackbox"`` and lists come back as a :class:`Mixture`
    named after the pool (or ``"mixture"``) whose ``name_of(b)`` names the script battle b plays. Raises
    ValueError for unknown names, scripts that do not play the map, and invalid ``opponent_probs`` (one per script,
    finite, non-negative, summing to 1).

    How user scripts (files, references, Script objects that are not built-in) run is this function's
    ``isolation``, the single entry point for it (built-in scripts are trusted and always run in-process, zero
    copy):

    - None (default, "auto"): ``"process"`` for a script loaded from a file or module reference (where the platform
      supports it: POSIX), ``"guard"`` for a Script object built in-process.
    - ``"guard"``: in-process under :class:`GuardedScript`: read-only copies of the state, checked commands, a
      best-effort ``time_limit`` per call. A bug catcher for your own code, not a security boundary (see
      :mod:`~smac_hard_gym.opponents.guard` for what it cannot stop).
    - ``"process"``: in a child process (:class:`ProcessIsolatedScript`) killed with its process group at
      ``time_limit``, with a memory limit; hangs, segfaults and ``os._exit`` become a :class:`ScriptError` and the
      next call starts a new child. Costs a process start and a round trip per call.
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
