"""``smac-hard-gym bench engine``: engine-only throughput (env-steps/s), machine and batch size named."""

from __future__ import annotations

import argparse

HELP = "throughput benchmarks (engine alone)"


def _ints(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated positive ints, got {text!r}") from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected comma-separated positive ints, got {text!r}")
    return values


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="target", metavar="TARGET", required=True)
    eng = sub.add_parser("engine", help="the battle engine alone, random commands, resets counted")
    eng.add_argument("--map", default="3m", help="map name, or comma-separated names (default 3m)")
    eng.add_argument("--batch", type=_ints, default=[4096], help="battles per batch, comma-separated (default 4096)")
    eng.add_argument("--steps", type=int, default=200, help="timed steps per repeat (default 200)")
    eng.add_argument("--repeats", type=int, default=3, help="timed repeats; the median is reported (default 3)")
    eng.add_argument("--json", default=None, metavar="PATH", help="write results as JSON")


def run(args: argparse.Namespace) -> int:
    from smac_hard_gym.bench import bench_engine, machine_info, write_json
    from smac_hard_gym.maps import load_map

    maps = [m for m in args.map.split(",") if m]
    for name in maps:
        load_map(name)  # clear error for an unknown map before any timing
    info = machine_info()
    print(f"machine: {info['cpu']}, {info['cores']} cores, numba {info['numba']} ({info['numba_threads']} threads)")
    print(f"{'map':<18}{'batch':>7}{'env-steps/s':>14}{'startup s':>11}{'bytes/battle':>14}")
    results = []
    for name in maps:
        for batch in args.batch:
            r = bench_engine(name, batch, steps=args.steps, repeats=args.repeats)
            results.append(r)
            print(f"{name:<18}{batch:>7}{r.steps_per_second:>14,.0f}{r.startup_seconds:>11.1f}"
                  f"{r.bytes_per_battle:>14,.0f}")
    if args.json:
        write_json(args.json, "engine", results)
        print(f"wrote {args.json}")
    return 0
