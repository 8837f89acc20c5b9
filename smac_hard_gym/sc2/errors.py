"""Errors of the sc2 backend. Each message names the path, value or request involved and the fix."""

from __future__ import annotations

__all__ = [
    "Sc2Error", "Sc2NotFoundError", "MapNotInstalledError", "MapInstallError", "Sc2LaunchError", "Sc2GameError",
]


class Sc2Error(RuntimeError):
    """Base class of every error raised by :mod:`smac_hard_gym.sc2`."""


class Sc2NotFoundError(Sc2Error, FileNotFoundError):
    """No StarCraft II installation where ``SC2PATH`` (or the platform default) points."""


class MapNotInstalledError(Sc2Error, FileNotFoundError):
    """A SMAC-HARD map file is missing from ``$SC2PATH/Maps/SMAC_HARD_maps``."""


class MapInstallError(Sc2Error, ValueError):
    """``smac-hard-gym maps install`` was given a source it cannot use."""


class Sc2LaunchError(Sc2Error):
    """The game could not be started and joined within the configured time and attempts."""


class Sc2GameError(Sc2Error):
    """The running game does not hold what the map promises (unit counts, types, map size)."""
