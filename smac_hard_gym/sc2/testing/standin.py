"""A throwaway SC2PATH whose ``SC2_x64`` is the protocol test server, so the real launch path runs without the game.

::

    root = make_sc2path(tmp_path, maps=["3m"])
    env = StarCraft2Env("3m", backend="sc2", backend_options={"sc2path": str(root)})

The folder looks like a Linux install to pysc2_evolved's ``run_configs``: ``Versions/Base<build>/SC2_x64`` (a small
executable Python script that runs :mod:`smac_hard_gym.sc2.testing.server` with the interpreter that wrote it),
``Libs/`` and ``Maps/SMAC_HARD_maps/<map>.SC2Map`` placeholders (an MPQ signature and a note; the test server reads
only the name). Everything is written at run time under the folder you pass; no map file is ever part of this
repository.
"""

from __future__ import annotations

import os
import stat
import sys
from collections.abc import Iterable
from pathlib import Path

from smac_hard_gym.maps import SMAC_MAPS
from smac_hard_gym.sc2.maps import MAP_FOLDER, MAP_SUFFIX
from smac_hard_gym.sc2.testing.server import BASE_BUILD, MODES

__all__ = ["make_sc2path", "standin_path", "PLACEHOLDER_NOTE"]

PLACEHOLDER_NOTE = b"smac-hard-gym test placeholder, not a StarCraft II map\n"
_SHEBANG_LIMIT = 127  # longest "#!interpreter" line every Linux kernel accepts

_SCRIPT = '''{shebang}
"""Stand-in for the StarCraft II binary: the smac-hard-gym protocol test server. Written by make_sc2path."""
import sys

from smac_hard_gym.sc2.testing.server import main

sys.exit(main(sys.argv[1:] + {baked!r}))
'''
_SHELL = '''#!/bin/sh
# Stand-in for the StarCraft II binary: the smac-hard-gym protocol test server. Written by make_sc2path.
exec "{python}" -m smac_hard_gym.sc2.testing.server "$@" {baked}
'''


def standin_path(root: str | os.PathLike, build: int = BASE_BUILD) -> Path:
    return Path(root) / "Versions" / f"Base{build:05d}" / "SC2_x64"


def make_sc2path(root: str | os.PathLike, maps: Iterable[str] = ("3m",), *, mode: str = "serve",
                 custom_id_base: int = 1970, build: int = BASE_BUILD, python: str = sys.executable) -> Path:
    """Write a stand-in StarCraft II folder at ``root`` and return it.

    ``maps``: SMAC map names to place (placeholders). ``mode``: ``"serve"`` (play), ``"hang"`` (accept connections,
    never answer) or ``"silent"`` (never listen), the last two for launch-timeout tests. ``custom_id_base``: the
    unit type id of the first custom ``*_RL`` unit (the real game's value differs by version and platform).
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    names = list(maps)
    unknown = [n for n in names if n not in SMAC_MAPS]
    if unknown:
        raise ValueError(f"unknown SMAC map name(s) {unknown}; allowed: {', '.join(SMAC_MAPS)}")
    root = Path(root)
    exe = standin_path(root, build)
    exe.parent.mkdir(parents=True, exist_ok=True)
    (root / "Libs").mkdir(exist_ok=True)
    baked = ["--mode", mode, "--custom-id-base", str(int(custom_id_base)), "--exit-with-parent"]
    if len(python) + 2 <= _SHEBANG_LIMIT:
        exe.write_text(_SCRIPT.format(shebang=f"#!{python}", baked=baked))
    else:  # too long for a shebang line: a shell wrapper that execs (same pid) the interpreter
        exe.write_text(_SHELL.format(python=python, baked=" ".join(baked)))
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
    maps_dir = root / "Maps" / MAP_FOLDER
    maps_dir.mkdir(parents=True, exist_ok=True)
    for name in names:
        (maps_dir / f"{name}{MAP_SUFFIX}").write_bytes(b"MPQ\x1b" + PLACEHOLDER_NOTE)
    return root
