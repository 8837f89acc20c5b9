"""``smac-hard-gym maps``: list every known map; ``maps install SRC`` / ``maps check`` for real StarCraft II.

- ``smac-hard-gym maps [--json]``: the maps with their units and episode limits.
- ``smac-hard-gym maps install SRC [--sc2path P]``: copy SMAC-HARD's two-player map files from a folder or zip into
  ``$SC2PATH/Maps/SMAC_HARD_maps`` (names checked against the 23 SMAC maps).
- ``smac-hard-gym maps check [--sc2path P]``: where the game is and which SMAC-HARD maps are installed.
"""

from __future__ import annotations

import argparse
import sys

HELP = "list all maps; `maps install SRC` / `maps check` set up SMAC-HARD's maps for real StarCraft II"
ACTIONS = ("list", "install", "check")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", nargs="?", choices=ACTIONS, default="list",
                        help="list (default), install SRC, or check the StarCraft II folder")
    parser.add_argument("src", nargs="?", help="install: a folder or zip holding SMAC-HARD's .SC2Map files")
    parser.add_argument("--json", action="store_true", help="list: print machine-readable JSON")
    parser.add_argument("--sc2path", help="install/check: the StarCraft II folder (default: $SC2PATH, then the "
                                          "platform default)")


def run(args: argparse.Namespace) -> int:
    if args.action != "install" and args.src is not None:
        print(f"error: `maps {args.action}` takes no SRC (got {args.src!r}); did you mean `maps install "
              f"{args.src}`?", file=sys.stderr)
        return 2
    if args.action == "install":
        return _install(args)
    if args.action == "check":
        return _check(args)
    return _list(args)


def _list(args: argparse.Namespace) -> int:
    import json

    from smac_hard_gym.maps import list_maps, load_map

    specs = [load_map(name) for name in list_maps()]
    if args.json:
        print(json.dumps([{"name": s.name, "n_agents": s.n_red, "n_enemies": s.n_blue,
                           "episode_limit": s.episode_limit, "red": s.red_unit_names,
                           "blue": s.blue_unit_names, "map_type": s.map_type} for s in specs], indent=1))
        return 0
    print(f"{len(specs)} maps")
    for spec in specs:
        print(spec.describe())
    return 0


def _install(args: argparse.Namespace) -> int:
    from smac_hard_gym.sc2.errors import Sc2Error
    from smac_hard_gym.sc2.maps import install_maps

    if args.src is None:
        print("error: `maps install` needs SRC, the folder or zip holding SMAC-HARD's .SC2Map files "
              "(the SMAC_HARD_maps folder of the SMAC-HARD repository)", file=sys.stderr)
        return 2
    try:
        report = install_maps(args.src, args.sc2path)
    except Sc2Error as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    print("\n".join(report.lines()))
    return 0


def _check(args: argparse.Namespace) -> int:
    from smac_hard_gym.maps import SMAC_MAPS
    from smac_hard_gym.sc2.errors import Sc2Error
    from smac_hard_gym.sc2.maps import find_sc2

    try:
        install = find_sc2(args.sc2path)
    except Sc2Error as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    installed = install.installed_maps()
    missing = [name for name in SMAC_MAPS if name not in installed]
    print(f"StarCraft II: {install.root} (from {install.source})")
    print(f"maps folder:  {install.maps_dir}")
    print(f"installed ({len(installed)}/{len(SMAC_MAPS)}): {', '.join(installed) or '-'}")
    if missing:
        print(f"missing: {', '.join(missing)}; run `smac-hard-gym maps install <folder-or-zip>`")
        return 1
    return 0
