"""``smac-hard-gym eval``: masked win rate of a trained model per opponent script and for their mixture.

``--opponent all`` evaluates every script that plays the map, ``blackbox`` the map's SMAC-HARD pool without
``base`` (the paper's black-box evaluation), ``default`` the full pool, or a script name (names joined by commas).
The mixture row is the pool's expected win rate: the scripts' win rates weighted by the pool's probabilities.

By default every script plays the test battles that ``train`` evaluates on (seeded from
:data:`~smac_hard_gym.training.protocol.TEST_SEED_BASE`, disjoint from every run's training battles), so a model's
win rate against a script here is the one ``train`` reported against that script alone, with the same episodes. Each
row gives the episodes, the standard error and a 95% Wilson interval of its win rate. The evaluation itself is
:func:`smac_hard_gym.training.evaluation.evaluate_scripts`; this module parses options and prints the table.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

HELP = "evaluate a trained model's win rate per opponent script and for the mixture"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--model", required=True,
                        help="path of a model.zip written by `smac-hard-gym train` (loading runs the pickled code "
                             "it holds, as stable-baselines3 loads models: only load files you trust)")
    parser.add_argument("--map", default=None, help="map name (default: the map the model was trained on)")
    parser.add_argument("--opponent", default="all", help="all | default | blackbox | NAME[,NAME...] (default all)")
    parser.add_argument("--episodes", type=int, default=32, help="episodes per script (default 32)")
    parser.add_argument("--num-envs", type=int, default=16, help="battles stepped together (default 16)")
    parser.add_argument("--seed", type=int, default=None,
                        help="seed of the first test battle (battle b: SEED + b; default: the test seeds train "
                             "evaluates on, 1000000000 + b)")
    parser.add_argument("--sample-actions", action="store_true",
                        help="sample each unit's action from the policy instead of taking the most likely one (the "
                             "protocol's default, as in SB3's evaluate_policy, MAPPO and EPyMARL); torch's generator "
                             "is seeded with the first test battle's seed, so a run repeats")
    parser.add_argument("--json", default=None, help="write the results here (default: next to the model)")


def run(args: argparse.Namespace) -> int:
    from smac_hard_gym.files import write_json
    from smac_hard_gym.training.evaluation import evaluate_scripts, resolve_opponents
    from smac_hard_gym.training.protocol import TEST_SEED_BASE, eval_seeds, training_seeds
    from smac_hard_gym.training.run_files import load_run_config

    model_path = Path(args.model)
    if not model_path.is_file():
        raise SystemExit(f"no model at {model_path}")
    if args.episodes < 1 or args.num_envs < 1:
        raise SystemExit(f"--episodes and --num-envs must be >= 1, got {args.episodes} and {args.num_envs}")
    run_config = load_run_config(model_path)
    map_name = args.map or (run_config.map_name if run_config else None)
    if map_name is None:
        raise SystemExit("the model has no config.json next to it; pass --map")
    env_kwargs = run_config.env_kwargs() if run_config else {}
    seed = TEST_SEED_BASE if args.seed is None else args.seed
    if seed < 0:
        raise SystemExit(f"--seed must be >= 0, got {seed}")
    seeds = eval_seeds(min(args.num_envs, args.episodes), seed)
    if run_config is not None and set(seeds) & set(training_seeds(run_config.seed, run_config.num_envs)):
        print(f"warning: test battles seeded {seeds[0]}..{seeds[-1]} include seeds of the model's training battles "
              f"({run_config.seed}..{run_config.seed + run_config.num_envs - 1}); leave --seed out to evaluate on "
              "the test seeds")
    try:
        names, _ = resolve_opponents(map_name, args.opponent)
    except (TypeError, ValueError) as err:
        raise SystemExit(f"smac-hard-gym eval: {err}") from None

    import torch

    from smac_hard_gym.training.run_files import load_model

    torch.set_num_threads(1)
    model = load_model(model_path)  # a file that is not a model: one ValueError naming it
    _check_fits(model, map_name, env_kwargs, run_config.map_name if run_config else None)
    actions = "sampled" if args.sample_actions else "most likely"
    print(f"model {model_path} on {map_name}: {len(names)} script(s) x {args.episodes} episodes, test battles "
          f"seeded {seeds[0]}..{seeds[-1]}, {actions} actions")
    results = evaluate_scripts(model, map_name, args.opponent, args.episodes, num_envs=args.num_envs,
                               seed=seed, env_kwargs=env_kwargs, log=print, deterministic=not args.sample_actions)
    rows = [("opponent", "weight", "win rate", "stderr", "95% interval", "wins", "mean return")]
    for name, row in results["scripts"].items():
        low, high = row["ci95"]
        rows.append((name, f"{results['weights'][name]:.3f}", f"{row['win_rate']:.3f}", f"{row['stderr']:.3f}",
                     f"[{low:.3f}, {high:.3f}]", f"{row['wins']}/{row['episodes']}", f"{row['mean_return']:.2f}"))
    mixture = results["mixture"]
    rows.append((f"{args.opponent} (mixture)", "1.000", f"{mixture['win_rate']:.3f}", f"{mixture['stderr']:.3f}",
                 f"[{mixture['ci95'][0]:.3f}, {mixture['ci95'][1]:.3f}]", "", ""))
    print()
    print(format_table(rows))
    sampled = "_sampled" if args.sample_actions else ""
    default_name = f"eval_{map_name}_{args.opponent.replace(',', '+')}{sampled}.json"
    out = Path(args.json) if args.json else model_path.with_name(default_name)
    write_json(out, results)
    print(f"\nwrote {out}")
    return 0


def _check_fits(model: Any, map_name: str, env_kwargs: dict, trained_on: str | None) -> None:
    """Fail with one line when the model's observation or action space is not the map's (a 3m model on 8m)."""
    from smac_hard_gym.envs.gym_env import SMACHardEnv

    env = SMACHardEnv(map_name, **{k: v for k, v in env_kwargs.items() if k != "map_name"})
    try:
        fits = (model.observation_space == env.observation_space and model.action_space == env.action_space)
        if not fits:
            where = f"trained on {trained_on}" if trained_on else "trained on another map"
            raise ValueError(f"the model was {where} (action space {model.action_space}); {map_name} needs "
                             f"{env.action_space}: evaluate it on {trained_on or 'its own map'}, or train one on "
                             f"{map_name}")
    finally:
        env.close()


def format_table(rows: Sequence[tuple[str, ...]]) -> str:
    """Left-aligned text columns."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip() for row in rows)
