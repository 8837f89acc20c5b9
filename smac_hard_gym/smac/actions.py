"""SMAC's discrete actions: which are available, and how a choice becomes an engine command.

Per agent, ``n_actions = 6 + n_enemies`` (``docs/smac_interface.md`` §2):

====  ====================================  ===========================================================
id    meaning                               available when
====  ====================================  ===========================================================
0     no-op                                 the agent is dead (then it is the only choice)
1     stop                                  alive
2-5   move north / south / east / west      alive and the probe cell at move_amount/2 is pathable
6+j   attack enemy j                        alive, enemy j alive, centre distance <= 6
6+j   heal ally j (medivacs)                alive, ally j alive and not a medivac, centre distance <= 6
====  ====================================  ===========================================================

A move goes to ``(x, y +- move_amount)`` or ``(x +- move_amount, y)``; every command replaces the current order.
The probe cell is ``(int(x), int(y + move_amount / 2))`` and so on, with Python's ``int`` truncation toward zero.

Every API (``StarCraft2Env``, the gymnasium env, the vector envs, self-play) checks actions with
:func:`validate_actions`: an action is an integer (a Python or NumPy int, or a float with an integral value such as
``3.0``, since some libraries hand over float arrays); bools, strings, complex numbers, ``None``, nested sequences
and fractional floats raise ``TypeError``; a wrong shape, a value out of ``0..n_actions-1`` (``-1``, ``inf``,
``nan``, ``1e19``, ``2**70``) or an unavailable action raises :class:`InvalidActionError` (a ``ValueError``). The
messages name the value as it was passed. A rejected step changes nothing.
"""

from __future__ import annotations

import math
import operator
from typing import Any

import numpy as np
from gymnasium.error import ResetNeeded

from smac_hard_gym.engine.state import BattleState, Commands
from smac_hard_gym.smac.features import SIDE_NAMES, SideFeatures
from smac_hard_gym.smac.kernels import (
    N_ACTIONS_NO_ATTACK,
    check_decode_batch,
    first_invalid_action,
)

__all__ = ["InvalidActionError", "ResetNeededError", "available_actions", "check_actions", "validate_actions",
           "decode_actions", "raise_unavailable", "action_name"]

ACTION_NOOP, ACTION_STOP = 0, 1
_MOVE_WORDS = ("move north", "move south", "move east", "move west")


class InvalidActionError(ValueError):
    """Actions of the wrong shape, out of range or not available (the message names agent and action)."""


class ResetNeededError(ResetNeeded, RuntimeError):
    """``step()`` before the first ``reset()`` or after the episode ended, from any env API: gymnasium's
    ``ResetNeeded`` (what its order-enforcing wrapper raises) and a ``RuntimeError``."""


