"""Real StarCraft II behind the backend interface, through pysc2_evolved (the ``[sc2]`` extra).

- :class:`Sc2Backend` (:mod:`.backend`): B battles, two game processes each; ``make_backend("sc2", ...)``,
  ``StarCraft2Env(backend="sc2")`` and ``gymnasium.make(..., backend="sc2")`` build it.
- :mod:`.launcher`: starting and joining games with bounded time and retries; nothing left behind.
- :mod:`.convert`: raw units <-> battle state, commands -> raw unit commands; :mod:`.abilities`: the id tables.
- :mod:`.maps`: where the game and SMAC-HARD's maps live; ``smac-hard-gym maps install``.
- :mod:`.testing` (not part of the backend): a protocol-level test server driven by the native engine and a
  stand-in ``SC2_x64`` in a temporary SC2PATH, for testing without the game.

Only :mod:`.maps` and :mod:`.errors` work without the extra; the rest import pysc2_evolved on first use.
"""

from __future__ import annotations

from smac_hard_gym.sc2.errors import (
    MapInstallError,
    MapNotInstalledError,
    Sc2Error,
    Sc2GameError,
    Sc2LaunchError,
    Sc2NotFoundError,
)

__all__ = [
    "Sc2Backend", "Sc2Error", "Sc2NotFoundError", "MapNotInstalledError", "MapInstallError", "Sc2LaunchError",
    "Sc2GameError", "make_sc2path",
]


def __getattr__(name: str):  # the backend and the stand-in need the [sc2] extra: import them on first use
    if name == "Sc2Backend":
        from smac_hard_gym.sc2.backend import Sc2Backend

        return Sc2Backend
    if name == "make_sc2path":
        from smac_hard_gym.sc2.testing.standin import make_sc2path

        return make_sc2path
    raise AttributeError(f"module 'smac_hard_gym.sc2' has no attribute {name!r}")
