"""Autoreset mode spellings shared by the vector envs (kept free of the engine, so worker plumbing stays light)."""

from __future__ import annotations

from gymnasium.vector import AutoresetMode

__all__ = ["AUTORESET_NAMES", "parse_autoreset_mode"]

# Every spelling of a mode that users meet: gymnasium's values ("NextStep"), enum names, RLlib's "next_step".
AUTORESET_NAMES = {key: mode for mode in AutoresetMode for key in (mode.value, mode.name, mode.name.lower())}


def parse_autoreset_mode(mode: AutoresetMode | str) -> AutoresetMode:
    """An :class:`~gymnasium.vector.AutoresetMode` from the enum or one of its spellings."""
    if isinstance(mode, AutoresetMode):
        return mode
    if isinstance(mode, str) and mode in AUTORESET_NAMES:
        return AUTORESET_NAMES[mode]
    raise ValueError(f"autoreset_mode must be an AutoresetMode or one of {sorted(AUTORESET_NAMES)}, got {mode!r}")