def validate_actions(actions: Any, shape: tuple[int, ...], n_actions: int, who: str = "red") -> np.ndarray:
    """``actions`` as a fresh int64 array of ``shape`` ((n_agents,) or (battles, n_agents)), in ``0..n_actions-1``.

    Accepts Python and NumPy integers (and other ``__index__`` types, such as torch tensors) and floats with an
    integral value. Raises ``TypeError`` for anything else
    (bool, str, complex, None, nested sequences, fractional floats) and :class:`InvalidActionError` for a wrong
    shape or a value out of range (``nan``, ``inf`` and ints beyond int64 included); ``who`` ("red", "blue")
    starts the agent's name in the message. Availability is :func:`check_actions`'s job.
    """
    if (type(actions) is list and len(shape) == 1 and len(actions) == shape[0]
            and all(type(a) is int and 0 <= a < n_actions for a in actions)):
        return np.array(actions, dtype=np.int64)  # pymarl's usual call, a list of legal Python ints: no detour
    if type(actions) is np.ndarray and actions.dtype == np.int64 and actions.shape == tuple(shape) and actions.size:
        # A policy's int64 array, the usual call: a range check and a copy (on a few agents, Python's min and max
        # over a list beat numpy's reductions, whose call costs dominate there).
        if actions.size <= 64:
            flat = actions.ravel().tolist()
            low, high = min(flat), max(flat)
        else:
            low, high = actions.min(), actions.max()
        if low >= 0 and high < n_actions:
            return actions.copy()
    if isinstance(actions, (str, bytes, dict, set)) or actions is None:
        raise TypeError(f"{who} actions must be a sequence or array of ints of shape {shape}, got {actions!r}")
    if isinstance(actions, np.ndarray) and actions.dtype.kind in "iuf":
        arr = actions
    else:
        try:
            arr = np.asarray(actions, dtype=object)
        except (ValueError, TypeError):  # ragged nesting numpy cannot lay out
            raise InvalidActionError(f"{who} actions must have shape {tuple(shape)} ({_axes(shape)}), got the "
                                     f"ragged {actions!r}") from None
    if arr.shape != tuple(shape):
        raise InvalidActionError(f"{who} actions must have shape {tuple(shape)} ({_axes(shape)}), got {arr.shape}")
    kind = arr.dtype.kind
    if kind in "iu":
        out_of_range = (arr < 0) | (arr >= n_actions)
    elif kind == "f":
        finite = np.isfinite(arr)
        fraction = finite & (arr != np.floor(np.where(finite, arr, 0)))
        if fraction.any():
            _raise_type(arr, _first(fraction), shape, n_actions, who)
        out_of_range = ~finite | (arr < 0) | (arr >= n_actions)
    else:
        return _validate_objects(arr, shape, n_actions, who)
    if out_of_range.any():
        _raise_range(arr, _first(out_of_range), shape, n_actions, who)
    return arr.astype(np.int64)


def _validate_objects(arr: np.ndarray, shape: tuple[int, ...], n_actions: int, who: str) -> np.ndarray:
    """The element-wise path for lists and object arrays: each element's type decides."""
    flat = arr.reshape(-1).tolist()
    types = set(map(type, flat))
    if types <= {int}:  # plain Python ints: one conversion, unless some overflow int64
        try:
            return validate_actions(np.array(flat, dtype=np.int64).reshape(shape), shape, n_actions, who)
        except OverflowError:
            pass
    values = np.empty(len(flat), dtype=np.int64)
    for k, v in enumerate(flat):
        if isinstance(v, (bool, np.bool_)):
            _raise_type(arr, _at(arr, k), shape, n_actions, who)
        if isinstance(v, (float, np.floating)):
            if math.isfinite(v) and v != math.floor(v):
                _raise_type(arr, _at(arr, k), shape, n_actions, who)
        elif not isinstance(v, (int, np.integer)):
            try:  # other integer types (a 0-d torch int tensor) say so through __index__
                v = operator.index(v)
            except TypeError:
                _raise_type(arr, _at(arr, k), shape, n_actions, who)
        if not 0 <= v < n_actions:  # also false for nan
            _raise_range(arr, _at(arr, k), shape, n_actions, who)
        values[k] = int(v)
    return values.reshape(shape)


def _at(arr: np.ndarray, k: int) -> tuple[int, ...]:
    """The index of flat element ``k`` of ``arr``."""
    return tuple(int(i) for i in np.unravel_index(k, arr.shape))


def _first(flags: np.ndarray) -> tuple[int, ...]:
    """The index of the first True of ``flags``."""
    return tuple(int(v) for v in np.argwhere(flags)[0])


def _axes(shape: tuple[int, ...]) -> str:
    return "battles, agents" if len(shape) == 2 else "one action per agent"


def _agent(index: tuple[int, ...], shape: tuple[int, ...], who: str) -> str:
    """The agent at ``index``: "red agent 2", or "battle 3, red agent 2" in a batch."""
    where = f"battle {index[0]}, " if len(shape) == 2 and shape[0] > 1 else ""
    return f"{where}{who} agent {index[-1]}"


def _shown(value: Any) -> str:
    """The value as the caller wrote it: NumPy scalars as their Python value (``1e+19``, not a wrapped int)."""
    return repr(value.item() if isinstance(value, np.generic) else value)


