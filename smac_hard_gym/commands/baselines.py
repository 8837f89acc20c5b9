"""``smac-hard-gym baselines``: the SMAC-HARD paper's experiments as a resumable sweep of ``train`` runs.

MaskablePPO per map x opponent (``smac``, ``default``) x seed, one process per run; the ``smac`` models are then
evaluated against each script of the map's ``blackbox`` pool; results, CSV tables and curves go under ``--out``
(see :mod:`smac_hard_gym.training.baselines`). ``--report PATH`` writes the markdown tables from ``--out`` without
training; ``--experiment mixing`` is the paper's section 4.2 (10m_vs_11m: nearest, weakest, the 50/50 mixture,
mean values).
"""

from __future__ import annotations

import argparse
import shlex

HELP = "sweep MaskablePPO over maps, opponents and seeds (resumable), black-box evaluation, tables and curves"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--maps", default="all", help="'all' or maps joined by commas (default all)")
    parser.add_argument("--seeds", type=int, default=3, help="seeds per map and opponent: 0 .. N-1 (default 3)")
    parser.add_argument("--timesteps", type=int, default=1_000_000, help="env steps per run (default 1000000)")
    parser.add_argument("--out", default="results", help="results directory (default results/)")
    parser.add_argument("--opponents", default="smac,default",
                        help="opponents trained against, joined by commas (default smac,default; the models "
                             "trained against smac are evaluated black-box)")
    parser.add_argument("--eval-episodes", type=int, default=32, help="test episodes per evaluation (default 32)")
    parser.add_argument("--num-envs", type=int, default=64, help="battles stepped together per run (default 64)")
    parser.add_argument("--jobs", type=int, default=1, help="runs at the same time (default 1)")
    parser.add_argument("--experiment", default="", choices=("", "mixing"),
                        help="mixing: the paper's section 4.2 on 10m_vs_11m (nearest, weakest, nearest,weakest) "
                             "with the critic's mean value at the end; replaces --opponents")
    parser.add_argument("--train-args", default="", metavar="ARGS",
                        help="more arguments for every `smac-hard-gym train` run, as one string "
                             "(e.g. \"--n-steps 64 --lr 3e-4\")")
    parser.add_argument("--dry-run", action="store_true", help="print the plan (runs to do, skipped, redone) and stop")
    parser.add_argument("--report", default="", metavar="PATH",
                        help="write the markdown tables of --out's results to PATH, without training")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from smac_hard_gym.training.baselines import SweepConfig, report_markdown, run_sweep, write_report
    from smac_hard_gym.training.baselines.sweep import describe_states, sweep_states

    if args.report:
        path = write_report(args.out, args.report)
        print(f"wrote {path}")
        return 0
    maps = [] if args.maps == "all" else [m.strip() for m in args.maps.split(",") if m.strip()]
    if args.maps != "all" and not maps:
        raise ValueError(f"--maps must be 'all' or map names joined by commas, got {args.maps!r}")
    opponents = [o.strip() for o in args.opponents.split(",") if o.strip()]
    config = SweepConfig(maps=maps, seeds=args.seeds, timesteps=args.timesteps, out=args.out, opponents=opponents,
                         eval_episodes=args.eval_episodes, num_envs=args.num_envs, jobs=args.jobs,
                         experiment=args.experiment, train_args=shlex.split(args.train_args))
    states = sweep_states(config)
    print(f"sweep: {len(config.maps)} map(s) x {len(config.opponents)} opponent(s) "
          f"({', '.join(config.opponents)}) x {config.seeds} seed(s) = {len(states)} runs of {config.timesteps:,} "
          f"steps, {config.jobs} at a time, into {config.out}")
    print(f"  {describe_states(states)}"
          f"; black-box evaluation: {'yes' if config.blackbox else 'no'}; values: {'yes' if config.values else 'no'}")
    if args.dry_run:
        for r, state in states.items():
            print(f"  {state:<8} {r.label}")
        return 0
    results = run_sweep(config, progress=not args.no_progress)
    print()
    print(report_markdown(results, config.maps))
    print(f"wrote {config.out}/results.json, results.csv, blackbox.csv, curves/")
    return 1 if results["failed"] else 0
