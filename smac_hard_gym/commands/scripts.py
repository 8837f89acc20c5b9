"""``smac-hard-gym scripts [--map M | --path DIR]``: list the built-in opponent scripts with one-line descriptions,
or the script files in a folder (a script lab's output, say) without running them."""

from __future__ import annotations

import argparse

BASE_OPPONENTS = ("smac", "base")  # SMAC's one-player behaviour and SMAC-HARD's base_script

HELP = "list the built-in opponent scripts (all, or those that play one map) and the per-map pools"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--map", default=None, help="only the scripts that play this map, with its pools")
    parser.add_argument("--path", default=None, metavar="DIR",
                        help="list the scripts in the .py files of DIR (and its round_* folders) instead: name, class, "
                             "description and the reference opponent= takes (files are parsed, never run)")
    parser.add_argument("--json", action="store_true", help="print machine-readable JSON")


def _catalogue(map_name: str | None) -> dict:
    from smac_hard_gym.maps import list_maps, load_map
    from smac_hard_gym.opponents import SCRIPTS, pool_for_map, scripts_for_map

    if map_name is not None:
        spec = load_map(map_name)
        scripts = scripts_for_map(spec)
        return {"map": spec.name, "default": list(pool_for_map(spec, "default")),
                "blackbox": list(pool_for_map(spec, "blackbox")),
                "scripts": {n: {"description": i.description, "maps": None if i.maps is None else list(i.maps)}
                            for n, i in scripts.items()}}
    return {"scripts": {n: {"description": i.description, "maps": None if i.maps is None else list(i.maps)}
                        for n, i in SCRIPTS.items()},
            "default": {m: list(pool_for_map(m, "default")) for m in list_maps()}}


def _run_path(args: argparse.Namespace) -> int:
    import json

    from smac_hard_gym.scriptlab.report import list_scripts

    scripts = list_scripts(args.path)
    if args.json:
        print(json.dumps(scripts, indent=1))
        return 0
    if not scripts:
        print(f"no script classes in {args.path}")
        return 0
    width = max(len(s["name"]) for s in scripts) + 2
    for info in scripts:
        print(f"  {info['name']:<{width}}{info['description']}")
        print(f"  {'':<{width}}{info['reference'] or info['file']}")
    print("(use a reference as opponent=..., --red or --blue; file scripts run in the process sandbox)")
    return 0


def run(args: argparse.Namespace) -> int:
    import json

    if getattr(args, "path", None) is not None:
        if args.map is not None:
            raise ValueError("give --map or --path, not both")
        return _run_path(args)
    cat = _catalogue(args.map)
    if args.json:
        print(json.dumps(cat, indent=1))
        return 0
    scripts = cat["scripts"]
    width = max(len(n) for n in scripts) + 2
    if args.map is not None:
        print(f"map {cat['map']}: default = {', '.join(cat['default'])}; blackbox = {', '.join(cat['blackbox'])}")
        for name, info in scripts.items():
            mark = "*" if name in cat["default"] else " "
            print(f" {mark} {name:<{width}}{info['description']}")
        print("(* in the default pool; smac = SMAC's opponent, base = SMAC-HARD's; also accepted: default, blackbox, "
              "'file.py[:Class]', 'module:Name')")
        return 0
    print("the two base opponents (every map; not the same behaviour):")
    for name in BASE_OPPONENTS:
        print(f"  {name:<{width}}{scripts[name]['description']}")
    print("generic scripts (every map):")
    for name, info in scripts.items():
        if info["maps"] is None and name not in BASE_OPPONENTS:
            print(f"  {name:<{width}}{info['description']}")
    print("map scripts (SMAC-HARD strategies):")
    for name, info in scripts.items():
        if info["maps"] is not None:
            print(f"  {name:<{width}}{info['description']}  [{', '.join(info['maps'])}]")
    print("default pools (blackbox = the same without base):")
    for map_name, pool in cat["default"].items():
        print(f"  {map_name:<18}{', '.join(pool)}")
    return 0