def _raise_type(arr: np.ndarray, index: tuple[int, ...], shape: tuple[int, ...], n_actions: int, who: str) -> None:
    value = arr[index]
    what = "a bool" if isinstance(value, (bool, np.bool_)) else f"of type {type(value).__name__}"
    if isinstance(value, (float, np.floating)):
        what = "not a whole number"
    raise TypeError(f"{_agent(index, shape, who)}: action {_shown(value)} is {what}; actions are ints "
                    f"0..{n_actions - 1}")


def _raise_range(arr: np.ndarray, index: tuple[int, ...], shape: tuple[int, ...], n_actions: int, who: str) -> None:
    raise InvalidActionError(f"{_agent(index, shape, who)}: action {_shown(arr[index])} is out of range; actions are "
                             f"0..{n_actions - 1}")


def action_name(action: int, healer: bool = False) -> str:
    """Readable name of a SMAC action id."""
    if action == ACTION_NOOP:
        return "no-op"
    if action == ACTION_STOP:
        return "stop"
    if action < N_ACTIONS_NO_ATTACK:
        return _MOVE_WORDS[action - 2]
    j = action - N_ACTIONS_NO_ATTACK
    return f"heal ally {j}" if healer else f"attack enemy {j}"


def available_actions(feats: SideFeatures, state: BattleState, out: np.ndarray | None = None,
                      rows: np.ndarray | None = None) -> np.ndarray:
    """Available actions of every agent of ``feats``'s side: bool ``(B, n_agents, n_actions)`` (of battles ``rows``
    only, when given: ``(len(rows), n_agents, n_actions)``)."""
    return feats.available_actions(state, out, rows)


def check_actions(feats: SideFeatures, actions: Any, avail: np.ndarray, active: np.ndarray | None = None,
                  hint: str = "") -> np.ndarray:
    """Validate a side's actions ``(B, n_agents)`` (:func:`validate_actions`), then against ``avail``; returns them
    as a fresh int64 array.

    Raises :class:`InvalidActionError` naming the first offending agent, its action and the available ones (then
    ``hint``). Availability is not checked in battles with ``active[b]`` False; types and range always are.
    """
    batch, n = avail.shape[0], feats.n_agents
    acts = validate_actions(actions, (batch, n), feats.n_actions, SIDE_NAMES[feats.side])
    check = np.ones(batch, dtype=bool) if active is None else np.ascontiguousarray(active, dtype=bool)
    bad = first_invalid_action(acts, avail, check)
    if bad >= 0:
        raise_unavailable(feats, acts, avail, bad, hint)
    return acts


def raise_unavailable(feats: SideFeatures, actions: np.ndarray, avail: np.ndarray, bad: int, hint: str = "") -> None:
    """Raise :class:`InvalidActionError` for the unavailable action at flat index ``bad`` (battle * n + agent),
    naming the agent, its action and the available ones (then ``hint``)."""
    batch, n = avail.shape[0], feats.n_agents
    b, i = divmod(int(bad), n)
    a = int(actions[b, i])
    who = _agent((b, i), (batch, n), SIDE_NAMES[feats.side])
    healer = bool(feats.own_healer[i])
    allowed = [int(v) for v in np.flatnonzero(avail[b, i])]
    names = ", ".join(f"{v} ({action_name(v, healer)})" for v in allowed)
    raise InvalidActionError(f"{who}: action {a} ({action_name(a, healer)}) is not available; "
                             f"available: {names}{hint}")


def decode_actions(feats: SideFeatures, state: BattleState, actions: np.ndarray, commands: Commands,
                   active: np.ndarray) -> None:
    """Write the engine commands of ``actions`` ``(B, n_agents)`` (in range; availability is not checked) into
    ``commands`` for this side's slots in battles with ``active[b]`` (other battles' commands are left as they are):
    the decoding half of the core's way down (:func:`~smac_hard_gym.smac.kernels.check_decode_batch`)."""
    batch = state.alive.shape[0]
    acts = validate_actions(actions, (batch, feats.n_agents), feats.n_actions, SIDE_NAMES[feats.side])
    anything = np.ones((batch, feats.n_agents, feats.n_actions), dtype=bool)
    check_decode_batch(acts, anything, np.ascontiguousarray(active, dtype=bool), np.zeros(0, np.int64), state.x,
                       state.y, commands, feats.constants.actions)
