"""``smac-hard-gym maps``: list every known map with its units and episode limit."""

from __future__ import annotations

import argparse

HELP = "list all maps with their units and episode limits"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print machine-readable JSON")


def run(args: argparse.Namespace) -> int:
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
