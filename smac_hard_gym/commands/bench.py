"""``smac-hard-gym bench``: throughput benchmarks, with the machine, versions and date named.

- ``bench vector``: the suite through the gymnasium vector API (native and subprocess vector envs, the engine
  alone, ``StarCraft2Env`` on one battle, opponents, memory, profiles), optionally side by side with SMAX
  (``--peer smax``); writes JSON, a markdown table and a PNG.
- ``bench report PATH.json``: re-render the tables, targets and plot of a ``bench vector`` JSON.
- ``bench engine``: the battle engine alone, random commands, resets counted.
- ``bench train``: MaskablePPO training steps/s, sb3-contrib's policy and buffer against ``train``'s joint ones.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

HELP = "throughput benchmarks: vector envs (side by side with SMAX), the engine alone, or MaskablePPO training"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from smac_hard_gym.bench import suite  # the defaults and choices of `bench vector`
    from smac_hard_gym.bench.arguments import comma_ints, comma_names, map_sizes, positive_int, positive_seconds

    def csv(values: tuple) -> str:
        return ",".join(map(str, values))

    sub = parser.add_subparsers(dest="target", metavar="TARGET", required=True)
    vec = sub.add_parser("vector", help="env-steps/s through the gymnasium vector API (and SMAX with --peer smax)",
                         description="Env-steps/s through the gymnasium vector API with random legal actions, "
                                     "resets included; medians of repeats, compile time apart.")
    vec.add_argument("--maps", type=comma_names, default=list(suite.DEFAULT_MAPS),
                     help=f"default {csv(suite.DEFAULT_MAPS)}")
    vec.add_argument("--num-envs", type=comma_ints, default=list(suite.DEFAULT_NUM_ENVS),
                     help=f"battles per native vector env (default {csv(suite.DEFAULT_NUM_ENVS)})")
    vec.add_argument("--opponent", choices=suite.OPPONENTS, default="base",
                     help="opponent of the main grid: SMAC's base, or the map's default SMAC-HARD mixture")
    vec.add_argument("--workers", type=comma_ints, default=list(suite.DEFAULT_WORKERS),
                     help=f"subprocess workers (default {csv(suite.DEFAULT_WORKERS)})")
    vec.add_argument("--envs-per-worker", type=comma_ints, default=list(suite.DEFAULT_ENVS_PER_WORKER),
                     help=f"battles per subprocess worker, K (default {csv(suite.DEFAULT_ENVS_PER_WORKER)})")
    vec.add_argument("--subproc-maps", type=comma_names, default=list(suite.DEFAULT_SUBPROC_MAPS),
                     help=f"maps of the subprocess runs (default {csv(suite.DEFAULT_SUBPROC_MAPS)})")
    vec.add_argument("--opponent-num-envs", type=positive_int, default=256,
                     help="battles of the base-vs-default opponent comparison (default 256)")
    vec.add_argument("--memory", type=map_sizes, default=[("3m", 4096)],
                     help="MAP:N configurations whose peak RSS is read in a fresh process (default 3m:4096)")
    vec.add_argument("--profile", type=map_sizes, default=[],
                     help="MAP:N configurations to profile (default: each SMAX map at its best native batch)")
    vec.add_argument("--sections", type=comma_names, default=list(suite.DEFAULT_SECTIONS),
                     help=f"subset of {csv(suite.SECTIONS)} (default {csv(suite.DEFAULT_SECTIONS)}; ray needs the "
                          "[ray] extra)")
    vec.add_argument("--ray-maps", type=comma_names, default=list(suite.DEFAULT_RAY_MAPS),
                     help=f"maps of the ray section (default {csv(suite.DEFAULT_RAY_MAPS)})")
    vec.add_argument("--ray-actors", type=comma_ints, default=list(suite.DEFAULT_RAY_ACTORS),
                     help=f"Ray actor counts, each against as many subprocess workers (default "
                          f"{csv(suite.DEFAULT_RAY_ACTORS)})")
    vec.add_argument("--ray-envs-per-actor", type=positive_int, default=256,
                     help="battles per Ray actor (and subprocess worker) in the ray section, K (default 256)")
    vec.add_argument("--ray-address", default=None, metavar="ADDRESS",
                     help="run the ray section on this Ray cluster (default: a local Ray started for it)")
    vec.add_argument("--seconds", type=positive_seconds, default=1.0, help="seconds per timed window (default 1)")
    vec.add_argument("--repeats", type=positive_int, default=3,
                     help="timed windows; the median is reported (default 3)")
    vec.add_argument("--seed", type=int, default=0)
    vec.add_argument("--peer", choices=["smax"], default=None,
                     help="also run SMAX (JaxMARL) on the maps it has, in the same run, through its own Python")
    vec.add_argument("--peer-python", default=None, metavar="PATH",
                     help="the Python with jaxmarl (default $SMAX_PYTHON, else smax-venv/ beside the repository)")
    vec.add_argument("--numba-threads", type=positive_int, default=None, metavar="N",
                     help="threads of the engine's parallel kernels here (default: numba's, one per core); "
                          "subprocess workers always use one")
    vec.add_argument("--json", default=None, metavar="PATH",
                     help="write the results as JSON here, with the markdown table (.md) and the plot (.png) beside")
    vec.add_argument("--markdown", default=None, metavar="PATH", help="markdown table path (default: beside --json)")
    vec.add_argument("--plot", default=None, metavar="PATH", help="PNG path (default: beside --json)")

    rep = sub.add_parser("report", help="re-render the tables (.md), targets and plot (.png) of a `bench vector` JSON")
    rep.add_argument("json", metavar="PATH", help="a JSON written by `bench vector --json`")
    rep.add_argument("--markdown", default=None, metavar="PATH", help="markdown path (default: beside the JSON)")
    rep.add_argument("--plot", default=None, metavar="PATH", help="PNG path (default: beside the JSON)")

    eng = sub.add_parser("engine", help="the battle engine alone, random commands, resets counted")
    eng.add_argument("--map", default="3m", help="map name, or comma-separated names (default 3m)")
    eng.add_argument("--batch", type=comma_ints, default=[4096],
                     help="battles per batch, comma-separated (default 4096)")
    eng.add_argument("--steps", type=int, default=200, help="timed steps per repeat (default 200)")
    eng.add_argument("--repeats", type=int, default=3, help="timed repeats; the median is reported (default 3)")
    eng.add_argument("--json", default=None, metavar="PATH", help="write results as JSON")

    tr = sub.add_parser("train", help="MaskablePPO training steps/s, sb3-contrib's policy against train's joint one "
                                      "(needs the [train] extra)")
    tr.add_argument("--map", type=comma_names, default=["8m"], help="map name, or comma-separated names (default 8m)")
    tr.add_argument("--timesteps", type=positive_int, default=8192,
                    help="env steps per timed round, rounded up to whole rollouts (2048 steps for the joint policy, "
                         "3200 for the shared one; default 8192)")
    tr.add_argument("--rounds", type=positive_int, default=3, help="timed rounds per variant; the median is reported "
                                                               "(default 3)")
    tr.add_argument("--json", default=None, metavar="PATH", help="write results as JSON")


def run(args: argparse.Namespace) -> int:
    if args.target == "engine":
        return _run_engine(args)
    if args.target == "train":
        return _run_train(args)
    if args.target == "report":
        return _run_report(args)
    return _run_vector(args)


def _run_report(args: argparse.Namespace) -> int:
    import json

    from smac_hard_gym.bench import must_reach

    path = Path(args.json)
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as err:
        print(f"smac-hard-gym bench report: cannot read {path}: {err}", file=sys.stderr)
        return 2
    if doc.get("benchmark") != "vector":
        print(f"smac-hard-gym bench report: {path} is not a `bench vector` result (benchmark="
              f"{doc.get('benchmark')!r})", file=sys.stderr)
        return 2
    doc["must_reach"] = must_reach(doc)
    _write_outputs(doc, doc.get("command", ""), None, args.markdown or str(path.with_suffix(".md")),
                   args.plot or str(path.with_suffix(".png")))
    return 0


def _write_outputs(doc: dict, command: str, json_path: str | None, markdown: str | None, plot: str | None) -> None:
    import json

    from smac_hard_gym.bench import markdown_report, plot_report

    text = markdown_report(doc, command)
    print()
    print(text)
    if json_path:
        Path(json_path).parent.mkdir(parents=True, exist_ok=True)
        Path(json_path).write_text(json.dumps(doc, indent=1))
        print(f"wrote {json_path}")
    if markdown:
        Path(markdown).parent.mkdir(parents=True, exist_ok=True)
        Path(markdown).write_text(text)
        print(f"wrote {markdown}")
    if plot:
        print(f"wrote {plot}" if plot_report(doc, plot) else "no plot: matplotlib is not installed (pip install "
              "matplotlib)")


def _run_vector(args: argparse.Namespace) -> int:
    from smac_hard_gym.bench import SuiteConfig, run_suite

    config = SuiteConfig(maps=args.maps, num_envs=args.num_envs, opponent=args.opponent, workers=args.workers,
                         envs_per_worker=args.envs_per_worker, subproc_maps=args.subproc_maps,
                         opponent_num_envs=args.opponent_num_envs, memory=args.memory, profile=args.profile,
                         sections=args.sections, seconds=args.seconds, repeats=args.repeats, seed=args.seed,
                         peer=args.peer, peer_python=args.peer_python, numba_threads=args.numba_threads,
                         ray_maps=args.ray_maps, ray_actors=args.ray_actors,
                         ray_envs_per_actor=args.ray_envs_per_actor, ray_address=args.ray_address)
    print("config: " + ", ".join(f"{k}={v}" for k, v in vars(args).items() if k not in ("command", "target")))
    try:
        doc = run_suite(config)
    except (ValueError, RuntimeError, KeyError) as err:
        print(f"smac-hard-gym bench vector: {err}", file=sys.stderr)
        return 2
    command = "smac-hard-gym " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv[1:] else ""
    doc["command"] = command
    markdown = args.markdown or (str(Path(args.json).with_suffix(".md")) if args.json else None)
    plot = args.plot or (str(Path(args.json).with_suffix(".png")) if args.json else None)
    _write_outputs(doc, command, args.json, markdown, plot)
    return 0


def _run_engine(args: argparse.Namespace) -> int:
    from smac_hard_gym.bench import bench_engine, machine_info
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
            print(f"{name:<18}{batch:>7}{r.steps_per_second:>14,.0f}{r.setup_seconds:>11.1f}"
                  f"{r.extra['state_bytes_per_battle']:>14,.0f}")
    return _save(args.json, "engine", results)


def _save(path: str | None, kind: str, results: list) -> int:
    from smac_hard_gym.bench import write_json

    if path:
        write_json(path, kind, results)
        print(f"wrote {path}")
    return 0


def _run_train(args: argparse.Namespace) -> int:
    from smac_hard_gym.bench import machine_info
    from smac_hard_gym.bench.training import bench_training
    from smac_hard_gym.maps import load_map

    for name in args.map:
        load_map(name)  # clear error for an unknown map before any training
    info = machine_info()
    print(f"machine: {info['cpu']}, {info['cores']} cores; one torch and one engine thread, 64 battles, "
          f"train's PPO settings; {args.rounds} rounds of {args.timesteps:,} steps per variant, interleaved")
    print(f"{'map':<14}{'variant':>8}{'env-steps/s':>13}{'min-max':>16}{'vs stock':>10}{'vs joint':>10}"
          f"{'same weights':>14}")
    results = []
    for name in args.map:
        for r in bench_training(name, timesteps=args.timesteps, rounds=args.rounds):
            results.append(r)
            low, high = r.spread
            print(f"{name:<14}{r.mode:>8}{r.steps_per_second:>13,.0f}{f'{low:,.0f}-{high:,.0f}':>16}"
                  f"{r.extra['speedup_vs_stock']:>9.2f}x{r.extra['speedup_vs_joint']:>9.2f}x"
                  f"{'n/a' if r.extra['same_weights'] is None else str(r.extra['same_weights']):>14}")
    return _save(args.json, "train", results)
