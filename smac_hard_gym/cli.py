"""``smac-hard-gym`` command line: thin argparse front ends, one module per subcommand.

Each module in :mod:`smac_hard_gym.commands` defines ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``;
adding a subcommand is one line in ``COMMANDS``. Modules are imported lazily so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

COMMANDS: dict[str, str] = {
    "maps": "smac_hard_gym.commands.maps",
    "scripts": "smac_hard_gym.commands.scripts",
    "duel": "smac_hard_gym.commands.duel",
    "solutions": "smac_hard_gym.commands.solutions",
    "bench": "smac_hard_gym.commands.bench",
    "demo": "smac_hard_gym.commands.demo",
    "replay": "smac_hard_gym.commands.replay",
    "train": "smac_hard_gym.commands.train",
    "eval": "smac_hard_gym.commands.eval",
    "baselines": "smac_hard_gym.commands.baselines",
    "scriptlab": "smac_hard_gym.commands.scriptlab",
}


def _user_errors() -> tuple[type[BaseException], ...]:
    from smac_hard_gym.opponents.api import ScriptError

    return (ValueError, TypeError, FileNotFoundError, ImportError, ScriptError)


def build_parser() -> argparse.ArgumentParser:
    from smac_hard_gym import __version__

    parser = argparse.ArgumentParser(prog="smac-hard-gym", description="SMAC-HARD on an embedded battle engine.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, module_name in COMMANDS.items():
        module = importlib.import_module(module_name)
        module.add_arguments(sub.add_parser(name, help=module.HELP, description=module.HELP))
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    module = importlib.import_module(COMMANDS[args.command])
    try:
        return int(module.run(args) or 0)
    except KeyboardInterrupt:
        print(f"\nsmac-hard-gym {args.command}: interrupted", file=sys.stderr)
        return 130
    except _user_errors() as err:  # bad input: one line naming it, no traceback (SMAC_HARD_GYM_TRACEBACK=1 shows it)
        if os.environ.get("SMAC_HARD_GYM_TRACEBACK"):
            raise
        print(f"smac-hard-gym {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
